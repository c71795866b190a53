"""Fit a network's σ model (:mod:`thermocal.nn.uncertainty`) and write it beside its weights.

The errors it is fitted on are the network's on bursts of camera units of its own
(:data:`SIGMA_UNITS`: neither training, validation nor evaluation units; one per burst, so that
the spread of the units' own levels, the largest part of the error, is sampled as a population:
fitted on 33 bursts of 13 units, the floor came out 0.43 °C and σ covered 59–65 % of 200 other
units' errors within 1σ, on 220 bursts of 220 units 0.49 °C and 72 %) over the
training scenes (the real ones that are not held out, and procedural maps), flown and
registered as the evaluation set is. The evaluation units and scenes stay unseen, so that the
coverage measured on them (``benchmarks/coverage.py``) is honest.

Run: ``python -m thermocal.evaluation.sigma_fit WEIGHTS.pt [--per-scene K] [--out PATH]``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

from thermocal.burst import fill_stuck_pixels
from thermocal.errors import InvalidInputError
from thermocal.estimation.base import PreparedBurst
from thermocal.estimation.pipeline import estimate
from thermocal.evaluation.heldout import eval_bursts
from thermocal.nn.data import training_real_scenes
from thermocal.nn.infer import NetworkEstimator
from thermocal.nn.uncertainty import SigmaModel, features, fit_sigma_model, sidecar_path
from thermocal.scenes.procedural import procedural_scene

__all__ = ["PER_SCENE", "SIGMA_UNITS", "fit_network_sigma", "main", "scored_features",
           "validation_scenes"]

#: The camera units whose bursts the σ model is fitted on, one per burst.
SIGMA_UNITS: tuple[int, ...] = tuple(range(1000, 1400))

#: Validation bursts per scene.
PER_SCENE = 20

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
        return None


def scored_features(network: NetworkEstimator, bursts: list[dict]) -> list[tuple]:
    """Per burst of :func:`~thermocal.evaluation.heldout.eval_bursts`: ``(error, features,
    estimate)`` over its scored pixels (seen by at least half the frames): ``(M,)`` °C,
    ``(3, M)`` and the :class:`~thermocal.estimation.base.Estimate`."""
    rec = _Recording(network.model, network.norm)
    out = []
    for b in bursts:
        frames, _ = fill_stuck_pixels(b["frames"], b["hs"])
        est = estimate(frames, rec, fpa_c=b["fpa_read"], homographies=b["hs"],
                       pivot=b["pivot"], fill_defects=False)
        mask = b["mask"]
        out.append(((est.temperature_c - b["truth"])[mask], rec.feats[:, mask], est))
    return out


def fit_network_sigma(weights: str | os.PathLike[str], *, per_scene: int = PER_SCENE,
                      seed: int = 0) -> SigmaModel:
    """The σ model of the network in ``weights`` (any variant), fitted on ``per_scene``
    validation bursts per scene, each of its own unit, :data:`PIXELS_PER_BURST` pixels of
    each."""
    from thermocal.nn.store import load_model

    model, norm, content = load_model(weights)
    network = NetworkEstimator(model, norm)
    scenes = validation_scenes()
    if not 1 <= per_scene * len(scenes) <= len(SIGMA_UNITS):
        raise InvalidInputError(f"--per-scene {per_scene}: 1 to "
                                f"{len(SIGMA_UNITS) // len(scenes)} (one unit per burst)")
    bursts = eval_bursts(model.config.n_frames, quick=False, units=SIGMA_UNITS, scenes=scenes,
                         per_scene=per_scene, unit_per_burst=True)
    rng = np.random.default_rng(seed)
    errors, feats = [], []
    for err, f, _ in scored_features(network, bursts):
        pick = rng.choice(err.size, size=min(PIXELS_PER_BURST, err.size), replace=False)
        errors.append(err[pick])
        feats.append(f[:, pick])
    fitted_on = {"units": sorted({int(b["unit"]) for b in bursts}), "scenes": sorted(scenes),
                 "bursts": len(bursts), "frames_per_burst": model.config.n_frames}
    return fit_sigma_model(np.concatenate(errors), np.concatenate(feats, axis=1),
                           weights_sha256=content["sha256"], fitted_on=fitted_on)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m thermocal.evaluation.sigma_fit",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("weights", type=Path)
    parser.add_argument("--per-scene", type=int, default=PER_SCENE,
                        help="Bursts per scene (default %(default)s).")
    parser.add_argument("--out", type=Path, default=None,
                        help="Default: NAME.sigma.json beside the weights.")
    args = parser.parse_args(argv)
    sigma = fit_network_sigma(args.weights, per_scene=args.per_scene)
    out = sigma.save(args.out or sidecar_path(args.weights))
    print(f"σ model of {args.weights}: floor {sigma.floor_c:.3f} °C, coefficients "
          f"{', '.join(f'{c:.3f}' for c in sigma.coef)}; fitted on {sigma.fitted_on['bursts']} "
          f"bursts ({sigma.fitted_on['pixels']} pixels); written to {out}")


if __name__ == "__main__":
    main()
