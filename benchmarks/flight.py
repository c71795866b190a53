"""Run the ``flight`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.flight`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.flight import main

if __name__ == "__main__":
    main()
