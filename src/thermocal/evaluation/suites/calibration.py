"""Calibration benchmarks (issue 3): Wolf et al. Fig. 6a/b, Lin et al. Fig. 6, the polynomial model
on held-out set points, and speed.

Every method is fitted on one simulated chamber session of a camera unit (a program of ambient
steps 5→40 °C with plateaus, then a fast 5↔40 °C sawtooth at 1.5 °C/min; blackbody at 5, 15, …,
75 °C, ε = 0.98) and evaluated on other runs, with blackbody temperatures and FPA states the fit
never saw. Errors are against the blackbody-equivalent (radiance) temperature of the scene; the
camera's few dead/hot pixels are left out of the scores.

Run: ``python benchmarks/calibration.py [--quick] [--json OUT.json]``.
"""

from __future__ import annotations

import argparse
import json
import time
import tracemalloc
import warnings

import numpy as np

from thermocal.bench import machine
from thermocal.calibration import (
    OutsideCalibrationRangeWarning,
    fit_calibration,
    prepare_chamber,
)
from thermocal.camera.model import expected_counts, render
from thermocal.camera.presets import make_camera
from thermocal.camera.thermal import ThermalParams, ambient_profile, fpa_sensor, thermal_response
from thermocal.io.chamber import ChamberSession
from thermocal.simulate.chamber import ChamberPlan, radiance_temperature_c, simulate_chamber

SETPOINTS = (5.0, 15.0, 25.0, 35.0, 45.0, 55.0, 65.0, 75.0)
HELD_OUT = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
LIN_REGIONS = (11.6, 26.4, 67.6, 36.8)
HW_SETPOINTS = (15.0, 25.0, 35.0, 45.0)


def simulate(camera, plans, seed):
    """One session from chamber plans run one after another (1 h apart); and its truth, °C."""
    runs, t0 = [], 0.0
    for i, plan in enumerate(plans):
        parts = list(simulate_chamber(camera, plan, seed=seed + i))
        run = {k: np.concatenate([getattr(p, k) for p in parts]) for k in (
            "frames", "blackbody_c", "fpa_c", "time_s", "housing_c", "ambient_c",
            "fpa_true_c")}
        run["time_s"] = run["time_s"] + t0
        t0 = run["time_s"][-1] + 3600.0
        runs.append(run)
    cat = {k: np.concatenate([r[k] for r in runs]) for k in runs[0]}
    cat.pop("fpa_true_c")
    truth = radiance_temperature_c(cat["blackbody_c"], cat["ambient_c"], plans[0].emissivity,
                                   camera.band)
    attrs = {"blackbody_emissivity": plans[0].emissivity, "unit": camera.info["unit"],
             "preset": "tau2", "seed": seed}
    return ChamberSession(cat.pop("frames"), **cat, attrs=attrs), truth


def calibration_session(camera, seed, quick):
    steps = ChamberPlan(setpoints_c=SETPOINTS, frames_per_point=3, profile="steps",
                        ambient_c=(5.0, 40.0), interval_s=20.0 if quick else 10.0)
    fast = ChamberPlan(setpoints_c=SETPOINTS, frames_per_point=3, profile="sawtooth",
                       ambient_c=(5.0, 40.0), rate_c_per_min=1.5, interval_s=5.0 if quick else 2.0)
    return simulate(camera, [steps, fast], seed)


def rms_per_frame(est, truth, good):
    return np.sqrt(np.mean((est[:, good] - np.asarray(truth)[:, None]) ** 2, axis=1))


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutsideCalibrationRangeWarning)
        return fn(*args, **kwargs)


# ------------------------------------------------------------------------------- Wolf Fig. 6


def bench_wolf(camera, session, seed, quick):
    amb = ThermalParams().ambient_for_fpa_c(20.0)
    plan = ChamberPlan(setpoints_c=(30.0,), frames_per_point=1, profile="ramp",
                       ambient_c=(amb, amb + 15.0), rate_c_per_min=15.0 / 40.0,
                       interval_s=4.0 if quick else 1.0, duration_s=2400.0)
    ev, truth = simulate(camera, [plan], seed)
    good = ~camera.defects
    ref = float(ev.fpa_c[0])
    rows = []
    two = fit_calibration(session, "two-point", fpa_ref_c=ref, fpa_tolerance_c=1.0)
    variants = {
        "two-point (at start FPA)": (two, {}),
        "wolf2016 (Ω on 15-45 °C set points)": (
            fit_calibration(session, "wolf2016", fpa_ref_c=ref, hw_setpoints_c=HW_SETPOINTS), {}),
        "wolf2016 (Ω on all set points)": (fit_calibration(session, "wolf2016", fpa_ref_c=ref),
                                           {}),
    }
    minute = np.floor(ev.time_s / 60.0).astype(int)
    settle = None
    for name, (cal, _) in variants.items():
        est = quiet(cal.apply, ev.frames, fpa_c=ev.fpa_c, time_s=ev.time_s)
        per = rms_per_frame(est, truth, good)
        per_min = [np.sqrt(np.mean(per[minute == m] ** 2)) for m in np.unique(minute)]
        rows.append({"method": name, "rmse_c": float(np.sqrt(np.mean(per**2))),
                     "median_frame_rmse_c": float(np.median(per)),
                     "worst_minute_rmse_c": float(np.max(per_min))})
        if settle is None and name.startswith("wolf2016"):
            settle = lms_settling(cal, ev, truth, good)
            steady = lms_settling(cal, ev, truth, good, hw_start="steady")
            settle["output_frames_to_settle_steady_hw"] = steady["output_frames_to_settle"]
            settle["cold_rmse_at_frame_100_steady_hw_c"] = steady["cold_rmse_at_frame_100_c"]
    return {"frames": int(ev.n_frames), "fpa_start_c": float(ev.fpa_c[0]),
            "fpa_end_c": float(ev.fpa_c[-1]), "interval_s": plan.interval_s, "rows": rows,
            "lms_settling": settle}


def lms_settling(cal, ev, truth, good, **options):
    """Frames for a cold-started stream to match a warm one, ~10 °C above the reference.

    ``options`` go to both streams (e.g. ``hw_start``).
    """
    start = int(np.searchsorted(ev.fpa_c - ev.fpa_c[0], 10.0))
    n = min(300, ev.n_frames - start)
    warm = cal.stream(**options)
    for k in range(start):
        warm.process(ev.frames[k], fpa_c=ev.fpa_c[k], time_s=ev.time_s[k])
    cold = cal.stream(**options)
    err_cold, err_warm, dt_diff = [], [], []
    for k in range(start, start + n):
        tc = cold.process(ev.frames[k], fpa_c=ev.fpa_c[k], time_s=ev.time_s[k])
        tw = warm.process(ev.frames[k], fpa_c=ev.fpa_c[k], time_s=ev.time_s[k])
        err_cold.append(rms_per_frame(tc[None], truth[k : k + 1], good)[0])
        err_warm.append(rms_per_frame(tw[None], truth[k : k + 1], good)[0])
        dt_diff.append(cold.delta_t_c - warm.delta_t_c)

    def settled(ok):
        not_ok = np.flatnonzero(~ok)
        return 0 if not_ok.size == 0 else int(not_ok[-1] + 1)

    err_cold, err_warm = np.array(err_cold), np.array(err_warm)
    return {"start_frame": start, "delta_t_at_start_c": float(ev.fpa_c[start] - ev.fpa_c[0]),
            "first_frame_rmse_c": float(err_cold[0]),
            "lms_frames_to_settle": settled(np.abs(np.array(dt_diff)) < 0.05),
            "output_frames_to_settle": settled(np.abs(err_cold - err_warm) < 0.05),
            "cold_rmse_at_frame_100_c": float(err_cold[min(100, n - 1)])}


# ------------------------------------------------------------------------------- Lin Fig. 6


def four_region_run(camera, seed, quick):
    h, w = camera.shape
    scene = np.empty((h, w))
    scene[: h // 2, : w // 2], scene[: h // 2, w // 2 :] = LIN_REGIONS[0], LIN_REGIONS[1]
    scene[h // 2 :, : w // 2], scene[h // 2 :, w // 2 :] = LIN_REGIONS[2], LIN_REGIONS[3]
    time_s = np.arange(0.0, 2 * 25 / 1.2 * 60, 4.0 if quick else 2.0)
    amb = ambient_profile("sawtooth", time_s, low_c=10.0, high_c=35.0, rate_c_per_min=1.2)
    state = thermal_response(time_s, amb)
    rng = np.random.default_rng(seed)
    sensor = fpa_sensor(state.fpa_c, ThermalParams(), rng=rng)
    frames = render(camera, np.broadcast_to(scene, (time_s.size, h, w)), state.fpa_c,
                    housing_c=state.housing_c, fpa_rate_c_per_min=state.fpa_rate_c_per_min,
                    rng=rng)
    return frames, scene, sensor, time_s, state, rng


def region_masks(camera):
    h, w = camera.shape
    m = 2
    boxes = ((slice(m, h // 2 - m), slice(m, w // 2 - m)),
             (slice(m, h // 2 - m), slice(w // 2 + m, w - m)),
             (slice(h // 2 + m, h - m), slice(m, w // 2 - m)),
             (slice(h // 2 + m, h - m), slice(w // 2 + m, w - m)))
    out = []
    for rows, cols in boxes:
        mask = np.zeros(camera.shape, dtype=bool)
        mask[rows, cols] = True
        out.append(mask & ~camera.defects)
    return out


def bench_lin(camera, session, seed, quick):
    frames, scene, sensor, time_s, state, rng = four_region_run(camera, seed, quick)
    lin = fit_calibration(session, "lin")
    ref = lin.t_ref_c
    shutter = fit_calibration(session, "shutter", fpa_ref_c=ref, interval_s=180.0)
    shut_t = np.arange(0.0, time_s[-1], shutter.interval_s)
    idx = np.searchsorted(time_s, shut_t)
    # the shutter sits inside the housing: it is at the housing temperature, not the FPA's
    shut = render(camera, state.housing_c[idx], state.fpa_c[idx], housing_c=state.housing_c[idx],
                  fpa_rate_c_per_min=state.fpa_rate_c_per_min[idx], rng=rng)
    shutter = shutter.with_shutter(shut, fpa_c=sensor[idx], time_s=shut_t)
    two = fit_calibration(session, "two-point", fpa_ref_c=ref)
    masks = region_masks(camera)
    rows = []
    level = fit_calibration(session, "lin-level")
    for name, cal in (("lin", lin),
                      ("lin-level (extension: eq. 1 linear in the scene level)", level),
                      ("shutter (every 180 s)", shutter),
                      ("two-point (at reference FPA)", two)):
        est = quiet(cal.apply, frames, fpa_c=sensor, time_s=time_s)
        row = {"method": name}
        for t_c, mask in zip(LIN_REGIONS, masks, strict=True):
            err = np.median(est[:, mask], axis=1) - t_c  # the region's reading per frame
            row[f"{t_c}"] = (float(np.abs(err).mean()), float(np.abs(err).max()))
        rows.append(row)
    return {"frames": int(time_s.size), "interval_s": float(time_s[1] - time_s[0]),
            "fpa_range_c": [float(state.fpa_c.min()), float(state.fpa_c.max())],
            "max_fpa_rate_c_per_min": float(np.abs(state.fpa_rate_c_per_min).max()),
            "lin_t_ref_c": ref, "rows": rows}


def bench_lin_diagnosis(camera, session_seed, run_seed, quick):
    """Lin on the same unit with the responsivity's FPA dependence switched off (a test camera;
    the preset is unchanged): is the scene-dependent FPA slope what eq. 1 cannot follow?"""
    from dataclasses import replace

    gain = camera.gain.copy()
    gain[1:] = 0.0  # G_p(t_fpa) = G_p(t_ref): no responsivity change with the FPA temperature
    flat = replace(camera, gain=gain)
    session, _ = calibration_session(flat, session_seed, quick)
    frames, _, sensor, time_s, _, _ = four_region_run(flat, run_seed, quick)
    row = {"method": "lin, responsivity independent of the FPA temperature (diagnosis)"}
    est = quiet(fit_calibration(session, "lin").apply, frames, fpa_c=sensor, time_s=time_s)
    for t_c, mask in zip(LIN_REGIONS, region_masks(flat), strict=True):
        err = np.median(est[:, mask], axis=1) - t_c
        row[f"{t_c}"] = (float(np.abs(err).mean()), float(np.abs(err).max()))
    return row


# ------------------------------------------------------------------------------- polynomial


def held_out_run(camera, seed, quick):
    plan = ChamberPlan(setpoints_c=HELD_OUT, frames_per_point=2, profile="steps",
                       ambient_c=(7.0, 37.0), interval_s=30.0 if quick else 15.0)
    return simulate(camera, [plan], seed)


def bench_polynomial(cam_a, cam_b, sess_a, sess_b, seed, quick):
    ev_a, truth_a = held_out_run(cam_a, seed, quick)
    ev_b, truth_b = held_out_run(cam_b, seed + 1, quick)
    rows = []
    cals = {}
    for scene in ("radiance", "t4", "linear"):
        cals[("A", scene)] = fit_calibration(sess_a, "polynomial", scene=scene)
    cals[("B", "radiance")] = fit_calibration(sess_b, "polynomial", scene="radiance")
    cals[("A-radial", "radiance")] = cals[("A", "radiance")].radial(order=4)

    def score(cal, ev, truth, cam):
        data = prepare_chamber(ev)
        lo, hi = cal.fpa_range_c
        inside = (data.stability == 0) & (ev.fpa_c >= lo) & (ev.fpa_c <= hi)
        est = quiet(cal.apply, ev.frames[inside], fpa_c=ev.fpa_c[inside])
        err = est[:, ~cam.defects] - truth[inside][:, None]
        return float(np.abs(err).mean()), float(np.percentile(np.abs(err), 99)), int(inside.sum())

    for (fit_on, scene), cal in cals.items():
        targets = [("A", ev_a, truth_a, cam_a), ("B", ev_b, truth_b, cam_b)]
        for unit, ev, truth, cam in targets:
            if fit_on == "B" and unit == "A":
                continue
            mae, p99, n = score(cal, ev, truth, cam)
            rows.append({"fitted_on": fit_on, "scene_term": scene, "applied_to": unit,
                         "mae_c": mae, "p99_abs_c": p99, "frames": n})
    # as a degradation model (what the network is trained on): counts error against unit B
    model_rows = []
    from thermocal.calibration import camera_model_from_chamber
    from thermocal.camera.presets import radial_map

    r = radial_map(cam_b.shape).astype(np.float64)
    basis = np.stack([r**j for j in range(5)], axis=-1)
    good = ~cam_b.defects
    for name, radial in (("per-pixel model of A", False), ("radial model of A", True)):
        model = camera_model_from_chamber(sess_a, radial=radial)
        errs, radial_part, fpn_part = [], [], []
        for scene_c, fpa_c in ((15.0, 20.0), (35.0, 28.0), (60.0, 36.0)):
            fitted = expected_counts(model, scene_c, fpa_c)[0]
            true = expected_counts(cam_b, scene_c, fpa_c, housing_c=fpa_c - 1.5)[0]
            err = (fitted - true).astype(np.float64)
            coef, *_ = np.linalg.lstsq(basis[good], err[good], rcond=None)
            smooth = basis @ coef
            errs.append(np.sqrt(np.mean(err[good] ** 2)))
            radial_part.append(np.sqrt(np.mean(smooth[good] ** 2)))
            fpn_part.append(np.sqrt(np.mean((err - smooth)[good] ** 2)))
        model_rows.append({"model": name, "rms_counts_vs_B": float(np.mean(errs)),
                           "radial_part": float(np.mean(radial_part)),
                           "non_radial_part": float(np.mean(fpn_part))})
    return {"rows": rows, "model_rows": model_rows,
            "frames_held_out": [int(ev_a.n_frames), int(ev_b.n_frames)]}


# ------------------------------------------------------------------------------- speed


def bench_speed(quick):
    cam = make_camera("tau2", unit=0, size=(640, 512))
    scale = 5 if quick else 1
    steps = ChamberPlan(setpoints_c=SETPOINTS, frames_per_point=3, profile="steps",
                        ambient_c=(5.0, 40.0), interval_s=10.0 * scale)
    fast = ChamberPlan(setpoints_c=SETPOINTS, frames_per_point=3, profile="sawtooth",
                       ambient_c=(5.0, 40.0), rate_c_per_min=1.5, interval_s=2.5 * scale)
    session, _ = simulate(cam, [steps, fast], 77)
    n = session.n_frames
    tracemalloc.start()
    t = time.perf_counter()
    poly = fit_calibration(session, "polynomial", frames="all", chunk=32)
    fit_s = time.perf_counter() - t
    peak_mb = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    frames_mb = session.frames.nbytes / 2**20
    cals = {"polynomial": poly, "two-point": fit_calibration(session, "two-point"),
            "shutter": fit_calibration(session, "shutter"),
            "wolf2016": fit_calibration(session, "wolf2016"),
            "lin": fit_calibration(session, "lin"),
            "lin-level": fit_calibration(session, "lin-level")}
    frame = session.frames[n // 2]
    fpa = float(session.fpa_c[n // 2])
    apply_ms = {}
    for name, cal in cals.items():
        if name == "wolf2016":
            stream = cal.stream()
            for k in range(stream.warmup_frames + 1):  # past the warm-up: LMS every 0.5 s
                stream.process(frame, fpa_c=fpa, time_s=k / 30.0)
            clock = [stream.warmup_frames / 30.0]

            def fn(stream=stream, clock=clock):
                clock[0] += 1 / 30.0  # 30 Hz recording: the LMS runs on every 15th frame
                stream.process(frame, fpa_c=fpa, time_s=clock[0])
        else:
            def fn(cal=cal):
                quiet(cal.apply, frame, fpa_c=fpa, time_s=0.0)
        fn()
        times = []
        for _ in range(20):
            t = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t)
        apply_ms[name] = 1000 * float(np.median(times))
    return {"frames": n, "fit_s": fit_s, "fit_s_per_2000": fit_s * 2000 / n,
            "fit_peak_mb": peak_mb, "frames_in_memory_mb": frames_mb, "apply_ms": apply_ms}


# ------------------------------------------------------------------------------- report


def report(res):
    lines = [f"Machine: {res['machine']}. Camera: tau2 preset, unit A = {res['units'][0]}, unit "
             f"B = {res['units'][1]}, {res['size'][0]}x{res['size'][1]} px (speed: 640x512). "
             f"Calibration session per unit: {res['calibration_frames']} frames (ambient steps "
             "5→40 °C, then a 1.5 °C/min sawtooth; blackbody 5…75 °C step 10, ε = 0.98).", ""]
    for key, label in (("wolf", "unit A"), ("wolf_b", "unit B")):
        w = res[key]
        lines += [f"### Wolf et al. Fig. 6a/b — blackbody 30 °C, FPA {w['fpa_start_c']:.1f} → "
                  f"{w['fpa_end_c']:.1f} °C in 40 min ({w['frames']} frames every "
                  f"{w['interval_s']} s), {label}", "",
                  "| method | RMSE °C | median frame RMSE °C | worst minute RMSE °C |",
                  "|---|---|---|---|"]
        for r in w["rows"]:
            lines.append(f"| {r['method']} | {r['rmse_c']:.3f} | {r['median_frame_rmse_c']:.3f}"
                         f" | {r['worst_minute_rmse_c']:.3f} |")
        s = w["lms_settling"]
        lines += ["", f"Cold start (ΔT̂ = 0, HW state on the ramp fitted to the first FPA "
                  f"samples) at ΔT = {s['delta_t_at_start_c']:.1f} °C, {w['interval_s']} s per "
                  f"frame: first-frame RMSE {s['first_frame_rmse_c']:.2f} °C; the LMS estimate "
                  f"ΔT̂ is within 0.05 °C of a warm stream's after {s['lms_frames_to_settle']} "
                  f"frames; the output RMSE is within 0.05 °C of the warm stream's after "
                  f"{s['output_frames_to_settle']} frames; RMSE at frame 100: "
                  f"{s['cold_rmse_at_frame_100_c']:.2f} °C. With the HW state settled at the "
                  f"first FPA sample instead (hw_start='steady'): the output after "
                  f"{s['output_frames_to_settle_steady_hw']} frames, RMSE at frame 100 "
                  f"{s['cold_rmse_at_frame_100_steady_hw_c']:.2f} °C.", ""]
    for key, label in (("lin", "unit A"), ("lin_b", "unit B")):
        lin = res[key]
        lines += [f"### Lin et al. Fig. 6 — four blackbody regions, ambient 10 → 35 → 10 °C, FPA "
                  f"{lin['fpa_range_c'][0]:.1f}…{lin['fpa_range_c'][1]:.1f} °C, max rate "
                  f"{lin['max_fpa_rate_c_per_min']:.2f} °C/min ({lin['frames']} frames), {label}",
                  "", "| method | " + " | ".join(f"{t} °C mean / max abs" for t in LIN_REGIONS)
                  + " |", "|---|" + "---|" * len(LIN_REGIONS)]
        for r in lin["rows"]:
            lines.append(f"| {r['method']} | " + " | ".join(
                f"{r[str(t)][0]:.2f} / {r[str(t)][1]:.2f}" for t in LIN_REGIONS) + " |")
        lines.append("")
    p = res["polynomial"]
    lines += ["### Polynomial model — held-out set points 10…70 °C, stable frames inside the "
              "calibrated FPA range", "",
              "| fitted on | scene term | applied to | MAE °C | 99th pct abs °C | frames |",
              "|---|---|---|---|---|---|"]
    for r in p["rows"]:
        lines.append(f"| {r['fitted_on']} | {r['scene_term']} | {r['applied_to']} | "
                     f"{r['mae_c']:.3f} | {r['p99_abs_c']:.3f} | {r['frames']} |")
    lines += ["", "Degradation model fitted on unit A (camera_model_from_chamber) against unit B's "
              "true expected counts (3 scene/FPA pairs; error split into its radial least-squares "
              "part and the rest, i.e. FPN):", "",
              "| degradation model | RMS error, counts | radial part | non-radial (FPN) part |",
              "|---|---|---|---|"]
    for r in p["model_rows"]:
        lines.append(f"| {r['model']} | {r['rms_counts_vs_B']:.1f} | {r['radial_part']:.1f} | "
                     f"{r['non_radial_part']:.1f} |")
    sp = res["speed"]
    lines += ["", "### Speed (640x512)", "",
              "| what | result | target |", "|---|---|---|",
              f"| polynomial fit, {sp['frames']} frames | {sp['fit_s']:.2f} s "
              f"({sp['fit_s_per_2000']:.1f} s per 2,000 frames), peak extra memory "
              f"{sp['fit_peak_mb']:.0f} MiB (frames: {sp['frames_in_memory_mb']:.0f} MiB) | "
              "≤ 10 s / 2,000 frames |"]
    for name, ms in sp["apply_ms"].items():
        what = "(stream at 30 Hz after the warm-up)" if name == "wolf2016" else ""
        lines.append(f"| apply {name}, one frame {what}| {ms:.1f} ms | ≤ 5 ms |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small frames, coarse time steps")
    ap.add_argument("--json", help="write the results to this JSON file")
    args = ap.parse_args(argv)
    quick = args.quick
    size = (96, 64) if quick else (336, 256)
    started = time.perf_counter()
    cam_a = make_camera("tau2", unit=0, size=size)
    cam_b = make_camera("tau2", unit=1, size=size)
    sess_a, _ = calibration_session(cam_a, 100, quick)
    sess_b, _ = calibration_session(cam_b, 200, quick)
    res = {"machine": machine(), "quick": quick, "size": list(size), "units": [0, 1],
           "calibration_frames": int(sess_a.n_frames)}
    res["wolf"] = bench_wolf(cam_a, sess_a, 300, quick)
    res["wolf_b"] = bench_wolf(cam_b, sess_b, 301, quick)
    res["lin"] = bench_lin(cam_a, sess_a, 400, quick)
    res["lin_b"] = bench_lin(cam_b, sess_b, 401, quick)
    res["lin"]["rows"].append(bench_lin_diagnosis(cam_a, 100, 400, quick))
    res["polynomial"] = bench_polynomial(cam_a, cam_b, sess_a, sess_b, 500, quick)
    res["speed"] = bench_speed(quick)
    res["wall_time_s"] = time.perf_counter() - started
    print(report(res))
    print(f"\n(total {res['wall_time_s']:.0f} s)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=2)


if __name__ == "__main__":
    main()
