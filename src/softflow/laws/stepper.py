"""The adaptive BDF's usual steps in one compiled loop (issue 38, the compiled
core's third step).

:class:`softflow.solve.bdf.BDF` hands this loop its state (the difference
table, the order and step, Newton's factors and contraction estimates, the
run's magnitudes) and the network as :mod:`.network` evaluates it; the loop
takes steps as the BDF takes them (:meth:`~softflow.solve.bdf.BDF._propose`,
Newton's chord iterations on reused and then fresh factors, the error test
and its rejections, :meth:`~softflow.solve.bdf.BDF._take`'s difference update,
order and step selection), records each accepted step into preallocated
arrays, and returns to Python at the first event that needs more than that
(:data:`EXITS`): a step that would reach the next breakpoint or the end, a
Newton solve that its chord stages do not converge (the BDF's damped stages,
the culprit finder, continuation), a step forced at the smallest step, a
mode switch, a volume past its limit, a full record buffer, the step budget.
The step that caused an exit is not taken: the BDF takes it again from the
state the loop leaves (the same step size, its table rescaled to it), so a
run is the same run whichever loop took each step, to the round-off of the
linear algebra (a compiled LU here, LAPACK and its inverse there).

Settings arrive as arguments (the arrays ``ist``, ``fst`` and their slots
below), never as module globals: numba freezes globals into its cache.
"""
from __future__ import annotations

import math

import numpy as np

from . import jit
from .network import residual
from .waves import source_values

#: why the loop returned
LIMIT, NEWTON, FORCED, SWITCH, EMPTIED, FULL, BUDGET = range(7)
EXITS = ("limit", "newton", "forced", "switch", "emptied", "full", "budget")

#: slots of the integer state ``ist``
(K, N_EQUAL, FAILS, FAIL_HOLD, PASSED, AGE, STALE, ONE_ITER, FACTORED, BUDGET_LEFT,
 MAX_ORDER, MAX_REUSE, MAX_ITER, MAX_AGE, N_REC, N_DENSE, N_EVENTS, HOLD_STEPS,
 N_DISC, M_ERR, HAS_FLOOR, CLIP) = range(22)
IST_SIZE = 22
#: slots of the float state ``fst``
(H, FAIL_CAP, ETA, CRATE, LU_DT, DT_LO, DT_HI, ERR, RTOL, NEWTON_RTOL, FLOOR_FACTOR,
 FIRST_MAX, STEP_MIN, STEP_MAX, LIMIT_T, RATIO_LO, RATIO_HI, T_LO, T_HI, SAFETY,
 MIN_FACTOR, MAX_FACTOR, GROW_MIN, PEAK_FACTOR, PIVOT_RTOL, CRDOWN) = range(26)
FST_SIZE = 26
#: slots of ``stats``
(STEPS, REJECTED, ERROR_FAILS, ITERATIONS, RESIDUALS, JACOBIANS, FACTORIZATIONS) = range(7)
STATS_SIZE = 7 + 6      # then the accepted steps per order 0..5


# -- dense linear algebra ------------------------------------------------------------
@jit
def lu_factor(A, piv):
    """LU of A in place with partial pivoting, as LAPACK's getrf (piv[j]: the
    row swapped with row j, 0-based). Returns the smallest and largest |U_jj|."""
    n = A.shape[0]
    d_min, d_max = math.inf, 0.0
    for j in range(n):
        p, amax = j, abs(A[j, j])
        for i in range(j + 1, n):
            v = abs(A[i, j])
            if v > amax:
                p, amax = i, v
        piv[j] = p
        if p != j:
            for k in range(n):
                A[j, k], A[p, k] = A[p, k], A[j, k]
        d = A[j, j]
        ad = abs(d)
        if ad < d_min:
            d_min = ad
        if ad > d_max:
            d_max = ad
        if d != 0.0:
            r = 1.0 / d
            for i in range(j + 1, n):
                A[i, j] *= r
        for i in range(j + 1, n):
            m = A[i, j]
            if m != 0.0:
                for k in range(j + 1, n):
                    A[i, k] -= m * A[j, k]
    return d_min, d_max


@jit
def lu_solve(A, piv, ir, ic, b, out):
    """out = C (R J C)^-1 R b from the factors of :func:`lu_factor` (row and
    column scales ir, ic: ones where J was factored as it is)."""
    n = A.shape[0]
    for i in range(n):
        out[i] = ir[i] * b[i]
    for i in range(n):
        p = piv[i]
        if p != i:
            out[i], out[p] = out[p], out[i]
    for i in range(n):
        s = out[i]
        for k in range(i):
            s -= A[i, k] * out[k]
        out[i] = s
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, n):
            s -= A[i, k] * out[k]
        out[i] = s / A[i, i]
    for i in range(n):
        out[i] *= ic[i]


@jit
def factor(raw, flat, J, LU, piv, ir, ic, pivot_rtol):
    """The dense Jacobian from the raw entries (``flat``: each entry's place
    in the flattened matrix; entries of one place summed) into J, factored
    into LU as :class:`softflow.solve.linalg.DenseLU` factors it: as it is,
    or rows then columns scaled to a largest entry of 1 where its pivots fail
    the singularity test. Returns 0, 1 (not finite) or 2 (singular)."""
    n = J.shape[0]
    Jf = J.ravel()
    for i in range(Jf.size):
        Jf[i] = 0.0
    for e in range(raw.size):
        Jf[flat[e]] += raw[e]
    for i in range(Jf.size):
        if not math.isfinite(Jf[i]):
            return 1
    LU[:, :] = J
    d_min, d_max = lu_factor(LU, piv)
    if d_min > pivot_rtol * max(d_max, 1e-300):
        ir[:] = 1.0
        ic[:] = 1.0
        return 0
    for i in range(n):
        r = 0.0
        for k in range(n):
            r = max(r, abs(J[i, k]))
        if not r > 0.0:
            return 2
        ir[i] = r
    for k in range(n):
        c = 0.0
        for i in range(n):
            c = max(c, abs(J[i, k] / ir[i]))
        if not c > 0.0:
            return 2
        ic[k] = c
    for i in range(n):
        for k in range(n):
            LU[i, k] = (J[i, k] / ir[i]) / ic[k]
    d_min, d_max = lu_factor(LU, piv)
    if not d_min > pivot_rtol * max(d_max, 1e-300):
        return 2
    for i in range(n):
        ir[i] = 1.0 / ir[i]
        ic[i] = 1.0 / ic[i]
    return 0


# -- the BDF's arithmetic --------------------------------------------------------------
@jit
def _rescale(D, k, factor):
    """D[1:k+1] as the backward differences of the same polynomial at
    ``factor`` times the spacing (:func:`softflow.solve.bdf._rescale_matrix`)."""
    if factor == 1.0:
        return
    m = k + 1
    A = np.ones((m, m))
    B = np.ones((m, m))
    for j in range(1, m):
        for i in range(m):
            A[i, j] = A[i, j - 1] * ((j - 1) - i * 1.0) / j
            B[i, j] = B[i, j - 1] * ((j - 1) - i * factor) / j
    piv = np.zeros(m, dtype=np.int64)
    lu_factor(A, piv)
    one = np.ones(m)
    M = np.empty((m, m))
    col = np.empty(m)
    for j in range(m):
        lu_solve(A, piv, one, one, B[:, j].copy(), col)
        M[:, j] = col
    width = D.shape[1]
    old = D[1:m].copy()
    for i in range(1, m):
        for c in range(width):
            s = 0.0
            for j in range(1, m):
                s += M[i, j] * old[j - 1, c]
            D[i, c] = s


@jit
def _weights(S_a, S_b, x, atol_s, atol_x, x_off, q_id, qmax_run, rtol, w):
    """The error weights (states, then unknowns) into w, the run's largest
    magnitude of each quantity raised to x's (:meth:`BDF._weights`)."""
    ns = S_a.size
    for i in range(ns):
        w[i] = atol_s[i] + rtol * max(abs(S_a[i]), abs(S_b[i]))
    nq = qmax_run.size
    qmax = np.zeros(nq)
    for i in range(x.size):
        v = abs(x[i] - x_off[i])
        q = q_id[i]
        if v > qmax[q]:
            qmax[q] = v
    for q in range(nq):
        if qmax_run[q] > qmax[q]:
            qmax[q] = qmax_run[q]
        qmax_run[q] = qmax[q]
    for i in range(x.size):
        w[ns + i] = atol_x[i] + rtol * qmax[q_id[i]]


@jit
def _enorm(v, w, m, n_disc, peak_factor):
    """The weighted RMS of v[:m] / w[:m] over its continuous entries, or its
    largest weighted entry over ``peak_factor`` where that is larger."""
    size = m - n_disc
    if size <= 0:
        return 0.0
    acc, peak = 0.0, 0.0
    for i in range(m):
        e = v[i] / w[i]
        acc += e * e
        if abs(e) > peak:
            peak = abs(e)
    return max(math.sqrt(acc / size), peak / peak_factor)


@jit
def _newton_scale(x0, natol, nrtol, x_off, q_id, floor, has_floor, links, itol):
    """Newton's reciprocal tolerances for a solve from x0 (:meth:`Newton._set_scale`)."""
    nq = floor.size
    qmax = np.zeros(nq)
    for i in range(x0.size):
        v = abs(x0[i] - x_off[i])
        if v > qmax[q_id[i]]:
            qmax[q_id[i]] = v
    if has_floor:
        for q in range(nq):
            if floor[q] > qmax[q]:
                qmax[q] = floor[q]
    for r in range(links.shape[0]):
        q, base = int(links[r, 0]), int(links[r, 1])
        qmax[q] = max(qmax[q], links[r, 2] * qmax[base])
    for i in range(x0.size):
        itol[i] = 1.0 / (natol[i] + nrtol * qmax[q_id[i]])


@jit
def _norm(step, itol):
    nrm = 0.0
    for i in range(step.size):
        v = abs(step[i]) * itol[i]
        if not v <= nrm:          # NaN propagates
            nrm = v
    return nrm


@jit
def _finite(F):
    for i in range(F.size):
        if not math.isfinite(F[i]):
            return False
    return True


@jit
def _clip(x, step, T_idx, t_lo, t_hi):
    """Newton's clipped node temperature updates (:meth:`Newton._clip_temperature`),
    on minus the update as the chord carries it."""
    for j in range(T_idx.size):
        i = T_idx[j]
        T = x[i]
        d = min(max(-step[i], -0.5 * T), T)
        d = min(max(T + d, t_lo), t_hi) - T
        step[i] = -d


@jit
def _evaluate(net, x, S, t, c, jac, F, Sout, stats):
    stats[RESIDUALS] += 1
    if jac:
        stats[JACOBIANS] += 1
    raw, nr, trows, tcols, groups, cols, fpar, u = net
    return residual(x, S, t, c, jac, F, raw, nr, trows, tcols, groups, cols, fpar, u, Sout)


@jit
def _chord(net, lin, x0, psi, t, c, fresh, ist, fst, itol, T_idx, x, F, step, xn,
           Fn, none, stats):
    """Chord iterations from x0 (:meth:`Newton._chord`): the solution in x and
    True, or False (diverging, too slow, not finite, refused by a law)."""
    raw, flat, J, LU, piv, ir, ic = lin
    x[:] = x0
    if _evaluate(net, x, psi, t, c, fresh, F, none, stats) >= 0 or not _finite(F):
        return False
    if fresh:
        stats[FACTORIZATIONS] += 1
        if factor(raw, flat, J, LU, piv, ir, ic, fst[PIVOT_RTOL]) != 0:
            ist[STALE] = 1
            return False
        ist[FACTORED] = 1
        ist[AGE] = 0
        ist[STALE] = 0
        fst[LU_DT] = c
        fst[CRATE] = 1.0
        fst[DT_LO], fst[DT_HI] = fst[RATIO_LO] * c, fst[RATIO_HI] * c
    limit = ist[MAX_ITER] if fresh else ist[MAX_REUSE]
    prev = -1.0
    clip = ist[CLIP] > 0
    for k in range(limit):
        lu_solve(LU, piv, ir, ic, F, step)
        nrm = _norm(step, itol)
        stats[ITERATIONS] += 1
        if clip:
            _clip(x, step, T_idx, fst[T_LO], fst[T_HI])
        if not math.isfinite(nrm):
            return False
        if prev >= 0.0:
            rate = nrm / prev
            if rate >= 0.9:
                return False
            fst[ETA] = rate / (1.0 - rate)
            crate = max(rate, fst[CRDOWN] * fst[CRATE])
            fst[CRATE] = crate
            done = nrm * crate <= 1.0 - crate
            if not done and nrm * rate ** (limit - 1 - k) / (1.0 - rate) > 1.0:
                return False
        else:
            done = nrm <= 1.0 or (nrm <= fst[FIRST_MAX]
                                  and nrm * max(fst[ETA], 1e-3) ** 0.8 <= 1.0)
        if done:
            for i in range(x.size):
                x[i] = x[i] - step[i]
            ist[ONE_ITER] = 1 if k == 0 else 0
            if k + 1 >= ist[MAX_REUSE] and not fresh:
                ist[STALE] = 1
            return True
        for i in range(x.size):
            xn[i] = x[i] - step[i]
        # Newton damps only to keep the residual finite: the compiled loop
        # leaves that to it
        if _evaluate(net, xn, psi, t, c, False, Fn, none, stats) >= 0 or not _finite(Fn):
            return False
        x[:] = xn
        F[:] = Fn
        prev = nrm
    return False


@jit
def _positive(x, p_idx):
    for j in range(p_idx.size):
        if not x[p_idx[j]] > 0.0:
            return False
    return True


@jit
def _solve(net, lin, x0, psi, t, c, ist, fst, itol, floor, links, natol, x_off, q_id,
           p_idx, T_idx, work, none, stats):
    """Newton's solve of one step (:meth:`Newton.solve`'s chord stages): True
    with the solution in work[0], or False where the BDF's own Newton must
    take the step (its damped stages, the culprit finder)."""
    x, F, step, xn, Fn = work[0], work[1], work[2], work[3], work[4]
    _newton_scale(x0, natol, fst[NEWTON_RTOL], x_off, q_id, floor, ist[HAS_FLOOR] > 0,
                  links, itol)
    reusable = (ist[STALE] == 0 and ist[AGE] < ist[MAX_AGE]
                and fst[DT_LO] <= c <= fst[DT_HI])
    if reusable:
        if _chord(net, lin, x0, psi, t, c, False, ist, fst, itol, T_idx, x, F, step, xn, Fn,
                  none, stats):
            if not _positive(x, p_idx):
                return False
            ist[AGE] += 1
            return True
    if _chord(net, lin, x0, psi, t, c, True, ist, fst, itol, T_idx, x, F, step, xn, Fn,
              none, stats):
        if not _positive(x, p_idx):
            return False
        ist[AGE] += 1
        return True
    return False


@jit
def stretch(t, x, S, D, Q, ist, fst, qmax_run, floor, stats,
            net, lin, sources, tol, rec, dense, events, watch, G, ERRC):
    """Steps of the BDF from (t, x, S) until an event (module docstring).

    Arguments: the point and the difference table D (states, unknowns,
    quadratures), the quadratures Q, the integer and float state (slots
    above), the run's magnitudes per quantity and Newton's floor of them,
    the counters; ``net`` the network as :func:`.network.residual` takes it,
    ``lin`` (raw entries, their dense places, J, LU, piv, row and column
    scales), ``sources`` (:func:`.waves.source_values`'s arrays), ``tol``
    (atol of the states, atol and offsets of the unknowns, their quantity
    ids, Newton's atol, the links between quantities' scales, the pressures'
    and temperatures' indices, the quadratures' unknowns), ``rec`` and
    ``dense`` (the record buffers), ``events`` (rejections: t, h, cause,
    error), ``watch`` (the watched states and their floors), the BDF's g_j
    and error constants. Returns (exit, t); x, S, Q and the state arrays
    are updated in place to the last step taken."""
    atol_s, atol_x, x_off, q_id, natol, links, p_idx, T_idx, q_sel = tol
    rec_t, rec_x, rec_s, rec_q, x_index, s_index = rec
    d_t, d_h, d_k, d_row, d_D, d_cols = dense
    w_index, w_floor = watch
    base, slot, codes, factors, starts, floats = sources
    u = net[7]
    ns, n, width = S.size, x.size, D.shape[1]
    nQ = Q.size
    m_err = ist[M_ERR]
    n_disc = ist[N_DISC]
    rtol = fst[RTOL]
    smin = fst[STEP_MIN] * 1.0000001
    limit_t = fst[LIMIT_T]
    n_rec_cap, n_dense_cap, n_ev_cap = rec_t.size, d_D.shape[0], events.shape[0]
    kmax = ist[MAX_ORDER]
    pred = np.empty(width)
    psi_all = np.empty(width)
    delta = np.empty(width)
    w = np.empty(ns + n)
    itol = np.empty(n)
    work = np.empty((5, n))
    S_new = np.empty(ns)
    Fe = np.empty(n)
    none = np.empty(0)
    Q_new = np.empty(nQ)
    used = 0           # steps tried, accepted and rejected (Simulation(max_steps=))
    while True:
        if ist[N_REC] >= n_rec_cap or ist[N_DENSE] + kmax > n_dense_cap \
                or ist[N_EVENTS] >= n_ev_cap:
            return FULL, t
        if used >= ist[BUDGET_LEFT]:
            return BUDGET, t
        k, h = ist[K], fst[H]
        # the step: no overshoot of the limit, no sliver left before it
        h_try = min(h, fst[STEP_MAX], fst[FAIL_CAP])
        if t + h_try >= limit_t or limit_t - (t + h_try) < 0.2 * h_try:
            return LIMIT, t
        if h_try != h:
            _rescale(D, k, h_try / h)
            fst[H] = h = h_try
            ist[N_EQUAL] = 0
        t_new = t + h
        gk = G[k]
        for c_ in range(width):
            s = D[0, c_]
            p = D[0, c_]
            for j in range(1, k + 1):
                s += D[j, c_]
                p += (1.0 - G[j] / gk) * D[j, c_]
            pred[c_] = s
            psi_all[c_] = p
        c = h / gk
        psi = psi_all[:ns]
        source_values(t_new, base, slot, codes, factors, starts, floats, u)
        if not _solve(net, lin, pred[ns:ns + n], psi, t_new, c, ist, fst, itol, floor, links,
                      natol, x_off, q_id, p_idx, T_idx, work, none, stats):
            ist[STALE] = 1
            return NEWTON, t
        x_new = work[0]
        # the end-of-step states, from the network's own laws
        if _evaluate(net, x_new, psi, t_new, c, False, Fe, S_new, stats) >= 0:
            return NEWTON, t
        stats[RESIDUALS] -= 1         # (no equation solved: the states' update)
        if n_disc:
            for i in range(ns):
                if S_new[i] != S[i] and not math.isfinite(atol_s[i]):
                    return SWITCH, t
        # the error test (BDF._judge)
        for i in range(ns):
            delta[i] = S_new[i] - pred[i]
        for i in range(n):
            delta[ns + i] = x_new[i] - pred[ns + i]
        _weights(S, S_new, x_new, atol_s, atol_x, x_off, q_id, qmax_run, rtol, w)
        for q in range(floor.size):
            floor[q] = qmax_run[q] * fst[FLOOR_FACTOR]
        ist[HAS_FLOOR] = 1
        err = ERRC[k] * _enorm(delta, w, m_err, n_disc, fst[PEAK_FACTOR])
        fst[ERR] = err
        if err > 1.0:
            if h <= smin:
                return FORCED, t
            stats[REJECTED] += 1
            stats[ERROR_FAILS] += 1
            used += 1
            e = ist[N_EVENTS]
            events[e, 0], events[e, 1], events[e, 2], events[e, 3] = t_new, h, 0.0, err
            ist[N_EVENTS] = e + 1
            fails = ist[FAILS] + 1
            ist[FAILS] = fails
            fst[FAIL_CAP] = 0.9 * h
            ist[FAIL_HOLD] = ist[HOLD_STEPS]
            factor_ = max(fst[MIN_FACTOR], fst[SAFETY] * (2 * err + 1e-4) ** (-1.0 / (k + 1)))
            if fails == 2:
                factor_ = min(factor_, 0.25)
            elif fails >= 3:
                factor_ = 0.25
                if k > 1:
                    D[2:, :] = 0.0
                    ist[K] = k = 1
            factor_ = max(factor_, fst[STEP_MIN] / h)
            _rescale(D, k, factor_)
            fst[H] = h * factor_
            ist[N_EQUAL] = 0
            continue
        # a volume past its limit: the BDF locates where it empties
        for j in range(w_index.size):
            if S_new[w_index[j]] < w_floor[j]:
                return EMPTIED, t
        # the step is taken (BDF._take)
        ist[FAILS] = 0
        if ist[FAIL_HOLD]:
            ist[FAIL_HOLD] -= 1
            if not ist[FAIL_HOLD]:
                fst[FAIL_CAP] = math.inf
        stats[STEPS] += 1
        stats[7 + k] += 1
        for i in range(nQ):
            Q_new[i] = psi_all[ns + n + i] + c * x_new[q_sel[i]]
            delta[ns + n + i] = Q_new[i] - pred[ns + n + i]
        # the difference table at the new point from nabla^(k+1)
        for c_ in range(width):
            d = delta[c_]
            D[k + 2, c_] = d - D[k + 1, c_]
            D[k + 1, c_] = d
            for i in range(k, -1, -1):
                D[i, c_] += D[i + 1, c_]
        # recorded: the point, and the step's differences for dense output
        r = ist[N_REC]
        rec_t[r] = t_new
        for i in range(x_index.size):
            rec_x[r, i] = x_new[x_index[i]]
        for i in range(s_index.size):
            rec_s[r, i] = S_new[s_index[i]]
        rec_q[r, :] = Q_new
        ist[N_REC] = r + 1
        dn = ist[N_DENSE]
        e = r                      # dense entries and points advance together
        d_t[e], d_h[e], d_k[e], d_row[e] = t_new, h, k, r
        for i in range(k):
            for j in range(d_cols.size):
                d_D[dn + i, j] = D[1 + i, d_cols[j]]
        ist[N_DENSE] = dn + k
        ist[PASSED] = 1
        t = t_new
        x[:] = x_new
        S[:] = S_new
        Q[:] = Q_new
        used += 1
        ist[N_EQUAL] += 1
        if ist[N_EQUAL] < k + 1:
            continue
        # order and step: estimates at k - 1, k, k + 1
        _weights(S, S, x, atol_s, atol_x, x_off, q_id, qmax_run, rtol, w)
        for q in range(floor.size):
            floor[q] = qmax_run[q] * fst[FLOOR_FACTOR]
        safety = fst[SAFETY]
        err_k = max(err, 1e-16)
        best, k_new = safety * err_k ** (-1.0 / (k + 1)), k
        if k > 1:
            e_lo = max(ERRC[k - 1] * _enorm(D[k], w, m_err, n_disc, fst[PEAK_FACTOR]), 1e-16)
            f_lo = safety * e_lo ** (-1.0 / k)
            if f_lo > best or (f_lo == best and k - 1 > k_new):
                best, k_new = f_lo, k - 1
        if k < kmax:
            e_hi = max(ERRC[k + 1] * _enorm(D[k + 2], w, m_err, n_disc, fst[PEAK_FACTOR]),
                       1e-16)
            f_hi = safety * e_hi ** (-1.0 / (k + 2))
            if f_hi > best or (f_hi == best and k + 1 > k_new):
                best, k_new = f_hi, k + 1
        factor_ = min(fst[MAX_FACTOR], best)
        if 1.0 <= factor_ < fst[GROW_MIN]:
            if k_new == k:
                continue
            factor_ = 1.0
        ist[K] = k_new
        factor_ = max(fst[MIN_FACTOR], factor_)
        _rescale(D, k_new, factor_)
        fst[H] = h * factor_
        ist[N_EQUAL] = 0
