"""Pressure–volume curves of inflatable actuators."""
from __future__ import annotations

import bisect
from pathlib import Path

import numpy as np
from scipy.interpolate import PchipInterpolator

from ..constants import pressure_atmospheric
from ..units import to_si
from .csvdata import DataFileError, read_table


class PVCurve:
    """A measured or analytic pressure–volume characteristic p(V).

    Interpolation is monotone piecewise-cubic Hermite (PCHIP): C1-continuous,
    so Newton sees a continuous dp/dV, and free of overshoot between samples,
    so a peak–valley curve keeps its measured peak and valley. Outside the
    sampled volumes the curve continues linearly with its end slopes.

    Parameters
    ----------
    source : str or Path, optional
        CSV file with a names row and a units row (e.g. ``s, ml, mbar``), as in
        ``PVCurve('actuator.csv')``.
    volume : array_like [m^3] or Quantity, optional
        Volumes, strictly increasing (instead of ``source``).
    pressure : array_like [Pa] or Quantity, optional
        Pressures at those volumes (instead of ``source``).
    gauge : bool, optional
        The given pressures are gauge (relative to 1 atm). Default: True for a
        CSV file (measured PV data usually are gauge), False for arrays
        (softflow's convention is absolute pressure).
    volume_column, pressure_column : str
        Column names in the CSV file (case-insensitive).
    volume_unit, pressure_unit : str, optional
        Units of the columns if the file has no units row.
    """

    def __init__(self, source=None, volume=None, pressure=None, *, gauge=None,
                 volume_column="Volume", pressure_column="Pressure",
                 volume_unit=None, pressure_unit=None):
        self.gauge = (source is not None) if gauge is None else bool(gauge)
        if source is not None:
            if volume is not None or pressure is not None:
                raise ValueError("PVCurve: give either a CSV file or volume and pressure arrays")
            table = read_table(source)
            v = table.column(volume_column, "m**3", default_unit=volume_unit)
            p = table.column(pressure_column, "Pa", default_unit=pressure_unit)
            self.origin = str(Path(source))
            lines = table.lines
        else:
            if volume is None or pressure is None:
                raise ValueError("PVCurve: give a CSV file, or both volume and pressure")
            v = np.atleast_1d(to_si(volume, "m**3", name="volume", owner="PVCurve"))
            p = np.atleast_1d(to_si(pressure, "Pa", name="pressure", owner="PVCurve"))
            self.origin = "arrays"
            lines = None
        v = np.asarray(v, dtype=float)
        p = np.asarray(p, dtype=float)
        where = f"PVCurve ({self.origin})"
        if v.shape != p.shape or v.ndim != 1:
            raise ValueError(f"{where}: volume and pressure must be 1-D arrays of equal length")
        if len(v) < 2:
            raise ValueError(f"{where}: needs at least 2 points, got {len(v)}")
        bad = ~(np.isfinite(v) & np.isfinite(p))
        if bad.any():
            raise ValueError(f"{where}: NaN or inf at point {int(np.argmax(bad))}")
        steps = np.diff(v)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            loc = f"line {lines[i]}" if lines is not None else f"point {i}"
            raise DataFileError(f"{where}: volume must increase strictly (single-valued p(V)); "
                                f"it does not at {loc} ({v[i - 1]:.6g} -> {v[i]:.6g} m^3)")
        if self.gauge:
            p = p + pressure_atmospheric
        self.volume = v
        self.pressure = p
        self.slope = PchipInterpolator(v, p)(v, 1)
        self._vl = v.tolist()
        self._pl = p.tolist()
        self._dl = self.slope.tolist()

    def __call__(self, volume):
        """Absolute pressure [Pa] at ``volume`` [m^3]."""
        return self.fdf_volume(volume)[0]

    def fdf_volume(self, volume):
        """Absolute pressure [Pa] and its derivative dp/dV [Pa/m^3] at ``volume`` [m^3]
        (a float, an array or a pint Quantity)."""
        if not isinstance(volume, float):   # ints, arrays, Quantities -> float or ndarray
            volume = to_si(volume, "m**3", name="volume", owner="PVCurve.fdf_volume")
        if isinstance(volume, float):
            return self._scalar(volume)
        return self._array(volume)

    def _scalar(self, x):
        v, p, d = self._vl, self._pl, self._dl
        n = len(v)
        if x <= v[0]:
            return p[0] + d[0] * (x - v[0]), d[0]
        if x >= v[-1]:
            return p[-1] + d[-1] * (x - v[-1]), d[-1]
        i = bisect.bisect_right(v, x) - 1
        if i >= n - 1:
            i = n - 2
        h = v[i + 1] - v[i]
        s = (x - v[i]) / h
        s2 = s * s
        s3 = s2 * s
        h00 = 2 * s3 - 3 * s2 + 1
        h10 = s3 - 2 * s2 + s
        h01 = -2 * s3 + 3 * s2
        h11 = s3 - s2
        val = h00 * p[i] + h10 * h * d[i] + h01 * p[i + 1] + h11 * h * d[i + 1]
        dval = ((6 * s2 - 6 * s) * (p[i] - p[i + 1]) / h
                + (3 * s2 - 4 * s + 1) * d[i] + (3 * s2 - 2 * s) * d[i + 1])
        return val, dval

    def _array(self, x):
        v, p, d = self.volume, self.pressure, self.slope
        i = np.clip(np.searchsorted(v, x, side="right") - 1, 0, len(v) - 2)
        h = v[i + 1] - v[i]
        s = (x - v[i]) / h
        s2 = s * s
        s3 = s2 * s
        val = ((2 * s3 - 3 * s2 + 1) * p[i] + (s3 - 2 * s2 + s) * h * d[i]
               + (-2 * s3 + 3 * s2) * p[i + 1] + (s3 - s2) * h * d[i + 1])
        dval = ((6 * s2 - 6 * s) * (p[i] - p[i + 1]) / h
                + (3 * s2 - 4 * s + 1) * d[i] + (3 * s2 - 2 * s) * d[i + 1])
        lo = x <= v[0]
        hi = x >= v[-1]
        val = np.where(lo, p[0] + d[0] * (x - v[0]), val)
        dval = np.where(lo, d[0], dval)
        val = np.where(hi, p[-1] + d[-1] * (x - v[-1]), val)
        dval = np.where(hi, d[-1], dval)
        return val, dval

    def __repr__(self):
        return (f"<PVCurve {self.origin}: {len(self.volume)} points, "
                f"V {self.volume[0]:.3g}..{self.volume[-1]:.3g} m^3>")
