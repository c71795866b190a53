"""Process a whole flight: overlapping groups of frames → one temperature map per pivot.

The recording is streamed (a few groups of frames in memory at a time). Each group of ``N``
consecutive frames is registered onto its middle frame (the pivot) and turned into that pivot's
temperature map by the chosen estimator of :data:`thermocal.estimation.registry.ESTIMATORS`
(the network variants, the registered average of a calibration ``mean``, or a per-frame
calibration applied to the pivot ``calibration``) through the estimation pipeline
(:func:`thermocal.estimation.pipeline.estimate`). Outputs, each written atomically::

    OUT/temps/frame_000123.tiff     float32 °C (H, W), one per pivot
    OUT/temps/frame_000123_sigma.tiff  its standard uncertainty, float32 °C (1σ), for an
                                    estimator with an uncertainty model
    OUT/previews/frame_000123.png   a preview with a colour bar in °C
    OUT/log.jsonl                   one line per pivot: frame, time, FPA, registration quality
                                    (lowest ECC correlation in the group), warnings, errors
    OUT/log.csv, OUT/summary.json   written at the end (frames per second per stage)
    OUT/run.json                    what the maps are made from (recording, options, files:
                                    :mod:`thermocal.pipeline.run_record`), written first

A frame whose raw image does not decode while streamed (it passed the checks at open, e.g. a
CSQ frame whose JPEG-LS data is damaged) cannot be left out, the pivots being planned from the
count of frames: the stream gives zeros in its place and names it, by its index in the
recording, in the chunk it comes in (:meth:`thermocal.io.open.StreamHeader.stream`), which the
frame window keeps beside its frames. Every group that holds it fails with its own log error,
``frame 123 does not decode (raw image does not decode (…)); group of frames 119-125 skipped``
(registration sees the nearest frame before it in its place, so that the other groups of its
batch are registered as ever); ``summary.json``'s ``damaged_frames`` lists it (``frame``: its
place in its file or its file, ``recording_index``, ``reason``) after the frames left out at
open, and one warning at the end names them. A rerun redoes those groups, which fail the same
way.

A pivot whose frame has a GPS position (a drone's R-JPEGs, FLIR files with GPS) gets it in its
maps, with the frame's time, camera and attitude, as EXIF and XMP that OpenDroneMap, Metashape
and Pix4D read; ``geotiff=True`` adds GeoTIFF tags to the same files where the frame's ground
footprint can be computed (:mod:`thermocal.io.geotag`; the log line gives the ground size of
a pixel and the field of view it came from). A frame without GPS keeps its time and camera
(EXIF) and attitude (XMP); one with none of them gives the plain writer's bytes.

The groups of a batch are estimated several at once, one per CPU core by default
(:func:`pivot_workers`: each network call on its share of the cores), their log lines written
in the groups' order: the same bytes as one at a time.

A rerun with the same options resumes, and gives the same bytes as an uninterrupted run (a
rerun with another recording, method, FPA, calibration or weights file is refused: ``run.json``):

* a pivot is finished once its preview, its σ map, its map and then its log line are written
  (in that order); a pivot is skipped only when its log line says it succeeded and its maps
  check out (readable float32 TIFFs of the frame size, finite, with the logged means); anything
  else is redone;
* groups are registered in batches fixed by their place in the recording (:data:`BATCH_FRAMES`),
  whatever was done before, so a group's map depends only on the recording and the options
  (a batch aligns only the frame pairs its groups compose through, :func:`_group_pairs`);
* temporary files an interrupted run left in the output folders (:func:`atomic_path`'s names)
  are removed, and a log line cut short is dropped; unreadable log lines and files that are not
  named like an output are ignored.

The output folders are created only once the options, the estimator and the recording have been
checked: bad input leaves nothing behind.

**Segments** (``thermocal campaign``'s tasks of a long recording): ``process_flight(...,
segment=(first, stop))`` does only the batches ``first … stop − 1``, into the flight's own
folders, its log lines into ``OUT/log.segment-FIRST.jsonl`` (several segments of one recording
run at once, in other processes, each writing only its own pivots' files), and returns its
counts instead of a summary; :func:`finish_segments` then appends their log lines to
``OUT/log.jsonl`` in order and writes the summary. The batches being fixed by place, the maps,
previews and log are the bytes of one uninterrupted run. Not for a flight-level estimator
(``selfcal``), which fits across batches.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import re
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from thermocal._validate import check_fpa_c, check_output_dir
from thermocal.burst import check_burst, fpa_value
from thermocal.cores import available_cores
from thermocal.errors import InvalidInputError, OutputError, RegistrationError
from thermocal.estimation.base import Estimator
from thermocal.estimation.paces import pace_at, recording_paces
from thermocal.estimation.pipeline import check_fpa_sigma, estimate, refuse_unchecked
from thermocal.estimation.registry import (
    ESTIMATORS,
    check_method_options,
    make_estimator,
)
from thermocal.io import geotag
from thermocal.io.atomic import (
    atomic_path,
    ensure_output_dir,
    temp_name_pattern,
    write_json_atomic,
)
from thermocal.io.open import open_stream, undecodable_text
from thermocal.io.recording import (
    quiet_tifffile,
    read_temperature_tiff,
    write_sigma_tiff,
    write_temperature_tiff,
)
from thermocal.pipeline.flight_log import read_log
from thermocal.pipeline.run_record import RUN_FILE, check_run_record, run_record
from thermocal.plotting import TemperaturePreviews
from thermocal.registration.sequence import SequenceRegistration, register_sequence
from thermocal.threads import caught_warnings, routed_warnings

#: Frames registered together as one sequence (a batch of groups). The batches are fixed by the
#: groups' places in the recording (``BATCH_FRAMES // stride`` consecutive pivots each), never by
#: what is left to do, so that a resumed run registers the same frames as an uninterrupted one.
BATCH_FRAMES = 512

#: Most frames a flight-level estimator (``selfcal``) is fitted on per batch; a longer batch is
#: fitted on every k-th frame.
MAX_FIT_FRAMES = 320


@dataclass(frozen=True)
class FlightOptions:
    """How to process a flight (see :func:`process_flight`)."""

    method: str = "kpn"
    calibration: str | None = None
    model: str | None = None
    frames: int = 7
    stride: int = 7
    fpa_c: float | None = None
    #: The standard uncertainty of ``fpa_c``, °C, which σ takes in (None: exact).
    fpa_sigma_c: float | None = None
    preview_every: int = 1
    force: bool = False
    geotiff: bool = False
    hfov_deg: float | None = None
    family: str = "tau2"
    references: str | None = None
    backend: str = "torch"
    threads: int | None = None
    #: Threads the registration may use (None: its default, up to two); a campaign's worker
    #: gives its share of the cores.
    registration_threads: int | None = None
    #: Pivots estimated at once, on as many threads (None: one per CPU core this process may
    #: use, or one when ``threads`` says how many threads the network runs on); see
    #: :func:`pivot_workers`.
    pivot_workers: int | None = None

    def __post_init__(self) -> None:
        info = ESTIMATORS.get(self.method)
        if info is None:
            raise InvalidInputError(
                f"unknown method {self.method!r}; choose from {', '.join(ESTIMATORS)}")
        if self.frames < 1 or self.stride < 1:
            raise InvalidInputError("--frames and --stride must be >= 1")
        if self.fpa_c is not None:  # before anything is read or written (a campaign's too)
            check_fpa_c(self.fpa_c, "--fpa-c")
        check_fpa_sigma(self.fpa_c, self.fpa_sigma_c)
        check_method_options(self.method, backend=self.backend, threads=self.threads,
                             calibration=self.calibration, model=self.model,
                             family=self.family, fpa_c=self.fpa_c, force=self.force)
        if self.registration_threads is not None and self.registration_threads < 1:
            raise InvalidInputError(
                f"registration threads must be >= 1, got {self.registration_threads}")
        if self.pivot_workers is not None and self.pivot_workers < 1:
            raise InvalidInputError(f"pivot workers must be >= 1, got {self.pivot_workers}")
        if info.needs == "calibration" and self.calibration is None:
            raise InvalidInputError(f"--method {self.method} needs --calibration CAL.h5")
        if self.preview_every < 0:
            raise InvalidInputError("--preview-every must be >= 0 (0: no previews)")
        if self.references is not None and info.needs != "pass":
            raise InvalidInputError(
                "--reference fixes the level of a flight-level method: use --method selfcal")
        if self.hfov_deg is not None and not self.geotiff:
            raise InvalidInputError("--hfov-deg is the field of view --geotiff maps with: give "
                                    "--geotiff, or leave --hfov-deg out")
        if self.hfov_deg is not None and not (
                math.isfinite(self.hfov_deg) and 0 < self.hfov_deg < 180):
            raise InvalidInputError("--hfov-deg must be between 0 and 180 degrees")


@dataclass
class StageTimes:
    """Seconds spent per stage and frames that went through it."""

    seconds: dict[str, float] = field(
        default_factory=lambda: dict.fromkeys(("reading", "registration", "estimate", "writing"),
                                              0.0)
    )

    def add(self, stage: str, started: float) -> float:
        now = time.perf_counter()
        self.seconds[stage] = self.seconds.get(stage, 0.0) + now - started
        return now

    def share(self, started: float, spent: dict[str, float]) -> None:
        """Add the wall time since ``started`` to the stages of ``spent`` in proportion to the
        seconds spent in each on the workers (work on several threads at once: the stages'
        seconds add up to the wall time, as when one thread does it all)."""
        wall = time.perf_counter() - started
        total = sum(spent.values())
        for stage, seconds in spent.items():
            share = wall * seconds / total if total > 0 else 0.0
            self.seconds[stage] = self.seconds.get(stage, 0.0) + share


def pivots_of(n_total: int, n: int, stride: int) -> list[int]:
    """Pivot frame indices of the groups ``[p − n//2, p − n//2 + n)`` that fit the recording."""
    if n_total < n:
        raise InvalidInputError(f"the recording has {n_total} frames, fewer than a group of {n}"
                                f": give --frames {n_total} --stride {n_total} where the method "
                                "takes so few (--method camera: one map per frame)")
    return [start + n // 2 for start in range(0, n_total - n + 1, stride)]


def pivot_workers(options: FlightOptions) -> int:
    """How many pivots a flight estimates at once, each on its own thread: ``pivot_workers``
    when given, else one per CPU core this process may use, each network call on its share of
    the cores (on two cores, two bursts at once, each on one thread: 101–112 ms per burst of
    336×256 against 126–129 ms one at a time on both, the steps around the network in parallel
    too); one when ``threads`` fixes the network's threads. The maps are the same bytes."""
    if options.pivot_workers is not None:
        return options.pivot_workers
    return 1 if options.threads is not None else available_cores()


def _estimator(options: FlightOptions, frame_shape: tuple[int, int]) -> Estimator:
    """The estimator of ``options``, checked against the recording before any work: the
    calibration's frame size, the network's burst length."""
    estimator = make_estimator(options.method, model=options.model,
                               calibration=options.calibration, family=options.family,
                               backend=options.backend, threads=options.threads,
                               concurrent=pivot_workers(options))
    refuse_unchecked(estimator, options.calibration, force=options.force)
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


def _register(estimator: Estimator, frames: np.ndarray, workers: int | None,
              pairs: np.ndarray | None = None) -> SequenceRegistration | None:
    """Frame-to-previous registration of a run of frames (only ``pairs``, when given: see
    :func:`~thermocal.registration.sequence.register_sequence`); None for a per-frame estimator.

    Consecutive frames of a recording overlap most, and the run's many frames give a good
    fixed-pattern estimate: far faster and more accurate than registering each group alone.
    """
    return (None if estimator.per_frame else
            register_sequence(frames, workers=workers, pairs=pairs))


def _group_pairs(batch: list[int], n: int) -> np.ndarray:
    """The frame pairs the groups of ``batch`` (pivots) compose through, as the mask of
    :func:`~thermocal.registration.sequence.register_sequence` over the batch's frames: each
    group's frames to the one before, not a group's first frame to the frame before the group
    (a sixth of the pairs at N = 7, stride 7; more at a longer stride)."""
    a = batch[0] - n // 2
    mask = np.zeros(batch[-1] - n // 2 + n - a, dtype=bool)
    for pivot in batch:
        first = pivot - n // 2 - a
        mask[first + 1 : first + n] = True
    return mask


def flight_batches(n_frames: int, options: FlightOptions) -> int:
    """How many batches (:data:`BATCH_FRAMES`) a flight of a recording of ``n_frames`` frames
    registers: what a campaign splits a long recording by (a flight-level estimator joins a
    short last batch to the one before: not split)."""
    return len(_batches(pivots_of(n_frames, options.frames, options.stride), options.stride))


def batch_span(stride: int) -> int:
    """How many frames of the recording one batch of pivots spans (:data:`BATCH_FRAMES`, a
    whole number of strides, at least one)."""
    return max(1, BATCH_FRAMES // stride) * stride


def _batches(pivots: list[int], stride: int) -> list[list[int]]:
    """The pivots in batches of :func:`batch_span` frames, by place in the recording."""
    per_batch = batch_span(stride) // stride
    return [pivots[b : b + per_batch] for b in range(0, len(pivots), per_batch)]


def _segment_log(out: Path, segment: tuple[int, int]) -> Path:
    return out / f"log.segment-{segment[0]:05d}.jsonl"


def process_flight(
    recording: str | Path,
    out_dir: str | Path,
    options: FlightOptions = FlightOptions(),
    *,
    progress: Callable[[int], None] | None = None,
    command: str | None = None,
    segment: tuple[int, int] | None = None,
) -> dict[str, Any]:
    """Process a recording into per-pivot temperature maps in ``out_dir``; returns the summary.

    ``progress(k)`` is called with the number of frames each finished group advanced;
    ``command`` (the command line that runs it) is kept in the summary, for the report.
    ``segment``: only batches ``first … stop − 1`` (see the module docstring); returns their
    counts, for :func:`finish_segments`.
    """
    if segment is not None and ESTIMATORS[options.method].needs == "pass":
        raise InvalidInputError(f"--method {options.method} fits across the whole recording: "
                                "it cannot run in segments")
    header = open_stream(recording, fpa_c=options.fpa_c)
    if header.series["fpa_c"] is None and not ESTIMATORS[options.method].per_frame:
        raise InvalidInputError(
            f"{header.path}: no FPA temperature (a sidecar's fpa_c; FLIR files carry none): "
            "give --fpa-c, or --method camera for the camera's own calibration"
        )
    n, stride = options.frames, options.stride
    pivots = pivots_of(header.n_frames, n, stride)
    if ESTIMATORS[options.method].needs == "recording":  # the file's own constants
        from thermocal.estimation.vendor import VendorCalibration

        estimator = VendorCalibration.from_metadata(
            header.series.get("frame_metadata") or [], header.path)
    else:
        estimator = _estimator(options, header.frame_shape)
    series = header.series | recording_paces(header.series["fpa_c"], header.series["time_s"],
                                             estimator.fpa_paces,
                                             getattr(estimator, "rate_lags_s", ()))
    geo = _pivot_tags(header.series.get("frame_metadata"), pivots, options, header.frame_shape)
    batches = _batches(pivots, stride)
    flight_level = ESTIMATORS[options.method].needs == "pass"
    if flight_level and len(batches) > 1 and len(batches[-1]) < len(batches[0]) // 2:
        # a short last batch would be too short to fit on: it joins the one before
        batches[-2:] = [batches[-2] + batches[-1]]
    prefit_started = time.perf_counter()
    pass_fit = (_PassFit.before(header, batches, estimator, options, series)
                if flight_level else None)
    prefit_s = time.perf_counter() - prefit_started
    if segment is not None and not 0 <= segment[0] < segment[1] <= len(batches):
        raise InvalidInputError(f"segment {segment}: the flight has batches 0…{len(batches)}")
    record = run_record(header.path, options, model=_default_model(options))
    check_run_record(Path(out_dir), record)
    out = _output_dirs(Path(out_dir))  # only now: every check has passed
    write_json_atomic(out / RUN_FILE, record)  # what its maps are made from, before any map
    log_path = out / "log.jsonl" if segment is None else _segment_log(out, segment)
    if segment is None:  # a segment's neighbours may be writing theirs now
        _remove_stale_temp_files(out)
    _drop_cut_log_line(log_path)
    mine = range(len(batches)) if segment is None else range(*segment)
    previews = TemperaturePreviews(dpi=80)  # one figure for the run's previews
    done = _finished_pivots(out, pivots, options, header.frame_shape, previews,
                            logs=(out / "log.jsonl", log_path),
                            only={p for bi in mine for p in batches[bi]})
    tally = _Tally()
    first = 0 if segment is None else max(0, batches[segment[0]][0] - n // 2)
    reader = _FrameWindow(header.stream(max(64, n), start=first), header.frame_shape)
    undecodable: dict[int, tuple[str, str]] = {}  # met in the groups of this run
    skipped_groups = 0
    if pass_fit is not None:
        tally.times.seconds["self-calibration"] = prefit_s
    started = time.perf_counter() - prefit_s
    workers = pivot_workers(options)
    shown: dict = {}  # the run's warnings registry: a warning the caller shows once, once
    with (open(log_path, "a", encoding="utf-8") as log, previews,
          contextlib.nullcontext() if workers == 1 else
          ThreadPoolExecutor(workers, thread_name_prefix="pivot") as pool):
        for bi, batch in enumerate(batches):
            if bi not in mine:
                continue
            b = sum(map(len, batches[:bi]))
            todo = [(b + i, p) for i, p in enumerate(batch) if p not in done]
            tally.skipped += len(batch) - len(todo)
            if progress and len(todo) < len(batch):
                progress(stride * (len(batch) - len(todo)))
            if not todo:
                continue
            # the whole batch, done pivots included: the same frames as an uninterrupted run
            run = _register_batch(reader, estimator, batch, n, tally.times,
                                  workers=options.registration_threads,
                                  known=pass_fit.registered.get(bi) if pass_fit else None,
                                  groups_only=True)
            batch_estimator = estimator
            if pass_fit is not None:
                t = time.perf_counter()
                run, batch_estimator = pass_fit.for_batch(bi, run, series)
                tally.times.add("self-calibration", t)

            def one(item: tuple[int, int], run: _Batch = run,
                    estimator_: Estimator = batch_estimator) -> _Pivot:
                index, pivot = item
                with caught_warnings() as raised:  # besides the estimate's: given back below
                    finished = _process_pivot(
                        run, pivot, series, estimator_, options, out,
                        preview=previews if _preview_due(options, index) else None,
                        bit_depth=header.bit_depth, geo=geo[pivot])
                return replace(finished, stray=tuple(raised))

            # the pivots on the workers (Executor.map: in order; the ones not started are
            # cancelled when this loop stops), their log lines here in the pivots' order
            t = time.perf_counter()
            spent = dict.fromkeys(("estimate", "writing"), 0.0)
            stray: list[warnings.WarningMessage] = []
            with routed_warnings():
                results = map(one, todo) if pool is None else pool.map(one, todo)
                for (_, pivot), result in zip(todo, results, strict=True):
                    bad = _undecodable_in(run, pivot - n // 2, n)
                    undecodable.update((i, (where, why)) for i, where, why in bad)
                    skipped_groups += bool(bad)
                    tally.count(pivot, result)
                    stray += result.stray
                    for stage, seconds in result.seconds.items():
                        spent[stage] += seconds
                    log.write(json.dumps(result.entry) + "\n")  # last: the pivot is finished
                    log.flush()
                    if progress:
                        progress(stride)
            tally.times.share(t, spent)
            for w in stray:  # under the caller's filters again, in the pivots' order
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno,
                                       registry=shown)
    if segment is not None:
        return {"segment": list(segment), "groups": sum(len(batches[bi]) for bi in mine),
                "processed": tally.processed, "skipped_already_done": tally.skipped,
                "failed": tally.failed, "first_error": tally.first_error,
                "stage_seconds": tally.times.seconds,
                "wall_time_s": time.perf_counter() - started, "skipped_groups": skipped_groups,
                "undecodable": [[i, where, why] for i, (where, why) in undecodable.items()]}
    about = _about(header, undecodable, command,
                   {"selfcal": pass_fit.summary()} if pass_fit is not None else {})
    summary = _finish(out, header.path, options, len(pivots), tally,
                      time.perf_counter() - started, about=about)
    if undecodable:
        warnings.warn(_undecodable_warning(header.path, undecodable, skipped_groups),
                      stacklevel=2)
    return summary


def _about(header: Any, undecodable: dict[int, tuple[str, str]], command: str | None,
           extra: dict[str, Any]) -> dict[str, Any]:
    """The summary's facts of the recording: its format, the frames left out at open and those
    that did not decode while streamed, the command."""
    return {"format": header.source.format if header.source is not None else "tiff",
            "damaged_frames": [{"frame": where, "reason": why} for where, why in header.damaged]
            + [{"frame": where, "recording_index": i, "reason": why}
               for i, (where, why) in sorted(undecodable.items())],
            **({"command": command} if command is not None else {}), **extra}


def finish_segments(recording: str | Path, out_dir: str | Path, options: FlightOptions,
                    results: list[dict[str, Any]], *, command: str | None = None
                    ) -> dict[str, Any]:
    """Finish a flight run in segments (``results``: what :func:`process_flight` returned for
    each, every batch of the recording once): their log lines appended to ``log.jsonl`` in the
    segments' order (a line already there is not appended twice: a rerun after an interrupted
    finish), their log files removed, ``log.csv`` and ``summary.json`` written (``processed``
    and the stage times summed over the segments, ``wall_time_s`` too); the summary."""
    if not results:
        raise InvalidInputError("finish_segments: no segment to finish")
    header = open_stream(recording, fpa_c=options.fpa_c)
    out = Path(out_dir)
    results = sorted(results, key=lambda r: r["segment"][0])
    spans = [tuple(r["segment"]) for r in results]
    n_batches = flight_batches(header.n_frames, options)
    if [a for a, _ in spans] != [0, *[z for _, z in spans[:-1]]] or spans[-1][1] != n_batches:
        raise InvalidInputError(f"segments {spans} do not cover the flight's {n_batches} "
                                "batches once each")
    _remove_stale_temp_files(out)
    main = out / "log.jsonl"
    _drop_cut_log_line(main)
    kept = main.read_bytes() if main.is_file() else b""
    seen = set(kept.splitlines(keepends=True))
    added = []
    for span in spans:
        path = _segment_log(out, span)
        _drop_cut_log_line(path)
        for line in path.read_bytes().splitlines(keepends=True) if path.is_file() else ():
            if line not in seen:
                added.append(line)
                seen.add(line)
    if added:
        with atomic_path(main) as tmp:
            Path(tmp).write_bytes(kept + b"".join(added))
    for span in spans:
        _segment_log(out, span).unlink(missing_ok=True)
    tally = _Tally(processed=sum(r["processed"] for r in results),
                   skipped=sum(r["skipped_already_done"] for r in results),
                   failed=sum(r["failed"] for r in results),
                   first_error=next((r["first_error"] for r in results if r["first_error"]),
                                    None))
    for r in results:
        for stage, seconds in r["stage_seconds"].items():
            tally.times.seconds[stage] = tally.times.seconds.get(stage, 0.0) + seconds
    undecodable = {int(i): (where, why) for r in results for i, where, why in r["undecodable"]}
    pivots = pivots_of(header.n_frames, options.frames, options.stride)
    summary = _finish(out, header.path, options, len(pivots), tally,
                      sum(r["wall_time_s"] for r in results),
                      about=_about(header, undecodable, command, {"segments": len(results)}))
    if undecodable:
        warnings.warn(_undecodable_warning(header.path, undecodable,
                                           sum(r["skipped_groups"] for r in results)),
                      stacklevel=2)
    return summary


def _undecodable_warning(path: Path, undecodable: dict[int, tuple[str, str]],
                         groups: int) -> str:
    """One line naming the frames that did not decode (by index in the recording) and how
    many groups were skipped for them."""
    k = len(undecodable)
    listed = "; ".join(undecodable_text(i, *undecodable[i]) for i in sorted(undecodable)[:10])
    more = f"; and {k - 10} more" if k > 10 else ""
    return (f"{path}: {k} frame{'s' if k > 1 else ''} did not decode while streamed, "
            f"{groups} group{'s' if groups > 1 else ''} skipped: {listed}{more}")


#: A pivot's map tags, why its maps have no GeoTIFF tags, and their footprint
#: (:func:`_pivot_tags`).
_PivotGeo = tuple[geotag.MapTags | None, str | None, geotag.Footprint | None]


def _pivot_tags(metadata: list[Any] | None, pivots: list[int], options: FlightOptions,
                shape: tuple[int, int]) -> dict[int, _PivotGeo]:
    """Each pivot's map tags (None: its frame has no GPS, time, make or model) and, with
    ``--geotiff``, why its maps have no GeoTIFF tags (None when they have) and their footprint
    (None when they have none); refused when no pivot can have them."""
    geo: dict[int, _PivotGeo] = {}
    for pivot in pivots:
        meta = metadata[pivot] if metadata is not None and pivot < len(metadata) else None
        where, why = None, None
        if options.geotiff:
            try:
                where = geotag.footprint(meta, shape=shape, hfov_deg=options.hfov_deg)
            except InvalidInputError as exc:
                why = f"frame {pivot}: {exc}"
        geo[pivot] = (geotag.map_tags(meta, footprint=where), why, where)
    reasons = [why for _, why, _ in geo.values()]
    if options.geotiff and reasons and all(reasons):
        raise InvalidInputError(f"--geotiff: no pivot can be georeferenced (the first, "
                                f"{reasons[0]}); leave out --geotiff")
    return geo


def _preview_due(options: FlightOptions, index: int) -> bool:
    """Whether the ``index``-th pivot of the recording gets a preview (every ``preview_every``-th,
    by its place in the recording, so that a resumed run makes the same ones)."""
    return bool(options.preview_every) and index % options.preview_every == 0


def _preview_title(options: FlightOptions, pivot: int) -> str:
    return f"frame {pivot}, {options.method}"


@dataclass(frozen=True)
class _Pivot:
    """A pivot done (:func:`_process_pivot`): its log entry (with ``error`` when it failed, and
    the estimate's warnings), the seconds its stages took on its worker, and the warnings it
    raised outside the estimate (given back to the caller after its batch)."""

    entry: dict[str, Any]
    seconds: dict[str, float]
    stray: tuple[warnings.WarningMessage, ...] = ()


@dataclass
class _Tally:
    """What a run did so far: pivots processed, skipped (done before), failed; stage times."""

    processed: int = 0
    skipped: int = 0
    failed: int = 0
    first_error: str | None = None
    times: StageTimes = field(default_factory=StageTimes)

    def count(self, pivot: int, done: _Pivot) -> None:
        """Count a pivot done (in the pivots' order: the first error is the first pivot's)."""
        error = done.entry.get("error")
        if error is None:
            self.processed += 1
            return
        self.failed += 1
        if self.first_error is None:
            self.first_error = f"pivot {pivot}: {error}"


@dataclass(frozen=True)
class _Batch:
    """A run of frames ``[start, start + len(frames))`` read and registered together (or the
    registration's error, which every group of it then reports), with its frames that do not
    decode (zeros in ``frames``): ``(index in the recording, where, reason)``."""

    start: int
    frames: np.ndarray
    sequence: SequenceRegistration | None
    error: str | None
    undecodable: tuple[tuple[int, str, str], ...] = ()


class _PassFit:
    """A flight-level estimator (``selfcal``) fitted batch by batch: one residual pattern per
    batch of frames (long flights in segments), the level fixed by ground references.

    :meth:`before` runs before anything is written: it fits the first batch (a pass of one
    batch too short or too still is refused there, exit 2) and the batches that hold a reference
    frame, and fixes the level from the references; :meth:`for_batch` gives each batch its fitted
    estimator (a batch whose fit fails fails its groups with the reason). A batch's fit
    depends only on its frames, so a resumed run fits it the same way.
    """

    def __init__(self, estimator: Any, fits: dict[int, Any], level: Any,
                 registered: dict[int, _Batch]) -> None:
        self.estimator = estimator  # with the references' level
        self.fits = fits  # batch index → fitted estimator (made before the loop)
        self.level = level
        # batch index → its registration made before the loop (frames dropped: the loop
        # reads them again, registering them once)
        self.registered = registered
        self.segments: list[dict[str, Any]] = []

    @classmethod
    def before(cls, header: Any, batches: list[list[int]], estimator: Any,
               options: FlightOptions, series: dict[str, Any]) -> _PassFit:
        from thermocal.pipeline.references import level_from_references, read_references

        n = options.frames
        refs = (read_references(options.references, n_frames=header.n_frames,
                                frame_shape=header.frame_shape) if options.references else ())
        spans = [(batch[0] - n // 2, batch[-1] - n // 2 + n) for batch in batches]
        where = {}
        for ref in refs:
            inside = [i for i, (a, z) in enumerate(spans) if a <= ref.frame < z]
            if not inside:
                raise InvalidInputError(
                    f"{options.references} line {ref.row}: frame {ref.frame} is in no group of "
                    f"--frames {n} --stride {options.stride}; pick a frame between {spans[0][0]} "
                    f"and {spans[-1][1] - 1}")
            where[ref.frame] = inside[0]
        reader = _FrameWindow(header.stream(max(64, n)), header.frame_shape)
        fits, maps, registered = {}, {}, {}
        for bi in sorted({0, *where.values()}):
            run = _register_batch(reader, estimator, batches[bi], n, StageTimes(),
                                  workers=options.registration_threads)
            registered[bi] = replace(run, frames=run.frames[:0])
            try:
                fitted = _fit_batch(estimator, run, series)
            except (InvalidInputError, RegistrationError) as exc:
                if bi in where.values():
                    raise InvalidInputError(
                        f"{options.references}: the references' frames {run.start}-"
                        f"{run.start + len(run.frames) - 1} cannot be self-calibrated: {exc}"
                    ) from None
                if len(batches) == 1 and isinstance(exc, InvalidInputError):
                    raise  # the whole pass is too short or too still: nothing to write
                continue  # a later batch may move: this one's groups fail with the reason
            for ref in refs:
                if where[ref.frame] == bi:
                    k = ref.frame - run.start
                    if any(i == ref.frame for i, _, _ in run.undecodable):
                        raise InvalidInputError(
                            f"{options.references} line {ref.row}: frame {ref.frame} does not "
                            "decode")
                    times = series["time_s"]
                    maps[ref.frame] = fitted.calibrate(
                        run.frames[k : k + 1], series["fpa_c"][ref.frame : ref.frame + 1],
                        None if times is None else times[ref.frame : ref.frame + 1])[0]
            fits[bi] = fitted
        level = None
        if refs:
            # the line pattern the pass could not show lies under the discs too
            unseen = max(fits[where[r.frame]].unseen_sigma(maps[r.frame],
                                                            float(series["fpa_c"][r.frame]))
                         for r in refs)
            level = level_from_references(refs, maps, estimator.band, pattern_sigma_c=unseen)
            estimator = estimator.with_level(level.offset, level.sigma_c)
            fits = {bi: f.with_level(level.offset, level.sigma_c) for bi, f in fits.items()}
            if level.disagreeing:
                warnings.warn(
                    f"{options.references}: the references of line(s) "
                    f"{', '.join(map(str, level.disagreeing))} disagree with the others beyond "
                    f"their σ: {'left out' if len(level.disagreeing) < len(refs) else 'all used'}"
                    f" (the level's σ {level.sigma_c:.2f} °C)",
                    stacklevel=3)
        return cls(estimator, fits, level, registered)

    def for_batch(self, bi: int, run: _Batch, series: dict[str, Any]) -> tuple[_Batch, Any]:
        """The batch's run (with its fit's error, when it fails) and its fitted estimator."""
        fitted = self.fits.get(bi)
        if fitted is None and run.error is None:
            try:
                fitted = _fit_batch(self.estimator, run, series)
            except (InvalidInputError, RegistrationError) as exc:
                return replace(run, error=f"selfcal: {exc}"), self.estimator
        if fitted is None:
            return run, self.estimator
        p = fitted.pattern
        self.segments.append({
            "frames": [run.start, run.start + len(run.frames) - 1], "rounds": p.rounds,
            "residual_sd_radiance": p.residual_sd, "motion_px": list(p.motion_px),
            "pattern_fpa_dependent": p.fitted_fpa, "bad_pixels": int(p.bad.sum()),
            "not_identified": p.unidentified()})
        return run, fitted

    def summary(self) -> dict[str, Any]:
        """What ``summary.json`` says of the fit: the start model, each batch fitted in this
        run, the references' level."""
        e = self.estimator
        start = (f"the {e.family} family's average unit (training units of the network)"
                 if e.calibration is None else "the calibration given (--calibration)")
        return {"start": start, "segments": self.segments,
                "references": None if self.level is None else self.level.as_dict()}


def _fit_batch(estimator: Any, run: _Batch, series: dict[str, Any]) -> Any:
    """``estimator`` fitted on a batch's frames: each registered onto the batch's middle frame
    (frames whose chain there failed, or that do not decode, left out), stuck pixels left
    out."""
    from thermocal.burst import stuck_pixels
    from thermocal.estimation.pass_pattern import MIN_FRAMES, MIN_MOTION_FRACTION

    if run.sequence is None:
        raise RegistrationError(run.error or "the batch was not registered")
    m = len(run.frames)
    if m < MIN_FRAMES:  # the frames the groups use, not the recording's (which may hold more)
        raise InvalidInputError(
            f"selfcal needs at least {MIN_FRAMES} frames of a pass; the groups at this --frames "
            f"and --stride use {m} (frames {run.start}-{run.start + m - 1}): give a smaller "
            "--stride or a longer recording")
    mid = m // 2
    homographies, use = run.sequence.chained_to(mid)
    for i, _, _ in run.undecodable:
        use[i - run.start] = False
    if MIN_FRAMES <= m and use.sum() < MIN_FRAMES:
        h, w = run.frames.shape[1:]
        raise InvalidInputError(
            f"only {int(use.sum())} of frames {run.start}-{run.start + m - 1} register onto frame "
            f"{run.start + mid} (a hover, or frames that do not overlap); selfcal needs at least "
            f"{MIN_FRAMES} of a pass that moves steadily across the scene, by at least "
            f"{MIN_MOTION_FRACTION:g} of the frame over them ({MIN_MOTION_FRACTION * w:.0f} px "
            f"along the rows or {MIN_MOTION_FRACTION * h:.0f} px along the columns)")
    # long batches are fitted on every k-th frame: ample views of each ground point, and
    # bounded memory and time
    use &= np.arange(m) % max(1, -(-int(use.sum()) // MAX_FIT_FRAMES)) == 0
    # a stuck pixel is stuck in every frame: every 8th frame shows it
    sample = np.flatnonzero(use)[::8]
    good = ~stuck_pixels(run.frames[sample], homographies[sample])
    part = slice(run.start, run.start + m)
    times, rates = series["time_s"], series.get("fpa_rate_c_per_min")
    return estimator.fitted(run.frames, homographies, np.asarray(series["fpa_c"][part]),
                            use=use, good=good,
                            time_s=None if times is None else np.asarray(times[part]),
                            fpa_rate_c_per_min=None if rates is None or times is None
                            else np.asarray(rates[part]))


def _undecodable_in(run: _Batch, first: int, n: int) -> tuple[tuple[int, str, str], ...]:
    """The frames of the group ``[first, first + n)`` of ``run`` that do not decode."""
    return tuple(e for e in run.undecodable if first <= e[0] < first + n)


def _stand_ins(frames: np.ndarray, bad: list[int]) -> np.ndarray:
    """``frames`` where each frame at ``bad`` (indices into it) is the nearest other frame
    before it (after it, at the start), as a new array: what registration sees of a frame that
    does not decode (its groups fail; the others keep their chain and fixed pattern)."""
    good = sorted(set(range(len(frames))) - set(bad))
    if not bad or not good:
        return frames
    out = frames.copy()
    for k in bad:
        before = [g for g in good if g < k]
        out[k] = frames[before[-1] if before else good[0]]
    return out


def _register_batch(reader: _FrameWindow, estimator: Estimator, batch: list[int], n: int,
                    times: StageTimes, *, workers: int | None = None,
                    known: _Batch | None = None, groups_only: bool = False) -> _Batch:
    """Read the frames of the groups of ``batch`` (pivots) and register them as one sequence
    on ``workers`` threads (None: the registration's default; ``groups_only``: only the pairs
    the groups compose through, :func:`_group_pairs`), or take the registration of ``known``,
    the same batch read before."""
    t = time.perf_counter()
    a, z = batch[0] - n // 2, batch[-1] - n // 2 + n
    frames, undecodable = reader.frames(a, z)
    t = times.add("reading", t)
    if known is not None:
        return _Batch(a, frames, known.sequence, known.error, undecodable)
    try:
        sequence = _register(estimator, _stand_ins(frames, [i - a for i, _, _ in undecodable]),
                             workers, _group_pairs(batch, n) if groups_only else None)
        error = None
    except (RegistrationError, InvalidInputError) as exc:
        sequence, error = None, str(exc)
    times.add("registration", t)
    return _Batch(a, frames, sequence, error, undecodable)


def _process_pivot(run: _Batch, pivot: int, series: dict[str, Any], estimator: Estimator,
                   options: FlightOptions, out: Path, *,
                   preview: TemperaturePreviews | None, bit_depth: int,
                   geo: _PivotGeo = (None, None, None)) -> _Pivot:
    """Estimate one pivot's map from its group of ``run``, write it (and its preview, drawn by
    ``preview`` when given) with its tags and reason for no GeoTIFF ``geo``
    (:func:`_pivot_tags`) and return its log entry and stage times; a group that cannot be
    estimated is logged with its error. Runs on a worker thread, inside
    :func:`~thermocal.threads.routed_warnings`.

    The group's frames are validated first (frames that do not decode, saturated or dead
    frames, the FPA temperature), so that a bad group says what is wrong with it rather than
    that its registration failed.
    """
    n = options.frames
    first = pivot - n // 2
    fpa, time_s = series["fpa_c"], series["time_s"]
    entry = {"frame": pivot, "time_s": None if time_s is None else float(time_s[pivot]),
             "fpa_c": None if fpa is None else float(fpa[pivot]), "warnings": []}
    t = time.perf_counter()
    group = run.frames[first - run.start : first - run.start + n]
    try:
        _check_decoded(_undecodable_in(run, first, n), first, n)
        _check_group(group, first, bit_depth)
        if estimator.needs_fpa:
            fpa_value(None if fpa is None else fpa[first : first + n], n)
        if run.error is not None:
            raise RegistrationError(run.error)
        homographies, fallback = None, None
        if run.sequence is not None:
            local = first - run.start
            try:
                homographies = run.sequence.to_pivot(range(local, local + n),
                                                     pivot - run.start)
                if n > 1:  # a group of one frame has no pair to correlate
                    entry["registration_correlation"] = float(
                        run.sequence.correlation[local + 1 : local + n].min())
            except RegistrationError as exc:
                # the chain broke where the recording's fixed-pattern estimate kept the scene
                # (a hovering camera: the scene hardly moves through the window): the group is
                # registered on its own, its fixed pattern fitted with it, as `estimate` does
                fallback = f"registered as a burst ({exc})"
        # an estimator of the recording's own constants takes those of the group's frames
        group_estimator = (estimator.for_frames(first, n) if hasattr(estimator, "for_frames")
                           else estimator)
        with caught_warnings() as caught:
            result = estimate(
                group, group_estimator,
                fpa_c=None if fpa is None else fpa[first : first + n],
                time_s=None if time_s is None else time_s[first : first + n],
                pivot=n // 2, homographies=homographies, force=options.force,
                bit_depth=bit_depth, fpa_sigma_c=options.fpa_sigma_c or 0.0,
                **pace_at(series, time_s, pivot))
            temp, sigma = result.temperature_c, result.sigma_c
        entry["warnings"] = sorted({str(w.message) for w in caught})
        if fallback is not None:
            entry["warnings"].append(fallback)
        if result.outside:  # estimated all the same (--force): why it is not validated
            entry["warnings"].append(
                f"outside the domain (--force): {'; '.join(result.outside)}")
    except (RegistrationError, InvalidInputError) as exc:
        entry["error"] = str(exc)
        return _Pivot(entry, {"estimate": time.perf_counter() - t})
    estimated = time.perf_counter()
    _write_pivot(out, pivot, temp, sigma, _preview_title(options, pivot), method=options.method,
                 tags=geo[0], previews=preview)
    if geo[1] is not None:
        entry["warnings"].append(f"no GeoTIFF tags: {geo[1]}")
    if geo[2] is not None:  # what the GeoTIFF tags were computed with
        entry["ground"] = {"gsd_m": geo[2].gsd_m, "hfov_deg": geo[2].hfov_deg}
    entry["mean_c"] = float(temp.mean())
    if sigma is not None:
        entry["sigma_mean_c"] = float(sigma.mean())
        entry["sigma_median_c"] = float(np.median(sigma))
        entry["sigma_p95_c"] = float(np.percentile(sigma, 95))
    return _Pivot(entry, {"estimate": estimated - t, "writing": time.perf_counter() - estimated})


def _check_decoded(undecodable: tuple[tuple[int, str, str], ...], first: int, n: int) -> None:
    """Refuse a group holding frames that do not decode (zeros in their place), naming them:
    ``frame 123 does not decode (…); group of frames 119-125 skipped``."""
    if undecodable:
        named = "; ".join(undecodable_text(*e) for e in undecodable)
        raise InvalidInputError(f"{named}; group of frames {first}-{first + n - 1} skipped")


def _check_group(group: np.ndarray, first: int, bit_depth: int = 14) -> None:
    """The estimation pipeline's check of a group's frames (saturated, dead, constant), its
    message naming the frame by its place in the recording."""
    try:
        check_burst(group, bit_depth=bit_depth)
    except InvalidInputError as exc:
        last = first + len(group) - 1
        message = re.sub(r"^frames: frame (\d+)\b",
                         lambda m: f"frame {first + int(m[1])} (group of frames {first}-{last})",
                         str(exc))
        if message == str(exc):
            message = f"group of frames {first}-{last}: {exc}"
        raise InvalidInputError(message) from None


def _write_pivot(out: Path, pivot: int, temp: np.ndarray, sigma: np.ndarray | None,
                 preview_title: str, *, method: str, tags: geotag.MapTags | None = None,
                 previews: TemperaturePreviews | None = None) -> None:
    """A pivot's preview (by ``previews``, when given), its σ map when it has one, then its
    temperature TIFF (both maps with the georeferencing ``tags`` when given, and the ``method``
    and each other's names in their descriptions); each written atomically, so that
    the finished ones stand when the disk fills. The map comes last (before the log line that
    its caller writes): a pivot interrupted before its log line is redone whole."""
    name = f"frame_{pivot:06d}"
    try:
        if previews is not None:
            previews.save(out / "previews" / f"{name}.png", temp, title=preview_title)
        about = {"method": method, "frame": pivot}
        if sigma is not None:
            write_sigma_tiff(out / "temps" / f"{name}_sigma.tiff", sigma, tags=tags,
                             about=about | {"temperature": f"{name}.tiff"})
        write_temperature_tiff(out / "temps" / f"{name}.tiff", temp, tags=tags, about=about | {
            "sigma": "none" if sigma is None else f"{name}_sigma.tiff"})
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise OutputError(
            f"{where}{exc.strerror or exc}; the maps finished so far are kept, rerun to resume"
        ) from None


def _finish(out: Path, recording: Path, options: FlightOptions, groups: int, tally: _Tally,
            elapsed: float, *, about: dict[str, Any]) -> dict[str, Any]:
    """Write ``log.csv`` (the latest try of each pivot) and ``summary.json`` (with ``about``
    the recording: its format, damaged frames left out or not decoded, the command); the
    summary."""
    _write_csv(out / "log.csv", read_log(out / "log.jsonl"))
    frames_done = tally.processed * options.frames
    summary = {
        "recording": str(recording),
        **about,
        "options": asdict(options),
        "groups": groups,
        "processed": tally.processed,
        "skipped_already_done": tally.skipped,
        "failed": tally.failed,
        **({"first_error": tally.first_error} if tally.first_error is not None else {}),
        "sigma_c": _sigma_summary(read_log(out / "log.jsonl"), options.method),
        "wall_time_s": elapsed,
        "frames_per_second": {
            stage: (frames_done / s if s > 0 else None) for stage, s in tally.times.seconds.items()
        },
        "stage_seconds": tally.times.seconds,
    }
    write_json_atomic(out / "summary.json", summary)
    return summary


def _sigma_summary(entries: list[dict[str, Any]], method: str) -> dict[str, Any] | None:
    """The maps' uncertainty: the median over the pivots of each map's median σ, and the
    largest 95th percentile (°C), and where ``method``'s σ is known not to hold, the
    ``caveat`` (:attr:`~thermocal.nn.variants.Variant.sigma_caveat`); None when the
    estimator gives no σ."""
    from thermocal.nn.variants import VARIANTS

    done = [e for e in entries if isinstance(e.get("sigma_median_c"), int | float)]
    if not done:
        return None
    caveat = VARIANTS[method].sigma_caveat if method in VARIANTS else ""
    return {"median_of_medians": float(np.median([e["sigma_median_c"] for e in done])),
            "max_p95": float(max(e["sigma_p95_c"] for e in done)), "maps": len(done),
            **({"caveat": caveat} if caveat else {})}


class _FrameWindow:
    """Frames ``[a, z)`` of a recording, read in order, keeping only what is still needed, and
    beside them those of its frames that do not decode
    (:meth:`~thermocal.io.open.StreamHeader.stream`)."""

    def __init__(self, chunks: Iterator[tuple[int, np.ndarray, tuple[tuple[int, str, str], ...]]],
                 shape: tuple[int, int]) -> None:
        self._chunks = chunks
        self._start = 0  # index of self._buffer[0]
        self._buffer = np.empty((0, *shape), np.uint16)
        self._undecodable: tuple[tuple[int, str, str], ...] = ()  # those in the buffer

    def _drop_before(self, a: int) -> None:
        drop = min(max(0, a - self._start), len(self._buffer))
        self._buffer = self._buffer[drop:]
        self._start += drop
        self._undecodable = tuple(e for e in self._undecodable if e[0] >= self._start)

    def frames(self, a: int, z: int) -> tuple[np.ndarray, tuple[tuple[int, str, str], ...]]:
        """Frames ``a … z − 1`` (``a`` never decreases between calls), and those of them that
        do not decode (zeros): ``(index in the recording, where, reason)``."""
        self._drop_before(a)
        parts, end = [self._buffer], self._start + len(self._buffer)
        while end < z:  # the chunks joined once (joined one by one, each copied the rest again)
            start, chunk, undecodable = next(self._chunks)
            if end == self._start:  # nothing kept: the buffer starts at this chunk
                parts, self._start = [], start
            parts.append(chunk)
            end = start + len(chunk)
            self._undecodable += undecodable
        if len(parts) > 1:
            self._buffer = np.concatenate(parts)
        elif parts[0] is not self._buffer:
            self._buffer = parts[0]
        self._drop_before(a)
        return (self._buffer[a - self._start : z - self._start],
                tuple(e for e in self._undecodable if a <= e[0] < z))


def _default_model(options: FlightOptions) -> Path | None:
    """The shipped weights a network method runs without ``--model`` (None otherwise)."""
    if options.model is not None or ESTIMATORS[options.method].needs != "model":
        return None
    from thermocal.nn.infer import shipped_model_path

    return shipped_model_path(options.method)


def _output_dirs(out: Path) -> Path:
    """Create ``out``, ``out/temps`` and ``out/previews`` (none of them when one of the paths is
    taken by a file)."""
    for path in (out, out / "temps", out / "previews"):
        check_output_dir(path)
    log = out / "log.jsonl"
    if log.exists() and not log.is_file():
        raise InvalidInputError(f"{log}: is not a file; give another output directory")
    for path in (out, out / "temps", out / "previews"):
        ensure_output_dir(path)
    return out


#: The temporary files of :func:`~thermocal.io.atomic.atomic_path` for what a flight writes, by
#: output folder.
_TEMP_FILES = {
    ".": (temp_name_pattern("log", ".csv"), temp_name_pattern("summary", ".json"),
          temp_name_pattern("log", ".jsonl"), temp_name_pattern("run", ".json")),
    "temps": (temp_name_pattern(r"frame_\d{6,}(?:_sigma)?", ".tiff"),),
    "previews": (temp_name_pattern(r"frame_\d{6,}", ".png"),),
}


def _remove_stale_temp_files(out: Path) -> None:
    """Remove the temporary files a killed run left behind (only names a flight writes)."""
    for sub, patterns in _TEMP_FILES.items():
        with contextlib.suppress(OSError):
            for path in (out / sub).iterdir():
                if (any(p.fullmatch(path.name) for p in patterns) and path.is_file()
                        and not path.is_symlink()):
                    with contextlib.suppress(OSError):
                        path.unlink()


def _drop_cut_log_line(log_path: Path) -> None:
    """Cut a last log line that an interruption left without its newline (its pivot is redone),
    so that the next line is appended on a line of its own."""
    try:
        data = log_path.read_bytes()
    except FileNotFoundError:
        return
    if data and not data.endswith(b"\n"):
        os.truncate(log_path, data.rfind(b"\n") + 1)


def _finished_pivots(out: Path, pivots: list[int], options: FlightOptions,
                     shape: tuple[int, int], previews: TemperaturePreviews, *,
                     logs: tuple[Path, ...], only: set[int]) -> set[int]:
    """Pivots of ``only`` an earlier run finished: the latest line of the pivot in ``logs`` (in
    that order) says it succeeded and its map checks out (:func:`_map_ok`). A missing preview of
    such a pivot is made from its map (by ``previews``)."""
    logged = {e["frame"]: e for log in dict.fromkeys(logs) for e in read_log(log)}
    done = set()
    for index, pivot in enumerate(pivots):
        if pivot not in only:
            continue
        entry = logged.get(pivot)
        if entry is None or "error" in entry:
            continue
        name = f"frame_{pivot:06d}"
        temp = _map_ok(out / "temps" / f"{name}.tiff", shape, entry.get("mean_c"))
        if temp is None:
            continue
        if "sigma_mean_c" in entry and _map_ok(out / "temps" / f"{name}_sigma.tiff", shape,
                                               entry["sigma_mean_c"]) is None:
            continue
        png = out / "previews" / f"{name}.png"
        if _preview_due(options, index) and not png.is_file():
            _write_pivot_preview(previews, png, temp, _preview_title(options, pivot))
        done.add(pivot)
    return done


def _write_pivot_preview(previews: TemperaturePreviews, png: Path, temp: np.ndarray,
                         title: str) -> None:
    try:
        previews.save(png, temp, title=title)
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise OutputError(f"{where}{exc.strerror or exc}; rerun to resume") from None


def _map_ok(path: Path, shape: tuple[int, int], mean_c: Any) -> np.ndarray | None:
    """The map at ``path`` if it is what a finished pivot wrote: a readable float32 TIFF of
    ``shape``, finite, whose mean is the logged ``mean_c``; None otherwise (it is redone)."""
    import tifffile

    if not isinstance(mean_c, int | float) or isinstance(mean_c, bool):
        return None
    try:
        with quiet_tifffile():  # a damaged map is redone, without tifffile's log lines
            with tifffile.TiffFile(path) as tif:
                if len(tif.series) != 1 or tif.series[0].dtype != np.float32:
                    return None
            temp = read_temperature_tiff(path)  # corrupt, truncated, NaN: FileFormatError
    except Exception:  # missing, unreadable: tifffile raises many types on corrupt input
        return None
    if temp.shape != tuple(shape):
        return None
    mean = float(temp.mean())
    if not math.isfinite(mean_c) or abs(mean - mean_c) > 1e-4 * max(1.0, abs(mean_c)):
        return None
    return temp


def _write_csv(path: Path, entries: list[dict[str, Any]]) -> None:
    columns = ("frame", "time_s", "fpa_c", "mean_c", "registration_correlation", "warnings",
               "error")
    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(columns)
        for e in entries:
            found = e.get("warnings")
            warned = "; ".join(map(str, found)) if isinstance(found, list) else ""
            writer.writerow([e.get("frame"), e.get("time_s"), e.get("fpa_c"), e.get("mean_c"),
                             e.get("registration_correlation"), warned, e.get("error", "")])


__all__ = ["FlightOptions", "batch_span", "finish_segments", "flight_batches", "pivots_of",
           "process_flight"]
