"""The ``thermocal calibrate`` and ``thermocal correct`` commands.

Their method names and help come from the registry,
:data:`thermocal.calibration.registry.CALIBRATION_METHODS`.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import click

from thermocal._validate import TIFF_SUFFIXES, check_output_file
from thermocal.calibration.registry import CALIBRATION_METHODS, method_help
from thermocal.errors import InvalidInputError

_CALIBRATION_SUFFIXES = (".h5", ".hdf5")


def _fpa_ref_help() -> str:
    takes = ", ".join(name for name, c in CALIBRATION_METHODS.items() if c.takes_fpa_ref)
    return f"Reference FPA temperature, °C ({takes})."


@click.command(epilog=method_help())
@click.argument("chamber", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--method", type=click.Choice(list(CALIBRATION_METHODS)), default="polynomial",
              show_default=True, help="Calibration method (listed below).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Calibration file to write (.h5).")
@click.option("--fpa-ref-c", type=float, default=None, help=_fpa_ref_help())
@click.option("--scene-term", type=click.Choice(["radiance", "t4", "linear"]), default="radiance",
              show_default=True, help="Scene term of the polynomial model.")
@click.option("--radial", is_flag=True, help="Polynomial: keep only the radial fit (eq. 16–17).")
def calibrate(chamber: Path, method: str, out: Path, fpa_ref_c: float | None, scene_term: str,
              radial: bool) -> None:
    """Fit a calibration to a chamber file (HDF5, or an EnvChamberCtrl .npz)."""
    from thermocal.calibration.dataset import prepare_chamber
    from thermocal.calibration.registry import fit_calibration

    check_output_file(out, _CALIBRATION_SUFFIXES)
    if radial and method != "polynomial":
        raise InvalidInputError("--radial applies to --method polynomial only")
    data = prepare_chamber(chamber)
    options: dict = {}
    if method == "polynomial":
        options["scene"] = scene_term
    elif fpa_ref_c is not None and CALIBRATION_METHODS[method].takes_fpa_ref:
        options["fpa_ref_c"] = fpa_ref_c
    cal = fit_calibration(data, method, **options)
    if radial:
        cal = cal.radial()  # type: ignore[attr-defined]
    cal.save(out)
    lo, hi = getattr(cal, "fpa_range", None) or cal.fpa_range_c  # type: ignore[attr-defined]
    click.echo(
        f"{method} calibration of {data.frame_shape[1]}x{data.frame_shape[0]} from "
        f"{data.n_frames} frames ({len(data.setpoints_c)} set points, FPA {lo:.2f}…{hi:.2f} °C, "
        f"{int(cal.bad.sum())} bad pixels) written to {out}"
    )


@click.command(epilog=method_help())
@click.argument("frames", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False, path_type=Path),
              required=True, help="Calibration file made by `thermocal calibrate`.")
@click.option("--fpa-c", type=float, default=None,
              help="FPA temperature for every frame, °C (default: the sidecar's fpa_c).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Temperature TIFF to write (float32 °C, (N, H, W)).")
def correct(frames: Path, calibration_path: Path, fpa_c: float | None, out: Path) -> None:
    """Turn a recording's raw frames into temperatures (°C) with a calibration file of any
    method (the file records which)."""
    from thermocal.calibration.base import ThermocalWarning
    from thermocal.calibration.registry import load_any_calibration
    from thermocal.io.recording import read_recording, write_temperature_tiff

    check_output_file(out, TIFF_SUFFIXES)
    cal = load_any_calibration(calibration_path)
    rec = read_recording(frames, fpa_c=fpa_c)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ThermocalWarning)
        temps = cal.apply(rec.frames, fpa_c=rec.fpa_c, time_s=rec.time_s)
    for w in caught:
        click.echo(f"thermocal: warning: {w.message}", err=True)
    write_temperature_tiff(out, temps)
    click.echo(f"wrote {temps.shape[0]} temperature frame(s) to {out}")
