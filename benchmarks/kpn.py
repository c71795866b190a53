"""Run the ``kpn`` benchmark suite: the network on the held-out set beside the references
(:mod:`thermocal.evaluation.suites.kpn`; ``--help`` for its options). ``thermocal bench`` runs
every suite and names the machine; Fig. 7 is ``benchmarks/kpn_fig7.py``."""

from thermocal.evaluation.suites.kpn import main

if __name__ == "__main__":
    main()
