"""``thermocal flight``: a whole recording → temperature maps, previews and a log."""

from __future__ import annotations

from pathlib import Path

import click

from thermocal.estimation.registry import ESTIMATORS, method_help
from thermocal.progress import progress_bar


@click.command("flight")
@click.argument("recording", type=click.Path(path_type=Path))
@click.option("--out", "out_dir", type=click.Path(path_type=Path), required=True,
              help="Output folder (created; a rerun resumes).")
@click.option("--method", type=click.Choice(list(ESTIMATORS)), default="kpn", show_default=True,
              help=method_help())
@click.option("--calibration", type=click.Path(dir_okay=False), default=None,
              help="Calibration file (thermocal calibrate) for --method mean|calibration.")
@click.option("--model", type=click.Path(dir_okay=False), default=None,
              help="Network weights (default: the shipped model of --method).")
@click.option("--frames", "n_frames", type=int, default=7, show_default=True,
              help="Frames per group (the network's N).")
@click.option("--stride", type=int, default=7, show_default=True, help="Frames between pivots.")
@click.option("--fpa-c", type=float, default=None, help="FPA temperature, °C (overrides sidecar).")
@click.option("--preview-every", type=int, default=1, show_default=True,
              help="A PNG preview every K pivots (0: none).")
@click.option("--force", is_flag=True,
              help="Estimate groups outside the method's domain (FPA or scene range, camera "
              "family) instead of failing them; the log says why each is not validated.")
def flight(recording: Path, out_dir: Path, method: str, calibration: str | None,
           model: str | None, n_frames: int, stride: int, fpa_c: float | None,
           preview_every: int, force: bool) -> None:
    """Turn a whole RECORDING into one temperature map per pivot: frames.tiff + sidecar, or any
    format thermocal reads (FLIR SEQ/CSQ/FFF, R-JPEGs, a folder of them, a DualTauUAV flight)."""
    from thermocal._validate import check_not_input
    from thermocal.errors import ThermocalError
    from thermocal.io.open import recording_length
    from thermocal.pipeline.flight import FlightOptions, process_flight

    check_not_input(out_dir, recording, calibration, model)
    options = FlightOptions(method=method, calibration=calibration, model=model, frames=n_frames,
                            stride=stride, fpa_c=fpa_c, preview_every=preview_every,
                            force=force)
    total = recording_length(recording)
    with progress_bar() as bar:
        task = bar.add_task("flight", total=total - total % stride or total)
        summary = process_flight(recording, out_dir, options,
                                 progress=lambda k: bar.advance(task, k))
    if summary["processed"] == 0 and summary["skipped_already_done"] == 0:
        # the summary and the log are written; exit 2 rather than report success
        raise ThermocalError(
            f"no temperature map made: all {summary['groups']} groups failed; the first, "
            f"{summary.get('first_error')}; every group's error is in {Path(out_dir) / 'log.csv'}"
        )
    click.echo(
        f"{summary['processed']} temperature maps written to {out_dir}/temps "
        f"({summary['skipped_already_done']} already done, {summary['failed']} failed) "
        f"in {summary['wall_time_s']:.1f} s"
    )
