"""The network's uncertainty: a 1σ map (°C) beside each estimate (numpy/scipy only).

Per pivot pixel ``p``::

    σ²(p) = floor² + (k·(T_p − t))² + exp(c0 + c1·ln(s_p + 0.05) + c2·ln(g_p + 0.05)
                                          + c3·ln(1 / n_p))

- ``s_p``: how much the views disagree, the standard deviation over the frames that see ``p`` of
  the calibrated, warped frames (°C): the fixed pattern the nominal calibration leaves,
  misregistration, noise;
- ``g_p``: the estimate's local gradient (°C/px, Gaussian derivative of σ = 1 px), where a
  registration error costs most;
- ``n_p``: how many frames see ``p``;
- ``floor``: what no view reveals, the unit's own level against the family's: fitted, and never
  below :data:`UNIT_FLOOR_MIN_C`;
- ``k·(T_p − t)``: the part of the unit's level that grows with the contrast between the
  estimate ``T_p`` and the FPA temperature ``t`` (°C; ``k`` per °C): a unit's responsivity
  differs from its family's by a share of the signal, and the signal is that contrast. On the
  preset's units the level's RMS grows from 0.47–0.66 °C where the scene is 0–40 °C colder
  than the FPA to 0.73–0.83 °C where it is 40–90 °C colder, in the units σ is fitted on and in two
  held-out sets of 200 units alike (``coverage.py``'s and another);
- for a network trained on one camera's chamber file, ``m(T)²`` more: what the camera model
  fitted on that file misses of the camera's level at scene temperature ``T`` (the estimate),
  measured on the file's frames at its blackbody set points, interpolated between them and
  growing linearly beyond them (:attr:`SigmaModel.misfit_c`).

The coefficients are fitted by minimising the Gaussian negative log-likelihood of the errors
(a proper scoring rule) on bursts of the validation units over training scenes, never on the
evaluation set, in two stages where the bursts are of a population of units: the level's
(``floor``, ``k``) on the bursts' mean errors, one draw per unit, against their mean contrast
(the pixels of a burst share their unit's level: pooled as if independent, they would count
one unit thousands of times); then ``c0 … c3`` on the pixels' errors, the level's variance
held. The coefficients are stored in a JSON file beside the weights (``NAME.sigma.json``) with the
SHA-256 of the weights they were fitted for. Outside the network's domain (``--force``) σ gains
:attr:`SigmaModel.outside_c` in quadrature.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.ndimage import gaussian_gradient_magnitude
from scipy.optimize import minimize

from thermocal.errors import FileFormatError, InvalidInputError
from thermocal.estimation.base import view_spread
from thermocal.io.atomic import atomic_path

__all__ = ["MAX_CONTRAST_PER_C", "OUTSIDE_SIGMA_C", "UNIT_FLOOR_MIN_C", "SigmaModel",
           "features", "fit_sigma_model", "level_variance", "sidecar_path"]

#: The smallest σ of a calibration-free estimate, °C: the unit's own scalars (gain, offset, FPA
#: coefficients) alone leave 0.34 °C mean absolute error on the most typical unit of the
#: preset (``benchmarks/unit_spread.py``: 0.34–0.69 °C over 200 units), σ = MAE·√(π/2).
UNIT_FLOOR_MIN_C = 0.34 * math.sqrt(math.pi / 2)

#: The largest contrast term a σ model may hold, °C of σ per °C between estimate and FPA.
MAX_CONTRAST_PER_C = 0.2

#: σ added in quadrature to an estimate outside the network's domain (``--force``), °C: the
#: scale of the errors of the tau2-trained network on bursts of the ``boson`` family (1.1–11.4
#: °C per burst, 4.2 on average; benchmarks/coverage.py, where this σ covers 74.5 % / 94.8 % of
#: their pixels at 1σ / 2σ). Another family may err more; that is why it is refused.
OUTSIDE_SIGMA_C = 6.0

_FORMAT = "thermocal-sigma-model"
_EPS = 0.05


def features(warped: np.ndarray, valid: np.ndarray, temperature_c: np.ndarray
             ) -> np.ndarray:
    """The three features of each pivot pixel, ``(3, H, W)`` float64: ``ln(s + 0.05)``,
    ``ln(g + 0.05)``, ``ln(1 / n)`` (see the module docstring); ``warped`` ``(N, H, W)`` °C and
    ``valid`` ``(N, H, W)`` as the pipeline gives them."""
    spread, n = view_spread(warped, valid)
    grad = gaussian_gradient_magnitude(np.asarray(temperature_c, np.float64), 1.0,
                                       mode="nearest")
    return np.stack([np.log(spread + _EPS), np.log(grad + _EPS), -np.log(n)])


def level_variance(floor_c: float, contrast_per_c: float | None, contrast_c: Any) -> np.ndarray:
    """The variance of the unit's level, °C², ``floor_c² + (contrast_per_c · contrast_c)²``
    (float64, the shape of ``contrast_c``: the estimate less the FPA temperature, °C;
    ``contrast_per_c`` None: no contrast term). The one formula the fit holds, :class:`SigmaModel`
    states and the level benchmark checks."""
    x = np.asarray(contrast_c, np.float64)
    if contrast_per_c is None:
        return np.full_like(x, floor_c**2)
    return floor_c**2 + (contrast_per_c * x) ** 2


@dataclass(frozen=True)
class SigmaModel:
    """A fitted σ model of one weights file (see the module docstring).

    Attributes
    ----------
    floor_c : float
        σ of the unit's own level where the scene is at the FPA temperature (no contrast), °C
        (>= :data:`UNIT_FLOOR_MIN_C`).
    coef : (4,) tuple of float
        ``c0 … c3``.
    weights_sha256 : str or None
        The content SHA-256 of the weights it was fitted for.
    outside_c : float
        σ added in quadrature outside the domain, °C.
    fitted_on : dict
        What it was fitted on (units, scenes, bursts, pixels, the NLL).
    misfit_c : ((K,) tuple, (K,) tuple) or None
        Scene temperatures (°C, increasing) and the camera model's level misfit there (°C RMS):
        a network trained on a chamber file's camera model (see the module docstring).
    contrast_per_c : float or None
        ``k``: the level's σ per °C of contrast between the estimate and the FPA temperature
        (0 to :data:`MAX_CONTRAST_PER_C`); None for a model fitted without it.
    """

    floor_c: float
    coef: tuple[float, float, float, float]
    weights_sha256: str | None = None
    outside_c: float = OUTSIDE_SIGMA_C
    fitted_on: dict[str, Any] = field(default_factory=dict)
    misfit_c: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    contrast_per_c: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.floor_c) and UNIT_FLOOR_MIN_C - 1e-9 <= self.floor_c <= 10.0
                and len(self.coef) == 4 and all(math.isfinite(c) and abs(c) < 50 for c in self.coef)
                and math.isfinite(self.outside_c) and 0.0 <= self.outside_c <= 100.0):
            raise InvalidInputError(
                f"σ model: floor {self.floor_c!r:.12} °C (>= {UNIT_FLOOR_MIN_C:.2f}), "
                f"coefficients {self.coef!r:.60} or outside σ {self.outside_c!r:.12} out of range"
            )
        k = self.contrast_per_c
        if k is not None:
            if isinstance(k, (int, float)) and not isinstance(k, bool):
                object.__setattr__(self, "contrast_per_c", k := float(k))  # JSON, the digest
            if not (isinstance(k, float) and 0.0 <= k <= MAX_CONTRAST_PER_C):
                raise InvalidInputError(f"σ model: contrast term {k!r:.12} per °C is not a "
                                        f"number of 0-{MAX_CONTRAST_PER_C}")
        if self.misfit_c is not None:
            try:  # stored as tuples of floats, whatever it was given as (JSON, the digest)
                t, m = (np.asarray(v, np.float64) for v in self.misfit_c)
                object.__setattr__(self, "misfit_c", (tuple(t.tolist()), tuple(m.tolist())))
            except (TypeError, ValueError):
                t = m = np.zeros(0)
            if not (t.ndim == 1 and t.shape == m.shape and t.size >= 2
                    and np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)
                    and np.all(np.isfinite(m)) and np.all((m >= 0) & (m <= 10))):
                raise InvalidInputError(
                    f"σ model: misfit {self.misfit_c!r:.80} is not increasing temperatures and "
                    "their misfits of 0-10 °C")

    def sigma_of(self, feats: np.ndarray, *, outside: bool = False,
                 temperature_c: np.ndarray | None = None, fpa_c: float | None = None
                 ) -> np.ndarray:
        """σ (°C, ``(H, W)`` float32) from :func:`features`; with ``outside``, inflated; with
        :attr:`misfit_c`, the misfit at ``temperature_c`` (the estimate, °C) added; with
        :attr:`contrast_per_c`, the level's part that grows with ``temperature_c − fpa_c``."""
        c = np.asarray(self.coef)
        log_var = c[0] + np.tensordot(c[1:], feats, axes=1)
        var = self._level_variance(temperature_c, fpa_c) + np.exp(np.minimum(log_var, 10.0))
        if self.misfit_c is not None:
            if temperature_c is None:
                raise InvalidInputError("σ model: its misfit needs the estimate's temperature")
            var = var + self.misfit_at(temperature_c) ** 2
        if outside:
            var = var + self.outside_c**2
        return np.sqrt(var).astype(np.float32)

    def level_sigma(self, temperature_c: Any = None, fpa_c: float | None = None) -> np.ndarray:
        """σ of the unit's level (°C, float64, the shape of ``temperature_c``; a scalar without
        a contrast term and without ``temperature_c``): :func:`level_variance` at the estimate
        ``temperature_c`` less the FPA temperature ``fpa_c`` (°C), what no view reveals."""
        return np.sqrt(self._level_variance(temperature_c, fpa_c))

    def _level_variance(self, temperature_c: Any, fpa_c: float | None) -> np.ndarray:
        """:func:`level_variance` of this model at ``temperature_c`` less ``fpa_c``."""
        if self.contrast_per_c is None:  # no contrast term: the shape alone counts
            return level_variance(self.floor_c, None, 0.0 if temperature_c is None
                                  else temperature_c)
        if temperature_c is None or fpa_c is None:
            raise InvalidInputError("σ model: its contrast term needs the estimate's "
                                    "temperature and the FPA temperature")
        return level_variance(self.floor_c, self.contrast_per_c,
                              np.asarray(temperature_c, np.float64) - float(fpa_c))

    def misfit_at(self, temperature_c: np.ndarray) -> np.ndarray:
        """The camera model's level misfit (°C) at scene temperatures ``temperature_c``: linear
        between the set points of :attr:`misfit_c`, and beyond them growing along the end
        segment's slope, never below the end's value (0 without a misfit)."""
        x = np.asarray(temperature_c, np.float64)
        if self.misfit_c is None:
            return np.zeros_like(x)
        t, m = (np.asarray(v, np.float64) for v in self.misfit_c)
        lo = max((m[0] - m[1]) / (t[1] - t[0]), 0.0)  # growth per °C below the coldest
        hi = max((m[-1] - m[-2]) / (t[-1] - t[-2]), 0.0)  # and above the hottest
        out = np.interp(x, t, m)
        with np.errstate(invalid="ignore"):  # NaN stays NaN
            if lo > 0:
                out = out + lo * np.maximum(t[0] - x, 0)
            if hi > 0:
                out = out + hi * np.maximum(x - t[-1], 0)
        return out

    def sigma(self, warped: np.ndarray, valid: np.ndarray, temperature_c: np.ndarray, *,
              outside: bool = False, fpa_c: float | None = None) -> np.ndarray:
        """σ (°C, ``(H, W)`` float32) of an estimate ``temperature_c`` from its burst, whose
        FPA temperature is ``fpa_c`` (°C)."""
        return self.sigma_of(features(warped, valid, temperature_c), outside=outside,
                             temperature_c=temperature_c, fpa_c=fpa_c)

    def _content(self) -> dict[str, Any]:
        """Its fields, without a misfit or contrast term it has not (files from before them
        keep their SHA-256)."""
        d = asdict(self)
        for key in ("misfit_c", "contrast_per_c"):
            if d[key] is None:
                del d[key]
        return d

    def digest(self) -> str:
        """SHA-256 (hex) of its content (the canonical JSON of its fields)."""
        text = json.dumps(self._content(), sort_keys=True, allow_nan=False)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write it as JSON (atomically), with the SHA-256 of its content."""
        # version 2: with a contrast term, which a reader of version 1 would not apply
        version = 1 if self.contrast_per_c is None else 2
        text = json.dumps({"format": _FORMAT, "version": version, **self._content(),
                           "sha256": self.digest()}, indent=1, sort_keys=True)
        with atomic_path(Path(path)) as tmp:
            Path(tmp).write_text(text + "\n", encoding="utf-8")
        return Path(path)

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, weights_sha256: str | None) -> SigmaModel:
        """Read a σ model; refused unless it was fitted for the weights of ``weights_sha256``.

        Raises
        ------
        FileFormatError
            Not a σ model file, damaged (its SHA-256), or fitted for other weights.
        """
        p = Path(path)
        try:
            d = json.loads(p.read_text(encoding="utf-8"))
            if not isinstance(d, dict) or d.pop("format", None) != _FORMAT:
                raise ValueError("not a thermocal σ model")
            version = d.pop("version", None)
            if version not in (1, 2):
                raise ValueError(f"format version {version!r:.20}, this thermocal reads 1 and 2")
            if (version == 2) != (d.get("contrast_per_c") is not None):
                raise ValueError(f"version {version} with{'out' if version == 2 else ''} a "
                                 "contrast term")
            stored = d.pop("sha256", None)
            misfit, k = d.get("misfit_c"), d.get("contrast_per_c")
            model = cls(float(d["floor_c"]), tuple(float(c) for c in d["coef"]),
                        d.get("weights_sha256"), float(d.get("outside_c", OUTSIDE_SIGMA_C)),
                        dict(d.get("fitted_on") or {}),
                        None if misfit is None else tuple(tuple(float(v) for v in part)
                                                          for part in misfit),
                        None if k is None else float(k))
            if stored != model.digest():
                raise ValueError("its content does not match its SHA-256")
        except (OSError, ValueError, KeyError, TypeError, InvalidInputError) as exc:
            raise FileFormatError(f"{p}: not a usable σ model ({exc}); fit it again: "
                                  "`python -m thermocal.evaluation.sigma_fit WEIGHTS.pt`"
                                  ) from None
        if weights_sha256 is not None and model.weights_sha256 != weights_sha256:
            raise FileFormatError(f"{p}: fitted for other weights than the ones beside it; fit "
                                  "it again: `python -m thermocal.evaluation.sigma_fit WEIGHTS.pt`")
        return model


def sidecar_path(weights: str | os.PathLike[str]) -> Path:
    """Where a weights file's σ model lives: ``NAME.sigma.json`` beside ``NAME.pt``."""
    p = Path(weights)
    return p.with_name(p.stem + ".sigma.json")


def fit_sigma_model(errors: np.ndarray, feats: np.ndarray, *, weights_sha256: str | None,
                    fitted_on: dict[str, Any] | None = None, bursts: np.ndarray | None = None,
                    contrast_c: np.ndarray | None = None) -> SigmaModel:
    """Fit σ by minimising the mean Gaussian negative log-likelihood of ``errors``.

    Parameters
    ----------
    errors : (M,) array
        Estimate − truth of validation pixels, °C.
    feats : (3, M) array
        Their :func:`features`.
    weights_sha256, fitted_on
        Recorded in the model.
    bursts, contrast_c : (M,) arrays, optional
        The burst of each pixel (labels), and its estimate less the burst's FPA temperature,
        °C: given both, bursts of a population of units, one each, and the fit is in two stages
        (see the module docstring) with the contrast term; without, one stage, no contrast term
        (bursts of one camera).
    """
    e = np.asarray(errors, np.float64)
    f = np.asarray(feats, np.float64)
    if e.ndim != 1 or f.shape != (3, e.size) or e.size < 100 or not np.all(np.isfinite(e)):
        raise InvalidInputError("fit_sigma_model: need >= 100 finite errors and (3, M) features")
    if (bursts is None) != (contrast_c is None):
        raise InvalidInputError("fit_sigma_model: give both bursts and contrast_c, or neither")
    level = None
    if bursts is not None:
        labels, x = np.asarray(bursts), np.asarray(contrast_c, np.float64)
        if labels.shape != e.shape or x.shape != e.shape or not np.all(np.isfinite(x)):
            raise InvalidInputError("fit_sigma_model: bursts and contrast_c must be finite, "
                                    f"one per error ({e.size})")
        level = _fit_level(e, x, labels)
    e2 = e**2
    opts = {"maxiter": 4000, "xatol": 1e-4, "fatol": 1e-7}
    if level is None:
        def nll(theta: np.ndarray) -> float:
            floor2 = UNIT_FLOOR_MIN_C**2 + math.exp(theta[0])
            var = floor2 + np.exp(np.minimum(theta[1] + theta[2:] @ f, 10.0))
            return float(np.mean(np.log(var) + e2 / var))

        start = np.array([math.log(0.05), math.log(max(float(e2.mean()), 1e-4)), 0.0, 0.0, 0.0])
        best = minimize(nll, start, method="Nelder-Mead", options=opts)
        floor, k, coef = math.sqrt(UNIT_FLOOR_MIN_C**2 + math.exp(best.x[0])), None, best.x[1:]
    else:
        floor, k = level
        held = level_variance(floor, k, x)  # the level's variance, held in the second stage

        def nll(theta: np.ndarray) -> float:
            var = held + np.exp(np.minimum(theta[0] + theta[1:] @ f, 10.0))
            return float(np.mean(np.log(var) + e2 / var))

        start = np.array([math.log(max(float(e2.mean()) - float(held.mean()), 1e-4)),
                          0.0, 0.0, 0.0])
        best = minimize(nll, start, method="Nelder-Mead", options=opts)
        coef = best.x
    info = dict(fitted_on or {}) | {"pixels": int(e.size), "mean_nll": float(best.fun)}
    return SigmaModel(floor, tuple(float(c) for c in coef), weights_sha256, fitted_on=info,
                      contrast_per_c=k)


def _fit_level(errors: np.ndarray, contrast_c: np.ndarray, bursts: np.ndarray
               ) -> tuple[float, float]:
    """The level's ``(floor, k)`` (°C, per °C): the Gaussian NLL of the bursts' mean errors,
    variance ``floor² + (k · mean contrast)²``, floor never below :data:`UNIT_FLOOR_MIN_C`
    and ``k`` at most :data:`MAX_CONTRAST_PER_C`."""
    _, idx = np.unique(bursts, return_inverse=True)
    count = np.bincount(idx)
    if count.size < 10:
        raise InvalidInputError(f"fit_sigma_model: {count.size} bursts cannot show how the "
                                "units' level spreads: need >= 10")
    lev = np.bincount(idx, errors) / count
    c2 = (np.bincount(idx, contrast_c) / count) ** 2

    def nll(theta: np.ndarray) -> float:
        var = UNIT_FLOOR_MIN_C**2 + math.exp(theta[0]) + math.exp(theta[1]) * c2
        return float(np.sum(np.log(var) + lev**2 / var))

    start = np.array([math.log(max(float(np.mean(lev**2)) - UNIT_FLOOR_MIN_C**2, 1e-3)),
                      math.log(1e-5)])
    opts = {"maxiter": 4000, "xatol": 1e-6, "fatol": 1e-9}
    best = minimize(nll, start, method="Nelder-Mead", options=opts)
    k = math.sqrt(math.exp(best.x[1]))
    if k > MAX_CONTRAST_PER_C:  # held at the bound: the floor refitted with it
        k = MAX_CONTRAST_PER_C
        best = minimize(lambda t: nll(np.array([t[0], 2 * math.log(k)])), best.x[:1],
                        method="Nelder-Mead", options=opts)
    return math.sqrt(UNIT_FLOOR_MIN_C**2 + math.exp(best.x[0])), k
