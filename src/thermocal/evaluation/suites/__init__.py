"""The benchmark suites, one module each with ``main(argv)``: ``simulator``, ``calibration``,
``registration``, ``nuc``, ``kpn``, ``unit_spread``, ``flight``, ``physics``, ``coverage``,
``level_contrast``, ``backends``, ``chamber_io``, ``campaign``
(``python -m thermocal.evaluation.suites.NAME [--quick] [--json OUT]``; ``thermocal bench`` runs
them all)."""

#: The suites in the order ``thermocal bench`` runs them.
SUITES = ("simulator", "calibration", "registration", "nuc", "kpn", "unit_spread", "flight",
          "physics", "coverage", "level_contrast",
          "backends", "chamber_io", "campaign")
