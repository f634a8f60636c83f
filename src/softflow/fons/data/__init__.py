"""fonsim's data tools (``fons.data``): PV curves from CSV files
(``fons.data.pvcurve``), the columns of a CSV file (``fons.data.dataseries``)
and the JSON export of a simulation (``fons.data.writeout``), over softflow's
:class:`~softflow.PVCurve` and :class:`~softflow.Result`.
"""
from __future__ import annotations

from . import dataseries, pvcurve, writeout
from .dataseries import DataSeries
from .pvcurve import PVCurve
from .writeout import writeout_simulation

__all__ = ["DataSeries", "PVCurve", "writeout_simulation", "dataseries", "pvcurve",
           "writeout"]


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"data.{name}", __name__)
