"""Run the ``passes`` benchmark (``--help`` for its options): simulated UAV passes of camera units
over held-out real scenes, processed by ``thermocal flight`` with the shipped network and the
classical references, each pivot map scored against its frame's truth (MAE, bias-free MAE, column
and row bands); a thin script over :mod:`thermocal.evaluation.passes`.

    .venv/bin/python benchmarks/passes.py --units 9 --scenes builtin:aerial --frames 301
"""

from thermocal.evaluation.passes import main

if __name__ == "__main__":
    main()
