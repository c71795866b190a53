"""Process a whole flight: overlapping groups of frames → one temperature map per pivot.

The recording is streamed (a few groups of frames in memory at a time). Each group of ``N``
consecutive frames is registered onto its middle frame (the pivot) and turned into that pivot's
temperature map by the chosen estimator of :data:`thermocal.estimation.registry.ESTIMATORS`
(the network variants, the registered average of a calibration ``mean``, or a per-frame
calibration applied to the pivot ``calibration``) through the estimation pipeline
(:func:`thermocal.estimation.pipeline.estimate`). Outputs, each written atomically::

    OUT/temps/frame_000123.tiff     float32 °C (H, W), one per pivot
    OUT/previews/frame_000123.png   a preview with a colour bar in °C
    OUT/log.jsonl                   one line per pivot: frame, time, FPA, registration quality
                                    (lowest ECC correlation in the group), warnings, errors
    OUT/log.csv, OUT/summary.json   written at the end (frames per second per stage)

A rerun with the same options resumes: pivots whose TIFF exists are skipped.
"""

from __future__ import annotations

import csv
import json
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError, OutputError, RegistrationError
from thermocal.estimation.base import Estimator
from thermocal.estimation.pipeline import estimate
from thermocal.estimation.registry import ESTIMATORS, make_estimator
from thermocal.io.atomic import atomic_path, ensure_output_dir, write_json_atomic
from thermocal.io.recording import iter_recording, read_recording_header, write_temperature_tiff
from thermocal.registration.sequence import SequenceRegistration, register_sequence

#: Frames registered together as one sequence (a batch of groups).
BATCH_FRAMES = 512


@dataclass(frozen=True)
class FlightOptions:
    """How to process a flight (see :func:`process_flight`)."""

    method: str = "kpn"
    calibration: str | None = None
    model: str | None = None
    frames: int = 7
    stride: int = 7
    fpa_c: float | None = None
    preview_every: int = 1

    def __post_init__(self) -> None:
        info = ESTIMATORS.get(self.method)
        if info is None:
            raise InvalidInputError(
                f"unknown method {self.method!r}; choose from {', '.join(ESTIMATORS)}")
        if self.frames < 1 or self.stride < 1:
            raise InvalidInputError("--frames and --stride must be >= 1")
        if info.needs == "calibration" and self.calibration is None:
            raise InvalidInputError(f"--method {self.method} needs --calibration CAL.h5")
        if self.preview_every < 0:
            raise InvalidInputError("--preview-every must be >= 0 (0: no previews)")


@dataclass
class StageTimes:
    """Seconds spent per stage and frames that went through it."""

    seconds: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(("reading", "registration", "estimate", "writing"),
                                              0.0)
    )

    def add(self, stage: str, started: float) -> float:
        now = time.perf_counter()
        self.seconds[stage] += now - started
        return now


def pivots_of(n_total: int, n: int, stride: int) -> list[int]:
    """Pivot frame indices of the groups ``[p − n//2, p − n//2 + n)`` that fit the recording."""
    if n_total < n:
        raise InvalidInputError(f"the recording has {n_total} frames, fewer than a group of {n}")
    return [start + n // 2 for start in range(0, n_total - n + 1, stride)]


def _estimator(options: FlightOptions, frame_shape: tuple[int, int]) -> Estimator:
    """The estimator of ``options``, checked against the recording before any work: the
    calibration's frame size, the network's burst length."""
    estimator = make_estimator(options.method, model=options.model,
                               calibration=options.calibration)
    calibration = getattr(estimator, "calibration", None)
    if calibration is not None and tuple(calibration.shape) != tuple(frame_shape):
        raise InvalidInputError(
            f"the calibration is {calibration.shape[1]}x{calibration.shape[0]} "
            f"but the frames are {frame_shape[1]}x{frame_shape[0]}"
        )
    if estimator.n_frames is not None and estimator.n_frames != options.frames:
        raise InvalidInputError(
            f"the model was trained for N = {estimator.n_frames} frames; "
            f"use --frames {estimator.n_frames}"
        )
    return estimator


def _register(estimator: Estimator, frames: np.ndarray) -> SequenceRegistration | None:
    """Frame-to-previous registration of a run of frames; None for a per-frame estimator.

    Consecutive frames of a recording overlap most, and the run's many frames give a good
    fixed-pattern estimate: far faster and more accurate than registering each group alone.
    """
    return None if estimator.per_frame else register_sequence(frames)


def _preview(path: Path, temp_c: np.ndarray, title: str) -> None:
    from thermocal.plotting import save_figure, temperature_figure

    save_figure(temperature_figure(temp_c, title=title), path, dpi=80)


def process_flight(
    recording: str | Path,
    out_dir: str | Path,
    options: FlightOptions = FlightOptions(),
    *,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Process a recording into per-pivot temperature maps in ``out_dir``; returns the summary.

    ``progress(k)`` is called with the number of frames each finished group advanced.
    """
    header = read_recording_header(recording, fpa_c=options.fpa_c)
    if header.series["fpa_c"] is None and not ESTIMATORS[options.method].per_frame:
        raise InvalidInputError(
            f"{header.path}: no FPA temperature (sidecar fpa_c); give --fpa-c"
        )
    n, stride = options.frames, options.stride
    pivots = pivots_of(header.n_frames, n, stride)
    out = ensure_output_dir(Path(out_dir))
    for sub in ("temps", "previews"):
        ensure_output_dir(out / sub)
    done = _finished_pivots(out)
    estimator = _estimator(options, header.frame_shape)
    tally = _Tally()
    reader = _FrameWindow(header.path, header.frame_shape, chunk=max(64, n))
    per_batch = max(1, BATCH_FRAMES // stride)
    started = time.perf_counter()
    with open(out / "log.jsonl", "a", encoding="utf-8") as log:
        for b in range(0, len(pivots), per_batch):
            batch = pivots[b : b + per_batch]
            todo = [p for p in batch if p not in done]
            tally.skipped += len(batch) - len(todo)
            if progress and len(todo) < len(batch):
                progress(stride * (len(batch) - len(todo)))
            if not todo:
                continue
            run = _register_batch(reader, estimator, todo, n, tally.times)
            for pivot in todo:
                entry = _process_pivot(run, pivot, header.series, estimator, options, out, tally)
                log.write(json.dumps(entry) + "\n")
                log.flush()
                if progress:
                    progress(stride)
    return _finish(out, header.path, options, len(pivots), tally, time.perf_counter() - started)


@dataclass
class _Tally:
    """What a run did so far: pivots processed, skipped (done before), failed; stage times."""

    processed: int = 0
    skipped: int = 0
    failed: int = 0
    times: StageTimes = field(default_factory=StageTimes)


@dataclass(frozen=True)
class _Batch:
    """A run of frames ``[start, start + len(frames))`` read and registered together (or the
    registration's error, which every group of it then reports)."""

    start: int
    frames: np.ndarray
    sequence: SequenceRegistration | None
    error: str | None


def _register_batch(reader: _FrameWindow, estimator: Estimator, todo: list[int], n: int,
                    times: StageTimes) -> _Batch:
    """Read the frames of the groups of ``todo`` (pivots) and register them as one sequence."""
    t = time.perf_counter()
    a, z = todo[0] - n // 2, todo[-1] - n // 2 + n
    frames = reader.frames(a, z)
    t = times.add("reading", t)
    try:
        sequence, error = _register(estimator, frames), None
    except (RegistrationError, InvalidInputError) as exc:
        sequence, error = None, str(exc)
    times.add("registration", t)
    return _Batch(a, frames, sequence, error)


def _process_pivot(run: _Batch, pivot: int, series: dict[str, Any], estimator: Estimator,
                   options: FlightOptions, out: Path, tally: _Tally) -> dict[str, Any]:
    """Estimate one pivot's map from its group of ``run``, write it (and its preview) and
    return its log entry; a group that cannot be estimated is logged with its error."""
    n = options.frames
    first = pivot - n // 2
    fpa, time_s = series["fpa_c"], series["time_s"]
    entry = {"frame": pivot, "time_s": None if time_s is None else float(time_s[pivot]),
             "fpa_c": None if fpa is None else float(fpa[pivot]), "warnings": []}
    t = time.perf_counter()
    try:
        if run.error is not None:
            raise RegistrationError(run.error)
        homographies = None
        if run.sequence is not None:
            local = first - run.start
            homographies = run.sequence.to_pivot(range(local, local + n), pivot - run.start)
            entry["registration_correlation"] = float(
                run.sequence.correlation[local + 1 : local + n].min())
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            temp = estimate(
                run.frames[first - run.start : first - run.start + n], estimator,
                fpa_c=None if fpa is None else fpa[first : first + n],
                time_s=None if time_s is None else time_s[first : first + n],
                pivot=n // 2, homographies=homographies).temperature_c
        entry["warnings"] = sorted({str(w.message) for w in caught})
    except (RegistrationError, InvalidInputError) as exc:
        entry["error"] = str(exc)
        tally.failed += 1
        tally.times.add("estimate", t)
        return entry
    t = tally.times.add("estimate", t)
    preview = bool(options.preview_every) and tally.processed % options.preview_every == 0
    _write_pivot(out, pivot, temp, f"frame {pivot}, {options.method}" if preview else None)
    entry["mean_c"] = float(temp.mean())
    tally.processed += 1
    tally.times.add("writing", t)
    return entry


def _write_pivot(out: Path, pivot: int, temp: np.ndarray, preview_title: str | None) -> None:
    """A pivot's temperature TIFF, and its preview when titled; each written atomically, so
    that the finished ones stand when the disk fills."""
    name = f"frame_{pivot:06d}"
    try:
        write_temperature_tiff(out / "temps" / f"{name}.tiff", temp)
        if preview_title is not None:
            _preview(out / "previews" / f"{name}.png", temp, preview_title)
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise OutputError(
            f"{where}{exc.strerror or exc}; the maps finished so far are kept, rerun to resume"
        ) from None


def _finish(out: Path, recording: Path, options: FlightOptions, groups: int, tally: _Tally,
            elapsed: float) -> dict[str, Any]:
    """Write ``log.csv`` (the latest try of each pivot) and ``summary.json``; the summary."""
    _write_csv(out / "log.csv", _read_log(out / "log.jsonl"))
    frames_done = tally.processed * options.frames
    summary = {
        "recording": str(recording),
        "options": asdict(options),
        "groups": groups,
        "processed": tally.processed,
        "skipped_already_done": tally.skipped,
        "failed": tally.failed,
        "wall_time_s": elapsed,
        "frames_per_second": {
            stage: (frames_done / s if s > 0 else None) for stage, s in tally.times.seconds.items()
        },
        "stage_seconds": tally.times.seconds,
    }
    write_json_atomic(out / "summary.json", summary)
    return summary


class _FrameWindow:
    """Frames ``[a, z)`` of a recording, read in order, keeping only what is still needed."""

    def __init__(self, path: Path, shape: tuple[int, int], *, chunk: int) -> None:
        self._chunks = iter_recording(path, chunk=chunk)
        self._start = 0  # index of self._buffer[0]
        self._buffer = np.empty((0, *shape), np.uint16)

    def _drop_before(self, a: int) -> None:
        drop = min(max(0, a - self._start), len(self._buffer))
        self._buffer = self._buffer[drop:]
        self._start += drop

    def frames(self, a: int, z: int) -> np.ndarray:
        """Frames ``a … z − 1`` (``a`` never decreases between calls)."""
        self._drop_before(a)
        while self._start + len(self._buffer) < z:
            start, chunk = next(self._chunks)
            if not len(self._buffer):
                self._start = start
            self._buffer = np.concatenate([self._buffer, chunk]) if len(self._buffer) else chunk
            self._drop_before(a)
        return self._buffer[a - self._start : z - self._start]


def _finished_pivots(out: Path) -> set[int]:
    """Pivots already written by an earlier run (their TIFF exists)."""
    return {int(p.stem.split("_")[1]) for p in (out / "temps").glob("frame_*.tiff")}


def _read_log(log_path: Path) -> list[dict[str, Any]]:
    entries: dict[int, dict[str, Any]] = {}
    for line in log_path.read_text(encoding="utf-8").splitlines():
        try:
            entry = json.loads(line)
        except json.JSONDecodeError:  # a line cut by an interruption
            continue
        entries[int(entry["frame"])] = entry  # the latest try of each pivot
    return [entries[k] for k in sorted(entries)]


def _write_csv(path: Path, entries: list[dict[str, Any]]) -> None:
    columns = ("frame", "time_s", "fpa_c", "mean_c", "registration_correlation", "warnings",
               "error")
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for e in entries:
            writer.writerow([e.get("frame"), e.get("time_s"), e.get("fpa_c"), e.get("mean_c"),
                             e.get("registration_correlation"),
                             "; ".join(e.get("warnings", [])), e.get("error", "")])


__all__ = ["FlightOptions", "pivots_of", "process_flight"]
