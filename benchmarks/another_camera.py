"""Can a calibration tell frames of another camera by the fixed pattern it leaves in them?
(benchmarks/RESULTS.md, "Uncertainty and refusal": tried, and not used.)

``polynomial`` is fitted on unit 101 of each family (96×72, the physics benchmark's calibration
session, ``--quick`` timing) and applied to a 5-frame walk at FPA 30 °C of units 101 and 102 of
both families, over the built-in aerial scene and over procedural urban and farmland maps. The
largest line pattern left (:func:`thermocal.metrics.line_patterns`, rows or columns, °C) and the
MAE. Prints a Markdown table (a few seconds on 2 cores)::

    .venv/bin/python benchmarks/another_camera.py
"""

import warnings

import numpy as np

from thermocal.calibration import fit_calibration
from thermocal.camera.presets import make_camera
from thermocal.evaluation.suites import physics
from thermocal.metrics import line_patterns
from thermocal.scenes.builtin import load_builtin_scene
from thermocal.scenes.procedural import procedural_scene
from thermocal.simulate.flight import simulate_flight

SIZE = (96, 72)


def main() -> None:
    scenes = {"aerial": load_builtin_scene("aerial")}
    for kind in ("urban", "farmland"):
        scenes[kind] = procedural_scene((512, 512), rng=np.random.default_rng(1), kind=kind)
    print("| calibration of | frames of | scene | rows °C | columns °C | MAE °C |")
    print("|---|---|---|---|---|---|")
    for family in ("tau2", "boson"):
        cam = make_camera(family, unit=101, size=SIZE)
        session = physics.calibration_session(cam, physics.SESSION_SEED, True)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = fit_calibration(session.session, "polynomial")
        for other, unit in (("tau2", 101), ("tau2", 102), ("boson", 101), ("boson", 102)):
            camera = make_camera(other, unit=unit, size=SIZE)
            for name, scene in scenes.items():
                fl = simulate_flight(scene, camera, n_frames=5, motion="walk", fpa_c=30.0,
                                     seed=3)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    temps = cal.apply(fl.frames, fpa_c=fl.fpa_c)
                rows, cols = line_patterns(temps)
                mae = float(np.abs(temps - fl.truth_c).mean())
                print(f"| {family} 101 | {other} {unit} | {name} | {rows:.2f} | {cols:.2f} | "
                      f"{mae:.2f} |")


if __name__ == "__main__":
    main()
