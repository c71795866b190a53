"""Run the ``simulator`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.simulator`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.simulator import main

if __name__ == "__main__":
    main()
