"""Sphinx configuration: ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.

Sphinx rather than MkDocs: the docstrings are numpydoc (napoleon reads them as
they are), myst-nb executes the validation notebooks at build time with a
cache (jupyter-cache: a rebuild runs only the notebooks that changed), MyST's
``include`` reuses README's sections verbatim instead of a second copy that
drifts, and ``-W`` turns every warning into an error in CI.
"""
from __future__ import annotations

import os
import re

import softflow

project = "softflow"
author = "softflow developers"
copyright = "softflow developers, BSD-3-Clause"
release = version = softflow.__version__

extensions = ["myst_nb", "sphinx.ext.autodoc", "sphinx.ext.napoleon",
              "sphinx.ext.mathjax", "sphinx.ext.viewcode"]
exclude_patterns = ["_build", "validation/sources", "validation/*.py", "**.ipynb_checkpoints"]
myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3
html_theme = "furo"
html_title = f"softflow {release}"

# the notebooks run at build time, results cached between builds
nb_execution_mode = "cache"
nb_execution_cache_path = os.path.join(os.path.dirname(__file__), "_build", ".jupyter_cache")
nb_execution_timeout = 600
nb_execution_raise_on_error = True        # a failing notebook (or assert) fails the build
nb_execution_in_temp = True           # the pages write files (CSV, PNG): not into docs/
nb_merge_streams = True
# inline figures in the kernels (CI exports MPLBACKEND=Agg, which would hide them)
os.environ["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"

napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_use_ivar = True           # "Attributes" as fields, not duplicate object entries
autodoc_member_order = "bysource"
autodoc_typehints = "none"         # the docstrings give types and units
autodoc_default_options = {"members": True, "undoc-members": False}
# names the public API re-exports but whose own pages we do not build
nitpicky = False


_ABS = re.compile(r"(?<![|\w`])\|([^|\s`][^|`\n]*?)\|(?![|\w`])")


def _plain_text_math(app, what, name, obj, options, lines):
    """Docstrings write absolute values as |x| (plain-text math), which
    reStructuredText reads as a substitution: escape the bars."""
    for i, line in enumerate(lines):
        if "|" in line and not line.lstrip().startswith(("|", "+")):
            lines[i] = _ABS.sub(r"\\|\1\\|", line)


_SECTION = re.compile(r"^(Parameters|Attributes|Other Parameters|Returns|Raises)\s*$")


def _close_sections(app, what, name, obj, options, lines):
    """A free paragraph after a numpydoc list (no header of its own) would be read
    as more entries: give it a Notes header (runs before napoleon)."""
    in_list = False
    i = 0
    while i < len(lines):
        line = lines[i]
        if _SECTION.match(line) and i + 1 < len(lines) and set(lines[i + 1]) == {"-"}:
            in_list, i = True, i + 2
            continue
        if in_list and line and not line[0].isspace() and " : " not in line \
                and " " in line and i > 0 and not lines[i - 1].strip():
            lines[i:i] = ["Notes", "-----"]
            in_list = False
            i += 2
        elif in_list and line and not line[0].isspace() and i + 1 < len(lines) \
                and lines[i + 1] and set(lines[i + 1]) == {"-"}:
            in_list = False
        i += 1


def setup(app):
    app.connect("autodoc-process-docstring", _close_sections, priority=400)
    app.connect("autodoc-process-docstring", _plain_text_math)
