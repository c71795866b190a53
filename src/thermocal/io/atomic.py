"""Atomic file output: an output is either complete and in place, or not there at all.

Every writer in :mod:`thermocal.io` writes into a temporary file beside its target and renames it
onto the target with :func:`os.replace` only once the write has succeeded. A failed or interrupted
write therefore never leaves a half-written output, never clobbers an existing good file, and
removes its temporary file.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.errors import InvalidInputError, ThermocalError

__all__ = [
    "atomic_path",
    "ensure_output_dir",
    "removing_new_dirs_on_error",
    "staging_folder",
    "temp_name_pattern",
    "write_json_atomic",
]

#: The folders :func:`ensure_output_dir` created, one list per active
#: :func:`removing_new_dirs_on_error` block.
_NEW_DIRS: list[list[Path]] = []


def staging_folder(parent: Path, prefix: str, suffix: str = "") -> Path:
    """A new folder in ``parent`` named ``prefix…suffix`` (:func:`tempfile.mkdtemp`) with the
    permissions an ordinary ``mkdir`` gives under this process's umask, not mkdtemp's private
    0700: an output folder staged in it and renamed into place is readable as the others are."""
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix=prefix, suffix=suffix, dir=parent))
    folder.chmod(0o777 & ~_umask())
    return folder


def _umask() -> int:
    """Return the process umask without changing it where the platform allows (Linux)."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    old = os.umask(0o022)  # pragma: no cover - non-Linux fallback
    os.umask(old)  # pragma: no cover
    return old  # pragma: no cover


def _temp_name_parts(target: Path) -> tuple[str, str]:
    """Prefix and suffix of a temporary file: hidden, and ending like ``target``."""
    suffix = target.suffix
    stem = target.name[: len(target.name) - len(suffix)] if suffix else target.name
    return f".{stem}.", suffix


def temp_name_pattern(stem: str, suffix: str) -> re.Pattern[str]:
    """The names :func:`atomic_path` gives the temporary files of targets named
    ``STEM + suffix``, ``stem`` a regular expression (the prefix of :func:`_temp_name_parts`,
    the eight characters :func:`tempfile.mkstemp` draws, the suffix): to find the ones a killed
    run left behind, with :meth:`re.Pattern.fullmatch`."""
    return re.compile(rf"\.{stem}\.[a-z0-9_]{{8}}{re.escape(suffix)}")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], *, fsync: bool = False) -> Iterator[Path]:
    """Yield a temporary path to write to; it replaces ``path`` only if the block succeeds.

    The temporary file lies in the same directory as ``path`` (so that the final
    :func:`os.replace` is an atomic rename on the same file system), its name starts with ``'.'``
    and it ends with the target's suffix (``.tiff``, ``.h5``, ``.json``, ...) so that libraries
    which choose a format from the name pick the right one. It exists (empty) when the block
    starts; writers may truncate or overwrite it.

    Parameters
    ----------
    path : str or os.PathLike
        The final output file. Its directory must exist.
    fsync : bool, optional
        Flush the temporary file to disk before the rename (durable against power loss, slower
        for large files). Default False: the rename is still atomic for other processes.

    Yields
    ------
    pathlib.Path
        The temporary file to write.

    Raises
    ------
    InvalidInputError
        If the directory of ``path`` does not exist or ``path`` is an existing directory.
    ThermocalError
        If the block removed the temporary file instead of writing it.

    Notes
    -----
    On any exception in the block (``KeyboardInterrupt`` included) the temporary file is removed,
    the exception propagates, and an existing file at ``path`` is left untouched.

    Examples
    --------
    >>> with atomic_path("out/frames.tiff") as tmp:  # doctest: +SKIP
    ...     tifffile.imwrite(tmp, frames)
    """
    target = Path(path)
    directory = target.parent
    if not directory.is_dir():
        raise InvalidInputError(f"{target}: directory {directory} does not exist; create it first")
    if target.is_dir():
        raise InvalidInputError(f"{target}: is a directory; give a file name to write")
    prefix, suffix = _temp_name_parts(target)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=prefix, suffix=suffix, dir=directory)
    except OSError as exc:
        raise InvalidInputError(f"{target}: cannot write in {directory} ({exc.strerror})") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        # mkstemp makes the file private (0600); give it the mode a normal open() would.
        os.chmod(tmp, 0o666 & ~_umask())
        yield tmp
        if not tmp.exists():
            raise ThermocalError(
                f"{target}: the temporary file {tmp.name} vanished; nothing was written"
            )
        if fsync:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def _json_default(obj: Any) -> Any:
    """Turn numpy scalars and arrays (and paths) into plain JSON values."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(f"object of type {type(obj).__name__} is not JSON serialisable")


def write_json_atomic(path: str | os.PathLike[str], obj: Any, *, indent: int | None = 2) -> Path:
    """Write ``obj`` as JSON (UTF-8, trailing newline) to ``path`` atomically.

    numpy arrays and scalars are written as lists and numbers. NaN and infinity are not valid
    JSON and are rejected.

    Parameters
    ----------
    path : str or os.PathLike
        The output file; its directory must exist.
    obj : Any
        A JSON-serialisable object (dicts, lists, str, int, float, bool, None, numpy values).
    indent : int or None, optional
        Indentation passed to :func:`json.dumps`; None writes one line.

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.

    Raises
    ------
    InvalidInputError
        If ``obj`` holds NaN, infinity or a value JSON cannot represent; nothing is written.
    """
    try:
        text = json.dumps(obj, indent=indent, allow_nan=False, default=_json_default)
    except (TypeError, ValueError) as exc:
        msg = str(exc)
        if "Out of range float" in msg:
            msg = "NaN or infinite values cannot be written to JSON"
        raise InvalidInputError(f"{Path(path)}: {msg}") from None
    with atomic_path(path) as tmp:
        tmp.write_text(text + "\n", encoding="utf-8")
    return Path(path)


def ensure_output_dir(path: str | os.PathLike[str]) -> Path:
    """Create the output directory ``path`` (and its parents) if needed and check it is writable.

    Parameters
    ----------
    path : str or os.PathLike
        The directory.

    Returns
    -------
    pathlib.Path
        ``path`` as a Path.

    Raises
    ------
    InvalidInputError
        If ``path`` exists and is not a directory, cannot be created, or is not writable.
    """
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise InvalidInputError(f"{out}: exists and is a file; give a directory for the output")
    missing = []  # the folders this call makes, outermost last
    parent = out
    while not parent.exists() and parent.parent != parent:
        missing.append(parent)
        parent = parent.parent
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidInputError(f"{out}: cannot create the directory ({exc.strerror})") from None
    for new_dirs in _NEW_DIRS:
        new_dirs.extend(reversed(missing))
    if not os.access(out, os.W_OK | os.X_OK):
        raise InvalidInputError(f"{out}: directory is not writable; choose another output")
    return out


@contextlib.contextmanager
def removing_new_dirs_on_error() -> Iterator[None]:
    """Remove, when the block fails, the output folders :func:`ensure_output_dir` created in it
    that are still empty (a failed run leaves no empty folder behind; a folder holding any file,
    a finished output or a log, is kept). A ``SystemExit`` of status 0 is no failure.

    The command line runs every command in such a block.
    """
    created: list[Path] = []
    _NEW_DIRS.append(created)
    try:
        yield
    except SystemExit as exc:
        if exc.code not in (0, None):
            _remove_empty(created)
        raise
    except BaseException:
        _remove_empty(created)
        raise
    finally:
        del _NEW_DIRS[next(i for i, d in enumerate(_NEW_DIRS) if d is created)]


def _remove_empty(folders: list[Path]) -> None:
    """Remove the empty ones of ``folders``, innermost (last created) first."""
    for folder in reversed(folders):
        with contextlib.suppress(OSError):
            folder.rmdir()  # fails, and keeps the folder, unless it is empty
