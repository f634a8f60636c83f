"""The fixed costs of a run cut without changing its results (issue 38): the
Jacobian's blocks that softflow.solve.sourcenodes reads (a dense copy or the
CSR arrays instead of SciPy's sparse slicing), the structure it reads once per
network, the structural and numerical regularity tests of the Assembly, the
Python residual made on first use, the checks' shared work. Each is compared
with what it replaced, value for value."""
import warnings

import numpy as np
import pytest
from scipy.linalg import LinAlgWarning, lu_factor
from scipy.sparse import csc_matrix
from scipy.sparse.csgraph import structural_rank

import softflow as sf
from softflow import paper_scenes as ps
from softflow.solve import model_checks, sourcenodes
from softflow.solve.assembly import Assembly, _is_regular_dense, _structurally_regular

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings
from test_random_networks import networks


def _scenes():
    out = [ps.fig3(case) for case in ps.FIG3_CASES]
    out += [ps.fig4(case) for case in ps.FIG4_CASES]
    out += [ps.fig5(f) for f in (sf.air, sf.water, sf.ethylene_glycol)]
    return out


def _chain(n):
    """A pump into a chain of n tubes and tanks: more unknowns than the dense
    copy takes (the CSR path)."""
    s = sf.System()
    s += sf.MassFlowSource("pump", 1e-6)
    prev = ("pump", "a")
    for i in range(n):
        s += sf.CircularTube(f"t{i}", sf.air, 0.1, 1e-3)
        s += sf.Orifice(f"o{i}", sf.air, 1e-3, K=2.0)
        s += sf.Container(f"c{i}", sf.air, 1e-5)
        s.connect(prev, (f"t{i}", "a"))
        s.connect((f"t{i}", "b"), (f"o{i}", "a"))
        s.connect((f"o{i}", "b"), f"c{i}")
        prev = (f"c{i}", "a")
    return s


def _old_block(asm):
    """The block reader this module replaced: SciPy's sparse slicing."""
    J = asm.jacobian_csc().tocsr()
    return lambda rows, cols: J[rows][:, cols].toarray()


def _key(loc):
    return (loc.node, loc.p, loc.row, loc.rows.tolist(), loc.cols.tolist(),
            [id(c) for c in loc.sources], list(loc.source_rows), loc.ends.tolist(),
            [(id(c), list(cs)) for c, cs in loc.members], list(loc.inside), loc.dynamic)


class _ScipyBlocks:
    """sourcenodes._Jacobian as it was: SciPy's slicing of the CSR matrix."""

    def __init__(self, asm):
        self.block = _old_block(asm)


def _locals_every_way(asm, monkeypatch, region):
    """local_nodes' answers on dense blocks, on the CSR arrays and on SciPy's
    slicing (the old reader)."""
    out = []
    for way in ("dense", "csr", "scipy"):
        with monkeypatch.context() as m:
            if way == "csr":
                m.setattr(sourcenodes, "DENSE_CHECK_MAX", -1)
            elif way == "scipy":
                m.setattr(sourcenodes, "_Jacobian", _ScipyBlocks)
            asm.__dict__.pop("_source_topology", None)
            out.append([_key(loc) for loc in sourcenodes.local_nodes(
                asm, asm.x0, asm.S0, 0.0, region=region)])
    return out


def _old_topology(asm):
    """(owner, single) as local_nodes formed them before (NumPy per group)."""
    na, n = asm.n_across, asm.n
    node_of_col = np.full(na, -1, dtype=np.int64)
    for arr in asm.node_across.values():
        have = arr >= 0
        node_of_col[arr[have]] = np.flatnonzero(have)
    owner = np.full(n, -1, dtype=np.int64)
    single, count = [], 0
    for g in asm.groups:
        C = np.asarray(g.col, dtype=np.int64)
        if C.size == 0:
            continue
        base = count
        own = C >= na
        ids = np.broadcast_to(base + np.arange(g.n)[:, None], C.shape)
        owner[C[own]] = ids[own]
        at = np.where(own, -1, node_of_col[np.minimum(C, na - 1)])
        lo = np.where(own, np.iinfo(np.int64).max, at).min(axis=1)
        hi = at.max(axis=1)
        count += g.n
        single.extend((base + i, int(hi[i])) for i in np.flatnonzero((lo == hi) & (hi >= 0)))
    return owner.tolist(), single


@pytest.mark.parametrize("build", [lambda: ps.fig3("peak-valley"), lambda: ps.fig5(sf.water),
                                   lambda: _chain(30)])
def test_blocks_are_scipys_slices(build):
    asm = sf.Simulation(build(), duration=0.1).asm
    asm.residual(asm.x0, asm.S0, 0.0, 1e-3, jac=True)
    old = _old_block(asm)
    rng = np.random.default_rng(3)
    readers = [sourcenodes._Jacobian(asm)]
    sparse = sourcenodes._Jacobian.__new__(sourcenodes._Jacobian)
    sparse.__dict__.update(vars(readers[0]))
    if readers[0].dense is not None:       # the CSR path on a small network too
        J = sparse.csr = asm.jacobian_csc().tocsr()
        sparse.dense, sparse.indptr = None, J.indptr.astype(np.int64)
        sparse.indices, sparse.data = J.indices, J.data
        sparse.pos = np.full(asm.n, -1, dtype=np.int64)
        readers.append(sparse)
    for _ in range(300):
        rows = rng.integers(0, asm.n, rng.integers(0, 8))
        cols = (rng.integers(0, asm.n, rng.integers(0, 8)) if rng.random() < 0.2 else
                rng.permutation(asm.n)[:rng.integers(0, min(asm.n, 8))])
        want = old(rows, cols)
        for reader in readers:
            got = reader.block(rows.tolist() if rng.random() < 0.5 else rows, cols)
            assert got.shape == want.shape and np.array_equal(got, want)


@pytest.mark.parametrize("region", [False, True])
def test_local_nodes_of_the_paper_scenes_and_a_chain_every_way(region, monkeypatch):
    for system in _scenes() + [_chain(30)]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            asm = sf.Simulation(system, duration=0.1, allow_unconnected=True).asm
        dense, csr, scipy = _locals_every_way(asm, monkeypatch, region)
        assert dense == csr == scipy
        assert _old_topology(asm) == (sourcenodes._topology(asm).owner,
                                      sourcenodes._topology(asm).single)
    assert dense, "the chain's pump node"


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                 HealthCheck.function_scoped_fixture])
@given(networks())
def test_local_nodes_of_random_networks_every_way(monkeypatch, net):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            asm = sf.Simulation(net.system, allow_unconnected=True, thermal=net.thermal,
                                **net.options).asm
    except sf.NetworkError:
        return
    assert _old_topology(asm) == (sourcenodes._topology(asm).owner,
                                  sourcenodes._topology(asm).single)
    for region in (False, True):
        dense, csr, scipy = _locals_every_way(asm, monkeypatch, region)
        assert dense == csr == scipy


def test_structural_regularity_is_scipys():
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(3000):
        n = int(rng.integers(1, 30))
        A = (rng.random((n, n)) < rng.uniform(0.03, 0.4)).astype(float)
        if rng.random() < 0.5:
            A[np.arange(n), rng.permutation(n)] = 1.0
            if rng.random() < 0.3:
                A[rng.integers(n)] = 0.0
        M = csc_matrix(A)
        want = structural_rank(M) == n
        seen.add(want)
        assert _structurally_regular(n, M.indices, M.indptr) == want
    assert seen == {True, False}


def _old_regular_dense(J):
    if not J.size:
        return True
    r = np.abs(J).max(axis=1)
    if not r.all():
        return False
    J = J / r[:, None]
    c = np.abs(J).max(axis=0)
    if not c.all():
        return False
    J = J / c
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LinAlgWarning)
        lu, _ = lu_factor(J, check_finite=False)
    return bool(np.abs(np.diag(lu)).min() > 1e-12)


def test_numerical_regularity_is_as_before():
    rng = np.random.default_rng(2)
    cases = [np.array([[v]]) for v in (0.0, -0.0, 1e-300, -3.0, 5e300, np.inf, -np.inf, np.nan)]
    cases.append(np.zeros((0, 0)))
    for _ in range(2000):
        n = int(rng.integers(1, 12))
        A = rng.standard_normal((n, n)) * 10.0 ** rng.integers(-12, 12, (n, 1))
        if rng.random() < 0.3:
            A[:, rng.integers(n)] = A[:, 0] * rng.choice([1.0, 1.0 + 1e-13, 2.0])
        if rng.random() < 0.1:
            A[rng.integers(n), rng.integers(n)] = rng.choice([np.nan, np.inf, 0.0])
        cases.append(A)
    answers = set()
    with np.errstate(all="ignore"):
        for A in cases:
            want = _old_regular_dense(A)
            answers.add(want)
            assert _is_regular_dense(A.copy()) == want, A
    assert answers == {True, False}


def test_the_python_residual_is_made_on_first_use():
    asm = sf.Simulation(ps.fig3("monotonic"), duration=1.0).asm
    assert "_python_residual" not in asm.__dict__
    assert asm.residual is not asm.python_residual
    assert asm.python_residual is asm.python_residual          # made once
    F = asm.residual(asm.x0, asm.S0, 0.0, 1e-3)
    assert np.allclose(asm.python_residual(asm.x0, asm.S0, 0.0, 1e-3), F, rtol=1e-12, atol=0)


def test_the_laminar_shortfalls_of_tubes_at_once_are_each_ones():
    rng = np.random.default_rng(4)
    tubes = [sf.CircularTube(f"t{i}", sf.air, 0.1, float(d), roughness=float(e),
                             friction="laminar")
             for i, (d, e) in enumerate(zip(10 ** rng.uniform(-4, -2, 40),
                                            10 ** rng.uniform(-7, -4, 40)))]
    res = (10 ** rng.uniform(2, 5, 40)).tolist()
    assert (model_checks._laminar_shortfalls(tubes, res)
            == [model_checks.laminar_shortfall(t, r) for t, r in zip(tubes, res)])
    assert model_checks._laminar_shortfalls([], []) == []


def test_the_liquid_nodes_are_found_once_per_network():
    asm = Assembly(ps.fig5(sf.water))
    first = model_checks._liquid_nodes(asm)
    assert model_checks._liquid_nodes(asm) is first
    fresh = Assembly(ps.fig5(sf.water))
    again = model_checks._liquid_nodes(fresh)
    assert [(f.name, n.tolist()) for f, n, _ in first.values()] == \
        [(f.name, n.tolist()) for f, n, _ in again.values()]
    # another test of the fluids: its own answer
    assert model_checks._liquid_nodes(asm, keep=lambda f: True) is not first
