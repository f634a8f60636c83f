"""A group of sources' signals as the arrays of the compiled
:func:`softflow.laws.waves.source_values`, so that a compiled step loop
evaluates sources without calling Python.

:func:`describe` reads a group's parameters
(:class:`softflow.components.sources._SourceParams`): its constants and
offsets (``_base``), which signal each source follows (``_slot``) and the
signals themselves (``_varying``). A signal is compiled when it is a waveform
of exactly one of the classes of :mod:`softflow.curves.waveforms` that
:mod:`softflow.laws.waves` covers (Constant, Step, Ramp, PiecewiseLinear,
PiecewiseConstant, Trapezoid, Sine, Square; not a subclass, which may
override ``_scalar``), scaled to the source's unit; a Python function that
numba compiles as written (returning SI floats) is compiled and called by
address (:func:`softflow.solve.usercompile.signal_address`); anything else
(a function numba cannot compile or returning pint Quantities, a fons wave,
a user's Waveform) is called back in Python from the compiled code
(:data:`softflow.laws.waves.PYTHON`, :mod:`softflow.solve.usercall`: the
signal's own call, its units checked), unless ``settings.COMPILED_USER`` is
off: :func:`describe` then returns None.

The waveform's attributes are read when :func:`describe` is called: a
waveform edited afterwards needs describing again.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from .._laws import law_module
from ..curves import waveforms as wf

if TYPE_CHECKING:
    from .._typing import Array

#: the arrays of source_values: (base, slot, codes, factors, starts, floats)
Described = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


#: the waveform classes whose law softflow.laws.waves states (exactly these:
#: a subclass may compute otherwise)
_COVERED = (wf.Constant, wf.Step, wf.Ramp, wf.PiecewiseLinear, wf.PiecewiseConstant,
            wf.Trapezoid, wf.Sine, wf.Square)


def _floats(w: Any) -> tuple[int, list[float]] | None:
    """(kind code, floats) of the waveform w in the layout of
    :mod:`softflow.laws.waves` (the ones it evaluates with itself,
    ``Waveform._coded``), or None when its class is not covered (exactly one
    of the classes: a subclass may compute otherwise)."""
    if type(w) not in _COVERED:
        return None
    code, floats = w._coded()
    return code, floats.tolist()


def _closure(func: Any) -> dict[str, Any]:
    """The variables a function closes over, by name ({} for none)."""
    code, cells = getattr(func, "__code__", None), getattr(func, "__closure__", None)
    if code is None or not cells:
        return {}
    try:
        return {name: cell.cell_contents for name, cell in zip(code.co_freevars, cells)}
    except ValueError:                  # an empty cell
        return {}


def waveform_of(signal: Any) -> tuple[wf.Waveform, float] | None:
    """(waveform, factor) of a source's signal (``_Signal``): the waveform it
    follows and the factor [source unit / waveform unit] it multiplies it by
    (1.0: none), or None for a signal that follows no waveform (a constant, a
    Python function).

    A ``_Signal`` that keeps ``waveform`` and ``factor`` attributes is read
    from them; one that does not holds the waveform itself as ``func``
    (factor 1) or a function ``lambda t: factor * value(t)`` over it, read
    from its closure and checked against the waveform's own factor."""
    func = getattr(signal, "func", None)
    if func is None or not getattr(signal, "fast", False):
        return None
    w, factor = getattr(signal, "waveform", None), getattr(signal, "factor", None)
    if isinstance(w, wf.Waveform) and isinstance(factor, float):
        return w, factor
    if isinstance(func, wf.Waveform):
        return func, 1.0
    cells = _closure(func)
    w, factor = cells.get("value"), cells.get("factor")
    if not (isinstance(w, wf.Waveform) and isinstance(factor, float)):
        return None
    try:
        own = w.factor_to(signal.unit, name=signal.name, owner=signal.owner)
    except Exception:                   # noqa: BLE001 - not the _Signal we know: leave it
        return None
    return (w, factor) if own == factor else None


def describe(params: Any) -> Described | None:
    """The arrays (base, slot, codes, factors, starts, floats) of
    :func:`softflow.laws.waves.source_values` for a group of sources
    (``params``, a ``_SourceParams``): base (n,) float64 [SI], slot (n,) int64
    (0: constant, k > 0: signal k - 1), and per signal its kind code (int64),
    unit factor (float64), offset into floats (int64), and floats (float64).
    None when a signal is not a covered waveform (see the module) or the
    parameters' class computes its values otherwise."""
    from ..components.sources import _SourceParams

    if type(params).values is not _SourceParams.values:
        return None
    base = np.array(params._base, dtype=np.float64)
    slot = np.array(params._slot, dtype=np.int64)
    codes: list[int] = []
    factors: list[float] = []
    starts: list[int] = []
    floats: list[float] = []
    for signal in params._varying:
        found = waveform_of(signal)
        described = None if found is None else _floats(found[0])
        if described is None:
            from . import settings
            if not settings.COMPILED_USER:
                return None
            # a Python function (or a waveform the laws do not state): compiled
            # where numba can compile it as written, else called back
            from .usercall import signal_floats
            from .usercompile import signal_address
            got = (signal_address(signal) if getattr(signal, "func", None) is not None
                   else None)
            # (the compiled signal's key: the address of its run-time floats)
            key_at = (signal_floats(signal) if got is None
                      else [float(got[1]), float(got[0])])
            factor, described = 1.0, (law_module("waves").PYTHON, key_at)
        else:
            factor = found[1]
        code, values = described
        codes.append(code)
        factors.append(factor)
        starts.append(len(floats))
        floats.extend(float(v) for v in values)
    if base.shape != slot.shape or (slot.size and not 0 <= slot.min() <= slot.max()
                                    <= len(codes)):
        return None
    return (base, slot, np.array(codes, dtype=np.int64), np.array(factors, dtype=np.float64),
            np.array(starts, dtype=np.int64), np.array(floats, dtype=np.float64))


def join(parts: Sequence[Described]) -> Described:
    """Several groups' arrays (each from :func:`describe`) as one set, for one
    :func:`softflow.laws.waves.source_values` call over all their sources in
    order: the bases and slots end to end, each group's slots shifted past the
    signals of the groups before it (0 stays 0: a constant) and its signals'
    offsets past their floats."""
    shifted = []
    n_codes = n_floats = 0
    for base, slot, codes, factors, starts, floats in parts:
        shifted.append((base, np.where(slot > 0, slot + n_codes, 0), codes, factors,
                        starts + n_floats, floats))
        n_codes += codes.size
        n_floats += floats.size
    kinds = (np.float64, np.int64, np.int64, np.float64, np.int64, np.float64)
    joined = [np.concatenate([np.asarray(p[i], dtype=kind) for p in shifted] or
                             [np.empty(0, dtype=kind)]).astype(kind, copy=False)
              for i, kind in enumerate(kinds)]
    return (joined[0], joined[1], joined[2], joined[3], joined[4], joined[5])


def values(described: Described, t: float) -> Array:
    """The sources' values at the time t [s] from :func:`describe`'s arrays,
    through the compiled :func:`softflow.laws.waves.source_values` (for
    Python callers and tests; a compiled loop calls that function itself)."""
    base, slot, codes, factors, starts, floats = described
    out = np.empty(base.size)
    law_module("waves").source_values(float(t), base, slot, codes, factors, starts, floats,
                                      out)
    return out
