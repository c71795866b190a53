"""``thermocal estimate``: a burst file → its pivot frame's temperature TIFF."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import click

from thermocal._validate import (
    TIFF_SUFFIXES,
    check_not_input,
    check_output_file,
    check_outputs_differ,
)
from thermocal.errors import InvalidInputError
from thermocal.estimation.pipeline import FPA_SIGMA_HELP, check_fpa_sigma, refuse_unchecked
from thermocal.estimation.pipeline import estimate as run_pipeline
from thermocal.estimation.registry import (
    ESTIMATORS,
    check_method_options,
    make_estimator,
    method_help,
)

__all__ = ["backend_options", "estimate", "estimate_file"]


def backend_options(command, *, threads_help: str = (
        "Threads the network runs on (default: this process's CPU cores).")):
    """``--backend`` and ``--threads``: how a network runs (:mod:`thermocal.nn.backends`);
    ``threads_help``, what ``--threads`` says of itself."""
    from thermocal.nn.backends import BACKENDS, CHOICES

    command = click.option(
        "--threads", type=click.IntRange(min=1), default=None, help=threads_help)(command)
    return click.option(
        "--backend", type=click.Choice(CHOICES), default="torch", show_default=True,
        help="What runs the network: " + "; ".join(f"{b.name}: {b.summary}"
                                                  for b in BACKENDS.values())
        + "; auto: the fastest installed for many bursts (PyTorch for thermocal "
        "estimate's one; onnxruntime and openvino: pip install 'thermocal[backends]').")(command)


def estimate_file(
    frames_path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    fpa_c: float | None = None,
    fpa_sigma_c: float | None = None,
    method: str = "kpn",
    model_path: str | os.PathLike[str] | None = None,
    pivot: int | None = None,
    registered: bool = False,
    calibration: str | os.PathLike[str] | None = None,
    force: bool = False,
    sigma_out: str | os.PathLike[str] | None = None,
    backend: str = "torch",
    threads: int | None = None,
) -> Path:
    """``thermocal estimate``: read a recording, estimate the pivot's temperature through the
    estimator ``method`` (:data:`~thermocal.estimation.registry.ESTIMATORS`), write it.

    The output (float32 °C TIFF, ``(H, W)``) is written atomically and only after every check.
    A burst outside the estimator's domain is refused
    (:class:`~thermocal.errors.OutsideDomainError`) unless ``force``, which writes it with a
    warning that names why. ``sigma_out``: where to write its uncertainty (float32 °C, 1σ,
    ``(H, W)``), refused before any work when the estimator has none. ``backend``,
    ``threads``: what runs a network (:func:`~thermocal.estimation.registry.make_estimator`;
    ``auto`` is PyTorch for one burst, :func:`~thermocal.nn.backends.one_burst_backend`).
    A recording longer than a network's bursts gives it the frames around ``pivot``
    (:func:`~thermocal.burst.burst_window`); ``pivot`` indexes the recording. ``fpa_sigma_c``:
    the standard uncertainty of a typed ``fpa_c``, °C, which σ takes in
    (:func:`~thermocal.estimation.pipeline.estimate`).
    """
    from thermocal.io.geotag import map_tags
    from thermocal.io.open import check_outside_recording, read_any_recording
    from thermocal.io.recording import write_sigma_tiff, write_temperature_tiff
    from thermocal.io.replaces import check_map_replaces_only
    from thermocal.nn.backends import one_burst_backend

    check_fpa_sigma(fpa_c, fpa_sigma_c, sigma_out)
    if registered and method in ESTIMATORS and ESTIMATORS[method].needs == "recording":
        raise InvalidInputError(f"--registered: --method {method} maps the pivot frame alone, "
                                "through its own constants, which no registration touches: "
                                "leave it out")
    out = check_output_file(out, TIFF_SUFFIXES)
    check_not_input(out, frames_path, calibration, model_path)
    check_map_replaces_only(out)
    check_outside_recording(frames_path, (out, "--out"), (sigma_out, "--sigma-out"))
    if sigma_out is not None:
        sigma_out = check_output_file(sigma_out, TIFF_SUFFIXES)
        check_not_input(sigma_out, frames_path, calibration, model_path, what="--sigma-out")
        check_map_replaces_only(sigma_out, what="--sigma-out")
        check_outputs_differ(sigma_out, out, ("--sigma-out", "--out"))
    info = ESTIMATORS.get(method)
    if info is not None and info.needs == "model":  # a network on one burst
        backend = one_burst_backend(backend)
    own_constants = info is not None and info.needs == "recording"  # built from the file below
    if own_constants:
        check_method_options(method, backend=backend, threads=threads,
                             calibration=calibration, model=model_path, fpa_c=fpa_c,
                             force=force)
    estimator = (None if own_constants
                 else make_estimator(method, model=model_path, calibration=calibration,
                                     backend=backend, threads=threads))
    if estimator is not None:
        refuse_unchecked(estimator, calibration, force=force)
    # a network without its .sigma.json, a calibration without its report
    if sigma_out is not None and estimator is not None and getattr(
            estimator, "sigma_model", None) is None:
        raise InvalidInputError(f"--method {method} has no uncertainty model here: "
                                f"{NO_SIGMA_REMEDY[info.needs]}")
    rec = read_any_recording(frames_path, fpa_c=fpa_c)
    if estimator is None:  # the camera's own constants, from the file
        from thermocal.estimation.vendor import VendorCalibration

        estimator = VendorCalibration.from_recording(rec, frames_path)
    # a network takes bursts of its own length: the frames around --pivot (or the middle)
    window, pivot = _burst_of(rec, getattr(estimator, "n_frames", None), pivot, frames_path)
    fpa_series = None if rec.fpa_c is None else rec.fpa_c[window]
    times = None if rec.time_s is None else rec.time_s[window]
    try:
        result = run_pipeline(rec.frames[window], estimator, fpa_c=fpa_series, time_s=times,
                              pivot=pivot, registered=registered, force=force,
                              bit_depth=rec.bit_depth, fpa_sigma_c=fpa_sigma_c or 0.0,
                              **_pivot_pace(rec, estimator, window, pivot))
    except InvalidInputError as exc:  # a burst's fault: name the file it came from
        text = str(exc)
        if text.startswith(str(frames_path)):
            raise
        raise type(exc)(f"{frames_path}: {text}") from None
    if result.outside:
        click.echo(f"thermocal: warning: {frames_path} lies outside what {method} was "
                   f"trained or fitted on ({'; '.join(result.outside)}); estimated all the same "
                   "(--force)", err=True)
    # the pivot frame's GPS, time, make and model, as a flight's maps keep them
    metas = (rec.extra or {}).get("frame_metadata") or []
    at = (window.start or 0) + result.pivot  # the pivot among the frames read
    positions = (rec.extra or {}).get("frame_positions") or range(rec.n_frames)
    tags = map_tags(metas[at]) if len(metas) == rec.n_frames else None
    about = {"method": method, "source": Path(frames_path).name, "frame": int(positions[at])}
    if sigma_out is not None:  # σ first: a failure leaves neither file
        write_sigma_tiff(sigma_out, result.sigma_c, tags=tags,
                         about=about | {"temperature": Path(out).name})
    try:
        write_temperature_tiff(out, result.temperature_c, tags=tags, about=about | {
            "sigma": "none" if sigma_out is None else Path(sigma_out).name})
    except Exception:
        if sigma_out is not None:
            Path(sigma_out).unlink(missing_ok=True)
        raise
    return out


#: What to do when an estimator has no uncertainty model, by what it is built from.
NO_SIGMA_REMEDY = {
    "calibration": "the calibration file has no cross-validation report (made by an older "
                   "thermocal, or from a session with too few set points to leave one out): "
                   "calibrate again, from a session of at least 3 set points, to get its "
                   "uncertainty",
    "model": "its weights have no σ model beside them (NAME.sigma.json): fit one with "
             "`python -m thermocal.evaluation.sigma_fit WEIGHTS.pt` (with --chamber FILE for "
             "weights trained from a chamber file)",
    "pass": "selfcal fits a whole pass, not one burst: run `thermocal flight --method selfcal` "
            "on the recording (it writes σ beside each map)",
}


def warn_typed_fpa(method: str, fpa_c: float | None, fpa_sigma_c: float | None) -> None:
    """Say, once, that σ takes a typed ``--fpa-c`` as exact unless ``--fpa-sigma-c`` says how
    well it is known (the shipped network moves about 0.5 °C per °C of it: a helper's audit
    found 7.7 °C of error where σ said 0.84, from an FPA typed 15 °C off); the options were
    checked before the run (:func:`~thermocal.estimation.pipeline.check_fpa_sigma`)."""
    if fpa_c is not None and fpa_sigma_c is None and ESTIMATORS[method].needs != "recording":
        click.echo(f"thermocal: warning: σ takes --fpa-c {fpa_c:g} as exact; if it is not the "
                   "camera's own reading, give --fpa-sigma-c (its uncertainty, °C): the "
                   "temperatures move with it (the shipped network's about 0.5 °C per °C)",
                   err=True)


@click.command("estimate")
@click.argument("frames", type=click.Path(path_type=Path))
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    required=True,
    help="Output temperature TIFF (float32 °C, the pivot frame).",
)
@click.option(
    "--fpa-c", type=float, default=None, help="FPA temperature, °C (overrides the sidecar's fpa_c)."
)
@click.option("--fpa-sigma-c", type=float, default=None, help=FPA_SIGMA_HELP)
@click.option("--method", type=click.Choice(list(ESTIMATORS)), default="kpn", show_default=True,
              help=method_help())
@click.option(
    "--model",
    "model_path",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Weights file (default: the shipped model for --method: kpn; kpn-no-offset and e2e "
    "are not shipped, train them with `thermocal train --variant`).",
)
@click.option("--pivot", type=int, default=None,
              help="Pivot frame index in FRAMES (default: the middle); a network made for "
              "bursts of N frames takes the N frames around it.")
@click.option(
    "--registered",
    is_flag=True,
    help="The frames are already registered onto the pivot (skip registration; not for a network "
    "with --calibrated, the shipped one, which calibrates each frame before warping).",
)
@click.option(
    "--calibration",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Per-pixel calibration file (thermocal calibrate), for --method "
    + "|".join(n for n, e in ESTIMATORS.items() if e.needs == "calibration") + ".",
)
@click.option("--force", is_flag=True,
              help="Estimate a burst outside the method's domain (its FPA and scene range, its "
              "camera family) instead of refusing it; a warning names why and σ is inflated.")
@click.option("--sigma-out", type=click.Path(path_type=Path), default=None,
              help="Also write the estimate's standard uncertainty (float32 TIFF, °C, 1σ).")
@backend_options
def estimate(
    frames: Path,
    out: Path,
    fpa_c: float | None,
    fpa_sigma_c: float | None,
    method: str,
    model_path: Path | None,
    pivot: int | None,
    registered: bool,
    calibration: Path | None,
    force: bool,
    sigma_out: Path | None,
    backend: str,
    threads: int | None,
) -> None:
    """Estimate the scene temperature of a burst's pivot frame (by default the shipped network,
    Oz et al.'s KPN + offset; --method for the others).

    FRAMES are whole sensor frames as the camera gave them (not crops): a model trained with
    --radial uses where on the sensor each pixel lies. FRAMES: a file or a folder in any format
    `thermocal info` reads (the project's TIFF + JSON, FLIR FFF/SEQ/CSQ, R-JPEGs, DualTauUAV);
    damaged frames are left out with a warning naming them."""
    estimate_file(
        frames,
        out,
        fpa_c=fpa_c,
        fpa_sigma_c=fpa_sigma_c,
        method=method,
        model_path=model_path,
        pivot=pivot,
        registered=registered,
        calibration=calibration,
        force=force,
        sigma_out=sigma_out,
        backend=backend,
        threads=threads,
    )
    if sigma_out is not None:
        warn_typed_fpa(method, fpa_c, fpa_sigma_c)
    click.echo(f"wrote {out}" + (f" and its σ to {sigma_out}" if sigma_out is not None else ""),
               err=True)


def _burst_of(rec: Any, n: int | None, pivot: int | None, path: Any
              ) -> tuple[slice, int | None]:
    """:func:`~thermocal.burst.burst_window` with ``pivot`` numbered as the recording's frames
    were at open, as ``thermocal flight`` and ``info`` number them: a frame that does not decode
    (left out of ``rec``, with a warning) keeps its number, and a burst that would hold it is
    refused, naming it. Without ``pivot``, the middle of the frames that decode (so that a
    default run is never refused for a frame it could do without)."""
    from thermocal.burst import burst_window, pivot_index

    positions = (rec.extra or {}).get("frame_positions")
    total = (rec.extra or {}).get("frames_at_open", rec.n_frames)
    if (pivot is None or positions is None or len(positions) != rec.n_frames
            or total == rec.n_frames):  # no --pivot: the middle of the frames that decode
        return burst_window(rec.n_frames, n, pivot)
    if n is None or total <= n:  # every frame that decodes, the pivot by its number
        at = pivot_index(pivot, total)
        if at not in positions:
            raise InvalidInputError(f"{path}: frame {at} does not decode (see the warning): "
                                    "give another --pivot")
        return slice(0, rec.n_frames), positions.index(at)
    window, at = burst_window(total, n, pivot)
    missing = sorted(set(range(window.start, window.stop)) - set(positions))
    if missing:
        listed = ", ".join(map(str, missing))
        raise InvalidInputError(
            f"{path}: frame{'s' * (len(missing) > 1)} {listed} of the burst "
            f"{window.start}-{window.stop - 1} do{'es' * (len(missing) == 1)} not decode (see "
            "the warning): give another --pivot")
    first = positions.index(window.start)
    return slice(first, first + window.stop - window.start), at


def _pivot_pace(rec: Any, estimator: Any, window: slice, pivot: int | None) -> dict[str, Any]:
    """How the FPA was changing at the pivot, from the whole recording as ``thermocal flight``
    takes it (:func:`~thermocal.estimation.paces.recording_paces`): the pipeline's
    ``fpa_rate_c_per_min``, ``fpa_lagged_rate_c_per_min``, ``fpa_still_s``,
    ``fpa_lag_rates_c_per_min``, ``fpa_sustained_s``, ``fpa_swing_c`` and
    ``time_since_start_s``, each None where not known (a pivot out of range is the pipeline's
    to refuse)."""
    from thermocal.burst import pivot_index
    from thermocal.estimation.paces import pace_at, recording_paces

    try:
        k = window.start + pivot_index(pivot, window.stop - window.start)
    except InvalidInputError:
        return pace_at({}, None, 0)
    paces = recording_paces(rec.fpa_c, rec.time_s, getattr(estimator, "fpa_paces", {}),
                            getattr(estimator, "rate_lags_s", ()))
    return pace_at(paces, rec.time_s, k)
