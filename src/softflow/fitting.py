"""Fitting and design: thin layers over :mod:`scipy.optimize`.

:func:`fit` adjusts run-time parameters so that recorded variables match
measured traces, by ``scipy.optimize.least_squares`` with the Jacobian from
the run's own forward sensitivities (:mod:`softflow.solve.sensitivity`): one
run per iteration gives the residuals and their derivatives. :func:`design`
minimizes a user's objective of a run with ``scipy.optimize.minimize``.
Parameters are named as in ``Simulation.run(params=...)`` and worked on
relative to their starting values, so that a diameter [m] and a volume
[m^3] are equally well scaled.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Optional, Tuple

import numpy as np

from .units import quantity_unit, to_si

if TYPE_CHECKING:
    from ._typing import Array, ArrayLike, Scalar
    from .solve.result import Result
    from .solve.simulation import Simulation

    #: ``{"label.argument": (lower, upper)}``, None for no bound
    Bounds = Mapping[str, Tuple[Optional[Scalar], Optional[Scalar]]]


def _si(value: Any) -> float:
    """A number in SI: a Quantity in base units, or the number itself."""
    if hasattr(value, "to_base_units"):
        return float(value.to_base_units().magnitude)
    return float(value)


@dataclass
class FitResult:
    """What :func:`fit` or :func:`design` found.

    Attributes
    ----------
    params : dict
        The fitted (or designed) parameter values, SI.
    success : bool
    message : str
        scipy's message.
    cost : float
        The objective at the end (least squares: half the sum of squared
        scaled residuals).
    runs : int
        Simulation runs made.
    result : Result
        The run at the fitted parameters.
    optimizer : object
        scipy's own result (``OptimizeResult``).
    """

    params: dict[str, float]
    success: bool
    message: str
    cost: float
    runs: int
    result: Result | None = None
    optimizer: Any = field(default=None, repr=False)


def _start(sim: Simulation, params: Sequence[str], x0: Mapping[str, Scalar] | None
           ) -> tuple[list[str], Array]:
    names = list(params)
    if not names:
        raise ValueError("fit: name at least one parameter to adjust, e.g. params="
                         "['tube.diameter']")
    start = {}
    for name in names:
        if x0 is not None and name in x0:
            if hasattr(x0[name], "to_base_units"):     # its dimension and range checked
                sim.check_params({name: x0[name]})
            start[name] = _si(x0[name])
            continue
        label, arg = name.rsplit(".", 1) if "." in name else (name, "")
        if label not in sim.asm.where:
            raise KeyError(f"fit: parameter {name!r}: no component {label!r}")
        g, i = sim.asm.where[label]
        value = getattr(sim._compiled[label], arg, None)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value == 0:
            raise ValueError(f"fit: parameter {name!r} is not a nonzero number "
                             f"({value!r}); give its starting value in x0")
        start[name] = float(value)
    return names, np.array([start[n] for n in names])


def _quantity_of(sim: Simulation, label: str, var: str, key: str) -> str:
    """The quantity of a component's variable or output, by its entry in a
    result of ``sim`` (a clear KeyError naming what exists otherwise)."""
    probe = sim.probe()
    try:
        entry = probe._entry(label, var, None)
    except KeyError as err:
        raise KeyError(f"fit: measured key {key!r}: {err.args[0]}") from None
    if entry[0] == "output":
        return probe._component(label).outputs()[var][0]
    return entry[1]


def _bounds(sim: Simulation, names: list[str], theta0: Array, bounds: Bounds | None
            ) -> tuple[Array, Array]:
    lo = np.full(len(names), -np.inf)
    hi = np.full(len(names), np.inf)
    for k, name in enumerate(names):
        if bounds and name in bounds:
            a, b = bounds[name]
            for bound in (a, b):
                to_base = getattr(bound, "to_base_units", None)
                if to_base is not None:
                    # the bound's dimension, checked by the component's constructor
                    # on the starting value expressed in the bound's base units
                    base = to_base()
                    sim.check_params({name: type(base)(float(theta0[k]), base.units)})
            lo[k] = -np.inf if a is None else _si(a)
            hi[k] = np.inf if b is None else _si(b)
            if not lo[k] < hi[k]:
                raise ValueError(f"fit: bounds of {name!r} must have lower < upper, got "
                                 f"{bounds[name]!r}")
    return lo / theta0, hi / theta0     # relative, theta0 > 0 assumed below


def fit(sim: Simulation, measured: Mapping[str, tuple[ArrayLike, ArrayLike]],
        params: Sequence[str], *, bounds: Bounds | None = None,
        x0: Mapping[str, Scalar] | None = None, scale: Mapping[str, float] | None = None,
        **options: Any) -> FitResult:
    """Fit run-time parameters of ``sim`` to measured traces.

    Parameters
    ----------
    sim : Simulation
    measured : dict
        ``{"label.variable": (times [s], values [SI])}``: each compared with the
        run's values interpolated linearly at those times.
    params : sequence of str
        Parameters to adjust (``"label.argument"``, numeric).
    bounds : dict, optional
        ``{"label.argument": (lower, upper)}`` (SI or Quantities; None for none).
    x0 : dict, optional
        Starting values (default: the values the Simulation was built with).
    scale : dict, optional
        ``{"label.variable": typical size}`` of each trace's residuals (default:
        its measured range), so traces of different units weigh alike.
    **options
        Passed to ``scipy.optimize.least_squares`` (e.g. ``xtol``, ``max_nfev``).

    Returns
    -------
    FitResult
    """
    from scipy.optimize import least_squares
    names, theta0 = _start(sim, params, x0)
    if np.any(theta0 <= 0):
        raise ValueError("fit: starting values must be > 0 (parameters are worked on "
                         f"relative to them); got {dict(zip(names, theta0))}")
    traces = []
    for key, (times, values) in measured.items():
        if not isinstance(key, str) or "." not in key:
            raise KeyError(f"fit: measured key {key!r} is not 'label.variable'")
        label, var = key.rsplit(".", 1)
        times = np.asarray(to_si(times, "s", name="times", owner=f"fit[{key!r}]"), dtype=float)
        quantity = _quantity_of(sim, label, var, key)
        unit = quantity_unit(quantity) if quantity else None
        if unit is not None:       # Quantities converted (and checked) to the output's unit
            values = to_si(values, unit, name="values", owner=f"fit[{key!r}]")
        elif hasattr(values, "magnitude"):
            values = values.to_base_units().magnitude  # type: ignore[union-attr]  # a Quantity
        values = np.asarray(values, dtype=float)
        if times.size and (times.min() < 0 or times.max() > sim.duration * (1 + 1e-12)):
            raise ValueError(f"fit[{key!r}]: measured times {times.min():.6g} ... "
                             f"{times.max():.6g} s leave the simulated span 0 ... "
                             f"{sim.duration:.6g} s")
        if times.shape != values.shape or times.ndim != 1 or not times.size:
            raise ValueError(f"fit[{key!r}]: times and values must be 1-D arrays of one "
                             f"length, got {times.shape} and {values.shape}")
        size = (scale or {}).get(key) or float(np.ptp(values)) or float(np.abs(values).max()) or 1.0
        traces.append((label, var, times, values, size))
    lo, hi = _bounds(sim, names, theta0, bounds)
    cache: dict[str, Any] = {"u": None, "runs": 0}

    def run(u: Array) -> Result:
        if cache["u"] is not None and np.array_equal(u, cache["u"]):
            return cache["res"]
        theta = u * theta0
        res = sim.run(params=dict(zip(names, theta)), sensitivities=names,
                      raise_on_failure=False)
        cache.update(u=u.copy(), res=res)
        cache["runs"] += 1
        return res

    def residuals(u: Array) -> Array:
        res = run(u)
        if not res.success:
            return np.full(sum(tr[2].size for tr in traces), 1e6)
        out = [(np.interp(times, res.times, res.get(label, var)) - values) / size
               for label, var, times, values, size in traces]
        return np.concatenate(out)

    def jacobian(u: Array) -> Array:
        res = run(u)
        cols = []
        for k, name in enumerate(names):
            if not res.success:
                cols.append(np.zeros(sum(tr[2].size for tr in traces)))
                continue
            cols.append(np.concatenate([
                np.interp(times, res.times, res.sensitivity(label, var, name)) * theta0[k]
                / size for label, var, times, values, size in traces]))
        return np.column_stack(cols)

    opt = least_squares(residuals, np.ones(len(names)), jac=jacobian, bounds=(lo, hi),
                        **options)
    theta = opt.x * theta0
    final = sim.run(params=dict(zip(names, theta)), raise_on_failure=False)
    return FitResult(params=dict(zip(names, theta)), success=bool(opt.success),
                     message=str(opt.message), cost=float(opt.cost),
                     runs=cache["runs"] + 1, result=final, optimizer=opt)


def design(sim: Simulation, objective: Callable[[Result], float], params: Sequence[str], *,
           bounds: Bounds | None = None, x0: Mapping[str, Scalar] | None = None,
           method: str | None = None, **options: Any) -> FitResult:
    """Minimize ``objective(result)`` over run-time parameters of ``sim`` with
    ``scipy.optimize.minimize`` (``method`` and ``options`` passed on; the
    default, L-BFGS-B with bounds or BFGS without, takes finite-difference
    gradients of whole runs; a derivative-free method such as 'Powell' or
    'Nelder-Mead' suits objectives that are not smooth, e.g. times of events).
    A failed run counts as ``inf``. Parameters are worked on relative to their
    starting values."""
    from scipy.optimize import minimize
    names, theta0 = _start(sim, params, x0)
    lo, hi = _bounds(sim, names, theta0, bounds)
    runs = {"n": 0}

    def f(u: Array) -> float:
        runs["n"] += 1
        res = sim.run(params=dict(zip(names, u * theta0)), raise_on_failure=False)
        if not res.success:
            return np.inf
        return float(objective(res))

    has_bounds = np.isfinite(lo).any() or np.isfinite(hi).any()
    opt = minimize(f, np.ones(len(names)), method=method,
                   bounds=list(zip(lo, hi)) if has_bounds else None, **options)
    theta = np.asarray(opt.x) * theta0
    final = sim.run(params=dict(zip(names, theta)), raise_on_failure=False)
    return FitResult(params=dict(zip(names, theta)), success=bool(opt.success),
                     message=str(getattr(opt, "message", "")), cost=float(opt.fun),
                     runs=runs["n"] + 1, result=final, optimizer=opt)
