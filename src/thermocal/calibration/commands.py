"""The ``thermocal calibrate`` and ``thermocal correct`` commands.

Their method names and help come from the registry,
:data:`thermocal.calibration.registry.CALIBRATION_METHODS`.
"""

from __future__ import annotations

import contextlib
import warnings
from pathlib import Path

import click
import numpy as np
from click.core import ParameterSource

from thermocal._validate import (
    HDF5_SUFFIXES,
    TIFF_SUFFIXES,
    check_fpa_c,
    check_not_input,
    check_output_file,
    check_outputs_differ,
)
from thermocal.calibration.registry import CALIBRATION_METHODS, method_help
from thermocal.errors import (
    FileFormatError,
    FitError,
    InvalidInputError,
    ResolutionMismatchError,
    ThermocalError,
)
from thermocal.estimation.pipeline import FPA_SIGMA_HELP

_CALIBRATION_SUFFIXES = HDF5_SUFFIXES
_REPORT_SUFFIXES = (".json",)
#: The keys of an earlier calibration report, which a new --report may replace (no other file).
_REPORT_KEYS = frozenset({"chamber", "calibration", "version", "method"})
#: ``--method``'s choice that fits every method the session supports and keeps the best.
AUTO = "auto"


def _fpa_ref_help() -> str:
    takes = ", ".join(name for name, c in CALIBRATION_METHODS.items() if c.takes_fpa_ref)
    return f"Reference FPA temperature, °C ({takes})."


def _epilog() -> str:
    return method_help() + (
        f"\n\n\b\n{AUTO:<{max(map(len, CALIBRATION_METHODS))}}  cross-validate every method "
        "the session supports and keep the one of lowest expected error"
    )


@click.command(epilog=_epilog())
@click.argument("chamber", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--method", type=click.Choice([*CALIBRATION_METHODS, AUTO]), default="polynomial",
              show_default=True, help="Calibration method (listed below), or auto.")
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Calibration file to write (.h5).")
@click.option("--report", "report_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Also write the cross-validation report here (.json).")
@click.option("--fpa-ref-c", type=float, default=None, help=_fpa_ref_help())
@click.option("--scene-term", type=click.Choice(["radiance", "t4", "linear"]), default="radiance",
              show_default=True, help="Scene term of the polynomial model.")
@click.option("--radial", is_flag=True, help="Polynomial: keep only the radial fit (eq. 16–17).")
@click.option("--force", is_flag=True,
              help="Write a calibration that the session cannot cross-validate (no set point "
              "or FPA segment can be left out): its temperatures then have no uncertainty and "
              "are not checked against its ranges without --force.")
def calibrate(chamber: Path, method: str, out: Path, report_path: Path | None,
              fpa_ref_c: float | None, scene_term: str, radial: bool, force: bool) -> None:
    """Fit a calibration to a chamber file (HDF5, or an EnvChamberCtrl .npz), cross-validate it
    (set points and FPA segments left out in turn) and store the report with it.

    The session is first checked against the method's needs: a method it cannot support is
    refused, saying what to record; one it supports in part is fitted with a warning."""
    from dataclasses import replace

    from thermocal.calibration.dataset import prepare_chamber
    from thermocal.calibration.report import auto_calibration, fit_with_report, ranking_line
    from thermocal.io.atomic import atomic_path, write_json_atomic

    check_output_file(out, _CALIBRATION_SUFFIXES)
    check_not_input(out, chamber)
    from thermocal.io.replaces import check_json_replaces_only, check_replaces_only

    check_replaces_only(out, "calibration")
    if report_path is not None:
        check_output_file(report_path, _REPORT_SUFFIXES)
        check_not_input(report_path, chamber, what="--report")
        check_outputs_differ(report_path, out, ("--report", "--out"))
        check_json_replaces_only(report_path, _REPORT_KEYS, kind="calibration report",
                                 what="--report")
    if radial and method not in ("polynomial", AUTO):
        raise InvalidInputError("--radial applies to --method polynomial only")
    given = click.get_current_context().get_parameter_source("scene_term")
    if method not in ("polynomial", AUTO) and given == ParameterSource.COMMANDLINE:
        raise InvalidInputError("--scene-term applies to --method polynomial only")
    if fpa_ref_c is not None and method != AUTO and not CALIBRATION_METHODS[method].takes_fpa_ref:
        takes = ", ".join(name for name, c in CALIBRATION_METHODS.items() if c.takes_fpa_ref)
        raise InvalidInputError(f"--fpa-ref-c: --method {method} takes no reference FPA "
                                f"temperature (only {takes} do)")
    if fpa_ref_c is not None:
        check_fpa_c(fpa_ref_c, "--fpa-ref-c")
    data = prepare_chamber(chamber)
    options = {name: _options(name, scene_term, fpa_ref_c) for name in CALIBRATION_METHODS}
    if method == AUTO:
        cal, report = auto_calibration(data, options=options)
    else:
        cal, report = fit_with_report(data, method, **options[method])
    chosen = report.method
    if report.expected_mae_c is None and not force:  # σ comes from the interior folds
        raise FitError(f"{chosen} cannot be cross-validated on this session "
                       f"({'; '.join(report.notes[:1]) or 'no fold'}), so its temperatures "
                       "would have neither an uncertainty nor ranges to check: record at least "
                       "3 set points over FPA temperatures spanning 4 °C or more (`thermocal "
                       "simulate chamber --help` shows such a protocol), or --force to write "
                       "it all the same")
    if radial:
        if chosen != "polynomial":
            raise InvalidInputError(f"--radial applies to the polynomial model; auto chose "
                                    f"{chosen}")
        cal = cal.radial()  # type: ignore[attr-defined]
        report = replace(report, notes=[*report.notes, "cross-validated as the per-pixel fit "
                                        "(--radial keeps its radial fit)"])
    cal = replace(cal, info=cal.info | {"report": report.to_dict()})  # type: ignore[type-var]
    with contextlib.ExitStack() as stack:  # the report written first, put in place only once
        # the calibration is: a failure of either leaves neither (and an earlier report as it was)
        if report_path is not None:
            written = stack.enter_context(atomic_path(report_path))
            write_json_atomic(written, {"chamber": str(chamber), "calibration": str(out)}
                              | report.to_dict())
        cal.save(out)
    for text in report.warnings:
        click.echo(f"thermocal: warning: {' '.join(text.split())}", err=True)
    if report.ranking:
        click.echo(ranking_line(report))
        for r in report.ranking:
            if "refused" in r:
                why = r["refused"].split("; ")[0].removeprefix(f"{r['method']} ")
                click.echo(f"  skipped {r['method']}: {why}")
        for name, info in CALIBRATION_METHODS.items():  # never tried: said, not left silent
            if not info.auto and info.auto_note:
                click.echo(f"  not a candidate: {name}: {info.auto_note}")
    lo, hi = getattr(cal, "fpa_range", None) or cal.fpa_range_c  # type: ignore[attr-defined]
    info = getattr(cal, "info", None) or {}
    points = info.get("setpoints_c", data.setpoints_c)
    used, left_out = _frames_text(chosen, report.frames)
    click.echo(
        f"{chosen} calibration of {data.frame_shape[1]}x{data.frame_shape[0]} from {used} "
        f"({len(points)} set points, FPA {lo:.2f}…{hi:.2f} °C, {int(cal.bad.sum())} bad pixels) "
        f"written to {out}{left_out}"
    )
    for line in report.summary_lines():
        click.echo(line)
    if report_path is not None:
        click.echo(f"  report written to {report_path}")


def _options(method: str, scene_term: str, fpa_ref_c: float | None) -> dict:
    """The fitting options the command's flags give ``method``."""
    if method == "polynomial":
        return {"scene": scene_term}
    if fpa_ref_c is not None and CALIBRATION_METHODS[method].takes_fpa_ref:
        return {"fpa_ref_c": fpa_ref_c}
    return {}


def frames_used(method: str, info: dict, n_frames: int, options: dict | None = None
                ) -> tuple[str, str]:
    """How many of the chamber's ``n_frames`` frames a fit used (``"252 of 840 frames"``) and
    why the others were left out (``"; left out: ..."``, or ``""``), from the fit's ``info``
    (``frames_used``, ``excluded_frames``: the saturated ones, ...) and its ``options``."""
    from thermocal.calibration.report import frame_counts

    return _frames_text(method, frame_counts(method, info, n_frames, options))


def _frames_text(method: str, counts: dict) -> tuple[str, str]:
    """:func:`frames_used`'s text of :func:`~thermocal.calibration.report.frame_counts`."""
    n_frames = counts.get("total", 0)
    if counts.get("used") is None:
        return f"the chamber's {n_frames} frames", f"; frames used: not recorded by {method}"
    left = [f"{count} {why}" for why, count in counts.get("left_out", {}).items()]
    extra = (f"; {counts['used_hw']} frames for its Hammerstein-Wiener estimator"
             if "used_hw" in counts else "")
    return f"{counts['used']} of {n_frames} frames", (
        f"; left out: {', '.join(left)}" if left else "") + extra


@click.command(epilog=method_help())
@click.argument("frames", type=click.Path(path_type=Path))
@click.option("--calibration", "calibration_path", type=click.Path(dir_okay=False, path_type=Path),
              required=True, help="Calibration file made by `thermocal calibrate`.")
@click.option("--fpa-c", type=float, default=None,
              help="FPA temperature for every frame, °C (default: the sidecar's fpa_c).")
@click.option("--fpa-sigma-c", type=float, default=None, help=FPA_SIGMA_HELP)
@click.option("--out", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="Temperature TIFF to write (float32 °C, (N, H, W)).")
@click.option("--sigma-out", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Also write the temperatures' standard uncertainty (float32 TIFF, °C, 1σ, "
              "(N, H, W)), from the calibration's cross-validation report.")
@click.option("--force", is_flag=True,
              help="Correct frames outside the calibration's FPA or scene range instead of "
              "refusing them; their σ grows with the distance outside. A calibration without a "
              "cross-validation report is then used, without an uncertainty.")
def correct(frames: Path, calibration_path: Path, fpa_c: float | None,
            fpa_sigma_c: float | None, out: Path, sigma_out: Path | None, force: bool) -> None:
    """Turn a recording's raw frames into temperatures (°C) with a calibration file of any
    method (the file records which). Frames outside the FPA and scene ranges of the
    calibration's chamber session are refused unless --force. FRAMES: a file or a folder in any
    format `thermocal info` reads; damaged frames are left out with a warning naming them."""
    from thermocal.burst import check_burst
    from thermocal.calibration.base import ThermocalWarning, calibration_sigma_extra
    from thermocal.calibration.dataset import recording_fpa_rates
    from thermocal.calibration.imprint import OTHER_CAMERA_SIGMA_C, imprint_reason
    from thermocal.calibration.registry import load_any_calibration
    from thermocal.calibration.uncertainty import (
        NO_REPORT_REMEDY,
        REMEDY,
        CalibrationSigma,
        no_sigma_reason,
        older_report_warning,
    )
    from thermocal.errors import OutsideDomainError
    from thermocal.estimation.commands import warn_typed_fpa
    from thermocal.estimation.pipeline import FPA_STEP_C, check_fpa_sigma, fpa_step
    from thermocal.io.open import check_outside_recording, read_any_recording
    from thermocal.io.recording import write_sigma_tiff, write_temperature_tiff
    from thermocal.io.replaces import check_map_replaces_only

    check_fpa_sigma(fpa_c, fpa_sigma_c, sigma_out)
    check_output_file(out, TIFF_SUFFIXES)
    check_not_input(out, frames, calibration_path)
    check_map_replaces_only(out)
    check_outside_recording(frames, (out, "--out"), (sigma_out, "--sigma-out"))
    if sigma_out is not None:
        check_output_file(sigma_out, TIFF_SUFFIXES)
        check_not_input(sigma_out, frames, calibration_path, what="--sigma-out")
        check_map_replaces_only(sigma_out, what="--sigma-out")
        check_outputs_differ(sigma_out, out, ("--sigma-out", "--out"))
    if fpa_c is not None:
        check_fpa_c(fpa_c, "--fpa-c")
    cal = load_any_calibration(calibration_path)
    model = CalibrationSigma.of(cal)
    older = None if model is None else model.older_report()
    if older:
        click.echo(f"thermocal: warning: {calibration_path}: {older_report_warning(older)}",
                   err=True)
    if model is None and (sigma_out is not None or not force):  # --force cannot give σ
        if sigma_out is not None:
            raise InvalidInputError(
                f"{calibration_path}: no σ to write to --sigma-out: {no_sigma_reason(cal)}; "
                f"{NO_REPORT_REMEDY.split(';')[0]} (or leave out --sigma-out and give --force "
                "for the temperatures alone)")
        raise OutsideDomainError(
            f"{calibration_path}: {no_sigma_reason(cal)}; {NO_REPORT_REMEDY}")
    rec = read_any_recording(frames, fpa_c=fpa_c)
    try:  # a dead or blank frame, or one mostly saturated, is no scene: refused as by nuc and
        # estimate (correct blamed a blank frame on the scene range; forced, wrote -60 °C)
        check_burst(rec.frames, bit_depth=rec.bit_depth)
    except InvalidInputError as exc:  # correct maps every frame or none: a flight, each alone
        raise InvalidInputError(
            f"{frames}: {exc}; to map the other frames, `thermocal flight {frames} "
            f"--method calibration --calibration {calibration_path} --frames 1 --stride 1 "
            "--out DIR` maps each frame alone") from None
    if sigma_out is not None and rec.fpa_c is None:
        raise InvalidInputError(f"{frames}: no FPA temperature, which σ depends on: give --fpa-c "
                                "or a sidecar with fpa_c")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ThermocalWarning)
        try:
            temps = cal.apply(rec.frames, fpa_c=rec.fpa_c, time_s=rec.time_s)
        except InvalidInputError as exc:
            raise _naming_the_input(exc, frames, calibration_path) from None
    rates = recording_fpa_rates(rec.fpa_c, rec.time_s)
    # its stillness from its FPA series where the frames have times and FPA temperatures,
    # else not known
    still = (None if rec.time_s is not None and rec.fpa_c is not None
             else np.full(temps.shape[0], np.nan))
    outside = () if model is None else model.outside(
        temps, () if rec.fpa_c is None else rec.fpa_c, rate_c_per_min=rates,
        time_s=rec.time_s, still_s=still)
    foreign = None if model is None else imprint_reason(cal, rec.frames, temps,
                                                        fpa_c=rec.fpa_c, time_s=rec.time_s)
    outside = outside + ((foreign,) if foreign else ())
    if outside and not force:
        raise OutsideDomainError(f"{frames}: {'; '.join(outside)}; {REMEDY}")
    for w in caught:
        click.echo(f"thermocal: warning: {' '.join(str(w.message).split())}", err=True)
    if outside:
        click.echo(f"thermocal: warning: {frames} lies outside the calibration's ranges "
                   f"({'; '.join(outside)}); corrected all the same (--force)", err=True)
    elif model is None:
        click.echo(f"thermocal: warning: {calibration_path}: {no_sigma_reason(cal)}; corrected "
                   "all the same (--force), without an uncertainty", err=True)
    about = {"method": cal.method, "calibration": Path(calibration_path).name,
             "source": Path(frames).name}
    if sigma_out is not None:  # σ first: a failure leaves neither file
        since = None if rec.time_s is None else np.asarray(rec.time_s) - rec.time_s[0]
        sigma = model.sigma(temps, rec.fpa_c, rate_c_per_min=rates, time_since_start_s=since)
        # forced at paces the session never held: the rate terms' correction is unverified
        unverified = (model.paces_never_held(rates, rec.time_s, fpa_c=rec.fpa_c)
                      if outside and rates is not None else None)
        added = calibration_sigma_extra(cal, rec.frames, temps, time_s=rec.time_s,
                                        fpa_c=rec.fpa_c, unverified=unverified)
        if added is not None:  # a shutter's closures, unverified rate terms, filled pixels
            sigma = np.hypot(sigma, added).astype(np.float32)
        if foreign:  # forced through another camera's calibration
            sigma = np.hypot(sigma, np.float32(OTHER_CAMERA_SIGMA_C)).astype(np.float32)
        if fpa_sigma_c:  # a typed FPA temperature's uncertainty: how far a °C of it moves them
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ThermocalWarning)
                moved = cal.apply(rec.frames, fpa_c=rec.fpa_c + fpa_step(rec.fpa_c),
                                  time_s=rec.time_s)
            sensitivity = np.abs(moved.astype(np.float64) - temps) / FPA_STEP_C
            sigma = np.hypot(sigma, sensitivity * fpa_sigma_c).astype(np.float32)
        write_sigma_tiff(sigma_out, sigma, about=about | {"temperature": Path(out).name})
    try:
        write_temperature_tiff(out, temps, about=about | {
            "sigma": "none" if sigma_out is None else Path(sigma_out).name})
    except Exception:
        if sigma_out is not None:
            Path(sigma_out).unlink(missing_ok=True)
        raise
    if sigma_out is not None:
        warn_typed_fpa("calibration", fpa_c, fpa_sigma_c)
    click.echo(f"wrote {temps.shape[0]} temperature frame(s) to {out}"
               + (f" and their σ to {sigma_out}" if sigma_out is not None else ""))


def _naming_the_input(exc: InvalidInputError, frames: Path, calibration: Path
                      ) -> ThermocalError:
    """The error of a calibration's ``apply``, naming the input it is about."""
    message = str(exc)
    if isinstance(exc, ResolutionMismatchError):
        return ResolutionMismatchError(f"{frames}: {message} ({calibration}): a calibration "
                                       "serves the sensor size it was fitted at")
    if message.startswith((str(frames), str(calibration))):
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
