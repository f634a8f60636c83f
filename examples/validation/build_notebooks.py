"""Writes the validation notebooks of this folder from their sources in
``sources/`` (plain Python in the "percent" cell format: ``# %%`` starts a code
cell, ``# %% [markdown]`` a markdown cell whose lines start with ``# ``).

    python examples/validation/build_notebooks.py

Each notebook compares softflow with an independent reference (closed form,
the ``fluids`` package, CoolProp) and asserts the tolerance it states, so the
test suite (tests/validation/test_notebooks.py) fails when a case drifts.
Notebooks are stored without outputs; run them in Jupyter to see the plots.
"""
from __future__ import annotations

from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent


def cells_of(source: str):
    """[(kind, text)] of a percent-format script."""
    cells, kind, lines = [], None, []
    for line in source.splitlines():
        if line.startswith("# %%"):
            if kind is not None:
                cells.append((kind, "\n".join(lines)))
            kind = "md" if "[markdown]" in line else "code"
            lines = []
        elif kind == "md":
            lines.append(line[2:] if line.startswith("# ") else line.lstrip("#"))
        elif kind is not None:
            lines.append(line)
    if kind is not None:
        cells.append((kind, "\n".join(lines)))
    return cells


def build(name, cells):
    nb = new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                 "language": "python"}
    for kind, src in cells:
        src = src.strip("\n")
        nb.cells.append(new_markdown_cell(src) if kind == "md" else new_code_cell(src))
        nb.cells[-1].id = f"cell-{len(nb.cells)}"   # stable ids: rebuilding changes nothing
    path = HERE / f"{name}.ipynb"
    nbformat.write(nb, path)
    return path


if __name__ == "__main__":
    for src in sorted((HERE / "sources").glob("*.py")):
        print("wrote", build(src.stem, cells_of(src.read_text())))
