"""Evaluation: the held-out sets, the scores and the tables of thermocal's benchmarks, and the
benchmark suites themselves (``thermocal bench`` runs :mod:`thermocal.evaluation.suites`, so it
works from an installed package).

============== ==============================================================================
``heldout``    the fixed held-out bursts (held-out scenes, held-out camera units)
``scoring``    MAE, the bias / smooth / fine split, affine-free MAE, within 0.5 °C, by radius
``references`` the estimates the network is compared with (family floor, baselines, classical)
``network``    the network's rows, speed and training throughput (torch)
``tables``     Markdown tables
``suites``     one module per benchmark (``python -m thermocal.evaluation.suites.NAME``)
============== ==============================================================================
"""

from typing import Any

__all__ = ["scores", "split_error", "summarise"]


def __getattr__(name: str) -> Any:
    """``scores``, ``split_error``, ``summarise`` from :mod:`~thermocal.evaluation.scoring`,
    imported when first asked for: ``thermocal bench`` names the suites at start-up, and the
    scores' imports (scikit-image, scipy.stats: 0.4 s) would slow every command."""
    if name in __all__:
        from thermocal.evaluation import scoring

        return getattr(scoring, name)
    raise AttributeError(f"module 'thermocal.evaluation' has no attribute {name!r}")
