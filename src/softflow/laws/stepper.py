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

from . import borrowed, call_native, call_user, inline, jit, native_address
from .network import kinks, regimes, residual, switching
from .sparselu import row_maxima, sparse_factor, sparse_solve
from .waves import source_values

#: why the loop returned
DONE, NEWTON, FORCED, SWITCH, EMPTIED, FULL, BUDGET, RESTART = range(8)
EXITS = ("done", "newton", "forced", "switch", "emptied", "full", "budget", "restart")
#: the causes of the events it records (rejections, restarts)
ERROR_EVENT, RESTART_EVENT, SWITCH_EVENT, NEWTON_EVENT = 0.0, 1.0, 2.0, 3.0
#: how a Newton solve ended (:func:`_chord`, :func:`_solve`): solved; failed
#: as the BDF rejects a step (diverging, too slow, an undamped full step
#: that would need damping: its reason none of the culprit finder's);
#: failed while contracting (chord iterations too slow: the undamped full
#: stage may go on); failed in a way only the BDF's own Newton reports
#: (a residual not finite, a law's refusal, a singular Jacobian, another
#: piece of a piecewise law); converged on an absolute pressure <= 0 (the
#: BDF's too, which a looser tolerance does not change); a restart's
#: probe handed back before its damped stage (:func:`_solve`'s mode 4)
SOLVED, PLAIN, CONTRACTING, HAND, REFUSED, SOURCES = range(6)

#: slots of the integer state ``ist``
(K, N_EQUAL, FAILS, FAIL_HOLD, PASSED, AGE, STALE, ONE_ITER, FACTORED, BUDGET_LEFT,
 MAX_ORDER, MAX_REUSE, MAX_ITER, MAX_AGE, N_REC, N_DENSE, N_EVENTS, HOLD_STEPS,
 N_DISC, M_ERR, HAS_FLOOR, CLIP, RESTART_DUE, IB, CAP_HOLD, SECANT_TRIES,
 MAX_SECANT, LOG_SWITCHES, UNDAMPED, REJECT_NEWTON, FAILS_HERE, WATCHDOG,
 WANTS_SOURCES, FLOWS_FIRST, PROBE_FAILED, BEGIN_KEY, BEGIN_AT) = range(37)
IST_SIZE = 37
#: slots of the float state ``fst``
(H, FAIL_CAP, ETA, CRATE, LU_DT, DT_LO, DT_HI, ERR, RTOL, NEWTON_RTOL, FLOOR_FACTOR,
 FIRST_MAX, STEP_MIN, STEP_MAX, DURATION, RATIO_LO, RATIO_HI, T_LO, T_HI, SAFETY,
 MIN_FACTOR, MAX_FACTOR, GROW_MIN, PEAK_FACTOR, PIVOT_RTOL, CRDOWN, NEXT_BREAK,
 FIRST_STEP, FIRST_ESTIMATE, H_CAP, SWITCH_PAST, CHATTER_STEP, FULL_STAGE_STEPS,
 KEEP_CUT, TIGHT_KEEP_CUT, TIGHT_RTOL, FLIP_MATCH, LS_MIN, LS_GROSS, LS_DEEP) = range(40)
FST_SIZE = 40
#: slots of ``stats``
(STEPS, REJECTED, ERROR_FAILS, ITERATIONS, RESIDUALS, JACOBIANS, FACTORIZATIONS) = range(7)
#: then the accepted steps per order 0..5 (7 + k), then the failed solves,
#: then the residual evaluations made when the last step was accepted
NEWTON_FAILS = 13
RESIDUALS_AT_STEP = 14
STATS_SIZE = 15


# -- dense linear algebra ------------------------------------------------------------
@jit
def lu_factor(A, piv):
    """LU of A in place with partial pivoting, as LAPACK's getrf (piv[j]: the
    row swapped with row j, 0-based). Returns the smallest and largest |U_jj|.
    Each row's update stops at the pivot row's last nonzero entry, and where
    ``piv`` holds 3 n entries its last 2 n receive the factors' profile, as
    :func:`lu_profile` reads it, found on the way; :func:`lu_solve` then
    keeps to it. The entries skipped are exact zeros, whose products change
    no sum: the factors and solutions are those of the full loops (but for
    the sign of a zero, and a NaN or inf in a right-hand side no longer
    spreads to rows that do not depend on it). A chain of 8 tubes' Jacobian
    (34 unknowns, 82 nonzeros): factor 2.99 -> 2.66 us, solve 1.15 -> 0.77 us
    against the full loops before (benchmarks/bench_loop_lu.py --profile)."""
    n = A.shape[0]
    profile = piv.size >= 3 * n
    if profile:
        for i in range(n):
            piv[n + i] = -1         # (no entry of L's row yet: they move with their rows)
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
            if profile:
                piv[n + j], piv[n + p] = piv[n + p], piv[n + j]
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
        # U's row j is final: its last nonzero bounds the updates and the solves
        hi = _row_end(A, j)
        if profile:
            piv[2 * n + j] = hi
        for i in range(j + 1, n):
            m = A[i, j]
            if m != 0.0:
                if profile and piv[n + i] < 0:
                    piv[n + i] = j          # L's row i: its first nonzero
                for k in range(j + 1, hi):
                    A[i, k] -= m * A[j, k]
    if profile:
        for i in range(n):
            if piv[n + i] < 0:
                piv[n + i] = i
    return d_min, d_max


@jit
def _row_end(A, i):
    """One past the last nonzero of row i of A right of its diagonal (i + 1
    where none): U's row i's end in the factors of :func:`lu_factor`."""
    hi = A.shape[1]
    while hi > i + 1 and A[i, hi - 1] == 0.0:
        hi -= 1
    return hi


@jit
def lu_profile(A, piv):
    """The profile of the factors of :func:`lu_factor` in A into piv[n:3n]:
    piv[n + i] the first nonzero column of L's row i (i where none),
    piv[2n + i] one past the last nonzero column of U's row i (i + 1 where
    none). For factors made elsewhere (LAPACK's, adopted by the step loop)."""
    n = A.shape[0]
    for i in range(n):
        lo = 0
        while lo < i and A[i, lo] == 0.0:
            lo += 1
        piv[n + i] = lo
        piv[2 * n + i] = _row_end(A, i)


#: the smallest normal float: the solves below store smaller values as 0
#: (subnormal numbers, the tails of a step response down a long chain of
#: tubes, 1e-308 kg/s and less, cost ~100 times a normal operation: the air
#: chain of 5 000 tubes spent 5x its arithmetic's time on them)
TINY = 2.2250738585072014e-308


@jit
def lu_solve(A, piv, ir, ic, b, out):
    """out = C (R J C)^-1 R b from the factors of :func:`lu_factor` (row and
    column scales ir, ic: ones where J was factored as it is); subnormal
    values are stored as 0 (:data:`TINY`). Where ``piv`` holds the factors'
    profile (3 n entries, :func:`lu_factor`), each row's sums keep to it."""
    n = A.shape[0]
    profile = piv.size >= 3 * n
    for i in range(n):
        out[i] = ir[i] * b[i]
    for i in range(n):
        p = piv[i]
        if p != i:
            out[i], out[p] = out[p], out[i]
    for i in range(n):
        s = out[i]
        for k in range(piv[n + i] if profile else 0, i):
            s -= A[i, k] * out[k]
        out[i] = s if abs(s) >= TINY or s != s else 0.0
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, piv[2 * n + i] if profile else n):
            s -= A[i, k] * out[k]
        s = s / A[i, i]
        out[i] = s if abs(s) >= TINY or s != s else 0.0
    for i in range(n):
        out[i] *= ic[i]


@jit
def _assemble(raw, flat, J):
    """J from the raw entries (``flat``: each entry's place in the flattened
    J; entries of one place summed): whether every entry is finite."""
    Jf = J.ravel()
    for i in range(Jf.size):
        Jf[i] = 0.0
    for e in range(raw.size):
        Jf[flat[e]] += raw[e]
    for i in range(Jf.size):
        if not math.isfinite(Jf[i]):
            return False
    return True


@jit
def _reciprocals(ir, ic):
    """The scales an equilibrated factorization found, as the solves take them."""
    for i in range(ir.size):
        ir[i] = 1.0 / ir[i]
        ic[i] = 1.0 / ic[i]


@jit
def _row_maxima(J, ir):
    """ir[i] = max_j |J_ij| over the stored entries of each row (a dense
    matrix's, or a band's: its places outside the matrix hold 0); False
    where a row is all zero (singular)."""
    for i in range(J.shape[0]):
        r = 0.0
        for o in range(J.shape[1]):
            r = max(r, abs(J[i, o]))
        if not r > 0.0:
            return False
        ir[i] = r
    return True


@jit
def factor(raw, flat, J, LU, piv, ir, ic, pivot_rtol):
    """The dense Jacobian from the raw entries (``flat``: each entry's place
    in the flattened matrix; entries of one place summed) into J, factored
    into LU as :class:`softflow.solve.linalg.DenseLU` factors it: as it is,
    or rows then columns scaled to a largest entry of 1 where its pivots fail
    the singularity test. Returns 0, 1 (not finite) or 2 (singular)."""
    n = J.shape[0]
    if not _assemble(raw, flat, J):
        return 1
    LU[:, :] = J
    d_min, d_max = lu_factor(LU, piv)
    if d_min > pivot_rtol * max(d_max, 1e-300):
        ir[:] = 1.0
        ic[:] = 1.0
        return 0
    if not _row_maxima(J, ir):
        return 2
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
    _reciprocals(ir, ic)
    return 0


@jit
def band_lu(A, piv, kl):
    """LU of a band matrix in place with partial pivoting, as LAPACK's gbtrf
    keeps it: row i of A holds the columns i - kl .. i + ku + kl (A[i, j - i
    + kl]; the last kl for the fill that row swaps bring), L's multipliers
    below the diagonal where the matrix's lower band was, not swapped by
    later pivots (piv[j]: the row swapped with row j at step j). Returns
    the smallest and largest |U_jj|."""
    n, w = A.shape
    d_min, d_max = math.inf, 0.0
    for j in range(n):
        i_end = min(n, j + kl + 1)
        p, amax = j, abs(A[j, kl])
        for i in range(j + 1, i_end):
            v = abs(A[i, j - i + kl])
            if v > amax:
                p, amax = i, v
        piv[j] = p
        k_end = min(n, j + w - kl)          # past the last column row j can hold
        if p != j:
            for k in range(j, k_end):
                A[j, k - j + kl], A[p, k - p + kl] = A[p, k - p + kl], A[j, k - j + kl]
        d = A[j, kl]
        ad = abs(d)
        if ad < d_min:
            d_min = ad
        if ad > d_max:
            d_max = ad
        if d != 0.0:
            r = 1.0 / d
            for i in range(j + 1, i_end):
                A[i, j - i + kl] *= r
        for i in range(j + 1, i_end):
            m = A[i, j - i + kl]
            if m != 0.0:
                for k in range(j + 1, k_end):
                    A[i, k - i + kl] -= m * A[j, k - j + kl]
    return d_min, d_max


@jit
def band_solve(A, piv, ir, ic, kl, b, out):
    """out = C (R J C)^-1 R b from the factors of :func:`band_lu` (the row
    swaps applied as the forward substitution reaches them, as LAPACK's
    gbtrs); subnormal values are stored as 0 (:data:`TINY`)."""
    n, w = A.shape
    for i in range(n):
        out[i] = ir[i] * b[i]
    for j in range(n):
        p = piv[j]
        if p != j:
            out[j], out[p] = out[p], out[j]
        y = out[j]
        if abs(y) < TINY:
            out[j] = 0.0
        elif y == y:
            for i in range(j + 1, min(n, j + kl + 1)):
                out[i] -= A[i, j - i + kl] * y
        else:                    # NaN: on into the rows below, as any value
            for i in range(j + 1, min(n, j + kl + 1)):
                out[i] -= A[i, j - i + kl] * y
    for i in range(n - 1, -1, -1):
        s = out[i]
        for k in range(i + 1, min(n, i + w - kl)):
            s -= A[i, k - i + kl] * out[k]
        s = s / A[i, kl]
        out[i] = s if abs(s) >= TINY or s != s else 0.0
    for i in range(n):
        out[i] *= ic[i]


@jit
def band_factor(raw, flat, J, LU, piv, ir, ic, kl, pivot_rtol, scaled=False):
    """:func:`factor` for a Jacobian held in band storage (``flat``: each raw
    entry's place in the flattened band array, rows and columns in the
    band's order): J from the raw entries, its factors in LU (:func:`band_lu`),
    equilibrated where its pivots fail the singularity test, or at once
    with ``scaled`` (the last factors needed it: a network's units do not
    change between steps). Returns 0, 1 (not finite) or 2 (singular)."""
    n, w = J.shape
    if not _assemble(raw, flat, J):
        return 1
    if not scaled:
        LU[:, :] = J
        d_min, d_max = band_lu(LU, piv, kl)
        if d_min > pivot_rtol * max(d_max, 1e-300):
            ir[:] = 1.0
            ic[:] = 1.0
            return 0
    if not _row_maxima(J, ir):
        return 2
    ic[:] = 0.0
    for i in range(n):
        for o in range(w):
            k = i + o - kl
            if 0 <= k < n:
                ic[k] = max(ic[k], abs(J[i, o] / ir[i]))
    for k in range(n):
        if not ic[k] > 0.0:
            return 2
    for i in range(n):
        for o in range(w):
            k = i + o - kl
            LU[i, o] = (J[i, o] / ir[i]) / ic[k] if 0 <= k < n else 0.0
    d_min, d_max = band_lu(LU, piv, kl)
    if not d_min > pivot_rtol * max(d_max, 1e-300):
        return 2
    _reciprocals(ir, ic)
    return 0


# -- the network's linear algebra, dense, banded or sparse ---------------------------
#: ``lin``: (raw entries, their places in J, J, LU, pivots, row and column
#: scales, the pieces of the Jacobian's laws, the pieces at a solution, the
#: kinks' sides at the point and at a step's end, switching values, the
#: rows the culprit finder looks into, the kind (0 dense, 1 banded, 2
#: sparse; the band's kl; whether its last factors were equilibrated; the
#: banded and sparse LUs' addresses: KIND ... MAXIMA_AT below),
#: the band's order (its rows' original rows, its columns' original
#: unknowns, each original row's band row), two scratch rows, the sparse
#: LU's integer arrays (Ap, Ai, Q, Lp, Li, Up, Ui, pinv, prow, Ar, iw,
#: state) and its float arrays (Lx, Ux, Ud, x, Sx, z, [refactor_rtol]):
#: :mod:`.sparselu`; a sparse J is one row of its values, (1, nnz))
DENSE, BANDED, SPARSE = 0, 1, 2


@jit
def _copy(dst, src):
    """dst[:] = src for arrays of the same size, as a loop: numba's slice
    assignment checks the shapes and builds its error message with them,
    and the compile of that message's code (its string formatting) was
    ~8 s of the step loop's first compile (stretch 54.9 -> 45.4 s of CPU).
    Sizes that differ raise, as the slice assignment did (a fixed message)."""
    if dst.size != src.size:
        raise ValueError("softflow: an array copy between arrays of different sizes")
    for i in range(dst.size):
        dst[i] = src[i]


#: ``lin[13]``'s places: the kind, the band's kl, whether the band's last
#: factors were equilibrated, and the addresses of :func:`far_factor`,
#: :func:`far_solve` and :func:`far_row_maxima` compiled for this ``lin``'s
#: types, each followed by its types' key (:func:`softflow.laws.native_address`;
#: 0 for a dense ``lin``)
KIND, KL, EQUILIBRATED, FACTOR_AT, SOLVE_AT, MAXIMA_AT = 0, 1, 2, 3, 5, 7
LIN_INFO_SIZE = 9


@inline
def lin_factor(lin, pivot_rtol):
    """The Jacobian from the raw entries, factored (:func:`factor`, or
    :func:`far_factor` where ``lin`` is banded or sparse, called through
    its address: the loops that call this compile the dense LU alone).
    Inlined, as :func:`lin_solve`: a call that passes ``lin`` (eighteen
    arrays and tuples, some 150 machine words) costs ~100 ns."""
    if lin[13][KIND] != DENSE:
        return call_native(lin[13][FACTOR_AT], lin[13][FACTOR_AT + 1], (lin, pivot_rtol))
    return factor(lin[0], lin[1], lin[2], lin[3], lin[4], lin[5], lin[6], pivot_rtol)


@jit
def far_factor(lin, pivot_rtol):
    """:func:`lin_factor` of a banded ``lin`` (:func:`band_factor`) or a
    sparse one (:func:`softflow.laws.sparselu.sparse_factor`: its factors
    too large for their arrays count as singular, which hands the step to
    the BDF's own Newton). Compiled on its own, for the first run with a
    banded or sparse LU (:func:`softflow.laws.call_native`)."""
    if lin[13][KIND] == SPARSE:
        if not _assemble(lin[0], lin[1], lin[2]):
            return 1
        si, sx = lin[16], lin[17]
        code = sparse_factor(si[0], si[1], lin[2][0], si[2], si[3], si[4], sx[0], si[5],
                             si[6], sx[1], sx[2], si[7], si[8], si[9], si[10], sx[3], sx[4],
                             lin[5], lin[6], pivot_rtol, sx[6][0], si[11])
        return 0 if code == 0 else 2
    band = lin[13]
    code = band_factor(lin[0], lin[1], lin[2], lin[3], lin[4], lin[5], lin[6],
                       band[KL], pivot_rtol, band[EQUILIBRATED] > 0)
    if code == 0:
        band[EQUILIBRATED] = 0 if lin[5][0] == 1.0 and (lin[5] == 1.0).all() else 1
    elif band[EQUILIBRATED]:            # (once more from the plain factors)
        band[EQUILIBRATED] = 0
        code = band_factor(lin[0], lin[1], lin[2], lin[3], lin[4], lin[5], lin[6],
                           band[KL], pivot_rtol, bool(False))
    return code


@inline
def lin_solve(lin, b, out):
    """out = J^-1 b on the current factors (inlined: see :func:`lin_factor`)."""
    if lin[13][KIND] != DENSE:
        call_native(lin[13][SOLVE_AT], lin[13][SOLVE_AT + 1], (lin, b, out))
    else:
        lu_solve(lin[3], lin[4], lin[5], lin[6], b, out)


@jit
def far_solve(lin, b, out):
    """:func:`lin_solve` on a banded or sparse ``lin``'s factors (compiled
    on its own, as :func:`far_factor`); returns 0."""
    if lin[13][KIND] == SPARSE:
        si, sx = lin[16], lin[17]
        sparse_solve(si[2], si[3], si[4], sx[0], si[5], si[6], sx[1], sx[2], si[8], lin[5],
                     lin[6], b, out, sx[5])
        return 0
    order, tmp = lin[14], lin[15]
    n = b.size
    for i in range(n):
        tmp[0, i] = b[order[0, i]]
    band_solve(lin[3], lin[4], lin[5], lin[6], lin[13][KL], tmp[0], tmp[1])
    for j in range(n):
        out[order[1, j]] = tmp[1, j]
    return 0


@jit
def far_row_maxima(lin, rs):
    """rs[i] = max_j |J_ij| of a sparse ``lin``'s Jacobian (compiled on its
    own, as :func:`far_factor`); returns 0."""
    row_maxima(lin[16][0], lin[16][1], lin[2][0], rs)
    return 0


@jit
def lin_row_scale(lin, rs):
    """rs[i] = 1 / max_j |J_ij| of the current Jacobian's rows
    (:attr:`DenseLU.row_scale`)."""
    J = lin[2]
    kind = lin[13][KIND]
    if kind == SPARSE:
        call_native(lin[13][MAXIMA_AT], lin[13][MAXIMA_AT + 1], (lin, rs))
        for i in range(rs.size):
            rs[i] = 1.0 / max(rs[i], 1e-300)
        return
    for i in range(rs.size):
        r = lin[14][2, i] if kind == BANDED else i
        m = 0.0
        for j in range(J.shape[1]):
            m = max(m, abs(J[r, j]))
        rs[i] = 1.0 / max(m, 1e-300)


def far_addresses(lin):
    """Set ``lin``'s addresses of :func:`far_factor`, :func:`far_solve` and
    :func:`far_row_maxima` where it is banded or sparse (compiled for its
    types now, the first time: about 15-20 s of CPU once per installation,
    then from numba's cache)."""
    info = lin[13]
    if info[KIND] == DENSE:
        return
    probe = np.zeros(0)            # (its type alone: as residual_address's)
    info[FACTOR_AT:FACTOR_AT + 2] = native_address(far_factor, (lin, 0.0))
    info[SOLVE_AT:SOLVE_AT + 2] = native_address(far_solve, (lin, probe, probe))
    info[MAXIMA_AT:MAXIMA_AT + 2] = native_address(far_row_maxima, (lin, probe))


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


@inline
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


@inline
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


@inline
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


@inline
def _begin(net, x, S, t, ist, F, none):
    """The coefficients a network sets at the start of each step (a
    heat-transfer correlation's h A), from the point (x, S): the call-back
    ``ist[BEGIN_KEY]`` at ``ist[BEGIN_AT]`` (:mod:`softflow.solve.usercall`),
    which writes them into the network's floats. False where it raised (the
    caller raises that error once the loop returns)."""
    return call_user(ist[BEGIN_AT], ist[BEGIN_KEY], t, 0.0, False, x, S, F, net[0],
                     none) == 0


@inline
def _evaluate(net, x, S, t, c, jac, F, Sout, stats):
    stats[RESIDUALS] += 1
    if jac:
        stats[JACOBIANS] += 1
    raw, nr, trows, tcols, groups, cols, fpar, u, at = net
    # the residual through its address (net[8], :func:`residual_address`):
    # compiled once, on its own (the overload the Python Newton calls), not
    # again inside each loop that calls it
    return call_native(at[0], at[1], (x, S, float(t), float(c), bool(jac), F, raw, nr, trows,
                                      tcols, groups, cols, fpar, u, Sout))


def residual_address(arrays):
    """``net`` for the loops here: the network's ``arrays`` (raw, n_node_rows,
    trows, tcols, groups, cols, fpar, u: :class:`softflow.solve.netcore.
    CompiledNetwork`) and, last, an array of the address of
    :func:`softflow.laws.network.residual` compiled for their types and
    their key (:func:`softflow.laws.native_address`), which the loops call
    it by."""
    probe = np.zeros(0)
    at = native_address(residual, (probe, probe, 0.0, 0.0, True, probe) + tuple(arrays)
                        + (probe,))
    return tuple(arrays) + (np.array(at, dtype=np.int64),)


@inline
def _chord(net, lin, x0, psi, t, c, fresh, ist, fst, itol, T_idx, x, F, step, F0, none,
           stats, last):
    """Chord iterations from x0 (:meth:`Newton._chord`): SOLVED with the
    solution in x; PLAIN (diverging, an update not finite, no convergence
    within the iterations), CONTRACTING (too slow: x the last iterate) or
    HAND (a residual not finite, a law's refusal, a singular Jacobian). One
    evaluation of the residual per pass (:func:`softflow.laws.inline`):
    at x0 first (with the Jacobian on fresh factors, and a copy of the
    residual into F0), then at each update. ``last``: scratch, the update
    before (an update flipping it back is halved once: FLIP_MATCH)."""
    _copy(x, x0)
    limit = ist[MAX_ITER] if fresh else ist[MAX_REUSE]
    prev = -1.0
    flipped = False
    clip = ist[CLIP] > 0
    for k in range(limit):
        jac = fresh and k == 0
        # Newton damps only to keep the residual finite: the compiled loop
        # leaves that to it
        if _evaluate(net, x, psi, t, c, jac, F, none, stats) >= 0 or not _finite(F):
            return HAND
        if jac:
            stats[FACTORIZATIONS] += 1
            if lin_factor(lin, fst[PIVOT_RTOL]) != 0:
                ist[STALE] = 1
                return HAND
            if lin[7].size:        # the pieces of the laws this Jacobian is of
                regimes(x, net[4], net[5], net[6], lin[7])
            ist[FACTORED] = 1
            ist[AGE] = 0
            ist[STALE] = 0
            fst[LU_DT] = c
            fst[CRATE] = 1.0
            fst[DT_LO], fst[DT_HI] = fst[RATIO_LO] * c, fst[RATIO_HI] * c
            _copy(F0, F)
        lin_solve(lin, F, step)
        nrm = _norm(step, itol)
        stats[ITERATIONS] += 1
        if clip:
            _clip(x, step, T_idx, fst[T_LO], fst[T_HI])
        if not math.isfinite(nrm):
            return PLAIN
        flip = False
        if prev >= 0.0 and nrm >= 0.9 * prev and not flipped and nrm * 0.9 <= prev:
            # flipping about a root where the law's slope is not the
            # Jacobian's (Newton._chord, settings.FLIP_MATCH): half of it
            back = 0.0
            for i in range(x.size):
                v = abs(step[i] + last[i]) * itol[i]
                if not v <= back:
                    back = v
            flip = back <= fst[FLIP_MATCH] * nrm
        if flip:
            flipped = True
            for i in range(x.size):
                step[i] = 0.5 * step[i]
            done = False
        elif prev >= 0.0:
            rate = nrm / prev
            if rate >= 0.9:
                return PLAIN
            fst[ETA] = rate / (1.0 - rate)
            crate = max(rate, fst[CRDOWN] * fst[CRATE])
            fst[CRATE] = crate
            done = nrm * crate <= 1.0 - crate
            if not done and nrm * rate ** (limit - 1 - k) / (1.0 - rate) > 1.0:
                return CONTRACTING
        else:
            done = nrm <= 1.0 or (nrm <= fst[FIRST_MAX]
                                  and nrm * max(fst[ETA], 1e-3) ** 0.8 <= 1.0)
        for i in range(x.size):
            x[i] = x[i] - step[i]
        if done:
            ist[ONE_ITER] = 1 if k == 0 else 0
            if k + 1 >= ist[MAX_REUSE] and not fresh:
                ist[STALE] = 1
            return SOLVED
        prev = nrm
        _copy(last, step)
    # (Newton's F here is the last update's residual, not evaluated here:
    # its worst equation, which the culprit finder reads, is the BDF's)
    return HAND


@jit
def _full(net, lin, psi, t, c, ist, fst, itol, T_idx, work, none, stats, natol, nrtol,
          x_off, q_id, floor, links, damped, factored):
    """Full Newton from work[0] (:meth:`Newton._full`: a Jacobian at each
    iterate, refactored unless the last full step cut the scaled residual
    by 1/KEEP_CUT or more). ``damped``: Newton's full stage (a line search
    on the scaled residual, and its watchdog of undamped steps where that
    finds no decrease; up to twice MAX_ITER iterations), else its undamped
    variant after chord iterations that contracted too slowly (it fails at
    the first full step that neither lowers the residual nor contracts).
    ``factored``: the current factors and work[9] are the Jacobian and the
    residual at work[0] (the fresh chord's at the predictor). Returns
    SOLVED with the solution in work[0]; PLAIN where the undamped variant
    fails as above or runs out of iterations; HAND where a residual is not
    finite, a law refuses an iterate, the Jacobian is singular, or the
    damped stage fails (its messages are Newton's)."""
    x, F, step, xn, Fn, v, rs, jx, it2, F0 = (work[0], work[1], work[2], work[3], work[4],
                                               work[5], work[6], work[7], work[8], work[9])
    n = x.size
    keep_cut = fst[TIGHT_KEEP_CUT] if nrtol <= fst[TIGHT_RTOL] else fst[KEEP_CUT]
    clip = ist[CLIP] > 0
    # the evaluations at x with the Jacobian come at the top of an
    # iteration (``pending``: 1 the residual into F, which must be finite;
    # 2 the Jacobian alone), so that the residual is built into this stage
    # at two places, not five (:func:`softflow.laws.inline`); Newton._full
    # makes them at the end of the iteration before (the last one's, which
    # changes nothing but the count of evaluations, is left out)
    pending = 1
    if factored:
        _copy(F, F0)
        pending = 0
    refactor = True
    watch, f_ref, used = 0, math.inf, False
    limit = 2 * ist[MAX_ITER] if damped else ist[MAX_ITER]
    for k in range(limit):
        if pending:
            out = F if pending == 1 else Fn
            if (_evaluate(net, x, psi, t, c, True, out, none, stats) >= 0
                    or (pending == 1 and not _finite(F))):
                return HAND
            _copy(jx, x)
            pending = 0
        if refactor:
            if not factored:
                stats[FACTORIZATIONS] += 1
                if lin_factor(lin, fst[PIVOT_RTOL]) != 0:
                    ist[STALE] = 1
                    return HAND
                if lin[7].size:
                    regimes(jx, net[4], net[5], net[6], lin[7])
                ist[FACTORED] = 1
                ist[AGE] = 0
                ist[STALE] = 0
                fst[LU_DT] = c
                fst[CRATE] = 1.0
                fst[DT_LO], fst[DT_HI] = fst[RATIO_LO] * c, fst[RATIO_HI] * c
            factored = False
            lin_row_scale(lin, rs)
        f0 = _scaled(F, rs)
        if watch and f0 < (1 - 1e-4) * f_ref:
            watch = 0                 # below the starting residual: monotone again
        lin_solve(lin, F, step)
        stats[ITERATIONS] += 1
        nrm = _norm(step, itol)
        if nrm > 1.0 and k:
            # the tolerances raised to the iterate's magnitudes (Newton._raise_scale)
            _newton_scale(x, natol, nrtol, x_off, q_id, floor, ist[HAS_FLOOR] > 0, links, it2)
            for i in range(n):
                itol[i] = min(itol[i], it2[i])
            nrm = _norm(step, itol)
        if nrm <= 1.0:
            for i in range(n):
                x[i] = x[i] - step[i]
            ist[ONE_ITER] = 1 if k == 0 else 0
            return SOLVED
        if clip:
            _clip(x, step, T_idx, fst[T_LO], fst[T_HI])
        lam, lam_min, lam_prev, f_prev = 1.0, fst[LS_MIN], 0.0, 0.0
        f1 = math.inf
        while not watch:
            for i in range(n):
                xn[i] = x[i] - lam * step[i] if lam != 1.0 else x[i] - step[i]
            # the full step is usually taken: its Jacobian with it
            if _evaluate(net, xn, psi, t, c, lam == 1.0, Fn, none, stats) >= 0:
                return HAND
            if lam == 1.0:
                _copy(jx, xn)
            f1 = _scaled(Fn, rs) if _finite(Fn) else math.inf
            if f1 <= (1 - 1e-4 * lam) * f0 or not refactor:
                break        # descent, or stale factors: refactor at x first (below)
            if lam == 1.0 and f1 < math.inf and _contracts(lin, Fn, v, itol, step):
                break
            if not damped:   # the full step neither descends nor contracts
                return PLAIN
            # (a gross overshoot's length only at the consistent start, c = 0)
            nxt, lam_min = backtrack(lam, f0, f1, lam_prev, f_prev, lam_min,
                                     fst[LS_GROSS] if c == 0.0 else math.inf, fst[LS_DEEP])
            lam_prev, f_prev, lam = lam, f1, nxt
            if lam < lam_min:
                break
        if watch or lam < lam_min:
            if watch == 1 or (not watch and used):
                return HAND          # the line search failed
            if not watch:
                # the watchdog: up to WATCHDOG undamped steps, kept if the
                # residual ends below where it started
                used = True
                watch, f_ref = ist[WATCHDOG] + 1, f0
            watch -= 1
            for i in range(n):
                x[i] = x[i] - step[i]
            pending = 1
            refactor = True
            continue
        if not refactor and not f1 <= (1 - 1e-4) * f0:
            # stale factors: this iterate again on a Jacobian evaluated at x
            refactor = True
            pending = 2
            continue
        refactor = lam < 1.0 or f1 > keep_cut * f0
        _copy(x, xn)
        _copy(F, Fn)
        if refactor and lam < 1.0:        # the Jacobian at the damped iterate
            pending = 2
    return HAND if damped else PLAIN


@jit
def backtrack(lam, f0, f1, lam_prev, f_prev, lam_min, gross, deep):
    """The damped stage's next step length after a trial ``lam`` whose scaled
    residual ``f1`` gave no descent from ``f0`` (the trial before it:
    ``lam_prev``, ``f_prev``; 0 for none), and the smallest length the search
    may go on to (``lam_min``, where it gives up). Half of ``lam``, except
    after a gross overshoot (``f1`` above ``gross`` times ``f0``, and falling
    from the trial before): the residual taken as growing as a power k of the
    length between the two trials (k held to 1 ... 4), the length where that
    power law reaches half of ``f0``, at most half of ``lam``, and the search
    may go on down to ``deep``. Halving alone gives up at its smallest length
    1e4 times short of a step that overshoots 1e10 times (a tube of 1 nm from
    rest, whose laminar slope there is ~1e-13 of the law's slope at the flow
    it carries). Both Newtons' rule (:meth:`softflow.solve.newton.Newton._full`
    and :func:`_full`; the lengths in :mod:`softflow.solve.settings`,
    LINE_SEARCH_*); both pass an infinite ``gross`` but at the consistent
    start: within a run, a solve failing near a law's singular point (a node
    at a tube's choked flow) went on with ever shorter steps that barely
    lowered the residual, ~10x the failure's work."""
    if f0 * gross < f1 < math.inf and 0.0 < lam < lam_prev and f1 < f_prev:
        k = min(max(math.log(f_prev / f1) / math.log(lam_prev / lam), 1.0), 4.0)
        return min(lam * (0.5 * f0 / f1) ** (1.0 / k), 0.5 * lam), min(lam_min, deep)
    return 0.5 * lam, lam_min


@jit
def _scaled(F, rs):
    """The 2-norm of F scaled by rows (the damped stage's residual measure)."""
    s = 0.0
    for i in range(F.size):
        s += (F[i] * rs[i]) ** 2
    return math.sqrt(s)


@jit
def _worst_row(F, lin):
    """The equation whose residual is largest relative to its row of the
    current Jacobian (:meth:`Newton._worst_row`)."""
    n = F.size
    rs = np.empty(n)
    lin_row_scale(lin, rs)
    best, row = -1.0, 0
    for i in range(n):
        v = abs(F[i]) * rs[i]
        if not math.isfinite(v):
            v = math.inf
        if v > best:
            best, row = v, i
    return row


@jit
def _contracts(lin, Fn, v, itol, step):
    lin_solve(lin, Fn, v)
    return _norm(v, itol) <= 0.75 * _norm(step, itol)


@jit
def _positive(x, p_idx):
    for j in range(p_idx.size):
        if not x[p_idx[j]] > 0.0:
            return False
    return True


@inline
def _solve(net, lin, x0, psi, t, c, ist, fst, itol, floor, links, natol, x_off, q_id,
           p_idx, T_idx, work, none, stats, nrtol, mode):
    """Newton's solve of one step (:meth:`Newton.solve`): chord iterations
    on reused factors where they serve the step, then on fresh ones, then,
    by ``mode``: 0 (Newton's full stage on: BDF's steps within
    FULL_STAGE_STEPS of the smallest) the damped full stage (:func:`_full`);
    4 (a restart's probe at 1e-12) as 0, but SOURCES where the chords
    failed on a flow source's region, or before those regions are known
    (ist[WANTS_SOURCES] then set); 1 (BDF's other steps,
    :data:`softflow.solve.bdf.UNDAMPED_FULL`) chord iterations that
    contracted too slowly go on as undamped full Newton; 2 no more; 3 no
    more, and any failure is handed back (backward Euler's steps: its own
    Newton then takes the step, damped stages and all, whose work a
    failing damped stage here would only double). Returns SOLVED with the
    solution in work[0], PLAIN where the solve failed as Newton fails it
    without its damped stages (the BDF cuts the step), HAND where the BDF's
    own Newton must take the step (its damped stages, the culprit
    finder)."""
    x = work[0]
    code = _chords(net, lin, x0, psi, t, c, ist, fst, itol, floor, links, natol, x_off, q_id,
                   p_idx, T_idx, work, none, stats, nrtol)
    if code == SOLVED or code == REFUSED:
        return code
    if code == HAND or mode == 3:
        return HAND
    if mode == 4:
        # a restart's probe at 1e-12: mode 0, unless the chords failed on
        # an equation the culprit finder looks into (a flow source's region;
        # any, while those are not known), where a flow source may ask what
        # no pressure gives (a source's jump at a breakpoint) and the finder,
        # not a damped stage, says so: SOURCES, before that stage (a failing
        # one was most of such a run's work: 114 of its 239 residual
        # evaluations after its last step, a pump behind a shut valve)
        if code == PLAIN or code == CONTRACTING:
            if not ist[REJECT_NEWTON]:
                ist[WANTS_SOURCES] = 1     # (the caller finds them and calls again)
                return SOURCES
            if lin[12][_worst_row(work[1], lin)]:
                return SOURCES
        mode = 0
    if mode == 0 or (code == CONTRACTING and mode == 1):
        # Newton's full stage: damped from the predictor (on the fresh
        # factors made there), or from the chord's last iterate where it
        # contracted; undamped from there (mode 1)
        fresh_x0 = mode == 0 and code != CONTRACTING
        if fresh_x0:
            _copy(x, x0)
        code = _full(net, lin, psi, t, c, ist, fst, itol, T_idx, work, none, stats, natol,
                     nrtol, x_off, q_id, floor, links, mode == 0, fresh_x0)
        if code == SOLVED:
            if not _positive(x, p_idx):
                return REFUSED
            ist[AGE] += 1
            return SOLVED
        return code
    return PLAIN


@inline
def _chords(net, lin, x0, psi, t, c, ist, fst, itol, floor, links, natol, x_off, q_id,
            p_idx, T_idx, work, none, stats, nrtol):
    """Newton's chord stages (:func:`_solve`'s first part; backward Euler's
    whole solve in the loop): SOLVED with the solution in work[0], REFUSED
    (a pressure <= 0), HAND (the fresh chord's, or a second fresh chord's
    from a solution on another piece of a piecewise law that failed), or
    the fresh chord's PLAIN or CONTRACTING."""
    x, F, step = work[0], work[1], work[2]
    _newton_scale(x0, natol, nrtol, x_off, q_id, floor, ist[HAS_FLOOR] > 0, links, itol)
    reusable = (ist[STALE] == 0 and ist[AGE] < ist[MAX_AGE]
                and fst[DT_LO] <= c <= fst[DT_HI])
    # the stages: 0 the reused factors' chord (where they serve), 1 the fresh
    # chord, 2 the fresh chord once more from a solution on another piece of
    # a piecewise law (one call of _chord for all three: it is built into
    # each loop that calls this, and the first compile pays for each copy)
    code = HAND
    stage = 0 if reusable else 1
    while stage < 3:
        start = x0 if stage < 2 else work[4]
        code = _chord(net, lin, start, psi, t, c, stage >= 1, ist, fst, itol, T_idx, x, F,
                      step, work[9], none, stats, work[3])
        if code != SOLVED:
            if stage == 2:
                ist[STALE] = 1
                return HAND
            if stage == 0:
                stage = 1
                continue
            return code
        if not _positive(x, p_idx):
            return REFUSED
        if stage < 2:
            # a piecewise law (a check valve) on another piece than the
            # Jacobian's (Newton.solve): from reused factors, on to the fresh
            # chord; from fresh ones (a valve that closes within the step,
            # its Jacobian evaluated open), once more from there on its own
            # piece's Jacobian, whose result stands (where that fails, the
            # BDF's Newton takes the step: its damped stage starts from the
            # predictor, whose factors these are not)
            r_fact, r_now = lin[7], lin[8]
            off = False
            if r_fact.size:
                regimes(x, net[4], net[5], net[6], r_now)
                for i in range(r_now.size):
                    if r_now[i] != r_fact[i]:
                        off = True
            if off:
                ist[STALE] = 1
                if stage == 0:
                    code = PLAIN
                else:
                    _copy(work[4], x)
                stage += 1
                continue
        ist[AGE] += 1
        return SOLVED
    return code


#: :func:`_solve` compiled on its own, for the restarts' probes: the step's
#: solve is built into the loop (inlined: a call passes some 60 arrays' fields,
#: ~1 us, which each step would pay), the probes' a call (a few a restart), so
#: that the loop's first compile builds one copy of the solve, not two
_solve_apart = jit(getattr(_solve, "py_func", _solve))   # (pure-Python mode: _solve itself)


@inline
def _probe(net, lin, x0, S, t, h, ist, fst, itol, floor, links, natol, x_off, q_id, p_idx,
           T_idx, work, none, stats, sources, Fe, rate, n_disc, atol_s, mode):
    """Backward Euler from (x0, S) at t over h, Newton held to 1e-12 (or the
    run's own tolerance where that fails; not where the solve converged on
    a pressure <= 0), as :meth:`BDF._probe` solves it: at 1e-12 with
    Newton's full stage (the BDF's probes turn it on), at the run's
    tolerance by ``mode`` (:func:`_solve`: 0 with the full stage, 3 the
    chord stages only). SOLVED with the unknowns in work[0] and the states'
    rate in ``rate`` (discrete states: 0), or where the BDF's own probe
    (with continuation) must take over: SOURCES where the chords at 1e-12
    failed on an equation the culprit finder looks into (:func:`_solve`'s
    mode 4: the finder before any damped stage), else HAND; also where a
    failed solve at 1e-12 would go on to Newton's flows-first stage there
    (ist[FLOWS_FIRST]: a thermal network, :meth:`Newton._flows_first`),
    which the loop has not, before the tolerance is loosened."""
    base, slot, codes, factors, starts, floats = sources
    source_values(t + h, base, slot, codes, factors, starts, floats, net[7])
    nrtol = fst[NEWTON_RTOL]
    solved = False
    for tight in range(2):
        if tight == 1 and not nrtol > 1e-12:
            break
        # (at 1e-12 the damped stage, as the BDF's probe: with the chord
        # stages alone there, as mode 3 was, a chord contracting too slowly
        # at 1e-12, common after a breakpoint, went on to the chord at the
        # run's tolerance, which converged on a point the BDF's damped stage
        # does not give: a probe of 5e-9 s on the 63-component water network
        # had states' rates 1e-3 off the BDF's, the first step a predictor
        # Newton could not solve: 77 failed solves in the run, 2 in Python)
        code = _solve_apart(net, lin, x0, S, t + h, h, ist, fst, itol, floor, links, natol,
                            x_off, q_id, p_idx, T_idx, work, none, stats,
                            min(nrtol, 1e-12) if tight == 0 else nrtol,
                            4 if tight == 0 else mode)
        if code == SOLVED:
            solved = True
            break
        ist[STALE] = 1           # (as Newton after a failed solve)
        if code == SOURCES:
            return SOURCES
        if code == REFUSED or ist[FLOWS_FIRST]:   # (the BDF's probe takes it from here)
            break
    if not solved:
        return HAND
    if _evaluate(net, work[0], S, t + h, h, False, Fe, rate, stats) >= 0:
        return HAND
    stats[RESIDUALS] -= 1
    for i in range(S.size):
        rate[i] = (rate[i] - S[i]) / h
        if n_disc and not math.isfinite(atol_s[i]):
            rate[i] = 0.0
    return SOLVED


@jit
def _restart_norm(v, vx, w, m, n_disc, peak_factor, buf):
    """:meth:`BDF._norm`: the error norm of the states' v and the first
    unknowns' vx together."""
    ns = v.size
    buf[:ns] = v
    buf[ns:m] = vx[:m - ns]
    return _enorm(buf, w, m, n_disc, peak_factor)


@inline
def _restart(net, lin, x, S, t, limit, ist, fst, itol, floor, links, natol, x_off, q_id,
             p_idx, T_idx, work, none, stats, sources, atol_s, atol_x, qmax_run, w, Fe,
             x_right, r0, xdot, buf):
    """The rates just after t and the first step (:meth:`BDF._restart`): two
    backward Euler probes of tiny steps, a third over the step the first
    derivatives suggest; the first step aims at an order-1 error estimate
    of FIRST_ESTIMATE. Returns the step, or -1 where a probe needs the
    BDF's own (its damped stages, continuation); then Newton's contraction
    estimates are as they were before the probes, so that the BDF's
    restart starts from the state it would have had without the loop. (One
    probe call in a loop over the three: :func:`softflow.laws.inline`.)"""
    ns, n = S.size, x.size
    eta0, crate0, one0 = fst[ETA], fst[CRATE], ist[ONE_ITER]
    n_disc, m = ist[N_DISC], ist[M_ERR]
    span = limit - t
    h_p = min(max(fst[STEP_MIN], 1e-7 * fst[DURATION]), 0.25 * span)
    rate = np.empty(ns)
    x1 = np.empty(n)
    pf = fst[PEAK_FACTOR]
    h0 = h_p
    for probe in range(3):
        if probe == 0:
            start, step_, out = x, h_p, r0
        elif probe == 1:
            start, step_, out = x1, 2 * h_p, rate
        else:
            if math.isfinite(fst[FIRST_STEP]):
                return max(min(fst[FIRST_STEP], span), fst[STEP_MIN])
            _weights(S, S, x_right, atol_s, atol_x, x_off, q_id, qmax_run, fst[RTOL], w)
            for q in range(floor.size):
                floor[q] = qmax_run[q] * fst[FLOOR_FACTOR]
            ist[HAS_FLOOR] = 1
            d0 = _restart_norm(S, x_right, w, m, n_disc, pf, buf)
            d1 = _restart_norm(r0, xdot, w, m, n_disc, pf, buf)
            h0 = 1e-6 * span if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
            h0 = min(max(h0, 4 * h_p), span, fst[STEP_MAX])
            start, step_, out = x_right, h0, rate
        ok = _probe(net, lin, start, S, t, step_, ist, fst, itol, floor, links, natol, x_off,
                    q_id, p_idx, T_idx, work, none, stats, sources, Fe, out, n_disc, atol_s,
                    0 if probe == 2 or ist[RESTART_DUE] == 2 else 3)
        # a probe not solved here: the BDF's own restart (its continuation).
        # Each probe takes Newton's damped stage at 1e-12, as the BDF's do
        # (after a breakpoint, one that fails there is done twice: here and
        # in the BDF's probe; a chord at 1e-12 contracting too slowly is the
        # usual case, which the damped stage converges in the loop); at the
        # run's tolerance the first two take it only after a mode switch (a
        # snapping valve's: the chord diverges on the new piece, the damped
        # stage converges); after a breakpoint (a source's jump, which may
        # ask what no state gives: the culprit finder's ground) a failing
        # damped stage there would only be done twice
        if ok != SOLVED:
            fst[ETA], fst[CRATE], ist[ONE_ITER] = eta0, crate0, one0
            # which probe failed its solve at 1e-12 (the BDF's probe there
            # goes on at the run's tolerance without solving it again: the
            # same damped stage failing twice was most of a failed run's
            # work; not where the BDF's flows-first stage would follow), or
            # 3 + the probe whose chords failed on a flow source's region
            # (the BDF asks the culprit finder first)
            ist[PROBE_FAILED] = (3 + probe if ok == SOURCES
                                 else -1 if ist[FLOWS_FIRST] else probe)
            return -1.0
        if probe == 0:
            _copy(x1, work[0])
        elif probe == 1:
            for i in range(n):
                xdot[i] = (work[0][i] - x1[i]) / h_p
                x_right[i] = x1[i] - h_p * xdot[i]
    x3 = work[0]
    ddx = np.empty(n)
    for i in range(n):
        ddx[i] = 2 * (x3[i] - x_right[i] - h0 * xdot[i]) / h0 ** 2
    for i in range(ns):
        rate[i] = (rate[i] - r0[i]) / h0
    d2 = _restart_norm(rate, ddx, w, m, n_disc, pf, buf)
    h1 = (math.sqrt(2 * fst[FIRST_ESTIMATE] / d2) if d2 > 1e-15
          else max(1e-6 * span, 1e3 * h0))
    h = min(100 * h0, h1)
    return max(min(h, span, fst[STEP_MAX]), fst[STEP_MIN])


@jit
def _next_break(t, breaks, ist, fst):
    """The first breakpoint after t (the steppers' ``_next_break``), the
    pointer into the sorted breakpoints moved on past t."""
    nxt = fst[NEXT_BREAK]
    if nxt <= t * (1 + 1e-14) + 1e-300:
        ib = ist[IB]
        while ib < breaks.size and breaks[ib] <= t * (1 + 1e-14) + 1e-300:
            ib += 1
        ist[IB] = ib
        nxt = fst[NEXT_BREAK] = breaks[ib] if ib < breaks.size else math.inf
    return nxt


@jit
def _crossing(net, x, S, x_new, S_new, atol_s, g0, g1, modes):
    """The fraction of the step at which the first switching function
    crosses zero, by a secant between the step's ends (the end evaluated
    with the old modes), or -1 where none crosses (:meth:`BDF._crossing`)."""
    groups, cols, fpar = net[4], net[5], net[6]
    switching(x, S, groups, cols, fpar, g0)
    for i in range(S.size):
        modes[i] = S_new[i] if math.isfinite(atol_s[i]) else S[i]
    switching(x_new, modes, groups, cols, fpar, g1)
    theta = math.inf
    for i in range(g0.size):
        if g0[i] < 0.0 and g1[i] >= 0.0:
            v = g0[i] / (g0[i] - g1[i])
            if v < theta:
                theta = v
    return theta if 0.0 < theta <= 1.0 else -1.0


def stretch_scratch(n, ns, width, nQ, nk):
    """The work arrays of :func:`stretch` for n unknowns, ns states, a
    difference table ``width`` wide, nQ quadratures and nk kinks (made by
    the caller, which holds them: the loop borrows them)."""
    return (np.empty(width), np.empty(width), np.empty(width), np.empty(ns + n),
            np.empty(n), np.empty((10, n)), np.empty(ns), np.empty(n), np.empty(0),
            np.empty(nQ), np.empty(n), np.empty(ns), np.empty(n), np.empty(ns + n),
            np.empty(nk), np.empty(nk), np.empty(ns))


@jit
def stretch(t, x, S, D, Q, ist, fst, qmax_run, floor, stats,
            net, lin, sources, tol, rec, dense, events, watch, breaks, G, ERRC, scratch):
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
    ``dense`` (the record buffers), ``events`` (rejections and restarts: t,
    h, cause, error), ``watch`` (the watched states and their floors), the
    run's breakpoints (sorted, inside the run), the BDF's g_j and error
    constants, and the loop's work arrays (:func:`stretch_scratch`). Returns
    (exit, t); x, S, Q and the state arrays are updated in place to the last
    step taken. Every array is used through a view that counts no references
    (:func:`borrowed`): the caller holds them for the call."""
    x, S, D, Q, ist, fst, qmax_run, floor, stats = borrowed(
        (x, S, D, Q, ist, fst, qmax_run, floor, stats))
    net, lin, sources, tol, rec, dense, events, watch, breaks, G, ERRC, scratch = borrowed(
        (net, lin, sources, tol, rec, dense, events, watch, breaks, G, ERRC, scratch))
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
    T = fst[DURATION]
    t_stop = T * (1 - 1e-14)
    n_rec_cap, n_dense_cap, n_ev_cap = rec_t.size, d_D.shape[0], events.shape[0]
    kmax = ist[MAX_ORDER]
    (pred, psi_all, delta, w, itol, work, S_new, Fe, none, Q_new, x_right, r0, xdot,
     buf) = scratch[:14]
    # the sides of the laws' kinks (a check valve shut, opening, open) at the
    # point: a step across one is the BDF's (its dense output, its order)
    g0, g1, modes = scratch[14:]
    kink_at, kink_new = lin[9], lin[10]
    if kink_at.size:
        kinks(x, net[4], net[5], net[6], kink_at)
    used = 0           # steps tried, accepted and rejected (Simulation(max_steps=))
    while t < t_stop:
        if ist[BEGIN_KEY] > 0 and not _begin(net, x, S, t, ist, Fe, none):
            return NEWTON, t
        if ist[N_REC] >= n_rec_cap or ist[N_DENSE] + kmax > n_dense_cap \
                or ist[N_EVENTS] + 2 >= n_ev_cap:
            return FULL, t
        if used >= ist[BUDGET_LEFT]:
            return BUDGET, t
        nxt = _next_break(t, breaks, ist, fst)
        limit = nxt if nxt < T else T
        if ist[RESTART_DUE]:
            h = _restart(net, lin, x, S, t, limit, ist, fst, itol, floor, links, natol, x_off,
                         q_id, p_idx, T_idx, work, none, stats, sources, atol_s, atol_x,
                         qmax_run, w, Fe, x_right, r0, xdot, buf)
            if h < 0.0:
                ist[STALE] = 1
                return RESTART, t
            e = ist[N_EVENTS]
            events[e, 0], events[e, 1], events[e, 2], events[e, 3] = t, h, RESTART_EVENT, 0.0
            ist[N_EVENTS] = e + 1
            D[:, :] = 0.0
            for i in range(ns):
                D[0, i], D[1, i] = S[i], h * r0[i]
            for i in range(n):
                D[0, ns + i], D[1, ns + i] = x_right[i], h * xdot[i]
            for i in range(nQ):
                D[0, ns + n + i], D[1, ns + n + i] = Q[i], h * x_right[q_sel[i]]
            ist[K], ist[N_EQUAL], ist[FAILS] = 1, 0, 0
            ist[RESTART_DUE] = 0
            ist[PASSED] = 0
            fst[H] = h
        k, h = ist[K], fst[H]
        # the step: no overshoot of the limit, no sliver left before it
        h_try = min(h, fst[STEP_MAX], fst[H_CAP], fst[FAIL_CAP])
        # the smallest step, step_min stretched over a sliver included (BDF._propose)
        smallest = h_try <= smin
        if t + h_try >= limit or limit - (t + h_try) < 0.2 * h_try:
            h_try = limit - t
        smallest = smallest or h_try <= smin
        if h_try != h:
            _rescale(D, k, h_try / h)
            fst[H] = h = h_try
            ist[N_EQUAL] = 0
        t_new = t + h
        at_break = t_new == nxt
        t_eval = np.nextafter(t_new, -math.inf) if at_break else t_new
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
        source_values(t_eval, base, slot, codes, factors, starts, floats, u)
        # Newton's full stage only on steps near the smallest (BDF._propose)
        mode = 0 if h <= fst[FULL_STAGE_STEPS] * fst[STEP_MIN] else ist[UNDAMPED]
        code = _solve(net, lin, pred[ns:ns + n], psi, t_eval, c, ist, fst, itol, floor, links,
                      natol, x_off, q_id, p_idx, T_idx, work, none, stats, fst[NEWTON_RTOL],
                      mode)
        if code != SOLVED:
            ist[STALE] = 1
            # a failure the BDF's own Newton reports, or one at the smallest
            # step (a fold's jump, continuation), or one the culprit finder
            # would look into (its nodes of flow sources not yet known, or
            # the worst equation in one's region), or a run logged in
            # detail: the BDF's
            if code != PLAIN or smallest or ist[LOG_SWITCHES]:
                return NEWTON, t
            if not ist[REJECT_NEWTON]:
                # (the caller may find those nodes and call again)
                ist[WANTS_SOURCES] = 1
                return NEWTON, t
            if lin[12][_worst_row(work[1], lin)]:
                return NEWTON, t
            # rejected as BDF._newton_failed rejects it: a quarter of the step
            stats[REJECTED] += 1
            stats[NEWTON_FAILS] += 1
            used += 1
            e = ist[N_EVENTS]
            events[e, 0], events[e, 1], events[e, 2], events[e, 3] = t_new, h, NEWTON_EVENT, 0.0
            ist[N_EVENTS] = e + 1
            ist[FAILS_HERE] += 1
            factor_ = max(0.25, fst[STEP_MIN] / h)
            _rescale(D, k, factor_)
            fst[H] = h * factor_
            ist[N_EQUAL] = 0
            continue
        x_new = work[0]
        # the end-of-step states, from the network's own laws
        if _evaluate(net, x_new, psi, t_eval, c, False, Fe, S_new, stats) >= 0:
            return NEWTON, t
        stats[RESIDUALS] -= 1         # (no equation solved: the states' update)
        switched = False
        if n_disc:
            for i in range(ns):
                if S_new[i] != S[i] and not math.isfinite(atol_s[i]):
                    switched = True
            # a switch logged in detail, or one at the smallest steps (a mode
            # that may chatter): the BDF's
            if switched and (ist[LOG_SWITCHES] or h <= fst[CHATTER_STEP] * fst[STEP_MIN]):
                return SWITCH, t
        # a law's kink (a check valve that shuts or opens) inside the step:
        # taken as the BDF's _take takes it, below
        kinked = False
        if kink_at.size:
            kinks(x_new, net[4], net[5], net[6], kink_new)
            for i in range(kink_new.size):
                if kink_new[i] != kink_at[i]:
                    kinked = True
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
            if smallest:
                return FORCED, t
            stats[REJECTED] += 1
            stats[ERROR_FAILS] += 1
            used += 1
            e = ist[N_EVENTS]
            events[e, 0], events[e, 1], events[e, 2], events[e, 3] = t_new, h, ERROR_EVENT, err
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
        # a mode switched: the step is shortened to end just past the
        # crossing where the part past it moves the solution by more than
        # the tolerance (BDF._switch_rejected)
        if switched and not smallest:
            for i in range(ns):
                buf[i] = S_new[i] - S[i]
            for i in range(n):
                buf[ns + i] = x_new[i] - x[i]
            motion = _enorm(buf, w, ns + n, n_disc, fst[PEAK_FACTOR])
            theta = -1.0
            if motion > 1.0 and ist[SECANT_TRIES] < ist[MAX_SECANT]:
                theta = _crossing(net, x, S, x_new, S_new, atol_s, g0, g1, modes)
            past = 1.0 if theta < 0.0 else 1.0 - theta
            if motion * past > 1.0:
                stats[REJECTED] += 1
                used += 1
                e = ist[N_EVENTS]
                events[e, 0], events[e, 1], events[e, 2], events[e, 3] = t_new, h, SWITCH_EVENT, 0.0
                ist[N_EVENTS] = e + 1
                if theta >= 0.0:
                    ist[SECANT_TRIES] += 1
                    past = min(fst[SWITCH_PAST], 0.5 / max(motion * theta, 1.0))
                    factor_ = max(theta * (1.0 + past), fst[STEP_MIN] / h)
                else:
                    factor_ = max(0.5, fst[STEP_MIN] / h)
                    fst[H_CAP] = h * factor_
                    ist[CAP_HOLD] = ist[HOLD_STEPS]
                _rescale(D, k, factor_)
                fst[H] = h * factor_
                ist[N_EQUAL] = 0
                continue
        ist[SECANT_TRIES] = 0
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
        if ist[CAP_HOLD]:          # the switch did not come back: stop locating it
            ist[CAP_HOLD] -= 1
            if not ist[CAP_HOLD]:
                fst[H_CAP] = math.inf
        stats[STEPS] += 1
        stats[RESIDUALS_AT_STEP] = stats[RESIDUALS]
        stats[7 + k] += 1
        ist[FAILS_HERE] = 0
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
        # (across a kink the step's polynomial, smooth through the points
        # before, overshoots it: dense output reads the straight line, D_1)
        kd = 1 if kinked else k
        d_t[e], d_h[e], d_k[e], d_row[e] = t_new, h, kd, r
        for i in range(kd):
            for j in range(d_cols.size):
                d_D[dn + i, j] = D[1 + i, d_cols[j]]
        ist[N_DENSE] = dn + kd
        if kinked:
            _copy(kink_at, kink_new)
        ist[PASSED] = 1
        t = t_new
        _copy(x, x_new)
        _copy(S, S_new)
        _copy(Q, Q_new)
        used += 1
        if at_break or switched:
            # a declared jump, or a mode switched: the method restarts from
            # the far side
            if switched:
                e = ist[N_EVENTS]
                events[e, 0], events[e, 1], events[e, 2], events[e, 3] = t, h, SWITCH_EVENT, 1.0
                ist[N_EVENTS] = e + 1
            ist[RESTART_DUE] = 2 if switched else 1
            fst[FAIL_CAP] = fst[H_CAP] = math.inf
            ist[FAIL_HOLD] = ist[CAP_HOLD] = 0
            ist[STALE] = 1
            continue
        if kinked:
            # the history from before a kink extrapolates a smooth trajectory
            # past it: on at order 1, the order free to rise once k + 1
            # steps lie past the kink (BDF._take)
            if k > 1:
                D[2:, :] = 0.0
                ist[K] = 1
            ist[N_EQUAL] = 0
            continue
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
    return DONE, t


@jit
def start_solve(x, S, ist, fst, floor, stats, net, lin, sources, tol, scratch):
    """The consistent point at t = 0 (dt = 0, the states S at their initial
    values) solved from x as Newton solves it (:meth:`Newton.solve`: chord
    iterations on fresh factors, then the damped full stage), in one call,
    for :meth:`softflow.solve.integrator.Integrator._solve_initial` where no
    component may impose a flow and no node has a temperature (the Python
    solve's hooks and stages beyond these do not apply). Returns
    :func:`_solve`'s code, the solution in x where SOLVED. ``scratch``: as
    :func:`fixed_scratch`'s. Every array is borrowed, as in :func:`stretch`."""
    x, S, ist, fst, floor, stats = borrowed((x, S, ist, fst, floor, stats))
    net, lin, sources, tol, scratch = borrowed((net, lin, sources, tol, scratch))
    atol_s, atol_x, x_off, q_id, natol, links, p_idx, T_idx, q_sel = tol
    base, slot, codes, factors, starts, floats = sources
    itol, work, S_new, Fe, none, x_pred = scratch
    source_values(0.0, base, slot, codes, factors, starts, floats, net[7])
    _copy(x_pred, x)
    code = _solve(net, lin, x_pred, S, 0.0, 0.0, ist, fst, itol, floor, links, natol,
                  x_off, q_id, p_idx, T_idx, work, none, stats, fst[NEWTON_RTOL], 0)
    if code == SOLVED:
        _copy(x, work[0])
    return code


def fixed_scratch(n, ns):
    """The work arrays of :func:`fixed_stretch` (see :func:`stretch_scratch`)."""
    return (np.empty(n), np.empty((10, n)), np.empty(ns), np.empty(n), np.empty(0),
            np.empty(n))


@jit
def fixed_stretch(t, x, S, x_prev, ist, fst, floor, stats, net, lin, sources, tol, rec,
                  watch, breaks, grid, scratch):
    """Steps of backward Euler on its fixed grid from (t, x, S)
    (:class:`softflow.solve.integrator.ImplicitEuler`: psi = S, c = h, Newton
    from the linear extrapolation of the last two points, from the last
    point after a breakpoint), until an event: a failed solve (the stepper
    cuts the step), a mode switch, a volume past its limit, a full record
    buffer, the step budget, the end. ``x_prev``: the point before (its
    step in fst[H]; fst[ERR] < 0 where there is none to extrapolate from);
    ``grid``: (step, number of grid steps); ist[FAILS] holds the index of
    the last grid point reached; ``scratch``: the work arrays
    (:func:`fixed_scratch`). Returns (exit, t). Every array is borrowed, as
    in :func:`stretch`."""
    x, S, x_prev, ist, fst, floor, stats = borrowed((x, S, x_prev, ist, fst, floor, stats))
    net, lin, sources, tol, rec, watch, breaks, grid, scratch = borrowed(
        (net, lin, sources, tol, rec, watch, breaks, grid, scratch))
    atol_s, atol_x, x_off, q_id, natol, links, p_idx, T_idx, q_sel = tol
    rec_t, rec_x, rec_s, rec_q, x_index, s_index = rec
    w_index, w_floor = watch
    base, slot, codes, factors, starts, floats = sources
    u = net[7]
    ns, n = S.size, x.size
    n_disc = ist[N_DISC]
    T = fst[DURATION]
    t_stop = T * (1 - 1e-14)
    h0, n_grid = grid[0], int(grid[1])
    itol, work, S_new, Fe, none, x_pred = scratch
    used = 0
    while t < t_stop:
        if ist[BEGIN_KEY] > 0 and not _begin(net, x, S, t, ist, Fe, none):
            return NEWTON, t
        if ist[N_REC] >= rec_t.size:
            return FULL, t
        if used >= ist[BUDGET_LEFT]:
            return BUDGET, t
        nxt = _next_break(t, breaks, ist, fst)
        kg = ist[FAILS]
        grid_next = T if kg + 1 >= n_grid else min((kg + 1) * h0, T)
        end = nxt if nxt < grid_next else grid_next
        h = end - t
        if fst[ERR] < 0.0:
            _copy(x_pred, x)
        else:
            r = h / fst[H]
            if r == 1.0:
                for i in range(n):
                    x_pred[i] = x[i] + (x[i] - x_prev[i])
            else:
                for i in range(n):
                    x_pred[i] = x[i] + (x[i] - x_prev[i]) * r
        t_new = t + h
        at_break = t_new == nxt
        t_eval = np.nextafter(t_new, -math.inf) if at_break else t_new
        source_values(t_eval, base, slot, codes, factors, starts, floats, u)
        if _chords(net, lin, x_pred, S, t_eval, h, ist, fst, itol, floor, links, natol,
                   x_off, q_id, p_idx, T_idx, work, none, stats, fst[NEWTON_RTOL]) != SOLVED:
            ist[STALE] = 1
            return NEWTON, t
        x_new = work[0]
        if _evaluate(net, x_new, S, t_eval, h, False, Fe, S_new, stats) >= 0:
            return NEWTON, t
        stats[RESIDUALS] -= 1
        if t_new != end and abs(t_new - end) <= 1e-12 * max(1.0, end):
            t_new = end
            at_break = t_new == nxt
        for j in range(w_index.size):
            if S_new[w_index[j]] < w_floor[j]:
                return EMPTIED, t
        if n_disc and not at_break:
            for i in range(ns):
                if S_new[i] != S[i] and not math.isfinite(atol_s[i]):
                    return SWITCH, t
        used += 1
        stats[STEPS] += 1
        stats[RESIDUALS_AT_STEP] = stats[RESIDUALS]
        r_ = ist[N_REC]
        rec_t[r_] = t_new
        for i in range(x_index.size):
            rec_x[r_, i] = x_new[x_index[i]]
        for i in range(s_index.size):
            rec_s[r_, i] = S_new[s_index[i]]
        ist[N_REC] = r_ + 1
        if t_new == grid_next:
            ist[FAILS] = kg + 1
        if at_break:
            fst[ERR] = -1.0
            ist[STALE] = 1
        else:
            _copy(x_prev, x)
            fst[H] = h
            fst[ERR] = 0.0
        t = t_new
        _copy(x, x_new)
        _copy(S, S_new)
    return DONE, t


#: how a variant's run on :func:`variants` ended, beside the EXITS of the
#: stretch that stopped it: its start's solve failed (whatever Newton's
#: code), the records' room ran out (the variant is run again once the
#: caller gave more)
START_FAILED, NO_ROOM = -1, -2


@jit
def variants(j0, j1, given, first, net0, lin, start_lin, tol, start_tol, rec, dense, events,
             w_index, G, ERRC, scratch, start_scratch, work, out, pos, meta, totals):
    """The variants j0 <= j < j1 of one scene, each its own run of the BDF on
    its own clock: the consistent start solved from its initial values
    (:func:`start_solve`, then solved again from its solution, fresh
    factors at it, while that takes more than one iteration, up to three
    times: the Python start's confirmation) and its steps by
    :func:`stretch` to the end, one after the other, every variant from the
    same first state of the loop (``first``). For the batched engine
    (:mod:`softflow.solve.variants`, which makes the arguments; several
    threads may each run a range of variants, each with work arrays of its
    own: the loop holds no lock).

    ``given``: the variants' own arrays, one row each (initial unknowns and
    states, the network's floats and source values, the sources'
    descriptions padded (base, slot, codes, factors, starts, floats) with
    their number of signals, the watched volumes' floors, the breakpoints
    padded and their number); ``first``: the
    loop's ``ist`` and ``fst`` at a run's first stretch, the start's, Newton's
    floor and the run's magnitudes; ``net0``: the network's arrays (its
    floats and source values replaced by each variant's); ``lin``, ``tol``,
    ``rec``, ``dense``, ``events``, ``G``, ``ERRC``, ``scratch``
    as :func:`stretch` takes them (``start_lin``, ``start_tol`` and
    ``start_scratch`` for the start's solve: its dense LU, whatever the
    loop's), ``w_index`` the watched states; ``work``: the
    point, difference table, quadratures and state arrays the runs work in.

    Each variant's points (its start's included) go to ``out`` (t, x, S,
    Q rows, and each point's step, order and first row of its differences
    in the last of ``out``, the dense output's entries) from row ``pos[0]``
    on (the differences from row ``pos[1]``); ``meta`` receives per variant its first
    row, its number of points, how it ended (DONE, another of the EXITS,
    :data:`START_FAILED`), its accepted and rejected steps; ``totals`` the
    counters of all. Returns the next variant to run: j1, or the variant
    whose points did not fit in ``out`` (its row count is then NO_ROOM and
    it is run again from its start when called again)."""
    X0, S00, FPAR, U, BASE, SLOT, CODES, FACTORS, STARTS, FLOATS, M, WFLOOR, BREAKS, NB = given
    ist0, fst0, sist0, sfst0, floor0, qmax0 = first
    x, S, D, Q, ist, fst, sist, sfst, floor, qmax_run, stats, counters, u = work
    out_t, out_x, out_s, out_q, out_h, out_k, out_off, out_D = out
    v_first, v_count, v_code, v_steps, v_rejected = meta
    rec_t, rec_x, rec_s, rec_q, x_index, s_index = rec
    d_t, d_h, d_k, d_row, d_D, d_cols = dense
    cap, d_cap = out_t.size, out_D.shape[0]
    for j in range(j0, j1):
        net = (net0[0], net0[1], net0[2], net0[3], net0[4], net0[5], FPAR[j], u, net0[8])
        m = M[j]
        sources = (BASE[j], SLOT[j], CODES[j][:m], FACTORS[j][:m], STARTS[j][:m], FLOATS[j])
        watch = (w_index, WFLOOR[j])
        breaks = BREAKS[j][:NB[j]]
        start, d_start = pos[0], pos[1]
        v_first[j], v_count[j], v_steps[j], v_rejected[j] = start, 0, 0, 0
        # the consistent start
        _copy(x, X0[j])
        _copy(S, S00[j])
        _copy(sist, sist0)
        _copy(sfst, sfst0)
        _copy(floor, floor0)
        counters[:] = 0
        code = start_solve(x, S, sist, sfst, floor, counters, net, start_lin, sources,
                           start_tol, start_scratch)
        tries = 0
        while code == SOLVED and tries < 3:
            done_before = counters[ITERATIONS]
            sist[STALE] = 1
            sfst[DT_LO], sfst[DT_HI] = 1.0, -1.0
            code = start_solve(x, S, sist, sfst, floor, counters, net, start_lin, sources,
                               start_tol, start_scratch)
            tries += 1
            if counters[ITERATIONS] - done_before <= 1:
                break
        if code != SOLVED:
            for c in range(counters.size):
                totals[c] += counters[c]
            v_code[j] = START_FAILED
            continue
        if start >= cap:
            v_count[j] = NO_ROOM
            return j
        out_t[start] = 0.0
        out_x[start, :] = x
        out_s[start, :] = S
        out_q[start, :] = 0.0
        out_h[start], out_k[start], out_off[start] = 0.0, 0, d_start
        row, d_row_ = start + 1, d_start
        # the steps, from the loop's first state with the start's estimates
        _copy(ist, ist0)
        _copy(fst, fst0)
        ist[IB] = 0
        fst[NEXT_BREAK] = breaks[0] if breaks.size else math.inf
        ist[ONE_ITER] = sist[ONE_ITER]
        fst[ETA], fst[CRATE] = sfst[ETA], sfst[CRATE]
        _copy(floor, floor0)
        _copy(qmax_run, qmax0)
        D[:, :] = 0.0
        Q[:] = 0.0
        stats[:] = 0
        t = 0.0
        used = 0
        exit_ = DONE
        room = True
        while True:
            exit_, t = stretch(t, x, S, D, Q, ist, fst, qmax_run, floor, stats, net, lin,
                               sources, tol, rec, dense, events, watch, breaks, G, ERRC,
                               scratch)
            taken = ist[N_REC]
            if row + taken > cap or d_row_ + ist[N_DENSE] > d_cap:
                room = False
                break
            dd = 0
            for r in range(taken):
                out_t[row + r] = rec_t[r]
                for i in range(x_index.size):
                    out_x[row + r, x_index[i]] = rec_x[r, i]
                for i in range(s_index.size):
                    out_s[row + r, s_index[i]] = rec_s[r, i]
                out_q[row + r, :] = rec_q[r, :]
                # the step's polynomial (the dense output's entry)
                k = d_k[r]
                out_h[row + r], out_k[row + r], out_off[row + r] = d_h[r], k, d_row_
                out_D[d_row_:d_row_ + k, :] = d_D[dd:dd + k, :]
                dd += k
                d_row_ += k
            row += taken
            ist[N_REC] = ist[N_DENSE] = ist[N_EVENTS] = 0
            now = stats[STEPS] + stats[REJECTED]
            ist[BUDGET_LEFT] -= now - used
            used = now
            if exit_ != FULL:
                break
        if not room:            # (its work is counted where it is run again)
            v_count[j] = NO_ROOM
            return j
        for c in range(stats.size):
            totals[c] += stats[c] + counters[c]
        pos[0], pos[1] = row, d_row_
        v_count[j] = row - start
        v_code[j] = exit_
        v_steps[j], v_rejected[j] = stats[STEPS], stats[REJECTED]
    return j1
