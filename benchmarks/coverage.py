"""Run the ``coverage`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.coverage`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.coverage import main

if __name__ == "__main__":
    main()
