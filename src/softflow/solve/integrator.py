"""Time integrators: the shared base, and backward Euler at a fixed step.

The adaptive, variable-order integrator is :mod:`softflow.solve.bdf`.
"""
from __future__ import annotations

import math

import numpy as np

from .linalg import make_linear_solver
from .progress import SILENT


class StepFailure(Exception):
    def __init__(self, t, dt, outcome):
        self.t, self.dt, self.outcome = t, dt, outcome


class StoppedAtStart(Exception):
    """The run ends after its consistent point at t = 0 (see
    :attr:`Integrator.stop_at_start`): what it would compute from there on is
    refused anyway."""


class Recorder:
    """Accepted steps, written into preallocated arrays that grow by doubling
    (no stacking of a list of rows at the end: for large networks that copy
    alone cost as much as the solve)."""

    def __init__(self, x_index, s_index, capacity=64):
        self.t = []
        # index arrays of the unknowns/states to keep, or plain sizes to keep all
        self.x_index, self.s_index = x_index, s_index
        self._x_all, self._s_all = isinstance(x_index, int), isinstance(s_index, int)
        n = x_index if self._x_all else len(x_index)
        ns = s_index if self._s_all else len(s_index)
        self._X = np.empty((capacity, n))
        self._S = np.empty((capacity, ns))
        self._Q = None      # time integrals of the recorded unknowns, if the integrator keeps them

    def keep_integrals(self):
        """Record, with each point, the integrals of the recorded unknowns since t = 0
        (``q`` of :meth:`add`, already restricted to the recorded columns)."""
        self._Q = np.empty_like(self._X)

    def add(self, t, x, s, q=None):
        k = len(self.t)
        if k == len(self._X):
            self._X = np.concatenate([self._X, np.empty_like(self._X)])
            self._S = np.concatenate([self._S, np.empty_like(self._S)])
            if self._Q is not None:
                self._Q = np.concatenate([self._Q, np.empty_like(self._Q)])
        self._X[k] = x if self._x_all else x[self.x_index]
        self._S[k] = s if self._s_all else s[self.s_index]
        if self._Q is not None:
            self._Q[k] = 0.0 if q is None else q
        self.t.append(t)

    def arrays(self):
        k = len(self.t)
        return np.array(self.t, dtype=float), self._X[:k], self._S[:k]

    def integrals(self):
        """(k, n_recorded) integrals of the recorded unknowns, or None."""
        return None if self._Q is None else self._Q[:len(self.t)]


class FixedStep:
    """Constant step h0 on a grid t_k = k·h0, landing on breakpoints in between.
    A failed Newton solve cuts the step by 4 (substeps are recorded too) until
    ``step_min``; the next step aims at the grid again. The stepping itself is
    written into :meth:`ImplicitEuler._run_fixed`; this holds its settings and
    the index of the last grid point reached."""

    def __init__(self, step, step_min, duration):
        self.h0, self.step_min, self.T = step, step_min, duration
        self.n_grid = max(1, int(math.ceil(duration / step - 1e-9)))
        self.k = 0            # index of the last grid point reached


class Integrator:
    """What every time integrator shares: the breakpoints (sorted, searched with
    a pointer), the recorder, the consistent start at t = 0."""

    def __init__(self, asm, newton, stats, *, duration, breakpoints=(), record=None,
                 expected_steps=256):
        self.asm, self.newton, self.stats = asm, newton, stats
        self.T = duration
        self.breaks = sorted(b for b in set(breakpoints) if 0.0 < b < duration)
        self._break_set = set(self.breaks)
        # record: (unknown indices, state indices, labels) to keep, or None for all
        x_index, s_index = record[:2] if record is not None else (asm.n, len(asm.S0))
        self.rec = Recorder(x_index, s_index, capacity=min(max(expected_steps, 16), 100_000))

    forced_steps = 0
    #: reporter of the run (bar, logged events); Simulation.run sets its own
    progress = SILENT
    #: forward sensitivities carried along (softflow.solve.sensitivity), or None
    sens = None
    #: None, or a callable that, after the consistent point at t = 0 is recorded,
    #: says whether the run should stop there (a model past its own maximum from
    #: the start: Simulation.run refuses every later point anyway)
    stop_at_start = None

    def _next_break(self, t, ib):
        """(index, time) of the first breakpoint after t, searching from index ib
        (the loops keep a pointer into the sorted breakpoints)."""
        breaks = self.breaks
        while ib < len(breaks) and breaks[ib] <= t * (1 + 1e-14) + 1e-300:
            ib += 1
        return ib, (breaks[ib] if ib < len(breaks) else math.inf)

    #: a consistent point at t = 0 from an earlier run of the same network, inputs
    #: and tolerances, to try before solving (Simulation.run remembers them):
    #: (x, Newton's contraction estimate ``eta`` after the solve that made x,
    #: whether ``stop_at_start`` passed x, the dense linear solver that solve
    #: factored or None), or None
    start = None
    #: the same of this run, set by :meth:`initial`
    consistent = None

    def initial(self):
        """Consistent algebraic unknowns at t = 0 (dt = 0, states at their initial values).

        A remembered ``start`` that Newton confirms (:meth:`Newton.confirms`:
        one residual and update, no iteration from the initial values) is
        taken as it is, with the contraction estimate the solve that made it
        left behind, so that the run goes on exactly as that one did; any
        other is dropped and the unknowns are solved for from their initial
        values. Dense systems solve it on a linear solver of its own, whose
        factors stay as that solve left them: the next run confirms its point
        on them, without a Jacobian (larger systems confirm on a Jacobian of
        their own: a second sparse solver's analysis costs more than that)."""
        asm, newton = self.asm, self.newton
        x, passed, lin0 = None, False, None
        if self.start is not None:
            x, eta, passed, lin0 = self.start
            if (x.shape == asm.x0.shape
                    and newton.confirms(x, asm.S0, 0.0, 0.0, lin=lin0)):
                x = x.copy()
                newton.eta = eta
            else:
                x, passed, lin0 = None, False, None
        if x is None:
            x, lin0 = self._solve_initial()
        eta = newton.eta
        newton.invalidate()
        self.rec.add(0.0, x, asm.S0.copy())
        if self.sens is not None:
            self.sens_S = self.sens.initial(x, asm.S0)[1]
        if self.stop_at_start is None:
            passed = False
        elif not passed:
            # the same point passed the same checks in the run it is remembered
            # from; only a point of its own is asked (the check only spares a run
            # refused from its start its remaining steps: the checks after the
            # run, always made, refuse it all the same)
            self.consistent = (x.copy(), eta, False, lin0)
            if self.stop_at_start():
                raise StoppedAtStart()
            passed = True
        self.consistent = (x.copy(), eta, passed, lin0)
        return x, asm.S0.copy()

    def _solve_initial(self):
        """The consistent point at t = 0 solved for from the initial values, and
        the dense linear solver of its own that solve factored (None: the
        run's solver, for sparse and condensed systems)."""
        asm, newton = self.asm, self.newton
        lin0 = make_linear_solver(asm, "dense") if newton.lin.kind == "dense" else None
        run_lin = newton.lin
        if lin0 is not None:
            newton.lin = lin0
        try:
            out = newton.solve(asm.x0.copy(), asm.S0, 0.0, 0.0)
        finally:
            newton.lin = run_lin
        if not out.converged:
            raise StepFailure(0.0, 0.0, out)
        return out.x, lin0


class ImplicitEuler(Integrator):
    """Backward Euler at a fixed step (the FONS paper's scheme) on a
    :class:`FixedStep` grid. Newton starts from a linear extrapolation of the
    last two points; after a breakpoint, a mode switch of a discrete state or a
    failed solve it starts from the last point instead. (Adaptive steps:
    :class:`softflow.solve.bdf.BDF`, whose order 1 is backward Euler.)"""

    def __init__(self, asm, newton, stats, *, duration, step, step_min, breakpoints=(),
                 record=None):
        # a breakpoint on a grid point must be that grid point's float exactly,
        # or the step lands twice (0.3 vs 3*0.1) with a ~1e-17 s step between
        snapped = []
        for b in breakpoints:
            k = round(b / step)
            snapped.append(k * step if abs(b - k * step) <= 1e-9 * step else b)
        super().__init__(asm, newton, stats, duration=duration, breakpoints=snapped,
                         record=record,
                         expected_steps=int(duration / step) + 2 + len(set(snapped)))
        self.ctrl = FixedStep(step, step_min, duration)

    def run(self):
        x, S = self.initial()
        return self._run_fixed(x, S)

    def _run_fixed(self, x, S):
        """The loop of :meth:`run` for a :class:`FixedStep` controller: the grid,
        the breakpoints (a pointer into the sorted list) and the step cut after
        a failed solve written in, on local variables (on the paper's
        three-component scene the calls of a generic loop into the controller
        cost ~1.5 us of each step). Same steps and arithmetic as that loop."""
        asm, ctrl, stats, rec = self.asm, self.ctrl, self.stats, self.rec
        solve, update, T = self.newton.solve, asm.update_states, self.T
        begin = asm.begin_step if asm.has_begin_step else None
        if begin is not None:
            begin(x, S)
        disc = asm.s_discrete if asm.has_discrete else None
        h0, n_grid, step_min = ctrl.h0, ctrl.n_grid, ctrl.step_min
        break_set = self._break_set
        ib, next_break = 0, (self.breaks[0] if self.breaks else math.inf)
        rec_add, tick = rec.add, self.progress.step
        t, k, h_cut = 0.0, 0, None
        t_stop = T * (1 - 1e-14)
        x_prev = h_prev = None
        extrapolate = True
        while t < t_stop:
            if next_break <= t * (1 + 1e-14) + 1e-300:
                ib, next_break = self._next_break(t, ib)
            grid_next = T if k + 1 >= n_grid else min((k + 1) * h0, T)
            end = next_break if next_break < grid_next else grid_next
            h = end - t
            if h_cut is not None and h_cut < h:
                h = h_cut
                end = t + h
            if x_prev is None or not extrapolate:
                x_pred = x
            else:
                r = h / h_prev
                x_pred = x + (x - x_prev) if r == 1.0 else x + (x - x_prev) * r
            t_new = t + h
            # at a breakpoint the step sees the inputs' left limit
            at_break = t_new in break_set
            out = solve(x_pred, S, math.nextafter(t_new, -math.inf) if at_break else t_new, h)
            if not out.converged:
                stats.rejected_steps += 1
                self.progress.rejected(t_new, h, "newton", out)
                if h / 4 < step_min:
                    ctrl.k = k
                    raise StepFailure(t + h, h, out)
                h_cut = h / 4
                extrapolate = False
                continue
            S_new = update(out.x, S, h)
            if t_new != end and abs(t_new - end) <= 1e-12 * max(1.0, end):
                t_new = end
                at_break = t_new in break_set
            stats.steps += 1
            if disc is not None and not at_break:
                at_break = bool((S_new[disc] != S[disc]).any())
                if at_break:
                    self.progress.switched(t_new, S, S_new, disc)
            if self.sens is not None:      # backward Euler: psi = S_n, c = h
                self.sens.step(out.x, S, math.nextafter(t_new, -math.inf)
                               if at_break and t_new in break_set else t_new, h)
            x_prev, h_prev = x, h
            x, S, t = out.x, S_new, t_new
            rec_add(t, x, S)
            tick(t)
            if begin is not None:
                begin(x, S)
            h_cut = None
            if t == grid_next:
                k += 1
            extrapolate = True
            if at_break:
                x_prev = None
                self.newton.invalidate()
        ctrl.k = k
