"""Does the cross-validated error that ``thermocal calibrate`` reports hold on another session?

For four chamber protocols (ambient steps, a ramp only, a sawtooth, steps with three set points)
of one simulated camera unit, every calibration method the protocol supports is fitted and
cross-validated (:func:`thermocal.calibration.report.fit_with_report`; ``auto`` is
:func:`~thermocal.calibration.report.auto_calibration`), then applied to a separate session of
the same unit: the same ambient profile run again with other noise and other set points (15…65
°C, between the calibration's), scored within the FPA and scene ranges the calibration covered.
A second held-out session of another profile (a sawtooth; steps for the sawtooth protocol) shows
what no session can foresee: FPA rates it never held.

Prints a Markdown table; ``--size WxH`` (default 160x120) and ``--seed``.

    python benchmarks/calibration_report.py
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

from thermocal.calibration import CALIBRATION_METHODS, prepare_chamber
from thermocal.calibration.report import auto_calibration, fit_with_report
from thermocal.camera.presets import make_camera
from thermocal.errors import FitError
from thermocal.io.chamber import ChamberSession
from thermocal.simulate.chamber import ChamberPlan, simulate_chamber

SETPOINTS = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0)
HELD_OUT_SETPOINTS = (15.0, 25.0, 35.0, 45.0, 55.0, 65.0)
#: protocol → (ambient profile, set points, the other profile held out)
PROTOCOLS = {
    "steps": ("steps", SETPOINTS, "sawtooth"),
    "ramp only": ("ramp", SETPOINTS, "sawtooth"),
    "sawtooth": ("sawtooth", SETPOINTS, "steps"),
    "few set points (3)": ("steps", (10.0, 40.0, 70.0), "sawtooth"),
}
#: What ``thermocal calibrate`` gives the polynomial model.
OPTIONS = {"polynomial": {"scene": "radiance"}}


def session(camera, profile: str, setpoints: tuple[float, ...], seed: int):
    """A chamber session as ``thermocal simulate chamber`` makes it by default (10 s frames,
    0.5 °C/min, ambient 10…40 °C, 6 frames per set point), prepared."""
    plan = ChamberPlan(setpoints_c=setpoints, frames_per_point=6, profile=profile,
                       ambient_c=(10.0, 40.0), interval_s=10.0)
    parts = list(simulate_chamber(camera, plan, seed=seed))
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in (
        "frames", "blackbody_c", "fpa_c", "time_s", "housing_c", "ambient_c")}
    return prepare_chamber(ChamberSession(
        cat.pop("frames"), **cat, attrs={"blackbody_emissivity": plan.emissivity}))


def held_out_mae(cal, held, report) -> float:
    """Mean absolute error, °C, on ``held`` within the report's FPA and scene ranges."""
    lo, hi = report.fpa_range_c
    s_lo, s_hi = report.scene_range_c
    sel = (held.usable & (held.fpa_c >= lo) & (held.fpa_c <= hi) & (held.scene_c >= s_lo)
           & (held.scene_c <= s_hi))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        est = cal.apply(np.asarray(held.session.frames), fpa_c=held.fpa_c, time_s=held.time_s)
    return float(np.abs(est[sel] - held.scene_c[sel, None, None]).mean())


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="160x120", help="frame size WxH")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.split("x"))
    camera = make_camera("tau2", unit=0, size=(width, height))
    print(f"tau2 unit 0, {width}x{height}; held out: seed {args.seed + 10}, set points "
          f"{HELD_OUT_SETPOINTS[0]:g}…{HELD_OUT_SETPOINTS[-1]:g} °C\n")
    print("| protocol | method | reported CV MAE °C | held-out MAE °C | ratio | "
          "other profile held out: MAE °C (ratio) | fit + CV s |")
    print("|---|---|---|---|---|---|---|")
    for name, (profile, points, other) in PROTOCOLS.items():
        data = session(camera, profile, points, args.seed)
        held = session(camera, profile, HELD_OUT_SETPOINTS, args.seed + 10)
        held_other = session(camera, other, HELD_OUT_SETPOINTS, args.seed + 20)
        for method in ("auto", *CALIBRATION_METHODS):
            if method == "shutter":
                continue  # two-point in a chamber (its offsets come from shutter closures)
            start = time.perf_counter()
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    cal, report = (auto_calibration(data, options=OPTIONS) if method == "auto"
                                   else fit_with_report(data, method, **OPTIONS.get(method, {})))
            except FitError as exc:
                why = str(exc).split(";")[0].removeprefix(f"{method} ")
                print(f"| {name} | {method} | refused: {why} | | | | |")
                continue
            seconds = time.perf_counter() - start
            label = f"auto → {report.method}" if method == "auto" else method
            if report.expected_mae_c is None:
                print(f"| {name} | {label} | not measured | | | | {seconds:.1f} |")
                continue
            cv = report.expected_mae_c
            mae = held_out_mae(cal, held, report)
            other_mae = held_out_mae(cal, held_other, report)
            print(f"| {name} | {label} | {cv:.3f} | {mae:.3f} | {cv / mae:.2f} | "
                  f"{other} {other_mae:.3f} ({cv / other_mae:.2f}) | {seconds:.1f} |")


if __name__ == "__main__":
    main()
