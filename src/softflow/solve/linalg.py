"""Linear solvers behind one small interface: factor the current Jacobian, solve."""
from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
from scipy.linalg.lapack import dgetrs
from scipy.sparse import csc_matrix
from scipy.sparse.linalg import splu

#: Up to this many unknowns a dense LU is at least as fast as SuperLU: measured
#: on chains (benchmarks/bench_linear_solver.py), dense wins 1.03-1.2x up to 130
#: unknowns and loses 2x at 146 (the n^3 factorization takes over).
DENSE_MAX = 128


#: SuperLU's relaxed-supernode size. Its default (a few columns) merges small
#: near-dense column groups into supernodes whose triangular solves go through a
#: BLAS call each; on the 2x2 (pressure, temperature) blocks of thermal networks
#: that made each solve ~2x slower (bench_thermal.py chain N=1000: 0.38 -> 0.17 ms
#: per solve), and factoring is ~1.3x faster with 1 on both kinds of network.
RELAX = 1


class SingularJacobian(RuntimeError):
    pass


#: Up to this many unknowns DenseLU solves by a product with the inverse
#: instead of LAPACK getrs (measured: 0.28 vs 0.44 us on 6 unknowns, 0.36 vs
#: 1.0 on 36, 0.49 vs 1.6 on 64). Newton only needs the update to a relative
#: accuracy far coarser than the inverse's round-off, and checks convergence on it.
INVERSE_MAX = 64


class DenseLU:
    """LAPACK LU of the assembled Jacobian (small systems)."""

    kind = "dense"

    def __init__(self, asm):
        self.asm = asm
        self.n = asm.n
        self.flat = asm.pattern_rows * asm.n + asm.pattern_cols
        self.lu = None

    def factor(self):
        J = np.bincount(self.flat, weights=self.asm.raw, minlength=self.n * self.n)
        J = J.reshape(self.n, self.n)
        if not np.isfinite(J).all():
            raise SingularJacobian("Jacobian contains NaN or inf")
        with warnings.catch_warnings():   # singularity is reported by our own check
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            lu, piv = sla.lu_factor(J, check_finite=False)
        d = np.abs(np.diag(lu))
        if d.min() <= 1e-14 * max(d.max(), 1e-300):
            raise SingularJacobian("Jacobian is singular", int(np.argmin(d)))
        self.lu = (lu, piv)
        self._J = J
        if self.n <= INVERSE_MAX:
            # the inverse: a solve is then one product. NumPy's inv, not getrs on
            # the identity: scipy's getrs with n right-hand sides was measured at
            # 1.1 ms for 14 unknowns (against 7 us) on this project's 2-core machine
            self._inv = np.linalg.inv(J)
            self.solve = self._inv.dot

    @property
    def row_scale(self):
        """1 / max |J_ij| per row (for damped Newton and error messages)."""
        return 1.0 / np.maximum(np.abs(self._J).max(axis=1), 1e-300)

    def solve(self, b):
        # LAPACK getrs directly: scipy.linalg.lu_solve's checks cost more than
        # the solve itself for the small systems this class serves
        x, info = dgetrs(self.lu[0], self.lu[1], b)
        return x


class SparseLU:
    """SuperLU with a COLAMD fill-reducing column ordering (large systems)."""

    kind = "sparse"

    def __init__(self, asm, permc_spec="COLAMD"):
        self.asm = asm
        self.n = asm.n
        self.permc_spec = permc_spec
        self.lu = None

    def factor(self):
        data = self.asm.jacobian_data()
        if not np.isfinite(data).all():
            raise SingularJacobian("Jacobian contains NaN or inf")
        A = csc_matrix((data, self.asm.indices, self.asm.indptr), shape=(self.n, self.n))
        try:
            self.lu = splu(A, permc_spec=self.permc_spec, relax=RELAX)
        except RuntimeError as err:  # "Factor is exactly singular"
            raise SingularJacobian(str(err)) from None
        self._data = data

    @property
    def row_scale(self):
        """1 / max |J_ij| per row, computed only when asked for: a pass over all
        nonzeros that most factorizations never need."""
        rs = np.zeros(self.n)
        np.maximum.at(rs, self.asm.indices, np.abs(self._data))
        return 1.0 / np.maximum(rs, 1e-300)

    def solve(self, b):
        return self.lu.solve(b)


def make_linear_solver(asm, kind="auto"):
    from .condense import CondensedLU
    if kind == "auto":
        if asm.n <= DENSE_MAX:
            return DenseLU(asm)
        lin = CondensedLU(asm)
        return lin if lin.worthwhile else SparseLU(asm)
    if kind == "dense":
        return DenseLU(asm)
    if kind == "sparse":
        return SparseLU(asm)
    if kind == "condensed":
        return CondensedLU(asm)
    raise ValueError("linear_solver must be 'auto', 'dense', 'sparse' or 'condensed', "
                     f"got {kind!r}")
