"""Sphinx configuration of thermocal's documentation (built offline: no intersphinx, no remote
theme). Build: ``sphinx-build -W --keep-going -b html docs docs/_build/html``."""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
# a checkout without an editable install still documents its own source
sys.path.insert(0, str(HERE.parent / "src"))
os.environ.setdefault("MPLBACKEND", "Agg")

import thermocal  # noqa: E402

project = "thermocal"
author = "thermocal contributors"
copyright = "thermocal contributors"
release = thermocal.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_click",
    "thermocal_docs",
]

root_doc = "index"
exclude_patterns = ["_build"]
templates_path: list[str] = []
html_theme = "alabaster"
html_static_path: list[str] = []
html_theme_options = {"description": "radiometric temperature from uncooled thermal cameras"}

# autodoc: each module documents what it defines (in source order, the documented members only),
# not what it imports: a package's ``__all__`` re-exports the objects of its submodules, which
# are documented there; type hints in the signature
autodoc_default_options = {"members": True, "member-order": "bysource", "ignore-module-all": True}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
autoclass_content = "class"

# numpydoc: the class pages list their members through autodoc, not numpydoc's own autosummary
# tables (which would need stub pages); no cross-reference guessing of the types in the
# Parameters sections (nothing to link them to offline)
numpydoc_show_class_members = False
numpydoc_show_inherited_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()
