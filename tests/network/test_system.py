"""System, connect, Component and Simulation behaviour, and their errors on bad input."""
import math
import re

import numpy as np
import pytest

import softflow as sf

P0 = sf.pressure_atmospheric


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------
class Balloon(sf.Component):
    """The paper's user-written actuator, with a linear PV law (compliance C) so that
    the tests need no data file.

    ``n_residuals`` and ``nan_after`` make it misbehave on purpose.
    """

    C = 5e-12         # m^3/Pa (tau = R C ~ 0.12 s with the tube)
    V0 = 1e-6         # m^3 at 1 atm

    def __init__(self, label, *, n_residuals=1, nan_after=None):
        super().__init__(label)
        p_ = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf_ = sf.Variable("massflow", "through", label="mf")
        m_ = sf.Variable("mass", "local", label="mass", initial_value=self.V0 * sf.water.rho)
        self.set_terminals(sf.Terminal("a", [p_, mf_]))
        self.set_states(m_)
        rho, C, V0 = sf.water.rho, self.C, self.V0

        def evaluate(t, p, mass):
            r = p - (P0 + (mass / rho - V0) / C)
            if nan_after is not None and t > nan_after:
                r = float("nan")
            return [r] * n_residuals

        self.evaluate = self.auto(evaluate)

        def update_state(dt, mass, mf):
            return {"mass": mass + mf * dt}

        self.update_state = self.auto_state(update_state)


def source_tube_actuator(actuator=None, pressure=None):
    """The paper's network: source -> tube -> actuator."""
    s = sf.System()
    s += sf.PressureSource("source",
                           pressure=pressure or (lambda t: P0 + (3e4 if t < 0.5 else 0.0)))
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += actuator if actuator is not None else Balloon("actu")
    s.connect("tube", "source")
    s.connect("tube", "actu")
    return s


def node_names(system):
    return sorted(sorted(t.name for t in nd.terminals) for nd in system.nodes())


def tube_source_acc():
    s = sf.System()
    s += sf.PressureSource("source", pressure=P0 + 1e4)
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-10)
    return s


# ---------------------------------------------------------------------------------------
# adding components
# ---------------------------------------------------------------------------------------
def test_add_and_lookup():
    s = tube_source_acc()
    assert len(s) == 3
    assert [c.label for c in s] == ["source", "tube", "acc"]
    assert "tube" in s and "tub" not in s
    assert s.get("tube").label == "tube"
    assert isinstance(s.get("acc"), sf.LinearAccumulator)


def test_add_returns_system_and_accepts_lists():
    s = sf.System()
    out = s.add([sf.PressureSource("a", pressure=P0), sf.PressureSource("b", pressure=P0)])
    assert out is s
    assert len(s) == 2


def test_duplicate_label_raises():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError, match="duplicate component label 'tube'"):
        s += sf.CircularTube("tube", sf.air, length=1.0, diameter=1e-3)
    assert len(s) == 3
    assert s.get("tube").fluid is sf.water


def test_add_non_component_raises():
    s = sf.System()
    with pytest.raises(sf.NetworkError, match="expects Component objects"):
        s.add("tube")


def test_component_without_terminals_raises():
    class Empty(sf.Component):
        pass

    with pytest.raises(sf.NetworkError, match="no terminals"):
        sf.System().add(Empty("e"))


def test_get_unknown_label_suggests_close_matches():
    s = tube_source_acc()
    with pytest.raises(KeyError, match=re.escape("did you mean ['tube']")):
        s.get("tueb")


def test_network_error_is_value_error():
    assert issubclass(sf.NetworkError, ValueError)


# ---------------------------------------------------------------------------------------
# connect
# ---------------------------------------------------------------------------------------
def test_paper_connect_rule_uses_first_unconnected_terminal():
    s = tube_source_acc()
    s.connect("tube", "source")
    s.connect("tube", "acc")
    assert node_names(s) == [["acc.a", "tube.b"], ["source.a", "tube.a"]]


def test_connect_with_explicit_terminals_components_and_terminal_objects():
    s = tube_source_acc()
    tube = s.get("tube")
    s.connect(("tube", "b"), s.get("source"))
    s.connect(tube.get_terminal("a"), "acc")
    assert node_names(s) == [["acc.a", "tube.a"], ["source.a", "tube.b"]]


def test_connect_merges_nodes_and_three_way_junction():
    s = sf.System()
    for k in range(3):
        s += sf.CircularTube(f"t{k}", sf.water, length=0.1, diameter=1e-3)
    s.connect(("t0", "b"), ("t1", "a"))
    s.connect(("t1", "a"), ("t2", "a"))           # joins the existing node
    assert ["t0.b", "t1.a", "t2.a"] in node_names(s)
    assert len(s.nodes()) == 4
    s.connect(("t0", "a"), ("t1", "b"), ("t2", "b"))
    assert len(s.nodes()) == 2


def test_connect_unknown_component_suggests_close_matches():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError) as info:
        s.connect("tubee", "source")
    msg = str(info.value)
    assert "'tubee'" in msg and "did you mean ['tube']" in msg
    with pytest.raises(sf.NetworkError, match="no component 'sauce'.*'source'"):
        s.connect(("sauce", "a"), "tube")


def test_connect_unknown_label_without_close_match_has_no_hint():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError) as info:
        s.connect("zzzzzz", "tube")
    assert "did you mean" not in str(info.value)


def test_connect_unknown_terminal():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError) as info:
        s.connect(("tube", "c"), "source")
    msg = str(info.value)
    assert "CircularTube 'tube' has no terminal 'c'" in msg
    assert "['a', 'b']" in msg


def test_connect_terminal_to_itself():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError, match=re.escape("terminal 'tube.a' is given twice")):
        s.connect(("tube", "a"), ("tube", "a"))


def test_failed_connect_leaves_system_unchanged():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError):
        s.connect(("tube", "a"), "source", ("tube", "a"))
    with pytest.raises(sf.NetworkError):
        s.connect("tube", "nosuch")
    assert len(s.unconnected_terminals()) == 4
    # the paper's rule still starts at tube.a
    s.connect("tube", "source")
    assert ["source.a", "tube.a"] in node_names(s)


def test_connect_needs_two_terminals():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError, match="at least two"):
        s.connect("tube")


def test_connect_bad_argument_type():
    s = tube_source_acc()
    with pytest.raises(sf.NetworkError, match="expected a component label"):
        s.connect("tube", 42)


def test_connect_foreign_terminal():
    s = tube_source_acc()
    other = sf.CircularTube("tube", sf.water, length=0.1, diameter=1e-3)
    with pytest.raises(sf.NetworkError, match="belongs to no component of this system"):
        s.connect(other.get_terminal("a"), "source")


def test_connect_component_with_no_unconnected_terminal_left():
    """A full multi-terminal component is refused, with the terminal naming to
    use; a one-terminal component's only terminal is reused (its node grows)."""
    s = tube_source_acc()
    s.connect("tube", "source")
    s.connect("tube", "acc")
    with pytest.raises(sf.NetworkError, match="'tube' has no unconnected terminal left") as info:
        s.connect("tube", "acc")
    assert "('tube', 'a')" in str(info.value)   # suggests naming the terminal


# ---------------------------------------------------------------------------------------
# Simulation creation: topology checks
# ---------------------------------------------------------------------------------------
def test_unconnected_terminals_raise_naming_them():
    s = tube_source_acc()
    s.connect("tube", "source")
    with pytest.raises(sf.NetworkError) as info:
        sf.Simulation(s)
    msg = str(info.value)
    assert "tube.b" in msg and "acc.a" in msg
    assert "source.a" not in msg and "tube.a" not in msg
    assert "allow_unconnected=True" in msg


def test_allow_unconnected_treats_them_as_closed_ends():
    s = tube_source_acc()
    s.connect("tube", "source")
    res = sf.Simulation(s, duration=0.05, allow_unconnected=True).run()
    assert res.status == "success"
    # closed end: no flow through the tube, the accumulator stays at its initial pressure
    np.testing.assert_allclose(s.get("tube").get("mf", "a"), 0.0, atol=1e-12)
    np.testing.assert_allclose(s.get("acc").get("pressure"), P0, rtol=1e-9)
    np.testing.assert_allclose(s.get("tube").get("pressure", "b"), P0 + 1e4, rtol=1e-9)


def test_empty_system_raises():
    with pytest.raises(sf.NetworkError, match="empty"):
        sf.Simulation(sf.System())


def test_floating_network_is_structurally_singular():
    """Two flow sources and a tube: no pressure reference anywhere."""
    s = sf.System()
    s += sf.MassFlowSource("in", massflow=1e-4)
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += sf.MassFlowSource("out", massflow=-1e-4)
    s.connect("tube", "in")
    s.connect("tube", "out")
    with pytest.raises(sf.NetworkError, match="structurally singular"):
        sf.Simulation(s)


def rc_plus_floating_loop():
    """A healthy RC circuit plus a separate loop of two water tubes: the loop's
    pressures enter its equations only as differences, so their level is free."""
    s = tube_source_acc()
    s.connect("tube", "source")
    s.connect("tube", "acc")
    s += sf.CircularTube("l1", sf.water, length=0.1, diameter=1e-3)
    s += sf.CircularTube("l2", sf.water, length=0.1, diameter=1e-3)
    s.connect(("l1", "a"), ("l2", "a"))
    s.connect(("l1", "b"), ("l2", "b"))
    return s


@pytest.mark.filterwarnings("ignore::scipy.linalg.LinAlgWarning")
def test_floating_subnetwork_fails_cleanly():
    """Whether it is caught at creation or at t = 0, the user gets a softflow error."""
    with pytest.raises((sf.NetworkError, sf.SimulationError)):
        sf.Simulation(rc_plus_floating_loop(), duration=0.1).run()


def test_floating_subnetwork_raises_network_error_at_creation():
    with pytest.raises(sf.NetworkError) as info:
        sf.Simulation(rc_plus_floating_loop())
    assert "l1" in str(info.value) or "l2" in str(info.value)


# ---------------------------------------------------------------------------------------
# user components
# ---------------------------------------------------------------------------------------
def test_paper_network_with_user_component_runs():
    s = source_tube_actuator()
    res = sf.Simulation(s, duration=1.0).run()
    assert res.status == "success"
    p = s.get("actu").get("pressure")
    t = res.times
    assert t[0] == 0.0 and t[-1] == pytest.approx(1.0)
    assert p.max() > P0 + 0.9 * 3e4            # inflates towards the source pressure
    assert p[-1] < P0 + 0.1 * 3e4              # and deflates after t = 0.5 s
    assert p.max() < P0 + 3e4 + 1.0


def test_user_component_matches_library_accumulator():
    """The paper-style user component with a linear PV law and LinearAccumulator
    are the same model; their responses must agree."""
    s1 = source_tube_actuator()
    s2 = source_tube_actuator(sf.LinearAccumulator("actu", sf.water, volume=Balloon.V0,
                                                   compliance=Balloon.C))
    r1 = sf.Simulation(s1, duration=0.4, step=1e-3).run()
    r2 = sf.Simulation(s2, duration=0.4, step=1e-3).run()
    np.testing.assert_allclose(r1.times, r2.times)
    np.testing.assert_allclose(s1.get("actu").get("pressure"),
                               s2.get("actu").get("pressure"), rtol=1e-6)


def test_evaluate_with_wrong_number_of_residuals():
    s = source_tube_actuator(Balloon("actu", n_residuals=2))
    with pytest.raises((sf.NetworkError, sf.SimulationError)) as info:
        sf.Simulation(s, duration=0.1).run()
    msg = str(info.value)
    assert "Balloon 'actu'" in msg
    assert "returned 2 residual(s)" in msg
    assert "has 1 unknown(s)" in msg


def test_evaluate_argument_matching_no_variable():
    class Bad(sf.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across", label="p"),
                                                 sf.Variable("massflow", "through",
                                                             label="mf")]))

            def evaluate(t, pressure):
                return [pressure - P0]

            self.evaluate = self.auto(evaluate)

    s = source_tube_actuator(Bad("actu"))
    with pytest.raises(sf.NetworkError) as info:
        sf.Simulation(s)
    msg = str(info.value)
    assert "Bad 'actu'" in msg
    assert "argument 'pressure' matches no variable" in msg
    assert "'p'" in msg and "'mf'" in msg      # lists the names that would match


def test_update_state_argument_matching_no_variable():
    class Bad(Balloon):
        def __init__(self, label):
            super().__init__(label)

            def update_state(dt, m, mf):
                return {"mass": m + mf * dt}

            self.update_state = self.auto_state(update_state)

    with pytest.raises(sf.NetworkError, match="update_state argument 'm' matches no variable"):
        sf.Simulation(source_tube_actuator(Bad("actu")))


def test_auto_rejects_varargs():
    comp = Balloon("b")
    with pytest.raises(TypeError, match=r"\*args"):
        comp.auto(lambda t, *args: [0.0])


def test_missing_evaluate_raises():
    class NoEval(sf.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across"),
                                                 sf.Variable("massflow", "through")]))

    with pytest.raises(sf.NetworkError, match="no evaluate function"):
        sf.Simulation(source_tube_actuator(NoEval("actu")))


def test_nan_in_user_component_raises_simulation_error_with_partial_result():
    s = source_tube_actuator(Balloon("actu", nan_after=0.3))
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(s, duration=1.0).run()
    err = info.value
    assert err.time == pytest.approx(0.3, abs=1e-6)
    assert f"t = {err.time:.6g} s" in str(err)
    assert err.component == "actu"
    res = err.result
    assert res is not None
    assert res.status == "failed"
    assert res.message == str(err)
    t = res.times
    assert t[0] == 0.0
    assert (np.diff(t) > 0).all()
    assert 0.29 < t[-1] <= 0.3
    p = res.get("actu", "pressure")
    assert p.shape == t.shape and np.isfinite(p).all()
    # the components see the partial result too
    np.testing.assert_array_equal(s.get("actu").get("pressure"), p)


def test_nan_with_fixed_step_reports_time():
    s = source_tube_actuator(Balloon("actu", nan_after=0.305))
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(s, duration=1.0, step=0.01).run()
    err = info.value
    assert err.time == pytest.approx(0.305, abs=1e-6)
    assert f"{err.time:.6g}" in str(err)
    assert err.result.times[-1] <= 0.305


def test_run_without_raising_returns_failed_result():
    s = source_tube_actuator(Balloon("actu", nan_after=0.3))
    sim = sf.Simulation(s, duration=1.0)
    res = sim.run(raise_on_failure=False)
    assert isinstance(res, sf.Result)
    assert res.status == "failed"
    assert not res.success
    assert "0.3" in res.message and "actu" in res.message
    assert 0.29 < res.times[-1] <= 0.3
    assert sim.result is res


def test_successful_run_has_success_status():
    res = sf.Simulation(source_tube_actuator(), duration=0.2).run(raise_on_failure=False)
    assert res.status == "success" and res.success and res.message == ""


# ---------------------------------------------------------------------------------------
# Simulation arguments
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("duration", [0.0, -1.0, sf.Q_(-5, "ms")])
def test_nonpositive_duration(duration):
    with pytest.raises(ValueError, match="duration must be > 0"):
        sf.Simulation(source_tube_actuator(), duration=duration)


@pytest.mark.parametrize("step", [0.0, -1e-3])
def test_nonpositive_step(step):
    with pytest.raises(ValueError, match="step must be > 0"):
        sf.Simulation(source_tube_actuator(), duration=1.0, step=step)


def test_nan_duration():
    with pytest.raises(ValueError, match="duration"):
        sf.Simulation(source_tube_actuator(), duration=float("nan"))


def test_bad_linear_solver_name():
    sim = sf.Simulation(source_tube_actuator(), duration=0.1, linear_solver="cholesky")
    with pytest.raises(ValueError, match="linear_solver"):
        sim.run()


def test_times_before_run():
    sim = sf.Simulation(source_tube_actuator(), duration=0.1)
    with pytest.raises(RuntimeError, match="run"):
        sim.times


# ---------------------------------------------------------------------------------------
# Variable, Terminal, Component
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("role", ["acros", "Across", "state", None, ""])
def test_variable_bad_role(role):
    with pytest.raises(ValueError, match="role must be one of"):
        sf.Variable("pressure", role)


def test_variable_defaults_and_copy():
    v = sf.Variable("pressure", "across")
    assert v.label == "pressure" and v.initial_value is None
    w = sf.Variable("mass", "local", label="m", initial_value=2)
    assert w.initial_value == 2.0 and isinstance(w.initial_value, float)
    c = w.copy()
    assert c is not w and (c.quantity, c.role, c.label, c.initial_value) == ("mass", "local",
                                                                             "m", 2.0)


def test_variable_bad_quantity():
    with pytest.raises(ValueError, match="quantity"):
        sf.Variable("", "across")


def test_terminal_rejects_local_variables_and_repeats():
    with pytest.raises(ValueError, match="role 'local'"):
        sf.Terminal("a", [sf.Variable("mass", "local")])
    with pytest.raises(ValueError, match="appears twice"):
        sf.Terminal("a", [sf.Variable("pressure", "across"), sf.Variable("pressure", "across")])
    with pytest.raises(TypeError):
        sf.Terminal("a", ["pressure"])


def test_terminal_copies_variables():
    p = sf.Variable("pressure", "across", label="p")
    t1 = sf.Terminal("a", [p])
    t2 = sf.Terminal("b", [p])
    assert t1.variables[0] is not p and t1.variables[0] is not t2.variables[0]


def test_component_bad_label():
    with pytest.raises(ValueError, match="label"):
        sf.Component("")
    with pytest.raises(ValueError, match="label"):
        sf.Component(3)


def test_component_duplicate_terminal_labels():
    c = sf.Component("c")
    with pytest.raises(ValueError, match="duplicate terminal labels"):
        c.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across")]),
                        sf.Terminal("a", [sf.Variable("pressure", "across")]))


def test_component_states_must_be_local():
    c = sf.Component("c")
    with pytest.raises(ValueError, match="must be 'local'"):
        c.set_states(sf.Variable("pressure", "across"))
    with pytest.raises(TypeError):
        c.set_locals("mass")


def test_component_variable_names_disambiguate_repeated_labels():
    t = sf.CircularTube("t", sf.water, length=0.1, diameter=1e-3)
    names, states = t.variable_names()
    assert names == ["p_a", "mf_a", "p_b", "mf_b"]
    assert states == []
    assert t.n_equations == 2
    b = Balloon("b")
    assert b.variable_names() == (["p", "mf"], ["mass"])
    assert b.n_equations == 1


def test_component_get_before_run():
    with pytest.raises(RuntimeError, match="no results yet"):
        Balloon("b").get("pressure")


def test_user_exception_mid_run_keeps_partial_results():
    class Bomb(sf.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across", label="p"),
                                                 sf.Variable("massflow", "through", label="mf")]))

            def evaluate(t, mf):
                if t > 0.0045:
                    raise ZeroDivisionError("boom")
                return [mf]
            self.evaluate = self.auto(evaluate)
    s = sf.System()
    s += sf.PressureSource("src", pressure=2e5)
    s += sf.CircularTube("tube", sf.water, length=0.1, diameter=1e-3)
    s += Bomb("bomb")
    s.connect("tube", "src")
    s.connect("tube", "bomb")
    sim = sf.Simulation(s, duration=0.01, step=1e-3)
    with pytest.raises(sf.SimulationError, match="ZeroDivisionError: boom") as info:
        sim.run()
    assert info.value.result is sim.result
    assert sim.result.status == "failed"
    assert sim.result.times[-1] == pytest.approx(0.004)


def test_volume_joined_directly_to_a_pressure_source_is_reported_at_creation():
    s = sf.System()
    s += sf.PressureSource("src", pressure=2e5)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect("src", "tank")
    with pytest.raises(sf.NetworkError, match="initial values at t = 0.*tank"):
        sf.Simulation(s, duration=0.1)


def test_fixed_stepping_without_a_step_is_refused():
    s = sf.System()
    s += sf.PressureSource("src", pressure=2e5)
    s += sf.CircularTube("tube", sf.water, length=0.1, diameter=1e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-12)
    s.connect("tube", "src")
    s.connect("tube", "acc")
    with pytest.raises(ValueError, match="adaptive=False needs a step"):
        sf.Simulation(s, duration=0.1, adaptive=False)


def _small_tank_scene():
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    s += sf.CircularTube("tube", sf.water, length=0.1, diameter=1e-3)
    s += sf.Container("tank", sf.water, volume=1e-6)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    return s


def test_a_dropped_scene_is_freed_after_its_run():
    """The link Component.get reads does not keep a scene alive: once the
    System, its Simulation and the Result are dropped (and RECENT_RESULTS
    runs came after), they are freed."""
    import gc
    import weakref

    from softflow.network import component
    s = _small_tank_scene()
    sim = sf.Simulation(s, duration=0.01, step=1e-3)
    sim.run()
    gone = [weakref.ref(s.get("tank")), weakref.ref(sim)]
    del s, sim
    other = sf.Simulation(_small_tank_scene(), duration=0.01, step=1e-3)
    for _ in range(component.RECENT_RESULTS):
        other.run()
    gc.collect()
    assert all(r() is None for r in gone)


def test_a_one_line_run_leaves_its_result_readable_until_it_is_dropped():
    from softflow.network import component
    s = _small_tank_scene()
    sf.Simulation(s, duration=0.01, step=1e-3).run()     # neither kept
    assert s.get("tank").get("pressure")[-1] > 1.0e5
    other = sf.Simulation(_small_tank_scene(), duration=0.01, step=1e-3)
    for _ in range(component.RECENT_RESULTS):
        other.run()
    with pytest.raises(RuntimeError, match="no longer held.*keep the Simulation"):
        s.get("tank").get("pressure")
    kept = sf.Simulation(s, duration=0.01, step=1e-3)
    kept.run()
    for _ in range(component.RECENT_RESULTS):
        other.run()
    assert s.get("tank").get("pressure")[-1] > 1.0e5       # kept through kept.result
