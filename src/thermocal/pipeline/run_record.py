"""What a flight's output folder was made from, so that a rerun resumes only the same run.

A rerun of ``thermocal flight`` (or a campaign) into a folder resumes it: the maps an earlier
run finished are kept. That is right only when they were made from the same recording with the
same options. ``OUT/run.json`` records what decides the maps' numbers -- the recording (its
name, size and a digest of its first and last MiB; a folder's names and sizes), the options
that change them, and the content of the calibration, weights and reference files -- and a
rerun in which any of them changed is refused, saying what changed, rather than mixing the two
runs' maps under the new run's summary.

Threads, workers and previews are not recorded: they do not change the maps (tested).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from thermocal.errors import InvalidInputError

__all__ = ["RECORDING_SUFFIXES", "RUN_FILE", "check_not_a_recording_folder", "check_run_record",
           "run_record"]

#: The record's name in the output folder.
RUN_FILE = "run.json"
#: Names of the files a recording is made of (what ``thermocal info`` reads; a TIFF with its
#: JSON sidecar); an output folder writes none of them at its top.
RECORDING_SUFFIXES = (".tif", ".tiff", ".seq", ".csq", ".fff", ".jpg", ".jpeg", ".npz")
#: :class:`~thermocal.pipeline.flight.FlightOptions` fields that change the maps' numbers.
MAP_OPTIONS = ("method", "frames", "stride", "fpa_c", "fpa_sigma_c", "force", "geotiff",
               "hfov_deg", "family", "backend")
#: Fields naming files whose content changes the maps.
FILE_OPTIONS = ("calibration", "model", "references")
_EDGE_BYTES = 1 << 20  # how much of each end of a recording file the digest reads


def run_record(recording: Path, options: Any, *, model: Path | None = None) -> dict[str, Any]:
    """The record of a run of ``options`` (a ``FlightOptions``) on ``recording``; ``model``: the
    weights the method runs when ``options.model`` is None (the shipped ones)."""
    files = {name: getattr(options, name) for name in FILE_OPTIONS}
    if files["model"] is None and model is not None:
        files["model"] = model
    record = {
        "recording": _recording_digest(Path(recording)),
        "options": {name: getattr(options, name) for name in MAP_OPTIONS},
        "files": {name: None if path is None else _content_digest(Path(path))
                  for name, path in files.items()},
    }
    return json.loads(json.dumps(record))  # as it reads back from the file


def check_not_a_recording_folder(out: Path) -> None:
    """Refuse an output folder ``out`` that holds a recording's files at its top (its maps and
    logs would be mixed in beside another recording's frames, which a later flight of that
    folder would read as one recording)."""
    def recording(p: Path) -> bool:  # a TIFF is one with its sidecar; hidden files are ours
        if p.name.startswith(".") or p.suffix.lower() not in RECORDING_SUFFIXES:
            return False
        tiff = p.suffix.lower() in (".tif", ".tiff")
        return p.is_file() and (not tiff or p.with_suffix(".json").is_file())

    try:
        found = sorted(p.name for p in out.iterdir() if recording(p))
    except (FileNotFoundError, NotADirectoryError):
        return  # made later, or refused as a file where the folder goes
    except OSError as exc:
        raise InvalidInputError(f"{out}: cannot list ({exc.strerror or exc})") from None
    if found:
        raise InvalidInputError(
            f"{out}: holds a recording ({found[0]}{', …' if len(found) > 1 else ''}); give an "
            "output folder of its own (e.g. a new folder beside it)")


#: What a flight writes at the top of its folder beside its maps: in a folder that holds no
#: run of its own (no :data:`RUN_FILE`), one of these is the user's, which a run would replace
#: (a flight into a folder replaced the user's report.html, exit 0: a helper's audit).
FLIGHT_TOP_OUTPUTS = ("report.html", "summary.json", "log.csv", "mosaic")


def check_no_foreign_outputs(out: Path, names: tuple[str, ...], command: str) -> None:
    """Refuse an output folder ``out`` holding any of ``names`` (what ``command`` would write
    there) that no run of its own wrote."""
    found = [n for n in names if os.path.lexists(out / n)]
    if found:
        raise InvalidInputError(
            f"{out}: holds {', '.join(found)}, which thermocal {command} did not write and "
            "would replace; give an output folder of its own (e.g. a new folder)")


def check_run_record(out: Path, record: dict[str, Any]) -> None:
    """Refuse to resume ``out`` when its ``run.json`` says its maps came from another run than
    ``record``, or when it has a run's log but no record (an older thermocal); refuse an
    ``out`` holding a recording (:func:`check_not_a_recording_folder`). A record with no map
    finished under it (no log line: a run that failed or was stopped before its first pivot)
    is no run to resume: the new one takes its place."""
    check_not_a_recording_folder(out)
    path = out / RUN_FILE
    remedy = f"give a new --out, or remove {out} to redo the run"
    if not path.is_file():
        if _has_log_lines(out):
            raise InvalidInputError(
                f"{out}: holds maps of a run whose recording and options were not recorded; "
                f"resuming could mix two runs' maps: {remedy}")
        check_no_foreign_outputs(out, FLIGHT_TOP_OUTPUTS, "flight")
        return
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        if not _has_log_lines(out):
            return  # a damaged record with nothing under it: replaced
        raise InvalidInputError(f"{path}: not a run record ({exc}); {remedy}") from None
    changed = _changes(old if isinstance(old, dict) else {}, record)
    if changed and _has_log_lines(out):
        raise InvalidInputError(
            f"{out}: holds maps of another run ({'; '.join(changed)}); resuming would mix the "
            f"two runs' maps: {remedy}")


def _has_log_lines(out: Path) -> bool:
    """Whether ``out`` holds the log of an earlier run (the flight's or a segment's)."""
    try:
        return any(p.is_file() and p.stat().st_size > 0 for p in out.glob("log*.jsonl"))
    except OSError:
        return False


def _changes(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """What differs between two records, in words."""
    out = []
    if old.get("recording") != new["recording"]:
        out.append("another recording")
    before = old.get("options") if isinstance(old.get("options"), dict) else {}
    for name, value in new["options"].items():
        if before.get(name) != value:
            out.append(f"--{name.replace('_', '-')} {before.get(name)} → {value}")
    files = old.get("files") if isinstance(old.get("files"), dict) else {}
    for name, digest in new["files"].items():
        was = files.get(name)
        if was != digest:
            # a network's weights are recorded whether given (--model) or the shipped default
            out.append(f"a {name} file used now, none before" if was is None else
                       f"the {name} file used before, none now" if digest is None else
                       f"another {name} file")
    return out


def _recording_digest(path: Path) -> dict[str, Any]:
    """A recording's identity: a file's name, size and a digest of its first and last MiB (a
    whole-file hash would read gigabytes on every rerun); a folder's names and sizes."""
    if path.is_dir():
        entries = sorted((str(p.relative_to(path)), p.stat().st_size)
                         for p in path.rglob("*") if p.is_file())
        return {"name": path.name, "files": len(entries),
                "sha256": hashlib.sha256(json.dumps(entries).encode()).hexdigest()}
    size = path.stat().st_size
    digest = hashlib.sha256()
    with path.open("rb") as f:
        digest.update(f.read(_EDGE_BYTES))
        if size > 2 * _EDGE_BYTES:
            f.seek(size - _EDGE_BYTES)
        digest.update(f.read(_EDGE_BYTES))
    return {"name": path.name, "bytes": size, "sha256": digest.hexdigest()}


def _content_digest(path: Path) -> str:
    """sha256 of a file's content (a folder: of its files' names and contents)."""
    digest = hashlib.sha256()
    for p in ([path] if path.is_file() else sorted(q for q in path.rglob("*") if q.is_file())):
        if p != path:  # a file's own name is not its content: a renamed copy is the same
            digest.update(str(p.relative_to(path)).encode())
        with p.open("rb") as f:
            for block in iter(lambda f=f: f.read(1 << 20), b""):
                digest.update(block)
    return digest.hexdigest()
