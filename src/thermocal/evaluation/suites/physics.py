"""Cross-physics benchmark: every method fitted or trained on one camera family, run on both.

Issue 18, item 4: every calibration and estimation method fitted or trained on one camera family,
evaluated on the other family and on its own.

The two families of :data:`thermocal.camera.presets.PRESETS` differ in the *form* of six parts of
the physics: ``tau2`` has a cubic response in the FPA temperature, a flat 7.5-13.5 µm band, column
FPN with a radial offset, radial housing emission with a first-order lag, white noise and a
``C·dT/dt`` transient; ``boson`` an exponential response, a sloped 8-14 µm band, row FPN with a
smooth offset field, a one-sided housing gradient with a second-order optics lag, row noise, 1/f
noise and a warm-up drift, and a lagged transient. Every method was designed and tuned on ``tau2``.

1. **Calibrations** (every method of :data:`thermocal.calibration.CALIBRATION_METHODS`): unit 101
   of each family (no network was trained on it), a 96×72 px crop (``--quick``: 48×36). Each
   method is fitted on its family's chamber session, the protocol of
   :mod:`~thermocal.evaluation.suites.calibration` (ambient steps 5→40 °C with 20-min plateaus,
   then a 1.5 °C/min sawtooth; blackbody 5…75 °C, ε = 0.98), with its default options except the
   reference FPA temperature of the methods that take one: the settled FPA reading of the 25 °C
   plateau, for both families (the default, the first frame's, sits at the cold end of the range).
   A method that refuses the session is skipped with its reason. Each calibration is then applied
   to a held-out run of its own unit and to the same run of the other family's unit 101 (what a
   calibration of another camera gives). The held-out run is another seed, blackbody at 10…70 °C,
   ambient a slow ramp 5→40 °C at 0.25 °C/min held 30 min at the top, then (an hour later, a
   separate recording) a 5↔40 °C sawtooth at 1 °C/min; the shutter closes every 180 s (used by
   ``shutter``). Score: the MAE against the blackbody's radiance-equivalent temperature in the
   camera's own band, over the non-defective pixels, on the frames inside the calibration's FPA
   range, i.e. those its :class:`~thermocal.calibration.OutsideCalibrationRangeWarning` does not
   flag (the fitted range ± 0.5 °C). The table also gives the fraction it flagged, the MAE of
   each part, of the stable frames (FPA rate within ±0.05 °C/min) and of every frame.
2. **The network**: the shipped ``kpn`` (trained on tau2 units 0-23 only) on the held-out bursts
   of :func:`~thermocal.evaluation.heldout.eval_bursts` (N = 7, units 100-104) made by each
   family, beside the kpn suite's references (:func:`~thermocal.evaluation.network.run_methods`:
   fitted on tau2) and the same references fitted on boson (boson unit 7's two-point calibration,
   the average boson unit). There are no boson-trained weights: "not trained".
3. **The table for README**: rows are methods; columns are fitted on tau2 → evaluated on tau2,
   tau2 → boson, boson → boson and boson → tau2 (MAE °C).
4. **Other lags**: ``polynomial``, ``lin-level`` and ``lin-lag`` on cameras whose optics and
   transient lag by time constants unlike either preset's (:data:`LAG_VARIANTS`; ``lin-lag``'s
   lag basis was chosen on the presets).

Run: ``python -m thermocal.evaluation.suites.physics [--quick] [--json OUT.json]`` (or
``python benchmarks/physics.py``).
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from thermocal.bench import machine
from thermocal.calibration import (
    CALIBRATION_METHODS,
    OutsideCalibrationRangeWarning,
    fit_calibration,
    prepare_chamber,
)
from thermocal.camera.model import CameraModel, render
from thermocal.camera.presets import PRESETS, make_camera
from thermocal.camera.thermal import WARMED_UP_S, thermal_response
from thermocal.errors import ThermocalError
from thermocal.evaluation.suites.calibration import HELD_OUT, SETPOINTS
from thermocal.io.chamber import ChamberSession
from thermocal.simulate.chamber import ChamberPlan, radiance_temperature_c, simulate_chamber

#: The camera families, in table order.
FAMILIES = tuple(PRESETS)

#: The camera unit of each family the calibrations are fitted on and evaluated on.
UNIT = 101

#: Crop ``(W, H)`` of the calibration part; ``--quick``.
SIZE = (96, 72)
QUICK_SIZE = (48, 36)

SESSION_SEED = 100
HELD_OUT_SEED = 500
SHUTTER_INTERVAL_S = 180.0

#: How long the held-out ramp holds its top ambient (40 °C), s.
HOLD_S = 1800.0

#: The ambient plateau whose settled FPA reading is the reference of the methods taking one, °C.
PLATEAU_AMBIENT_C = 25.0

#: How far outside its fitted FPA range a calibration applies without warning, °C (as
#: :func:`thermocal.calibration.base.warn_outside_range`).
RANGE_MARGIN_C = 0.5

#: The held-out run's parts, by name (one chamber recording each).
PARTS = ("slow ramp", "fast sawtooth")


# ------------------------------------------------------------------------------- chamber runs


@dataclass
class Run:
    """A simulated chamber run of one camera: the session, its truth and what goes with it.

    ``truth_c`` ``(M,)``: the blackbody's radiance-equivalent temperature in the camera's band;
    ``part`` ``(M,)``: which chamber plan (recording) made each frame; ``shutter``: per part,
    the closed-shutter frames with their FPA reading and time (empty without a shutter).
    """

    camera: CameraModel
    session: ChamberSession
    truth_c: np.ndarray
    part: np.ndarray
    shutter: list[dict] = field(default_factory=list)

    @property
    def family(self) -> str:
        return str(self.session.attrs["preset"])


_SERIES = ("frames", "blackbody_c", "fpa_c", "time_s", "housing_c", "ambient_c", "fpa_true_c")


def shutter_closures(camera: CameraModel, run: dict, interval_s: float, seed: int) -> dict:
    """Closed-shutter frames every ``interval_s`` of one chamber recording ``run`` (its series,
    times from its start): the shutter sits inside the housing, at the temperature of what
    radiates onto the FPA; the camera's own thermal state is recomputed from the ambient."""
    t = run["time_s"]
    state = thermal_response(t, run["ambient_c"], camera.thermal)
    if not np.allclose(state.fpa_c, run["fpa_true_c"]):
        raise RuntimeError("the recomputed thermal state does not match the chamber's")
    idx = np.unique(np.searchsorted(t, np.arange(0.0, t[-1], interval_s)))
    frames = render(camera, state.housing_c[idx], state.fpa_c[idx],
                    housing_c=state.housing_c[idx],
                    fpa_rate_c_per_min=state.transient_rate_c_per_min[idx],
                    rng=np.random.default_rng(seed), time_s=t[idx] + WARMED_UP_S)
    return {"frames": frames, "fpa_c": run["fpa_c"][idx], "time_s": t[idx]}


def simulate_run(camera: CameraModel, plans: list[ChamberPlan], seed: int, *,
                 shutter_interval_s: float | None = None) -> Run:
    """One session from chamber plans run one after another (1 h apart), recorded with the
    camera's family (``attrs["preset"]``) and unit; with ``shutter_interval_s``, the shutter
    closures of each."""
    runs, shutters, t0 = [], [], 0.0
    for i, plan in enumerate(plans):
        chunks = list(simulate_chamber(camera, plan, seed=seed + i))
        run = {k: np.concatenate([getattr(c, k) for c in chunks]) for k in _SERIES}
        if shutter_interval_s:
            shut = shutter_closures(camera, run, shutter_interval_s, seed + 1000 + i)
            shutters.append(shut | {"time_s": shut["time_s"] + t0})
        run["time_s"] = run["time_s"] + t0
        run["part"] = np.full(run["fpa_c"].size, i)
        t0 = float(run["time_s"][-1]) + 3600.0
        runs.append(run)
    cat = {k: np.concatenate([r[k] for r in runs]) for k in runs[0]}
    cat.pop("fpa_true_c")
    part = cat.pop("part")
    truth = radiance_temperature_c(cat["blackbody_c"], cat["ambient_c"], plans[0].emissivity,
                                   camera.band)
    attrs = {"blackbody_emissivity": plans[0].emissivity, "unit": int(camera.info["unit"]),
             "preset": str(camera.info["preset"]), "seed": int(seed)}
    session = ChamberSession(cat.pop("frames"), **cat, attrs=attrs)
    return Run(camera, session, truth, part, shutters)


def calibration_session(camera: CameraModel, seed: int, quick: bool) -> Run:
    """The calibration suite's protocol: ambient steps 5→40 °C (20-min plateaus), then a
    1.5 °C/min 5↔40 °C sawtooth; blackbody 5…75 °C, 3 frames per set point."""
    steps = ChamberPlan(setpoints_c=SETPOINTS, frames_per_point=3, profile="steps",
                        ambient_c=(5.0, 40.0), interval_s=20.0 if quick else 10.0)
    fast = ChamberPlan(setpoints_c=SETPOINTS, frames_per_point=3, profile="sawtooth",
                       ambient_c=(5.0, 40.0), rate_c_per_min=1.5, interval_s=5.0 if quick else 2.0)
    return simulate_run(camera, [steps, fast], seed)


def held_out_run(camera: CameraModel, seed: int, quick: bool) -> Run:
    """The held-out run: blackbody at 10…70 °C (2 frames per set point), ambient a 0.25 °C/min
    ramp 5→40 °C then held for :data:`HOLD_S` (the camera settles), and a separate 1 °C/min
    5↔40 °C sawtooth; the shutter closed every :data:`SHUTTER_INTERVAL_S`."""
    slow = ChamberPlan(setpoints_c=HELD_OUT, frames_per_point=2, profile="ramp",
                       ambient_c=(5.0, 40.0), rate_c_per_min=0.25,
                       interval_s=30.0 if quick else 10.0,
                       duration_s=60.0 * 35.0 / 0.25 + HOLD_S)
    fast = ChamberPlan(setpoints_c=HELD_OUT, frames_per_point=2, profile="sawtooth",
                       ambient_c=(5.0, 40.0), rate_c_per_min=1.0,
                       interval_s=15.0 if quick else 5.0)
    return simulate_run(camera, [slow, fast], seed, shutter_interval_s=SHUTTER_INTERVAL_S)


def plateau_fpa_c(session: ChamberSession, ambient_c: float = PLATEAU_AMBIENT_C) -> float:
    """The settled FPA reading of the ambient plateau at ``ambient_c`` (the median over the
    plateau's second half), °C."""
    gaps = np.flatnonzero(np.diff(session.time_s) > 1800.0)  # between recordings
    end = int(gaps[0]) + 1 if gaps.size else session.n_frames  # the first one: the steps
    idx = np.flatnonzero(np.abs(session.ambient_c[:end] - ambient_c) < 1e-9)
    if idx.size < 2:
        raise ValueError(f"no ambient plateau at {ambient_c} °C")
    return float(np.median(session.fpa_c[idx[idx.size // 2 :]]))


# ------------------------------------------------------------------------------- calibrations


def fitted_fpa_range(cal) -> tuple[float, float] | None:
    """The FPA range, °C, a calibration was fitted on (None if it records none)."""
    rng = getattr(cal, "fpa_range", None) or getattr(cal, "fpa_range_c", None)
    return None if rng is None else (float(rng[0]), float(rng[1]))


def fit_methods(run: Run) -> dict:
    """Every calibration method fitted on ``run``'s session: ``{"fpa_ref_c", "cals": {name:
    calibration}, "refused": {name: reason}, "fit_s": {name: s}, "default_refused": {name:
    reason}}`` (the last: methods whose fit with the default reference FPA refuses)."""
    data = prepare_chamber(run.session)
    ref = plateau_fpa_c(run.session)
    out = {"fpa_ref_c": ref, "cals": {}, "refused": {}, "fit_s": {}, "default_refused": {}}
    for name, info in CALIBRATION_METHODS.items():
        options = {"fpa_ref_c": ref} if info.takes_fpa_ref else {}
        started = time.perf_counter()
        try:
            out["cals"][name] = fit_calibration(data, name, **options)
        except ThermocalError as exc:
            out["refused"][name] = f"{type(exc).__name__}: {exc}"
        out["fit_s"][name] = time.perf_counter() - started
        if info.takes_fpa_ref:
            try:
                fit_calibration(data, name)
            except ThermocalError as exc:
                out["default_refused"][name] = f"{type(exc).__name__}: {exc}"
    return out


def part_calibration(cal, run: Run, part: int):
    """``cal`` as it serves recording ``part`` of ``run``: a shutter calibration with that
    recording's closures, any other as it is."""
    if hasattr(cal, "with_shutter") and run.shutter:
        return cal.with_shutter(**run.shutter[part])
    return cal


def apply_run(cal, run: Run) -> tuple[np.ndarray, np.ndarray]:
    """``cal`` applied to each recording of ``run`` on its own (a stream from a cold start; with
    its shutter closures for a shutter calibration): the temperatures ``(M, H, W)`` °C and which
    frames it flagged outside its range ``(M,)`` bool (per recording: if it warned, the frames
    beyond its fitted range ± :data:`RANGE_MARGIN_C`)."""
    s = run.session
    frames = np.asarray(s.frames)
    est = np.empty(frames.shape, dtype=np.float32)
    flagged = np.zeros(s.n_frames, dtype=bool)
    rng = fitted_fpa_range(cal)
    for k in np.unique(run.part):
        sel = run.part == k
        c = part_calibration(cal, run, k)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", OutsideCalibrationRangeWarning)
            est[sel] = c.apply(frames[sel], fpa_c=s.fpa_c[sel], time_s=s.time_s[sel])
        warned = any(issubclass(w.category, OutsideCalibrationRangeWarning) for w in caught)
        for w in caught:  # anything else is shown as usual
            if not issubclass(w.category, OutsideCalibrationRangeWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        if warned and rng is not None:
            fpa = s.fpa_c[sel]
            flagged[sel] = (fpa < rng[0] - RANGE_MARGIN_C) | (fpa > rng[1] + RANGE_MARGIN_C)
    return est, flagged


def _mae(per_frame: np.ndarray, sel: np.ndarray) -> float | None:
    return float(per_frame[sel].mean()) if sel.any() else None


def score(cal, run: Run) -> dict:
    """``cal`` on the held-out ``run``: frames, frames scored (inside its range), the fraction
    flagged, MAE / bias / 99th percentile of the absolute error (°C) on the scored frames, the
    MAE of each part's scored frames, of the scored stable ones (FPA rate within ±0.05 °C/min,
    :func:`~thermocal.calibration.prepare_chamber`'s class) and of every frame (warnings
    ignored)."""
    est, flagged = apply_run(cal, run)
    good = ~run.camera.defects
    err = est[:, good] - run.truth_c[:, None]
    per_frame = np.abs(err).mean(axis=1)
    inside = ~flagged
    out = {
        "frames": int(run.session.n_frames),
        "scored_frames": int(inside.sum()),
        "flagged_fraction": float(flagged.mean()),
        "mae_c": _mae(per_frame, inside),
        "bias_c": float(err[inside].mean()) if inside.any() else None,
        "p99_abs_c": float(np.percentile(np.abs(err[inside]), 99)) if inside.any() else None,
        "mae_all_frames_c": float(per_frame.mean()),
        "non_finite": int((~np.isfinite(est)).sum()),
    }
    for k, name in enumerate(PARTS):
        sel = inside & (run.part == k)
        out[f"mae_{name.replace(' ', '_')}_c"] = _mae(per_frame, sel)
        out[f"scored_{name.replace(' ', '_')}"] = int(sel.sum())
    stable = inside & (prepare_chamber(run.session).stability == 0)
    out["mae_stable_c"] = _mae(per_frame, stable)
    out["scored_stable"] = int(stable.sum())
    return out


def run_summary(run: Run) -> dict:
    """Frames, FPA range and largest FPA rate of each part of a run."""
    data = prepare_chamber(run.session)
    parts = []
    for k, name in enumerate(PARTS[: int(run.part.max()) + 1]):
        sel = run.part == k
        parts.append({"part": name, "frames": int(sel.sum()),
                      "fpa_range_c": [float(run.session.fpa_c[sel].min()),
                                      float(run.session.fpa_c[sel].max())],
                      "max_fpa_rate_c_per_min": float(np.abs(data.fpa_rate_c_per_min[sel]).max())})
    return {"frames": int(run.session.n_frames), "parts": parts}


def bench_calibrations(quick: bool, *, size: tuple[int, int] | None = None,
                       unit: int = UNIT) -> dict:
    """Part 1: every calibration method fitted on each family's session and scored on each
    family's held-out run. ``size`` overrides the crop (tests)."""
    size = size or (QUICK_SIZE if quick else SIZE)
    cams = {f: make_camera(f, unit=unit, size=size) for f in FAMILIES}
    sessions = {f: calibration_session(cams[f], SESSION_SEED, quick) for f in FAMILIES}
    held = {f: held_out_run(cams[f], HELD_OUT_SEED, quick) for f in FAMILIES}
    fits = {f: fit_methods(sessions[f]) for f in FAMILIES}
    rows = []
    for name in CALIBRATION_METHODS:
        for fit_on in FAMILIES:
            fitted = fits[fit_on]
            for on in FAMILIES:
                row = {"method": name, "fitted_on": fit_on, "evaluated_on": on}
                if name in fitted["refused"]:
                    row["refused"] = fitted["refused"][name]
                else:
                    cal = fitted["cals"][name]
                    rng = fitted_fpa_range(cal)
                    row["fpa_range_c"] = None if rng is None else list(rng)
                    row |= score(cal, held[on])
                rows.append(row)
    return {
        "size": list(size), "unit": unit,
        "sessions": {f: run_summary(sessions[f]) for f in FAMILIES},
        "held_out": {f: run_summary(held[f]) for f in FAMILIES},
        "shutter_closures": {f: [len(s["fpa_c"]) for s in held[f].shutter] for f in FAMILIES},
        "fpa_ref_c": {f: fits[f]["fpa_ref_c"] for f in FAMILIES},
        "fit_s": {f: fits[f]["fit_s"] for f in FAMILIES},
        "refused": {f: fits[f]["refused"] for f in FAMILIES},
        "default_refused": {f: fits[f]["default_refused"] for f in FAMILIES},
        "bad_pixels": {f: {n: int(c.bad.sum()) for n, c in fits[f]["cals"].items()}
                       for f in FAMILIES},
        "rows": rows,
    }


# ------------------------------------------------------------------------------- the network

#: Display names of the kpn suite's rows (:mod:`thermocal.evaluation.references`), by its names.
OWN_TWO_POINT_ROW = "(reference) own two-point at the burst FPA (eq. 9 mean)"

#: The "fitted on" of a reference fitted on the burst's own unit.
OWN = "own unit"


#: Cameras whose optics and transient lag by other time constants than the presets' (which
#: ``lin-lag``'s lag basis was chosen on): family, what changes in its thermal parameters.
LAG_VARIANTS = (
    ("boson", {"tau_optics_s": 600.0, "transient_lag_s": 90.0, "tau_housing_s": 300.0}),
    ("boson", {"tau_optics_s": 120.0, "transient_lag_s": 20.0, "tau_housing_s": 120.0}),
    ("tau2", {"tau_optics_s": 300.0, "transient_lag_s": 60.0}),
)
#: The methods scored on :data:`LAG_VARIANTS`.
LAG_METHODS = ("polynomial", "lin-level", "lin-lag")


def bench_lag_variants(quick: bool) -> list[dict]:
    """Part 4: the rate-term methods on cameras whose lags differ from both presets' (unit 101,
    its own session and held-out run, as part 1): MAE °C over every frame of the held-out
    run, its slow ramp and its sawtooth."""
    from dataclasses import replace

    size = QUICK_SIZE if quick else SIZE
    out = []
    for family, change in LAG_VARIANTS:
        cam = make_camera(family, unit=UNIT, size=size)
        cam = replace(cam, thermal=replace(cam.thermal, **change))
        session = calibration_session(cam, SESSION_SEED, quick)
        held = held_out_run(cam, HELD_OUT_SEED, quick)
        ref = plateau_fpa_c(session.session)
        row = {"family": family, "thermal": change, "methods": {}}
        for name in LAG_METHODS:
            options = {"fpa_ref_c": ref} if CALIBRATION_METHODS[name].takes_fpa_ref else {}
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", OutsideCalibrationRangeWarning)
                est, _ = apply_run(fit_calibration(session.session, name, **options), held)
            err = np.abs(est[:, ~cam.defects] - held.truth_c[:, None]).mean(axis=1)
            row["methods"][name] = [float(err.mean())] + [float(err[held.part == k].mean())
                                                          for k in range(len(PARTS))]
        out.append(row)
    return out


def _row_names() -> dict[str, str]:
    from thermocal.evaluation.network import KPN_ROW
    from thermocal.evaluation.references import FAMILY_ROW, HYBRID_ROW

    return {
        KPN_ROW: "kpn: the shipped network (KPN + offset)",
        FAMILY_ROW: "(floor) exact model of the family's average unit 0-23 (eq. 9 mean)",
        "two-point, other unit, FPA 30 °C (pivot frame)":
            "estimator `calibration`: the pivot frame through another unit's (7) two-point at "
            "FPA 30 °C",
        "two-point, other unit, FPA 30 °C (eq. 9 mean)":
            "estimator `mean`: eq. 9 mean through another unit's (7) two-point at FPA 30 °C",
        "hardie2000 NUC + global fit (other unit)":
            "hardie2000 NUC + global fit (another unit's two-point)",
        HYBRID_ROW: "(classical) the family model's eq. 9 mean, low-pass σ = 6 px, + hardie2000 "
                    "NUC's high-pass",
        OWN_TWO_POINT_ROW: "(reference) estimator `mean` through the unit's own two-point at the "
                           "burst FPA",
    }


def burst_summary(lst: list[dict]) -> dict:
    """A method's per-burst :func:`~thermocal.evaluation.scoring.scores` summarised: mean,
    median, min and max MAE, bias-free MAE, mean absolute bias (°C), bursts."""
    maes = np.array([s["mae"] for s in lst])
    return {"mae_c": float(maes.mean()), "median_mae_c": float(np.median(maes)),
            "min_mae_c": float(maes.min()), "max_mae_c": float(maes.max()),
            "bias_free_mae_c": float(np.mean([s["bias_free"] for s in lst])),
            "mean_abs_bias_c": float(np.mean([abs(s["bias"]) for s in lst])),
            "bursts": len(lst), "per_burst_mae_c": [float(m) for m in maes]}


def bench_network(quick: bool) -> dict:
    """Part 2: the shipped network and the kpn suite's references (fitted on each family) on
    the held-out bursts of each family."""
    import torch

    from thermocal.burst import fill_stuck_pixels
    from thermocal.evaluation.heldout import (
        NOMINAL_FPA_C,
        OTHER_UNIT,
        eval_bursts,
        two_point_of,
    )
    from thermocal.evaluation.network import KPN_ROW, run_methods
    from thermocal.evaluation.references import FAMILY_ROW, ExactModel, reference_scores
    from thermocal.nn.data import EVAL_UNITS, TRAIN_UNITS
    from thermocal.nn.infer import shipped_model_path
    from thermocal.nn.inputs import nominal_camera
    from thermocal.nn.store import load_model

    torch.set_num_threads(2)
    path = shipped_model_path("kpn")
    model, norm, info = load_model(path)
    n = model.config.n_frames
    size = (336, 256)
    other = make_camera("boson", unit=OTHER_UNIT, size=size)
    # the references fitted on boson: another boson unit's two-point at the nominal FPA (the
    # camera settled: housing = FPA − its self-heating) and the average boson unit 0-23
    boson_refs = ({FAMILY_ROW: ExactModel(nominal_camera(
                      [make_camera("boson", unit=u, size=size) for u in TRAIN_UNITS]))},
                  two_point_of(other, NOMINAL_FPA_C,
                               NOMINAL_FPA_C - other.thermal.fpa_self_heating_c, 5))
    names = _row_names()
    out = {"model": path.name, "config": model.config.to_dict(),
           "trained_on": {"preset": info["data"].get("preset", "tau2"),
                          "units": info["data"].get("units")},
           "units": list(EVAL_UNITS), "n_frames": n, "families": {}}
    for on in FAMILIES:
        started = time.perf_counter()
        bursts = eval_bursts(n, quick=quick, preset=on)
        refusal = None
        try:  # the network and the kpn suite's references, fitted on tau2
            res = run_methods(bursts, model, norm)
        except ThermocalError as exc:
            refusal = f"{type(exc).__name__}: {exc}"
            res = run_methods(bursts, None, norm)
        rows = []
        for name, lst in res.items():
            fit_on = OWN if name == OWN_TWO_POINT_ROW else "tau2"
            rows.append({"method": names.get(name, name), "row": name, "fitted_on": fit_on,
                         **burst_summary(lst)})
        extra: dict[str, list] = {}  # the same references fitted on boson
        for b in bursts:
            frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
            for name, s in reference_scores(b, frames, boson_refs[0], boson_refs[1]).items():
                if name != OWN_TWO_POINT_ROW:  # the unit's own: computed above
                    extra.setdefault(name, []).append(s)
        rows += [{"method": names.get(name, name), "row": name, "fitted_on": "boson",
                  **burst_summary(lst)} for name, lst in extra.items()]
        out["families"][on] = {
            "bursts": len(bursts), "frame_size": list(bursts[0]["frames"].shape[1:][::-1]),
            "units": sorted({int(b["unit"]) for b in bursts}),
            "scenes": sorted({b["scene"] for b in bursts}),
            "bursts_info": [{"scene": b["scene"], "unit": int(b["unit"]),
                             "fpa_c": float(b["fpa_c"]), "motion": b["motion"]} for b in bursts],
            "network_refused": refusal, "network_ran": KPN_ROW in res,
            "rows": rows, "seconds": time.perf_counter() - started,
        }
    return out


# ------------------------------------------------------------------------------- the table

COLUMNS = (("tau2", "tau2"), ("tau2", "boson"), ("boson", "boson"), ("boson", "tau2"))


def _cell(value: float | None, note: str = "") -> str:
    return f"{value:.2f}{note}" if value is not None else "–"


def summary_rows(res: dict) -> list[dict]:
    """The table for README: ``{"method", "cells": [4 str]}`` for every calibration method, every
    estimator and the kpn suite's references; cells in the order of :data:`COLUMNS` (fitted or
    trained on → evaluated on), MAE °C."""
    from thermocal.estimation.registry import ESTIMATORS
    from thermocal.evaluation.network import KPN_ROW

    out = []
    cal = res.get("calibration")
    if cal:
        index = {(r["method"], r["fitted_on"], r["evaluated_on"]): r for r in cal["rows"]}
        for name in CALIBRATION_METHODS:
            cells = []
            for fit_on, on in COLUMNS:
                r = index[(name, fit_on, on)]
                if "refused" in r:
                    cells.append("refused")
                elif r["mae_c"] is None:
                    cells.append("– (no frame in range)")
                else:
                    cells.append(_cell(r["mae_c"]))
            out.append({"method": f"calibration `{name}`", "cells": cells})
    net = res.get("network")
    if net:
        fams = net["families"]

        def lookup(row: str, fit_on: str, on: str) -> dict | None:
            return next((r for r in fams[on]["rows"] if r["row"] == row
                         and r["fitted_on"] == fit_on), None)

        names = _row_names()
        for row in names:
            cells = []
            for fit_on, on in COLUMNS:
                r = lookup(row, OWN if row == OWN_TWO_POINT_ROW else fit_on, on)
                if row == KPN_ROW and fit_on == "boson":
                    cells.append("not trained")
                elif row == KPN_ROW and fams[on]["network_refused"]:
                    cells.append("refused")
                elif row == OWN_TWO_POINT_ROW and fit_on != on:
                    cells.append("n/a (own unit)")
                else:
                    cells.append(_cell(None if r is None else r["mae_c"]))
            label = names[row]
            if row == KPN_ROW:
                label = "estimator `kpn`: the shipped network (trained on tau2 units 0-23)"
            out.append({"method": label, "cells": cells})
        for name, e in ESTIMATORS.items():
            if e.needs == "model" and name != "kpn":
                out.append({"method": f"estimator `{name}`", "cells": ["no shipped weights"] * 4})
            elif e.needs == "recording":  # a FLIR file's own constants: none in simulated frames
                out.append({"method": f"estimator `{name}`",
                            "cells": ["n/a (needs a FLIR file's constants)"] * 4})
            elif e.needs == "pass":  # fitted on a whole pass, not on bursts
                out.append({"method": f"estimator `{name}`",
                            "cells": ["n/a (whole passes: benchmarks/passes.py)"] * 4})
    return out


# ------------------------------------------------------------------------------- report


def _f(value: float | None, fmt: str = ".2f") -> str:
    return "–" if value is None else format(value, fmt)


def report(res: dict) -> str:
    """The Markdown report."""
    lines = [f"## Cross-physics benchmark ({'quick' if res['quick'] else 'full'})", "",
             f"machine: {res['machine']}", ""]
    cal = res.get("calibration")
    if cal:
        w, h = cal["size"]
        lines += ["### 1. Calibrations fitted on one family, evaluated on both", "",
                  f"Data: unit {cal['unit']} of each family (tau2, boson), {w}x{h} px. "
                  "Calibration session per unit (the calibration suite's protocol: ambient steps "
                  "5→40 °C with 20-min plateaus, then a 1.5 °C/min sawtooth; blackbody 5…75 °C, "
                  "ε = 0.98): " + ", ".join(
                      f"{f} {cal['sessions'][f]['frames']} frames" for f in FAMILIES) + ". "
                  "Every method with its default options, except the reference FPA of the "
                  "methods that take one: the settled FPA of the 25 °C plateau (" + ", ".join(
                      f"{f} {cal['fpa_ref_c'][f]:.2f} °C" for f in FAMILIES) + ").", ""]
        lines += ["Held-out run of each unit (another seed; blackbody 10…70 °C; the shutter "
                  f"closed every {SHUTTER_INTERVAL_S:.0f} s, used by `shutter` only):", "",
                  "| family | part | frames | FPA range °C | max FPA rate °C/min |",
                  "|---|---|---|---|---|"]
        for f in FAMILIES:
            for p in cal["held_out"][f]["parts"]:
                what = (f"ambient ramp 5→40 °C at 0.25 °C/min, then held {HOLD_S / 60:.0f} min"
                        if p["part"] == "slow ramp" else "ambient sawtooth 5↔40 °C at 1 °C/min")
                lines.append(f"| {f} | {p['part']} ({what}) | {p['frames']} | "
                             f"{p['fpa_range_c'][0]:.1f}…{p['fpa_range_c'][1]:.1f} | "
                             f"{p['max_fpa_rate_c_per_min']:.2f} |")
        lines += ["", "MAE °C against the blackbody's radiance-equivalent temperature in the "
                  "evaluated camera's band, non-defective pixels; *scored* = the frames inside "
                  "the calibration's FPA range (those its OutsideCalibrationRangeWarning does "
                  f"not flag: fitted range ± {RANGE_MARGIN_C} °C); the last column scores every "
                  "frame, the warning ignored.", "",
                  "| method | fitted on | FPA range °C | evaluated on | MAE °C (scored) | "
                  "frames scored / all | flagged outside | slow ramp MAE | fast sawtooth MAE | "
                  "stable frames MAE (n) | bias °C | 99th pct abs °C | MAE every frame |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in cal["rows"]:
            head = f"| {r['method']} | {r['fitted_on']} |"
            if "refused" in r:
                lines.append(f"{head} – | {r['evaluated_on']} | refused | | | | | | | | |")
                continue
            rng = r["fpa_range_c"]
            lines.append(
                f"{head} {rng[0]:.1f}…{rng[1]:.1f} | {r['evaluated_on']} | "
                f"**{_f(r['mae_c'])}** | {r['scored_frames']} / {r['frames']} | "
                f"{100 * r['flagged_fraction']:.0f} % | {_f(r['mae_slow_ramp_c'])} | "
                f"{_f(r['mae_fast_sawtooth_c'])} | {_f(r['mae_stable_c'])} "
                f"({r['scored_stable']}) | {_f(r['bias_c'], '+.2f')} | "
                f"{_f(r['p99_abs_c'])} | {_f(r['mae_all_frames_c'])} |")
        notes = [f"- `{name}` refused {f}'s session: {why}"
                 for f in FAMILIES for name, why in cal["refused"][f].items()]
        notes += [f"- with its default reference FPA (the first frame's), `{name}` refuses "
                  f"{f}'s session: {why}"
                  for f in FAMILIES for name, why in cal["default_refused"][f].items()]
        if notes:
            lines += ["", *notes]
        lines.append("")
    net = res.get("network")
    if net:
        from thermocal.evaluation.network import KPN_ROW

        fams = net["families"]
        desc = "; ".join(
            f"{f}: {d['bursts']} bursts of N = {net['n_frames']} frames "
            f"{d['frame_size'][0]}x{d['frame_size'][1]}, units {d['units']}, {d['seconds']:.0f} s"
            for f, d in fams.items())
        scenes = sorted({s for d in fams.values() for s in d["scenes"]})
        tr = net["trained_on"]
        units = tr.get("units") or []
        lines += ["### 2. The network (trained on tau2) and the references, on both families", "",
                  f"Model `{net['model']}`, trained on {tr['preset']} units "
                  f"{units[0] if units else '?'}…{units[-1] if units else '?'} only; no "
                  "boson-trained weights exist (not trained). Held-out bursts "
                  "(`eval_bursts`, the kpn suite's set: held-out scenes "
                  f"{', '.join(scenes)}; FPA 15-45 °C; walks and hovers; true homographies + Oz "
                  f"registration error; stuck pixels replaced) made by each family: {desc}. "
                  "MAE °C on the pixels seen by at least half the frames. *Fitted on*: the family "
                  "of the camera model / calibration a reference uses (tau2 rows: as the kpn "
                  "suite).", "",
                  "| method | fitted / trained on | tau2 bursts: MAE (median; per-burst "
                  "min–max) | bias-free | boson bursts: MAE (median; per-burst min–max) | "
                  "bias-free |", "|---|---|---|---|---|---|"]
        keys = []
        for d in fams.values():
            for r in d["rows"]:
                if (r["row"], r["fitted_on"]) not in keys:
                    keys.append((r["row"], r["fitted_on"]))
        order = {"tau2": 0, OWN: 1, "boson": 2}
        for row, fit_on in sorted(keys, key=lambda k: (order.get(k[1], 3), keys.index(k))):
            cells, label = [], row
            for on in FAMILIES:
                r = next((x for x in fams[on]["rows"]
                          if x["row"] == row and x["fitted_on"] == fit_on), None)
                if r is None:
                    cells += ["–", "–"]
                    continue
                label = r["method"]
                cells += [f"{r['mae_c']:.2f} ({r['median_mae_c']:.2f}; {r['min_mae_c']:.2f}–"
                          f"{r['max_mae_c']:.2f})", f"{r['bias_free_mae_c']:.2f}"]
            lines.append(f"| {label} | {fit_on} | " + " | ".join(cells) + " |")
        lines.append("| kpn: the network trained on boson | boson | not trained | | "
                     "not trained | |")
        for f, d in fams.items():
            r = next((x for x in d["rows"] if x["row"] == KPN_ROW), None)
            if r is not None:
                k = int(np.argmax(r["per_burst_mae_c"]))
                b = d["bursts_info"][k]
                lines.append(f"\nThe network's worst {f} burst: {r['max_mae_c']:.2f} °C, "
                             f"{b['scene']} ({b['motion']}), unit {b['unit']}, FPA "
                             f"{b['fpa_c']:.1f} °C.")
        for f, d in fams.items():
            if d["network_refused"]:
                lines.append(f"\nThe network refused the {f} bursts: {d['network_refused']}")
        lines.append("")
    rows = summary_rows(res)
    if rows:
        lines += ["### 3. Summary for README: MAE °C, fitted (or trained) on → evaluated on", "",
                  "Calibrations: unit 101's chamber session → unit 101's held-out run, frames "
                  "inside the calibration's FPA range (section 1). Estimators and references: "
                  "the held-out bursts of units 100-104 (section 2); another unit's calibration "
                  "is unit 7's of the family fitted on.", "",
                  "| method | " + " | ".join(f"{a} → {b}" for a, b in COLUMNS) + " |",
                  "|---|" + "---|" * len(COLUMNS)]
        for r in rows:
            lines.append(f"| {r['method']} | " + " | ".join(r["cells"]) + " |")
        lines.append("")
    variants = res.get("lag_variants")
    if variants:
        lines += ["### 4. Other lags: cameras whose optics and transient lag unlike either "
                  "preset", "",
                  "`lin-lag`'s lags (30, 120, 480 s) were chosen on the two presets' sessions; "
                  "these cameras change the lags' time constants (unit 101, its own session → "
                  "its held-out run, as section 1; MAE °C over every frame: all / slow ramp / "
                  "fast sawtooth).", "",
                  "| family | lags changed | " + " | ".join(f"`{m}`" for m in LAG_METHODS) + " |",
                  "|---|---|" + "---|" * len(LAG_METHODS)]
        for v in variants:
            change = ", ".join(f"{k.removesuffix('_s')} {val:g} s"
                               for k, val in v["thermal"].items())
            cells = [" / ".join(f"{x:.2f}" for x in v["methods"][m]) for m in LAG_METHODS]
            lines.append(f"| {v['family']} | {change} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="smaller crops, coarser time steps, 5 bursts per family")
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args(argv)
    started = time.perf_counter()
    res: dict = {"machine": machine(), "quick": args.quick}
    t = time.perf_counter()
    res["calibration"] = bench_calibrations(args.quick)
    res["calibration"]["seconds"] = time.perf_counter() - t
    t = time.perf_counter()
    res["network"] = bench_network(args.quick)
    res["network"]["seconds"] = time.perf_counter() - t
    t = time.perf_counter()
    res["lag_variants"] = bench_lag_variants(args.quick)
    res["lag_variants_seconds"] = time.perf_counter() - t
    res["summary"] = summary_rows(res)
    res["wall_time_s"] = time.perf_counter() - started
    print(report(res))
    print(f"\n(calibrations {res['calibration']['seconds']:.0f} s, network and references "
          f"{res['network']['seconds']:.0f} s; total {res['wall_time_s']:.0f} s)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2)


if __name__ == "__main__":
    main()
