"""The reference estimates the network is compared with (numpy only): a camera model inverted
exactly (the family floor), the calibration-free baselines, the classical pipeline given the
network's camera model, and the unit's own two-point calibration."""

from __future__ import annotations

import numpy as np

from thermocal.camera.presets import make_camera
from thermocal.constants import ZERO_CELSIUS_K
from thermocal.estimation.calibrated import naive_mean
from thermocal.evaluation.heldout import two_point_of
from thermocal.evaluation.scoring import SPLIT_SIGMA_PX, masked_smooth, scores
from thermocal.nn.inputs import calibrate_frames, nominal_camera
from thermocal.nuc import correct_nonuniformity
from thermocal.radiometry import BandRadiance

__all__ = ["CHAMBER_ROW", "FAMILY_ROW", "HYBRID_CHAMBER_ROW", "HYBRID_ROW", "ExactModel",
           "fuse", "nuc_global_fit", "reference_scores"]


class ExactModel:
    """A camera model inverted exactly, for the eq. 9 mean (``naive_mean``) through it.

    :meth:`family` is the average of the training units' models: a perfect calibration-free
    calibration of the camera *family*; on a held-out unit its error is the floor of any
    calibration-free method (what the unit differs from the family: offset, gain, radial
    strengths, averaged over the burst by eq. 9). With a model fitted on unit A's chamber file
    (``--chamber``) it is the floor of a network trained from that file.
    """

    def __init__(self, model) -> None:
        self.model = model

    @classmethod
    def family(cls, units) -> ExactModel:
        """The average of ``units`` of the ``tau2`` preset at 336×256."""
        return cls(nominal_camera([make_camera("tau2", unit=u, size=(336, 256)) for u in units]))

    @property
    def shape(self):
        """Frame shape ``(H, W)``."""
        return self.model.shape

    def apply(self, frames, *, fpa_c=None, time_s=None):
        """Raw frames ``(N, H, W)`` → °C ``(N, H, W)`` through the model's exact inverse
        (``time_s``, as every calibration takes it, unused: the model has no rate term)."""
        return calibrate_frames(self.model, frames, fpa_c)  # the camera settled, as in training


FAMILY_ROW = "(floor) exact model of the average training unit (eq. 9 mean)"


CHAMBER_ROW = "(floor) unit A's chamber model, exact (eq. 9 mean)"


#: The classical pipeline given the camera model the network was trained from (not
#: calibration-free, as the family row): the eq. 9 mean through that model, low-passed by a
#: Gaussian of SPLIT_SIGMA_PX, plus the scene-based NUC baseline's high-pass (:func:`fuse`).
HYBRID_ROW = ("(classical, the network's camera model) the exact average training unit's eq. 9 "
              f"mean, low-pass σ = {SPLIT_SIGMA_PX:.0f} px, + hardie2000 NUC's high-pass")


HYBRID_CHAMBER_ROW = ("(classical, the network's camera model) unit A's chamber model's eq. 9 "
                      f"mean, low-pass σ = {SPLIT_SIGMA_PX:.0f} px, + hardie2000 NUC's high-pass")


def fuse(low: np.ndarray, high: np.ndarray, mask: np.ndarray,
         sigma: float = SPLIT_SIGMA_PX) -> np.ndarray:
    """``low``'s Gaussian low-pass (σ = ``sigma`` px, over ``mask``) plus ``high``'s remainder:
    two ``(H, W)`` estimates, °C, joined across spatial frequencies."""
    return masked_smooth(low, mask, sigma) + high - masked_smooth(high, mask, sigma)


def nuc_global_fit(frames: np.ndarray, homographies: np.ndarray, pivot: int, cal) -> np.ndarray:
    """The scene-based NUC baseline: hardie2000 on the registered burst ``frames (N, H, W)``
    counts, its pivot frame turned into °C by a global fit (``cal``'s array-mean gain and
    offset, a two-point calibration), ``(H, W)``."""
    nuc = correct_nonuniformity(frames, method="hardie2000", homographies=homographies)[pivot]
    g, o = float(cal.gain.mean()), float(cal.offset.mean())
    band = BandRadiance()
    lo, hi = band.radiance_range
    return band.temperature(np.clip((nuc - o) / g, lo, hi)) - ZERO_CELSIUS_K


def reference_scores(b: dict, frames: np.ndarray, references: dict[str, ExactModel],
                     other_cal=None) -> dict[str, dict]:
    """Scores of the reference estimates of the held-out burst ``b`` from ``frames`` (its
    frames, stuck pixels replaced), in table order: an eq. 9 mean through each of
    ``references``; with ``other_cal`` (the other unit's two-point calibration) also the
    calibration-free baselines, the classical pipeline given the model the network was trained
    from (:data:`HYBRID_ROW`, or :data:`HYBRID_CHAMBER_ROW` where ``references`` hold
    :data:`CHAMBER_ROW`) and the unit's own two-point reference."""
    out: dict[str, dict] = {}
    piv, hs = b["pivot"], b["hs"]
    through = {}  # each reference's eq. 9 mean, °C
    for name, ref in references.items():
        through[name] = naive_mean(frames, ref, fpa_c=b["fpa_read"], homographies=hs,
                                   pivot=piv, fill_defects=False).temperature_c
        out[name] = scores(through[name], b)
    if other_cal is None:
        return out
    out["two-point, other unit, FPA 30 °C (pivot frame)"] = scores(
        other_cal.apply(frames[piv : piv + 1])[0], b)
    m9 = naive_mean(frames, other_cal, homographies=hs, pivot=piv, fill_defects=False)
    out["two-point, other unit, FPA 30 °C (eq. 9 mean)"] = scores(m9.temperature_c, b)
    t_nuc = nuc_global_fit(frames, hs, piv, other_cal)
    out["hardie2000 NUC + global fit (other unit)"] = scores(t_nuc, b)
    # what the network was trained from: unit A's chamber model if given, else the family
    prior, row = ((through[CHAMBER_ROW], HYBRID_CHAMBER_ROW) if CHAMBER_ROW in through
                  else (through[FAMILY_ROW], HYBRID_ROW))
    out[row] = scores(fuse(prior, t_nuc, b["mask"]), b)
    own = two_point_of(b["camera"], float(np.mean(b["fpa_true"])), float(np.mean(b["housing"])),
                       6)
    m9o = naive_mean(frames, own, homographies=hs, pivot=piv, fill_defects=False)
    out["(reference) own two-point at the burst FPA (eq. 9 mean)"] = scores(m9o.temperature_c, b)
    return out
