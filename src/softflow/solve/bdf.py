"""Variable-order, variable-step BDF (orders 1-5) for the network's DAE.

The continuous states X (masses, internal energies, inertial flows) obey
X' = r(x, t), the unknowns x (pressures, flows, temperatures) algebraic
equations. The k-step backward differentiation formula in backward
differences at constant step h,

    sum_{j=1..k} (1/j) nabla^j X_{n+1} = h X'_{n+1},

written with the predictor X_pred = sum_{j=0..k} nabla^j X_n (the polynomial
through the last k + 1 points, extrapolated) and d = X_{n+1} - X_pred, is

    X_{n+1} = psi + c r(x_{n+1}, t_{n+1}),
    psi = X_pred - (sum_{j=1..k} g_j nabla^j X_n) / g_k,   c = h / g_k,
    g_j = 1 + 1/2 + ... + 1/j

(Shampine & Reichelt, The MATLAB ODE suite, SIAM J. Sci. Comput. 18, 1997;
Hairer & Wanner, Solving ODEs II, sec. III.1). Every order and every step is
therefore one solve of the step equations with the start-of-step states
replaced by psi and the step by c: library components state rates and
residuals, which :mod:`softflow.solve.discretize` turns into the equations
F(V, psi + c·r(V)) = 0 for any (psi, c); a user component's ``update_state``
is read the same way, as "states = S + dt * rate" (it must be affine in dt),
or it gives ``state_rates`` directly. Backward Euler is the case k = 1
(psi = X_n, c = h).

The unknowns x carry a difference table of their own: their predictor
starts Newton, and the nodes' across unknowns (pressures, temperatures)
enter the error test with the states, as in SUNDIALS IDA (a liquid
accumulator's stored mass hardly changes while its pressure does: the
pressure is what rtol must hold). The other unknowns (the flows through
terminals, the components' own algebraic unknowns) are left out of it, as
IDA's ``suppressalg`` leaves algebraic unknowns out: each is fixed at every
step by its component's equation from the nodes' values, so its error is
theirs carried through that equation. Held to the test themselves, the
flows (the states' rates, one derivative rougher) set the step: 1.4-3.3x
the steps on eight of the nine paper scenes at the default rtol (the
snapping valve's alike), and at tight rtol their Newton noise through a
nearly stagnant tube (a drop of 0.08 Pa against a pressure tolerance of
0.05 Pa) failed the test at every step size (Fig. 3's hysteretic scene
with air at rtol 1e-5: 44 307 steps, 2 253 of them forced at the smallest
step; 516 now). A step in which a mode switches is still judged on every
unknown (:meth:`BDF._judge`: how far the part past the switch moves).
Local error: (1/(k+1)) (X_{n+1} - X_pred, x_{n+1} - x_pred) over those
entries in the weighted RMS norm, weights atol + rtol |X_i| for the states
and atol + rtol max_j |x_j| over the unknowns j of the same quantity for
the unknowns (pressures as gauge pressures: the largest |p - p_atm|). A
network made of independent sub-networks (the variants of a batched sweep)
is tested per sub-network: the error is the largest of their own norms,
each with its own quantity scales, so every one of them meets the
tolerance. After k + 1 steps at one step size the estimates of orders k - 1 and k + 1 (from nabla^k and nabla^(k+2)) choose
the order and the next step. A step size change re-interpolates the
difference table onto the new spacing ("quasi-constant step size"), which
is the Nordsieck-array rescaling in difference form.

Dense output (:mod:`softflow.solve.dense`): every accepted step records the
recorded columns of its difference table (D_1..D_k, order k, step h), so
that values between the steps come from the step's own interpolating
polynomial (``Result.at``, ``Simulation(times=)``, the points of ``refine``),
each polynomial over its own step only; a step across a law's kink is read
as the straight line between its ends.

Every restart (t = 0, a declared breakpoint, a discrete-state switch) starts
at order 1 from the rate at the restart point, found with a tiny backward
Euler probe, and chooses its first step from the first and second
derivatives (Hairer, Norsett & Wanner I, sec. II.4): no step is taken
without an error test. Undeclared jumps show as failed error tests and are
located by step rejection, down to ``step_min``. A discrete state (a valve's
or a hysteretic actuator's mode) that switches at the end of a step is
located before the method restarts from the new mode: where the class states
a switching function (negative while the mode holds, crossing zero where it
changes: a snapping valve's dp - opening_pressure), the step is retried to
end just past the secant crossing of the functions between the step's ends,
until the part of the step past the crossing moves the solution by no more
than the tolerance (as IDA's rootfinding places a root, but by re-stepping);
without one, a step over which the solution moved by more than the tolerance
(weighted norm > 1) is bisected until the switching step is that short.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .dense import DenseRecorder, insert_interior, refine_counts
from .integrator import Integrator, StepFailure
from .newton import Outcome, gauge_offsets
from .settings import (
    CHATTER_STEP,
    CHATTER_SWITCHES,
    FAIL_HOLD,
    FIRST_ESTIMATE,
    FORCED_RESTART,
    FULL_STAGE_STEPS,
    GROW_MIN,
    MAX_FACTOR,
    MAX_ORDER,
    MIN_FACTOR,
    NEWTON_FLOOR,
    NEWTON_FLOOR_FRACTION,
    PEAK_FACTOR,
    SAFETY,
    SECANT_TRIES,
    SWITCH_PAST,
    UNDAMPED_FULL,
)

#: g_j = sum_{i<=j} 1/i, the BDF coefficients in backward-difference form
_G = np.concatenate([[0.0], np.cumsum(1.0 / np.arange(1, MAX_ORDER + 2))])
#: local error constant of order k, times nabla^(k+1) X
_ERR = np.array([0.0] + [1.0 / (k + 1) for k in range(1, MAX_ORDER + 3)])
#: rows (predictor, psi) of the coefficients on D_0..D_k at order k: the predictor
#: sum_j D_j and psi = predictor - (sum_{j>=1} g_j D_j) / g_k, in one product
_PRED_PSI = [None] + [np.array([np.ones(k + 1), np.r_[1.0, 1.0 - _G[1:k + 1] / _G[k]]])
                      for k in range(1, MAX_ORDER + 1)]


def newton_limits(rtol, newton_rtol):
    """(floor factor, first_max) of Newton in an adaptive run at ``rtol``: the
    run's magnitudes times the factor are the floor of Newton's scale (its
    tolerances at least NEWTON_FLOOR of them, or NEWTON_FLOOR_FRACTION of
    Newton's rtol where that is smaller); first_max, the largest first update
    (in tolerances) a predicted contraction alone may accept, rtol of the scale."""
    return (min(NEWTON_FLOOR / newton_rtol, NEWTON_FLOOR_FRACTION),
            max(rtol / newton_rtol, 1.0))


@functools.lru_cache(maxsize=256)
def _rescale_matrix(order, factor):
    """Matrix M with D_new[:order+1] = M @ D[:order+1]: the backward differences
    of the same interpolating polynomial at spacing ``factor`` times the old.

    With s the time from t_n in old steps, the Newton backward form reads
    p(s) = sum_j D_j phi_j(s), phi_j(s) = prod_{i<j} (s + i) / j!. Values at
    s = -m·factor (m = 0..order) are the new nodes; the new differences are
    the coefficients of the same values in the basis phi_j(-m)."""
    m = np.arange(order + 1)[:, None]

    def basis(scale):
        A = np.ones((order + 1, order + 1))
        for j in range(1, order + 1):
            A[:, j] = A[:, j - 1] * (j - 1 - m[:, 0] * scale) / j
        return A

    M = np.linalg.solve(basis(1.0), basis(factor))
    M.setflags(write=False)        # cached: shared by every caller
    return M


#: the ufunc method: ~0.6 us against ~1.5 us for np.max on small arrays
_max = np.maximum.reduce


class BDF(Integrator):
    """Variable-order (1 to ``max_order``), variable-step BDF on the states: a
    controller of the one integration loop (:meth:`Integrator.run`), whose
    steps it proposes (:meth:`_propose`), judges (its error test and the
    location of a mode switch, :meth:`_judge`) and takes (the difference
    tables, the order and the next step, :meth:`_take`).

    Newton solves for the unknowns at each step with the kernels' states
    replaced by psi and the step by c (module docstring), reusing LU factors
    as in backward Euler; where its chord iterations fail on fresh factors,
    the step is cut by 4 (its damped full stage only on the shortest steps,
    :data:`FULL_STAGE_STEPS`; on longer ones, chord iterations that contract
    too slowly go on as undamped Newton first, :data:`UNDAMPED_FULL`). The error test covers the continuous states
    and the nodes' across unknowns (pressures, temperatures; module docstring);
    discrete states are left out (a switch restarts the method).
    Alongside, the integrals of the recorded unknowns are integrated by the
    same formula (:meth:`softflow.solve.result.Result.integral`)."""

    def __init__(self, asm, newton, stats, *, duration, rtol, atol_states, atol_unknowns,
                 step_min, step_max,
                 max_order=MAX_ORDER, first_step=None, breakpoints=(), record=None,
                 refine=1):
        super().__init__(asm, newton, stats, duration=duration, breakpoints=breakpoints,
                         record=record, expected_steps=256)
        self.rtol = rtol
        self.atol = np.broadcast_to(np.asarray(atol_states, dtype=float), asm.S0.shape).copy()
        self.step_min, self.step_max = step_min, step_max
        self.max_order = max_order
        self.first_step = first_step
        # points recorded per step (finish): an int, or None to choose per step
        self.refine = None if refine is None else int(refine)
        # (self.breaks, Integrator's, keep a jump declared at the end point: the
        # last step sees its left limit, else the error test, seeing the new
        # value, would never let it land)
        self.cont = asm.s_continuous
        self._all_cont = self.cont.size == asm.S0.size
        # a discrete state's weight is inf: its entries leave the norm
        self._atol_s = self.atol.copy()
        self._atol_s[asm.s_discrete] = math.inf
        self._ns = asm.S0.size
        # the error test's entries: the continuous states and the nodes' across
        # unknowns (pressures, temperatures: x[:n_across]), first in the
        # difference table; discrete states count out of the RMS (weight inf)
        self._m_err = self._ns + asm.n_across
        self._n_disc = self._ns - self.cont.size
        # unknowns: absolute tolerance per unknown; rtol scales with the largest
        # magnitude of each one's quantity (Assembly.quantity_max)
        self.atol_x = np.asarray(atol_unknowns, dtype=float) * np.ones(asm.n)
        # pressures are scaled by their gauge magnitude: what a network of soft
        # actuators does is set by pressure differences of a fraction of an
        # atmosphere, which rtol of the absolute pressure would hold 3-10x looser
        self._x_offset = gauge_offsets(asm.x_quantity)
        self._qmax_run = None
        # Newton weighs pressures alike, takes the run's magnitudes, scaled, as
        # a floor (_weights), and accepts a first update on its predicted
        # contraction alone only up to rtol of the scale (newton_limits)
        self._floor_factor = 1.0
        if newton is not None:
            newton.set_gauge()
            self._floor_factor, newton.first_max = newton_limits(rtol, newton.rtol)
            newton.undamped_full = UNDAMPED_FULL
        # independent sub-networks (e.g. the variants of a batched sweep) each
        # meet the tolerance: the error is the largest of their own norms, and
        # an unknown's scale is that of its quantity in its own sub-network
        x_block, s_block, self._n_blocks = asm.subnetworks()
        if self._n_blocks > 1:
            nq = len(asm.q_names)
            key = x_block * nq + asm.q_id
            self._bq_order = np.argsort(key, kind="stable")
            self._bq_starts = np.searchsorted(key[self._bq_order], np.arange(self._n_blocks * nq))
            self._bq_key = key
            self._x_block = x_block
            self._s_block = s_block[self.cont]
        self.forced_steps = 0
        self.order_counts = [0] * (max_order + 1)
        # time integrals of the recorded unknowns, by the same BDF (a quadrature
        # "state" Q' = x): Result.integral hands the run's own quadrature back
        xi = self.rec.x_index
        self._q_sel = slice(None) if isinstance(xi, int) else xi
        self.rec.keep_integrals()
        # dense output (softflow.solve.dense): per accepted step the recorded
        # columns of its difference table, states, unknowns, quadratures
        ns, n = asm.S0.size, asm.n
        if isinstance(xi, int):
            cols, width = None, ns + 2 * n
        else:
            si = np.asarray(self.rec.s_index, dtype=np.int64)
            xi = np.asarray(xi, dtype=np.int64)
            cols = np.concatenate([si, ns + xi, ns + n + np.arange(xi.size)])
            width = cols.size
        self.dense = DenseRecorder(cols, width)

    # -- norms ---------------------------------------------------------------------
    def _weights(self, S_a, S_b, x):
        """Error weights for a step from S_a to S_b, the unknowns' from their
        magnitudes in x: one vector (ns + n) in the difference table's order
        (states, then unknowns); a discrete state's is inf (left out)."""
        wS = self._atol_s + self.rtol * np.maximum(np.abs(S_a), np.abs(S_b))
        if not x.size:
            return wS
        if self._n_blocks > 1:
            # per (sub-network, quantity); a pair with no unknowns reads the next
            # pair's start, which no unknown indexes
            v = np.abs(x - self._x_offset)[self._bq_order]
            starts = np.minimum(self._bq_starts, v.size - 1)
            qmax = np.maximum.reduceat(v, starts)
            key = self._bq_key
        else:
            qmax = self.asm.quantity_max(x - self._x_offset)
            key = self.asm.q_id
        # the largest magnitude seen so far in the run: a flow that decays to rest
        # is held to the network's flow scale, not to its own vanishing size
        if self._qmax_run is not None:
            qmax = np.maximum(qmax, self._qmax_run)
        self._qmax_run = qmax
        newton = self.newton
        if newton is not None and self._n_blocks == 1:
            # Newton's tolerances too are relative to the run's magnitudes: a
            # settled network's flows (1e-9 kg/s after 0.1) are resolved to the
            # network's flow scale, as round-off allows
            floor = qmax * self._floor_factor
            newton.scale_floor = floor.tolist() if newton._small else floor
        return np.concatenate((wS, self.atol_x + self.rtol * qmax[key]))

    def _norm(self, v, w, vx):
        """:meth:`_enorm` of the states' v and the unknowns' vx."""
        return self._enorm(np.concatenate((v, vx)), w)

    def _enorm(self, v, w):
        """Weighted RMS of the continuous states' and the unknowns' entries of v
        (states then the first unknowns, as many as v has; w as v, from
        :meth:`_weights`), or their largest weighted entry over
        :data:`PEAK_FACTOR` where that is larger."""
        e = v / w
        if self._n_blocks > 1:
            ns = self._ns
            return self._block_norm(e[:ns][self.cont], e[ns:])
        size = e.size - self._n_disc
        if not size:
            return 0.0
        return max(math.sqrt(e.dot(e) / size), float(_max(np.abs(e))) / PEAK_FACTOR)

    def _block_norm(self, e, ex):
        """The largest of the sub-networks' norms (each as :meth:`_norm`)."""
        nb = self._n_blocks
        acc = np.bincount(self._s_block, weights=e * e, minlength=nb)
        size = np.bincount(self._s_block, minlength=nb).astype(float)
        if ex is not None:
            xb = self._x_block[:ex.size]      # across unknowns first
            acc += np.bincount(xb, weights=ex * ex, minlength=nb)
            size += np.bincount(xb, minlength=nb)
        peak = max(float(np.max(np.abs(e), initial=0.0)),
                   0.0 if ex is None else float(np.max(np.abs(ex), initial=0.0)))
        return max(float(math.sqrt(np.max(acc / np.maximum(size, 1.0)))), peak / PEAK_FACTOR)

    # -- restarts ------------------------------------------------------------------
    def _probe(self, x, S, t, h, continuation=True, tight=True):
        """Backward Euler from (x, S) at t over h, Newton held tight: (x_h, rate at
        x_h), rate = (update(x_h, S, h) - S) / h exactly (discrete states: 0).
        None if Newton fails, also by continuation (:meth:`Newton.continued`,
        with ``continuation``: the first two probes of every restart, at t =
        0, a breakpoint, a switch or a fold jump, without which the run
        stops). ``tight`` False: at the run's Newton tolerance at once (the
        compiled loop's probe failed at 1e-12 already: :meth:`_restart`)."""
        newton = self.newton
        newton.full_stage = True
        rtol = newton.rtol
        if tight or rtol <= 1e-12:
            newton.rtol = min(rtol, 1e-12)
            try:
                out = newton.solve(x, S, t + h, h)
            finally:
                newton.rtol = rtol
        else:
            out = None
        if (out is None or not out.converged) and rtol > 1e-12:
            # held to the run's own Newton tolerance where 1e-12 is out of
            # reach (round-off of an ill-conditioned point: flows starting
            # from rest beside a gas volume's ~1e-10 dm/dp)
            out = newton.solve(x, S, t + h, h)
        if continuation:
            out = newton.continued(out, x, S, t + h, h)
        if not out.converged:
            return None, out
        r = (self.asm.update_states(out.x, S, h) - S) / h
        if not self._all_cont:
            r[self.asm.s_discrete] = 0.0
        return (out.x, r), out

    def _restart(self, x, S, t, limit):
        """Rates just after t and the first step: (x(t+), X'(t+), x'(t+), h).

        Two backward Euler probes of tiny steps h_p and 2 h_p give the states'
        rate (exact at the probe) and the unknowns' (a difference; Newton is held
        to 1e-12 there); a third over h0 = 0.01 ||X|| / ||X'|| gives the second
        derivatives, and the first step aims at an order-1 error estimate of
        FIRST_ESTIMATE (Hairer, Norsett & Wanner I, sec. II.4, for a DAE)."""
        span = limit - t
        # the probe whose solve at 1e-12 the compiled loop tried and failed
        # at this point (steploop.CompiledSteps.run): not solved so again
        hint, self._tight_failed = self._tight_failed, None
        done = hint[1] if hint is not None and hint[0] == t else -1
        h_p = min(max(self.step_min, 1e-7 * self.T), 0.25 * span)
        p1, out = self._probe(x, S, t, h_p, tight=done != 0)
        if p1 is None:
            raise StepFailure(t + h_p, h_p, out)
        p2, out = self._probe(p1[0], S, t, 2 * h_p, tight=done != 1)
        if p2 is None:
            raise StepFailure(t + 2 * h_p, 2 * h_p, out)
        (x1, r0), (x2, _) = p1, p2
        xdot = (x2 - x1) / h_p
        x_right = x1 - h_p * xdot           # back to t+
        if self.first_step is not None:
            return x_right, r0, xdot, max(min(self.first_step, span), self.step_min)
        m, na = self._m_err, self.asm.n_across
        w = self._weights(S, S, x_right)[:m]
        d0, d1 = self._norm(S, w, x_right[:na]), self._norm(r0, w, xdot[:na])
        h0 = 1e-6 * span if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(max(h0, 4 * h_p), span, self.step_max)
        p3, _ = self._probe(x_right, S, t, h0, continuation=False, tight=done != 2)
        if p3 is None:
            h = 0.1 * h0
        else:
            x3, r3 = p3
            ddx = 2 * (x3 - x_right - h0 * xdot) / h0 ** 2
            d2 = self._norm((r3 - r0) / h0, w, ddx[:na])
            h1 = math.sqrt(2 * FIRST_ESTIMATE / d2) if d2 > 1e-15 else max(1e-6 * span, 1e3 * h0)
            h = min(100 * h0, h1)
        return x_right, r0, xdot, max(min(h, span, self.step_max), self.step_min)

    def _crossing(self, x, S, x_new, S_new):
        """The fraction of the step at which the first switching function crosses
        zero, by a secant between the step's ends (the end evaluated with the
        old modes), or None where no group states one or none crosses."""
        asm = self.asm
        g0 = asm.switching(x, S)
        if g0 is None:
            return None
        old_modes = S_new.copy()
        old_modes[asm.s_discrete] = S[asm.s_discrete]
        g1 = asm.switching(x_new, old_modes)
        cross = (g0 < 0.0) & (g1 >= 0.0)
        if not cross.any():
            return None
        theta = float(np.min(g0[cross] / (g0[cross] - g1[cross])))
        return theta if 0.0 < theta <= 1.0 else None

    def _check_affine_updates(self, x, S):
        """A user component's ``update_state`` must be affine in dt (states + dt ·
        rate): BDF passes it psi and c in place of the states and the step. Checked
        at the consistent start, on dt = 0, h, 2h."""
        h = 1e-3 * self.T
        for g in self.asm.groups:
            if g.row is None or not g.has_states:
                continue
            V, Sg = x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns)
            u0, u1, u2 = (np.array(g.update(V, Sg, dt), dtype=float).reshape(Sg.shape)
                          for dt in (0.0, h, 2 * h))
            bent = np.abs(u2 - 2 * u1 + u0)
            if (bent > 1e-6 * np.abs(u2 - u0) + 1e-12 * np.abs(u0) + 1e-300).any():
                comp = g.comps[0]
                raise ValueError(
                    f"{comp.describe()}: update_state is not affine in dt: its states at dt "
                    f"= 0, {h:.3g}, {2 * h:.3g} s do not lie on a line. The adaptive BDF "
                    "integrator reads a state's rate from update_state as "
                    "(update_state(dt) - states) / dt, so write it as states plus dt times "
                    "a rate (e.g. {'mass': mass + mf * dt}), or run with step= for "
                    "fixed-step backward Euler, which takes any update_state.")

    # -- the loop's controller (Integrator.run) --------------------------------------------
    def _setup(self, x, S):
        self._check_affine_updates(x, S)
        self.dense.point(0.0, len(self.rec.t) - 1)      # the consistent start
        asm = self.asm
        self._disc = asm.s_discrete if asm.has_discrete else None
        ns, n = S.size, x.size
        self._Q = np.zeros(x[self._q_sel].size)
        # one difference table for the states, the unknowns and the quadratures
        # (one NumPy call per operation instead of three); slices name the parts.
        # The error test's entries are the first ns + n_across columns
        self._D = np.zeros((self.max_order + 3, ns + n + self._Q.size))
        self._iS, self._iX = slice(0, ns), slice(ns, ns + n)
        self._iQ, self._iErr = slice(ns + n, None), slice(0, self._m_err)
        # the states' sensitivities keep their own table, differenced and
        # rescaled with the states' (softflow.solve.sensitivity)
        self._tables = (self._D,)
        self._delta = np.empty(self._D.shape[1])
        self._ib, self._next = 0, (self.breaks[0] if self.breaks else math.inf)
        self._restart_due = True
        self._h = 0.0
        self._k = self._n_equal = self._fails = 0
        self._forced = self._passed = self._forced_restart = False
        self._h_cap, self._cap_hold = math.inf, 0     # while a mode switch is being located
        self._smallest = False     # the step tried is the smallest (_propose)
        self._tight_failed = None  # (t, probe) the compiled loop's restart failed at 1e-12
        # below a step that failed the error test, for a while: without it a step
        # that doubles across a stability boundary (a fast mode near h·lambda = 1)
        # fails, halves, doubles and fails again every third step
        self._fail_cap, self._fail_hold = math.inf, 0
        self._secant_tries = 0     # secant placements of the current switch
        self._jump = None          # a switch's left side, for the sensitivities
        self._chatter = 0          # accepted steps in a row that switched at the smallest steps
        self._fold_at = None       # the time of the last fold jump (_fold_jump)
        # laws with kinks (a check valve's shut / opening / open): the side of
        # them at the last point taken (its bytes) and that point (_take)
        self._kinks = asm.kinks if asm.has_kinks else None
        self._kink_x = self._kink_at = None

    def _propose(self, t, x, S):
        self._point = (x, S)       # for a fold jump (_fold_jump)
        if self._next <= t * (1 + 1e-14) + 1e-300:
            self._ib, self._next = self._next_break(t, self._ib)
        next_break, T = self._next, self.T
        limit = next_break if next_break < T else T
        D, iS, iX, iQ = self._D, self._iS, self._iX, self._iQ
        restart = self._restart_due
        if restart and self._forced_restart:
            try:
                x_right, r0, xdot, h = self._restart(x, S, t, limit)
            except StepFailure:
                # a restart only a forced step asked for, whose probes fail
                # (a marginal failure of the error test, not a jump: the pumped
                # noisy balloon at rtol 1e-5 stopped there): on with the history
                restart = self._restart_due = False
            self._forced_restart = False
        elif restart:
            x_right, r0, xdot, h = self._restart(x, S, t, limit)
        if restart:
            self.progress.restarted(t, h)
            D[:] = 0.0
            D[0, iS], D[1, iS] = S, h * r0
            D[0, iX], D[1, iX] = x_right, h * xdot
            D[0, iQ], D[1, iQ] = self._Q, h * x_right[self._q_sel]
            sens = self.sens
            if sens is not None:      # order 1: psi is the value alone
                if self._jump is not None:  # a located switch: the jump of s_S there
                    sens.switch(*self._jump, r0)
                    self._jump = None
                sens.restart(self.max_order)
            self._k, self._n_equal, self._fails = 1, 0, 0
            self._restart_due = False
            self._passed = False
            self._h = h
        h, k = self._h, self._k
        # the step: no overshoot of the limit, no sliver left before it
        h_try = min(h, self.step_max, self._h_cap, self._fail_cap)
        smin = self.step_min * 1.0000001
        # the smallest step: step_min, or step_min stretched over the sliver
        # before the limit (up to 1.2 step_min): at it, a failed error test
        # forces the step, a failed Newton stops. Without the stretched case
        # a jump inside the last step_min before a breakpoint was rejected
        # until max_steps (the stretch undid each shrink to step_min)
        smallest = h_try <= smin
        if t + h_try >= limit or limit - (t + h_try) < 0.2 * h_try:
            h_try = limit - t
        self._smallest = smallest or h_try <= smin
        if h_try != h:
            self._rescale(self._tables, k, h_try / h)
            self._h = h = h_try
            self._n_equal = 0
        t_new = t + h
        self._at_break = at_break = t_new == next_break
        pred, psi_all = self._pred, self._psi_all = _PRED_PSI[k] @ D[:k + 1]
        c = h / _G[k]
        self._t_eval = t_eval = math.nextafter(t_new, -math.inf) if at_break else t_new
        self.newton.full_stage = h <= FULL_STAGE_STEPS * self.step_min
        return pred[iX], psi_all[iS], t_new, t_eval, c

    def _stretch_for(self):
        """The compiled loop's entry (:mod:`softflow.solve.steploop`), where it
        serves this run: it takes the usual steps while no restart is due, no
        mode switch is being located and no emptying volume (module
        docstring of softflow.solve.steploop)."""
        from .steploop import compiled_steps
        steps = compiled_steps(self)
        if steps is None:
            return None

        def stretch(t, x, S):
            if ((self._restart_due and self._forced_restart) or self._empty_tries
                    or self._approached
                    or (self._k < 1 and not self._restart_due)):
                return None
            t1, x1, S1 = steps.run(t, x, S)[1:4]
            failed = steps.failed_here()
            if failed:
                # the loop's rejected solves at the point it leaves, counted
                # by the culprit finder as its own
                self.culprit.failed_at(x1 if t1 > t else x, failed)
            return t1, x1, S1
        return stretch

    def _newton_failed(self, t, t_new, out):
        h = self._h
        self.progress.rejected(t_new, h, "newton", out)
        if self._smallest or (self.culprit is not None and self.culprit.stalled(t, h, out)):
            x_far = self._fold_jump(t, out)
            if x_far is None:
                raise StepFailure(t_new, h, out)
            return x_far
        self._shrink(max(0.25, self.step_min / h))
        return None

    def _fold_jump(self, t, out):
        """The point at t past a fold, or None: where Newton fails at the
        smallest step on the equation of an actuator whose gas's mass has
        reached a fold of its PV curve (a snap: no volume nearby holds the mass
        it is taking in, or giving out; ``fold_pressure`` of its class), the
        actuator snaps, at the mass it holds, to the volume past the snap that
        does (a gas-filled actuator whose curve falls more steeply than its
        gas expands). The unknowns at t are solved for anew
        from that actuator's pressure there (states held, as at t = 0), the
        point recorded at t beside the one before the snap, and the method
        restarted from it. Where the equation Newton failed on is not an
        actuator's (a negative pressure at the node of a pump that draws from
        an actuator at a fold), every actuator whose class states a fold is
        asked, and the first at one snaps. A snap lands on the far side:
        where Newton's solve from the far pressure goes back nearer the
        pressure it started from, it is none. At most once at one time; not with
        sensitivities (a jump of the unknowns at fixed states, which they do
        not carry)."""
        if self.sens is not None or self._fold_at == t:
            return None
        g, k = (None, None) if out.row is None else self.asm.group_of_row(out.row)
        if g is not None and g.fold is not None and g.ns:
            candidates = [(g, k)]
        else:
            # the failure shows elsewhere (a negative pressure at the node of
            # a pump that draws from an actuator at a fold): any actuator at one
            candidates = [(g, k) for g in self.asm.groups if g.fold is not None and g.ns
                          for k in range(g.n)]
        for g, k in candidates:
            snapped = self._snap(g, k, t)
            if snapped is not None:
                break
        else:
            return None
        self._fold_at = t
        x_far = snapped.x
        self.dense.point(t, len(self.rec.t))
        self.rec.add(t, x_far, self._point[1], self._Q)
        self._restart_due = True
        self._h_cap = self._fail_cap = math.inf
        self._fail_hold = self._cap_hold = 0
        return x_far

    def _snap(self, g, k, t):
        """The Outcome of the solve at t with actuator k of group g snapped to
        the far side of a fold of its curve, or None where it is at none or
        that solve fails (:meth:`_fold_jump`)."""
        x, S = self._point
        mass = g.s0 + k * g.ns                      # the mass: its first state
        rate = self._D[1, self._iS][mass]           # h m'(t), the direction it goes
        if not rate:
            return None
        p_far = g.fold(x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns), k, bool(rate > 0))
        if not np.isfinite(p_far) or p_far <= 0.0:
            return None
        i = g.col[k, 0]                              # its pressure: terminal a's
        guess = x.copy()
        guess[i] = p_far
        newton = self.newton
        newton.full_stage = True
        snapped = newton.solve(guess, S, t, 0.0)
        newton.invalidate()
        # a snap lands on the far side: nearer p_far than where it started
        # (a solve that went back to the near branch is none)
        if not snapped.converged or abs(snapped.x[i] - p_far) >= abs(snapped.x[i] - x[i]):
            return None
        return snapped

    def _chattering(self, S, S_new, x_new, h):
        """The failed Outcome of a run whose modes chatter (CHATTER_SWITCHES), on
        the first equation of the component whose mode switched last."""
        asm = self.asm
        # (the discrete states: a mask over the states)
        i = int(np.flatnonzero(S_new[self._disc] != S[self._disc])[0])
        state = int(np.flatnonzero(self._disc)[i])
        row, name = None, "a component"
        for g in asm.groups:
            if g.ns and g.s0 <= state < g.s1:
                k = (state - g.s0) // g.ns
                row = g.r0 + k * g.neq
                name = g.comps[k].describe()
                break
        reason = (f"{name} switched its mode at each of the last {CHATTER_SWITCHES} steps, "
                  f"all of at most {CHATTER_STEP:g} x step_min ({h:.3g} s): the mode undoes "
                  "itself as soon as it is taken (it chatters), and time no longer "
                  "advances. Typically a flow source pushes into (or draws from) a valve "
                  "with no volume between them: give that node a volume (a Container), "
                  "or the valve a wider band between its opening and closing pressures")
        return Outcome(False, x_new, 0, reason, row)

    def _shrink(self, factor):
        """The next try at ``factor`` times the step (a rejected step)."""
        self._rescale(self._tables, self._k, factor)
        self._h *= factor
        self._n_equal = 0

    def _aim(self, h):
        """The next step no longer than h (one that ends just past a located
        crossing), from the point just taken; whether that shortens it."""
        if h < self._h:
            self._shrink(h / self._h)
            return True
        return False

    def _judge(self, t, x, S, x_new, S_new, t_new):
        delta, iS, iX, pred = self._delta, self._iS, self._iX, self._pred
        np.subtract(S_new, pred[iS], out=delta[iS])
        np.subtract(x_new, pred[iX], out=delta[iX])
        w = self._weights(S, S_new, x_new)
        k, h = self._k, self._h
        err = self._err = _ERR[k] * self._enorm(delta[self._iErr], w[self._iErr])
        smallest = self._smallest
        if err > 1.0:
            if not smallest:
                stats = self.stats
                stats.rejected_steps += 1
                stats.error_test_failures += 1
                self.progress.rejected(t_new, h, "error", err)
                self._fails = fails = self._fails + 1
                self._fail_cap, self._fail_hold = 0.9 * h, FAIL_HOLD
                # as IDA: the first failure shrinks the step from twice the
                # estimate (the failures here are mostly at kinks of PV curves,
                # where the error falls slower than h^(k+1): from the estimate
                # alone a second failure followed; on the nine paper scenes
                # 582 -> 522 rejections, 11 100 -> 10 600 Newton iterations),
                # the second by at least 4, later ones restart at order 1
                factor = max(MIN_FACTOR, SAFETY * (2 * err + 1e-4) ** (-1.0 / (k + 1)))
                if fails == 2:
                    factor = min(factor, 0.25)
                elif fails >= 3:
                    factor = 0.25
                    if k > 1:
                        self._reset_order(self._tables, k, 1)
                        self._k = 1
                self._shrink(max(factor, self.step_min / h))
                return None
            self.forced_steps += 1
            self._forced = True
        else:
            self._forced = False
        disc = self._disc
        switched = self._switched = disc is not None and bool((S_new[disc] != S[disc]).any())
        if switched and not smallest and self._switch_rejected(t_new, h, x, S, x_new, S_new, w):
            return None
        self._secant_tries = 0
        return t_new

    def _switch_rejected(self, t_new, h, x, S, x_new, S_new, w):
        """Whether a step of ``h`` that switched a mode is rejected to locate
        the switch (the next try shrunk, :meth:`_shrink`); ``w``: the step's
        error weights (:meth:`_weights`)."""
        motion = self._norm(S_new - S, w, x_new - x)
        theta = (self._crossing(x, S, x_new, S_new)
                 if motion > 1.0 and self._secant_tries < SECANT_TRIES else None)
        # the part of the step past the switch ran in the old mode: accepted
        # where the motion over that part is within the tolerance
        past = 1.0 if theta is None else 1.0 - theta
        if motion * past <= 1.0:
            return False
        self.stats.rejected_steps += 1
        self.progress.rejected(t_new, h, "switch")
        if theta is not None:
            # end the step just past the crossing (a secant of the switching
            # functions between the step's ends), by a part whose motion
            # stays within half the tolerance
            self._secant_tries += 1
            past = min(SWITCH_PAST, 0.5 / max(motion * theta, 1.0))
            factor = max(theta * (1.0 + past), self.step_min / h)
        else:
            # no switching function (or the secant did not settle): bisect
            # until the switching step is that short
            factor = max(0.5, self.step_min / h)
            self._h_cap, self._cap_hold = h * factor, FAIL_HOLD
        self._shrink(factor)
        return True

    def _take(self, t, x, S, x_new, psi, c, S_new, t_new):
        self._fails = 0
        if self._fail_hold:
            self._fail_hold -= 1
            if not self._fail_hold:
                self._fail_cap = math.inf
        if self._cap_hold:              # the switch did not come back: stop locating it
            self._cap_hold -= 1
            if not self._cap_hold:
                self._h_cap = math.inf
        k, h, D = self._k, self._h, self._D
        self.order_counts[k] += 1
        iQ, delta, sens = self._iQ, self._delta, self.sens
        Q_new = self._psi_all[iQ] + c * x_new[self._q_sel]
        if sens is not None:
            sens.step(x_new, psi, self._t_eval, c, k)
        np.subtract(Q_new, self._pred[iQ], out=delta[iQ])
        self._difference_update(D, delta, k)
        switched = self._switched
        if switched:
            self.progress.switched(t_new, S, S_new, self._disc)
            if sens is not None:
                # the unknowns' rate at the switch from the table (order k)
                xdot = (1.0 / np.arange(1, k + 1)) @ D[1:k + 1, self._iX] / h
                self._jump = (x, S, x_new, S_new, psi, c, xdot)
        self._Q = Q_new
        # a law's kink (a check valve that has just shut) inside the step: the
        # solution is not smooth there, and the step's polynomial, smooth
        # through the points before, overshoots it (a shut valve's flow read
        # negative inside): dense output reads the step as the straight line
        # between its ends instead (D_0, D_1 of its table)
        kinked = self._kinks is not None and self._across_kink(x, x_new)
        rec = self.rec
        self.dense.step(t_new, h, 1 if kinked else k, len(rec.t), D)
        rec.add(t_new, x_new, S_new, Q_new)
        if switched and h <= CHATTER_STEP * self.step_min:
            self._chatter += 1
            if self._chatter >= CHATTER_SWITCHES:
                raise StepFailure(t_new, h, self._chattering(S, S_new, x_new, h))
        else:
            self._chatter = 0
        # a step taken past the error test at the smallest step: the solution
        # jumped there (an actuator's gas that Newton took to another volume
        # holding its mass, past a fold): the history before it extrapolates
        # a trajectory that no longer is, so the method restarts from the new
        # point, as after a fold jump (not again before a step has passed the
        # test since the last restart: at the start of a run, forced steps in
        # a row follow each other)
        forced = self._forced and FORCED_RESTART and self._passed
        if not self._forced:
            self._passed = True
        if kinked and not (self._at_break or switched or forced):
            # the history from before a kink (a valve that has just shut)
            # extrapolates a smooth trajectory past it: on at order 1, and
            # the order may rise only once k + 1 steps lie past the kink
            if k > 1:
                self._reset_order(self._tables, k, 1)
                self._k = 1
            self._n_equal = 0
            return x_new, S_new, t_new
        if self._at_break or switched or forced:
            self._restart_due = True
            # only the forced step asks for it: where its probes fail, BDF
            # goes on with its history (_propose)
            self._forced_restart = not (self._at_break or switched)
            self._h_cap = self._fail_cap = math.inf
            self._fail_hold = self._cap_hold = 0
            self.newton.invalidate()
            return x_new, S_new, t_new
        self._n_equal += 1
        if self._n_equal < k + 1:
            return x_new, S_new, t_new
        # order and step: estimates at k - 1, k, k + 1
        w = self._weights(S_new, S_new, x_new)[self._iErr]
        DErr, kmax = D[:, self._iErr], self.max_order
        err_k = max(self._err, 1e-16)
        cands = [(SAFETY * err_k ** (-1.0 / (k + 1)), k)]
        if k > 1:
            e_lo = max(_ERR[k - 1] * self._enorm(DErr[k], w), 1e-16)
            cands.append((SAFETY * e_lo ** (-1.0 / k), k - 1))
        if k < kmax:
            e_hi = max(_ERR[k + 1] * self._enorm(DErr[k + 2], w), 1e-16)
            cands.append((SAFETY * e_hi ** (-1.0 / (k + 2)), k + 1))
        factor, k_new = max(cands)
        factor = min(MAX_FACTOR, factor)
        if 1.0 <= factor < GROW_MIN:
            if k_new == k:
                return x_new, S_new, t_new     # not worth a new step size
            factor = 1.0          # an order change alone
        self._k = k_new
        self._rescale(self._tables, k_new, max(MIN_FACTOR, factor))
        self._h = h * max(MIN_FACTOR, factor)
        self._n_equal = 0
        return x_new, S_new, t_new

    def _across_kink(self, x, x_new):
        """Whether a law's kink (``kinks`` of its class) lies between the points
        x and x_new of the step just taken."""
        kinks = self._kinks
        before = self._kink_at if self._kink_x is x else kinks(x).tobytes()
        now = kinks(x_new).tobytes()
        self._kink_x, self._kink_at = x_new, now
        return now != before

    def finish(self, t, X, S, Q):
        """The recorded points (t, X, S, Q: the steps' end points) with the
        points ``refine`` asks for inside each step, and the run's
        :class:`~softflow.solve.dense.DenseOutput` on them: (t, X, S, Q,
        dense). The inside points lie evenly on each step's own polynomial
        (its difference table; Newton's backward formula, as scipy's BDF
        dense output), discrete states at their values at the step's start
        (a switch takes effect at its end): ``refine`` of them per step, or
        where it is None as many as keep straight lines between them within
        the run's tolerance of the polynomial (:func:`dense.refine_counts`,
        weighed as the error test weighs: atol + rtol x the run's largest
        magnitude of each state, and of each unknown's quantity)."""
        if not self.dense.t:          # stopped at its consistent start
            self.dense.point(0.0, 0)
        dense = self.dense.output(X, S, Q, self._recorded_discrete())
        if self.refine is None:
            counts = refine_counts(dense, self._read_weights(S))
        else:
            counts = np.full(dense.k.size, self.refine)
        # X, S, Q the records' own first rows: refine's points may go into
        # those arrays (the run's last use of its recorder)
        rec = self.rec
        own = (X.base is rec._X and S.base is rec._S
               and (Q is None or Q.base is rec._Q))
        t, X, S, Q, dense = insert_interior(dense, counts, t, X, S, Q, in_place=own)
        return t, X, S, Q, dense

    def _read_weights(self, S):
        """Weights of the recorded states, then unknowns, for reading the
        result between its points (:meth:`finish`): atol + rtol x the run's
        largest magnitude of each state (discrete ones: inf), and of each
        unknown's quantity (as the error test weighs them, :meth:`_weights`)."""
        si, xi = self.rec.s_index, self.rec.x_index
        s_sel = slice(None) if isinstance(si, int) else si
        x_sel = slice(None) if isinstance(xi, int) else xi
        wS = self._atol_s[s_sel] + self.rtol * (np.abs(S).max(axis=0) if len(S) else 0.0)
        qmax = self._qmax_run
        key = self._bq_key if self._n_blocks > 1 else self.asm.q_id
        if qmax is None or not self.asm.n:
            wX = np.full(self.asm.n, math.inf)[x_sel]
        else:
            wX = (self.atol_x + self.rtol * qmax[key])[x_sel]
        return np.concatenate([wS, wX])

    # -- difference table ------------------------------------------------------------
    @staticmethod
    def _difference_update(D, d, k):
        """Backward differences at the new point from d = nabla^(k+1) X_{n+1}."""
        D[k + 2] = d - D[k + 1]
        D[k + 1] = d
        for i in range(k, -1, -1):
            D[i] += D[i + 1]

    def _rescale(self, tables, k, factor):
        if factor == 1.0:
            return
        # row 0 (the value at t_n) stays as it is: a constant has no differences at
        # any spacing, so only rows 1..k mix, and the states' and quadratures'
        # absolute levels never meet the rounding of the matrix
        M = _rescale_matrix(k, factor)[1:, 1:]
        for D in tables:
            D[1:k + 1] = M @ D[1:k + 1]
        if self.sens is not None:
            self.sens.rescale(k, M)

    def _reset_order(self, tables, k, k_new):
        """Lower the order: the differences above k_new are dropped."""
        for D in tables:
            D[k_new + 1:] = 0.0
        if self.sens is not None:
            self.sens.reset_order(k_new)
