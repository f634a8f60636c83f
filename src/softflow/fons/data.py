"""fonsim's data tools (``fons.data``): PV curves from CSV files and the JSON
export of a simulation, over softflow's :class:`~softflow.PVCurve` and
:class:`~softflow.Result`.
"""
from __future__ import annotations

import datetime
import json
import socket
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..constants import pressure_atmospheric
from ..curves.csvdata import DataFileError, read_table
from ..curves.pvcurve import PVCurve as _PVCurve

#: softflow PVCurve options a fons PVCurve passes on (fonsim's interpolation
#: options have no counterpart: softflow interpolates with PCHIP)
_CURVE_OPTIONS = ("smoothing", "filter_window", "filter_order")


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


def _column(table, word):
    """Index of the column named ``word``, else of the first whose name contains it."""
    names = [n.strip().lower() for n in table.names]
    if word in names:
        return names.index(word)
    for i, n in enumerate(names):
        if word in n:
            return i
    raise DataFileError(f"{table.path}: no column named like {word!r}; columns are "
                        f"{table.names}")


class PVCurve(_PVCurve):
    """A PV curve read as fonsim reads it: a softflow :class:`~softflow.PVCurve`
    (monotone cubic interpolation, linear beyond the data) with fonsim's
    ``v``, ``p`` and ``get_initial_volume``.

    Parameters
    ----------
    data : str, Path or DataSeries
        CSV file with a names row (columns named like 'volume' and
        'pressure') and a units row (e.g. ``s, ml, mbar``).
    pressure_reference : {'relative', 'absolute'}
        The file's pressures are gauge ('relative', to softflow's 1 atm) or
        absolute.
    autocorrect : bool, float, callable or pair (volume, pressure) of those
        True shifts volumes to start at 0 m^3 and pressures to start at 1 atm;
        a number [m^3 or Pa] shifts further by it; a callable maps the series
        (SI) to the corrected one. Pressure corrections give absolute pressure
        (``pressure_reference`` then has no effect).
    smoothing, filter_window, filter_order :
        softflow's noise options (see :class:`softflow.PVCurve`).
    """

    def __init__(self, data, pressure_reference="relative", autocorrect=False,
                 **interpolation_opts):
        owner = "fons.data.PVCurve"
        unknown = [k for k in interpolation_opts if k not in _CURVE_OPTIONS]
        if unknown:
            raise TypeError(f"{owner}: interpolation option(s) {unknown} are not supported: "
                            f"softflow interpolates monotone cubics (PCHIP); it accepts "
                            f"{list(_CURVE_OPTIONS)} for noisy data")
        if pressure_reference not in ("relative", "absolute"):
            raise ValueError(f"{owner}: pressure_reference must be 'relative' or 'absolute', "
                             f"got {pressure_reference!r}")
        table = data.table if isinstance(data, DataSeries) else read_table(data)
        v = table.column(table.names[_column(table, "volume")], "m**3")
        p = table.column(table.names[_column(table, "pressure")], "Pa")
        lines = table.lines
        if len(v) > 1 and (np.diff(v) < 0).all():   # fonsim takes falling volumes too
            v, p, lines = v[::-1], p[::-1], lines[::-1]
        steps = np.diff(v)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            raise DataFileError(f"{table.path}, line {lines[i]}: the volume must rise (or "
                                f"fall) through the whole file; it goes {v[i - 1]:.6g} -> "
                                f"{v[i]:.6g} m^3 from line {lines[i - 1]}")
        if pressure_reference == "relative":
            p = p + pressure_atmospheric
        v_fix, p_fix = (autocorrect if isinstance(autocorrect, (tuple, list))
                        else (autocorrect, autocorrect))
        v = _correct(v, v_fix, 0.0, "volume", owner)
        if p_fix is not False:
            raw = p - pressure_atmospheric if pressure_reference == "relative" else p
            p = _correct(raw, p_fix, pressure_atmospheric, "pressure", owner)
        super().__init__(volume=v, pressure=p, gauge=False, **interpolation_opts)
        self.origin = str(table.path)
        self.pressure_reference = pressure_reference

    @property
    def v(self):
        """Volumes of the data points [m^3]."""
        return self.volume

    @property
    def p(self):
        """Absolute pressures of the data points [Pa]."""
        return self.pressure

    def get_initial_volume(self, p0):
        """Volume [m^3] of the first data point whose pressure is closest to ``p0`` [Pa]."""
        return float(self.volume[int(np.argmin(np.abs(self.pressure - p0)))])


def _correct(values, how, start, name, owner):
    if how is False or how is None:
        return values
    if callable(how):
        out = np.asarray(how(values.copy()), dtype=float)
        if out.shape != values.shape:
            raise ValueError(f"{owner}: autocorrect for {name} returned shape {out.shape}, "
                             f"expected {values.shape}")
        return out
    if how is True:
        return values - values[0] + start
    if isinstance(how, (int, float)):
        return values - values[0] + start + float(how)
    raise TypeError(f"{owner}: autocorrect for {name} must be False, True, a number or a "
                    f"function, got {how!r}")


#: fonsim's module path ``fons.data.pvcurve.PVCurve``
pvcurve = SimpleNamespace(PVCurve=PVCurve)


def writeout_simulation(filename, simulation):
    """Write a run's results to a JSON file (the format follows the extension;
    JSON only), laid out as fonsim's: ``components`` map each component's
    terminal variables ('over' for across, 'through') and states to keys of
    ``data``, which holds the time series (SI: Pa, kg/s, kg, s).

    Parameters
    ----------
    filename : str or Path
        Ends in ``.json``.
    simulation : Simulation
        A Simulation that has run.
    """
    path = Path(filename)
    if path.suffix.lower() != ".json":
        raise ValueError(f"fons.data.writeout_simulation: {str(filename)!r}: only JSON files "
                         f"are written (name it *.json); for CSV use "
                         f"simulation.result.to_csv(path)")
    result = getattr(simulation, "result", None)
    if result is None:
        raise RuntimeError("fons.data.writeout_simulation: the simulation has not run; call "
                           "simulation.run() first")
    from .. import __version__
    data = {"time": result.times.tolist()}
    components = {}
    for comp in simulation.system.components:
        terms = {}
        for t in comp.terminals:
            entry = {"over": {}, "through": {}}
            for var in t.variables:
                key = f"{comp.label}/{t.label}/{var.label}"
                data[key] = result.get(comp.label, var.quantity, terminal=t.label).tolist()
                entry["over" if var.role == "across" else "through"][var.label] = key
            terms[t.label] = entry
        states = {}
        for s in comp.states:
            key = f"{comp.label}/{s.label}"
            data[key] = result.get(comp.label, s.label).tolist()
            states[s.label] = key
        components[comp.label] = {"terminals": terms, "states": states, "time": "time"}
    doc = {
        "scheme": "softflow.fons simulation writeout 1",
        "general": {"date": datetime.datetime.now().isoformat(timespec="seconds"),
                    "hostname": socket.gethostname(), "version": f"softflow {__version__}"},
        "simulation": {"system": {"label": simulation.system.label,
                                  "nb components": len(simulation.system.components)},
                       "solver": {"name": f"softflow {result.stats.get('method', '')}"},
                       "time": "time"},
        "components": components,
        "data": data,
    }
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh)


def __getattr__(name):
    from ._unsupported import unsupported
    return unsupported(f"data.{name}", __name__)
