"""Whole-pass evaluation: simulated UAV passes of held-out camera units over held-out real scenes,
processed by ``thermocal flight`` with any registered method and scored map by map.

A pass (:class:`PassSpec`) is a camera unit of a family flown over one scene (UAV motion, a
constant FPA temperature), written as ``thermocal simulate flight`` writes it (``frames.tiff`` +
``frames.json``, ``truth.tiff``: the true scene of every frame, °C, ``homographies.npy``). Each
method (:class:`PassMethod`: an estimator of :data:`~thermocal.estimation.registry.ESTIMATORS`
by name, with its calibration file or a recipe that makes one for the pass's unit) runs through
:func:`thermocal.pipeline.flight.process_flight` (groups of ``frames`` frames every ``stride``
frames, as the product does), and each pivot's map is scored against the truth of its pivot
frame (:func:`map_scores`) over the unit's good pixels (dead and hot pixels left out):

* ``mae_c``: mean absolute error, °C;
* ``bias_c``: the map's mean error, °C (the unit's level, mostly);
* ``bias_free_mae_c``: the MAE once the map's mean error is removed;
* ``affine_free_mae_c``: the MAE after the map's best affine map (Oz et al., Fig. 9's measure);
* ``column_bands_c``, ``row_bands_c``: the SD of the error's column (row) means
  (:func:`~thermocal.metrics.column_bands`);
* ``column_fine_c``, ``row_fine_c``: the same of the profile less its Gaussian of
  :data:`DETREND_PX` lines: stripes only, without smooth trends across the frame.

Over a whole pass, :func:`score_flight` also splits the error into the part fixed in the sensor
(each map's error less its mean, averaged over the maps) and the rest (:data:`FIXED_SCORES`): the
most a flight-level pattern estimate could remove. A pass's figure is the mean over its maps
(:func:`summarise_maps`), a method's over passes the mean of the passes'
(:func:`summarise_passes`). A flight-level method (``selfcal``) slots in as
another :class:`PassMethod` once it is registered.

Run: ``python benchmarks/passes.py [--units 9] [--scenes builtin:aerial] [--frames 301]`` (or
``python -m thermocal.evaluation.passes``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal import metrics
from thermocal.errors import InvalidInputError

__all__ = [
    "DETREND_PX",
    "FIXED_SCORES",
    "PassMethod",
    "PassSpec",
    "SCORES",
    "SIGMA_SCORES",
    "default_methods",
    "evaluate_pass",
    "load_pass_scene",
    "main",
    "map_scores",
    "other_unit_two_point",
    "one_reference_disc",
    "own_polynomial",
    "report",
    "score_flight",
    "sigma_scores",
    "simulate_pass",
    "summarise_maps",
    "summarise_passes",
]

#: σ, columns (rows), of the Gaussian trend removed from the error's column (row) profile for the
#: ``*_fine_c`` scores: what is left is stripes a few pixels wide.
DETREND_PX = 6.0

#: The scores of one map (keys of :func:`map_scores`), °C.
SCORES = ("mae_c", "bias_c", "bias_free_mae_c", "affine_free_mae_c", "column_bands_c",
          "row_bands_c", "column_fine_c", "row_fine_c")


@dataclass(frozen=True)
class PassSpec:
    """One simulated UAV pass.

    Attributes
    ----------
    scene : str
        A held-out scene's name (:data:`thermocal.nn.data.EVAL_SCENES`, e.g. ``builtin:aerial``).
    unit : int
        The camera unit of ``preset`` (100–104 are the network benchmark's held-out units).
    n_frames : int
        Frames of the pass (default 301: 43 groups of 7).
    size : tuple of int
        Frame size ``(W, H)``, px (default 336×256, the network's training size).
    fpa_c : float
        The FPA temperature the camera settled at, °C.
    seed : int
        The flight's seed (path, noise).
    preset : str
        The camera family.
    ambient_rate_c_per_min : float
        How fast the ambient changes from the first frame on, °C/min (0: the FPA stays at
        ``fpa_c``; else it drifts through the camera's lags).
    crab_deg : float
        The pass's crab angle, degrees (0: the ground moves along the rows).
    """

    scene: str
    unit: int
    n_frames: int = 301
    size: tuple[int, int] = (336, 256)
    fpa_c: float = 30.0
    seed: int = 0
    preset: str = "tau2"
    ambient_rate_c_per_min: float = 0.0
    crab_deg: float = 0.0

    def label(self) -> str:
        """``tau2 unit 9 over builtin:aerial`` (the size and frames are the table's)."""
        return f"{self.preset} unit {self.unit} over {self.scene}"


#: A calibration for a pass: a file, or a recipe ``(spec, workdir) → file`` that makes one for the
#: pass's unit (:func:`own_polynomial`, :func:`other_unit_two_point`).
CalibrationSource = str | os.PathLike[str] | Callable[[PassSpec, Path], Path] | None


@dataclass(frozen=True)
class PassMethod:
    """A method as ``thermocal flight`` runs it.

    Attributes
    ----------
    label : str
        Its row's name.
    method : str
        An estimator name of :data:`~thermocal.estimation.registry.ESTIMATORS`.
    calibration : str, os.PathLike, callable or None
        A calibration file, or a recipe ``(spec, workdir) → path`` for the pass's unit; for the
        methods that need one (``mean``, ``calibration``).
    model : str, optional
        A network weights file (default: the shipped one).
    force : bool
        ``--force``: estimate groups outside the estimator's domain rather than fail them.
    references : callable, optional
        A recipe ``(spec, pass folder) → REF.csv`` of ground references (``--reference``), e.g.
        :func:`one_reference_disc`.
    """

    label: str
    method: str
    calibration: CalibrationSource = None
    model: str | None = None
    force: bool = False
    references: Callable[[PassSpec, Path], Path] | None = None


# ------------------------------------------------------------------------------------------------
# data
# ------------------------------------------------------------------------------------------------


def load_pass_scene(name: str) -> np.ndarray:
    """A held-out scene by name, °C map ``(H, W)``: ``builtin:NAME`` or a shared scene.

    Raises
    ------
    InvalidInputError
        If the scene is not one of :data:`~thermocal.nn.data.EVAL_SCENES` or cannot be found
        (the shared scenes live in ``shared/data``).
    """
    from thermocal.nn.data import EVAL_SCENES
    from thermocal.scenes.builtin import load_builtin_scene
    from thermocal.scenes.real import list_shared_scenes, load_scene

    if name not in EVAL_SCENES:
        raise InvalidInputError(f"scene {name!r} is not held out; choose from "
                                f"{', '.join(EVAL_SCENES)}")
    if name.startswith("builtin:"):
        return load_builtin_scene(name.split(":", 1)[1])
    shared = list_shared_scenes()
    if name not in shared:
        raise InvalidInputError(f"scene {name!r} not found in shared/data")
    return load_scene(shared[name])


def simulate_pass(spec: PassSpec, folder: str | os.PathLike[str], *,
                  scene_c: np.ndarray | None = None) -> Path:
    """Write the pass ``spec`` into ``folder`` (the files of ``thermocal simulate flight
    --motion uav``); ``scene_c`` (°C map) replaces the named scene. Returns the recording's
    path (``folder/frames.tiff``)."""
    from thermocal.camera.presets import make_camera
    from thermocal.simulate.flight import plan_flight, write_simulated_flight

    scene = load_pass_scene(spec.scene) if scene_c is None else scene_c
    camera = make_camera(spec.preset, unit=spec.unit, size=spec.size)
    plan = plan_flight(scene, camera, n_frames=spec.n_frames, motion="uav", fpa_c=spec.fpa_c,
                       seed=spec.seed, ambient_rate_c_per_min=spec.ambient_rate_c_per_min,
                       crab_deg=spec.crab_deg)
    extra = {"scene": spec.scene, "unit": spec.unit, "preset": spec.preset, "seed": spec.seed,
             "motion": "uav"}
    write_simulated_flight(folder, plan, camera, extra=extra)
    return Path(folder) / "frames.tiff"


def own_polynomial(spec: PassSpec, workdir: Path) -> Path:
    """The pass's unit's own per-pixel polynomial calibration (FPA-dependent, on radiance),
    fitted on a simulated chamber session of that unit (blackbody 0–60 °C, ambient 15–35 °C, as
    ``thermocal demo``'s); made once per unit and size in ``workdir``."""
    from thermocal.calibration.report import fit_with_report
    from thermocal.camera.presets import make_camera
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber

    w, h = spec.size
    path = workdir / f"polynomial_{spec.preset}_{spec.unit}_{w}x{h}.h5"
    if path.exists():
        return path
    camera = make_camera(spec.preset, unit=spec.unit, size=spec.size)
    plan = ChamberPlan(setpoints_c=(0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.25,
                       interval_s=20.0)
    session = workdir / f"chamber_{spec.preset}_{spec.unit}_{w}x{h}.h5"
    write_simulated_chamber(session, camera, plan, seed=spec.unit)
    cal, _ = fit_with_report(session, "polynomial", scene="radiance", frames="settled")
    session.unlink()
    cal.save(path)
    return path


def other_unit_two_point(spec: PassSpec, workdir: Path) -> Path:
    """Another unit's two-point calibration (:data:`~thermocal.evaluation.heldout.OTHER_UNIT`,
    blackbody 10 and 50 °C at FPA :data:`~thermocal.evaluation.heldout.NOMINAL_FPA_C`), as the
    calibration-free baselines of the network benchmark borrow it; made once per size."""
    from thermocal.camera.presets import make_camera
    from thermocal.evaluation.heldout import NOMINAL_FPA_C, OTHER_UNIT, two_point_of

    w, h = spec.size
    path = workdir / f"two_point_{spec.preset}_{OTHER_UNIT}_{w}x{h}.h5"
    if not path.exists():
        other = make_camera(spec.preset, unit=OTHER_UNIT, size=spec.size)
        two_point_of(other, NOMINAL_FPA_C, NOMINAL_FPA_C - 1.5, 5).save(path)
    return path


#: The simulated ground reference: its disc's radius (px) and the σ of its thermometer (°C).
REFERENCE_RADIUS_PX = 6.0
REFERENCE_SIGMA_C = 0.1


def one_reference_disc(spec: PassSpec, folder: Path, *, sigma_c: float = REFERENCE_SIGMA_C
                       ) -> Path:
    """One ground reference in one frame (``REF.csv`` in ``folder``): a disc of
    :data:`REFERENCE_RADIUS_PX` px in the pass's middle frame where the true scene is most
    uniform (a water body, a panel) within the frame's middle half (where one aims at it), its
    temperature the truth's mean over the disc plus a thermometer's error drawn with σ
    ``sigma_c`` (°C, > 0; default :data:`REFERENCE_SIGMA_C`; seeded by the pass), the σ the file
    states."""
    import tifffile
    from scipy.ndimage import uniform_filter

    from thermocal.pipeline.references import Reference

    with tifffile.TiffFile(folder / "truth.tiff") as tif:
        k = len(tif.pages) // 2
        truth = tif.pages[k].asarray().astype(np.float64)
    size = int(2 * REFERENCE_RADIUS_PX + 1)
    var = uniform_filter(truth**2, size) - uniform_filter(truth, size) ** 2
    h, w = truth.shape  # the target in the frame's middle half, as one aims at it
    var[: h // 4], var[-h // 4 :], var[:, : w // 4], var[:, -w // 4 :] = (np.inf,) * 4
    y, x = np.unravel_index(int(np.argmin(var)), var.shape)
    disc = Reference(0, k, float(x), float(y), REFERENCE_RADIUS_PX, 0.0).disc(truth.shape)
    error = np.random.default_rng(spec.seed).normal(0.0, sigma_c)
    path = folder / "REF.csv"
    path.write_text("frame,x,y,radius_px,temperature_c,sigma_c\n"
                    f"{k},{x},{y},{REFERENCE_RADIUS_PX:g},{truth[disc].mean() + error:.3f},"
                    f"{sigma_c:g}\n", encoding="utf-8")
    return path


def default_methods() -> list[PassMethod]:
    """The shipped network, and the classical ``mean`` with another unit's two-point
    (calibration-free, as the network; run with ``--force``: a fit in hand without a
    cross-validation report, which a flight cannot check) and with the unit's own polynomial (a
    reference, run with ``--force``: the held-out scenes reach below its chamber session's
    coldest blackbody)."""
    return [
        PassMethod("kpn (calibration-free)", "kpn"),
        PassMethod("mean + other unit's two-point", "mean", other_unit_two_point, force=True),
        PassMethod("mean + own polynomial (reference)", "mean", own_polynomial, force=True),
    ]


# ------------------------------------------------------------------------------------------------
# scores
# ------------------------------------------------------------------------------------------------


def map_scores(estimate: np.ndarray, truth: np.ndarray, *, valid: np.ndarray | None = None
               ) -> dict[str, float]:
    """The scores (:data:`SCORES`, °C) of one map ``estimate (H, W)`` °C against ``truth
    (H, W)`` °C over the pixels of ``valid (H, W) bool`` (all when None)."""
    err = np.asarray(estimate, np.float64) - np.asarray(truth, np.float64)
    bias = float(err.mean() if valid is None else err[valid].mean())
    kw = {"valid": valid}
    return {
        "mae_c": metrics.mae(estimate, truth, **kw),
        "bias_c": bias,
        "bias_free_mae_c": metrics.bias_free_mae(estimate, truth, **kw),
        "affine_free_mae_c": metrics.affine_free_mae(estimate, truth, **kw),
        "column_bands_c": metrics.column_bands(estimate, truth, **kw),
        "row_bands_c": metrics.row_bands(estimate, truth, **kw),
        "column_fine_c": metrics.column_bands(estimate, truth, detrend_px=DETREND_PX, **kw),
        "row_fine_c": metrics.row_bands(estimate, truth, detrend_px=DETREND_PX, **kw),
    }


def _pairs(out: Path, truth_path: Path, frames: Sequence[int]):
    """``(frame, estimate, truth)`` of each of ``frames``: the flight's map and the truth TIFF's
    page (one page a frame), °C ``(H, W)``, read one at a time (long passes)."""
    import tifffile

    from thermocal.io.recording import read_temperature_tiff

    with tifffile.TiffFile(truth_path) as tif:
        n = len(tif.pages)
        for k in frames:
            if not 0 <= k < n:
                raise InvalidInputError(f"{truth_path}: no frame {k} (it has {n})")
            est = read_temperature_tiff(out / "temps" / f"frame_{k:06d}.tiff")
            yield k, est, tif.pages[k].asarray()


#: The stated σ's scores of a map (where the flight wrote its σ map): the fractions of its
#: pixels' errors within 1σ and 2σ, and its median σ (°C).
SIGMA_SCORES = ("within_1sigma", "within_2sigma", "median_sigma_c")


def sigma_scores(estimate: np.ndarray, truth: np.ndarray, sigma: np.ndarray, *,
                 valid: np.ndarray | None = None) -> dict[str, float]:
    """:data:`SIGMA_SCORES` of a map, its truth and its σ map (°C, ``(H, W)``) over ``valid``."""
    err = np.abs(np.asarray(estimate, np.float64) - truth)
    sig = np.asarray(sigma, np.float64)
    if valid is not None:
        err, sig = err[valid], sig[valid]
    return {"within_1sigma": float(np.mean(err <= sig)),
            "within_2sigma": float(np.mean(err <= 2 * sig)),
            "median_sigma_c": float(np.median(sig))}


#: The scores of the part of a pass's error that is fixed in the sensor (:func:`score_flight`).
FIXED_SCORES = ("fixed_sd_c", "fixed_column_bands_c", "fixed_row_bands_c",
                "moving_bias_free_mae_c", "moving_column_bands_c", "moving_row_bands_c")


def score_flight(out_dir: str | os.PathLike[str], truth_path: str | os.PathLike[str], *,
                 valid: np.ndarray | None = None) -> dict[str, Any]:
    """Score the maps a processed flight wrote in ``out_dir`` (its ``log.jsonl`` and
    ``temps/frame_NNNNNN.tiff``) against the truth of their pivot frames (``truth_path``: the
    pass's ``truth.tiff``), over ``valid (H, W) bool``; and split the pass's error into the part
    fixed in the sensor and the rest.

    The fixed part is the mean over the maps of each map's error less its mean, ``F (H, W)``: what
    stays in the same pixels while the scene moves (the camera's residual pattern), the most a
    flight-level pattern estimate could remove. It is measured with the truth, in-sample: a
    ceiling, not a method.

    Returns
    -------
    dict
        ``maps``: one dict per scored pivot (``frame`` and :func:`map_scores`); ``failed``: the
        pivots the flight logged an error for, with the error; ``fixed`` (None with fewer than 2
        maps): :data:`FIXED_SCORES`, °C: the SD of ``F``, the column and row bands of ``F``,
        and the bias-free MAE and the column and row bands of the maps once ``F`` is removed
        (means over the maps).
    """
    from thermocal.pipeline.flight_log import read_log

    out, truth_file = Path(out_dir), Path(truth_path)
    entries = read_log(out / "log.jsonl")
    done = [e["frame"] for e in entries if "error" not in e]
    failed = [{"frame": e["frame"], "error": str(e["error"])} for e in entries if "error" in e]
    maps = []
    total = None
    for pivot, est, tru in _pairs(out, truth_file, done):
        scores = map_scores(est, tru, valid=valid)
        sigma_path = out / "temps" / f"frame_{pivot:06d}_sigma.tiff"
        if sigma_path.is_file():
            from thermocal.io.recording import read_temperature_tiff

            scores |= sigma_scores(est, tru, read_temperature_tiff(sigma_path), valid=valid)
        maps.append({"frame": pivot, **scores})
        part = np.asarray(est, np.float64) - tru - scores["bias_c"]
        total = part if total is None else total + part
    fixed = None
    if len(maps) >= 2:
        pattern = total / len(maps)
        zero = np.zeros_like(pattern)
        moving: dict[str, list[float]] = {"mae": [], "cols": [], "rows": []}
        for _, est, tru in _pairs(out, truth_file, done):
            err = np.asarray(est, np.float64) - tru - pattern
            moving["mae"].append(metrics.bias_free_mae(err, zero, valid=valid))
            moving["cols"].append(metrics.column_bands(err, zero, valid=valid))
            moving["rows"].append(metrics.row_bands(err, zero, valid=valid))
        kept = pattern if valid is None else pattern[valid]
        fixed = {"fixed_sd_c": float(np.std(kept)),
                 "fixed_column_bands_c": metrics.column_bands(pattern, zero, valid=valid),
                 "fixed_row_bands_c": metrics.row_bands(pattern, zero, valid=valid),
                 "moving_bias_free_mae_c": float(np.mean(moving["mae"])),
                 "moving_column_bands_c": float(np.mean(moving["cols"])),
                 "moving_row_bands_c": float(np.mean(moving["rows"]))}
    return {"maps": maps, "failed": failed, "fixed": fixed}


def summarise_maps(maps: Sequence[dict[str, Any]]) -> dict[str, float]:
    """A pass's figures: the mean over its maps of each score (:data:`SCORES`), the mean
    absolute bias ``mean_abs_bias_c`` and the number of maps; NaN scores when there is none."""
    out: dict[str, float] = {"maps": len(maps)}
    for key in (*SCORES, *SIGMA_SCORES):
        values = [m[key] for m in maps if key in m]
        out[key] = float(np.mean(values)) if values else float("nan")
    out["mean_abs_bias_c"] = (float(np.mean([abs(m["bias_c"]) for m in maps])) if maps
                              else float("nan"))
    return out


def summarise_passes(results: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per method over the passes ``results`` (of :func:`evaluate_pass`): the mean of
    the passes' figures, and the smallest and largest pass MAE; passes where a method scored no
    map are counted, not averaged."""
    rows: dict[str, dict[str, Any]] = {}
    for res in results:
        unit = (res.get("pass") or {}).get("unit")
        for label, r in res["methods"].items():
            rows.setdefault(label, {"method": label, "passes": [], "empty": 0, "units": []})
            if r["summary"]["maps"]:
                rows[label]["passes"].append(r["summary"])
                rows[label]["units"].append(unit)
            else:
                rows[label]["empty"] += 1
    out = []
    for label, row in rows.items():
        passes = row["passes"]
        entry: dict[str, Any] = {"method": label, "passes": len(passes),
                                 "passes_without_maps": row["empty"],
                                 "maps": int(sum(p["maps"] for p in passes))}
        for key in (*SCORES, "mean_abs_bias_c", *FIXED_SCORES, *SIGMA_SCORES):
            values = [p.get(key, float("nan")) for p in passes]
            entry[key] = float(np.mean(values)) if values else float("nan")
        maes = [p["mae_c"] for p in passes]
        entry["pass_mae_range_c"] = [min(maes), max(maes)] if maes else None
        for key in ("within_1sigma", "within_2sigma"):
            entry[f"{key}_interval"] = _interval_over_units(
                [p.get(key, float("nan")) for p in passes], row["units"])
        out.append(entry)
    return out


def _interval_over_units(values: Sequence[float], units: Sequence[Any]) -> list[float] | None:
    """A 90 % bootstrap interval (scipy's percentile) of the mean of ``values`` (one per pass)
    over the passes' units, resampled whole: a unit's level is one draw shared by all its passes
    (its coverage over a few units says little). None with fewer than two units or no values."""
    from scipy import stats

    by_unit: dict[Any, list[float]] = {}
    for v, u in zip(values, units, strict=True):
        if np.isfinite(v) and u is not None:
            by_unit.setdefault(u, []).append(float(v))
    means = np.array([np.mean(v) for v in by_unit.values()])
    if means.size < 2 or np.ptp(means) == 0:
        return None
    ci = stats.bootstrap((means,), np.mean, confidence_level=0.90, method="percentile",
                         n_resamples=2000, rng=np.random.default_rng(0)).confidence_interval
    return [float(ci.low), float(ci.high)]


# ------------------------------------------------------------------------------------------------
# running
# ------------------------------------------------------------------------------------------------


def _slug(label: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", label).strip("_") or "method"


def evaluate_pass(spec: PassSpec, methods: Sequence[PassMethod], workdir: str | os.PathLike[str],
                  *, frames: int = 7, stride: int = 7, scene_c: np.ndarray | None = None,
                  keep: bool = False) -> dict[str, Any]:
    """Simulate the pass ``spec`` in ``workdir``, run every method of ``methods`` over it through
    ``thermocal flight`` (groups of ``frames`` every ``stride`` frames) and score its maps.

    ``scene_c`` (°C map) replaces the named scene (tests); ``keep`` keeps the recording and the
    maps in ``workdir`` (default: removed once scored; calibrations made by a recipe are kept
    for the next pass of the same unit).

    Returns
    -------
    dict
        ``pass`` (the spec as a dict), ``simulate_s``, and ``methods``: label → ``summary``
        (:func:`summarise_maps` and the fixed part's :data:`FIXED_SCORES` of
        :func:`score_flight`, NaN with fewer than 2 maps), ``maps`` (per pivot), ``failed``
        (pivots and errors), ``flight_s`` (the flight's wall time) and ``calibration`` (the file
        used, if any).
    """
    from thermocal.camera.presets import make_camera
    from thermocal.pipeline.flight import FlightOptions, process_flight

    work = Path(workdir)
    work.mkdir(parents=True, exist_ok=True)
    folder = work / f"pass_{_slug(spec.label())}_{spec.seed}"
    started = time.perf_counter()
    recording = simulate_pass(spec, folder, scene_c=scene_c)
    simulate_s = time.perf_counter() - started
    valid = ~make_camera(spec.preset, unit=spec.unit, size=spec.size).defects
    result: dict[str, Any] = {"pass": asdict(spec), "simulate_s": simulate_s, "methods": {}}
    try:
        for m in methods:
            cal = m.calibration(spec, work) if callable(m.calibration) else m.calibration
            refs = None if m.references is None else str(m.references(spec, folder))
            options = FlightOptions(method=m.method, calibration=None if cal is None else str(cal),
                                    model=m.model, frames=frames, stride=stride, preview_every=0,
                                    force=m.force, references=refs,
                                    # the family's average unit: where selfcal starts from
                                    family=spec.preset if m.method == "selfcal" else "tau2")
            out = folder / f"out_{_slug(m.label)}"
            t = time.perf_counter()
            process_flight(recording, out, options)
            flight_s = time.perf_counter() - t
            scored = score_flight(out, folder / "truth.tiff", valid=valid)
            result["methods"][m.label] = {
                "method": m.method, "calibration": None if cal is None else str(cal),
                "summary": summarise_maps(scored["maps"]) | (scored["fixed"] or dict.fromkeys(
                    FIXED_SCORES, float("nan"))), "maps": scored["maps"],
                "failed": scored["failed"], "flight_s": flight_s}
            if not keep:
                shutil.rmtree(out, ignore_errors=True)
    finally:
        if not keep:
            shutil.rmtree(folder, ignore_errors=True)
    return result


# ------------------------------------------------------------------------------------------------
# the benchmark
# ------------------------------------------------------------------------------------------------


def _f(x: float) -> str:
    return "–" if x != x else f"{x:.2f}"  # NaN: no map


def _pct(x: float) -> str:
    return "–" if x != x else f"{100 * x:.1f} %"  # NaN: no σ


def report(results: Sequence[dict[str, Any]], *, info: dict[str, Any]) -> str:
    """The Markdown report: one row per pass and method, and the means over passes."""
    header = ("pass", "method", "maps", "failed", "MAE °C", "mean abs bias °C", "bias-free MAE °C",
              "affine-free MAE °C", "column bands °C", "row bands °C", "column fine °C",
              "row fine °C", "flight s")
    cells = []
    for res in results:
        spec = PassSpec(**{**res["pass"], "size": tuple(res["pass"]["size"])})
        for label, r in res["methods"].items():
            s = r["summary"]
            cells.append((f"unit {spec.unit}, {spec.scene}, FPA {spec.fpa_c:g} °C", label,
                          s["maps"], len(r["failed"]), _f(s["mae_c"]), _f(s["mean_abs_bias_c"]),
                          _f(s["bias_free_mae_c"]), _f(s["affine_free_mae_c"]),
                          _f(s["column_bands_c"]), _f(s["row_bands_c"]), _f(s["column_fine_c"]),
                          _f(s["row_fine_c"]), f"{r['flight_s']:.0f}"))
    from thermocal.evaluation.tables import markdown_table

    per_pass = markdown_table(header, cells)
    mean_header = ("method", "passes", "maps", "MAE °C (pass range)", "mean abs bias °C",
                   "bias-free MAE °C", "affine-free MAE °C", "column bands °C", "row bands °C",
                   "column fine °C", "row fine °C")
    mean_cells = []
    for row in summarise_passes(results):
        rng = row["pass_mae_range_c"]
        span = f" ({rng[0]:.2f}–{rng[1]:.2f})" if rng else ""
        mean_cells.append((row["method"], row["passes"], row["maps"], _f(row["mae_c"]) + span,
                           _f(row["mean_abs_bias_c"]), _f(row["bias_free_mae_c"]),
                           _f(row["affine_free_mae_c"]), _f(row["column_bands_c"]),
                           _f(row["row_bands_c"]), _f(row["column_fine_c"]),
                           _f(row["row_fine_c"])))
    means = markdown_table(mean_header, mean_cells)
    def share(row: dict[str, Any], key: str) -> str:
        ci = row.get(f"{key}_interval")
        return _pct(row[key]) + ("" if ci is None else
                                 f" ({100 * ci[0]:.0f}–{100 * ci[1]:.0f})")

    sigma_cells = [(row["method"], row["maps"], share(row, "within_1sigma"),
                    share(row, "within_2sigma"), _f(row["median_sigma_c"]))
                   for row in summarise_passes(results)]
    sigma_table = markdown_table(("method", "maps", "within 1σ", "within 2σ", "median σ °C"),
                                 sigma_cells)
    fixed_header = ("pass", "method", "fixed part SD °C", "its column bands °C",
                    "its row bands °C", "without it: bias-free MAE °C", "column bands °C",
                    "row bands °C")
    fixed_cells = [(f"unit {res['pass']['unit']}, {res['pass']['scene']}", label,
                    *(_f(r["summary"][k]) for k in FIXED_SCORES))
                   for res in results for label, r in res["methods"].items()]
    fixed_cells += [("mean over the passes", row["method"], *(_f(row[k]) for k in FIXED_SCORES))
                    for row in summarise_passes(results)]
    fixed = markdown_table(fixed_header, fixed_cells)
    failures = sorted({f"{label}: {r['failed'][0]['error']}"
                       for res in results for label, r in res["methods"].items() if r["failed"]})
    failed = ("\n\nThe first error of each pass with failed groups, by method:\n\n"
              + "\n".join(f"- {f}" for f in failures)) if failures else ""
    return (f"## Whole UAV passes, map by map\n\nmachine: {info['machine']}; load average "
            f"{info['load_before']} before, {info['load_after']} after; {info['wall_s']:.0f} s\n\n"
            f"command: `{info['command']}`\n\n"
            f"data: {info['data']}\n\n### Per pass\n\n{per_pass}\n\n"
            f"### Means over the passes\n\n{means}{failed}\n\n"
            "### The stated σ\n\nPixels whose error lies within the map's σ and 2σ "
            f"(targets 68 ± 5 % and 95 ± 3 %), mean over the maps; in brackets a 90 % "
            "bootstrap interval over the camera units (a unit's level is one draw shared by "
            f"all its maps):\n\n{sigma_table}\n\n"
            "### The part of the error fixed in the sensor\n\nEach map's error less its mean, "
            "averaged over the pass's maps (measured with the truth, in-sample: the most a "
            "flight-level pattern estimate could remove), and what is left of the maps' error "
            f"without it.\n\n{fixed}\n")


def _methods_by_name(names: Sequence[str], *, force: bool,
                     reference_sigma_c: float = REFERENCE_SIGMA_C) -> list[PassMethod]:
    import functools

    one_reference_disc_ = functools.partial(one_reference_disc, sigma_c=reference_sigma_c)
    table = {"kpn": PassMethod("kpn (calibration-free)", "kpn", force=force),
             "mean-other": PassMethod("mean + other unit's two-point", "mean",
                                      other_unit_two_point, force=True),  # no report
             "mean-own": PassMethod("mean + own polynomial (reference)", "mean", own_polynomial,
                                    force=True),
             "calibration-own": PassMethod("calibration (pivot alone) + own polynomial",
                                           "calibration", own_polynomial, force=True),
             "selfcal": PassMethod("selfcal (calibration-free)", "selfcal", force=force),
             "selfcal-ref": PassMethod("selfcal + one reference disc", "selfcal", force=force,
                                       references=one_reference_disc_),
             "selfcal-own": PassMethod("selfcal from own polynomial", "selfcal", own_polynomial,
                                       force=True),
             "selfcal-own-ref": PassMethod("selfcal from own polynomial + one reference disc",
                                           "selfcal", own_polynomial, force=True,
                                           references=one_reference_disc_)}
    unknown = [n for n in names if n not in table]
    if unknown:
        raise InvalidInputError(f"unknown method {unknown[0]!r}; choose from {', '.join(table)}")
    return [table[n] for n in names]


def main(argv: list[str] | None = None) -> None:
    """The ``passes`` benchmark: every unit of ``--units`` over every scene of ``--scenes``."""
    import sys

    from thermocal._validate import parse_size
    from thermocal.bench import machine

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", default="9", help="Camera units, comma separated.")
    parser.add_argument("--scenes", default="builtin:aerial",
                        help="Held-out scenes, comma separated, or 'all'.")
    parser.add_argument("--frames", type=int, default=301, help="Frames per pass.")
    parser.add_argument("--size", default="336x256", help="Frame size WxH.")
    parser.add_argument("--fpa-c", type=float, default=30.0, help="FPA temperature, °C.")
    parser.add_argument("--methods", default="kpn,mean-other,mean-own",
                        help="kpn, mean-other, mean-own, calibration-own, selfcal, selfcal-ref, "
                        "selfcal-own, selfcal-own-ref (comma separated).")
    parser.add_argument("--preset", default="tau2", help="Camera family of the units.")
    parser.add_argument("--ambient-rate", type=float, default=0.0,
                        help="Ambient change from the first frame on, °C/min (FPA drift).")
    parser.add_argument("--crab-deg", type=float, default=0.0,
                        help="Crab angle of the passes, degrees (0: the ground moves along the "
                        "rows; a crosswind yaws the airframe a few degrees).")
    parser.add_argument("--reference-sigma-c", type=float, default=REFERENCE_SIGMA_C,
                        help="σ of the simulated reference thermometer, °C (> 0).")
    parser.add_argument("--group", type=int, default=7, help="Frames per group (N).")
    parser.add_argument("--stride", type=int, default=7)
    parser.add_argument("--force", action="store_true", help="--force for every method.")
    parser.add_argument("--json", type=Path, default=None, help="Write the results here.")
    parser.add_argument("--markdown", type=Path, default=None, help="Write the report here.")
    args = parser.parse_args(argv)

    from thermocal.nn.data import EVAL_SCENES

    scenes = list(EVAL_SCENES) if args.scenes == "all" else args.scenes.split(",")
    units = [int(u) for u in args.units.split(",")]
    size = parse_size(args.size)
    if not (math.isfinite(args.reference_sigma_c) and args.reference_sigma_c > 0):
        raise SystemExit("--reference-sigma-c must be a number above 0")
    methods = _methods_by_name(args.methods.split(","), force=args.force,
                               reference_sigma_c=args.reference_sigma_c)
    load_before = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    started = time.perf_counter()
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes:
            for unit in units:
                # the seed by the scene's place among the held-out ones: a pass is the same
                # whatever else the command runs
                seed = 1000 * (EVAL_SCENES.index(scene) if scene in EVAL_SCENES else 0) + unit
                spec = PassSpec(scene=scene, unit=unit, n_frames=args.frames, size=size,
                                fpa_c=args.fpa_c, seed=seed, preset=args.preset,
                                ambient_rate_c_per_min=args.ambient_rate,
                                crab_deg=args.crab_deg)
                res = evaluate_pass(spec, methods, tmp, frames=args.group, stride=args.stride)
                results.append(res)
                for label, r in res["methods"].items():
                    s = r["summary"]
                    print(f"{spec.label()}: {label}: MAE {s['mae_c']:.3f}, bias-free "
                          f"{s['bias_free_mae_c']:.3f}, column bands {s['column_bands_c']:.3f}, "
                          f"{s['maps']} maps, {len(r['failed'])} failed, {r['flight_s']:.0f} s",
                          flush=True)
    w, h = size
    info = {"machine": machine(), "wall_s": time.perf_counter() - started,
            "load_before": load_before,
            "load_after": ", ".join(f"{x:.1f}" for x in os.getloadavg()),
            "command": "python benchmarks/passes.py " + " ".join(sys.argv[1:] if argv is None
                                                                 else argv),
            "data": ("UAV passes (motion `uav`, 3.8 px per frame"
                     + (f", crab angle {args.crab_deg:g}°" if args.crab_deg else "")
                     + f") of {args.frames} frames of "
                     f"{w}×{h}, FPA {args.fpa_c:g} °C"
                     + (f" then the ambient changing {args.ambient_rate:+g} °C/min"
                        if args.ambient_rate else "") + f", {args.preset} units "
                     f"{', '.join(map(str, units))} "
                     f"over {', '.join(scenes)} (seed 1000 × the scene's index in "
                     f"EVAL_SCENES + the unit); groups of N = {args.group} every {args.stride} "
                     "frames through `thermocal flight` (process_flight); each pivot map scored "
                     "against its frame's truth over the unit's good pixels (dead and hot "
                     f"pixels left out); 'fine': the line profile less its Gaussian of "
                     f"{DETREND_PX:g} lines"
                     + (f"; reference thermometer σ {args.reference_sigma_c:g} °C"
                        if any(m.references is not None for m in methods) else ""))}
    text = report(results, info=info)
    print(text)
    if args.markdown:
        args.markdown.write_text(text, encoding="utf-8")
    if args.json:
        args.json.write_text(json.dumps({"info": info, "results": results}, indent=1),
                             encoding="utf-8")


if __name__ == "__main__":
    main()
