"""Campaign throughput on a Dask LocalCluster: one worker against two (issue 21).

Four recordings (``tau2`` unit 9, 336×256, UAV passes over four procedural scenes, :data:`FRAMES`
frames each) are processed by :func:`~thermocal.pipeline.campaign.run_campaign` with
``--method mean`` (eq. 9 through the unit's polynomial calibration: registration, calibration,
warping, writing — no network, whose threads would blur the comparison) on a LocalCluster of one
worker and of two, each into a new folder, wall time including the cluster's start. The maps of
every run are compared byte for byte.

Three runs: one worker on this machine's cores (it estimates its share of groups at once), two
workers (a core each), and one worker held to one core (the suite's own process, started
with an affinity of one core: its cluster's processes inherit it). Two workers against the
first say what a campaign gains on this machine over one process using it fully; against
the last, how Dask scales a worker's throughput (the same resources per worker).

Run: ``python -m thermocal.evaluation.suites.campaign [--quick] [--json OUT]`` (``--quick``:
shorter recordings).
"""

from __future__ import annotations

import multiprocessing
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

#: Frames per recording (``--quick``: 70).
FRAMES = 280
RECORDINGS = 4
SIZE = (336, 256)


def recordings_and_calibration(tmp: Path, *, frames: int, count: int = RECORDINGS,
                               size: tuple[int, int] = SIZE) -> tuple[list[Path], Path]:
    """``count`` UAV passes of ``frames`` frames of ``size`` (``tau2`` unit 9, procedural
    scenes) in ``tmp/pass<k>``, and the unit's polynomial calibration ``tmp/cal.h5``."""
    from thermocal.calibration.report import fit_with_report
    from thermocal.camera import make_camera
    from thermocal.scenes.procedural import procedural_scene
    from thermocal.simulate.chamber import ChamberPlan, write_simulated_chamber
    from thermocal.simulate.flight import plan_flight, write_simulated_flight

    camera = make_camera("tau2", unit=9, size=size)
    # set points over the procedural scenes' 16…66 °C: a pass beyond them would be refused
    plan = ChamberPlan(setpoints_c=(10.0, 25.0, 40.0, 55.0, 70.0), frames_per_point=2,
                       profile="sawtooth", ambient_c=(15.0, 35.0), rate_c_per_min=0.2,
                       interval_s=20.0)
    write_simulated_chamber(tmp / "chamber.h5", camera, plan, seed=1)
    # with its report: a calibration file given to a command must carry one
    fit_with_report(tmp / "chamber.h5", "polynomial", frames="settled")[0].save(tmp / "cal.h5")
    recordings = []
    side = 2 * max(size)
    for k in range(count):
        scene = procedural_scene((side, side), rng=np.random.default_rng(k), kind="mixed")
        write_simulated_flight(tmp / f"pass{k}", plan_flight(
            scene, camera, n_frames=frames, motion="uav", fpa_c=28.0, seed=10 + k), camera)
        recordings.append(tmp / f"pass{k}")
    return recordings, tmp / "cal.h5"


#: The runs: (name, workers, whether the process is held to one core).
RUNS = (("1 worker", 1, False), ("2 workers", 2, False), ("1 worker on 1 core", 1, True))


def timed_campaign(recordings: list[Path], target: Path, options: Any, workers: int
                   ) -> dict[str, Any]:
    """The recordings through :func:`~thermocal.pipeline.campaign.run_campaign` on a
    LocalCluster of ``workers`` into ``target``: wall time, the cluster's start, failures, each
    recording's seconds."""
    from thermocal.pipeline.campaign import campaign_tasks, run_campaign

    t = time.perf_counter()
    summary = run_campaign(campaign_tasks(recordings, target, options), target, workers=workers)
    return {"wall_s": time.perf_counter() - t, "failed": summary["failed"],
            "start_s": summary["cluster_start_s"],
            "per_recording_s": [r.get("seconds") for r in summary["recordings"]]}


def _on_one_core(recordings: list[Path], target: Path, options: Any, workers: int,
                 results: Any) -> None:
    """:func:`timed_campaign` in a process of its own held to one core (its first), the
    result put on ``results``."""
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})  # before any thread starts
    results.put(timed_campaign(recordings, target, options, workers))


def run(*, quick: bool) -> dict:
    from thermocal.cores import available_cores
    from thermocal.pipeline.flight import FlightOptions

    frames = 70 if quick else FRAMES
    with tempfile.TemporaryDirectory() as tmp:
        recordings, cal = recordings_and_calibration(Path(tmp), frames=frames)
        options = FlightOptions(method="mean", calibration=str(cal))
        out, maps = {}, {}
        for k, (name, workers, one_core) in enumerate(RUNS):
            target = Path(tmp) / f"out{k}"
            if one_core:  # a fresh process (spawned: no thread of this one's inherited)
                ctx = multiprocessing.get_context("spawn")
                results = ctx.Queue()
                child = ctx.Process(target=_on_one_core,
                                    args=(recordings, target, options, workers, results))
                child.start()
                out[name] = results.get()
                child.join()
            else:
                out[name] = timed_campaign(recordings, target, options, workers)
            out[name]["cores"] = 1 if one_core else available_cores()
            maps[name] = {str(p.relative_to(target)): p.read_bytes()
                          for p in sorted(target.rglob("temps/*.tiff"))}
    work = {w: r["wall_s"] - r["start_s"] for w, r in out.items()}
    first, two, single = (name for name, _, _ in RUNS)
    return {"frames": frames, "recordings": RECORDINGS, "size": list(SIZE), "runs": out,
            "maps": len(maps[first]),
            "identical": all(m == maps[first] for m in maps.values()),
            "speedup": out[first]["wall_s"] / out[two]["wall_s"],
            "speedup_after_start": work[first] / work[two],
            "scaling": out[single]["wall_s"] / out[two]["wall_s"],
            "scaling_after_start": work[single] / work[two]}


def report(res: dict, info: dict) -> str:
    from thermocal.evaluation.tables import markdown_table

    rows = [(name, r["cores"], f"{r['wall_s']:.1f}", f"{r['start_s']:.1f}", r["failed"],
             ", ".join(f"{s:.1f}" for s in r["per_recording_s"] if s is not None))
            for name, r in res["runs"].items()]
    return (f"## Campaigns on a Dask LocalCluster\n\nmachine: {info['machine']}; "
            f"{info['wall_s']:.0f} s\n\ndata: {res['recordings']} recordings of "
            f"{res['frames']} frames, {res['size'][0]}×{res['size'][1]} (`tau2` unit 9, UAV "
            "passes over procedural scenes), `--method mean` through the unit's polynomial "
            "calibration, groups of 7 at stride 7; wall time with the cluster's start.\n\n"
            + markdown_table(("run", "cores", "wall s", "of which the cluster's start s",
                              "failed", "per recording s"), rows)
            + f"\n\nThroughput with 2 workers: **{res['speedup']:.2f}×** one worker's on the "
            f"same cores ({res['speedup_after_start']:.2f}× once the clusters have started); "
            f"**{res['scaling']:.2f}×** one worker's on one core "
            f"({res['scaling_after_start']:.2f}× once started); "
            f"{res['maps']} maps, {'byte-identical' if res['identical'] else 'DIFFERENT'} "
            "between the runs.\n")


def main(argv: list[str] | None = None) -> None:
    from thermocal.bench import suite_main

    suite_main(__doc__, run, report, argv, quick_help="70 frames per recording.")


if __name__ == "__main__":
    main()
