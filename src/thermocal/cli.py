"""The ``thermocal`` command line (the contract of DESIGN.md).

Bad input ends with a one-line message on stderr and exit status 2, never a traceback; a warning
is one line ``thermocal: warning: ...``; Ctrl-C ends with ``thermocal: interrupted`` (status 130),
also while the modules load.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys


def _interrupted_while_loading(signum, frame) -> None:  # pragma: no cover - timing dependent
    """Ctrl-C before :func:`main` runs (the imports below take a second): nothing has been read
    or written yet, so end at once, without the import machinery's traceback."""
    sys.stderr.write("thermocal: interrupted\n")
    sys.stderr.flush()
    os._exit(130)


def _catch_interrupt_while_loading():
    """Install :func:`_interrupted_while_loading` for SIGINT; return the handler to restore
    (None where signals cannot be set: not the main thread)."""
    try:
        previous = signal.getsignal(signal.SIGINT)
        if previous is signal.default_int_handler:
            signal.signal(signal.SIGINT, _interrupted_while_loading)
            return previous
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not the main thread
        pass
    return None


_SIGINT_BEFORE_LOADING = _catch_interrupt_while_loading()

import warnings  # noqa: E402 - after the Ctrl-C handler, on purpose
from pathlib import Path  # noqa: E402

import click  # noqa: E402

from thermocal import __version__  # noqa: E402
from thermocal._validate import (  # noqa: E402
    HDF5_SUFFIXES,
    check_fpa_c,
    check_not_input,
    check_output_dir,
    check_output_file,
    parse_range,
)
from thermocal.camera.presets import PRESETS  # noqa: E402
from thermocal.errors import InvalidInputError, ThermocalError  # noqa: E402
from thermocal.progress import progress_bar  # noqa: E402

#: The camera families ``simulate`` offers (the registry: :data:`thermocal.camera.presets.PRESETS`).
CAMERA_PRESETS = tuple(PRESETS)

#: Most blackbody set points of a simulated chamber session.
MAX_SETPOINTS = 1000


def setpoints_from_range(start: float, stop: float, step: float) -> tuple[float, ...]:
    """Set points ``start, start ± step, …`` up to (down to, where ``stop < start``) and
    including ``stop`` (°C; ``step`` > 0): the order the chamber's sweep visits them."""
    count = abs(stop - start) / step + 1  # a float: inf for a step too small to count
    if not count <= MAX_SETPOINTS:
        raise InvalidInputError(
            f"{count:.0f} blackbody set points is too many (at most {MAX_SETPOINTS})")
    sign = 1.0 if stop >= start else -1.0
    n = int(round(abs(stop - start) / step)) + 1
    offsets = (step * k for k in range(n))
    # ``stop`` itself within a ten-thousandth of a step (a step written to a few digits,
    # 20:70:16.6667, reaches 70.0001: 70 is meant)
    slack = 1e-4 * abs(step)
    span = abs(stop - start)
    return tuple(float(start + sign * min(d, span)) for d in offsets if d <= span + slack)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="thermocal")
def cli() -> None:
    """Radiometric temperature from uncooled thermal cameras (microbolometer cores such as FLIR's
    Tau2)."""


@cli.group()
def simulate() -> None:
    """Simulate a camera unit: chamber sessions and flights with ground truth."""


@simulate.command("chamber")
@click.argument("out", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of noise and schedule.")
@click.option("--unit", type=int, default=0, show_default=True, help="Camera unit of the preset.")
@click.option("--preset", type=click.Choice(CAMERA_PRESETS), default="tau2", show_default=True,
              help="Camera family (thermocal.camera.presets).")
@click.option("--size", default="336x256", show_default=True, help="Frame size WxH.")
@click.option(
    "--blackbody-c", default="10:70:10", show_default=True,
    help="Set points A:B:STEP, °C, visited from A to B (A > B: falling)."
)
@click.option(
    "--order",
    type=click.Choice(["sweep", "sawtooth", "random"]),
    default="sweep",
    show_default=True,
    help="Order in which the blackbody visits its set points.",
)
@click.option(
    "--ambient-profile",
    type=click.Choice(["constant", "steps", "ramp", "sawtooth"]),
    default="steps",
    show_default=True,
)
@click.option("--ambient-c", default="10:40", show_default=True, help="Ambient range A:B, °C.")
@click.option("--rate-c-per-min", type=float, default=0.5, show_default=True)
@click.option("--frames-per-point", type=int, default=3, show_default=True)
@click.option("--interval-s", type=float, default=10.0, show_default=True, help="Frame spacing.")
@click.option("--duration-min", type=float, default=None, help="Length (default: one cycle).")
@click.option("--emissivity", type=float, default=0.98, show_default=True, help="Blackbody ε.")
def simulate_chamber_cmd(
    out: Path, seed: int, unit: int, preset: str, size: str, blackbody_c: str, order: str,
    ambient_profile: str, ambient_c: str, rate_c_per_min: float, frames_per_point: int,
    interval_s: float, duration_min: float | None, emissivity: float,
) -> None:
    """Simulate an environmental-chamber session into OUT (HDF5 chamber file)."""
    from thermocal._validate import check_number, parse_size
    from thermocal.camera.presets import make_camera
    from thermocal.simulate.chamber import (
        SOURCE,
        ChamberPlan,
        check_chamber_run,
        write_simulated_chamber,
    )

    start, stop, step = parse_range(blackbody_c, "--blackbody-c", step=True)
    amb_low, amb_high = parse_range(ambient_c, "--ambient-c")
    check_output_file(out, HDF5_SUFFIXES)
    from thermocal.io.replaces import check_replaces_only

    check_replaces_only(out, "chamber session", what="OUT", source=SOURCE)
    check_number(rate_c_per_min, "--rate-c-per-min", low=0.0, low_open=True)
    check_number(interval_s, "--interval-s", low=0.0, low_open=True)
    if duration_min is not None:
        check_number(duration_min, "--duration-min", low=0.0, low_open=True)
    check_number(emissivity, "--emissivity", low=0.0, high=1.0, low_open=True)
    plan = ChamberPlan(
        setpoints_c=setpoints_from_range(start, stop, step),
        frames_per_point=frames_per_point,
        order=order,
        profile=ambient_profile,
        ambient_c=(amb_low, amb_high),
        rate_c_per_min=rate_c_per_min,
        interval_s=interval_s,
        duration_s=None if duration_min is None else 60.0 * duration_min,
        emissivity=emissivity,
    )
    width, height = parse_size(size)
    check_chamber_run(plan, (height, width), thermal=PRESETS[preset].thermal,
                      folder=out.parent)  # before the camera's maps
    camera = make_camera(preset, unit=unit, size=(width, height))
    with progress_bar() as bar:
        task = bar.add_task("chamber", total=plan.n_frames)
        n = write_simulated_chamber(
            out, camera, plan, seed=seed, progress=lambda k: bar.advance(task, k)
        )
    click.echo(f"wrote {n} frames of {camera.shape[1]}x{camera.shape[0]} to {out}")


#: ``simulate flight --format`` choices (:data:`thermocal.simulate.formats.WRITE_FORMATS`) and
#: the name of the frames in OUT_DIR where it is not ``frames`` (a folder) or frames.tiff.
FLIGHT_FORMATS = ("tiff", "seq", "csq", "fff", "rjpeg", "dji-rjpeg", "dualtau")
_FLIGHT_FRAMES = {"seq": "frames.seq", "csq": "frames.csq"}


@simulate.command("flight")
@click.argument("out_dir", type=click.Path(path_type=Path))
@click.option(
    "--scene", default="procedural", show_default=True, help="Scene file or 'procedural'."
)
@click.option("--frames", "n_frames", type=int, default=7, show_default=True)
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True)
@click.option("--unit", type=int, default=0, show_default=True)
@click.option("--preset", type=click.Choice(CAMERA_PRESETS), default="tau2", show_default=True,
              help="Camera family (thermocal.camera.presets).")
@click.option("--size", default="336x256", show_default=True, help="Frame size WxH.")
@click.option("--fpa-c", type=float, default=30.0, show_default=True, help="FPA temperature, °C.")
@click.option(
    "--motion", type=click.Choice(["walk", "hover", "uav"]), default="walk", show_default=True
)
@click.option("--fps", type=float, default=30.0, show_default=True, help="Frame rate, Hz.")
@click.option(
    "--format", "fmt", type=click.Choice(FLIGHT_FORMATS), default="tiff", show_default=True,
    help="File format of the frames: the project's frames.tiff + frames.json, a FLIR "
    "frames.seq/frames.csq, or a folder frames/ of FFF files, FLIR or DJI XT-R R-JPEGs, or "
    "DualTauUAV .npz files (in every format but tiff, frames.json becomes flight.json).",
)
def simulate_flight_cmd(
    out_dir: Path, scene: str, n_frames: int, seed: int, unit: int, preset: str, size: str,
    fpa_c: float, motion: str, fps: float, fmt: str,
) -> None:
    """Simulate a flight over a scene into OUT_DIR (frames.tiff/json, truth.tiff, homographies)."""
    from thermocal._validate import parse_size
    from thermocal.camera.presets import make_camera
    from thermocal.simulate.flight import check_flight_run, plan_flight, write_simulated_flight

    # every check before the folder is made (write_simulated_flight makes it)
    check_output_dir(out_dir)
    _check_no_other_recording(out_dir, fmt)
    frames_out = _check_flight_format(out_dir, fmt)
    check_fpa_c(fpa_c, "--fpa-c")
    width, height = parse_size(size)
    check_flight_run(n_frames, (height, width), motion=motion, fps=fps, folder=out_dir)
    if scene != "procedural":
        outputs = ("frames.tiff", "frames.json", "truth.tiff", "homographies.npy")
        for name in outputs:
            check_not_input(out_dir / name, scene, what="the output")
    camera = make_camera(preset, unit=unit, size=(width, height))
    flir = {}  # a FLIR file states its camera's constants: this unit's (checked before any work)
    if frames_out is not None and fmt != "dualtau":
        from thermocal.simulate.formats import simulated_model, unit_planck

        flir = {"planck": unit_planck(camera, fpa_c), "model": simulated_model(preset)}
    scene_c, scene_name = load_scene_or_procedural(scene, seed=seed)
    plan = plan_flight(
        scene_c, camera, n_frames=n_frames, motion=motion, fpa_c=fpa_c, fps=fps, seed=seed
    )
    extra = {"scene": scene_name, "unit": unit, "preset": preset, "seed": seed, "motion": motion}
    with progress_bar() as bar:
        task = bar.add_task("flight", total=n_frames)
        write_simulated_flight(
            out_dir, plan, camera, extra=extra, progress=lambda k: bar.advance(task, k)
        )
    if frames_out is not None:  # the frames in a camera's format, converted in a stream
        from thermocal.simulate.formats import convert_recording

        convert_recording(out_dir / "frames.tiff", frames_out, format=fmt, fps=fps, **flir)
        os.replace(out_dir / "frames.json", out_dir / "flight.json")
        (out_dir / "frames.tiff").unlink()
    click.echo(f"wrote {n_frames} frames ({motion}, scene {scene_name}) to {out_dir}")


def _flight_frames_name(fmt: str) -> str:
    """The name of ``simulate flight --format FMT``'s frames in OUT_DIR."""
    return "frames.tiff" if fmt == "tiff" else _FLIGHT_FRAMES.get(fmt, "frames")


#: What ``simulate flight`` writes into OUT_DIR, in any format: a folder holding only these,
#: with the sidecar and truth of a simulation (:func:`_simulated_run`), is one of its earlier
#: runs, which a rerun replaces (in the file formats: tiff, seq and csq; a folder format's
#: ``frames`` folder is refused as not empty).
_FLIGHT_OUTPUTS = frozenset({"frames.tiff", "frames.json", "flight.json", "truth.tiff",
                             "homographies.npy", *_FLIGHT_FRAMES.values(), "frames"})


def _check_no_other_recording(out_dir: Path, fmt: str) -> None:
    """Refuse an OUT_DIR that holds the frames of a flight in another format (writing beside
    them would leave two recordings in one folder, and the sidecar of one replaced, which a
    flight then reads as either), or anything simulate flight does not write (a camera's own
    recording, a flight's outputs: a rerun replaces only its own earlier run)."""
    ours = _flight_frames_name(fmt)
    for other in sorted({_flight_frames_name(f) for f in FLIGHT_FORMATS} - {ours}):
        if (out_dir / other).exists():
            raise InvalidInputError(
                f"{out_dir}: holds a recording ({other}); simulate flight --format {fmt} "
                f"would write {ours} beside it: choose an empty folder or remove it")
    if out_dir.is_dir():
        names = sorted(p.name for p in out_dir.iterdir() if not p.name.startswith("."))
        others = [n for n in names if n not in _FLIGHT_OUTPUTS]
        if others:
            shown = ", ".join(others[:3]) + (f", … {len(others)} in all" if len(others) > 3
                                             else "")
            raise InvalidInputError(
                f"{out_dir}: holds files simulate flight does not write ({shown}); it writes "
                "into an empty folder or one of its own earlier runs: choose another folder")
        if names and not _simulated_run(out_dir):
            raise InvalidInputError(
                f"{out_dir}: holds a recording simulate flight did not write "
                f"({', '.join(names[:3])}; no simulation's sidecar and truth.tiff beside it), "
                "which writing here would lose: choose another folder")


def _simulated_run(out_dir: Path) -> bool:
    """Whether OUT_DIR holds an earlier ``simulate flight`` run: its truth.tiff, and a sidecar
    (frames.json or flight.json) with the simulation's scene, preset, seed and motion."""
    from thermocal.io.replaces import json_object_with

    simulation = {"scene", "preset", "seed", "motion"}
    return (out_dir / "truth.tiff").is_file() and any(
        json_object_with(out_dir / name, simulation) for name in ("frames.json", "flight.json"))


def _check_flight_format(out_dir: Path, fmt: str) -> Path | None:
    """Where ``simulate flight --format FMT`` puts the frames other than in frames.tiff
    (OUT_DIR/frames.seq, frames.csq, or the folder OUT_DIR/frames), checked before any work;
    None for tiff."""
    if fmt == "tiff":
        return None
    from thermocal.simulate.formats import FILE_LIKE_SUFFIXES, check_output_path

    if out_dir.suffix.lower() in FILE_LIKE_SUFFIXES:
        raise InvalidInputError(
            f"{out_dir}: OUT_DIR is a folder, not a {out_dir.suffix} file; simulate flight "
            f"--format {fmt} writes its frames into OUT_DIR/{_flight_frames_name(fmt)}")
    return check_output_path(out_dir / _flight_frames_name(fmt), format=fmt,
                             parent_made_later=True)


def load_scene_or_procedural(scene: str, *, seed: int):
    """A °C map from a scene file, or a procedural one for ``'procedural'``; with its name."""
    import numpy as np

    if scene == "procedural":
        from thermocal.scenes.procedural import procedural_scene

        return procedural_scene((512, 512), rng=np.random.default_rng(seed), kind="mixed"), scene
    from thermocal.scenes.real import load_scene

    return load_scene(scene), Path(scene).name


@cli.command()
@click.option(
    "--out", "out_dir", type=click.Path(), default="demo-out",
    show_default=True, help="Report folder.",
)
def demo(out_dir: str) -> None:
    """Simulate, calibrate and measure on built-in data; print a table and write a figure."""
    from thermocal.demo import run_demo

    if not out_dir.strip():  # an empty path is the current folder to pathlib: a mistake
        raise InvalidInputError("--out: an empty path; give the report's folder")
    run_demo(Path(out_dir))


def _register_commands() -> None:
    """Add the commands that live beside their capability (each module imports lazily)."""
    import importlib

    for module, name in COMMANDS:
        command = getattr(importlib.import_module(module), name)
        cli.add_command(command)


# (module, click command) pairs; each module keeps heavy imports (torch, cv2) inside functions.
COMMANDS: list[tuple[str, str]] = [
    ("thermocal.calibration.commands", "calibrate"),
    ("thermocal.calibration.commands", "correct"),
    ("thermocal.nuc.commands", "nuc"),
    ("thermocal.estimation.commands", "estimate"),
    ("thermocal.nn.commands", "train"),
    ("thermocal.nn.commands", "export"),
    ("thermocal.pipeline.commands", "flight"),
    ("thermocal.pipeline.commands", "campaign"),
    ("thermocal.pipeline.commands", "mosaic"),
    ("thermocal.pipeline.commands", "report"),
    ("thermocal.io.commands", "info"),
    ("thermocal.bench", "bench"),
]

_register_commands()

if _SIGINT_BEFORE_LOADING is not None:  # loaded: Ctrl-C raises KeyboardInterrupt again
    signal.signal(signal.SIGINT, _SIGINT_BEFORE_LOADING)


#: The warnings :func:`_show_warning` has shown in this run (reset by :func:`main`).
_shown: set[str] = set()


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """:func:`warnings.showwarning` for the command line: one line ``thermocal: warning: ...``,
    without the source path and line of Python's own form; a text already shown in this run
    is not repeated (a file's metadata read twice warned twice)."""
    text = " ".join(str(message).split())
    if text in _shown:
        return
    _shown.add(text)
    click.echo(f"thermocal: warning: {text}", err=True)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the CLI, turning thermocal errors into one line and exit status 2.

    Warnings are shown as one line each; output folders this run created are removed again
    when it fails before writing anything into them.
    """
    from thermocal.io.atomic import removing_new_dirs_on_error

    shown = warnings.showwarning
    warnings.showwarning = _show_warning
    _shown.clear()
    terminate = _exit_cleanly_on_sigterm()
    try:
        with removing_new_dirs_on_error():
            _invoke(sys.argv[1:] if argv is None else list(argv))
    except click.exceptions.Abort:
        click.echo("thermocal: aborted", err=True)
        sys.exit(130)
    except click.exceptions.ClickException as exc:
        # one line, like every other bad input (click's own form prints the usage too)
        # (a missing choice option lists its choices a line each: joined)
        click.echo(f"thermocal: error: {' '.join(exc.format_message().split())}", err=True)
        sys.exit(exc.exit_code)
    except ThermocalError as exc:
        click.echo(f"thermocal: error: {_one_line(exc)}", err=True)
        sys.exit(2)
    except BrokenPipeError:
        # the reader of our output went away (``thermocal info … | head -1``): nothing is
        # wrong and nothing more can be said; stdout to /dev/null so that its final flush
        # does not raise again, and the status a shell gives a command ended by SIGPIPE
        with contextlib.suppress(OSError, ValueError, AttributeError):  # a captured stdout
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(141)
    except MemoryError:
        click.echo("thermocal: error: out of memory; use smaller or fewer frames (nothing "
                   "half-written is left)", err=True)
        sys.exit(2)
    except OSError as exc:
        # the machine, not the input: a full or read-only disk, a vanished file; outputs are
        # written atomically, so what finished is kept and nothing half-written is left
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"thermocal: error: {where}{exc.strerror or _one_line(exc)} (outputs are "
                   "written whole or not at all)", err=True)
        sys.exit(2)
    except KeyboardInterrupt:
        click.echo("thermocal: interrupted", err=True)
        sys.exit(130)
    finally:
        warnings.showwarning = shown
        if terminate is not None:
            signal.signal(signal.SIGTERM, terminate)


def _check_not_special(arg: str) -> None:
    """Refuse an argument naming a FIFO, a device or a socket: reading one blocks until
    something writes to it (a FIFO named ``p.tiff`` hung ``correct``, ``flight`` and
    ``campaign`` for good, and was called missing by others: a helper's audit)."""
    import stat

    try:
        mode = os.stat(arg).st_mode
    except (OSError, ValueError):  # not a path, or none there
        return
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        raise InvalidInputError(f"{arg}: not a file or a folder (a pipe, a device): give a "
                                "file")


def _invoke(args: list[str]) -> None:
    """Run the command line ``args`` (click's ``main`` without its handling of Ctrl-C, which
    writes an empty line before it aborts: :func:`main` says ``thermocal: interrupted`` alone);
    ``--help`` and ``--version`` exit here. An empty value is refused first: an unset shell
    variable (``--out "$OUT"``) is the current folder to pathlib (a flight wrote its outputs
    there, over a report.html of the user's: a helper's audit)."""
    for k, arg in enumerate(args):
        option = (arg[:-1] if arg.startswith("--") and arg.endswith("=")
                  else args[k - 1] if arg == "" and k and args[k - 1].startswith("-") else None)
        if arg == "" or option is not None:
            raise InvalidInputError(f"{option or f'argument {k + 1}'}: an empty value (an unset "
                                    "shell variable?); give it a value")
        _check_not_special(arg.split("=", 1)[1] if arg.startswith("--") and "=" in arg
                           else arg)
    try:
        with cli.make_context("thermocal", args) as ctx:
            cli.invoke(ctx)
    except click.exceptions.Exit as exc:
        if exc.exit_code:
            sys.exit(exc.exit_code)


def _exit_cleanly_on_sigterm():
    """Make SIGTERM (``kill``, ``timeout``) end the run like an error, through every ``finally``:
    the temporary file of an output being written is removed (:func:`~thermocal.io.atomic.
    atomic_path`). Returns the handler to restore (None where signals cannot be set)."""

    def terminated(signum, frame):
        click.echo("thermocal: terminated", err=True)
        sys.exit(143)

    try:
        previous = signal.getsignal(signal.SIGTERM)
        if previous in (signal.SIG_DFL, None):
            signal.signal(signal.SIGTERM, terminated)
            return previous
    except (ValueError, OSError, AttributeError):  # pragma: no cover - not the main thread
        pass
    return None


def _one_line(exc: BaseException) -> str:
    """An exception's message on one line."""
    return " ".join(str(exc).split())


if __name__ == "__main__":  # pragma: no cover
    main()
