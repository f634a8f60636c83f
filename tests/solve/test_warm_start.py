"""A run starts from the last run's consistent point at t = 0 where nothing it
was solved for changed and Newton confirms it (Integrator.initial,
Newton.confirms): the same answer as a cold start, bitwise, at the cost of one
Jacobian; anything changed gives a cold start's answer."""
import numpy as np
import pytest

import softflow as sf
from softflow.solve.linalg import make_linear_solver
from softflow.solve.newton import Newton, Stats

P0 = sf.pressure_atmospheric


def scene(pressure=1.2e5, diameter=1e-3, **tube):
    s = sf.System()
    s += sf.PressureSource("src", pressure=pressure)
    s += sf.CircularTube("t", sf.air, 0.1, diameter, **tube)
    s += sf.Container("c", sf.air, 1e-6)
    s.connect("src", "t")
    s.connect("t", "c")
    return s


def _same(a, b):
    np.testing.assert_array_equal(a.times, b.times)
    np.testing.assert_array_equal(a.X, b.X)
    np.testing.assert_array_equal(a.S, b.S)


STEPPING = [{"duration": 1e-3, "step": 1e-3}, {"duration": 0.02, "step": 1e-3},
            {"duration": 0.02}]


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
@pytest.mark.parametrize("stepping", STEPPING, ids=["one-step", "fixed", "bdf"])
def test_a_warm_run_is_the_cold_run_with_less_work(stepping):
    cold = sf.Simulation(scene(), **stepping).run()
    sim = sf.Simulation(scene(), **stepping)
    first, second, third = sim.run(), sim.run(), sim.run()
    _same(first, cold)
    _same(second, cold)
    _same(third, cold)
    assert first.stats == cold.stats
    # the t = 0 solve from zero flow takes ~14 evaluations; a confirmed start one
    saved = first.stats["residual_evaluations"] - second.stats["residual_evaluations"]
    assert saved >= 5
    assert second.stats["jacobian_evaluations"] < first.stats["jacobian_evaluations"]
    assert third.stats == second.stats
    assert [str(w) for w in second.warnings] == [str(w) for w in cold.warnings]


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_a_changed_parameter_starts_cold_and_the_next_plain_run_is_back():
    sim = sf.Simulation(scene(), duration=0.01, step=1e-3)
    base = sim.run()
    changed = sim.run(params={"t.diameter": 1.5e-3})
    _same(changed, sf.Simulation(scene(diameter=1.5e-3), duration=0.01, step=1e-3).run())
    assert changed.stats == sf.Simulation(scene(diameter=1.5e-3), duration=0.01,
                                          step=1e-3).run().stats     # a cold start
    again = sim.run(params={"t.diameter": 1.5e-3})
    _same(again, changed)
    back = sim.run()
    _same(back, base)
    p0 = sim.run(params={"c.initial_pressure": 1.1e5})       # x0 and S0 change
    _same(p0, sf.Simulation(_with_tank_pressure(1.1e5), duration=0.01, step=1e-3).run())


def _with_tank_pressure(p):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    s += sf.CircularTube("t", sf.air, 0.1, 1e-3)
    s += sf.Container("c", sf.air, 1e-6, initial_pressure=p)
    s.connect("src", "t")
    s.connect("t", "c")
    return s


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_what_no_key_sees_is_caught_by_the_confirmation():
    """A source pressure read from user state at run time: the remembered
    point is refused by Newton and the run solves from the initial values, as
    a fresh Simulation does."""
    box = [1.2e5]
    sim = sf.Simulation(scene(pressure=lambda t: box[0]), duration=0.01, step=1e-3)
    base = sim.run()
    box[0] = 1.3e5
    moved = sim.run()
    # (a fresh Simulation of the same kind of source: a Python function of
    # time, which the compiled step loop does not take)
    _same(moved, sf.Simulation(scene(pressure=lambda t: 1.3e5), duration=0.01,
                               step=1e-3).run())
    assert moved.get("src", "pressure")[0] == 1.3e5
    assert not np.array_equal(moved.X[0], base.X[0])
    box[0] = 1.2e5
    _same(sim.run(), base)


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_newton_confirms_a_solution_and_refuses_a_start_point():
    sim = sf.Simulation(scene(), duration=1e-3, step=1e-3)
    x = sim.run().X[0]
    asm = sim.asm
    stats = Stats()
    newton = Newton(asm, make_linear_solver(asm, "dense"), stats,
                    atol=sim._atol_vector(asm.x_quantity, 1e-3))
    kept = x.copy()
    assert newton.confirms(x, asm.S0, 0.0, 0.0)
    np.testing.assert_array_equal(x, kept)
    assert (stats.residual_evaluations, stats.jacobian_evaluations,
            stats.factorizations, stats.newton_iterations) == (1, 1, 1, 1)
    assert not newton.stale
    assert not newton.confirms(asm.x0, asm.S0, 0.0, 0.0)
    assert newton.stale
    off = x.copy()
    off[2:] *= 1.01           # 1 % off in every flow: far past the tolerance
    assert not newton.confirms(off, asm.S0, 0.0, 0.0)
    bad = x.copy()
    bad[1] = -1.0             # a negative absolute pressure is no solution
    assert not newton.confirms(bad, asm.S0, 0.0, 0.0)


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_a_run_refused_at_start_is_refused_again():
    """A (mean-density) tube choked at t = 0 stops the run there; the rerun,
    from the remembered point, stops the same way."""
    sim = sf.Simulation(scene(pressure=4e5, compressible="mean_density"), duration=0.01,
                        step=1e-3)
    with pytest.raises(sf.SimulationError) as one:
        sim.run()
    with pytest.raises(sf.SimulationError) as two:
        sim.run()
    assert str(one.value) == str(two.value)
    _same(one.value.result, two.value.result)


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_a_check_registered_between_runs_is_asked_at_the_start():
    """The start's check is remembered with the point it passed; a check
    registered after that run is asked at the next start, which it refuses."""
    from softflow.solve import validity

    sim = sf.Simulation(scene(), duration=0.01, step=1e-3)
    assert len(sim.run().times) == 11
    asked = []

    def refuse(g, result):
        asked.append(len(result.times))
        c = g.comps[0]
        return [validity.ValidityRecord(
            component=c.label, check="refuse", measured=1.0, limit=0.0, unit="",
            suggestion="none", message=f"{c.label} refused", status="beyond",
            details={"fatal": True, "first_time": float(result.times[0])})]
    refuse.can_refuse = True
    validity.register(sf.CircularTube, refuse)
    try:
        with pytest.raises(sf.SimulationError, match="t refused") as err:
            sim.run()
        assert asked[0] == 1             # asked at the start, on the point at t = 0
        assert len(err.value.result.times) == 1
    finally:
        validity._CHECKS[sf.CircularTube].remove(refuse)
        validity._VERSION += 1
    assert len(sim.run().times) == 11


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_the_start_check_is_asked_once_per_remembered_point(monkeypatch):
    calls = []
    ask = sf.Simulation._fatal_at_start

    def counted(self, rec):
        calls.append(len(rec.t))
        return ask(self, rec)
    monkeypatch.setattr(sf.Simulation, "_fatal_at_start", counted)
    sim = sf.Simulation(scene(), duration=0.01, step=1e-3)
    first, second = sim.run(), sim.run()
    assert calls == [1]
    _same(first, second)
    sim.run(params={"t.diameter": 1.2e-3})       # another point: asked
    assert calls == [1, 1]
    sim.beyond_limits = "warn"                   # not asked; and not remembered as passed
    sim.run()
    sim.beyond_limits = "error"
    sim.run()
    sim.run()
    assert calls == [1, 1, 1]


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_a_dense_start_is_confirmed_on_the_factors_of_its_own_solve():
    sim = sf.Simulation(scene(), duration=1e-3, step=1e-3)
    cold = sim.run()
    x, _, _, lin0 = sim._start[1]
    assert lin0 is not None and lin0.kind == "dense"
    asm = sim.asm
    stats = Stats()
    newton = Newton(asm, make_linear_solver(asm, "dense"), stats,
                    atol=sim._atol_vector(asm.x_quantity, 1e-3))
    assert newton.confirms(x, asm.S0, 0.0, 0.0, lin=lin0)
    assert (stats.residual_evaluations, stats.jacobian_evaluations,
            stats.factorizations) == (1, 0, 0)
    off = x.copy()
    off[2:] *= 1.01
    assert not newton.confirms(off, asm.S0, 0.0, 0.0, lin=lin0)
    warm = sim.run()
    _same(warm, cold)
    # warm, the step's Jacobian is the run's only one
    assert warm.stats["jacobian_evaluations"] == 1
    assert sim._start[1][3] is lin0          # kept as the cold solve left it


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
@pytest.mark.parametrize("kind", ["sparse", "condensed"])
def test_other_linear_solvers_confirm_on_a_jacobian_of_their_own(kind):
    cold = sf.Simulation(scene(), duration=0.01, step=1e-3, linear_solver=kind).run()
    sim = sf.Simulation(scene(), duration=0.01, step=1e-3, linear_solver=kind)
    first, second = sim.run(), sim.run()
    assert sim._start[1][3] is None
    _same(first, cold)
    _same(second, cold)
    assert second.stats["residual_evaluations"] < first.stats["residual_evaluations"]
