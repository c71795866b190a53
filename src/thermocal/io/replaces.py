"""What an output file would replace (h5py only): a command's output may replace an earlier
output of its own kind, never a file of another kind (a chamber session overwritten by a
calibration, or a calibration by a simulated session, is lost for good)."""

from __future__ import annotations

import os
from pathlib import Path

from thermocal.errors import InvalidInputError

__all__ = ["check_replaces_only", "hdf5_kind"]

_HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
#: The ``format`` attribute of each kind of the project's HDF5 files, and its name.
_KINDS = {"thermocal-calibration": "calibration", "thermocal-chamber": "chamber session"}


def hdf5_kind(path: str | os.PathLike[str]) -> str:
    """What a file holds, in words: ``"calibration"``, ``"chamber session"`` (the project's
    HDF5 files by their ``format`` attribute; a chamber file without one by its ``frames`` and
    ``blackbody_c``), ``"another HDF5 file"``, ``"a file that is not HDF5"``, or ``"an unreadable
    file"``."""
    import h5py

    p = Path(path)
    try:
        with open(p, "rb") as fh:
            if fh.read(8) != _HDF5_MAGIC:
                return "a file that is not HDF5"
        with h5py.File(p, "r") as f:
            fmt = f.attrs.get("format")
            fmt = fmt.decode("ascii", "replace") if isinstance(fmt, bytes) else str(fmt)
            if fmt in _KINDS:
                return _KINDS[fmt]
            if "frames" in f and "blackbody_c" in f:
                return "chamber session"
            return "another HDF5 file"
    except (OSError, ValueError):
        return "an unreadable file"


def check_replaces_only(path: str | os.PathLike[str], kind: str, *, what: str = "--out"
                        ) -> None:
    """Refuse an output ``path`` that exists and holds something other than ``kind`` (a
    :func:`hdf5_kind` name): it would be lost.

    Raises
    ------
    InvalidInputError
    """
    p = Path(path)
    if not p.is_file():
        return
    found = hdf5_kind(p)
    if found != kind:
        article = "a " if found in _KINDS.values() else ""
        raise InvalidInputError(
            f"{what} {p}: exists and holds {article}{found}, not a {kind}, which writing it "
            f"would lose: choose another {what}")
