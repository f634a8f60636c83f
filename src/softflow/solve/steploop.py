"""The steppers' usual steps taken by the compiled loop (issue 38, third
step): :func:`softflow.laws.stepper.stretch` for the adaptive BDF and
:func:`softflow.laws.stepper.fixed_stretch` for backward Euler at fixed
steps, called from the integration loop (:meth:`Integrator.run
<softflow.solve.integrator.Integrator.run>`) through the stepper's
``_stretch_for``.

Which runs: a network the compiled residual covers
(:mod:`softflow.solve.netcore`), solved by the dense LU (up to
:data:`softflow.solve.linalg.DENSE_MAX` unknowns; its factors shared with
the Python Newton's) or by the loop's own banded LU where the Jacobian
orders as a band (:func:`band_layout`; beyond DENSE_MAX, or narrower than a
quarter of the matrix: :func:`_banded`; user components, sources given
as Python functions and the h A a heat-transfer correlation sets at each
step's start (``begin_step``, at the top of each pass of the loop) called
back, :mod:`softflow.solve.usercall`, unless ``settings.COMPILED_USER`` is
off), without sensitivities or independent sub-networks (batched
variants). Every other run, and every step the loop hands back
(:data:`softflow.laws.stepper.EXITS`: a failed solve whose reason the
BDF's Newton reports itself (a residual not finite, a law's refusal, a
singular Jacobian, a pressure <= 0) or that the culprit finder would look
into (its worst equation in the region of a node without volume that
carries a flow source: :meth:`CompiledSteps.run` has the finder find those
nodes at the run's first failure, and the loop try that step again), a
failure at the smallest step (a fold's jump,
continuation), forced steps, a mode switch logged in detail or at the
smallest steps (where it may chatter), a second fresh chord that fails
after a solution on another piece of a piecewise law than the Jacobian's,
emptied volumes, restarts whose probes fail), is the stepper's own in
Python, from the state the loop leaves. The loop takes restarts, steps to
breakpoints and the end itself, steps across a law's kink (a check valve
that shuts or opens: on at order 1, the step read as a straight line, as
BDF._take takes it), solutions on another piece than the Jacobian's (the
fresh chord after reused factors, once more from there after fresh ones,
as Newton.solve does), Newton's full stages
(undamped after slow chord iterations, damped near the smallest step and in
restart probes) and the rejection of a step whose solve fails otherwise
(a quarter of the step, as BDF._newton_failed). Backward Euler's steps
hand back every failed solve (its Newton's damped stages then take it).

The consistent start's solve from the initial values is one compiled call
too, :func:`softflow.laws.stepper.start_solve` through :func:`start_solver`,
where the dense LU serves the run, no component may impose a flow and no
node has a temperature (the Python solve takes it elsewhere, and where that
call does not converge).

:data:`softflow.solve.settings.COMPILED_STEPS` turns the loop off (the
benchmarks compare both), :data:`~softflow.solve.settings.COMPILED_START` the
compiled start.
"""
from __future__ import annotations

import math

import numpy as np

from .._laws import law_module
from . import settings
from .dense import expected_rows
from .usercall import PENDING, raise_pending


class _Bound:
    """What both loops share: the network's arrays, Newton's tolerances and
    factors in and out, the record buffers, the counters."""

    def __init__(self, integ, net, sources, atol_s, x_off, q_sel, nq):
        st = self.st = law_module("stepper")
        self.integ = integ
        asm, newton = integ.asm, integ.newton
        n, ns = asm.n, asm.S0.size
        self.net, self.sources = net, sources
        # the Python Newton's dense factors are shared with the loop's (each
        # adopts the other's); a banded or sparse Jacobian is the loop's own
        sparse = _sparse(asm, newton)
        band = _banded(asm, newton) if sparse is None else None
        self.band, self.sparse = band, sparse
        self.own = band is not None or sparse is not None
        lu_shape = None
        no_int, no_float = np.zeros(0, dtype=np.int64), np.zeros(0)
        sp_int, sp_float = (no_int,) * 12, (no_float,) * 7
        info = np.zeros(st.LIN_INFO_SIZE, dtype=np.int64)
        if band is not None:
            flat, shape, order = band.flat, (n, band.width), band.order
            info[st.KIND], info[st.KL] = st.BANDED, band.kl
        elif sparse is not None:
            flat, shape, lu_shape = sparse.flat, (1, sparse.Ai.size), (1, 1)
            info[st.KIND], order = st.SPARSE, np.zeros((3, n), np.int64)
            room, nnz = sparse.room, sparse.Ai.size
            sp_int = (sparse.Ap, sparse.Ai, sparse.Q, np.zeros(n + 1, dtype=np.int64),
                      np.zeros(room, dtype=np.int64), np.zeros(n + 1, dtype=np.int64),
                      np.zeros(room, dtype=np.int64), np.zeros(n, dtype=np.int64),
                      np.zeros(n, dtype=np.int64), np.zeros(nnz, dtype=np.int64),
                      np.zeros(4 * n, dtype=np.int64), np.zeros(4, dtype=np.int64))
            sp_float = (np.zeros(room), np.zeros(room), np.zeros(n), np.zeros(n),
                        np.zeros(nnz), np.zeros(n),
                        np.array([settings.COMPILED_SPARSE_REFACTOR]))
        else:
            flat, shape, order = asm.dense_index(), (n, n), np.zeros((3, n), dtype=np.int64)
        self.lin = _lin_tuple(net, asm, flat, shape, lu_shape, info, order, sp_int, sp_float)
        # (a banded or sparse LU is compiled on its own: its addresses)
        _far_addresses(st, self.lin)
        self.tol = _tol_tuple(integ, newton, atol_s, x_off, q_sel)
        watch = integ._watch
        self.watch = ((np.zeros(0, dtype=np.int64), np.zeros(0)) if watch is None else
                      (np.ascontiguousarray(watch.index, dtype=np.int64),
                       np.ascontiguousarray(watch.floor, dtype=float)))
        rec = integ.rec
        self.x_index = (np.arange(n, dtype=np.int64) if rec._x_all
                        else np.asarray(rec.x_index, dtype=np.int64))
        self.s_index = (np.arange(ns, dtype=np.int64) if rec._s_all
                        else np.asarray(rec.s_index, dtype=np.int64))
        cap = self.cap = record_rows(1 + self.x_index.size + self.s_index.size + nq
                                     + self._dense_floats(integ))
        self.buffers = (np.empty(cap), np.empty((cap, self.x_index.size)),
                        np.empty((cap, self.s_index.size)), np.empty((cap, nq)))
        self.ist = np.zeros(st.IST_SIZE, dtype=np.int64)
        self.fst = np.zeros(st.FST_SIZE)
        self.stats = np.zeros(st.STATS_SIZE, dtype=np.int64)
        self.floor = np.zeros(len(asm.q_names))
        self.breaks = np.asarray(integ.breaks, dtype=float)
        _newton_settings(st, self.ist, self.fst, newton, asm.n, atol_s)
        self.fst[st.DURATION] = integ.T
        self.begin = None
        if asm.has_begin_step:
            # h A set at each step's start (a heat-transfer correlation),
            # called back from the loop (softflow.solve.usercall)
            from . import usercall
            self.begin = usercall.Begin(asm, asm.residual.network.refresh)
            self.ist[st.BEGIN_KEY] = usercall.register(self.begin)
            self.ist[st.BEGIN_AT] = usercall.ADDRESS

    def _dense_floats(self, integ):
        """The dense output's floats a recorded step takes in the loop's
        buffers (none at fixed steps)."""
        return 0

    def _newton_in(self):
        """Newton's factors, contraction estimates and tolerance floor in."""
        st, integ = self.st, self.integ
        newton, ist, fst = integ.newton, self.ist, self.fst
        ist[st.N_REC] = ist[st.N_DENSE] = ist[st.N_EVENTS] = ist[st.FACTORED] = 0
        ist[st.IB], fst[st.NEXT_BREAK] = integ._ib, integ._next
        stats = integ.stats
        # the steps left to max_steps, or before the progress bar's next look
        ist[st.BUDGET_LEFT] = min(integ.max_steps - stats.steps - stats.rejected_steps
                                  if integ.max_steps is not None else 1 << 62,
                                  integ.progress.steps_to_look())
        _estimates_in(st, ist, fst, self.floor, newton)
        lin = newton.lin
        r_fact = self.lin[7]
        pieces = newton._jac_regime
        if (not self.own and not newton.stale and newton.lu_dt is not None
                and lin.lu is not None and (not r_fact.size or pieces is not None)):
            LU, piv, ir, ic = self.lin[3:7]
            if r_fact.size:
                r_fact[:] = np.frombuffer(pieces, dtype=np.int8)
            LU[:] = lin.lu[0]
            piv[:LU.shape[0]] = lin.lu[1]
            self.st.lu_profile(LU, piv)         # (the loop's solves keep to it)
            if lin.scales is None:
                ir[:] = 1.0
                ic[:] = 1.0
            else:
                ir[:], ic[:] = lin.scales
            fst[st.LU_DT], fst[st.DT_LO], fst[st.DT_HI] = newton.lu_dt, newton._dt_lo, newton._dt_hi
            ist[st.AGE], ist[st.STALE] = newton.age, 0
        else:
            ist[st.STALE] = 1
            fst[st.DT_LO], fst[st.DT_HI] = 1.0, -1.0
        self.stats[:] = 0

    def _newton_out(self):
        """The counters, the breakpoint pointer and Newton's state out."""
        st, integ = self.st, self.integ
        newton, ist, fst, s = integ.newton, self.ist, self.fst, self.stats
        integ._ib, integ._next = int(ist[st.IB]), float(fst[st.NEXT_BREAK])
        stats = integ.stats
        if s[st.STEPS]:
            stats.residuals_at_last_step = (stats.residual_evaluations
                                             + int(s[st.RESIDUALS_AT_STEP]))
        stats.steps += int(s[st.STEPS])
        stats.rejected_steps += int(s[st.REJECTED])
        stats.error_test_failures += int(s[st.ERROR_FAILS])
        _solve_counts_out(st, s, stats)
        stats.newton_failures += int(s[st.NEWTON_FAILS])
        if s[st.STEPS]:
            integ._chatter = 0
            integ._approached = False
            integ._empty_tries = 0
        newton.eta, newton._crate = float(fst[st.ETA]), float(fst[st.CRATE])
        newton._one_iteration = bool(ist[st.ONE_ITER])
        if ist[st.HAS_FLOOR]:
            floor = self.floor.copy()
            newton.scale_floor = floor.tolist() if newton._small else floor
        if self.own:
            # (the Python Newton's own factors, older than the loop's steps)
            newton.stale = True
            return
        if ist[st.FACTORED] and not ist[st.STALE]:
            J, LU, piv, ir, ic = self.lin[2:7]
            newton.lin.adopt(J, LU, piv[:LU.shape[0]], ir, ic)
            if self.lin[7].size:
                newton._jac_regime = self.lin[7].astype(np.int8).tobytes()
        if ist[st.STALE]:
            newton.stale = True
        else:
            newton.stale = False
            newton.age = int(ist[st.AGE])
            newton.lu_dt = float(fst[st.LU_DT])
            newton._dt_lo, newton._dt_hi = float(fst[st.DT_LO]), float(fst[st.DT_HI])

    def _records_out(self, t, Q=True):
        """The steps' points into the run's recorder; how many."""
        taken = int(self.ist[self.st.N_REC])
        if taken:
            bt, bx, bs, bq = self.buffers
            rec = self.integ.rec
            rec.extend(bt[:taken], bx[:taken], bs[:taken], bq[:taken] if Q else None,
                       expected_rows(len(rec.t) + taken, t, self.integ.T))
            self.integ.progress.advance(t, taken)
        return taken


class CompiledSteps(_Bound):
    """The compiled loop bound to one BDF run: the arrays it works in, made
    once, and the copies of the BDF's and Newton's state in and out."""

    def _dense_floats(self, bdf):
        """Up to the largest order's rows of the step's differences."""
        dense = bdf.dense
        return bdf.max_order * (dense.width if dense.cols is None else dense.cols.size)

    def __init__(self, bdf, net, sources):
        n = bdf.asm.n
        q_sel = np.arange(n) if isinstance(bdf._q_sel, slice) else bdf._q_sel
        super().__init__(bdf, net, sources, bdf._atol_s, bdf._x_offset, q_sel, bdf._Q.size)
        st, ist, fst = self.st, self.ist, self.fst
        self.bdf = bdf
        dense = bdf.dense
        self.d_cols = (np.arange(dense.width, dtype=np.int64) if dense.cols is None
                       else dense.cols)
        kmax, cap = bdf.max_order, self.cap
        self.dbuf = (np.empty(cap), np.empty(cap), np.empty(cap, dtype=np.int64),
                     np.empty(cap, dtype=np.int64), np.empty((cap * kmax, self.d_cols.size)))
        self.events = np.empty((settings.COMPILED_EVENT_ROWS, 4))
        from . import bdf as bdf_mod
        self.G, self.ERRC = bdf_mod._G, bdf_mod._ERR
        ist[st.MAX_ORDER] = kmax
        ist[st.HOLD_STEPS] = bdf_mod.FAIL_HOLD
        ist[st.M_ERR] = bdf._m_err
        fst[st.RTOL] = bdf.rtol
        fst[st.FLOOR_FACTOR] = bdf._floor_factor
        fst[st.STEP_MIN], fst[st.STEP_MAX] = bdf.step_min, bdf.step_max
        fst[st.SAFETY], fst[st.MIN_FACTOR] = bdf_mod.SAFETY, bdf_mod.MIN_FACTOR
        fst[st.MAX_FACTOR], fst[st.GROW_MIN] = bdf_mod.MAX_FACTOR, bdf_mod.GROW_MIN
        fst[st.PEAK_FACTOR] = bdf_mod.PEAK_FACTOR
        fst[st.FIRST_STEP] = math.nan if bdf.first_step is None else bdf.first_step
        fst[st.FIRST_ESTIMATE] = bdf_mod.FIRST_ESTIMATE
        fst[st.SWITCH_PAST], fst[st.CHATTER_STEP] = bdf_mod.SWITCH_PAST, bdf_mod.CHATTER_STEP
        ist[st.MAX_SECANT] = bdf_mod.SECANT_TRIES
        fst[st.FULL_STAGE_STEPS] = bdf_mod.FULL_STAGE_STEPS
        ist[st.UNDAMPED] = 1 if bdf.newton.undamped_full else 2

    def state_in(self):
        """The BDF's and Newton's state into the loop's ``ist`` and ``fst``
        (before each :meth:`run`; the batched engine's variants,
        :mod:`softflow.solve.variants`, read a run's first from them)."""
        st, bdf = self.st, self.bdf
        ist, fst = self.ist, self.fst
        self._newton_in()
        self._used = 0
        ist[st.K], ist[st.N_EQUAL], ist[st.FAILS] = bdf._k, bdf._n_equal, bdf._fails
        ist[st.FAIL_HOLD], ist[st.PASSED] = bdf._fail_hold, int(bdf._passed)
        ist[st.RESTART_DUE] = int(bdf._restart_due)
        ist[st.CAP_HOLD], ist[st.SECANT_TRIES] = bdf._cap_hold, bdf._secant_tries
        ist[st.LOG_SWITCHES] = int(getattr(bdf.progress, "_debug", False))
        ist[st.REJECT_NEWTON] = int(_source_rows(bdf.culprit, self.lin[12]))
        ist[st.FAILS_HERE] = 0
        ist[st.PROBE_FAILED] = -1
        fst[st.H], fst[st.FAIL_CAP], fst[st.H_CAP] = bdf._h, bdf._fail_cap, bdf._h_cap
        fst[st.ERR] = getattr(bdf, "_err", 0.0)

    def run(self, t, x, S):
        """Steps from (t, x, S) until the loop hands back (or the run's end):
        (why, t, x, S, steps taken), the point after the steps taken (the
        same where none was)."""
        st, bdf = self.st, self.bdf
        ist, fst = self.ist, self.fst
        self.state_in()
        qmax_run = (np.zeros(self.floor.size) if bdf._qmax_run is None
                    else np.array(bdf._qmax_run, dtype=float))
        x, S, Q = x.copy(), S.copy(), bdf._Q.copy()
        rec = self.buffers + (self.x_index, self.s_index)
        dense = self.dbuf + (self.d_cols,)
        scratch = st.stretch_scratch(x.size, S.size, bdf._D.shape[1], Q.size,
                                     self.lin[11].size)
        taken = 0
        while True:
            ist[st.WANTS_SOURCES] = 0
            exit_, t = st.stretch(float(t), x, S, bdf._D, Q, ist, fst, qmax_run, self.floor,
                                  self.stats, self.net, self.lin, self.sources, self.tol, rec,
                                  dense, self.events, self.watch, self.breaks, self.G,
                                  self.ERRC, scratch)
            taken += self._flush(t, Q)
            if PENDING:       # (the points taken kept: the run's result ends there)
                raise_pending()
            if exit_ in (st.NEWTON, st.RESTART) and ist[st.WANTS_SOURCES]:
                # a failed solve (a step's, or a restart probe's before its
                # damped stage) that only the culprit finder's nodes, not yet
                # found, kept from the loop: found here, from the point the
                # finder would ask (the last taken), and the step or the
                # restart tried again
                ist[st.REJECT_NEWTON] = int(_source_rows(bdf.culprit, self.lin[12],
                                                         (x, S, t)))
                if ist[st.REJECT_NEWTON]:
                    exit_ = st.FULL
            if exit_ != st.FULL:
                break
            # buffers full: emptied into the run's records, and on
            used = int(self.stats[st.STEPS] + self.stats[st.REJECTED])
            ist[st.BUDGET_LEFT] -= used - self._used
            self._used = used
        # the state out
        self._newton_out()
        if exit_ == st.RESTART and 0 <= ist[st.PROBE_FAILED] < 3:
            # (the restart's probe whose solve at 1e-12 failed here; from 3
            # on, one whose chords failed on a flow source's region, which
            # the BDF's probe solves whole, its Newton asking the culprit
            # finder before its damped stage)
            bdf._tight_failed = (float(t), int(ist[st.PROBE_FAILED]))
        bdf._k, bdf._n_equal, bdf._fails = int(ist[st.K]), int(ist[st.N_EQUAL]), int(ist[st.FAILS])
        bdf._fail_hold, bdf._passed = int(ist[st.FAIL_HOLD]), bool(ist[st.PASSED])
        bdf._h, bdf._fail_cap, bdf._err = float(fst[st.H]), float(fst[st.FAIL_CAP]), float(fst[st.ERR])
        bdf._qmax_run = qmax_run
        bdf._restart_due = bool(ist[st.RESTART_DUE])
        bdf._h_cap, bdf._cap_hold = float(fst[st.H_CAP]), int(ist[st.CAP_HOLD])
        bdf._secant_tries = int(ist[st.SECANT_TRIES])
        for k in range(1, bdf.max_order + 1):
            bdf.order_counts[k] += int(self.stats[7 + k])
        return exit_, t, x, S, taken

    def _flush(self, t, Q):
        """The loop's records, dense-output differences and events since the
        last flush into the run's recorder, dense output and progress
        reporter (the buffers emptied): the steps recorded."""
        st, bdf, ist = self.st, self.bdf, self.ist
        r0 = len(bdf.rec.t)
        taken = self._records_out(t)
        if taken:
            dt_, dh, dk, drow, dD = self.dbuf
            dense, rows = bdf.dense, int(ist[st.N_DENSE])
            dense.extend(dt_[:taken], dh[:taken], dk[:taken], drow[:taken] + r0, dD[:rows],
                         expected_rows(dense.rows + rows, t, bdf.T))
            bdf._Q = Q.copy()
        progress = bdf.progress
        for e in range(int(ist[st.N_EVENTS])):
            t_e, h_e, cause, err = self.events[e]
            if cause == st.RESTART_EVENT:
                progress.restarted(float(t_e), float(h_e))
            elif cause == st.SWITCH_EVENT:
                if not err:          # (1: a switch taken, logged only in detail)
                    progress.rejected(float(t_e), float(h_e), "switch")
            elif cause == st.NEWTON_EVENT:
                progress.rejected(float(t_e), float(h_e), "newton")
            else:
                progress.rejected(float(t_e), float(h_e), "error", float(err))
        ist[st.N_REC] = ist[st.N_DENSE] = ist[st.N_EVENTS] = 0
        return taken

    def failed_here(self):
        """The solves the last :meth:`run` rejected (BDF._newton_failed)
        since its last step taken, or the start (0 without a culprit
        finder)."""
        return int(self.ist[self.st.FAILS_HERE]) if self.bdf.culprit is not None else 0


def record_rows(floats_per_row):
    """The rows of the loop's record buffers: as many as
    :data:`~softflow.solve.settings.COMPILED_RECORD_BYTES` hold at
    ``floats_per_row`` floats a row, between
    :data:`~softflow.solve.settings.COMPILED_RECORD_ROWS` and
    :data:`~softflow.solve.settings.COMPILED_RECORD_ROWS_MAX`: a small
    network's run of a few hundred steps in one call of the loop, a large
    network's buffers no larger than before."""
    fit = settings.COMPILED_RECORD_BYTES // (8 * max(int(floats_per_row), 1))
    return int(max(settings.COMPILED_RECORD_ROWS, min(fit, settings.COMPILED_RECORD_ROWS_MAX)))


def _lin_tuple(net, asm, flat, shape, lu_shape, info, order, sp_int, sp_float):
    """softflow.laws.stepper's ``lin`` for the network ``net`` (its arrays) of
    ``asm``: the Jacobian's raw entries' places ``flat`` in J of ``shape``,
    LU of ``lu_shape`` (or the same), the pivots (with a dense LU's profile
    after them: :func:`softflow.laws.stepper.lu_factor`) and scales; the pieces of
    the Jacobian's laws and at a solution; the kinks' sides at the point and
    at a step's end; the switching functions; the culprit finder's rows; the
    kind (``info``), band ``order`` and sparse arrays."""
    network = asm.residual.network
    n, nr, nk = asm.n, network.n_regimes, network.n_kinks
    return (net[0], np.ascontiguousarray(flat, dtype=np.int64),
            np.zeros(shape), np.zeros(lu_shape or shape), np.zeros(3 * n, dtype=np.int64),
            np.ones(n), np.ones(n), np.zeros(nr, dtype=np.int64),
            np.zeros(nr, dtype=np.int64), np.zeros(nk if asm.has_kinks else 0, dtype=np.int64),
            np.zeros(nk if asm.has_kinks else 0, dtype=np.int64),
            np.zeros(network.n_switching),
            np.zeros(n, dtype=np.int64), info, order, np.zeros((2, n)), sp_int, sp_float)


def _tol_tuple(integ, newton, atol_s, x_off, q_sel):
    """softflow.laws.stepper's ``tol``: the states' and unknowns' absolute
    tolerances, the unknowns' offsets and quantities, Newton's tolerances
    and magnitude links, the pressures and temperatures among the unknowns,
    the unknowns integrated."""
    asm = integ.asm
    n = asm.n
    links = np.array([[q, b, f] for q, b, f in newton._links], dtype=float).reshape(-1, 3)
    return (np.ascontiguousarray(atol_s, dtype=float),
            np.ascontiguousarray(getattr(integ, "atol_x", np.zeros(n)), dtype=float),
            np.ascontiguousarray(x_off, dtype=float),
            np.ascontiguousarray(asm.q_id, dtype=np.int64),
            np.ascontiguousarray(np.broadcast_to(newton.atol, (n,)), dtype=float),
            links, np.ascontiguousarray(newton._p_idx, dtype=np.int64),
            np.ascontiguousarray(newton._T_idx, dtype=np.int64),
            np.asarray(q_sel, dtype=np.int64))


def _modes_only(asm):
    """The states' absolute tolerances of a loop without an error test (the
    fixed steps, the start): inf for the discrete states (modes), else 0."""
    atol_s = np.zeros(asm.S0.size)
    if asm.has_discrete:
        atol_s[asm.s_discrete] = math.inf
    return atol_s


def _estimates_in(st, ist, fst, floor, newton):
    """Newton's contraction estimates and its magnitudes' floor into the
    loop's ``ist``, ``fst`` and ``floor``."""
    ist[st.ONE_ITER] = int(newton._one_iteration)
    fst[st.ETA], fst[st.CRATE] = newton.eta, newton._crate
    fst[st.FIRST_MAX] = newton.first_max
    if newton.scale_floor is not None:
        floor[:] = newton.scale_floor
    ist[st.HAS_FLOOR] = int(newton.scale_floor is not None)


def _solve_counts_out(st, counters, stats):
    """The loop's Newton counters (iterations, residuals, Jacobians,
    factorizations) added to the run's ``stats``."""
    stats.newton_iterations += int(counters[st.ITERATIONS])
    stats.residual_evaluations += int(counters[st.RESIDUALS])
    stats.jacobian_evaluations += int(counters[st.JACOBIANS])
    stats.factorizations += int(counters[st.FACTORIZATIONS])


def _newton_settings(st, ist, fst, newton, n, atol_s):
    """Newton's settings into the loop's ``ist`` and ``fst``."""
    from . import linalg
    from . import newton as newton_mod
    ist[st.MAX_REUSE], ist[st.MAX_ITER] = newton.max_reuse_iter, newton.max_iter
    ist[st.MAX_AGE] = newton.max_age
    ist[st.N_DISC] = int(np.count_nonzero(~np.isfinite(atol_s)))
    ist[st.CLIP] = int(newton._T_idx.size > 0)
    # where a failed solve with Newton's full stage goes on to its
    # flows-first stage (thermal networks of up to 256 unknowns,
    # Newton.solve and Newton._flows_first): a restart probe's failed
    # solve at 1e-12 is the BDF's then, not loosened in the loop
    ist[st.FLOWS_FIRST] = int(newton._E_rows.size == newton._T_idx.size > 0 and n <= 256)
    fst[st.NEWTON_RTOL] = newton.rtol
    fst[st.RATIO_LO], fst[st.RATIO_HI] = newton.dt_ratio
    lo, hi = newton._T_range if newton._T_range is not None else (-math.inf, math.inf)
    fst[st.T_LO], fst[st.T_HI] = lo, hi
    fst[st.PIVOT_RTOL], fst[st.CRDOWN] = linalg.PIVOT_RTOL, newton_mod.CRDOWN
    fst[st.KEEP_CUT], fst[st.TIGHT_KEEP_CUT] = (newton_mod.FULL_KEEP_CUT,
                                                newton_mod.TIGHT_KEEP_CUT)
    fst[st.TIGHT_RTOL] = newton_mod.TIGHT_RTOL
    fst[st.FLIP_MATCH] = newton_mod.FLIP_MATCH
    fst[st.LS_MIN], fst[st.LS_GROSS], fst[st.LS_DEEP] = (
        newton_mod.LINE_SEARCH_MIN, newton_mod.LINE_SEARCH_GROSS, newton_mod.LINE_SEARCH_DEEP)
    ist[st.WATCHDOG] = newton_mod.WATCHDOG


class FixedSteps(_Bound):
    """The compiled loop bound to one run of backward Euler at fixed steps
    (:class:`softflow.solve.integrator.ImplicitEuler`)."""

    def __init__(self, euler, net, sources):
        asm = euler.asm
        atol_s = _modes_only(asm)
        # (Newton's magnitudes of absolute values: backward Euler sets no gauge)
        super().__init__(euler, net, sources, atol_s, np.zeros(asm.n),
                         np.zeros(0, dtype=np.int64), 0)
        self.grid = np.array([euler.h0, float(euler.n_grid)])
        self.x_prev = np.zeros(asm.n)

    def run(self, t, x, S):
        """As :meth:`CompiledSteps.run`."""
        st, euler = self.st, self.integ
        ist, fst = self.ist, self.fst
        self._newton_in()
        ist[st.FAILS] = euler.k
        if euler._x_prev is None or not euler._extrapolate:
            fst[st.ERR] = -1.0
        else:
            fst[st.ERR], fst[st.H] = 0.0, euler._h_prev
            self.x_prev[:] = euler._x_prev
        x, S = x.copy(), S.copy()
        rec = self.buffers + (self.x_index, self.s_index)
        scratch = st.fixed_scratch(x.size, S.size)
        taken, used0 = 0, 0
        while True:
            exit_, t = st.fixed_stretch(float(t), x, S, self.x_prev, ist, fst, self.floor,
                                        self.stats, self.net, self.lin, self.sources,
                                        self.tol, rec, self.watch, self.breaks, self.grid,
                                        scratch)
            taken += self._records_out(t, Q=False)
            if PENDING:       # (the points taken kept: the run's result ends there)
                raise_pending()
            ist[st.N_REC] = 0
            if exit_ != st.FULL:
                break
            # the record buffer full: emptied into the run's records, and on
            used = int(self.stats[st.STEPS])
            ist[st.BUDGET_LEFT] -= used - used0
            used0 = used
        self._newton_out()
        euler.k = int(ist[st.FAILS])
        if taken:
            if fst[st.ERR] < 0.0:
                euler._x_prev = None
            else:
                euler._x_prev, euler._h_prev = self.x_prev.copy(), float(fst[st.H])
            euler._extrapolate = True
        return exit_, t, x, S, taken


class BandLayout:
    """A banded order of a network's Jacobian (:func:`band_layout`): ``order``
    (3, n): the band's rows as the Jacobian's rows, its columns as unknowns,
    and each Jacobian row's place in the band; ``kl``, ``ku`` the band's
    widths below and above the diagonal; ``width`` = 2 kl + ku + 1, a band
    row's storage (LAPACK's gbtrf: kl more for the fill of its row swaps);
    ``flat`` each raw entry's place in the flattened (n, width) band."""

    def __init__(self, order, kl, ku, flat):
        self.order, self.kl, self.ku, self.flat = order, kl, ku, flat
        self.width = 2 * kl + ku + 1


def _pattern(asm):
    """(n, rows, cols): the network's unknowns and its Jacobian's raw entries'
    rows and columns (int64)."""
    return (asm.n, np.asarray(asm.pattern_rows, dtype=np.int64),
            np.asarray(asm.pattern_cols, dtype=np.int64))


def band_layout(asm):
    """The Jacobian of a network too large for dense factors, ordered as a
    band (:class:`BandLayout`), or None where its band is wider than
    :data:`softflow.solve.settings.COMPILED_BAND_MAX` (then the Python
    loop, with its sparse or condensed factors, takes the run). Each
    equation is paired with an unknown it has a nonzero slope in (a maximum
    bipartite matching of the pattern: scipy's), and the pairs are ordered
    by reverse Cuthill-McKee on the symmetrized pattern (scipy's): chains
    and trees of components get a band a few unknowns wide. Kept on the
    Assembly (one per network)."""
    got = asm.__dict__.get("_band_layout", False)
    if got is not False:
        return got
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching, reverse_cuthill_mckee
    n, rows, cols = _pattern(asm)
    layout = None
    pattern = csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    match = maximum_bipartite_matching(pattern, perm_type="column")
    if (match >= 0).all():
        pos = np.empty(n, dtype=np.int64)
        pos[match] = np.arange(n)            # unknown -> the row it is paired with
        paired = csr_matrix((np.ones(rows.size), (rows, pos[cols])), shape=(n, n))
        rcm = np.asarray(reverse_cuthill_mckee((paired + paired.T).tocsr(),
                                               symmetric_mode=True), dtype=np.int64)
        place = np.empty(n, dtype=np.int64)
        place[rcm] = np.arange(n)            # row (and its unknown) -> band place
        i, j = place[rows], place[pos[cols]]
        kl, ku = int(max(np.max(i - j), 0)), int(max(np.max(j - i), 0))
        if max(kl, ku) <= settings.COMPILED_BAND_MAX:
            width = 2 * kl + ku + 1
            order = np.stack([rcm, match[rcm], place]).astype(np.int64)
            layout = BandLayout(order, kl, ku, i * width + (j - i + kl))
    asm.__dict__["_band_layout"] = layout
    return layout


class SparseLayout:
    """A network's Jacobian in compressed columns for the loop's sparse LU
    (:mod:`softflow.laws.sparselu`, :func:`sparse_layout`): ``Ap``, ``Ai``
    its columns' starts and rows, ``flat`` each raw entry's place among its
    values, ``Q`` the order its columns are factored in, ``room`` the
    entries L and U may hold each."""

    def __init__(self, Ap, Ai, flat, Q, room):
        self.Ap, self.Ai, self.flat, self.Q, self.room = Ap, Ai, flat, Q, room


def sparse_layout(asm):
    """The :class:`SparseLayout` of a network's Jacobian, or None where its
    pattern is structurally singular. The column order is SuperLU's COLAMD
    (SciPy's splu, on the pattern with random values: the order depends on
    the pattern alone), which keeps the fill of a network's factors small
    (the 2 000-component water network: 9 763 nonzeros, 8 386 entries of L
    and U off their diagonals); the room for L and U is
    :data:`softflow.solve.settings.COMPILED_SPARSE_ROOM` times what SuperLU's
    own factors of that matrix hold (a factorization that needs more hands
    the step back to Python). Kept on the Assembly (one per network)."""
    got = asm.__dict__.get("_sparse_layout", False)
    if got is not False:
        return got
    from scipy.sparse import csc_matrix
    from scipy.sparse.linalg import splu
    n, rows, cols = _pattern(asm)
    places, flat = np.unique(cols * n + rows, return_inverse=True)
    Ai = places % n
    Ap = np.searchsorted(places // n, np.arange(n + 1)).astype(np.int64)
    values = np.random.default_rng(0).uniform(1.0, 2.0, places.size)
    layout = None
    try:
        lu = splu(csc_matrix((values, Ai, Ap), shape=(n, n)), permc_spec="COLAMD")
    except RuntimeError:                 # structurally (or by chance) singular
        pass
    else:
        room = int(settings.COMPILED_SPARSE_ROOM * (lu.L.nnz + lu.U.nnz)) + n
        Q = np.argsort(lu.perm_c).astype(np.int64)    # (L U = Pr A Pc, Pc[i, perm_c[i]] = 1)
        layout = SparseLayout(Ap, Ai.astype(np.int64), flat.astype(np.int64), Q, room)
    asm.__dict__["_sparse_layout"] = layout
    return layout


def _sparse(asm, newton):
    """The :class:`SparseLayout` the loop factors a network's Jacobian in
    where the Python Newton's factors are not dense, or None (off:
    settings.COMPILED_SPARSE; then the band of :func:`_banded` where it is
    narrow enough). Even where the band is narrow the sparse LU is the
    faster: a chain of 1 000 tubes at fixed 1 ms steps (4 002 unknowns, a
    band 3-4 wide) ~97 -> ~76 ms a run (the Python loop ~87 ms), of 128
    tubes 15.4 -> 13.2 ms; the adaptive chain of 200 at rtol 1e-8 ~93 ->
    ~77 ms (fastest of 7; benchmarks/bench_loop_lu.py)."""
    if newton.lin.kind == "dense" or not settings.COMPILED_SPARSE:
        return None
    return sparse_layout(asm)


def _banded(asm, newton):
    """The :class:`BandLayout` the loop factors the network's Jacobian in,
    or None for the dense LU shared with the Python Newton: banded where
    the Python Newton's factors are not dense, and where the band's storage
    is at most a quarter of the dense matrix's
    (:data:`softflow.solve.settings.COMPILED_BAND_SHARE`); not asked below
    :data:`~softflow.solve.settings.COMPILED_BAND_MIN` unknowns."""
    dense = newton.lin.kind == "dense"
    if dense and asm.n < settings.COMPILED_BAND_MIN:
        return None
    band = band_layout(asm)
    if dense and (band is None or settings.COMPILED_BAND_SHARE * band.width > asm.n):
        return None
    return band


def _source_rows(culprit, rows, point=None):
    """Whether the equations the culprit finder (:mod:`softflow.solve.culprit`)
    looks into after a step's failed solve whose reason is not a range's (a
    Newton iteration diverging, too slow) are known, and those equations
    into ``rows`` (:meth:`Finder.region_rows`; ``point``: where to find
    them if not yet known). Known without a finder, or once it has found
    the nodes (:meth:`CompiledSteps.run` asks it at the run's first failed
    solve)."""
    if culprit is None:
        rows[:] = 0
        return True
    return culprit.region_rows(rows, point)


def _served(integ):
    """The compiled network's arrays and sources' description for the run of
    ``integ``, or None where the loop does not serve it (module docstring);
    found once a run (the start's solve and the steps ask alike)."""
    got = _served_or_why(integ)
    return None if isinstance(got, str) else got


def not_served_because(integ):
    """Why the compiled loop does not serve the run of ``integ`` (a phrase
    naming the component or setting), or None where it does."""
    got = _served_or_why(integ)
    return got if isinstance(got, str) else None


def _served_or_why(integ):
    got = integ.__dict__.get("_served_by_loop")
    if got is None:
        got = integ.__dict__["_served_by_loop"] = _find_served(integ)
    return got


#: whether this process has looked for the compiled loop in numba's cache
_CACHE_LOOKED = []


def _compile_notice():
    """Say once, where the compiled loop is not in numba's cache yet (its
    first use after an installation or an upgrade: a compile of a minute or
    two), that it is compiled now and kept (:func:`_say_if_cold`)."""
    _CACHE_LOOKED.append(True)
    st = law_module("stepper")
    _say_if_cold((st.stretch, st.fixed_stretch, st.start_solve),
                 "its step loop", "about 1-2 minutes")


#: whether this process has looked for the banded and sparse LUs in numba's cache
_FAR_LOOKED = []


def _far_addresses(st, lin):
    """:func:`softflow.laws.stepper.far_addresses` for ``lin``, said once a
    process where its banded and sparse LUs are not in numba's cache yet
    (compiled on their own, at the first run that needs them)."""
    if lin[13][st.KIND] != st.DENSE and not _FAR_LOOKED:
        _FAR_LOOKED.append(True)
        _say_if_cold((st.far_factor, st.far_solve, st.far_row_maxima),
                     "the step loop's banded and sparse LUs", "about 15-20 seconds")
    st.far_addresses(lin)


def _say_if_cold(functions, what, how_long):
    """Where any of the compiled ``functions`` is neither compiled in this
    process nor in numba's cache: one INFO line on the ``'softflow'``
    logger, and on standard error where that is a terminal, that softflow
    compiles ``what`` now, once (``how_long``), and keeps it. Reads the
    cache's index files (numba's own, internal: any surprise there and
    nothing is said)."""
    try:
        cold = [f for f in functions
                if not f.overloads and not f._cache._cache_file._load_index()]
    except Exception:          # noqa: BLE001 - numba's internals moved: say nothing
        return
    if not cold:
        return
    import sys

    from .progress import logger
    where = cold[0]._cache._cache_path
    message = (f"softflow: compiling {what} for this installation (once: {how_long}; "
               f"later runs load it from numba's cache in {where})")
    logger.info(message)
    if getattr(sys.stderr, "isatty", lambda: False)():
        print(message, file=sys.stderr, flush=True)


def per_step_coefficients(asm):
    """The phrase naming the first component that sets coefficients at each
    step's start (a heat-transfer correlation's h A), or None."""
    g = next((g for g in asm.groups if g.begin is not None), None)
    return None if g is None else (f"{g.comps[0].describe()} sets coefficients at each step "
                                   "(a heat-transfer correlation's h A)")


def _find_served(integ):
    """:func:`_served`'s answer, found: (arrays, sources), or why not."""
    if not settings.COMPILED_STEPS:
        return "settings.COMPILED_STEPS is off"
    if not _CACHE_LOOKED:
        _compile_notice()
    asm, newton = integ.asm, integ.newton
    net = getattr(asm.residual, "network", None)
    if net is None:
        return "a component the compiled network does not cover"
    if asm.has_begin_step and (not settings.COMPILED_USER or net.refresh is None):
        return per_step_coefficients(asm)
    if integ.sens is not None:
        return "sensitivities"
    if newton is None or newton.offset is not None or not asm.n:
        return "no Newton solve of the loop's kind"
    if (newton.lin.kind != "dense" and _sparse(asm, newton) is None
            and _banded(asm, newton) is None):
        return f"its linear solver ({newton.lin.kind})"
    sources = net.source_arrays()
    if sources is None:
        return ("a source's signal the compiled loop does not evaluate (a Python function, "
                "not a softflow waveform)")
    return law_module("stepper").residual_address(net.arrays), sources


def compiled_steps(bdf):
    """A :class:`CompiledSteps` for the BDF run ``bdf``, or None where the
    compiled loop does not serve it (module docstring)."""
    served = _served(bdf)
    if served is None or bdf._n_blocks > 1:
        return None
    return CompiledSteps(bdf, *served)


def start_solver(integ, lin0):
    """The consistent start's solve from the initial values in one compiled
    call (:func:`softflow.laws.stepper.start_solve`), for
    :meth:`softflow.solve.integrator.Integrator._solve_initial`: a function
    of x0 that returns the solution (a new array, the counters added to the
    run's and Newton's contraction estimates set as its solve sets them),
    or None where the compiled solve did not converge (the Python solve
    takes the start then, from x0). None where it does not serve the run:
    the compiled network's residual, a dense solver of the start's own
    (``lin0``), no node temperatures (the thermal solve's flows-first
    stage), no component that may impose a flow (the culprit finder's
    hooks before the damped stage and the continuation), and
    ``settings.COMPILED_START``."""
    if not settings.COMPILED_START or lin0 is None:
        return None
    setup = start_setup(integ)
    if setup is None:
        return None
    net, sources, lin, tol, ist, fst, floor = setup
    asm, newton = integ.asm, integ.newton
    st = law_module("stepper")
    n, ns = asm.n, asm.S0.size
    counters = np.zeros(st.STATS_SIZE, dtype=np.int64)
    S0 = np.ascontiguousarray(asm.S0, dtype=float)

    def solve(x0):
        x = np.array(x0, dtype=float)
        counters[:] = 0
        code = st.start_solve(x, S0, ist, fst, floor, counters, net, lin, sources, tol,
                              st.fixed_scratch(n, ns))
        if PENDING:
            raise_pending()
        _solve_counts_out(st, counters, integ.stats)
        if code != st.SOLVED:
            return None
        newton.eta, newton._crate = float(fst[st.ETA]), float(fst[st.CRATE])
        newton._one_iteration = bool(ist[st.ONE_ITER])
        return x
    return solve


def start_setup(integ, hooks_aside=False):
    """What :func:`softflow.laws.stepper.start_solve` takes for the run of
    ``integ`` beside the point: (net, sources, lin, tol, ist, fst, floor),
    the dense ``lin`` its own; or None where the compiled start does not
    serve the run (:func:`start_solver`; ``settings.COMPILED_START`` and the
    start's dense solver aside). ``hooks_aside``: set up also where the
    Python solve would ask the culprit finder (a component that may impose
    a flow) or take its flows-first stage (node temperatures), which the
    compiled solve has not: for callers that take a start it does not
    converge elsewhere (the batched variants, :mod:`softflow.solve.variants`:
    such a variant runs alone)."""
    newton = integ.newton
    culprit = getattr(integ, "culprit", None)
    if not hooks_aside and (newton._T_idx.size
                            or (culprit is not None and culprit._may_impose_flow())):
        return None
    served = _served(integ)
    if served is None:
        return None
    net, sources = served
    asm = integ.asm
    st = law_module("stepper")
    n = asm.n
    info, order = np.zeros(st.LIN_INFO_SIZE, dtype=np.int64), np.zeros((3, n), dtype=np.int64)
    no_int, no_float = np.zeros(0, dtype=np.int64), np.zeros(0)
    lin = _lin_tuple(net, asm, asm.dense_index(), (n, n), None, info, order,
                     (no_int,) * 12, (no_float,) * 7)
    atol_s = _modes_only(asm)
    tol = _tol_tuple(integ, newton, atol_s, np.zeros(n), np.zeros(0, dtype=np.int64))
    ist = np.zeros(st.IST_SIZE, dtype=np.int64)
    fst = np.zeros(st.FST_SIZE)
    _newton_settings(st, ist, fst, newton, n, atol_s)
    ist[st.STALE] = 1                 # no factors to reuse: the fresh chord first
    fst[st.DT_LO], fst[st.DT_HI] = 1.0, -1.0
    floor = np.zeros(len(asm.q_names))
    _estimates_in(st, ist, fst, floor, newton)
    return net, sources, lin, tol, ist, fst, floor


def fixed_steps(euler):
    """A :class:`FixedSteps` for the backward Euler run ``euler``, or None."""
    served = _served(euler)
    return None if served is None else FixedSteps(euler, *served)
