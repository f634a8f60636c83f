"""The BDF's usual steps taken by the compiled loop (issue 38, third step):
:func:`softflow.laws.stepper.stretch`, called from :meth:`BDF._stretch
<softflow.solve.bdf.BDF>` at the top of each pass of the integration loop.

Which runs: the adaptive BDF on a network the compiled residual covers
(:mod:`softflow.solve.netcore`), solved by the dense LU, whose sources are
constants or waveforms of the kinds :mod:`softflow.solve.wavecodes`
describes, without laws that change pieces inside Newton's solve (check
valves: ``regimes``, ``kinks``), per-step coefficients (a heat-transfer
correlation's ``begin_step``), sensitivities or independent sub-networks
(batched variants). Every other run, and every step the loop hands back
(:data:`softflow.laws.stepper.EXITS`: the steps to a breakpoint and to the
end, restarts, Newton's damped stages, forced steps, mode switches, emptied
volumes), is the BDF's own in Python, from the state the loop leaves.

:data:`softflow.solve.settings.COMPILED_STEPS` turns the loop off (the
benchmarks compare both).
"""
from __future__ import annotations

import math

import numpy as np

from .._laws import law_module
from . import settings


class CompiledSteps:
    """The compiled loop bound to one BDF run: the arrays it works in, made
    once, and the copies of the BDF's and Newton's state in and out."""

    def __init__(self, bdf, net, sources):
        st = law_module("stepper")
        self.st = st
        self.bdf = bdf
        asm, newton = bdf.asm, bdf.newton
        n, ns = asm.n, asm.S0.size
        self.net = net
        self.sources = sources
        self.lin = (net[0], np.ascontiguousarray(asm.dense_index(), dtype=np.int64),
                    np.zeros((n, n)), np.zeros((n, n)), np.zeros(n, dtype=np.int64),
                    np.ones(n), np.ones(n))
        links = np.array([[q, b, f] for q, b, f in newton._links], dtype=float).reshape(-1, 3)
        q_sel = (np.arange(n, dtype=np.int64) if isinstance(bdf._q_sel, slice)
                 else np.asarray(bdf._q_sel, dtype=np.int64))
        self.tol = (np.ascontiguousarray(bdf._atol_s, dtype=float),
                    np.ascontiguousarray(bdf.atol_x, dtype=float),
                    np.ascontiguousarray(bdf._x_offset, dtype=float),
                    np.ascontiguousarray(asm.q_id, dtype=np.int64),
                    np.ascontiguousarray(np.broadcast_to(newton.atol, (n,)), dtype=float),
                    links, np.ascontiguousarray(newton._p_idx, dtype=np.int64),
                    np.ascontiguousarray(newton._T_idx, dtype=np.int64), q_sel)
        watch = bdf._watch
        self.watch = ((np.zeros(0, dtype=np.int64), np.zeros(0)) if watch is None else
                      (np.ascontiguousarray(watch.index, dtype=np.int64),
                       np.ascontiguousarray(watch.floor, dtype=float)))
        rec = bdf.rec
        self.x_index = (np.arange(n, dtype=np.int64) if rec._x_all
                        else np.asarray(rec.x_index, dtype=np.int64))
        self.s_index = (np.arange(ns, dtype=np.int64) if rec._s_all
                        else np.asarray(rec.s_index, dtype=np.int64))
        dense = bdf.dense
        self.d_cols = (np.arange(dense.width, dtype=np.int64) if dense.cols is None
                       else dense.cols)
        self.cap = settings.COMPILED_RECORD_ROWS
        nq = bdf._Q.size
        kmax = bdf.max_order
        self.buffers = (np.empty(self.cap), np.empty((self.cap, self.x_index.size)),
                        np.empty((self.cap, self.s_index.size)), np.empty((self.cap, nq)))
        self.dbuf = (np.empty(self.cap), np.empty(self.cap), np.empty(self.cap, dtype=np.int64),
                     np.empty(self.cap, dtype=np.int64),
                     np.empty((self.cap * kmax, self.d_cols.size)))
        self.events = np.empty((64, 4))
        self.ist = np.zeros(st.IST_SIZE, dtype=np.int64)
        self.fst = np.zeros(st.FST_SIZE)
        self.stats = np.zeros(st.STATS_SIZE, dtype=np.int64)
        self.floor = np.zeros(len(asm.q_names))
        from .bdf import _ERR, _G
        self.G, self.ERRC = _G, _ERR
        from . import bdf as bdf_mod
        from . import linalg
        from . import newton as newton_mod
        ist, fst = self.ist, self.fst
        ist[st.MAX_ORDER] = kmax
        ist[st.MAX_REUSE], ist[st.MAX_ITER] = newton.max_reuse_iter, newton.max_iter
        ist[st.MAX_AGE] = newton.max_age
        ist[st.HOLD_STEPS] = bdf_mod.FAIL_HOLD
        ist[st.N_DISC], ist[st.M_ERR] = bdf._n_disc, bdf._m_err
        ist[st.CLIP] = int(newton._T_idx.size > 0)
        fst[st.RTOL], fst[st.NEWTON_RTOL] = bdf.rtol, newton.rtol
        fst[st.FLOOR_FACTOR] = bdf._floor_factor
        fst[st.STEP_MIN], fst[st.STEP_MAX] = bdf.step_min, bdf.step_max
        fst[st.RATIO_LO], fst[st.RATIO_HI] = newton.dt_ratio
        lo, hi = newton._T_range if newton._T_range is not None else (-math.inf, math.inf)
        fst[st.T_LO], fst[st.T_HI] = lo, hi
        fst[st.SAFETY], fst[st.MIN_FACTOR] = bdf_mod.SAFETY, bdf_mod.MIN_FACTOR
        fst[st.MAX_FACTOR], fst[st.GROW_MIN] = bdf_mod.MAX_FACTOR, bdf_mod.GROW_MIN
        fst[st.PEAK_FACTOR], fst[st.PIVOT_RTOL] = bdf_mod.PEAK_FACTOR, linalg.PIVOT_RTOL
        fst[st.CRDOWN] = newton_mod.CRDOWN

    def run(self, t, x, S, limit):
        """Steps from (t, x, S) up to the step that would reach ``limit``: the
        new point (t, x, S) after the steps taken (the same where none was)."""
        st, bdf, newton = self.st, self.bdf, self.bdf.newton
        ist, fst = self.ist, self.fst
        # the BDF's and Newton's state in
        ist[st.K], ist[st.N_EQUAL], ist[st.FAILS] = bdf._k, bdf._n_equal, bdf._fails
        ist[st.FAIL_HOLD], ist[st.PASSED] = bdf._fail_hold, int(bdf._passed)
        ist[st.N_REC] = ist[st.N_DENSE] = ist[st.N_EVENTS] = ist[st.FACTORED] = 0
        ist[st.ONE_ITER] = int(newton._one_iteration)
        stats = bdf.stats
        left = (bdf.max_steps - stats.steps - stats.rejected_steps
                if bdf.max_steps is not None else 1 << 62)
        ist[st.BUDGET_LEFT] = left
        fst[st.H], fst[st.FAIL_CAP], fst[st.ERR] = bdf._h, bdf._fail_cap, getattr(bdf, "_err", 0.0)
        fst[st.ETA], fst[st.CRATE] = newton.eta, newton._crate
        fst[st.FIRST_MAX] = newton.first_max
        fst[st.LIMIT_T] = limit
        lin = newton.lin
        usable = (not newton.stale and newton.lu_dt is not None and lin.lu is not None)
        if usable:
            LU, piv, ir, ic = self.lin[3], self.lin[4], self.lin[5], self.lin[6]
            LU[:] = lin.lu[0]
            piv[:] = lin.lu[1]
            scales = getattr(lin, "scales", None)
            if scales is None:
                ir[:] = 1.0
                ic[:] = 1.0
            else:
                ir[:], ic[:] = scales
            fst[st.LU_DT], fst[st.DT_LO], fst[st.DT_HI] = newton.lu_dt, newton._dt_lo, newton._dt_hi
            ist[st.AGE], ist[st.STALE] = newton.age, 0
        else:
            ist[st.STALE] = 1
            fst[st.DT_LO], fst[st.DT_HI] = 1.0, -1.0
        floor = newton.scale_floor
        if floor is not None:
            self.floor[:] = floor
        ist[st.HAS_FLOOR] = int(floor is not None)
        qmax_run = (np.zeros(self.floor.size) if bdf._qmax_run is None
                    else np.array(bdf._qmax_run, dtype=float))
        x, S, Q = x.copy(), S.copy(), bdf._Q.copy()
        self.stats[:] = 0
        rec = self.buffers + (self.x_index, self.s_index)
        dense = self.dbuf + (self.d_cols,)
        exit_, t = st.stretch(float(t), x, S, bdf._D, Q, ist, fst, qmax_run, self.floor,
                              self.stats, self.net, self.lin, self.sources, self.tol, rec,
                              dense, self.events, self.watch, self.G, self.ERRC)
        # the state out
        self._out(qmax_run)
        taken = int(ist[st.N_REC])
        if taken:
            r0 = len(bdf.rec.t)
            bt, bx, bs, bq = self.buffers
            bdf.rec.extend(bt[:taken], bx[:taken], bs[:taken], bq[:taken])
            dt_, dh, dk, drow, dD = self.dbuf
            bdf.dense.extend(dt_[:taken], dh[:taken], dk[:taken], drow[:taken] + r0,
                             dD[:ist[st.N_DENSE]])
            bdf._Q = Q
        progress = bdf.progress
        for e in range(int(ist[st.N_EVENTS])):
            t_e, h_e, _, err = self.events[e]
            progress.rejected(float(t_e), float(h_e), "error", float(err))
        if taken:
            progress.advance(t, taken)
        return exit_, t, x, S, taken

    def _out(self, qmax_run):
        st, bdf, newton = self.st, self.bdf, self.bdf.newton
        ist, fst, s = self.ist, self.fst, self.stats
        bdf._k, bdf._n_equal, bdf._fails = int(ist[st.K]), int(ist[st.N_EQUAL]), int(ist[st.FAILS])
        bdf._fail_hold = int(ist[st.FAIL_HOLD])
        bdf._h, bdf._fail_cap, bdf._err = float(fst[st.H]), float(fst[st.FAIL_CAP]), float(fst[st.ERR])
        bdf._qmax_run = qmax_run
        stats = bdf.stats
        stats.steps += int(s[st.STEPS])
        stats.rejected_steps += int(s[st.REJECTED])
        stats.error_test_failures += int(s[st.ERROR_FAILS])
        stats.newton_iterations += int(s[st.ITERATIONS])
        stats.residual_evaluations += int(s[st.RESIDUALS])
        stats.jacobian_evaluations += int(s[st.JACOBIANS])
        stats.factorizations += int(s[st.FACTORIZATIONS])
        for k in range(1, bdf.max_order + 1):
            bdf.order_counts[k] += int(s[7 + k])
        if s[st.STEPS]:
            bdf._passed = True
            bdf._chatter = 0
            bdf._secant_tries = 0
            bdf._approached = bdf._empty_tries > 0 and s[st.STEPS] == 1
            bdf._empty_tries = 0
        newton.eta, newton._crate = float(fst[st.ETA]), float(fst[st.CRATE])
        newton._one_iteration = bool(ist[st.ONE_ITER])
        if ist[st.HAS_FLOOR]:
            floor = self.floor.copy()
            newton.scale_floor = floor.tolist() if newton._small else floor
        if ist[st.FACTORED] and not ist[st.STALE]:
            J, LU, piv, ir, ic = self.lin[2:]
            newton.lin.adopt(J, LU, piv, ir, ic)
        if ist[st.STALE]:
            newton.stale = True
        else:
            newton.stale = False
            newton.age = int(ist[st.AGE])
            newton.lu_dt = float(fst[st.LU_DT])
            newton._dt_lo, newton._dt_hi = float(fst[st.DT_LO]), float(fst[st.DT_HI])


def compiled_steps(bdf):
    """A :class:`CompiledSteps` for the BDF run ``bdf``, or None where the
    compiled loop does not serve it (module docstring)."""
    if not settings.COMPILED_STEPS:
        return None
    asm, newton = bdf.asm, bdf.newton
    net = getattr(asm.residual, "network", None)
    if (net is None or newton is None or newton.lin.kind != "dense" or asm.has_regimes
            or asm.has_kinks or asm.has_begin_step or bdf.sens is not None
            or bdf._n_blocks > 1 or newton.offset is not None or not asm.n):
        return None
    sources = net.source_arrays()
    if sources is None:
        return None
    return CompiledSteps(bdf, net.arrays, sources)
