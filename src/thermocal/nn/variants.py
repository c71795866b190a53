"""The network variants, by name (numpy- and torch-free: the estimator registry reads it).

Each variant is Oz et al.'s network or one of their ablations (§V-C, Fig. 7); ``weights`` names
the file shipped in ``thermocal/nn/weights/`` for it, where one is shipped.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["VARIANTS", "Variant"]


@dataclass(frozen=True)
class Variant:
    """One network variant: its name, what it is, and its shipped weights file."""

    name: str
    summary: str
    weights: str


#: Name → variant; the first is the default network.
VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("kpn", "kernel prediction network with the FPA-temperature offset block",
                "kpn_n7.pt"),
        Variant("kpn-no-offset", "the KPN without the offset block (ablation)",
                "kpn_no_offset_n7.pt"),
        Variant("e2e", "an end-to-end UNet predicting the temperature itself (ablation)",
                "e2e_n7.pt"),
    )
}
