"""Run the ``nuc`` benchmark suite (:mod:`thermocal.evaluation.suites.nuc`; ``--help`` for its
options), writing its Fig. 7 to ``benchmarks/results/nuc_fig7.png`` unless ``--out`` is given.
``thermocal bench`` runs every suite and names the machine."""

import sys
from pathlib import Path

from thermocal.evaluation.suites.nuc import main

if __name__ == "__main__":
    argv = sys.argv[1:]
    if not any(a == "--out" or a.startswith("--out=") for a in argv):
        argv += ["--out", str(Path(__file__).resolve().parent / "results" / "nuc_fig7.png")]
    main(argv)
