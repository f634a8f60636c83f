"""Simulation results: times and every variable as arrays, by component and label;
exports (dict, CSV, pandas, xarray) and plots (matplotlib) under one naming:
``component.name``, where ``result.get(component, name)`` gives the same values."""
from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Literal, Union, overload

import numpy as np
import numpy.typing as npt

from ..constants import pressure_atmospheric
from ..units import Q_, UnitError, quantity_unit, to_quantity

if TYPE_CHECKING:
    import pandas as pd
    import xarray as xr
    from matplotlib.axes import Axes
    from pint import Quantity

Array = npt.NDArray[np.float64]
#: a variable to plot: 'component.name', (component, name) or (component, name, terminal)
Spec = Union[str, tuple[str, str], tuple[str, str, Union[str, None]]]
#: display units: one for all, or {quantity or column: unit}
Units = Union[str, Mapping[str, str], None]
#: (label, quantity, terminal or None, 'x' unknown | 's' state, column in X or S)
Entry = tuple[str, str, Union[str, None], str, int]

#: unit written for a quantity without a known SI unit (a dimensionless state)
_DIMENSIONLESS = "1"


class _Located:
    """Where a pickled Result finds a component: just the component."""

    def __init__(self, comp: Any) -> None:
        self.comps = [comp]


class Result:
    """Outcome of a simulation run.

    Attributes
    ----------
    times : ndarray [s]
    status : str
        ``'success'`` or ``'failed'``.
    message : str
        Why a run failed (time, component, equation), or ``''``.
    stats : dict
        Counters: steps, rejected_steps, newton_iterations, residual_evaluations,
        jacobian_evaluations, factorizations, ...; ``residuals_at_last_step``:
        the residual evaluations made when the last point was accepted (the
        consistent start's at t = 0, then each step's; 0 where the start
        failed): a failed run's work after its last accepted point is
        ``residual_evaluations`` minus this.
    warnings : list of ValidityRecord
        What the run's validity checks found (:mod:`softflow.solve.validity`): each
        with ``component``, ``check``, ``measured``, ``limit``, ``unit``,
        ``suggestion`` and ``message``; also warned as :class:`softflow.ModelWarning`.
    validity : list of ValidityRecord
        Every finding of the checks: those in ``warnings`` (status 'beyond') and
        the near misses (status 'near': a figure at half its limit or more, not
        past it; not warned). ``softflow.solve.validity.table(result.validity)``
        is a DataFrame of them.
    """

    def __init__(self, asm: Any, times: Array, X: Array, S: Array, status: str = "success",
                 message: str = "", stats: Mapping[str, Any] | None = None,
                 recorded: tuple | None = None, integrals: Array | None = None,
                 dense: Any = None) -> None:
        self.times = times
        self.X = X
        self.S = S
        # the integrator's interpolant between its steps (softflow.solve.dense),
        # or None: what at() and interpolate() read
        self._dense = dense
        # time integrals of the recorded unknowns as the integrator formed them
        # (BDF runs), or None: backward Euler's are sums of step times end value
        self._Q = integrals
        self.status = status
        self.message = message
        self.stats = dict(stats or {})
        self.warnings: list[Any] = []     # ValidityRecords, set by Simulation.run
        self.validity: list[Any] = []     # the same and the near misses
        # where each component lives; its variable index is built on first access
        self._where = asm.where
        self._entries: dict[str, list[Entry]] = {}
        self._specs: list[tuple[str, str, str, str]] | None = None   # export columns
        # every component recorded, X and S holding every unknown and state
        self._complete = recorded is None
        # column of X (S) holding each unknown (state); -1 where it was not recorded
        if recorded is None:
            self._xcol = np.arange(asm.n)
            self._scol = np.arange(len(asm.S0))
        else:
            self._xcol = np.full(asm.n, -1)
            self._xcol[recorded[0]] = np.arange(len(recorded[0]))
            self._scol = np.full(len(asm.S0), -1)
            self._scol[recorded[1]] = np.arange(len(recorded[1]))
            self._where = {label: asm.where[label] for label in recorded[2]}

    def _set_sensitivities(self, sens: Any, x_index: Any, s_index: Any, n_points: int) -> None:
        """Keep the run's sensitivities (softflow.solve.sensitivity) for the
        recorded unknowns and states, at the result's points."""
        arrays = sens.arrays(x_index, s_index)
        self._sens = {}
        for p, name in enumerate(sens.names):
            sx, ss = arrays[name]
            if len(sx) < n_points:      # a run that failed before its sensitivities
                sx = np.vstack([sx, np.full((n_points - len(sx), sx.shape[1]), np.nan)])
                ss = np.vstack([ss, np.full((n_points - len(ss), ss.shape[1]), np.nan)])
            _, _, _, _, eps, comp, twin = sens.parameters[p]
            self._sens[name] = (sx[:n_points], ss[:n_points], eps, comp.label, twin)

    def sensitivity(self, label: str, name: str, parameter: str, terminal: str | None = None,
                    ) -> Array:
        """d(variable)/d(parameter) over time, shaped like ``get(label, name)``, in SI
        units per SI unit of the parameter (a run with
        ``sensitivities=[parameter]``; see :mod:`softflow.solve.sensitivity` for
        what it means across switches)."""
        sens = getattr(self, "_sens", None) or {}
        if parameter not in sens:
            have = sorted(sens) or "none (run with sensitivities=[...])"
            raise KeyError(f"no sensitivity to {parameter!r} in this result; it has {have}")
        sx, ss, eps, owner, twin = sens[parameter]
        e = self._entry(label, name, terminal)
        if e[0] != "output":
            if e[4] < 0:
                raise KeyError(f"{label!r} {name!r} was not recorded (Simulation(record=...))")
            return (sx if e[3] == "x" else ss)[:, e[4]].copy()
        # a derived output: along the perturbed trajectory, with the perturbed
        # component's own output function where it is the parameter's owner
        comp = twin if label == owner else self._component(label)
        _, fn = comp.outputs()[name]
        _, fn0 = self._component(label).outputs()[name]

        def moved(n: str, term: str | None = None) -> Array:
            return self.get(label, n, term) + eps * self.sensitivity(label, n, parameter, term)

        def here(n: str, term: str | None = None) -> Array:
            return self.get(label, n, term)
        return (np.asarray(fn(moved), dtype=float) - np.asarray(fn0(here), dtype=float)) / eps

    def __getstate__(self) -> dict:
        # the compiled model stays behind: every component's variable index is
        # made now, and each label keeps only its component (for its outputs)
        for label in self._where:
            self._component_entries(label)
        state = self.__dict__.copy()
        state["_where"] = {label: (_Located(g.comps[i]), 0)
                           for label, (g, i) in self._where.items()}
        return state

    def _component_entries(self, label: str) -> list[Entry]:
        if label not in self._entries:
            if label not in self._where:
                have = sorted(self._where)
                listed = ", ".join(map(repr, have[:20])) + (", ..." if len(have) > 20 else "")
                raise KeyError(f"no component {label!r} in this result (not in the system, "
                               f"or not among Simulation(record=...)); it has {listed}")
            g, i = self._where[label]
            iface, states = g.iface[i]
            # the columns as Python ints at once (an int of a NumPy scalar each cost
            # ~0.5 us a variable)
            xcol = self._xcol[g.col[i]].tolist()
            s0 = g.s0 + i * g.ns
            scol = self._scol[s0:s0 + len(states)].tolist()
            if len(scol) < len(states):
                raise IndexError(f"index {s0 + len(states) - 1} is out of bounds for the "
                                 f"states of size {len(self._scol)}")
            entries = [(v.label, v.quantity, term, "x", xcol[k])
                       for k, (term, v) in enumerate(iface)]
            entries += [(sv.label, sv.quantity, None, "s", scol[j])
                        for j, sv in enumerate(states)]
            self._entries[label] = entries
        return self._entries[label]

    def _columns(self, labels: Sequence[str], name: str) -> tuple[str, Array] | None:
        """Where variable ``name`` of each of ``labels`` is kept: ('x' or 's', its
        column of X or S per label), for components that sit alike in one
        group (a batch's copies of one component, :mod:`softflow.solve.batched`)
        and are all recorded; None where ``name`` is a derived output or they
        do not sit alike. One lookup for all of them, where :meth:`get`
        resolves each label's entry anew."""
        e = self._entry(labels[0], name, None)
        if e[0] == "output":
            return None
        pos = self._component_entries(labels[0]).index(e)
        places = [self._where[label] for label in labels]
        g = places[0][0]
        if any(p[0] is not g for p in places):
            return None
        rows = np.array([i for _, i in places], dtype=np.int64)
        n_iface = len(g.iface[places[0][1]][0])
        if pos < n_iface:
            where, cols = "x", self._xcol[g.col[rows, pos]]
        else:
            where, cols = "s", self._scol[g.s0 + rows * g.ns + (pos - n_iface)]
        return None if (cols < 0).any() else (where, cols)

    def _component(self, label: str) -> Any:
        g, i = self._where[label]
        return g.comps[i]

    @property
    def success(self) -> bool:
        return self.status == "success"

    def _entry(self, label: str, name: str, terminal: str | None) -> Any:
        e = self._lookup(label, name, terminal)
        if e is None:
            entries = self._component_entries(label)
            outs = self._component(label).outputs()
            names = sorted({e[0] for e in entries} | {e[1] for e in entries} | set(outs))
            raise KeyError(f"component {label!r} has no variable {name!r}"
                           + (f" at terminal {terminal!r}" if terminal else "")
                           + f"; it has {names}")
        return e

    def _lookup(self, label: str, name: str, terminal: str | None) -> Any:
        """:meth:`_entry`, or None where the component has no such variable or
        output (without the KeyError's list of what it has); an ambiguous name
        raises as there."""
        entries = self._component_entries(label)
        by_label = [e for e in entries if e[0] == name or f"{e[0]}_{e[2]}" == name]
        cands = by_label or [e for e in entries if e[1] == name or f"{e[1]}_{e[2]}" == name]
        if terminal is not None:
            cands = [e for e in cands if e[2] == terminal]
        if len(cands) == 1:
            return cands[0]
        if not cands:
            outs = self._component(label).outputs()
            if name in outs and terminal is None:
                return ("output", name)
            return None
        terms = [e[2] for e in cands]
        raise KeyError(f"component {label!r}: {name!r} is ambiguous (terminals {terms}); "
                       f"pass terminal=, e.g. get({name!r}, {terms[0]!r})")

    @overload
    def get(self, label: str, name: str, terminal: str | None = None, *,
            as_quantity: Literal[False] = False) -> Array: ...

    @overload
    def get(self, label: str, name: str, terminal: str | None = None, *,
            as_quantity: Literal[True]) -> Quantity: ...

    @overload
    def get(self, label: str, name: str, terminal: str | None = None, *,
            as_quantity: bool) -> Array | Quantity: ...

    def get(self, label: str, name: str, terminal: str | None = None, *,
            as_quantity: bool = False) -> Array | Quantity:
        """Values of variable ``name`` of component ``label``: its label (``'p'``), its
        quantity (``'pressure'``), either with the terminal (``'massflow_a'``), a state
        (``'mass'``) or a derived output (an Actuator's ``'volume'``); SI units, or a
        pint Quantity with ``as_quantity=True``. ``terminal`` picks one where the
        name occurs at several."""
        e = self._entry(label, name, terminal)
        if e[0] == "output":
            quantity, fn = self._component(label).outputs()[name]
            values = np.asarray(fn(lambda n, term=None: self.get(label, n, term)), dtype=float)
        else:
            _, quantity, _, where, idx = e
            values = (self.X if where == "x" else self.S)[:, idx]
        return to_quantity(values, quantity) if as_quantity else values

    def integral(self, label: str, name: str, terminal: str | None = None, *,
                 as_quantity: bool = False) -> Array | Quantity:
        """Time integral since t = 0 of an unknown (a flow, a pressure, ...) at
        every recorded time, formed by the run's own integrator: what flowed
        through a terminal is then exactly what the states took up, to
        round-off, under every method (a mass flow gives kg, an energy flow J).

        Backward Euler adds each step's end value times the step; BDF runs
        integrate Q' = x with the same formula, order and steps as the states.
        """
        e = self._entry(label, name, terminal)
        if e[0] == "output" or e[3] != "x":
            raise KeyError(f"Result.integral: {label!r} {name!r} is not an unknown of the "
                           "network (states and outputs are not integrated); "
                           "integrate a flow, pressure or other interface variable")
        _, quantity, _, _, idx = e
        if self._Q is not None:
            values = self._Q[:, idx].copy()
        else:
            x = self.X[:, idx]
            values = np.concatenate([[0.0], np.cumsum(np.diff(self.times) * x[1:])])
        if not as_quantity:
            return values
        return to_quantity(values, quantity) * to_quantity(1.0, "time")

    def __getitem__(self, key: str | tuple) -> Array:
        """``result['tube.massflow_a']``, ``result['tube', 'massflow', 'a']`` or
        ``result['time']``: every column name of :meth:`to_dict` works."""
        if key == "time":
            return self.times
        if isinstance(key, tuple):
            return self.get(*key)
        label, _, name = key.rpartition(".")
        return self.get(label, name)

    def get_times(self, *, as_quantity: bool = False) -> Array | Quantity:
        """The recorded times [s], as a pint Quantity with ``as_quantity=True``."""
        return Q_(self.times, "s") if as_quantity else self.times

    # -- values at any time: the integrator's own interpolant --------------------------------
    def at(self, t: Any, label: str | None = None, name: str | None = None,
           terminal: str | None = None, *, as_quantity: bool = False) -> Any:
        """Values at any time(s) of the run, from the integrator's own
        interpolant between its steps.

        Each value comes from the polynomial of the step that covers its time
        (:mod:`softflow.solve.dense`): the adaptive BDF's interpolating
        polynomial of that step's order (its difference table), backward
        Euler's straight line between its steps at fixed steps. Values between
        the steps are then as accurate as those at the steps, where reading
        the recorded points linearly (``np.interp``) adds the straight line's
        error. No polynomial is used across a discontinuity: each covers its
        own step only, and a time on a step's end is that step's recorded
        point (at a breakpoint, the inputs' left limit). Discrete states (a
        valve's mode) hold their value at a step's start inside it.

        Parameters
        ----------
        t : float, array_like [s] or Quantity
            Time(s) within the run, [0, its last time]; any shape and order.
        label, name, terminal : str, optional
            The variable, named as in :meth:`get`: ``at(t, 'tank', 'pressure')``,
            or ``at(t, 'tank.pressure')``. None: every column.
        as_quantity : bool
            Values as pint Quantities.

        Returns
        -------
        ndarray or float or Quantity, or dict
            The variable's values shaped like ``t`` (a float for a single time);
            with no variable named, ``{'time': t, column: values, ...}`` for
            every column of :meth:`columns`, as :meth:`to_dict` names them.

        Examples
        --------
        >>> res = sf.Simulation(system, duration=0.05).run()       # doctest: +SKIP
        >>> res.at(0.0123, "tank", "pressure")                      # doctest: +SKIP
        >>> res.at(np.linspace(0, 0.05, 501), "tank.pressure")      # doctest: +SKIP
        >>> res.at(sf.Q_(12.3, "ms"))["tank.pressure"]               # doctest: +SKIP
        """
        from ..units import to_si
        where = "Result.at"
        if label is None and name is not None:
            raise ValueError(f"{where}: name the component too, as at(t, 'tank', {name!r})")
        if name is None and label is not None:
            label, dot, name = label.rpartition(".")
            if not dot:
                raise ValueError(f"{where}: name the variable, as at(t, {name!r}, 'pressure') "
                                 f"or at(t, '{name}.pressure'); got only {name!r}")
        values = np.asarray(to_si(t, "s", name="t", owner=where), dtype=float)
        shape = values.shape
        flat = values.reshape(-1)
        dense = self._interpolant(where)
        bad = np.flatnonzero(~np.isfinite(flat) | (flat < -1e-9 * dense.end)
                             | (flat > dense.end * (1 + 1e-9)))
        if bad.size:
            v = float(flat[bad[0]])
            raise ValueError(f"{where}: t = {v:.6g} s is outside the run, [0, {dense.end:.6g}] s"
                             + ("" if self.success or not math.isfinite(v)
                                or v < 0 else " (the run failed there)"))
        flat = np.clip(flat, 0.0, dense.end)

        def shaped(v: Any) -> Any:
            if hasattr(v, "magnitude") and hasattr(v, "units"):      # a Quantity
                return Q_(shaped(v.magnitude), v.units)
            v = np.asarray(v).reshape(shape)
            return v[()] if not shape else v
        if label is None:
            inside = self._at_times(flat)
            return {c: shaped(v) for c, v in inside.to_dict(as_quantity=as_quantity).items()}
        assert name is not None
        e = self._entry(label, name, terminal)
        if e[0] == "output":          # a derived output: from the variables it reads
            return shaped(self._at_times(flat).get(label, name, terminal,
                                                   as_quantity=as_quantity))
        # one recorded column: that column of the interpolant alone
        none = np.empty(0, dtype=np.int64)
        one = np.array([e[4]], dtype=np.int64)
        X, S, _ = dense.values(flat, (one, none, none) if e[3] == "s" else (none, one, none))
        v = shaped((S if e[3] == "s" else X)[:, 0])
        return to_quantity(v, e[1]) if as_quantity else v

    def interpolate(self, times: Any) -> Result:
        """A Result of the same run at ``times``, from the integrator's own
        interpolant (see :meth:`at`): every variable, derived output and
        integral (:meth:`integral`) at those times, read with the same
        methods, exported and plotted the same way; ``status``, ``message``,
        ``stats`` and the validity findings are the run's (its checks judged
        every step). Sensitivities are not carried over.

        Parameters
        ----------
        times : array_like [s] or Quantity
            1-D, sorted (non-decreasing), finite, within [0, the run's last
            time].

        Returns
        -------
        Result

        Examples
        --------
        >>> fine = res.interpolate(np.linspace(0, 0.05, 1001))     # doctest: +SKIP
        >>> fine.to_dataframe()                                      # doctest: +SKIP
        """
        from .dense import check_times
        dense = self._interpolant("Result.interpolate")
        grid = check_times(times, dense.end, owner="Result.interpolate", name="times")
        return self._at_times(grid)

    def _interpolant(self, where: str) -> Any:
        dense = getattr(self, "_dense", None)
        if dense is None:
            raise ValueError(f"{where}: this Result holds no interpolant between its points "
                             "(only Simulation.run makes one; a Result rebuilt by hand or "
                             "pickled by an older softflow has none): read its points with "
                             "get(), or run the simulation again")
        return dense

    def _at_times(self, times: Array, labels: Iterable[str] | None = None) -> Result:
        """This run at ``times`` (1-D, within [0, the interpolant's end]; a failed
        run keeps those it reached) as a Result of its own. ``labels``: where
        given, only those components' columns are read (the rest NaN: a
        batched sweep's outputs, :func:`softflow.sweep._sample`)."""
        dense = self._interpolant("Result")
        if not self.success:
            times = times[times <= dense.end]
        if labels is None:
            X, S, Q = dense.values(times)
        else:
            X, S, Q = self._columns_at(dense, times, labels)
        out = object.__new__(type(self))
        out.__dict__.update(self.__dict__)
        out.times, out.X, out.S, out._Q = np.asarray(times, dtype=float), X, S, Q
        out.stats = dict(self.stats)
        out.warnings, out.validity = list(self.warnings), list(self.validity)
        for own in ("_sens", "instance_times"):      # at the steps only
            out.__dict__.pop(own, None)
        return out

    def _columns_at(self, dense: Any, times: Array,
                    labels: Iterable[str]) -> tuple[Array, Array, Array | None]:
        """(X, S, Q) at ``times`` with the columns of the components
        ``labels`` read from ``dense`` (their interface unknowns and their
        states, all a component's outputs are made of), NaN elsewhere."""
        xs: set[int] = set()
        ss: set[int] = set()
        for label in labels:
            g, i = self._where[label]
            xs.update(c for c in self._xcol[g.col[i]].tolist() if c >= 0)
            s0 = g.s0 + i * g.ns
            ss.update(c for c in self._scol[s0:s0 + g.ns].tolist() if c >= 0)
        cX = np.array(sorted(xs), dtype=np.int64)
        cS = np.array(sorted(ss), dtype=np.int64)
        has_q = getattr(dense, "Q", None) is not None or self._Q is not None
        x, s, q = dense.values(times, (cS, cX, cX if has_q else np.empty(0, np.int64)))
        X = np.full((times.size, self.X.shape[1]), np.nan)
        S = np.full((times.size, self.S.shape[1]), np.nan)
        X[:, cX], S[:, cS] = x, s
        Q = None
        if q is not None and q.size:
            Q = np.full((times.size, self.X.shape[1]), np.nan)
            Q[:, cX] = q
        return X, S, Q

    # -- columns: one name per recorded variable and derived output ----------------------
    def _names(self, label: str) -> list[tuple[str, str]]:
        """[(name, quantity)] of a component's columns, each ``name`` one that
        ``get(label, name)`` resolves to that variable: the quantity (``pressure``), or
        the label where it names the quantity more closely (a state ``internal_energy``
        of quantity ``energy``), with ``_terminal`` where it occurs at several
        terminals (a quantity without a unit, such as a valve's ``dimensionless``
        mode, goes by its label: ``open``); then the derived outputs (``volume``)
        not already among them."""
        entries = self._component_entries(label)
        base = [q if quantity_unit(q) and not (q in lab and lab != q) else lab
                for lab, q, *_ in entries]
        names = [f"{b}_{e[2]}" if base.count(b) > 1 and e[2] is not None else b
                 for b, e in zip(base, entries)]
        out = []
        for name, e in zip(names, entries):
            if not self._resolves(label, name, e):
                # the variable's own label, as get() takes it (two variables of one
                # quantity at one terminal)
                name = e[0] if [x[0] for x in entries].count(e[0]) == 1 else f"{e[0]}_{e[2]}"
            out.append((name, e[1]))
        taken = {n for n, _ in out}
        for name, (quantity, _) in self._component(label).outputs().items():
            if name not in taken and self._resolves(label, name, ("output", name)):
                out.append((name, quantity))
        return out

    def _resolves(self, label: str, name: str, entry: tuple) -> bool:
        try:
            return self._entry(label, name, None) == entry
        except KeyError:
            return False

    def _column_specs(self) -> list[tuple[str, str, str, str]]:
        """[(column, label, name, quantity)], built once."""
        specs = self._specs
        if specs is None:
            specs = self._specs = [(f"{label}.{name}", label, name, quantity)
                                   for label in self._where
                                   for name, quantity in self._names(label)]
        return specs

    def columns(self) -> list[str]:
        """Column names ``component.name`` of every recorded variable and derived output
        (an Actuator's ``volume``), as :meth:`to_dict`, :meth:`to_csv`,
        :meth:`to_dataframe` and :meth:`to_xarray` name them; ``result[column]``
        and ``result.get(component, name)`` give each one's values."""
        return [c for c, *_ in self._column_specs()]

    def units(self) -> dict[str, str]:
        """{column: SI unit} of ``'time'`` and every column (``'1'``: dimensionless)."""
        out = {"time": "s"}
        for column, _, _, quantity in self._column_specs():
            out[column] = quantity_unit(quantity) or _DIMENSIONLESS
        return out

    # -- exports ----------------------------------------------------------------------
    def to_dict(self, *, as_quantity: bool = False) -> dict[str, Any]:
        """{'time': times, 'component.name': values, ...} in SI units (see
        :meth:`columns`); every value a pint Quantity with ``as_quantity=True``."""
        out = {"time": self.get_times(as_quantity=as_quantity)}
        for column, label, name, _ in self._column_specs():
            out[column] = self.get(label, name, as_quantity=as_quantity)
        return out

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write ``time`` and every column to a CSV file: one header row with the SI
        unit in each name (``time [s]``, ``act.pressure [Pa]``), then numbers only,
        so ``pandas.read_csv(path)`` reads every column as floats."""
        units = self.units()
        d = self.to_dict()
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([f"{column} [{units[column]}]" for column in d])
            w.writerows(np.column_stack(list(d.values())).tolist())

    def to_dataframe(self) -> pd.DataFrame:
        """A pandas DataFrame indexed by ``time`` [s], one column per :meth:`columns`
        name, SI units in ``df.attrs['units']`` ({column: unit}); ``df.attrs`` also
        holds the run's ``status`` and ``message`` (needs pandas: the pandas extra)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("Result.to_dataframe needs pandas, an optional dependency: "
                              "pip install 'softflow[pandas]' (or pip install pandas)") from None
        d = self.to_dict()
        t = d.pop("time")
        df = pd.DataFrame(d, index=pd.Index(t, name="time"))
        df.attrs.update(units=self.units(), status=self.status, message=self.message)
        return df

    def to_xarray(self) -> xr.Dataset:
        """An xarray Dataset on the ``time`` coordinate [s], one data variable per
        :meth:`columns` name with attributes ``units``, ``component``, ``variable``
        and ``quantity``; the Dataset's attributes hold ``status``, ``message`` and
        the scalar counters of ``stats`` (``ds.to_netcdf(...)`` writes it; needs
        xarray: the xarray extra)."""
        try:
            import xarray as xr
        except ImportError:
            raise ImportError("Result.to_xarray needs xarray, an optional dependency: "
                              "pip install 'softflow[xarray]' (or pip install xarray)") from None
        units = self.units()
        data = {}
        for column, label, name, quantity in self._column_specs():
            data[column] = ("time", self.get(label, name),
                            {"units": units[column], "component": label, "variable": name,
                             "quantity": quantity})
        attrs: dict[str, Any] = {"status": self.status, "message": self.message}
        attrs.update({k: v for k, v in self.stats.items()
                      if isinstance(v, (int, float, np.integer, np.floating))
                      and not isinstance(v, bool)})
        return xr.Dataset(data, coords={"time": ("time", self.times, {"units": "s"})},
                          attrs=attrs)

    # -- plots (matplotlib, imported on first use) ----------------------------------------
    def _series(self, spec: Spec, units: Units, gauge: bool, where: str
                ) -> tuple[str, str, Array, str, bool]:
        """(column, quantity, values in the display unit, unit text, gauge) of a spec:
        ``'act.volume'``, ``('act', 'volume')`` or ``('tube', 'massflow', 'a')``."""
        if isinstance(spec, str):
            label, dot, name = spec.rpartition(".")
            if not dot:
                raise ValueError(f"{where}: {spec!r} is not 'component.variable' (e.g. "
                                 f"'{next(iter(self._where), 'act')}.pressure'); columns: "
                                 f"{self.columns()}")
            parts: tuple = (label, name, None)
        elif isinstance(spec, (tuple, list)) and len(spec) in (2, 3):
            parts = (*spec, None) if len(spec) == 2 else tuple(spec)
        else:
            raise TypeError(f"{where}: a variable is 'component.variable' or (component, "
                            f"variable[, terminal]), got {spec!r}")
        label, name, terminal = parts
        values = self.get(label, name, terminal)       # KeyError lists what there is
        e = self._entry(label, name, terminal)
        quantity = self._component(label).outputs()[name][0] if e[0] == "output" else e[1]
        column = f"{label}.{name}" + (f"_{terminal}" if terminal is not None else "")
        si = quantity_unit(quantity) or "dimensionless"
        is_gauge = gauge and quantity == "pressure"
        if is_gauge:
            values = values - pressure_atmospheric
        unit = None
        if isinstance(units, str):
            unit = units
        elif units:
            unit = units.get(column, units.get(quantity))
        if unit is not None:
            try:
                values = Q_(values, si).to(unit).magnitude
            except Exception as err:        # pint: undefined unit or wrong dimension
                raise UnitError(f"{where}: {column} is a {quantity} [{si}]; cannot show it "
                                f"in {unit!r} ({err})") from None
        # the unit as the caller wrote it ('mL', not pint's 'ml'); SI as pint prints it
        shown = unit if unit is not None else (f"{Q_(1.0, si).units:~P}" or "-")
        return column, quantity, values, shown, is_gauge

    def _time_axis(self, time_unit: str, where: str) -> tuple[Array, str]:
        try:
            t = Q_(self.times, "s").to(time_unit).magnitude
        except Exception as err:
            raise UnitError(f"{where}: time_unit {time_unit!r} is not a time ({err})") from None
        return t, f"time [{time_unit}]"

    def plot(self, *variables: Spec, components: Sequence[str] | None = None,
             names: Sequence[str] | None = None, units: Units = None, gauge: bool = False,
             time_unit: str = "s", ax: Axes | Sequence[Axes] | None = None
             ) -> Axes | list[Axes]:
        """Plot variables against time; one call, units on the axes.

        Parameters
        ----------
        *variables : str or tuple
            ``'act.volume'``, ``('act', 'volume')`` or ``('tube', 'massflow', 'a')``.
            With no variables (and no ``components``), the pressure of every
            one-port component (sources, volumes, actuators) and every volume
            that changes (actuators'): a first look at a run.
        components, names : list of str, optional
            Every name of every component, after ``variables``:
            ``plot(components=['act1', 'act2'], names=['pressure', 'volume'])``.
        units : str or dict, optional
            Display unit: one for all (``'bar'``), or per quantity or column
            (``{'pressure': 'mbar', 'volume': 'mL'}``); default SI.
        gauge : bool
            Show pressures relative to 1 atm.
        time_unit : str
            Unit of the time axis (default ``'s'``).
        ax : matplotlib Axes or list of Axes, optional
            Where to draw: one Axes per quantity; by default a new figure.

        Returns
        -------
        Axes, or a list of Axes (stacked, sharing the time axis) when the
        variables are of several quantities (pressure, volume, ...).
        """
        where = "Result.plot"
        specs = list(variables) + [(c, n) for c in (components or []) for n in (names or [])]
        if bool(components) != bool(names):
            raise ValueError(f"{where}: give components= and names= together")
        if not specs:
            specs = self._default_plot()
        if not specs:
            raise ValueError(f"{where}: name what to plot, e.g. plot('{next(iter(self._where), 'act')}"
                             f".pressure'); columns: {self.columns()}")
        series = [self._series(spec, units, gauge, where) for spec in specs]
        t, t_axis = self._time_axis(time_unit, where)
        groups: dict[str, list[tuple[str, Array]]] = {}
        for column, quantity, values, shown, is_gauge in series:
            axis = f"{'gauge ' if is_gauge else ''}{quantity} [{shown}]"
            groups.setdefault(axis, []).append((column, values))
        axes = _axes(ax, len(groups), where, sharex=True)
        for a, (axis, lines) in zip(axes, groups.items()):
            for column, values in lines:
                a.plot(t, values, label=column)
            a.set_ylabel(axis)
            a.legend()
        axes[-1].set_xlabel(t_axis)
        return axes[0] if len(axes) == 1 else axes

    def _default_plot(self) -> list[Spec]:
        """What :meth:`plot` draws when named nothing: the pressure of every
        one-port component (sources, volumes, actuators: the network's nodes
        that hold something) and every volume that changes over the run (an
        actuator's)."""
        out: list[Spec] = []
        for column in self.columns():
            label, name = column.split(".", 1)
            if name == "pressure":
                out.append(column)
            elif name == "volume":
                values = self[column]
                if len(values) and np.ptp(values) > 0.0:
                    out.append(column)
        return out

    def plot_path(self, x: Spec, y: Spec, *, units: Units = None, gauge: bool = False,
                  ax: Axes | None = None, label: str | None = None) -> Axes:
        """Plot one variable against another over the run (the FONS paper's panel D:
        ``plot_path(('act1', 'volume'), ('act2', 'volume'))``), the start marked.

        ``x``, ``y``: as in :meth:`plot`; ``units``, ``gauge`` as there; ``ax``: an
        Axes to draw in; ``label``: the legend entry. Returns the Axes.
        """
        where = "Result.plot_path"
        xc, _, xv, x_unit, x_gauge = self._series(x, units, gauge, where)
        yc, _, yv, y_unit, y_gauge = self._series(y, units, gauge, where)
        (a,) = _axes(ax, 1, where)
        line, = a.plot(xv, yv, label=label)
        if len(xv):
            a.plot(xv[:1], yv[:1], "o", color=line.get_color())
        a.set_xlabel(f"{xc}{' (gauge)' if x_gauge else ''} [{x_unit}]")
        a.set_ylabel(f"{yc}{' (gauge)' if y_gauge else ''} [{y_unit}]")
        if label is not None:
            a.legend()
        return a

    def __repr__(self) -> str:
        return (f"<Result {self.status}: {len(self.times)} points, "
                f"t = {self.times[0] if len(self.times) else 0:g}..{self.times[-1] if len(self.times) else 0:g} s>")

    def report(self) -> str:
        """A readable summary of the run, as text: its status (and, for a failed
        run, why it stopped), the time it covers, the solver's counters (steps,
        rejected steps, Newton iterations, factorizations, rtol), and the model
        validity warnings (``self.warnings``) grouped by component and check,
        each with its figure against its limit (how far past it) and the
        finding in words; then the near misses (``self.validity`` records with
        status 'near', not warned) as one line each.

        >>> print(result.report())      # doctest: +SKIP
        Run: success, t = 0 .. 1 s (44 points)
        Solver: 43 steps (0 rejected), 91 Newton iterations, 31 factorizations, rtol 0.001
        Warnings: none
        """
        import re
        import textwrap

        def wrap(text: str, indent: str) -> list[str]:
            return textwrap.wrap(text, 88, initial_indent=indent, subsequent_indent=indent)

        def figure(value: float, unit: str) -> str:
            return f"{value:.3g}{' ' + unit if unit else ''}"

        n = len(self.times)
        span = f"t = {self.times[0]:g} .. {self.times[-1]:g} s" if n else "no points"
        lines = [f"Run: {self.status}, {span} ({n} points)"]
        if self.message:
            lines += wrap(f"Message: {self.message}", "")
        st = self.stats
        counters = [f"{st[k]} {name}" for k, name in (
            ("steps", "steps"), ("rejected_steps", "rejected"),
            ("newton_iterations", "Newton iterations"),
            ("factorizations", "factorizations")) if k in st]
        if counters:
            if "rejected_steps" in st and "steps" in st:     # '43 steps (2 rejected)'
                counters = [c for c in counters if not c.endswith(" rejected")]
                counters[0] += f" ({st['rejected_steps']} rejected)"
            rtol = f", rtol {st['rtol']:g}" if "rtol" in st else ""
            lines.append(f"Solver: {', '.join(counters)}{rtol}")
        warned = list(self.warnings)
        if not warned:
            lines.append("Warnings: none")
        else:
            groups: dict[str, dict[str, list[Any]]] = {}
            for r in warned:
                groups.setdefault(r.component, {}).setdefault(r.check, []).append(r)
            lines.append(f"Warnings: {len(warned)} ({len(groups)} component"
                         f"{'s' if len(groups) != 1 else ''})")
            for component, checks in groups.items():
                lines.append(f"  {component}:")
                for check, records in checks.items():
                    for r in records:
                        size = f"{figure(r.measured, r.unit)} against a limit of " \
                               f"{figure(r.limit, r.unit)}"
                        if r.fraction == r.fraction:          # not NaN
                            size += f" (fraction {r.fraction:.3g}; 1 at the limit)"
                        lines.append(f"    {check}: {size}")
                        # the finding, less the "Class 'label': " it starts with
                        text = re.sub(rf"^\w+ '{re.escape(component)}': ", "", r.message)
                        lines += wrap(text, "      ")
        near = [r for r in self.validity if getattr(r, "status", "beyond") == "near"]
        if near:
            lines.append(f"Near misses (not warned): {len(near)}")
            for r in near:
                lines.append(f"  {r.component}: {r.check} at {r.fraction:.0%} of its limit")
        return "\n".join(lines)


def _axes(ax: Any, n: int, where: str, sharex: bool = False) -> list[Axes]:
    """``n`` Axes: the given one(s), or a new figure's (stacked)."""
    if ax is None:
        import matplotlib.pyplot as plt
        _, axes = plt.subplots(n, 1, sharex=sharex, squeeze=False,
                               figsize=(6.4, 2.2 + 2.2 * n if n > 1 else 4.8))
        return list(axes[:, 0])
    given = list(np.ravel(ax)) if isinstance(ax, (list, tuple, np.ndarray)) else [ax]
    if len(given) != n:
        raise ValueError(f"{where}: {n} quantit{'y' if n == 1 else 'ies'} to plot, each on "
                         f"its own Axes, but ax= gives {len(given)}")
    return given
