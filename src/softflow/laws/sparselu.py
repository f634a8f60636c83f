"""A sparse LU for the compiled step loop: the Jacobians of large networks
(thousands of unknowns, a few nonzeros per row, wide bands) factored and
solved without leaving compiled code.

The method is the left-looking LU with partial pivoting of Gilbert and
Peierls (SIAM J. Sci. Stat. Comput. 9 (1988) 862-874), as KLU uses it for
circuit matrices (Davis and Palamadai Natarajan, ACM TOMS 37 (2010) 36):
columns are taken in a fill-reducing order ``Q`` chosen once per network
(SuperLU's COLAMD ordering, :mod:`softflow.solve.steploop`); for each column
a depth-first search through the columns of L already computed gives the
nonzero pattern of the column in topological order, a sparse triangular
solve gives its values, and the largest entry among the rows not yet
pivoted becomes the pivot. The work is proportional to the arithmetic, so a
network's Jacobian of 4 000 unknowns with ~10 000 nonzeros and little fill
factors in tens of microseconds.

Storage (all preallocated by the caller; a factorization that needs more
than the arrays hold returns :data:`CAPACITY`, and the caller factors in
Python instead):

- the matrix: compressed columns ``Ap`` (n + 1), ``Ai`` (row of each entry),
  values ``Ax`` (the caller's order; duplicates summed);
- L, unit lower triangular, by columns: ``Lp``, ``Li`` (rows in pivot
  order: the column of L whose pivot row it is), ``Lx``;
- U by columns without its diagonal: ``Up``, ``Ui`` (pivot-order row, i.e.
  the column of L whose pivot row it is), ``Ux``; the diagonal ``Ud``;
- ``pinv`` (original row -> its pivot column, -1 before), ``prow`` (pivot
  column -> original row), ``Ar`` (each entry's row in pivot order);
- ``iw`` (4 n integers of work), ``x`` (n floats of work, zero between
  calls).

So that ``A[prow, Q] = L U`` with ``L[Li, k] = Lx`` below its unit diagonal.
"""
from __future__ import annotations

import math

from . import inline, jit

#: what :func:`sparse_lu` returns besides the pivots' range
OK, SINGULAR, CAPACITY = 0, 2, 3

#: the smallest normal float: the solves store smaller values as 0 (as the
#: dense solves of :mod:`softflow.laws.stepper`)
TINY = 2.2250738585072014e-308


@inline
def _reach(i0, j, Lp, Li, pinv, mark, xi, top, stack, pstack):
    """Push onto ``xi[:top]`` (downwards) the rows reachable from row ``i0``
    through the columns of L computed so far, in reverse post-order (a
    topological order of the triangular solve); ``mark[i] == j``: row i
    seen in column j. Returns the new top."""
    head = 0
    stack[0] = i0
    while head >= 0:
        i = stack[head]
        k = pinv[i]
        if mark[i] != j:
            mark[i] = j
            pstack[head] = Lp[k] if k >= 0 else 0
        done = True
        if k >= 0:
            p, end = pstack[head], Lp[k + 1]
            while p < end:
                r = Li[p]
                p += 1
                if mark[r] != j:
                    pstack[head] = p          # where to go on in this column
                    head += 1
                    stack[head] = r
                    done = False
                    break
        if done:
            head -= 1
            top -= 1
            xi[top] = i
    return top


@jit
def sparse_lu(Ap, Ai, Ax, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, pinv, prow, Ar, iw, x):
    """The LU factors of the matrix (``Ap``, ``Ai``, ``Ax``) with its columns
    in the order ``Q`` and rows by partial pivoting, into the arrays of the
    module docstring. Returns (code, smallest |pivot|, largest |pivot|):
    :data:`OK`, :data:`SINGULAR` (a column without a nonzero pivot) or
    :data:`CAPACITY` (L or U longer than its arrays)."""
    n = Q.size
    xi, stack, pstack, mark = iw[:n], iw[n:2 * n], iw[2 * n:3 * n], iw[3 * n:4 * n]
    for i in range(n):
        pinv[i] = -1
        mark[i] = -1
        x[i] = 0.0            # (zero again after each column, and so on return)
    d_min, d_max = math.inf, 0.0
    lnz = unz = 0
    Lp[0] = Up[0] = 0
    for j in range(n):
        q = Q[j]
        top = n
        for p in range(Ap[q], Ap[q + 1]):
            if mark[Ai[p]] != j:
                top = _reach(Ai[p], j, Lp, Li, pinv, mark, xi, top, stack, pstack)
        for p in range(Ap[q], Ap[q + 1]):
            x[Ai[p]] += Ax[p]
        # the triangular solve with the columns of L the pattern reaches
        for p in range(top, n):
            i = xi[p]
            k = pinv[i]
            if k < 0:
                continue
            xk = x[i]
            if xk != 0.0:
                for e in range(Lp[k], Lp[k + 1]):
                    x[Li[e]] -= Lx[e] * xk
        # U's column above the diagonal, and the pivot among the rows left
        ipiv, amax = -1, -1.0
        for p in range(top, n):
            i = xi[p]
            k = pinv[i]
            if k >= 0:
                if unz >= Ui.size:
                    return CAPACITY, d_min, d_max
                Ui[unz] = k
                Ux[unz] = x[i]
                unz += 1
            else:
                a = abs(x[i])
                if a > amax:
                    ipiv, amax = i, a
        if ipiv < 0 or not amax > 0.0:
            return SINGULAR, 0.0, d_max
        d = x[ipiv]
        Ud[j] = d
        pinv[ipiv] = j
        prow[j] = ipiv
        d_min = min(d_min, amax)
        d_max = max(d_max, amax)
        r = 1.0 / d
        for p in range(top, n):
            i = xi[p]
            if pinv[i] < 0:
                if lnz >= Li.size:
                    return CAPACITY, d_min, d_max
                Li[lnz] = i
                Lx[lnz] = x[i] * r
                lnz += 1
        Lp[j + 1] = lnz
        Up[j + 1] = unz
        for p in range(top, n):
            x[xi[p]] = 0.0
    # L's rows and the matrix's in pivot order, U's columns sorted: what
    # the refactorization and the solves read
    for e in range(lnz):
        Li[e] = pinv[Li[e]]
    for p in range(Ap[n]):
        Ar[p] = pinv[Ai[p]]
    sort_columns(Up, Ui, Ux)
    return OK, d_min, d_max


@jit
def sort_columns(Up, Ui, Ux):
    """U's columns with their rows in increasing order (insertion sort: the
    columns are short), as :func:`sparse_refactor` takes them."""
    for j in range(Up.size - 1):
        for e in range(Up[j] + 1, Up[j + 1]):
            k, v = Ui[e], Ux[e]
            f = e - 1
            while f >= Up[j] and Ui[f] > k:
                Ui[f + 1] = Ui[f]
                Ux[f + 1] = Ux[f]
                f -= 1
            Ui[f + 1] = k
            Ux[f + 1] = v


@jit
def sparse_refactor(Ap, Ar, Ax, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, x, pivot_rtol):
    """The factors of a matrix of the same pattern as the one :func:`sparse_lu`
    factored last, on its row order: no search, the triangular solves alone
    (KLU's refactorization). Returns (code, smallest |pivot|, largest
    |pivot|); :data:`SINGULAR` where a pivot is zero or below ``pivot_rtol``
    times its column's largest entry below it (the old row order no longer
    serves: factor again with :func:`sparse_lu`)."""
    n = Q.size
    d_min, d_max = math.inf, 0.0
    for j in range(n):
        q = Q[j]
        for p in range(Ap[q], Ap[q + 1]):
            x[Ar[p]] += Ax[p]
        for e in range(Up[j], Up[j + 1]):
            k = Ui[e]
            xk = x[k]
            x[k] = 0.0
            Ux[e] = xk
            if xk != 0.0:
                for f in range(Lp[k], Lp[k + 1]):
                    x[Li[f]] -= Lx[f] * xk
        d = x[j]
        x[j] = 0.0
        ad = abs(d)
        below = 0.0
        for e in range(Lp[j], Lp[j + 1]):
            below = max(below, abs(x[Li[e]]))
        if not ad > pivot_rtol * below or ad == 0.0:
            for e in range(Lp[j], Lp[j + 1]):
                x[Li[e]] = 0.0
            return SINGULAR, 0.0, d_max
        Ud[j] = d
        d_min = min(d_min, ad)
        d_max = max(d_max, ad)
        r = 1.0 / d
        for e in range(Lp[j], Lp[j + 1]):
            Lx[e] = x[Li[e]] * r
            x[Li[e]] = 0.0
    return OK, d_min, d_max


@jit
def sparse_solve(Q, Lp, Li, Lx, Up, Ui, Ux, Ud, prow, ir, ic, b, out, z):
    """out = C (R A C)^-1 R b from the factors of :func:`sparse_lu` (row and
    column scales ir, ic: ones where A was factored as it is; ``z``: n
    floats of work); subnormal values are stored as 0 (:data:`TINY`)."""
    n = Q.size
    for k in range(n):
        i = prow[k]
        z[k] = ir[i] * b[i]
    # L y = P R b, in pivot order
    for k in range(n):
        y = z[k]
        if abs(y) < TINY:
            y = 0.0
            z[k] = 0.0
        if y != 0.0:
            for e in range(Lp[k], Lp[k + 1]):
                z[Li[e]] -= Lx[e] * y
    # U w = y, by columns from the last
    for j in range(n - 1, -1, -1):
        w = z[j] / Ud[j]
        if abs(w) < TINY:
            w = 0.0
        z[j] = w
        if w != 0.0:
            for e in range(Up[j], Up[j + 1]):
                z[Ui[e]] -= Ux[e] * w
    for j in range(n):
        c = Q[j]
        out[c] = z[j] * ic[c]


@jit
def row_maxima(Ap, Ai, Ax, out):
    """out[i] = max |A_ij| over the stored entries of row i (0 for none)."""
    for i in range(out.size):
        out[i] = 0.0
    for c in range(Ap.size - 1):
        for p in range(Ap[c], Ap[c + 1]):
            out[Ai[p]] = max(out[Ai[p]], abs(Ax[p]))


@jit
def _equilibrate(Ap, Ai, Ax, Sx, ir, ic):
    """Sx = the matrix's rows then columns scaled to a largest entry of 1
    (row maxima into ir, the scaled columns' into ic); False where a row or
    column is all zero."""
    n = ir.size
    row_maxima(Ap, Ai, Ax, ir)
    for i in range(n):
        if not ir[i] > 0.0:
            return False
    for c in range(n):
        m = 0.0
        for p in range(Ap[c], Ap[c + 1]):
            m = max(m, abs(Ax[p] / ir[Ai[p]]))
        if not m > 0.0:
            return False
        ic[c] = m
        for p in range(Ap[c], Ap[c + 1]):
            Sx[p] = (Ax[p] / ir[Ai[p]]) / m
    return True


@jit
def _factor_once(Ap, Ai, Ax, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, pinv, prow, Ar, iw, x, Sx, ir,
                 ic, pivot_rtol, refactor_rtol, scaled, state):
    # one factorization, as the matrix is or equilibrated: on the last row
    # order where ``reuse`` and its pivots hold, else with a new one
    n = Q.size
    if scaled:
        if not _equilibrate(Ap, Ai, Ax, Sx, ir, ic):
            return SINGULAR, False
        M = Sx
    else:
        M = Ax
    code, d_min, d_max = SINGULAR, 0.0, 0.0
    if state[0] > 0:
        code, d_min, d_max = sparse_refactor(Ap, Ar, M, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, x,
                                             refactor_rtol)
        if code == OK:
            state[3] += 1
    if code != OK:
        state[2] += 1
        code, d_min, d_max = sparse_lu(Ap, Ai, M, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, pinv, prow,
                                       Ar, iw, x)
        if code != OK:
            return code, False
    if not d_min > pivot_rtol * max(d_max, 1e-300):
        return SINGULAR, True
    if scaled:
        for i in range(n):
            ir[i] = 1.0 / ir[i]
            ic[i] = 1.0 / ic[i]
    else:
        for i in range(n):
            ir[i] = 1.0
            ic[i] = 1.0
    return OK, True


@jit
def sparse_factor(Ap, Ai, Ax, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, pinv, prow, Ar, iw, x, Sx, ir,
                  ic, pivot_rtol, refactor_rtol, state):
    """The factors of the matrix (``Ap``, ``Ai``, ``Ax``) with the singularity
    test of the dense and banded factorizations
    (:func:`softflow.laws.stepper.factor`): as it is where its pivots pass,
    else rows then columns scaled to a largest entry of 1 (``Sx``: the
    scaled values, nnz floats; ``ir``, ``ic`` the scales as
    :func:`sparse_solve` takes them). ``state``: [a row order to reuse
    (:func:`sparse_refactor`, its pivots at least ``refactor_rtol`` of their
    column), the last factors were equilibrated (tried so at once: a
    network's units do not change between steps), the factorizations with
    a new row order so far, the refactorizations so far], updated. Returns
    0, 2 (singular) or 3 (capacity: the caller factors otherwise)."""
    args = (Ap, Ai, Ax, Q, Lp, Li, Lx, Up, Ui, Ux, Ud, pinv, prow, Ar, iw, x, Sx, ir, ic)
    scaled = state[1] > 0
    code, valid = _factor_once(*args, pivot_rtol, refactor_rtol, scaled, state)
    state[0] = 1 if valid else 0
    if code == OK or code == CAPACITY:
        return code
    # the other way: equilibrated where plain failed, plain where scaled did
    code, valid = _factor_once(*args, pivot_rtol, refactor_rtol, not scaled, state)
    state[0] = 1 if valid else 0
    if code == OK:
        state[1] = 0 if scaled else 1
    return code
