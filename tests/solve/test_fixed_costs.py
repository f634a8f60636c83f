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


# -- issue 38, fixed costs (2): the compile's small paths, its regularity answers,
# the checks' Python paths -------------------------------------------------------------
from softflow.components.base import Params                                 # noqa: E402
from softflow.components.sources import _SourceParams                        # noqa: E402
from softflow.solve import assembly, input_checks, validity                  # noqa: E402
from softflow.solve.thermal import configure_thermal                         # noqa: E402

from helpers import (UserChamber, rc_circuit, snapping_valve_scene,          # noqa: E402
                     tank_and_actuator)


def _every_scene():
    """The paper scenes, the RC circuit, the chain (151 terminals: the small
    paths still) and a thermal scene (compiled from a configured copy)."""
    out = [(s, "isothermal") for s in _scenes() + [rc_circuit(), _chain(30)]]
    user = rc_circuit()                # a user's component among the library's
    user += UserChamber("chamber")
    user.connect("chamber", ("acc", "a"))
    return out + [(tank_and_actuator(), "adiabatic"), (ps.fig5(sf.air), "heat_transfer"),
                  (user, "isothermal"), (snapping_valve_scene(), "isothermal")]


def _compiled(system, thermal, **patches):
    """An Assembly of ``system`` (configured for ``thermal`` on a copy) with the
    module attributes ``patches`` of softflow.solve.assembly in force."""
    import copy
    model = system if thermal == "isothermal" else copy.deepcopy(system)
    if thermal != "isothermal":
        for c in model.components:        # a wall for the volumes that need one
            if getattr(c, "states", None) and getattr(c, "fluid", None) is not None \
                    and thermal == "heat_transfer" and hasattr(c, "hA"):
                c.hA = 0.05
        configure_thermal(model, thermal)
    saved = {k: getattr(assembly, k) for k in patches}
    try:
        for k, v in patches.items():
            setattr(assembly, k, v)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return Assembly(model, allow_unconnected=True)
    finally:
        for k, v in saved.items():
            setattr(assembly, k, v)


def _arrays(asm):
    """What the numbering and the pattern made, array by array (dtypes too)."""
    out = {k: getattr(asm, k) for k in ("x0", "S0", "through_rows", "through_cols", "q_id",
                                         "q_order", "q_starts", "indices", "indptr", "_inv",
                                         "pattern_rows", "pattern_cols", "raw", "s_discrete",
                                         "s_continuous")}
    if not asm.duplicates:
        out["_order"] = asm._order
    for k, g in enumerate(asm.groups):
        out[f"col{k}"] = g.col
    return out


def _same_arrays(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
        assert np.array_equal(a[k], b[k]), k


def _same_compile(small, numpy_):
    _same_arrays(_arrays(small), _arrays(numpy_))
    for k in ("n", "nnz", "duplicates", "n_across", "n_node_rows", "x_quantity", "q_names",
              "s_quantity", "node_row_quantities", "has_discrete"):
        assert getattr(small, k) == getattr(numpy_, k), k
    assert list(small.x_names) == list(numpy_.x_names)
    assert list(small.row_names) == list(numpy_.row_names)
    # the initial values of other components (Assembly.replace) the same way too
    assert np.array_equal(small._initial_unknowns(), numpy_._initial_unknowns())


@pytest.mark.parametrize("k", range(len(_every_scene())))
def test_the_small_numbering_pattern_and_initial_values_are_numpys(k):
    system, thermal = _every_scene()[k]
    small = _compiled(system, thermal)
    assert small.n <= assembly.SMALL_NUMBERING_MAX
    _same_compile(small, _compiled(system, thermal, SMALL_NUMBERING_MAX=-1))


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(networks())
def test_the_small_numbering_of_random_networks_is_numpys(net):
    try:
        small = _compiled(net.system, net.thermal)
    except sf.NetworkError as err:
        with pytest.raises(sf.NetworkError, match="^" + __import__("re").escape(str(err))):
            _compiled(net.system, net.thermal, SMALL_NUMBERING_MAX=-1)
        return
    _same_compile(small, _compiled(net.system, net.thermal, SMALL_NUMBERING_MAX=-1))


def test_a_group_of_one_has_the_layout_compared_member_by_member():
    seen = 0
    for system, thermal in _every_scene():
        asm = _compiled(system, thermal)
        for g in asm.groups:
            if g.row is not None:
                continue
            for c in g.comps:
                own, shared = assembly._own_layout(c), assembly._shared_layout([c])
                assert (own.slots, own.terminal_sigs, own.lists, own.first) == \
                    (shared.slots, shared.terminal_sigs, shared.lists, shared.first)
                seen += 1
    assert seen > 50


def test_an_affine_group_description_is_made_on_first_use_and_anew_on_replace():
    sim = sf.Simulation(rc_circuit(), duration=0.1)
    g, _ = sim.asm.where["tube"]
    assert g._affine is assembly._UNMADE
    made = g.affine
    want = g.cls.affine(g.params)
    assert np.array_equal(made.coef, want.coef) and g.affine is made       # made once
    assert sim.asm.where["src"][0].affine.offset is not None
    # the per-group residual (which reads them) as before: the compiled one's values
    F = sim.asm.residual(sim.asm.x0, sim.asm.S0, 0.0, 1e-3)
    assert np.allclose(sim.asm.python_residual(sim.asm.x0, sim.asm.S0, 0.0, 1e-3), F,
                       rtol=1e-12, atol=0)
    sim.asm.replace({"tube": sf.CircularTube("tube", sf.water, length=1.0, diameter=0.6e-3)})
    assert g._affine is assembly._UNMADE
    assert not np.array_equal(g.affine.coef, made.coef)


def _params_per_name(comps):
    """Params' arrays as made before: one np.array per name."""
    return {name: np.array([getattr(c, name) for c in comps], dtype=float)
            for name in type(comps[0]).param_names}


def test_params_in_one_table_are_the_arrays_per_name():
    seen = set()
    for system, thermal in _every_scene():
        for g in _compiled(system, thermal).groups:
            if g.row is not None:
                continue
            P = Params(g.comps)
            for name, want in _params_per_name(g.comps).items():
                got = getattr(P, name)
                assert got.dtype == want.dtype and got.shape == want.shape
                assert np.array_equal(got, want, equal_nan=True), name
                seen.add(type(g.comps[0]).__name__)
    assert {"CircularTube", "Actuator", "TeslaValve", "LinearAccumulator"} <= seen

    class Vector(sf.LinearAccumulator):       # a parameter per instance that is a vector
        param_names = ("volume", "pair")

    a = Vector("a", sf.water, volume=1e-6, compliance=1e-11)
    b = Vector("b", sf.water, volume=2e-6, compliance=1e-11)
    a.pair, b.pair = (1.0, 2.0), (3.0, 4.0)
    P = Params([a, b])
    assert P.pair.shape == (2, 2) and P.pair.tolist() == [[1.0, 2.0], [3.0, 4.0]]
    assert P.volume.tolist() == [1e-6, 2e-6]


def _old_source_flags(comps):
    """_SourceParams' _slot, _one_signal and _uniform as it made them before."""
    signals = [c.signal for c in comps]
    offsets = np.array([getattr(c, "offset", 0.0) for c in comps])
    base = offsets + [0.0 if s.func is not None else s.const for s in signals]
    slots, varying = {}, []
    slot = np.zeros(len(comps), dtype=np.int64)
    for i, s in enumerate(signals):
        if s.func is not None:
            if id(s.func) not in slots:
                varying.append(s)
                slots[id(s.func)] = len(varying)
            slot[i] = slots[id(s.func)]
    one = len(varying) == 1 and bool(np.all(slot == 1))
    uniform = (not varying or one) and bool(np.all(base == base[0]))
    return slot, one, uniform, base


def test_the_source_groups_flags_are_as_before():
    from softflow.curves.waveforms import Step
    step = Step(0.1, 1e5, 2e5)
    cases = [[sf.PressureSource("a", 2e5)],
             [sf.PressureSource("a", 2e5), sf.PressureSource("b", 2e5)],
             [sf.PressureSource("a", 2e5), sf.PressureSource("b", 3e5)],
             [sf.PressureSource("a", step)],
             [sf.PressureSource("a", step), sf.PressureSource("b", step)],
             [sf.PressureSource("a", step), sf.PressureSource("b", 2e5)],
             [sf.PressureSource("a", step), sf.PressureSource("b", lambda t: 1e5 + t)],
             [sf.PressureSource("a", step), sf.PressureSource("b", step, gauge=True)],
             [sf.MassFlowSource("a", 1e-6), sf.MassFlowSource("b", float("nan"))]]
    for comps in cases:
        try:
            P = _SourceParams(comps)
        except ValueError:
            continue
        slot, one, uniform, base = _old_source_flags(comps)
        assert P._slot.dtype == slot.dtype and np.array_equal(P._slot, slot)
        assert (P._one_signal, P._uniform) == (one, uniform)
        assert np.array_equal(P._base, base, equal_nan=True)


def test_the_regularity_tests_answer_a_scene_compiled_again_from_memory():
    for build in (rc_circuit, lambda: ps.fig3("monotonic"), lambda: _chain(3)):
        dense, structural = assembly._DENSE_REGULAR.calls, assembly._STRUCTURAL.calls
        first = sf.Simulation(build(), duration=0.01)
        made = assembly._DENSE_REGULAR.calls - dense, assembly._STRUCTURAL.calls - structural
        again = sf.Simulation(build(), duration=0.01)
        assert (assembly._DENSE_REGULAR.calls - dense,
                assembly._STRUCTURAL.calls - structural) == made    # none asked again
        assert np.array_equal(first.run(raise_on_failure=False).X,
                              again.run(raise_on_failure=False).X)
    # the answers are the tests' own
    for J in [np.eye(3), np.zeros((2, 2)), np.array([[1.0, 1.0], [1.0, 1.0 + 1e-14]]),
              np.array([[2.0, 1e-30], [0.0, 3.0]])]:
        assert assembly._DENSE_REGULAR(assembly._array_key(J), J) == _is_regular_dense(J.copy())


def test_a_changed_parameter_is_tested_and_run_with_its_new_value():
    system = rc_circuit()
    first = sf.Simulation(system, duration=0.5).run()
    calls = assembly._DENSE_REGULAR.calls
    system.get("acc").compliance *= 3.0      # the same System, one number changed
    changed = sf.Simulation(system, duration=0.5)
    assert assembly._DENSE_REGULAR.calls > calls        # another Jacobian: tested
    fresh = rc_circuit()
    fresh.get("acc").compliance *= 3.0
    want = sf.Simulation(fresh, duration=0.5).run()
    got = changed.run()
    assert np.array_equal(got.X, want.X) and not np.array_equal(got.X[-1], first.X[-1])


def test_a_singular_network_is_refused_again_with_its_message():
    def singular():
        s = sf.System()
        s += sf.PressureSource("src", pressure=2e5)
        s += sf.Container("tank", sf.air, volume=1e-5)
        s.connect("src", "tank")
        return s
    messages = set()
    for _ in range(2):
        with pytest.raises(sf.NetworkError) as err:
            sf.Simulation(singular(), duration=0.1)
        messages.add(str(err.value))
    assert len(messages) == 1 and "undetermined" in messages.pop()


def test_the_answers_are_bounded():
    memo = assembly._Answers(lambda x: x > 0, size=3)
    for v in range(10):
        assert memo((v,), v) == (v > 0)
    assert len(memo.known) == 3 and memo.calls == 10
    assert memo((9,), 9) and memo.calls == 10


def test_the_small_liquid_nodes_are_numpys(monkeypatch):
    for system, thermal in _every_scene() + [(ps.fig5(sf.water), "isothermal")]:
        asm = _compiled(system, thermal)
        for keep in (None, lambda f: True):
            small = model_checks._liquid_nodes(asm, keep=keep)
            asm.__dict__.pop("_liquid_nodes")
            with monkeypatch.context() as m:
                m.setattr(model_checks, "SMALL_NETWORK", -1)
                numpy_ = model_checks._liquid_nodes(asm, keep=keep)
            asm.__dict__.pop("_liquid_nodes")
            assert small.keys() == numpy_.keys()
            for key in small:
                (f1, n1, o1), (f2, n2, o2) = small[key], numpy_[key]
                assert f1 is f2 and n1.dtype == n2.dtype and np.array_equal(n1, n2)
                assert [(id(g), p) for g, p in o1] == [(id(g), p) for g, p in o2]


def test_the_vapour_pressure_is_remembered_by_what_it_depends_on(monkeypatch):
    from softflow.fluids.ideal import ConstantLiquid
    from softflow.fluids.tables import TABLES_ENV
    from softflow.fluids.vapour import vapour_pressure
    asked = []

    def counting(fluid, temperature=None):
        asked.append(fluid)
        return vapour_pressure(fluid, temperature)
    model_checks._vapour_pressure(sf.water)        # (the names imported)
    monkeypatch.setattr(model_checks, "_VAPOUR_FN", (TABLES_ENV, counting))
    monkeypatch.setattr(model_checks, "_VAPOUR", {})
    hot = ConstantLiquid("water", 985.0, 5e-4, temperature=330.0, spec=sf.water.spec)
    bare = ConstantLiquid("oil", 900.0, 1e-2)
    for fluid in (sf.water, sf.ethylene_glycol, hot, bare):
        assert model_checks._vapour_pressure(fluid) == vapour_pressure(fluid)
    assert len(asked) == 4
    for fluid in (sf.water, sf.ethylene_glycol, hot):
        model_checks._vapour_pressure(fluid)
    assert len(asked) == 4                            # remembered
    model_checks._vapour_pressure(bare)
    assert len(asked) == 5                            # no spec: asked every time
    assert model_checks._vapour_pressure(hot) != model_checks._vapour_pressure(sf.water)
    monkeypatch.setenv(TABLES_ENV, "/nonexistent")
    model_checks._vapour_pressure(sf.water)
    assert len(asked) == 6                            # another tables directory


def _old_initial_volume_records(comps):
    """initial_volume_records' selection as it was (NumPy): (index, volume)."""
    from softflow.components.actuators import INITIAL_VOLUME_SLACK, _data_range
    found = _data_range(comps[0])
    if found is None:
        return []
    lo, hi, _, _ = found
    slack = INITIAL_VOLUME_SLACK * (hi - lo)
    v0 = np.fromiter((c.initial_volume for c in comps), dtype=float, count=len(comps))
    return [(int(k), float(v0[k])) for k in np.flatnonzero((v0 < lo - slack) |
                                                            (v0 > hi + slack))]


def test_initial_volume_records_select_as_before():
    from softflow.components.actuators import initial_volume_records
    curve = ps.curve_plateau(20.0)
    lo, hi = float(curve.volume[0]), float(curve.volume[-1])
    volumes = [lo, hi, 0.5 * lo, hi + 0.5 * (hi - lo), 0.5 * (lo + hi),
               hi + 0.001 * (hi - lo)]
    comps = [sf.Actuator(f"a{k}", sf.water, curve, initial_volume=v)
             for k, v in enumerate(volumes)]
    got = initial_volume_records(comps)
    want = _old_initial_volume_records(comps)
    assert [(r.component, r.measured) for r in got] == [(f"a{k}", v) for k, v in want]
    assert want and not {0, 1, 4} & {k for k, _ in want}


def test_pv_curve_range_warns_of_a_volume_without_numbers_as_nanmax_did():
    sim = sf.Simulation(ps.fig3("monotonic"), duration=1.0, beyond_limits="warn")
    res = sim.run()
    g, _ = sim.asm.where["act1"]
    res.S[:, g.s0] = np.nan                 # act1's mass: its volume NaN throughout
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert validity.pv_curve_range(g, res) == []
    assert [(w.category, str(w.message)) for w in seen] == \
        [(RuntimeWarning, "All-NaN slice encountered")] * 2
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        np.nanmax(res.S[:, [g.s0]], axis=0)
        np.nanmin(res.S[:, [g.s0]], axis=0)
    assert [(w.category, str(w.message)) for w in seen] == \
        [(RuntimeWarning, "All-NaN slice encountered")] * 2


def test_group_values_of_a_complete_result_are_those_of_a_recorded_one():
    for build, fig in ((lambda: ps.fig3("monotonic"), 3), (lambda: ps.fig5(sf.air), 5)):
        sim = sf.Simulation(build(), duration=2.0, beyond_limits="warn")
        res = sim.run()
        for g in sim.asm.groups:
            for name in ("pressure_a", "massflow_a", "mass", "volume", "pressure"):
                try:
                    keep, got = validity.group_values(g, res, name)
                except KeyError:
                    continue
                validity._FOUND.pop(g, None)
                res._complete = False          # the general path: every column looked up
                try:
                    keep2, want = validity.group_values(g, res, name)
                finally:
                    res._complete = True
                assert keep == keep2 and np.array_equal(got, want, equal_nan=True)


def test_the_input_checks_import_their_names_once():
    names = input_checks._names()
    assert input_checks._names() is names
    from softflow.components.actuators import Actuator, initial_volume_records
    assert names.Actuator is Actuator and names.initial_volume_records is initial_volume_records


def test_an_outputs_variables_are_found_once_per_group():
    sim = sf.Simulation(ps.fig5(sf.air), duration=2.0, beyond_limits="warn")
    res = sim.run()
    g, _ = sim.asm.where["act1"]
    validity._FOUND.pop(g, None)
    keep, vol = validity.group_values(g, res, "volume")
    assert {"mass", "pressure"} <= set(validity._FOUND[g])     # what the output read
    _, mass = validity.group_values(g, res, "mass")
    assert np.array_equal(vol, mass / sf.air.density(res.get("act1", "pressure"))[:, None])
    assert np.array_equal(mass[:, 0], res.get("act1", "mass"))
    assert np.array_equal(validity.group_values(g, res, "volume")[1], vol)


def test_a_missing_name_gives_the_default_or_the_error_as_before():
    sim = sf.Simulation(rc_circuit(), duration=0.01)
    res = sim.run()
    g, _ = sim.asm.where["acc"]
    marker = object()
    assert validity.group_values(g, res, "temperature", default=marker) is marker
    with pytest.raises(KeyError, match="has no variable 'temperature'; it has"):
        validity.group_values(g, res, "temperature")
    assert validity.group_values(g, res, "temperature", default=marker) is marker
    assert res._lookup("acc", "temperature", None) is None
    with pytest.raises(KeyError, match="has no variable 'temperature'; it has"):
        res.get("acc", "temperature")
    with pytest.raises(KeyError, match="ambiguous"):
        res._lookup("tube", "pressure", None)
    tube, _ = sim.asm.where["tube"]
    with pytest.raises(KeyError, match="ambiguous"):
        validity.group_values(tube, res, "pressure")
    assert validity.group_values(tube, res, "pressure", default=marker) is marker
    assert res._lookup("acc", "volume", None) == res._entry("acc", "volume", None)


def test_the_checks_of_a_class_are_those_registered_for_it_in_order():
    validity.checks_version()
    kinds = {type(g.comps[0]) for system, thermal in _every_scene()
             for g in _compiled(system, thermal).groups}
    for kind in kinds:
        want = [check for cls, checks in validity._CHECKS.items() if isinstance(
            object.__new__(kind), cls) for check in checks]
        assert validity._checks_of(kind) == want

    def extra(g, result):
        return []
    validity.register(sf.Container, extra)
    try:
        assert validity._checks_of(sf.Container)[-1] is extra
    finally:
        validity._CHECKS[sf.Container].remove(extra)
        validity._VERSION += 1
    assert extra not in validity._checks_of(sf.Container)


def test_the_collector_is_paused_and_restored_as_it_was():
    import gc

    from softflow.solve.simulation import _collector_paused
    assert gc.isenabled()
    with pytest.raises(ValueError):
        with _collector_paused():
            assert not gc.isenabled()
            raise ValueError
    assert gc.isenabled()
    gc.disable()
    try:
        with _collector_paused():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_numpys_huge_pages_are_off_during_a_run_and_restored_as_they_were(monkeypatch):
    """settings.HUGE_PAGES = False (the default): NumPy's madvise switch is
    off while a run integrates and builds its result, and put back as it
    was (on or off), also where the run raises; runs in threads hold it
    together and the last to leave restores it; True leaves it alone. The
    numbers are the same either way."""
    import threading

    from softflow.solve import settings as solve_settings
    from softflow.solve import simulation as sim_mod
    if sim_mod._MADVISE is None:
        pytest.skip("this NumPy has no madvise switch")
    state = {"on": True}
    calls = []
    seen = []

    def switch(enabled):
        calls.append(bool(enabled))
        before, state["on"] = state["on"], bool(enabled)
        return before

    monkeypatch.setattr(sim_mod, "_MADVISE", switch)

    from softflow.solve.integrator import Integrator
    integrate = Integrator.run

    def spied(self):
        seen.append(state["on"])
        return integrate(self)

    monkeypatch.setattr(Integrator, "run", spied)

    sim = sf.Simulation(ps.fig3(ps.FIG3_CASES[0]), duration=ps.duration(3))
    a = sim.run()
    assert seen == [False] and state["on"] and calls[:1] == [False] and calls[-1] is True
    calls.clear()
    state["on"] = False          # a process that turned them off itself
    b = sim.run()
    assert state["on"] is False and calls and all(c is False for c in calls)
    np.testing.assert_array_equal(a.X, b.X)

    # an error inside the run: restored
    state["on"] = True
    with pytest.raises(RuntimeError, match="inside"):
        with sim_mod._huge_pages_off():
            assert state["on"] is False
            raise RuntimeError("inside")
    assert state["on"] is True

    # two holders in threads: off until the last leaves
    inside = threading.Barrier(3)
    leave = [threading.Event(), threading.Event()]

    def hold(i):
        with sim_mod._huge_pages_off():
            inside.wait()
            leave[i].wait()

    threads = [threading.Thread(target=hold, args=(i,)) for i in range(2)]
    for th in threads:
        th.start()
    inside.wait()
    assert state["on"] is False
    leave[0].set()
    threads[0].join()
    assert state["on"] is False          # the other still holds it
    leave[1].set()
    threads[1].join()
    assert state["on"] is True and sim_mod._huge_pages_off._holders == 0

    # HUGE_PAGES = True: left alone
    monkeypatch.setattr(solve_settings, "HUGE_PAGES", True)
    calls.clear()
    c = sim.run()
    assert calls == [] and state["on"] is True
    np.testing.assert_array_equal(a.X, c.X)
