"""LU factors of many small matrices of one sparsity pattern, in vector operations.

The batched engine (:mod:`softflow.solve.clocks`) solves K variants of one
scene, each with the same small Jacobian block (n x n, the same entries
structurally non-zero). LAPACK inverts such a stack matrix by matrix (~0.7 us
a 6 x 6 block, ~0.7 ms for 1 000 of them), whatever their sparsity. Here the
elimination is planned once, for the pattern, with one row order (partial
pivoting on one of the matrices), and then run on all K at once: each step
of the elimination is one NumPy operation on the (entries, K) array of the
values, touching only the structurally non-zero entries and their fill.
A source-tube-tank block (6 x 6, 12 entries, 2 of fill) is factored in
~50 us and solved in ~20 us for 1 000 variants, where LAPACK's inverses take
~0.7 ms and their products ~27 us.

One row order for all matrices is partial pivoting only for the matrix it
was chosen on. Each matrix's multipliers are therefore held to threshold
pivoting's bound (``|l_ik| <= 1 / PIVOT_THRESHOLD``, the test of sparse
direct solvers that keep a pivot order for sparsity): a matrix whose
multipliers exceed it, or whose pivot is zero or not finite, is reported, and
its caller factors it another way (the batched engine: LAPACK's inverse, which
pivots afresh and says whether it is singular).

References: I. S. Duff, A. M. Erisman, J. K. Reid, *Direct Methods for Sparse
Matrices*, 2nd ed., Oxford University Press, 2017 (threshold pivoting).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

#: Threshold pivoting: a multiplier larger than 1 / PIVOT_THRESHOLD in
#: magnitude (the planned pivot is that much smaller than an entry below it
#: in its column) sends that matrix to the caller's other factorization.
PIVOT_THRESHOLD = 1e-3


class PlanError(ValueError):
    """No elimination can be planned on the matrix offered: it is singular or
    not finite, or partial pivoting's row order puts a pivot off the pattern."""


class BlockLU:
    """Factors of K matrices (n x n) of one pattern, by one planned elimination.

    Parameters
    ----------
    rows, cols : int arrays
        The pattern's entries (structurally non-zero; repeats allowed).
    n : int

    Use: :meth:`plan` with one matrix (n, n) to choose the row order, then
    :meth:`factor` with a stack (m, n, n) of matrices of the pattern (values
    outside it are ignored), or :meth:`factor_values` with their entries in
    the order of :attr:`source`, which return a :class:`Factors` and which
    matrices it serves; :meth:`solve` with the factors and right-hand sides
    (m, n).
    """

    def __init__(self, rows, cols, n):
        self.n = int(n)
        pattern = np.zeros((self.n, self.n), dtype=bool)
        pattern[np.asarray(rows), np.asarray(cols)] = True
        self.pattern = pattern
        self.perm = None

    def plan(self, A):
        """Choose the row order from ``A`` (n, n) by partial pivoting, and the
        elimination's steps from the pattern (with its fill). PlanError
        where ``A`` is singular or a pivot is off the pattern."""
        n = self.n
        A = np.where(self.pattern, np.asarray(A, dtype=float), 0.0)
        if not np.isfinite(A).all():
            raise PlanError("the matrix has entries that are not finite")
        with np.errstate(all="ignore"):
            lu, piv = scipy.linalg.lu_factor(A, check_finite=False)
        if not np.all(np.abs(np.diag(lu)) > 0.0):
            raise PlanError("the matrix is singular")
        perm = np.arange(n)
        for i, p in enumerate(piv):
            perm[i], perm[p] = perm[p], perm[i]
        P = self.pattern[perm].copy()            # row k of P: original row perm[k]
        slot = np.full((n, n), -1, dtype=np.int64)
        src_rows, src_cols = np.nonzero(P)
        slot[src_rows, src_cols] = np.arange(src_rows.size)
        n_slots = src_rows.size
        steps, forward, back = [], [], []
        for k in range(n):
            if not P[k, k]:
                raise PlanError(f"pivot {k} is structurally zero in the row order chosen")
            below = np.flatnonzero(P[k + 1:, k]) + k + 1
            right = np.flatnonzero(P[k, k + 1:]) + k + 1
            for i in below:
                for j in right:
                    if not P[i, j]:
                        P[i, j] = True
                        slot[i, j] = n_slots
                        n_slots += 1
            target = slot[np.ix_(below, right)].ravel()
            steps.append((int(slot[k, k]), slot[below, k], slot[k, right], target))
            forward.append(_terms(below, slot[below, k]))
            back.append(_terms(right, slot[k, right]))
        self.perm = perm
        self.n_slots = n_slots
        # the pattern's entries (the first slots), by their place in a flattened
        # (n, n) matrix in the original row order
        self.source = perm[src_rows] * n + src_cols
        self._steps = steps
        self._multipliers = np.concatenate([lo for _, lo, _, _ in steps])
        self._forward, self._back = forward, back
        return self

    def factor(self, A):
        """Factors of the stack ``A`` (m, n, n) (see :meth:`factor_values`)."""
        return self.factor_values(A.reshape(A.shape[0], -1)[:, self.source].T)

    def factor_values(self, values):
        """Factors of m matrices given by their pattern's entries ``values``
        (entries, m), in the order of :attr:`source`. Returns (factors, ok):
        ok[v] False where matrix v's pivot is zero or not finite, or a
        multiplier exceeds threshold pivoting's bound (factor it another way)."""
        m = values.shape[1]
        W = np.empty((self.n_slots, m))
        n_src = self.source.size
        W[:n_src] = values
        W[n_src:] = 0.0
        inv = np.empty((self.n, m))
        with np.errstate(all="ignore"):
            for k, (kk, lo, up, target) in enumerate(self._steps):
                np.divide(1.0, W[kk], out=inv[k])
                if lo.size:
                    L = W[lo] * inv[k]
                    W[lo] = L
                    if up.size:
                        W[target] -= (L[:, None, :] * W[up][None, :, :]).reshape(-1, m)
            ok = np.isfinite(inv).all(axis=0)
            if self._multipliers.size:
                ok &= np.abs(W[self._multipliers]).max(axis=0) <= 1.0 / PIVOT_THRESHOLD
        return Factors(W, inv), ok

    def solve(self, f, b):
        """Solutions (m, n) of the factored matrices ``f`` for ``b`` (m, n)."""
        W, inv = f.W, f.inv
        y = np.ascontiguousarray(b[:, self.perm].T)
        for k, terms in enumerate(self._forward):
            _apply(y, k, terms, W)
        for k in range(self.n - 1, -1, -1):
            _apply_to(y, k, self._back[k], W)
            y[k] *= inv[k]
        return y.T

    def take(self, f, ids, g):
        """Put the factors ``g`` (of matrices ``ids`` of ``f``) into ``f``."""
        f.W[:, ids] = g.W
        f.inv[:, ids] = g.inv


#: Up to this many terms a substitution step goes entry by entry (row views:
#: ~1.5 us each) rather than by fancy indexing (~6 us whatever the count)
FEW_TERMS = 3


def _terms(rows, slots):
    """A substitution step's terms: (rows, slots) as arrays, or as a list of
    (row, slot) pairs where they are few."""
    if rows.size <= FEW_TERMS:
        return [(int(r), int(s)) for r, s in zip(rows, slots)]
    return (rows, slots)


def _apply(y, k, terms, W):
    """Forward substitution: y[rows] -= L[rows, k] y[k]."""
    if isinstance(terms, list):
        yk = y[k]
        for i, s in terms:
            yi = y[i]
            yi -= W[s] * yk
    else:
        rows, slots = terms
        y[rows] -= W[slots] * y[k]


def _apply_to(y, k, terms, W):
    """Back substitution: y[k] -= sum_j U[k, j] y[j]."""
    yk = y[k]
    if isinstance(terms, list):
        for j, s in terms:
            yk -= W[s] * y[j]
    else:
        rows, slots = terms
        yk -= (W[slots] * y[rows]).sum(axis=0)


class Factors:
    """The planned elimination's values: ``W`` (slots, m), the multipliers
    and the upper factor's entries; ``inv`` (n, m), the pivots' reciprocals."""

    __slots__ = ("W", "inv")

    def __init__(self, W, inv):
        self.W, self.inv = W, inv

    @classmethod
    def empty(cls, lu, m):
        return cls(np.zeros((lu.n_slots, m)), np.zeros((lu.n, m)))
