"""Dense output in compiled passes (:mod:`softflow.solve.dense`):

- :func:`dense_terms`, the sum of each step's backward differences weighted
  by the interpolating polynomial's coefficients at the asked times
  (:meth:`~softflow.solve.dense.DenseOutput.on`), point by point, without
  the NumPy temporaries of a gather per term (at refine='auto' the air
  chain of 200 tubes at rtol 1e-6, 1 711 points of 1 804 columns, spent
  0.16 s of its 0.2 s run there; now 0.06 s, bitwise the same values);
- :func:`refine_counts`, the points per step that refine='auto' records;
- :func:`interior`, those points inserted among the steps' own, each with
  :meth:`~softflow.solve.dense.DenseOutput.on`'s arithmetic (bitwise), into
  new arrays, or :func:`interior_in_place`, into the records' own arrays
  where they have the rows (one point's arithmetic, :func:`_inside`, for
  both).

The last two replaced NumPy code whose fixed costs were a small run's:
0.17 and 0.24 ms of fig5:air's ~6 ms, now 0.06 and 0.10 ms."""
from __future__ import annotations

import math

import numpy as np

from . import jit


@jit
def dense_terms(C, rows, diffs, dcols, out):
    """out[m, c] = sum_j C[m, j] diffs[rows[m, j], dcols[c]] (dcols empty:
    every column), summed in order of j from the first term (the NumPy
    code's order: each term added to the sum of those before)."""
    kmax = C.shape[1]
    every = dcols.size == 0
    for m in range(out.shape[0]):
        o = out[m]
        for j in range(kmax):
            coef = C[m, j]
            D = diffs[rows[m, j]]
            if every:
                _term(o, coef, D, j == 0)
            else:
                if j == 0:
                    for c in range(o.size):
                        o[c] = coef * D[dcols[c]]
                else:
                    for c in range(o.size):
                        o[c] = o[c] + coef * D[dcols[c]]


@jit
def _term(o, coef, D, first):
    """o = coef D where ``first``, else o + coef D, entry by entry (each
    sum in the order of its terms)."""
    if first:
        for c in range(o.size):
            o[c] = coef * D[c]
    else:
        for c in range(o.size):
            o[c] = o[c] + coef * D[c]


@jit
def refine_counts(k, off, diffs, m, inv, C, most, target, r):
    """The points per step of :func:`softflow.solve.dense.refine_counts` into
    r (entries of order 2 and more; the others keep r's 1): the least r in
    1..most whose straight lines stay within ``target`` of the step's
    polynomial, from the largest |p''| x ``inv`` over the first m columns at
    the samples (``C``: phi_2''..phi_kmax'' there, a row per sample). A NaN
    anywhere in an entry's |p''| counts as 0 (the NumPy code's answer). One
    pass, without the gathers and stacked products per batch of entries that
    cost a small run ~0.15 ms."""
    last = max(diffs.shape[0] - 1, 0)
    cap = 8.0 * target * most ** 2
    acc = np.empty((C.shape[0], m))
    for i in range(k.size):
        ki = k[i]
        if ki < 2:
            continue
        for s in range(C.shape[0]):
            for c in range(m):
                acc[s, c] = 0.0
        for jj in range(min(ki - 1, C.shape[1])):
            D = diffs[min(off[i] + jj + 1, last)]
            for s in range(C.shape[0]):
                coef = C[s, jj]
                for c in range(m):
                    acc[s, c] += coef * D[c]
        peak = 0.0
        for s in range(C.shape[0]):
            for c in range(m):
                v = abs(acc[s, c]) * inv[c]
                if v > peak:
                    peak = v
                elif v != v:
                    peak = math.nan
                    break
            if peak != peak:
                peak = 0.0
                break
        need = math.ceil(math.sqrt(min(peak, cap) / (8.0 * target)))
        r[i] = min(max(need, 1), most)


@jit
def interior(t_end, h, k, row, off, diffs, linear, discrete, extra, counts, t, X, S, Q,
             t_out, X_out, S_out, Q_out):
    """The recorded points t, X, S, Q (Q may have no columns) with extra[i]
    points inserted evenly inside each step i before its end point, into
    t_out, X_out, S_out, Q_out (rows: the old ones and the inserted, in
    order): :func:`softflow.solve.dense.insert_interior`'s arrays in one
    pass, each inserted value the arithmetic of
    :meth:`~softflow.solve.dense.DenseOutput.on` on the same entries
    (bitwise: the polynomial's coefficients as its cumulative product,
    every term up to the largest order among the stepped entries, each
    sum in order; ``linear``: backward Euler's line from the point before;
    discrete states, ``discrete`` their columns of S, at their values at
    the step's start)."""
    kmax = _kmax(k, extra)
    C = np.zeros(max(kmax, 1))
    d = np.empty(diffs.shape[1])
    # old row q goes to row q + shift, shift the points inserted before it
    # (rows as sums and range indices: a row counted up from a literal 0 had
    # numba compile _row once more for that literal)
    shift = 0
    q0 = 0          # the first old row not yet copied
    for i in range(k.size):
        if extra[i] <= 0:
            continue
        r = row[i]
        for q in range(q0, r):
            _row(t, X, S, Q, q, t_out, X_out, S_out, Q_out, q + shift)
        q0 = r
        start = row[i - 1] if i > 0 else row[k.size - 1]
        for m in range(1, extra[i] + 1):
            _inside(t_end[i], h[i], k[i], counts[i], m, off[i], diffs, linear, discrete, kmax,
                    C, d, X, S, Q, r, max(r - 1, 0), start, t_out, X_out, S_out, Q_out,
                    r + shift + m - 1)
        shift += extra[i]
    for q in range(q0, t.size):
        _row(t, X, S, Q, q, t_out, X_out, S_out, Q_out, q + shift)


@jit
def interior_in_place(t_end, h, k, row, off, diffs, linear, discrete, extra, counts, t, X, S,
                      Q, t_out):
    """:func:`interior` within the arrays X, S, Q themselves, whose first
    t.size rows are the recorded points and whose rows reach the points
    with those inserted (t_out: the times, a new array): from the last
    step back, each old row moved to its new place before the points
    inserted below it are formed (they read the step's end point there, the
    point before it and the start of a discrete state's step where they
    were, not yet moved), with the same arithmetic as :func:`interior`:
    bitwise the same values, without a second copy of the records."""
    kmax = _kmax(k, extra)
    C = np.zeros(max(kmax, 1))
    d = np.empty(diffs.shape[1])
    shift = 0
    for i in range(k.size):
        if extra[i] > 0:
            shift += extra[i]
    q = t.size - 1      # the next old row to move (from the end)
    for i in range(k.size - 1, -1, -1):
        if extra[i] <= 0:
            continue
        r = row[i]
        while q >= r:
            _row(t, X, S, Q, q, t_out, X, S, Q, q + shift)
            q -= 1
        shift -= extra[i]
        end = r + shift + extra[i]          # where the step's end point is now
        start = row[i - 1] if i > 0 else row[k.size - 1]
        for m in range(1, extra[i] + 1):
            _inside(t_end[i], h[i], k[i], counts[i], m, off[i], diffs, linear, discrete, kmax,
                    C, d, X, S, Q, end, max(r - 1, 0), start, t_out, X, S, Q, r + shift + m - 1)
    while q >= 0:
        t_out[q] = t[q]
        q -= 1


@jit
def _kmax(k, extra):
    """The largest order among the steps that get points inside."""
    kmax = 0
    for i in range(k.size):
        if extra[i] > 0 and k[i] > kmax:
            kmax = k[i]
    return kmax


@jit
def _inside(te, hi, ki, count, m, off, diffs, linear, discrete, kmax, C, d, X, S, Q, r, p,
            start, t_out, X_out, S_out, Q_out, out):
    """The m-th of a step's points inside it (the step ending at te, of
    spacing hi and order ki, cut in ``count`` parts), into row ``out``: from
    the step's end point, row r of X, S, Q, its differences from row ``off``
    of ``diffs`` (``linear``: the line from row p, the point before), its
    discrete states from row ``start`` (the step's start)."""
    nS, nX, nQ = S.shape[1], X.shape[1], Q.shape[1]
    last = max(diffs.shape[0] - 1, 0)
    tau = te - hi + hi * float(m) / float(count)
    s = 0.0
    if ki > 0:
        s = (tau - te) / (hi if hi > 0.0 else 1.0)
    if s < -1.0:
        s = -1.0
    elif s > 0.0:
        s = 0.0
    t_out[out] = tau
    Xo, So = X_out[out], S_out[out]
    for c in range(nX):
        Xo[c] = X[r, c]
    for c in range(nS):
        So[c] = S[r, c]
    if nQ:
        for c in range(nQ):
            Q_out[out, c] = Q[r, c]
    if kmax:
        if linear:
            for c in range(nX):
                Xo[c] += s * (X[r, c] - X[p, c])
            for c in range(nS):
                So[c] += s * (S[r, c] - S[p, c])
            for c in range(nQ):
                Q_out[out, c] += s * (Q[r, c] - Q[p, c])
        else:
            coef = 1.0
            for j in range(1, kmax + 1):
                coef = coef * ((s + (j - 1)) / j)
                C[j - 1] = coef if j <= ki else 0.0
            for j in range(kmax):
                _term(d, C[j], diffs[min(off + j, last)], j == 0)
            for c in range(nS):
                So[c] += d[c]
            for c in range(nX):
                Xo[c] += d[nS + c]
            for c in range(nQ):
                Q_out[out, c] += d[nS + nX + c]
    if discrete.size and ki > 0 and -1.0 < s < 0.0:
        for c in discrete:
            So[c] = S[start, c]


@jit
def _row(t, X, S, Q, q, t_out, X_out, S_out, Q_out, out):
    """Row q of the old points into row ``out`` of the new (element by
    element: no slice assignment, whose shape-checked error message is
    seconds of a first compile)."""
    t_out[out] = t[q]
    for c in range(X.shape[1]):
        X_out[out, c] = X[q, c]
    for c in range(S.shape[1]):
        S_out[out, c] = S[q, c]
    for c in range(Q.shape[1]):
        Q_out[out, c] = Q[q, c]
