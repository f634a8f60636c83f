"""Simulation results: times and every variable as arrays, by component and label."""
from __future__ import annotations

import csv

import numpy as np

from ..units import to_quantity


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
        Counters: steps, rejected_steps, newton_iterations, jacobian_evaluations,
        factorizations, ...
    """

    def __init__(self, asm, times, X, S, status="success", message="", stats=None,
                 recorded=None, integrals=None):
        self.times = times
        self.X = X
        self.S = S
        # time integrals of the recorded unknowns as the integrator formed them
        # (BDF runs), or None: backward Euler's are sums of step times end value
        self._Q = integrals
        self.status = status
        self.message = message
        self.stats = dict(stats or {})
        # where each component lives; its variable index is built on first access
        self._where = asm.where
        self._entries = {}
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

    def _component_entries(self, label):
        if label not in self._entries:
            if label not in self._where:
                raise KeyError(f"no component {label!r} in this result (not in the system, "
                               "or not among Simulation(record=...))")
            g, i = self._where[label]
            iface, states = g.iface[i]
            entries = [(v.label, v.quantity, term, "x", int(self._xcol[g.col[i, k]]))
                       for k, (term, v) in enumerate(iface)]
            entries += [(sv.label, sv.quantity, None, "s", int(self._scol[g.s0 + i * g.ns + j]))
                        for j, sv in enumerate(states)]
            self._entries[label] = entries
        return self._entries[label]

    def _component(self, label):
        g, i = self._where[label]
        return g.comps[i]

    @property
    def success(self):
        return self.status == "success"

    def _entry(self, label, name, terminal):
        entries = self._component_entries(label)
        by_label = [e for e in entries if e[0] == name or f"{e[0]}_{e[2]}" == name]
        cands = by_label or [e for e in entries if e[1] == name]
        if terminal is not None:
            cands = [e for e in cands if e[2] == terminal]
        if len(cands) == 1:
            return cands[0]
        if not cands:
            outs = self._component(label).outputs()
            if name in outs and terminal is None:
                return ("output", name)
            names = sorted({e[0] for e in entries} | {e[1] for e in entries} | set(outs))
            raise KeyError(f"component {label!r} has no variable {name!r}"
                           + (f" at terminal {terminal!r}" if terminal else "")
                           + f"; it has {names}")
        terms = [e[2] for e in cands]
        raise KeyError(f"component {label!r}: {name!r} is ambiguous (terminals {terms}); "
                       f"pass terminal=, e.g. get({name!r}, {terms[0]!r})")

    def get(self, label, name, terminal=None, *, as_quantity=False):
        """Values of variable ``name`` (label, quantity or output name) of component ``label``."""
        e = self._entry(label, name, terminal)
        if e[0] == "output":
            quantity, fn = self._component(label).outputs()[name]
            values = np.asarray(fn(lambda n, term=None: self.get(label, n, term)), dtype=float)
        else:
            _, quantity, _, where, idx = e
            values = (self.X if where == "x" else self.S)[:, idx]
        return to_quantity(values, quantity) if as_quantity else values

    def integral(self, label, name, terminal=None, *, as_quantity=False):
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

    def __getitem__(self, key):
        """``result['tube.massflow']`` or ``result['tube', 'massflow', 'a']``."""
        if isinstance(key, tuple):
            return self.get(*key)
        label, _, name = key.rpartition(".")
        return self.get(label, name)

    def columns(self):
        """Unique column names ``component.variable[_terminal]`` of every variable."""
        cols = []
        for label in self._where:
            entries = self._component_entries(label)
            counts = {}
            for e in entries:
                counts[e[0]] = counts.get(e[0], 0) + 1
            for e in entries:
                name = e[0] if counts[e[0]] == 1 else f"{e[0]}_{e[2]}"
                cols.append((f"{label}.{name}", e))
        return cols

    def to_dict(self):
        """{'time': times, 'component.variable': values, ...} (SI units)."""
        out = {"time": self.times}
        for name, e in self.columns():
            out[name] = (self.X if e[3] == "x" else self.S)[:, e[4]]
        return out

    def to_csv(self, path):
        """Write every variable to a CSV file with a names row and an SI units row."""
        from ..units import quantity_unit
        d = self.to_dict()
        units = ["s"] + [quantity_unit(e[1]) or "" for _, e in self.columns()]
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(list(d))
            w.writerow(units)
            w.writerows(np.column_stack(list(d.values())).tolist())

    def to_dataframe(self):
        """A pandas DataFrame indexed by time (needs the optional pandas extra)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("to_dataframe needs pandas: pip install 'softflow[pandas]'") from None
        d = self.to_dict()
        t = d.pop("time")
        return pd.DataFrame(d, index=pd.Index(t, name="time"))

    def __repr__(self):
        return (f"<Result {self.status}: {len(self.times)} points, "
                f"t = {self.times[0] if len(self.times) else 0:g}..{self.times[-1] if len(self.times) else 0:g} s>")
