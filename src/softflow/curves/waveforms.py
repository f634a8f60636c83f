"""Input waveforms for sources: callables t [s] -> value (SI float).

Each waveform knows the unit of its values (from the pint Quantities it was
given; plain numbers are SI of whatever the source expects) and the times at
which its value or slope jumps, so that the adaptive integrator lands on them::

    import softflow as sf
    from softflow.curves.waveforms import PiecewiseConstant, Step

    # the FONS paper's Figs. 3-5 input: 1.8 mL/s in, pause, 1.8 mL/s out
    pump = PiecewiseConstant(sf.Q_([0, 10, 15], "s"), sf.Q_([1.8, 0, -1.8], "mL/s"))
    valve = Step(0.1, sf.Q_(0, "bar"), sf.Q_(0.5, "bar"))

A waveform is evaluated with a float time (fast path, returns a float) or an
array of times (returns an array). ``breakpoints`` lists the jump times;
periodic waveforms have infinitely many, so for them ``breakpoints`` covers
the first period and ``breakpoints_until(T)`` every one up to T (sources and
the Simulation use the latter).
"""
from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pint

from .._laws import law_module
from ..units import UnitError, describe_dimension, to_si, ureg

if TYPE_CHECKING:
    from .._typing import Array, ArrayLike, Scalar


# ---------------------------------------------------------------------------------------
# unit helpers (run at construction only)
# ---------------------------------------------------------------------------------------
def _magnitude(value: Any, name: str, owner: str) -> tuple[Array, Any]:
    """Value(s) in SI base units and their pint unit (None for plain numbers)."""
    if isinstance(value, pint.Quantity):
        q = value.to_base_units()
        mag, unit = np.asarray(q.magnitude, dtype=float), q.units
    elif isinstance(value, (list, tuple)) and any(isinstance(v, pint.Quantity) for v in value):
        parts = [_magnitude(v, f"{name}[{i}]", owner) for i, v in enumerate(value)]
        unit = _common_unit([(f"{name}[{i}]", u) for i, (_, u) in enumerate(parts)], owner)
        mag = np.array([float(m) for m, _ in parts])
    elif isinstance(value, str):
        raise UnitError(f"{owner}: {name} must be a number or a pint Quantity, got the "
                        f"string {value!r}")
    else:
        try:
            mag = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"{owner}: {name} must be a number, an array or a pint "
                            f"Quantity, got {value!r}") from None
        unit = None
    if not np.isfinite(mag).all():
        raise ValueError(f"{owner}: {name} must be finite, got {mag}")
    return mag, unit


def _common_unit(named_units: list[tuple[str, Any]], owner: str) -> Any:
    """The one unit shared by several parameters (None if all were plain numbers)."""
    found = [(n, u) for n, u in named_units if u is not None]
    for n, u in found[1:]:
        if u.dimensionality != found[0][1].dimensionality:
            raise UnitError(f"{owner}: {n} is in {u:~P} but {found[0][0]} is in "
                            f"{found[0][1]:~P}; all values of a waveform share one dimension")
    return found[0][1] if found else None


def _scalar_value(value: Any, name: str, owner: str) -> tuple[float, Any]:
    mag, unit = _magnitude(value, name, owner)
    if mag.ndim != 0:
        raise ValueError(f"{owner}: {name} must be a scalar, got shape {mag.shape}")
    return float(mag), unit


def _time(value: Any, name: str, owner: str, *, positive: bool = False,
          nonnegative: bool = False) -> float | Array:
    if isinstance(value, (list, tuple)) and any(isinstance(v, pint.Quantity) for v in value):
        t = np.array([to_si(v, "s", name=f"{name}[{i}]", owner=owner)
                      for i, v in enumerate(value)], dtype=float)
    else:
        t = to_si(value, "s", name=name, owner=owner)
    if not np.isfinite(t).all():
        raise ValueError(f"{owner}: {name} must be finite, got {t}")
    if positive and not np.all(t > 0):
        raise ValueError(f"{owner}: {name} must be > 0 s, got {t}")
    if nonnegative and not np.all(t >= 0):
        raise ValueError(f"{owner}: {name} must be >= 0 s, got {t}")
    return t


# ---------------------------------------------------------------------------------------
# base
# ---------------------------------------------------------------------------------------
@functools.cache
def _waves() -> Any:
    """softflow.laws.waves, imported at the first evaluation (not with this
    module: numba is imported where a law is first used)."""
    return law_module("waves")


class Waveform:
    """Base class: a function of time with a unit and breakpoints.

    The library's waveforms state their law once, compiled
    (:mod:`softflow.laws.waves`): each gives its kind and floats in that
    module's layout (``_layout() -> (kind name, floats)``), and its values,
    scalar or array, are that law's (``wave_value``, ``wave_values``). Other
    subclasses implement ``_scalar(t: float) -> float`` and ``_array(t) ->
    ndarray`` themselves. Each sets ``unit`` (pint Unit in SI base units, or
    None) and ``_breaks``.
    """

    unit: Any = None                    # a pint Unit in SI base units, or None
    period: float | None = None
    _breaks: tuple[float, ...] = ()

    if TYPE_CHECKING:                   # what subclasses implement, or inherit
        def _layout(self) -> tuple[str, list[float]]: ...

    def __setattr__(self, name: str, value: Any) -> None:
        # an attribute changed: the compiled law's floats are made again
        object.__setattr__(self, name, value)
        self.__dict__.pop("_law", None)

    def _coded(self) -> tuple[int, Array]:
        """(kind code, floats) of this waveform for softflow.laws.waves, made at
        first use (and again after an attribute changes)."""
        got = self.__dict__.get("_law")
        if got is None:
            kind, floats = self._layout()
            got = (int(getattr(_waves(), kind)), np.array(floats, dtype=np.float64))
            self.__dict__["_law"] = got
        return got

    def _scalar(self, t: float) -> float:
        code, floats = self._coded()
        return float(_waves().wave_value(code, floats, 0, t))

    def _array(self, t: Array) -> Array:
        code, floats = self._coded()
        out = np.empty(t.shape)
        _waves().wave_values(code, floats, 0, t.ravel(), out.reshape(-1))
        return out

    def __call__(self, t: float | ArrayLike) -> float | Array:
        if isinstance(t, float) or np.ndim(t) == 0:
            return self._scalar(float(t))  # type: ignore[arg-type]  # a 0-d value
        return self._array(np.asarray(t, dtype=float))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Times [s] at which the value or its slope jumps (first period if periodic)."""
        return self._breaks

    def breakpoints_until(self, until: float) -> tuple[float, ...]:
        """All breakpoints in [0, until] [s], periodic repetitions included."""
        if self.period is None:
            return tuple(b for b in self._breaks if 0.0 <= b <= until)
        out: list[float] = []
        start = getattr(self, "start", 0.0)
        k0 = max(0, math.floor((0.0 - start) / self.period))
        k = k0
        while True:
            # the same float as laws.waves.period_base gives the evaluation, so that a
            # jump falls exactly at its breakpoint (not an ulp before it)
            base = start + k * self.period
            if base > until:
                break
            out.extend(base + (b - start) for b in self._breaks)
            k += 1
        return tuple(sorted(b for b in set(out) if 0.0 <= b <= until))

    def factor_to(self, unit: str, *, name: str, owner: str) -> float:
        """Factor turning this waveform's values into ``unit`` (an SI unit string);
        raises UnitError if the dimensions differ. Plain-number waveforms: 1."""
        if self.unit is None:
            return 1.0
        target = ureg.Unit(unit)
        if self.unit.dimensionality != target.dimensionality:
            raise UnitError(f"{owner}: {name} expects {describe_dimension(unit)}, got a "
                            f"{type(self).__name__} in {self.unit:~P}")
        return float(ureg.Quantity(1.0, self.unit).to(target).magnitude)

    def __repr__(self) -> str:
        unit = f" [{self.unit:~P}]" if self.unit is not None else ""
        return f"<{type(self).__name__}{unit}>"


class Constant(Waveform):
    """A constant value.

    Parameters
    ----------
    value : float [SI of the source] or Quantity
    """

    def __init__(self, value: Scalar) -> None:
        self.value, self.unit = _scalar_value(value, "value", "Constant")

    def _layout(self) -> tuple[str, list[float]]:
        return "CONSTANT", [self.value]


class Step(Waveform):
    """``before`` until ``time``, ``after`` from ``time`` on (right-continuous).

    Parameters
    ----------
    time : float [s]
    before, after : float [SI of the source] or Quantity
    """

    def __init__(self, time: Scalar, before: Scalar, after: Scalar) -> None:
        owner = "Step"
        self.time = float(_time(time, "time", owner))
        self.before, ub = _scalar_value(before, "before", owner)
        self.after, ua = _scalar_value(after, "after", owner)
        self.unit = _common_unit([("before", ub), ("after", ua)], owner)
        self._breaks = (self.time,)

    def _layout(self) -> tuple[str, list[float]]:
        return "STEP", [self.time, self.before, self.after]


class Ramp(Waveform):
    """``v0`` until ``t0``, linear to ``v1`` at ``t1``, then ``v1``.

    Parameters
    ----------
    t0, t1 : float [s]
        Start and end of the ramp, t1 > t0.
    v0, v1 : float [SI of the source] or Quantity
    """

    def __init__(self, t0: Scalar, t1: Scalar, v0: Scalar, v1: Scalar) -> None:
        owner = "Ramp"
        self.t0 = float(_time(t0, "t0", owner))
        self.t1 = float(_time(t1, "t1", owner))
        if not self.t1 > self.t0:
            raise ValueError(f"{owner}: t1 ({self.t1} s) must be after t0 ({self.t0} s)")
        self.v0, u0 = _scalar_value(v0, "v0", owner)
        self.v1, u1 = _scalar_value(v1, "v1", owner)
        self.unit = _common_unit([("v0", u0), ("v1", u1)], owner)
        self._slope = (self.v1 - self.v0) / (self.t1 - self.t0)
        self._breaks = (self.t0, self.t1)

    def _layout(self) -> tuple[str, list[float]]:
        return "RAMP", [self.t0, self.t1, self.v0, self.v1, self._slope]


def _checked_table(times: ArrayLike, values: ArrayLike, owner: str
                   ) -> tuple[Array, Array, Any]:
    t = np.atleast_1d(_time(times, "times", owner)).astype(float)
    v, unit = _magnitude(values, "values", owner)
    v = np.atleast_1d(v).astype(float)
    if t.ndim != 1 or v.ndim != 1 or len(t) != len(v):
        raise ValueError(f"{owner}: times and values must be 1-D and equally long, got "
                         f"shapes {t.shape} and {v.shape}")
    if len(t) < 1:
        raise ValueError(f"{owner}: times is empty")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise ValueError(f"{owner}: times must be strictly increasing, but times[{i}] = "
                         f"{t[i]:g} s is not after times[{i - 1}] = {t[i - 1]:g} s")
    return t, v, unit


class _Tabulated(Waveform):
    """A waveform given by a table of strictly increasing times and values."""

    def __init__(self, times: ArrayLike, values: ArrayLike) -> None:
        self.times, self.values, self.unit = _checked_table(times, values, type(self).__name__)
        self._t = self.times.tolist()
        self._v = self.values.tolist()
        self._breaks = self._table_breaks()

    def _table_breaks(self) -> tuple[float, ...]:
        return tuple(self._t)


class PiecewiseLinear(_Tabulated):
    """Linear interpolation through (times[i], values[i]); held constant
    before the first and after the last point.

    Parameters
    ----------
    times : array [s], strictly increasing
    values : array [SI of the source] or Quantity array
    """

    def _layout(self) -> tuple[str, list[float]]:
        return "LINEAR", [float(len(self._t)), *self._t, *self._v]


class PiecewiseConstant(_Tabulated):
    """values[i] from times[i] until times[i+1]; values[0] before times[0],
    values[-1] after the last time (right-continuous steps).

    The FONS paper's Figs. 3-5 input (pump in, pause, pump out) is one line::

        PiecewiseConstant(sf.Q_([0, 10, 15], "s"), sf.Q_([1.8, 0, -1.8], "mL/s"))

    Parameters
    ----------
    times : array [s], strictly increasing
    values : array [SI of the source] or Quantity array
    """

    def _table_breaks(self) -> tuple[float, ...]:
        return tuple(self._t[1:])   # values[0] holds before times[0]: no jump there

    def _layout(self) -> tuple[str, list[float]]:
        return "HELD", [float(len(self._t)), *self._t, *self._v]


class Trapezoid(Waveform):
    """``low`` until ``start``, linear rise to ``high`` over ``rise``, ``high``
    for ``hold``, linear fall to ``low`` over ``fall``, then ``low``;
    repeated every ``period`` if given.

    Parameters
    ----------
    low, high : float [SI of the source] or Quantity
    rise, hold, fall : float [s], >= 0 (0 gives a jump)
    start : float [s], default 0
    period : float [s], optional
        At least rise + hold + fall.
    """

    def __init__(self, low: Scalar, high: Scalar, rise: Scalar, hold: Scalar, fall: Scalar,
                 start: Scalar = 0.0, period: Scalar | None = None) -> None:
        owner = "Trapezoid"
        self.low, ul = _scalar_value(low, "low", owner)
        self.high, uh = _scalar_value(high, "high", owner)
        self.unit = _common_unit([("low", ul), ("high", uh)], owner)
        self.rise = float(_time(rise, "rise", owner, nonnegative=True))
        self.hold = float(_time(hold, "hold", owner, nonnegative=True))
        self.fall = float(_time(fall, "fall", owner, nonnegative=True))
        self.start = float(_time(start, "start", owner))
        self._t_hold = self.rise
        self._t_fall = self.rise + self.hold
        self._t_low = self.rise + self.hold + self.fall
        if period is not None:
            self.period = float(_time(period, "period", owner, positive=True))
            if self.period < self._t_low:
                raise ValueError(f"{owner}: period ({self.period} s) must be at least "
                                 f"rise + hold + fall ({self._t_low} s)")
        self._breaks = tuple(sorted({self.start + x for x in
                                     (0.0, self._t_hold, self._t_fall, self._t_low)}))
        # the edges' offsets from a period's start: base + offset is the float
        # breakpoints_until gives (start + x itself when not periodic), and
        # the value changes side exactly there
        self._edges = tuple((self.start + x) - self.start if self.period is not None else x
                            for x in (self._t_hold, self._t_fall, self._t_low))

    def _layout(self) -> tuple[str, list[float]]:
        period = 0.0 if self.period is None else self.period
        return "TRAPEZOID", [self.low, self.high, self.rise, self.fall, self.start, period,
                             self._t_fall, *self._edges]


class Sine(Waveform):
    """offset + amplitude · sin(2 pi frequency t + phase). Smooth: no breakpoints.

    Parameters
    ----------
    amplitude : float [SI of the source] or Quantity
    frequency : float [Hz]
    offset : float [SI of the source] or Quantity, default 0
    phase : float [rad] or Quantity (e.g. degrees), default 0
    """

    def __init__(self, amplitude: Scalar, frequency: Scalar, offset: Scalar = 0.0,
                 phase: Scalar = 0.0) -> None:
        owner = "Sine"
        self.amplitude, ua = _scalar_value(amplitude, "amplitude", owner)
        self.offset, uo = _scalar_value(offset, "offset", owner)
        self.unit = _common_unit([("amplitude", ua), ("offset", uo)], owner)
        self.frequency = float(to_si(frequency, "Hz", name="frequency", owner=owner))
        if not (np.isfinite(self.frequency) and self.frequency > 0):
            raise ValueError(f"{owner}: frequency must be > 0 Hz, got {self.frequency}")
        self.phase = float(to_si(phase, "rad", name="phase", owner=owner))
        self._omega = 2.0 * math.pi * self.frequency

    def _layout(self) -> tuple[str, list[float]]:
        return "SINE", [self.offset, self.amplitude, self._omega, self.phase]


class Square(Waveform):
    """``high`` for the first ``duty`` fraction of each period from ``start``
    on, ``low`` otherwise (and before ``start``).

    Parameters
    ----------
    low, high : float [SI of the source] or Quantity
    frequency : float [Hz]
    duty : float [-], default 0.5, in (0, 1)
    start : float [s], default 0
    """

    period: float                       # always set (1 / frequency)

    def __init__(self, low: Scalar, high: Scalar, frequency: Scalar, duty: Scalar = 0.5,
                 start: Scalar = 0.0) -> None:
        owner = "Square"
        self.low, ul = _scalar_value(low, "low", owner)
        self.high, uh = _scalar_value(high, "high", owner)
        self.unit = _common_unit([("low", ul), ("high", uh)], owner)
        f = float(to_si(frequency, "Hz", name="frequency", owner=owner))
        if not (np.isfinite(f) and f > 0):
            raise ValueError(f"{owner}: frequency must be > 0 Hz, got {f}")
        self.frequency = f
        self.period = 1.0 / f
        self.duty = float(to_si(duty, "", name="duty", owner=owner))
        if not 0.0 < self.duty < 1.0:
            raise ValueError(f"{owner}: duty must be in (0, 1), got {self.duty}")
        self.start = float(_time(start, "start", owner))
        self._t_off = self.duty * self.period
        self._breaks = (self.start, self.start + self._t_off)
        # the fall's offset from a period's start, as breakpoints_until adds it
        self._off = self._breaks[1] - self.start

    def _layout(self) -> tuple[str, list[float]]:
        return "SQUARE", [self.low, self.high, self.start, self.period, self._off]


def from_csv(path: str | Path, time_column: str | None = None, value_column: str | None = None,
             unit: str | None = None, *, time_unit: str = "s",
             kind: str = "linear") -> PiecewiseLinear | PiecewiseConstant:
    """A waveform from two columns of a CSV file (see :func:`read_table`).

    Parameters
    ----------
    path : str or Path
    time_column, value_column : str, optional
        Column names; default the first and second column.
    unit : str, optional
        Unit of the values when the file has no units row (e.g. 'mbar');
        with a units row, the file's unit is used and ``unit``, if given, must
        have the same dimension.
    time_unit : str, default 's'
        Unit of the times when the file has no units row.
    kind : {'linear', 'previous'}
        PiecewiseLinear or PiecewiseConstant between the rows.
    """
    from .csvdata import DataFileError, read_table

    if kind not in ("linear", "previous"):
        raise ValueError(f"from_csv: kind must be 'linear' or 'previous', got {kind!r}")
    table = read_table(path)
    if len(table.names) < 2 and (time_column is None or value_column is None):
        raise DataFileError(f"{table.path}: need a time and a value column, found "
                            f"{table.names}")
    tname = table.names[0] if time_column is None else time_column
    vname = table.names[1] if value_column is None else value_column
    times = table.column(tname, "s", default_unit=time_unit)
    vi = table.index(vname)
    src = table.units[vi] if table.units is not None else None
    if src is None or (src == ureg.dimensionless and unit is not None):
        if unit is None:
            raise DataFileError(f"{table.path}: column {table.names[vi]!r} has no unit "
                                "(no units row); give unit=")
        src = ureg.Unit(unit)
    elif unit is not None and ureg.Unit(unit).dimensionality != src.dimensionality:
        raise UnitError(f"{table.path}: column {table.names[vi]!r} is in {src:~P}, not "
                        f"convertible to unit={unit!r}")
    values = ureg.Quantity(table.data[:, vi], src)
    bad = np.flatnonzero(np.diff(times) <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise DataFileError(f"{table.path}, line {table.lines[i]}: times must be strictly "
                            f"increasing ({table.names[table.index(tname)]!r} = {times[i]:g} s "
                            f"after {times[i - 1]:g} s)")
    cls = PiecewiseLinear if kind == "linear" else PiecewiseConstant
    return cls(times, values)
