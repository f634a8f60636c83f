"""The culprit of a step that cannot be taken, named as soon as it shows.

Newton's failure names the equation it left worst (``line search failed ...;
worst equation: equation 1 of CheckValve 'e2'``): the first law that
complained, often not the cause; and before it does, the stepper cuts the
step down to its smallest and tries a continuation (thousands of residual
evaluations). Where a step's solve fails, this module asks the state the run
stands at (the last accepted point) what no step could get past:

* **An input that sets a pressure outside its fluid's range**
  (:meth:`Finder._inputs_out_of_range`): a pressure source whose value at
  the step's end lies at or below vacuum, or outside a table's range at its
  node (asked after a solve that met a non-finite residual or a pressure
  <= 0; at the consistent start too, where no shorter step can pass it).
* **A flow source that no pressure balances**
  (:func:`softflow.solve.sourcenodes.unbalanced`): a MassFlowSource or
  VolumeFlowSource at a node without volume fixes the flow the node's other
  components must pass; where they cannot pass it at any pressure between 1
  Pa and 1 GPa (a valve that closed, a check valve that shuts that way, a
  tube past its choked capacity, a dead end), the node has no state at all:
  the consistent start refuses such a node at t = 0, and a later step meets
  it when a valve closes or the source's signal grows. The node's balance
  takes in the nodes without volume behind it (junctions), up to the volumes
  and pressure sources that hold theirs; it is asked at the time the failed
  step ends, with those held pressures the last accepted point's and, where
  the node still fails, that point's moved on by its rates to the step's end
  (a volume that fills within the step): both must fail, so that a neighbour
  that would supply the flow by the step's end does not stop a run that can
  go on. A node that balances at the point but not at the stepper's
  prediction for the step's end, where its balance at its limit changes
  sign within EXHAUSTED_WITHIN (1 %) of the step, stops the run at the
  point too: its supply runs out there (a pump drawing through a tube whose
  choked flow falls as the container behind it empties), and the steps
  that converge only crawl towards that time. A region with an inertial
  tube inside (its flow held at dt = 0, free within a step) is not asked.

Either found at a step's first failed solve (:meth:`Finder.hopeless`), the
run stops there: the shorter steps and the continuation that would follow
can only end the same way (a fixed-step run crawled towards the time the
demand exceeded the supply in ever shorter steps: 6 587 residual
evaluations against 77). The message names the source, the node, the
components that limit the flow and what closed (a discrete state's last
change), and the time the result ends.

Besides:

* **A root the run refuses, found again on every shorter step**
  (:meth:`Finder.stalled`): a step's solve that converges on an absolute
  pressure <= 0 at the same unknowns, to the digit, on steps 4, 16 and 64
  times shorter, is the point's failure, not the step's: the stepper stops
  cutting.
* **A step solved again from the node's balance** (:meth:`Finder.retry`):
  after a solve that ended on a pressure <= 0 at a node without volume that
  carries a flow source, the step's solve from the last point with the node
  at the pressure that balances it (:func:`sourcenodes.rebalanced`, what the
  consistent start does at t = 0): a pump whose draw steps up behind a check
  valve at rest, whose closed slope (its leakage) took Newton far below
  vacuum, where the valve opens 200 Pa below the tank's pressure.
* **A time constant far below the step** (:func:`fastest_mode`): where
  nothing else is found, the network's fastest mode at the last accepted
  point, from the Jacobians of the step equations at dt = 0 and dt = 1 s
  (their difference is the states' coupling, ``F_S r_x``; the generalized
  eigenvalues of the pair are the modes' rates), and the components whose
  states move most in it (relative to their values). Named beside the
  failure where its time constant lies below :data:`FAR_BELOW` times the
  smallest step tried (a volume that fills or empties within a small
  fraction of the step: its pressure jumps to its neighbour's within each
  step), and where a run stops at max_steps because its steps follow it (a
  1e-15 m^3 chamber ringing behind an inertial tube at ~4e-9 s).

Only the failure path calls in here (:class:`Finder`, kept by the
integrator: ``Integrator.culprit``, and by Newton before a continuation:
``Newton.before_continuation``): a run whose solves all converge pays
nothing, one with failed solves an analysis of the concerned nodes per
failure (~30 residual evaluations where a node has a flow source: +0.1 to
+2 % of the residual evaluations of the randomized networks that succeed).
"""
from __future__ import annotations

import dataclasses
import re

import numpy as np

from ..fluids.base import FluidError
from . import sourcenodes
from .newton import Outcome
from .settings import (
    EXHAUSTED_RESOLVED,
    EXHAUSTED_WITHIN,
    FAR_BELOW,
    MODE_NAMES,
    MODE_SHARE,
    MODES_MAX_UNKNOWNS,
    STALL_REPEATS,
    STALL_RTOL,
    STEP_FOLLOWS,
)
from .validity import ComponentError

#: the failed solves after which the inputs are asked for a pressure outside
#: the fluid's range (:meth:`Finder._inputs_out_of_range`)
RANGE_REASONS = ("residual not finite", "absolute pressure")
STALL_REASONS = ("absolute pressure",)
#: the failed solves after which a step is solved again from its nodes'
#: balancing pressures (:meth:`Finder.retry`): a root below vacuum, where
#: Newton followed a closed valve's slope past the one the node has
RETRY_REASONS = ("absolute pressure",)
#: ... or a residual not finite where a trial point's pressure was <= 0 (a
#: fluid's message: a watchdog step of the damped stage below vacuum)
RETRY_NOT_FINITE = ("residual not finite", "not a positive absolute pressure")


def _below_vacuum(reason):
    """Whether a failed solve's ``reason`` says it went to an absolute
    pressure <= 0 (:data:`RETRY_REASONS`, :data:`RETRY_NOT_FINITE`)."""
    return reason.startswith(RETRY_REASONS) or (
        reason.startswith(RETRY_NOT_FINITE[0]) and RETRY_NOT_FINITE[1] in reason)


#: Finder._retried where the consistent start was solved again (start_retry)
_START = object()

#: the failed solves after which a network without flow sources is solved
#: again from its junctions balanced (Finder.retry), besides RETRY_REASONS
JUNCTION_REASONS = ("residual not finite along", "line search failed")

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


@dataclasses.dataclass
class Finding:
    """A culprit: the message that names it (the failure's cause), the
    component, and ``kind``: 'unbalanced' (a flow source that no pressure
    balances) or 'fast' (a time constant far below the step)."""

    message: str
    component: str
    kind: str


class Finder:
    """The culprit finder of one run (module docstring), kept by its
    integrator (``integ.culprit``) and asked by Newton before a
    continuation (``newton.hopeless``) and by the run's failure message.

    ``integ``: the integrator, whose last accepted point is
    ``integ._point`` (x, S) at ``integ.rec.t[-1]``; ``newton``: its
    tolerances (``atol``) and counters (``stats``: the analyses' residual
    evaluations are counted with the run's)."""

    def __init__(self, asm, newton, integ):
        self.asm, self.newton, self.integ = asm, newton, integ
        self._cache = None        # (x of the point, t, found, inputs asked)
        self._local_nodes = None  # found once (_locals)
        self._start_nodes = None  # the consistent start's (_locals)
        self._fixed_rows = None   # found once (_fixed)
        self._hit = None          # (x of the point, Finding) hopeless found
        self._start_refused = None  # (x, Unbalanced): a start node alone, unbalanced
        self._stall = None        # (t, reason, refused x, h, repeats) (stalled)
        self._retried = None      # the x of the point retry last tried from
        self._fails = (None, 0)   # (x of the point, failed solves from it) (hopeless)
        self._imposes = None      # whether a component may impose a flow (_may_impose_flow)
        self._junction_nodes = None  # the nodes without volume or flow source (retry)
        self._runs_out = None     # the time a node's supply runs out (unbalanced)
        self._stated = None       # the initial values' stated pressures (_as_stated)

    # -- the last accepted point ----------------------------------------------------
    def point(self):
        """(t, x, S) of the last accepted point, or None before the first."""
        integ = self.integ
        p = getattr(integ, "_point", None)
        if p is None or not integ.rec.t:
            return None
        return integ.rec.t[-1], p[0], p[1]

    # -- the compiled step loop's failed solves (softflow.solve.steploop) ---------------
    def region_rows(self, rows, point=None):
        """The equations :meth:`_concerned` looks into after a failed solve
        (the rows of the regions of the nodes without volume that carry a
        flow source) as 1 in ``rows``, 0 elsewhere; whether those nodes are
        known (found at the run's first failed solve, from the last point
        taken, or here from ``point`` = (x, S, t) where given; not known
        where finding them fails, as :meth:`_concerned` then finds none)."""
        rows[:] = 0
        if self._local_nodes is None:
            if not self._may_impose_flow():
                # (no component imposes a flow: no node lacks a balance,
                # and no region need be found: ~0.1 ms of a small run's
                # first failed solve)
                return True
            if point is None:
                return False
            try:
                self._locals(*point)
            except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError):
                return False
        for loc in self._local_nodes:
            if not loc.dynamic:
                rows[loc.row] = 1
                rows[loc.rows] = 1
        return True

    def failed_at(self, x, n):
        """``n`` failed solves of steps from the point whose unknowns are ``x``
        that the compiled loop rejected itself (their reasons none that
        :meth:`stalled` or :meth:`find` act on), counted as :meth:`hopeless`
        and :meth:`stalled` count the BDF's."""
        self._stall = None
        self._fails = (x, (self._fails[1] if self._fails[0] is x else 0) + n)

    # -- failures that no shorter step changes -----------------------------------------
    def stalled(self, t, h, out):
        """Whether the failed solves of the steps tried from t have failed
        alike STALL_REPEATS times in a row, each on a shorter step: a solution
        refused for an absolute pressure <= 0 (:data:`STALL_REASONS`: Newton
        converged, on a root the run refuses), the same reason (its numbers
        aside) at the same unknown, and within STALL_RTOL the same refused
        unknowns (``out.x``). A root that a step 4^k times shorter lands on to
        the digit is the point's, not the step's: the steppers stop there
        instead of cutting on to their smallest step (13 more failed solves,
        from a fixed step of 2.5 ms to the default smallest of duration x
        1e-9), and the run's failure (after the continuation the smallest
        step gets) comes after a few failed solves. (Other failures, Newton
        diverging from a predictor, leave the refused unknowns near the point
        as the step shrinks, alike for any step: not asked.)"""
        if not out.reason.startswith(STALL_REASONS):
            self._stall = None
            return False
        key = (_NUMBER.sub("#", out.reason), out.row, getattr(out, "unknown", None))
        x = np.asarray(out.x, dtype=float)
        last = self._stall
        if (last is not None and last[0] == t and last[1] == key and h < last[3]
                and x.shape == last[2].shape):
            atol = np.broadcast_to(np.asarray(self.newton.atol, dtype=float), x.shape)
            gap = np.abs(x - last[2]) - STALL_RTOL * (np.abs(x) + np.abs(last[2])) - atol
            if np.isfinite(gap).all() and float(gap.max(initial=-1.0)) <= 0.0:
                self._stall = (t, key, x.copy(), h, last[4] + 1)
                return last[4] + 1 >= STALL_REPEATS
        self._stall = (t, key, x.copy(), h, 1)
        return False

    # -- what no step gets past -------------------------------------------------------
    def find(self, t_new, x=None, S=None, out=None, every=False, ahead=None):
        """The :class:`Finding` that no step from the last accepted point (or
        from the point (x, S) given: the consistent start's) gets past at time
        t_new, or None: a pressure an input sets outside its fluid's range
        (:meth:`_inputs_out_of_range`; asked where the failed solve ``out``
        says a pressure went <= 0 or a residual was not finite, or where no
        solve is given), else a flow source that no pressure balances
        (:meth:`unbalanced`; the nodes whose region holds the failed solve's
        worst equation or unknown, all of them where it names neither or
        where no solve is given). ``ahead``: the failed solve's start (the
        stepper's prediction of the unknowns at t_new), for a supply that
        runs out (:meth:`_running_out`). Cached for one (point, t_new)."""
        if x is None:
            at = self.point()
            if at is None:
                return None
            t, x, S = at
            key = x
        else:
            # (the start's cache and findings are kept under the x given)
            t = t_new
            key, x = x, self._as_stated(x)
        reason = None if out is None else out.reason
        ranged = reason is None or reason.startswith(RANGE_REASONS)
        if not ranged and not self._may_impose_flow():
            # no input's range to ask, and no node that a flow source may
            # leave unbalanced: nothing to find, without the nodes' analysis
            # (~0.5 ms of a chain of 8 tubes' first failed chord stage)
            return None
        # inputs held outside a fluid's range since before the point: asked
        # where no solve is given, or where a fluid's range failed a shorter
        # step from the point too (a first failure may be the step's: a square
        # wave below a table, whose tube works at its mean pressure, went on
        # at a quarter of the step)
        held = reason is None or ("range" in reason and self._fails[1] >= 2
                                  and self._fails[0] is x)
        asked = self._concerned(x, S, t, t_new, None if every else out)
        c = self._cache
        start = t_new == t
        if c is not None and c[0] is key and (c[3] or not ranged) and asked <= c[4] and (
                c[5] or not held or start) and (
                c[1] == t_new or (c[2] is None and t < t_new <= c[1])):
            # the same question, or a shorter step from the same point where
            # the longer one found nothing (inputs and demands are asked at
            # the step's end: a shorter step's are nearer the point's)
            return c[2]
        found = None
        try:
            if t_new > t and ranged:
                found = self._inputs_out_of_range(x, S, t_new, held)
            elif start and ranged:
                # the consistent start's failed solve: an input that sets a
                # pressure outside its fluid's range at t = 0 (no shorter
                # step there to pass it)
                found = self._inputs_out_of_range(x, S, t_new, held=True)
            if found is None and (asked or t_new == t):
                nodes = self.unbalanced(t, t_new, x, S, asked, ahead)
                if nodes:
                    found = self._unbalanced_finding(nodes[0], t_new, self._runs_out)
        except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError):
            found = None
        self._cache = (key, t_new, found, ranged, asked, held)
        return found

    def _as_stated(self, x):
        """The consistent start's point to analyse for ``x``: where ``x`` is
        the initial values, the same with each node's pressure at the value a
        volume or a pressure source states there
        (:meth:`Assembly.stated_unknowns`), not at a tube's or a flow source's
        guess of 1 atm (a pump drawing from a junction behind a check valve
        from a LinearAccumulator at 80 kPa, asked with the accumulator's node
        at 1 atm, balanced; its start was refused after 2 660 residual
        evaluations); else ``x``."""
        asm = self.asm
        if x.shape != asm.x0.shape or not np.array_equal(x, asm.x0):
            return x
        if self._stated is None:
            self._stated = asm.stated_unknowns()
        return self._stated

    def _concerned(self, x, S, t, t_new, out):
        """The indices (into :meth:`_locals`) of the nodes whose regions a
        failed solve ``out`` concerns: its worst equation among their rows, or
        its unknown among their unknowns; all where it names neither, or
        where ``out`` is None."""
        try:
            locals_ = self._locals(x, S, t, start=t_new == t)
        except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError):
            return frozenset()
        every = frozenset(range(len(locals_)))
        if out is None or t_new == t:
            return every          # (the consistent start: balanced_start asks all)
        row, unknown = out.row, getattr(out, "unknown", None)
        if row is None and unknown is None:
            return every
        # a fluid's range left in a flow source's own law (a volume flow
        # source's density at a pressure past a table's end: its node's
        # region, whatever the worst equation)
        named = getattr(self.newton.fluid_error, "components", frozenset())
        return frozenset(k for k, loc in enumerate(locals_)
                         if (row is not None and (row == loc.row or row in loc.rows_set))
                         or (unknown is not None and (unknown == loc.p
                                                      or unknown in loc.cols_set))
                         or (named and any(c.label in named for c in loc.sources)))

    def retry(self, out, x_start, psi, t, c):
        """After a step's failed solve (``out``, from ``x_start``; the step's
        equations at time t with psi and c): the converged Outcome of the
        same equations solved again from the last accepted point with each
        node without volume that carries a flow source at the pressure that
        balances it (:func:`sourcenodes.rebalanced`), else ``out``. Tried
        once per point, after a solve that ended on a root the run refuses
        (:data:`RETRY_REASONS`: an absolute pressure <= 0) or whose line
        search failed on a flow source's region (:data:`JUNCTION_REASONS`,
        its worst equation or unknown there), and not where nothing gets
        there (:meth:`find`). Newton's solve from the step's predictor
        follows the slopes there (a check valve at rest: its leakage) to a
        root below vacuum, where the valve opens 200 Pa below the point's
        pressure; or it finds no decrease along them (a volume flow source
        that jumps from 0.01 to 7.5 mL/s into a junction whose way out is a
        check valve shut without leakage: every shorter step failed alike,
        1 085 residual evaluations before the run stopped; now it goes on)."""
        at = self.point()
        below = _below_vacuum(out.reason)
        # (not after a fluid's range error: a source past a table, which the
        # finder then names, the balance cannot get past)
        junction = (out.reason.startswith(JUNCTION_REASONS)
                    and "outside the" not in out.reason)
        if (at is None or c == 0.0 or self._retried is at[1]
                or not (below or junction)):
            return out
        t0, x, S = at
        self._retried = x
        newton = self.newton
        try:
            locals_ = self._locals(x, S, t0)
            if locals_:
                # (after a line search's failure, where it concerns a flow
                # source's region: its worst equation or unknown there)
                if ((not below and not self._concerned(x, S, t0, t, out))
                        or self.find(t, out=out) is not None):
                    return out
                start = sourcenodes.rebalanced(self.asm, x, S, t, newton.atol, newton.stats,
                                               locals_)
            elif junction:
                start = self._junctions_balanced(x, S, t0, t)
            else:
                return out
        except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError):
            return out
        if start is None:
            return out
        again = self.newton.solve(start, psi, t, c)
        return again if again.converged else out

    def _junctions_balanced(self, x, S, t0, t):
        """A start for a step's solve (to time t, from the point (x, S) at t0)
        in a network without flow sources: the pressure sources' unknowns at
        their values at t, then each node without volume alone at the
        pressure that balances its components' flows there
        (:func:`sourcenodes.rebalanced` on ``local_nodes(...,
        junctions=True)``); None where none moves. For a source's jump
        behind a restriction into a junction whose other way out is a check
        valve at rest: Newton's step along the valve's closed slope (its
        leakage) throws the junction's pressure to -3.9 bar, and every
        shorter step fails alike (a random air network's Tesla valve, 2.7 bar
        after a square wave's jump, in front of a check valve to an actuator
        at 1.04 bar: 1 000-1 300 residual evaluations before the run
        stopped)."""
        asm, newton = self.asm, self.newton
        if self._junction_nodes is None:
            self._junction_nodes = sourcenodes.local_nodes(asm, x, S, t0, junctions=True)
            newton.stats.residual_evaluations += 1
        if not self._junction_nodes:
            return None
        got = self._input_values(x, S, t)
        x_in = x.copy()
        if got is not None:
            _, cols, value = got
            ok = np.isfinite(value)
            x_in[cols[ok]] = value[ok]
        return sourcenodes.rebalanced(asm, x_in, S, t, newton.atol, newton.stats,
                                      self._junction_nodes)

    def before_continuation(self, out, x0, S, t, dt):
        """Newton's hook (``Newton.before_continuation``) where a solve failed
        and a continuation would follow: ``out`` where nothing gets to time t
        (:meth:`hopeless`: the continuation is skipped), a converged Outcome
        from the nodes' balancing pressures (:meth:`retry`, after the start),
        or None (on to the continuation)."""
        if self.hopeless(x0, S, t, dt, out):
            return out
        again = self.retry(out, x0, S, t, dt) if dt > 0.0 else self.start_retry(out, x0, S)
        return again if again.converged else None

    def start_retry(self, out, x0, S):
        """The consistent start's failed solve ``out`` from ``x0``, once per
        run: the converged Outcome of the start solved again with each node
        without volume that carries a flow source, and the nodes without
        volume beyond it, at the pressure that balances them
        (:func:`sourcenodes.rebalanced` on the regions :meth:`hopeless` read
        off, where it found each balanced at some pressure), else ``out``.
        Before the continuation, which does not find such a root where it
        lies beyond the balance's minimum: a volume flow source into a
        junction behind a valve shut on a 2 bar container balances at 2 MPa,
        but from 1 atm its balance falls as the pressure rises (the source's
        flow, rho(p) Q, grows faster than the leak's), and Newton and the
        continuation follow it down to vacuum (4 641 residual evaluations
        before the run was refused)."""
        regions = self._local_nodes
        if self._retried is _START or not regions:
            return out
        self._retried = _START
        newton = self.newton
        try:
            start = sourcenodes.rebalanced(self.asm, x0, S, 0.0, newton.atol, newton.stats,
                                           regions)
        except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError):
            return out
        if start is None:
            return out
        again = newton.solve(start, S, 0.0, 0.0)
        return again if again.converged else out

    def before_full(self, out, x0, S, t, dt):
        """Newton's hook (``Newton.before_full``) where a solve's chord
        iterations diverged or converged on a pressure <= 0 (``out``) and its
        damped stage would follow (a restart's probe, a step near the
        smallest, the consistent start): whether no step gets to time t, as
        :meth:`hopeless` asks, but before that stage, whose line searches
        failing on a flow source that no pressure balances were most of such
        a run's work (a pump behind a shut snapping valve: 112 of the 239
        residual evaluations after its last step; a flow source into an
        inertial tube at rest, refused at the start: 74 of 82). Asked of
        every flow source's region (the chords' worst equation need not lie
        in it). The inputs only where the chords' reason names a fluid's
        range, as after any failed solve: a pressure source set below a
        table's range, whose chords merely converge too slowly, may be passed
        by a shorter step (its tubes evaluate the fluid at their mean
        pressures), and asked at once such runs stopped there (6 random
        water networks). At the consistent start (dt = 0), whose chords fail
        from the initial values in most runs, only where a component may
        impose a flow (:meth:`_may_impose_flow`): the nodes' analysis
        (~0.1 ms at N = 8) is not paid by networks that have none."""
        if dt == 0.0 and not self._may_impose_flow():
            return False
        return self._found(x0, S, t, dt, out, every=True)

    def _may_impose_flow(self):
        """Whether a component of the network may impose a flow at its node
        whatever its pressure (a flow source, a user component: its class's
        ``imposes_flow``, True where the class does not say), found once:
        without one, no node is left unbalanced at the start."""
        got = self._imposes
        if got is None:
            got = self._imposes = any(getattr(g.comps[0], "imposes_flow", True)
                                      for g in self.asm.groups if g.comps)
        return got

    def hopeless(self, x0, S, t, dt, out=None):
        """Newton's hook (via :meth:`before_continuation`) and the integration
        loop's after a step's failed solve ``out``: whether no step gets to
        time t (the step's end: :meth:`find`), from the last accepted point
        (dt > 0) or from (x0, S) (dt = 0: the consistent start, where
        :func:`sourcenodes.balanced_start` then says why)."""
        if dt > 0.0:
            at = self.point()
            point = None if at is None else at[1]
            self._fails = (point, self._fails[1] + 1 if self._fails[0] is point else 1)
        return self._found(x0, S, t, dt, out)

    def _found(self, x0, S, t, dt, out, every=False):
        """:meth:`hopeless`'s answer, the finding kept for :meth:`explain`
        (``every``: all the nodes' regions asked, not only those the failed
        solve names: :meth:`before_full`)."""
        found = (self.find(t, x0, S, out) if dt == 0.0
                 else self.find(t, out=out, every=every, ahead=x0))
        if found is not None:
            self._hit = (self._cache[0], found)
        return found is not None

    def start_hopeless(self, x):
        """Whether this finder found, from the initial values ``x`` (their
        values), that no start gets past a node (or a region of nodes)
        without volume that carries a flow source (:meth:`hopeless` at
        dt = 0): the start's other tries (the nodes balanced alone, the dead
        ends at their neighbours' pressures: ~170 residual evaluations of a
        refused start's ~270) would not change that."""
        hit = self._hit
        return hit is not None and np.array_equal(hit[0], x)

    def start_refusal(self, x):
        """The consistent start's refusal (a failed Outcome, as
        :func:`sourcenodes.balanced_start` gives it) where this finder already
        found, from the initial values ``x`` (their values), a node without
        volume that carries a flow source and that, alone, no pressure
        balances; else None. Asked before the start searches the nodes itself
        (the same search made twice was ~47 residual evaluations of a refused
        start's ~110)."""
        got = self._start_refused
        if got is None or not np.array_equal(got[0], self._as_stated(x)):
            return None
        u = got[1]
        loc = u.local
        # (the worst equation the first source's the message names)
        why, first = sourcenodes.refusal(self.asm, loc, u.kind, u.p, u.edge, u.flows)
        return Outcome(False, x.copy(), 0, why, loc.source_rows[first], unknown=loc.p)

    def unbalanced(self, t, t_new, x, S, asked=None, ahead=None):
        """The :class:`~softflow.solve.sourcenodes.Unbalanced` nodes at time
        t_new from the point (x, S) at t (of :meth:`_locals`, those whose
        indices ``asked`` holds, or all), where both that point and that
        point moved on by its rates to t_new fail to balance them (module
        docstring); [] where none. With ``ahead`` (the start of the failed
        solve: the stepper's prediction at t_new), also those that balance at
        the point but not moved on, where the supply runs out within
        EXHAUSTED_WITHIN of the step (:meth:`_running_out`; the time it does
        in ``_runs_out``)."""
        asm, newton = self.asm, self.newton
        self._runs_out = None
        if t_new == t:
            # the consistent start: its own nodes (each alone), then their
            # regions (two sources drawing from nodes joined by tubes that
            # only the other supplies: each alone balances, together not)
            # (the first found refuses the start: the others are not asked)
            found = sourcenodes.unbalanced(asm, x, S, t, newton.atol, newton.stats,
                                           self._locals(x, S, t, start=True), first=True)
            if found:
                self._start_refused = (x, found[0])
            else:
                self._locals(x, S, t)
                regions = [loc for loc in self._local_nodes if len(loc.inside) > 1]
                if regions:
                    found = sourcenodes.unbalanced(asm, x, S, t, newton.atol, newton.stats,
                                                   regions, first=True)
            return found
        locals_ = self._locals(x, S, t)
        if asked is not None:
            locals_ = [loc for k, loc in enumerate(locals_) if k in asked]
        if not locals_:
            return []
        found = sourcenodes.unbalanced(asm, x, S, t_new, newton.atol, newton.stats, locals_)
        if found and t_new > t:
            # the neighbours as the step would move them: the states at t_new
            # by the rates at the point (forward Euler); each node's balance
            # there at the state's pressure and at the limit found (solved
            # from the point's solution there), both on the unbalanced side
            S_on = np.asarray(asm.update_states(x, S, t_new - t), dtype=float)
            atol, stats = newton.atol, newton.stats
            kept = []
            for u in found:
                loc = u.local
                g0 = sourcenodes.balance_at(asm, loc, x, S_on, t_new, float(x[loc.p]), atol,
                                            stats)
                g1 = (None if g0 is None else sourcenodes.balance_at(
                    asm, loc, x, S_on, t_new, u.p, atol, stats, start=u.at))
                if g1 is not None and ((g0 < 0.0 and g1 < 0.0) if u.kind == "above"
                                       else (g0 > 0.0 and g1 > 0.0)):
                    kept.append(u)
            found = kept
        elif ahead is not None and t_new > t:
            found = self._running_out(t, t_new, x, S, locals_, ahead)
        return found

    def _running_out(self, t, t_new, x, S, locals_, ahead):
        """The nodes of ``locals_``, balanced at the point (x, S) at t, that
        the point moved on to t_new leaves unbalanced (its states by their
        rates, the unknowns outside the nodes' regions as the stepper
        predicts them: ``ahead``, the pressures of the volumes that supply
        them), where their balance at the limit it reaches
        (:func:`sourcenodes.balance_at` there, at both states) changes sign
        within EXHAUSTED_WITHIN of the step, taken as linear in time: the
        supply runs out at the point
        (a pump drawing through a tube choked from a container that
        empties: each step short enough to converge ends nearer the time
        the draw exceeds the tube's sonic flow, and no step passes it). The
        time it runs out in ``_runs_out``."""
        asm, newton = self.asm, self.newton
        atol, stats = newton.atol, newton.stats
        S_on = np.asarray(asm.update_states(x, S, t_new - t), dtype=float)
        found = []
        for u in sourcenodes.unbalanced(asm, ahead, S_on, t_new, atol, stats, locals_):
            g_on = u.g
            g_at = sourcenodes.balance_at(asm, u.local, x, S, t_new, u.p, atol, stats,
                                          start=u.at)
            if g_on is None or g_at is None or (g_at < 0.0) == (g_on < 0.0):
                continue
            share = g_at / (g_at - g_on)
            # (a balance at the limit within Newton's tolerance of the
            # sources' flows: the point stands where the supply runs out,
            # whatever the step: the BDF at rtol 1e-5 followed a pump's node
            # there in steps of 1e-10 s, its balance at 1 Pa -6e-15 kg/s at
            # the point against atol 1e-14, and failed ~900 residual
            # evaluations later)
            cols = [c for k in range(len(u.local.sources)) for c in u.local.members[k][1]]
            if cols and abs(g_at) <= float(np.max(atol[cols])):
                share = 0.0
            if (share <= EXHAUSTED_WITHIN
                    or share * (t_new - t) <= EXHAUSTED_RESOLVED * t):
                found.append(u)
                self._runs_out = t + share * (t_new - t)
        return found

    def _locals(self, x, S, t, start=False):
        """The network's nodes without volume that carry a flow source
        (:func:`sourcenodes.local_nodes`, each with the nodes without volume
        beyond it), found once, at the first failure, from the last accepted
        point (a network without any costs one residual evaluation). After
        the start (t > 0), a region with an inertial tube inside, whose flow
        is held at dt = 0 but changes within any step, is no bound on a step:
        left out. At the ``start`` (the consistent start's solve from the
        initial values), the nodes of :func:`sourcenodes.balanced_start`,
        each alone (its flows through inertial tubes the initial ones), which
        it refuses once Newton has failed."""
        if start:
            # the consistent start's own nodes (balanced_start's: each node
            # alone, its neighbours held), which it refuses after the hook
            if self._start_nodes is None:
                self._start_nodes = sourcenodes.local_nodes(self.asm, x, S, t)
                self.newton.stats.residual_evaluations += 1
            return self._start_nodes
        if self._local_nodes is None:
            self._local_nodes = sourcenodes.local_nodes(self.asm, x, S, t, region=True)
            self.newton.stats.residual_evaluations += 1
        return [loc for loc in self._local_nodes if not loc.dynamic]

    # -- inputs that set a pressure outside the fluid's range ---------------------------
    def _fixed(self, x, S, t):
        """[(row, column)]: the equations that set one across unknown alone (a
        pressure source's: their only nonzero slope is that unknown's), read
        off the Jacobian at (x, S) once (at the consistent start where the
        point is at a fluid's edge)."""
        if self._fixed_rows is None:
            asm = self.asm
            self.newton.stats.residual_evaluations += 1
            try:
                F = asm.residual(x, S, t, 0.0, jac=True)
            except FluidError:
                start = getattr(self.integ, "consistent", None)
                if start is None:
                    return []
                F = asm.residual(start[0], asm.S0, 0.0, 0.0, jac=True)
            if not np.isfinite(F).all():
                return []
            J = asm.jacobian_csc().tocsr()
            J.eliminate_zeros()
            na, nr = asm.n_across, asm.n_node_rows
            counts = np.diff(J.indptr)
            rows = np.flatnonzero(counts == 1)
            rows = rows[rows >= nr]
            cols = J.indices[J.indptr[rows]]
            keep = cols < na
            self._fixed_rows = list(zip(rows[keep].tolist(), cols[keep].tolist()))
        return self._fixed_rows

    def _input_values(self, x, S, t_new):
        """(rows, columns, values): the equations that set one across unknown
        alone (:meth:`_fixed`: a pressure source's), their unknowns, and the
        values they set at t_new, the other unknowns as at the point (x, S)
        (one residual evaluation; the point's own values where the point is
        at a fluid's edge); None where there are none."""
        fixed = self._fixed(x, S, t_new)
        if not fixed:
            return None
        asm = self.asm
        rows = np.array([r for r, _ in fixed])
        cols = np.array([c for _, c in fixed])
        self.newton.stats.residual_evaluations += 1
        try:
            F = asm.residual(x, S, t_new, 0.0, jac=True)
        except FluidError:
            # the point itself at a fluid's edge (a tube's mean pressure): the
            # inputs' values as the point has them, asked where held
            value = x[cols].astype(float)
        else:
            J = asm.jacobian_csc().tocsr()
            slope = np.asarray(J[rows, cols]).ravel()
            with np.errstate(all="ignore"):
                value = x[cols] - F[rows] / slope
        return rows, cols, value

    def _inputs_out_of_range(self, x, S, t_new, held=False):
        """A :class:`Finding` where an equation that sets an across unknown
        alone (:meth:`_fixed`: a pressure source) sets it at t_new to an
        absolute pressure <= 0 or where a component's fluid cannot be
        evaluated (a table's range), the other unknowns as at the point:
        no state there. Else None. The inputs whose values changed since the
        point, and with ``held`` (a failure on a fluid's range) those that
        did not too: a source held below a table's range since t = 0, which
        ran while the tube it feeds worked at a mean pressure inside it, until
        the tube's other end fell."""
        got = self._input_values(x, S, t_new)
        if got is None:
            return None
        asm = self.asm
        rows, cols, value = got
        moved = np.isfinite(value) & ((value != x[cols]) | held)
        if not moved.any():
            return None
        names = asm.x_names
        q = np.asarray(asm.x_quantity, dtype=object)[cols]
        for i in np.flatnonzero(moved & (q == "pressure") & (value <= 0.0)):
            comp, _ = asm.component_of_row(int(rows[i]))
            g, k = asm.group_of_row(int(rows[i]))
            return Finding(
                f"{g.comps[k].describe()} sets {names[int(cols[i])]} to {value[i]:.4g} Pa "
                f"absolute at t = {t_new:.6g} s: no fluid state there (vacuum is an absolute "
                "pressure of 0; a gauge source's value is added to 1 atm); keep its "
                "signal above vacuum", comp, "input")
        def refused(i, err, where=""):
            g, k = asm.group_of_row(int(rows[i]))
            src = g.comps[k]
            unit = " Pa" if q[i] == "pressure" else " K" if q[i] == "temperature" else ""
            return Finding(
                f"{src.describe()} sets {names[int(cols[i])]} to {value[i]:.6g}{unit} at t = "
                f"{t_new:.6g} s{where}, where a fluid cannot be evaluated: {err}; no state "
                "there: keep the input within the fluid's range, or use a level that covers "
                "it (Fluid(..., level='eos'), or a table's out_of_range='eos')",
                src.label, "input")

        # the fluids of the components at each node an input sets a pressure of
        p_of = asm.node_across.get("pressure")
        node_of = {} if p_of is None else {int(c): j for j, c in enumerate(p_of) if c >= 0}
        for i in np.flatnonzero(moved & (q == "pressure")):
            j = node_of.get(int(cols[i]))
            if j is None:
                continue
            fluids = {id(f): f for f in (getattr(term.component, "fluid", None)
                                         for term in asm.nodes[j].terminals)
                      if f is not None}
            for fluid in fluids.values():
                try:
                    fluid.density(float(value[i]))
                except FluidError as err:
                    return refused(int(i), err)
        # the components there at those pressures, the others as at the point
        x2 = x.copy()
        x2[cols[moved]] = value[moved]
        self.newton.stats.residual_evaluations += 1
        try:
            asm.residual(x2, S, t_new, 0.0)
        except FluidError as err:
            # the input whose value changed at the node the fluid refused
            i = int(np.flatnonzero(moved)[0])
            return refused(i, err, "" if len(np.flatnonzero(moved)) == 1
                           else " (with the other sources set)")
        return None

    # -- the message ---------------------------------------------------------------------
    def explain(self, fail):
        """The :class:`Finding` of a failed step (``fail``: the
        :class:`~softflow.solve.integrator.StepFailure`), or None: what no
        step gets past at the failed step's end (:meth:`find`), else a time
        constant far below the smallest step tried."""
        if fail.t == 0.0:
            # the consistent start says its own where its nodes alone are
            # refused; a region found at the start (hopeless) is said here
            hit = self._hit
            if hit is None or fail.outcome.reason.startswith("no consistent start"):
                return None
            return hit[1]
        at = self.point()
        if self._hit is not None and at is not None and self._hit[0] is at[1]:
            return self._hit[1]   # what stopped the step (hopeless)
        found = self.find(fail.t)
        if found is not None:
            return found
        if at is None or fail.dt <= 0.0:
            return None
        t, x, S = at
        try:
            mode = fastest_mode(self.asm, x, S, t)
        except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError,
                ValueError):
            return None
        if mode is None or not mode[0] < FAR_BELOW * fail.dt:
            return None
        tau, named = mode
        return Finding(
            f"the network's fastest mode at t = {t:.6g} s has a time constant of {tau:.3g} "
            f"s, far below the smallest step tried ({fail.dt:.3g} s); it moves "
            f"{_listed(named)}: within each step they jump to where their neighbours hold "
            "them, and the step's solve does not get there (a volume that small or a "
            "coupling that fast: make it larger, or leave it out)",
            named[0][0].label, "fast")

    def step_limit_note(self, t, x, S):
        """'; ...' naming the component whose time constant the steps follow
        where a run stops at max_steps (its fastest mode at the point (x, S)
        at t, where that lies within STEP_FOLLOWS times the last step: the
        mode the error test resolves), or ''."""
        h = float(getattr(self.integ, "_h", 0.0) or 0.0)
        try:
            mode = fastest_mode(self.asm, x, S, t)
        except (FluidError, ComponentError, ArithmeticError, np.linalg.LinAlgError,
                ValueError):
            return ""
        if mode is None or h <= 0.0 or not mode[0] < STEP_FOLLOWS * h:
            return ""
        tau, named = mode
        return (f"; the steps (the last {h:.3g} s) follow the network's fastest mode, a time "
                f"constant of {tau:.3g} s at t = {t:.6g} s, which moves {_listed(named)}: a "
                "volume that small or a coupling that fast makes every step that short "
                "(make it larger, or leave it out)")

    def _unbalanced_finding(self, u, t, runs_out=None):
        asm, loc = self.asm, u.local
        draw = u.kind == "below"
        names, several, picked = sourcenodes.source_names(loc, u.flows, draw)
        # (the node of the first source named: the region's others behind it)
        at = loc.source_nodes[picked[0]]
        node = asm.nodes[at].name
        behind = [asm.nodes[j].name for j in (loc.inside or ()) if j != at]
        if behind:
            more = f" and {len(behind) - 3} more" if len(behind) > 3 else ""
            verb = "is" if len(behind) == 1 else "are"
            node += (f", a node without volume (as {verb} {', '.join(behind[:3])}{more} "
                     "behind it)")
        else:
            node += ", a node without volume"
        n_src = len(loc.sources)
        # a source the other way is among what passes the flow
        others = [(loc.members[i], u.flows[i]) for i in range(n_src)
                  if i not in picked and u.flows[i] != 0.0]
        others += list(zip(loc.members[n_src:], u.flows[n_src:]))
        rate = sum(u.flows[i] for i in picked)
        rate_text = f"{abs(rate):.4g} kg/s"
        at_p = f"{u.p:.4g} Pa"
        where = "" if u.edge is None else f", where the fluid's range ends ({u.edge})"
        parts = []
        for (comp, _), flow in others:
            passed = -flow if draw else flow     # into the node / out of it
            parts.append(f"{comp.describe()} {passed:.4g} kg/s{self._switched(comp)}")
        total = sum((-f if draw else f) for _, f in others)
        if draw:
            verb = "draw" if several else "draws"
            head = (f"{names} {verb} {rate_text} from {node}, at t = "
                    f"{t:.6g} s: more than the components there supply at any pressure down "
                    f"to {at_p}{where} (they supply {total:.4g} kg/s there")
            tail = "inlets that supply the flow"
        else:
            verb = "push" if several else "pushes"
            head = (f"{names} {verb} {rate_text} into {node}, at t = "
                    f"{t:.6g} s: more than the components there pass at any pressure up to "
                    f"{at_p}{where} (they pass {total:.4g} kg/s there")
            tail = "outlets that pass the flow"
        # (balanced at the last point: what supplies the node runs out)
        ran_out = ("" if runs_out is None else
                   f"; they {'supply' if draw else 'pass'} it until t = {runs_out:.6g} s, as "
                   "the states behind them change")
        msg = (head + (": " + ", ".join(parts) if parts else "") + ")" + ran_out
               + "; the node has no state from there on (closed, at rest, dead ends, or a "
               f"gas's flow at its sonic limit): give the node a volume (a Container), or {tail}")
        return Finding(msg, loc.sources[picked[0]].label, "unbalanced")

    def _switched(self, comp):
        """' (closed: its state 'open' went 1 -> 0 at t = ...)' for a component
        whose discrete state changed in the recorded points (the last change),
        or ''."""
        asm = self.asm
        if not asm.has_discrete or comp.label not in asm.where:
            return ""
        g, k = asm.where[comp.label]
        if not g.ns:
            return ""
        integ = self.integ
        times, _, S_rec = integ.rec.arrays()
        s_index = integ.rec.s_index
        notes = []
        for j, var in enumerate(g.comps[k].states):
            i = g.s0 + k * g.ns + j
            if not asm.s_discrete[i]:
                continue
            if isinstance(s_index, (int, np.integer)):
                col = i
            else:
                hit = np.flatnonzero(np.asarray(s_index) == i)
                if not hit.size:
                    continue
                col = int(hit[0])
            values = S_rec[:, col]
            changed = np.flatnonzero(values[1:] != values[:-1])
            if changed.size:
                m = int(changed[-1])
                notes.append(f"its state '{var.label}' went {values[m]:g} -> "
                             f"{values[m + 1]:g} at t = {times[m + 1]:.6g} s")
            elif values.size:
                notes.append(f"its state '{var.label}' = {values[-1]:g} throughout")
        return f" ({'; '.join(notes)})" if notes else ""


def _listed(named):
    return ", ".join(f"{c.describe()} (its {label})" for c, label in named)


def fastest_mode(asm, x, S, t):
    """The fastest mode of the network at the point (x, S) at time t: (its
    time constant [s], [(component, state label)] of the components whose
    states move most in it relative to their values, most first), or None (no states, a network over
    :data:`MODES_MAX_UNKNOWNS` unknowns, a singular Jacobian).

    The step equations F(x; psi, c) evaluate the states at psi + c r(x); with
    psi = S - c r(x) they hold the states at S, and their Jacobian is
    J(c) = F_x + c F_S r_x. The modes' rates lam solve
    (J(1) - J(0)) v = -lam J(0) v (the linearized DAE: F_x dx + F_S dS = 0,
    dS' = r_x dx); each mode's states move by r_x v."""
    n = asm.n
    ns = S.size
    if not ns or n > MODES_MAX_UNKNOWNS:
        return None
    asm.residual(x, S, t, 0.0, jac=True)
    J0 = asm.jacobian_csc().toarray()
    r = np.asarray(asm.update_states(x, S, 1.0), dtype=float) - S
    if asm.has_discrete:
        r[asm.s_discrete] = 0.0
    c = 1.0
    asm.residual(x, S - c * r, t, c, jac=True)
    D = asm.jacobian_csc().toarray() - J0
    if not (np.isfinite(J0).all() and np.isfinite(D).all()):
        return None
    K = -np.linalg.solve(J0, D) / c
    lam, V = np.linalg.eig(K)
    mag = np.abs(lam)
    if not mag.size or not np.isfinite(mag).all() or mag.max() <= 0.0:
        return None
    j = int(np.argmax(mag))
    v = V[:, j]
    # the states' motion in the mode: r_x v (r affine in x), real and imaginary parts
    base = np.asarray(asm.update_states(x, S, 1.0), dtype=float)
    scale = 1e-6 * max(float(np.max(np.abs(x))), 1e-300) / max(float(np.max(np.abs(v))), 1e-300)
    w = np.zeros(ns)
    for part in (v.real, v.imag):
        if np.any(part):
            w += np.abs(np.asarray(asm.update_states(x + scale * part, S, 1.0),
                                   dtype=float) - base)
    if asm.has_discrete:
        w[asm.s_discrete] = 0.0
    # relative to the states' values (a floor of 1e-9 of the largest of the
    # same quantity, for a state at zero)
    q = np.asarray(asm.s_quantity, dtype=object)
    size = np.abs(S)
    floor = np.zeros(ns)
    for name in set(q.tolist()):
        m = q == name
        floor[m] = 1e-9 * float(size[m].max(initial=0.0))
    rel = w / (size + floor + 1e-300)
    if not np.any(rel > 0.0):
        return None
    # the components whose states move most, each once, down to MODE_SHARE
    # of the most (a tube's flow and the volume it fills: both)
    named = []
    for i in np.argsort(-rel):
        if rel[i] < MODE_SHARE * rel.max() or len(named) == MODE_NAMES:
            break
        for g in asm.groups:
            if g.ns and g.s0 <= i < g.s1:
                k, jj = divmod(int(i) - g.s0, g.ns)
                comp = g.comps[k]
                if all(c is not comp for c, _ in named):
                    named.append((comp, comp.states[jj].label))
                break
    if not named:
        return None
    return 1.0 / float(mag[j]), named
