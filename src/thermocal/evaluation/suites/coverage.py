"""Does the stated uncertainty hold? Coverage, sharpness and refusals (issue 18, items 1–2).

For each estimate with a σ, the share of scored pixels whose error lies within 1σ (target
68 ± 5 %) and within 2σ (95 ± 3 %), and the median σ (sharpness: a σ that covers by being huge
is no use). Scored pixels: seen by at least half the frames, as in ``benchmarks/kpn.py``.

The network (``kpn``, trained on ``tau2`` units 0–23; its σ model fitted on units of its own,
one per burst, over training scenes: :mod:`thermocal.evaluation.sigma_fit`) is run through the
product's pipeline, domain check included, on

1. the held-out set of ``benchmarks/kpn.py``: ``tau2`` units 100–104 over the held-out scenes;
2. 200 more held-out ``tau2`` units (300–499), one per burst, over the same scenes: the units'
   own levels, the largest part of the error, are a draw per unit, so five units sample them
   poorly (a 90 % bootstrap interval over units says how poorly);
3. the ``boson`` family (units 100–104, same scenes), which the network never saw: how many
   bursts it refuses, and for those it would estimate with ``--force``, the coverage of the
   inflated σ; a "silent" error is a burst it does not refuse whose MAE exceeds 1 °C.

The accepted bursts are also told by condition (:func:`condition_table`): FPA temperature, and
the scene's mean estimate less the FPA temperature, where the network's σ misses most; and
their pixels by their estimate's temperature (:data:`PIXEL_TEMPERATURE_BINS_C`), where a σ
that covers the pixels as a whole may miss a part of the scenes.

The calibrations (every method; ``shutter`` re-reads its offsets on the held-out run's shutter
closures, every 180 s, which its chamber report never saw) are fitted with their
cross-validation report on one unit's chamber session of each family and scored, frame by frame,
on a held-out run of the same unit (``benchmarks/physics.py``'s sessions: its own physics): a
frame outside the session's FPA or scene range, or (a memoryless method) at an FPA pace the
session never held, is refused (scored as ``--force`` gives it); the σ of a frame uses its FPA
rate and pace history, as ``thermocal correct`` does for a recording with frame times.
``--held-out other`` scores them on another held-out protocol instead
(:func:`other_held_out_run`: a 0.6 °C/min sawtooth and ambient steps over a narrower range,
other seeds): a check of choices made on the first one (the pace margin of a method with
memory, :data:`~thermocal.calibration.report.MEMORY_PACE_MARGIN_C_PER_MIN`).

``--held-out both`` scores them on each, a row each, and tells whether one factor on a
method's σ could meet the bands in every case (:func:`method_factors`). ``--more-units``
draws the network's population of held-out units elsewhere (a check that its figures are not
those units' luck).

``--model`` scores a network trained with ``thermocal train`` (any variant: ``e2e``,
``kpn-no-offset``) instead, with the σ model fitted beside it.

Run: ``python -m thermocal.evaluation.suites.coverage [--quick] [--units U] [--held-out
{ramp,other,both}] [--more-units U] [--model W.pt] [--json OUT]``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy import stats

from thermocal.bench import machine
from thermocal.burst import fill_stuck_pixels
from thermocal.calibration.base import calibration_sigma_extra
from thermocal.calibration.dataset import RATE_SMOOTH_S, fpa_rate_c_per_min
from thermocal.calibration.registry import CALIBRATION_METHODS
from thermocal.calibration.report import fit_with_report
from thermocal.calibration.uncertainty import CalibrationSigma
from thermocal.camera.presets import PRESETS, make_camera
from thermocal.errors import InvalidInputError, OutsideDomainError, ThermocalError
from thermocal.estimation.pipeline import estimate
from thermocal.evaluation.heldout import eval_bursts
from thermocal.evaluation.suites import physics
from thermocal.evaluation.suites.calibration import HELD_OUT
from thermocal.evaluation.tables import markdown_table
from thermocal.metrics import coverage_interval, rescaled_coverage, sigma_coverage
from thermocal.nn.infer import NetworkEstimator
from thermocal.simulate.chamber import ChamberPlan

__all__ = ["calibration_rows", "main", "method_factors", "network_rows"]

#: Pixels of each held-out frame scored (a fixed sample: the frames are uniform scenes).
PIXELS_PER_FRAME = 400

#: An accepted estimate erring by more than this (MAE, °C) and twice its median σ is silent.
SILENT_MAE_C = 1.0

#: More held-out units of the preset than the five of the held-out set, one per burst.
MORE_UNITS = tuple(range(300, 500))

#: Bursts per held-out scene on :data:`MORE_UNITS`.
MORE_PER_SCENE = 40

def other_held_out_run(camera, seed: int, quick: bool) -> physics.Run:
    """A second held-out protocol, at paces neither the calibration session (steps, a
    1.5 °C/min sawtooth) nor the first held-out run holds: a 0.6 °C/min 8↔38 °C sawtooth, then
    ambient steps 8→38 °C; blackbody at the held-out set points (2 frames each); seeds
    ``seed + 50`` on; the shutter as in the first."""
    interval = 18.0 if quick else 6.0
    saw = ChamberPlan(setpoints_c=HELD_OUT, frames_per_point=2, profile="sawtooth",
                      ambient_c=(8.0, 38.0), rate_c_per_min=0.6, interval_s=interval)
    steps = ChamberPlan(setpoints_c=HELD_OUT, frames_per_point=2, profile="steps",
                        ambient_c=(8.0, 38.0), interval_s=interval)
    return physics.simulate_run(camera, [saw, steps], seed + 50,
                                shutter_interval_s=physics.SHUTTER_INTERVAL_S)


#: The calibrations' held-out runs (``--held-out``) by name: the physics benchmark's (a
#: 0.25 °C/min ramp and hold, a 1 °C/min sawtooth) and :func:`other_held_out_run`.
HELD_OUT_RUNS = {"ramp": physics.held_out_run, "other": other_held_out_run}


def _run(network: NetworkEstimator, bursts: list[dict]) -> dict:
    """Each burst through the pipeline: accepted, or refused (and then forced): the coverage of
    the accepted bursts' pixels and of the forced ones', and the silent errors."""
    kept: dict[str, list] = {"accepted": [], "forced": []}
    by_unit: dict[int, list] = {}  # the accepted bursts' (errors, σ) of each unit
    by_condition: dict[str, dict[int, list]] = {}  # and of each condition's bin
    silent, maes = 0, []
    for b in bursts:
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        args = {"fpa_c": b["fpa_read"], "homographies": b["hs"], "pivot": b["pivot"],
                "fill_defects": False}
        try:
            est = estimate(frames, network, **args)
        except OutsideDomainError:
            est = estimate(frames, network, force=True, **args)
        err = (est.temperature_c - b["truth"])[b["mask"]]
        mae = float(np.abs(err).mean())
        silent += int(not est.outside and _silent(mae, est.sigma_c[b["mask"]]))
        kept["forced" if est.outside else "accepted"].append((err, est.sigma_c[b["mask"]]))
        if not est.outside:
            by_unit.setdefault(b["unit"], []).append(kept["accepted"][-1])
            temps = est.temperature_c[b["mask"]]
            sigma = kept["accepted"][-1][1]
            scene_c = float(np.mean(temps))
            parts = [(key, kept["accepted"][-1])
                     for key in _conditions(b["fpa_c"], scene_c - b["fpa_c"])]
            parts += [(key, (err[sel], sigma[sel])) for key, sel in _pixel_conditions(temps)]
            for key, pair in parts:
                by_condition.setdefault(key, {}).setdefault(b["unit"], []).append(pair)
        maes.append(mae)
    out = {"bursts": len(bursts), "refused": len(kept["forced"]), "silent_over_1c": silent,
           "mae_c": float(np.mean(maes)), "burst_mae_range_c": [min(maes), max(maes)]}
    for name, pairs in kept.items():
        out[name] = sigma_coverage(*_pooled(pairs)) if pairs else None
    out["accepted_rescaled"] = _rescaled(kept["accepted"])
    out["accepted_interval"] = _unit_interval(by_unit)
    out["accepted_by_condition"] = {key: _condition_cell(by_condition[key])
                                    for key in _condition_keys() if key in by_condition}
    return out


def _unit_interval(by_unit: dict[int, list]) -> dict | None:
    """:func:`~thermocal.metrics.coverage_interval` of ``(errors, σ)`` pairs by unit, resampling
    whole units (a unit's bursts share its level); None for fewer than two units."""
    units = [_pooled(pairs) for pairs in by_unit.values()]
    return coverage_interval(units) if len(units) > 1 else None


def _condition_cell(by_unit: dict[int, list]) -> dict:
    """The coverage of one condition's accepted bursts (``(errors, σ)`` pairs by unit), with
    its interval over units where there are two or more."""
    pairs = [p for unit in by_unit.values() for p in unit]
    return {"bursts": len(pairs), "units": len(by_unit), **sigma_coverage(*_pooled(pairs)),
            "interval": _unit_interval(by_unit)}


def _pooled(pairs: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    """The errors and σ of ``(errors, σ)`` pairs (bursts, frames), each concatenated."""
    return (np.concatenate([e for e, _ in pairs]), np.concatenate([s for _, s in pairs]))


#: The bins of the network's accepted bursts: FPA temperature, and the scene's mean estimate
#: less the FPA temperature (°C).
FPA_BINS_C = (15.0, 25.0, 35.0, 45.0)
SCENE_LESS_FPA_BINS_C = (-90.0, -40.0, -20.0, 0.0, 60.0)


#: The bins of the accepted bursts' pixels by their estimate's temperature (°C): a σ that
#: covers the pixels as a whole may miss a part of the scenes (an ``e2e`` network trained
#: 20 min: 95.1 % within 1σ overall, 20.6–25.7 % of the held-out scenes' pixels below −5 °C,
#: 98–100 % of those above, σ 5.2–5.9 °C throughout: results/coverage_e2e_2026-11-29b.md).
PIXEL_TEMPERATURE_BINS_C = (-90.0, -20.0, -5.0, 5.0, 15.0, 60.0)

_BINS = (("FPA", FPA_BINS_C), ("scene − FPA", SCENE_LESS_FPA_BINS_C),
         ("pixels at", PIXEL_TEMPERATURE_BINS_C))


def _bin_key(name: str, edges: tuple[float, ...], k: int) -> str:
    return f"{name} {edges[k]:g}…{edges[k + 1]:g} °C"


def _condition_keys() -> list[str]:
    """Every condition's name, in the table's order."""
    return [_bin_key(name, edges, k) for name, edges in _BINS for k in range(len(edges) - 1)]


def _conditions(fpa_c: float, scene_less_fpa_c: float) -> list[str]:
    """The bins (:data:`FPA_BINS_C`, :data:`SCENE_LESS_FPA_BINS_C`) a burst falls in."""
    out = []
    for name, edges, v in (("FPA", FPA_BINS_C, fpa_c),
                           ("scene − FPA", SCENE_LESS_FPA_BINS_C, scene_less_fpa_c)):
        k = int(np.searchsorted(edges, v, side="right")) - 1
        if 0 <= k < len(edges) - 1:
            out.append(_bin_key(name, edges, k))
    return out


def _pixel_conditions(temps_c: np.ndarray) -> list[tuple[str, np.ndarray]]:
    """The bins of :data:`PIXEL_TEMPERATURE_BINS_C` that pixels of estimates ``temps_c``
    (°C, ``(M,)``) fall in, each with its pixels (``(M,)`` bool)."""
    edges = PIXEL_TEMPERATURE_BINS_C
    k = np.searchsorted(edges, temps_c, side="right") - 1
    return [(_bin_key("pixels at", edges, i), k == i) for i in range(len(edges) - 1)
            if np.any(k == i)]


def condition_table(rows: list[dict]) -> str:
    """The network rows' coverage by FPA and by scene less FPA (accepted bursts), and by
    their pixels' estimate's temperature."""
    cells = [(r["data"], key, c["bursts"], *_cells(c, c.get("interval")))
             for r in rows for key, c in (r.get("accepted_by_condition") or {}).items()]
    if not cells:
        return ""
    header = ("data", "bursts where", "bursts", "within 1σ", "within 2σ", "median σ °C")
    return ("\n### The network's accepted bursts by condition\n\nFPA temperature, and the "
            "scene's mean estimate less the FPA temperature; and their pixels by their "
            "estimate's temperature (\"pixels at\": the bursts with such pixels); in brackets, "
            "a 90 % bootstrap interval over the units.\n\n"
            + markdown_table(header, cells) + "\n")


def _rescaled(pairs: list[tuple[np.ndarray, np.ndarray]]) -> dict | None:
    """:func:`~thermocal.metrics.rescaled_coverage` of ``(errors, σ)`` pairs, one per frame or
    burst (None without), with what the factor costs in silent frames: ``silent_at_factor``,
    the frames silent with σ × that factor; ``safe_factor``, the factor nearest it that
    silences no frame more than σ itself does (the best factor where that one does), and its
    coverage (``safe_within_1sigma``, ``safe_within_2sigma``): how sharp this σ's shape can be
    made without a silent error."""
    if not pairs:
        return None
    errors, sigmas = _pooled(pairs)
    out = rescaled_coverage(errors, sigmas)
    # a frame is silent at factor k (:func:`_silent` of σ × k) when its MAE exceeds
    # SILENT_MAE_C and 2·k·median σ: below k_f = MAE / (2·median σ); the frames not silent at
    # k = 1 bound the safe factor
    mae = np.array([float(np.mean(np.abs(e))) for e, _ in pairs])
    twice = np.array([2.0 * float(np.median(s)) for _, s in pairs])
    with np.errstate(divide="ignore", invalid="ignore"):
        k_f = np.where(mae > SILENT_MAE_C, mae / twice, 0.0)
    out["silent_at_factor"] = int(np.sum(k_f > out["factor"]))
    best = out["factor"]
    safe = best if best >= 1.0 else max(best, float(np.max(k_f[k_f <= 1.0], initial=0.0)))
    out["safe_factor"] = safe
    cov = sigma_coverage(errors, max(safe, 1e-9) * sigmas)
    out["safe_within_1sigma"], out["safe_within_2sigma"] = (cov["within_1sigma"],
                                                            cov["within_2sigma"])
    return out


def _silent(mae: float, sigma: np.ndarray) -> bool:
    """An error no one was told of: an accepted estimate whose MAE exceeds
    :data:`SILENT_MAE_C` and twice its median σ."""
    return mae > max(SILENT_MAE_C, 2.0 * float(np.median(sigma)))


def silent_share(sigma: np.ndarray) -> float:
    """How often a frame of this σ would be silent (:func:`_silent`) if its error were a level
    drawn from a Gaussian of its median σ: ``P(|e| > max(SILENT_MAE_C, 2σ))``."""
    s = float(np.median(sigma))
    return float(2.0 * stats.norm.sf(max(SILENT_MAE_C / s, 2.0))) if s > 0 else 0.0


def _run_calibration(cal, model: CalibrationSigma, run: physics.Run, rng) -> dict:
    """``cal`` on a held-out chamber run, frame by frame: refused (outside the ranges) or not,
    the errors and σ of a pixel sample, and the silent errors."""
    est, _ = physics.apply_run(cal, run)
    s = run.session
    good = np.flatnonzero(~run.camera.defects.ravel())
    pick = rng.choice(good, size=min(PIXELS_PER_FRAME, good.size), replace=False)
    kept: dict[str, list] = {"accepted": [], "forced": []}
    silent, expected = 0, 0.0
    for k in np.unique(run.part):
        sel = np.flatnonzero(run.part == k)
        rate = fpa_rate_c_per_min(s.fpa_c[sel], s.time_s[sel], smooth_s=RATE_SMOOTH_S)
        since = s.time_s[sel] - s.time_s[sel][0]
        temps = est[sel].reshape(sel.size, -1)[:, pick]
        sigmas = model.sigma(temps[:, None, :], s.fpa_c[sel], rate_c_per_min=rate,
                             time_since_start_s=since)[:, 0, :]
        unseen = model.unseen_paces(rate, since, fpa_c=s.fpa_c[sel])  # its pace history
        # as `thermocal correct` gives them: a shutter's closures, the rate terms' correction
        # on frames at paces never held (refused unless forced); the sample leaves the
        # camera's defects out
        added = calibration_sigma_extra(physics.part_calibration(cal, run, k),
                                        np.asarray(s.frames[sel]), est[sel],
                                        time_s=s.time_s[sel], fpa_c=s.fpa_c[sel],
                                        unverified=model.paces_never_held(
                                            rate, since, fpa_c=s.fpa_c[sel]))
        if added is not None:
            sigmas = np.hypot(sigmas, added.reshape(sel.size, -1)[:, pick])
        for j, i in enumerate(sel):
            err = temps[j] - run.truth_c[i]
            outside = bool(model.outside(temps[j], [s.fpa_c[i]], rate_c_per_min=[rate[j]])
                           or unseen[j])
            silent += int(not outside and _silent(float(np.abs(err).mean()), sigmas[j]))
            expected += 0.0 if outside else silent_share(sigmas[j])
            kept["forced" if outside else "accepted"].append((err, sigmas[j]))
    out = {"frames": int(s.n_frames), "refused": len(kept["forced"]), "silent_over_1c": silent,
           "silent_expected": expected,
           "mae_c": float(np.mean(np.abs(est[:, ~run.camera.defects]
                                         - run.truth_c[:, None]))),
           "expected_mae_c": model.report.expected_mae_c}
    for name, pairs in kept.items():  # the sample's MAE and coverage, accepted and refused
        errors, sigmas = _pooled(pairs) if pairs else (None, None)
        out[f"mae_{name}_c"] = None if errors is None else float(np.mean(np.abs(errors)))
        out[name] = None if errors is None else sigma_coverage(errors, sigmas)
    out["accepted_rescaled"] = _rescaled(kept["accepted"])
    return out


def calibration_rows(*, quick: bool, units: tuple[int, ...] = (physics.UNIT,),
                     held_out: str | tuple[str, ...] = "ramp") -> list[dict]:
    """Every calibration method, fitted with its report on each family's session
    of each of ``units`` and scored on the same unit's held-out run (``held_out``, one or more
    of :data:`HELD_OUT_RUNS`, a row each; unit ``u``'s sessions take the seeds of unit
    :data:`~thermocal.evaluation.suites.physics.UNIT`'s plus ``u − UNIT``: other noise, other
    drift)."""
    protocols = (held_out,) if isinstance(held_out, str) else tuple(held_out)
    # one stream of pixel samples: a case's sample depends on the protocols scored beside it
    # (its figures move by a point or so between a run of one protocol and of both)
    rng = np.random.default_rng(0)
    size = physics.QUICK_SIZE if quick else physics.SIZE
    rows = []
    for family, unit in ((f, u) for f in PRESETS for u in units):
        cam = make_camera(family, unit=unit, size=size)
        shift = unit - physics.UNIT
        session = physics.calibration_session(cam, physics.SESSION_SEED + shift, quick)
        runs = {p: HELD_OUT_RUNS[p](cam, physics.HELD_OUT_SEED + shift, quick)
                for p in protocols}
        ref = physics.plateau_fpa_c(session.session)
        for name, info in CALIBRATION_METHODS.items():
            # a method auto leaves out (``shutter``) draws its pixels from a stream of its own,
            # so that scoring it leaves the other methods' samples as they were
            draw = rng if info.auto else np.random.default_rng(
                [1, list(PRESETS).index(family), unit, list(CALIBRATION_METHODS).index(name)])
            try:
                cal, report = fit_with_report(session.session, name,
                                              **({"fpa_ref_c": ref} if info.takes_fpa_ref
                                                 else {}))
            except ThermocalError as exc:
                cal, refused = None, {"refused_fit": str(exc).split(";")[0]}
            model = None if cal is None else CalibrationSigma(report)
            for protocol, held in runs.items():
                label = (f"{family} unit {unit} (own session → held-out run"
                         + ("" if protocol == "ramp" else ", other protocol") + ")")
                scored = refused if cal is None else _run_calibration(cal, model, held, draw)
                rows.append({"method": name, "data": label, "preset": family, "unit": unit,
                             "held_out": protocol, **scored})
    return rows


def network_rows(*, quick: bool, more_units: tuple[int, ...] = MORE_UNITS,
                 model: str | None = None) -> list[dict]:
    """A network's coverage on each evaluation set (``more_units``: the population of held-out
    units, one per burst; none the σ model was fitted on): the shipped one, or the weights
    file ``model`` (any variant, with its σ model beside it, as ``thermocal train`` writes)."""
    variant = "kpn" if model is None else _variant_of(model)
    network = NetworkEstimator.from_file(variant, model)
    if network.sigma_model is None:
        raise InvalidInputError(f"{model or 'the shipped ' + variant + ' network'}: no σ model "
                                "beside it: fit one with `python -m "
                                "thermocal.evaluation.sigma_fit`")
    fitted = set(network.sigma_model.fitted_on.get("units", []))
    if fitted & set(more_units):
        raise InvalidInputError(f"units {sorted(fitted & set(more_units))[:3]}… are among those "
                                "the network's σ model was fitted on: choose held-out units")
    more = {"units": more_units, "per_scene": 4 if quick else MORE_PER_SCENE,
            "unit_per_burst": True}
    sets = [("tau2 held-out units 100–104 (kpn benchmark set)", "tau2", {}),
            (f"tau2 units {more_units[0]}–{more_units[-1]}, one per burst", "tau2", more),
            ("boson units 100–104 (another family)", "boson", {})]
    rows = []
    for label, preset, kwargs in sets:
        bursts = eval_bursts(network.n_frames, quick=quick, preset=preset, **kwargs)
        if kwargs and len({b["unit"] for b in bursts}) < len(bursts):  # fewer units than bursts
            label = label.replace("one per burst", "cycled over the bursts")
        rows.append({"method": variant if model is None else f"{variant} ({model})",
                     "data": label, "preset": preset, **_run(network, bursts)})
    return rows


def _variant_of(path: str) -> str:
    """The network variant a weights file holds (checked as it is loaded)."""
    from thermocal.nn.store import load_model

    return load_model(path)[0].config.variant


def _cells(cov: dict | None, interval: dict | None = None) -> tuple[str, str, str]:
    if cov is None:
        return "–", "–", "–"
    shares = []
    for key in ("within_1sigma", "within_2sigma"):
        span = "" if interval is None else " ({:.0f}–{:.0f})".format(
            *(100 * v for v in interval[key]))
        shares.append(f"{100 * cov[key]:.1f} %{span}")
    return (*shares, f"{cov['median_sigma_c']:.2f}")


def _rescaled_cell(res: dict | None) -> str:
    if res is None:
        return "–"
    return (f"×{res['factor']:.2f}: {100 * res['within_1sigma']:.0f} / "
            f"{100 * res['within_2sigma']:.0f} %" + ("" if res["in_band"] else " (no k in band)")
            + ("" if res.get("silent_at_factor") is None
               else f", {res['silent_at_factor']} silent"))


def _safe_cell(res: dict | None) -> str:
    if res is None or res.get("safe_factor") is None:
        return "–"
    return (f"×{res['safe_factor']:.2f}: {100 * res['safe_within_1sigma']:.0f} / "
            f"{100 * res['safe_within_2sigma']:.0f} %")


def report(rows: list[dict], info: dict) -> str:
    header = ("method", "data", "bursts / frames", "refused", "MAE °C (accepted / refused)",
              "accepted: within 1σ",
              "within 2σ", "median σ °C", "refused, if forced: within 1σ", "within 2σ",
              "median σ °C", "silent", "accepted, best σ × k: within 1σ / 2σ, silent",
              "sharpest σ × k with no more silent: within 1σ / 2σ")
    cells = []
    for r in rows:
        if "refused_fit" in r:
            cells.append((r["method"], r["data"], "fit refused: " + r["refused_fit"][:90],
                          *["–"] * (len(header) - 3)))
            continue
        split = "" if "mae_accepted_c" not in r else " ({} / {})".format(
            *("–" if v is None else f"{v:.2f}" for v in (r["mae_accepted_c"],
                                                         r["mae_forced_c"])))
        cells.append((r["method"], r["data"], r.get("bursts", r.get("frames")), r["refused"],
                      f"{r['mae_c']:.2f}{split}",
                      *_cells(r["accepted"], r.get("accepted_interval")),
                      *_cells(r["forced"]), r["silent_over_1c"],
                      _rescaled_cell(r.get("accepted_rescaled")),
                      _safe_cell(r.get("accepted_rescaled"))))
    table = markdown_table(header, cells)
    which = info.get("held_out", "ramp")
    other = ("" if which == "ramp" else
             f"**Held-out protocol: {'the other one' if which == 'other' else 'each of two'}**"
             " (`--held-out " + which + "`: the other is a 0.6 °C/min 8↔38 °C "
             "sawtooth, then ambient steps 8→38 °C, a frame every 6 s; paces neither the "
             "session nor the first held-out run holds); no network rows.\n\n")
    return (f"## Coverage of the stated uncertainty\n\n{other}machine: {info['machine']}; "
            f"{info['wall_s']:.0f} s\n\ndata: bursts of N = 7 frames, 336×256, over the held-out "
            "scenes (kpn benchmark set); FPA 15–45 °C; true homographies + Oz et al.'s "
            "registration error; pixels seen by ≥ half the frames. Calibrations: one unit "
            "per family at the physics benchmark's size, its own calibration session and "
            "held-out run (benchmarks/physics.py), 400 pixels of every frame. Accepted: what "
            "the domain check lets through; refused: the rest, scored as `--force` gives it "
            "(σ grown or inflated); in brackets, a 90 % bootstrap interval over the units (whose "
            "bursts share their unit's level); silent: accepted bursts or frames whose "
            "MAE exceeds both "
            "1 °C and twice their median σ. Targets: 68 ± 5 % within 1σ, 95 ± 3 % within "
            "2σ. Best σ × k: the one factor on every accepted σ that comes closest to those "
            "shares (chosen on the errors it scores: a diagnostic, not a correction); \"no k in "
            "band\": no overall level of this σ meets both bands, its errors over σ are not "
            "spread as a Gaussian's; silent: the frames (bursts) that factor leaves silent. "
            "Sharpest σ × k: the factor nearest the best that silences no frame more than σ "
            f"does, and its coverage: how far this σ's shape can be sharpened safely.\n\n{table}\n")


def unit_spread(rows: list[dict]) -> str:
    """Per method and family over the units scored: the range of the accepted frames' coverage
    at 1σ and 2σ, of their median σ and of the silent frames (is a row's miss the draw of one
    unit, or the method's?); ``""`` for one unit."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for r in rows:
        if "unit" in r and r.get("accepted"):
            groups.setdefault((r["method"], r["preset"], r.get("held_out", "ramp")),
                              []).append(r)
    if not groups or max(len(g) for g in groups.values()) < 2:
        return ""
    protocols = len({key[2] for key in groups})

    def span(values: list[float], fmt: str) -> str:
        lo, hi = format(min(values), fmt), format(max(values), fmt)
        return lo if lo == hi else f"{lo}–{hi}"

    cells = [(method, family + ("" if protocols == 1 else f", {protocol}"),
              ", ".join(str(r["unit"]) for r in g),
              span([100 * r["accepted"]["within_1sigma"] for r in g], ".1f") + " %",
              span([100 * r["accepted"]["within_2sigma"] for r in g], ".1f") + " %",
              span([r["accepted"]["median_sigma_c"] for r in g], ".2f"),
              span([r["silent_over_1c"] for r in g], "d"),
              _rescaled_span([r.get("accepted_rescaled") for r in g], span),
              _safe_span([r.get("accepted_rescaled") for r in g], span))
             for (method, family, protocol), g in groups.items()]
    header = ("method", "family" + ("" if protocols == 1 else ", held-out run"), "units",
              "accepted: within 1σ", "within 2σ", "median σ °C",
              "silent frames", "best σ × k (units with a k in band): silent there",
              "sharpest σ × k with no more silent: within 1σ / 2σ")
    return ("\n### The same, unit by unit\n\nEach unit's own session and held-out run (other "
            "seeds): the range over the units.\n\n" + markdown_table(header, cells) + "\n")


def _common_factor(cases: list[tuple[str, list[float] | None]]) -> str:
    """The factors that put every case in both bands, from each case's ``(name, band_factors)``
    (:func:`~thermocal.metrics.rescaled_coverage`): their interval, or why there is none (the
    cases with no factor in band; else the two cases whose intervals do not meet)."""
    if not cases:
        return "–"
    none = [n for n, b in cases if b is None]
    if none:
        return f"none: no factor in band for {len(none)} of {len(cases)} ({none[0]}, …)"
    (hi_name, (_, hi)), (lo_name, (lo, _)) = (min(cases, key=lambda c: c[1][1]),
                                              max(cases, key=lambda c: c[1][0]))
    if lo > hi:
        return f"none: {hi_name} needs ≤ {hi:.2f}, {lo_name} ≥ {lo:.2f}"
    return f"×{lo:.2f}–{hi:.2f}"


def method_factors(rows: list[dict]) -> str:
    """Could one factor on a calibration method's σ meet both bands wherever it is used? Per
    method, over every family, unit and held-out protocol scored: the factors each case needs
    and whether they meet (over all cases, and over each family's alone: a σ drawn from a
    session knows neither its camera's family nor the protocol that follows); ``""`` for fewer
    than two cases of a method."""
    groups: dict[str, list[dict]] = {}
    for r in rows:
        if r.get("accepted_rescaled") is not None and "unit" in r:
            groups.setdefault(r["method"], []).append(r)
    if not groups or max(len(g) for g in groups.values()) < 2:
        return ""

    def case(r: dict) -> tuple[str, list[float] | None]:
        return (f"{r['preset']} {r['unit']} {r.get('held_out', 'ramp')}",
                r["accepted_rescaled"].get("band_factors"))

    cells = []
    for method, g in groups.items():
        best = [r["accepted_rescaled"]["factor"] for r in g]
        families = sorted({r["preset"] for r in g})
        cells.append((method, len(g), sum(case(r)[1] is not None for r in g),
                      f"×{min(best):.2f}–{max(best):.2f}",
                      f"{sum(r.get('silent_over_1c', 0) for r in g)} / "
                      f"{sum(r.get('silent_expected', 0.0) for r in g):.0f}",
                      _common_factor([case(r) for r in g]),
                      *(_common_factor([case(r) for r in g if r["preset"] == f])
                        for f in PRESETS if f in families)))
    present = [f for f in PRESETS if any(r["preset"] == f for g in groups.values() for r in g)]
    header = ("method", "cases", "with a factor in band", "best factors",
              "silent frames / a Gaussian σ's share", "one factor for every case",
              *(f"for `{f}`'s cases alone" for f in present))
    return ("\n### One factor per method\n\nA case: one family's unit, its own session, one "
            "held-out protocol. The factors that put a case's accepted frames in both bands "
            "(68 ± 5 % within 1σ, 95 ± 3 % within 2σ) form an interval; one factor on a "
            "method's σ meets the target everywhere only where every case's interval meets. "
            "Silent frames, all cases, beside how many a σ would leave if each frame's error "
            "were a level drawn from a Gaussian of its median σ (beyond both 1 °C and 2σ).\n\n"
            + markdown_table(header, cells) + "\n")


def _rescaled_span(results: list[dict | None], span) -> str:
    """The range of the best factors over units, and in how many units some factor meets both
    bands."""
    done = [r for r in results if r is not None]
    if not done:
        return "–"
    silent = [r["silent_at_factor"] for r in done if r.get("silent_at_factor") is not None]
    return (f"×{span([r['factor'] for r in done], '.2f')} "
            f"({sum(r['in_band'] for r in done)} of {len(done)})"
            + (f": {span(silent, 'd')}" if len(silent) == len(done) else ""))


def _safe_span(results: list[dict | None], span) -> str:
    """The range over units of the sharpest safe factor and its coverage at 1σ and 2σ."""
    done = [r for r in results if r is not None and r.get("safe_factor") is not None]
    if not done:
        return "–"
    return (f"×{span([r['safe_factor'] for r in done], '.2f')}: "
            f"{span([100 * r['safe_within_1sigma'] for r in done], '.0f')} / "
            f"{span([100 * r['safe_within_2sigma'] for r in done], '.0f')} %")


def _units(text: str) -> tuple[int, ...]:
    """``"101"``, ``"101,103"`` or ``"101-105"`` → the units."""
    units: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        units += range(int(lo), int(hi or lo) + 1)
    return tuple(units)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="One burst per scene.")
    parser.add_argument("--json", default=None, help="Write the results as JSON here.")
    parser.add_argument("--units", type=_units, default=(physics.UNIT,),
                        help="The calibrations' units, e.g. 101-105 (default %(default)s).")
    parser.add_argument("--held-out", choices=[*HELD_OUT_RUNS, "both"], default="ramp",
                        help="The calibrations' held-out protocol (other: a 0.6 °C/min "
                        "sawtooth and steps; both: each, a row each; the network is run "
                        "with ramp only).")
    parser.add_argument("--more-units", type=_units, default=MORE_UNITS,
                        help="The network's population of held-out units, one per burst "
                        f"(default {MORE_UNITS[0]}-{MORE_UNITS[-1]}; 200 are drawn).")
    parser.add_argument("--model", default=None,
                        help="Score this weights file (any variant, its σ model beside it) "
                        "instead of the shipped network, and no calibration.")
    args = parser.parse_args(argv)
    if args.model and args.held_out != "ramp":
        parser.error("--model scores a network, which runs on the ramp protocol's sets only: "
                     "leave --held-out out")
    start = time.perf_counter()
    held_out = tuple(HELD_OUT_RUNS) if args.held_out == "both" else args.held_out
    rows = ([] if args.model else
            calibration_rows(quick=args.quick, units=args.units, held_out=held_out))
    rows += (network_rows(quick=args.quick, more_units=args.more_units, model=args.model)
             if args.held_out == "ramp" else [])
    info = {"machine": machine(), "wall_s": time.perf_counter() - start, "quick": args.quick,
            "units": list(args.units), "held_out": args.held_out}
    print(report(rows, info) + unit_spread(rows) + method_factors(rows) + condition_table(rows))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({**info, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
