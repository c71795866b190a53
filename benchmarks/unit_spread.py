"""Run the ``unit_spread`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.unit_spread`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.unit_spread import main

if __name__ == "__main__":
    main()
