"""Time integrators: the one integration loop, and backward Euler at a fixed step.

Every stepper runs the same loop, :meth:`Integrator.run`: from the consistent
point at t = 0, each step is *proposed* by the stepper (the start of Newton,
the step equations' start-of-step states psi and step coefficient c, the
time the step ends at), *solved* by Newton (:mod:`softflow.solve.newton`:
F(x; psi, c) = 0, the equations of :mod:`softflow.solve.discretize`), its
states *updated* (psi + c r(x)), and then *judged* by the stepper (its error
test, a mode switch's location): accepted, it is *taken* (recorded, the
stepper's own bookkeeping: sensitivities, difference tables, order and next
step); rejected, the stepper has shrunk its step and the loop proposes
again. A failed Newton solve goes to the stepper too (a smaller step, or
:class:`StepFailure` at ``step_min``).

The steppers are the controllers of that loop:

* :class:`ImplicitEuler`: backward Euler at a fixed step (the FONS paper's
  scheme): psi = X_n, c = h on a grid, every converged step accepted;
* :class:`softflow.solve.bdf.BDF`: variable-order, variable-step BDF (orders
  1-5; ``method='euler'`` is its order 1), with its error test, order and
  step selection, restarts and mode-switch location.

(Batched variants on clocks of their own run the BDF's controller vectorized
over the variants, :mod:`softflow.solve.clocks`.)
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import sourcenodes
from .linalg import make_linear_solver
from .newton import StepLimitError
from .progress import SILENT

#: steps in a row the loop solves by continuation where Newton failed at the
#: smallest step (:meth:`Integrator._rescue`); the next such failure stops the
#: run (each rescue costs up to 2 x CONTINUATION_SOLVES Newton solves)
RESCUES_IN_A_ROW = 8


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


class Integrator:
    """The integration loop (:meth:`run`) and what every stepper shares: the
    breakpoints (sorted, searched with a pointer), the recorder, the
    consistent start at t = 0. A stepper (a subclass) is the loop's
    controller: it states

    ``_setup(x, S)``
        its state at the consistent point at t = 0;
    ``_propose(t, x, S)``
        the next step: (Newton's start, psi, the time t_new the step ends at,
        the time the equations are evaluated at, c);
    ``_newton_failed(t, t_new, out)``
        after a failed solve: a smaller step, and None, or the unknowns of
        another point at t to go on from (BDF past an actuator's fold); or
        :class:`StepFailure` at the smallest step, where the loop tries the
        step's equations once more by continuation
        (:meth:`softflow.solve.newton.Newton.continuation`) before the run
        stops;
    ``_judge(t, x, S, x_new, S_new, t_new)``
        whether the solved step is accepted: the time it ends at, or None
        where it is rejected (the stepper having shrunk its step);
    ``_take(t, x, S, x_new, psi, c, S_new, t_new)``
        the accepted step recorded and the stepper's own bookkeeping; returns
        the new point (x, S, t).
    """

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
    #: Simulation(max_steps=): the most steps a run may take, accepted and
    #: rejected (``stats.steps + stats.rejected_steps``, as the run's stats
    #: report them; a step whose failed solve continuation rescued counts as
    #: that rejected try and the accepted step), or None. The solves that are
    #: no steps are not counted: the consistent start's, BDF's restart probes
    #: (three at t = 0 and at each breakpoint, switch or fold jump), a fold
    #: jump's, continuation's. The batched engine (softflow.solve.clocks)
    #: counts each variant's tries alike
    max_steps = None
    #: None, or a callable that, after the consistent point at t = 0 is recorded,
    #: says whether the run should stop there (a model past its own maximum from
    #: the start: Simulation.run refuses every later point anyway)
    stop_at_start = None

    def run(self):
        """Integrate from the consistent point at t = 0 to the end (module
        docstring): the one loop of every stepper."""
        x, S = self.initial()
        self._setup(x, S)
        asm, stats = self.asm, self.stats
        solve, update = self.newton.solve, asm.update_states
        begin = asm.begin_step if asm.has_begin_step else None
        if begin is not None:
            begin(x, S)
        propose, failed, judge, take = self._propose, self._newton_failed, self._judge, self._take
        tick = self.progress.step
        t, t_stop = 0.0, self.T * (1 - 1e-14)
        rescues = 0      # steps in a row solved by continuation (_rescue)
        max_steps = math.inf if self.max_steps is None else self.max_steps
        while t < t_stop:
            if stats.steps + stats.rejected_steps >= max_steps:
                raise StepLimitError(
                    f"more than max_steps = {self.max_steps} steps (accepted and rejected) "
                    f"by t = {t:.6g} s; pass a larger Simulation(max_steps=...) to go on")
            x_pred, psi, t_new, t_eval, c = propose(t, x, S)
            out = solve(x_pred, psi, t_eval, c)
            if not out.converged:
                stats.rejected_steps += 1
                try:
                    # a controller may go on from another point at t (BDF: past
                    # an actuator's fold)
                    jumped = failed(t, t_new, out)
                except StepFailure:
                    # the smallest step failed: its equations by continuation
                    # (Newton.continuation) before the run stops, unless the
                    # steps before needed it too (a run that would crawl on)
                    rescued = (self._rescue(x_pred, x, psi, t_eval, c, out)
                               if rescues < RESCUES_IN_A_ROW else None)
                    if rescued is None:
                        raise
                    rescues += 1
                    out = rescued
                else:
                    if jumped is not None:
                        x = jumped
                    continue
            else:
                rescues = 0
            x_new = out.x
            S_new = update(x_new, psi, c)
            t_new = judge(t, x, S, x_new, S_new, t_new)
            if t_new is None:
                continue
            stats.steps += 1
            x, S, t = take(t, x, S, x_new, psi, c, S_new, t_new)
            tick(t)
            if begin is not None:
                begin(x, S)

    def _rescue(self, x_pred, x, psi, t_eval, c, out):
        """The converged Outcome of a step whose Newton solve failed at the
        smallest step, by continuation (:meth:`Newton.continued`) from its
        predictor and, where that fails, from the step's start x (a predictor
        whose residual is not finite); or None. The failed solve stays
        counted as a rejected step."""
        for start in (x_pred, x):
            rescued = self.newton.continued(out, start, psi, t_eval, c)
            if rescued.converged:
                return rescued
        return None

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
        """The consistent point at t = 0 solved for from the initial values
        (confirmed on a Jacobian at it, else solved again from it, up to
        INITIAL_CONFIRMS times), and the dense linear solver of its own that
        solve factored (None: the run's solver, for sparse and condensed
        systems). Where that fails, or puts a node above
        :data:`softflow.solve.sourcenodes.PRESSURE_CAP`, it is solved again
        from a start with each node without volume that a flow source feeds
        at the pressure that balances it alone
        (:func:`softflow.solve.sourcenodes.balanced_start`), or the run is
        refused where no pressure does; a start that converges from the
        initial values is taken as it always was."""
        asm, newton = self.asm, self.newton
        lin0 = make_linear_solver(asm, "dense") if newton.lin.kind == "dense" else None
        run_lin = newton.lin
        if lin0 is not None:
            lin0.note_scale = True
            newton.lin = lin0
        try:
            out = self._solve_from(asm.x0.copy())
            if not out.converged or sourcenodes.above_cap(asm, out.x):
                # a flow source at a node without volume, whose balance needs a
                # pressure far from the initial one: each such node balanced
                # alone first (softflow.solve.sourcenodes), or the run refused
                # where no pressure up to the cap balances it
                start, refusal = sourcenodes.balanced_start(
                    asm, asm.x0, asm.S0, newton.atol, self.stats)
                if refusal is not None:
                    raise StepFailure(0.0, 0.0, refusal)
                if start is not None:
                    again = self._solve_from(start)
                    if again.converged and not sourcenodes.above_cap(asm, again.x):
                        out = again
        finally:
            newton.lin = run_lin
        if not out.converged:
            raise StepFailure(0.0, 0.0, _with_scale_hint(out, lin0))
        return out.x, lin0

    def _solve_from(self, start):
        """The Outcome of the consistent point at t = 0 solved for from
        ``start`` (:meth:`_solve_initial`)."""
        newton, S0 = self.newton, self.asm.S0
        # each point is confirmed on a Jacobian of its own, else solved
        # again from it: chord iterations on the slopes at the initial
        # values (an orifice's laminar slope at rest, many times its slope
        # at the flow it reaches) stop where their updates are small,
        # which such a slope makes them far from the root
        for tries in range(INITIAL_CONFIRMS + 1):
            out = newton.continued(newton.solve(start, S0, 0.0, 0.0), start, S0, 0.0, 0.0)
            if (not out.converged or tries == INITIAL_CONFIRMS
                    or newton.confirms(out.x, S0, 0.0, 0.0)):
                break
            start = out.x
        return out


#: How many times the consistent point at t = 0 is solved again from where the
#: last solve stopped, where a Jacobian at that point does not confirm it
#: (Integrator._solve_initial); still unconfirmed after that, it is taken.
INITIAL_CONFIRMS = 3


#: failures of a consistent start that say no more than that Newton did not
#: get there: where the dense solver found a component's scale extreme on
#: the way, that component is named beside them as the likely cause
_UNSPECIFIC = ("line search failed", "no convergence", "Newton diverging",
               "Newton converging too slowly", "residual not finite along")


def _with_scale_hint(out, lin):
    """A failed consistent start's Outcome, with the component whose scale
    :meth:`Assembly.diagnose_scale` found extreme where the start's dense
    solver had to equilibrate (``DenseLU.scale_note``) named as the likely
    cause (a 1 nm long tube between a source and a 1000 m^3 tank: the line
    search fails on the source's equation). Only a hint, and only beside an
    unspecific failure (:data:`_UNSPECIFIC`; not one that names a fluid's
    range or a negative pressure): such networks are solved where they can
    be, and the failure's own equation (``row``, the error's component)
    stays as it is."""
    why = getattr(lin, "scale_note", None)
    if (why is None or "extreme relative" in out.reason or "(in " in out.reason
            or not out.reason.startswith(_UNSPECIFIC)):
        return out
    return dataclasses.replace(out, reason=f"{out.reason}; likely cause: {why}")


class ImplicitEuler(Integrator):
    """Backward Euler at a fixed step (the FONS paper's scheme): psi = X_n,
    c = h, on a grid t_k = k·h0 that lands on the breakpoints in between.
    Every converged step is accepted. A failed Newton solve cuts the step by
    4 (substeps are recorded too) until ``step_min``; the next step aims at the
    grid again. Newton starts from a linear extrapolation of the last two
    points; after a breakpoint, a mode switch of a discrete state or a failed
    solve it starts from the last point instead. (Adaptive steps:
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
        self.h0, self.step_min = step, step_min
        self.n_grid = max(1, int(math.ceil(duration / step - 1e-9)))
        self.k = 0            # index of the last grid point reached

    def _setup(self, x, S):
        self._disc = self.asm.s_discrete if self.asm.has_discrete else None
        self._ib, self._next = 0, (self.breaks[0] if self.breaks else math.inf)
        self._h_cut = None            # the step after a failed solve
        self._x_prev = self._h_prev = None
        self._extrapolate = True

    def _propose(self, t, x, S):
        if self._next <= t * (1 + 1e-14) + 1e-300:
            self._ib, self._next = self._next_break(t, self._ib)
        T, k = self.T, self.k
        grid_next = T if k + 1 >= self.n_grid else min((k + 1) * self.h0, T)
        next_break = self._next
        end = next_break if next_break < grid_next else grid_next
        h = end - t
        h_cut = self._h_cut
        if h_cut is not None and h_cut < h:
            h = h_cut
            end = t + h
        x_prev = self._x_prev
        if x_prev is None or not self._extrapolate:
            x_pred = x
        else:
            r = h / self._h_prev
            x_pred = x + (x - x_prev) if r == 1.0 else x + (x - x_prev) * r
        t_new = t + h
        # at a breakpoint the step sees the inputs' left limit
        at_break = t_new in self._break_set
        self._h, self._end, self._grid_next, self._at_break = h, end, grid_next, at_break
        return x_pred, S, t_new, math.nextafter(t_new, -math.inf) if at_break else t_new, h

    def _newton_failed(self, t, t_new, out):
        h = self._h
        self.progress.rejected(t_new, h, "newton", out)
        if h / 4 < self.step_min:
            raise StepFailure(t + h, h, out)
        self._h_cut = h / 4
        self._extrapolate = False

    def _judge(self, t, x, S, x_new, S_new, t_new):
        end = self._end
        if t_new != end and abs(t_new - end) <= 1e-12 * max(1.0, end):
            t_new = end
            self._at_break = t_new in self._break_set
        return t_new

    def _take(self, t, x, S, x_new, psi, c, S_new, t_new):
        at_break, disc = self._at_break, self._disc
        if disc is not None and not at_break:
            at_break = bool((S_new[disc] != S[disc]).any())
            if at_break:
                self.progress.switched(t_new, S, S_new, disc)
        if self.sens is not None:      # backward Euler: psi = S_n, c = h
            self.sens.step(x_new, S, math.nextafter(t_new, -math.inf)
                           if at_break and t_new in self._break_set else t_new, c)
        self.rec.add(t_new, x_new, S_new)
        self._h_cut = None
        if t_new == self._grid_next:
            self.k += 1
        self._extrapolate = True
        if at_break:
            self._x_prev = None
            self.newton.invalidate()
        else:
            self._x_prev, self._h_prev = x, self._h
        return x_new, S_new, t_new
