"""The planned elimination of many small matrices of one pattern (blocklu)."""
import numpy as np
import pytest

from softflow.solve import blocklu
from softflow.solve.blocklu import BlockLU, PlanError


def _stack(rng, n, K, density=0.3):
    pattern = rng.random((n, n)) < density
    pattern[np.arange(n), rng.permutation(n)] = True       # structurally regular
    A = np.where(pattern, rng.normal(size=(K, n, n)), 0.0)
    return pattern, A


@pytest.mark.parametrize("n", [1, 2, 6, 12, 24])
def test_solves_as_lapack_where_it_serves(n):
    rng = np.random.default_rng(n)
    pattern, A = _stack(rng, n, 400)
    rows, cols = np.nonzero(pattern)
    lu = BlockLU(rows, cols, n).plan(A[0])
    f, ok = lu.factor(A)
    assert ok[0]                       # partial pivoting's own matrix
    assert ok.mean() > 0.8
    b = rng.normal(size=(400, n))
    x = lu.solve(f, b)
    ref = np.linalg.solve(A, b[..., None])[..., 0]
    cond = np.linalg.cond(A[ok])
    err = np.abs(x[ok] - ref[ok]).max(axis=1) / np.abs(ref[ok]).max(axis=1)
    assert (err <= 1e-13 * np.maximum(cond, 1.0)).all()


def test_fill_is_planned():
    # an arrow matrix eliminated from its dense row first fills in everywhere
    n = 5
    pattern = np.eye(n, dtype=bool)
    pattern[0, :] = pattern[:, 0] = True
    rows, cols = np.nonzero(pattern)
    A = np.where(pattern, 1.0, 0.0) + np.diag([10.0, 1, 1, 1, 1])
    lu = BlockLU(rows, cols, n).plan(A)
    assert lu.n_slots == n * n
    f, ok = lu.factor(A[None])
    b = np.arange(1.0, n + 1)[None]
    np.testing.assert_allclose(lu.solve(f, b)[0], np.linalg.solve(A, b[0]), rtol=1e-14)


def test_threshold_pivoting_refuses_a_matrix_the_order_does_not_suit():
    # planned on [[2, 1], [1, 1]] (pivot 2 first); [[1e-6, 1], [1, 1]] would
    # take multiplier 1e6 under that order: refused, not solved inaccurately
    rows, cols = np.nonzero(np.ones((2, 2)))
    lu = BlockLU(rows, cols, 2).plan(np.array([[2.0, 1.0], [1.0, 1.0]]))
    A = np.array([[[2.0, 1.0], [1.0, 1.0]], [[1e-6, 1.0], [1.0, 1.0]]])
    _, ok = lu.factor(A)
    assert ok.tolist() == [True, False]
    assert blocklu.PIVOT_THRESHOLD == 1e-3


def test_a_zero_pivot_is_refused():
    rows, cols = np.nonzero(np.ones((2, 2)))
    lu = BlockLU(rows, cols, 2).plan(np.array([[2.0, 1.0], [1.0, 1.0]]))
    _, ok = lu.factor(np.array([[[0.0, 1.0], [0.0, 1.0]], [[np.nan, 1.0], [1.0, 1.0]]]))
    assert not ok.any()


def test_plan_errors():
    rows, cols = np.nonzero(np.ones((2, 2)))
    with pytest.raises(PlanError, match="singular"):
        BlockLU(rows, cols, 2).plan(np.ones((2, 2)))
    with pytest.raises(PlanError, match="not finite"):
        BlockLU(rows, cols, 2).plan(np.array([[np.inf, 1.0], [1.0, 1.0]]))
