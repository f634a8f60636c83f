"""softflow.fons's Simulation, result access and custom components as fonsim
0.6 has them (issue 39): its step range, run() returning None, sim.state,
sim.phi, argument_history, state_history, print_equations, get() by fonsim's
labels, array-form evaluate/update_state with set_arguments,
Terminal.variables_across/through and System.nodes. Where fonsim is cheap to
run, the same script runs under both."""
import contextlib
import io

import numpy as np
import pytest

import softflow as sf
import softflow.fons as fons

fonsim = pytest.importorskip("fonsim")
with contextlib.redirect_stdout(io.StringIO()):   # fonsim prints a notice on import
    import fonsim  # noqa: F811


def _quiet(fn, *args, **kw):
    with contextlib.redirect_stdout(io.StringIO()) as out:
        value = fn(*args, **kw)
    return value, out.getvalue()


def first_network(F, duration=0.05, **kw):
    """Tutorial 'A first network', shortened: source, tube, container."""
    s = F.System("net")
    s.add(F.PressureSource("src", pressure=2e5))
    s.add(F.CircularTube("tube", fluid=F.air))
    s.add(F.Container("tank", fluid=F.air, volume=20e-6))
    s.connect("src", "tube")
    s.connect("tube", "tank")
    sim = F.Simulation(s, duration=duration, **kw)
    return s, sim


# -- steps ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kw", [
    {}, dict(step=(None, 1e-3)), dict(step=(1e-6, None)), dict(step=(0.01, None)),
    dict(step=(None, 0.1)), dict(step=(1e-5, 1e-3), step_min=1e-6),
    dict(step=1e-3, step_max=1e-2), dict(step_max=1e-3),
])
def test_adaptive_step_range_is_fonsim_s(kw):
    with pytest.warns(FutureWarning) if ("step_min" in kw or "step_max" in kw) else \
            contextlib.nullcontext():
        _, ref = first_network(fonsim, duration=0.5, **kw)
    _, sim = first_network(fons, duration=0.5, **kw)
    assert sim.adaptive
    assert sim.step_min == pytest.approx(ref.solver.dt_min, rel=1e-12)
    assert sim.step_max == pytest.approx(min(ref.solver.dt_max, 0.5), rel=1e-12)


@pytest.mark.parametrize("step, dt", [(None, 0.5e-3), (2e-3, 2e-3)])
def test_fixed_steps_are_fonsim_s(step, dt):
    _, ref = first_network(fonsim, duration=0.5, step=step)
    _, sim = first_network(fons, duration=0.5, step=step)
    assert ref.solver.dt == pytest.approx(dt) and not sim.adaptive and sim.step == dt


def test_step_range_bad_input():
    with pytest.raises(ValueError, match="step must be a number .* or a pair"):
        first_network(fons, step=(1e-4, 1e-3, 1e-2))
    with pytest.raises(ValueError, match="relative_solving_tolerance must be a number > 0"):
        first_network(fons, relative_solving_tolerance=0)
    with pytest.raises(TypeError, match="give the step as fonsim does"):
        first_network(fons, adaptive=True)


def test_default_run_agrees_with_fonsim_s_default_run():
    s_ref, ref = first_network(fonsim, duration=0.2)
    _quiet(ref.run)
    s, sim = first_network(fons, duration=0.2)
    sim.run()
    p_ref = s_ref.get("tank").get("pressure")
    p = np.interp(ref.times, sim.times, s.get("tank").get("pressure"))
    assert np.max(np.abs(p - p_ref)) / np.ptp(p_ref) < 0.005
    # within fonsim's bounds: at most duration/100 apart
    assert np.diff(sim.result.times).max() <= 0.2e-2 * (1 + 1e-9)


# -- run, results --------------------------------------------------------------------------
def test_run_returns_none_and_state_phi_histories_are_fonsim_s():
    s_ref, ref = first_network(fonsim, step=1e-3)
    out, _ = _quiet(ref.run)
    assert out is None
    s, sim = first_network(fons, step=1e-3)
    assert sim.run() is None
    assert isinstance(sim.result, sf.Result)
    np.testing.assert_allclose(sim.times, ref.times, rtol=0, atol=1e-12)
    assert sim.phi.shape == ref.phi.shape and sim.state.shape == ref.state.shape
    # the same backward Euler at the same step: the same numbers, column by column
    scale = np.max(np.abs(ref.phi), axis=0)
    assert np.max(np.abs(sim.phi - ref.phi) / scale) < 2e-3
    np.testing.assert_allclose(sim.state, ref.state, rtol=2e-4)
    for label in ("src", "tube", "tank"):
        c_ref, c = s_ref.get(label), s.get(label)
        assert [(a.key, a.label) for a in c.arguments] == \
            [(a.key, a.label) for a in c_ref.arguments]
        assert c.argument_history.shape == c_ref.argument_history.shape
        assert c.state_history.shape == c_ref.state_history.shape
    np.testing.assert_allclose(s.get("tank").state_history[:, 0],
                               s.get("tank").get_state("mass"))
    np.testing.assert_array_equal(s.get("tube").argument_history[:, 3],
                                  s.get("tube").get("pressure", "b"))


def test_print_equations_counts_as_fonsim():
    _, ref = first_network(fonsim, step=1e-3)
    _, printed_ref = _quiet(ref.print_equations)
    _, sim = first_network(fons, step=1e-3)
    _, printed = _quiet(sim.print_equations)
    lines = printed.strip().splitlines()
    assert len(lines) == len(printed_ref.strip().splitlines()) == 8
    assert lines[0].startswith("eq 0: pressure[src.a] - pressure[tube.a] = 0")
    assert lines[-1] == "eq 7: tank equation 0 = 0"


def test_get_by_fonsim_labels():
    s_ref, ref = first_network(fonsim, step=1e-3)
    _quiet(ref.run)
    s, sim = first_network(fons, step=1e-3)
    sim.run()
    tube, tank = s.get("tube"), s.get("tank")
    np.testing.assert_array_equal(tube.get("p1"), tube.get("pressure", "b"))
    np.testing.assert_array_equal(tube.get("mf0"), tube.get("massflow", "a"))
    values, term = tube.get_all("p1")
    assert term.label == "b"
    np.testing.assert_array_equal(tank.get("p"), tank.get("pressure"))
    # fonsim labels the container's mass 'm'
    m_ref = s_ref.get("tank").get_state("mass")
    np.testing.assert_allclose(tank.get_state("m"), m_ref, rtol=2e-4)
    np.testing.assert_array_equal(tank.get_state("m"), tank.get_state("mass"))
    # fonsim's get() matches 'm' to 'massflow' by its first letter: an error here
    with pytest.raises(KeyError, match=r"'m' is fonsim's label of its state 'mass': use "
                                       r"get_state\('m'\)"):
        tank.get("m")


def test_free_actuator_terminals_a_and_b_are_fonsim_s():
    import fonsim_scripts as S

    def chain(F):
        curve = F.data.PVCurve(str(S.DATA), pressure_reference="relative")
        s = F.System()
        s += F.PressureSource("source", pressure=F.pressure_atmospheric + 0.35e5)
        s += F.CircularTube("tube_0", fluid=F.water, length=0.3, diameter=2e-3)
        s += F.FreeActuator("actu_0", fluid=F.water, curve=curve)
        s += F.CircularTube("tube_1", fluid=F.water, length=1.5, diameter=1e-3)
        s += F.FreeActuator("actu_1", fluid=F.water, curve=curve)
        s.connect("source", "tube_0", "actu_0")
        s.connect(("actu_0", "b"), "tube_1", "actu_1")
        sim = F.Simulation(s, duration=1.0, step=2e-3)
        _quiet(sim.run)
        return s, sim
    (s_ref, ref), (s, sim) = chain(fonsim), chain(fons)
    # the same backward Euler at the same step; the flows differ most (1.3 % of
    # their largest) where the actuator's volume crosses a sample of its curve
    for key, term, within in (("massflow", "a", 0.02), ("massflow", "b", 0.01),
                              ("pressure", "b", 0.002)):
        r = s_ref.get("actu_0").get(key, term)
        g = s.get("actu_0").get(key, term)
        assert np.max(np.abs(g - r)) / np.max(np.abs(r)) < within, (key, term)
    actu = s.get("actu_0")
    np.testing.assert_allclose(actu.get("mf1"), -s.get("tube_1").get("massflow", "a"))
    np.testing.assert_allclose(actu.get("massflow", "a") + actu.get("massflow", "b"),
                               sf.Component.get(actu, "massflow"))
    assert actu.get_all("mf1")[1].label == "a"     # fonsim's b is softflow's a
    assert ref.phi.shape == sim.phi.shape
    # fonsim's nodes: actu_0's b apart from its a, actu_1's b alone
    assert s.fonsim_node_count() == len(s_ref.nodes) == 5 and len(s.nodes) == 3


# -- custom components ---------------------------------------------------------------------
V_TANK = 20e-6


def array_form_tank(F, order):
    """A container written in fonsim's array form (evaluate / update_state
    filling arrays, nb_equations, optionally set_arguments)."""
    rho = F.air.rho_stp if hasattr(F.air, "rho_stp") else F.air.rho

    class Tank(F.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(F.Terminal("a", F.terminal_fluidic,
                                          {"pressure": "p", "massflow": "mf"}))
            self.set_states(F.Variable("mass", "local", label="m", initial_value=V_TANK * rho))
            if order:
                self.set_arguments(self.terminals[0]("pressure"),
                                   self.terminals[0]("massflow"))
            self.nb_equations = 1

        def evaluate(self, values, jacobian_state, jacobian_arguments, state, arguments,
                     elapsed_time):
            p = arguments[0] if order else arguments[1]
            values[0] = state[0] * F.pressure_atmospheric - p * V_TANK * rho
            jacobian_state[0, 0] = F.pressure_atmospheric
            jacobian_arguments[0, 0 if order else 1] = -V_TANK * rho

        def update_state(self, state_new, jacobian, state, arguments, dt):
            mf = arguments[1] if order else arguments[0]
            state_new[0] = state[0] + dt * mf
            jacobian[0, 1 if order else 0] = dt
    return Tank


@pytest.mark.parametrize("order", [False, True])
def test_array_form_component_runs_as_in_fonsim(order):
    def run(F, make_tank):
        s = F.System()
        s.add(F.PressureSource("src", pressure=2e5))
        s.add(F.CircularTube("tube", fluid=F.air))
        s.add(make_tank("tank"))
        s.connect("src", "tube")
        s.connect("tube", "tank")
        sim = F.Simulation(s, duration=0.1, step=1e-3)
        _quiet(sim.run)
        return s
    ref = run(fonsim, array_form_tank(fonsim, order))
    got = run(fons, array_form_tank(fons, order))
    lib = run(fons, lambda label: fons.Container(label, fluid=fons.air, volume=V_TANK))
    p_ref, p = ref.get("tank").get("pressure"), got.get("tank").get("pressure")
    assert np.max(np.abs(p - p_ref)) / np.ptp(p_ref) < 2e-3
    np.testing.assert_allclose(p, lib.get("tank").get("pressure"), rtol=1e-6)
    tank = got.get("tank")
    expected = [("pressure", "p"), ("massflow", "mf")] if order else \
        [("massflow", "mf"), ("pressure", "p")]
    assert [(a.key, a.label) for a in tank.arguments] == expected
    assert [(a.key, a.label) for a in ref.get("tank").arguments] == expected
    np.testing.assert_array_equal(tank.argument_history[:, 0 if order else 1],
                                  tank.get("pressure"))


def test_set_arguments_bad_input_names_the_component():
    class C(fons.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(fons.Terminal("a", fons.terminal_fluidic))
            self.set_arguments("nonsense")
    with pytest.raises(ValueError, match="C 'c': set_arguments got 'nonsense', which is none "
                                         "of its terminals' variables"):
        C("c")


def test_terminal_variable_dicts_and_system_nodes_are_fonsim_s():
    s_ref, _ = first_network(fonsim)
    s, _ = first_network(fons)
    for label in ("src", "tube", "tank"):
        for t_ref, t in zip(s_ref.get(label).terminals, s.get(label).terminals):
            assert set(t.variables_across) == set(t_ref.variables_across) == {"pressure"}
            assert set(t.variables_through) == set(t_ref.variables_through) == {"massflow"}
            assert t.variables_across["pressure"].key == "pressure"
            assert t.isconnected == t_ref.isconnected
    assert len(s.nodes) == len(s_ref.nodes) == 2      # an attribute, as in fonsim
    assert [len(n.terminals) for n in s.nodes] == [len(n.terminals) for n in s_ref.nodes]
    assert len(s.nodes()) == 2                        # and softflow's method
    custom = fons.Terminal("x", fons.terminal_fluidic, {"pressure": "px"})
    assert custom.variables_across["pressure"].label == "px"


def test_relative_solving_tolerance_sets_the_adaptive_error_test():
    _, sim = first_network(fons)
    assert sim.rtol == pytest.approx(1e-3)          # fonsim's 0.01: softflow's default
    _, sim = first_network(fons, relative_solving_tolerance=1e-4)
    assert sim.rtol == pytest.approx(1e-5)
    _, sim = first_network(fons, relative_solving_tolerance=1e-4, rtol=1e-6)
    assert sim.rtol == pytest.approx(1e-6)          # softflow's own option wins


# -- waves ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["previous", "zero", "next", "nearest", "linear", "slinear",
                                  "quadratic", "cubic"])
def test_wave_custom_kinds_give_fonsim_s_values(kind):
    pts = [(0, 1.0), (0.5, 3.0), (1.0, 2.0), (1.5, 5.0), (2.0, 4.0)]
    t = np.concatenate([[0.25, 0.5, 0.75, 1.25], np.linspace(-1, 3, 161)])
    ref = np.asarray(fonsim.wave.Custom(pts, kind=kind)(t), dtype=float)
    w = fons.wave.Custom(pts, kind=kind)
    np.testing.assert_allclose(w(t), ref, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose([w(float(x)) for x in t], ref, rtol=1e-14, atol=1e-14)


def test_wave_custom_arithmetic_in_place_as_fonsim():
    pts = [(0, 1.0), (0.5, 3.0), (1.0, 2.0)]
    for F in (fonsim, fons):
        w = F.wave.Custom(pts)
        assert (w * 1e5 + 101300.0) is w
        w * 2
        w + np.array([1.0, 2.0, 3.0])
        assert float(w(0.5)) == 2 * (3e5 + 101300.0) + 2.0
