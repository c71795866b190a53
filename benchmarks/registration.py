"""Run the ``registration`` benchmark suite (``--help`` for its options): a thin script over
:mod:`thermocal.evaluation.suites.registration`. ``thermocal bench`` runs every suite and names the
machine."""

from thermocal.evaluation.suites.registration import main

if __name__ == "__main__":
    main()
