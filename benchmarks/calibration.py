"""Run the ``calibration`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.calibration`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.calibration import main

if __name__ == "__main__":
    main()
