"""Optional dependencies (the extras of ``pyproject.toml``): imported where a command needs
them, and refused in one line naming the extra that installs them where they are missing."""

from __future__ import annotations

import importlib
from types import ModuleType

from thermocal.errors import InvalidInputError

__all__ = ["require"]


def require(module: str, what: str, extra: str) -> ModuleType:
    """Import ``module`` (``"torch"``, ``"onnx"``, ``"distributed"``…) for ``what`` (words: the
    method or command that needs it), or raise :class:`InvalidInputError` saying that ``what``
    needs it and that ``pip install 'thermocal[EXTRA]'`` installs it; where it is installed
    but fails to import (a dependency of its own missing, a binary built for another numpy),
    saying so and why: pip would answer that it is already there."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if (exc.name or "").split(".")[0] == module.split(".")[0]:
            raise InvalidInputError(
                f"{what} needs {module}: pip install 'thermocal[{extra}]'") from None
        raise InvalidInputError(f"{what} needs {module}, which is installed but fails to "
                                f"import: {exc}") from None
    except ImportError as exc:
        raise InvalidInputError(f"{what} needs {module}, which is installed but fails to "
                                f"import: {exc}") from None
