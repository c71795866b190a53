"""Run the ``chamber_io`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.chamber_io`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.chamber_io import main

if __name__ == "__main__":
    main()
