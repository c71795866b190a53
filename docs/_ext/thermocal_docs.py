"""Sphinx helpers of thermocal's documentation.

``.. registry-table:: NAME`` renders one of :data:`TABLES` (the estimators, the calibration
methods and their file layouts, the NUC methods, the network variants, the registration methods,
the camera presets, the benchmark suites) from thermocal's registries at build time, so that a
method added to a registry appears in the documentation without editing it.

Module data and attributes show their value only when it is short (a constant, not a registry
whose repr runs over many lines: the registries have their tables).

A ``missing-reference`` handler links a cross-reference to an object by the name a package
re-exports it under (``thermocal.registration.register_burst``) or by its short name in the
module that imports it (``InvalidInputError``) to where the object is documented (the module
that defines it).
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable
from typing import Any

from docutils import nodes
from sphinx.application import Sphinx
from sphinx.domains.python import PyAttribute, PyVariable
from sphinx.util.docutils import SphinxDirective


def _first_line(obj: object) -> str:
    """The first sentence-line of ``obj``'s docstring (its summary), or an empty string."""
    doc = inspect.getdoc(obj) or ""
    summary = doc.split("\n\n", 1)[0]
    return " ".join(line.strip() for line in summary.splitlines())


def _qualified(obj: object) -> str:
    return f"{obj.__module__}.{obj.__qualname__}"


def _estimators() -> tuple[list[str], list[list[str]]]:
    from thermocal.estimation.registry import ESTIMATORS

    rows = [
        [f"``{e.name}``", e.needs, e.source, e.summary, "yes" if e.per_frame else "no"]
        for e in ESTIMATORS.values()
    ]
    return ["name", "needs", "source", "summary", "per frame"], rows


def _calibration_methods() -> tuple[list[str], list[list[str]]]:
    from thermocal.calibration import CALIBRATION_METHODS

    rows = [
        [f"``{c.name}``", c.source, c.summary, f":func:`~{_qualified(c.fit)}`",
         f":class:`~{_qualified(c.loads)}`"]
        for c in CALIBRATION_METHODS.values()
    ]
    return ["name", "source", "summary", "fitting function", "fitted calibration"], rows


def _calibration_layouts() -> tuple[list[str], list[list[str]]]:
    """Each calibration method's datasets and metadata entries, from its class's file layout."""
    import numpy as np

    from thermocal.calibration import CALIBRATION_METHODS

    def dtype_name(dtype: object) -> str:
        return "bool" if dtype is bool else np.dtype(dtype).name  # type: ignore[call-overload]

    rows = []
    for name, info in CALIBRATION_METHODS.items():
        layout = getattr(info.loads, "_layout", None)
        if layout is None:
            raise ValueError(f"{_qualified(info.loads)} has no file layout (_layout)")
        arrays = ", ".join(f"``{a}`` ({dtype_name(d)})" for a, d in layout.arrays_for(name).items())
        optional = ", ".join(f"``{a}``" for a in layout.optional_arrays)
        meta = ", ".join(f"``{m}``" + (" (optional)" if m in layout.optional_metadata else "")
                         for m in layout.metadata)
        rows.append([f"``{name}``", arrays, optional, meta + ", ``info``"])
    return ["method", "datasets", "optional datasets", "metadata entries"], rows


def _nuc_methods() -> tuple[list[str], list[list[str]]]:
    from thermocal.nuc import NUC_METHODS

    rows = [
        [f"``{m.name}``", m.source, m.summary, f":func:`~{_qualified(m.correct)}`",
         f":class:`~{_qualified(m.streaming)}`" if m.streaming else "(whole burst or one frame)"]
        for m in NUC_METHODS.values()
    ]
    return ["name", "source", "summary", "function", "streaming class"], rows


def _variants() -> tuple[list[str], list[list[str]]]:
    from thermocal.nn.variants import VARIANTS

    rows = [[f"``{v.name}``", v.summary, f"``{v.weights}``"] for v in VARIANTS.values()]
    return ["name", "summary", "shipped weights"], rows


def _registration_methods() -> tuple[list[str], list[list[str]]]:
    from thermocal.registration import BURST_METHODS

    return ["method of register_burst"], [[f"``{m}``"] for m in BURST_METHODS]


def _suites() -> tuple[list[str], list[list[str]]]:
    import importlib

    from thermocal.evaluation.suites import SUITES

    rows = []
    for name in SUITES:
        module = importlib.import_module(f"thermocal.evaluation.suites.{name}")
        rows.append([f"``{name}``", f":mod:`{module.__name__}`", _first_line(module)])
    return ["suite", "module", "what it measures"], rows


def _presets() -> tuple[list[str], list[list[str]]]:
    from thermocal.camera.presets import PRESETS

    rows = [
        [f"``{name}``", f"{p.band_m[0] * 1e6:g}–{p.band_m[1] * 1e6:g} µm", f"{p.t_ref_c:g} °C"]
        for name, p in PRESETS.items()
    ]
    return ["preset", "band", "reference FPA temperature"], rows


#: Table name → function giving its header and rows (reStructuredText cells).
TABLES: dict[str, Callable[[], tuple[list[str], list[list[str]]]]] = {
    "estimators": _estimators,
    "calibration-methods": _calibration_methods,
    "calibration-layouts": _calibration_layouts,
    "nuc-methods": _nuc_methods,
    "variants": _variants,
    "registration-methods": _registration_methods,
    "suites": _suites,
    "presets": _presets,
}


def _list_table(header: list[str], rows: list[list[str]]) -> str:
    def cell(text: str, first: bool) -> str:
        lead = "   * - " if first else "     - "
        return lead + (text.replace("\n", " ") or "\\ ")

    lines = [".. list-table::", "   :header-rows: 1", ""]
    for row in [header, *rows]:
        lines += [cell(text, k == 0) for k, text in enumerate(row)]
    return "\n".join(lines)


class RegistryTable(SphinxDirective):
    """``.. registry-table:: NAME``: a table made from a thermocal registry at build time."""

    required_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        name = self.arguments[0]
        make = TABLES.get(name)
        if make is None:
            raise self.error(f"unknown registry table {name!r}; choose from {', '.join(TABLES)}")
        header, rows = make()
        return self.parse_text_to_nodes(_list_table(header, rows))


#: Longest value (characters of its repr) shown after a data or attribute name.
MAX_VALUE_CHARS = 60


class _ShortValueMixin:
    """Drop the ``:value:`` of a data or attribute description when it is long."""

    options: dict[str, Any]

    def handle_signature(self, sig: str, signode: Any) -> Any:
        value = self.options.get("value")
        if value is not None and len(value) > MAX_VALUE_CHARS:
            del self.options["value"]
        return super().handle_signature(sig, signode)  # type: ignore[misc]


class ShortValueData(_ShortValueMixin, PyVariable):
    """``py:data`` showing short values only."""


class ShortValueAttribute(_ShortValueMixin, PyAttribute):
    """``py:attribute`` showing short values only."""


_MISSING = object()


def _import_path(path: str) -> Any:
    """The object named by the dotted ``path`` (a module, then attributes), or :data:`_MISSING`."""
    parts = path.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:k]))
        except Exception:  # not a module (or not importable): try a shorter one
            continue
        for attr in parts[k:]:
            obj = getattr(obj, attr, _MISSING)
            if obj is _MISSING:
                return _MISSING
        return obj
    return _MISSING


def _documented_names(env: Any) -> dict[str, list[str]]:
    """Last component of each documented Python object → its full names (cached per build)."""
    domain = env.get_domain("py")
    key = len(domain.objects)
    cached = getattr(env, "_thermocal_names", None)
    if cached is None or cached[0] != key:
        names: dict[str, list[str]] = {}
        for full in domain.objects:
            names.setdefault(full.rsplit(".", 1)[-1], []).append(full)
        cached = (key, names)
        env._thermocal_names = cached
    return cached[1]


def _resolve_reexport(app: Sphinx, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve a Python cross-reference to an object documented under another (its real) name."""
    if node.get("refdomain") != "py" or not node.get("reftarget"):
        return None
    target = node["reftarget"].lstrip(".~")
    if not target.startswith("thermocal") and not node.get("py:module", "").startswith("thermocal"):
        return None
    candidates = [target]
    if node.get("py:module"):
        candidates.insert(0, f"{node['py:module']}.{target}")
    for path in candidates:
        obj = _import_path(path)
        if obj is _MISSING or inspect.ismodule(obj):
            continue
        last = target.rsplit(".", 1)[-1]
        for full in _documented_names(env).get(last, []):
            if full != path and _import_path(full) is obj:
                domain = env.get_domain("py")
                return domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"],
                                           full, node, contnode)
    return None


def setup(app: Sphinx) -> dict[str, object]:
    app.add_directive("registry-table", RegistryTable)
    app.connect("missing-reference", _resolve_reexport)
    app.add_directive_to_domain("py", "data", ShortValueData, override=True)
    app.add_directive_to_domain("py", "attribute", ShortValueAttribute, override=True)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
