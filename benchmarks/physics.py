"""Run the ``physics`` benchmark suite (``--help`` for its options): every calibration and
estimation method fitted or trained on one camera family (tau2, boson), evaluated on the other and
on its own; a thin script over :mod:`thermocal.evaluation.suites.physics`. ``thermocal bench`` runs
every suite and names the machine."""

from thermocal.evaluation.suites.physics import main

if __name__ == "__main__":
    main()
