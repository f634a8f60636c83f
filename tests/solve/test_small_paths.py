"""The small-system paths of the solver give what the general ones give:
Newton's written-out step (Python-list tolerance scale and norm), the dense
LU's inverse, the thermal scenes' magnitude links and temperature clipping on
that path, and generated code cached by its text."""
import numpy as np
import pytest
from scipy.linalg import lu_factor, lu_solve

import softflow as sf
from softflow.solve import compiled, newton as newton_module
from softflow.solve.linalg import DenseLU

P0 = sf.pressure_atmospheric


@pytest.fixture(autouse=True)
def _python_loop(monkeypatch):
    """These scenes' sources are Python functions, which the compiled loop
    calls back by default; these tests are the Python step loop's."""
    monkeypatch.setattr("softflow.solve.settings.COMPILED_USER", False)

def _scene(fluid=sf.water, thermal="isothermal", step=2e-3):
    s = sf.System()
    s += sf.PressureSource("src", pressure=lambda t: P0 + (3e4 if t < 0.3 else 1e4))
    s += sf.CircularTube("tube", fluid, length=0.5, diameter=1e-3)
    s += sf.Container("tank", fluid, volume=2e-6) if fluid.compressible else \
        sf.LinearAccumulator("tank", fluid, volume=2e-6, compliance=1e-11)
    s += sf.CircularTube("tube2", fluid, length=0.3, diameter=1e-3)
    s += sf.Container("tank2", fluid, volume=1e-6) if fluid.compressible else \
        sf.LinearAccumulator("tank2", fluid, volume=1e-6, compliance=2e-11)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    s.connect(("tank", "a"), "tube2")
    s.connect("tube2", "tank2")
    return sf.Simulation(s, duration=0.6, step=step, thermal=thermal)


@pytest.mark.parametrize("step", [2e-3, None])
@pytest.mark.parametrize("fluid, thermal", [(sf.water, "isothermal"), (sf.air, "isothermal"),
                                            (sf.air, "adiabatic")])
def test_small_system_path_matches_the_general_one(monkeypatch, fluid, thermal, step):
    """At fixed steps, and adaptive (Newton at rtol / 20 with the pressures'
    gauge magnitudes and the run's magnitudes as a floor, on either path)."""
    fast = _scene(fluid, thermal, step)
    assert fast.asm.n <= newton_module.SMALL
    a = fast.run()
    # the general path: NumPy scale and norm, and no written-out step at all
    monkeypatch.setattr(newton_module, "SMALL", 0)
    init = newton_module.Newton.__init__

    def general(self, *args, **kwargs):
        init(self, *args, **kwargs)
        self._quick_ok = False

    monkeypatch.setattr(newton_module.Newton, "__init__", general)
    b = _scene(fluid, thermal, step).run()
    assert a.stats["steps"] == b.stats["steps"]
    assert abs(a.stats["newton_iterations"] - b.stats["newton_iterations"]) <= 2
    for label in ("tank", "tank2"):
        pa, pb = a.get(label, "pressure"), b.get(label, "pressure")
        assert np.max(np.abs(pa - pb)) <= 1e-6 * np.ptp(pa) + 1e-9 * P0


def test_written_out_step_takes_the_usual_steps(monkeypatch):
    """It must actually serve the run (else the test above compares a path with itself)."""
    sim = _scene()
    calls = []
    orig = newton_module.Newton._quick

    def spy(self, *args):
        out = orig(self, *args)
        calls.append(type(out) is newton_module.Outcome)
        return out

    newton_module.Newton._quick = spy
    try:
        res = sim.run()
    finally:
        newton_module.Newton._quick = orig
    # this scene needs two iterations in most steps (then _chord goes on from the
    # residual _quick evaluated); the others take the written-out step
    assert sum(calls) > 0.25 * res.stats["steps"]
    assert len(calls) + res.stats["factorizations"] >= res.stats["steps"]


def test_dense_inverse_solves_as_lapack():
    sim = _scene()
    sim.run()
    asm = sim.asm
    asm.residual(sim.result.X[-1], sim.result.S[-1], 0.5, 2e-3, jac=True)
    lin = DenseLU(asm)
    lin.factor()
    J = lin._J
    b = np.random.default_rng(3).standard_normal(asm.n) * np.abs(J).max(axis=1)
    x = lin.solve(b)
    ref = lu_solve(lu_factor(J), b)
    # equal to the round-off the conditioning allows, row by row in the residual
    assert np.all(np.abs(J @ x - b) <= 1e-9 * (np.abs(J) @ np.abs(ref) + np.abs(b)))


def test_generated_code_is_compiled_once_per_text():
    src = "def f(x):\n    return x + k"
    f1 = compiled.function(src, "f", {"k": 1})
    f2 = compiled.function(src, "f", {"k": 2})
    assert f1.__code__ is f2.__code__            # one compilation
    assert (f1(1), f2(1)) == (2, 3)               # each with its own values
    g = compiled.expression("lambda x: x * k", {"k": 3})
    assert g(2) == 6


def test_newton_takes_a_scalar_atol():
    sim = _scene()
    asm = sim.asm
    from softflow.solve.linalg import make_linear_solver
    nw = newton_module.Newton(asm, make_linear_solver(asm), newton_module.Stats(), atol=1e-6)
    out = nw.solve(asm.x0.copy(), asm.S0, 0.0, 0.0)
    assert out.converged


class _KeptArray(sf.Component):
    """A user actuator whose update_state hands back an array it keeps and
    overwrites at the next call (the solver must copy what it stores)."""

    def __init__(self, label, keep):
        super().__init__(label)
        self.set_terminals(sf.Terminal("a", [
            sf.Variable("pressure", "across", label="p", initial_value=P0),
            sf.Variable("massflow", "through", label="mf")]))
        self.set_states(sf.Variable("mass", "local", label="mass", initial_value=1e-3))
        buf = np.zeros(1)

        def evaluate(t, p, mass):
            return [p - (P0 + 1e9 * (mass - 1e-3))]

        def update_state(dt, mass, mf):
            if not keep:
                return [mass + mf * dt]
            buf[0] = mass + mf * dt
            return buf

        self.evaluate = self.auto(evaluate)
        self.update_state = self.auto_state(update_state)


def test_user_state_arrays_are_copied():
    runs = []
    for keep in (False, True):
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 2e4)
        s += sf.CircularTube("tube", sf.water, length=0.5, diameter=1e-3)
        s += _KeptArray("act", keep)
        s.connect("src", "tube")
        s.connect("tube", "act")
        runs.append(sf.Simulation(s, duration=0.2, step=1e-2).run())
    np.testing.assert_array_equal(runs[0].get("act", "mass"), runs[1].get("act", "mass"))
    assert runs[1].stats == runs[0].stats


def test_newton_tolerance_follows_rtol_in_adaptive_runs():
    """newton_rtol: 1e-6 at fixed steps; adaptive runs rtol / 20, or the value
    given where smaller; the floor of the run's magnitudes at 1e-6 of them, or
    a fifth of Newton's rtol where that is smaller."""
    from softflow.solve.bdf import newton_limits
    sim = _scene(step=None)
    assert sim.newton_rtol is None and sim._newton_rtol() == pytest.approx(1e-3 / 20)
    sim = _scene()
    assert sim._newton_rtol() == 1e-6
    s = sim.system
    assert sf.Simulation(s, duration=0.6, rtol=1e-5)._newton_rtol() == pytest.approx(5e-7)
    assert sf.Simulation(s, duration=0.6, newton_rtol=1e-9)._newton_rtol() == 1e-9
    assert sf.Simulation(s, duration=0.6, newton_rtol=1e-2)._newton_rtol() == pytest.approx(5e-5)
    assert sf.Simulation(s, duration=0.6, step=1e-3, newton_rtol=1e-8)._newton_rtol() == 1e-8
    for bad in (0.0, -1e-6, float("nan")):
        with pytest.raises(ValueError, match="newton_rtol must be a finite number > 0"):
            sf.Simulation(s, duration=0.6, newton_rtol=bad)
    assert newton_limits(1e-3, 5e-5) == pytest.approx((0.02, 20.0))   # 1e-6 of the run's
    assert newton_limits(1e-7, 5e-9) == pytest.approx((0.2, 20.0))    # a fifth of 5e-9
    assert newton_limits(1e-3, 1e-9)[1] == pytest.approx(1e6)        # a tighter Newton given


def test_newton_weighs_pressures_by_their_gauge_magnitude_in_adaptive_runs():
    """The tolerance of the pressures: rtol / 20 of the largest gauge pressure
    (|p - 1 atm|), on the small path and the general one alike."""
    sim = _scene(sf.air, step=None)
    res = sim.run()
    from softflow.solve.linalg import make_linear_solver
    from softflow.solve.newton import Stats
    asm = sim.asm
    x = res.X[-1]
    p = np.array([q == "pressure" for q in asm.x_quantity])
    gauge = np.abs(x[p] - P0).max()
    for small in (True, False):
        nt = newton_module.Newton(asm, make_linear_solver(asm, "dense"), Stats(), rtol=5e-5,
                                  atol=sim._atol_vector(asm.x_quantity, 1e-3))
        nt._small = small and nt._small
        nt.set_gauge(P0)
        nt._set_scale(x)
        tol = nt.tol[p]
        np.testing.assert_allclose(tol, sim._atol_vector(asm.x_quantity, 1e-3)[p]
                                   + 5e-5 * gauge, rtol=1e-12)
        assert tol.max() < 0.2 * 5e-5 * x[p].max()    # of the absolute pressure: 5x looser


class _Matrix:
    """What DenseLU reads of an Assembly: a dense Jacobian, and the scale
    diagnosis (None: no component of extreme scale)."""

    def __init__(self, J, diagnosis=None):
        self.n, self._J, self._diagnosis = J.shape[0], J, diagnosis

    def dense_jacobian(self):
        return self._J.copy()

    def diagnose_scale(self):
        return self._diagnosis, None


@pytest.mark.parametrize("n", [12, 90])          # the inverse's path, and getrs'
def test_dense_lu_equilibrates_a_jacobian_singular_only_in_its_units(n):
    """Rows 1e-8 and columns 1e-8 apart (the units: a gas volume's rho V = m at
    18 MPa against a tube's pressure drop): the unscaled pivots span more than
    1e14, R J C is well conditioned, and the solves are J's, one vector or
    several, also where the scale diagnosis names a component (kept as a
    note); a singular R J C stays singular."""
    from softflow.solve.linalg import SingularJacobian
    rng = np.random.default_rng(5)
    A = rng.standard_normal((n, n)) + n * np.eye(n)
    rows = np.where(np.arange(n) % 2, 1e-8, 1.0)
    cols = np.where(np.arange(n) % 3, 1.0, 1e-8)
    J = rows[:, None] * A * cols
    d = np.abs(np.diag(lu_factor(J)[0]))
    assert d.min() < 1e-14 * d.max()               # the plain test calls it singular
    lin = DenseLU(_Matrix(J))
    lin.factor()
    b = rng.standard_normal(n) * rows
    np.testing.assert_allclose(J @ lin.solve(b), b, rtol=0, atol=1e-12 * np.abs(b).max())
    B = rng.standard_normal((n, 3)) * rows[:, None]
    np.testing.assert_allclose(J @ lin.solve(B), B, rtol=0, atol=1e-12 * np.abs(B).max())
    # a component the scale diagnosis names is no veto: the factors are R J C's,
    # and the diagnosis is kept for a failure's message
    named = DenseLU(_Matrix(J, diagnosis="the scale of X is extreme"))
    named.note_scale = True          # as for the consistent start's solver
    named.factor()
    np.testing.assert_allclose(J @ named.solve(b), b, rtol=0, atol=1e-12 * np.abs(b).max())
    assert named.scale_note == "the scale of X is extreme" and lin.scale_note is None
    with pytest.raises(SingularJacobian, match="singular"):
        DenseLU(_Matrix(np.zeros((n, n)) + np.eye(n) * (np.arange(n) > 0))).factor()
    # a well-scaled matrix afterwards is solved on its own factors again
    lin2 = DenseLU(_Matrix(A))
    lin2.factor()
    lin2.asm._J = J
    lin2.factor()
    lin2.asm._J = A
    lin2.factor()
    c = rng.standard_normal(n)
    np.testing.assert_allclose(A @ lin2.solve(c), c, rtol=0, atol=1e-10)


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_small_networks_find_their_subnetworks_as_the_sparse_graph_does(monkeypatch, thermal):
    """Assembly.subnetworks by union-find (up to SMALL_BLOCKS_MAX unknowns)
    numbers the blocks of every unknown and state as scipy's connected
    components do: four variants of the two-tank scene in one System (each a
    block, labelled in the order of their lowest unknown), and one scene."""
    from softflow.solve import assembly
    from softflow.solve.batched import build_batch
    scene = _scene(sf.air, thermal).system
    batch = build_batch(scene, [{}] * 4, {c.label for c in scene.components})
    for system in (batch, scene):
        asm = sf.Simulation(system, duration=0.1, thermal=thermal).asm
        assert asm.n <= assembly.SMALL_BLOCKS_MAX
        small = asm.subnetworks()
        monkeypatch.setattr(assembly, "SMALL_BLOCKS_MAX", -1)
        asm._subnetworks = None
        sparse = asm.subnetworks()
        monkeypatch.undo()
        assert small[2] == sparse[2] == (4 if system is batch else 1)
        np.testing.assert_array_equal(small[0], sparse[0])
        np.testing.assert_array_equal(small[1], sparse[1])


def test_small_blocks_number_random_graphs_as_scipy_does():
    """Assembly._small_blocks on random group layouts (groups of 0-4 columns,
    repeated entries, unknowns no group touches) against scipy's
    connected_components on the same edges: the same count and labels."""
    from types import SimpleNamespace
    from scipy.sparse import csc_matrix
    from scipy.sparse.csgraph import connected_components
    from softflow.solve.assembly import Assembly
    rng = np.random.default_rng(3)
    for _ in range(300):
        n = int(rng.integers(1, 40))
        groups = [SimpleNamespace(col=rng.integers(0, n, size=(int(rng.integers(1, 5)),
                                                               int(rng.integers(0, 5)))))
                  for _ in range(int(rng.integers(0, 6)))]
        fake = SimpleNamespace(n=n, groups=groups)
        count, labels = Assembly._small_blocks(fake)
        a = [g.col[:, :1].repeat(g.col.shape[1] - 1, axis=1).ravel() for g in groups
             if g.col.shape[1] > 1]
        b = [g.col[:, 1:].ravel() for g in groups if g.col.shape[1] > 1]
        a = np.concatenate(a) if a else np.zeros(0, dtype=int)
        b = np.concatenate(b) if b else np.zeros(0, dtype=int)
        expected = connected_components(csc_matrix((np.ones(a.size), (a, b)), shape=(n, n)),
                                        directed=False)
        assert count == expected[0]
        np.testing.assert_array_equal(labels, expected[1])
