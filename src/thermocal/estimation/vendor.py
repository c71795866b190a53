"""The camera's own calibration (``--method camera``): the temperatures the vendor's software
gives, from the Planck constants a FLIR file carries (numpy only).

Each frame's raw counts go through the FLIR formula
(:meth:`thermocal.radiometry.FlirPlanck.raw_to_temperature_c`) with that frame's constants,
emissivity, reflected temperature, atmosphere and window, as read by
:func:`thermocal.io.open_recording` (R-JPEG, FFF, SEQ, CSQ). It is the baseline a
thermographer compares with, and the check of the readers against the camera.

Its uncertainty is the vendor's stated accuracy, taken as 2σ (a data sheet's "±2 °C or ±2 %"
bounds most readings, not one in three): ±2 °C or 2 % of the reading, whichever is larger, for
FLIR's own cameras (T, A, E series); ±5 °C or 5 % for radiometric Tau2 cores, as in the DJI
Zenmuse XT, XT2 and XT-R and FLIR's Duo Pro R and Vue Pro R (their data sheets, high-gain
mode). The camera is told by the names its file gives (:data:`~thermocal.io.fff.CORE_CAMERAS`).
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np

from thermocal._validate import clipped_mask
from thermocal.burst import clipped_parts
from thermocal.calibration.base import ThermocalWarning, fill_bad_pixels
from thermocal.errors import InvalidInputError
from thermocal.estimation.base import PreparedBurst
from thermocal.io.fff import CORE_CAMERAS, TAU2_CAMERAS, flir_bit_depth, names_core
from thermocal.io.recording import Recording
from thermocal.radiometry import FlirPlanck

__all__ = ["CORE_CAMERAS", "MAX_UNDEFINED_FRACTION", "SATURATED_SIGMA_C", "TAU2_CAMERAS",
           "VendorCalibration", "vendor_accuracy"]

#: Pixels of a frame whose counts its constants give no temperature (below the count of a
#: blackbody at 0 K: dead pixels) filled from their neighbours, at most this fraction of them.
MAX_UNDEFINED_FRACTION = 0.001


#: σ of a saturated pixel forced through (°C): its count says only that it is hotter than the
#: top count's temperature, by an amount no file states; the width of a Tau2's high-gain range.
SATURATED_SIGMA_C = 160.0


def _clipped_parts(frame: np.ndarray, bit_depth: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`~thermocal.burst.clipped_parts` of a frame ``(H, W)`` of a sensor of
    ``bit_depth`` (its file's names), 16 where the frame's counts exceed it (not the sensor its
    file names)."""
    if frame.size and int(frame.max()) > 2**bit_depth - 1:
        bit_depth = 16
    return clipped_parts(clipped_mask(frame, bit_depth))


def _converted(planck: FlirPlanck, frame: np.ndarray, bit_depth: int) -> np.ndarray:
    """One frame ``(H, W)`` through ``planck``, °C float32 (see ``VendorCalibration.calibrate``);
    ``bit_depth``: its sensor's, whose top count is where it saturates."""
    raw = frame.astype(np.float64)
    # a clipped defect says nothing of the scene (a saturated Tau2 pixel, 16,383, read 125 °C
    # with σ 3 where the scene was 32-39 °C): filled; a saturated object (a larger group) is
    # converted as it is, a lower bound, and outside (:meth:`VendorCalibration.outside`)
    isolated, clusters = _clipped_parts(frame, bit_depth)
    undefined = ~((raw > planck.raw_min) & (raw < planck.raw_max)) & ~isolated & ~clusters
    if undefined.mean() > MAX_UNDEFINED_FRACTION:
        raise InvalidInputError(
            f"{int(undefined.sum())} pixel(s) ({100 * undefined.mean():.2g} %) of a frame have "
            "counts its file's Planck constants give no temperature (more than "
            f"{100 * MAX_UNDEFINED_FRACTION:g} % are not dead pixels): a damaged frame, or "
            "constants that are not this camera's")
    bad = isolated | undefined
    unconvertible = clusters & ~((raw > planck.raw_min) & (raw < planck.raw_max))
    if unconvertible.any():  # a dead area at 0, or a top beyond what the constants reach
        raise InvalidInputError(
            f"{int(unconvertible.sum())} clipped pixel(s) of a frame, in groups, have counts its "
            "file's constants give no temperature: a dead or blinded area of the sensor")
    if not bad.any():
        return np.asarray(planck.raw_to_temperature_c(raw), np.float32)
    if bad.all():
        raise InvalidInputError("every pixel of a frame is dead or saturated")
    warnings.warn(f"{int(bad.sum())} pixel(s) of a frame dead or saturated alone (counts at 0 "
                  "or at the sensor's top) or with counts the file's constants give no "
                  "temperature: filled from their neighbours", ThermocalWarning, stacklevel=2)
    raw[bad] = np.median(raw[~bad])
    temps = np.asarray(planck.raw_to_temperature_c(raw), np.float32)[None]
    return fill_bad_pixels(temps, bad)[0]


def _saturated(frames: np.ndarray, k: int, bit_depth: int) -> np.ndarray:
    """The saturated objects (clipped groups larger than a defect) of frame ``k`` of raw
    ``frames`` ``(N, H, W)``, ``(H, W)`` bool."""
    return _clipped_parts(np.asarray(frames[k]), bit_depth)[1]


def vendor_accuracy(metadata: dict[str, Any]) -> tuple[float, float]:
    """The stated accuracy of the camera a frame's metadata names: ``(°C, fraction of the
    reading)``, whichever is larger bounds the error (see the module docstring)."""
    return (5.0, 0.05) if names_core(metadata) else (2.0, 0.02)


class VendorCalibration:
    """``--method camera``: each frame through its own FLIR Planck constants.

    Parameters
    ----------
    plancks : list of FlirPlanck
        One per frame of the recording.
    accuracy : list of (float, float)
        Each frame's stated accuracy (:func:`vendor_accuracy`).
    ranges : list of (float, float) or None, optional
        Each frame's measuring range, °C, as its file states it (``temperature_range_c``; None:
        not stated): the stated accuracy holds within it. A burst whose scene (its 1st–99th
        percentile) lies beyond it is outside; beyond it σ grows by the distance.
    bit_depths : list of int, optional
        Each frame's sensor bit depth (:func:`~thermocal.io.fff.flir_bit_depth`; default 16),
        whose top count is where it saturates: a pixel or two there, or at 0, are filled from
        their neighbours; a larger group is a saturated object, outside.
    """

    name = "camera"
    n_frames = None
    needs_fpa = False
    per_frame = True
    accepts_registered = True
    remedy = ("the file's own calibration does not vouch for these temperatures: calibrate the "
              "camera over them (`thermocal calibrate`); --force gives them with σ grown by "
              "their distance beyond the range")
    fpa_paces: dict = {}  # the file's constants: no chamber session's paces

    def __init__(self, plancks: list[FlirPlanck], accuracy: list[tuple[float, float]],
                 ranges: list[tuple[float, float] | None] | None = None,
                 bit_depths: list[int] | None = None) -> None:
        self.plancks = plancks
        self.accuracy = accuracy
        self.ranges = list(ranges) if ranges is not None else [None] * len(plancks)
        self.bit_depths = list(bit_depths) if bit_depths is not None else [16] * len(plancks)

    @classmethod
    def from_recording(cls, recording: Recording, path: Any = "the recording"
                       ) -> VendorCalibration:
        """From the per-frame metadata :func:`thermocal.io.open_recording` reads
        (``extra["frame_metadata"]``); refused for a recording without Planck constants."""
        metas = (recording.extra or {}).get("frame_metadata") or []
        if len(metas) != recording.frames.shape[0]:
            metas = []
        return cls.from_metadata(metas, path)

    @classmethod
    def from_metadata(cls, metas: list[dict[str, Any]], path: Any = "the recording"
                      ) -> VendorCalibration:
        """From one metadata dict per frame (each with its ``planck``); refused otherwise."""
        from thermocal.io.fff import planck_from_metadata

        if not metas or not all(m.get("planck") for m in metas):
            raise InvalidInputError(
                f"{path}: --method camera needs the camera's Planck constants in every frame, "
                "which only FLIR files carry (R-JPEG, FFF, SEQ, CSQ); use a calibration "
                "(--method calibration --calibration CAL.h5) or the network"
            )
        # the reader states a range only where it is plausible (io.fff._measuring_range)
        return cls([planck_from_metadata(m) for m in metas], [vendor_accuracy(m) for m in metas],
                   [tuple(m["temperature_range_c"]) if m.get("temperature_range_c") else None
                    for m in metas],
                   [flir_bit_depth(m) for m in metas])

    def for_frames(self, start: int, n: int) -> VendorCalibration:
        """The same for frames ``start … start + n − 1`` of the recording (a flight's group)."""
        return VendorCalibration(self.plancks[start : start + n], self.accuracy[start : start + n],
                                 self.ranges[start : start + n],
                                 self.bit_depths[start : start + n])

    def check(self, frames: np.ndarray, *, registered: bool, homographies: Any) -> None:
        if frames.shape[0] != len(self.plancks):
            raise InvalidInputError(
                f"--method camera: {frames.shape[0]} frames but the file's constants are for "
                f"{len(self.plancks)}"
            )

    def calibrate(self, frames: np.ndarray, fpa_c: Any, time_s: Any, *,
                  pace: Any = None) -> np.ndarray:
        """Each frame through its constants; a few pixels whose counts the constants give no
        temperature (dead pixels, at most :data:`MAX_UNDEFINED_FRACTION` of a frame), and
        clipped ones alone or in pairs, are filled from their neighbours with a warning; more
        are refused by the formula; larger clipped groups are converted as they are (a lower
        bound: :meth:`outside`)."""
        return np.stack([_converted(p, f, bits) for p, f, bits
                         in zip(self.plancks, frames, self.bit_depths, strict=True)])

    def outside(self, calibrated: np.ndarray, fpa_c: float | None, *,
                pace: Any = None, burst: PreparedBurst | None = None) -> tuple[str, ...]:
        """Where the pivot's scene (its 1st–99th percentile, °C) lies beyond the measuring
        range its file states (a corrupted DJI file read −104…651 °C with σ of a few degrees:
        a helper's audit); counts the formula cannot convert are refused by it
        (:meth:`~thermocal.radiometry.FlirPlanck.raw_to_temperature_c`)."""
        k = 0 if burst is None else burst.pivot
        saturated = (np.zeros(0, bool) if burst is None
                     else _saturated(burst.frames, k, self.bit_depths[k]))
        why = (f"{int(saturated.sum())} pixel(s) saturated in groups (a scene beyond the "
               "sensor's range: their count says only that they are hotter than its top)",
               ) if saturated.any() else ()
        stated = self.ranges[k]
        frames = np.asarray(calibrated)
        frame = frames[k if frames.shape[0] > 1 else 0] if frames.ndim == 3 else frames  # the
        # pipeline gives a per-frame estimator's pivot alone
        if stated is None or not np.size(frame):
            return why
        p1, p99 = (float(v) for v in np.percentile(frame, [1, 99]))
        if stated[0] <= p1 and p99 <= stated[1]:
            return why
        return why + (f"the scene reads {p1:.1f}…{p99:.1f} °C, beyond the camera's measuring "
                      f"range {stated[0]:g}…{stated[1]:g} °C (its file's), where its stated "
                      "accuracy holds",)

    def estimate(self, burst: PreparedBurst) -> np.ndarray:
        return np.asarray(burst.warped[burst.pivot], dtype=np.float32)

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> np.ndarray:
        """The vendor's stated accuracy as 2σ: ``max(a, r·|T|) / 2`` (°C, :func:`vendor_accuracy`
        of the pivot frame's camera); beyond the measuring range its file states, grown by the
        distance outside it (the accuracy is stated within it alone)."""
        absolute, relative = self.accuracy[burst.pivot]
        t = temperature_c.astype(np.float64)
        sigma = 0.5 * np.maximum(absolute, relative * np.abs(t))
        stated = self.ranges[burst.pivot]
        if stated is not None:
            beyond = np.maximum(stated[0] - t, 0.0) + np.maximum(t - stated[1], 0.0)
            if beyond.any():
                warnings.warn(
                    f"{int(np.count_nonzero(beyond))} pixel(s) read {float(t.min()):.0f}…"
                    f"{float(t.max()):.0f} °C, beyond the camera's measuring range "
                    f"{stated[0]:g}…{stated[1]:g} °C: their σ grows by the distance",
                    ThermocalWarning, stacklevel=2)
            sigma += beyond
        if outside:  # forced: a saturated object's pixels are only a lower bound
            saturated = _saturated(burst.frames, burst.pivot, self.bit_depths[burst.pivot])
            sigma[saturated] = np.hypot(sigma[saturated], SATURATED_SIGMA_C)
        return sigma.astype(np.float32)
