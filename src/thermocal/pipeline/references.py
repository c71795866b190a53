"""Ground references: targets of known temperature that fix a unit's level.

No motion of the camera over an unknown scene reveals the unit's own level against its
family's (0.34–0.69 °C over the units of the ``tau2`` preset); a target of known temperature in
a frame does: a water body measured with a thermometer, a reference panel. ``--reference
REF.csv`` names them, one row each::

    frame,x,y,radius_px,temperature_c[,emissivity][,reflected_c][,sigma_c]

``frame`` the frame's index in the recording (0-based), ``x, y`` the disc's centre in that
frame (px, 0 at the top left pixel's centre), ``radius_px`` its radius, ``temperature_c`` the
target's temperature (°C), ``emissivity`` (default 1), ``reflected_c`` the temperature of what
it reflects (°C; default the frame's median: the surroundings), ``sigma_c`` the reference's
standard uncertainty (°C; default :data:`DEFAULT_SIGMA_C`).

:func:`read_references` checks the file against the recording (one line naming the row and what
is wrong); :func:`level_from_references` combines the references into one level correction, in
band radiance, with its σ, and reports those that disagree with the others beyond their σ.
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.constants import ZERO_CELSIUS_K
from thermocal.errors import InvalidInputError
from thermocal.radiometry import BandRadiance

__all__ = ["COLUMNS", "DEFAULT_SIGMA_C", "LevelFix", "Reference", "level_from_references",
           "read_references"]

#: Required columns, in order.
COLUMNS = ("frame", "x", "y", "radius_px", "temperature_c")
#: Optional columns.
OPTIONAL = ("emissivity", "reflected_c", "sigma_c")
#: A reference's σ when the file gives none, °C (a contact thermometer in water).
DEFAULT_SIGMA_C = 0.1
#: References this many σ from the combined level are reported as disagreeing.
DISAGREE_SIGMAS = 3.0


def _check_in_tables(t_c: float, column: str, where: str) -> None:
    """A reference's temperature (°C) inside the radiance tables' range
    (:class:`~thermocal.radiometry.BandRadiance`'s default ``t_min_k``…``t_max_k``); one line
    naming the row otherwise."""
    from thermocal.radiometry import BandRadiance

    lo = BandRadiance.t_min_k - ZERO_CELSIUS_K
    hi = BandRadiance.t_max_k - ZERO_CELSIUS_K
    if not lo <= t_c <= hi:
        raise InvalidInputError(f"{where}: {column} {t_c:g} °C is outside the {lo:.0f}…{hi:.0f} "
                                "°C the radiance tables cover")


@dataclass(frozen=True)
class Reference:
    """One row of a reference file (see the module)."""

    row: int
    frame: int
    x: float
    y: float
    radius_px: float
    temperature_c: float
    emissivity: float = 1.0
    reflected_c: float | None = None
    sigma_c: float = DEFAULT_SIGMA_C

    def disc(self, shape: tuple[int, int]) -> np.ndarray:
        """The disc's pixels, ``(H, W)`` bool."""
        yy, xx = np.mgrid[: shape[0], : shape[1]]
        return (xx - self.x) ** 2 + (yy - self.y) ** 2 <= self.radius_px**2


def _number(value: str, what: str, where: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: {what} {value!r} is not a number") from None
    if not math.isfinite(v):
        raise InvalidInputError(f"{where}: {what} is {value}, not a finite number")
    return v


def read_references(path: str | os.PathLike[str], *, n_frames: int,
                    frame_shape: tuple[int, int]) -> tuple[Reference, ...]:
    """The references of ``path`` checked against a recording of ``n_frames`` frames of
    ``frame_shape`` ``(H, W)``.

    Raises
    ------
    InvalidInputError
        A file that cannot be read, missing columns, no rows, a frame that does not exist, a
        disc not wholly inside the frame, a temperature, emissivity, radius or σ that is not a
        finite number in range — one line naming the row.
    """
    p = Path(path)
    try:
        with open(p, newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            fields = [(c or "").strip() for c in reader.fieldnames or []]
            rows = list(reader)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InvalidInputError(f"{p}: cannot read the reference file ({exc})") from None
    missing = [c for c in COLUMNS if c not in fields]
    if missing:
        raise InvalidInputError(
            f"{p}: missing column(s) {', '.join(missing)}; expected "
            f"{','.join(COLUMNS)}[,{'][,'.join(OPTIONAL)}]")
    if not rows:
        raise InvalidInputError(f"{p}: no references (a header and no rows)")
    h, w = frame_shape
    refs = []
    for i, raw in enumerate(rows, start=2):
        row = {(k or "").strip(): (v or "").strip() for k, v in raw.items()}
        where = f"{p} line {i}"
        frame_v = _number(row["frame"], "frame", where)
        if frame_v != int(frame_v) or not 0 <= frame_v < n_frames:
            raise InvalidInputError(
                f"{where}: frame {row['frame']} does not exist (the recording has {n_frames} "
                f"frames, 0-{n_frames - 1})")
        x, y = _number(row["x"], "x", where), _number(row["y"], "y", where)
        r = _number(row["radius_px"], "radius_px", where)
        if r <= 0:
            raise InvalidInputError(f"{where}: radius_px must be > 0, not {r:g}")
        if x - r < -0.5 or y - r < -0.5 or x + r > w - 0.5 or y + r > h - 0.5:
            raise InvalidInputError(
                f"{where}: the disc at ({x:g}, {y:g}), radius {r:g} px, is not wholly inside the "
                f"{w}x{h} frame")
        t = _number(row["temperature_c"], "temperature_c", where)
        if t <= -ZERO_CELSIUS_K:
            raise InvalidInputError(f"{where}: temperature_c {t:g} °C is at or below absolute zero")
        _check_in_tables(t, "temperature_c", where)
        eps = _number(row["emissivity"], "emissivity", where) if row.get("emissivity") else 1.0
        if not 0 < eps <= 1:
            raise InvalidInputError(f"{where}: emissivity must be in (0, 1], not {eps:g}")
        refl = (_number(row["reflected_c"], "reflected_c", where) if row.get("reflected_c")
                else None)
        if refl is not None:
            _check_in_tables(refl, "reflected_c", where)
        sigma = (_number(row["sigma_c"], "sigma_c", where) if row.get("sigma_c")
                 else DEFAULT_SIGMA_C)
        if sigma <= 0:
            raise InvalidInputError(f"{where}: sigma_c must be > 0, not {sigma:g}")
        refs.append(Reference(i, int(frame_v), x, y, r, t, eps, refl, sigma))
    return tuple(refs)


@dataclass(frozen=True)
class LevelFix:
    """The references' level correction.

    Attributes
    ----------
    offset : float
        Band radiance (W·m⁻²·sr⁻¹) to subtract from every corrected frame.
    sigma_c : float
        Its standard uncertainty, °C (at the references' mean temperature).
    residuals : list of dict
        Per reference: its row, frame, the map's disc temperature before the fix (°C), the
        target's apparent temperature (°C), what it says of the level (°C), its σ (°C) and
        whether it disagrees with the others.
    disagreeing : list of int
        The rows that disagree with the others beyond :data:`DISAGREE_SIGMAS` σ (from their
        weighted median): left out when others agree, all used (σ widened by their scatter)
        when none does.
    """

    offset: float
    sigma_c: float
    residuals: list[dict[str, Any]]
    disagreeing: list[int]

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def level_from_references(references: tuple[Reference, ...], maps_c: dict[int, np.ndarray],
                          band: BandRadiance, *, pattern_sigma_c: float = 0.0) -> LevelFix:
    """One level correction from ``references`` and the temperature map (°C, ``(H, W)``, the
    level not yet fixed) of each reference's frame in ``maps_c``.

    Each reference says the level is off by its disc's mean band radiance less the target's
    apparent radiance ``ε·L(T) + (1 − ε)·L(T_reflected)``; the combined offset is the
    inverse-variance mean (σ²: the reference's own, the disc mean's standard error and
    ``pattern_sigma_c``) of those that agree (:attr:`LevelFix.disagreeing`), its σ widened by
    the Birge ratio.
    """
    offsets, variances, rows = [], [], []
    for ref in references:
        m = np.asarray(maps_c[ref.frame], np.float64)
        disc = ref.disc(m.shape)
        radiance = band.radiance(m[disc] + ZERO_CELSIUS_K)
        observed = float(radiance.mean())
        t_refl = float(np.median(m)) if ref.reflected_c is None else ref.reflected_c
        target = ref.emissivity * float(band.radiance(ref.temperature_c + ZERO_CELSIUS_K)) + (
            1 - ref.emissivity) * float(band.radiance(t_refl + ZERO_CELSIUS_K))
        t_target = float(band.temperature(np.float64(target))) - ZERO_CELSIUS_K
        slope = float(band.radiance(t_target + ZERO_CELSIUS_K + 0.5)
                      - band.radiance(t_target + ZERO_CELSIUS_K - 0.5))  # per °C
        se_c = float(np.std(m[disc]) / math.sqrt(disc.sum()))
        sigma_c = math.sqrt(ref.sigma_c**2 + se_c**2 + pattern_sigma_c**2)
        offsets.append(observed - target)
        variances.append((sigma_c * slope) ** 2)
        rows.append({"row": ref.row, "frame": ref.frame,
                     "map_c": float(band.temperature(np.float64(observed))) - ZERO_CELSIUS_K,
                     "apparent_c": t_target, "level_error_c": (observed - target) / slope,
                     "sigma_c": sigma_c, "slope": slope})
    o, sd = np.asarray(offsets), np.sqrt(np.asarray(variances))
    # two references agree within DISAGREE_SIGMAS of their combined σ; those that agree with the
    # best-supported one are kept when they are more than half of them (one bad reference cannot
    # drag the others with it); otherwise there is no consensus and all are used
    agree = np.abs(o[:, None] - o[None, :]) <= DISAGREE_SIGMAS * np.hypot(sd[:, None], sd[None])
    support = agree.sum(axis=1)
    best = int(np.argmax(support))
    if support[best] > len(o) / 2:
        keep = agree[best]
        off = ~keep
    else:
        keep = np.ones(len(o), bool)
        off = ~agree.all(axis=1)
    w = 1.0 / sd[keep] ** 2
    offset = float((w * o[keep]).sum() / w.sum())
    sigma = math.sqrt(1.0 / w.sum())
    if keep.sum() > 1:  # the Birge ratio: the kept references' scatter beyond their σ
        chi2 = float((w * (o[keep] - offset) ** 2).sum())
        sigma *= max(1.0, math.sqrt(chi2 / (keep.sum() - 1)))
    slope_mean = float(np.mean([r["slope"] for r in rows]))
    disagreeing = [r["row"] for r, bad in zip(rows, off, strict=True) if bad]
    for r, bad, kept in zip(rows, off, keep, strict=True):
        r["disagrees"], r["used"] = bool(bad), bool(kept)
        del r["slope"]
    return LevelFix(offset, sigma / slope_mean, rows, disagreeing)
