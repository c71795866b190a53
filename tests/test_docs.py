"""The documentation (docs/, Sphinx + numpydoc): every module has a page, and it builds cleanly."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PACKAGE = ROOT / "src" / "thermocal"

#: Modules documented otherwise: the command definitions by the CLI page (sphinx-click), the
#: package root by the index.
NOT_AUTOMODULE = {"thermocal", "thermocal.cli"}


def _modules() -> list[str]:
    """Every public module of the package (no ``_private`` ones, no ``commands``)."""
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        if any(p.startswith("_") for p in parts) or parts[-1] in ("commands", "__main__"):
            continue
        names.append(".".join(parts))
    return [n for n in names if n not in NOT_AUTOMODULE]


def test_every_module_has_a_page():
    documented = set()
    for page in DOCS.glob("*.rst"):
        documented |= set(re.findall(r"^\.\. automodule:: (\S+)", page.read_text("utf-8"), re.M))
    missing = [m for m in _modules() if m not in documented]
    assert not missing, f"modules without an '.. automodule::' in docs/*.rst: {missing}"


@pytest.mark.slow
def test_docs_build_without_warnings(tmp_path):
    pytest.importorskip("sphinx")
    cmd = [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
           "-d", str(tmp_path / "doctrees"), str(DOCS), str(tmp_path / "html")]
    run = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"sphinx-build failed:\n{run.stderr[-6000:]}"
    assert (tmp_path / "html" / "index.html").is_file()
