"""Run the ``backends`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.backends`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.backends import main

if __name__ == "__main__":
    main()
