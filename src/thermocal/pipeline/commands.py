"""``thermocal flight``: a whole recording → temperature maps, previews, a log and a report;
``thermocal mosaic`` and ``thermocal report``: a processed flight's mosaic and report."""

from __future__ import annotations

from pathlib import Path

import click

from thermocal.estimation.commands import backend_options, warn_typed_fpa
from thermocal.estimation.pipeline import FPA_SIGMA_HELP
from thermocal.estimation.registry import ESTIMATORS, method_help
from thermocal.nn.variants import sigma_warning
from thermocal.progress import progress_bar


def flight_options(command):
    """The options of ``thermocal flight`` that ``thermocal campaign`` passes on to each of its
    flights: the method and its files, the FPA temperature, the groups, the previews,
    ``--force``, ``selfcal``'s family, and how a network runs
    (:func:`~thermocal.estimation.commands.backend_options`)."""
    options = [
        click.option("--method", type=click.Choice(list(ESTIMATORS)), default="kpn",
                     show_default=True, help=method_help()),
        click.option("--calibration", type=click.Path(dir_okay=False), default=None,
                     help="Calibration file (thermocal calibrate) for --method "
                     "mean|calibration; for --method selfcal, the model to start from "
                     "(default: the family's average unit)."),
        click.option("--model", type=click.Path(dir_okay=False), default=None,
                     help="Network weights (default: the shipped model of --method)."),
        click.option("--fpa-c", type=float, default=None,
                     help="FPA temperature, °C, for every frame (overrides a sidecar's; FLIR "
                     "files carry none)."),
        click.option("--fpa-sigma-c", type=float, default=None, help=FPA_SIGMA_HELP),
        click.option("--frames", "n_frames", type=int, default=7, show_default=True,
                     help="Frames per group (the network's N)."),
        click.option("--stride", type=int, default=7, show_default=True,
                     help="Frames between pivots."),
        click.option("--preview-every", type=int, default=1, show_default=True,
                     help="A PNG preview every K pivots (0: none)."),
        click.option("--force", is_flag=True,
                     help="Estimate groups outside the method's domain (FPA or scene range, "
                     "camera family) instead of failing them; the log says why each is not "
                     "validated."),
        click.option("--family", type=click.Choice(["tau2", "boson"]), default="tau2",
                     show_default=True,
                     help="Camera family whose average unit --method selfcal starts from "
                     "(without --calibration)."),
    ]
    command = backend_options(command, threads_help=(
        "Threads the network runs on, one group at a time (default: a group per CPU core at "
        "once, each on one thread: the same maps, sooner)."))
    for option in reversed(options):  # listed in --help in this order
        command = option(command)
    return command


@click.command("flight")
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Output folder (created; a rerun resumes).")
@flight_options
@click.option("--geotiff", is_flag=True,
              help="Also GeoTIFF tags (EPSG:4326, rotated by the yaw) in the maps of nadir "
              "frames with GPS and DJI relative altitude; the maps of frames with GPS always "
              "carry it as EXIF/XMP.")
@click.option("--mosaic", "with_mosaic", is_flag=True,
              help="Also mosaic the maps into OUT/mosaic (thermocal mosaic OUT).")
@click.option("--hfov-deg", type=float, default=None,
              help="Horizontal field of view, degrees, for --geotiff (default: the file's, "
              "else its lens's, from the EXIF focal length, else the camera's: DJI "
              "XT/XT-R/XT2 with the 13 mm lens, 45° at 640 px).")
@click.option("--reference", "reference", type=click.Path(dir_okay=False), default=None,
              help="Ground references for --method selfcal: a CSV with columns frame,x,y,"
              "radius_px,temperature_c (optional emissivity, reflected_c, sigma_c); they fix "
              "the unit's level.")
def flight(recording: Path, out_dir: Path, method: str, calibration: str | None,
           model: str | None, n_frames: int, stride: int, fpa_c: float | None,
           fpa_sigma_c: float | None,
           preview_every: int, force: bool, geotiff: bool, with_mosaic: bool,
           hfov_deg: float | None, family: str, reference: str | None, backend: str,
           threads: int | None) -> None:
    """Turn a whole RECORDING into one temperature map per pivot: frames.tiff + sidecar, or any
    format thermocal reads (FLIR SEQ/CSQ/FFF, R-JPEGs, a folder of them, a DualTauUAV flight).
    Ends with OUT/report.html (and OUT/mosaic with --mosaic)."""
    from thermocal._validate import check_not_input
    from thermocal.errors import ThermocalError
    from thermocal.io.open import check_outside_recording, recording_length
    from thermocal.pipeline.flight import FlightOptions, process_flight
    from thermocal.pipeline.report import write_report

    check_not_input(out_dir, recording, calibration, model, reference)
    check_outside_recording(recording, (out_dir, "--out"))
    options = FlightOptions(method=method, calibration=calibration, model=model, frames=n_frames,
                            stride=stride, fpa_c=fpa_c, fpa_sigma_c=fpa_sigma_c,
                            preview_every=preview_every,
                            force=force, geotiff=geotiff, hfov_deg=hfov_deg, family=family,
                            references=reference, backend=backend, threads=threads)
    total = recording_length(recording)
    with progress_bar() as bar:
        task = bar.add_task("flight", total=total - total % stride or total)
        summary = process_flight(recording, out_dir, options,
                                 progress=lambda k: bar.advance(task, k),
                                 command=_command_line())
    mosaic_note = _mosaic_after_flight(out_dir) if with_mosaic and summary["processed"] + \
        summary["skipped_already_done"] else ""
    report = write_report(out_dir)
    if summary["processed"] == 0 and summary["skipped_already_done"] == 0:
        # the summary and the log are written; exit 2 rather than report success
        raise ThermocalError(
            f"no temperature map made: all {summary['groups']} groups failed; the first, "
            f"{summary.get('first_error')}; every group's error is in {Path(out_dir) / 'log.csv'} "
            f"and {report}"
        )
    if summary.get("sigma_c") is None:  # never silently: maps without their uncertainty
        _warn_no_sigma(method)
    else:
        warn_typed_fpa(method, fpa_c, fpa_sigma_c)
    click.echo(
        f"{summary['processed']} temperature maps written to {out_dir}/temps "
        f"({summary['skipped_already_done']} already done, {summary['failed']} failed) "
        f"in {summary['wall_time_s']:.1f} s{mosaic_note}; report: {report}"
    )


@click.command("campaign")
@click.argument("inputs", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Output folder: one flight folder per recording, and campaign.json (a rerun "
              "resumes).")
@click.option("--scheduler", default=None,
              help="Address of a running Dask scheduler (tcp://HOST:8786; one of dask-jobqueue "
              "or dask-kubernetes); default: a LocalCluster of this machine's cores.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Workers of the LocalCluster (default: this process's CPU cores).")
@flight_options
def campaign(inputs: tuple[Path, ...], out_dir: Path, scheduler: str | None,
             workers: int | None, method: str, calibration: str | None, model: str | None,
             fpa_c: float | None, fpa_sigma_c: float | None, n_frames: int, stride: int,
             preview_every: int, force: bool, family: str, backend: str,
             threads: int | None) -> None:
    """Process many RECORDINGS as `thermocal flight` runs, each a task on a Dask cluster (a
    LocalCluster of this machine by default, or --scheduler): OUT/<name> per recording, the
    same bytes as `thermocal flight`; a failed recording is reported in OUT/campaign.json and
    the others go on."""
    from thermocal._validate import check_not_input
    from thermocal.errors import InvalidInputError, ThermocalError
    from thermocal.pipeline.campaign import campaign_tasks, run_campaign
    from thermocal.pipeline.flight import FlightOptions

    if scheduler is not None and workers is not None:  # the cluster's own workers run them
        raise InvalidInputError("--workers sizes the LocalCluster; with --scheduler the "
                                "cluster's own workers run the tasks: leave --workers out")
    check_not_input(out_dir, *inputs, calibration, model)
    options = FlightOptions(method=method, calibration=calibration, model=model,
                            frames=n_frames, stride=stride, fpa_c=fpa_c, fpa_sigma_c=fpa_sigma_c,
                            preview_every=preview_every, force=force, family=family,
                            backend=backend, threads=threads)
    tasks = campaign_tasks(list(inputs), out_dir, options)
    with progress_bar() as bar:
        task = bar.add_task("campaign", total=sum(t.frames for t in tasks))
        summary = run_campaign(tasks, out_dir, scheduler=scheduler, workers=workers,
                               progress=lambda k: bar.advance(task, k))
    for r in summary["recordings"]:  # results on stdout, as a flight's: stderr is for errors
        click.echo(f"{r['name']}: " + (f"{r['processed']} maps made, "
                                       f"{r['skipped_already_done']} already done, "
                                       f"{r['failed_groups']} groups failed" if r["ok"]
                                       else f"failed: {r['error']}"))
    no_sigma = [r["name"] for r in summary["recordings"] if r["ok"] and not r.get("sigma", True)]
    if no_sigma:  # as a flight says it: never silently
        _warn_no_sigma(method, of=no_sigma)
    said = sigma_warning(method)
    if said and len(no_sigma) < sum(r["ok"] for r in summary["recordings"]):
        click.echo(f"thermocal: warning: {said}", err=True)  # said on the workers, not here
    if len(no_sigma) < sum(r["ok"] for r in summary["recordings"]):
        warn_typed_fpa(method, fpa_c, fpa_sigma_c)
    _echo_workers_warnings(summary["recordings"], said=said)
    if summary["failed"]:
        total = len(summary["recordings"])
        raise ThermocalError(
            (f"all {total} recordings failed" if summary["failed"] == total else
             f"{summary['failed']} of {total} recordings failed (the others are done)")
            + f"; each one's error is in {Path(out_dir) / 'campaign.json'}")
    click.echo(f"{len(summary['recordings'])} recordings processed into {out_dir} in "
               f"{summary['wall_time_s']:.1f} s")


def _echo_workers_warnings(recordings: list[dict], *, said: str = "") -> None:
    """Say on stderr what the workers warned while processing ``recordings`` (each result's
    ``warnings``, kept in campaign.json), as a flight says its own: each text once, with the
    recordings that raised it (``said``, already said, left out)."""
    raised: dict[str, list[str]] = {}
    for r in recordings:
        for text in r.get("warnings", ()):
            raised.setdefault(text, []).append(r["name"])
    for text, names in raised.items():
        if text != said:
            click.echo(f"thermocal: warning: {', '.join(names)}: {text}", err=True)


def _warn_no_sigma(method: str, *, of: list[str] | None = None) -> None:
    """Say on stderr that maps were written without their σ, and what to do about it."""
    from thermocal.estimation.commands import NO_SIGMA_REMEDY

    why = NO_SIGMA_REMEDY.get(ESTIMATORS[method].needs, "")
    which = "" if of is None else f" of {len(of)} recording{'s' * (len(of) > 1)} ({', '.join(of)})"
    click.echo(f"thermocal: warning: the maps{which} have no uncertainty (no σ files): "
               f"--method {method} has no uncertainty model here" + (f": {why}" if why else ""),
               err=True)


def _command_line() -> str:
    """The running command with every option it took, defaults included, as a shell would
    take it (for the report: it reruns the same way even after the defaults change)."""
    import shlex

    ctx = click.get_current_context()
    words = ctx.command_path.split()
    for param in ctx.command.params:
        value = ctx.params.get(param.name)
        if isinstance(param, click.Argument):
            words.append(str(value))
        elif value is True:
            words.append(param.opts[0])
        elif value is not None and value is not False:
            words += [param.opts[0], str(value)]
    return shlex.join(words)


def _mosaic_after_flight(out_dir: Path) -> str:
    """Mosaic a finished flight; a mosaic that cannot be made is a warning, not a failed
    flight (its maps stand). Returns a note for the flight's last line."""
    import warnings

    from thermocal.errors import InvalidInputError
    from thermocal.pipeline.mosaic import build_mosaic

    try:
        mosaic = build_mosaic(out_dir)
    except InvalidInputError as exc:
        warnings.warn(f"no mosaic: {exc}", stacklevel=2)
        return ""
    return f"; a mosaic of {len(mosaic['maps_used'])} maps in {Path(out_dir) / 'mosaic'}"


@click.command("mosaic")
@click.argument("out_dir", metavar="OUT", type=click.Path(path_type=Path))
@click.option("--clip-sigma", type=float, default=3.0, show_default=True,
              help="Leave out views further than this many robust SDs from the median.")
@click.option("--clip-floor-c", type=float, default=0.1, show_default=True,
              help="Smallest robust SD, °C (views this close to the median are kept).")
@click.option("--memory-mb", type=float, default=512.0, show_default=True,
              help="Memory for one tile's views, MiB (the canvas layers come on top).")
@click.option("--motion", metavar="[rigid|affine]", default="rigid", show_default=True,
              help="Consecutive maps differ by a rotation and translation, or an affine map.")
def mosaic(out_dir: Path, clip_sigma: float, clip_floor_c: float, memory_mb: float,
           motion: str) -> None:
    """Mosaic the temperature maps of a processed flight OUT (thermocal flight --out OUT) into
    OUT/mosaic: temperature, views, spread and σ TIFFs, a preview and mosaic.json; then
    rewrite OUT/report.html with it."""
    from thermocal.pipeline.mosaic import build_mosaic, check_options
    from thermocal.pipeline.report import load_summary, write_report

    # first here, so that a bad value is named by its option, not by the function's keyword
    check_options(clip_sigma=clip_sigma, clip_floor_c=clip_floor_c, memory_mb=memory_mb,
                  option=lambda keyword: "--" + keyword.replace("_", "-"))
    if (Path(out_dir) / "summary.json").exists():  # the report follows: its summary first, so
        load_summary(Path(out_dir))  # that a damaged one leaves no mosaic without its report
    summary = build_mosaic(out_dir, clip_sigma=clip_sigma, clip_floor_c=clip_floor_c,
                           memory_mb=memory_mb, motion=motion)
    canvas = summary["canvas"]
    report = write_report(out_dir) if (Path(out_dir) / "summary.json").is_file() else None
    click.echo(
        f"mosaic of {len(summary['maps_used'])} maps ({len(summary['maps_left_out'])} left out) "
        f"{canvas['width']}x{canvas['height']} px, {100 * canvas['covered_fraction']:.0f} % "
        f"covered, written to {Path(out_dir) / 'mosaic'} in {summary['seconds']['total']:.1f} s"
        + (f"; report: {report}" if report else "")
    )


@click.command("report")
@click.argument("out_dir", metavar="OUT", type=click.Path(path_type=Path))
def report(out_dir: Path) -> None:
    """Write OUT/report.html: the report of the flight output folder OUT (thermocal flight),
    one self-contained page to read offline."""
    from thermocal.pipeline.report import write_report

    click.echo(f"report written to {write_report(out_dir)}")
