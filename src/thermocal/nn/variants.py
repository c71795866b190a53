"""The network variants, by name (numpy- and torch-free: the estimator registry reads it).

Each variant is Oz et al.'s network or one of their ablations (§V-C, Fig. 7); ``weights`` names
the file shipped in ``thermocal/nn/weights/`` for it, where one is shipped; ``sigma_caveat``
what its σ model (:mod:`thermocal.nn.uncertainty`) is known not to hold for, said wherever it is
fitted or used.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["VARIANTS", "Variant", "sigma_warning"]


@dataclass(frozen=True)
class Variant:
    """One network variant: its name, what it is, its shipped weights file, and where its σ
    is known not to hold ("" where none is known)."""

    name: str
    summary: str
    weights: str
    sigma_caveat: str = ""


#: Name → variant; the first is the default network.
VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("kpn", "kernel prediction network with the FPA-temperature offset block",
                "kpn_n7.pt"),
        Variant("kpn-no-offset", "the KPN without the offset block (ablation)",
                "kpn_no_offset_n7.pt"),
        Variant("e2e", "an end-to-end UNet predicting the temperature itself (ablation)",
                "e2e_n7.pt",
                # benchmarks/coverage.py --model (results/coverage_e2e_2026-11-29b.md); no
                # feature added to the σ model (the estimate's contrast with the FPA, its
                # distance from the burst's median) mends it: benchmarks/RESULTS.md
                "its σ is fitted on bursts of the scenes it was trained on, and an end-to-end "
                "network's error does not carry over to scenes unlike them: one trained for "
                "20 min had 21-26 % of the held-out scenes' pixels below -5 °C within 1σ "
                "(98-100 % above -5 °C): check it on scenes of your own before trusting its σ, "
                "or use kpn"),
    )
}


def sigma_warning(method: str) -> str:
    """The warning that ``method``'s σ is known not to hold somewhere (``"NAME: caveat"``), as
    every place that fits or uses it says it; "" for a method that is no variant or whose σ
    has no caveat."""
    variant = VARIANTS.get(method)
    return f"{variant.name}: {variant.sigma_caveat}" if variant and variant.sigma_caveat else ""
