"""``thermocal campaign``: many recordings processed as ``thermocal flight`` runs, as tasks on a
Dask cluster.

Each recording is one task: :func:`~thermocal.pipeline.flight.process_flight` into
``OUT/<name>/`` (``name``: the one an earlier run into OUT gave the recording, else its file
or folder name, numbered where several share one in the order of their paths, whatever the
order given; ``OUT/campaign.json`` keeps the recordings a rerun left out under ``earlier``),
so that every recording's folder is what ``thermocal flight RECORDING --out OUT/<name>`` writes,
the same bytes (tested). The tasks run on a :class:`distributed.LocalCluster` of this machine's
cores by default, or on the scheduler at ``--scheduler ADDRESS`` — one started by
``dask-jobqueue`` on a batch cluster or ``dask-kubernetes`` on Kubernetes: the workers there
need thermocal installed and the recordings and ``OUT`` at the same paths (a shared file
system).

- **Long recordings in segments**: a recording of more than :data:`SEGMENT_BATCHES` of the
  flight's batches (:data:`~thermocal.pipeline.flight.BATCH_FRAMES` frames each) is split into
  segments of that many batches, each a task (``process_flight(..., segment=...)``), and
  finished by one more (:func:`~thermocal.pipeline.flight.finish_segments`: the log in order,
  the summary) once all its segments are done: the same bytes as one flight (tested). A
  flight-level method (``selfcal``) fits across the recording: one task.
- **Resumable**: a rerun resumes each flight where it stopped (a flight's own resume: its
  finished maps are verified and kept; a segment's, those of its segment).
- **A failed task is reported, not fatal**: a recording whose flight fails (a bad recording
  found while streaming, every group failed, a worker that died twice) is named in
  ``OUT/campaign.json`` with its error; the others go on. The command exits 2 when any failed.
- **Threads**: with ``W`` workers of a LocalCluster on ``C`` cores, each worker's thread pools
  (OpenCV's, the registration's, the pivots estimated at once, each network call on one
  thread) get ``max(1, C // W)`` threads (``--threads``: the network's, one pivot at a time).

Everything is checked before a task starts: every input a recording (its header read), the
options a flight would refuse, the scheduler reachable.
"""

from __future__ import annotations

import json
import os
import threading
import time
import uuid
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from thermocal.calibration.base import ThermocalWarning
from thermocal.errors import InvalidInputError, ThermocalError
from thermocal.pipeline.flight import FlightOptions
from thermocal.pipeline.run_record import check_not_a_recording_folder
from thermocal.threads import caught_warnings, routed_warnings

__all__ = ["CampaignTask", "campaign_tasks", "run_campaign"]

#: Seconds to wait for a scheduler given by address.
CONNECT_TIMEOUT_S = 10
#: The workers' progress events' topic (:func:`_progress_events`), before each run's own id.
PROGRESS_TOPIC = "thermocal-progress"
#: Times a task is retried after its worker died (then reported as failed).
RETRIES = 1
#: Batches of a flight (:data:`~thermocal.pipeline.flight.BATCH_FRAMES` frames each) per task
#: of a long recording. Fixed, not set by the number of workers: the outputs never depend on
#: the cluster.
SEGMENT_BATCHES = 2


@dataclass(frozen=True)
class CampaignTask:
    """One recording's flight: where it is read, where it is written, how."""

    name: str
    recording: str
    out_dir: str
    frames: int
    options: FlightOptions
    #: Threads the worker's OpenCV pool may use (None: as it is).
    threads: int | None = None
    #: The flight's batches ``(first, stop)`` this task does (None: the whole recording).
    segment: tuple[int, int] | None = None
    #: The topic its groups' progress events go to, one per campaign run (None: none sent).
    events: str | None = None


def campaign_tasks(inputs: list[str | os.PathLike[str]], out: str | os.PathLike[str],
                   options: FlightOptions) -> list[CampaignTask]:
    """The campaign's tasks, after checking every input is a recording (its header read) and
    every output folder lies outside the recordings.

    Raises
    ------
    InvalidInputError, FileFormatError
        An input that is not a recording (named), the same recording twice, ``out`` inside one.
    """
    from thermocal._validate import check_not_input
    from thermocal.io.open import check_outside_recording

    if not inputs:
        raise InvalidInputError("give at least one recording")
    names = _output_names([Path(raw) for raw in inputs], _earlier_names(Path(out)))
    tasks, seen, lengths = [], set(), []
    for raw in inputs:
        path = Path(raw)
        try:
            key, n = _recording_file_and_length(path)
        except ThermocalError as exc:
            text = str(exc)
            raise type(exc)(text if text.startswith(str(path)) else f"{path}: {text}") from None
        if key in seen:
            raise InvalidInputError(f"{path}: given twice")
        seen.add(key)
        name = names[path.resolve()]
        target = Path(out) / name
        check_not_input(target, path)
        check_outside_recording(path, (out, "--out"))
        tasks.extend(_segments(CampaignTask(name, str(path), str(target), n, options)))
        lengths.append(n)
    longest = max(lengths)
    if options.frames > longest:  # no recording could make one map: an option, not a file
        raise InvalidInputError(
            f"--frames {options.frames}: a group longer than every recording (the longest has "
            f"{longest} frames)")
    return tasks


def _output_names(paths: list[Path], earlier: dict[Path, str] | None = None
                  ) -> dict[Path, str]:
    """Each recording's output folder name, by its resolved path: the name an earlier run of
    the campaign gave it (``earlier``, :func:`_earlier_names`), else its file's stem (a
    folder's name), recordings of one stem numbered ``stem``, ``stem-2``, … in the order of
    their resolved paths past every name taken, so that a rerun with the inputs in another
    order, or with some left out or added, finds its own folders."""
    earlier = earlier or {}
    names = {path.resolve(): earlier[path.resolve()] for path in paths
             if path.resolve() in earlier}
    by_stem: dict[str, list[Path]] = {}
    for path in paths:
        if path.resolve() not in names:
            stem = path.stem if path.is_file() else path.name
            by_stem.setdefault(stem, []).append(path.resolve())
    groups = {stem: sorted(set(group), key=str) for stem, group in by_stem.items()}
    taken = set(earlier.values())
    for stem, group in groups.items():  # every stem its own first, unless an earlier run's
        if stem not in taken:
            names[group[0]] = stem
            taken.add(stem)
        else:
            groups[stem] = [None, *group]  # numbered from its first
    used = taken | set(groups)
    for stem in sorted(groups):  # the others numbered past every name taken (a stem "a-2" too)
        k = 2
        for real in groups[stem][1:]:
            while f"{stem}-{k}" in used:
                k += 1
            names[real] = f"{stem}-{k}"
            used.add(names[real])
    return names


def _recording_file_and_length(path: Path) -> tuple[Path, int]:
    """The file a recording is read from, resolved (a folder holding one recording of the
    project's format is its ``NAME.tiff``, so that the folder and the file are one recording;
    anything else its own resolved path), and its frame count: its headers read once."""
    from thermocal.io.open import open_recording, recording_length

    if path.is_dir():
        source = open_recording(path)
        file = Path(source.path)
        return (file.resolve() if file.is_file() else path.resolve()), source.n_frames
    return path.resolve(), recording_length(path)


def _earlier_runs(out: Path) -> list[dict[str, Any]]:
    """The recordings an earlier run of the campaign into ``out`` listed in its
    ``campaign.json`` (its own and those it kept from runs before), each with its ``name``
    and ``recording``; ``[]`` without a readable one."""
    try:
        summary = json.loads((out / "campaign.json").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return []
    if not isinstance(summary, dict):
        return []
    runs = [*(summary.get("recordings") or []), *(summary.get("earlier") or [])]
    return [r for r in runs if isinstance(r, dict) and isinstance(r.get("name"), str)
            and isinstance(r.get("recording"), str)]


def _earlier_names(out: Path) -> dict[Path, str]:
    """Each recording's output folder name in an earlier run into ``out`` (:func:`_earlier_runs`),
    by its resolved path, for the folders that are still there."""
    names: dict[Path, str] = {}
    for r in _earlier_runs(out):
        name = r["name"]
        if Path(name).name == name and name not in (".", "..") and (out / name).is_dir():
            names.setdefault(Path(r["recording"]).resolve(), name)
    return names


def _segments(task: CampaignTask) -> list[CampaignTask]:
    """``task`` split into segments of :data:`SEGMENT_BATCHES` batches (itself when its
    recording has no more, or its method fits across the recording); each segment's
    ``frames`` are its share of the recording's, for the progress bar."""
    from thermocal.estimation.registry import ESTIMATORS
    from thermocal.pipeline.flight import batch_span, flight_batches

    if task.frames < task.options.frames or ESTIMATORS[task.options.method].needs == "pass":
        return [task]  # too short for a group (its task says so), or fitted across the whole
    batches = flight_batches(task.frames, task.options)
    if batches <= SEGMENT_BATCHES:
        return [task]
    spans = [(a, min(a + SEGMENT_BATCHES, batches)) for a in range(0, batches, SEGMENT_BATCHES)]
    span_frames = batch_span(task.options.stride)
    frames = [min(task.frames, z * span_frames) - a * span_frames for a, z in spans]
    frames[-1] = task.frames - sum(frames[:-1])  # the progress bar's total: every frame
    return [replace(task, segment=span, frames=f) for span, f in zip(spans, frames, strict=True)]


def _progress_events(task: CampaignTask) -> Callable[[int], None]:
    """``progress(k)`` for a task's flight on a worker: each group's frames sent to the client
    as an event of :data:`PROGRESS_TOPIC` (the campaign's bar moves as groups finish, not as
    whole recordings do); nothing outside a worker."""
    if task.events is None:
        return lambda k: None
    from distributed import get_worker

    try:
        worker = get_worker()
    except ValueError:  # not on a worker (a task run in this process)
        return lambda k: None
    key, topic = _task_key(task), task.events
    return lambda k: worker.log_event(topic, {"key": key, "frames": int(k)})


def _run_task(task: CampaignTask) -> dict[str, Any]:
    """One flight, or one segment of it, on a worker: its summary's counts (a segment's counts,
    for the recording's finishing task), or its error (a failed flight is a result, not an
    exception: the campaign goes on)."""
    from thermocal.pipeline.flight import process_flight

    progress = _progress_events(task)

    if task.threads is not None:
        import cv2

        # OpenCV has one process-wide pool, which defaults to every core: the workers of one
        # machine would fight over them
        cv2.setNumThreads(task.threads)
    if task.segment is not None:
        started = time.perf_counter()
        try:
            # kept for the finishing task, which warns them once for the recording
            with routed_warnings(), caught_warnings() as caught:
                segment = process_flight(task.recording, task.out_dir, task.options,
                                         segment=task.segment, progress=progress)
        except ThermocalError as exc:
            return _failed(task, str(exc), started)
        return {"name": task.name, "ok": True,
                "segment": segment | {"warnings": sorted({str(w.message) for w in caught})}}
    return _reported(task, lambda: process_flight(task.recording, task.out_dir, task.options,
                                                  progress=progress))


def _finish_task(task: CampaignTask, segments: list[dict[str, Any]]) -> dict[str, Any]:
    """The last task of a recording run in segments, on a worker: the segments' warnings, once
    each, its log and summary
    (:func:`~thermocal.pipeline.flight.finish_segments`) and report; the recording's result,
    its counts summed over the segments."""
    from thermocal.pipeline.flight import finish_segments

    def finish() -> dict[str, Any]:
        for text in sorted({t for r in segments for t in r.get("warnings", ())}):
            warnings.warn(text, ThermocalWarning, stacklevel=2)  # the segments', once each
        return finish_segments(task.recording, task.out_dir, task.options, segments)

    return _reported(task, finish, earlier_s=sum(r["wall_time_s"] for r in segments))


def _reported(task: CampaignTask, flight: Callable[[], dict[str, Any]], *,
              earlier_s: float = 0.0) -> dict[str, Any]:
    """``flight()`` (a flight's summary) and its report, its warnings kept: the recording's
    result (its ``seconds`` with ``earlier_s`` of its segments), or its error."""
    from thermocal.pipeline.report import write_report

    started = time.perf_counter() - earlier_s
    try:
        with routed_warnings(), caught_warnings() as caught:
            summary = flight()
            write_report(task.out_dir)
    except ThermocalError as exc:
        return _failed(task, str(exc), started)
    return _result(task, summary, caught, started)


def _failed(task: CampaignTask, error: str, started: float) -> dict[str, Any]:
    return {"name": task.name, "recording": task.recording, "ok": False, "error": error,
            "seconds": time.perf_counter() - started}


def _result(task: CampaignTask, summary: dict[str, Any], caught: list, started: float
            ) -> dict[str, Any]:
    """A finished flight's result from its summary (``caught``: its warnings)."""
    done = summary["processed"] + summary["skipped_already_done"]
    return {"name": task.name, "recording": task.recording, "out": task.out_dir,
            "ok": done > 0, "processed": summary["processed"],
            "skipped_already_done": summary["skipped_already_done"],
            "failed_groups": summary["failed"], "groups": summary["groups"],
            "sigma": summary.get("sigma_c") is not None,
            "warnings": sorted({str(w.message) for w in caught}),
            **({} if done > 0 else {"error": f"every group failed: {summary.get('first_error')}"}),
            **({"segments": summary["segments"]} if "segments" in summary else {}),
            "seconds": time.perf_counter() - started}


def connect(scheduler: str | None, workers: int) -> Any:
    """A :class:`distributed.Client` of the scheduler at ``scheduler``, or of a new
    :class:`distributed.LocalCluster` of ``workers`` single-threaded worker processes.

    Raises
    ------
    InvalidInputError
        dask.distributed not installed, or the scheduler unreachable.
    """
    from thermocal.optional import require

    distributed = require("distributed", "thermocal campaign", "campaign")
    Client, LocalCluster = distributed.Client, distributed.LocalCluster
    if scheduler is not None:
        _check_scheduler(scheduler)
        try:
            client = Client(scheduler, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise _unreachable(scheduler, exc) from None
        if not client.scheduler_info().get("workers"):
            warnings.warn(f"the Dask scheduler at {scheduler} has no workers yet: the tasks "
                          "wait for its cluster's (Ctrl-C stops)", ThermocalWarning,
                          stacklevel=2)
        return client
    import logging
    import signal

    # the worker processes start with Ctrl-C ignored (a disposition a new process keeps, and
    # Python then installs no KeyboardInterrupt of its own): Ctrl-C reaches the whole process
    # group, and only this process should answer it, closing the cluster, in one line (each
    # worker printed its tracebacks). While the workers start, Ctrl-C waits.
    main = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
    try:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0",  # any free port: no clash, no warning
                               silence_logs=logging.ERROR)  # the command says what went wrong
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)
    return Client(cluster)


def _unreachable(scheduler: str, exc: BaseException) -> InvalidInputError:
    text = str(exc).splitlines()[0][:120] if str(exc) else ""
    return InvalidInputError(
        f"cannot reach the Dask scheduler at {scheduler} ({type(exc).__name__}: {text}); start "
        "one (dask scheduler, dask-jobqueue, dask-kubernetes) or leave out --scheduler for this "
        "machine's cores")


def _check_scheduler(scheduler: str) -> None:
    """Refuse ``scheduler`` unless a Dask scheduler answers there within
    :data:`CONNECT_TIMEOUT_S`: its ``identity`` asked over a comm of its own (with the TLS
    settings of Dask's configuration, as a client takes them), bounded as a whole, since
    :class:`distributed.Client` waits forever on a port that accepts and never answers, and
    reads an HTTP server's answer (a dashboard's port) as a 3-EiB message. Asked on a thread
    of its own, so that a caller inside a running event loop (a notebook) can ask too."""
    import asyncio
    import socket
    from concurrent.futures import ThreadPoolExecutor

    from distributed.comm import get_address_host_port
    from distributed.core import rpc
    from distributed.security import Security

    try:  # nothing listening: said at once (Dask's own connect retries until its timeout)
        if scheduler.startswith(("tcp://", "tls://")):
            socket.create_connection(get_address_host_port(scheduler),
                                     timeout=CONNECT_TIMEOUT_S).close()
    except (OSError, ValueError) as exc:
        raise _unreachable(scheduler, exc) from None

    async def identity() -> Any:
        remote = rpc(scheduler, connection_args=Security().get_connection_args("client"))
        try:
            return await remote.identity()
        finally:
            await remote.close_rpc()

    def ask() -> Any:
        return asyncio.run(asyncio.wait_for(identity(), CONNECT_TIMEOUT_S))

    with ThreadPoolExecutor(1) as pool:
        try:
            info = pool.submit(ask).result()
        except TimeoutError:
            raise InvalidInputError(
                f"{scheduler} did not answer as a Dask scheduler within {CONNECT_TIMEOUT_S} s: "
                "give the scheduler's address (tcp://HOST:8786, not its dashboard's)") from None
        except (OSError, ValueError) as exc:
            raise _unreachable(scheduler, exc) from None
        except Exception as exc:  # noqa: BLE001 — whatever a stranger answered (MemoryError)
            raise InvalidInputError(
                f"{scheduler} is not a Dask scheduler (it answered otherwise: "
                f"{type(exc).__name__}); give the scheduler's address (tcp://HOST:8786, not "
                "its dashboard's)") from None
    kind = info.get("type") if isinstance(info, dict) else None
    if kind != "Scheduler":
        raise InvalidInputError(
            f"{scheduler} is a Dask {kind or 'server'}, not a scheduler: give the scheduler's "
            "address (tcp://HOST:8786)")


def run_campaign(tasks: list[CampaignTask], out: str | os.PathLike[str], *,
                 scheduler: str | None = None, workers: int | None = None,
                 progress: Callable[[int], None] | None = None) -> dict[str, Any]:
    """Run ``tasks`` on the cluster; write and return ``OUT/campaign.json`` (each recording's
    result, in the order given). ``progress(k)`` as the workers' groups finish (their events,
    :data:`PROGRESS_TOPIC`), each task's frames counted once whatever its retries, and the rest
    of a task's frames when it ends (the bar's total: every task's ``frames``).
    """
    from thermocal.cores import available_cores, check_per_core
    from thermocal.io.atomic import ensure_output_dir, write_json_atomic
    from thermocal.io.replaces import check_json_replaces_only

    cores = available_cores()
    n_workers = cores if workers is None else workers
    if n_workers < 1:
        raise InvalidInputError(f"--workers must be >= 1, got {n_workers}")
    if scheduler is None:  # processes of this machine's LocalCluster
        check_per_core(n_workers, "--workers")
    check_not_a_recording_folder(Path(out))
    check_json_replaces_only(Path(out) / "campaign.json", frozenset({"recordings", "failed"}),
                             kind="campaign summary", what="--out")
    networks = sorted({t.options.method for t in tasks if _runs_network(t)})
    if networks and scheduler is None:  # this machine's workers: before any starts, not in each
        from thermocal.optional import require

        require("torch", f"--method {networks[0]} (a network)", "nn")
    started = time.perf_counter()
    client = connect(scheduler, n_workers)
    from distributed import as_completed  # installed: connect() checked
    connected = time.perf_counter()
    counted: dict[str, int] = {}  # frames of each task's key the bar has moved by
    limits: dict[str, int] = {}
    lock = threading.Lock()

    def advance(key: str, frames: int) -> None:
        with lock:  # events arrive on the client's thread, task ends on this one
            k = max(0, min(frames, limits.get(key, 0) - counted.get(key, 0)))
            counted[key] = counted.get(key, 0) + k
        if k and progress is not None:
            progress(k)

    def on_event(event: Any) -> None:
        message = event[1] if isinstance(event, tuple | list) and len(event) == 2 else event
        if isinstance(message, dict) and isinstance(message.get("frames"), int):
            advance(str(message.get("key")), message["frames"])

    try:
        out_dir = ensure_output_dir(out)  # only now: every check has passed
        # a topic of this run's own: campaigns sharing a scheduler keep their bars apart
        events = f"{PROGRESS_TOPIC}-{uuid.uuid4().hex}" if progress is not None else None
        if events is not None:
            client.subscribe_topic(events, on_event)
        share = max(1, cores // n_workers) if scheduler is None else None
        futures = {}
        for task in tasks:
            if share is not None:  # this machine's cores, shared out between its workers
                # its pivots at once, as a flight does on its cores, each network on one
                # thread; one at a time on --threads threads when they are given
                given = task.options.threads
                options = replace(task.options, registration_threads=share,
                                  pivot_workers=share if given is None else 1)
                if given is None and _runs_network(task):
                    options = replace(options, threads=1)
                task = replace(task, threads=share, options=options)
            task = replace(task, events=events)
            limits[_task_key(task)] = task.frames
            futures[client.submit(_run_task, task, key=_task_key(task), pure=False,
                                  retries=RETRIES)] = task
        results: dict[str, dict[str, Any]] = {}
        segments: dict[str, list[dict[str, Any]]] = {}  # a recording's finished segments
        parts = {t.name: sum(u.name == t.name for u in tasks) for t in tasks}
        running = as_completed(futures)
        for future in running:
            task = futures[future]
            try:
                result = future.result()
            except Exception as exc:  # noqa: BLE001 - a dead worker, a lost task: reported
                result = {"name": task.name, "recording": task.recording, "ok": False,
                          "error": f"{type(exc).__name__}: {exc}"}
            if task.segment is not None and result.get("segment") is not None:
                done = segments.setdefault(task.name, [])
                done.append(result["segment"])
                if len(done) == parts[task.name]:  # every segment: finish the recording
                    last = client.submit(_finish_task, task, done, pure=False,
                                         key=_task_key(task, finish=True),
                                         retries=RETRIES)
                    futures[last] = replace(task, segment=None, frames=0)
                    running.add(last)
            elif task.name not in results or results[task.name]["ok"]:  # its first failure
                results[task.name] = result | {"recording": task.recording}
            advance(_task_key(task), task.frames)  # what its events did not say
    finally:
        client.close()
        cluster = getattr(client, "cluster", None)
        if cluster is not None:
            cluster.close()
    names = list(dict.fromkeys(t.name for t in tasks))  # a recording's segments: one result
    # what earlier runs into OUT did for recordings this one left out: kept, not lost
    earlier = [r for r in _earlier_runs(out_dir) if r["name"] not in names]
    summary = {"recordings": [results[name] for name in names],
               **({"earlier": list({r["name"]: r for r in earlier}.values())}
                  if earlier else {}),
               "failed": sum(not results[name]["ok"] for name in names),
               "workers": n_workers, "scheduler": scheduler or "LocalCluster",
               "options": asdict(tasks[0].options) if tasks else {},
               "wall_time_s": time.perf_counter() - started,
               "cluster_start_s": connected - started}
    write_json_atomic(out_dir / "campaign.json", summary)
    return summary


def _task_key(task: CampaignTask, *, finish: bool = False) -> str:
    """The task's key on the scheduler: the kind of task before the recording's name, so that
    no name makes another task's key (``a``'s finishing task and a recording ``a-finish``)."""
    if finish:
        return f"thermocal-finish-{task.name}"
    if task.segment is None:
        return f"thermocal-flight-{task.name}"
    return f"thermocal-segment-{task.segment[0]}-{task.name}"


def _runs_network(task: CampaignTask) -> bool:
    """Whether the task's method runs a network (whose threads the campaign shares out)."""
    from thermocal.estimation.registry import ESTIMATORS

    return ESTIMATORS[task.options.method].needs == "model"
