"""User components, Python signals and per-step coefficients called back
from the compiled loop.

The compiled network residual (:func:`softflow.laws.network.residual`)
evaluates a group of user-written components (the paper's ``Actuator``, any
``evaluate`` / ``update_state`` / ``auto*`` component) that numba does not
compile as written (:mod:`softflow.solve.usercompile` compiles those it
can) by calling back into Python: one C function made once per process with :mod:`ctypes` (it takes
the interpreter's lock itself, so the loop may run without it), whose address
the group's row of the loop's arrays carries, and a key per group into
:data:`_EVALUATORS`. The callback wraps the loop's arrays (passed by their
data pointers) as NumPy views, calls the group's own kernel, the same one
the per-group path calls (:mod:`softflow.solve.userkernel`: its residual and
Jacobian by the component's functions and finite differences), and writes its
rows, its Jacobian entries and its states at the end of the step in place.

An exception inside the user's code is not raised through the compiled code:
the callback returns 1 and the loop reports the group as refusing the state,
whereupon the caller evaluates the network on the per-group path, which
raises the error naming the component and the time (or, for a fluid's range,
cuts the step as it does for library components). An interrupt (Ctrl-C's
KeyboardInterrupt) is kept and raised as soon as the compiled code returns
(:func:`raise_pending`), the call-backs answering at once until then.

A source's signal given as a Python function is called back alike from the
compiled source values (:class:`Signal`), and the h A that a heat-transfer
correlation sets at each step's start from the compiled step loop
(:class:`Begin`).

Cost (the paper's scene, measured in ``benchmarks/README.md``): a call
costs a few microseconds beside the kernel's own Python.
"""
from __future__ import annotations

import ctypes
import itertools
import weakref
from typing import Any, Callable

import numpy as np

from . import settings

#: key -> the evaluator of one group (a weak reference: the network that made
#: it owns it; a network gone leaves no entry behind)
_EVALUATORS: weakref.WeakValueDictionary = weakref.WeakValueDictionary()
_KEYS = itertools.count(1)

_SIGNATURE = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_int64, ctypes.c_double, ctypes.c_double,
                              ctypes.c_int64, *([ctypes.c_void_p, ctypes.c_int64] * 5))


class _Views:
    """A call-back from the compiled loop that reads its arrays as NumPy
    views: ``least``, the least size of each array (x, S, F, raw, Sout;
    Sout may be empty: no states wanted), set by the subclass."""

    least: tuple = (0, 0, 0, 0, 0)

    def __init__(self) -> None:
        # the views made of the loop's arrays, by (address, size): the loop
        # passes the same few arrays at every call
        self._views: dict = {}

    def _views_of(self, where: tuple) -> tuple | None:
        """NumPy views of the loop's arrays, ``where`` their (address, size)
        pairs in a row (kept by those: the loop passes the same few arrays
        at every call), or None where one is too short for this component's
        places in it (Sout may be empty: no states wanted)."""
        got = self._views.get(where)
        if got is None:
            sizes = where[1::2]
            if any(size < least and not (k == 4 and size == 0)
                   for k, (size, least) in enumerate(zip(sizes, self.least))):
                return None
            if len(self._views) > settings.CALLBACK_VIEWS_MAX:
                self._views.clear()
            got = self._views[where] = tuple(
                np.frombuffer((ctypes.c_double * size).from_address(address), dtype=np.float64)
                if size > 0 and address else np.empty(0)
                for address, size in zip(where[0::2], where[1::2]))
        return got

    def from_pointers(self, t: float, dt: float, jac: int, *where: Any) -> int:
        """The call with the arrays as (address, size) pairs, in order (1
        where one is too short)."""
        views = self._views_of(where)
        return 1 if views is None else self(t, dt, bool(jac), *views)


class Evaluator(_Views):
    """One user component's callback (a group of one, whose kernel the
    assembly calls with 1-D rows: ``g.row``): its kernel and update, where
    its unknowns, rows, Jacobian entries and states lie in the network's
    arrays."""

    def __init__(self, g: Any) -> None:
        super().__init__()
        uk = g.row
        self.kernel_row, self.update_row = uk.kernel_row, uk.update_row
        self.col = np.asarray(g.col[0], dtype=np.int64)
        self.r0, self.r1, self.j0, self.j1 = g.r0, g.r1, g.j0, g.j1
        self.s0, self.s1 = g.s0, g.s1
        self.has_states = bool(g.has_states)
        self.least = (int(self.col.max()) + 1 if self.col.size else 0, g.s1, g.r1, g.j1, g.s1)

    def __call__(self, t: float, dt: float, jac: bool, x: np.ndarray, S: np.ndarray,
                 F: np.ndarray, raw: np.ndarray, Sout: np.ndarray) -> int:
        v, s = x[self.col], S[self.s0:self.s1]
        Fg, Jg = self.kernel_row(v, s, t, dt, jac)
        F[self.r0:self.r1] = Fg
        if jac and self.j1 > self.j0:
            raw[self.j0:self.j1] = Jg
        if Sout.size and self.has_states:
            Sout[self.s0:self.s1] = self.update_row(v, s, dt)
        return 0


class Begin(_Views):
    """The coefficients a network sets at the start of each step (a
    heat-transfer correlation's h A: ``asm.begin_step``), called back from
    the compiled step loop at each step's start with the point (x, S), and
    copied into the network's floats (``refresh``). An error raised there is
    the run's, as where the Python loop calls ``begin_step``: kept
    (:data:`PENDING`) and raised once the loop returns."""

    def __init__(self, asm: Any, refresh: Callable) -> None:
        super().__init__()
        self.begin_step, self.refresh = asm.begin_step, refresh
        self.least = (asm.n, len(asm.S0), 0, 0, 0)

    def __call__(self, t: float, dt: float, jac: bool, x: np.ndarray, S: np.ndarray,
                 F: np.ndarray, raw: np.ndarray, Sout: np.ndarray) -> int:
        try:
            self.begin_step(x, S)
            self.refresh()
        except BaseException as err:        # the run's error: raised when the loop returns
            PENDING.append(err)
            return 1
        return 0


def register(evaluator: Any) -> int:
    """A new key for ``evaluator`` (held weakly: keep the evaluator alive
    while the network that calls it lives)."""
    key = next(_KEYS)
    _EVALUATORS[key] = evaluator
    return key


#: an interrupt (KeyboardInterrupt, SystemExit: not an Exception) met inside a
#: call-back, or any error of :class:`Begin`'s, which the caller raises once
#: the compiled code returns (:func:`raise_pending`); while one waits,
#: call-backs return at once
PENDING: list = []


def raise_pending() -> None:
    """Raise the error a call-back kept, if any (see :data:`PENDING`)."""
    if PENDING:
        err = PENDING.pop()
        PENDING.clear()
        raise err


def _guarded(key: int, how: str, *args: Any) -> int:
    """``_EVALUATORS[key].<how>(*args)``: 0, or 1 where the user's code
    raised (see the module) or a call-back's interrupt waits."""
    if PENDING:
        return 1
    try:
        return getattr(_EVALUATORS[key], how)(*args)
    except Exception:          # raised again by the per-group path
        return 1
    except BaseException as err:    # an interrupt: raised once the loop returns
        PENDING.append(err)
        return 1


def dispatch(key: int, t: float, dt: float, jac: bool, x: np.ndarray, S: np.ndarray,
             F: np.ndarray, raw: np.ndarray, Sout: np.ndarray) -> int:
    """The callback with the arrays themselves (pure-Python mode, and tests):
    0, or 1 where the user's code raised (see the module)."""
    return _guarded(key, "__call__", t, dt, jac, x, S, F, raw, Sout)


def _entry(key: int, t: float, dt: float, jac: int, *where: Any) -> int:
    return _guarded(key, "from_pointers", t, dt, jac, *where)


#: the C function the compiled loop calls, and its address
CALLBACK: Callable = _SIGNATURE(_entry)
ADDRESS: int = ctypes.cast(CALLBACK, ctypes.c_void_p).value or 0


# -- sources' signals given as Python functions -------------------------------------------
class Signal:
    """A source's signal (``softflow.components.sources._Signal``: a Python
    function of t, its units checked and turned into SI at each call) called
    back from the compiled source values (:data:`softflow.laws.waves.PYTHON`),
    by its key in :data:`_EVALUATORS`. Held while the signal lives
    (:data:`_SIGNALS`), which it refers to weakly (a copied or pickled
    component's signal gets a key of its own). Where the function raises,
    the value is NaN and the error is kept (:data:`RAISED`, the last few, for
    inspection); the Python path, evaluating the signal again, raises it
    naming the source."""

    def __init__(self, signal: Any) -> None:
        self.signal = weakref.ref(signal)
        self.key = register(self)

    def value(self, t: float) -> float:
        if PENDING:
            return float("nan")
        signal = self.signal()
        if signal is None:
            return float("nan")
        try:
            return float(signal(t))
        except Exception as err:    # raised again by the Python path
            RAISED.append(err)
            del RAISED[:-settings.CALLBACK_ERRORS_KEPT]
            return float("nan")
        except BaseException as err:    # an interrupt: raised once the loop returns
            PENDING.append(err)
            return float("nan")


#: the last errors the signals called back raised (settings.CALLBACK_ERRORS_KEPT)
RAISED: list = []
#: each signal's call-back, while the signal lives
_SIGNALS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def signal_floats(signal: Any) -> list[float]:
    """The floats of :data:`softflow.laws.waves.PYTHON` for ``signal``: its
    key and the callback's address (exact as floats: addresses < 2^53)."""
    mine = _SIGNALS.get(signal)
    if mine is None:
        mine = _SIGNALS[signal] = Signal(signal)
    return [float(mine.key), float(SIGNAL_ADDRESS)]


def signal_value(key: int, t: float) -> float:
    """The signal ``key``'s value at t (NaN where it raised or is gone)."""
    evaluator = _EVALUATORS.get(key)
    return float("nan") if evaluator is None else evaluator.value(t)


SIGNAL_CALLBACK: Callable = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_int64,
                                             ctypes.c_double)(signal_value)
SIGNAL_ADDRESS: int = ctypes.cast(SIGNAL_CALLBACK, ctypes.c_void_p).value or 0
