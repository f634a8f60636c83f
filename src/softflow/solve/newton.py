"""Newton–Raphson for one implicit-Euler step, with Jacobian/LU reuse.

Three stages, each tried only if the cheaper one before it fails:

1. *reuse*: chord iterations with the LU factors of an earlier Jacobian (modified
   Newton, as SUNDIALS IDA does), while the step size stays within a factor of
   the one it was built for. How many chord iterations are worth trying before
   refactoring depends on what a factorization costs relative to an
   iteration: measured on chain networks of 1e3-1e5 unknowns, a SuperLU
   factorization costs 20-35 triangular solves; among limits 4, 6 and 10, 6
   was fastest there, so sparse systems allow 6;
   a small dense LU costs about one iteration, so dense systems allow 4 (the
   limit is fixed, not timed, so that runs are reproducible);
2. *fresh*: a new Jacobian at the predictor, then chord iterations;
3. *full*: a new Jacobian every iteration, with backtracking on the scaled
   residual norm (damped Newton), from where a contracting but too slow chord
   stage stopped, else from the predictor;
4. *flows first* (thermal scenes, where the others failed): the pressures and
   flows solved with the node temperatures held, then all unknowns from
   there, by damped Newton on equilibrated dense systems
   (:meth:`Newton._flows_first`: a pump that starts to draw gas from a node
   at rest, a flow source that reverses).

Convergence is judged on the scaled update max_i |dx_i| / tol_i with
tol_i = atol_i + rtol · max(|x_i|, max |x_j| over unknowns j of the same
quantity): each variable is held to a relative accuracy of the typical
magnitude of its quantity in the network, so a nearly stagnant tube does not
demand absurd absolute accuracy from its flow. The test is corrected by the
observed contraction rate (Hairer & Wanner, Solving ODEs II, sec. IV.8),
damped as CVODE damps it (:data:`CRDOWN`: at least 0.3 times the rate taken
at the iteration before on the same factors, 1 on fresh ones), so that the
rate of the first two updates alone, which holds the predictor's jump, does
not stand for the slower mode left after it.
An update-based test trusts the Jacobian's slopes: one read from another
piece of a piecewise law (a check valve's steep opening band, where the
valve has shut) makes the updates small far from the root. Where a class
states its pieces (``regime``, :mod:`softflow.components.base`), a chord
result on another piece than its factors' Jacobian is not accepted: the
reuse stage's goes to the fresh stage, and a fresh stage that converged on
another piece than its predictor's goes once more from its point
(:meth:`Newton._off_piece`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..constants import pressure_atmospheric
from .._laws import law_module
from ..fluids.base import FluidError
from .linalg import DOT_MAX, SingularJacobian, all_finite  # noqa: F401 (DOT_MAX: re-exported)
from .settings import (
    CONTINUATION_FIRST,
    CONTINUATION_MIN,
    CONTINUATION_RTOL,
    CONTINUATION_SOLVES,
    CRDOWN,
    FLIP_MATCH,
    FULL_KEEP_CUT,
    LINE_SEARCH_DEEP,
    LINE_SEARCH_GROSS,
    LINE_SEARCH_MIN,
    RANGE_AIMS,
    SMALL,
    TIGHT_KEEP_CUT,
    TIGHT_RTOL,
    WATCHDOG,
)


def gauge_offsets(quantities, offset=pressure_atmospheric):
    """Per unknown, what its magnitude is counted from: ``offset`` (the
    atmosphere) for a pressure, 0 for any other quantity. Newton's scale
    (:meth:`Newton.set_gauge`), BDF's error weights and the batched engine's
    take a pressure's magnitude as its gauge |p - offset|."""
    return np.where(np.asarray(quantities, dtype=object) == "pressure", float(offset), 0.0)


@dataclass
class Stats:
    """Solver counters."""

    steps: int = 0
    rejected_steps: int = 0
    newton_iterations: int = 0
    residual_evaluations: int = 0
    jacobian_evaluations: int = 0
    factorizations: int = 0
    newton_failures: int = 0
    error_test_failures: int = 0
    #: residual_evaluations when the last point was accepted (the
    #: consistent start's, then each step's; 0 where the start failed): a
    #: failed run's work after it is the difference
    residuals_at_last_step: int = 0

    def as_dict(self):
        return dict(self.__dict__)


# the ufunc methods: 0.65 us against 0.8 us for ndarray.max/min on small arrays
_max = np.maximum.reduce
_min = np.minimum.reduce


class StepLimitError(RuntimeError):
    """A run went past ``Simulation(max_steps=...)`` steps, accepted and
    rejected (:meth:`softflow.solve.integrator.Integrator.run` counts them)."""


@dataclass
class Outcome:
    converged: bool
    x: np.ndarray
    iterations: int = 0
    reason: str = ""
    row: int | None = None
    #: a chord iteration that contracted, too slowly: x is closer than its start
    contracting: bool = False
    #: the unknown at fault where no equation is (a node's pressure), or None
    unknown: int | None = None


def _network_setup(asm):
    """What Newton derives from the compiled network alone (kept on the Assembly:
    every run of a Simulation builds a new Newton)."""
    bounds = np.append(asm.q_starts, asm.n).tolist()
    q_bounds = list(zip(bounds[:-1], bounds[1:]))
    q_sorted = bool(np.array_equal(asm.q_order, np.arange(asm.n)))
    # absolute node pressures must stay positive: a solution with p <= 0 is
    # rejected (user locals of quantity 'pressure', e.g. a difference, are not)
    nodal = list(enumerate(asm.x_quantity[:asm.n_across]))
    p_idx = np.array([i for i, q in nodal if q == "pressure"], dtype=np.int64)
    # isothermal scenes: the node pressures are x[:n], read as a view
    contiguous = p_idx.size and np.array_equal(
        p_idx, np.arange(p_idx[0], p_idx[0] + p_idx.size))
    p_sel = (slice(int(p_idx[0]), int(p_idx[-1]) + 1) if contiguous else p_idx)
    # thermal scenes: a node through which (almost) nothing flows has a weakly
    # determined temperature, and a Newton update from a zero-flow start can move
    # it by orders of magnitude; each node temperature update is clipped to
    # [-50 %, +100 %] of its value, the other unknowns are left as they are.
    # Convergence is judged on the unclipped update.
    T_idx = np.array([i for i, q in nodal if q == "temperature"], dtype=np.int64)
    # the node rows that conserve energy (the equations that set node temperatures)
    E_rows = np.array([r for r, q in enumerate(getattr(asm, "node_row_quantities", ()))
                       if q == "energyflow"], dtype=np.int64)
    return q_bounds, q_sorted, p_idx, p_sel, T_idx, E_rows


class Newton:
    """Solves F(x; S, t, dt) = 0 for x, reusing LU factors across iterations and steps."""

    def __init__(self, asm, lin, stats, *, atol, rtol=1e-6, max_reuse_iter=None,
                 max_iter=10, max_age=200, dt_ratio=(0.6, 1.67)):
        self.asm = asm
        self.lin = lin
        self.stats = stats
        self.rtol = rtol
        self.atol = np.asarray(atol, dtype=float)
        self._q_names, self._links = asm.q_names, []
        self._q_order, self._q_starts, self._qid = asm.q_order, asm.q_starts, asm.q_id
        # what depends on the compiled network only, derived once per Assembly
        setup = asm.__dict__.get("_newton_setup")
        if setup is None:
            setup = asm._newton_setup = _network_setup(asm)
        (self._q_bounds, self._q_sorted, self._p_idx, self._p_sel, self._T_idx,
         self._E_rows) = setup
        # small systems: per-quantity maxima on Python lists (see SMALL)
        self._small = 0 < asm.n <= SMALL
        # atol as one value per quantity, if it is that (the small-system path needs it)
        if self._small:
            key = (self.atol.shape, self.atol.tobytes())
            known = asm.__dict__.get("_newton_q_atol")
            if known is not None and known[0] == key:
                q_atol = known[1]
            else:
                atol_n = np.broadcast_to(self.atol, (asm.n,))
                per_q = [atol_n[self._q_order[a:b]] for a, b in self._q_bounds]
                q_atol = ([float(v[0]) for v in per_q] if all((v == v[0]).all() for v in per_q)
                          else None)
                asm._newton_q_atol = (key, q_atol)
            if q_atol is not None:
                self._q_atol = list(q_atol)
            else:
                self._small = False
        self._itol = 1.0 / self.atol
        self._qtol = list(getattr(self, "_q_atol", ()))
        self._has_p = bool(self._p_idx.size)
        # the written-out step (_quick) serves small systems, and other dense ones
        # while their solves take one iteration: a step that needs a second one
        # pays the NumPy tolerance scale and norm twice (chain N = 8, 34 unknowns,
        # 2.5 iterations a step: 4 % slower with it always on, measured)
        self._quick_ok = lin.kind == "dense"
        self._one_iteration = True    # the last solve converged in one iteration
        self._p_list = self._p_idx.size <= SMALL
        self.fluid_error = None   # the last fluid-range error of the current stage
        if max_reuse_iter is None:
            max_reuse_iter = 4 if lin.kind == "dense" else 6
        self.max_reuse_iter = max_reuse_iter
        self.max_iter = max_iter
        self.max_age = max_age
        self.dt_ratio = dt_ratio
        self.lu_dt = None      # step size the current factors were built for
        self._dt_lo = self._dt_hi = -1.0
        self.age = 0           # steps since the last factorization
        self.stale = True      # force a fresh Jacobian at the next solve
        self.eta = 1.0         # rate/(1 - rate) seen in earlier solves, for the first test
        self._crate = 1.0      # the damped rate of the current factors (CRDOWN)
        # piecewise laws (a check valve's pieces, Assembly.regimes): the point of
        # the last Jacobian evaluation, and the pieces (their bytes: compared
        # at every accepted point) of the current factors' Jacobian
        self._regimes = asm.regimes if asm.has_regimes else None
        self._jac_x = None
        self._jac_regime = None
        self._T_range = None    # (lo, hi) [K]: the iterates' temperatures stay inside
        #: per quantity (q_names order), magnitudes the tolerances are at least
        #: relative to (BDF: the largest of the run so far; a list on small
        #: systems), or None: x0's alone (:meth:`_set_scale`)
        self.scale_floor = None
        #: the largest first update (in tolerances) the predicted contraction
        #: alone may accept (:meth:`_first_done`); adaptive runs: rtol over
        #: Newton's rtol, so that where the prediction fails (a chord Jacobian
        #: from before a kink of a PV curve) the error left is within the
        #: error test's tolerance
        self.first_max = math.inf
        #: (quantity index of 'pressure', offset) and the offsets per unknown,
        #: or None: magnitudes of absolute values (:meth:`set_gauge`)
        self._gauge = self._x_gauge = None

    #: whether a solve whose chord iterations fail on fresh factors goes on to
    #: the damped full stage (:meth:`_full`) and, in thermal scenes, the
    #: flows-first stage (:meth:`_flows_first`); BDF turns it off on steps it
    #: would rather cut (:data:`softflow.solve.bdf.FULL_STAGE_STEPS`)
    full_stage = True
    #: where ``full_stage`` is off: whether chord iterations on fresh factors
    #: that contracted too slowly go on as undamped full Newton (a Jacobian
    #: at each iterate, its factors kept after a step that cut the residual
    #: tenfold as in the damped stage; at most ``max_iter`` iterations), which
    #: fails at the first full step that would need the line search
    #: (:meth:`_full` with ``undamped``). A law whose slope changes
    #: by orders of magnitude between the predictor and the solution (a
    #: turbulent tube, dp ~ mdot^2, whose flow dies out) holds the chord to
    #: its predictor's slope, and it contracts at ~0.5 an iteration where
    #: Newton itself converges; a fold (an actuator's snap) needs damping and
    #: fails at once. BDF turns it on (:data:`softflow.solve.bdf.UNDAMPED_FULL`)
    undamped_full = False

    def invalidate(self):
        """Ask for a fresh Jacobian (after a discontinuity, for instance)."""
        self.stale = True

    #: None, or a callable (out, x0, S, t, dt) -> Outcome or None, asked where a
    #: continuation would follow the failed solve ``out``: an Outcome to return
    #: instead (no solution to continue to, or one found from another start),
    #: or None (softflow.solve.culprit.Finder.before_continuation)
    before_continuation = None

    #: None, or a callable (out, x0, S, t, dt) -> bool, asked before the damped
    #: stage of a solve whose chord iterations failed or converged on an
    #: absolute pressure <= 0 (``out``): True where no step gets to t (a flow
    #: source at a node without volume asking what no pressure there gives,
    #: a source setting a pressure outside its fluid's range), and the solve
    #: fails with ``out`` at once (softflow.solve.culprit.Finder.before_full)
    before_full = None

    #: None, or a constant subtracted from every residual this Newton evaluates
    #: (:meth:`continuation`): it solves F(x) = offset, with F's Jacobian
    offset = None

    def continuation(self, x0, S, t, dt):
        """Solve F(x) = 0 by continuation where :meth:`solve` from x0 fails:
        Newton's homotopy F(x) = (1 - lam) F(x0), lam from 0 (x0 solves it) to
        1, each solve starting from the one before; lam's step doubles after a
        solve that converges (from CONTINUATION_FIRST) and halves after one
        that fails, down to CONTINUATION_MIN; at most CONTINUATION_SOLVES
        solves, each held to CONTINUATION_RTOL at most; the last is of F
        itself. For a point that Newton's steps overshoot from afar (a check
        valve whose cracking pressure a source exceeds or falls below: its
        flow changes over a narrow opening band, and the steps from x0 land
        far past it). Used where a run would otherwise stop (:meth:`continued`).
        Returns the converged Outcome, or None where the continuation fails
        too."""
        F0 = self._eval(x0, S, t, dt, False)
        if not all_finite(F0):
            return None
        x, lam, step = x0, 0.0, CONTINUATION_FIRST
        rtol = self.rtol
        self.rtol = min(rtol, CONTINUATION_RTOL)
        # (its solves are not steps: Simulation(max_steps=) counts the steps
        # of the integration loop; CONTINUATION_SOLVES bounds these)
        try:
            for _ in range(CONTINUATION_SOLVES):
                target = min(1.0, lam + step)
                self.offset = None if target == 1.0 else (1.0 - target) * F0
                out = self.solve(x, S, t, dt)
                if out.converged:
                    if target == 1.0:
                        return out
                    x, lam, step = out.x, target, 2.0 * step
                else:
                    step *= 0.5
                    if step < CONTINUATION_MIN:
                        return None
            return None
        finally:
            self.offset = None
            self.rtol = rtol

    def continued(self, out, x0, S, t, dt):
        """After the solve from x0 that gave ``out``: ``out`` where it
        converged, or failed on an absolute pressure <= 0 (a solution that
        continuation would reach again); else :meth:`continuation`'s Outcome
        where it converges, else ``out``. Where a run would otherwise stop:
        the consistent start, the first probes of a BDF restart, a step that
        fails at the smallest step."""
        if out.converged:
            return out
        if self.before_continuation is not None:
            # no state there to continue to, or one from a better start
            # (softflow.solve.culprit.Finder.before_continuation)
            done = self.before_continuation(out, x0, S, t, dt)
            if done is not None:
                return done
        if out.reason.startswith("absolute pressure"):
            return out
        return self.continuation(x0, S, t, dt) or out

    def _eval(self, x, S, t, dt, jac):
        self.stats.residual_evaluations += 1
        if jac:
            self.stats.jacobian_evaluations += 1
            self._jac_x = x       # (never written in place: iterates are new arrays)
        try:
            F = self.asm.residual(x, S, t, dt, jac)
            return F if self.offset is None else F - self.offset
        except FluidError as err:
            # an iterate outside a fluid's valid range (e.g. a table's) is a failed
            # trial point, like a non-finite residual: damp or cut the step
            self.fluid_error = err
            return np.full(self.asm.n, np.nan)

    def _nonfinite_row(self, F):
        """The first non-finite equation; none after a fluid-range error, which
        makes the whole residual NaN and is named in the message instead."""
        return None if self.fluid_error is not None else int(np.argmax(~np.isfinite(F)))

    def _not_finite(self, reason):
        err = self.fluid_error
        return f"{reason} ({err})" if err is not None else reason

    def _factor(self, dt):
        self.lin.factor()
        self.stats.factorizations += 1
        if self._regimes is not None:
            self._jac_regime = self._regimes(self._jac_x).tobytes()
        self.lu_dt = dt
        self._crate = 1.0
        # the step sizes these factors serve (see _reusable; 0 serves only 0)
        self._dt_lo, self._dt_hi = self.dt_ratio[0] * dt, self.dt_ratio[1] * dt
        self.age = 0
        self.stale = False

    def _off_piece(self, x):
        """Whether a piecewise law is at x on another piece than the one the
        current factors' Jacobian was evaluated on (``regime`` of its class,
        :mod:`softflow.components.base`): a slope read from the wrong piece
        (an opening check valve's steep one where the valve has closed)
        makes the chord's updates small far from the root, and the
        update-based convergence test is fooled. False without such laws."""
        return (self._regimes is not None and self._jac_regime is not None
                and self._regimes(x).tobytes() != self._jac_regime)

    def set_temperature_range(self, lo, hi):
        """Keep the iterates' node temperatures within [lo, hi] K (the range the
        scene's fluids cover, e.g. a property table's): a Newton update that
        would leave it is cut at its edge instead of making a trial point where
        the fluid cannot be evaluated. A scene that starts a sonic discharge
        sends the first iterates' temperatures far out (a 180:1 valve: 290 ->
        590 -> 780 K) before they come back."""
        bounded = (lo > 0 or hi < math.inf) and lo < hi    # fluids that share no range: none
        self._T_range = (float(lo), float(hi)) if bounded else None

    def set_magnitude_link(self, quantity, base, factor):
        """Let the magnitude of ``quantity`` be at least ``factor`` times that of
        ``base`` when tolerances are set. Thermal scenes count energy flows from a
        reference enthalpy, so they are small numbers; their natural size is the
        mass flow times cp·T, and without the link Newton would resolve them far
        more finely than the mass flows that carry them."""
        names = self._q_names
        if quantity in names and base in names:
            self._links.append((names.index(quantity), names.index(base), float(factor)))

    @property
    def tol(self):
        """Per-unknown Newton tolerances of the current solve."""
        if self._small:
            return np.array(self._qtol)[self._qid]
        return 1.0 / self._itol

    def _set_scale(self, x):
        """Tolerances for this solve (see module docstring): on small systems
        one per quantity, as a list; else per unknown, kept as reciprocals."""
        if self._small:
            v = (x if self._q_sorted else x[self._q_order]).tolist()
            rtol, qtol = self.rtol, []
            for at, m in zip(self._q_atol, self._small_qmax(v)):
                qtol.append(at + rtol * m)
            self._qtol = qtol
        elif x.size:
            qmax = self.asm.quantity_max(x if self._x_gauge is None else x - self._x_gauge)
            if self.scale_floor is not None:
                qmax = np.maximum(qmax, self.scale_floor)
            for q, base, factor in self._links:
                qmax[q] = max(qmax[q], factor * qmax[base])
            # max(|x_i|, the largest |x_j| of its quantity) is that largest one
            self._itol = 1.0 / (self.atol + self.rtol * qmax[self._qid])
        else:
            self._itol = 1.0 / self.atol

    def _small_qmax(self, v):
        """Per quantity, the magnitude the tolerances of a small system are
        relative to, from the unknowns' values ``v`` (a list, in quantity
        order): the largest |v| of the quantity (of the gauge pressure, where
        :meth:`set_gauge` was called), at least ``scale_floor``, and at least
        the linked quantities' (:meth:`set_magnitude_link`)."""
        qmax = [max(map(abs, v[a:b])) for a, b in self._q_bounds]
        gauge = self._gauge
        if gauge is not None:
            q, off = gauge
            a, b = self._q_bounds[q]
            seg = v[a:b]
            qmax[q] = max(max(seg) - off, off - min(seg))
        floor = self.scale_floor
        if floor is not None:
            qmax = [max(a, b) for a, b in zip(qmax, floor)]
        for q, base, factor in self._links:
            qmax[q] = max(qmax[q], factor * qmax[base])
        return qmax

    def set_gauge(self, offset=None):
        """Take the magnitude of the quantity 'pressure' as |p - offset| (the
        gauge pressure, with ``offset`` the atmosphere), as the adaptive error
        test weighs it, instead of |p|: at a tolerance that follows rtol (an
        adaptive run's rtol / 20), an air network's 0.1 bar swing on 1 bar
        would otherwise be resolved to a tenth of that. ``offset``: default
        the atmosphere (:func:`gauge_offsets`)."""
        names = self._q_names
        if "pressure" not in names:
            return
        q = names.index("pressure")
        offset = pressure_atmospheric if offset is None else float(offset)
        self._gauge = (q, offset)
        self._x_gauge = gauge_offsets(self.asm.x_quantity, offset)

    def _raise_scale(self, x):
        """Raise this solve's tolerances (never lower them) to what
        :meth:`_set_scale` gives at x."""
        if self._small:
            old = self._qtol
            self._set_scale(x)
            self._qtol = [max(a, b) for a, b in zip(old, self._qtol)]
        elif x.size:
            old = self._itol
            self._set_scale(x)
            self._itol = np.minimum(old, self._itol)

    def _norm(self, dx):
        """max_i |dx_i| / tol_i (NaN if dx holds a NaN)"""
        if self._small:
            v = (dx if self._q_sorted else dx[self._q_order]).tolist()
            s = sum(v)
            if s != s:          # the builtins max/min skip a NaN where NumPy propagates it
                return math.nan
            nrm = 0.0
            for (a, b), tq in zip(self._q_bounds, self._qtol):
                m = max(map(abs, v[a:b])) / tq
                if m > nrm:
                    nrm = m
            return nrm
        return float(_max(np.abs(dx) * self._itol)) if dx.size else 0.0

    def _first_done(self, nrm):
        """Whether a solve's first update, of norm ``nrm`` (in tolerances),
        converges it: within the tolerance, or where the contraction seen in
        earlier solves predicts the error left after it to be (Hairer &
        Wanner), for an update of at most ``first_max`` tolerances."""
        return nrm <= 1.0 or (nrm <= self.first_max
                              and nrm * max(self.eta, 1e-3) ** 0.8 <= 1.0)

    def _positive(self, x):
        """All absolute node pressures of x > 0."""
        p = x[self._p_sel]
        if self._p_list:
            v = p.tolist()
            s = sum(v)          # the builtin min skips a NaN that is not first; the sum does not
            return s == s and min(v) > 0.0
        return _min(p) > 0.0

    def confirms(self, x, S, t, dt, lin=None):
        """Whether ``x`` already solves F(x; S, t, dt) = 0 to this Newton's
        tolerance (a consistent point remembered from an earlier run, say): the
        Newton update at x passes the convergence test of an iteration,
        max_i |dx_i| / tol_i <= 1 with the tolerances of x (no contraction
        estimate: there is no iterate before it), and the absolute pressures of
        x are positive. The update is on a Jacobian evaluated and factored at
        x, or with ``lin``, on that linear solver's factors (those of the solve
        that made x, left as they were): the test of a chord iteration on
        earlier factors, which the 'reuse' stage makes at every step. x itself
        is the answer, not x minus the update: a point that passes is as good
        as the solve that made it, and taking it unchanged keeps a run that
        does so the same as the one that made it. One residual evaluation and
        one iteration (and without ``lin`` a Jacobian and a factorization),
        counted as such; a point that does not pass (or a non-finite residual,
        a singular Jacobian, a fluid's range left) leaves this Newton's factors
        stale."""
        self.fluid_error = None
        F = self._eval(x, S, t, dt, jac=lin is None)
        ok = False
        if all_finite(F):
            try:
                if lin is None:
                    self._factor(dt)
                    lin = self.lin
            except SingularJacobian:
                pass
            else:
                self._set_scale(x)
                self.stats.newton_iterations += 1
                ok = self._norm(lin.solve(F)) <= 1.0 and (not self._has_p
                                                          or self._positive(x))
        if not ok:
            self.stale = True
        return ok

    def _reusable(self, dt):
        """The current factors serve a step dt: within dt_ratio of the step they
        were built for (exactly 0 for the dt = 0 solve at t = 0)."""
        return (not self.stale and self.lu_dt is not None and self.age < self.max_age
                and self._dt_lo <= dt <= self._dt_hi)

    def solve(self, x0, S, t, dt):
        """The step equations F(x; S, t, dt) = 0 from the predictor x0 by the
        stages of the module docstring (a small dense system's usual step in
        one frame, :meth:`_quick`): the converged Outcome, or the last
        stage's failed one (its reason and worst equation)."""
        F0 = first = None
        # the usual step of a dense system: a step size and factors the last ones serve
        if (self._quick_ok and not self.stale and self._dt_lo <= dt <= self._dt_hi
                and self.age < self.max_age and (self._small or self._one_iteration)
                and self.max_reuse_iter >= 1):
            self.fluid_error = None
            out = self._quick(x0, S, t, dt)
            if type(out) is Outcome:
                return out
            F0, first = out
        self._F_at_x0 = None      # set by a fresh stage that factored at x0
        last = None
        if self._reusable(dt):
            if F0 is None:
                self.fluid_error = None
            if first is None:     # (else _quick set the tolerances for x0)
                self._set_scale(x0)
            out = self._chord(x0, S, t, dt, "reuse", F0, first)
            if out.converged and self._regimes is not None and self._off_piece(out.x):
                out = Outcome(False, out.x, out.iterations, "a piecewise law changed "
                              "pieces since the Jacobian was evaluated")
            if out.converged and out.iterations >= self.max_reuse_iter:
                self.stale = True  # convergence slowing: refresh at the next step
            last = self._accept(out)
            if last is None:
                return out
        else:
            self._set_scale(x0)
        hopeless = False     # the culprit finder said no step gets there (before_full)
        if last is None or not last.reason.startswith(("singular", "absolute pressure")):
            for stage in ("fresh", "full"):
                self.fluid_error = None       # each stage reports its own fluid-range error
                undamped = stage == "full" and not self.full_stage
                if undamped and not (self.undamped_full and last is not None
                                     and last.contracting):
                    break
                if stage == "fresh":
                    out = self._chord(x0, S, t, dt, stage)
                    if (out.converged and self._regimes is not None
                            and self._off_piece(out.x)):
                        # converged on the slope of another piece (a valve that
                        # closes within the step, its Jacobian evaluated open):
                        # once more from there, on its own piece's Jacobian
                        out = self._chord(out.x, S, t, dt, stage)
                        self._F_at_x0 = None        # (those factors are not x0's)
                elif (not undamped and self.before_full is not None and last is not None
                      and self.before_full(last, x0, S, t, dt)):
                    hopeless = True   # no step gets there: the damped stages would only fail
                    break
                elif last is not None and last.contracting:
                    # a contracting chord iteration got closer than x0: go on from
                    # there (thermal chain N = 1000, second step: 14 -> 10 iterations)
                    self._F_at_x0 = None
                    out = self._full(last.x, S, t, dt, undamped)
                else:
                    out = self._full(x0, S, t, dt)
                last = self._accept(out)
                if last is None:
                    return out
                if last.reason.startswith(("singular", "absolute pressure")):
                    break
        if (self.full_stage and self._has_p and last is not None
                and last.reason.startswith("absolute pressure")
                and not (self.before_full is not None
                         and self.before_full(last, x0, S, t, dt))):
            # converged on an absolute pressure <= 0: where that is the mirror
            # root of a gas law in p^2 (p1^2 - p2^2 = 0 at p2 = -p1: a node
            # without volume between a tube and an orifice, started adiabatic),
            # the damped stage held to positive pressures finds the physical
            # one; where none is, the failure stays as it was
            out = self._full(x0, S, t, dt, positive=True)
            if out.converged and self._accept(out) is None:
                return out
        if (self.full_stage and self._E_rows.size == self._T_idx.size > 0 and not hopeless
                and not last.reason.startswith("absolute pressure")):
            out = self._flows_first(x0, S, t, dt)
            if out is not None and out.converged and self._accept(out) is None:
                return out
        self.stats.newton_failures += 1
        self.stale = True
        return last

    def _quick(self, x0, S, t, dt):
        """The usual step of a dense system, in one frame: one chord iteration on
        the current factors that passes the convergence test (the steps of
        :meth:`_set_scale`, :meth:`_chord`, :meth:`_norm` and :meth:`_accept`,
        same arithmetic); small systems take the tolerance scale and the update
        norm in one pass over Python lists. Returns the converged Outcome, or
        (F, first) for :meth:`_chord` to go on from: the residual at x0 and,
        once the tolerances for x0 are set, the first update and its norm
        (else None). The residual is not tested for finiteness first: a NaN
        or inf in it makes the update non-finite (its sum, or its dot
        product), and :meth:`_chord` then reports it."""
        self.stats.residual_evaluations += 1
        try:
            F = self.asm.residual(x0, S, t, dt, False)
        except FluidError as err:     # as in _eval
            self.fluid_error = err
            return np.full(self.asm.n, np.nan), None
        if self.offset is not None:
            F = F - self.offset
        step = self.lin.solve(F)
        if not self._small:
            if not all_finite(step):
                return F, None
            self._set_scale(x0)
            nrm = self._norm(step)
            if not self._first_done(nrm):
                self._one_iteration = False
                return F, (step, nrm)
            return self._quick_accept(x0, step) or (F, (step, nrm))
        if self._q_sorted:
            v, w = x0.tolist(), step.tolist()
        else:
            v, w = x0[self._q_order].tolist(), step[self._q_order].tolist()
        total = sum(w)
        if total - total != 0.0:      # NaN or inf
            return F, None
        rtol, nrm, qtol = self.rtol, 0.0, []
        if self._links or self._gauge is not None or self.scale_floor is not None:
            for (a, b), at, m in zip(self._q_bounds, self._q_atol, self._small_qmax(v)):
                tq = at + rtol * m
                qtol.append(tq)
                m = max(map(abs, w[a:b])) / tq
                if m > nrm:
                    nrm = m
        else:
            for (a, b), at in zip(self._q_bounds, self._q_atol):
                tq = at + rtol * max(map(abs, v[a:b]))
                qtol.append(tq)
                m = max(map(abs, w[a:b])) / tq
                if m > nrm:
                    nrm = m
        self._qtol = qtol
        if not self._first_done(nrm):
            return F, (step, nrm)
        return self._quick_accept(x0, step) or (F, (step, nrm))

    def _quick_accept(self, x0, step):
        """The end of :meth:`_quick` for an update that passed the test: the
        converged Outcome, or None if an absolute pressure would be <= 0."""
        if self._T_idx.size:
            step = -self._clip_temperature(x0, -step)
        x = x0 - step
        if self._has_p and not self._positive(x):
            return None
        if self._regimes is not None and self._off_piece(x):
            self.stale = True     # to the fresh stage (Newton.solve)
            return None
        self.stats.newton_iterations += 1
        self.age += 1
        if self.max_reuse_iter <= 1:
            self.stale = True
        return Outcome(True, x, 1)

    def _accept(self, out):
        """None for a converged solve with positive absolute pressures (counted
        as one more step on the current factors), else the failed outcome."""
        if not out.converged:
            return out
        self._one_iteration = out.iterations == 1
        if self._p_idx.size and not self._positive(out.x):
            p = out.x[self._p_sel]
            i = int(self._p_idx[np.argmin(p)])
            return Outcome(False, out.x, out.iterations,
                           f"absolute pressure {p.min():.4g} Pa <= 0 at "
                           f"{self.asm.x_names[i]} (cavitation and vacuum are not "
                           "modelled; check sources and volumes)", unknown=i)
        self.age += 1
        return None

    def _chord(self, x0, S, t, dt, stage, F=None, first=None):
        """Chord iterations from x0 (``F``: the residual there, if evaluated;
        ``first``: the first update and its norm, if computed, with the
        tolerances already set for x0)."""
        fresh = stage == "fresh"
        x = x0          # never written in place: each update makes a new array
        if F is None:
            F = self._eval(x, S, t, dt, jac=fresh)
        if not all_finite(F):
            return Outcome(False, x, 0, self._not_finite("residual not finite at the predictor"),
                           self._nonfinite_row(F))
        if fresh:
            try:
                self._factor(dt)
            except SingularJacobian as err:
                return self._singular(x, 0, err)
            self._F_at_x0 = F
        limit = self.max_iter if fresh else self.max_reuse_iter
        prev = prev_step = None
        flipped = False
        solve, norm, stats, clip = self.lin.solve, self._norm, self.stats, self._T_idx.size
        for k in range(limit):
            # minus the Newton update, used as it comes (x - step is bitwise
            # x + (-step)): one negation fewer per iteration
            if first is None:
                step = solve(F)
                nrm = norm(step)
            else:
                (step, nrm), first = first, None
            stats.newton_iterations += 1
            if clip:
                step = -self._clip_temperature(x, -step)
            if not math.isfinite(nrm):
                return Outcome(False, x, k + 1, "Newton update not finite")
            if prev is not None and nrm >= 0.9 * prev and not flipped and (
                    nrm * 0.9 <= prev and norm(step + prev_step) <= FLIP_MATCH * nrm):
                # flipping about a root where the law's slope is not the
                # Jacobian's (settings.FLIP_MATCH): half of the update
                flipped = True
                step = 0.5 * step
                done = False
            elif prev is not None:
                rate = nrm / prev
                if rate >= 0.9:
                    return Outcome(False, x, k + 1, f"Newton diverging (rate {rate:.2f})",
                                   self._worst_row(F))
                self.eta = rate / (1.0 - rate)
                crate = self._crate = max(rate, CRDOWN * self._crate)
                done = nrm * crate <= 1.0 - crate
                # Hairer & Wanner's early exit: at this rate the remaining
                # iterations cannot reach the tolerance
                if not done and nrm * rate ** (limit - 1 - k) / (1.0 - rate) > 1.0:
                    return Outcome(False, x, k + 1, f"Newton converging too slowly (rate {rate:.2f})",
                                   self._worst_row(F), contracting=True)
            else:
                # Hairer & Wanner: the contraction seen before predicts the error
                # left after this first update
                done = self._first_done(nrm)
            if done:
                return Outcome(True, x - step, k + 1)
            # damp only to keep the residual finite (e.g. negative pressure in a gas)
            lam = 1.0
            for _ in range(6):
                xn = x - step if lam == 1.0 else x - lam * step
                Fn = self._eval(xn, S, t, dt, jac=False)
                if all_finite(Fn):
                    break
                lam *= 0.25
            else:
                return Outcome(False, x, k + 1,
                              self._not_finite("residual not finite along the Newton step"),
                               self._nonfinite_row(Fn))
            x, F = xn, Fn
            prev, prev_step = nrm, step
        return Outcome(False, x, limit, f"no convergence in {limit} iterations ({stage} Jacobian)",
                       self._worst_row(F))

    def _full(self, x0, S, t, dt, undamped=False, positive=False):
        """Damped Newton. The factors are kept for the next iteration only when the
        last full step cut the scaled residual by 1/FULL_KEEP_CUT (1/TIGHT_KEEP_CUT
        in a solve held to TIGHT_RTOL) or more (Shamanskii's
        variant): far from the solution every iteration refactors, close to it
        the factorizations are saved.

        Where the line search finds no decrease (at a fold: an air-filled
        actuator whose PV curve falls more steeply than its gas can expand jumps
        to a far branch at constant mass, and the residual has a hump between),
        a watchdog takes up to ``WATCHDOG`` undamped Newton steps and keeps them
        if the residual ends below where it started; otherwise the solve fails.

        After a failed fresh stage, the factors it made at x0 are this stage's
        first ones: the same Jacobian, one evaluation and factorization fewer
        (each start-up step of a thermal chain N = 1000 enters this stage).

        With ``undamped`` (:attr:`undamped_full`: a longer BDF step, after
        chord iterations that contracted too slowly) it takes full steps
        only: at most ``max_iter`` iterations, and it fails at the first full
        step that neither lowers the residual nor contracts (where the line
        search would begin).

        With ``positive`` a trial point with an absolute pressure <= 0 counts
        as one without descent (the line search halves the step; no watchdog
        step goes there): after a solve that converged on such a point, the
        mirror root of a gas law in p^2 (:meth:`solve`)."""
        x = x0.copy()
        F = self._F_at_x0
        factored = F is not None
        keep_cut = TIGHT_KEEP_CUT if self.rtol <= TIGHT_RTOL else FULL_KEEP_CUT
        if not factored:
            F = self._eval(x, S, t, dt, jac=True)
            if not all_finite(F):
                return Outcome(False, x, 0, self._not_finite("residual not finite"),
                               self._nonfinite_row(F))
        refactor = True
        watch, f_ref, x_ref, F_ref, used = 0, np.inf, x, F, False
        limit = self.max_iter if undamped else self.max_iter * 2
        edge, aims = None, 0       # the fluid's edge the full steps aim past, how often
        for k in range(limit):
            if refactor:
                try:
                    if not factored:
                        self._factor(dt)
                    factored = False
                except SingularJacobian as err:
                    return self._singular(x, k, err)
                rs = self.lin.row_scale
            f0 = float(np.linalg.norm(F * rs))
            if watch and f0 < (1 - 1e-4) * f_ref:
                watch = 0                       # below the starting residual: monotone again
            dx = -self.lin.solve(F)
            self.stats.newton_iterations += 1
            nrm = self._norm(dx)
            if nrm > 1.0 and k:
                # the tolerances were set from x0's magnitudes; where the
                # iterates have grown past them (flows starting from rest at
                # a jump of a source) they are raised to the iterate's, else
                # round-off of the solve alone (1e-15 kg/s on a 0.07 kg/s
                # flow) never meets a tolerance of atol = 1e-15 kg/s
                self._raise_scale(x)
                nrm = self._norm(dx)
            if nrm <= 1.0:
                return Outcome(True, x + dx, k + 1)
            if self._T_idx.size:
                dx = self._clip_temperature(x, dx)
            lam, lam_min, trial = 1.0, LINE_SEARCH_MIN, (0.0, 0.0)
            while not watch:
                xn = x + lam * dx
                if positive and not self._positive(xn):
                    lam *= 0.5
                    if lam < lam_min:
                        break
                    continue
                # the full step is usually taken: evaluate its Jacobian with it
                if lam == 1.0:
                    before, self.fluid_error = self.fluid_error, None
                    Fn = self._eval(xn, S, t, dt, jac=True)
                    hit, self.fluid_error = self.fluid_error, self.fluid_error or before
                    # the full steps aiming past one edge of a fluid's range,
                    # RANGE_AIMS iterations in a row: the root lies past it
                    at = (None if hit is None or hit.limit is None
                          else (hit.quantity, hit.limit))
                    aims = aims + 1 if at is not None and at == edge else int(at is not None)
                    edge = at
                    if aims >= RANGE_AIMS and not undamped:
                        return Outcome(False, x, k + 1, self._not_finite(
                            "residual not finite along the Newton step"), None)
                else:
                    Fn = self._eval(xn, S, t, dt, jac=False)
                f1 = np.linalg.norm(Fn * rs) if all_finite(Fn) else np.inf
                if f1 <= (1 - 1e-4 * lam) * f0 or not refactor:
                    break          # descent, or stale factors: refactor at x first (below)
                if lam == 1.0 and f1 < np.inf and self._contracts(Fn, dx):
                    break
                if undamped:        # the full step neither descends nor contracts
                    return Outcome(False, x, k + 1, "full Newton would need damping",
                                   self._worst_row(F))
                # halved, or from the growth of a gross overshoot at the
                # consistent start (settings.LINE_SEARCH_GROSS; the compiled
                # loop's rule)
                nxt, lam_min = law_module("stepper").backtrack(
                    lam, float(f0), float(f1), trial[0], trial[1], lam_min,
                    LINE_SEARCH_GROSS if dt == 0.0 else math.inf, LINE_SEARCH_DEEP)
                trial, lam = (lam, float(f1)), nxt
                if lam < lam_min:
                    break
            if watch or lam < lam_min:
                if watch == 1 or (not watch and used) or positive:
                    return Outcome(False, x_ref if watch else x, k + 1, "line search failed: no "
                                   "decrease of the residual along the Newton direction",
                                   self._worst_row(F_ref if watch else F))
                if not watch:
                    used = True
                    # judged below with each iterate's own row scaling: measured more
                    # robust at folds than keeping the starting one
                    watch, f_ref, x_ref, F_ref = WATCHDOG + 1, f0, x, F
                watch -= 1
                x = x + dx
                F = self._eval(x, S, t, dt, jac=True)
                if not all_finite(F):
                    return Outcome(False, x_ref, k + 1, self._not_finite(
                        "residual not finite along the Newton step"), self._worst_row(F_ref))
                refactor = True
                continue
            if not refactor and not f1 <= (1 - 1e-4) * f0:
                refactor = True   # retry this iterate with a Jacobian evaluated at x
                self._eval(x, S, t, dt, jac=True)
                continue
            refactor = lam < 1.0 or f1 > keep_cut * f0
            x, F = xn, Fn
            if refactor and lam < 1.0:
                self._eval(x, S, t, dt, jac=True)   # Jacobian at the damped iterate
        return Outcome(False, x, limit, "no convergence with full Newton",
                       self._worst_row(F))

    def _flows_first(self, x0, S, t, dt):
        """The last stage of a thermal solve: the pressures and flows first,
        with the node temperatures held, then all unknowns; None where it
        does not apply (a system too large for dense solves). From a point
        at rest, the node temperatures are set by the zero-flow conductance
        alone (ZERO_FLOW_CONDUCTANCE, 1e-6 W/K) and the upwind blend's mean
        enthalpy: a pump that starts to draw gas out of a node at rest makes
        the first Newton update move that node's temperature by thousands of
        kelvin, and each later one doubles it (Fig. 3's architecture filled
        with air, adiabatic: at the pump's reversal). With the temperatures
        held, the pressures and flows converge (they depend on temperature
        only through densities); with the flows out of the blend's band, the
        upwind enthalpies make the temperatures well determined.

        Both parts solve dense systems with every row and column scaled to a
        largest entry of 1 (equilibrated): at such a point a gas volume's
        dm/dp (~1e-10 kg/Pa) and a tube's dp/dmf (~1e6 Pa s/kg) stand alone
        in their rows, and the factors' pivots of the unscaled matrix, which
        the other stages judge singular below 1e-14 of the largest, span more
        than that."""
        asm, n = self.asm, self.asm.n
        if n > 256:
            return None
        held = (np.setdiff1d(np.arange(n), self._E_rows),
                np.setdiff1d(np.arange(n), self._T_idx))
        x = x0.copy()
        first, held_for = True, 0          # first: the temperatures held
        for k in range(3 * self.max_iter):
            if first and held_for == self.max_iter:
                first = False
            held_for += 1
            self.fluid_error = None
            F = self._eval(x, S, t, dt, jac=True)
            if not all_finite(F):
                return None
            J = asm.dense_jacobian()
            rows, cols = held if first else (slice(None), slice(None))
            A = J[np.ix_(rows, cols)] if first else J
            r = 1.0 / np.maximum(np.abs(A).max(axis=1), 1e-300)
            c = 1.0 / np.maximum(np.abs(A * r[:, None]).max(axis=0), 1e-300)
            try:
                step = c * np.linalg.solve(A * r[:, None] * c, F[rows] * r)
            except np.linalg.LinAlgError:
                return None
            self.stats.newton_iterations += 1
            self.stats.factorizations += 1
            dx = np.zeros(n)
            dx[cols] = -step
            if not all_finite(dx):
                return None
            if not first:
                # tolerances from the iterate: flows that were at rest at the
                # start (the scale of a solve's first point) are not now
                self._set_scale(x)
                if self._norm(dx) <= 1.0:
                    return Outcome(True, x + dx, k + 1)
            if self._T_idx.size:
                dx = self._clip_temperature(x, dx)
            # backtracking on the scaled residual (temperatures held: only to keep
            # it finite and the pressures positive)
            f0 = float(np.linalg.norm(F[rows] * r))
            lam = 1.0
            while True:
                xn = x + lam * dx
                if not self._has_p or self._positive(xn):
                    Fn = self._eval(xn, S, t, dt, jac=False)
                    if all_finite(Fn) and (first or np.linalg.norm(Fn[rows] * r)
                                           <= (1 - 1e-4 * lam) * f0):
                        break
                lam *= 0.5
                if lam < 1e-4:
                    return None
            x = xn
            if first and lam == 1.0 and self._norm(dx) <= 1.0:
                first = False       # converged with the temperatures held
        return None

    def _singular(self, x, iterations, err):
        """The failed Outcome of a singular Jacobian: names the component whose scale
        is extreme relative to the rest where that is the cause (its row), else the
        factorization's own row."""
        row = err.args[1] if len(err.args) > 1 else None
        reason = f"singular Jacobian ({err.args[0]})"
        unknown = None
        bad = np.flatnonzero(~np.isfinite(self.asm.raw))
        if bad.size:            # NaN or inf entries: the first one's equation and unknown
            row = int(self.asm.pattern_rows[bad[0]])
            unknown = int(self.asm.pattern_cols[bad[0]])
            reason += f" in {self.asm.describe_row(row)}, in its derivative in " \
                      f"{self.asm.x_names[unknown]}"
        else:
            try:
                why, culprit = self.asm.diagnose_scale()
            except Exception:         # a diagnosis must never hide the failure itself
                why, culprit = None, None
            if why is not None:
                reason, row = f"{reason}: {why}", culprit
        return Outcome(False, x, iterations, reason, row, unknown=unknown)

    def _contracts(self, Fn, dx):
        """Deuflhard's natural monotonicity test (Newton Methods for Nonlinear
        Problems, 2004, sec. 3.3): the simplified Newton correction at the new
        point, J(x)^-1 F(x + dx), is at most 3/4 of dx in the scaled norm.
        Unlike the residual norm it does not depend on how rows are scaled: at
        the first step of a thermal chain, the energy rows' residual grows where
        flows leave the upwind blend band (0.0006 -> 0.7) while the update
        contracts (rate 0.63), and the residual test backtracked 7 times."""
        return self._norm(self.lin.solve(Fn)) <= 0.75 * self._norm(dx)

    def _clip_temperature(self, x, dx):
        """Clips the node temperature updates of dx in place (callers pass a fresh
        update; np.clip's dispatch costs more than the clipping, measured)."""
        i = self._T_idx
        T = x[i]
        step = np.minimum(np.maximum(dx[i], -0.5 * T), T)
        if self._T_range is not None:
            lo, hi = self._T_range
            step = np.minimum(np.maximum(T + step, lo), hi) - T
        dx[i] = step
        return dx

    def _worst_row(self, F):
        rs = getattr(self.lin, "row_scale", None)
        scaled = np.abs(F) * (rs if rs is not None else 1.0)
        scaled = np.where(np.isfinite(scaled), scaled, np.inf)
        return int(np.argmax(scaled)) if scaled.size else None
