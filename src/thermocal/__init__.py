"""thermocal: radiometric temperature from low-cost uncooled microbolometer cameras."""

import os

# The same numbers whatever the thread count: PyTorch's CPU build does its convolutions of a
# few channels at a coarse level through MKL, whose reductions split by thread count (on an
# AVX-512 Xeon the shipped network's maps on 1 and on 2 threads differed by 1.5e-5 °C, so a
# flight's pivots estimated at once were not the bytes of one at a time). MKL's conditional
# numerical reproducibility, strict, makes them bitwise the same at no measured cost. MKL reads
# it at its first call: a program that runs a torch operation before importing thermocal keeps
# MKL's default (set MKL_CBWR=AUTO,STRICT in its environment then); a value the user set is kept.
os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

from thermocal.errors import (  # noqa: E402
    FileFormatError,
    FitError,
    InvalidInputError,
    RegistrationError,
    ResolutionMismatchError,
    ThermocalError,
)


def __getattr__(name: str) -> str:
    """``__version__``, looked up when first asked for: importing the package stays quick (the
    command line's Ctrl-C handler is installed only once the package is imported)."""
    if name != "__version__":
        raise AttributeError(f"module 'thermocal' has no attribute {name!r}")
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("thermocal")
    except PackageNotFoundError:  # pragma: no cover - a source tree without install
        found = "0+unknown"
    globals()["__version__"] = found
    return found

__all__ = [
    "FileFormatError",
    "FitError",
    "InvalidInputError",
    "RegistrationError",
    "ResolutionMismatchError",
    "ThermocalError",
    "__version__",
]
