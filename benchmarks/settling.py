"""Which calibrations the report warns of plateaus that ended before the camera settled
(``thermocal.calibration.report.settling_warning``), on the physics suite's chamber sessions
(20-minute ambient steps, then a sawtooth) of each camera family: per method, the units warned
and the slopes the warnings give (°C/min).

Run: ``python benchmarks/settling.py [--units 101-105] [--size 96x72]`` (about a minute per
unit on 2 cores)."""

import argparse
import re
import time
import warnings

from thermocal._validate import parse_units
from thermocal.bench import machine
from thermocal.calibration.registry import CALIBRATION_METHODS
from thermocal.calibration.report import fit_with_report
from thermocal.camera.presets import PRESETS, make_camera
from thermocal.errors import ThermocalError
from thermocal.evaluation.suites import physics

_SLOPE = re.compile(r"still changing by ([-+][0-9.]+) °C/min")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--units", default="101-105")
    ap.add_argument("--size", default="96x72")
    args = ap.parse_args()
    units = parse_units(args.units)
    size = tuple(int(v) for v in args.size.split("x"))
    started = time.perf_counter()
    rows = {}
    for family in PRESETS:
        for unit in units:
            cam = make_camera(family, unit=unit, size=size)
            run = physics.calibration_session(cam, physics.SESSION_SEED + unit - physics.UNIT,
                                              False)
            ref = physics.plateau_fpa_c(run.session)
            for name, info in CALIBRATION_METHODS.items():
                if not info.auto:
                    continue
                options = {"fpa_ref_c": ref} if info.takes_fpa_ref else {}
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        _, report = fit_with_report(run.session, name, **options)
                except ThermocalError:
                    continue
                said = [_SLOPE.search(w) for w in report.warnings if "settled" in w]
                row = rows.setdefault((family, name), {"memoryless": info.memoryless,
                                                       "units": [], "warned": []})
                row["units"].append(unit)
                if said and said[0]:
                    row["warned"].append(float(said[0].group(1)))
    print(f"## Plateaus that end before the camera settles\n\nmachine: {machine()}; "
          f"{time.perf_counter() - started:.0f} s\n\ndata: the physics suite's calibration "
          f"sessions (20-minute ambient steps 5→40 °C, then a 1.5 °C/min sawtooth), {args.size}, "
          f"units {args.units}; `python benchmarks/settling.py --units {args.units} --size "
          f"{args.size}`\n")
    print("| family | method | judged (no memory of the FPA's pace) | units warned | slopes "
          "°C/min |\n|---|---|---|---|---|")
    for (family, name), row in rows.items():
        slopes = sorted(row["warned"])
        print(f"| {family} | {name} | {'yes' if row['memoryless'] else 'no'} | "
              f"{len(slopes)} of {len(row['units'])} | "
              f"{f'{slopes[0]:+.2f}…{slopes[-1]:+.2f}' if slopes else '–'} |")


if __name__ == "__main__":
    main()
