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

(Batched variants on clocks of their own run this BDF each, in the compiled
step loop: :mod:`softflow.solve.variants`.)

Chambers and actuators that empty
---------------------------------
A chamber or actuator cannot hold less than no fluid. The loop watches the
stored mass of every library volume (:class:`VolumeWatch`): a solved step
that takes one below zero by more than its slack (:data:`EMPTY_SLACK_ATOL`
times its absolute tolerance: within that it is at zero as far as the run
resolves it) is a step failure. (An actuator whose PV curve's data start at a
volume <= 0, volumes given as changes from a rest volume, defines the volumes
down to that first sample: its limit is there.) A step past the limit may
only be too long (a higher-order step overshooting a state that levels off
at its limit), so the stepper first retries it shortened to end just short
of the crossing (:data:`EMPTY_PAST` of it; the crossing from a secant of the
state between the step's ends, as BDF places a mode switch; up to
:data:`EMPTY_TRIES` times, then by quarters). The state truly reaches its
limit where the step right after such a located one goes past it again (that
step ends :data:`EMPTY_AHEAD` times its distance to the estimated crossing
past its start: a short solve, where the next step of the grid or the
controller failed Newton near the emptied volume; where that step ends short
of the crossing too, or the estimate falls behind the point, the next is
EMPTY_AHEAD times as long as the one just taken, and so on while shorter
than the stepper's own: a volume that empties ever faster), where a step
starts with the state within its slack of the limit, or the smallest step
does: the run stops there with
:class:`softflow.solve.validity.EmptiedError` (Simulation.run: a
SimulationError naming the component and the time of the crossing, status
'failed', the result up to the located step, just short of it). A linear
drain costs two solves more than the steps up to it. A rigid container of
gas empties by its mass (a mass flow source drawing it), which takes its
pressure through zero, which Newton refuses: a solve that failed on an
absolute pressure <= 0 is asked the same, from the states of its refused
solution. Checked after BDF's error test: one comparison over the volumes
per step (~1 us; the paper scenes' steps cost ~150 us each).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..fluids.base import FluidError
from . import sourcenodes
from .dense import DenseOutput, grown_rows
from .linalg import make_linear_solver
from .newton import Outcome, StepLimitError
from .progress import SILENT
from .settings import (
    EMPTY_ATOL_FIXED,
    EMPTY_AHEAD,
    EMPTY_PAST,
    EMPTY_SLACK_ATOL,
    EMPTY_SLACK_SHARE,
    EMPTY_TRIES,
)
from .validity import EmptiedError, curve_first_volume

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


class VolumeWatch:
    """The stored fluid of a network's chambers and actuators, watched at every
    step of the loop (module docstring, "Chambers and actuators that empty").

    Attributes
    ----------
    index : ndarray of int
        The watched states: the stored mass of every library volume
        (Container, LinearAccumulator, Actuator, HystereticActuator and their
        thermal variants).
    limit : ndarray
        Each one's limit [kg]: 0, or, for an actuator whose PV curve's data
        start at a volume v0 <= 0 (the curve defines the volumes down to
        v0), rho(p0) v0 at the density of its fluid at that sample's pressure.
    slack : ndarray
        How far below its limit a state may end a step and still count as at
        it [kg] (:data:`EMPTY_SLACK_ATOL`, :data:`EMPTY_SLACK_SHARE`).
    floor : ndarray
        limit - slack: a step that ends a state below its floor went past it.
    owner : list of (group, member)
        The component of each watched state.
    """

    def __init__(self, index, limit, slack, owner):
        self.index, self.limit, self.slack, self.owner = index, limit, slack, owner
        self.floor = limit - slack

    @classmethod
    def of(cls, asm, S, atol=None):
        """The watch of ``asm``'s volumes at the states S of t = 0 (their
        initial distances from their limits), or None where it has none.
        ``atol``: absolute tolerances per state (the BDF's), else
        :data:`EMPTY_ATOL_FIXED`."""
        from ..components.thermal import VOLUME_CLASSES
        index, limit, owner = [], [], []
        for g in asm.groups:
            c0 = g.comps[0]
            if not g.ns or not isinstance(c0, VOLUME_CLASSES):
                continue
            labels = [v.label for v in c0.states]
            if "mass" not in labels:
                continue
            first = curve_first_volume(c0)        # a group shares its curve
            lim = 0.0
            if first is not None and first[0] <= 0.0:
                lim = first[0] * float(c0.fluid.density(first[1]))
            index.append(g.s0 + np.arange(g.n) * g.ns + labels.index("mass"))
            limit.append(np.full(g.n, lim))
            owner.extend((g, k) for k in range(g.n))
        if not index:
            return None
        index, limit = np.concatenate(index), np.concatenate(limit)
        tol = (np.full(index.size, EMPTY_ATOL_FIXED) if atol is None
               else np.broadcast_to(np.asarray(atol, dtype=float), S.shape)[index])
        share = EMPTY_SLACK_SHARE * np.abs(S[index] - limit)
        slack = EMPTY_SLACK_ATOL * tol
        slack = np.where((share > 0.0) & (share < slack), share, slack)
        return cls(index, limit, slack, owner)

    def past(self, S):
        """Whether a watched state of S is below its floor."""
        return bool(_min(S[self.index] - self.floor) < 0.0)


#: the ufunc method: a reduction without np.min's dispatch
_min = np.minimum.reduce


def _grown(a, k, size):
    """``a`` with room for ``size`` rows, its first k kept."""
    out = np.empty((size,) + a.shape[1:], dtype=a.dtype)
    out[:k] = a[:k]
    return out


class Recorder:
    """Accepted steps, written into preallocated arrays that grow by doubling,
    or to the points expected at the run's pace where the compiled loop says
    so (:meth:`extend`) (no stacking of a list of rows at the end: for large
    networks that copy alone cost as much as the solve)."""

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

    def extend(self, t, X, S, Q=None, expect=None):
        """Rows of points at once (the compiled loop's steps): X and S already
        restricted to the recorded columns, Q to the recorded unknowns'.
        ``expect``: the points the run is expected to record in all (from its
        pace so far: :func:`softflow.solve.dense.grown_rows`; a 4 000-unknown
        run's records are hundreds of MB, and each doubling copies them into
        fresh memory)."""
        k, m = len(self.t), len(t)
        if k + m > len(self._X):
            size = grown_rows(len(self._X), k + m, expect)
            self._X = _grown(self._X, k, size)
            self._S = _grown(self._S, k, size)
            if self._Q is not None:
                self._Q = _grown(self._Q, k, size)
        self._X[k:k + m] = X
        self._S[k:k + m] = S
        if self._Q is not None:
            self._Q[k:k + m] = 0.0 if Q is None else Q
        self.t.extend(t.tolist())

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
        the new point (x, S, t);
    ``_shrink(factor)``, ``_h``, ``step_min``
        the next try at ``factor`` times the step being tried (``_h``), down
        to ``step_min``: the loop's own rejection of a step that emptied a
        volume (:meth:`_emptied`).
    """

    def __init__(self, asm, newton, stats, *, duration, breakpoints=(), record=None,
                 expected_steps=256):
        self.asm, self.newton, self.stats = asm, newton, stats
        self.T = duration
        # (one that falls on the end kept: the last step sees its left limit,
        # as a step that ends on any breakpoint does)
        self.breaks = breaks_inside(breakpoints, duration)
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
    #: jump's, continuation's. Batched variants on their own clocks
    #: (softflow.solve.variants) count each variant's tries alike
    max_steps = None
    #: the run's culprit finder (softflow.solve.culprit.Finder), or None
    culprit = None
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
        watch = self._watch = VolumeWatch.of(asm, S, getattr(self, "atol", None))
        # tries in a row at locating where a volume empties; whether the last
        # step taken was one (it ended just short of the crossing)
        self._empty_tries, self._approached = 0, False
        self._aiming = False         # the last step aimed past a crossing (_aim)
        self._cross_at = math.inf    # a located crossing's time (_emptied)
        # the usual steps in the compiled loop, where the stepper has one
        # (BDF: softflow.solve.steploop); each pass it hands back is the
        # stepper's own in Python
        stretch, handed_back = self._stretch_for(), False
        while t < t_stop:
            if stats.steps + stats.rejected_steps >= max_steps:
                raise StepLimitError(
                    f"more than max_steps = {self.max_steps} steps (accepted and rejected) "
                    f"by t = {t:.6g} s; pass a larger Simulation(max_steps=...) to go on"
                    + ("" if self.culprit is None else self.culprit.step_limit_note(t, x, S)))
            if stretch is not None and not handed_back:
                moved = stretch(t, x, S)
                if moved is not None:
                    handed_back = True
                    if moved[0] > t:
                        t, x, S = moved
                        rescues = 0
                    continue
            handed_back = False
            x_pred, psi, t_new, t_eval, c = propose(t, x, S)
            out = solve(x_pred, psi, t_eval, c)
            if not out.converged and self.culprit is not None:
                # again from the flow sources' nodes balanced (softflow.solve.culprit)
                out = self.culprit.retry(out, x_pred, psi, t_eval, c)
            if not out.converged:
                stats.rejected_steps += 1
                # a rigid volume of gas emptied: its pressure went through zero
                # with its mass (the solve's solution, refused, says how far)
                if (watch is not None and out.reason.startswith("absolute pressure")
                        and self._emptied(t, S, out.x, update(out.x, psi, c), t_new, True)):
                    continue
                # a flow source that no pressure balances at t_new: no smaller
                # step gets past it (softflow.solve.culprit)
                if self.culprit is not None and self.culprit.hopeless(x, S, t_eval, t_new - t,
                                                                      out):
                    raise StepFailure(t_new, t_new - t, out)
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
            if watch is not None and watch.past(S_new):
                stats.rejected_steps += 1
                self._emptied(t, S, x_new, S_new, t_new)
                continue
            if watch is not None:
                self._approached = self._empty_tries > 0
                self._empty_tries = 0
            stats.steps += 1
            stats.residuals_at_last_step = stats.residual_evaluations
            t_was = t
            x, S, t = take(t, x, S, x_new, psi, c, S_new, t_new)
            if self._approached or self._aiming:
                # just short of a located crossing: the next step ends a
                # little past it (EMPTY_AHEAD), where the watch stops the run;
                # where it ended past the crossing's estimate (which lags a
                # volume that empties ever faster), EMPTY_AHEAD times as long
                # as the step just taken, and so on while such steps stay
                # short of it and shorter than the stepper's own (the grid's
                # next step, instead, failed Newton three times at an
                # actuator drawn empty: 58 residual evaluations before the
                # stop)
                ahead = EMPTY_AHEAD * (self._cross_at - t)
                if ahead <= 0.0:
                    ahead = EMPTY_AHEAD * (t - t_was)
                self._aiming = self._aim(max(ahead, self.step_min))
            tick(t)
            if begin is not None:
                begin(x, S)

    def _stretch_for(self):
        """The compiled loop's entry for this run, ``stretch(t, x, S)`` ->
        (t, x, S) after the steps it took, or None where it did not run
        (the stepper's own conditions); or None where the stepper has none."""
        return None

    def finish(self, t, X, S, Q):
        """The recorded points (t, X, S and Q, the integrals or None) as the
        run's result holds them, and the run's
        :class:`~softflow.solve.dense.DenseOutput` on them: (t, X, S, Q,
        dense). Here (backward Euler, and any stepper that states no
        interpolant of its own) the points as they are, and between them the
        straight line from each point to the next: backward Euler's own
        interpolant (its order 1 polynomial). BDF states its own
        (:meth:`softflow.solve.bdf.BDF.finish`)."""
        dense = DenseOutput.linear_between(t, X, S, self._recorded_discrete())
        return t, X, S, Q, dense

    def _recorded_discrete(self):
        """A mask of the recorded states that are discrete (a valve's mode), or
        None."""
        asm = self.asm
        if not asm.has_discrete:
            return None
        si = self.rec.s_index
        return asm.s_discrete if isinstance(si, int) else asm.s_discrete[si]

    def _emptied(self, t, S, x_new, S_new, t_new, refused=False):
        """After a step from t (states S) to t_new that ended with states S_new
        (unknowns x_new): False where no watched volume went past its limit;
        else True, the step rejected and shortened to end just short of the
        crossing (:meth:`_shrink`), or :class:`EmptiedError` where the volume
        truly reaches its limit (module docstring). ``refused``: the states
        of a solution Newton refused for a pressure <= 0, where a volume at
        its limit within its slack has emptied too (its pressure went with it)."""
        w = self._watch
        m0 = S[w.index] - w.limit            # distances from the limits
        m1 = S_new[w.index] - w.limit
        gone = m1 <= 0.0 if refused else m1 < -w.slack
        if not gone.any():
            return False
        # where each state crossed its limit, as a fraction of the step (linear)
        with np.errstate(all="ignore"):
            theta = np.where(gone, np.clip(m0 / (m0 - m1), 0.0, 1.0), np.inf)
        j = int(np.argmin(theta))
        th, h = float(theta[j]), self._h
        # (or where the state starts the step within its slack of its limit:
        # at it already, where an estimate of where it crosses that falls
        # behind the point it starts from gives no step to approach it by:
        # an actuator drawn empty by a pump, whose crossing each estimate
        # placed a little further on, took steps past it that failed Newton,
        # 80 residual evaluations after the point where it stood at its limit)
        if (self._approached or h <= self.step_min * 1.0000001
                or m0[j] <= w.slack[j]):
            raise self._emptied_error(j, t, t + th * h, x_new, S_new)
        self.progress.rejected(t_new, h, "emptied")
        self._cross_at = t + th * h          # (linear: where the next step aims)
        tries = self._empty_tries = self._empty_tries + 1
        factor = th * (1.0 - EMPTY_PAST) if tries <= EMPTY_TRIES else 0.25
        self._shrink(max(factor, self.step_min / h))
        return True

    def _emptied_error(self, j, t, t_cross, x_new, S_new):
        """The EmptiedError of watched state j, which reaches its limit at
        t_cross (the last step taken ends at t; the failed one's unknowns and
        states x_new, S_new)."""
        from ..components.chambers import Container
        w = self._watch
        g, k = w.owner[j]
        comp = g.comps[k]
        mass, lim = float(S_new[w.index[j]]), float(w.limit[j])
        try:          # its volume at the failed step's pressure (terminal a)
            volume = mass / float(comp.fluid.density(float(x_new[g.col[k, 0]])))
        except FluidError:          # a pressure outside the fluid's range
            volume = math.nan
        curve = curve_first_volume(comp)
        if isinstance(comp, Container):         # rigid: only its mass can go
            what, value = "its stored mass", mass
            reached = f"{mass:.4g} kg"
        else:
            what, value = "its fluid volume", volume
            reached = f"{volume:.4g} m^3 (a stored mass of {mass:.4g} kg)"
        limit = ("zero" if lim == 0.0 else
                 f"the first sample of its PV curve's data, {curve[0]:.6g} m^3 (the least "
                 "volume the curve defines)")
        msg = (f"{comp.describe()}: {what} reached {limit} at t = {t_cross:.6g} s (a "
               f"step past it leaves {reached}): a chamber or actuator cannot hold less "
               "than no fluid, so the run stops there (its result ends at t = "
               f"{t:.6g} s). What flows out of it takes more fluid than it holds: check "
               "the sources, pumps and pressures that draw from it"
               + (" (or, for a curve given as volume changes, give its data down to the "
                  "volumes it reaches)" if curve is not None else "") + ".")
        return EmptiedError(msg, component=comp.label, time=t_cross,
                            quantity="mass" if what == "its stored mass" else "volume",
                            value=value)

    def _rescue(self, x_pred, x, psi, t_eval, c, out):
        """The converged Outcome of a step whose Newton solve failed at the
        smallest step, by continuation (:meth:`Newton.continued`) from its
        predictor and, where that fails, from the step's start x (a predictor
        whose residual is not finite); or None. The failed solve stays
        counted as a rejected step. A fixed step's predictor is its start x
        itself: no continuation there (tried from x, on the 2 400 random
        networks of bench_random_networks' draws it completed no more runs
        and made the failing ones 1.3-2x dearer; a well-posed air network
        behind a Tesla valve got 5 ms further, to fail there)."""
        for start in (x_pred, x):
            if start is x and _same(x_pred, x, self.newton.atol):
                break         # the same start again, or a fixed step's (above)
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
        # the consistent start is the run's first accepted point: a failure
        # on its first step counts its work from here
        self.stats.residuals_at_last_step = self.stats.residual_evaluations
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
        refused where no pressure does. Where it still fails, it is solved
        again from a start with each dead end at the pressure of the node it
        hangs from (:func:`softflow.solve.sourcenodes.dead_end_start`: a gas
        restriction choked in front of a dead end started at 1 atm). A start
        that converges from the initial values is taken as it always was."""
        asm, newton = self.asm, self.newton
        lin0 = make_linear_solver(asm, "dense") if newton.lin.kind == "dense" else None
        run_lin = newton.lin
        if lin0 is not None:
            lin0.note_scale = True
            newton.lin = lin0
        try:
            out = self._compiled_start(lin0)
            if out is None:
                out = self._solve_from(asm.x0.copy())
            if not out.converged or sourcenodes.above_cap(asm, out.x):
                # a flow source at a node without volume, whose balance needs a
                # pressure far from the initial one: each such node balanced
                # alone first (softflow.solve.sourcenodes), or the run refused
                # where no pressure up to the cap balances it
                # (refused already where the culprit finder, asked before
                # the continuation, found such a node alone: not searched twice)
                # (and where it found a region of such nodes that no pressure
                # balances: the run stops there, the finder's message its own)
                refusal = (None if self.culprit is None
                           else self.culprit.start_refusal(asm.x0))
                if (refusal is None and self.culprit is not None
                        and self.culprit.start_hopeless(asm.x0)):
                    raise StepFailure(0.0, 0.0, out)
                start = None
                if refusal is None:
                    start, refusal = sourcenodes.balanced_start(
                        asm, asm.x0, asm.S0, newton.atol, self.stats)
                if refusal is not None:
                    raise StepFailure(0.0, 0.0, refusal)
                if start is not None:
                    again = self._solve_from(start)
                    if again.converged and not sourcenodes.above_cap(asm, again.x):
                        out = again
            if not out.converged:
                # a dead end started away from the node it hangs from, behind a
                # gas restriction choked there: its pressure's column is zero
                # (softflow.solve.sourcenodes.dead_end_start); once more from a
                # start with each dead end at the pressure of that node
                start = sourcenodes.dead_end_start(asm, asm.x0)
                if start is not None:
                    # (a failure stays as it was: its message's scale hint too)
                    note = getattr(lin0, "scale_note", None)
                    again = self._solve_from(start)
                    if again.converged and not sourcenodes.above_cap(asm, again.x):
                        out = again
                    elif lin0 is not None:
                        lin0.scale_note = note
        finally:
            newton.lin = run_lin
        if not out.converged:
            raise StepFailure(0.0, 0.0, _with_scale_hint(out, lin0))
        return out.x, lin0

    def _compiled_start(self, lin0):
        """The consistent point solved for from the initial values in one
        compiled call where that serves the run
        (:func:`softflow.solve.steploop.start_solver`), confirmed as
        :meth:`_solve_from` confirms its own (a Jacobian at the point,
        factored on ``lin0``, and one update within the tolerance); the
        Outcome, or None (the Python solve then). The same Newton stages as
        the Python solve's, without its interpreter: the N = 8 chain's start
        ~0.4 -> ~0.1 ms."""
        from .steploop import start_solver
        solve = start_solver(self, lin0)
        if solve is None:
            return None
        asm = self.asm
        x = solve(asm.x0)
        if x is None:
            return None
        # confirmed (or solved again from there) as the Python solve's point
        return self._solve_from(asm.x0, first=Outcome(True, x, 0))

    def _solve_from(self, start, first=None):
        """The Outcome of the consistent point at t = 0 solved for from
        ``start`` (:meth:`_solve_initial`; ``first``: that solve's Outcome
        where it was made already, by :meth:`_compiled_start`)."""
        newton, S0 = self.newton, self.asm.S0
        # each point is confirmed on a Jacobian of its own, else solved
        # again from it: chord iterations on the slopes at the initial
        # values (an orifice's laminar slope at rest, many times its slope
        # at the flow it reaches) stop where their updates are small,
        # which such a slope makes them far from the root
        for tries in range(INITIAL_CONFIRMS + 1):
            if first is not None:
                out, first = first, None
            else:
                out = newton.continued(newton.solve(start, S0, 0.0, 0.0), start, S0, 0.0,
                                       0.0)
            if (not out.converged or tries == INITIAL_CONFIRMS
                    or newton.confirms(out.x, S0, 0.0, 0.0)):
                break
            start = out.x
        return out


def breakpoints_within(comp, duration):
    """The breakpoints [s] of the component ``comp`` for a run of ``duration``:
    a periodic input's every one up to it (``breakpoints_until``: it has
    endless ones), else its ``breakpoints()``."""
    until = getattr(comp, "breakpoints_until", None)
    return until(duration) if until else comp.breakpoints()


def breaks_inside(breakpoints, duration):
    """The breakpoints a run of ``duration`` stops at: those strictly inside
    (0, duration), sorted, each once, then the end itself where one falls on
    it (the last step then reads the sources' left limit there, as a step
    that ends on any breakpoint does: every stepper, fixed or adaptive,
    single or batched)."""
    inside = sorted(b for b in set(breakpoints) if 0.0 < b < duration)
    if any(b == duration for b in breakpoints):
        inside.append(duration)
    return inside


def _same(a, b, atol):
    """Whether two starts of a solve agree within Newton's absolute tolerances
    and 1e-9 relative (a continuation from the second would repeat the first's)."""
    return a is b or bool(np.all(np.abs(a - b) <= atol + 1e-9 * np.abs(b)))


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
        self._point = (x, S)       # the last point taken (softflow.solve.culprit)
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

    def _stretch_for(self):
        """The compiled loop's entry (:mod:`softflow.solve.steploop`), where it
        serves this run: it takes the grid's steps while no cut step is due
        and no emptying volume is being located."""
        from .steploop import fixed_steps
        steps = fixed_steps(self)
        if steps is None:
            return None

        def stretch(t, x, S):
            if self._h_cut is not None or self._empty_tries:
                return None
            _, t, x, S, _ = steps.run(t, x, S)
            return t, x, S
        return stretch

    def _newton_failed(self, t, t_new, out):
        h = self._h
        self.progress.rejected(t_new, h, "newton", out)
        if h / 4 < self.step_min or (self.culprit is not None
                                     and self.culprit.stalled(t, h, out)):
            raise StepFailure(t + h, h, out)
        self._h_cut = h / 4
        self._extrapolate = False

    def _shrink(self, factor):
        """The next try at ``factor`` times the step (a step rejected by the
        loop: a volume emptied within it), from the last point."""
        self._h_cut = self._h * factor
        self._extrapolate = False

    def _aim(self, h):
        """The next step no longer than h (one that ends just past a located
        crossing), from the point just taken; the grid's next step where
        that is shorter. Whether h is shorter than the grid's step."""
        self._h_cut = h
        self._extrapolate = False
        return h < self.h0

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
