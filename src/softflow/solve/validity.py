"""Model validity after a run: checks evaluated on the solution, reported as
``result.warnings`` and through Python's ``warnings`` with :class:`ModelWarning`.

A run can succeed and still return an answer from outside what its models
describe: an actuator pushed past the measured data of its PV curve is
extrapolated (or clamped) there, not measured. Each check here looks at the
recorded solution once, after the run (vectorized per group of components,
so it costs a few array reductions), and returns :class:`ValidityRecord` s:
which component, which check, the figure measured, the limit it crossed and
what to do about it. :func:`check_result` runs every registered check and
:func:`issue` warns once per record.

Near misses
-----------
A check also reports a figure that came within reach of its limit without
crossing it: at :data:`NEAR_FRACTION` of the way or more (``fraction``, the
measured figure relative to the limit in the check's own direction, is
>= 0.5 and < 1). Such a record has ``status='near'``; it is not a warning
(nothing is wrong with the run) and is not warned, but it says which
modelling choices are close to mattering. A run keeps every record in
``result.validity`` (a list; :func:`table` makes a DataFrame of it) and the
ones past their limit (``status='beyond'``) in ``result.warnings``.
``sf.assess`` runs one model level up on the axes whose check is near or
beyond its limit, and only on those.

Checks are registered per component class with :func:`register` (the first
one: PV curves beyond their data). A check is ``check(group, result) ->
[ValidityRecord]`` for one group of components compiled together (same class,
fluid and curve), reading the result's arrays. A check about the network's
nodes (a liquid below its vapour pressure) is registered once with
:func:`register_network`, ``check(asm, result)`` on the whole network.

Also here: :class:`ComponentError`, how an exception raised inside a user's
code (``evaluate``, ``update_state``, ``state_rates``, a curve function)
surfaces: with the component's label, the method and the time, the original
exception chained.
"""
from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator

import numpy as np


class ModelWarning(UserWarning):
    """A result that comes from outside a model's range of validity (a PV curve
    beyond its data, ...). The same records are in ``result.warnings``."""


@dataclass(frozen=True)
class ValidityRecord:
    """One validity finding of a run.

    Attributes
    ----------
    component : str
        The component's label.
    check : str
        Which check (``'pv_curve_range'``, ...).
    measured : float
        The figure the run reached (SI units, see ``unit``).
    limit : float
        The limit it crossed (same unit).
    unit : str
        Unit of ``measured`` and ``limit``.
    suggestion : str
        What to change (more data, another model or policy).
    message : str
        The whole finding in one sentence, as warned.
    details : dict
        Check-specific figures (e.g. the time it first crossed the limit).
    status : {'beyond', 'near'}
        'beyond': the limit was crossed (a warning, in ``result.warnings``);
        'near': the figure came within :data:`NEAR_FRACTION` of the limit but
        did not cross it (in ``result.validity`` only).
    fraction : float
        How far the figure went towards the limit, in the check's own
        direction: 1 at the limit, > 1 beyond it (nan where not defined).
    """

    component: str
    check: str
    measured: float
    limit: float
    unit: str
    suggestion: str
    message: str
    details: dict = field(default_factory=dict, compare=False)
    status: str = "beyond"
    fraction: float = float("nan")

    def __str__(self) -> str:
        return self.message


class ComponentError(RuntimeError):
    """User code (``evaluate``, ``update_state``, ``state_rates``, a curve
    function) raised while the solver evaluated a component. ``component`` is
    its label, ``method`` the function, ``time`` the time [s] of the
    evaluation; the original exception is ``__cause__``."""

    def __init__(self, message: str, component: str | None = None,
                 method: str | None = None, time: float | None = None) -> None:
        super().__init__(message)
        self.component, self.method, self.time = component, method, time


class EmptiedError(ComponentError):
    """A chamber's or actuator's stored fluid reached zero (or, for an actuator
    whose PV curve defines volumes down to a first sample <= 0, that sample)
    during a run: raised by the integration loop
    (:mod:`softflow.solve.integrator`), reported by ``Simulation.run`` as a
    SimulationError (status 'failed', the result up to the last step taken)
    with ``component`` and ``time`` (when it reached it, located within the
    step that went past). ``quantity`` is 'volume' or 'mass' (a rigid
    container's), ``value`` what the step past the limit would have left
    [m^3 or kg]."""

    def __init__(self, message: str, component: str | None = None,
                 time: float | None = None, quantity: str = "volume",
                 value: float = float("nan")) -> None:
        super().__init__(message, component=component, time=time)
        self.quantity, self.value = quantity, value


def user_code_error(err: BaseException, describe: str, label: str, method: str,
                    t: float | None, what: str = "") -> ComponentError:
    """The ComponentError for ``err`` raised in ``method`` of a component
    (``describe``: "Actuator 'act1'", ``label``: 'act1'), at time ``t``."""
    when = f" at t = {t:.6g} s" if t is not None else ""
    extra = f" ({what})" if what else ""
    out = ComponentError(f"{describe}: {method}{extra} raised{when}: {type(err).__name__}: {err}",
                         component=label, method=method, time=t)
    out.__cause__ = err
    return out


#: A figure at this fraction of its limit or more (but not past it) is
#: reported as a near miss (status 'near').
NEAR_FRACTION = 0.5


def grade(fraction: float) -> str | None:
    """'beyond' (at or past the limit), 'near' (at :data:`NEAR_FRACTION` of it
    or more) or None, for a figure ``fraction`` of the way to its limit."""
    if not fraction >= NEAR_FRACTION:       # nan too
        return None
    return "beyond" if fraction > 1.0 else "near"


def beyond(records: list[ValidityRecord]) -> list[ValidityRecord]:
    """The records whose limit was crossed (the warnings)."""
    return [r for r in records if r.status == "beyond"]


def table(records: list[ValidityRecord]) -> Any:
    """``records`` (e.g. ``result.validity``) as a pandas DataFrame: one row
    each, columns component, check, status, measured, limit, unit, fraction,
    suggestion."""
    import pandas as pd
    cols = ["component", "check", "status", "measured", "limit", "unit", "fraction",
            "suggestion"]
    return pd.DataFrame([[getattr(r, c) for c in cols] for r in records], columns=cols)


#: component class -> checks, each check(group, result) -> [ValidityRecord]
_CHECKS: dict[type, list[Callable[[Any, Any], list[ValidityRecord]]]] = {}


#: how many checks were registered: what a run remembers of the checks its start passed
_VERSION = 0


#: checks of a whole network, each check(asm, result) -> [ValidityRecord], run
#: once per result (a finding about nodes rather than one class's components)
_NETWORK_CHECKS: list[Callable[[Any, Any], list[ValidityRecord]]] = []


def register(cls: type, check: Callable[[Any, Any], list[ValidityRecord]]) -> None:
    """Run ``check(group, result)`` after every run on each compiled group of
    components that are instances of ``cls``."""
    global _VERSION
    _CHECKS.setdefault(cls, []).append(check)
    _VERSION += 1


def register_network(check: Callable[[Any, Any], list[ValidityRecord]]) -> None:
    """Run ``check(asm, result)`` once after every run, on the whole compiled
    network ``asm`` (:class:`softflow.solve.assembly.Assembly`): a finding
    about its nodes (the liquid's pressure below its vapour pressure), which a
    check per group would make once for each component at the node."""
    global _VERSION
    _NETWORK_CHECKS.append(check)
    _VERSION += 1


def checks_version() -> int:
    """A number that changes whenever a check is registered (the library's are
    registered first)."""
    _register_library_checks()
    return _VERSION


def _register_library_checks() -> None:
    if _CHECKS:
        return
    from ..components.actuators import Actuator, HystereticActuator
    register(Actuator, pv_curve_range)
    register(HystereticActuator, pv_curve_range)
    from .model_checks import register_all     # tubes, orifices, gases, thermal, nodes
    register_all(register, register_network)


#: per component class, the checks registered for it and its bases in the order
#: _group_checks lists them, as of registration number _VERSION (found once)
_CHECKS_OF: dict[type, list[Callable[[Any, Any], list[ValidityRecord]]]] = {}
_CHECKS_OF_VERSION = -1


def _checks_of(kind: type) -> list[Callable[[Any, Any], list[ValidityRecord]]]:
    """The registered checks of a group whose members are ``kind``s: those of
    every registered class it is a subclass of, in registration order."""
    global _CHECKS_OF_VERSION
    if _CHECKS_OF_VERSION != _VERSION:
        _CHECKS_OF.clear()
        _CHECKS_OF_VERSION = _VERSION
    got = _CHECKS_OF.get(kind)
    if got is None:
        got = _CHECKS_OF[kind] = [check for cls, checks in _CHECKS.items()
                                  if issubclass(kind, cls) for check in checks]
    return got


def _group_checks(asm: Any, fatal_only: bool = False) -> Iterator[tuple[Any, Any]]:
    """(group, check) for every registered check of every group of the network;
    ``fatal_only``: only the checks that can refuse a run (``can_refuse``)."""
    _register_library_checks()
    for g in asm.groups:
        for check in _checks_of(type(g.comps[0])):
            if not fatal_only or getattr(check, "can_refuse", False):
                yield g, check


def check_result(asm: Any, result: Any, fatal_only: bool = False,
                 rtol: float | None = None) -> list[ValidityRecord]:
    """Every registered check on every group of the run's network: the records
    past their limit and the near misses (see :func:`beyond`). ``fatal_only``:
    only the checks that can refuse a run (marked ``can_refuse``). ``rtol``:
    judge the limits that follow the tolerance (10 rtol) as for a run at this
    rtol instead of the run's own (sf.assess runs its base at 10 rtol0 and
    judges it at rtol0)."""
    records: list[ValidityRecord] = []
    if len(result.times) == 0:
        return records
    FluidError = _fluid_error()
    own = result.stats.get("rtol")
    if rtol is not None:
        result.stats["rtol"] = rtol
    try:
        for g, check in _group_checks(asm, fatal_only):
            try:
                records.extend(check(g, result))
            except FluidError as err:    # a check must never fail the run it checks
                records.append(_not_evaluated(g.comps[0], check, err))
        for check in _NETWORK_CHECKS:
            if fatal_only and not getattr(check, "can_refuse", False):
                continue
            try:
                records.extend(check(asm, result))
            except FluidError as err:
                records.append(_not_evaluated(asm.groups[0].comps[0], check, err))
    finally:
        if rtol is not None:
            if own is None:
                del result.stats["rtol"]
            else:
                result.stats["rtol"] = own
    return records


_FLUID_ERROR = None


def _fluid_error() -> type:
    """softflow.fluids.base.FluidError, imported once (at its first check)."""
    global _FLUID_ERROR
    if _FLUID_ERROR is None:
        from ..fluids.base import FluidError
        _FLUID_ERROR = FluidError
    return _FLUID_ERROR


def _not_evaluated(c: Any, check: Any, err: Exception) -> ValidityRecord:
    """The record of a check that could not be evaluated (a fluid's range)."""
    return ValidityRecord(
        component=c.label, check=check.__name__, measured=float("nan"),
        limit=float("nan"), unit="",
        suggestion="use a fluid level whose range covers the run's states",
        message=f"{c.describe()}: the {check.__name__} check could not "
                f"be evaluated ({err}); its finding is unknown")


def can_refuse(asm: Any) -> bool:
    """Whether a check that can refuse a run (``can_refuse``) is registered for
    a group of the network (a gas tube's choke check), or for networks."""
    return (any(True for _ in _group_checks(asm, fatal_only=True))
            or any(getattr(check, "can_refuse", False) for check in _NETWORK_CHECKS))


def issue(records: list[ValidityRecord], stacklevel: int = 3) -> None:
    """Warn once per record past its limit (category :class:`ModelWarning`);
    near misses are not warned."""
    for r in beyond(records):
        warnings.warn(r.message, ModelWarning, stacklevel=stacklevel)


# -- reading a group's values from a result -----------------------------------------
#: per compiled group, {name: where group_values finds it in a result that
#: recorded every component}: ('x' or 's', columns of X or S, the group's
#: indices) or ('missing', the KeyError's message). A group's members share
#: one interface and their columns are fixed when the network compiles (run-time
#: parameters replace members by members of the same class), so each name is
#: looked up once per network instead of once per run.
_FOUND: weakref.WeakKeyDictionary[Any, dict[str, tuple[str, Any, Any]]] = \
    weakref.WeakKeyDictionary()


#: group_values's default: raise the KeyError of a name the group does not have
_RAISE = object()


def group_values(g: Any, result: Any, name: str, default: Any = _RAISE
                 ) -> tuple[list[int], np.ndarray]:
    """(indices in the group, values (times x those components)) of variable or
    output ``name`` of the recorded components of group ``g``. The components of
    a group share one interface, so the columns are found once for all of them
    (the variables an output reads too). ``default``: returned where the
    components have no (single) variable or output ``name``, instead of the
    KeyError saying so (whose message lists what they have)."""
    complete = getattr(result, "_complete", False)    # every component recorded: _FOUND
    if complete:
        found = _FOUND.get(g)
        hit = found.get(name) if found is not None else None
        if hit is not None:
            kind, cols, keep = hit
            if kind == "missing":
                if default is not _RAISE:
                    return default
                raise KeyError(cols)
            return list(keep), (result.X if kind == "x" else result.S)[:, cols]
    where = result._where
    idx = [i for i, c in enumerate(g.comps) if c.label in where]     # recorded
    if not idx:
        return [], np.empty((len(result.times), 0))
    label = g.comps[idx[0]].label
    if default is not _RAISE:
        try:
            e = result._lookup(label, name, None)
        except KeyError:            # ambiguous
            e = None
        if e is None:
            return default
    else:
        try:
            e = result._entry(label, name, None)
        except KeyError as err:
            if complete:
                _FOUND.setdefault(g, {})[name] = ("missing", err.args[0], None)
            raise
    if e[0] == "output":
        _, fn = g.comps[idx[0]].outputs()[name]

        def get(n: str, term: str | None = None) -> np.ndarray:
            return _variable(g, result, n, term, label, idx, complete)
        return idx, np.asarray(fn(get), dtype=float)
    return _columns(g, result, e, label, idx, name)


def _variable(g: Any, result: Any, name: str, term: str | None, label: str,
              idx: list[int], complete: bool) -> np.ndarray:
    """The values of variable ``name`` (at ``term``) of the components ``idx`` of
    group ``g`` (an output's ``get``): found once per group in a result that
    recorded every component, as group_values finds them."""
    key = name if term is None else (name, term)
    if complete:
        found = _FOUND.get(g)
        hit = found.get(key) if found is not None else None
        if hit is not None and hit[0] != "missing":
            kind, cols, _ = hit
            return (result.X if kind == "x" else result.S)[:, cols]
    return _columns(g, result, result._entry(label, name, term), label, idx, key)[1]


def group_times(g: Any, result: Any, keep: list[int]) -> np.ndarray:
    """Times (points x len(keep)) of the points of group ``g``'s components
    ``keep`` (indices in the group, as :func:`group_values` gives them): the
    result's times for each, or, in a batched run whose variants keep clocks
    of their own (:mod:`softflow.solve.variants`), each one's variant's."""
    own = getattr(result, "instance_times", None)
    if own is not None:
        return np.asarray(own(g, keep))
    t = np.asarray(result.times, dtype=float)
    if len(keep) == 1:        # a read-only column view: broadcast_to costs ~15x more
        column = t[:, None]
        column.flags.writeable = False
        return column
    return np.broadcast_to(t[:, None], (t.size, len(keep)))


def _columns(g: Any, result: Any, entry: Any, label: str, idx: list[int], key: Any = None
             ) -> tuple[list[int], np.ndarray]:
    """The recorded columns of ``entry`` (of component ``label`` of group ``g``) for
    the group's components ``idx``: (those recorded, values). In a result that
    recorded every component (``idx`` all of them), kept in _FOUND under
    ``key`` where one is given."""
    k = result._component_entries(label).index(entry)
    i = np.asarray(idx)
    col = g.col.reshape(len(g.comps), -1)
    n_iface = col.shape[1]
    if k < n_iface:
        kind, cols, data = "x", col[i, k], result.X
    else:
        kind, cols, data = "s", g.s0 + i * g.ns + (k - n_iface), result.S
    if result._complete:       # every column recorded, at its own index
        keep = i.tolist()
        if key is not None:
            _FOUND.setdefault(g, {})[key] = (kind, cols, tuple(keep))
        return keep, data[:, cols]
    cols = (result._xcol if kind == "x" else result._scol)[cols]
    ok = cols >= 0
    return i[ok].tolist(), data[:, cols[ok]]


# -- the checks ---------------------------------------------------------------------
#: A volume counts as beyond a PV curve's data when it is past the first or last
#: sample by more than this fraction of the data's volume range: adaptive steps
#: overshoot a curve's end by about the tolerance (rtol 1e-3) when an actuator
#: returns to where it started.
PV_CURVE_SLACK = 0.01


def _curves_of(comp: Any) -> list[Any]:
    loop = getattr(comp, "loop", None)
    if loop is not None:
        return [loop.inflation, loop.deflation]
    curve = getattr(comp, "curve", None)
    return [curve] if hasattr(curve, "volume") and hasattr(curve, "extrapolate") else []


def curve_first_volume(comp: Any) -> tuple[float, float] | None:
    """(volume [m^3], absolute pressure [Pa]) of the first sample of an
    actuator's PV curve data (the smaller of a hysteresis loop's two), or None
    for a component without curve data (a curve given as a function)."""
    curves = _curves_of(comp)
    if not curves:
        return None
    first = min(curves, key=lambda c: float(c.volume[0]))
    return float(first.volume[0]), float(first.pressure[0])


def pv_curve_range(g: Any, result: Any) -> list[ValidityRecord]:
    """Actuators whose volume left their PV curve's measured data (by more than
    :data:`PV_CURVE_SLACK` of its range): how far, in which direction, when."""
    curves = _curves_of(g.comps[0])
    if not curves:
        return []
    keep, vol = group_values(g, result, "volume")
    if not keep:
        return []
    lo = min(float(c.volume[0]) for c in curves)
    hi = max(float(c.volume[-1]) for c in curves)
    span = hi - lo
    slack = PV_CURVE_SLACK * span
    policies = sorted({c.extrapolate for c in curves})
    policy = policies[0] if len(policies) == 1 else "/".join(policies)
    origin = curves[0].origin if len(curves) == 1 else "inflation/deflation curves"
    # np.nanmax and np.nanmin as they compute them (fmax/fmin reductions, which
    # leave NaN out), and their warning where a column holds no number at all
    vmax = np.fmax.reduce(vol, axis=0)
    vmin = np.fmin.reduce(vol, axis=0)
    if np.isnan(vmax).any():
        warnings.warn("All-NaN slice encountered", RuntimeWarning, stacklevel=1)
        warnings.warn("All-NaN slice encountered", RuntimeWarning, stacklevel=1)
    out = []
    above_hi, below_lo = hi + slack, lo - slack
    for j in [j for j, (a, b) in enumerate(zip(vmax.tolist(), vmin.tolist()))
              if a > above_hi or b < below_lo]:
        comp = g.comps[keep[j]]
        above = vmax[j] - hi >= lo - vmin[j]
        reached = float(vmax[j] if above else vmin[j])
        limit = hi if above else lo
        past = abs(reached - limit)
        col = vol[:, j]
        first = int(np.argmax(col > hi + slack) if above else np.argmax(col < lo - slack))
        t_first = float(group_times(g, result, keep)[first, j])
        side = "last" if above else "first"
        how = {"linear": "continued in a straight line with its end slope",
               "clamp": "held at its end pressure",
               "error": "refused (extrapolate='error')"}.get(policy, f"extrapolated ({policy})")
        suggestion = ("measure the PV curve over the volumes the actuator reaches, or "
                      "choose what happens beyond the data with PVCurve(..., extrapolate=...): "
                      "'linear' continues the end slope, 'clamp' holds the end pressure, "
                      "'error' stops the run there")
        message = (f"{comp.describe()}: volume reached {reached * 1e6:.6g} mL, "
                   f"{past * 1e6:.3g} mL ({100 * past / span:.3g} % of the data's range) "
                   f"beyond the {side} sample of its PV curve ({origin}) at "
                   f"{limit * 1e6:.6g} mL, first at t = {t_first:.6g} s; there the curve is "
                   f"{how}, not measured. Suggestion: {suggestion}")
        out.append(ValidityRecord(component=comp.label, check="pv_curve_range",
                                  measured=reached, limit=limit, unit="m^3",
                                  suggestion=suggestion, message=message,
                                  details={"beyond": past, "fraction_of_range": past / span,
                                           "first_time": t_first, "policy": policy,
                                           "side": side}))
    return out
