"""The input waveforms of sources, compiled: the value at a time t [s] of each
waveform of :mod:`softflow.curves.waveforms`, and a group of sources' values
(what :meth:`softflow.components.sources._SourceParams.values` gives), so
that a compiled step loop evaluates its sources without calling Python.

A waveform reaches these functions as a kind code (below) and its floats,
stored in one float64 array from an offset ``at`` (every time in s, every
value in SI of the waveform, before a source's unit factor):

=================  ==========================================================
code               floats[at:]
=================  ==========================================================
:data:`CONSTANT`   value
:data:`STEP`       time, before, after
:data:`RAMP`       t0, t1, v0, v1, slope (the class's ``_slope``)
:data:`LINEAR`     n, times[0..n-1], values[0..n-1] (PiecewiseLinear)
:data:`HELD`       n, times[0..n-1], values[0..n-1] (PiecewiseConstant)
:data:`TRAPEZOID`  low, high, rise, fall, start, period (0: not periodic),
                   t_fall (the class's ``_t_fall``), the edges' offsets
                   (``_edges``: hold, fall, low)
:data:`SINE`       offset, amplitude, omega (``_omega`` = 2 pi frequency), phase
:data:`SQUARE`     low, high, start, period, the fall's offset (``_off``)
=================  ==========================================================

:mod:`softflow.solve.wavecodes` writes these arrays from the waveform objects.

This is the waveforms' one law: the classes give their floats in this
layout (``Waveform._layout``) and evaluate through :func:`wave_value` and
:func:`wave_values`, in Python as in the compiled step loop. A period's count
is kept as a float (``floor`` of a float is an integer-valued float), so that
no time overflows an integer.
"""
from __future__ import annotations

import math

import numpy as np

from . import call_signal, jit
from .volumes import bisect_right

#: kind codes of the waveforms (one per class of softflow.curves.waveforms)
CONSTANT, STEP, RAMP, LINEAR, HELD, TRAPEZOID, SINE, SQUARE = 0, 1, 2, 3, 4, 5, 6, 7
#: a source's signal given as a Python function, called back
#: (softflow.solve.usercall): its floats are its key and the callback's address
PYTHON = 8
#: how many floats each kind stores (tables: 1 + 2 n, see :func:`size`)
SIZES = {CONSTANT: 1, STEP: 3, RAMP: 5, TRAPEZOID: 10, SINE: 4, SQUARE: 5, PYTHON: 2}


def size(code: int, n: int = 0) -> int:
    """The number of floats a waveform of kind ``code`` stores (``n`` the
    number of rows of a table: :data:`LINEAR`, :data:`HELD`)."""
    return 1 + 2 * n if code in (LINEAR, HELD) else SIZES[code]


@jit
def _linear(floats, at, t):
    # PiecewiseLinear._scalar: held before the first and after the last time
    n = int(floats[at])
    ts = at + 1
    vs = ts + n
    i = bisect_right(floats, ts, ts + n, t) - ts
    if i == 0:
        return floats[vs]
    if i == n:
        return floats[vs + n - 1]
    t0, t1 = floats[ts + i - 1], floats[ts + i]
    v0, v1 = floats[vs + i - 1], floats[vs + i]
    return v0 + (v1 - v0) * (t - t0) / (t1 - t0)


@jit
def _held(floats, at, t):
    # PiecewiseConstant._scalar: right-continuous, values[0] before times[0]
    n = int(floats[at])
    ts = at + 1
    i = bisect_right(floats, ts, ts + n, t) - ts
    return floats[ts + n + max(i - 1, 0)]


@jit
def period_base(t, start, period):
    """The start [s] of the period of a periodic waveform that holds t >= start:
    ``start + k period`` as :meth:`Waveform.breakpoints_until` computes it,
    with k the one for which t lies in [start + k period, start + (k + 1)
    period) in floating point (k kept as a float). ``floor((t - start) /
    period)`` alone can be off by one at a period's edge, and a remainder
    computed from it put a jump an ulp away from its declared breakpoint:
    the step landing there saw the new value (or the next one's start the
    old)."""
    k = np.floor((t - start) / period)
    base = start + k * period
    if t < base:
        return start + (k - 1.0) * period
    if t >= start + (k + 1.0) * period:
        return start + (k + 1.0) * period
    return base


@jit
def _trapezoid(floats, at, t):
    low, high, rise, fall = floats[at], floats[at + 1], floats[at + 2], floats[at + 3]
    start, period, t_fall = floats[at + 4], floats[at + 5], floats[at + 6]
    e_hold, e_fall, e_low = floats[at + 7], floats[at + 8], floats[at + 9]
    if t < start:
        return low
    base = period_base(t, start, period) if period > 0.0 else start
    tau = t - base
    if t < base + e_hold:
        return low + (high - low) * tau / rise
    if t < base + e_fall:
        return high
    if t < base + e_low:
        return high - (high - low) * (tau - t_fall) / fall
    return low


@jit
def _square(floats, at, t):
    low, high, start, period, off = (floats[at], floats[at + 1], floats[at + 2],
                                     floats[at + 3], floats[at + 4])
    if t < start:
        return low
    return high if t < period_base(t, start, period) + off else low


@jit
def wave_value(code, floats, at, t):
    """The value (SI of the waveform) at the time t [s] of the waveform of kind
    ``code`` whose floats start at ``floats[at]`` (the module's table): the
    ``_scalar(t)`` of Constant, Step, Ramp, PiecewiseLinear, PiecewiseConstant,
    Trapezoid, Sine or Square (:mod:`softflow.curves.waveforms`), or of a
    Python function called back (:data:`PYTHON`). An unknown code gives nan."""
    if code == CONSTANT:
        return floats[at]
    if code == STEP:
        return floats[at + 2] if t >= floats[at] else floats[at + 1]
    if code == RAMP:
        t0, t1, v0, v1, slope = (floats[at], floats[at + 1], floats[at + 2],
                                 floats[at + 3], floats[at + 4])
        if t <= t0:
            return v0
        if t >= t1:
            return v1
        return v0 + slope * (t - t0)
    if code == LINEAR:
        return _linear(floats, at, t)
    if code == HELD:
        return _held(floats, at, t)
    if code == TRAPEZOID:
        return _trapezoid(floats, at, t)
    if code == SINE:
        offset, amplitude, omega, phase = (floats[at], floats[at + 1], floats[at + 2],
                                           floats[at + 3])
        return offset + amplitude * math.sin(omega * t + phase)
    if code == SQUARE:
        return _square(floats, at, t)
    if code == PYTHON:
        return call_signal(int(floats[at + 1]), int(floats[at]), t)
    return math.nan


@jit
def wave_values(code, floats, at, t, out):
    """:func:`wave_value` at each time of t (1-D) into out: a waveform's values
    at many times (``Waveform(t)`` for an array t)."""
    for i in range(t.size):
        out[i] = wave_value(code, floats, at, t[i])


@jit
def _signal(k, codes, factors, starts, floats, t):
    # _Signal of a waveform: factor * value(t), or value(t) itself for factor 1
    v = wave_value(codes[k], floats, starts[k], t)
    f = factors[k]
    return v if f == 1.0 else f * v


@jit
def source_values(t, base, slot, codes, factors, starts, floats, out):
    """A group of sources' values at the time t [s] into out (n,): source i's
    is base[i] (its constant and offset, SI) plus, where slot[i] > 0, the
    signal k = slot[i] - 1, ``factors[k] * wave_value(codes[k], floats,
    starts[k], t)`` (the factor turns the waveform's unit into the source's;
    1.0 means none is applied). Each signal is evaluated once. The same floats
    as ``_SourceParams.values(t)``: base alone without signals, base + value
    with one signal for all, base + [0, values...][slot] otherwise."""
    m = codes.size
    n = base.size
    if m == 0:
        for i in range(n):
            out[i] = base[i]
        return
    if m == 1:
        v = _signal(int(0), codes, factors, starts, floats, t)   # int(): one compile, not a literal's
        for i in range(n):
            out[i] = base[i] + (v if slot[i] > 0 else 0.0)
        return
    vals = np.empty(m)
    for k in range(m):
        vals[k] = _signal(k, codes, factors, starts, floats, t)
    for i in range(n):
        out[i] = base[i] + (vals[slot[i] - 1] if slot[i] > 0 else 0.0)
