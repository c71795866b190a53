"""Reading speed per recording format (issue 19, "Measure"): frames per second streamed through
:func:`thermocal.io.open_recording`, 640×512 frames where the format has them.

Files are built from the real samples: a SEQ of N copies of the 640×512 FFF frame of the
package's data (a FLIR Duo Pro R, flirpy), a folder of N copies of the DJI XT-R R-JPEG
(640×512) and of the FFF frame, the project's TIFF + JSON and a DualTauUAV folder of the same
counts, and the FLIR CSQ sample (1024×768, JPEG-LS, 8 frames, repeated by reading it again),
where ``../shared/data/recordings`` has it. Opening (headers only: every record's header checked),
streaming, and what ``thermocal flight`` reads (:func:`~thermocal.io.open.open_stream`: the
per-frame series from headers and metadata, then the frames streamed) are timed apart; the best
of 3 runs. Prints a Markdown table::

    .venv/bin/python benchmarks/readers.py [--frames N]
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from thermocal.bench import machine
from thermocal.io.open import open_recording, open_stream
from thermocal.io.recording import Recording, write_recording
from thermocal.scenes.real import find_shared_data


def _best(fn, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def _stream(path: Path) -> int:
    return sum(len(c.frames) for c in open_recording(path).iter_frames(64))


def _flight_read(path: Path) -> int:
    return sum(len(f) for _, f in open_stream(path).chunks(64))


def build(folder: Path, n: int, data: Path) -> dict[str, Path]:
    """The recordings to read, by format name."""
    out: dict[str, Path] = {}
    fff = data / "flirpy" / "frame_000000.fff"
    record = fff.read_bytes()
    (folder / "f.seq").write_bytes(record * n)
    out["seq (FFF records, plain counts)"] = folder / "f.seq"
    ffff = folder / "fff"
    ffff.mkdir()
    for k in range(n):
        shutil.copy(fff, ffff / f"f{k:05d}.fff")
    out["folder of FFF files"] = ffff
    frames = open_recording(fff).read_all().frames
    stack = np.repeat(frames, n, axis=0)
    write_recording(folder / "r.tiff", Recording(stack, fpa_c=np.full(n, 30.0), bit_depth=16))
    out["project TIFF + JSON"] = folder / "r.tiff"
    dual = folder / "dualtau"
    dual.mkdir()
    per_file = 50
    for i, k in enumerate(range(0, n, per_file)):
        m = min(per_file, n - k)
        start = 1_700_000_000_000_000_000 + (k + np.arange(m, dtype=np.int64)) * 100_000_000
        np.savez(dual / f"flight_{i:04d}.npz", frames=stack[k : k + m],
                 fpa=np.full(m, 3000, np.uint16), time_ns_start=start, time_ns_end=start + 1)
    out["DualTauUAV folder (.npz)"] = dual
    recordings = data / "recordings"
    jpg = recordings / "dji_xtr_tau2.jpg"
    if jpg.is_file():
        rj = folder / "rjpeg"
        rj.mkdir()
        for k in range(n):
            shutil.copy(jpg, rj / f"DJI_{k:05d}.jpg")
        out["folder of DJI XT-R R-JPEGs"] = rj
    csq = recordings / "thermimage_sample.csq"
    if csq.is_file():
        out["CSQ (JPEG-LS, 1024×768, 8 frames)"] = csq  # read in place, never copied
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=500, help="Frames per built recording.")
    args = parser.parse_args(argv)
    data = find_shared_data()
    if data is None:
        raise SystemExit("no shared data found")
    with tempfile.TemporaryDirectory() as tmp:
        files = build(Path(tmp), args.frames, data)
        rows = []
        for name, path in files.items():
            src = open_recording(path)
            opened = _best(lambda p=path: open_recording(p))
            streamed = _best(lambda p=path: _stream(p))
            flight = _best(lambda p=path: _flight_read(p))
            rows.append((name, src.n_frames, f"{src.frame_shape[1]}x{src.frame_shape[0]}",
                         f"{1000 * opened:.1f}", f"{src.n_frames / streamed:,.0f}",
                         f"{src.n_frames / flight:,.0f}"))
    print(f"machine: {machine()}\n")
    print("| format | frames | size | open (headers) ms | frames/s streamed | frames/s as "
          "flight reads them |")
    print("|---|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(str(c) for c in row) + " |")


if __name__ == "__main__":
    main()
