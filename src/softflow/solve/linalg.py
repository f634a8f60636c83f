"""Linear solvers behind one small interface: factor the current Jacobian, solve."""
from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dgetrf, dgetri, dgetrs
from scipy.sparse import csc_matrix
from scipy.sparse.linalg import splu

from .settings import DENSE_MAX, DOT_MAX, INVERSE_MAX, PIVOT_RTOL, RELAX, SMALL_PIVOTS


class SingularJacobian(RuntimeError):
    pass


def all_finite(a):
    """True if every entry of ``a`` is finite. On small arrays a finite sum of
    squares proves it with one dot product (0.3 us against 1 us for
    np.isfinite(a).all(), measured); an overflowing one (entries above 1e154)
    falls back to the exact test."""
    if a.size <= DOT_MAX and math.isfinite(a.dot(a)):
        return True
    return bool(np.isfinite(a).all())


class DenseLU:
    """LAPACK LU of the assembled Jacobian (small systems)."""

    kind = "dense"

    #: the message of :meth:`Assembly.diagnose_scale` at the last
    #: factorization that needed equilibrating where it named a component,
    #: or None; kept only where ``note_scale`` is set (the solver of the
    #: consistent start, Integrator._solve_initial: a diagnosis costs a
    #: sparse pass over the Jacobian, 17.5 of 122 ms on a random network
    #: that equilibrated at every step)
    scale_note: str | None = None
    note_scale = False

    #: (1 / row scales, 1 / column scales) of factors of the equilibrated
    #: R J C (:meth:`_factor_equilibrated`), or None: J's own
    scales = None

    def __init__(self, asm):
        self.asm = asm
        self.n = asm.n
        self.lu = None

    def factor(self):
        self.scales = None
        n = self.n
        J = self.asm.dense_jacobian()
        if not all_finite(J.ravel()):
            raise SingularJacobian("Jacobian contains NaN or inf")
        # LAPACK getrf directly: scipy.linalg.lu_factor's wrapper, and the warning
        # filter it needed (an exactly singular matrix warns), cost ~4x the
        # factorization of a 10 x 10 matrix (measured: 38 -> 10 us a factor
        # call on the paper's scenes); singularity is reported by our own check
        lu, piv, info = dgetrf(J)
        if info < 0:
            raise SingularJacobian(f"LAPACK getrf argument {-info} is invalid")
        d = np.abs(lu.diagonal())
        if n <= SMALL_PIVOTS:
            v = d.tolist()
            d_min, d_max = min(v), max(v)
        else:
            d_min, d_max = d.min(), d.max()
        if not d_min > PIVOT_RTOL * max(d_max, 1e-300):
            if not self._factor_equilibrated(J):
                raise SingularJacobian("Jacobian is singular", int(np.argmin(d)))
            return
        self.lu = (lu, piv)
        self._J = J
        if n > INVERSE_MAX:
            self.__dict__.pop("solve", None)      # an equilibrated factor's, if any
        else:
            # the inverse from these factors (getri): a solve is then one
            # product. Not getrs on the identity: scipy's getrs with n right-hand
            # sides was measured at 1.1 ms for 14 unknowns (against 7 us) on
            # this project's 2-core machine
            inv, info = dgetri(lu, piv)
            if info != 0:
                raise SingularJacobian("Jacobian is singular", info - 1)
            self._inv = inv
            self.solve = inv.dot

    def _factor_equilibrated(self, J):
        """Factor R J C (rows, then columns, scaled to a largest entry of 1)
        where J's own pivots fail the singularity test: they then often only
        reflect the units. Two air tanks settled at 18 MPa weigh a volume's
        pressure by V/(R T) ~ 2e-11 against a tube's 1: J's pivots span more
        than 1e14 where R J C has a condition number of ~2e5 ('singular
        Jacobian' at t = 16 ms, adiabatic, rtol <= 1e-6, before). R J C is
        held to the same pivot test; where it passes, the network is solved
        as SuperLU (:class:`SparseLU`, which pivots by magnitude within
        columns) solves it. (Until 2026-12-03 a network that
        :meth:`Assembly.diagnose_scale` called extreme, its equations' scales
        1e12 or more apart, was refused here even so: 42 of 600 random
        networks of tests/test_random_networks.py, a 0.43 m x 0.46 mm tube or
        a stiff liquid accumulator among them, stopped at t = 0 although the
        sparse solver ran them, to the same results, within 1.4e-4 of the
        pressure ranges; the diagnosis is now kept in :attr:`scale_note`, for
        the message where the consistent start fails.) Returns whether R J C
        was factored; solves are then C (R J C)^-1 R."""
        r = np.abs(J).max(axis=1)
        if not (r > 0.0).all():
            return False
        Jr = J / r[:, None]
        c = np.abs(Jr).max(axis=0)
        if not (c > 0.0).all():
            return False
        lu, piv, info = dgetrf(Jr / c)
        if info < 0:
            return False
        d = np.abs(lu.diagonal())
        if not d.min() > PIVOT_RTOL * max(d.max(), 1e-300):
            return False
        # kept for a failure's message (Integrator._solve_initial): where the
        # consistent start fails after all, the extreme component is named
        if self.note_scale:
            why = self.asm.diagnose_scale()[0]
            if why is not None:
                self.scale_note = why
        ir, ic = 1.0 / r, 1.0 / c
        if self.n <= INVERSE_MAX:
            inv, info = dgetri(lu, piv)
            if info != 0:
                return False
            self._inv = inv = (ic[:, None] * inv) * ir
            self.solve = inv.dot
        else:
            def solve(b):
                x, _ = dgetrs(lu, piv, ir[:, None] * b if b.ndim > 1 else ir * b)
                return ic[:, None] * x if x.ndim > 1 else ic * x
            self.solve = solve
        self.lu = (lu, piv)
        self.scales = (ir, ic)
        self._J = J
        return True

    def adopt(self, J, lu, piv, ir, ic):
        """Take factors made elsewhere (the compiled step loop's,
        :func:`softflow.laws.stepper.factor`) as this solver's own: J, the
        LU of C (R J C) R as getrf leaves it and its pivots, the scales ir =
        1/R and ic = 1/C (ones where J was factored as it is)."""
        lu, piv = np.array(lu, order="F"), np.asarray(piv, dtype=np.int32)
        self._J = J.copy()
        self.lu = (lu, piv)
        plain = bool((ir == 1.0).all() and (ic == 1.0).all())
        self.scales = None if plain else (ir.copy(), ic.copy())
        if self.n <= INVERSE_MAX:
            inv, info = dgetri(lu, piv)
            if info != 0:
                raise SingularJacobian("Jacobian is singular", info - 1)
            if not plain:
                inv = (ic[:, None] * inv) * ir
            self._inv = inv
            self.solve = inv.dot
        elif plain:
            self.__dict__.pop("solve", None)
        else:
            ir, ic = self.scales

            def solve(b):
                x, _ = dgetrs(lu, piv, ir[:, None] * b if b.ndim > 1 else ir * b)
                return ic[:, None] * x if x.ndim > 1 else ic * x
            self.solve = solve

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
