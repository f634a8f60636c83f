"""LU factors of many small matrices of one sparsity pattern, in vector operations.

The batched engine (:mod:`softflow.solve.clocks`) solves K variants of one
scene, each with the same small Jacobian block (n x n, the same entries
structurally non-zero). LAPACK inverts such a stack matrix by matrix (~0.8 us
a 6 x 6 block, ~0.8 ms for 1 000 of them), whatever their sparsity. Here the
elimination is planned once, for the pattern, with one row order (partial
pivoting on one of the matrices), and then run on all K at once: each step
of the elimination is one NumPy operation on the (entries, K) array of the
values, touching only the structurally non-zero entries and their fill.
A source-tube-tank block (6 x 6, 12 entries, no fill) is factored in ~25 us
and solved in ~20 us for 1 000 variants.

One row order for all matrices is partial pivoting only for the matrix it
was chosen on. Each matrix's multipliers are therefore held to threshold
pivoting's bound (``|l_ik| <= 1 / PIVOT_THRESHOLD``, the test of sparse
direct solvers that keep a pivot order for sparsity): a matrix whose
multipliers pass it, or whose pivot is zero or not finite, is reported, and
its caller factors it another way (the batched engine: LAPACK's inverse, which
pivots afresh and says whether it is singular).

References: I. S. Duff, A. M. Erisman, J. K. Reid, *Direct Methods for Sparse
Matrices*, 2nd ed., OUP 2017 (threshold pivoting, sec. 5.4, 9.3).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg

#: Threshold pivoting: a multiplier larger than 1 / PIVOT_THRESHOLD in
#: magnitude (the planned pivot is that much smaller than an entry below it
#: in its column) sends that matrix to the caller's other factorization.
PIVOT_THRESHOLD = 1e-3


class PlanError(ValueError):
    """No row order serves: the matrix offered has a zero pivot in every
    order partial pivoting finds, or a pivot that is structurally zero."""


class BlockLU:
    """Factors of K matrices (n x n) of one pattern, by one planned elimination.

    Parameters
    ----------
    rows, cols : int arrays
        The pattern's entries (structurally non-zero; repeats allowed).
    n : int

    Use: :meth:`plan` with one matrix (n, n) to choose the row order, then
    :meth:`factor` with a stack (m, n, n) of matrices of the pattern (values
    outside it are ignored), which returns a :class:`Factors`; :meth:`solve`
    with the factors and right-hand sides (m, n).
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
        steps = []
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
            steps.append((int(slot[k, k]), slot[below, k], slot[k, right], target,
                          below, right))
        self.perm = perm
        self.n_slots = n_slots
        # the values' place in a flattened (n, n) matrix: each slot that is an
        # entry of the pattern, in the row order chosen
        self._src = perm[src_rows] * n + src_cols
        self._n_src = src_rows.size
        self._steps = steps
        # each row's entries, for the solve's back substitution
        return self

    def factor(self, A):
        """Factors of the stack ``A`` (m, n, n). Returns (factors, ok): ok[v]
        False where matrix v's pivot is zero or not finite, or a multiplier
        passes threshold pivoting's bound (factor it another way)."""
        m = A.shape[0]
        W = np.zeros((self.n_slots, m))
        W[:self._n_src] = A.reshape(m, -1)[:, self._src].T
        inv = np.empty((self.n, m))
        ok = np.ones(m, dtype=bool)
        bound = 1.0 / PIVOT_THRESHOLD
        with np.errstate(all="ignore"):
            for k, (kk, lo, up, target, _, _) in enumerate(self._steps):
                inv[k] = 1.0 / W[kk]
                if lo.size:
                    L = W[lo] * inv[k]
                    W[lo] = L
                    ok &= (np.abs(L) <= bound).all(axis=0)
                    if up.size:
                        W[target] -= (L[:, None, :] * W[up][None, :, :]).reshape(-1, m)
            ok &= np.isfinite(inv).all(axis=0)
        return Factors(W, inv), ok

    def solve(self, f, b):
        """Solutions (m, n) of the factored matrices ``f`` for ``b`` (m, n)."""
        W, inv = f.W, f.inv
        y = np.ascontiguousarray(b[:, self.perm].T)
        steps = self._steps
        for k, (_, lo, _, _, below, _) in enumerate(steps):
            if lo.size:
                y[below] -= W[lo] * y[k]
        for k in range(self.n - 1, -1, -1):
            _, _, up, _, _, right = steps[k]
            if up.size:
                y[k] -= (W[up] * y[right]).sum(axis=0)
            y[k] *= inv[k]
        return y.T

    def take(self, f, ids, g):
        """Put the factors ``g`` (of matrices ``ids`` of ``f``) into ``f``."""
        f.W[:, ids] = g.W
        f.inv[:, ids] = g.inv


class Factors:
    """The planned elimination's values: ``W`` (slots, m), the multipliers
    and the upper factor's entries; ``inv`` (n, m), the pivots' reciprocals."""

    __slots__ = ("W", "inv")

    def __init__(self, W, inv):
        self.W, self.inv = W, inv

    @classmethod
    def empty(cls, lu, m):
        return cls(np.zeros((lu.n_slots, m)), np.zeros((lu.n, m)))
