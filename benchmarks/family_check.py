"""The network's family check on passes whose scene has lines of its own (crop rows, roads):
how often each family's bursts are refused, frame by frame and without the registered scene.

Flights of ``--frames`` frames (bursts of 7, stride 7) of the ``tau2`` and ``boson`` presets at
FPA 30 °C, one unit and procedural scene per seed (as ``thermocal simulate flight`` makes them),
per row of the table: UAV passes at 160×120 (with the simulator's attitude jitter, and without:
a gimbal-steady camera whose scene slides along the rows alone) and 336×256, walks, and UAV
passes over three
photographed scenes (``shared/data/scenes``, skipped when absent). For each burst, through the
shipped network's nominal calibration: the cross-line to own-line pattern ratio frame by frame
(:func:`thermocal.metrics.line_patterns`, refused above
:data:`~thermocal.nn.validity.LINE_RATIO_MAX`) and without the scene
(:func:`thermocal.nn.validity.family_lines` given the registered burst, refused above
:data:`~thermocal.nn.validity.FIXED_RATIO_MAX` for a burst that moved). Prints a Markdown
table (about a minute per 40 seeds on 2 cores)::

    .venv/bin/python benchmarks/family_check.py [--seeds 10-29] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import functools
import json
import time
from pathlib import Path
from unittest import mock

import numpy as np

from thermocal._validate import parse_units
from thermocal.bench import machine
from thermocal.burst import find_homographies
from thermocal.camera.presets import make_camera
from thermocal.cli import load_scene_or_procedural
from thermocal.errors import RegistrationError
from thermocal.metrics import line_patterns
from thermocal.nn.infer import NetworkEstimator
from thermocal.nn.validity import (
    FIXED_RATIO_MAX,
    LINE_RATIO_MAX,
    UNCROSSED_RATIO_MAX,
    family_lines,
)
from thermocal.registration.warp import warp_to_pivot
from thermocal.scenes import trajectory
from thermocal.simulate.flight import simulate_flight

N = 7
PHOTOS = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "scenes"
PHOTO_SCENES = ("11_ir_moving_car", "05_aqua_tower_thermal_image", "14_kujawy_wiatrak")


def ratios(network: NetworkEstimator, frames: np.ndarray, fpa_c: np.ndarray, time_s: np.ndarray
           ) -> tuple[float, float, float] | None:
    """A burst's cross/own line-pattern ratios for the ``tau2`` family (columns): frame by
    frame, and as the check reads them (:func:`thermocal.nn.validity.family_lines`) with the
    limit it holds that one to; None when it cannot be registered."""
    try:
        hs = find_homographies(frames, N // 2, None)
    except RegistrationError:
        return None
    calibrated = network.calibrate(frames, fpa_c, time_s)
    rows, cols = line_patterns(calibrated)
    warped, valid = warp_to_pivot(calibrated, hs)
    own, cross, limit, _ = family_lines(calibrated, "column", warped_c=warped, valid=valid,
                                        homographies=hs)
    return rows / cols, (cross / own if own > 0 else float("inf")), limit


def _flight(scene_c: np.ndarray, camera, n_frames: int, motion: str, seed: int):
    """:func:`simulate_flight`; ``motion`` ``"steady"``: a UAV pass without the simulator's
    attitude jitter (a gimbal-steady camera: the scene slides along the rows alone)."""
    if motion != "steady":
        return simulate_flight(scene_c, camera, n_frames=n_frames, motion=motion, seed=seed)
    steady = functools.partial(trajectory.uav_homographies, attitude_jitter_deg=0.0)
    with mock.patch.object(trajectory, "uav_homographies", steady):
        return simulate_flight(scene_c, camera, n_frames=n_frames, motion="uav", seed=seed)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="10-29", help="procedural scenes and units (unit = 90 + "
                    "seed), A-B")
    ap.add_argument("--frames", type=int, default=35, help="frames per flight")
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    seeds = parse_units(args.seeds)
    network = NetworkEstimator.from_file("kpn")
    settings = [("UAV, 160×120", (160, 120), "uav", seeds),
                ("UAV, gimbal-steady (no attitude jitter), 160×120", (160, 120), "steady",
                 seeds),
                ("UAV, 336×256", (336, 256), "uav", seeds[:4]),
                ("walk, 160×120", (160, 120), "walk", seeds[:4])]
    photos = [name for name in PHOTO_SCENES if (PHOTOS / f"{name}.jpg").is_file()]
    if photos:
        settings.append(("UAV over photographs, 160×120", (160, 120), "uav", photos))
    started = time.perf_counter()
    rows = []
    for label, size, motion, which in settings:
        for preset in ("tau2", "boson"):
            frame_ratio, fixed_ratio, refused, unregistered = [], [], 0, 0
            for k, item in enumerate(which):
                seed = item if isinstance(item, int) else k
                scene = "procedural" if isinstance(item, int) else str(PHOTOS / f"{item}.jpg")
                scene_c, _ = load_scene_or_procedural(scene, seed=seed)
                camera = make_camera(preset, unit=90 + seed, size=size)
                flight = _flight(scene_c, camera, args.frames, motion, seed)
                for g in range(0, args.frames - N + 1, N):
                    got = ratios(network, flight.frames[g:g + N], flight.fpa_c[g:g + N],
                                 flight.time_s[g:g + N])
                    if got is None:
                        unregistered += 1
                        continue
                    frame_ratio.append(got[0])
                    fixed_ratio.append(got[1])
                    refused += got[1] > got[2]
            a, b = np.array(frame_ratio), np.array(fixed_ratio)
            rows.append({"setting": label, "preset": preset, "bursts": int(a.size),
                         "unregistered": unregistered,
                         "frame_ratio": [float(a.min()), float(a.max())],
                         "frame_refused": int(np.sum(a > LINE_RATIO_MAX)),
                         "fixed_ratio": [float(b.min()), float(b.max())],
                         "fixed_refused": int(refused)})
    print("## The network's family check on a moving scene (`benchmarks/family_check.py`)\n")
    print(f"{machine()}; the shipped network's nominal calibration (`tau2`, columns); bursts of "
          f"{N}, FPA 30 °C, flights of {args.frames} frames, seeds {args.seeds} (unit 90 + seed)"
          f"; {time.perf_counter() - started:.0f} s\n")
    print(f"| pass | family | bursts | frame by frame: ratio | refused (> {LINE_RATIO_MAX:g}) "
          f"| without the scene: ratio | refused (> {FIXED_RATIO_MAX:g}; > "
          f"{UNCROSSED_RATIO_MAX:g}·√(120/H) with the rows not crossed) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['setting']} | {r['preset']} | {r['bursts']} | "
              f"{r['frame_ratio'][0]:.2f}–{r['frame_ratio'][1]:.2f} | {r['frame_refused']} | "
              f"{r['fixed_ratio'][0]:.2f}–{r['fixed_ratio'][1]:.2f} | {r['fixed_refused']} |")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
