"""Reading measured data from CSV files that may carry a title line and a units row.

Layout understood (as in ``shared/data/latex_balloon_60mm_pv.csv``)::

    Latex balloon actuator 60 mm,2017-11-16,MECH1A1   <- optional title line(s)
    Time,Volume,Pressure                               <- column names
    s,ml,mbar                                          <- units row (optional)
    14.31,1,22                                         <- numeric data
"""
from __future__ import annotations

import csv
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
import pint

from ..units import UnitError, ureg

if TYPE_CHECKING:
    from .._typing import Array


class DataFileError(ValueError):
    """A data file could not be read as expected (names the file and line)."""


def _is_number(cell: str) -> bool:
    try:
        float(cell)
        return True
    except ValueError:
        return False


@lru_cache(maxsize=256)
def _parse_unit(cell: str) -> Any:
    """The pint unit of a units-row cell (cached: pint's parser takes ~0.1 ms
    a cell, and files of one kind repeat the same few units)."""
    cell = cell.strip()
    if cell in ("", "-", "1"):
        return ureg.dimensionless
    return ureg.Unit(cell)


@lru_cache(maxsize=256)
def _factor(src: Any, unit: str) -> float | None:
    """The factor converting ``src`` to ``unit`` when the conversion is a plain
    scaling (not degC -> K), else None; cached, as pint's conversion of an
    array costs ~0.1 ms."""
    zero = ureg.Quantity(0.0, src).to(unit).magnitude
    return None if zero != 0.0 else float(ureg.Quantity(1.0, src).to(unit).magnitude)


class Table:
    """Columns of a CSV file with their units.

    Attributes
    ----------
    names : list[str]
    units : list[pint.Unit or None]
        None where the file has no units row.
    data : ndarray (rows, columns)
    path : Path
    lines : ndarray of int
        1-based line number in the file of each data row.
    """

    def __init__(self, path: Path, names: list[str], units: list[Any] | None, data: Array,
                 lines: Sequence[int]) -> None:
        self.path, self.names, self.units, self.data = path, names, units, data
        self.lines = np.asarray(lines, dtype=np.int64)

    @property
    def first_data_line(self) -> int:
        return int(self.lines[0])

    def index(self, name: str) -> int:
        lowered = [n.strip().lower() for n in self.names]
        key = name.strip().lower()
        if key in lowered:
            return lowered.index(key)
        raise DataFileError(f"{self.path}: no column named {name!r}; columns are {self.names}")

    def column(self, name: str, unit: str, *, default_unit: str | None = None) -> Array:
        """Column ``name`` converted to ``unit`` (an SI unit string).

        If the file has no units row, ``default_unit`` says what the numbers are in;
        without it that is an error.
        """
        i = self.index(name)
        src = self.units[i] if self.units is not None else None
        if src is None:
            if default_unit is None:
                raise DataFileError(
                    f"{self.path}: column {self.names[i]!r} has no unit (no units row); "
                    f"give its unit explicitly")
            src = ureg.Unit(default_unit)
        values = self.data[:, i]
        try:
            factor = _factor(src, unit)
            if factor is not None:
                return values * factor
            return ureg.Quantity(values, src).to(unit).magnitude
        except pint.DimensionalityError:
            raise UnitError(
                f"{self.path}: column {self.names[i]!r} is in {src:~P}, which cannot be "
                f"converted to {unit}") from None


def read_table(path: str | Path) -> Table:
    """Read a CSV file with optional title lines, a names row and an optional units row."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"data file not found: {path}")
    with open(path, newline="", encoding="utf-8-sig") as fh:
        rows = [(i + 1, [c.strip() for c in row]) for i, row in enumerate(csv.reader(fh))]
    rows = [(n, r) for n, r in rows if any(r)]
    # data start at the first row whose cells are mostly numbers; a bad cell in
    # a data row is then reported as such, not mistaken for a header
    header = []
    k = 0
    while k < len(rows) and not _mostly_numeric(rows[k][1]):
        header.append(rows[k])
        k += 1
    body = rows[k:]
    if not body:
        raise DataFileError(f"{path}: no numeric data rows found")
    if not header:
        raise DataFileError(f"{path}: no column-names row above the data (line {body[0][0]})")
    ncol = len(body[0][1])
    units = None
    names_row = header[-1]
    if len(header) >= 2 and len(header[-1][1]) == ncol:
        parsed: list[Any] | None
        try:
            parsed = [_parse_unit(cell) for cell in header[-1][1]]
        except (pint.UndefinedUnitError, pint.errors.DefinitionSyntaxError, ValueError,
                AttributeError, TypeError):
            parsed = None
        if parsed is not None and len(header[-2][1]) == ncol:
            units = parsed
            names_row = header[-2]
        elif parsed is None and len(header[-2][1]) == ncol and not _looks_like_names(header[-1][1]):
            bad = [c for c in header[-1][1] if not _unit_ok(c)]
            raise DataFileError(f"{path}, line {header[-1][0]}: unknown unit(s) {bad}")
    names = names_row[1]
    if len(names) != ncol:
        raise DataFileError(f"{path}, line {names_row[0]}: {len(names)} column names for "
                            f"{ncol} data columns")
    data = np.empty((len(body), ncol))
    for r, (lineno, cells) in enumerate(body):
        if len(cells) != ncol:
            raise DataFileError(f"{path}, line {lineno}: expected {ncol} cells, got {len(cells)}")
        for c, cell in enumerate(cells):
            try:
                data[r, c] = float(cell)
            except ValueError:
                raise DataFileError(f"{path}, line {lineno}: column {names[c]!r} holds "
                                    f"{cell!r}, which is not a number") from None
    return Table(path, names, units, data, [lineno for lineno, _ in body])


def _mostly_numeric(cells: list[str]) -> bool:
    filled = [c for c in cells if c != ""]
    return bool(filled) and 2 * sum(_is_number(c) for c in filled) > len(filled)


def _unit_ok(cell: str) -> bool:
    try:
        _parse_unit(cell)
        return True
    except Exception:
        return False


def _looks_like_names(cells: list[str]) -> bool:
    """A row of words none of which is a unit is taken as names, not units."""
    return not any(_unit_ok(c) for c in cells)
