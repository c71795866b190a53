"""The screenshot of a flight report in the docs (``docs/images/report.png``).

Simulates a small flight (``thermocal simulate flight``: a ``tau2`` unit, 336×256, 350 frames at
10 Hz over the real aerial scene of the package's data, flirpy's ``example_radiometric.tiff``),
saturates a few frames as a sun glint would (so that their groups fail and the report shows
why), processes it with ``thermocal flight --method kpn --mosaic`` (which writes the report,
:func:`thermocal.pipeline.report.write_report`) and renders the report with a headless Chromium
(Debian: ``apt-get install chromium``) into a palette PNG.

    python benchmarks/report_screenshot.py [--work DIR] [--png docs/images/report.png]
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import subprocess
import tempfile
from pathlib import Path

import tifffile

from thermocal.cli import main
from thermocal.pipeline.report import REPORT_NAME
from thermocal.scenes.real import find_shared_data

ROOT = Path(__file__).resolve().parents[1]

#: Frames saturated (most pixels at full scale) as by a sun glint.
GLINT_FRAMES = (121, 122, 240)


def _thermocal(*args: object) -> str:
    argv = [str(a) for a in args]
    main(argv)
    return shlex.join(["thermocal", *argv])


def make_flight(work: Path) -> Path:
    """Simulate, glint and process a flight in ``work``; the flight output folder."""
    rec, out = work / "recording", work / "flight"
    for path in (rec, out):
        shutil.rmtree(path, ignore_errors=True)
    scene = find_shared_data() / "flirpy" / "example_radiometric.tiff"
    _thermocal("simulate", "flight", rec, "--frames", 350, "--fps", 10, "--size", "336x256",
               "--motion", "uav", "--unit", 101, "--seed", 3, "--scene", scene)
    frames = tifffile.imread(rec / "frames.tiff")
    rows = frames.shape[1] * 3 // 4
    frames[list(GLINT_FRAMES), :rows] = 2**14 - 1  # the top three quarters clipped
    tifffile.imwrite(rec / "frames.tiff", frames)
    _thermocal("flight", rec / "frames.tiff", "--out", out, "--method", "kpn", "--mosaic")
    return out


def screenshot(html: Path, png: Path, *, size: tuple[int, int] = (1200, 2200)) -> Path:
    """Render ``html`` with headless Chromium into ``png`` (a palette PNG, small)."""
    from PIL import Image

    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    if browser is None:
        raise SystemExit("no chromium on PATH: apt-get install chromium")
    with tempfile.TemporaryDirectory() as tmp:
        shot = Path(tmp) / "shot.png"
        subprocess.run([browser, "--headless", "--disable-gpu", "--no-sandbox",
                        "--hide-scrollbars", f"--screenshot={shot}",
                        f"--window-size={size[0]},{size[1]}", html.resolve().as_uri()],
                       check=True, capture_output=True, timeout=120)
        png.parent.mkdir(parents=True, exist_ok=True)
        with Image.open(shot) as img:
            img.convert("RGB").quantize(colors=128).save(png, optimize=True)
    return png


def _main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", type=Path, default=Path(tempfile.gettempdir()) /
                        "thermocal-report-demo")
    parser.add_argument("--png", type=Path, default=ROOT / "docs" / "images" / "report.png")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    report = make_flight(args.work) / REPORT_NAME
    png = screenshot(report, args.png)
    print(f"{report} ({report.stat().st_size / 1e3:.0f} kB) -> {png} "
          f"({png.stat().st_size / 1e3:.0f} kB)")


if __name__ == "__main__":
    _main()
