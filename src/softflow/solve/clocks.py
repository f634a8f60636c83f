"""Batched variants on clocks of their own, the BDF vectorized over the
variants: for the batches that the compiled step loop, where each variant
is its own run (:mod:`softflow.solve.variants`, tried first), does not
serve (heat-transfer correlations' per-step h A, sources given as Python
functions, fluids at the table or eos level, variants too large for a
dense start).

A batched sweep (:mod:`softflow.solve.batched`) solves K variants of one
scene as one network of K independent sub-networks. With one shared step
sequence, the variant that needs the smallest steps at each moment sets
everybody's step: 250 source-tube-tank variants took 340 shared steps where
each alone takes 4-57. Here every variant keeps its own time t_v, step h_v,
order k_v and difference table, and the batch advances them together: at
each pass, each running variant proposes its next step; the kernels evaluate
all variants in one vectorized call, each instance at its own variant's time
and with its own step coefficient (``kernel(V, S, t, dt)`` with t an array
(n,) and dt a column (n, 1), see :mod:`softflow.solve.discretize`); Newton
solves each variant's block (small ones factored afresh at every pass, all
in a few vector operations by one planned sparse elimination,
:mod:`softflow.solve.blocklu`, with LAPACK's inverse for a variant it does
not serve; large ones by the batch's sparse factors, kept while they serve)
and judges each variant's convergence on its own; and each variant's step is
accepted or rejected, and its next step and order chosen, by its own error test, exactly
as :class:`softflow.solve.bdf.BDF` does for one network (same formulas,
constants and controller; vectorized over the variants). A variant that
finishes, or waits, is held at its last point (a zero step) while the others
go on, so a stiff variant costs the others nothing but its share of the
batch's vectorized evaluations.

Declared breakpoints (an input's jump) are shared: the union of the
variants' breakpoints is a barrier that every variant reaches, and all of
them restart there together (the restart probes of the BDF, batched). A
variant whose own inputs have no jump there restarts anyway: a cost, not an
error.

A discrete mode that switches (a snapping valve, a hysteretic actuator) is
located and restarted from per variant as the BDF does for one network (the
step retried to end just past the secant crossing of the switching
functions, then order 1 from the new mode): each variant snaps at its own
time, and only the variants that switch pay for the restart.

What this covers: scenes of library components in rate form, isothermal or
thermal (a heat-transfer correlation's h A frozen at each variant's own
step start, as the BDF freezes it), run with the adaptive BDF. Others (user
components, fixed steps, check valves: the variants' Newton here does not
refresh a Jacobian where a valve changes pieces, as
:meth:`softflow.solve.newton.Newton.solve` does) keep the shared step
sequence (:func:`reason_not` says why). A variant whose step fails (Newton
down to ``step_min``) is reported failed here and run again on its own by the caller, where its result says why; an
iterate that leaves a fluid's range sends the whole batch back to the shared
steps, which find the variant responsible.

Results: each variant's points are its own accepted steps; the batch's
Result holds them padded to the longest (a variant's last point repeated)
and :attr:`instance_times` gives each component its variant's times, which
the model validity checks read (:func:`softflow.solve.validity.group_times`).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..fluids.base import FluidError
from .bdf import (_ERR, _G, CHATTER_STEP, CHATTER_SWITCHES, FAIL_HOLD, FIRST_ESTIMATE, GROW_MIN,
                  MAX_FACTOR, MIN_FACTOR, PEAK_FACTOR, SAFETY, SECANT_TRIES, SWITCH_PAST,
                  _rescale_matrix, newton_limits)
from .blocklu import BlockLU, Factors, PlanError
from .discretize import linearizable
from .integrator import breakpoints_within, breaks_inside
from .linalg import make_linear_solver
from .newton import CRDOWN, Newton, Stats, gauge_offsets
from .variants import Layout, checked
from .variants import Unsupported as _Unsupported

#: Newton on the batch: chord iterations, at most NEWTON_MAX on fresh factors.
#: Dense blocks get fresh factors at every pass: one Jacobian evaluation of the
#: batch costs about one residual evaluation, and factoring 1 000 6 x 6 blocks
#: ~0.05 ms (blocklu; LAPACK's inversions took ~0.7 ms), where factors kept
#: across passes (as Newton keeps its LU across steps, serially) make most
#: passes iterate on until some variants find them too old and refresh them at
#: their iterate anyway (1 000
#: source-tube-tank variants: 359 residual evaluations and 174 factorizations
#: of the batch when kept, 244 and 133 fresh, ~10 % less time). The batch's
#: sparse factors (variants of more than DENSE_BLOCK_MAX unknowns) are kept
#: while every variant's step coefficient stays within NEWTON_REUSE of the one
#: they were made for (and for at most NEWTON_MAX_AGE passes), with at most
#: NEWTON_REUSE_ITER iterations on kept factors, then fresh ones at the iterate
NEWTON_MAX = 7
#: a variant whose chord iterations fail on fresh factors goes on as
#: Newton.solve's full stage goes on: a fresh Jacobian at every iterate (not
#: damped), for at most this many iterations (Newton's max_iter * 2), before
#: its step is rejected (1 000 source-tube-tank variants: the most attempts
#: any variant makes, which sets the number of passes, 76 -> 71). Unlike
#: BDF (FULL_STAGE_STEPS), at any step: this engine refactors its dense blocks
#: at every pass, and cutting the step instead took it from 36 to 57 steps on
#: an adiabatic tank behind a 2 mm tube (its own run: 28)
NEWTON_FULL_STAGE = 2 * NEWTON_MAX
#: iterations of a full Newton solve (fresh Jacobian at every iterate: the
#: consistent point at t = 0 and the restart probes, from a point across a jump)
NEWTON_FULL_MAX = 20
#: variants of up to this many unknowns solve by their dense blocks (factored
#: all at once by blocklu's planned elimination, LAPACK's inverse for a block
#: it does not serve); larger ones by the batch's sparse factors
DENSE_BLOCK_MAX = 24
NEWTON_REUSE_ITER = 4
NEWTON_REUSE = (0.6, 1.67)
NEWTON_MAX_AGE = 50
#: Row orders the planned elimination of the dense blocks may choose anew
#: (blocklu), where most variants factored have left the last one's bound
REPLANS_MAX = 3


class Unsupported(_Unsupported):
    """The batch cannot run on own clocks (see :func:`reason_not`)."""


# -- per-variant reductions -------------------------------------------------------------
# A (K, m) array is variant-major: a reduction along its rows (axis 1) makes
# NumPy loop over K rows of m entries each, ~40 us for 1 000 x 6; the same
# reduction on its transposed copy runs along contiguous columns, ~6 us
# (copy included). Passes of a 1 000-variant sweep make ~2 000 of them.
def _row_max(a):
    """Largest entry of each row of ``a`` (K, m); 0.0 where m is 0."""
    return np.ascontiguousarray(a.T).max(axis=0, initial=0.0)


def _row_sum_squares(a):
    """Sum of squares of each row of ``a`` (K, m)."""
    return np.einsum("ij,ij->i", a, a)


def _row_any(a):
    """Whether each row of the boolean ``a`` (K, m) has a True entry."""
    return np.ascontiguousarray(a.T).any(axis=0)


def reason_not(sim):
    """Why the compiled batch ``sim`` cannot run on own clocks, or None."""
    asm = sim.asm
    if not sim.adaptive:
        return "fixed steps (step=) share one grid"
    if sim.refine > 1:
        return "refine= records points inside each step on the one-network BDF only"
    from ..components.base import LibraryComponent
    for g in asm.groups:
        c0 = g.comps[0]
        if g.row is not None or not isinstance(c0, LibraryComponent):
            return f"{c0.describe()} is not a library component"
        if g.regime is not None:
            # Newton.solve keeps a Jacobian only while such a law stays on its
            # piece; the variants' own Newton here does not check it
            return (f"{c0.describe()} has a piecewise law whose pieces Newton checks "
                    "(regime) on the one-network BDF only")
        cls = c0.kernel_class()
        if not linearizable(cls):
            return f"{c0.describe()} writes its own step equations"
        # each instance's own time reaches the library's residuals (only the
        # sources read it, through their signal values); a user's residual may
        # read t as one number
        if not cls.residual.__func__.__module__.startswith("softflow."):
            return f"{c0.describe()} has a residual of its own"
    return None


@functools.lru_cache(maxsize=None)
def _rescale_polynomials(kmax):
    """C (kmax + 1, kmax + 1, kmax, kmax): the rescaling matrix of order k for a
    factor f is sum_p C[k, p] f^p (its entries are polynomials of degree <= k
    in f), padded with the identity past row and column k, so that one
    product rescales variants of every order. Found from the matrices at
    kmax + 1 factors (a Vandermonde solve, exact for those degrees)."""
    f = np.linspace(0.5, 2.0, kmax + 1)
    V = np.vander(f, kmax + 1, increasing=True)           # V[i, p] = f_i^p
    C = np.zeros((kmax + 1, kmax + 1, kmax, kmax))
    for k in range(1, kmax + 1):
        M = np.zeros((kmax + 1, kmax, kmax))
        M[:] = np.eye(kmax)
        M[:, :k, :k] = [_rescale_matrix(k, float(fi))[1:, 1:] for fi in f]
        C[k] = np.linalg.solve(V, M.reshape(kmax + 1, -1)).reshape(kmax + 1, kmax, kmax)
    C.setflags(write=False)
    return C


def _source(idx, var, local, kept):
    """For batch columns ``idx`` (of variants ``var``, places ``local``): their
    place in the flattened (K, kept) rows each variant keeps."""
    pos = np.searchsorted(kept, local[idx])
    if (kept[np.minimum(pos, kept.size - 1)] != local[idx]).any():
        raise Unsupported("the variants record different columns")
    return var[idx] * kept.size + pos


class VariantBDF:
    """The BDF of :class:`softflow.solve.bdf.BDF`, one clock per variant (module
    docstring). ``run()`` returns each variant's points (:meth:`_collect`) and
    leaves ``failed`` (variant -> reason), ``steps`` and ``rejected`` (per
    variant) and ``stats`` (the batch's Newton work)."""

    def __init__(self, sim, K):
        asm = self.asm = sim.asm
        self.K = K
        self.lay = Layout(asm, K)
        lay = self.lay
        self.T = sim.duration
        self.rtol = sim.rtol
        self.step_min, self.step_max = sim.step_min, sim.step_max
        self.kmax = sim.max_order
        self.first_step = sim.step      # adaptive runs: the first step, if given
        self.max_steps = sim.max_steps
        self.stats = Stats()
        # small variants: each one's dense block factored, all in one pass
        self.dense = lay.nx <= DENSE_BLOCK_MAX
        self._lin_kind = sim.linear_solver_kind
        self._lin = None
        self._inv = np.zeros((K, lay.nx, lay.nx)) if self.dense else None
        # the dense blocks by one planned sparse elimination (blocklu), LAPACK's
        # inverse for the variants it does not serve (self._fb)
        self._blu = None
        if self.dense:
            local = lay.block_pos % (lay.nx * lay.nx)
            self._blu = BlockLU(local // lay.nx, local % lay.nx, lay.nx)
            self._blu_f = None
            self._fb = np.zeros(K, dtype=bool)
            self._replans = 0
        # tolerances, variant-major (every variant has the same)
        atol_s = np.broadcast_to(sim._atol_vector(asm.s_quantity), (len(asm.S0),))
        atol_x = np.broadcast_to(sim._atol_vector(asm.x_quantity), (asm.n,))
        self.atol_s = lay.s_to_v(np.asarray(atol_s, dtype=float))
        # discrete states (a valve's or an actuator's mode) are left out of the
        # error test; each variant's are the same columns
        disc = lay.s_to_v(asm.s_discrete)
        if disc.size and (disc != disc[0]).any():
            raise Unsupported("the variants' modes are ordered differently")
        self.disc_cols = np.flatnonzero(disc[0]) if disc.size else np.zeros(0, dtype=np.int64)
        self.cont = (None if not self.disc_cols.size
                     else np.flatnonzero(~disc[0]))
        self.atol_s_c = self.atol_s if self.cont is None else self.atol_s[:, self.cont]
        self._sw_var = None        # the variant of each switching function's entry
        self.atol_x = lay.to_v(np.asarray(atol_x, dtype=float))
        self.newton_atol = 1e-3 * self.atol_x
        # as Simulation's Newton in an adaptive run: rtol / 20, pressures by their
        # gauge magnitude, the run's magnitudes a floor, the first update bound
        self.newton_rtol = sim._newton_rtol()
        self._floor_factor, self._first_max = newton_limits(sim.rtol, self.newton_rtol)
        names = sorted(set(lay.x_quantity))
        self.qid = np.array([names.index(q) for q in lay.x_quantity], dtype=np.int64)
        q_cols = [np.flatnonzero(self.qid == q) for q in range(len(names))]
        self._q_order = np.concatenate(q_cols)
        self._q_starts = np.cumsum([0] + [c.size for c in q_cols[:-1]])
        self.offset = gauge_offsets(lay.x_quantity)
        # absolute node pressures (the first n_across unknowns) must stay positive
        across = lay.xperm[:lay.nx] < asm.n_across
        self.p_cols = np.flatnonzero((np.array(lay.x_quantity, dtype=object) == "pressure")
                                     & across)
        # the error test's unknowns (as BDF's): the node across unknowns, a slice
        # where they come first (they do, in variant order, as in the System's)
        xe = np.flatnonzero(across)
        self.x_err = (slice(0, xe.size) if np.array_equal(xe, np.arange(xe.size))
                      else xe)
        self._qmax_run = None
        # the breakpoints of every variant: one barrier list
        breaks = set(float(b) for b in sim.breakpoints)
        for c in asm.where:
            comp = asm.where[c][0].comps[asm.where[c][1]]
            breaks.update(float(b) for b in breakpoints_within(comp, self.T))
        self.breaks = breaks_inside(breaks, self.T)
        # per group: what the kernels need, with each instance's variant
        self._plan = [(g, lay.inst[id(g)]) + tuple(p[1:]) for g, p in
                      zip(asm.groups, asm._plan)]
        self._update_plan = [(g.update, g.col, g.s0, g.s1, (g.n, g.ns), lay.inst[id(g)])
                             for g in asm.groups if g.has_states]
        # what is kept of each point: every unknown and state, or those of the
        # components Simulation(record=...) names (the same in every variant)
        self._keep = self._kept(sim.record)
        self.forced_steps = 0
        self.order_counts = np.zeros(self.kmax + 1, dtype=np.int64)
        self.steps = np.zeros(K, dtype=np.int64)
        self.rejected = np.zeros(K, dtype=np.int64)
        self.failed = {}
        self._lu_c = np.full(K, np.nan)     # each variant's c its factors were made for
        self._lu_age = np.zeros(K, dtype=np.int64)
        self.eta = np.ones(K)      # each variant's last Newton rate / (1 - rate)
        self._crate = np.ones(K)   # each variant's damped rate on its factors (CRDOWN)
        self.progress = None       # a softflow.solve.progress.Progress, or None

    @property
    def lin(self):
        """The batch's sparse linear solver (made where it is used)."""
        if self._lin is None:
            self._lin = make_linear_solver(self.asm, self._lin_kind)
        return self._lin

    # -- the batch's equations, each instance at its variant's time and step -----------
    def _residual(self, x, S, tv, cv, jac):
        asm = self.asm
        self.stats.residual_evaluations += 1
        F = np.empty(asm.n)
        nr = asm.n_node_rows
        if nr:
            F[:nr] = np.bincount(asm.through_rows, weights=x[asm.through_cols], minlength=nr)
        raw = asm.raw
        for (g, iv, kernel, col, s0, s1, s_shape, no_states, r0, r1, j0, j1) in self._plan:
            try:
                Fg, Jg = kernel(x[col], S[s0:s1].reshape(s_shape) if no_states is None
                                else no_states, tv[iv], cv[iv][:, None], jac)
            except FluidError as err:
                # which variant's iterate left the fluid's range is not known here:
                # the batch goes back to the shared steps, which isolate it
                raise Unsupported(f"an iterate left a fluid's range ({err})") from None
            F[r0:r1] = Fg.ravel()
            if jac and j1 > j0:
                raw[j0:j1] = Jg.ravel()
        return F

    def _update(self, x, S, cv):
        out = S.copy()
        for update, col, s0, s1, s_shape, iv in self._update_plan:
            try:
                new = update(x[col], S[s0:s1].reshape(s_shape), cv[iv][:, None])
            except FluidError as err:
                raise Unsupported(f"a state left a fluid's range ({err})") from None
            out[s0:s1] = new.ravel()
        return out

    # -- norms, per variant -----------------------------------------------------------
    def _weights(self, Sa, Sb, Xv, ids=None):
        """Error weights (continuous states', unknowns') of each variant for a step
        from Sa to Sb (as BDF._weights), which updates the run's largest values.
        ``ids``: the rows given are those variants' (the largest values read,
        not updated)."""
        c = self.cont
        if c is not None:
            Sa, Sb = Sa[:, c], Sb[:, c]
        atol_s, atol_x, run = self.atol_s_c, self.atol_x, self._qmax_run
        if ids is not None:
            atol_s, atol_x = atol_s[ids], atol_x[ids]
            run = None if run is None else run[ids]
        wS = atol_s + self.rtol * np.maximum(np.abs(Sa), np.abs(Sb))
        v = np.abs(Xv - self.offset)
        qmax = self._quantity_max(v)
        if run is not None:
            qmax = np.maximum(qmax, run)
        if ids is None:
            self._qmax_run = qmax
        return wS, atol_x + self.rtol * qmax[:, self.qid]

    def _quantity_max(self, v):
        """(K, quantities): each variant's largest entry of ``v`` (K, nx, not
        negative) per quantity (as Assembly.quantity_max for one network)."""
        # the columns grouped by quantity, then one reduction per group
        return np.maximum.reduceat(v.T[self._q_order], self._q_starts, axis=0).T

    def _norms(self, dS, dX, w, every=False):
        """Each variant's weighted RMS of (dS, dX) (continuous states only; of
        dX the error test's columns, ``every``: all), or its largest weighted
        entry over PEAK_FACTOR where that is larger (as BDF._norm)."""
        if self.cont is not None:
            dS = dS[:, self.cont]
        if every:
            e, ex = dS / w[0], dX / w[1]
        else:
            xe = self.x_err
            e, ex = dS / w[0], dX[:, xe] / w[1][:, xe]
        size = e.shape[1] + ex.shape[1]
        if not size:
            return np.zeros(len(e))
        rms = np.sqrt((_row_sum_squares(e) + _row_sum_squares(ex)) / size)
        peak = np.maximum(_row_max(np.abs(e)), _row_max(np.abs(ex)))
        return np.maximum(rms, peak / PEAK_FACTOR)

    # -- Newton on the batch ------------------------------------------------------------
    def _newton(self, x0, S, tv, cv, live, tight=False, full=False):
        """Solve the step equations of the variants ``live`` (the others are held:
        zero step, their own point). Returns (x, converged per variant).

        Chord iterations as :class:`softflow.solve.newton.Newton` makes them,
        each variant judged on its own: the update's largest entry over its
        tolerance, and the Hairer-Wanner test on the contraction rate (the
        rate seen in earlier solves for a first update). Each variant keeps its
        factors while its step coefficient stays within NEWTON_REUSE of the one
        they were made for (sparse factors, all variants together; dense
        blocks are factored afresh at every call, see NEWTON_MAX). A variant
        that diverges or converges too slowly on reused factors gets fresh
        ones at its iterate; on fresh factors, it goes on as
        :meth:`Newton.solve`'s full stage goes on (a fresh Jacobian at every
        iterate, from its iterate where the chord iterations contracted, else
        from its start, for NEWTON_FULL_STAGE iterations, not damped), and
        fails only where that fails. ``full``: a fresh Jacobian at every
        iterate, converged where the update is within the tolerance (the
        consistent point at t = 0);
        ``tight``: that, held to 1e-12 (the restart probes)."""
        lay, K = self.lay, self.K
        rtol = min(self.newton_rtol, 1e-12) if tight else self.newton_rtol
        full = full or tight
        X0 = lay.to_v(x0)
        qmax = self._quantity_max(np.abs(X0 - self.offset))
        if self._qmax_run is not None:
            qmax = np.maximum(qmax, self._floor_factor * self._qmax_run)
        itol = 1.0 / (self.newton_atol + rtol * qmax[:, self.qid])
        x = x0.copy()
        conv = ~live
        bad = np.zeros(K, dtype=bool)
        fresh = live.copy() if (full or self.dense) else self._stale(cv, live)
        F = self._residual(x, S, tv, cv, bool(fresh.any()))
        if fresh.any():
            bad |= self._factor(cv, fresh, start=bool((fresh == live).all())) & live
        eta = self.eta
        prev = np.full(K, np.nan)
        limit = np.where(fresh, NEWTON_FULL_MAX if full else NEWTON_MAX, NEWTON_REUSE_ITER)
        it = np.zeros(K, dtype=np.int64)     # iterations on each one's current factors
        Xv = X0.copy()                       # the iterates, variant-major
        rperm, dense = lay.rperm, self.dense
        # the variants in the full stage (a fresh Jacobian at every iterate)
        stage = None if full else np.zeros(K, dtype=bool)
        for _ in range(NEWTON_FULL_MAX if full
                       else NEWTON_MAX + NEWTON_REUSE_ITER + NEWTON_FULL_STAGE):
            self.stats.newton_iterations += 1
            Fv = F[rperm].reshape(K, -1)
            if not np.isfinite(F).all():
                finite = ~_row_any(~np.isfinite(Fv))
                bad |= ~finite & ~conv
                Fv[~finite] = 0.0
                F[~np.isfinite(F)] = 0.0
            if dense:
                dXv = self._block_solve(Fv)
            else:
                dXv = lay.to_v(self.lin.solve(F))
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                nrm = _row_max(np.abs(dXv * itol))
                nrm[~np.isfinite(nrm)] = np.inf
                first = np.isnan(prev)
                rate = nrm / prev
                new_eta = rate / (1.0 - rate)
                if full:
                    done = nrm <= 1.0
                    trouble = np.isinf(nrm)
                else:
                    predicted = (nrm <= self._first_max) & (nrm * np.maximum(eta, 1e-3) ** 0.8
                                                            <= 1.0)
                    # the damped rate of Newton.CRDOWN (not for a first update)
                    crate = np.where(first, self._crate,
                                     np.maximum(rate, CRDOWN * self._crate))
                    done = np.where(first, (nrm <= 1.0) | predicted, nrm * crate <= 1.0 - crate)
                    diverge = rate >= 0.9                # (False where first: NaN)
                    slow = ~done & ~diverge & (
                        nrm * rate ** np.maximum(limit - 1 - it, 0) / (1.0 - rate) > 1.0)
                    trouble = diverge | slow | np.isinf(nrm)
                    if stage.any():
                        done = np.where(stage, nrm <= 1.0, done)
                        trouble = np.where(stage, np.isinf(nrm), trouble)
            move = ~conv & ~bad
            step_ok = move & ~trouble
            # the contraction seen (full solves too, as Newton keeps it)
            keep_eta = step_ok & ~first & (rate < 1.0)
            if stage is not None:
                keep_eta &= ~stage
            eta[keep_eta] = new_eta[keep_eta]
            if not full:
                self._crate[keep_eta] = crate[keep_eta]
            if step_ok.all():
                Xv -= dXv
            else:
                Xv -= np.where(step_ok[:, None], dXv, 0.0)
            conv = conv | (step_ok & done)
            prev = np.where(step_ok, nrm, prev)
            it += move
            trouble = move & (trouble | (~conv & (it >= limit)))
            refresh = (live & ~conv & ~bad) if full else None
            if stage is not None and stage.any():
                refresh = stage & ~conv & ~trouble
            if trouble.any():
                if full:
                    bad |= trouble & fresh
                else:
                    # failed on fresh factors: the full stage, from the iterate
                    # where the chord iterations contracted, else from the start
                    enter = trouble & fresh & ~stage
                    bad |= trouble & fresh & ~enter
                    if enter.any():
                        back = enter & (~(prev < np.inf) | (rate >= 1.0))
                        Xv[back] = X0[back]
                        stage |= enter
                        limit[enter], it[enter], prev[enter] = NEWTON_FULL_STAGE, 0, np.nan
                        refresh = enter if refresh is None else refresh | enter
                again = trouble & ~fresh        # fresh factors at the iterate
                fresh |= again
                refresh = again if refresh is None else refresh | again
                limit[again], it[again], prev[again] = NEWTON_MAX, 0, np.nan
            if (conv | bad).all():
                break
            lay.from_v(Xv, x)
            jac = refresh is not None and bool(refresh.any())
            F = self._residual(x, S, tv, cv, jac)
            if jac:
                bad |= self._factor(cv, refresh) & live
        lay.from_v(Xv, x)
        # absolute pressures stay positive
        if self.p_cols.size:
            conv &= ~(_row_any(Xv[:, self.p_cols] <= 0.0) & live)
        conv &= ~bad | ~live
        self._lu_c[live & ~conv] = np.nan      # fresh factors for the retries
        return x, conv

    def _stale(self, cv, live):
        """The variants among ``live`` whose factors do not serve their step
        coefficient now: the batch's sparse factors, all of them where one
        does not (dense blocks are factored at every pass, see NEWTON_MAX)."""
        lo, hi = NEWTON_REUSE
        ref = self._lu_c
        with np.errstate(invalid="ignore"):
            ok = (cv >= lo * ref) & (cv <= hi * ref) & (self._lu_age < NEWTON_MAX_AGE)
        stale = live & ~ok
        return live.copy() if stale.any() else stale

    def _factor(self, cv, which, start=False):
        """Factors of the Jacobian just evaluated (asm.raw) for the variants
        ``which`` (dense blocks) or all (sparse). Returns the variants whose
        block is singular (all of them where the sparse factors fail).
        ``start``: ``which`` are all the variants Newton is solving (the
        pass's first factors), so the dense blocks' planned elimination may
        choose its row order anew (:meth:`_block_factor`)."""
        K = self.K
        singular = np.zeros(K, dtype=bool)
        self.stats.factorizations += 1
        self.stats.jacobian_evaluations += 1
        if self.dense:
            ids = np.flatnonzero(which)
            inverse = self._block_factor(ids, start)
            if inverse.size:
                J = self._dense_blocks()
                try:
                    self._inv[inverse] = np.linalg.inv(J[inverse])
                except np.linalg.LinAlgError:
                    for v in inverse:          # find the singular ones
                        try:
                            self._inv[v] = np.linalg.inv(J[v])
                        except np.linalg.LinAlgError:
                            singular[v] = True
            done = which & ~singular
        else:
            try:
                self.lin.factor()
            except (RuntimeError, ValueError, np.linalg.LinAlgError):
                self._lu_c[:] = np.nan
                return np.ones(K, dtype=bool)
            done = np.ones(K, dtype=bool)
        self._lu_c[done] = cv[done]
        self._lu_age[done] = 0
        self._crate[done] = 1.0
        self._lu_c[singular] = np.nan
        return singular

    def _dense_blocks(self):
        """Each variant's dense block (K, nx, nx) of the Jacobian just evaluated."""
        K, nx = self.K, self.lay.nx
        return np.bincount(self.lay.block_pos, weights=self.asm.raw,
                           minlength=K * nx * nx).reshape(K, nx, nx)

    def _block_factor(self, ids, start):
        """Factor the dense blocks of the variants ``ids`` by the planned
        elimination (:class:`~softflow.solve.blocklu.BlockLU`); returns the
        variants it does not serve (a pivot that threshold pivoting refuses, or
        a plan that failed), which LAPACK's inverse then serves. The row order
        is chosen on the first block factored; where more than half of the
        blocks of a pass's first factors (``start``: the factors of every
        variant in use) leave it, it is chosen anew on one of them (at most
        REPLANS_MAX times; the factors of the variants not in use are then
        void, and made at their next pass)."""
        blu = self._blu
        if blu is None or not ids.size:
            return ids
        if blu.perm is None:
            if not self._plan_blocks(self._dense_blocks()[ids[0]]):
                return ids
        f, ok = blu.factor_values(self._block_values()[:, ids])
        if (start and not ok.all() and (~ok).sum() > 0.5 * ids.size
                and self._replans < REPLANS_MAX):
            # the row order no longer suits most of them: another, from one of them
            self._replans += 1
            self._blu_f = None
            if not self._plan_blocks(self._dense_blocks()[ids[np.argmin(ok)]]):
                return ids
            f, ok = blu.factor_values(self._block_values()[:, ids])
        if self._blu_f is None:
            self._blu_f = Factors.empty(blu, self.K)
        blu.take(self._blu_f, ids, f)
        self._fb[ids] = ~ok
        return ids[~ok]

    def _block_values(self):
        """The planned elimination's entries of every variant's block (entries,
        K), summed from the Jacobian's raw entries in one pass."""
        n_src = self._blu.source.size
        return np.bincount(self._blu_index, weights=self.asm.raw,
                           minlength=n_src * self.K).reshape(n_src, self.K)

    def _plan_blocks(self, A):
        """Plan the dense blocks' elimination on the block ``A``, and where each
        raw Jacobian entry goes among its values; on failure LAPACK's inverses
        from here on."""
        try:
            self._blu.plan(A)
        except PlanError:
            self._blu = None
            self._fb[:] = True
            return False
        nn = self.lay.nx * self.lay.nx
        slot_at = np.full(nn, -1, dtype=np.int64)
        slot_at[self._blu.source] = np.arange(self._blu.source.size)
        pos = self.lay.block_pos
        self._blu_index = slot_at[pos % nn] * self.K + pos // nn
        return True

    def _block_solve(self, Fv):
        """Each variant's Newton update from its dense block's factors."""
        if self._blu is None:
            return self._inverse_solve(Fv)
        dXv = self._blu.solve(self._blu_f, Fv)
        fb = self._fb
        if fb.any():
            dXv[fb] = self._inverse_solve(Fv[fb], fb)
        return dXv

    def _inverse_solve(self, Fv, which=None):
        """The Newton updates from LAPACK's inverses (all variants, or ``which``)."""
        # np.einsum's loop, not np.matmul: that calls BLAS's gemv once per
        # variant (~200 instructions of call and zeroing each)
        inv = self._inv if which is None else self._inv[which]
        return np.einsum("vij,vj->vi", inv, Fv)

    # -- the difference tables --------------------------------------------------------
    def _rescale(self, ids, factors):
        """Re-interpolate the tables of the variants ``ids`` for their steps times
        ``factors`` (rows 1..k of each, k its order), in one product."""
        keep = factors != 1.0
        ids, factors = ids[keep], factors[keep]
        if not ids.size:
            return
        kmax = self.kmax
        powers = factors[:, None] ** np.arange(kmax + 1)
        C = _rescale_polynomials(kmax)[self.k[ids]]
        # batched products (np.matmul) where np.einsum's loops were ~4x slower
        M = np.matmul(powers[:, None, :], C.reshape(ids.size, kmax + 1, -1)).reshape(
            ids.size, kmax, kmax)
        D = self.D
        rows = D[1:kmax + 1, ids].transpose(1, 0, 2)          # (v, kmax, m)
        D[1:kmax + 1, ids] = np.matmul(M, rows).transpose(1, 0, 2)

    def _difference_update(self, ids, delta):
        """The tables of the variants ``ids`` after their accepted steps (the
        corrections ``delta``), as BDF's: each row i <= k of a variant's table
        gains row i + 1, from the highest down. In place, the rows of the
        other variants left out by ``where=`` (a gather and scatter of the
        variants' tables took ~6x as long: 0.87 against 0.15 ms for 1 000)."""
        D = self.D
        kk = self.k[ids]
        D[kk + 2, ids] = delta - D[kk + 1, ids]
        D[kk + 1, ids] = delta
        k_of = np.full(self.K, -1, dtype=np.int64)
        k_of[ids] = kk
        for i in range(self.kmax, -1, -1):
            np.add(D[i], D[i + 1], out=D[i], where=(i <= k_of)[:, None])

    # -- restarts -----------------------------------------------------------------------
    def _probe(self, ids, x, S, Xv_from, hv):
        """Backward Euler over hv from each variant's point (states S, unknowns
        starting at Xv_from) for the variants ``ids``, Newton held tight; the
        others held. (x_h batch, rate (K, ns), converged)."""
        lay, K = self.lay, self.K
        live = np.zeros(K, dtype=bool)
        live[ids] = True
        cv = np.where(live, hv, 0.0)
        tv = self.t + cv
        x0 = lay.from_v(np.where(live[:, None], Xv_from, self.Xv), x.copy())
        xh, conv = self._newton(x0, S, tv, cv, live, tight=True)
        Sh = lay.s_to_v(self._update(xh, S, cv))
        with np.errstate(all="ignore"):
            r = (Sh - self.Sv) / np.where(live, hv, 1.0)[:, None]
        r[:, self.disc_cols] = 0.0          # a mode has no rate
        return xh, r, conv & live | ~live

    def _restart(self, ids, x, S):
        """Order 1 and a first step for the variants ``ids`` at their points (as
        BDF._restart, batched); False for a variant whose probe failed."""
        lay = self.lay
        T = self.T
        span_all = self._limit()[0] - self.t
        hp = np.full(self.K, 0.0)
        hp[ids] = np.minimum(max(self.step_min, 1e-7 * T), 0.25 * span_all[ids])
        x1, r0, ok1 = self._probe(ids, x, S, self.Xv, hp)
        X1 = lay.to_v(x1)
        x2, _, ok2 = self._probe(ids, x, S, X1, 2 * hp)
        X2 = lay.to_v(x2)
        ok = ok1 & ok2
        with np.errstate(all="ignore"):
            xdot = (X2 - X1) / np.where(hp > 0, hp, 1.0)[:, None]
        x_right = X1 - hp[:, None] * xdot
        Sv = self.Sv
        w = self._weights(Sv, Sv, x_right)
        d0 = self._norms(Sv, x_right, w)
        d1 = self._norms(r0, xdot, w)
        with np.errstate(all="ignore"):
            h0 = np.where((d0 < 1e-5) | (d1 < 1e-5), 1e-6 * span_all, 0.01 * d0 / d1)
        h0 = np.minimum(np.minimum(np.maximum(h0, 4 * hp), span_all), self.step_max)
        if self.first_step is not None:
            h = np.maximum(np.minimum(self.first_step, span_all), self.step_min)
        else:
            x3, r3, ok3 = self._probe(ids, x, S, x_right, h0)
            X3 = lay.to_v(x3)
            with np.errstate(all="ignore"):
                ddx = 2 * (X3 - x_right - h0[:, None] * xdot) / (h0 ** 2)[:, None]
                d2 = self._norms((r3 - r0) / h0[:, None], ddx, w)
                h1 = np.where(d2 > 1e-15, np.sqrt(2 * FIRST_ESTIMATE / d2),
                              np.maximum(1e-6 * span_all, 1e3 * h0))
            h = np.where(ok3, np.minimum(100 * h0, h1), 0.1 * h0)
            h = np.maximum(np.minimum(np.minimum(h, span_all), self.step_max), self.step_min)
        D = self.D
        D[:, ids] = 0.0
        ns, nx = lay.ns, lay.nx
        D[0, ids, :ns] = Sv[ids]
        D[1, ids, :ns] = h[ids, None] * r0[ids]
        D[0, ids, ns:ns + nx] = x_right[ids]
        D[1, ids, ns:ns + nx] = h[ids, None] * xdot[ids]
        D[0, ids, ns + nx:] = self.Qv[ids]
        D[1, ids, ns + nx:] = h[ids, None] * x_right[ids]
        self.h[ids] = h[ids]
        self.k[ids] = 1
        self.n_equal[ids] = 0
        self.fails[ids] = 0
        self.fail_cap[ids] = math.inf
        self.fail_hold[ids] = 0
        self.h_cap[ids] = math.inf
        self.cap_hold[ids] = 0
        self._lu_c[ids] = np.nan
        return ok[ids]

    def _limit(self):
        """(where each variant's step may end at most: its next breakpoint or the
        end, that next breakpoint or inf)."""
        if not self.breaks:
            return np.full(self.K, self.T), np.full(self.K, math.inf)
        b = np.asarray(self.breaks + [math.inf])
        i = np.searchsorted(b, self.t * (1 + 1e-14) + 1e-300, side="right")
        nxt = b[i]
        return np.where(nxt < self.T, nxt, self.T), nxt

    # -- the loop -----------------------------------------------------------------------
    def run(self):
        asm, lay, K = self.asm, self.lay, self.K
        kmax = self.kmax
        x, S = self._initial()
        ns, nx = lay.ns, lay.nx
        self.Xv, self.Sv = lay.to_v(x), lay.s_to_v(S)
        self.Qv = np.zeros((K, nx))
        self.t = np.zeros(K)
        self.h = np.zeros(K)
        self.k = np.ones(K, dtype=np.int64)
        self.n_equal = np.zeros(K, dtype=np.int64)
        self.fails = np.zeros(K, dtype=np.int64)
        self.chatter = np.zeros(K, dtype=np.int64)     # as BDF._chatter, per variant
        self.fail_cap = np.full(K, math.inf)
        self.fail_hold = np.zeros(K, dtype=np.int64)
        # while a mode switch is being located (as BDF)
        self.h_cap = np.full(K, math.inf)
        self.smallest = np.zeros(K, dtype=bool)   # the step tried is the smallest
        self.cap_hold = np.zeros(K, dtype=np.int64)
        self.secant_tries = np.zeros(K, dtype=np.int64)
        self.D = np.zeros((kmax + 3, K, ns + 2 * nx))
        done = np.zeros(K, dtype=bool)
        waiting = np.zeros(K, dtype=bool)
        tried = np.zeros(K, dtype=np.int64)
        kx, ks = self._keep
        rec = [(np.arange(K), self.t.copy(), self.Xv[:, kx], self.Sv[:, ks], self.Qv[:, kx])]
        iS, iX, iQ = slice(0, ns), slice(ns, ns + nx), slice(ns + nx, None)
        ar = np.arange(K)
        pred_rows = np.zeros((kmax + 1, 2, kmax + 1))
        for kk in range(1, kmax + 1):
            pred_rows[kk, 0, :kk + 1] = 1.0
            pred_rows[kk, 1, :kk + 1] = np.r_[1.0, 1.0 - _G[1:kk + 1] / _G[kk]]
        t_stop = self.T * (1 - 1e-14)
        smin = self.step_min * 1.0000001

        def fail(ids, why):
            for v in ids:
                self.failed[int(v)] = why
            done[ids] = True

        # per-step coefficients (heat-transfer correlations) frozen at the point
        # where each variant's step starts, as BDF freezes them
        begin = asm.begin_step if asm.has_begin_step else None
        if begin is not None:
            begin(x, S)
        ok = self._restart(ar, x, S)
        fail(ar[~ok], "the restart probes at t = 0 failed")
        while True:
            live = ~done & ~waiting
            if not live.any():
                if not waiting.any():
                    break
                ids = np.flatnonzero(waiting)
                waiting[:] = False
                x = lay.from_v(self.Xv, x)
                S = lay.s_from_v(self.Sv, S)
                ok = self._restart(ids, x, S)
                fail(ids[~ok], "a restart at a breakpoint failed")
                continue
            lim, nxt = self._limit()
            # step sizes: no overshoot of the limit, no sliver left before it
            h = self.h
            h_try = np.minimum(np.minimum(np.minimum(h, self.step_max), self.fail_cap),
                               self.h_cap)
            short = (self.t + h_try >= lim) | (lim - (self.t + h_try) < 0.2 * h_try)
            # the smallest step, step_min stretched over a sliver included (BDF._propose)
            smallest = h_try <= smin
            h_try = np.where(short, lim - self.t, h_try)
            self.smallest = smallest = smallest | (h_try <= smin)
            change = live & (h_try != h)
            if change.any():
                ids = np.flatnonzero(change)
                self._rescale(ids, h_try[ids] / h[ids])
                h[ids] = h_try[ids]
                self.n_equal[ids] = 0
            # a step aimed at the limit lands on it exactly
            land = live & short
            t_new = np.where(land, lim, np.where(live, self.t + h, self.t))
            at_break = land & (lim == nxt)
            coef = pred_rows[self.k]
            # the predictor and psi of each variant: (2, K, m); a batched product
            # (np.einsum's loop took ~4x as long: 263 against 69 us for 1 000)
            pp = np.matmul(coef, self.D[:kmax + 1].transpose(1, 0, 2)).transpose(1, 0, 2)
            pred, psi_all = pp[0], pp[1]
            S_pred, X_pred = pred[:, iS], pred[:, iX]
            psi = np.where(live[:, None], psi_all[:, iS], self.Sv)
            x_pred = np.where(live[:, None], X_pred, self.Xv)
            cv = np.where(live, h / _G[self.k], 0.0)
            tv = np.where(at_break, np.nextafter(t_new, -np.inf), t_new)
            tried += live
            if self.max_steps is not None and (tried > self.max_steps).any():
                over = np.flatnonzero(live & (tried > self.max_steps))
                fail(over, f"more than max_steps = {self.max_steps} steps")
                continue
            S_b = lay.s_from_v(psi, S.copy())
            x_new, conv = self._newton(lay.from_v(x_pred, x.copy()), S_b, tv, cv, live)
            self._lu_age += 1
            # Newton failures: a quarter of the step, down to step_min
            nf = live & ~conv
            if nf.any():
                ids = np.flatnonzero(nf)
                self.rejected[ids] += 1
                self.stats.rejected_steps += ids.size
                gone = ids[smallest[ids]]
                fail(gone, "Newton failed at the smallest step")
                ids = ids[~smallest[ids]]
                factor = np.maximum(0.25, self.step_min / h[ids])
                self._rescale(ids, factor)
                h[ids] *= factor
                self.n_equal[ids] = 0
            ok = live & conv
            if not ok.any():
                continue
            S_new_b = self._update(x_new, S_b, cv)
            S_new, X_new = lay.s_to_v(S_new_b), lay.to_v(x_new)
            d, dx = S_new - S_pred, X_new - X_pred
            w = self._weights(self.Sv, S_new, X_new)
            err = _ERR[self.k] * self._norms(d, dx, w)
            big = ok & (err > 1.0)
            efail = big & ~smallest
            self.forced_steps += int((big & ~efail).sum())
            if efail.any():
                ids = np.flatnonzero(efail)
                self.rejected[ids] += 1
                self.stats.rejected_steps += ids.size
                self.stats.error_test_failures += ids.size
                self.fails[ids] += 1
                self.fail_cap[ids] = 0.9 * h[ids]
                self.fail_hold[ids] = FAIL_HOLD
                kk = self.k[ids]
                factor = np.maximum(MIN_FACTOR,
                                    SAFETY * (2 * err[ids] + 1e-4) ** (-1.0 / (kk + 1)))
                f = self.fails[ids]
                factor = np.where(f == 2, np.minimum(factor, 0.25), factor)
                factor = np.where(f >= 3, 0.25, factor)
                drop = ids[(f >= 3) & (kk > 1)]
                if drop.size:
                    self.D[2:, drop] = 0.0
                    self.k[drop] = 1
                factor = np.maximum(factor, self.step_min / h[ids])
                self._rescale(ids, factor)
                h[ids] *= factor
                self.n_equal[ids] = 0
            acc = ok & ~efail
            switched = None
            if self.disc_cols.size and acc.any():
                switched = acc & _row_any(S_new[:, self.disc_cols]
                                          != self.Sv[:, self.disc_cols])
                if switched.any():
                    acc &= ~self._locate(switched, x, S, x_new, S_new_b, S_new, X_new, w, h)
                    switched &= acc
                self.secant_tries[acc] = 0
            if not acc.any():
                continue
            ids = np.flatnonzero(acc)
            self.fails[ids] = 0
            held = ids[self.fail_hold[ids] > 0]
            self.fail_hold[held] -= 1
            self.fail_cap[held[self.fail_hold[held] == 0]] = math.inf
            held = ids[self.cap_hold[ids] > 0]      # the switch did not come back
            self.cap_hold[held] -= 1
            self.h_cap[held[self.cap_hold[held] == 0]] = math.inf
            self.steps[ids] += 1
            np.add.at(self.order_counts, self.k[ids], 1)
            c_ids = cv[ids]
            Q_new = psi_all[ids, iQ] + c_ids[:, None] * X_new[ids]
            delta = np.concatenate([d[ids], dx[ids], Q_new - pred[ids, iQ]], axis=1)
            self._difference_update(ids, delta)
            self.Xv[ids], self.Sv[ids], self.Qv[ids] = X_new[ids], S_new[ids], Q_new
            self.t[ids] = t_new[ids]
            rec.append((ids, self.t[ids].copy(), X_new[ids][:, kx], S_new[ids][:, ks],
                        Q_new[:, kx]))
            x = lay.from_v(self.Xv, x)
            S = lay.s_from_v(self.Sv, S)
            if begin is not None:
                begin(x, S)
            # a mode that chatters (as BDF): its variant fails, and runs alone,
            # where its result says so
            swi = (switched[ids] if switched is not None else np.zeros(ids.size, dtype=bool)) \
                & (h[ids] <= CHATTER_STEP * self.step_min)
            self.chatter[ids] = np.where(swi, self.chatter[ids] + 1, 0)
            fail(ids[self.chatter[ids] >= CHATTER_SWITCHES], "its mode chatters")
            fin = ids[self.t[ids] >= t_stop]
            done[fin] = True
            brk = ids[at_break[ids] & ~done[ids]]
            waiting[brk] = True
            self._lu_c[brk] = np.nan
            if switched is not None:        # a mode switched: order 1 from the new mode
                sw = ids[switched[ids] & ~done[ids] & ~waiting[ids]]
                if sw.size:
                    ok_sw = self._restart(sw, x, S)
                    fail(sw[~ok_sw], "a restart after a mode switch failed")
                    done[sw[~ok_sw]] = True
                    ids = ids[~np.isin(ids, sw)]
            go = ids[~done[ids] & ~waiting[ids]]
            self.n_equal[go] += 1
            if self.progress is not None and not done.all():
                self.progress.step(float(self.t[~done].min()))
            sel = go[self.n_equal[go] >= self.k[go] + 1]
            if sel.size:
                self._choose(sel, err)
        self._rec = rec
        return self._collect()

    def _locate(self, switched, x, S, x_new, S_new_b, S_new, X_new, w, h):
        """The variants among ``switched`` (a mode switched at the end of their
        step) whose step is rejected to place the switch (as BDF: the step
        retried to end just past the secant crossing of the switching functions,
        or bisected where there is none, until the part past the switch moves
        the solution by no more than the tolerance); their steps are cut."""
        locate = switched & ~self.smallest
        if not locate.any():
            return np.zeros(self.K, dtype=bool)
        motion = self._norms(S_new - self.Sv, X_new - self.Xv, w, every=True)
        theta = self._crossings(x, S, x_new, S_new_b)
        secant = locate & (motion > 1.0) & (self.secant_tries < SECANT_TRIES) & np.isfinite(theta)
        past = np.where(secant, 1.0 - theta, 1.0)
        rej = locate & (motion * past > 1.0)
        if not rej.any():
            return rej
        ids = np.flatnonzero(rej)
        self.rejected[ids] += 1
        self.stats.rejected_steps += ids.size
        sec = secant[ids]
        self.secant_tries[ids[sec]] += 1
        with np.errstate(all="ignore"):
            part = np.minimum(SWITCH_PAST, 0.5 / np.maximum(motion[ids] * theta[ids], 1.0))
            factor = np.where(sec, np.maximum(theta[ids] * (1.0 + part), self.step_min / h[ids]),
                              np.maximum(0.5, self.step_min / h[ids]))
        bis = ids[~sec]
        self.h_cap[bis] = h[bis] * factor[~sec]
        self.cap_hold[bis] = FAIL_HOLD
        self._rescale(ids, factor)
        h[ids] *= factor
        self.n_equal[ids] = 0
        return rej

    def _crossings(self, x, S, x_new, S_new_b):
        """Each variant's first crossing of a switching function over its step,
        as a fraction of the step (a secant between the ends, the end with the
        old modes), or NaN (none, or none in (0, 1])."""
        asm = self.asm
        g0 = asm.switching(x, S)
        out = np.full(self.K, np.nan)
        if g0 is None:
            return out
        if self._sw_var is None:
            parts = []
            for g in asm.groups:
                if g.switching is not None:
                    m = np.asarray(g.switching(x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns))).size
                    parts.append(np.repeat(self.lay.inst[id(g)], m // g.n))
            self._sw_var = np.concatenate(parts)
        old = S_new_b.copy()
        old[asm.s_discrete] = S[asm.s_discrete]
        g1 = asm.switching(x_new, old)
        with np.errstate(all="ignore"):
            cross = (g0 < 0.0) & (g1 >= 0.0)
            th = np.where(cross, g0 / (g0 - g1), np.inf)
        first = np.full(self.K, np.inf)
        np.minimum.at(first, self._sw_var, th)
        ok = (first > 0.0) & (first <= 1.0)
        out[ok] = first[ok]
        return out

    def _initial(self):
        """The consistent point at t = 0 of every variant (zero step), by Newton
        on the variants' blocks, else by :class:`softflow.solve.newton.Newton` on
        the batch (which damps its steps)."""
        asm, K = self.asm, self.K
        S = asm.S0.copy()
        zero = np.zeros(K)
        self.t = zero
        x, conv = self._newton(asm.x0.copy(), S, zero, zero, np.ones(K, dtype=bool), full=True)
        if conv.all():
            return x, S
        atol = self.lay.from_v(1e-3 * self.atol_x, np.empty(asm.n))
        newton = Newton(asm, self.lin, self.stats, rtol=self.newton_rtol, atol=atol)
        out = newton.solve(asm.x0.copy(), S, 0.0, 0.0)
        if not out.converged:
            raise Unsupported("no consistent point at t = 0 for the batch")
        self._lu_c[:] = np.nan
        return out.x.copy(), S

    def _choose(self, ids, err):
        """Order and next step of the variants ``ids`` after k + 1 steps at one step
        size: estimates at k - 1, k and k + 1 (as BDF)."""
        lay = self.lay
        ns, nx = lay.ns, lay.nx
        kmax = self.kmax
        D, k = self.D, self.k[ids]
        Sv = self.Sv[ids]
        w = self._weights(Sv, Sv, self.Xv[ids], ids)
        err_k = np.maximum(err[ids], 1e-16)
        cands = np.full((3, ids.size), -np.inf)     # orders k + 1, k, k - 1
        cands[1] = SAFETY * err_k ** (-1.0 / (k + 1))
        lo = k > 1
        if lo.any():
            row = D[k, ids]
            e_lo = np.maximum(_ERR[np.maximum(k - 1, 0)] * self._norms(row[:, :ns],
                                                                       row[:, ns:ns + nx], w),
                              1e-16)
            cands[2] = np.where(lo, SAFETY * e_lo ** (-1.0 / np.maximum(k, 1)), -np.inf)
        hi = k < kmax
        if hi.any():
            row = D[np.minimum(k + 2, kmax + 2), ids]
            e_hi = np.maximum(_ERR[np.minimum(k + 1, kmax + 1)]
                              * self._norms(row[:, :ns], row[:, ns:ns + nx], w), 1e-16)
            cands[0] = np.where(hi, SAFETY * e_hi ** (-1.0 / (k + 2)), -np.inf)
        best = np.argmax(cands, axis=0)       # ties: the higher order
        factor = np.minimum(MAX_FACTOR, cands[best, np.arange(ids.size)])
        k_new = k + 1 - best
        small = (factor >= 1.0) & (factor < GROW_MIN)
        stay = small & (k_new == k)
        factor = np.where(small, 1.0, factor)
        go = ~stay
        ids, k_new, factor = ids[go], k_new[go], np.maximum(MIN_FACTOR, factor[go])
        self.k[ids] = k_new
        self._rescale(ids, factor)
        self.h[ids] *= factor
        self.n_equal[ids] = 0

    # -- the results ----------------------------------------------------------------------
    def _collect(self):
        """(times (M, K), X (M, n), S (M, ns), Q (M, n), points per variant): each
        variant's points in the batch layout, padded with its last point."""
        K = self.K
        ids = np.concatenate([r[0] for r in self._rec])
        t = np.concatenate([r[1] for r in self._rec])
        X = np.concatenate([r[2] for r in self._rec])
        S = np.concatenate([r[3] for r in self._rec])
        Q = np.concatenate([r[4] for r in self._rec])
        order = np.argsort(ids, kind="stable")
        counts = np.bincount(ids, minlength=K)
        M = int(counts.max())
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        j = np.arange(M)[:, None]
        rows = order[starts[None, :] + np.minimum(j, counts[None, :] - 1)]     # (M, K)
        times = t[rows]
        # padded points follow the last one by a hair: the checks' time
        # derivatives see no change there (not a division by zero)
        pad = j >= counts[None, :]
        times = np.where(pad, times + (j - counts[None, :] + 1) * 1e-12 * self.T, times)
        # the batch's columns (all, or the recorded ones in Simulation's order)
        # from each variant's kept ones
        gx, gs = self._gather
        Xb = X[rows].reshape(M, -1)[:, gx]
        Sb = S[rows].reshape(M, -1)[:, gs]
        Qb = Q[rows].reshape(M, -1)[:, gx]
        return times, Xb, Sb, Qb, counts

    def _kept(self, record):
        """(unknowns, states) each variant keeps of a point (variant-local
        columns), and, in ``_gather``, where each column of the batch's result
        comes from in the (K, kept) rows flattened."""
        lay = self.lay
        if record is None:
            xi, si = np.arange(self.asm.n), np.arange(len(self.asm.S0))
        else:
            xi, si = np.asarray(record[0]), np.asarray(record[1])
        kx, ks = np.unique(lay.x_local[xi]), np.unique(lay.s_local[si])
        self._gather = (_source(xi, lay.x_var, lay.x_local, kx),
                        _source(si, lay.s_var, lay.s_local, ks))
        return kx, ks


def run(sim, K, progress=None):
    """Run the compiled batch ``sim`` of K variants on own clocks.

    ``progress``: a bar in simulated time, at the slowest variant's clock
    (as ``Simulation.run(progress=)``).

    Returns (result, counts, times, steps, failed): the batch's Result (each
    variant's points padded to the longest, its validity checked on each
    variant's own times), the number of points of each variant, their times
    (M, K), accepted and rejected steps per variant, and {variant: reason}
    of the variants whose run failed. Raises :class:`Unsupported` where the
    batch cannot run so (:func:`reason_not`)."""
    from .result import Result
    why = reason_not(sim)
    if why is not None:
        raise Unsupported(why)
    from .progress import Progress
    integ = VariantBDF(sim, K)
    # the bar follows the slowest clock
    integ.progress = Progress(sim.duration, progress)
    with np.errstate(all="ignore"), integ.progress:
        times, X, S, Q, counts = integ.run()
    info = integ.stats.as_dict()
    info.update(method=sim.method, rtol=sim.rtol, unknowns=sim.asm.n, clocks="own",
                forced_steps=integ.forced_steps,
                linear_solver="dense blocks" if integ.dense else integ.lin.kind,
                order_steps=integ.order_counts.tolist())
    result = Result(sim.asm, times[:, 0], X, S, stats=info, recorded=sim.record, integrals=Q)
    failed = dict(integ.failed)
    checked(result, sim, integ.lay.inst, times, failed)
    return result, counts, times, (integ.steps, integ.rejected), failed
