"""Run the ``campaign`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.campaign`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.campaign import main

if __name__ == "__main__":
    main()
