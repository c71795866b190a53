"""Exceptions raised by thermocal.

Every error caused by bad input derives from :class:`ThermocalError`; its message is one line that
says what was wrong and what to do. The command line turns it into exit status 2.
"""


class ThermocalError(Exception):
    """Base class of all thermocal errors caused by bad input or a failed fit."""


class InvalidInputError(ThermocalError, ValueError):
    """An array or value of the wrong shape, dtype or range (NaN, below absolute zero, ...)."""


class FileFormatError(ThermocalError):
    """A file that is missing, truncated, or not what it claims to be."""


class ResolutionMismatchError(InvalidInputError):
    """Frames whose size does not match a calibration, a model or each other."""


class OutsideDomainError(InvalidInputError):
    """Input outside what a model was fitted or trained on (its FPA or scene range, its camera
    family); the message says why and what to do (calibrate, train, or ``--force``)."""


class RegistrationError(ThermocalError):
    """Registration found no usable homography."""


class FitError(ThermocalError):
    """A fit that could not be made from the data given (too few points, singular system)."""


class OutputError(ThermocalError):
    """An output that could not be written (a full or read-only disk)."""
