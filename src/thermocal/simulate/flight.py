"""Simulated flights: a camera unit moving over a large temperature map.

Each frame is the scene in that frame's view (the ground truth), rendered into raw counts by the
camera model at the camera's thermal state. The true homographies of every frame to the pivot frame
are kept, so that registration and multi-frame methods can be measured against them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from thermocal._validate import as_temperature_c
from thermocal.camera.model import CameraModel, render
from thermocal.camera.thermal import ThermalParams, ambient_profile, fpa_sensor, thermal_response
from thermocal.errors import InvalidInputError
from thermocal.registration.warp import render_views
from thermocal.scenes import trajectory
from thermocal.scenes.maps import make_map

MOTIONS = ("walk", "hover", "uav")


@dataclass(frozen=True)
class Flight:
    """A simulated recording with its ground truth.

    frames : (N, H, W) uint16 raw counts.
    truth_c : (N, H, W) float32 scene temperature in each frame's view, °C.
    homographies : (N, 3, 3) float64, pixel of frame i → pixel of the pivot frame (true).
    to_map : (N, 3, 3) float64, pixel of frame i → pixel of the map.
    pivot : index of the pivot frame (the middle one).
    time_s, fpa_c (sensor reading), fpa_true_c, housing_c, ambient_c : (N,) series.
    """

    frames: np.ndarray
    truth_c: np.ndarray
    homographies: np.ndarray
    to_map: np.ndarray
    pivot: int
    time_s: np.ndarray
    fpa_c: np.ndarray
    fpa_true_c: np.ndarray
    housing_c: np.ndarray
    ambient_c: np.ndarray


def map_shape_for(motion: str, n_frames: int, frame_size: tuple[int, int]) -> tuple[int, int]:
    """A map shape ``(H, W)`` large enough for ``n_frames`` views of ``frame_size = (W, H)``."""
    w, h = frame_size
    if motion == "uav":
        step = trajectory.pixel_motion_per_frame()
        return (int(1.25 * h) + 16, int(w + 1.1 * step * n_frames) + 32)
    if motion in ("walk", "hover"):
        return (2 * h + 16, 2 * w + 16)
    raise InvalidInputError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")


def flight_homographies(
    motion: str, n_frames: int, frame_size: tuple[int, int], map_shape: tuple[int, int], *,
    rng: np.random.Generator,
) -> np.ndarray:
    """Frame → map homographies ``(N, 3, 3)`` of a walk, a hover or a UAV pass."""
    map_size = (map_shape[1], map_shape[0])
    if motion == "walk":
        return trajectory.walk_homographies(n_frames, frame_size, map_size, rng=rng)
    if motion == "hover":
        return trajectory.hover_homographies(n_frames, frame_size, map_size, rng=rng)
    if motion == "uav":
        return trajectory.uav_homographies(n_frames, frame_size, map_size, heading_deg=0.0, rng=rng)
    raise InvalidInputError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")


def simulate_flight(
    scene_c: np.ndarray,
    camera: CameraModel,
    *,
    n_frames: int = 7,
    motion: str = "walk",
    fpa_c: float = 30.0,
    fps: float = 30.0,
    seed: int = 0,
    thermal: ThermalParams = ThermalParams(),
) -> Flight:
    """Fly ``camera`` over ``scene_c`` (°C map, any size: it is resized into a large map).

    The camera has settled at a constant ambient that puts its FPA at ``fpa_c`` (°C).
    """
    if n_frames < 1:
        raise InvalidInputError(f"a flight needs at least 1 frame, got {n_frames}")
    if fps <= 0:
        raise InvalidInputError(f"frame rate must be > 0, got {fps}")
    scene = as_temperature_c(scene_c, "scene", ndim=2)
    as_temperature_c(fpa_c, "fpa_c")
    rng = np.random.default_rng(seed)
    h, w = camera.shape
    shape = map_shape_for(motion, n_frames, (w, h))
    big_map = make_map(scene, shape)
    to_map = flight_homographies(motion, n_frames, (w, h), shape, rng=rng)
    pivot = n_frames // 2
    truth = render_views(big_map, to_map, (w, h))

    time_s = np.arange(n_frames) / fps
    ambient = ambient_profile(
        "constant", time_s, low_c=thermal.ambient_for_fpa_c(fpa_c), high_c=fpa_c
    )
    state = thermal_response(time_s, ambient, thermal)
    frames = render(
        camera,
        truth,
        state.fpa_c,
        housing_c=state.housing_c,
        fpa_rate_c_per_min=state.fpa_rate_c_per_min,
        rng=rng,
    )
    return Flight(
        frames=frames,
        truth_c=truth,
        homographies=trajectory.to_pivot(to_map, pivot),
        to_map=to_map,
        pivot=pivot,
        time_s=time_s,
        fpa_c=fpa_sensor(state.fpa_c, thermal, rng=rng),
        fpa_true_c=state.fpa_c,
        housing_c=state.housing_c,
        ambient_c=ambient,
    )


def write_flight(out_dir: str | Path, flight: Flight, *, extra: dict | None = None) -> None:
    """Write ``frames.tiff`` + ``frames.json``, ``truth.tiff``, ``homographies.npy`` to ``out_dir``.

    Each file is written atomically; the folder is created if needed (an existing file of that
    name is an error).
    """
    from thermocal.io.atomic import atomic_path, ensure_output_dir
    from thermocal.io.recording import Recording, write_recording, write_temperature_tiff

    out = Path(out_dir)
    ensure_output_dir(out)
    meta = {"pivot": int(flight.pivot), "fpa_true_c": flight.fpa_true_c.tolist()}
    meta |= extra or {}
    rec = Recording(
        frames=flight.frames,
        fpa_c=flight.fpa_c,
        time_s=flight.time_s,
        housing_c=flight.housing_c,
        ambient_c=flight.ambient_c,
        extra=json.loads(json.dumps(meta)),
    )
    write_recording(out / "frames.tiff", rec)
    write_temperature_tiff(out / "truth.tiff", flight.truth_c)
    with atomic_path(out / "homographies.npy") as tmp:
        np.save(tmp, flight.homographies)
