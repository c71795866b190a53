"""The ``thermocal calibrate`` and ``thermocal correct`` commands.

Their method names and help come from the registry,
:data:`thermocal.calibration.registry.CALIBRATION_METHODS`.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import click

from thermocal._validate import (
    HDF5_SUFFIXES,
    TIFF_SUFFIXES,
    check_fpa_c,
    check_not_input,
    check_output_file,
)
from thermocal.calibration.registry import CALIBRATION_METHODS, method_help
from thermocal.errors import (
    FileFormatError,
    InvalidInputError,
    ResolutionMismatchError,
    ThermocalError,
)

_CALIBRATION_SUFFIXES = HDF5_SUFFIXES

#: Why a method leaves chamber frames out of its fit by default (saturated frames apart).
_LEFT_OUT_WHY = {
    "two-point": "not at the two end set points with the FPA settled at the reference",
    "one-point": "not at its three set points with the FPA settled at the reference",
    "shutter": "not at the two end set points with the FPA settled at the reference",
    "polynomial": "with a changing FPA (it fits the stable frames)",
    "wolf2016": "with the FPA changing or away from the reference",
    "lin": "not settled",
    "lin-level": "not settled",
}


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
    check_not_input(out, chamber)
    if radial and method != "polynomial":
        raise InvalidInputError("--radial applies to --method polynomial only")
    if fpa_ref_c is not None:
        check_fpa_c(fpa_ref_c, "--fpa-ref-c")
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
    info = getattr(cal, "info", None) or {}
    points = info.get("setpoints_c", data.setpoints_c)
    used, left_out = frames_used(method, info, data.n_frames)
    click.echo(
        f"{method} calibration of {data.frame_shape[1]}x{data.frame_shape[0]} from {used} "
        f"({len(points)} set points, FPA {lo:.2f}…{hi:.2f} °C, {int(cal.bad.sum())} bad pixels) "
        f"written to {out}{left_out}"
    )


def frames_used(method: str, info: dict, n_frames: int) -> tuple[str, str]:
    """How many of the chamber's ``n_frames`` frames a fit used (``"252 of 840 frames"``) and
    why the others were left out (``"; left out: ..."``, or ``""``), from the fit's ``info``
    (``frames_used``, ``excluded_frames``: the saturated ones, ...)."""
    why = _LEFT_OUT_WHY.get(method, "outside its default selection")
    if "frames_used" in info:
        used = int(info["frames_used"])
    elif "frames_used_s" in info:  # wolf2016: the S maps; its HW estimator uses more
        used = int(info["frames_used_s"])
    elif "stable_frames" in info and "unstable_frames" in info:  # lin
        used = int(info["stable_frames"]) + int(info["unstable_frames"])
    else:
        return f"the chamber's {n_frames} frames", f"; frames used: not recorded by {method}"
    saturated = int(info.get("excluded_frames", 0) or 0)
    other = max(0, n_frames - used - saturated)
    left = ([f"{other} {why}"] if other else []) + ([f"{saturated} saturated"] if saturated
                                                   else [])
    extra = (f"; {int(info['frames_used_hw'])} frames for its Hammerstein-Wiener estimator"
             if "frames_used_hw" in info else "")
    return f"{used} of {n_frames} frames", (f"; left out: {', '.join(left)}" if left else "") \
        + extra


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
    check_not_input(out, frames, calibration_path)
    if fpa_c is not None:
        check_fpa_c(fpa_c, "--fpa-c")
    cal = load_any_calibration(calibration_path)
    rec = read_recording(frames, fpa_c=fpa_c)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ThermocalWarning)
        try:
            temps = cal.apply(rec.frames, fpa_c=rec.fpa_c, time_s=rec.time_s)
        except InvalidInputError as exc:
            raise _naming_the_input(exc, frames, calibration_path) from None
    for w in caught:
        click.echo(f"thermocal: warning: {' '.join(str(w.message).split())}", err=True)
    write_temperature_tiff(out, temps)
    click.echo(f"wrote {temps.shape[0]} temperature frame(s) to {out}")


def _naming_the_input(exc: InvalidInputError, frames: Path, calibration: Path
                      ) -> ThermocalError:
    """The error of a calibration's ``apply``, naming the input it is about."""
    message = str(exc)
    if isinstance(exc, ResolutionMismatchError) or message.startswith((str(frames),
                                                                        str(calibration))):
        return exc
    if message.startswith("frames"):
        return InvalidInputError(f"{frames}: {message}")
    if message.startswith("radiance") or "NaN" in message:
        # the frames and their FPA temperatures were checked when read: NaN computed from
        # them comes from the calibration's coefficients
        return FileFormatError(
            f"{calibration}: the calibration gives NaN for {frames} ({message}); its "
            "coefficients are damaged: calibrate again"
        )
    return InvalidInputError(f"{frames} with {calibration}: {message}")
