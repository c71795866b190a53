"""``thermocal train`` (torch is imported inside the command only).

The options' defaults are the configuration of the shipped network (``nn/weights/kpn_n7.pt``):
``--preset shipped``, the default. ``--preset paper`` gives Oz et al.'s optimisation (§IV-D)
instead. An option given on the command line wins over the preset. ``--help`` lists the options
a run needs (output, budget, camera, machine); the experiment options (network sizes, training
data, optimisation) are left out of it and listed by ``--help-all``.
"""

from __future__ import annotations

import copy
import math
from pathlib import Path
from typing import Any

import click
from click.core import ParameterSource

from thermocal._validate import parse_range, parse_units
from thermocal.errors import InvalidInputError
from thermocal.nn.variants import VARIANTS, sigma_warning

#: The configuration of the shipped network, ``nn/weights/kpn_n7.pt`` (trained by ``--device
#: cuda --workers 14 --max-minutes 8.2``: 20100 steps on an H100), by option name.
SHIPPED: dict[str, Any] = {
    "n_frames": 7,
    "variant": "kpn",
    "mu": 16,
    "xi": 2,
    "levels": 3,
    "kernel": 5,
    "degree": 4,
    "fpa_input": True,
    "centre": True,
    "radiance": True,
    "radial": 2,
    "radial_frames": False,
    "calibrated": True,
    "crop": 64,
    "batch": 16,
    "steps_per_epoch": 100,
    "max_epochs": 1000,
    "lr": 1e-3,
    "lr_schedule": "step",
    "max_minutes": 30.0,
    "seed": 42,
    "units_text": "0-23",
    "val_units_text": "50-53",
    "val_bursts": 64,
    "n_scenes": 24,
    "fpa_range_c": None,
    "temp_mean_range_c": None,
    "redraw_pixel_fpn": False,
    "walk_frames": None,
    "sensor_motion": False,
}

#: ``--preset NAME``: the values of the options not given on the command line.
PRESETS: dict[str, dict[str, Any]] = {
    "shipped": SHIPPED,
    # Oz et al. §IV-D: Adam at 1e-4 halved on validation plateaus, early stop; no time limit
    "paper": {"lr": 1e-4, "lr_schedule": "plateau", "max_epochs": 60, "max_minutes": None},
}


# --------------------------------------------------------------------------------------------
# --help and --help-all
# --------------------------------------------------------------------------------------------
_HELP_ALL = "thermocal.train.help_all"


class _TrainCommand(click.Command):
    """``--help`` lists the options that are not hidden; ``--help-all`` the hidden ones too,
    under "Experiment options"."""

    def format_options(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        main, hidden = [], []
        for param in self.get_params(ctx):
            record = param.get_help_record(ctx)
            if record:
                main.append(record)
            elif isinstance(param, click.Option) and param.hidden:
                shown = copy.copy(param)
                shown.hidden = False
                hidden.append(shown.get_help_record(ctx))
        with formatter.section("Options"):
            formatter.write_dl(main)
        if ctx.meta.get(_HELP_ALL):
            with formatter.section("Experiment options"):
                formatter.write_dl([r for r in hidden if r])


def _help_all(ctx: click.Context, _param: click.Parameter, value: bool) -> None:
    if not value or ctx.resilient_parsing:
        return
    ctx.meta[_HELP_ALL] = True
    click.echo(ctx.get_help(), color=ctx.color)
    ctx.exit()


def _experiment(*decls: str, **kwargs: Any):
    """A click option left out of ``--help`` (listed by ``--help-all``), its default the
    shipped configuration's."""
    name = kwargs.pop("name", None)
    param = name or decls[-1].split("/")[0].lstrip("-").replace("-", "_")
    kwargs.setdefault("default", SHIPPED[param])
    kwargs.setdefault("show_default", SHIPPED[param] is not None)
    return click.option(*decls, *([name] if name else []), hidden=True, **kwargs)


@click.command("train", cls=_TrainCommand)
@click.option(
    "--out",
    "out",
    type=click.Path(path_type=Path),
    required=True,
    help="Weights file to write (.pt); a checkpoint is kept beside it (m.pt → m.ckpt).",
)
@click.option(
    "--preset",
    type=click.Choice(sorted(PRESETS)),
    default="shipped",
    show_default=True,
    help="shipped: the shipped network's configuration (the options' defaults: Adam at 1e-3, "
    "halved at 50 % and 75 % of the budget). paper: Oz et al.'s optimisation instead (Adam at "
    "1e-4 halved on validation plateaus, early stop, at most 60 epochs, no time limit). "
    "Options given on the command line win.",
)
@click.option(
    "--chamber",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Fit the camera model on this chamber file (polynomial + radial) and train "
    "on it instead of the simulator preset.",
)
@click.option(
    "--init",
    "init",
    type=click.Path(path_type=Path),
    default=None,
    help="Start from this weights file, or 'shipped' for the shipped KPN (same network; its "
    "normalisation is kept).",
)
@click.option("--resume", is_flag=True,
              help="Continue from the checkpoint beside OUT (m.pt → m.ckpt; the budget is "
              "this call's).")
@click.option(
    "--max-minutes",
    type=float,
    default=SHIPPED["max_minutes"],
    show_default=True,
    help="Wall-clock budget of the training; the run saves and stops cleanly when it runs out "
    "(--preset paper: none). The σ model is fitted after it, outside the budget (about 5 "
    "minutes on 2 CPU cores; 1 with --chamber).",
)
@click.option(
    "--steps", type=int, default=None,
    help="Stop after this many batches (or when --max-minutes run out, if first).",
)
@click.option(
    "--frames", "n_frames", type=int, default=SHIPPED["n_frames"], show_default=True,
    help="Frames per burst N (the bursts the network will estimate).",
)
@click.option("--seed", type=click.IntRange(min=0), default=SHIPPED["seed"], show_default=True)
@click.option(
    "--workers", type=int, default=1, show_default=True, help="Data-generating processes."
)
@click.option("--threads", type=int, default=2, show_default=True)
@click.option(
    "--device",
    type=click.Choice(["auto", "cpu", "cuda"]),
    default="auto",
    show_default=True,
    help="Where the network trains (auto: a GPU when there is one).",
)
@click.option(
    "--help-all",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_help_all,
    help="Show this message with the experiment options too (network sizes, training data, "
    "optimisation) and exit.",
)
# experiment options: network
@_experiment(
    "--variant",
    type=click.Choice(list(VARIANTS)),
    help="; ".join(f"{v.name}: {v.summary}" for v in VARIANTS.values()),
)
@_experiment("--mu", type=int, help="Channels μ (paper: 64).")
@_experiment("--xi", type=int, help="Level factor ξ.")
@_experiment("--levels", type=int, help="Levels L (paper: 4).")
@_experiment("--kernel", type=int, help="Kernel side K.")
@_experiment("--degree", type=int, help="Offset degree ν.")
@_experiment(
    "--fpa-input/--no-fpa-input",
    help="Feed the FPA temperature to the UNet too (not only the offset block).",
)
@_experiment(
    "--centre/--no-centre",
    help="KPN with offset block: apply the kernels to the frames minus the burst's "
    "mean level (the offset block carries the level).",
)
@_experiment(
    "--radiance/--no-radiance",
    help="The kernels and the offset give band radiance, turned into temperature by the "
    "inverse of Planck's band integral (an addition to the paper).",
)
@_experiment(
    "--radial",
    type=click.IntRange(0, 4),
    help="Degree in R² of position terms: the UNet sees where on the sensor a pixel lies and "
    "the offset block gives a radial map (an addition to the paper; 0: none, as the paper).",
)
@_experiment(
    "--radial-frames",
    is_flag=True,
    help="With --radial: the position terms take where on the sensor each frame saw each pixel "
    "(N planes), not the pivot's position alone.",
)
@_experiment(
    "--calibrated/--no-calibrated",
    help="Give the network each frame through the camera model it is trained from (the "
    "training units' average, or the --chamber fit), not raw counts: it learns what that model "
    "gets wrong for the unit at hand (an addition to the paper; the model travels with the "
    "weights).",
)
# experiment options: optimisation
@_experiment("--crop", type=int, help="Training crop side, px.")
@_experiment("--batch", type=int, help="Bursts per batch.")
@_experiment("--steps-per-epoch", type=int, help="Batches between validations.")
@_experiment("--max-epochs", type=int, help="Upper bound on epochs (--preset paper: 60).")
@_experiment("--lr", type=float, help="Adam learning rate (--preset paper: 1e-4).")
@_experiment(
    "--lr-schedule",
    type=click.Choice(["plateau", "step"]),
    help="plateau (Oz et al.; --preset paper): halve the learning rate once more than 3 epochs "
    "in a row have not improved the validation loss, stop after 8; step: halve it at 50 % and "
    "75 % of the budget (--steps, --max-minutes or --max-epochs, the first to run out), no "
    "early stop. --resume keeps the checkpoint's schedule and its budget for the rate.",
)
@_experiment("--val-bursts", type=int, help="Size of the fixed validation set.")
# experiment options: training data
@_experiment("--units", name="units_text", help="Training camera units of the preset.")
@_experiment(
    "--val-units", name="val_units_text", help="Validation camera units (never training units)."
)
@_experiment(
    "--scenes",
    name="n_scenes",
    type=int,
    help="Procedural maps in the training pool (beside the real training scenes).",
)
@_experiment(
    "--fpa-range-c",
    help="FPA temperature range of the training data, °C (default 10:50, or the "
    "range the chamber file covers).",
)
@_experiment(
    "--temp-mean-range-c",
    help="Range of the training maps' mean temperature, °C (default -15:60).",
)
@_experiment(
    "--redraw-pixel-fpn",
    is_flag=True,
    help="Give every training burst a new pixel FPN of the preset's spread instead of its "
    "unit's own (the validation units keep theirs).",
)
@_experiment(
    "--walk-frames",
    type=int,
    help="Draw each training trajectory for this many frames and keep the --frames around its "
    "pivot (less motion per burst; the validation bursts keep --frames).",
)
@_experiment(
    "--sensor-motion",
    is_flag=True,
    help="Displace the training frames on the sensor as whole-sensor frames of the same overlap "
    "are (each frame rendered by its own sensor window), not by crop-sized amounts; the "
    "validation bursts too.",
)
def train(**opts: Any) -> None:
    """Train the KPN on synthetic bursts from the camera simulator (Oz et al. §IV).

    The defaults train the shipped network's configuration (--preset shipped) for 30 minutes;
    --help-all lists the experiment options.
    """
    import os
    import sys

    from thermocal._validate import check_not_input
    from thermocal.optional import require

    for module in ("torch", "kornia"):  # the [nn] extra's
        require(module, "thermocal train", "nn")
    init = opts.get("init")
    inputs = (opts.get("chamber"), None if init == "shipped" else init)
    check_not_input(opts.get("out"), *inputs)
    if opts.get("out") is not None:  # and what is written beside it (a chamber named x.ckpt)
        from thermocal.nn.uncertainty import sidecar_path

        out = Path(opts["out"])
        check_not_input(out.with_suffix(".ckpt"), *inputs, what="the checkpoint beside --out,")
        check_not_input(sidecar_path(out), *inputs, what="the σ model beside --out,")
    # OpenMP threads that sleep instead of spinning while they wait: on a shared machine a
    # spinning thread burns the core the other one needs (3x slower steps, measured).
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

    from thermocal.nn.data import ScenePool
    from thermocal.nn.train import train as run_training

    _apply_preset(click.get_current_context(), opts)
    _check_numbers(opts)
    meta = {"command": " ".join(sys.argv[1:]) if sys.argv else "", "preset": opts["preset"]}
    camera = _camera_setup(opts, meta)
    model_cfg = _model_config(opts, camera["band_m"])
    burst_cfg = _burst_config(opts, camera)
    init = opts["init"]
    if init is not None and str(init) == "shipped":
        from thermocal.nn.infer import shipped_model_path

        init = shipped_model_path("kpn")
    seed, n_scenes = opts["seed"], opts["n_scenes"]
    n_val_scenes = max(3, (3 * n_scenes) // 8)
    result = run_training(
        opts["out"],
        model_cfg,
        burst_cfg,
        _train_config(opts),
        resume=opts["resume"],
        cameras=camera["cameras"],
        val_units=camera["val_units"],
        log=lambda line: click.echo(line, err=True),
        meta=meta,
        pool_fn=lambda: ScenePool.training(seed=seed, n_procedural=n_scenes),
        val_pool_fn=lambda: ScenePool.training(seed=seed + 1000, n_procedural=n_val_scenes),
        init=init,
    )
    click.echo(
        f"trained {result.steps} steps ({result.epochs} epochs, stopped: {result.stopped}) in "
        f"{result.wall_s / 60:.1f} min at {result.samples_per_s:.1f} samples/s; best validation "
        f"MAE {result.best_val_mae_c:.3f} °C; wrote {opts['out']}",
        err=True,
    )
    if result.steps > 0:
        _fit_sigma(opts["out"], chamber=opts["chamber"])


def _fit_sigma(weights: Path, *, chamber: Path | None) -> None:
    """Fit the trained network's σ model and write it beside the weights
    (:mod:`thermocal.evaluation.sigma_fit`): on bursts of units it never saw, or of the camera
    model fitted on its chamber file."""
    from thermocal.errors import ThermocalError
    from thermocal.evaluation.sigma_fit import fit_network_sigma
    from thermocal.nn.uncertainty import sidecar_path

    click.echo(f"fitting the σ model of {weights} on bursts of "
               + ("units it never saw (about 5 minutes on 2 CPU cores)…" if chamber is None
                  else f"the camera model of {chamber} (about a minute)…"), err=True)
    try:
        sigma = fit_network_sigma(weights, chamber=chamber)
        path = sigma.save(sidecar_path(weights))
    except ThermocalError as exc:  # the weights are written: say so, and how to fit σ later
        click.echo(f"thermocal: warning: no σ model for {weights} (its estimates will have no "
                   f"uncertainty): {exc}", err=True)
        return
    on = ("units it never saw" if chamber is None else
          f"the camera model fitted on {chamber}, with what that model misses of the camera's "
          f"level on its frames: {sigma.fitted_on['model_level_misfit_c']:.2f} °C RMS")
    contrast = ("" if sigma.contrast_per_c is None else
                f" + {sigma.contrast_per_c:.3f} °C per °C between scene and FPA")
    click.echo(f"σ model (floor {sigma.floor_c:.2f} °C{contrast}, fitted on "
               f"{sigma.fitted_on['bursts']} "
               f"bursts of {on}) written to {path}", err=True)
    variant = sigma.fitted_on["variant"]  # the weights' (a resumed run's is its checkpoint's)
    if said := sigma_warning(variant):
        click.echo(f"thermocal: warning: {said}", err=True)


def _apply_preset(ctx: click.Context, opts: dict[str, Any]) -> None:
    """The preset's value for every option the command line does not give."""
    for name, value in PRESETS[opts["preset"]].items():
        if ctx.get_parameter_source(name) in (ParameterSource.DEFAULT, ParameterSource.DEFAULT_MAP):
            opts[name] = value


def _check_numbers(opts: dict[str, Any]) -> None:
    for name, key in (
        ("--frames", "n_frames"),
        ("--batch", "batch"),
        ("--steps-per-epoch", "steps_per_epoch"),
        ("--max-epochs", "max_epochs"),
        ("--threads", "threads"),
        ("--val-bursts", "val_bursts"),
        ("--scenes", "n_scenes"),
    ):
        if opts[key] < 1:
            raise InvalidInputError(f"{name} must be >= 1, got {opts[key]}")
    if opts["steps"] is not None and opts["steps"] < 1:
        raise InvalidInputError(f"--steps must be >= 1, got {opts['steps']}")
    if opts["workers"] < 0:
        raise InvalidInputError(f"--workers must be >= 0, got {opts['workers']}")
    minutes = opts["max_minutes"]
    if minutes is not None and not (math.isfinite(minutes) and minutes > 0):
        raise InvalidInputError(f"--max-minutes must be a number > 0, got {minutes}")
    if not (math.isfinite(opts["lr"]) and opts["lr"] > 0):
        raise InvalidInputError(f"--lr must be a number > 0, got {opts['lr']}")


def _camera_setup(opts: dict[str, Any], meta: dict[str, Any]) -> dict[str, Any]:
    """Units, sensor size, band and FPA range of the training cameras: the simulator preset's,
    or (``--chamber``) the camera model fitted on a chamber file (recorded in ``meta``)."""
    from thermocal.camera.presets import PRESETS as CAMERA_PRESETS

    fpa_range_c = opts["fpa_range_c"]
    setup = {
        "cameras": None,
        "units": parse_units(opts["units_text"]),
        "val_units": parse_units(opts["val_units_text"]),
        "fpa_range": (parse_range(fpa_range_c, "--fpa-range-c", increasing=True)
                      if fpa_range_c else (10.0, 50.0)),
        "sensor_size": (336, 256),
        "band_m": CAMERA_PRESETS["tau2"].band_m,
    }
    chamber = opts["chamber"]
    if chamber is not None:
        try:
            from thermocal.calibration.polynomial import camera_model_from_chamber
        except ImportError:
            raise InvalidInputError(
                "--chamber needs thermocal.calibration.camera_model_from_chamber, which this "
                "installation does not have"
            ) from None
        camera = camera_model_from_chamber(chamber, radial=True)
        setup.update(cameras={0: camera}, units=(0,), val_units=(0,),
                     sensor_size=(camera.shape[1], camera.shape[0]), band_m=camera.band.band_m)
        meta["chamber"] = str(chamber)
        if fpa_range_c is None and "fpa_range_c" in camera.info:
            setup["fpa_range"] = tuple(float(v) for v in camera.info["fpa_range_c"])
    if opts["crop"] > min(setup["sensor_size"]):
        w, h = setup["sensor_size"]
        raise InvalidInputError(
            f"--crop {opts['crop']} (the training crop, px) is larger than the sensor, "
            f"{w}x{h}: give --crop {min(w, h)} or less (a multiple of the network's "
            f"{opts['xi'] ** opts['levels']} px)")
    return setup


def _model_config(opts: dict[str, Any], band_m: tuple[float, float]):
    from thermocal.nn.model import ModelConfig

    model_cfg = ModelConfig(
        n_frames=opts["n_frames"],
        mu=opts["mu"],
        xi=opts["xi"],
        levels=opts["levels"],
        kernel=opts["kernel"],
        degree=opts["degree"],
        variant=opts["variant"],
        fpa_input=opts["fpa_input"],
        centre=opts["centre"] and opts["variant"] == "kpn",
        radiance=opts["radiance"],
        radial=opts["radial"],
        band_m=band_m,
        radial_frames=opts["radial_frames"],
        calibrated=opts["calibrated"],
    )
    if opts["crop"] % model_cfg.multiple:
        raise InvalidInputError(f"--crop must be a multiple of ξ^L = {model_cfg.multiple}")
    return model_cfg


def _burst_config(opts: dict[str, Any], camera: dict[str, Any]):
    from thermocal.nn.data import BurstConfig

    extra: dict[str, Any] = {}
    if opts["temp_mean_range_c"]:
        extra["temp_mean_range_c"] = parse_range(opts["temp_mean_range_c"],
                                                 "--temp-mean-range-c", increasing=True)
    if opts["redraw_pixel_fpn"]:
        extra["redraw_pixel_fpn"] = True
    if opts["walk_frames"] is not None:
        extra["walk_frames"] = opts["walk_frames"]
    if opts["calibrated"]:
        extra["calibrated"] = True
    if opts["sensor_motion"]:
        extra["sensor_motion"] = True
    elif opts["radial_frames"]:
        click.echo("warning: --radial-frames without --sensor-motion: the training frames move "
                   "by crop-sized amounts, far less than whole-sensor bursts do", err=True)
    return BurstConfig(
        n_frames=opts["n_frames"],
        crop=opts["crop"],
        fpa_range_c=camera["fpa_range"],
        units=camera["units"],
        sensor_size=camera["sensor_size"],
        **extra,
    )


def _train_config(opts: dict[str, Any]):
    from thermocal.nn.train import TrainConfig

    return TrainConfig(
        batch=opts["batch"],
        steps_per_epoch=opts["steps_per_epoch"],
        max_epochs=opts["max_epochs"],
        lr=opts["lr"],
        lr_schedule=opts["lr_schedule"],
        seed=opts["seed"],
        val_bursts=opts["val_bursts"],
        max_minutes=opts["max_minutes"],
        max_steps=opts["steps"],
        threads=opts["threads"],
        workers=opts["workers"],
        device=opts["device"],
    )


@click.command("export")
@click.argument("model", required=False, default=None)
@click.option("--out", "out", type=click.Path(path_type=Path), required=True,
              help="Output ONNX file (.onnx).")
@click.option("--size", default="640x512", show_default=True,
              help="Frame size WxH the graph runs at (padded up to the network's multiple).")
@click.option("--method", type=click.Choice(list(VARIANTS)), default=None,
              help="The shipped network to export when MODEL is not given (default kpn, the "
              "one shipped; the other variants are trained by `thermocal train --variant`).")
def export(model: str | None, out: Path, size: str, method: str | None) -> None:
    """Export a network (MODEL: a weights file of `thermocal train`; default the shipped one of
    --method) as an ONNX graph, for ONNX Runtime, OpenVINO, or an edge device's compiler
    (TensorRT on a Jetson, an NPU's). The graph ends at the network's linear output; how to feed
    it and read it is stored in its metadata (docs: "Running on an edge device")."""
    from thermocal._validate import check_not_input, check_output_file, parse_size

    out = check_output_file(out, (".onnx",))
    if model is not None and method is not None:  # MODEL's own variant would be exported
        raise InvalidInputError(
            f"--method picks a shipped network; {model} is given: leave --method out (the "
            "file's own network is exported)")
    width, height = parse_size(size)
    from thermocal.optional import require

    require("torch", "thermocal export", "nn")
    require("onnx", "thermocal export", "backends")
    from thermocal.nn.infer import shipped_model_path
    from thermocal.nn.runners import export_onnx

    weights = Path(model) if model is not None else shipped_model_path(method or "kpn")
    check_not_input(out, weights)
    meta = export_onnx(weights, out, size=(width, height))
    click.echo(f"wrote {out}: {meta['thermocal.variant']}, N = {meta['thermocal.frames']}, "
               f"{meta['thermocal.size_px']} px", err=True)
