"""fonsim's ``fons.data.pvcurve``: PV curves read from CSV files with fonsim's
conventions, as softflow :class:`~softflow.PVCurve` objects."""
from __future__ import annotations

import inspect

import numpy as np

from ...curves.csvdata import DataFileError, read_table
from ...curves.pvcurve import EXTRAPOLATE
from ...curves.pvcurve import PVCurve as _PVCurve
from ..constants import norm
from .dataseries import DataSeries, column

#: softflow PVCurve options a fons PVCurve passes on (for noisy data)
NOISE_OPTIONS = ("smoothing", "filter_window", "filter_order")

#: fonsim's interpolation options and their defaults
FONSIM_OPTIONS = {"extrapolate": False, "extrapolate_derivative": False, "method": "linear"}


def extrapolation_mode(extrapolate=False, extrapolate_derivative=False,
                       owner="fons.data.PVCurve"):
    """softflow's ``extrapolate=`` for fonsim's pair of options.

    fonsim holds the end pressures beyond the data unless both options are
    True: ``extrapolate`` alone adds a zero slope, ``extrapolate_derivative``
    alone only changes the derivative its Newton iteration sees there, not the
    pressure it converges to. Both held pressures are softflow's ``'clamp'``.
    Both True continue the curve along the chord from the first to the last
    point, which softflow has not: an error that says so. softflow's own
    modes ('clamp', 'linear', 'error') are accepted as ``extrapolate`` too.
    """
    if isinstance(extrapolate, str):
        if extrapolate not in EXTRAPOLATE:
            raise ValueError(f"{owner}: extrapolate must be True or False (fonsim) or one of "
                             f"softflow's {', '.join(map(repr, EXTRAPOLATE))}, got "
                             f"{extrapolate!r}")
        return extrapolate
    for name, value in (("extrapolate", extrapolate),
                        ("extrapolate_derivative", extrapolate_derivative)):
        if not isinstance(value, (bool, np.bool_, int)):
            raise TypeError(f"{owner}: {name} must be True or False, got {value!r}")
    if extrapolate and extrapolate_derivative:
        raise ValueError(
            f"{owner}: extrapolate=True with extrapolate_derivative=True continues fonsim's "
            f"curve beyond its data along the chord from its first to its last point; "
            f"softflow has no such extension. Leave extrapolate=False (fonsim's default: the "
            f"end pressures held, softflow's extrapolate='clamp'), or give softflow's "
            f"extrapolate='linear' (the end slopes continued)")
    return "clamp"


#: fonsim's default ``method='linear'`` is followed exactly: softflow's PVCurve
#: takes ``interpolation='linear'`` (straight lines between the samples, the
#: chord's slope on each interval). (Kept for scripts and tests that asked
#: whether it does; always True now.)
LINEAR_INTERPOLATION = "interpolation" in inspect.signature(_PVCurve.__init__).parameters


def interpolation_method(method, owner="fons.data.PVCurve"):
    """softflow's PVCurve options for fonsim's ``method=``: 'linear' (fonsim's
    default, straight lines between the samples: softflow's
    ``interpolation='linear'``) and 'pchip' (fonsim's cubic with
    central-difference slopes, taken as softflow's monotone cubic, PCHIP:
    0.4 % of the balloon curve's pressure range apart). Other names are
    refused (fonsim 0.6 interpolates them linearly without a word)."""
    if not isinstance(method, str):
        raise TypeError(f"{owner}: method must be 'linear' or 'pchip', got {method!r}")
    kind = method.lower()
    if kind not in ("linear", "pchip"):
        raise ValueError(f"{owner}: method={method!r} is not supported: give 'linear' "
                         f"(fonsim's default: straight lines between the samples) or 'pchip' "
                         f"(a cubic through them)")
    return {"interpolation": kind} if LINEAR_INTERPOLATION else {}


class PVCurve(_PVCurve):
    """A PV curve read as fonsim reads it: a softflow :class:`~softflow.PVCurve`
    with fonsim's conventions (gauge pressures refer to fonsim's 101 300 Pa,
    end pressures held beyond the data) and attributes (``v``, ``p``,
    ``get_initial_volume``).

    Parameters
    ----------
    data : str, Path or DataSeries
        CSV file with a names row (columns named like 'volume' and
        'pressure') and a units row (e.g. ``s, ml, mbar``). Volumes may rise
        or fall through the file.
    pressure_reference : {'relative', 'absolute'}
        The file's pressures are gauge ('relative', to fonsim's 1 atm,
        ``fons.pressure_atmospheric``) or absolute.
    autocorrect : bool, float, callable, or a pair (volume, pressure) of those
        True shifts the volumes to start at 0 m^3 and the pressures to start
        at 1 atm; a number [m^3 or Pa] shifts further by it; a callable maps
        the series (SI, absolute pressures) to the corrected one. A pressure
        correction makes ``pressure_reference`` moot.
    extrapolate, extrapolate_derivative : bool, default False
        fonsim's options for volumes beyond the data: the end pressures are
        held (softflow's ``extrapolate='clamp'``) unless both are True, which
        softflow does not support (an error says what to use). softflow's
        modes ``'clamp'``, ``'linear'``, ``'error'`` may be given as
        ``extrapolate``.
    method : {'linear', 'pchip'}, default 'linear'
        fonsim's interpolation between the samples: straight lines
        (softflow's ``interpolation='linear'``: dp/dV is each chord's slope
        and jumps at the samples, as in fonsim), or a cubic (softflow's
        monotone PCHIP).
    smoothing, filter_window, filter_order :
        softflow's options for noisy data (see :class:`softflow.PVCurve`).
    """

    def __init__(self, data, pressure_reference="relative", autocorrect=False,
                 **interpolation_opts):
        owner = "fons.data.PVCurve"
        unknown = [k for k in interpolation_opts
                   if k not in FONSIM_OPTIONS and k not in NOISE_OPTIONS]
        if unknown:
            raise TypeError(f"{owner}: interpolation option(s) {unknown} are not supported; "
                            f"it takes fonsim's {list(FONSIM_OPTIONS)} and softflow's "
                            f"{list(NOISE_OPTIONS)} for noisy data")
        fonsim_opts = {**FONSIM_OPTIONS, **{k: v for k, v in interpolation_opts.items()
                                            if k in FONSIM_OPTIONS}}
        noise_opts = {k: v for k, v in interpolation_opts.items() if k in NOISE_OPTIONS}
        mode = extrapolation_mode(fonsim_opts["extrapolate"],
                                  fonsim_opts["extrapolate_derivative"], owner)
        curve_opts = interpolation_method(fonsim_opts["method"], owner)
        if noise_opts.get("smoothing") not in (None, False) and "method" not in \
                interpolation_opts:
            curve_opts = {}     # softflow's smoothing spline replaces the interpolation
        if pressure_reference not in ("relative", "absolute"):
            raise ValueError(f"{owner}: pressure_reference must be 'relative' or 'absolute', "
                             f"got {pressure_reference!r}")
        if isinstance(data, bytes):
            raise TypeError(f"{owner}: softflow reads CSV files only; write the bytes to a "
                            f"file and pass its path")
        table = data.table if isinstance(data, DataSeries) else read_table(data)
        v = table.column(table.names[column(table, "volume")], "m**3")
        p = table.column(table.names[column(table, "pressure")], "Pa")
        if pressure_reference == "relative":
            p = p + norm.pressure_atmospheric
        v, p = _autocorrect(v, p, autocorrect, owner)
        lines = table.lines
        if len(v) > 1 and (np.diff(v) < 0).all():   # fonsim takes falling volumes too
            v, p, lines = v[::-1], p[::-1], lines[::-1]
        steps = np.diff(v)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            raise DataFileError(f"{table.path}, line {lines[i]}: the volume must rise (or "
                                f"fall) through the whole file; it goes {v[i - 1]:.6g} -> "
                                f"{v[i]:.6g} m^3 from line {lines[i - 1]}")
        super().__init__(volume=v, pressure=p, gauge=False, extrapolate=mode, **curve_opts,
                         **noise_opts)
        self.origin = str(table.path)
        self.pressure_reference = pressure_reference
        self.interpolation_opts = dict(interpolation_opts)

    @property
    def v(self):
        """Volumes of the data points [m^3]."""
        return self.volume

    @property
    def p(self):
        """Absolute pressures of the data points [Pa]."""
        return self.pressure

    def get_initial_volume(self, p0):
        """Volume [m^3] where the curve first reaches ``p0`` [Pa] (see
        :func:`initial_volume`)."""
        return initial_volume(self.volume, self.pressure, p0)


def initial_volume(volume, pressure, p0):
    """fonsim's starting volume on a PV curve's samples for the pressure
    ``p0`` [Pa]: along the samples in order of volume, the first segment
    whose end pressures bracket ``p0``, linearly interpolated there; where
    none does, the volume of the sample whose pressure is closest to ``p0``
    (the first of equals). (fonsim 0.6 leaves the last sample out of that
    search; here it is in.)"""
    v = np.asarray(volume, dtype=float)
    p = np.asarray(pressure, dtype=float)
    lo, hi = np.minimum(p[:-1], p[1:]), np.maximum(p[:-1], p[1:])
    hits = np.flatnonzero((lo <= p0) & (p0 <= hi))
    if hits.size:
        i = int(hits[0])
        if p[i + 1] == p[i]:
            return float(v[i])
        return float(v[i] + (v[i + 1] - v[i]) * (p0 - p[i]) / (p[i + 1] - p[i]))
    return float(v[int(np.argmin(np.abs(p - p0)))])


def _autocorrect(v, p, how, owner):
    """fonsim's autocorrect of the volume and the (absolute) pressure series."""
    if not isinstance(how, (tuple, list)):
        if not how:             # False, None, 0: no correction (as in fonsim)
            return v, p
        how = (how, how)
    if len(how) != 2:
        raise ValueError(f"{owner}: autocorrect must be one value or a pair (volume, "
                         f"pressure), got {how!r}")
    return (_correct(v, how[0], 0.0, "volume", owner),
            _correct(p, how[1], norm.pressure_atmospheric, "pressure", owner))


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
    if isinstance(how, (int, float, np.integer, np.floating)):
        return values - values[0] + start + float(how)
    raise TypeError(f"{owner}: autocorrect for {name} must be False, True, a number or a "
                    f"function, got {how!r}")


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"data.pvcurve.{name}", __name__)
