"""A processed flight's report: ``OUT/report.html``, one page a person reads to judge the maps.

:func:`write_report` reads what ``thermocal flight`` left in ``OUT`` (``summary.json``,
``log.jsonl``, the maps in ``temps/``, the previews, and the mosaic in ``mosaic/`` when there is
one) and writes a single self-contained HTML file: every image inline (base64 PNG), no external
style sheet, script or font, so that it opens offline and can be mailed as one file. It says

* what was processed and how: the recording, its format, the method, the command, the date;
* how accurate the method says the maps are: the σ statistics of ``summary.json`` and, for a
  network, its σ model; or plainly that the method has no uncertainty model;
* the mosaic (or a few previews), the FPA temperature and each map's temperature range over the
  flight, with the failed groups marked;
* which groups failed and why, the warnings, what an earlier run had already done;
* how to read σ, and where the files are.

Every map is read once, one at a time (a 1,000-pivot flight: seconds); the table shows at most
``max_rows`` groups, evenly spaced, and says so. Strings from the files are escaped.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import io
import json
import math
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.errors import FileFormatError, InvalidInputError, OutputError
from thermocal.io.atomic import atomic_path
from thermocal.pipeline.flight_log import read_log

__all__ = ["REPORT_NAME", "load_summary", "write_report"]

#: The report's file name in the flight output folder.
REPORT_NAME = "report.html"

#: Widest image embedded, pixels (larger PNGs are scaled down).
_MAX_IMAGE_PX = 1100

#: Frames listed per failure reason or warning before "and N more".
_MAX_FRAMES_LISTED = 24

#: Kinds of failure or warning listed (the commonest first).
_MAX_KINDS = 20

_CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, Helvetica, Arial, sans-serif;
       max-width: 1100px; margin: 1.5em auto; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; word-break: break-all; }
h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.92em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.55em; text-align: left; vertical-align: top; }
th { background: #f0f0f0; }
td.n { text-align: right; font-variant-numeric: tabular-nums; }
table.facts th { width: 12em; }
tr:nth-child(even) td { background: #fafafa; }
code { background: #f4f4f4; padding: 0.05em 0.3em; word-break: break-all; }
.note { color: #555; font-size: 0.9em; }
.ok { color: #1a7f37; } .bad { color: #b42318; font-weight: 600; } .warn { color: #9a6700; }
.verdict { font-size: 1.05em; padding: 0.5em 0.8em; background: #f6f8fa;
           border-left: 4px solid #888; }
.grid { display: flex; flex-wrap: wrap; gap: 0.4em; }
.grid figure { margin: 0; width: 32.5%; }
figure { margin: 0.4em 0; }
img { max-width: 100%; height: auto; }
"""


def write_report(out_dir: str | Path, *, max_rows: int = 40, previews: int = 6) -> Path:
    """Write ``OUT/report.html`` for the flight output folder ``out_dir``; its path.

    Parameters
    ----------
    out_dir : str or os.PathLike
        A folder written by ``thermocal flight`` (its ``summary.json`` at least).
    max_rows : int, optional
        Most groups in the table of temperature ranges (evenly spaced when there are more).
    previews : int, optional
        Pivot previews shown when there is no mosaic.

    Returns
    -------
    pathlib.Path
        ``OUT/report.html``, written atomically.

    Raises
    ------
    InvalidInputError
        ``out_dir`` is not a flight output (no readable ``summary.json`` of a flight); nothing
        is written.
    OutputError
        The report could not be written.
    """
    if max_rows < 1 or previews < 0:
        raise InvalidInputError("max_rows must be >= 1 and previews >= 0")
    out = Path(out_dir)
    summary = load_summary(out)
    target = out / REPORT_NAME
    if target.exists() and not target.is_file():
        raise InvalidInputError(f"{target}: exists and is not a file; move it away")
    page = _page(out, summary, read_log(out / "log.jsonl"), max_rows=max_rows,
                 previews=previews)
    try:
        with atomic_path(target) as tmp:
            tmp.write_text(page, encoding="utf-8")
    except OSError as exc:
        raise OutputError(f"{target}: {exc.strerror or exc}; free space or make "
                          f"{out} writable, then run `thermocal report {out}` again") from None
    return target


def load_summary(out: Path) -> dict[str, Any]:
    """The flight's ``summary.json``, checked to be one; InvalidInputError otherwise."""
    if not out.is_dir():
        raise InvalidInputError(f"{out}: not a folder; give the output folder of `thermocal "
                                "flight` (the one holding summary.json)")
    path = out / "summary.json"
    try:
        summary = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InvalidInputError(f"{path}: missing, so {out} is not a finished flight output; "
                                "run (or rerun, it resumes) `thermocal flight RECORDING --out "
                                f"{out}`") from None
    except (OSError, ValueError, RecursionError) as exc:
        raise InvalidInputError(f"{path}: unreadable or damaged ({type(exc).__name__}); rerun "
                                f"`thermocal flight RECORDING --out {out}` to rewrite it "
                                "(it resumes)") from None
    options = summary.get("options") if isinstance(summary, dict) else None
    if (not isinstance(options, dict) or not isinstance(options.get("method"), str)
            or not _is_count(summary.get("groups"))):
        raise InvalidInputError(f"{path}: not the summary of a `thermocal flight` run (no "
                                "options.method or groups); give a flight output folder or "
                                "rerun the flight to rewrite it")
    return summary


# --- what the report shows, computed from the files -----------------------------------------


def _is_count(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _number(value: Any) -> float | None:
    """``value`` as a finite float, or None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def _map_stats(out: Path, entries: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per finished group: its frame, time, FPA, the map's min / p1 / median / p99 / max (°C)
    and the logged σ median; ``missing`` when its map cannot be read. Maps read one at a time."""
    from thermocal.io.recording import read_temperature_tiff

    rows = []
    for e in entries:
        if "error" in e:
            continue
        row = {"frame": e["frame"], "time_s": _number(e.get("time_s")),
               "fpa_c": _number(e.get("fpa_c")), "sigma_c": _number(e.get("sigma_median_c")),
               "correlation": _number(e.get("registration_correlation")),
               "warnings": len(e["warnings"]) if isinstance(e.get("warnings"), list) else 0}
        try:
            temp = read_temperature_tiff(out / "temps" / f"frame_{e['frame']:06d}.tiff")
        except FileFormatError:
            row["missing"] = True
        else:
            row["range"] = [float(v) for v in np.percentile(temp, [0, 1, 50, 99, 100])]
        rows.append(row)
    return rows


def _reason_key(message: str) -> str:
    """A message with its numbers blanked: the messages of one cause share it."""
    return re.sub(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", "#", message)


def _grouped(pairs: Iterable[tuple[int, str]]) -> list[tuple[str, list[int]]]:
    """``(frame, message)`` pairs grouped by cause (:func:`_reason_key`): each cause's first
    message and its frames, the commonest cause first."""
    groups: dict[str, tuple[str, list[int]]] = {}
    for frame, message in pairs:
        groups.setdefault(_reason_key(message), (message, []))[1].append(frame)
    return sorted(groups.values(), key=lambda g: (-len(g[1]), g[1][0]))


def _failures(entries: list[dict[str, Any]]) -> list[tuple[str, list[int]]]:
    return _grouped((e["frame"], str(e["error"])) for e in entries if "error" in e)


def _warnings(entries: list[dict[str, Any]]) -> list[tuple[str, list[int]]]:
    return _grouped((e["frame"], str(w)) for e in entries
                    if isinstance(e.get("warnings"), list) for w in e["warnings"])


def _recording_format(summary: dict[str, Any]) -> str | None:
    """The recording's format as the flight recorded it in its summary; None when it did not
    (a flight of an older thermocal): the report does not open the recording again."""
    fmt = summary.get("format")
    return fmt if isinstance(fmt, str) else None


def _sigma_model(options: dict[str, Any]) -> str | None:
    """The network's σ model in a sentence (from the ``NAME.sigma.json`` beside its weights),
    or None when the method is not a network."""
    from thermocal.nn.variants import VARIANTS

    method = options.get("method")
    if method not in VARIANTS:
        return None
    from importlib.resources import files

    from thermocal.nn.uncertainty import SigmaModel, sidecar_path

    model = options.get("model")
    weights = (Path(model) if isinstance(model, str)
               else Path(str(files("thermocal.nn") / "weights" / VARIANTS[method].weights)))
    path = sidecar_path(weights)
    try:
        sigma = SigmaModel.load(path, weights_sha256=None)
    except FileFormatError:
        return f"its σ model {path.name} cannot be read from here"
    fitted = sigma.fitted_on
    units = fitted.get("units")
    on = (f"fitted on {fitted.get('bursts')} bursts of {len(units)} camera units it never "
          "trained on" if isinstance(units, list) and fitted.get("bursts") else
          f"fitted on {fitted.get('bursts')} bursts of the camera model fitted on its chamber "
          "file, with what that model misses of the camera's level on the file's frames"
          if fitted.get("chamber") else
          "fitted")
    contrast = ("" if sigma.contrast_per_c is None else
                f", and by {sigma.contrast_per_c:.3f} °C per °C the scene lies from the FPA "
                "temperature")
    return (f"σ model {path.name}: σ grows where the frames disagree, at edges and where fewer "
            f"frames see a pixel, never below {sigma.floor_c:.2f} °C (the unit's own level, "
            f"which no view reveals{contrast}); {on}; outside the network's domain (--force) "
            f"{sigma.outside_c:.0f} °C more in quadrature, and the whole distance beyond its "
            "training scenes")


# --- figures ---------------------------------------------------------------------------------


def _png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _image_uri(path: Path) -> str | None:
    """A PNG file as a data URI, scaled down to :data:`_MAX_IMAGE_PX` wide; None when it
    cannot be read."""
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as img:
            if img.width <= _MAX_IMAGE_PX and img.format == "PNG":
                return _png_uri(path.read_bytes())
            img.thumbnail((_MAX_IMAGE_PX, _MAX_IMAGE_PX * 4))
            buffer = io.BytesIO()
            img.save(buffer, format="PNG", optimize=True)
    except (OSError, UnidentifiedImageError, ValueError, Image.DecompressionBombError):
        return None
    return _png_uri(buffer.getvalue())


def _map_figure(values: np.ndarray, *, label: str, cmap: str):
    """A map with NaN holes (a mosaic) and its colour bar, scaled to 1–99 %; None if empty."""
    from thermocal.plotting import pyplot

    step = max(1, math.ceil(max(values.shape) / _MAX_IMAGE_PX))
    shown = np.asarray(values[::step, ::step], np.float64)
    finite = shown[np.isfinite(shown)]
    if not finite.size:
        return None
    lo, hi = np.percentile(finite, [1, 99])
    from mpl_toolkits.axes_grid1 import make_axes_locatable

    h, w = shown.shape
    fig, ax = pyplot().subplots(figsize=(10.0 * w / max(h, w), 10.0 * h / max(h, w)))
    im = ax.imshow(shown, cmap=cmap, vmin=lo, vmax=max(hi, lo + 0.1))
    bar = make_axes_locatable(ax).append_axes("right", size=0.15, pad=0.1)  # inches
    fig.colorbar(im, cax=bar, label=label)
    ax.set_xticks([])
    ax.set_yticks([])
    return fig


def _flight_figure(rows: list[dict[str, Any]], entries: list[dict[str, Any]]):
    """FPA temperature, each map's temperature range and its σ median over the flight, the
    failed groups marked (by time when every group has one, else by frame)."""
    from thermocal.plotting import pyplot

    by_time = all(_number(e.get("time_s")) is not None for e in entries)
    where = (lambda e: float(e["time_s"])) if by_time else (lambda e: float(e["frame"]))
    failed = [where(e) for e in entries if "error" in e]
    mapped = [r for r in rows if "range" in r]
    has_sigma = any(r["sigma_c"] is not None for r in mapped)
    panels = 2 + has_sigma
    fig, axes = pyplot().subplots(panels, 1, figsize=(11.0, 2.0 * panels + 0.6), sharex=True,
                                   squeeze=False)
    axes = axes[:, 0]
    fpa = [(where(e), _number(e.get("fpa_c"))) for e in entries]
    fpa = [(x, v) for x, v in fpa if v is not None]
    if fpa:
        axes[0].plot(*zip(*fpa, strict=True), ".-", color="#444", markersize=3, linewidth=1)
        values = [v for _, v in fpa]  # at least 1 °C tall: a steady FPA looks steady
        middle, half = (max(values) + min(values)) / 2, max(0.5, (max(values) - min(values)) / 2)
        axes[0].set_ylim(middle - 1.1 * half, middle + 1.1 * half)
    axes[0].set_ylabel("FPA (°C)")
    if mapped:
        x = [where(r) for r in mapped]
        lo, p1, med, p99, hi = np.array([r["range"] for r in mapped]).T
        axes[1].fill_between(x, p1, p99, color="#f4a261", alpha=0.45, label="1–99 %")
        axes[1].plot(x, med, color="#9c3d00", linewidth=1.2, label="median")
        axes[1].plot(x, lo, ":", color="#555", linewidth=0.8, label="min / max")
        axes[1].plot(x, hi, ":", color="#555", linewidth=0.8)
        axes[1].legend(fontsize=7, loc="best", ncol=3)
    axes[1].set_ylabel("map (°C)")
    if has_sigma:
        sig = [(where(r), r["sigma_c"]) for r in mapped if r["sigma_c"] is not None]
        axes[2].plot(*zip(*sig, strict=True), ".-", color="#2a6f97", markersize=3, linewidth=1)
        axes[2].set_ylabel("median σ (°C)")
        axes[2].set_ylim(bottom=0)
    for i, x in enumerate(failed):
        for ax in axes:
            ax.axvline(x, color="#b42318", alpha=0.5, linewidth=1.2,
                       label="failed group" if i == 0 and ax is axes[0] else None)
    if failed:
        axes[0].legend(fontsize=7, loc="best")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time (s)" if by_time else "frame")
    fig.tight_layout()
    return fig


# --- HTML ------------------------------------------------------------------------------------


def _e(value: Any) -> str:
    return html.escape(str(value))


def _fmt(value: Any, spec: str = ".2f", unit: str = "") -> str:
    number = _number(value)
    return "–" if number is None else f"{number:{spec}}{unit}"


def _img(uri: str, alt: str) -> str:
    return f'<img src="{uri}" alt="{_e(alt)}">'


def _frames_text(frames: list[int]) -> str:
    shown = ", ".join(map(str, frames[:_MAX_FRAMES_LISTED]))
    more = len(frames) - _MAX_FRAMES_LISTED
    return shown + (f" and {more} more" if more > 0 else "")


def _table(head: list[str], rows: list[list[str]], *, numeric: Iterable[int] = ()) -> str:
    """An HTML table; ``head`` and the cells are HTML already (escape before)."""
    right = set(numeric)
    cells = "".join(
        "<tr>" + "".join(f'<td class="n">{c}</td>' if j in right else f"<td>{c}</td>"
                         for j, c in enumerate(row)) + "</tr>\n" for row in rows)
    return ("<table><tr>" + "".join(f"<th>{h}</th>" for h in head) + "</tr>\n" + cells
            + "</table>")


def _accuracy(summary: dict[str, Any]) -> str:
    """The method's stated accuracy: the σ statistics of the summary, or that there is none."""
    sigma = summary.get("sigma_c")
    options = summary["options"]
    model = _sigma_model(options)
    if not isinstance(sigma, dict):
        text = ('<span class="bad">no uncertainty model</span>: this method gives no σ, so '
                "these maps come with no stated accuracy")
        return text + (f" ({_e(model)})" if model else "")
    text = (f"σ (1σ) {_fmt(sigma.get('median_of_medians'), unit=' °C')} typical (median over "
            f"the maps of each map's median σ), up to {_fmt(sigma.get('max_p95'), unit=' °C')} "
            f"(largest 95th percentile of a map), over {_e(sigma.get('maps', '?'))} maps")
    if model:
        text += f"<br><span class=\"note\">{_e(model)}</span>"
    elif options.get("calibration"):
        text += ('<br><span class="note">σ from the cross-validation of the calibration '
                 f"{_e(options['calibration'])}</span>")
    if isinstance(sigma.get("caveat"), str):  # where the method's σ is known not to hold
        text += f"<br><span class=\"warn\">{_e(options['method'])}: {_e(sigma['caveat'])}</span>"
    return text


def _header(out: Path, summary: dict[str, Any], entries: list[dict[str, Any]]) -> str:
    from thermocal.estimation.registry import ESTIMATORS

    options = summary["options"]
    method = options["method"]
    info = ESTIMATORS.get(method)
    recording = str(summary.get("recording", "?"))
    written = dt.datetime.fromtimestamp((out / "summary.json").stat().st_mtime, dt.UTC)
    command = summary.get("command")
    facts = [
        ("recording", f"<code>{_e(recording)}</code>"),
        ("format", _e(_recording_format(summary) or "unknown")),
        ("method", f"<b>{_e(method)}</b>" + (f": {_e(info.summary)}; after {_e(info.source)}"
                                              if info else "")),
        ("groups", f"{_e(options.get('frames', '?'))} frames each, a pivot every "
                   f"{_e(options.get('stride', '?'))} frames"
                   + ("; <span class=\"warn\">--force: groups outside the method's domain "
                      "estimated anyway</span>" if options.get("force") else "")),
        ("stated accuracy", _accuracy(summary)),
        ("processed", f"{_e(summary['groups'])} groups"
         + (f", the last run in {_fmt(summary['wall_time_s'], '.1f', ' s')}"
            if _number(summary.get("wall_time_s")) is not None else "")),
        ("processed on", written.strftime("%Y-%m-%d %H:%M UTC")
         + ' <span class="note">(when summary.json was written)</span>'),
        ("command", f"<code>{_e(command)}</code>" if isinstance(command, str)
         else '<span class="note">not recorded in summary.json</span>'),
    ]
    rows = "".join(f"<tr><th>{k}</th><td>{v}</td></tr>\n" for k, v in facts)
    failed = sum("error" in e for e in entries)
    done = len(entries) - failed
    warned = sum(bool(e.get("warnings")) for e in entries if "error" not in e)
    verdict = (f'<span class="ok">{done} of {summary["groups"]} groups gave a map</span>'
               if done else '<span class="bad">no group gave a map</span>')
    if failed:
        verdict += f'; <span class="bad">{failed} failed</span> (see below)'
    if warned:
        verdict += f'; <span class="warn">{warned} with warnings</span>'
    gone = sum(not (out / "temps" / f"frame_{e['frame']:06d}.tiff").is_file()
               for e in entries if "error" not in e)
    if gone:  # moved or deleted since the flight: its figures are the log's, not the files'
        verdict += (f'; <span class="bad">{gone} of those maps no longer in temps/</span> '
                    "(moved or deleted since)")
    if len(entries) < summary["groups"]:
        verdict += f"; {summary['groups'] - len(entries)} not logged (interrupted?)"
    return (f"<h1>Flight report: {_e(Path(recording).name)}</h1>\n"
            f'<table class="facts">{rows}</table>\n{_HOW_TO_READ}'
            f'<p class="verdict">{verdict}.</p>\n')


def _maps_section(out: Path, previews: int, entries: Sequence[dict[str, Any]] = ()) -> str:
    """The mosaic and its σ when there is one (said to be out of date where the log has maps
    the mosaic was not made from: :func:`_mosaic_stale`); else a few pivot previews."""
    mosaic = out / "mosaic"
    parts = []
    for name, label, cmap in (("temperature.tiff", "°C", "inferno"),
                              ("sigma.tiff", "σ, °C (1σ)", "viridis")):
        uri = _layer_uri(mosaic / name, label=label, cmap=cmap)
        if uri is not None:
            parts.append((name, uri))
    if not any(name == "temperature.tiff" for name, _ in parts):
        uri = _image_uri(mosaic / "mosaic.png") if (mosaic / "mosaic.png").is_file() else None
        if uri is not None:
            parts.insert(0, ("mosaic.png", uri))
    if parts:
        meta = _mosaic_meta(mosaic / "mosaic.json")
        return ("<h2>Mosaic</h2>\n" + "".join(
            f"<figure>{_img(u, name)}<figcaption class=\"note\">mosaic/{_e(name)}"
            "</figcaption></figure>\n" for name, u in parts)
            + _mosaic_stale(out, meta, entries) + _mosaic_facts(meta))
    pngs = sorted((out / "previews").glob("frame_*.png")) if (out / "previews").is_dir() else []
    if not pngs or not previews:
        return ("<h2>Maps</h2>\n<p class=\"note\">No mosaic and no previews in this folder "
                "(--preview-every 0?); the maps are in temps/.</p>\n")
    picked = [pngs[round(i * (len(pngs) - 1) / max(1, previews - 1))]
              for i in range(min(previews, len(pngs)))]
    shown = [(p, _image_uri(p)) for p in dict.fromkeys(picked)]
    cells = "".join(f"<figure>{_img(u, p.name)}<figcaption class=\"note\">{_e(p.name)}"
                    "</figcaption></figure>" for p, u in shown if u)
    return (f"<h2>Maps</h2>\n<p class=\"note\">No mosaic in this folder: {len(shown)} of "
            f"{len(pngs)} pivot previews, evenly spaced.</p>\n<div class=\"grid\">{cells}</div>\n")


def _layer_uri(path: Path, *, label: str, cmap: str) -> str | None:
    """A mosaic layer (NaN: no data) drawn with its colour bar, as a data URI; None when absent
    or unreadable. Read through a memory map where it can be: only every k-th pixel is drawn."""
    import tifffile

    from thermocal.plotting import figure_png

    if not path.is_file():
        return None
    try:
        try:
            values = tifffile.memmap(path, mode="r")
        except ValueError:  # compressed or tiled: read whole
            values = tifffile.imread(path)
        fig = _map_figure(values, label=label, cmap=cmap) if values.ndim == 2 else None
    except Exception:  # a damaged TIFF: tifffile raises many types
        return None
    return None if fig is None else _png_uri(figure_png(fig, dpi=100))


def _mosaic_meta(path: Path) -> dict[str, Any] | None:
    """``mosaic.json`` as a dict; None when absent or damaged."""
    try:
        meta = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return meta if isinstance(meta, dict) else None


def _mosaic_stale(out: Path, meta: dict[str, Any] | None,
                  entries: Sequence[dict[str, Any]]) -> str:
    """A warning when the log lists maps the mosaic (``meta``, its ``mosaic.json``) neither used
    nor left out for a reason that still holds (a map the flight made or remade after the
    mosaic, e.g. a resumed flight without ``--mosaic``); '' otherwise, or without a readable
    mosaic.json (None)."""
    if meta is None:
        return ""

    def frames(key: str, keep: Any = lambda e: True) -> set[int]:
        value = meta.get(key)
        return {e["frame"] for e in value if isinstance(e, dict) and _is_count(e.get("frame"))
                and keep(e)} if isinstance(value, list) else set()

    # maps left out because the log or temps/ lacked them then: made since, if logged now and
    # their files are there now (a map still missing is no sign of age: it would stay)
    gone = ("not in log.jsonl", "no map:", "no σ:")
    seen = frames("maps_used") | frames(
        "maps_left_out", lambda e: not str(e.get("reason", "")).startswith(gone))
    temps = out / "temps"
    made = sorted(
        {e["frame"] for e in entries if _is_count(e.get("frame")) and "error" not in e
         and (temps / f"frame_{e['frame']:06d}.tiff").is_file()
         and ("sigma_mean_c" not in e
              or (temps / f"frame_{e['frame']:06d}_sigma.tiff").is_file())} - seen)
    if not made:
        return ""
    return (f'<p class="warn">This mosaic is out of date: it was made before {len(made)} '
            f"map{'s' * (len(made) > 1)} of this folder (frames {_e(_frames_text(made))}); "
            f"run <code>thermocal mosaic {_e(out)}</code> again.</p>\n")


def _mosaic_facts(meta: dict[str, Any] | None) -> str:
    """What ``mosaic.json`` (``meta``) says of the mosaic (its canvas, the maps used and left out
    and why, the views per pixel, its σ), as a few lines; '' when absent or damaged (None)."""
    if meta is None:
        return ""

    def part(key: str) -> dict[str, Any]:
        value = meta.get(key)
        return value if isinstance(value, dict) else {}

    canvas, views, sigma = part("canvas"), part("views"), part("sigma")
    used, left = meta.get("maps_used"), meta.get("maps_left_out")
    lines = []
    if _is_count(canvas.get("width")) and _is_count(canvas.get("height")):
        lines.append(f"canvas {canvas['width']} × {canvas['height']} px, "
                     f"{_fmt(100 * (_number(canvas.get('covered_fraction')) or 0), '.0f')} % "
                     "covered")
    if isinstance(used, list):
        lines.append(f"{len(used)} maps used"
                     + (f", {len(left)} left out" if isinstance(left, list) else ""))
    if _number(views.get("median")) is not None:
        lines.append(f"views per pixel: median {_fmt(views['median'], '.0f')}, most "
                     f"{_fmt(views.get('max'), '.0f')}; "
                     f"{_fmt(100 * (_number(views.get('rejected_fraction')) or 0), '.1f')} % "
                     "of views rejected as outliers")
    if sigma.get("written") is False:
        lines.append(f"no σ: {_e(sigma.get('reason', 'not written'))}")
    items = "".join(f"<li>{line}</li>" for line in lines)
    if isinstance(left, list) and left:
        pairs = [(e["frame"], str(e.get("reason", "?"))) for e in left
                 if isinstance(e, dict) and _is_count(e.get("frame"))]
        items += "".join(f"<li>left out ({len(f)}): {_e(m)} (frames {_e(_frames_text(f))})</li>"
                         for m, f in _grouped(pairs))
    return f'<ul class="note">{items}</ul>\n' if items else ""


def _ranges_section(rows: list[dict[str, Any]], entries: list[dict[str, Any]],
                    max_rows: int) -> str:
    from thermocal.plotting import figure_png

    parts = ["<h2>Over the flight</h2>\n"]
    if entries:
        parts.append(_img(_png_uri(figure_png(_flight_figure(rows, entries), dpi=90)),
                          "FPA temperature, map temperatures and σ over the flight") + "\n")
    else:
        return '<h2>Over the flight</h2>\n<p class="bad">log.jsonl is missing or empty.</p>\n'
    shown = rows
    if len(rows) > max_rows:
        shown = [rows[round(i * (len(rows) - 1) / (max_rows - 1))] for i in range(max_rows)]
        shown = list({r["frame"]: r for r in shown}.values())
    missing = sum("range" not in r for r in rows)
    head = ["frame", "time (s)", "FPA (°C)", "min", "p1", "median", "p99", "max",
            "median σ", "registration", "warnings"]
    cells = []
    for r in shown:
        rng = r.get("range")
        values = ([_fmt(v) for v in rng] if rng else
                  ['<span class="bad">map missing or unreadable</span>', "", "", "", ""])
        cells.append([str(r["frame"]), _fmt(r["time_s"]), _fmt(r["fpa_c"]), *values,
                      _fmt(r["sigma_c"]), _fmt(r["correlation"], ".3f"),
                      str(r["warnings"] or "")])
    note = ("Each map's temperatures, °C; median σ is the median of its σ map; registration is "
            "the lowest correlation of a frame with its neighbour in the group (1 is perfect).")
    if len(shown) < len(rows):
        note += (f" {len(shown)} of {len(rows)} groups shown, evenly spaced; every group is in "
                 "log.csv.")
    if missing:
        note += f' <span class="bad">{missing} logged maps are missing or unreadable.</span>'
    parts.append(f'<p class="note">{note}</p>\n'
                 + _table(head, cells, numeric=range(len(head))))
    return "".join(parts)


def _problems_section(summary: dict[str, Any], entries: list[dict[str, Any]]) -> str:
    parts = ["<h2>Failed groups and warnings</h2>\n"]
    for kind, found, none in (("reason", _failures(entries), '<p class="ok">No group failed.</p>'),
                              ("warning", _warnings(entries), "<p>No warnings.</p>")):
        parts.append(_table(["groups", f"{kind} (first of its kind)", "pivot frames"],
                            [[str(len(f)), _e(m), _e(_frames_text(f))]
                             for m, f in found[:_MAX_KINDS]], numeric=[0]) if found
                     else none + "\n")
        if len(found) > _MAX_KINDS:
            parts.append(f'<p class="note">and {len(found) - _MAX_KINDS} more kinds of '
                         f"{kind}, rarer: every group's are in log.csv.</p>\n")
    skipped = summary.get("skipped_already_done")
    if _is_count(skipped) and skipped:
        parts.append(f"<p>The last run resumed an earlier one: {_e(skipped)} groups were already "
                     f"done and kept, {_e(summary.get('processed', '?'))} made, "
                     f"{_e(summary.get('failed', '?'))} failed.</p>\n")
    return "".join(parts)


def _selfcal_section(summary: dict[str, Any]) -> str:
    """What ``--method selfcal`` fitted: the start model, each batch (motion, what it could not
    show), the references' level; empty for other methods."""
    fit = summary.get("selfcal")
    if not isinstance(fit, dict):
        return ""
    parts = [f"<h2>Self-calibration</h2>\n<p>Started from {_e(fit.get('start', '?'))}; the "
             "unit's residual pattern fitted over each batch of frames:</p>\n"]
    rows = []
    for seg in fit.get("segments") or []:
        if not isinstance(seg, dict):
            continue
        frames, motion = seg.get("frames") or ["?", "?"], seg.get("motion_px") or ["?", "?"]
        rows.append([_e(f"{frames[0]}–{frames[-1]}"), _fmt(motion[0], ".0f", " px"),
                     _fmt(motion[1], ".0f", " px"), _e(seg.get("bad_pixels", "?")),
                     _e("; ".join(map(str, seg.get("not_identified") or [])))])
    parts.append(_table(["frames", "motion along x", "along y", "bad pixels",
                         "not identified (kept from the start model)"], rows, numeric=[1, 2, 3])
                 if rows else "<p>No batch was fitted in the last run (all were done).</p>\n")
    refs = fit.get("references")
    if isinstance(refs, dict):
        used = [r for r in refs.get("residuals") or [] if isinstance(r, dict)]
        parts.append(f"<p>Level fixed by {len(used)} ground reference(s): σ "
                     f"{_fmt(refs.get('sigma_c'), '.2f', ' °C')}.</p>\n")
        parts.append(_table(
            ["line", "frame", "map °C", "reference (apparent) °C", "level error °C", "σ °C",
             "used"],
            [[_e(r.get("row")), _e(r.get("frame")), _fmt(r.get("map_c")),
              _fmt(r.get("apparent_c")), _fmt(r.get("level_error_c")), _fmt(r.get("sigma_c")),
              _e("yes" if r.get("used") else "no: disagrees")] for r in used],
            numeric=[1, 2, 3, 4, 5]))
    return "".join(parts)


def _files_section(out: Path) -> str:
    def count(sub: str, pattern: str) -> int:
        return sum(1 for _ in (out / sub).glob(pattern)) if (out / sub).is_dir() else 0

    maps = count("temps", "frame_*.tiff")
    sigmas = count("temps", "frame_*_sigma.tiff")
    items = [
        f"<code>temps/frame_NNNNNN.tiff</code>: {maps - sigmas} temperature maps, float32 °C",
        f"<code>temps/frame_NNNNNN_sigma.tiff</code>: {sigmas} σ maps, float32 °C (1σ)",
        f"<code>previews/</code>: {count('previews', 'frame_*.png')} previews (PNG)",
        "<code>log.csv</code>, <code>log.jsonl</code>: every group (FPA, registration, "
        "warnings, errors)",
        "<code>summary.json</code>: options, counts, σ statistics, timings",
    ]
    if (out / "mosaic").is_dir():
        items.append("<code>mosaic/</code>: " + _e(", ".join(
            sorted(p.name for p in (out / "mosaic").iterdir() if p.is_file()))))
    return (f"<h2>Files</h2>\n<p>In <code>{_e(out.resolve())}</code>:</p>\n<ul>"
            + "".join(f"<li>{i}</li>" for i in items) + "</ul>\n")


_HOW_TO_READ = (
    '<p class="note">How to read σ: it is the standard uncertainty (1σ) of each temperature. '
    "Where the method's σ model holds, about 68 % of pixels lie within ±σ of the true "
    "temperature and 95 % within ±2σ; it is measured on held-out cameras and scenes, not "
    "guaranteed (a camera or scene unlike those can err more). Warnings and --force mark maps "
    "that were not validated.</p>\n")


def _page(out: Path, summary: dict[str, Any], entries: list[dict[str, Any]], *,
          max_rows: int, previews: int) -> str:
    rows = _map_stats(out, entries)
    body = (_header(out, summary, entries) + _problems_section(summary, entries)
            + _selfcal_section(summary) + _maps_section(out, previews, entries)
            + _ranges_section(rows, entries, max_rows)
            + _files_section(out))
    title = f"Flight report: {Path(str(summary.get('recording', '?'))).name}"
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f"<title>{_e(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n{body}"
            f'<p class="note">Written by thermocal report.</p>\n</body>\n</html>\n')
