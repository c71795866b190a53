"""thermocal bench: finds the benchmarks, runs them, reports with the machine."""

from __future__ import annotations

import json

import pytest

from thermocal.bench import BENCHMARKS, find_benchmarks, machine, markdown_report
from thermocal.cli import main


def test_every_benchmark_script_exists():
    folder = find_benchmarks()
    for name in BENCHMARKS:
        assert (folder / f"{name}.py").is_file()


def test_report_names_the_machine_and_failures():
    runs = {"simulator": {"markdown": "| a |", "results": {}, "seconds": 3.0, "rc": 0,
                          "stderr_tail": []},
            "nuc": {"markdown": "", "results": None, "seconds": 1.0, "rc": 2,
                    "stderr_tail": ["boom"]}}
    text = markdown_report(runs, quick=True, host=machine())
    assert "cores" in text and "| a |" in text
    assert "nuc (1 s) — FAILED (exit 2)" in text and "boom" in text


@pytest.mark.slow
def test_bench_runs_the_simulator_benchmark(tmp_path):
    out = tmp_path / "r.json"
    md = tmp_path / "r.md"
    main(["bench", "--quick", "--only", "simulator", "--json", str(out), "--markdown", str(md)])
    data = json.loads(out.read_text())
    assert data["benchmarks"]["simulator"]["rc"] == 0
    assert "640x512" in md.read_text()
