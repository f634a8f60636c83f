"""The compiled sparse LU (softflow.laws.sparselu) against SciPy's solves:
random sparse matrices with zero diagonals, bad scaling and fill, a
randomized network's Jacobian; singular matrices and arrays too short for
the factors are reported, not solved."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from softflow.laws import sparselu


class Factors:
    """The arrays of sparselu's module docstring for an n x n matrix, with
    room for ``room`` entries of L and of U."""

    def __init__(self, A, room=None, order="COLAMD"):
        A = sp.csc_matrix(A)
        A.sort_indices()
        n = A.shape[0]
        self.n, self.A = n, A
        self.Ap, self.Ai = A.indptr.astype(np.int64), A.indices.astype(np.int64)
        self.Ax = A.data.astype(float)
        # SuperLU's column order (L U = Pr A Pc, Pc[i, perm_c[i]] = 1: the
        # j-th column taken is A's column argsort(perm_c)[j])
        self.Q = (np.argsort(sla.splu(A, permc_spec=order).perm_c).astype(np.int64)
                  if order != "NATURAL" else np.arange(n, dtype=np.int64))
        room = room if room is not None else n * n
        self.Lp, self.Up = np.zeros(n + 1, np.int64), np.zeros(n + 1, np.int64)
        self.Li, self.Ui = np.zeros(room, np.int64), np.zeros(room, np.int64)
        self.Lx, self.Ux, self.Ud = np.zeros(room), np.zeros(room), np.zeros(n)
        self.pinv, self.prow = np.zeros(n, np.int64), np.zeros(n, np.int64)
        self.Ar = np.zeros(A.nnz, np.int64)
        self.iw, self.x, self.z = np.zeros(4 * n, np.int64), np.zeros(n), np.zeros(n)
        self.Sx, self.ir, self.ic = np.zeros(A.nnz), np.ones(n), np.ones(n)
        self.state = np.zeros(4, np.int64)

    def factor(self, pivot_rtol=1e-14, scaled=False, refactor_rtol=1e-3, reuse=False):
        self.state[:2] = (1 if reuse else 0, 1 if scaled else 0)
        return sparselu.sparse_factor(self.Ap, self.Ai, self.Ax, self.Q, self.Lp, self.Li,
                                      self.Lx, self.Up, self.Ui, self.Ux, self.Ud, self.pinv,
                                      self.prow, self.Ar, self.iw, self.x, self.Sx, self.ir,
                                      self.ic,
                                      pivot_rtol, refactor_rtol, self.state)

    def solve(self, b):
        out = np.zeros(self.n)
        sparselu.sparse_solve(self.Q, self.Lp, self.Li, self.Lx, self.Up, self.Ui, self.Ux,
                              self.Ud, self.prow, self.ir, self.ic, np.asarray(b, float), out,
                              self.z)
        return out


def _random(n, density, seed, zero_diagonal=False, spread=0.0):
    rng = np.random.default_rng(seed)
    A = sp.random(n, n, density=density, random_state=rng, format="lil")
    A += sp.diags(rng.uniform(0.5, 2.0, n) * rng.choice([-1, 1], n))
    A = A.tolil()
    if zero_diagonal:                  # a permuted diagonal: pivoting needed
        perm = rng.permutation(n)
        A = A[perm, :]
    if spread:                         # rows and columns in very different units
        A = sp.diags(10.0 ** rng.uniform(-spread, spread, n)) @ A @ sp.diags(
            10.0 ** rng.uniform(-spread, spread, n))
    return sp.csc_matrix(A)


@pytest.mark.parametrize("n, density, seed, zero_diagonal, spread, order", [
    (1, 0.0, 0, False, 0.0, "NATURAL"),
    (5, 0.3, 1, False, 0.0, "NATURAL"),
    (40, 0.05, 2, True, 0.0, "COLAMD"),
    (200, 0.01, 3, True, 0.0, "COLAMD"),
    (200, 0.02, 4, False, 6.0, "COLAMD"),
    (300, 0.01, 5, True, 8.0, "NATURAL"),
])
def test_solves_agree_with_scipy(n, density, seed, zero_diagonal, spread, order):
    A = _random(n, density, seed, zero_diagonal, spread)
    f = Factors(A, order=order)
    assert f.factor() == sparselu.OK
    rng = np.random.default_rng(seed + 100)
    for _ in range(3):
        b = rng.normal(size=n)
        x = f.solve(b)
        ref = sla.spsolve(A, b)
        if not spread:
            # componentwise backward error (the residual against the
            # matrix's and the solution's scale), and SciPy's solution
            err = np.abs(A @ x - b) / (abs(A) @ np.abs(x) + np.abs(b))
            assert err.max() < 1e-13
            np.testing.assert_allclose(x, ref, rtol=1e-8, atol=1e-10 * np.abs(ref).max())
        else:
            # rows and columns spread over 12-16 decades: normwise backward
            # error of the equilibrated system (what partial pivoting
            # bounds), in the scales the factorization chose
            R, C = sp.diags(f.ir), sp.diags(1.0 / f.ic)
            S, y, rb = R @ A @ sp.diags(f.ic), C @ x, R @ b
            norm = abs(S).sum(axis=1).max()
            assert np.abs(S @ y - rb).max() <= 1e-13 * (norm * np.abs(y).max() + np.abs(rb).max())


def test_factors_reproduce_the_matrix():
    A = _random(60, 0.05, 7, zero_diagonal=True)
    f = Factors(A, order="COLAMD")
    assert f.factor() == sparselu.OK
    n = f.n
    L = np.eye(n)
    for k in range(n):
        for e in range(f.Lp[k], f.Lp[k + 1]):
            L[f.Li[e], k] = f.Lx[e]
    U = np.diag(f.Ud)
    for j in range(n):
        for e in range(f.Up[j], f.Up[j + 1]):
            U[f.Ui[e], j] = f.Ux[e]
    assert np.all(np.abs(np.tril(L, -1)) <= 1.0 + 1e-15)      # partial pivoting
    np.testing.assert_allclose(L @ U, A.toarray()[f.prow][:, f.Q], atol=1e-13)


def test_badly_scaled_matrices_are_equilibrated():
    # a pivot 1e-16 of the largest fails the singularity test as it is; the
    # scaled matrix passes it, and the solve takes the scales back
    A = sp.csc_matrix(np.array([[1e-12, 0.0, 2e-12], [0.0, 3e8, 1e8], [1.0, 0.0, 4.0]]))
    f = Factors(A, order="NATURAL")
    assert f.factor(pivot_rtol=1e-10) == sparselu.OK
    assert not np.all(f.ir == 1.0)
    b = np.array([1e-12, 2e8, 1.0])
    np.testing.assert_allclose(A @ f.solve(b), b, rtol=1e-12)


def test_singular_matrices_are_reported():
    A = sp.csc_matrix(np.array([[1.0, 2.0, 0.0], [2.0, 4.0, 0.0], [0.0, 1.0, 3.0]]))
    assert Factors(A, order="NATURAL").factor() == sparselu.SINGULAR
    zero_row = sp.csc_matrix(np.array([[1.0, 0.0], [0.0, 0.0]]))
    assert Factors(zero_row, order="NATURAL").factor() == sparselu.SINGULAR


def test_factors_longer_than_their_arrays_are_reported():
    A = _random(80, 0.1, 9)
    f = Factors(A, room=A.nnz // 4)
    assert f.factor() == sparselu.CAPACITY


def test_a_network_jacobian():
    # a randomized network's Jacobian (pressures, flows, states' unknowns of
    # very different sizes, zero diagonals), factored as the loop factors it
    import softflow as sf
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.5, "bar"))
    prev = ("src", "a")
    for k in range(30):
        s += sf.CircularTube(f"t{k}", sf.water, 0.2, 1e-3)
        s += sf.Container(f"c{k}", sf.water, 1e-6) if k % 3 else sf.LinearAccumulator(
            f"c{k}", sf.water, volume=1e-6, compliance=1e-11)
        s.connect(prev, (f"t{k}", "a"))
        s.connect((f"t{k}", "b"), (f"c{k}", "a"))
        prev = (f"c{k}", "a")
    sim = sf.Simulation(s, duration=0.01)
    J = sim.asm.jacobian_csc()
    f = Factors(J)
    assert f.factor() == sparselu.OK
    b = np.random.default_rng(3).normal(size=J.shape[0])
    np.testing.assert_allclose(f.solve(b), sla.spsolve(sp.csc_matrix(J), b), rtol=1e-9,
                               atol=1e-12)


def test_a_new_matrix_of_the_same_pattern_reuses_the_row_order_while_it_serves():
    rng = np.random.default_rng(11)
    A = _random(150, 0.03, 11, zero_diagonal=True)
    f = Factors(A)
    assert f.factor() == sparselu.OK and f.state[0] == 1
    prow = f.prow.copy()
    b = rng.normal(size=150)
    # values moved by 1 %: the same row order, the same solution as SciPy's
    f.Ax[:] = A.data * (1 + 0.01 * rng.uniform(-1, 1, A.nnz))
    A2 = sp.csc_matrix((f.Ax.copy(), f.Ai, f.Ap), shape=A.shape)
    assert f.factor(reuse=True) == sparselu.OK
    np.testing.assert_array_equal(f.prow, prow)
    np.testing.assert_allclose(f.solve(b), sla.spsolve(A2, b), rtol=1e-9)
    # a pivot that falls to 1e-6 of its column: a new row order, still solved
    j = next(j for j in range(150) if f.Lp[j + 1] > f.Lp[j])
    A3 = A2.toarray()
    A3[f.prow[j], f.Q[j]] *= 1e-6 if A3[f.prow[j], f.Q[j]] else 1.0
    A3 = sp.csc_matrix(A3)
    assert A3.nnz == A.nnz                   # (the same pattern)
    f.Ax[:] = A3.data
    assert f.factor(reuse=True) == sparselu.OK
    assert not np.array_equal(f.prow, prow)
    assert not f.x.any()          # the work row is zero again, as the next call needs
    np.testing.assert_allclose(A3 @ f.solve(b), b, atol=1e-9 * np.abs(b).max())
