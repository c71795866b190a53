"""Campaign throughput on a Dask LocalCluster: one worker against two (issue 21).

Four recordings (``tau2`` unit 9, 336×256, UAV passes over four procedural scenes, :data:`FRAMES`
frames each) are processed by :func:`~thermocal.pipeline.campaign.run_campaign` with
``--method mean`` (eq. 9 through the unit's polynomial calibration: registration, calibration,
warping, writing — no network, whose threads would blur the comparison) on a LocalCluster of one
worker and of two, each into a new folder, wall time including the cluster's start. The maps of
both runs are compared byte for byte.

Run: ``python -m thermocal.evaluation.suites.campaign [--quick] [--json OUT]`` (``--quick``:
shorter recordings).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

#: Frames per recording (``--quick``: 70).
FRAMES = 280
RECORDINGS = 4
SIZE = (336, 256)


def recordings_and_calibration(tmp: Path, *, frames: int, count: int = RECORDINGS,
                               size: tuple[int, int] = SIZE) -> tuple[list[Path], Path]:
    """``count`` UAV passes of ``frames`` frames of ``size`` (``tau2`` unit 9, procedural
    scenes) in ``tmp/pass<k>``, and the unit's polynomial calibration ``tmp/cal.h5``."""
    from thermocal.calibration import fit_calibration
    from thermocal.camera import make_camera
    from thermocal.scenes.procedural import procedural_scene
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
    from thermocal.simulate.flight import plan_flight, write_simulated_flight

    camera = make_camera("tau2", unit=9, size=size)
    plan = ChamberPlan(setpoints_c=(10.0, 20.0, 30.0, 40.0, 50.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.2,
                       interval_s=20.0)
    write_simulated_chamber(tmp / "chamber.h5", camera, plan, seed=1)
    fit_calibration(tmp / "chamber.h5", method="polynomial", frames="settled").save(tmp / "cal.h5")
    recordings = []
    side = 2 * max(size)
    for k in range(count):
        scene = procedural_scene((side, side), rng=np.random.default_rng(k), kind="mixed")
        write_simulated_flight(tmp / f"pass{k}", plan_flight(
            scene, camera, n_frames=frames, motion="uav", fpa_c=28.0, seed=10 + k), camera)
        recordings.append(tmp / f"pass{k}")
    return recordings, tmp / "cal.h5"


def run(*, quick: bool) -> dict:
    from thermocal.pipeline.campaign import campaign_tasks, run_campaign
    from thermocal.pipeline.flight import FlightOptions

    frames = 70 if quick else FRAMES
    with tempfile.TemporaryDirectory() as tmp:
        recordings, cal = recordings_and_calibration(Path(tmp), frames=frames)
        options = FlightOptions(method="mean", calibration=str(cal))
        out, maps = {}, {}
        for workers in (1, 2):
            target = Path(tmp) / f"out{workers}"
            t = time.perf_counter()
            summary = run_campaign(campaign_tasks(recordings, target, options), target,
                                   workers=workers)
            out[workers] = {"wall_s": time.perf_counter() - t, "failed": summary["failed"],
                            "start_s": summary["cluster_start_s"],
                            "per_recording_s": [r.get("seconds") for r in
                                                summary["recordings"]]}
            maps[workers] = {str(p.relative_to(target)): p.read_bytes()
                             for p in sorted(target.rglob("temps/*.tiff"))}
    work = {w: r["wall_s"] - r["start_s"] for w, r in out.items()}
    return {"frames": frames, "recordings": RECORDINGS, "size": list(SIZE), "runs": out,
            "maps": len(maps[1]), "identical": maps[1] == maps[2],
            "speedup": out[1]["wall_s"] / out[2]["wall_s"],
            "speedup_after_start": work[1] / work[2]}


def report(res: dict, info: dict) -> str:
    from thermocal.evaluation.tables import markdown_table

    rows = [(w, f"{r['wall_s']:.1f}", f"{r['start_s']:.1f}", r["failed"],
             ", ".join(f"{s:.1f}" for s in r["per_recording_s"] if s is not None))
            for w, r in res["runs"].items()]
    return (f"## Campaigns on a Dask LocalCluster\n\nmachine: {info['machine']}; "
            f"{info['wall_s']:.0f} s\n\ndata: {res['recordings']} recordings of "
            f"{res['frames']} frames, {res['size'][0]}×{res['size'][1]} (`tau2` unit 9, UAV "
            "passes over procedural scenes), `--method mean` through the unit's polynomial "
            "calibration, groups of 7 at stride 7; wall time with the cluster's start.\n\n"
            + markdown_table(("workers", "wall s", "of which the cluster's start s", "failed",
                              "per recording s"), rows)
            + f"\n\nThroughput with 2 workers: **{res['speedup']:.2f}×** one worker's "
            f"({res['speedup_after_start']:.2f}× once the clusters have started); "
            f"{res['maps']} maps, {'byte-identical' if res['identical'] else 'DIFFERENT'} "
            "between the two runs.\n")


def main(argv: list[str] | None = None) -> None:
    from thermocal.bench import suite_main

    suite_main(__doc__, run, report, argv, quick_help="70 frames per recording.")


if __name__ == "__main__":
    main()
