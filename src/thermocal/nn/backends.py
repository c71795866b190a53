"""The network's inference backends, by name (no torch import: the command line reads it).

=============== =================================================================================
``torch``       PyTorch eager (channels_last, inference_mode): always there
``onnxruntime`` ONNX Runtime's CPU execution provider on the exported ONNX graph
``openvino``    OpenVINO's CPU plugin at f32 on the same graph
=============== =================================================================================

``auto`` is the first installed of :data:`AUTO_ORDER`, fastest first on one thread as
``benchmarks/backends.py`` measures them (on two the three lie within their run-to-run
spread), for runs of many bursts (a flight, a campaign); for one burst (``thermocal
estimate``) it is PyTorch (:func:`one_burst_backend`). ONNX Runtime and OpenVINO are the
optional extra ``thermocal[backends]``. What runs each: :mod:`thermocal.nn.runners`.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

from thermocal.cores import available_cores
from thermocal.errors import InvalidInputError

__all__ = ["AUTO_ORDER", "BACKENDS", "CHOICES", "BackendInfo", "check_threads", "default_threads",
           "installed", "one_burst_backend", "resolve_backend"]


@dataclass(frozen=True)
class BackendInfo:
    """An inference backend: its name, the module it needs and what it is."""

    name: str
    module: str
    summary: str


#: Every backend, by name.
BACKENDS = {
    "torch": BackendInfo("torch", "torch", "PyTorch eager (channels_last, inference_mode)"),
    "onnxruntime": BackendInfo("onnxruntime", "onnxruntime",
                               "ONNX Runtime, CPU execution provider, the exported ONNX graph"),
    "openvino": BackendInfo("openvino", "openvino",
                            "OpenVINO, CPU plugin at f32, the exported ONNX graph"),
}
#: ``auto``'s order: fastest first on one thread (``benchmarks/backends.py``, one 336×256 burst
#: of 7: OpenVINO 0.78, ONNX Runtime 0.85 of PyTorch's time; on two threads the three lie within
#: their run-to-run spread since the kernel step was folded). A fixed order, not a race: the
#: same backend, and so the same bytes, on every run.
AUTO_ORDER = ("openvino", "onnxruntime", "torch")


def installed(name: str) -> bool:
    """Whether backend ``name``'s module can be imported."""
    return importlib.util.find_spec(BACKENDS[name].module) is not None


def resolve_backend(name: str) -> str:
    """The backend ``name`` stands for (``auto``: the first installed of :data:`AUTO_ORDER`).

    Raises
    ------
    InvalidInputError
        Unknown, or not installed (with the command that installs it).
    """
    if name == "auto":
        return next(b for b in AUTO_ORDER if installed(b))
    if name not in BACKENDS:
        raise InvalidInputError(
            f"unknown backend {name!r}; choose from auto, {', '.join(BACKENDS)}")
    if not installed(name):
        raise InvalidInputError(
            f"the {name} backend is not installed: pip install 'thermocal[backends]' "
            "(or --backend torch)")
    return name


def one_burst_backend(name: str) -> str:
    """The backend ``name`` stands for when one burst is estimated: ``auto`` is PyTorch there.
    A graph backend first exports and compiles the network (0.4–0.9 s, and importing its
    runtime), more than it gains on one burst (``thermocal estimate``: 4.1 s with PyTorch,
    5.7 s with OpenVINO, one run of a helper's audit); the others as given."""
    return "torch" if name == "auto" else name


def default_threads() -> int:
    """The threads a backend runs on by default: the CPU cores this process may use
    (:func:`thermocal.cores.available_cores`)."""
    return available_cores()


def check_threads(threads: int | None) -> int:
    """``threads`` checked (an integer >= 1), or :func:`default_threads` for None."""
    if threads is None:
        return default_threads()
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise InvalidInputError(f"--threads must be an integer >= 1, got {threads!r}")
    return threads


#: What ``--backend`` takes.
CHOICES = ("auto", *BACKENDS)
