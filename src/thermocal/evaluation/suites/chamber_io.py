"""How fast a chamber session is read and fitted, against the machine's memory bandwidth (issue 21).

A session of :data:`FRAMES` frames of 640×512 (``thermocal simulate chamber``: blackbody
10…70 °C, ambient steps 10…40 °C, a frame every 4 s) is written to a temporary folder once;
then, on the same machine in one run:

- ``thermocal calibrate --method polynomial`` as a user runs it (a new process: imports, the
  session's checks, the fit, its cross-validation, the file written), :data:`RUNS` times;
- the fit alone (:func:`~thermocal.calibration.registry.fit_calibration`, in this process) and
  the bytes of frames it reads per second, against the rate of a plain memory copy
  (``numpy.copyto`` of :data:`COPY_MB` MB) — the limit a pass over frames can reach;
- the fit's accumulation alone on one core (:func:`accumulate_rate`): twice its rate is the
  most this numpy fit can read on two cores, its ceiling against the memory copy;
- the same frames the fit reads, read through h5py chunk by chunk (how the reader read them
  before) and through :func:`thermocal.io.chamber.frame_offsets` (how it reads them now).

The session is written to ``/dev/shm`` (memory) where there is room, and read once before
anything is timed, so that what is timed is memory, not the disk: on this project's machine the
disk gives 30–100 MB/s and the page cache keeps only about 1–2.5 GB, less than a session
and its copies.

Run: ``python -m thermocal.evaluation.suites.chamber_io [--quick] [--json OUT]`` (``--quick``:
320×256, 3 runs). Needs about 1.4 GB of disk in the temporary folder.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

#: Frames of the session (``--interval-s 4`` over the steps protocol gives 2,100).
FRAMES = 2100
#: ``thermocal calibrate`` runs timed (``--quick``: 3).
RUNS = 5
#: Megabytes a memory copy moves to measure the bandwidth.
COPY_MB = 512


def _memory_folder(need_bytes: int = 3 << 30) -> str | None:
    """``/dev/shm`` (memory, not disk) where it exists with room, else None (the default
    temporary folder)."""
    try:
        st = os.statvfs("/dev/shm")
    except OSError:
        return None
    return "/dev/shm" if st.f_bavail * st.f_frsize > need_bytes else None


def _simulate(path: Path, size: str) -> None:
    subprocess.run([sys.executable, "-m", "thermocal.cli", "simulate", "chamber", str(path),
                    "--size", size, "--blackbody-c", "10:70:10", "--ambient-profile", "steps",
                    "--ambient-c", "10:40", "--interval-s", "4"], check=True,
                   capture_output=True)


def _calibrate_times(path: Path, out: Path, runs: int) -> list[float]:
    times = []
    for _ in range(runs):
        out.unlink(missing_ok=True)
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "thermocal.cli", "calibrate", str(path),
                        "--method", "polynomial", "--out", str(out)], check=True,
                       capture_output=True)
        times.append(time.perf_counter() - t)
    return times


def copy_rate(mb: int = COPY_MB, rounds: int = 5) -> float:
    """Bytes per second of ``numpy.copyto`` between two ``mb``-MB arrays (both touched first)."""
    src = np.ones(mb << 18, dtype=np.float32)
    dst = np.zeros_like(src)
    times = []
    for _ in range(rounds):
        t = time.perf_counter()
        np.copyto(dst, src)
        times.append(time.perf_counter() - t)
    return src.nbytes / float(np.median(times))


def accumulate_rate(shape: tuple[int, int], *, frames: int = 64, rounds: int = 5) -> float:
    """Bytes of frames per second the fit's accumulation
    (:func:`thermocal.calibration.polynomial._accumulate`: the counts centred, their product
    with the 8 design columns, Σy²) reads on one core, BLAS on one thread: a block of
    ``frames`` random 14-bit frames of ``shape``, its best of ``rounds``. Twice this is the
    most the numpy fit can read on two cores, whatever else it does."""
    from threadpoolctl import threadpool_limits

    from thermocal.calibration.polynomial import _accumulate

    rng = np.random.default_rng(0)
    n = shape[0] * shape[1]
    counts = rng.integers(3000, 9000, (frames, n)).astype(np.uint16)
    at = rng.random((8, frames)).astype(np.float32)
    ref = counts[0].astype(np.float32)
    aty, yy = np.zeros((8, n)), np.zeros(n)
    times = []
    with threadpool_limits(limits=1, user_api="blas"):
        for _ in range(rounds):
            t = time.perf_counter()
            _accumulate(counts, at, ref, aty, yy, slice(0, n))
            times.append(time.perf_counter() - t)
    return counts.nbytes / min(times)


def _reads(path: Path, index: np.ndarray) -> dict:
    """The frames ``index`` read per frame through h5py and through their file offsets, s."""
    import h5py

    from thermocal.io.chamber import _pread_frames, frame_offsets

    with h5py.File(path, "r") as f:
        dset = f["frames"]
        out = np.empty((index.size, *dset.shape[1:]), dtype=np.uint16)
        out[:] = 1  # mapped before the clock starts, for both reads
        t = time.perf_counter()
        for k, i in enumerate(index):
            dset.read_direct(out, np.s_[i : i + 1], np.s_[k : k + 1])
        h5 = time.perf_counter() - t
        offsets = frame_offsets(dset, path.stat().st_size)
    expected = out.copy()
    out[:] = 0  # the same memory, already mapped: what is timed is the reading
    t = time.perf_counter()
    _pread_frames(path, offsets, index, out.shape[1:], out=out)
    direct = time.perf_counter() - t
    if not np.array_equal(out, expected):
        raise RuntimeError("the two reads differ")
    return {"h5py_s": h5, "offsets_s": direct, "bytes": int(out.nbytes)}


def run(*, quick: bool) -> dict:
    from thermocal.calibration.dataset import prepare_chamber, stability_mask
    from thermocal.calibration.registry import fit_calibration
    from thermocal.io.chamber import read_chamber

    size = "320x256" if quick else "640x512"
    runs = 3 if quick else RUNS
    with tempfile.TemporaryDirectory(dir=_memory_folder()) as tmp:
        path = Path(tmp) / "chamber.h5"
        _simulate(path, size)
        with open(path, "rb") as f:  # into the page cache: what is timed is not the disk
            while f.read(1 << 26):
                pass
        session = read_chamber(path, frames=False)
        data = prepare_chamber(session)
        used = np.flatnonzero(data.usable & stability_mask(data, "stable"))
        reads = _reads(path, used)  # also warms the page cache for what follows
        command = _calibrate_times(path, Path(tmp) / "cal.h5", runs)
        fits = []
        for _ in range(3):
            t = time.perf_counter()
            fit_calibration(session, "polynomial")
            fits.append(time.perf_counter() - t)
    fit_s = float(np.median(fits))
    copy = copy_rate()
    return {"size": size, "frames": int(session.n_frames), "fit_frames": int(used.size),
            "calibrate_s": command, "fit_s": fits, "fit_bytes_per_s": reads["bytes"] / fit_s,
            "copy_bytes_per_s": copy, "reads": reads,
            "accumulate_bytes_per_s": accumulate_rate(session.frame_shape)}


def report(res: dict, info: dict) -> str:
    from thermocal.evaluation.tables import markdown_table

    cal = res["calibrate_s"]
    r = res["reads"]
    gb = r["bytes"] / 1e9
    rows = [
        ("`thermocal calibrate --method polynomial` (the whole command)",
         f"median {np.median(cal):.2f} s (best {min(cal):.2f}, worst {max(cal):.2f}; "
         f"{len(cal)} runs)"),
        (f"the fit alone ({res['fit_frames']} stable frames, {gb:.2f} GB)",
         f"{np.median(res['fit_s']):.2f} s: {res['fit_bytes_per_s'] / 1e9:.2f} GB/s, "
         f"{100 * res['fit_bytes_per_s'] / res['copy_bytes_per_s']:.0f} % of a memory copy's "
         f"{res['copy_bytes_per_s'] / 1e9:.1f} GB/s"),
        ("the fit's accumulation alone (`polynomial._accumulate`), one core",
         f"{res['accumulate_bytes_per_s'] / 1e9:.2f} GB/s of frames: on both cores at most "
         f"{200 * res['accumulate_bytes_per_s'] / res['copy_bytes_per_s']:.0f} % of a memory "
         "copy, the ceiling of this numpy fit"),
        ("the same frames through h5py, a frame at a time",
         f"{r['h5py_s']:.2f} s ({gb / r['h5py_s']:.2f} GB/s)"),
        ("the same frames at their file offsets (`frame_offsets`, `os.preadv`)",
         f"{r['offsets_s']:.2f} s ({gb / r['offsets_s']:.2f} GB/s)"),
    ]
    return (f"## Chamber reads and the polynomial fit\n\nmachine: {info['machine']}; "
            f"{info['wall_s']:.0f} s\n\ndata: a simulated chamber session, {res['frames']} "
            f"frames of {res['size']} (`thermocal simulate chamber --blackbody-c 10:70:10 "
            "--ambient-profile steps --ambient-c 10:40 --interval-s 4`), in memory (/dev/shm).\n\n"
            + markdown_table(("what", "time"), rows) + "\n")


def main(argv: list[str] | None = None) -> None:
    from thermocal.bench import suite_main

    suite_main(__doc__, run, report, argv, quick_help="320x256, 3 runs.")


if __name__ == "__main__":
    main()
