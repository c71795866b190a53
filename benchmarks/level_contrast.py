"""Run the ``level_contrast`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.level_contrast`. ``thermocal bench`` runs every suite and
names the machine."""

from thermocal.evaluation.suites.level_contrast import main

if __name__ == "__main__":
    main()
