"""How much fixed pattern a calibration leaves in frames of its own camera, of another unit of
its family, and of the other family: the figures behind
``thermocal.calibration.uncertainty.LINE_PATTERN_MAX_C`` (benchmarks/RESULTS.md, "Uncertainty
and refusal").

``polynomial`` is fitted on unit 101 of each family (96×72, the physics benchmark's calibration
session, ``--quick`` timing) and applied to a 5-frame walk over the built-in aerial scene at FPA
30 °C of units 101 and 102 of both families. Prints a Markdown table (4 s on 2 cores)::

    .venv/bin/python benchmarks/another_camera.py
"""

import warnings

import numpy as np

from thermocal.calibration import fit_calibration
from thermocal.camera.presets import make_camera
from thermocal.evaluation.suites import physics
from thermocal.metrics import line_patterns
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.simulate.flight import simulate_flight

SIZE = (96, 72)


def main() -> None:
    scene = load_builtin_scene("aerial")
    print("| calibration of | frames of | rows °C | columns °C | MAE °C |")
    print("|---|---|---|---|---|")
    for family in ("tau2", "boson"):
        cam = make_camera(family, unit=101, size=SIZE)
        session = physics.calibration_session(cam, physics.SESSION_SEED, True)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = fit_calibration(session.session, "polynomial")
        for other, unit in (("tau2", 101), ("tau2", 102), ("boson", 101), ("boson", 102)):
            camera = make_camera(other, unit=unit, size=SIZE)
            fl = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=30.0, seed=3)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                temps = cal.apply(fl.frames, fpa_c=fl.fpa_c)
            rows, cols = line_patterns(temps)
            mae = float(np.abs(temps - fl.truth_c).mean())
            print(f"| {family} 101 | {other} {unit} | {rows:.2f} | {cols:.2f} | {mae:.2f} |")


if __name__ == "__main__":
    main()
