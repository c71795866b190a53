"""``thermocal train`` (torch is imported inside the command only)."""

from __future__ import annotations

from pathlib import Path

import click

from thermocal.errors import InvalidInputError


def _parse_units(text: str) -> tuple[int, ...]:
    """``"0-23"``, ``"3"`` or ``"0,2,5-7"`` → unit numbers."""
    units: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if "-" in part:
                a, b = (int(x) for x in part.split("-"))
                units.extend(range(a, b + 1))
            elif part:
                units.append(int(part))
    except ValueError:
        raise InvalidInputError(f"units {text!r}: expected e.g. 0-23 or 0,2,5-7") from None
    if not units or min(units) < 0:
        raise InvalidInputError(f"units {text!r}: give unit numbers >= 0")
    return tuple(dict.fromkeys(units))


def _parse_range(text: str, name: str) -> tuple[float, float]:
    try:
        a, b = (float(x) for x in text.split(":"))
    except ValueError:
        raise InvalidInputError(f"{name} {text!r}: expected LOW:HIGH, e.g. 10:50") from None
    if not a < b:
        raise InvalidInputError(f"{name} {text!r}: LOW must be below HIGH")
    return a, b


@click.command("train")
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    required=True,
    help="Weights file to write (.pt); a checkpoint OUT.ckpt is kept beside it.",
)
@click.option(
    "--frames", "n_frames", type=int, default=7, show_default=True, help="Frames per burst N."
)
@click.option("--steps", type=int, default=None, help="Stop after this many batches.")
@click.option("--seed", type=int, default=42, show_default=True)
@click.option(
    "--variant",
    type=click.Choice(["kpn", "kpn-no-offset", "e2e"]),
    default="kpn",
    show_default=True,
)
@click.option("--mu", type=int, default=16, show_default=True, help="Channels μ (paper: 64).")
@click.option("--xi", type=int, default=2, show_default=True, help="Level factor ξ.")
@click.option("--levels", type=int, default=3, show_default=True, help="Levels L (paper: 4).")
@click.option("--kernel", type=int, default=5, show_default=True, help="Kernel side K.")
@click.option("--degree", type=int, default=4, show_default=True, help="Offset degree ν.")
@click.option(
    "--fpa-input/--no-fpa-input",
    default=True,
    show_default=True,
    help="Feed the FPA temperature to the UNet too (not only the offset block).",
)
@click.option(
    "--centre/--no-centre",
    default=True,
    show_default=True,
    help="KPN with offset block: apply the kernels to the frames minus the burst's "
    "mean level (the offset block carries the level).",
)
@click.option(
    "--radiance/--no-radiance",
    default=True,
    show_default=True,
    help="The kernels and the offset give band radiance, turned into temperature by the "
    "inverse of Planck's band integral (an addition to the paper).",
)
@click.option(
    "--radial",
    type=click.IntRange(0, 4),
    default=2,
    show_default=True,
    help="Degree in R² of position terms: the UNet sees where on the sensor a pixel lies and "
    "the offset block gives a radial map (an addition to the paper; 0: none, as the paper).",
)
@click.option("--crop", type=int, default=64, show_default=True, help="Training crop side, px.")
@click.option("--batch", type=int, default=16, show_default=True)
@click.option("--steps-per-epoch", type=int, default=100, show_default=True)
@click.option("--max-epochs", type=int, default=60, show_default=True)
@click.option("--lr", type=float, default=1e-4, show_default=True)
@click.option(
    "--units",
    "units_text",
    default="0-23",
    show_default=True,
    help="Training camera units of the preset.",
)
@click.option(
    "--val-units",
    "val_units_text",
    default="50-53",
    show_default=True,
    help="Validation camera units (never training units).",
)
@click.option(
    "--fpa-range-c",
    default=None,
    help="FPA temperature range of the training data, °C (default 10:50, or the "
    "range the chamber file covers).",
)
@click.option("--val-bursts", type=int, default=64, show_default=True)
@click.option(
    "--scenes",
    "n_scenes",
    type=int,
    default=24,
    show_default=True,
    help="Procedural maps in the training pool (beside the real training scenes).",
)
@click.option(
    "--chamber",
    type=click.Path(path_type=Path),
    default=None,
    help="Fit the camera model on this chamber file (polynomial + radial) and train "
    "on it instead of the simulator preset.",
)
@click.option(
    "--max-minutes",
    type=float,
    default=None,
    help="Wall-clock budget; the run saves and stops cleanly when it runs out.",
)
@click.option(
    "--lr-schedule",
    type=click.Choice(["plateau", "step"]),
    default="plateau",
    show_default=True,
    help="plateau (Oz et al.): halve the learning rate once more than 3 epochs in a row have "
    "not improved the validation loss, stop after 8; step: halve it at 50 % and 75 % of the "
    "budget (--steps, --max-minutes or --max-epochs, the first to run out), no early stop. "
    "--resume keeps the checkpoint's schedule and its budget for the rate.",
)
@click.option("--resume", is_flag=True, help="Continue from OUT.ckpt.")
@click.option("--threads", type=int, default=2, show_default=True)
@click.option(
    "--workers", type=int, default=1, show_default=True, help="Data-generating processes."
)
@click.option(
    "--temp-mean-range-c",
    default=None,
    help="Range of the training maps' mean temperature, °C (default -15:60).",
)
@click.option(
    "--redraw-pixel-fpn",
    is_flag=True,
    help="Give every training burst a new pixel FPN of the preset's spread instead of its "
    "unit's own (the validation units keep theirs).",
)
@click.option(
    "--walk-frames",
    type=int,
    default=None,
    help="Draw each training trajectory for this many frames and keep the --frames around its "
    "pivot (less motion per burst; the validation bursts keep --frames).",
)
@click.option(
    "--sensor-motion",
    is_flag=True,
    help="Displace the training frames on the sensor as whole-sensor frames of the same overlap "
    "are (each frame rendered by its own sensor window), not by crop-sized amounts; the "
    "validation bursts too.",
)
@click.option(
    "--radial-frames",
    is_flag=True,
    help="With --radial: the position terms take where on the sensor each frame saw each pixel "
    "(N planes), not the pivot's position alone.",
)
@click.option(
    "--calibrated/--no-calibrated",
    default=True,
    show_default=True,
    help="Give the network each frame through the camera model it is trained from (the "
    "training units' average, or the --chamber fit), not raw counts: it learns what that model "
    "gets wrong for the unit at hand (an addition to the paper; the model travels with the "
    "weights).",
)
@click.option(
    "--init",
    "init",
    type=click.Path(path_type=Path),
    default=None,
    help="Start from this weights file, or 'shipped' for the shipped KPN (same network; its "
    "normalisation is kept).",
)
@click.option(
    "--device",
    type=click.Choice(["auto", "cpu", "cuda"]),
    default="auto",
    show_default=True,
    help="Where the network trains (auto: a GPU when there is one).",
)
def train(
    out: Path,
    n_frames: int,
    steps: int | None,
    seed: int,
    variant: str,
    mu: int,
    xi: int,
    levels: int,
    kernel: int,
    degree: int,
    fpa_input: bool,
    centre: bool,
    radiance: bool,
    radial: int,
    crop: int,
    batch: int,
    steps_per_epoch: int,
    max_epochs: int,
    lr: float,
    units_text: str,
    val_units_text: str,
    fpa_range_c: str | None,
    val_bursts: int,
    n_scenes: int,
    chamber: Path | None,
    max_minutes: float | None,
    lr_schedule: str,
    resume: bool,
    threads: int,
    workers: int,
    temp_mean_range_c: str | None,
    redraw_pixel_fpn: bool,
    walk_frames: int | None,
    sensor_motion: bool,
    radial_frames: bool,
    calibrated: bool,
    init: Path | None,
    device: str,
) -> None:
    """Train the KPN on synthetic bursts from the camera simulator (Oz et al. §IV)."""
    import os
    import sys

    # OpenMP threads that sleep instead of spinning while they wait: on a shared machine a
    # spinning thread burns the core the other one needs (3x slower steps, measured).
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

    from thermocal.camera.presets import PRESETS
    from thermocal.nn.data import BurstConfig, ScenePool
    from thermocal.nn.model import ModelConfig
    from thermocal.nn.train import TrainConfig
    from thermocal.nn.train import train as run_training

    for name, value in (
        ("--frames", n_frames),
        ("--batch", batch),
        ("--steps-per-epoch", steps_per_epoch),
        ("--max-epochs", max_epochs),
        ("--threads", threads),
        ("--val-bursts", val_bursts),
        ("--scenes", n_scenes),
    ):
        if value < 1:
            raise InvalidInputError(f"{name} must be >= 1, got {value}")
    if steps is not None and steps < 1:
        raise InvalidInputError(f"--steps must be >= 1, got {steps}")
    if workers < 0:
        raise InvalidInputError(f"--workers must be >= 0, got {workers}")
    if max_minutes is not None and max_minutes <= 0:
        raise InvalidInputError(f"--max-minutes must be > 0, got {max_minutes}")
    if lr <= 0:
        raise InvalidInputError(f"--lr must be > 0, got {lr}")
    units = _parse_units(units_text)
    val_units = _parse_units(val_units_text)
    fpa_range = _parse_range(fpa_range_c, "--fpa-range-c") if fpa_range_c else (10.0, 50.0)
    cameras = None
    sensor_size = (336, 256)
    band_m = PRESETS["tau2"].band_m
    meta = {"command": " ".join(sys.argv[1:]) if sys.argv else ""}
    if chamber is not None:
        try:
            from thermocal.calibration.polynomial import camera_model_from_chamber
        except ImportError:
            raise InvalidInputError(
                "--chamber needs thermocal.calibration.camera_model_from_chamber, which this "
                "installation does not have"
            ) from None
        camera = camera_model_from_chamber(chamber, radial=True)
        cameras = {0: camera}
        units, val_units = (0,), (0,)
        sensor_size = (camera.shape[1], camera.shape[0])
        band_m = camera.band.band_m
        meta["chamber"] = str(chamber)
        if fpa_range_c is None and "fpa_range_c" in camera.info:
            fpa_range = tuple(float(v) for v in camera.info["fpa_range_c"])
    if crop > min(sensor_size):
        raise InvalidInputError(f"--crop {crop} is larger than the sensor {sensor_size}")
    model_cfg = ModelConfig(
        n_frames=n_frames,
        mu=mu,
        xi=xi,
        levels=levels,
        kernel=kernel,
        degree=degree,
        variant=variant,
        fpa_input=fpa_input,
        centre=centre and variant == "kpn",
        radiance=radiance,
        radial=radial,
        band_m=band_m,
        radial_frames=radial_frames,
        calibrated=calibrated,
    )
    if crop % model_cfg.multiple:
        raise InvalidInputError(f"--crop must be a multiple of ξ^L = {model_cfg.multiple}")
    if init is not None and str(init) == "shipped":
        from thermocal.nn.infer import shipped_model_path

        init = shipped_model_path("kpn")
    extra = {}
    if temp_mean_range_c:
        extra["temp_mean_range_c"] = _parse_range(temp_mean_range_c, "--temp-mean-range-c")
    if redraw_pixel_fpn:
        extra["redraw_pixel_fpn"] = True
    if walk_frames is not None:
        extra["walk_frames"] = walk_frames
    if calibrated:
        extra["calibrated"] = True
    if sensor_motion:
        extra["sensor_motion"] = True
    elif radial_frames:
        click.echo("warning: --radial-frames without --sensor-motion: the training frames move "
                   "by crop-sized amounts, far less than whole-sensor bursts do", err=True)
    burst_cfg = BurstConfig(
        n_frames=n_frames,
        crop=crop,
        fpa_range_c=fpa_range,
        units=units,
        sensor_size=sensor_size,
        **extra,
    )
    train_cfg = TrainConfig(
        batch=batch,
        steps_per_epoch=steps_per_epoch,
        max_epochs=max_epochs,
        lr=lr,
        lr_schedule=lr_schedule,
        seed=seed,
        val_bursts=val_bursts,
        max_minutes=max_minutes,
        max_steps=steps,
        threads=threads,
        workers=workers,
        device=device,
    )

    def log(line: str) -> None:
        click.echo(line, err=True)

    n_val_scenes = max(3, (3 * n_scenes) // 8)

    def pool_fn() -> ScenePool:
        return ScenePool.training(seed=seed, n_procedural=n_scenes)

    def val_pool_fn() -> ScenePool:
        return ScenePool.training(seed=seed + 1000, n_procedural=n_val_scenes)

    result = run_training(
        out,
        model_cfg,
        burst_cfg,
        train_cfg,
        resume=resume,
        cameras=cameras,
        val_units=val_units,
        log=log,
        meta=meta,
        pool_fn=pool_fn,
        val_pool_fn=val_pool_fn,
        init=init,
    )
    click.echo(
        f"trained {result.steps} steps ({result.epochs} epochs, stopped: {result.stopped}) in "
        f"{result.wall_s / 60:.1f} min at {result.samples_per_s:.1f} samples/s; best validation "
        f"MAE {result.best_val_mae_c:.3f} °C; wrote {out}",
        err=True,
    )
