"""fonsim's ``fons.wave.custom``: a wave through given points, as a softflow
waveform (:class:`softflow.curves.waveforms.PiecewiseConstant` or
:class:`~softflow.curves.waveforms.PiecewiseLinear`)."""
from __future__ import annotations

from numbers import Real

import numpy as np

from ...curves.waveforms import PiecewiseConstant, PiecewiseLinear, Waveform

_KINDS = {"previous": PiecewiseConstant, "zero": PiecewiseConstant,
          "linear": PiecewiseLinear, "slinear": PiecewiseLinear}


class Custom(Waveform):
    """A wave through the points (time [s], value), held or interpolated.

    Parameters
    ----------
    wave_array : array_like, shape (N, 2) or (2, N)
        (time [s], value) pairs, or a row of times and a row of values.
    time_notation : {'absolute', 'relative'}
        'relative': each time is counted from the one before it.
    kind : {'previous', 'zero', 'linear', 'slinear'}
        'previous'/'zero': each value holds until the next time (a step wave);
        'linear'/'slinear': straight lines between the points. Before the first
        and after the last time the end values hold.
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
        if time_notation == "relative":
            times = np.cumsum(times)
        elif time_notation != "absolute":
            raise ValueError(f"{owner}: time_notation must be 'absolute' or 'relative', got "
                             f"{time_notation!r}")
        if kind not in _KINDS:
            raise ValueError(f"{owner}: kind {kind!r} is not supported; use 'previous' (steps) "
                             f"or 'linear', or give the source any function of time")
        steps = np.diff(times)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            word = "relative time" if time_notation == "relative" else "time"
            raise ValueError(f"{owner}: times must increase, but point {i} (t = {times[i]:g} s) "
                             f"does not come after point {i - 1} (t = {times[i - 1]:g} s); "
                             f"check the {word} of row {i} of wave_array")
        self.times, self.values, self.kind = times, values, kind
        self._wave = _KINDS[kind](times, values)
        self._breaks = self._wave.breakpoints

    def _scalar(self, t):
        return self._wave._scalar(t)

    def _array(self, t):
        return self._wave._array(t)

    def _with_values(self, values):
        return Custom(np.column_stack([self.times, values]), kind=self.kind)

    def __mul__(self, other):
        if not isinstance(other, Real):
            return NotImplemented
        return self._with_values(self.values * float(other))

    __rmul__ = __mul__

    def __truediv__(self, other):
        if not isinstance(other, Real):
            return NotImplemented
        return self._with_values(self.values / float(other))

    def __add__(self, other):
        if not isinstance(other, Real):
            return NotImplemented
        return self._with_values(self.values + float(other))

    __radd__ = __add__

    def __sub__(self, other):
        if not isinstance(other, Real):
            return NotImplemented
        return self._with_values(self.values - float(other))

    def __rsub__(self, other):
        if not isinstance(other, Real):
            return NotImplemented
        return self._with_values(float(other) - self.values)

    def __neg__(self):
        return self._with_values(-self.values)

    def __repr__(self):
        return f"<wave.Custom {self.kind}: {len(self.times)} points, t {self.times[0]:g}.." \
               f"{self.times[-1]:g} s>"


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"wave.custom.{name}", __name__)
