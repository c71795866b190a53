"""thermocal: radiometric temperature from low-cost uncooled microbolometer cameras."""

from thermocal.errors import (
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
