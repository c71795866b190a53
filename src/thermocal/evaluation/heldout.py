"""The held-out evaluation set of the network benchmarks: fixed, seeded bursts of held-out
scenes flown over by held-out camera units, and the other unit's calibration that the
calibration-free baselines borrow (numpy only).

Each burst is a dict: ``scene``, ``unit``, ``fpa_c`` (the FPA temperature drawn, °C),
``motion`` (``walk`` / ``hover``), ``camera`` (its :class:`~thermocal.camera.model.CameraModel`),
``frames`` ``(N, H, W)`` counts, ``fpa_read`` ``(N,)`` °C (the sensor's reading), ``truth``
``(H, W)`` °C (the pivot's scene), ``hs`` ``(N, 3, 3)`` (the true homographies with the
registration error of Oz et al. §IV-D, or :func:`~thermocal.registration.register_burst`'s),
``pivot``, ``mask`` ``(H, W)`` bool (pixels seen by at least half the frames), ``fpa_true`` and
``housing`` ``(N,)`` °C.
"""

from __future__ import annotations

import numpy as np

from thermocal.calibration.two_point import fit_two_point
from thermocal.camera.model import render
from thermocal.camera.presets import make_camera
from thermocal.nn.data import EVAL_UNITS, coverage_mask, draw_pixel_fpn, evaluation_scenes
from thermocal.registration.burst import register_burst
from thermocal.registration.warp import warp_to_pivot
from thermocal.scenes.trajectory import perturb_homographies
from thermocal.simulate.flight import simulate_flight

__all__ = ["NOMINAL_FPA_C", "OTHER_UNIT", "eval_bursts", "other_unit_calibration",
           "two_point_of"]


NOMINAL_FPA_C = 30.0


OTHER_UNIT = 7  # the unit whose two-point calibration the calibration-free baselines borrow


def eval_bursts(n_frames: int, *, quick: bool, register: bool = False,
                units: tuple[int, ...] = EVAL_UNITS, preset="tau2",
                scenes: dict[str, np.ndarray] | None = None, per_scene: int | None = None,
                unit_per_burst: bool = False, camera=None):
    """The fixed evaluation bursts: list of dicts (frames, truth, valid mask, fpa, unit, …);
    ``units`` replaces the held-out camera units, ``preset`` (a name or a
    :class:`~thermocal.camera.presets.CameraPreset`) the camera family and ``scenes`` (name →
    °C map) the held-out scenes (diagnoses, and the validation bursts of
    :mod:`thermocal.evaluation.sigma_fit`).

    ``per_scene`` bursts of each scene (default 4, 1 with ``quick``); the units cycle over
    scenes, or with ``unit_per_burst`` each burst is of the next unit (as many units as
    bursts: a unit's own level, the largest part of a calibration-free error, is then sampled
    as a population, not a few draws repeated).

    ``camera`` (a :class:`~thermocal.camera.model.CameraModel`, e.g. fitted on a chamber file)
    replaces the units: every burst is of it, at its size, with a pixel FPN pattern of its own
    drawn as training draws it (:func:`~thermocal.nn.data.draw_pixel_fpn`), at FPA temperatures
    within the range it was fitted on (``info["fpa_range_c"]``); ``unit`` is None."""
    fpa_lo, fpa_hi = 15.0, 45.0
    if camera is not None and "fpa_range_c" in camera.info:  # 15-45 °C within it, or all of it
        lo, hi = (float(v) for v in camera.info["fpa_range_c"])
        inner = (max(lo, fpa_lo), min(hi, fpa_hi))
        fpa_lo, fpa_hi = inner if inner[0] < inner[1] else (lo, hi)
    scenes = evaluation_scenes() if scenes is None else scenes
    per_scene = (1 if quick else 4) if per_scene is None else per_scene
    # whole sensor frames: a network with position terms needs them
    size = (336, 256) if camera is None else (camera.shape[1], camera.shape[0])
    out = []
    for si, (name, scene) in enumerate(scenes.items()):
        for k in range(per_scene):
            seed = 1000 * si + k
            rng = np.random.default_rng([2026, seed])
            if camera is None:
                unit = units[(si * per_scene + k if unit_per_burst else si + k) % len(units)]
                cam = make_camera(preset, unit=unit, size=size)
            else:
                unit, cam = None, draw_pixel_fpn(camera, np.random.default_rng([2028, seed]))
            fpa = float(rng.uniform(fpa_lo, fpa_hi))
            motion = ("walk", "hover")[(si + k) % 2]
            fl = simulate_flight(scene, cam, n_frames=n_frames, motion=motion, fpa_c=fpa, seed=seed)
            hs = perturb_homographies(fl.homographies, rng=rng, frame_size=size, pivot=fl.pivot)
            if register:
                hs = register_burst(fl.frames, pivot=fl.pivot).homographies
            _, valid = warp_to_pivot(fl.frames, hs)
            out.append(
                {
                    "scene": name,
                    "unit": unit,
                    "fpa_c": fpa,
                    "motion": motion,
                    "camera": cam,
                    "frames": fl.frames,
                    "fpa_read": fl.fpa_c,
                    "truth": fl.truth_c[fl.pivot],
                    "hs": hs,
                    "pivot": fl.pivot,
                    "mask": coverage_mask(valid),
                    "fpa_true": fl.fpa_true_c,
                    "housing": fl.housing_c,
                }
            )
    return out


def two_point_of(cam, fpa_c: float, housing_c: float, seed: int):
    """A two-point calibration of camera ``cam`` at ``fpa_c`` (blackbody at 10 and 50 °C, 16
    frames each, seeded)."""
    rng = np.random.default_rng(seed)
    lo = render(cam, np.full(16, 10.0), fpa_c, housing_c=housing_c, rng=rng)
    hi = render(cam, np.full(16, 50.0), fpa_c, housing_c=housing_c, rng=rng)
    return fit_two_point(lo, hi, 10.0, 50.0, fpa_ref_c=fpa_c)


def other_unit_calibration():
    """The two-point calibration of :data:`OTHER_UNIT` at :data:`NOMINAL_FPA_C` that the
    calibration-free baselines borrow (a whole 336×256 sensor, as every burst)."""
    other = make_camera("tau2", unit=OTHER_UNIT, size=(336, 256))
    return two_point_of(other, NOMINAL_FPA_C, NOMINAL_FPA_C - 1.5, 5)
