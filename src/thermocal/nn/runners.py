"""What runs the network on a tile, per inference backend (:mod:`thermocal.nn.backends`).

:func:`make_runner` gives :func:`~thermocal.nn.infer.run_network` the model itself (``torch``),
or its graph exported to ONNX (:func:`onnx_graph`) run by ONNX Runtime or OpenVINO (at f32:
the same temperatures within 1e-4 °C, tested).

- **What is exported**: the network up to its linear output (``KPN.forward(..., linear=True)``).
  A ``radiance`` model's last step, band radiance → temperature, interpolates with
  ``torch.searchsorted``, which torch's exporter cannot write as ONNX; it stays outside the
  graph: the model's own table (:class:`~thermocal.nn.model.RadianceToTemperature`), read in
  numpy for the graph backends (:func:`_interp`, the same numbers, a few ms per tile).
- **One graph per tile size**: the graph is traced at the tile's size (torch's TorchScript
  exporter; its dynamic sizes gave wrong outputs at other sizes), once per size a run meets
  (one for any frame up to 512 px: :func:`~thermocal.nn.infer.inference_tiling`), in about a
  second. ``thermocal export`` writes it to a file, for an edge device (a Jetson's TensorRT, an
  NPU's compiler) to run at its sensor's size.
- **Threads**: each backend runs on ``threads`` threads (default: the CPU cores this process
  may use, :func:`~thermocal.nn.backends.default_threads`). A runner made for ``concurrent``
  callers may be called from that many threads at once, each call on ``threads`` threads (a
  flight estimates a pivot per core at once: more bursts a second on two cores than one burst
  at a time on both, the per-burst steps around the network running in parallel too).
"""

from __future__ import annotations

import io
import os
import threading
from collections.abc import Callable

import numpy as np
import torch

from thermocal.errors import InvalidInputError
from thermocal.nn.backends import check_threads, default_threads, resolve_backend
from thermocal.nn.model import KPN
from thermocal.threads import caught_warnings

__all__ = ["INPUT_NAMES", "OPSET", "Runner", "example_inputs", "export_onnx", "make_runner",
           "onnx_graph"]

#: A runner: ``(frames, fpa, valid, means, r2) → normalised temperature (1, 1, H, W)``, the
#: arguments of :meth:`KPN.forward <thermocal.nn.model.KPN.forward>` (``r2`` None without
#: position terms).
Runner = Callable[..., torch.Tensor]

#: The exported graph's inputs, in order (``r2`` only for a model with position terms).
INPUT_NAMES = ("frames", "fpa", "valid", "means", "r2")
#: ONNX opset of the exported graph (ONNX Runtime >= 1.13, OpenVINO >= 2022.3, TensorRT >= 8.5).
OPSET = 17


class _Linear(torch.nn.Module):
    """The network up to its linear output, with positional inputs (what is exported)."""

    def __init__(self, model: KPN) -> None:
        super().__init__()
        self.model = model

    def forward(self, frames: torch.Tensor, fpa: torch.Tensor, valid: torch.Tensor,
                means: torch.Tensor, r2: torch.Tensor | None = None) -> torch.Tensor:
        return self.model(frames, fpa, valid, means=means, r2=r2, linear=True)


def example_inputs(model: KPN, height: int, width: int) -> tuple[torch.Tensor, ...]:
    """Inputs of the exported graph for a ``height × width`` tile (zeros; valid everywhere)."""
    c = model.config
    n = c.n_frames
    frames = torch.zeros(1, n, height, width)
    args = (frames, torch.zeros(1), torch.ones(1, n, height, width, dtype=torch.bool),
            torch.zeros(1, n))
    return args + ((torch.zeros(1, c.position_planes, height, width),) if c.radial else ())


def onnx_graph(model: KPN, height: int, width: int) -> bytes:
    """The network (:class:`_Linear`) as an ONNX graph for ``height × width`` tiles (multiples
    of the model's ``ξ^L``), inputs :data:`INPUT_NAMES` and output ``out`` (1, 1, H, W)."""
    mult = model.config.multiple
    if height % mult or width % mult or height < mult or width < mult:
        raise InvalidInputError(
            f"an exported graph's size must be multiples of {mult} px, got {width}x{height}")
    wrapped = _Linear(model).eval()
    args = example_inputs(model, height, width)
    buf = io.BytesIO()
    # the tracer's warnings on the shape checks (sizes fixed) dropped: kept apart, since a
    # flight's other groups may be warning from other threads meanwhile
    with caught_warnings():
        torch.onnx.export(wrapped, args, buf, dynamo=False, opset_version=OPSET,
                          input_names=list(INPUT_NAMES[: len(args)]), output_names=["out"])
    return buf.getvalue()


class _Graphs:
    """An exported graph per tile size, compiled by ``compile_graph(bytes) → run(feeds)``
    when first met; the radiance → temperature step through the model's table in numpy.
    ``run`` takes the feeds of every input and gives its graph those it has: the exporter
    leaves out what a variant does not use (``valid`` for ``e2e``, ``valid`` and ``means`` for
    ``kpn-no-offset``), and a backend refuses a feed its graph has not."""

    def __init__(self, model: KPN, compile_graph: Callable[[bytes], Callable]) -> None:
        self.model = model
        self.compile_graph = compile_graph
        self.compiled: dict[tuple[int, int], Callable] = {}
        self._compiling = threading.Lock()  # callers at once compile a size once

    def __call__(self, frames: torch.Tensor, fpa: torch.Tensor, valid: torch.Tensor,
                 means: torch.Tensor, r2: torch.Tensor | None = None) -> torch.Tensor:
        size = (int(frames.shape[2]), int(frames.shape[3]))
        run = self.compiled.get(size)
        if run is None:
            with self._compiling:
                run = self.compiled.get(size)
                if run is None:
                    run = self.compiled[size] = self.compile_graph(onnx_graph(self.model, *size))
        feeds = {"frames": frames, "fpa": fpa, "valid": valid, "means": means, "r2": r2}
        out = np.asarray(run({k: np.ascontiguousarray(v.cpu().numpy())
                              for k, v in feeds.items() if v is not None}))
        table = self.model.to_temperature
        if table is not None:  # the model's own table and formula, in numpy: the same numbers
            out = _interp(out, table.x_grid.numpy(), table.t_grid.numpy())
        return torch.from_numpy(out)


def _interp(x: np.ndarray, xg: np.ndarray, yg: np.ndarray) -> np.ndarray:
    """:func:`thermocal.nn.model._interp` in numpy (float32): piecewise-linear ``y(x)`` through
    ``(xg, yg)``, extended by the end segments; 1.3–3× faster than torch's on a frame."""
    i = np.searchsorted(xg, x).clip(1, len(xg) - 1)
    x0, x1, y0, y1 = xg[i - 1], xg[i], yg[i - 1], yg[i]
    return y0 + (x - x0) * ((y1 - y0) / (x1 - x0))


def _onnxruntime(threads: int, concurrent: int) -> Callable[[bytes], Callable]:
    import onnxruntime as ort  # a session's run may be called from several threads at once

    def compile_graph(graph: bytes) -> Callable:
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        session = ort.InferenceSession(graph, options, providers=["CPUExecutionProvider"])
        names = [i.name for i in session.get_inputs()]  # the graph's own: see _Graphs
        return lambda feeds: session.run(None, {k: feeds[k] for k in names})[0]

    return compile_graph


def _openvino(threads: int, concurrent: int) -> Callable[[bytes], Callable]:
    import openvino as ov

    core = ov.Core()
    # one stream per concurrent caller, each on its threads (one stream, the latency hint,
    # runs one request at a time: two callers would wait for each other); the same numbers
    streams = ({"PERFORMANCE_HINT": "LATENCY"} if concurrent == 1 else
               {"NUM_STREAMS": concurrent})

    def compile_graph(graph: bytes) -> Callable:
        # f32: the CPU plugin's default on CPUs with bf16 units is bf16 (0.08 off, measured)
        # no pinning: processes beside this one (a campaign's workers) would pin theirs to the
        # same cores
        compiled = core.compile_model(core.read_model(graph), "CPU", {
            "INFERENCE_PRECISION_HINT": "f32", "INFERENCE_NUM_THREADS": threads * concurrent,
            "ENABLE_CPU_PINNING": False, **streams})
        requests = threading.local()  # a request serves one caller at a time
        # the graph's own (see _Graphs), by any of a port's names (``valid``'s has its cast's)
        names = {n for port in compiled.inputs for n in port.get_names()} & set(INPUT_NAMES)

        def run(feeds: dict[str, np.ndarray]) -> np.ndarray:
            request = getattr(requests, "request", None)
            if request is None:
                request = requests.request = compiled.create_infer_request()
            return request.infer({k: v for k, v in feeds.items() if k in names})[0]

        return run

    return compile_graph


def make_runner(model: KPN, backend: str = "torch", *, threads: int | None = None,
                concurrent: int = 1) -> Runner:
    """What runs ``model`` on a tile, on ``backend`` (a name of :data:`BACKENDS` or ``auto``)
    with ``threads`` threads per call (default: :func:`default_threads` shared out between the
    callers), callable from ``concurrent`` threads at once. For ``torch`` the thread count is
    per calling thread: set (``torch.set_num_threads``) in the thread that makes the runner when
    ``threads`` is given, and for ``concurrent`` callers in each caller's thread at its first
    call.

    Raises
    ------
    InvalidInputError
        An unknown or uninstalled backend, or a bad thread count.
    """
    name = resolve_backend(backend)
    if isinstance(concurrent, bool) or not isinstance(concurrent, int) or concurrent < 1:
        raise InvalidInputError(f"concurrent callers must be an integer >= 1, got {concurrent!r}")
    # by default the cores shared out between the callers
    n = check_threads(threads) if threads is not None else max(1, default_threads() // concurrent)
    if name == "torch":
        if threads is not None:  # else torch's own default (its physical cores)
            torch.set_num_threads(n)
        model.eval()
        # each calling thread runs its own OpenMP team, of the count set in that thread: callers
        # at once each set theirs when they first call (the count of the thread that made the
        # runner stays as it was, or as ``threads`` set it)
        callers = threading.local()

        def run(frames: torch.Tensor, fpa: torch.Tensor, valid: torch.Tensor,
                means: torch.Tensor, r2: torch.Tensor | None = None) -> torch.Tensor:
            if concurrent > 1 and not getattr(callers, "set", False):
                torch.set_num_threads(n)
                callers.set = True
            return model(frames.contiguous(memory_format=torch.channels_last), fpa, valid,
                         means=means, r2=r2)

        return run
    graphs = _onnxruntime if name == "onnxruntime" else _openvino
    return _Graphs(model.eval(), graphs(n, concurrent))


def export_onnx(weights: str | os.PathLike[str], out: str | os.PathLike[str], *,
                size: tuple[int, int] = (640, 512)
                ) -> dict[str, str]:
    """``thermocal export``: the network of weights file ``weights`` as an ONNX graph for
    frames of ``size = (W, H)`` px (padded up to the model's multiple), written atomically to
    ``out``; returns the metadata stored in it (``metadata_props``), which says how to feed it
    and read it: the normalisation of eq. 20-21, the band and temperature range of a
    ``radiance`` output, the frames' order (pivot in the middle), the weights' SHA-256.

    Raises
    ------
    FileFormatError
        ``weights`` is not a thermocal weights file.
    InvalidInputError
        A size that is not positive, or not the size of a chamber-trained network's camera.
    """
    import json

    import onnx

    from thermocal.io.atomic import atomic_path
    from thermocal.nn.store import load_model

    w, h = size
    if w < 1 or h < 1:
        raise InvalidInputError(f"--size must be positive, got {w}x{h}")
    model, norm, content = load_model(weights)
    c = model.config
    if c.calibrated:  # its inputs are °C through its nominal camera: one for this size
        from thermocal.nn.store import nominal_for

        try:
            nominal_for(model, (h, w))
        except InvalidInputError:
            nh, nw = model.nominal.shape
            raise InvalidInputError(
                f"--size {w}x{h}: this network's camera model is {nw}x{nh} (fitted on a "
                f"chamber file of that size): export it at --size {nw}x{nh}") from None
    mult = c.multiple
    hp, wp = -(-h // mult) * mult, -(-w // mult) * mult
    graph = onnx.load_from_string(onnx_graph(model, hp, wp))
    temp_range = (norm.temp_min_c, norm.temp_max_c)
    meta = {
        "thermocal.variant": c.variant,
        "thermocal.weights_sha256": str(content.get("sha256")),
        "thermocal.frames": str(c.n_frames),
        "thermocal.size_px": f"{wp}x{hp}",
        "thermocal.inputs": (
            "frames (1, N, H, W) float32: the registered frames (pivot in the middle), "
            + ("°C through the nominal camera stored in the weights" if c.calibrated
               else "raw counts") + ", normalised as eq. 20-21, 0 where a frame does not see "
            "the pixel; fpa (1,): the normalised FPA temperature; valid (1, N, H, W) bool; "
            "means (1, N): each frame's mean over its valid pixels"
            + ("; r2 (1, 1, H, W): the pixels' squared distance from the sensor centre over "
               "the half-diagonal squared" if c.radial else "")),
        "thermocal.output": (
            "out (1, 1, H, W): normalised band radiance over the temperature range; temperature "
            "= the inverse of Planck's band integral (thermocal.nn.model.RadianceToTemperature)"
            if c.radiance else "out (1, 1, H, W): normalised temperature (eq. 20)"),
        "thermocal.normalisation": json.dumps({
            "temp_min_c": norm.temp_min_c, "temp_max_c": norm.temp_max_c,
            "counts_min": norm.counts_min, "counts_max": norm.counts_max,
            "fpa_min_c": norm.fpa_min_c, "fpa_max_c": norm.fpa_max_c}),
        "thermocal.band_m": json.dumps(list(c.band_m)) if c.radiance else "",
        "thermocal.temp_range_c": json.dumps(list(temp_range)),
    }
    for key, value in meta.items():
        graph.metadata_props.add(key=key, value=value)
    with atomic_path(out) as tmp:
        onnx.save(graph, str(tmp))
    return meta
