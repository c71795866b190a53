"""thermocal: radiometric temperature from low-cost uncooled microbolometer cameras."""

from importlib.metadata import PackageNotFoundError, version

from thermocal.errors import (
    FileFormatError,
    FitError,
    InvalidInputError,
    RegistrationError,
    ResolutionMismatchError,
    ThermocalError,
)

try:
    __version__ = version("thermocal")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0+unknown"

__all__ = [
    "FileFormatError",
    "FitError",
    "InvalidInputError",
    "RegistrationError",
    "ResolutionMismatchError",
    "ThermocalError",
    "__version__",
]
