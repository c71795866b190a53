"""``thermocal nuc FRAMES.tiff --method NAME --out CORRECTED.tiff``.

Its method names and help come from the registry, :data:`thermocal.nuc.registry.NUC_METHODS`.
"""

from __future__ import annotations

from pathlib import Path

import click

from thermocal._validate import TIFF_SUFFIXES, check_not_input, check_output_file
from thermocal.errors import InvalidInputError, ResolutionMismatchError
from thermocal.nuc.registry import NUC_METHODS, method_help


@click.command("nuc", epilog=method_help())
@click.argument("frames", type=click.Path(path_type=Path))
@click.option("--method", type=click.Choice(list(NUC_METHODS)), required=True,
              help="NUC method (listed below).")
@click.option(
    "--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
    help="Output float32 TIFF (N, H, W), counts-like units (not radiometric).",
)
def nuc(frames: Path, method: str, out: Path) -> None:
    """Scene-based / single-frame nonuniformity correction of a recording. FRAMES: a file or a
    folder in any format `thermocal info` reads; damaged frames are left out with a warning."""
    from thermocal.burst import check_burst
    from thermocal.io.open import check_outside_recording, read_any_recording
    from thermocal.io.replaces import check_map_replaces_only
    from thermocal.nuc import correct_nonuniformity
    from thermocal.nuc._common import write_counts_tiff

    check_output_file(out, TIFF_SUFFIXES)
    check_not_input(out, frames)
    check_map_replaces_only(out)
    check_outside_recording(frames, (out, "--out"))
    rec = read_any_recording(frames)
    try:
        check_burst(rec.frames, bit_depth=rec.bit_depth)  # no saturated or dead (constant) frames
        corrected = correct_nonuniformity(rec.frames, method=method)
    except ResolutionMismatchError:
        raise
    except InvalidInputError as exc:  # about the frames: name their file
        if str(exc).startswith(str(frames)):
            raise
        raise InvalidInputError(f"{frames}: {exc}") from None
    write_counts_tiff(out, corrected, extra={"method": method})  # counts-like, not °C
    n, h, w = corrected.shape
    click.echo(f"wrote {n} corrected frames of {w}x{h} ({method}) to {out}")
