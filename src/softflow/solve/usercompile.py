"""User components compiled: the paper's ``evaluate`` / ``update_state``
called natively from the compiled loop where numba can compile them as written.

A user's component (any ``evaluate`` / ``update_state`` / ``state_rates``
component, the paper's ``Actuator``) is otherwise called back in Python from
the compiled loop (:mod:`softflow.solve.usercall`, a few microseconds a
call plus the user's own Python: the paper's listing spends most of its run
there). Here its functions are compiled with numba as they are written, and
its kernel (the residual rows, the finite-difference Jacobian and the states
at the end of the step, the arithmetic of
:meth:`softflow.solve.userkernel.UserKernel.kernel_row`) becomes a C function
with the call-back's signature, which the loop calls by address with the
component's layout (where its variables, rows, Jacobian entries and states
lie) in place of the call-back's key.

What a user's function may use. Numbers, tuples of numbers, NumPy arrays,
a module's numbers (``sf.pressure_atmospheric``: the module's numbers that
the code names, as a named tuple of constants), ``math`` and NumPy's
functions that numba compiles, from the paper's listing a
:class:`~softflow.curves.pvcurve.PVCurve` (``fdf_volume`` of one volume)
and a fluid (its ``rho``), and the user's own plain functions (compiled
with it, by the same rules), found in the function's closure or among its
globals, or as an attribute of an object it reads (a bound method's
``self``, or a closure's object: ``self.k``; :func:`_desugared` makes each
``obj.attr`` a closure variable of a function of the same code). The
floats, fluids and curves in the closures and module globals of
``evaluate`` and ``update_state`` or ``state_rates`` (and the floats of a
source function's) are run-time values (settings.USER_RUNTIME_VALUES): the function
is rewritten from its source to take them as its last arguments, and the
kernel reads them from the component's layout at each call
(:func:`layout`), so one kernel serves every value (a design loop over a
curve or a stiffness compiles once). The rest is compiled in as
constants. All are read when the Simulation is built and checked at the
start of each run
(:meth:`softflow.solve.netcore.CompiledNetwork.check_user_values`: run-time
values read again, changed constants get their own kernel, or the
call-back); a value changed during a run is not seen. Where
anything else is met, or numba cannot compile the function, the component is
called back in Python as before, and the reason is logged once (DEBUG, on
the ``'softflow'`` logger).

Compiled once. The kernel is written as a small module (its source names the
user's functions, the component's state names and its own integer and
float constants only, no component's label: components alike share it)
under the compile cache, in a file named by a hash of that source, of the
user functions' code and of the constants read from their closures and
globals (of the run-time values, their kinds), and of the text of
softflow's laws and softflow's, numba's and
Python's versions; numba caches the compiled kernel beside it, so a later
process loads it (milliseconds) instead of compiling it again (a second or
two, said once on the ``'softflow'`` logger). A function whose
compile numba refused is remembered the same way and not tried again.
Modules not used for settings.USER_CACHE_DAYS days are deleted at a
process's first compile (:func:`_prune`).
Where no cache directory can be written the kernel is compiled in a
temporary directory, for this process only.

Errors. The compiled kernel raises nothing into the loop: an exception in the
user's compiled code (an index out of range, a division by zero, a volume
beyond a curve made with ``extrapolate='error'``), a residual of the wrong
length or a missing state make it return 1, and the loop then evaluates the
component in Python, which raises the error naming the component and the
time (or, for a curve's range, cuts the step), as for a call-back.
"""
from __future__ import annotations

import __future__
import ast
import collections
import dis
import functools
import hashlib
import importlib.util
import linecache
import logging
import math
import os
import pickle
import re
import sys
import tempfile
import threading
import time
import types as pytypes
import warnings
from pathlib import Path
from typing import Any

import numba
import numpy as np
from numba import types
from numba.extending import intrinsic, overload_method

from .. import __version__
from ..curves.pvcurve import PVCurve
from ..fluids.base import Fluid
from . import settings

log = logging.getLogger("softflow")

#: the C signature the compiled loop calls (softflow.laws.call_user): the key
#: (here: the address of the component's layout), t, dt, jac, then each of
#: x, S, F, raw and Sout as its data pointer and size
_P = types.CPointer(types.float64)
SIGNATURE = types.int64(types.int64, types.float64, types.float64, types.int64,
                        _P, types.int64, _P, types.int64, _P, types.int64, _P, types.int64,
                        _P, types.int64)

#: the C signature of a source's signal (softflow.laws.call_signal): its value at t
SIGNAL_SIGNATURE = types.float64(types.int64, types.float64)

#: a layout's fields before the component's columns: the least size of x,
#: the offsets of its rows, its Jacobian entries (start, end), its states
#: (start, end), and whether it has states
LAYOUT_HEAD = 7

#: a PV curve as compiled code reads it (its lookup's table: softflow.laws.volumes)
CurveImage = collections.namedtuple("CurveImage", "knots table lo hi refuse")
#: a PV curve as a kernel reads it at run time (:func:`layout`): the
#: addresses of its knots and of its table's rows (end to end), the number
#: of knots, the ends of its data and whether it refuses volumes beyond them
CurveRef = collections.namedtuple("CurveRef", "knots n table lo hi refuse")
#: a fluid as compiled code reads it: the paper's ``fluid.rho``
FluidImage = collections.namedtuple("FluidImage", "rho")


class NotCompiled(Exception):
    """Why a user's function is called back instead of compiled."""


@intrinsic
def layout_at(typingctx, address):
    """The int64 pointer at ``address`` (int64): a component's layout."""
    sig = types.CPointer(types.int64)(address)

    def codegen(context, builder, sig, args):
        from llvmlite import ir
        return builder.inttoptr(args[0], ir.IntType(64).as_pointer())
    return sig, codegen


@intrinsic
def floats_at(typingctx, address):
    """The float64 pointer at ``address`` (int64): a layout's slots read as
    floats, or an array's data (:func:`layout`'s run-time values)."""
    sig = types.CPointer(types.float64)(address)

    def codegen(context, builder, sig, args):
        from llvmlite import ir
        return builder.inttoptr(args[0], ir.DoubleType().as_pointer())
    return sig, codegen


@overload_method(types.NamedTuple, "fdf_volume")
def _fdf_volume(curve, volume):
    """A :class:`CurveImage`'s ``fdf_volume`` of one volume: (p, dp/dV), as
    :meth:`PVCurve.fdf_volume` of a float gives them; a volume the curve
    refuses raises (the caller's Python path then raises CurveRangeError)."""
    kind = getattr(curve, "instance_class", None)
    if kind not in (CurveImage, CurveRef):
        return None
    if not isinstance(volume, (types.Float, types.Integer)):
        return None
    from ..laws.volumes import curve_point, curve_point_flat

    if kind is CurveRef:        # (a run-time curve: its arrays at their addresses)
        def ref(curve, volume):
            x = float(volume)
            if curve.refuse and not (curve.lo <= x <= curve.hi):
                raise ValueError("a volume beyond the PV curve's data")
            n = curve.n
            return curve_point_flat(numba.carray(floats_at(curve.knots), (n,)),
                                    numba.carray(floats_at(curve.table), (5 * n + 5,)), x)
        return ref

    def impl(curve, volume):
        x = float(volume)
        if curve.refuse and not (curve.lo <= x <= curve.hi):
            raise ValueError("a volume beyond the PV curve's data")
        return curve_point(curve.knots, curve.table, x)
    return impl


def _plain_curve(value: Any) -> bool:
    """Whether ``value`` is a PVCurve whose lookup is PVCurve's own (a
    subclass that overrides it is not compiled)."""
    return (isinstance(value, PVCurve) and type(value).fdf_volume is PVCurve.fdf_volume
            and type(value)._scalar is PVCurve._scalar)


def image(value: Any, where: str, depth: int = 0, names: frozenset = frozenset()) -> tuple:
    """(``value`` as compiled code may read it, what keys it): a number, a
    tuple of numbers or an array as it is (an array copied), ``math`` or
    ``numpy`` (keyed by name), another module as the numbers among its
    attributes that the code names (``names``: ``sf.pressure_atmospheric``),
    a curve's or a fluid's image, or a plain Python function compiled the
    same way (keyed by its code and values); anything else raises
    NotCompiled."""
    if isinstance(value, (bool, int, float, complex, np.number, np.bool_)):
        return value, value
    if isinstance(value, tuple) and all(isinstance(v, (int, float)) for v in value):
        return value, value
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        copy = np.array(value)
        return copy, copy
    if isinstance(value, pytypes.ModuleType) and value in (np, math):
        return value, f"module {value.__name__}"
    if isinstance(value, pytypes.ModuleType):
        attrs = tuple((n, getattr(value, n)) for n in sorted(names)   # (a named tuple's)
                      if not n.startswith("_") and type(getattr(value, n, None)) in (int, float))
        if attrs:
            return _numbers_of(value.__name__, tuple(n for n, _ in attrs))(
                *(v for _, v in attrs)), ("module", value.__name__, attrs)
    if _plain_curve(value):
        got = CurveImage(value._knots.copy(), value._table.copy(), float(value._lo),
                         float(value._hi), bool(value._refuse))
        return got, got
    if isinstance(value, Fluid):
        got = FluidImage(float(value.rho))
        return got, got
    if isinstance(value, pytypes.FunctionType) and depth < settings.USER_CALL_DEPTH:
        copy, key = imaged(value, depth + 1)
        return numba.njit(boundscheck=True)(copy), key
    raise NotCompiled(f"{where} is a {type(value).__name__}, which compiled code cannot read")


#: the layout slots each kind of run-time value takes (after the component's
#: columns): a float its bits; a fluid its density's bits; a PV curve its
#: knots' address and number, its table's address, rows and columns, the
#: bits of its data's ends and whether it refuses volumes beyond them
_SLOTS = {"float": 1, "fluid": 1, "curve": 8}


def _runtime_kind(value: Any) -> str | None:
    """The kind of run-time value ``value`` is (a key of :data:`_SLOTS`), or
    None where it is compiled in as a constant."""
    if type(value) in (float, np.float64):
        return "float"
    if isinstance(value, Fluid):
        return "fluid"
    if _plain_curve(value):
        return "curve"
    return None


def _runtime_vars(func: Any) -> tuple:
    """The (name, kind) of the values of the user's function ``func`` that
    its kernel reads as run-time data (:func:`layout`): the floats, fluids
    and PV curves of its closure and of the module globals it reads (a
    script's ``K = 1e-9`` rebound in a loop; settings.USER_RUNTIME_VALUES)."""
    if not settings.USER_RUNTIME_VALUES:
        return ()
    found = []
    code = func.__code__
    for var, cell in zip(code.co_freevars, func.__closure__ or ()):
        try:
            kind = _runtime_kind(cell.cell_contents)
        except ValueError:          # not set: imaged says so
            return ()
        if kind is not None:
            found.append((var, kind))
    for var in sorted(_global_names(code)):
        kind = _runtime_kind(func.__globals__.get(var))
        if kind is not None and var not in code.co_freevars:
            found.append((var, kind))
    return tuple(found)


@functools.lru_cache(maxsize=64)
def _numbers_of(module: str, fields: tuple) -> type:
    """The named tuple that stands for the numbers ``fields`` of a module."""
    return collections.namedtuple(f"numbers_of_{module.replace('.', '_')}", fields)


@functools.lru_cache(maxsize=256)
def _attribute_names(code) -> frozenset:
    """The names ``code`` (and the code nested in it) loads as globals or
    attributes."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, pytypes.CodeType):
            names |= _attribute_names(const)
    return frozenset(names)


@functools.lru_cache(maxsize=256)
def _global_names(code) -> frozenset:
    """The global names ``code`` (and the code nested in it) loads."""
    names = {ins.argval for ins in dis.get_instructions(code)
             if ins.opname in ("LOAD_GLOBAL", "LOAD_NAME")}
    for const in code.co_consts:
        if isinstance(const, pytypes.CodeType):
            names |= _global_names(const)
    return frozenset(names)


def imaged(func: Any, depth: int = 0, runtime: dict | None = None) -> tuple:
    """(a copy of ``func`` whose closure and globals hold images of its own,
    the bytes that identify its code and those values: see :func:`image`).
    ``runtime``: {name: kind} of closure values read at run time (their kind
    keyed, not their value; the copy's cell holds None: the function that
    reads them is :func:`_rewrite`'s)."""
    if not isinstance(func, pytypes.FunctionType):
        raise NotCompiled(f"{func!r} is not a plain Python function")
    name = func.__name__
    if func.__defaults__ or func.__kwdefaults__:
        raise NotCompiled(f"{name} has default arguments")
    code = func.__code__
    cells, keys = [], []
    for var, cell in zip(code.co_freevars, func.__closure__ or ()):
        try:
            content = cell.cell_contents
        except ValueError:
            raise NotCompiled(f"{name}: {_SHOWN.get(var, var)} is not set") from None
        if runtime and var in runtime:
            kind = _runtime_kind(content)
            if kind != runtime[var]:
                raise NotCompiled(f"{name}'s {_SHOWN.get(var, var)} is no longer a "
                                  f"{runtime[var]}")
            cells.append(pytypes.CellType(None))
            keys.append((var, ("run-time", kind)))
            continue
        got, key = image(content, f"{name}'s {_SHOWN.get(var, var)}", depth,
                         _attribute_names(code))
        cells.append(pytypes.CellType(got))
        keys.append((var, key))
    glob: dict = {"__builtins__": func.__globals__.get("__builtins__", __builtins__)}
    for var in sorted(_global_names(code)):
        if var in func.__globals__:
            if runtime and var in runtime and var not in code.co_freevars:
                kind = _runtime_kind(func.__globals__[var])
                if kind != runtime[var]:
                    raise NotCompiled(f"{name}'s global {var} is no longer a {runtime[var]}")
                keys.append((var, ("run-time", kind)))
                continue
            glob[var], key = image(func.__globals__[var], f"{name}'s global {var}", depth,
                                   _attribute_names(code))
            keys.append((var, key))
    copy = pytypes.FunctionType(code, glob, name, None, tuple(cells) or None)
    copy.__qualname__ = func.__qualname__
    try:
        data = pickle.dumps(keys, protocol=4)
    except Exception as err:
        raise NotCompiled(f"{name}'s values cannot be keyed: {err}") from None
    return copy, _code_key(code) + data


@functools.lru_cache(maxsize=256)
def _code_key(code) -> bytes:
    """Bytes that identify ``code``'s meaning (its bytecode, constants, names,
    and the code nested in it; marshal's bytes are not stable: they depend
    on reference counts)."""
    parts = [code.co_code, repr((code.co_names, code.co_varnames, code.co_freevars,
                                 code.co_cellvars, code.co_argcount, code.co_flags,
                                 code.co_filename, getattr(code, "co_qualname", code.co_name))).encode()]
    for const in code.co_consts:
        parts.append(_code_key(const) if isinstance(const, pytypes.CodeType)
                     else repr((type(const).__name__, const)).encode())
    return b"\0".join(hashlib.sha256(p).digest() for p in parts)


#: the module of a source's signal given as a Python function: its head,
#: then its kernel (:func:`_signal_source`)
_SIGNAL_HEAD = '''\
"""softflow: a source's signal compiled (generated by softflow.solve.usercompile;
do not edit)."""
import math

from numba import carray, cfunc

from softflow.solve.usercompile import SIGNAL_SIGNATURE, floats_at, functions_for

signal, _ = functions_for(__name__)


@cfunc(SIGNAL_SIGNATURE, cache=True)
def kernel(key, t):
'''


def _signal_source(n: int) -> str:
    """The text of a signal's module whose function takes ``n`` run-time
    floats after t, read from the float array at the key's address."""
    args = "".join(f", flay[{k}]" for k in range(n))
    return _SIGNAL_HEAD + "".join([
        f"    flay = carray(floats_at(key), ({n},))\n" if n else "",
        "    try:\n",
        f"        value = float(signal(t{args}))\n",
        "    except Exception:\n",
        "        return math.nan\n",
        "    # not finite: NaN, handed back (numba's math gives inf or nan where\n",
        "    # Python's raises; the Python path says which)\n",
        "    return value if math.isfinite(value) else math.nan\n"])


#: the kernel's module: its head, then what :func:`source` writes for the
#: component (its variables, states and rows as scalars: no arrays made)
_HEAD = '''\
"""softflow: the compiled kernel of a user component (generated by
softflow.solve.usercompile; do not edit)."""
import math

import numpy as np
from numba import carray, cfunc, njit

from softflow.solve.usercompile import (SIGNATURE, CurveRef, FluidImage, floats_at,
                                       functions_for, layout_at)

ev, up = functions_for(__name__)
'''

#: an array-form function's adaptor (softflow.fons's ``_ArrayForm``): the
#: arrays fonsim's method fills, made from the scalars, as the Python path
#: makes them
_ARRAY_ADAPTOR = '''
{name}_method = {name}


@njit
def {name}({params}):
    out = np.zeros({n_out})
    arguments = np.empty({na})
{fill_args}    state = np.empty({ns})
{fill_state}    {name}_method({call})
    return out
'''

_TAIL = '''

@cfunc(SIGNATURE, cache=True)
def kernel(key, t, dt, jac, xp, nx, Sp, nS, Fp, nF, rawp, nraw, Soutp, nSout):
    lay = carray(layout_at(key), ({head},))
    flay = carray(floats_at(key), ({head},))
    if (nx < lay[0] or nS < lay[5] or nF < lay[1] + {neq} or nraw < lay[3]
            or (nSout != 0 and nSout < lay[5])):
        return 1
    try:
        return _evaluate(lay, flay, t, dt, jac, carray(xp, (nx,)), carray(Sp, (nS,)),
                         carray(Fp, (nF,)), carray(rawp, (nraw,)), carray(Soutp, (nSout,)))
    except Exception:
        return 1
'''



def _names(prefix: str, n: int) -> list:
    return [f"{prefix}{i}" for i in range(n)]


def _row_of(names: list) -> str:
    """A tuple's target or value of ``names`` (a 1-tuple keeps its comma)."""
    return ", ".join(names) + ("," if len(names) == 1 else "")


def _array_adaptor(name: str, form: tuple, n_extra: int, evaluate: bool) -> str:
    """The adaptor of an array-form ``evaluate`` (``update_state``) for the
    kernel's module: a function of (t or dt, the variables, the states, the
    run-time values) that fills fonsim's arrays and calls the method (its
    values, or its new states, returned as an array); ``form`` from
    :func:`_array_form`."""
    picks, nv, ns, na, n_out = form
    extra = [f"x{k}" for k in range(n_extra)]
    params = ["t"] + [f"v{k}" for k in range(nv)] + [f"s{k}" for k in range(ns)] + extra
    fill_args = "".join(f"    arguments[{j}] = v{int(k)}\n" for j, k in enumerate(picks))
    fill_state = "".join(f"    state[{k}] = s{k}\n" for k in range(ns))
    if evaluate:
        call = (f"out, np.zeros(({n_out}, {ns})), np.zeros(({n_out}, {na})), state, "
                "arguments, t")
    else:
        call = f"out, np.zeros(({n_out}, {na})), state, arguments, t"
    return _ARRAY_ADAPTOR.format(name=name, params=", ".join(params), n_out=n_out, na=na,
                                 ns=ns, fill_args=fill_args, fill_state=fill_state,
                                 call=", ".join([call] + extra))


def _array_form(f: Any) -> tuple | None:
    """(picks, number of variables, of states, of arguments, of outputs) of
    a fonsim array-form function (softflow.fons's ``_ArrayForm``: a method
    filling arrays, called with the variables its ``arguments`` picks), or
    None for any other function."""
    if not getattr(f, "array_form", False):
        return None
    picks, nv, ns, na = f._layout()
    n_out = f.comp.nb_equations if f.kind == "evaluate" else ns
    return tuple(int(k) for k in picks), int(nv), int(ns), int(na), int(n_out)


def source(uk, order: list | None = None, plan: tuple = ()) -> str:
    """The kernel module's text for the user kernel ``uk``: the arithmetic
    of :meth:`UserKernel.kernel_row` (its finite differences, their steps,
    the chain rule through the states) on scalars, each variable, state,
    row and Jacobian entry a name of its own (no array is made); ``order``:
    the tuple :func:`tuple_update` made of ``update_state``'s dict; ``plan``
    (:func:`kernel`): the run-time values read from the layout and passed to
    evaluate (0) and update_state (1) as their last arguments."""
    nv, ns, neq = uk.nv, uk.ns, uk.neq
    if neq < 1 or nv * max(neq, ns, 1) > settings.USER_UNROLL_MAX:
        raise NotCompiled(f"{nv} variables, {ns} states and {neq} rows: not a size a "
                          "compiled kernel unrolls")
    rates = _rates_of(uk) is not None
    ev_form = _array_form(uk.ev)
    up_form = _array_form(uk.up) if uk.up is not None else None
    if up_form is not None:
        order = list(range(ns))             # (its new states, an array in their order)
    V, O, N, Fn = _names("v", nv), _names("o", ns), _names("n", ns), _names("f", neq)
    P, M = _names("p", neq), _names("m", ns)
    A = [f"a{k}" for k, entry in enumerate(plan) if entry[0] == 0]
    B = [f"a{k}" for k, entry in enumerate(plan) if entry[0] == 1]
    rel = float(_rel())

    def pick(binding, first, v, s):
        return ", ".join(first if kind == "t" else (v if kind == "v" else s)[int(k)]
                         for kind, k in binding)

    def residual(v, s):
        return f"_residual(t, {', '.join(A + v + s)})"

    def states(v):
        return f"_states(dt, {', '.join(B + v + O)})"

    def extra(names):
        return "".join(f", {n}" for n in names)

    def step(x, scale):
        return f"        h = {rel!r} * max(abs({x}), {float(scale)!r})"

    out = [_HEAD]
    if ev_form is not None:
        out.append(_array_adaptor("ev", ev_form, len(A), True))
    if up_form is not None:
        out.append(_array_adaptor("up", up_form, len(B), False))
    out += ["",
           "@njit", f"def _residual(t, {', '.join(A + V + N)}):",
           f"    r = ev({pick(uk.ev_args, 't', V, N)}{extra(A)})",
           f"    if len(r) != {neq}:",
           "        raise ValueError('evaluate returned another number of residuals')",
           *[f"    f{i} = float(r[{i}])" for i in range(neq)],
           # not finite: handed back (numba's math gives inf or nan where
           # Python's raises; the Python path says which)
           f"    if not ({' and '.join(f'math.isfinite(f{i})' for i in range(neq))}):",
           "        raise ValueError('a residual is not finite')",
           f"    return {_row_of(Fn)}", "", ""]
    if ns:
        out += ["@njit", f"def _states(dt, {', '.join(B + V + O)}):"]
        if uk.up is None:
            out.append(f"    return {_row_of(O)}")
        elif rates:     # state_rates(variables) -> {state: rate}: the state + dt rate
            # (userkernel._update_from_rates: its binding is dt, the states, then
            # the rates' variables)
            out.append(f"    o = up({pick(uk.up_args[1 + ns:], 'dt', V, O)}{extra(B)})")
            got = ([f"o[{n!r}]" for n in uk.snames] if order is None
                   else [f"o[{i}]" for i in order])
            out += [f"    n{k} = o{k} + dt * float({g})" for k, g in enumerate(got)]
        else:
            out.append(f"    o = up({pick(uk.up_args, 'dt', V, O)}{extra(B)})")
            if order is None:       # the dict the user's update_state returns
                out += [f"    if len(o) != {ns}:",
                        "        raise KeyError('update_state returned other states')"]
                out += [f"    n{k} = float(o[{n!r}])" for k, n in enumerate(uk.snames)]
            else:                   # its dict rewritten as a tuple (tuple_update)
                out += [f"    n{k} = float(o[{i}])" for k, i in enumerate(order)]
        if ns and uk.up is not None:
            out += [f"    if not ({' and '.join(f'math.isfinite({n})' for n in N)}):",
                    "        raise ValueError('a state is not finite')",
                    f"    return {_row_of(N)}"]
        out += ["", ""]
    out += ["@njit", "def _evaluate(lay, flay, t, dt, jac, x, S, F, raw, Sout):",
            "    r0, j0, j1, s0, has_states = lay[1], lay[2], lay[3], lay[4], lay[6]"]
    at = LAYOUT_HEAD + nv
    for k, (_, _, kind) in enumerate(plan):
        if kind == "float":
            out.append(f"    a{k} = flay[{at}]")
        elif kind == "fluid":
            out.append(f"    a{k} = FluidImage(flay[{at}])")
        else:
            out.append(f"    a{k} = CurveRef(lay[{at}], lay[{at + 1}], lay[{at + 2}], "
                       f"flay[{at + 5}], flay[{at + 6}], lay[{at + 7}] != 0)")
        at += _SLOTS[kind]
    out += [f"    v{k} = x[lay[{LAYOUT_HEAD + k}]]" for k in range(nv)]
    out += [f"    o{k} = S[s0 + {k}]" for k in range(ns)]
    if ns:
        out.append(f"    {_row_of(N)} = {states(V)}")
    out.append(f"    {_row_of(Fn)} = {residual(V, N)}")
    out += [f"    F[r0 + {e}] = f{e}" for e in range(neq)]
    if ns:
        out.append("    if Sout.size and has_states:")
        out += [f"        Sout[s0 + {k}] = n{k}" for k in range(ns)]
    out.append("    if jac and j1 > j0:")
    J = {(e, k): f"J{e}_{k}" for e in range(neq) for k in range(nv)}
    out += [f"        {J[e, k]} = 0.0" for e in range(neq) for k in range(nv)]
    for k in map(int, uk.ev_v):
        out += [step(f"v{k}", uk.vscale[k]),
                f"        {_row_of(P)} = {residual(V[:k] + [f'v{k} + h'] + V[k + 1:], N)}"]
        out += [f"        {J[e, k]} = (p{e} - f{e}) / h" for e in range(neq)]
    if uk.up is not None and ns and len(uk.ev_s):
        # the chain rule through the end-of-step states: J += dF/dS dS/dv
        D = {(e, j): f"D{e}_{j}" for e in range(neq) for j in range(ns)}
        E = {(j, k): f"E{j}_{k}" for j in range(ns) for k in range(nv)}
        out += [f"        {name} = 0.0" for name in [*D.values(), *E.values()]]
        for j in map(int, uk.ev_s):
            out += [step(f"n{j}", uk.sscale[j]),
                    f"        {_row_of(P)} = {residual(V, N[:j] + [f'n{j} + h'] + N[j + 1:])}"]
            out += [f"        {D[e, j]} = (p{e} - f{e}) / h" for e in range(neq)]
        for k in map(int, uk.up_v):
            out += [step(f"v{k}", uk.vscale[k]),
                    f"        {_row_of(M)} = {states(V[:k] + [f'v{k} + h'] + V[k + 1:])}"]
            out += [f"        {E[j, k]} = (m{j} - n{j}) / h" for j in range(ns)]
        for e in range(neq):
            for k in range(nv):
                out.append("        acc = 0.0")
                out += [f"        acc += {D[e, j]} * {E[j, k]}" for j in range(ns)]
                out.append(f"        {J[e, k]} += acc")
    out += [f"        raw[j0 + {e * nv + k}] = {J[e, k]}" for e in range(neq)
            for k in range(nv)]
    out.append("    return 0")
    return "\n".join(out) + "\n" + _TAIL.format(head=at, neq=neq)


def _rel() -> float:
    from .userkernel import _REL
    return _REL


#: the user's compiled functions handed to a kernel module as it is imported
_HANDED: dict = {}
#: kernel modules imported in this process, by name: (the module, its C address)
_LOADED: dict = {}
#: names whose compile failed in this process: the reason
_FAILED: dict = {}
#: how many kernels this process compiled for each code (its values aside)
_COMPILES: dict = {}


def functions_for(name: str) -> tuple:
    """The (evaluate, update) a kernel module named ``name`` compiles."""
    return _HANDED.pop(name)


def cache_root() -> Path:
    """Where kernel modules are written: ``softflow-user`` in numba's cache
    directory (NUMBA_CACHE_DIR, else the user's cache directory)."""
    base = numba.config.CACHE_DIR
    if not base:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"),
                                                                ".cache")
        base = os.path.join(base, "numba")
    return Path(base) / "softflow-user"


def _writable(root: Path) -> Path:
    """``root``, made, where it can be written; else a temporary directory,
    one per process (said once)."""
    got = _ROOTS.get(root)
    if got is not None:
        return got
    try:
        root.mkdir(parents=True, exist_ok=True)
        probe = root / f".probe-{os.getpid()}"
        probe.write_text("", encoding="utf-8")
        probe.unlink()
        got = root
    except OSError:
        got = Path(tempfile.mkdtemp(prefix="softflow-user-"))
        warnings.warn(f"softflow cannot write compiled user components under {root}; they "
                      f"are compiled in {got} for this process only (set NUMBA_CACHE_DIR to a "
                      "writable directory to keep them)", RuntimeWarning, stacklevel=2)
    _ROOTS[root] = got
    return got


#: each cache root asked for in this process: where kernels are written
_ROOTS: dict = {}


def _write_once(path: Path, text: str) -> None:
    """Write ``path`` unless it exists (atomically: a concurrent writer's file
    is kept, so numba's cache beside it stays valid)."""
    if path.exists():
        return
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text, encoding="utf-8")
    try:
        os.link(tmp, path)
    except FileExistsError:
        pass
    except OSError:            # no hard links here: a rename (last writer wins)
        os.replace(tmp, path)
        return
    tmp.unlink(missing_ok=True)


@functools.lru_cache(maxsize=1)
def _own_stamp() -> bytes:
    """What every kernel's name also hashes: the text of softflow's compiled
    laws (some are compiled into a kernel), softflow's, numba's and
    Python's versions and this module's text (the template and the
    images)."""
    from ..laws import source_stamp      # the laws a kernel compiles in (curve_point)
    h = hashlib.sha256(source_stamp())
    for part in (__version__, numba.__version__, sys.version,
                 Path(__file__).read_text(encoding="utf-8")):
        h.update(part.encode())
    return h.digest()


def kernel_address(uk) -> int | None:
    """The C address of the compiled kernel of the user kernel ``uk`` (see
    the module), or None where it is called back (the reason logged)."""
    return kernel(uk)[0]


def kernel(uk) -> tuple:
    """(:func:`kernel_address`, the :func:`values_key` of the values it was
    compiled with, its plan: the run-time values its layout holds, see
    :func:`layout`; None, None, None where ``uk`` is called back)."""
    if numba.config.DISABLE_JIT or not settings.COMPILED_USER_CODE:
        return None, None, None
    who = uk.comp.describe()
    what = ("evaluate" if uk.up is None else "evaluate, state_rates"
            if _rates_of(uk) is not None else "evaluate, update_state")
    runtime = True
    while True:
        try:
            roles = [(f, None if k == 0 else tuple(uk.snames))
                     for k, f in enumerate(_functions(uk))]
            funcs, plan, order = [], [], None
            for i, (func, snames) in enumerate(roles):
                copy, key, got, rt = _prepared(func, snames, runtime)
                funcs.append((copy, key))
                plan += [(i, var, kind) for var, kind in rt]
                if snames is not None:
                    order = got
            text = source(uk, order, tuple(plan))
            for i, var, kind in plan:          # readable now (a fluid's density, say)
                _slots(kind, _cell(roles[i][0], var), [])
        except NotCompiled as why:
            _note(who, str(why))
            return None, None, None
        except Exception as err:        # the user's objects, read: called back as before
            _note(who, f"{type(err).__name__}: {err}")
            return None, None, None
        address = _address(text, funcs, f"the user component {who} ({what})", who)
        if address is None and plan and _refused(text, funcs):
            runtime = False     # (numba refused the values as arguments: as constants)
            continue
        return (address, None if address is None else _key_of(key for _, key in funcs),
                None if address is None else tuple(plan))


def _prepared(func: Any, snames: tuple | None, runtime: bool,
              only: tuple | None = None) -> tuple:
    """(the user's function ``func`` to compile, its key, the order of its
    dict's states or None, its run-time values' (name, kind)): its closure's
    floats, fluids and curves (``only`` these (name, kind) where given) as
    its last arguments where ``runtime`` and its source can be rewritten so
    (:func:`_rewrite`), else compiled in."""
    rt = (_runtime_vars(func) if only is None else only) if runtime else ()
    if rt:
        copy, key = imaged(func, runtime=dict(rt))
        got = _rewrite(func, copy, snames, tuple(var for var, _ in rt))
        if got is not None:
            return got[0], key, got[1], rt
    copy, key = imaged(func)
    got = _rewrite(func, copy, snames, ()) if snames is not None else None
    return (copy, key, None, ()) if got is None else (got[0], key, got[1], ())


def _rates_of(uk) -> Any:
    """The user's ``state_rates`` function of the user kernel ``uk``, or None
    (then ``uk.up`` is the user's ``update_state``, if any)."""
    rates = getattr(uk.comp, "state_rates", None) if uk.up is not None else None
    return getattr(rates, "func", rates)


def _functions(uk) -> list:
    """The user's functions a kernel of ``uk`` compiles: ``evaluate``, then
    ``update_state`` or ``state_rates`` where it has states."""
    wrapped = [uk.ev] if uk.up is None else [uk.ev, uk.up if _rates_of(uk) is None else None]
    funcs = []
    for w in wrapped:
        if w is None:
            funcs.append(_rates_of(uk))
        elif _array_form(w) is not None:
            funcs.append(w.method)        # (fonsim's array form: called by an adaptor)
        else:
            # (softflow.fons wraps a function to drop the Jacobian fonsim lets it
            # return: its own function compiled, whose answer the kernel checks)
            funcs.append(getattr(w.func, "_softflow_values_of", w.func))
    return [_desugared(f) for f in funcs]


def _cell(func: Any, var: str) -> Any:
    """The value of ``func``'s closure variable ``var``, or of its module's
    global ``var``."""
    code = func.__code__
    if var in code.co_freevars:
        return func.__closure__[code.co_freevars.index(var)].cell_contents
    return func.__globals__[var]


def _key_of(keys) -> bytes:
    """:func:`values_key` of the functions' keys from :func:`imaged`."""
    return hashlib.sha256(b"".join(keys)).digest()


def tuple_update(func: Any, copy: Any, snames: list) -> tuple | None:
    """(``copy`` of the user's ``update_state`` ``func`` whose dict answer
    ``return {'state': value, ...}`` is written as a tuple of its values,
    the tuple's position of each of ``snames``), or None where its source
    is not that (then the dict is compiled as written): :func:`_rewrite`
    with no run-time values.

    Why: the dict is numba's typed dict, whose compile takes ~4.6 s the
    first time in a process; the tuple, a fraction of a second. Only the
    answer's form changes: the values are the same expressions, in the same
    order. Every ``return`` of the function must be a dict display of the
    same string keys, each state once (a lambda's body likewise)."""
    return _rewrite(func, copy, tuple(snames), ())


def _rewrite(func: Any, copy: Any, snames: tuple | None, extra: tuple) -> tuple | None:
    """The user's function ``func`` written again from its source: (the
    function, the order of its dict's states or None), or None where there
    is nothing to rewrite or it cannot be rewritten. ``snames`` (an
    ``update_state``'s states): its dict answer written as a tuple
    (:func:`tuple_update`) where it has that form; ``extra``: closure
    variables that become the function's last arguments (run-time values,
    :func:`layout`; needed: None where they cannot be). Its source (its
    file's text as ``linecache`` has it) must compile to the running
    function's own bytecode (a file edited since it was imported is not
    rewritten). ``copy`` (from
    :func:`imaged`) gives the globals and the closure's other values, which
    the rewritten function reads as its globals."""
    code = func.__code__
    rewritten = _rewritten(code, code.co_filename, code.co_name, snames, extra)
    if rewritten is None:
        return None
    module, order = rewritten
    code = func.__code__
    space = dict(copy.__globals__)
    space.update((var, cell.cell_contents)
                 for var, cell in zip(code.co_freevars, copy.__closure__ or ())
                 if var not in extra)
    try:            # defines the function only
        exec(module, space)
    except Exception:
        return None
    return space["_softflow_fn"], order


@functools.lru_cache(maxsize=256)
def _rewritten(code, filename: str, name: str, snames: tuple | None,
               extra: tuple) -> tuple | None:
    """:func:`_rewrite`'s rewrite of the function of ``code``, named
    ``name``: (the compiled module that defines it, the order or None), or
    None; found once a process for each code and its file (equal code
    objects of other files are one key of a cache otherwise)."""
    if snames is None and not extra:
        return None
    node = _node_of(code, name)
    if node is None:
        return None
    lam = isinstance(node, ast.Lambda)
    order = _as_tuple(node, lam, snames) if snames is not None else None
    if order is None and not extra:
        return None
    body = [ast.Return(value=node.body)] if lam else node.body
    node.args.args = node.args.args + [ast.arg(arg=v) for v in extra]
    fdef = ast.FunctionDef(name="_softflow_fn", args=node.args, body=body,
                           decorator_list=[], returns=None, type_comment=None)
    module = ast.fix_missing_locations(ast.Module(body=[fdef], type_ignores=[]))
    try:            # (a `nonlocal` there, say, does not compile)
        return compile(module, code.co_filename, "exec", flags=_futures(code),
                       dont_inherit=True), order
    except Exception:
        return None


def _futures(code) -> int:
    """The ``from __future__`` flags ``code`` was compiled with (what its
    text compiles with again; not this module's own)."""
    return code.co_flags & _FUTURE_FLAGS


#: every ``__future__`` feature's compiler flag
_FUTURE_FLAGS = functools.reduce(
    lambda a, b: a | b, (getattr(__future__, f).compiler_flag
                         for f in __future__.all_feature_names), 0)


def _node_of(code, name: str) -> Any:
    """The syntax tree (a new one) of the function or lambda of ``code``,
    named ``name``, from its file's text as ``linecache`` has it, where it
    compiles to ``code``'s own bytecode (:func:`_compiles_to`); else None."""
    try:        # the whole file: a lambda may sit inside a call over several lines
        linecache.checkcache(code.co_filename)
        tree = ast.parse("".join(linecache.getlines(code.co_filename)))
    except (OSError, TypeError, SyntaxError, ValueError):
        return None
    line = code.co_firstlineno
    args = list(code.co_varnames[:code.co_argcount])
    lam = name == "<lambda>"
    found = [n for n in ast.walk(tree)
             if (isinstance(n, ast.Lambda) if lam else
                 isinstance(n, ast.FunctionDef) and n.name == name)
             and n.lineno == line and [a.arg for a in n.args.args] == args
             and not (n.args.posonlyargs or n.args.kwonlyargs or n.args.vararg
                      or n.args.kwarg or n.args.defaults)
             and not getattr(n, "decorator_list", None)]
    if len(found) != 1 or not _compiles_to(found[0], code):
        return None
    return found[0]


def _holds(value: Any) -> bool:
    """Whether ``value`` is an object whose attributes a user's function may
    read (``self.k``, ``self.curve``): not a value :func:`image` reads
    itself, a function, a class or a module."""
    return (hasattr(value, "__dict__") and _runtime_kind(value) is None
            and not isinstance(value, (type, pytypes.ModuleType, pytypes.FunctionType,
                                       pytypes.MethodType, np.ndarray, PVCurve, Fluid)))


def _desugared(func: Any) -> Any:
    """``func`` itself, or where it reads attributes of objects (a bound
    method's ``self``, or a closure's object: ``self.k``, ``self.curve``) a
    function of the same code with each such ``obj.attr`` a closure variable
    holding the attribute's value now (:func:`_attribute_code`), which
    compiles as the closures do (run-time values or constants); raises
    NotCompiled where an object is used otherwise."""
    method = isinstance(func, pytypes.MethodType)
    base = func.__func__ if method else func
    if not isinstance(base, pytypes.FunctionType):
        return func
    code = base.__code__
    holders = {}
    if method:
        holders[code.co_varnames[0]] = func.__self__
    values = {}
    for var, cell in zip(code.co_freevars, base.__closure__ or ()):
        try:
            values[var] = cell.cell_contents
        except ValueError:
            continue
        if _holds(values[var]):
            holders[var] = values[var]
    if not holders:
        return func
    made = _attribute_code(code, code.co_filename, base.__name__, tuple(sorted(holders)),
                           method)
    if made is None:
        if _node_of(code, base.__name__) is None:
            raise NotCompiled(f"{base.__name__}'s source cannot be read as written (a "
                              "decorated function, or one without a file)")
        raise NotCompiled(f"{base.__name__} uses {', '.join(sorted(holders))} other than "
                          "by reading its attributes")
    inner, attrs = made
    cells = []
    for var in inner.co_freevars:
        if var in attrs:
            holder, attr = attrs[var]
            try:
                cells.append(pytypes.CellType(getattr(holders[holder], attr)))
            except Exception as err:
                raise NotCompiled(f"{base.__name__}: {holder}.{attr}: {err}") from None
        else:
            cells.append(pytypes.CellType(values[var]))
    fn = pytypes.FunctionType(inner, base.__globals__, base.__name__, None, tuple(cells))
    fn.__qualname__ = base.__qualname__
    return fn


#: what a variable of :func:`_attribute_code` stands for, as messages say it
_SHOWN: dict = {}


@functools.lru_cache(maxsize=256)
def _attribute_code(code, filename: str, name: str, holders: tuple,
                    method: bool) -> tuple | None:
    """(the code of the function of ``code`` with each ``h.attr`` of the
    names ``holders`` a free variable ``_sf_<len(h)>_h_attr`` (a method's first
    argument dropped), {that variable: (h, attr)}), or None where a holder
    is used other than by reading an attribute or the source is not had.
    Its text is kept in ``linecache`` under a name of its own (the run-time
    values' rewrite, :func:`_rewritten`, reads it there)."""
    node = _node_of(code, name)
    if node is None:
        return None
    own = node.args.args[0] if method and node.args.args else None
    if any(isinstance(n, ast.arg) and n.arg in holders and n is not own
           for n in ast.walk(node)):
        return None         # (a nested function's parameter of that name: another object)
    attrs: dict = {}

    class Reads(ast.NodeTransformer):
        def visit_Attribute(self, n):
            if (isinstance(n.value, ast.Name) and n.value.id in holders
                    and isinstance(n.ctx, ast.Load)):
                var = f"_sf_{len(n.value.id)}_{n.value.id}_{n.attr}"     # (unambiguous)
                attrs[var] = (n.value.id, n.attr)
                _SHOWN[var] = f"{n.value.id}.{n.attr}"
                return ast.copy_location(ast.Name(id=var, ctx=ast.Load()), n)
            return self.generic_visit(n)
    node = Reads().visit(node)
    if any(isinstance(n, ast.Name) and n.id in holders for n in ast.walk(node)):
        return None
    args = node.args
    if method:
        args.args = args.args[1:]
    body = [ast.Return(value=node.body)] if isinstance(node, ast.Lambda) else node.body
    fname = "_sf_lambda" if isinstance(node, ast.Lambda) else name
    inner = ast.FunctionDef(name=fname, args=args, body=body, decorator_list=[],
                            returns=None, type_comment=None)
    free = [v for v in code.co_freevars if v not in holders] + sorted(attrs)
    outer = ast.FunctionDef(
        name="_sf_outer", args=ast.arguments(posonlyargs=[], args=[ast.arg(arg=v) for v in free],
                                             kwonlyargs=[], kw_defaults=[], defaults=[]),
        body=[inner, ast.Return(value=ast.Name(id=fname, ctx=ast.Load()))],
        decorator_list=[], returns=None, type_comment=None)
    module = ast.fix_missing_locations(ast.Module(body=[outer], type_ignores=[]))
    try:
        text = ast.unparse(module) + "\n"
        filename = f"<softflow attributes {hashlib.sha256(text.encode()).hexdigest()[:16]}>"
        top = compile(text, filename, "exec", flags=_futures(code), dont_inherit=True)
    except Exception:
        return None
    linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
    outer_code = next(c for c in top.co_consts if isinstance(c, pytypes.CodeType))
    inner_code = next(c for c in outer_code.co_consts if isinstance(c, pytypes.CodeType)
                      and c.co_name == fname)
    return inner_code, attrs


def _as_tuple(node, lam: bool, snames: tuple) -> list | None:
    """Rewrite the dict answers of the function or lambda ``node`` as tuples
    of the same values where each is a display of the states ``snames``
    (in place): each state's position in them; None (nothing changed) where
    they are not that."""
    answers = [node.body] if lam else [r.value for r in _returns(node)]
    keys = None
    for answer in answers:
        if not (isinstance(answer, ast.Dict) and all(
                isinstance(k, ast.Constant) and isinstance(k.value, str) for k in answer.keys)):
            return None
        got = [k.value for k in answer.keys]      # type: ignore[union-attr]
        if keys is None:
            keys = got
        elif got != keys:
            return None
    if not keys or len(set(keys)) != len(keys) or sorted(keys) != sorted(snames):
        return None
    for answer in answers:
        answer.__class__ = ast.Tuple                    # the same values, in order
        answer.elts, answer.ctx = answer.values, ast.Load()    # type: ignore[attr-defined]
    return [keys.index(n) for n in snames]


def _returns(node) -> list:
    """The ``return`` statements of the function ``node`` (not of functions
    nested in it); none with no value."""
    found, todo = [], list(node.body)
    while todo:
        n = todo.pop()
        if isinstance(n, ast.Return):
            found.append(n)
        elif not isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda,
                                ast.ClassDef)):
            todo.extend(ast.iter_child_nodes(n))
    if any(r.value is None for r in found):
        return []
    return found


def _compiles_to(node, code) -> bool:
    """Whether the function or lambda ``node``, compiled where its free
    variables are an enclosing function's, has ``code``'s bytecode, names
    and constants."""
    inner = (node if isinstance(node, ast.FunctionDef)
             else ast.Assign(targets=[ast.Name(id="_f", ctx=ast.Store())], value=node))
    outer = ast.FunctionDef(
        name="_outer", args=ast.arguments(posonlyargs=[], args=[ast.arg(arg=v) for v in
                                                               code.co_freevars],
                                          kwonlyargs=[], kw_defaults=[], defaults=[]),
        body=[inner], decorator_list=[], returns=None, type_comment=None)
    try:
        top = compile(ast.fix_missing_locations(ast.Module(body=[outer], type_ignores=[])),
                      code.co_filename, "exec", flags=_futures(code), dont_inherit=True)
    except (SyntaxError, ValueError, TypeError):
        return False
    stack = list(top.co_consts)
    while stack:
        c = stack.pop()
        if isinstance(c, pytypes.CodeType):
            if c.co_name == code.co_name and _same_code(c, code):
                return True
            stack.extend(c.co_consts)
    return False


def _same_code(a, b) -> bool:
    """Whether the code objects ``a`` and ``b`` have the same bytecode, names
    and constants (each constant with its type: 2 is not 2.0, -0.0 is not
    0.0; nested code compared so too, its line numbers aside)."""
    if (a.co_code != b.co_code or a.co_names != b.co_names
            or a.co_varnames != b.co_varnames or len(a.co_consts) != len(b.co_consts)):
        return False
    for x, y in zip(a.co_consts, b.co_consts):
        if isinstance(x, pytypes.CodeType) and isinstance(y, pytypes.CodeType):
            if not _same_code(x, y):
                return False
        elif type(x) is not type(y) or repr(x) != repr(y):
            return False
    return True


def values_key(uk, plan: tuple = ()) -> bytes | None:
    """A key of the values the user kernel ``uk``'s functions read now (from
    their closures and globals, as :func:`imaged` reads them; of the
    run-time values of ``plan``, from :func:`kernel`, their kinds alone), or
    None where they cannot be read so: :meth:`CompiledNetwork.check_user_values`
    compares it with the key of the values its kernel was compiled with."""
    try:
        funcs = _functions(uk)
        return _key_of(imaged(f, runtime={var: kind for i, var, kind in plan if i == k})[1]
                       for k, f in enumerate(funcs))
    except Exception:
        return None


def signal_address(signal) -> tuple | None:
    """(the C address, its key) of a source's signal given as a Python
    function (``signal``: the source's ``_Signal``), compiled as
    :data:`SIGNAL_SIGNATURE` (its value in SI, NaN where it raised), or None
    where it is called back (the reason logged). Its function must return
    SI floats (a pint Quantity is not compiled). The floats of its closure
    are run-time values (settings.USER_RUNTIME_VALUES: one compile for all
    their values), read now into an array the signal holds, whose address
    is the key (0 where there are none)."""
    if numba.config.DISABLE_JIT or not settings.COMPILED_USER_CODE:
        return None
    who = f"{signal.owner}: {signal.name}"
    runtime = True
    while True:
        try:
            rt = tuple((var, kind) for var, kind in _runtime_vars(signal.func)
                       if kind == "float") if runtime else ()
            func, key, _, rt = _prepared(signal.func, None, bool(rt), only=rt)
            values = np.array([float(_cell(signal.func, var)) for var, _ in rt])
        except NotCompiled as why:
            _note(who, str(why))
            return None
        except Exception as err:
            _note(who, f"{type(err).__name__}: {err}")
            return None
        text = _signal_source(len(rt))
        address = _address(text, [(func, key)], f"{who} (t)", who)
        if address is None and rt and _refused(text, [(func, key)]):
            runtime = False     # (numba refused the values as arguments: as constants)
            continue
        if address is None:
            return None
        if not rt:
            return address, 0
        # the signal's array of these run-time values (one per number of
        # them, written in place: a Simulation run before keeps a valid key)
        held = signal.__dict__.setdefault("_softflow_runtime", {})
        data = held.setdefault(len(rt), np.zeros(len(rt)))
        data[:] = values
        return address, data.ctypes.data


def _address(text: str, funcs: list, what: str, who: str) -> int | None:
    """The address of ``kernel`` in the module ``text`` that compiles the
    functions ``funcs`` ((copy, key) pairs from :func:`imaged`): loaded in
    this process, or from numba's cache, or compiled now; None where numba
    cannot compile them (remembered). One thread at a time (Simulations
    built in threads: a module is imported once)."""
    name = _name_of(text, funcs)
    got = _LOADED.get(name)
    if got is not None:
        return got[1]
    with _LOCK:
        return _load(name, text, funcs, what, who)


def _name_of(text: str, funcs: list) -> str:
    """The name of the kernel module ``text`` that compiles ``funcs``."""
    h = hashlib.sha256(_own_stamp())
    for part in [text.encode()] + [key for _, key in funcs]:
        h.update(hashlib.sha256(part).digest())
    return f"softflow_user_{h.hexdigest()[:32]}"


def _refused(text: str, funcs: list) -> bool:
    """Whether numba refused to compile the module ``text`` (not: the
    compile was not tried, settings.USER_COMPILES_MAX)."""
    return _name_of(text, funcs) in _FAILED


#: held while a kernel module is found, loaded or compiled
_LOCK = threading.RLock()


def _load(name: str, text: str, funcs: list, what: str, who: str) -> int | None:
    """:func:`_address`'s work for the module ``name``, under its lock."""
    got = _LOADED.get(name)
    if got is not None:
        return got[1]
    if name in _FAILED:
        _note(who, _FAILED[name])
        return None
    root = _writable(cache_root())
    failed = root / f"{name}.failed"
    if failed.exists():
        _touch(failed)
        _FAILED[name] = failed.read_text(encoding="utf-8")
        _note(who, _FAILED[name])
        return None
    path = root / f"{name}.py"
    if not path.exists():
        # not compiled before (its module unwritten): a compile, unless the
        # same code was compiled for other values too often in this process
        code = hashlib.sha256(b"".join(_code_key(copy.__code__) for copy, _ in funcs)).digest()
        done = _COMPILES.get(code, 0)
        if done >= settings.USER_COMPILES_MAX:
            if done == settings.USER_COMPILES_MAX:
                log.info("%s is called back in Python from now on in this process: it was "
                         "compiled for %d sets of the values it reads already (each new set "
                         "is a compile of its own, ~1 s; settings.USER_COMPILES_MAX)", who,
                         done)
                _COMPILES[code] = done + 1
            _note(who, "compiled for other values too often in this process")
            return None
        _COMPILES[code] = done + 1
        _prune(root)
    _write_once(path, text)
    _touch(path)
    start = time.perf_counter()
    # bounds checked: an index out of range raises (the Python path then
    # raises it naming the component) instead of reading past an array
    jitted = [numba.njit(boundscheck=True)(copy) for copy, _ in funcs]
    _HANDED[name] = tuple(jitted + [None] * (2 - len(jitted)))
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)      # type: ignore[arg-type]
        sys.modules[name] = module
        spec.loader.exec_module(module)                      # type: ignore[union-attr]
    except Exception as err:
        sys.modules.pop(name, None)
        if not isinstance(err, numba.core.errors.NumbaError):
            _note(who, f"its kernel did not load: {type(err).__name__}: {err}")
            return None
        reason = f"numba cannot compile it: {_first_reason(err)}"
        _FAILED[name] = reason
        try:
            failed.write_text(reason, encoding="utf-8")
        except OSError:
            pass
        _note(who, reason)
        return None
    finally:
        _HANDED.pop(name, None)
    took = time.perf_counter() - start
    if not module.kernel.cache_hits and took > settings.COMPILE_NOTICE:
        log.info("compiled %s with numba in %.1f s, once; cached in %s", what, took, root)
    address = int(module.kernel.address)
    _LOADED[name] = (module, address)
    return address


def _touch(path: Path) -> None:
    """Mark the module (or refusal marker) ``path`` as used now: the
    modification time of ``path`` + ``.used`` beside it, which
    :func:`_prune` keeps by (not the module's own: numba before 0.68 takes a
    module whose time changed for an edited one and compiles it again)."""
    try:
        used = path.with_name(path.name + ".used")
        used.touch()
    except OSError:
        pass


#: the cache roots pruned in this process
_PRUNED: set = set()


def _prune(root: Path) -> None:
    """Delete the kernel modules under ``root`` not used (loaded or
    compiled, :func:`_touch`) for settings.USER_CACHE_DAYS days, their
    refusal markers and numba's cache files of them: once a process, at its
    first compile (each new set of constants and each version of softflow,
    numba or Python writes modules of its own, which would pile up)."""
    if root in _PRUNED:
        return
    _PRUNED.add(root)
    cutoff = time.time() - 86400.0 * settings.USER_CACHE_DAYS

    def last_used(p: Path) -> float:
        used = p.with_name(p.name + ".used")
        return max(p.stat().st_mtime, used.stat().st_mtime if used.exists() else 0.0)
    # numba's cache files: beside the modules, or under NUMBA_CACHE_DIR in a
    # folder named after this one (numba's own layout for a set cache dir)
    caches = [root / "__pycache__"] + sorted(Path(numba.config.CACHE_DIR).glob(
        f"{root.name}_*")) if numba.config.CACHE_DIR else [root / "__pycache__"]
    try:
        old = [p for p in root.glob("softflow_user_*")
               if p.suffix in (".py", ".failed") and last_used(p) < cutoff]
    except OSError:
        return
    for p in old:
        try:
            p.unlink()
            p.with_name(p.name + ".used").unlink(missing_ok=True)
            if p.suffix == ".py":
                for cache in caches:
                    for q in cache.glob(f"{p.stem}.*"):
                        q.unlink()
        except OSError:
            pass


def _first_reason(err: Exception) -> str:
    """The line of numba's message that says what it could not compile."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(err))      # numba's colours
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    said = [line for line in lines if not line.startswith(("Failed in ", "During:"))]
    return (said or lines or [type(err).__name__])[0]


def _note(who: str, why: str) -> None:
    log.debug("%s is called back in Python, not compiled: %s", who, why)


class Layout(np.ndarray):
    """A compiled user component's layout (int64, see :func:`layout`), which
    holds the arrays its run-time values point to (``keep``) and a digest
    of those values (``digest``: equal for equal values)."""
    keep: list = []
    digest: bytes = b""


def layout(g, plan: tuple = ()) -> Layout:
    """The layout a compiled kernel reads for the user group ``g`` (see
    :data:`LAYOUT_HEAD`), its run-time values (``plan`` from :func:`kernel`)
    after the component's columns: its address is the kernel's key."""
    col = np.asarray(g.col[0], dtype=np.int64)
    uk = g.row
    if (g.r1 - g.r0 != uk.neq or g.j1 - g.j0 not in (0, uk.neq * uk.nv) or col.size != uk.nv
            or (g.has_states and g.s1 - g.s0 != uk.ns)):
        raise RuntimeError(f"softflow: {uk.comp.describe()}'s places in the network are not "
                           "its kernel's sizes")
    head = [int(col.max()) + 1 if col.size else 0, g.r0, g.j0, g.j1, g.s0, g.s1,
            int(bool(g.has_states))]
    n_rt = sum(_SLOTS[kind] for _, _, kind in plan)
    lay = np.concatenate([np.array(head, dtype=np.int64), col,
                          np.zeros(n_rt, dtype=np.int64)]).view(Layout)
    if not refill(lay, uk, plan):
        raise RuntimeError(f"softflow: {uk.comp.describe()}'s run-time values could not be "
                           "read into its layout")
    return lay


def refill(lay: Layout, uk, plan: tuple) -> bool:
    """Write the run-time values of the user kernel ``uk`` now into its
    layout ``lay`` (its slots after the columns, as ``plan`` lays them out);
    False (nothing written) where the layout has not their size or they
    cannot be read as its kernel reads them."""
    keep: list = []
    slots = []
    h = hashlib.sha256()
    try:
        funcs = _functions(uk)
        for i, var, kind in plan:
            got = _slots(kind, _cell(funcs[i], var), keep)
            slots += got
            # (a curve's digest: its arrays' contents, not their addresses)
            h.update(repr(got[5:] if kind == "curve" else got).encode())
    except Exception:
        return False
    for a in keep:
        h.update(a.tobytes())
    at = LAYOUT_HEAD + uk.nv
    if lay.size != at + len(slots):
        return False
    lay[at:] = slots
    lay.keep = keep
    lay.digest = h.digest()
    return True


def _bits(x: float) -> int:
    """The int64 of the float ``x``'s bits."""
    return int(np.array([x], dtype=np.float64).view(np.int64)[0])


def _slots(kind: str, value: Any, keep: list) -> list:
    """The layout slots of a run-time value of ``kind`` (:data:`_SLOTS`);
    the arrays they point to appended to ``keep``."""
    if _runtime_kind(value) != kind:
        raise NotCompiled(f"a {type(value).__name__} where a {kind} was compiled for")
    if kind == "float":
        return [_bits(float(value))]
    if kind == "fluid":
        return [_bits(float(value.rho))]
    knots = np.ascontiguousarray(value._knots, dtype=np.float64)
    table = np.ascontiguousarray(value._table, dtype=np.float64)
    if table.shape != (knots.size + 1, 5):
        raise NotCompiled(f"a PV curve's table of shape {table.shape} for {knots.size} knots")
    keep += [knots, table]
    return [knots.ctypes.data, knots.size, table.ctypes.data, table.shape[0], table.shape[1],
            _bits(float(value._lo)), _bits(float(value._hi)), int(bool(value._refuse))]
