"""thermocal bench: finds the benchmarks, runs them, reports with the machine."""

from __future__ import annotations

import json

import pytest

from thermocal.bench import BENCHMARKS, machine, markdown_report
from thermocal.cli import main


def test_every_suite_is_a_package_module_with_a_script_beside_it():
    import importlib
    from pathlib import Path

    scripts = Path(__file__).resolve().parents[1] / "benchmarks"
    for name in BENCHMARKS:
        assert callable(importlib.import_module(f"thermocal.evaluation.suites.{name}").main)
        assert f"thermocal.evaluation.suites.{name}" in (scripts / f"{name}.py").read_text()


def test_bench_refuses_a_missing_output_folder_before_running(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "--quick", "--json", str(tmp_path / "no" / "r.json")])
    assert exc.value.code == 2 and "does not exist" in capsys.readouterr().err


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
