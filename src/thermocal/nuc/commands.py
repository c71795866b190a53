"""``thermocal nuc FRAMES.tiff --method NAME --out CORRECTED.tiff``."""

from __future__ import annotations

from pathlib import Path

import click

# the registry's keys, listed here so that --help does not import numpy-heavy modules
_METHODS = ("harris1999", "scribner", "ecr", "torres-kalman", "hardie2000", "zuo2011", "admire")


@click.command("nuc")
@click.argument("frames", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--method", type=click.Choice(_METHODS), required=True, help="NUC method.")
@click.option(
    "--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
    help="Output float32 TIFF (N, H, W), counts-like units (not radiometric).",
)
def nuc(frames: Path, method: str, out: Path) -> None:
    """Scene-based / single-frame nonuniformity correction of a recording."""
    from thermocal.errors import InvalidInputError
    from thermocal.io.recording import read_recording, write_temperature_tiff
    from thermocal.nuc import correct_nonuniformity

    if out.is_dir():
        raise InvalidInputError(f"{out}: is a directory, expected a file name")
    if not out.parent.exists():
        raise InvalidInputError(f"{out.parent}: output folder does not exist")
    if out.suffix.lower() not in (".tif", ".tiff"):
        raise InvalidInputError(f"{out}: the output must end in .tiff or .tif")
    rec = read_recording(frames)
    corrected = correct_nonuniformity(rec.frames, method=method)
    write_temperature_tiff(out, corrected)
    n, h, w = corrected.shape
    click.echo(f"wrote {n} corrected frames of {w}x{h} ({method}) to {out}")
