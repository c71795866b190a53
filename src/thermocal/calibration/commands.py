"""The ``thermocal calibrate`` and ``thermocal correct`` commands."""

from __future__ import annotations

import warnings
from pathlib import Path

import click

from thermocal.errors import InvalidInputError

_METHODS = ["two-point", "one-point", "shutter", "polynomial", "wolf2016", "lin", "lin-level"]


def _check_output(path: Path, suffixes: tuple[str, ...]) -> None:
    if path.is_dir():
        raise InvalidInputError(f"{path}: is a directory, expected a file name")
    if not path.parent.exists():
        raise InvalidInputError(f"{path.parent}: output folder does not exist")
    if path.suffix.lower() not in suffixes:
        raise InvalidInputError(f"{path}: the output must end in {' or '.join(suffixes)}")


@click.command()
@click.argument("chamber", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--method", type=click.Choice(_METHODS), default="polynomial", show_default=True)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Calibration file to write (.h5).")
@click.option("--fpa-ref-c", type=float, default=None,
              help="Reference FPA temperature, °C (two-point, one-point, shutter, wolf2016, lin, "
                   "lin-level).")
@click.option("--scene-term", type=click.Choice(["radiance", "t4", "linear"]), default="radiance",
              show_default=True, help="Scene term of the polynomial model.")
@click.option("--radial", is_flag=True, help="Polynomial: keep only the radial fit (eq. 16–17).")
def calibrate(chamber: Path, method: str, out: Path, fpa_ref_c: float | None, scene_term: str,
              radial: bool) -> None:
    """Fit a calibration to a chamber file (HDF5, or an EnvChamberCtrl .npz)."""
    from thermocal.calibration import fit_calibration
    from thermocal.calibration.dataset import prepare_chamber

    _check_output(out, (".h5", ".hdf5"))
    data = prepare_chamber(chamber)
    options: dict = {}
    if method == "polynomial":
        options["scene"] = scene_term
    elif fpa_ref_c is not None:
        options["fpa_ref_c"] = fpa_ref_c
    cal = fit_calibration(data, method, **options)
    if radial:
        if method != "polynomial":
            raise InvalidInputError("--radial applies to --method polynomial only")
        cal = cal.radial()
    cal.save(out)
    lo, hi = getattr(cal, "fpa_range", None) or cal.fpa_range_c
    n_bad = int(cal.bad.sum())
    click.echo(
        f"{method} calibration of {data.frame_shape[1]}x{data.frame_shape[0]} from "
        f"{data.n_frames} frames ({len(data.setpoints_c)} set points, FPA {lo:.2f}…{hi:.2f} °C, "
        f"{n_bad} bad pixels) written to {out}"
    )


@click.command()
@click.argument("frames", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False, path_type=Path),
              required=True, help="Calibration file made by `thermocal calibrate`.")
@click.option("--fpa-c", type=float, default=None,
              help="FPA temperature for every frame, °C (default: the sidecar's fpa_c).")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Temperature TIFF to write (float32 °C, (N, H, W)).")
def correct(frames: Path, calibration_path: Path, fpa_c: float | None, out: Path) -> None:
    """Turn a recording's raw frames into temperatures (°C) with a calibration."""
    from thermocal.calibration import load_any_calibration
    from thermocal.calibration.base import ThermocalWarning
    from thermocal.io.recording import read_recording, write_temperature_tiff

    _check_output(out, (".tif", ".tiff"))
    cal = load_any_calibration(calibration_path)
    rec = read_recording(frames, fpa_c=fpa_c)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ThermocalWarning)
        temps = cal.apply(rec.frames, fpa_c=rec.fpa_c, time_s=rec.time_s)
    for w in caught:
        click.echo(f"thermocal: warning: {w.message}", err=True)
    write_temperature_tiff(out, temps)
    click.echo(f"wrote {temps.shape[0]} temperature frame(s) to {out}")
