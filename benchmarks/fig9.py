"""Run Oz et al.'s Fig. 9 comparison (:mod:`thermocal.evaluation.suites.fig9`; ``--help`` for its
options), writing the figure to ``benchmarks/results/fig9.png`` unless ``--out`` is given."""

import sys
from pathlib import Path

from thermocal.evaluation.suites.fig9 import main

if __name__ == "__main__":
    argv = sys.argv[1:]
    if not any(a == "--out" or a.startswith("--out=") for a in argv):
        argv += ["--out", str(Path(__file__).resolve().parent / "results" / "fig9.png")]
    main(argv)
