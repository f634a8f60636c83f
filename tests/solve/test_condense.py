"""Static condensation (CondensedLU) against the plain sparse LU."""
import numpy as np
import pytest
from scipy.sparse import csc_matrix

import softflow as sf
from softflow.components.tubes import InertialCircularTube
from softflow.paper_scenes import curve_monotonic
from softflow.solve.assembly import Assembly
from softflow.solve.condense import CondensedLU
from softflow.solve.linalg import SingularJacobian, SparseLU, make_linear_solver
from softflow.solve.supernodes import ColumnLU, _gstrs_works
from softflow.solve.thermal import configure_thermal

P0 = sf.pressure_atmospheric


class LeakyOrifice(sf.Component):
    """User two-port with a local volume flow q: its own-unknown block (mf_a, mf_b,
    q) is not triangular, so it goes through the batched LAPACK path."""

    def __init__(self, label, G=1e-9):
        super().__init__(label)
        self.set_terminals(
            sf.Terminal("a", [sf.Variable("pressure", "across", label="p"),
                              sf.Variable("massflow", "through", label="mf")]),
            sf.Terminal("b", [sf.Variable("pressure", "across", label="p"),
                              sf.Variable("massflow", "through", label="mf")]))
        self.set_locals(sf.Variable("volumeflow", "local", label="q"))

        def evaluate(p_a, p_b, mf_a, mf_b, q):
            return [mf_a + mf_b, mf_a - 1.2 * q, 1.2 * q + mf_a - 2 * 1.2 * G * (p_a - p_b)]
        self.evaluate = self.auto(evaluate)


def mixed_network(n=12, user=True):
    """A source feeding a chain of mixed flow elements and volumes, with cross
    links (loops), a flow source and (isothermal only) a user component."""
    air = sf.air
    s = sf.System()
    s += sf.PressureSource("src", pressure=lambda t: P0 + (3e4 if t > 2e-3 else 1e4))
    prev = ("src", "a")
    for i in range(n):
        kind = i % 5
        if kind == 0:
            el = sf.CircularTube(f"e{i}", air, length=0.2, diameter=2e-3)
        elif kind == 1:
            el = sf.Orifice(f"e{i}", air, diameter=1e-3, Cd=0.6)
        elif kind == 2:
            el = sf.CheckValve(f"e{i}", air, diameter=1e-3, cracking_pressure=1e3,
                               leakage=1e-10)
        elif kind == 3:
            el = sf.TeslaValve(f"e{i}", air, length=0.05, diameter=1e-3)
        else:
            el = InertialCircularTube(f"e{i}", air, length=0.3, diameter=2e-3)
        kind = i % 3
        if kind == 0:
            vol = sf.Container(f"v{i}", air, volume=5e-6, initial_pressure=P0)
        elif kind == 1:
            vol = sf.LinearAccumulator(f"v{i}", air, volume=5e-6, compliance=1e-10)
        else:
            vol = sf.Actuator(f"v{i}", air, curve_monotonic(), initial_pressure=P0)
        s += el
        s += vol
        s.connect(prev, (el.label, "a"))
        s.connect((el.label, "b"), (vol.label, "a"))
        prev = (vol.label, "a")
        if i >= 2 and i % 4 == 0:
            link = sf.CircularTube(f"link{i}", air, length=0.5, diameter=1e-3)
            s += link
            s.connect((f"v{i - 2}", "a"), (link.label, "a"))
            s.connect((link.label, "b"), (vol.label, "a"))
    s += sf.MassFlowSource("inflow", massflow=1e-7)
    s.connect("inflow", prev)
    if user:
        s += LeakyOrifice("leak")
        s += sf.PressureSource("vent", pressure=P0)
        s.connect(("v1", "a"), ("leak", "a"))
        s.connect(("leak", "b"), ("vent", "a"))
    return s


def _assembly(thermal):
    s = mixed_network(user=thermal == "isothermal")
    configure_thermal(s, thermal)
    return Assembly(s)


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_condensed_solve_matches_sparse_lu(thermal):
    asm = _assembly(thermal)
    rng = np.random.default_rng(3)
    x = asm.x0.copy()
    x[:asm.n_across] *= 1 + 0.05 * rng.random(asm.n_across)   # flows in both directions
    x[asm.n_across:] = 1e-5 * rng.standard_normal(asm.n - asm.n_across)
    asm.residual(x, asm.S0, 0.0, 1e-3, jac=True)
    full, cond = SparseLU(asm), CondensedLU(asm)
    full.factor()
    cond.factor()
    assert cond.mode == "condensed"
    assert cond.plan.nr < asm.n / 2
    kinds = {b.order is None for b in cond.plan.blocks}
    assert kinds == ({True, False} if thermal == "isothermal" else {False})
    A = asm.jacobian_csc()
    scale = np.abs(A).max(axis=1).toarray().ravel()
    for _ in range(3):
        b = rng.standard_normal(asm.n)
        xf, xc = full.solve(b), cond.solve(b)
        # as accurate as the LU of the whole (row-scaled condition ~1e8 here)
        res_f, res_c = (np.max(np.abs(A @ x - b) / scale) for x in (xf, xc))
        assert res_c < max(10 * res_f, 1e-13)
        np.testing.assert_allclose(xc, xf, rtol=1e-6, atol=1e-9 * np.abs(xf).max())
    np.testing.assert_array_equal(cond.row_scale, full.row_scale)


def _sparse_solution(asm, b):
    full = SparseLU(asm)
    full.factor()
    return full.solve(b)


def test_volumes_at_dt_zero_stay_in_the_node_system():
    asm = _assembly("adiabatic")
    asm.residual(asm.x0, asm.S0, 0.0, 0.0, jac=True)   # consistent initial values
    cond, full = CondensedLU(asm), SparseLU(asm)
    cond.factor()
    full.factor()
    assert cond.mode == "condensed" and cond.active is not cond.plan
    # the plan without exclusions was only tested: its matrices are not built
    assert cond.plan._pending is not None and cond.active._pending is None
    kept = {type(b.g.comps[0]).__name__ for b in cond.active.blocks}
    assert kept and not kept & {"ThermalContainer", "ThermalLinearAccumulator", "ThermalActuator"}
    b = np.random.default_rng(0).standard_normal(asm.n)
    xf = full.solve(b)
    np.testing.assert_allclose(cond.solve(b), xf, rtol=1e-6, atol=1e-9 * np.abs(xf).max())
    # the next factorization with dt > 0 condenses everything again, from the cache
    asm.residual(asm.x0, asm.S0, 0.0, 1e-3, jac=True)
    cond.factor()
    assert cond.active is cond.plan and cond.plan._pending is None
    assert len(asm.solver_cache["condensation"]) == 2
    np.testing.assert_allclose(cond.solve(b), _sparse_solution(asm, b), rtol=1e-6,
                               atol=1e-9 * np.abs(xf).max())


def test_singular_and_nonfinite_jacobians_raise_as_before():
    asm = _assembly("isothermal")
    asm.residual(asm.x0, asm.S0, 0.0, 1e-3, jac=True)
    g, _ = asm.where["src"]
    asm.raw[g.j0:g.j1] = 0.0            # the source's equation no longer fixes its pressure
    with pytest.raises(SingularJacobian) as cond_err:
        CondensedLU(asm).factor()
    with pytest.raises(SingularJacobian) as full_err:
        SparseLU(asm).factor()
    assert str(cond_err.value) == str(full_err.value)
    asm.raw[-1] = np.nan
    with pytest.raises(SingularJacobian, match="NaN"):
        CondensedLU(asm).factor()


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_simulation_results_match_sparse_lu(thermal):
    kw = dict(duration=0.01, step=5e-4, newton_rtol=1e-12, thermal=thermal)
    user = thermal == "isothermal"
    a = sf.Simulation(mixed_network(user=user), linear_solver="sparse", **kw).run()
    b = sf.Simulation(mixed_network(user=user), linear_solver="condensed", **kw).run()
    assert a.stats["linear_solver"] == "sparse" and b.stats["linear_solver"] == "condensed"
    for args in (("v5", "pressure"), ("e3", "massflow", "a"), ("v11", "pressure")):
        va, vb = a.get(*args), b.get(*args)
        np.testing.assert_allclose(vb, va, rtol=1e-8, atol=1e-8 * np.abs(va).max())
    if thermal != "isothermal":
        Ta, Tb = a.get("v7", "temperature"), b.get("v7", "temperature")
        np.testing.assert_allclose(Tb, Ta, rtol=1e-9)


def test_auto_condenses_above_the_dense_size_only():
    small, large = Assembly(mixed_network(n=12)), Assembly(mixed_network(n=40))
    assert small.n <= 128 < large.n
    assert make_linear_solver(small).kind == "dense"
    assert make_linear_solver(large).kind == "condensed"


def test_auto_keeps_sparse_lu_where_nothing_condenses():
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0)
    for i in range(70):     # > DENSE_MAX unknowns, all of them node pressures and source flows
        s += sf.PressureSource(f"p{i}", pressure=P0 + i)
    asm = Assembly(s, allow_unconnected=True)
    assert make_linear_solver(asm).kind == "sparse"
    assert make_linear_solver(asm, "condensed").worthwhile is False


def test_columnwise_solve_matches_superlu():
    assert _gstrs_works() in (True, False)
    if not _gstrs_works():
        pytest.skip("this SciPy has no usable gstrs: SuperLU.solve is used")
    rng = np.random.default_rng(5)
    n = 40
    A = np.kron(np.eye(n // 2) * 3 + np.eye(n // 2, k=1) - np.eye(n // 2, k=-1),
                rng.random((2, 2)) + np.eye(2))
    A = csc_matrix(A)
    perm = ColumnLU.column_order(A)
    inv = np.argsort(perm)
    Ap = A[:, inv]                    # columns in the fill-reducing order
    b = rng.random(n)
    x = {}
    for columnwise in (True, False):
        lu = ColumnLU(columnwise=columnwise)
        lu.factor(csc_matrix(Ap))
        x[columnwise] = lu.solve(b)
    np.testing.assert_allclose(x[True], x[False], rtol=1e-12)
    np.testing.assert_allclose(Ap @ x[True], b, rtol=1e-12)


def test_block_regularity_test_agrees_with_scipys_matching():
    """A group is condensed where its own-unknown block is structurally regular:
    the small augmenting-path matching says so exactly where SciPy's maximum
    bipartite matching matches every row (random patterns up to 7 x 7)."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching
    from softflow.solve.condense import _perfect_matching
    rng = np.random.default_rng(0)
    seen = set()
    for _ in range(2000):
        n = int(rng.integers(1, 8))
        density = rng.uniform(0.1, 0.9)
        cells = {(r, c) for r in range(n) for c in range(n) if rng.random() < density}
        if not cells:
            continue
        r, c = np.array(sorted(cells)).T
        block = csr_matrix((np.ones(len(r)), (r, c)), shape=(n, n))
        want = bool((maximum_bipartite_matching(block, perm_type="column") >= 0).all())
        assert _perfect_matching(cells, n) == want
        seen.add(want)
    assert seen == {True, False}


@pytest.mark.parametrize("dt", [1e-3, 0.0])
def test_compiled_block_inverses_against_lapack(dt):
    """Each triangular block's X = B^-1 [I | A_er] from the compiled pass
    (softflow.laws.condense.invert_blocks, one call for all blocks) against
    numpy.linalg.solve of the block built from its pattern; at dt = 0 the
    volumes' blocks (singular there) are flagged, and only those."""
    asm = _assembly("adiabatic")
    rng = np.random.default_rng(7)
    x = asm.x0.copy()
    x[:asm.n_across] *= 1 + 0.05 * rng.random(asm.n_across)
    x[asm.n_across:] = 1e-5 * rng.standard_normal(asm.n - asm.n_across)
    asm.residual(x, asm.S0, 0.0, dt, jac=True)
    plan = CondensedLU(asm).plan
    raw = asm.raw.copy()
    assert plan._triangular.size == len(plan.blocks) > 5
    singular = plan.singular(raw)
    volumes = {"Container", "LinearAccumulator", "Actuator"}
    checked = 0
    for j, b in enumerate(plan.blocks):
        g, k, m = b.g, b.k, b.m
        J = raw[g.j0:g.j1].reshape(g.n, len(g.pattern))
        X = plan.values[b.xoff:b.xoff + b.xsize].reshape(g.n, k, k + m)
        if type(g.comps[0]).__name__ in volumes and dt == 0.0:
            assert b.index in singular
            continue
        assert b.index not in singular
        for i in range(g.n):
            M = np.zeros((k, 2 * k + m))
            for e in range(k):
                M[e, k + e] = 1.0
                for p, c in b.rows[e]:
                    M[e, c if c < k else k + c] += J[i, p]
            ref = np.linalg.solve(M[:, :k], M[:, k:])
            np.testing.assert_allclose(X[i], ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
            checked += 1
    assert checked >= len(plan.blocks) - 3
