"""Simulated environmental-chamber sessions: a blackbody at set points while the ambient drifts.

The camera looks at a uniform blackbody (emissivity ≈ 0.98, reflecting the chamber's air) that
steps through its set points, ``frames_per_point`` frames at each; meanwhile the chamber's ambient
follows a profile and the camera's housing and FPA follow it with their lags. Every frame carries
the blackbody temperature, the FPA sensor reading, the true housing and ambient temperatures.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from thermocal._validate import (
    FPA_RANGE_C,
    MAX_DATA_FRAMES,
    as_temperature_c,
    check_data_size,
)
from thermocal.camera.model import CameraModel, render
from thermocal.camera.thermal import (
    WARMED_UP_S,
    ThermalParams,
    ambient_profile,
    fpa_sensor,
    profile_duration_s,
    thermal_response,
)
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError
from thermocal.radiometry import BandRadiance
from thermocal.simulate._memory import frames_per_chunk, working_memory

ORDERS = ("sweep", "sawtooth", "random")
#: The ``source`` attribute of a simulated chamber session (what ``simulate chamber`` may
#: replace: never a measured session).
SOURCE = "thermocal simulate chamber"


@dataclass(frozen=True)
class ChamberPlan:
    """What the chamber does: set points (°C), their order, the ambient profile and the timing.

    ``order``: ``sweep`` visits ``setpoints_c`` in their order (low → high, or high → low for
    a falling range) and starts again, ``sawtooth`` goes through them and back, ``random``
    visits them in a random order each cycle. ``duration_s`` defaults to one
    full cycle of the ambient profile.
    """

    setpoints_c: tuple[float, ...] = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
    frames_per_point: int = 5
    order: str = "sweep"
    profile: str = "steps"
    ambient_c: tuple[float, float] = (10.0, 40.0)
    rate_c_per_min: float = 0.5
    interval_s: float = 2.0
    duration_s: float | None = None
    emissivity: float = 0.98

    def __post_init__(self) -> None:
        if len(self.setpoints_c) < 1:
            raise InvalidInputError("the chamber plan needs at least one blackbody set point")
        as_temperature_c(list(self.setpoints_c), "blackbody set points")
        as_temperature_c(list(self.ambient_c), "ambient range")
        if self.frames_per_point < 1:
            raise InvalidInputError(f"frames per point must be >= 1, got {self.frames_per_point}")
        if self.order not in ORDERS:
            raise InvalidInputError(f"unknown set-point order {self.order!r}; use {ORDERS}")
        # `not x > 0`, not `x <= 0`: NaN is refused too
        if not (math.isfinite(self.interval_s) and self.interval_s > 0):
            raise InvalidInputError(f"frame interval must be > 0 s, got {self.interval_s}")
        if not (math.isfinite(self.rate_c_per_min) and self.rate_c_per_min > 0):
            raise InvalidInputError(f"ambient rate must be > 0 °C/min, got {self.rate_c_per_min}")
        if not 0.0 < self.emissivity <= 1.0:
            raise InvalidInputError(f"blackbody emissivity must be in (0, 1]: {self.emissivity}")
        if self.duration_s is not None and not (
            math.isfinite(self.duration_s) and self.duration_s > 0
        ):
            raise InvalidInputError(f"duration must be > 0 s, got {self.duration_s}")

    @property
    def n_frames(self) -> int:
        """Number of frames in the session.

        Raises :class:`InvalidInputError` beyond :data:`thermocal._validate.MAX_DATA_FRAMES`.
        """
        duration = self.duration_s
        if duration is None:
            low, high = self.ambient_c
            duration = profile_duration_s(
                self.profile, low_c=low, high_c=high, rate_c_per_min=self.rate_c_per_min
            )
        ratio = duration / self.interval_s
        if not ratio <= MAX_DATA_FRAMES:  # inf and NaN too
            raise InvalidInputError(
                f"the chamber session would have {ratio:.3g} frames (duration / interval "
                f"{duration:g} s / {self.interval_s:g} s), more than thermocal makes in one run "
                f"({MAX_DATA_FRAMES:.3g}); shorten the duration or lengthen the interval"
            )
        return max(1, int(round(ratio)))


#: Frames rendered at once (fewer for very large frames: :func:`frames_per_chunk`).
CHUNK_FRAMES = 128


def check_chamber_run(
    plan: ChamberPlan,
    frame_shape: tuple[int, int],
    *,
    thermal: ThermalParams | None = None,
    folder: str | os.PathLike[str] | None = None,
) -> None:
    """Check, before any work, that ``plan`` can be simulated for frames of ``frame_shape``
    ``(H, W)``: its blackbody set points lie within the simulator's radiance tables, the FPA
    temperatures its ambient range gives are plausible
    (:data:`thermocal._validate.FPA_RANGE_C`), its frames visit every set point, and the session
    is a sane amount of data that fits the memory and ``folder``'s free disk
    (:func:`thermocal._validate.check_data_size`).

    Raises
    ------
    InvalidInputError
        If not.
    """
    band = BandRadiance()  # the range of the simulator's radiance tables (any band's default)
    t_lo, t_hi = band.t_min_k - ZERO_CELSIUS_K, band.t_max_k - ZERO_CELSIUS_K
    points = plan.setpoints_c
    if min(points) < t_lo or max(points) > t_hi:
        raise InvalidInputError(
            f"blackbody set points: {min(points):g}…{max(points):g} °C go beyond the "
            f"{t_lo:g}…{t_hi:g} °C the camera simulator covers")
    thermal = thermal or ThermalParams()
    lo, hi = FPA_RANGE_C
    for ambient in plan.ambient_c:
        fpa = thermal.steady_fpa_c(ambient)
        if not lo + 0.5 <= fpa <= hi - 0.5:  # the sensor's noise stays inside
            raise InvalidInputError(
                f"ambient range: an ambient of {ambient:g} °C puts the FPA at {fpa:g} °C, "
                f"outside what a microbolometer core reports ({lo + 0.5:g}…{hi - 0.5:g} °C)"
            )
    n = plan.n_frames
    visits = -(-n // plan.frames_per_point)
    if visits < len(points):  # it exited 0 having visited the first alone (a helper's audit)
        raise InvalidInputError(
            f"--frames-per-point {plan.frames_per_point}: the session's {n} frames visit "
            f"{visits} of its {len(points)} set points; give at most "
            f"{max(n // len(points), 1)} frames per point, or a longer --duration-min")
    chunk = frames_per_chunk(frame_shape, CHUNK_FRAMES)
    check_data_size(n, frame_shape, "the chamber session", folder=folder,
                    memory_bytes=working_memory(frame_shape, n, chunk))


def blackbody_schedule(plan: ChamberPlan, *, rng: np.random.Generator) -> np.ndarray:
    """The blackbody set point of every frame, °C, ``(plan.n_frames,)``."""
    points = np.asarray(plan.setpoints_c, dtype=np.float64)
    n_blocks = -(-plan.n_frames // plan.frames_per_point)
    if plan.order == "sweep":
        idx = np.arange(n_blocks) % len(points)
    elif plan.order == "sawtooth":
        cycle = np.r_[np.arange(len(points)), np.arange(len(points) - 2, 0, -1)]
        idx = cycle[np.arange(n_blocks) % len(cycle)]
    else:
        n_cycles = -(-n_blocks // len(points))
        idx = np.concatenate([rng.permutation(len(points)) for _ in range(n_cycles)])[:n_blocks]
    return np.repeat(points[idx], plan.frames_per_point)[: plan.n_frames]


def radiance_temperature_c(
    body_c: np.ndarray, surround_c: np.ndarray, emissivity: float, band: BandRadiance
) -> np.ndarray:
    """Temperature (°C) of the black body as bright in the band as a grey body at ``body_c``.

    The grey body of emissivity ``emissivity`` also reflects its surround at ``surround_c``:
    ``L(T_eff) = ε·L(T_body) + (1 − ε)·L(T_surround)``.
    """
    body_k = np.asarray(body_c, dtype=np.float64) + ZERO_CELSIUS_K
    surround_k = np.asarray(surround_c, dtype=np.float64) + ZERO_CELSIUS_K
    radiance = emissivity * band.radiance(body_k) + (1.0 - emissivity) * band.radiance(surround_k)
    return band.temperature(radiance) - ZERO_CELSIUS_K


@dataclass(frozen=True)
class ChamberChunk:
    """A run of consecutive simulated chamber frames and their metadata (all ``(k,)`` series)."""

    frames: np.ndarray
    blackbody_c: np.ndarray
    fpa_c: np.ndarray
    fpa_true_c: np.ndarray
    fpa_rate_c_per_min: np.ndarray
    time_s: np.ndarray
    housing_c: np.ndarray
    ambient_c: np.ndarray


def simulate_chamber(
    camera: CameraModel,
    plan: ChamberPlan = ChamberPlan(),
    *,
    seed: int = 0,
    thermal: ThermalParams | None = None,
    chunk: int | None = None,
) -> Iterator[ChamberChunk]:
    """Yield the session in chunks of at most ``chunk`` frames (memory stays bounded; default
    :data:`CHUNK_FRAMES`, fewer for very large frames). The frames do not depend on ``chunk``.
    ``thermal``: the camera's lags (default its family's, ``camera.thermal``); the session
    starts :data:`~thermocal.camera.thermal.WARMED_UP_S` after switch-on."""
    thermal = thermal or camera.thermal
    if chunk is None:
        chunk = frames_per_chunk(camera.shape, CHUNK_FRAMES)
    rng = np.random.default_rng(seed)
    time_s = np.arange(plan.n_frames) * plan.interval_s
    low, high = plan.ambient_c
    ambient = ambient_profile(
        plan.profile, time_s, low_c=low, high_c=high, rate_c_per_min=plan.rate_c_per_min
    )
    state = thermal_response(time_s, ambient, thermal)
    sensor = fpa_sensor(state.fpa_c, thermal, rng=rng)
    blackbody = blackbody_schedule(plan, rng=rng)
    effective_c = radiance_temperature_c(blackbody, ambient, plan.emissivity, camera.band)
    for start in range(0, plan.n_frames, chunk):
        s = slice(start, min(start + chunk, plan.n_frames))
        frames = render(
            camera,
            effective_c[s],
            state.fpa_c[s],
            housing_c=state.housing_c[s],
            fpa_rate_c_per_min=state.transient_rate_c_per_min[s],
            rng=rng,
            time_s=time_s[s] + WARMED_UP_S,
        )
        yield ChamberChunk(
            frames=frames,
            blackbody_c=blackbody[s],
            fpa_c=sensor[s],
            fpa_true_c=state.fpa_c[s],
            fpa_rate_c_per_min=state.fpa_rate_c_per_min[s],
            time_s=time_s[s],
            housing_c=state.housing_c[s],
            ambient_c=ambient[s],
        )


def write_simulated_chamber(
    path: str | Path,
    camera: CameraModel,
    plan: ChamberPlan = ChamberPlan(),
    *,
    seed: int = 0,
    thermal: ThermalParams | None = None,
    progress: Callable[[int], None] | None = None,
) -> int:
    """Simulate a session and stream it into a chamber HDF5 file; returns the number of frames.

    The file is written atomically: a failure leaves no file behind. ``progress(k)`` is called
    after each chunk with the number of frames it added. The run is checked first
    (:func:`check_chamber_run`).
    """
    from thermocal.io.chamber import ChamberWriter

    thermal = thermal or camera.thermal
    check_chamber_run(plan, camera.shape, thermal=thermal, folder=Path(path).parent)

    attrs = {
        "source": SOURCE,
        "preset": camera.info.get("preset", ""),
        "unit": int(camera.info.get("unit", -1)),
        "seed": int(seed),
        "blackbody_emissivity": float(plan.emissivity),
        "plan": repr(asdict(plan)),
    }
    n = 0
    with ChamberWriter(path, camera.shape, attrs=attrs) as writer:
        for part in simulate_chamber(camera, plan, seed=seed, thermal=thermal):
            writer.append(
                part.frames,
                blackbody_c=part.blackbody_c,
                fpa_c=part.fpa_c,
                time_s=part.time_s,
                housing_c=part.housing_c,
                ambient_c=part.ambient_c,
            )
            n += len(part.frames)
            if progress is not None:
                progress(len(part.frames))
    return n
