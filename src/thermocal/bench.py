"""``thermocal bench``: run the accuracy and speed benchmarks and gather them.

Each benchmark is a suite of the installed package (:mod:`thermocal.evaluation.suites`, ``python
-m thermocal.evaluation.suites.NAME [--quick] [--json OUT]``; ``benchmarks/NAME.py`` runs the
same from a checkout) that prints Markdown tables; this command runs them one after the other,
each in its own process (so that their timings do not disturb each other), and writes one JSON
file and one Markdown report that names the machine.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import click

from thermocal._validate import check_output_file, check_outputs_differ
from thermocal.evaluation.suites import SUITES as BENCHMARKS


def machine() -> str:
    """One line naming this machine: CPU model, cores, memory, Python."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if "model name" in line)
    except (OSError, StopIteration):
        pass
    mem = ""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            kib = int(next(line.split()[1] for line in f if line.startswith("MemTotal")))
        mem = f", {kib / 2**20:.0f} GiB"
    except (OSError, StopIteration, ValueError):
        pass
    return f"{cpu}, {os.cpu_count()} cores{mem}, Python {platform.python_version()}"


def run_benchmarks(names: tuple[str, ...], *, quick: bool) -> dict:
    """Run each suite in its own process; returns ``{name: {"markdown", "results", "seconds",
    "rc", "stderr_tail"}}``."""
    out: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            json_path = Path(tmp) / f"{name}.json"
            cmd = [sys.executable, "-m", f"thermocal.evaluation.suites.{name}", "--json",
                   str(json_path)]
            if quick:
                cmd.append("--quick")
            click.echo(f"running the {name} suite{' --quick' if quick else ''} …", err=True)
            started = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
            seconds = time.perf_counter() - started
            results = json.loads(json_path.read_text()) if json_path.is_file() else None
            out[name] = {"markdown": proc.stdout.strip(), "results": results, "seconds": seconds,
                         "rc": proc.returncode,
                         "stderr_tail": proc.stderr.strip().splitlines()[-5:]}
    return out


#: The Markdown report's first line (``--markdown`` replaces only a file that starts so), and
#: the keys of its JSON (``--json`` likewise).
MARKDOWN_TITLE = "# thermocal benchmarks"
_JSON_KEYS = frozenset({"machine", "quick", "benchmarks"})


def markdown_report(runs: dict, *, quick: bool, host: str, only: tuple[str, ...] = ()) -> str:
    """The Markdown report: a header with the machine and the command that reruns it (``only``:
    the suites ``--only`` chose), then each benchmark's own tables."""
    command = " ".join(["thermocal bench", *(["--quick"] if quick else []),
                        *(f"--only {name}" for name in only)])
    lines = [
        f"{MARKDOWN_TITLE}{' (--quick)' if quick else ''}",
        "",
        f"- machine: {host}",
        f"- date: {datetime.now(UTC).strftime('%Y-%m-%d %H:%M UTC')}",
        f"- command: `{command}`",
        "",
    ]
    for name, run in runs.items():
        status = "" if run["rc"] == 0 else f" — FAILED (exit {run['rc']})"
        lines += [f"## {name} ({run['seconds']:.0f} s){status}", "",
                  run["markdown"] or "(no output)"]
        if run["rc"] != 0:
            lines += ["", "```", *run["stderr_tail"], "```"]
        lines.append("")
    return "\n".join(lines)


@click.command("bench")
@click.option("--quick", is_flag=True, help="Small and short versions (about 4 min on 2 cores).")
@click.option("--json", "json_out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Write all results to this JSON file.")
@click.option("--markdown", "md_out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Write the Markdown report here (default: print it).")
@click.option("--only", type=click.Choice(BENCHMARKS), multiple=True,
              help="Run only these benchmarks (repeatable).")
def bench(quick: bool, json_out: Path | None, md_out: Path | None, only: tuple[str, ...]) -> None:
    """Run the calibration, registration, NUC, network, unit-spread and simulator benchmarks."""
    from thermocal.io.atomic import atomic_path, write_json_atomic
    from thermocal.io.replaces import check_json_replaces_only, check_text_replaces_only

    host = machine()
    # before hours of benchmarks, not after; replacing only an earlier report of its kind
    if json_out is not None and md_out is not None:
        check_outputs_differ(md_out, json_out, ("--markdown", "--json"))
    if json_out is not None:
        check_output_file(json_out, (".json",))
        check_json_replaces_only(json_out, _JSON_KEYS, kind="benchmark JSON", what="--json")
    if md_out is not None:
        check_output_file(md_out, (".md", ".markdown"))
        check_text_replaces_only(md_out, MARKDOWN_TITLE, kind="benchmark report",
                                 what="--markdown")
    only = tuple(dict.fromkeys(only))  # once each
    runs = run_benchmarks(only or BENCHMARKS, quick=quick)
    report = markdown_report(runs, quick=quick, host=host, only=only)
    if json_out:
        write_json_atomic(json_out, {"machine": host, "quick": quick, "benchmarks": runs})
    if md_out:
        with atomic_path(md_out) as tmp:
            tmp.write_text(report + "\n", encoding="utf-8")
    else:
        click.echo(report)
    failed = [name for name, run in runs.items() if run["rc"] != 0]
    if failed:
        raise click.ClickException(f"benchmarks failed: {', '.join(failed)}")


def suite_main(doc: str, run: Any, report: Any, argv: list[str] | None, *,
               quick_help: str) -> None:
    """The command line of a suite that is ``run(quick=…) → results`` and
    ``report(results, info) → Markdown``: ``[--quick] [--json OUT]``, the machine named."""
    import argparse

    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=quick_help)
    parser.add_argument("--json", default=None, help="Write the results as JSON here.")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    res = run(quick=args.quick)
    info = {"machine": machine(), "wall_s": time.perf_counter() - start, "quick": args.quick}
    print(report(res, info))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({**info, **res}, f, indent=1)
