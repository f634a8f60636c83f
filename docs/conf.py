"""Sphinx configuration: ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.

Sphinx rather than MkDocs: the docstrings are numpydoc (napoleon reads them as
they are), myst-nb executes the validation notebooks at build time with a
cache (jupyter-cache: a rebuild runs only the notebooks that changed), MyST's
``include`` makes benchmarks/README.md the benchmarks page without a second copy
that drifts (the guide pages are written for readers and include no README), and
``-W`` turns every warning into an error in CI.
"""
from __future__ import annotations

import os

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
