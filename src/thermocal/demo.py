"""``thermocal demo``: the main job on built-in data, end to end, with honest numbers.

A seeded Tau2-class camera unit that the network never saw in training is calibrated in a simulated
environmental chamber (two-point and per-pixel polynomial calibrations), then flown over the
built-in real aerial scene on a warm day. Each pivot frame of the pass is turned into temperature
by the classical methods and by the kernel prediction network (calibration-free: it needs only the
FPA temperature), and compared with the ground truth.
"""

from __future__ import annotations

import json
import tempfile
import time
import warnings
from importlib.resources import files
from pathlib import Path

import numpy as np

from thermocal import metrics
from thermocal.calibration.report import fit_with_report
from thermocal.camera.model import invert
from thermocal.camera.presets import make_camera
from thermocal.errors import InvalidInputError
from thermocal.estimation.calibrated import PivotCalibration
from thermocal.estimation.pipeline import estimate
from thermocal.estimation.registry import make_estimator
from thermocal.io.atomic import ensure_output_dir, write_json_atomic
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
from thermocal.simulate.flight import simulate_flight

#: A unit outside the network's training (0–23) and validation (50–53) units.
DEMO_UNIT = 101
FLIGHT_FPA_C = 36.0
TWO_POINT_FPA_C = 30.0
N_FRAMES = 7
N_GROUPS = 3


def calibrate_in_chamber(camera, *, seed: int, tmp: Path) -> dict:
    """A simulated chamber session of ``camera`` and the calibrations fitted on it."""
    plan = ChamberPlan(
        setpoints_c=(0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0),
        frames_per_point=2,
        profile="sawtooth",
        ambient_c=(15.0, 35.0),
        rate_c_per_min=0.25,
        interval_s=20.0,
    )
    path = tmp / "chamber.h5"
    write_simulated_chamber(path, camera, plan, seed=seed)
    # each with its cross-validation report, which gives its uncertainty
    return {
        f"two-point (FPA {TWO_POINT_FPA_C:.0f} °C)": fit_with_report(
            path, "two-point", fpa_ref_c=TWO_POINT_FPA_C)[0],
        "polynomial (per pixel, FPA-dependent)": fit_with_report(
            path, "polynomial", scene="radiance", frames="settled")[0],
    }


def _network():
    """The shipped KPN + offset estimator, or None (with the reason) when torch is not
    installed."""
    from thermocal.optional import require

    try:
        require("torch", "the network", "nn")  # an optional dependency
    except InvalidInputError as exc:
        return None, f"network skipped: {exc}"
    return make_estimator("kpn"), ""


KPN_ROW = "KPN + offset (calibration-free)"


def _coverage(estimate: np.ndarray, sigma: list[np.ndarray] | None, truth: np.ndarray,
              valid: np.ndarray) -> dict[str, float]:
    """Median σ and the share of pixels within 1σ and 2σ (nothing without σ)."""
    if not sigma:
        return {}
    cov = metrics.sigma_coverage((estimate - truth)[valid], np.stack(sigma)[valid])
    return {k: cov[k] for k in ("median_sigma_c", "within_1sigma", "within_2sigma")}


def _scores(estimate: np.ndarray, truth: np.ndarray, valid: np.ndarray) -> dict[str, float]:
    return {
        "mae_c": metrics.mae(estimate, truth, valid=valid),
        "rmse_c": metrics.rmse(estimate, truth, valid=valid),
        "within_0.5c": metrics.fraction_within(estimate, truth, 0.5, valid=valid),
    }


def run_demo(out_dir: str | Path, *, unit: int = DEMO_UNIT, size=(336, 256),
             seed: int = 2026) -> dict:
    """Run the demo, print its table, write ``results.json`` and the figures; return results."""
    from rich.console import Console
    from rich.table import Table

    from thermocal.plotting import burst_report_figure, error_cdf_figure, save_figure

    started = time.perf_counter()
    console = Console()
    out = ensure_output_dir(Path(out_dir))
    camera = make_camera("tau2", unit=unit, size=size)
    with tempfile.TemporaryDirectory() as tmp:
        calibrations = calibrate_in_chamber(camera, seed=seed, tmp=Path(tmp))
    network, note = _network()

    scene = load_builtin_scene("aerial")
    flight = simulate_flight(scene, camera, n_frames=N_FRAMES * N_GROUPS, motion="uav",
                             fpa_c=FLIGHT_FPA_C, seed=seed + 1)
    pivots = [g * N_FRAMES + N_FRAMES // 2 for g in range(N_GROUPS)]
    estimates: dict[str, list[np.ndarray]] = {}
    sigmas: dict[str, list[np.ndarray]] = {}
    outside: set[str] = set()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # e.g. the two-point used away from its FPA: shown below
        for pivot in pivots:
            first = pivot - N_FRAMES // 2
            group = flight.frames[first:first + N_FRAMES]
            fpa = flight.fpa_c[first:first + N_FRAMES]
            for name, cal in calibrations.items():
                # force: the two-point is shown away from its FPA, outside its range
                est = estimate(group, PivotCalibration(cal), fpa_c=fpa, force=True)
                estimates.setdefault(name, []).append(est.temperature_c)
                if est.sigma_c is not None:
                    sigmas.setdefault(name, []).append(est.sigma_c)
                if est.outside:
                    outside.add(name)
            if network is not None:
                est = estimate(group, network, fpa_c=fpa)
                estimates.setdefault(KPN_ROW, []).append(est.temperature_c)
                if est.sigma_c is not None:
                    sigmas.setdefault(KPN_ROW, []).append(est.sigma_c)
            oracle = invert(camera, flight.frames[pivot], flight.fpa_true_c[pivot],
                            housing_c=flight.housing_c[pivot])[0]
            estimates.setdefault("true camera model (oracle)", []).append(oracle)

    truth = flight.truth_c[pivots]
    # The unit's few dead and hot pixels carry no information: scored everywhere else.
    valid = np.broadcast_to(~camera.defects, truth.shape)
    rows = [{"method": m, **_scores(np.stack(e), truth, valid),
             **_coverage(np.stack(e), sigmas.get(m), truth, valid)} for m, e in estimates.items()]

    table = Table(title=(
        f"Tau2-class unit {unit} ({size[0]}x{size[1]}), never seen by the network; UAV pass over "
        f"the built-in aerial scene at FPA {FLIGHT_FPA_C:.0f} °C; {N_GROUPS} pivot frames of "
        f"{N_FRAMES}-frame groups; dead/hot pixels excluded"))
    for col in ("method", "MAE °C", "RMSE °C", "within 0.5 °C", "median σ °C", "within 2σ"):
        table.add_column(col, justify="left" if col == "method" else "right")
    for r in rows:
        has_sigma = "median_sigma_c" in r
        table.add_row(r["method"] + (" †" if r["method"] in outside else ""),
                      f"{r['mae_c']:.3f}", f"{r['rmse_c']:.3f}",
                      f"{100 * r['within_0.5c']:.1f} %",
                      f"{r['median_sigma_c']:.2f}" if has_sigma else "–",
                      f"{100 * r['within_2sigma']:.1f} %" if has_sigma else "–")
    console.print(table)
    console.print("σ: each estimate's own standard uncertainty (calibrations: from their "
                  "cross-validation; the network: its σ model); † outside its calibrated range "
                  "(estimated with --force, σ grown)")
    if note:
        console.print(note, markup=False)  # "thermocal[nn]" is no style tag

    shown = {m.split(" (")[0]: e[0] for m, e in estimates.items() if "oracle" not in m}
    figures = {"report.png": burst_report_figure(
        flight.frames[pivots[0]], truth[0], shown, valid=~camera.defects,
        title=f"pivot frame {pivots[0]}, FPA {FLIGHT_FPA_C:.0f} °C, camera unit {unit}")}
    figures["error_cdf.png"] = error_cdf_figure(
        {m: np.stack(e) for m, e in estimates.items()}, truth, valid=valid)
    if KPN_ROW in sigmas:
        from thermocal.plotting import uncertainty_figure

        figures["uncertainty.png"] = uncertainty_figure(
            estimates[KPN_ROW][0], sigmas[KPN_ROW][0], truth[0], valid=~camera.defects,
            title=f"{KPN_ROW}: pivot frame {pivots[0]} and its uncertainty")
    fig7 = _fig7_results()
    if fig7 is not None:
        from thermocal.plotting import mae_vs_frames_figure

        figures["mae_vs_n.png"] = mae_vs_frames_figure(fig7)
    for name, fig in figures.items():
        save_figure(fig, out / name)

    results = {
        "camera": {"preset": "tau2", "unit": unit, "size": list(size)},
        "scene": "aerial (flirpy example_radiometric.tiff, built in)",
        "flight_fpa_c": FLIGHT_FPA_C,
        "pivots": pivots,
        "seed": seed,
        "rows": rows,
        "outside_range": sorted(outside),
        "wall_time_s": time.perf_counter() - started,
    }
    write_json_atomic(out / "results.json", results)
    console.print(f"report written to {out}/ ({', '.join(figures)}, results.json) in "
                  f"{results['wall_time_s']:.1f} s", markup=False)  # a path is no markup
    return results


def _fig7_results() -> dict | None:
    """MAE against N (``benchmarks/kpn_fig7.py``), shipped beside the weights (if present)."""
    path = Path(str(files("thermocal") / "nn" / "weights" / "fig7.json"))
    return json.loads(path.read_text()) if path.is_file() else None
