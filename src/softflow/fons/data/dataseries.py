"""fonsim's ``fons.data.dataseries``: the columns of a CSV file."""
from __future__ import annotations

import numpy as np

from ...curves.csvdata import DataFileError, read_table


class DataSeries:
    """Columns of a CSV file: ``labels`` (names row), ``units`` (units row, as
    written) and ``array`` (rows x columns, the numbers as written).

    Parameters
    ----------
    filename : str or Path
        CSV file: optional title lines, a names row, an optional units row, data.
    bytestring : None
        fonsim reads bytes too; softflow reads files only.
    """

    def __init__(self, filename, bytestring=None):
        if bytestring is not None:
            raise ValueError("fons.data.DataSeries: softflow reads CSV files only; write the "
                             "bytes to a file and pass its path")
        self.table = read_table(filename)
        self.filename = str(filename)
        self.labels = list(self.table.names)
        self.units = (None if self.table.units is None
                      else [None if u is None else f"{u:~}" for u in self.table.units])
        self.array = np.array(self.table.data)


def column(table, word):
    """Index of the column named ``word``, else of the first whose name contains it."""
    names = [n.strip().lower() for n in table.names]
    if word in names:
        return names.index(word)
    for i, n in enumerate(names):
        if word in n:
            return i
    raise DataFileError(f"{table.path}: no column named like {word!r}; columns are "
                        f"{table.names}")


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"data.dataseries.{name}", __name__)
