"""Simulated flights: a camera unit moving over a large temperature map.

Each frame is the scene in that frame's view (the ground truth), rendered into raw counts by the
camera model at the camera's thermal state. The true homographies of every frame to the pivot frame
are kept, so that registration and multi-frame methods can be measured against them.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import tifffile

from thermocal._validate import MAX_DATA_FRAMES, as_temperature_c, check_data_size, check_fpa_c
from thermocal.camera.model import CameraModel, render
from thermocal.camera.thermal import (
    WARMED_UP_S,
    ThermalParams,
    ambient_profile,
    fpa_sensor,
    thermal_response,
)
from thermocal.errors import InvalidInputError
from thermocal.registration.warp import render_views
from thermocal.scenes import trajectory
from thermocal.scenes.maps import make_long_map, make_map
from thermocal.simulate._memory import frames_per_chunk, working_memory

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
    rng: np.random.Generator, crab_deg: float = 0.0,
) -> np.ndarray:
    """Frame → map homographies ``(N, 3, 3)`` of a walk, a hover or a UAV pass (flown with a
    crab angle of ``crab_deg``, degrees: :func:`thermocal.scenes.trajectory.uav_homographies`)."""
    map_size = (map_shape[1], map_shape[0])
    if motion == "walk":
        return trajectory.walk_homographies(n_frames, frame_size, map_size, rng=rng)
    if motion == "hover":
        return trajectory.hover_homographies(n_frames, frame_size, map_size, rng=rng)
    if motion == "uav":
        return trajectory.uav_homographies(n_frames, frame_size, map_size, heading_deg=0.0,
                                           crab_deg=crab_deg, rng=rng)
    raise InvalidInputError(f"unknown motion {motion!r}; choose from {', '.join(MOTIONS)}")


@dataclass(frozen=True)
class FlightChunk:
    """Frames ``start … start + k − 1`` of a flight (fields as in :class:`Flight`)."""

    start: int
    frames: np.ndarray
    truth_c: np.ndarray
    time_s: np.ndarray
    fpa_c: np.ndarray
    fpa_true_c: np.ndarray
    housing_c: np.ndarray
    ambient_c: np.ndarray


@dataclass(frozen=True)
class FlightPlan:
    """Everything about a flight but its frames: the map, the path, the thermal state."""

    big_map: np.ndarray
    to_map: np.ndarray
    pivot: int
    time_s: np.ndarray
    ambient_c: np.ndarray
    housing_c: np.ndarray
    fpa_true_c: np.ndarray
    fpa_rate_c_per_min: np.ndarray
    fpa_c: np.ndarray
    seed: int

    @property
    def homographies(self) -> np.ndarray:
        """Frame i → pivot frame homographies, ``(N, 3, 3)``."""
        return trajectory.to_pivot(self.to_map, self.pivot)


def plan_flight(
    scene_c: np.ndarray,
    camera: CameraModel,
    *,
    n_frames: int = 7,
    motion: str = "walk",
    fpa_c: float = 30.0,
    fps: float = 30.0,
    seed: int = 0,
    thermal: ThermalParams | None = None,
    ambient_rate_c_per_min: float = 0.0,
    crab_deg: float = 0.0,
) -> FlightPlan:
    """Lay out a flight of ``camera`` over ``scene_c`` (°C map, any size: resized into a map).

    The camera has settled at an ambient that puts its FPA at ``fpa_c`` (°C); from the first
    frame on the ambient changes at ``ambient_rate_c_per_min`` (°C/min; 0: constant), and the
    FPA follows through the camera's thermal lags. The FPA sensor reading is quantised and noisy
    (:func:`thermocal.camera.thermal.fpa_sensor`). ``thermal``: default the camera family's
    (``camera.thermal``). ``crab_deg``: a UAV pass's crab angle, degrees (0: the frames' rows
    along the track).
    """
    thermal = thermal or camera.thermal
    _check_flight_numbers(n_frames, fps)
    check_fpa_c(fpa_c, "fpa_c")
    scene = as_temperature_c(scene_c, "scene", ndim=2)
    rng = np.random.default_rng([seed, 0])
    h, w = camera.shape
    shape = map_shape_for(motion, n_frames, (w, h))
    big_map = make_long_map(scene, shape) if motion == "uav" else make_map(scene, shape)
    to_map = flight_homographies(motion, n_frames, (w, h), shape, rng=rng, crab_deg=crab_deg)
    time_s = np.arange(n_frames) / fps
    if not np.isfinite(ambient_rate_c_per_min):
        raise InvalidInputError("the ambient rate must be a finite number of °C/min")
    settled = thermal.ambient_for_fpa_c(fpa_c)
    if ambient_rate_c_per_min == 0:
        ambient = ambient_profile("constant", time_s, low_c=settled, high_c=fpa_c)
    else:
        ambient = ambient_profile(
            "ramp", time_s, low_c=settled,
            high_c=settled + ambient_rate_c_per_min * float(time_s[-1]) / 60.0,
            rate_c_per_min=abs(ambient_rate_c_per_min))
    state = thermal_response(time_s, ambient, thermal)
    return FlightPlan(
        big_map=big_map,
        to_map=to_map,
        pivot=n_frames // 2,
        time_s=time_s,
        ambient_c=ambient,
        housing_c=state.housing_c,
        fpa_true_c=state.fpa_c,
        fpa_rate_c_per_min=state.transient_rate_c_per_min,  # as the transient term sees it
        fpa_c=fpa_sensor(state.fpa_c, thermal, rng=rng),
        seed=seed,
    )


def _check_flight_numbers(n_frames: int, fps: float) -> None:
    if n_frames < 1:
        raise InvalidInputError(f"a flight needs at least 1 frame, got {n_frames}")
    if n_frames > MAX_DATA_FRAMES:
        raise InvalidInputError(
            f"a flight of {n_frames} frames is more than thermocal makes in one run "
            f"({MAX_DATA_FRAMES:.3g}); use fewer frames")
    if not (math.isfinite(fps) and fps > 0):  # NaN refused too
        raise InvalidInputError(f"frame rate must be > 0 and finite, got {fps}")


#: Frames rendered at once (fewer for very large frames: :func:`frames_per_chunk`).
CHUNK_FRAMES = 64


def check_flight_run(
    n_frames: int,
    frame_shape: tuple[int, int],
    *,
    motion: str = "walk",
    fps: float = 30.0,
    folder: str | os.PathLike[str] | None = None,
) -> None:
    """Check, before any work, that a flight of ``n_frames`` frames of ``frame_shape``
    ``(H, W)`` is a sane amount of data that fits the memory and ``folder``'s free disk (raw
    counts and the float32 truth: 6 bytes a pixel; :func:`thermocal._validate.check_data_size`).

    Raises
    ------
    InvalidInputError
        If not, or if ``n_frames`` or ``fps`` is out of range.
    """
    _check_flight_numbers(n_frames, fps)
    h, w = frame_shape
    map_h, map_w = map_shape_for(motion, n_frames, (w, h))
    chunk = frames_per_chunk(frame_shape, CHUNK_FRAMES)
    memory = working_memory(frame_shape, n_frames, chunk, extra_bytes=8.0 * map_h * map_w)
    check_data_size(n_frames, frame_shape, "the flight", bytes_per_pixel=6.0, folder=folder,
                    memory_bytes=memory)


def iter_flight(plan: FlightPlan, camera: CameraModel, *, chunk: int | None = None
                ) -> Iterator[FlightChunk]:
    """Render the flight ``chunk`` frames at a time (bounded memory for long recordings; default
    :data:`CHUNK_FRAMES`, fewer for very large frames). The frames do not depend on ``chunk``."""
    if chunk is None:
        chunk = frames_per_chunk(camera.shape, CHUNK_FRAMES)
    rng = np.random.default_rng([plan.seed, 1])
    h, w = camera.shape
    n = len(plan.time_s)
    for start in range(0, n, chunk):
        s = slice(start, min(start + chunk, n))
        truth = render_views(plan.big_map, plan.to_map[s], (w, h))
        frames = render(
            camera,
            truth,
            plan.fpa_true_c[s],
            housing_c=plan.housing_c[s],
            fpa_rate_c_per_min=plan.fpa_rate_c_per_min[s],
            rng=rng,
            time_s=plan.time_s[s] + WARMED_UP_S,
        )
        yield FlightChunk(
            start=start,
            frames=frames,
            truth_c=truth,
            time_s=plan.time_s[s],
            fpa_c=plan.fpa_c[s],
            fpa_true_c=plan.fpa_true_c[s],
            housing_c=plan.housing_c[s],
            ambient_c=plan.ambient_c[s],
        )


def simulate_flight(
    scene_c: np.ndarray,
    camera: CameraModel,
    *,
    n_frames: int = 7,
    motion: str = "walk",
    fpa_c: float = 30.0,
    fps: float = 30.0,
    seed: int = 0,
    thermal: ThermalParams | None = None,
) -> Flight:
    """Fly ``camera`` over ``scene_c`` and return the whole flight in memory (short flights).

    See :func:`plan_flight` for the parameters; :func:`write_simulated_flight` streams long ones.
    """
    plan = plan_flight(scene_c, camera, n_frames=n_frames, motion=motion, fpa_c=fpa_c, fps=fps,
                       seed=seed, thermal=thermal)
    chunks = list(iter_flight(plan, camera, chunk=max(1, n_frames)))
    return Flight(
        frames=np.concatenate([c.frames for c in chunks]),
        truth_c=np.concatenate([c.truth_c for c in chunks]),
        homographies=plan.homographies,
        to_map=plan.to_map,
        pivot=plan.pivot,
        time_s=plan.time_s,
        fpa_c=plan.fpa_c,
        fpa_true_c=plan.fpa_true_c,
        housing_c=plan.housing_c,
        ambient_c=plan.ambient_c,
    )


def write_simulated_flight(
    out_dir: str | Path,
    plan: FlightPlan,
    camera: CameraModel,
    *,
    extra: dict | None = None,
    chunk: int | None = None,
    progress: Callable[[int], None] | None = None,
) -> None:
    """Render a planned flight into ``out_dir`` chunk by chunk (the files of :func:`write_flight`).

    ``progress(k)`` is called after each chunk with the number of frames it added.
    """
    from thermocal.io.atomic import atomic_path, ensure_output_dir
    from thermocal.io.recording import RecordingWriter

    out = Path(out_dir)
    ensure_output_dir(out)
    meta = {"pivot": int(plan.pivot), "fpa_true_c": plan.fpa_true_c.tolist()}
    meta |= json.loads(json.dumps(extra or {}))
    with (
        RecordingWriter(out / "frames.tiff", extra=meta) as frames_out,
        atomic_path(out / "truth.tiff") as truth_tmp,
        tifffile.TiffWriter(truth_tmp, bigtiff=True) as truth_out,
    ):
        for part in iter_flight(plan, camera, chunk=chunk):
            frames_out.append(
                part.frames,
                fpa_c=part.fpa_c,
                time_s=part.time_s,
                housing_c=part.housing_c,
                ambient_c=part.ambient_c,
            )
            truth_out.write(part.truth_c, photometric="minisblack", contiguous=True,
                            metadata=None)
            if progress is not None:
                progress(len(part.frames))
    with atomic_path(out / "homographies.npy") as tmp:
        np.save(tmp, plan.homographies)


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
    write_temperature_tiff(out / "truth.tiff", flight.truth_c,
                           about={"quantity": "true scene temperature of each frame (simulated)"})
    with atomic_path(out / "homographies.npy") as tmp:
        np.save(tmp, flight.homographies)


def flat_field_corrected(camera: CameraModel, flight: Flight) -> np.ndarray:
    """A simulated flight's raw frames ``(N, H, W)`` as the camera gives them with its own
    flat-field correction on (a Tau2's FFC, done once before the first frame): less the
    deviation from its mean of a closed shutter at the housing temperature, rendered by
    ``camera`` at the first frame's FPA temperature (its fixed pattern and noise); uint16, a
    new array. A calibration fitted on raw frames does not apply to these."""
    shutter = render(camera, np.full((1, *camera.shape), float(flight.housing_c[0])),
                     flight.fpa_true_c[:1], housing_c=flight.housing_c[:1],
                     rng=np.random.default_rng(flight.frames.shape[0]))[0].astype(np.float64)
    corrected = flight.frames.astype(np.float64) - (shutter - shutter.mean())[None]
    return np.clip(np.round(corrected), 0, np.iinfo(np.uint16).max).astype(np.uint16)
