"""Running ``thermocal`` in the test process, shared by the command-line tests."""

from __future__ import annotations

from thermocal.cli import main


def run(args: list, capsys) -> tuple[int, str, str]:
    """Run ``thermocal ARGS`` in this process: (exit status, stdout, stderr)."""
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 1
    out = capsys.readouterr()
    return code, out.out, out.err
