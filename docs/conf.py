"""Sphinx configuration of the softhand-env documentation.

Build: ``python -m sphinx -W --keep-going -b html docs <out>/html`` (``.ci/run`` does, with
warnings as errors). Pages are Markdown (MyST); the API reference is generated from the
docstrings (autosummary, recursive over ``softhand_env`` and ``agents``); the environment pages
take the registered specs, the task defaults and the ``SoftHandEnv`` manual from the code at
build time, and a reference to one of this project's names that does not resolve is a warning
(``docs/_ext/softhand_docs.py``).
"""

from __future__ import annotations

import os
import sys
import types
import warnings
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # the checkout's packages, as the tests import them
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

# autosummary's recursion imports every submodule; a package's ``__main__`` would run its
# command (with sphinx's argv). They hold no API: stand in an empty module for each.
for _main in sorted(ROOT.glob("*/**/__main__.py")):
    _name = ".".join(_main.relative_to(ROOT).with_suffix("").parts)
    if _name.split(".")[0] in ("softhand_env", "agents"):
        sys.modules.setdefault(_name, types.ModuleType(_name))

# sphinx-autodoc-typehints 3.6 calls an API that Sphinx 9 deprecates: a Python warning printed
# once per docstring, not a problem of these docs (Sphinx's own warnings stay errors under -W).
warnings.filterwarnings("ignore", message=r".*_RstSnippetParser\.set_application.*")

project = "softhand-env"
author = "softhand-env contributors"
copyright = "softhand-env contributors"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx_autodoc_typehints",
    "softhand_docs",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store"]
html_theme = "furo"
html_title = "softhand-env"

myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

# API reference: one page per module, generated at build time into docs/_autosummary
autosummary_generate = True
autosummary_imported_members = False
# members defined in each module only (a package's re-exports are documented where they are
# defined: one target per name); inherited docstrings (Gymnasium's, SB3's) are not ours
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True,
                           "ignore-module-all": True}
autodoc_inherit_docstrings = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # "Attributes" as fields: dataclass fields are documented once
typehints_fully_qualified = False
always_document_param_types = False

# Suppressed warning categories, each for a reason outside these docs' control:
# - ref.python: "more than one target found" for words in numpy-style type fields that
#   describe shapes or tuples in prose (``goal_pose : (x, theta) or None``): Sphinx tries each
#   word as a class name and finds several attributes called ``x``; only these ambiguities are
#   hidden. Not nitpicky: it would report ~1,400 such shape words and third-party names
#   (numpy.ndarray, typing.Any); instead the docs extension warns on every unresolved
#   reference to a ``softhand_env.`` / ``agents.`` name (``softhand_docs.own_reference``, not
#   suppressed), after resolving re-exported names at their defining module.
# - sphinx_autodoc_typehints.forward_reference: Stable-Baselines3's classes (A2C, PPO, SAC,
#   imported by agents.sb3.policies) annotate with names imported under TYPE_CHECKING (VecEnv).
suppress_warnings = ["ref.python", "sphinx_autodoc_typehints.forward_reference"]
