"""fonsim's ``fons.wave.custom``: a wave through given points, held or
interpolated as fonsim's ``kind`` says, as a softflow waveform that declares
the times at which it (or its slope) jumps."""
from __future__ import annotations

import bisect
from numbers import Real

import numpy as np

from ...curves.waveforms import PiecewiseConstant, PiecewiseLinear, Waveform

#: fonsim's kinds (scipy's ``interp1d`` names) and what each does between points
KINDS = {
    "previous": "each value holds until the next time (steps)",
    "zero": "as 'previous'",
    "next": "each value holds from the time before it (steps, taken early)",
    "nearest": "the value of the nearest time (steps halfway; a tie takes the earlier)",
    "linear": "straight lines",
    "slinear": "as 'linear'",
    "quadratic": "a quadratic spline through the points (not-a-knot)",
    "cubic": "a cubic spline through the points (not-a-knot)",
}
#: the spline kinds and their degrees
SPLINES = {"quadratic": 2, "cubic": 3}


class _Held(Waveform):
    """Steps that take value ``values[i]`` on (times[i-1], times[i]] ('next')
    or on the half-open intervals between the midpoints ('nearest'), the end
    values held before the first and after the last time."""

    def __init__(self, times, values, kind):
        self.times, self.values = times, values
        if kind == "next":
            edges = times[:-1]                 # jumps just after each time but the last
        else:                                  # 'nearest': halfway, the earlier at a tie
            edges = 0.5 * (times[:-1] + times[1:])
        self._edges, self._v = edges.tolist(), values.tolist()
        self._breaks = tuple(self._edges)

    def _scalar(self, t):
        # value i on (edges[i-1], edges[i]] (left-continuous: at an edge, the earlier)
        return self._v[bisect.bisect_left(self._edges, t)]

    def _array(self, t):
        return self.values[np.searchsorted(self._edges, t, side="left")]


class _Spline(Waveform):
    """scipy's interpolating spline of degree k (not-a-knot) through the
    points, as fonsim's interp1d kinds 'quadratic' and 'cubic'; the end values
    held before the first and after the last time."""

    def __init__(self, times, values, k):
        from scipy.interpolate import make_interp_spline   # lazy: scipy.interpolate
        self.times, self.values = times, values
        self._spline = make_interp_spline(times, values, k=k)
        self._lo, self._hi = float(times[0]), float(times[-1])
        self._ends = (float(values[0]), float(values[-1]))
        self._breaks = (self._lo, self._hi)     # the slope jumps where the holds begin

    def _scalar(self, t):
        if t <= self._lo:
            return self._ends[0]
        if t >= self._hi:
            return self._ends[1]
        return float(self._spline(t))

    def _array(self, t):
        return self._spline(np.clip(t, self._lo, self._hi))


def _make(times, values, kind):
    if kind in ("previous", "zero"):
        return PiecewiseConstant(times, values)
    if kind in ("linear", "slinear"):
        return PiecewiseLinear(times, values)
    if kind in SPLINES:
        return _Spline(times, values, SPLINES[kind])
    return _Held(times, values, kind)


class Custom(Waveform):
    """A wave through the points (time [s], value), held or interpolated.

    Parameters
    ----------
    wave_array : array_like, shape (N, 2) or (2, N)
        (time [s], value) pairs, or a row of times and a row of values.
    time_notation : {'absolute', 'relative'}
        'relative': each time is counted from the one before it.
    kind : str, default 'previous'
        fonsim's (scipy ``interp1d``'s) kinds: 'previous' or 'zero' (each
        value holds until the next time), 'next' (each value holds from the
        time before it), 'nearest' (the value of the nearest time; halfway
        between two, the earlier), 'linear' or 'slinear' (straight lines),
        'quadratic' or 'cubic' (an interpolating spline of that degree,
        not-a-knot, as scipy's: at least 3 or 4 points). Before the first and
        after the last time the end values hold. The wave declares the times
        at which it or its slope jumps, so the adaptive integrator lands on
        them.

    Arithmetic: ``wave * x`` and ``wave + x`` (x a number, or one number per
    point) change the wave in place and return it, as fonsim's do, so
    ``Custom(points) * 1e5 + p_atm`` and a bare ``wave * 1e5`` statement both
    scale it; so do ``x * wave``, ``x + wave``, ``wave - x``, ``x - wave``,
    ``wave / x`` and ``-wave``, which fonsim refuses. :meth:`copy` makes a
    separate wave.
    """

    def __init__(self, wave_array, time_notation="absolute", kind="previous"):
        owner = "wave.Custom"
        try:
            arr = np.array(wave_array, dtype=float)
        except (TypeError, ValueError):
            raise TypeError(f"{owner}: wave_array must be (time, value) pairs of numbers, "
                            f"got {wave_array!r}") from None
        if arr.ndim != 2 or 2 not in arr.shape:
            raise ValueError(f"{owner}: wave_array must have shape (N, 2) or (2, N), got "
                             f"{arr.shape}")
        rows = arr if arr.shape[1] == 2 else arr.T
        times, values = rows[:, 0].copy(), rows[:, 1].copy()
        if not np.isfinite(rows).all():
            raise ValueError(f"{owner}: wave_array must be finite numbers, got {wave_array!r}")
        if time_notation == "relative":
            times = np.cumsum(times)
        elif time_notation != "absolute":
            raise ValueError(f"{owner}: time_notation must be 'absolute' or 'relative', got "
                             f"{time_notation!r}")
        if not isinstance(kind, str) or kind not in KINDS:
            raise ValueError(f"{owner}: kind {kind!r} is not supported; kind must be one of "
                             f"{', '.join(map(repr, KINDS))} (or give the source any function "
                             f"of time)")
        steps = np.diff(times)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            word = "relative time" if time_notation == "relative" else "time"
            raise ValueError(f"{owner}: times must increase, but point {i} (t = {times[i]:g} s) "
                             f"does not come after point {i - 1} (t = {times[i - 1]:g} s); "
                             f"check the {word} of row {i} of wave_array")
        need = SPLINES.get(kind, 0) + 1
        if len(times) < max(need, 1):
            raise ValueError(f"{owner}: kind={kind!r} needs at least {need} points, got "
                             f"{len(times)}")
        self.times, self.kind = times, kind
        self._set_values(values)

    def _set_values(self, values):
        self.values = np.asarray(values, dtype=float)
        self._wave = _make(self.times, self.values, self.kind)
        self._breaks = tuple(self._wave.breakpoints)

    def _scalar(self, t):
        return self._wave._scalar(t)

    def _array(self, t):
        return self._wave._array(t)

    def copy(self):
        """A separate wave with the same points and kind."""
        return Custom(np.column_stack([self.times, self.values]), kind=self.kind)

    # -- arithmetic: in place, as fonsim's * and + -----------------------------------------
    def _operand(self, other, op):
        if isinstance(other, Real):
            return float(other)
        if isinstance(other, Waveform):
            return None
        try:
            arr = np.asarray(other, dtype=float)
        except (TypeError, ValueError):
            return None
        if arr.ndim == 0:
            return float(arr)
        if arr.shape != self.values.shape:
            raise ValueError(f"wave.Custom {op}: an array operand needs one value per point "
                             f"({self.values.size}), got shape {arr.shape}")
        return arr

    def _inplace(self, other, op, fn):
        x = self._operand(other, op)
        if x is None:
            return NotImplemented
        self._set_values(fn(self.values, x))
        return self

    def __mul__(self, other):
        return self._inplace(other, "*", lambda v, x: v * x)

    __rmul__ = __imul__ = __mul__

    def __add__(self, other):
        return self._inplace(other, "+", lambda v, x: v + x)

    __radd__ = __iadd__ = __add__

    def __sub__(self, other):
        return self._inplace(other, "-", lambda v, x: v - x)

    __isub__ = __sub__

    def __rsub__(self, other):
        return self._inplace(other, "-", lambda v, x: x - v)

    def __truediv__(self, other):
        return self._inplace(other, "/", lambda v, x: v / x)

    __itruediv__ = __truediv__

    def __neg__(self):
        self._set_values(-self.values)
        return self

    def __repr__(self):
        return f"<wave.Custom {self.kind}: {len(self.times)} points, t {self.times[0]:g}.." \
               f"{self.times[-1]:g} s>"


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"wave.custom.{name}", __name__)
