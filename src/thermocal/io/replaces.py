"""What an output file would replace (h5py only): a command's output may replace an earlier
output of its own kind, never a file of another kind (a chamber session overwritten by a
calibration, or a calibration by a simulated session, is lost for good), nor one of its kind
that another source wrote (a measured chamber session overwritten by a simulated one)."""

from __future__ import annotations

import os
from pathlib import Path

from thermocal.errors import InvalidInputError

__all__ = ["HDF5_MAGIC", "check_json_replaces_only", "check_map_replaces_only",
           "check_replaces_only", "check_text_replaces_only", "hdf5_kind", "json_object_with",
           "map_kind"]

#: The first bytes of every HDF5 file (its superblock signature).
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
#: The ``format`` attribute of each kind of the project's HDF5 files, and its name.
_KINDS = {"thermocal-calibration": "calibration", "thermocal-chamber": "chamber session"}


def hdf5_kind(path: str | os.PathLike[str]) -> str:
    """What a file holds, in words: ``"calibration"``, ``"chamber session"`` (the project's
    HDF5 files by their ``format`` attribute; a chamber file without one by its ``frames`` and
    ``blackbody_c``), ``"another HDF5 file"``, ``"a file that is not HDF5"``, or ``"an unreadable
    file"``."""
    return _kind_and_source(Path(path))[0]


def _kind_and_source(p: Path) -> tuple[str, str | None]:
    """:func:`hdf5_kind` and the file's ``source`` attribute (what wrote it), None without."""

    def text(v: object) -> str | None:
        return None if v is None else (v.decode("utf-8", "replace") if isinstance(v, bytes)
                                       else str(v))
    try:
        with open(p, "rb") as fh:
            if fh.read(8) != HDF5_MAGIC:
                return "a file that is not HDF5", None
        import h5py  # here: a file that is not HDF5 is told without it

        with h5py.File(p, "r") as f:
            fmt, source = text(f.attrs.get("format")), text(f.attrs.get("source"))
            if fmt in _KINDS:
                return _KINDS[fmt], source
            if "frames" in f and "blackbody_c" in f:
                return "chamber session", source
            return "another HDF5 file", source
    except (OSError, ValueError):
        return "an unreadable file", None


def check_replaces_only(path: str | os.PathLike[str], kind: str, *, what: str = "--out",
                        source: str | None = None) -> None:
    """Refuse an output ``path`` that exists and holds something other than ``kind`` (a
    :func:`hdf5_kind` name), or, given ``source``, one of that kind its ``source`` attribute
    says something else wrote (a measured chamber session, which a simulation would replace):
    it would be lost.

    Raises
    ------
    InvalidInputError
    """
    p = Path(path)
    if not p.is_file():
        return
    found, by = _kind_and_source(p)
    if found != kind:
        article = "a " if found in _KINDS.values() else ""
        raise InvalidInputError(
            f"{what} {p}: exists and holds {article}{found}, not a {kind}, which writing it "
            f"would lose: choose another {what}")
    if source is not None and by != source:
        raise InvalidInputError(
            f"{what} {p}: exists and holds a {kind} from {by or 'an unknown source'}, not one "
            f"{source} wrote, which writing it would lose: choose another {what}")


def check_json_replaces_only(path: str | os.PathLike[str], keys: frozenset[str], *, kind: str,
                             what: str) -> None:
    """Refuse an output ``path`` that exists and is not a JSON object with ``keys`` (an
    earlier ``kind``, e.g. a calibration report, which it may replace): a recording's sidecar
    or any other file would be lost.

    Raises
    ------
    InvalidInputError
    """
    p = Path(path)
    if p.is_file() and not json_object_with(p, keys):
        raise InvalidInputError(
            f"{what} {p}: exists and is not a {kind}, which writing it would lose: choose "
            f"another {what}")


def json_object_with(path: str | os.PathLike[str], keys: frozenset[str] | set[str]) -> bool:
    """Whether ``path`` reads as a JSON object holding every one of ``keys`` (False for a file
    that cannot be read or is not JSON)."""
    import json

    try:
        held = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(held, dict) and keys <= held.keys()


def map_kind(path: str | os.PathLike[str]) -> str:
    """What an existing TIFF holds, in words: ``"a map"`` (floating-point pixels described by a
    JSON object, as this project's temperature, σ and NUC maps are: tifffile writes one), ``"raw
    counts"`` (integer pixels: a recording or a camera's frame), ``"a TIFF of another tool"``
    (floats without such a description), ``"a file that is not a TIFF"``."""
    import json

    import tifffile

    try:
        with tifffile.TiffFile(path) as tif:
            page = tif.pages.first
            kind, text = page.dtype.kind if page.dtype is not None else "", page.description
    except Exception:  # tifffile raises many types on what is not a TIFF
        return "a file that is not a TIFF"
    if kind in "ui":
        return "raw counts"
    try:
        described = isinstance(json.loads(text), dict)
    except ValueError:
        described = False
    return "a map" if kind == "f" and described else "a TIFF of another tool"


def check_map_replaces_only(path: str | os.PathLike[str], *, what: str = "--out") -> None:
    """Refuse an output map ``path`` that exists and holds anything but an earlier map
    (:func:`map_kind`), or that is a recording's frames (a sidecar ``.json`` beside it): raw
    counts, a real camera's frame or another tool's image would be lost (``correct --out
    rec.tiff`` replaced a recording's frames with temperatures, exit 0: a helper's audit).

    Raises
    ------
    InvalidInputError
    """
    p = Path(path)
    if not p.exists():  # nothing there, or a link to nothing: nothing to lose
        return
    if not p.is_file():
        raise InvalidInputError(f"{what} {p}: exists and is not a regular file: choose another "
                                f"{what}")
    if p.stat().st_size == 0:  # an empty placeholder (mktemp's): nothing to lose
        return
    found = map_kind(p)
    if p.with_suffix(".json").is_file():
        found = f"{found}, a recording's frames (its sidecar {p.with_suffix('.json').name})"
    elif found == "a map":
        return
    raise InvalidInputError(f"{what} {p}: exists and holds {found}, which writing it would "
                            f"lose: choose another {what}")


def check_text_replaces_only(path: str | os.PathLike[str], prefix: str, *, kind: str,
                             what: str) -> None:
    """Refuse an output ``path`` that exists and is not a text file whose first line starts
    with ``prefix`` (an earlier ``kind``, e.g. a benchmark report, which it may replace).

    Raises
    ------
    InvalidInputError
    """
    p = Path(path)
    if not os.path.lexists(p):
        return
    ours = False
    if p.is_file():  # not a FIFO, which would block the read
        try:
            with open(p, encoding="utf-8") as fh:
                ours = fh.readline().startswith(prefix)
        except (OSError, ValueError):
            pass
    if not ours:
        raise InvalidInputError(f"{what} {p}: exists and is not a {kind}, which writing it "
                                f"would lose: choose another {what}")
