"""Fit a network's σ model (:mod:`thermocal.nn.uncertainty`) and write it beside its weights.

The errors it is fitted on are the network's on bursts of camera units of its own
(:data:`SIGMA_UNITS`: neither training, validation nor evaluation units; one per burst, so that
the spread of the units' own levels, the largest part of the error, is sampled as a population:
fitted on 33 bursts of 13 units, the floor came out 0.43 °C and σ covered 65 % of 200 other
units' errors within 1σ, on 220 bursts of 220 units 0.47 °C and 72 %) over the
training scenes (the real ones that are not held out, and procedural maps), flown and
registered as the evaluation set is. The evaluation units and scenes stay unseen, so that the
coverage measured on them (``benchmarks/coverage.py``) is honest.

A network trained on one camera's chamber file (``thermocal train --chamber``) is fitted on
bursts of the camera model fitted on that file instead (with a pixel pattern drawn for each, as
its training draws them), and σ takes in quadrature what that model misses of the camera's
level on the file's own frames at the scene's temperature (:func:`model_misfit` by blackbody
set point, growing beyond them: :meth:`~thermocal.nn.uncertainty.SigmaModel.misfit_at`);
checked on the cameras the files were simulated from (``benchmarks/chamber_sigma.py``).

Run: ``python -m thermocal.evaluation.sigma_fit WEIGHTS.pt [--chamber FILE] [--per-scene K]
[--out PATH]``.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from thermocal.burst import fill_stuck_pixels
from thermocal.errors import InvalidInputError, ThermocalError
from thermocal.estimation.base import PreparedBurst
from thermocal.estimation.pipeline import estimate
from thermocal.evaluation.heldout import eval_bursts
from thermocal.nn.data import training_real_scenes
from thermocal.nn.infer import NetworkEstimator
from thermocal.nn.uncertainty import SigmaModel, features, fit_sigma_model, sidecar_path
from thermocal.scenes.procedural import procedural_scene

__all__ = ["CHAMBER_PER_SCENE", "PER_SCENE", "SIGMA_UNITS", "fit_network_sigma", "main",
           "model_misfit", "scored_features", "validation_scenes"]

#: The camera units whose bursts the σ model is fitted on, one per burst.
SIGMA_UNITS: tuple[int, ...] = tuple(range(1000, 1400))

#: Validation bursts per scene.
PER_SCENE = 20

#: Validation bursts per scene of a camera model fitted on a chamber file (one camera: no
#: population of units to sample).
CHAMBER_PER_SCENE = 4

#: Chamber frames inverted to measure the fitted model's misfit (every k-th).
CHAMBER_STRIDE = 4

#: The low-pass (Gaussian σ, px) of :func:`model_misfit`'s spatial part.
LOW_PASS_PX = 6.0

#: Pixels drawn from each burst for the fit.
PIXELS_PER_BURST = 4000


def validation_scenes(n_procedural: int = 4) -> dict[str, np.ndarray]:
    """The scenes of the validation bursts: the training real scenes and ``n_procedural``
    procedural maps (seeded), °C."""
    scenes = training_real_scenes()
    kinds = ("farmland", "urban", "mixed")
    for i in range(n_procedural):
        rng = np.random.default_rng([2027, i])
        scenes[f"procedural:{i}"] = procedural_scene((512, 512), rng=rng, kind=kinds[i % 3])
    return scenes


class _Recording(NetworkEstimator):
    """The network, keeping each burst's σ features (no σ model, no domain check)."""

    def uncertainty(self, burst: PreparedBurst, temperature_c: np.ndarray, *, outside: bool
                    ) -> None:
        self.feats = features(burst.warped, burst.valid, temperature_c)
        self.fpa_c = burst.fpa_c
        return None


def scored_features(network: NetworkEstimator, bursts: list[dict]) -> list[tuple]:
    """Per burst of :func:`~thermocal.evaluation.heldout.eval_bursts`: ``(error, features,
    estimate, contrast)`` over its scored pixels (seen by at least half the frames): ``(M,)``
    °C, ``(3, M)``, the :class:`~thermocal.estimation.base.Estimate` and ``(M,)`` the estimate
    less the burst's FPA temperature as the pipeline gives it, °C."""
    rec = _Recording(network.model, network.norm)
    out = []
    for b in bursts:
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        est = estimate(frames, rec, fpa_c=b["fpa_read"], homographies=b["hs"],
                       pivot=b["pivot"], fill_defects=False)
        mask = b["mask"]
        out.append(((est.temperature_c - b["truth"])[mask], rec.feats[:, mask], est,
                    est.temperature_c[mask].astype(np.float64) - rec.fpa_c))
    return out


def model_misfit(chamber: Any, camera: Any = None, *,
                 stride: int = CHAMBER_STRIDE) -> dict[str, Any]:
    """What the camera model fitted on a chamber file misses of its own camera: the model
    inverted exactly (:func:`~thermocal.camera.model.invert`) on every ``stride``-th usable
    frame of the file (the blackbody settled), against the scene temperature it was fitted to
    (the blackbody's, its emissivity and reflected ambient taken in:
    :func:`~thermocal.calibration.dataset.prepare_chamber`).

    Returns the RMS error (°C) of the good pixels (``rms_c``), of their low-passed error
    (Gaussian of :data:`LOW_PASS_PX`, leaving out the pixel pattern a network is trained to
    remove: ``low_pass_rms_c``) and of the frames' mean error (``level_rms_c``, what no view of
    a burst reveals), the last also at each blackbody set point (``setpoints_c``: the set
    points' mean scene temperature, increasing; ``level_rms_by_setpoint_c``), and ``frames``.
    In-sample (the model was fitted on these frames): a lower bound of what it misses elsewhere.
    ``chamber``: a path, or the file already prepared
    (:class:`~thermocal.calibration.dataset.ChamberData`); ``camera``: the model fitted on it,
    if already fitted.
    """
    from scipy.ndimage import gaussian_filter

    from thermocal.calibration.dataset import prepare_chamber
    from thermocal.calibration.polynomial import camera_model_from_chamber
    from thermocal.camera.model import invert

    data = prepare_chamber(chamber)
    camera = camera_model_from_chamber(data, radial=True) if camera is None else camera
    idx = np.flatnonzero(data.usable)[::stride]
    err = (invert(camera, np.asarray(data.session.frames[idx]), data.fpa_c[idx])
           - data.scene_c[idx][:, None, None])
    good = ~camera.defects
    low = np.stack([gaussian_filter(e, LOW_PASS_PX) for e in err])[:, good]
    level = err[:, good].mean(axis=1)
    blackbody = np.round(data.session.blackbody_c[idx], 6)
    points = np.unique(blackbody)
    scene = np.array([data.scene_c[idx][blackbody == v].mean() for v in points])
    order = np.argsort(scene)
    rms = [float(np.sqrt(np.mean(level[blackbody == points[i]] ** 2))) for i in order]
    return {"frames": int(idx.size), "rms_c": float(np.sqrt(np.mean(err[:, good] ** 2))),
            "low_pass_rms_c": float(np.sqrt(np.mean(low**2))),
            "level_rms_c": float(np.sqrt(np.mean(level**2))),
            "setpoints_c": scene[order].tolist(), "level_rms_by_setpoint_c": rms}


def fit_network_sigma(weights: str | os.PathLike[str], *, per_scene: int | None = None,
                      seed: int = 0, chamber: str | os.PathLike[str] | None = None
                      ) -> SigmaModel:
    """The σ model of the network in ``weights`` (any variant), fitted on ``per_scene``
    validation bursts per scene, :data:`PIXELS_PER_BURST` pixels of each: each burst of its
    own unit of the preset (default :data:`PER_SCENE`), or, with ``chamber``, of the camera
    model fitted on that chamber file (as ``thermocal train --chamber`` fits it; default
    :data:`CHAMBER_PER_SCENE`).

    Raises
    ------
    InvalidInputError
        ``per_scene`` out of range, or weights trained on a chamber file's camera model without
        ``chamber`` (units of the preset are not that camera).
    """
    from thermocal.nn.store import load_model

    model, norm, content = load_model(weights)
    trained_on = (content.get("meta") or {}).get("chamber")
    if chamber is None and trained_on:
        raise InvalidInputError(
            f"{weights} was trained on the camera model of chamber file {trained_on}: its σ is "
            f"fitted on that camera's bursts: give --chamber {trained_on}")
    if chamber is not None and (not trained_on or Path(trained_on).name != Path(chamber).name):
        raise InvalidInputError(
            f"{weights} was trained from chamber file {trained_on}, not {chamber}: its σ is "
            f"fitted on bursts of that file's camera: give --chamber {trained_on}" if trained_on
            else f"{weights} was trained on the simulator's units, not on chamber file "
            f"{chamber}: its σ is fitted on bursts of units it never saw: leave --chamber out")
    network = NetworkEstimator(model, norm)
    scenes = validation_scenes()
    if chamber is None:
        per_scene = PER_SCENE if per_scene is None else per_scene
        if not 1 <= per_scene * len(scenes) <= len(SIGMA_UNITS):
            raise InvalidInputError(f"--per-scene {per_scene}: 1 to "
                                    f"{len(SIGMA_UNITS) // len(scenes)} (one unit per burst)")
        bursts = eval_bursts(model.config.n_frames, quick=False, units=SIGMA_UNITS,
                             scenes=scenes, per_scene=per_scene, unit_per_burst=True)
        on: dict = {"units": sorted({int(b["unit"]) for b in bursts})}
    else:
        from thermocal.calibration.dataset import prepare_chamber
        from thermocal.calibration.polynomial import camera_model_from_chamber

        per_scene = CHAMBER_PER_SCENE if per_scene is None else per_scene
        if not 1 <= per_scene <= 100:
            raise InvalidInputError(f"--per-scene {per_scene}: 1 to 100")
        data = prepare_chamber(chamber)  # once, for the model and its misfit
        camera = camera_model_from_chamber(data, radial=True)
        misfit = model_misfit(data, camera)
        if len(misfit["setpoints_c"]) < 2:
            raise InvalidInputError(f"{chamber}: one blackbody set point cannot show how the "
                                    "fitted camera model errs with the scene's temperature")
        bursts = eval_bursts(model.config.n_frames, quick=False, scenes=scenes,
                             per_scene=per_scene, camera=camera)
        on = {"chamber": str(chamber), "model_level_misfit_c": misfit["level_rms_c"]}
    rng = np.random.default_rng(seed)
    errors, feats, labels, contrast = [], [], [], []
    for i, (err, f, _, x) in enumerate(scored_features(network, bursts)):
        pick = rng.choice(err.size, size=min(PIXELS_PER_BURST, err.size), replace=False)
        errors.append(err[pick])
        feats.append(f[:, pick])
        labels.append(np.full(pick.size, i))
        contrast.append(x[pick])
    fitted_on = {**on, "variant": model.config.variant, "scenes": sorted(scenes),
                 "bursts": len(bursts), "frames_per_burst": model.config.n_frames}
    # units of the preset, one per burst: the level in two stages, with its contrast term;
    # one camera (a chamber file's model): one stage, its level is the misfit's
    population = ({"bursts": np.concatenate(labels), "contrast_c": np.concatenate(contrast)}
                  if chamber is None else {})
    sigma = fit_sigma_model(np.concatenate(errors), np.concatenate(feats, axis=1),
                            weights_sha256=content["sha256"], fitted_on=fitted_on, **population)
    if chamber is None:
        return sigma
    # the bursts are of the fitted model: what it misses of the camera's level, no view shows
    # (without it, a boson unit's network erred 1.09 °C where σ said 0.70: 41 % within 1σ)
    return replace(sigma, misfit_c=(tuple(misfit["setpoints_c"]),
                                    tuple(misfit["level_rms_by_setpoint_c"])))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m thermocal.evaluation.sigma_fit",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("weights", type=Path)
    parser.add_argument("--per-scene", type=int, default=None,
                        help=f"Bursts per scene (default {PER_SCENE}, with --chamber "
                        f"{CHAMBER_PER_SCENE}).")
    parser.add_argument("--chamber", type=Path, default=None,
                        help="The chamber file the weights were trained from (thermocal train "
                        "--chamber): the bursts are of the camera model fitted on it.")
    parser.add_argument("--out", type=Path, default=None,
                        help="Default: NAME.sigma.json beside the weights.")
    args = parser.parse_args(argv)
    try:
        sigma = fit_network_sigma(args.weights, per_scene=args.per_scene, chamber=args.chamber)
        out = sigma.save(args.out or sidecar_path(args.weights))
    except ThermocalError as exc:  # one line, exit 2, as the commands say it
        print(f"sigma_fit: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None
    contrast = ("" if sigma.contrast_per_c is None
                else f", {sigma.contrast_per_c:.4f} °C per °C of contrast with the FPA")
    print(f"σ model of {args.weights}: floor {sigma.floor_c:.3f} °C{contrast}, coefficients "
          f"{', '.join(f'{c:.3f}' for c in sigma.coef)}; fitted on {sigma.fitted_on['bursts']} "
          f"bursts ({sigma.fitted_on['pixels']} pixels); written to {out}")
    from thermocal.nn.variants import sigma_warning

    if said := sigma_warning(sigma.fitted_on["variant"]):  # as `thermocal train` says it
        print(f"sigma_fit: warning: {said}", file=sys.stderr)


if __name__ == "__main__":
    main()
