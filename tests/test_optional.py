"""Optional dependencies: a command that needs one that is not installed says so in one line,
exit 2, naming the extra that installs it (README: without `[nn]` everything but the network
works)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from thermocal.errors import InvalidInputError
from thermocal.optional import require

_NO_TORCH = """
import contextlib, importlib.abc, io, json, sys


class NoTorch(importlib.abc.MetaPathFinder):  # as if not installed: `import torch` fails
    def find_spec(self, name, path, target=None):
        if name.split('.')[0] == 'torch':
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)


sys.meta_path.insert(0, NoTorch())
from thermocal.cli import main

def run(args):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            main(args)
            code = 0
        except SystemExit as exc:
            code = exc.code
    return [code, err.getvalue()]

d = sys.argv[1]
made = run(['simulate', 'flight', d + '/f', '--frames', '8', '--size', '64x48',
            '--motion', 'hover', '--fpa-c', '30'])
assert made[0] == 0, made
rec = d + '/f/frames.tiff'
print(json.dumps({name: run(args) for name, args in {
    'estimate': ['estimate', rec, '--out', d + '/t.tiff'],
    'flight': ['flight', rec, '--out', d + '/fl'],
    'train': ['train', '--out', d + '/n.pt'],
    'nuc he2018': ['nuc', rec, '--method', 'he2018', '--out', d + '/n.tiff'],
    'export': ['export', '--out', d + '/m.onnx'],
    'campaign': ['campaign', rec, '--out', d + '/camp', '--workers', '1'],
}.items()}))
"""


def test_network_commands_without_torch_say_which_extra_installs_it(tmp_path):
    """Without torch, `estimate` and `flight` (their default method is the network), `train`,
    `nuc --method he2018` and `export` each end in one line and exit 2 that names
    `pip install 'thermocal[nn]'` (they ended in a ModuleNotFoundError traceback, exit 1), and
    write nothing; `campaign` too, before its cluster starts (a review: it failed every
    recording, naming torch only in its campaign.json)."""
    res = subprocess.run([sys.executable, "-c", _NO_TORCH, str(tmp_path)], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    outcomes = json.loads(res.stdout.strip().splitlines()[-1])
    for name, (code, err) in outcomes.items():
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1, (name, code, err[-1500:])
        assert "needs torch: pip install 'thermocal[nn]'" in lines[0], (name, lines)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f"]


def test_the_demo_without_torch_runs_the_rest_and_says_why_not_the_network(tmp_path):
    """`thermocal demo` without torch gives every row but the network's, and says which extra
    installs it (rich took "[nn]" for a style tag and printed `pip install 'thermocal'`)."""
    code = _NO_TORCH.split("d = sys.argv[1]")[0] + (
        "code, err = run(['demo', '--out', sys.argv[1] + '/demo'])\n"
        "assert code == 0, err\n")
    out = subprocess.run([sys.executable, "-c", code.replace(
        "redirect_stdout(io.StringIO())", "redirect_stdout(sys.stdout)"), str(tmp_path)],
        capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    said = " ".join(out.stdout.split())
    assert "network skipped: the network needs torch: pip install 'thermocal[nn]'" in said
    assert "polynomial" in said and "KPN" not in said
    assert (tmp_path / "demo" / "results.json").is_file()


def test_require_imports_or_names_the_extra(tmp_path, monkeypatch):
    assert require("json", "reading", "none") is json
    with pytest.raises(InvalidInputError, match=r"^--method x needs no_such_module_here: "
                       r"pip install 'thermocal\[extra\]'$"):
        require("no_such_module_here", "--method x", "extra")
    # installed, but a dependency of its own is missing: pip would say it is there already
    (tmp_path / "half_installed_mod.py").write_text("import no_such_dependency_here\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(InvalidInputError, match="needs half_installed_mod, which is installed "
                       "but fails to import: No module named 'no_such_dependency_here'"):
        require("half_installed_mod", "--method x", "extra")
