"""Real radiometric scenes shipped inside the package: two files of its copy of ``shared/data``
(``thermocal/data/shared``; licenses in ``thermocal/data/README.md``)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

import numpy as np

from thermocal.errors import InvalidInputError

BUILTIN_SCENES = {
    "aerial": "flirpy/example_radiometric.tiff",
    "floor-heating": "scenes/10_ir_fussbodenheizung.jpg",
}


def builtin_scene_path(name: str) -> Path:
    """Path of the built-in scene ``name`` (one of :data:`BUILTIN_SCENES`)."""
    if name not in BUILTIN_SCENES:
        raise InvalidInputError(
            f"unknown built-in scene {name!r}; choose from {', '.join(BUILTIN_SCENES)}"
        )
    return Path(str(files("thermocal") / "data" / "shared" / BUILTIN_SCENES[name]))


def load_builtin_scene(name: str) -> np.ndarray:
    """The built-in scene ``name`` as a float32 °C map ``(H, W)``."""
    from thermocal.scenes.real import load_scene

    return load_scene(builtin_scene_path(name))
