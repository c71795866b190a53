"""The camera model: response polynomials, radial structure, FPN, noise, defects, thermal state."""

from thermocal.camera.model import CameraModel, expected_counts, invert, render
from thermocal.camera.presets import PRESETS, CameraPreset, make_camera, radial_map
from thermocal.camera.thermal import (
    PROFILES,
    ThermalParams,
    ThermalState,
    ambient_profile,
    fpa_sensor,
    profile_duration_s,
    thermal_response,
)

__all__ = [
    "PRESETS",
    "PROFILES",
    "CameraModel",
    "CameraPreset",
    "ThermalParams",
    "ThermalState",
    "ambient_profile",
    "expected_counts",
    "fpa_sensor",
    "invert",
    "make_camera",
    "profile_duration_s",
    "radial_map",
    "render",
    "thermal_response",
]
