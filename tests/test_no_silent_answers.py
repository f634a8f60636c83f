"""No silent wrong answers (issue 17): PV curves beyond their data (policy and
ModelWarning / result.warnings), fluids that differ at a node, failures in user
code and at extreme scales that name their component, bounded step counts."""
import warnings

import numpy as np
import pytest

import softflow as sf
from helpers import source_tube_tank
from softflow.curves.pvcurve import CurveRangeError
from softflow.solve.validity import PV_CURVE_SLACK, ValidityRecord

V_DATA = sf.Q_([1, 2, 4, 6], "mL")
P_DATA = sf.Q_([0, 100, 200, 400], "mbar")


def _curve(policy=None):
    kw = {} if policy is None else {"extrapolate": policy}
    return sf.PVCurve(volume=V_DATA, pressure=P_DATA, gauge=True, **kw)


def _pushed(policy=None, source=sf.Q_(2, "bar"), fluid=sf.air):
    """A 1-6 mL actuator pushed by a source far above its curve's last pressure."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=source)
    s += sf.CircularTube("tube", fluid, length=0.3, diameter=1e-3)
    s += sf.Actuator("act", fluid, _curve(policy))
    s.connect("tube", "src")
    s.connect("tube", "act")
    return s


def _run(system, **kw):
    """The result with only its PV-curve records, and the ModelWarnings of those
    (other validity checks may have their say about the same scene)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sf.Simulation(system, **kw).run(raise_on_failure=False)
    res.warnings = [r for r in res.warnings if r.check == "pv_curve_range"]
    mine = {r.message for r in res.warnings}
    return res, [w for w in caught
                 if issubclass(w.category, sf.ModelWarning) and str(w.message) in mine]


# -- the policy on the curve itself -----------------------------------------------------
def test_default_policy_is_linear_and_documented():
    c = _curve()
    assert c.extrapolate == "linear"
    assert "extrapolate : {'linear', 'clamp', 'error'}, default 'linear'" in sf.PVCurve.__doc__
    v, p, s = c.volume, c.pressure, c.slope
    val, dval = c.fdf_volume(np.array([v[-1] + 1e-6]))
    assert val[0] == pytest.approx(p[-1] + s[-1] * 1e-6, rel=1e-13) and dval[0] == s[-1]


def test_clamp_holds_the_end_pressures_with_zero_slope():
    c = _curve("clamp")
    v, p = c.volume, c.pressure
    for x, end in ((v[0] - 5e-7, p[0]), (v[-1] + 3e-6, p[-1])):
        val, dval = c.fdf_volume(np.array([x]))
        assert val[0] == pytest.approx(end, rel=1e-15) and dval[0] == 0.0
        assert c(float(x)) == pytest.approx(end, rel=1e-15)       # the scalar path too
    # inside the data nothing changes
    inside = np.linspace(v[0], v[-1], 17)
    np.testing.assert_array_equal(c(inside), _curve()(inside))


@pytest.mark.parametrize("x", [0.999e-6, 6.001e-6])
def test_error_refuses_volumes_beyond_the_data(x):
    c = _curve("error")
    with pytest.raises(CurveRangeError, match=r"beyond its data 1e-06 \.\.\. 6e-06 m\^3"):
        c(np.array([2e-6, x]))
    with pytest.raises(CurveRangeError, match="extrapolate='error'"):
        c(float(x))
    assert c(6e-6) == pytest.approx(_curve()(6e-6))   # the ends themselves are data


def test_unknown_policy_names_the_choices():
    with pytest.raises(ValueError, match="extrapolate must be one of 'linear', 'clamp', "
                                         "'error', got 'extend'"):
        _curve("extend")


def test_synthetic_curves_take_the_policy():
    c = sf.PVCurve.monotonic((1e-6, 1.0e5), (2e-6, 1.2e5), (5e-6, 1.3e5), extrapolate="clamp")
    assert c.extrapolate == "clamp" and c(1e-5) == pytest.approx(c.pressure[-1])
    assert "extrapolate='clamp'" in repr(c)


# -- warnings after a run -----------------------------------------------------------------
def test_actuator_beyond_its_data_warns_once_naming_it_and_how_far():
    res, caught = _run(_pushed(), duration=1.0)
    assert res.status == "success"
    assert len(res.warnings) == 1 and len(caught) == 1
    rec = res.warnings[0]
    assert isinstance(rec, ValidityRecord)
    assert rec.component == "act" and rec.check == "pv_curve_range" and rec.unit == "m^3"
    vol = res.get("act", "volume")
    assert rec.measured == vol.max() and rec.limit == pytest.approx(6e-6)
    assert rec.details["beyond"] == pytest.approx(vol.max() - 6e-6)
    first = res.times[np.argmax(vol > 6e-6 + PV_CURVE_SLACK * 5e-6)]
    assert rec.details["first_time"] == first
    assert str(caught[0].message) == rec.message == str(rec)
    assert "Actuator 'act'" in rec.message and "beyond the last sample" in rec.message
    assert f"{(vol.max() - 6e-6) * 1e6:.3g} mL" in rec.message
    assert "extrapolate=" in rec.suggestion


def test_clamp_warns_too_and_says_the_pressure_was_held():
    res, caught = _run(_pushed("clamp"), duration=0.2)
    assert res.status == "success" and len(caught) == 1
    assert "held at its end pressure" in res.warnings[0].message
    p_end = _curve().pressure[-1]
    beyond = res.get("act", "volume") > 6e-6
    np.testing.assert_allclose(res.get("act", "pressure")[beyond], p_end, rtol=1e-9)


def test_error_policy_fails_the_run_naming_the_actuator_and_time():
    res, caught = _run(_pushed("error"), duration=1.0)
    assert res.status == "failed" and not caught
    assert "Actuator 'act'" in res.message and "beyond its data" in res.message
    assert res.get("act", "volume").max() <= 6e-6 * (1 + 1e-9)
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(_pushed("error"), duration=1.0).run()
    assert info.value.time == pytest.approx(res.times[-1], rel=0.05)


def test_a_run_within_the_data_has_no_warning():
    res, caught = _run(_pushed(source=sf.pressure_atmospheric + 2e4), duration=1.0)
    assert res.status == "success" and res.warnings == [] and not caught
    assert res.get("act", "volume").max() < 6e-6


def test_below_the_first_sample_warns_with_the_first_sample():
    # -5 kPa: the curve's straight continuation below 1 mL settles at 0.5 mL (at
    # -30 kPa, as this test had it, at -2 mL: the actuator empties at 0.025 s, an
    # error since issue 41, tests/test_issue41_states.py)
    res, caught = _run(_pushed(source=sf.pressure_atmospheric - 5e3), duration=1.0)
    assert res.status == "success" and len(caught) == 1
    rec = res.warnings[0]
    assert rec.limit == pytest.approx(1e-6) and 0 < rec.measured < 0.6e-6
    assert "beyond the first sample" in rec.message


def test_warnings_follow_record_and_liquids():
    res, _ = _run(_pushed(), duration=0.5, record=["tube"])
    assert res.warnings == []                 # the actuator was not recorded: nothing to read
    res, caught = _run(_pushed(fluid=sf.water, source=3e5), duration=5.0)
    assert [r.component for r in res.warnings] == ["act"] and len(caught) == 1


def test_hysteretic_actuator_warns_beyond_both_branches_and_refuses_error_policy():
    loop = sf.HysteresisLoop.snapping((1e-6, 1.0e5), (3e-6, 1.3e5), (5e-6, 1.1e5),
                                      (7e-6, 1.4e5), snap_volume=2.5e-6)
    s = sf.System()
    s += sf.PressureSource("src", pressure=5e5)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    s += sf.HystereticActuator("hyst", sf.air, *loop)
    s.connect("tube", "src")
    s.connect("tube", "hyst")
    # the 5 bar step chokes the tube at t = 0, which stops the run there by
    # default (before the volume leaves the data): go on with the warning
    res, caught = _run(s, duration=0.5, beyond_limits="warn")
    assert [r.component for r in res.warnings] == ["hyst"] and len(caught) == 1
    strict = sf.PVCurve(volume=loop.inflation.volume, pressure=loop.inflation.pressure,
                        extrapolate="error")
    with pytest.raises(ValueError, match="HystereticActuator 'h2': inflation_curve built "
                                         "with extrapolate='error'"):
        sf.HystereticActuator("h2", sf.air, strict, loop.deflation)


def test_initial_pressure_beyond_the_data_is_refused_unless_linear():
    too_high = sf.pressure_atmospheric + 5e4          # above the curve's 400 mbar
    assert sf.Actuator("a", sf.air, _curve(), initial_pressure=too_high).initial_volume > 6e-6
    for policy in ("clamp", "error"):
        with pytest.raises(ValueError, match="initial_pressure .* is not reached"):
            sf.Actuator("a", sf.air, _curve(policy), initial_pressure=too_high)


# -- fluids at a node ---------------------------------------------------------------------
def test_different_fluids_at_a_node_name_the_components():
    s = source_tube_tank(pressure=1.5e5, tank_fluid=sf.water)
    with pytest.raises(sf.NetworkError, match=r"different fluids meet at node\(tube.b, "
                       r"tank.a\): CircularTube 'tube': 'air'; Container 'tank': 'water'"):
        sf.Simulation(s, duration=0.01)


def test_glycol_fractions_differ_but_levels_may():
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.5e5)
    s += sf.CircularTube("tube", sf.ethylene_glycol, length=0.3, diameter=1e-3)
    s += sf.LinearAccumulator("acc", sf.ethylene_glycol.at(fraction=0.3), volume=1e-6,
                              compliance=1e-12)
    s.connect("tube", "src")
    s.connect("tube", "acc")
    with pytest.raises(sf.NetworkError, match=r"'ethylene_glycol' \(fraction 0.6\).*"
                                              r"'ethylene_glycol' \(fraction 0.3\)"):
        sf.Simulation(s, duration=0.01)
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.5e5)
    s += sf.CircularTube("tube", sf.air.with_level("table"), length=0.3, diameter=1e-3)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    assert sf.Simulation(s, duration=0.01).run().status == "success"


# -- failures that name their culprit ------------------------------------------------------
class _User(sf.Component):
    """The paper's user actuator, made to raise in one of its functions."""

    def __init__(self, label, fails, after=0.004):
        super().__init__(label)
        self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across", label="p"),
                                             sf.Variable("massflow", "through", label="mf")]))
        self.set_states(sf.Variable("mass", "local", label="mass", initial_value=1e-6))

        def evaluate(p, mass, t):
            if fails == "evaluate" and t > after:
                raise ZeroDivisionError("in evaluate")
            return [p - (sf.pressure_atmospheric + 1e10 * (mass - 1e-6))]
        self.evaluate = self.auto(evaluate)
        if fails == "state_rates":
            def rates(mf):
                raise KeyError("in rates")
            self.state_rates = self.auto_rates(rates)
        else:
            def update(mass, mf, dt):
                if fails == "update_state":
                    raise RuntimeError("in update")
                return {"mass": mass + mf * dt}
            self.update_state = self.auto_state(update)


def _user_scene(fails):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    s += sf.CircularTube("tube", sf.air, length=0.1, diameter=1e-3)
    s += _User("mine", fails)
    s.connect("tube", "src")
    s.connect("tube", "mine")
    return s


def test_user_evaluate_failing_mid_run_names_component_method_time():
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(_user_scene("evaluate"), duration=0.01).run()
    e = info.value
    assert e.component == "mine" and e.method == "evaluate" and e.time > 0.004
    assert isinstance(e.__cause__, ZeroDivisionError)
    assert str(e).startswith(f"_User 'mine': evaluate raised at t = {e.time:.6g} s: "
                             "ZeroDivisionError: in evaluate")
    assert e.result.status == "failed" and e.result.times[-1] <= e.time


@pytest.mark.parametrize("fails, cause", [("update_state", RuntimeError),
                                          ("state_rates", KeyError)])
def test_user_update_or_rates_failing_at_t0_name_the_method(fails, cause):
    with pytest.raises(sf.ComponentError) as info:
        sf.Simulation(_user_scene(fails), duration=0.01)
    e = info.value
    assert (e.component, e.method, e.time) == ("mine", fails, 0.0)
    assert isinstance(e.__cause__, cause)
    assert f"_User 'mine': {fails} raised at t = 0 s: {cause.__name__}" in str(e)


def test_callable_curve_failing_names_the_actuator_whose_volume_broke_it():
    def curve(v):
        if np.any(np.asarray(v) > 3e-6):
            raise ArithmeticError("no data there")
        return 1e5 + 1e10 * np.asarray(v)
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.5e5)
    s += sf.CircularTube("slow", sf.air, length=3.0, diameter=0.5e-3)
    s += sf.CircularTube("fast", sf.air, length=0.1, diameter=1e-3)
    s += sf.Actuator("calm", sf.air, curve=curve, initial_volume=1e-6)
    s += sf.Actuator("eager", sf.air, curve=curve, initial_volume=1e-6)
    s.connect("slow", "src")
    s.connect("slow", "calm")
    s.connect("fast", "src")
    s.connect("fast", "eager")
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(s, duration=0.5).run()
    e = info.value
    assert e.component == "eager" and e.method == "curve"
    assert isinstance(e.__cause__, ArithmeticError)
    assert "Actuator 'eager': curve (V = 3" in str(e) and f"t = {e.time:.6g} s" in str(e)


def test_input_function_failing_names_the_source():
    def pressure(t):
        if t > 0.01:
            raise ValueError("waveform broke")
        return 1.2e5
    s = sf.System()
    s += sf.PressureSource("src", pressure=pressure)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(s, duration=0.05).run()
    assert info.value.component == "src" and info.value.time > 0.01
    assert "ValueError: waveform broke" in str(info.value)


def _tube_tank(length, diameter, volume, source=1.5e5):
    s = sf.System()
    s += sf.PressureSource("src", pressure=source)
    s += sf.CircularTube("tube", sf.air, length=length, diameter=diameter)
    s += sf.Container("tank", sf.air, volume=volume)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    return s


@pytest.mark.parametrize("length, diameter, volume, end", [
    (1e3, 1e-9, 1e-5, sf.pressure_atmospheric),     # 1 nm x 1 km: nothing flows
    (0.3, 1e-3, 1e-18, 1.5e5),                      # a 1 um^3 tank follows its source
])
def test_extreme_but_valid_scales_are_solved_as_the_sparse_solver_solves_them(
        length, diameter, volume, end):
    """Scales far apart (equations 1e13-1e31 apart) are no error in themselves:
    the dense solver equilibrates and runs them as SuperLU does, to the
    physical answer. (They stopped at t = 0 naming the component as extreme
    before, while linear_solver='sparse' ran them: so did 42 of 600 random
    networks, with ordinary parts such as a 0.43 m x 0.46 mm tube.)"""
    dense = sf.Simulation(_tube_tank(length, diameter, volume), duration=0.01).run()
    sparse = sf.Simulation(_tube_tank(length, diameter, volume), duration=0.01,
                           linear_solver="sparse").run()
    for res in (dense, sparse):
        assert res.get("tank", "pressure")[-1] == pytest.approx(end, rel=1e-6)
    np.testing.assert_allclose(dense.get("tank", "pressure"), sparse.get("tank", "pressure"),
                               rtol=1e-9)


def test_a_negligible_tube_says_only_that_not_what_its_noise_would_mean():
    """A 1 nm x 1 nm tube from 100 bar into a 10 mL tank: its flow is
    negligible (warned before the run: the result is that of a closed tube),
    and the flow the solver reports for it is noise below what it resolves
    (-5.5e-13 kg/s, the wrong sign): the checks on the solution say nothing
    of it (they said it choked as isothermal pipe flow, suggesting an
    adiabatic run)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        res = sf.Simulation(_tube_tank(1e-9, 1e-9, 1e-5, source=1e7), duration=0.01).run()
    said = [str(w.message) for w in seen if issubclass(w.category, sf.ModelWarning)]
    assert len(said) == 1 and "CircularTube 'tube': its flow is negligible" in said[0], said
    assert [r.check for r in res.warnings] == ["tube_negligible_flow"]
    assert res.get("tank", "pressure")[-1] == pytest.approx(sf.pressure_atmospheric, rel=1e-9)


@pytest.mark.parametrize("length", [1e-9, 1e-7])
def test_a_tube_of_almost_no_length_carries_its_entry_limited_flow(length):
    """A 1 nm (or 0.1 um) long, 1 cm wide air tube between a 1.5 bar source and
    a 1000 m^3 tank: friction is nothing, and the flow is what the isothermal
    entry from rest passes at the tank's pressure. Bernoulli for an
    isothermal gas from rest, c^2 ln(p0/p1) = u1^2/2 with u1 = G c^2/p1 and
    p1 = p_tank (no friction to drop more), gives z = 2 ln(p0/p_tank) and
    G = (p0/c) sqrt(z e^-z) (c^2 = R T). Newton's first step from rest, on
    the tube's laminar slope alone, overshoots that flow 3e10 times; the
    line search's power-law backtracking (settings.LINE_SEARCH_GROSS) gets
    there. Refused at t = 0 after 289 residual evaluations before."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", sf.ModelWarning)
        res = sf.Simulation(_tube_tank(length, 1e-2, 1e3), duration=0.01).run()
    p0, pt = 1.5e5, res.get("tank", "pressure")[-1]
    c = np.sqrt(pt / sf.air.density(pt))       # the isothermal sound speed, sqrt(R T)
    z = 2.0 * np.log(p0 / pt)
    flow = p0 / c * np.sqrt(z * np.exp(-z)) * np.pi / 4 * 1e-2 ** 2
    assert res.get("tube", "massflow", terminal="a")[-1] == pytest.approx(flow, rel=1e-5)
    assert res.stats["residual_evaluations"] <= 50


@pytest.mark.parametrize("make, name", [
    (lambda: sf.CircularTube("tube", sf.air, length=1e-12, diameter=1e-2), "length"),
    (lambda: sf.CircularTube("tube", sf.air, length=sf.Q_(1, "pm"), diameter=1e-2), "length"),
    (lambda: sf.TeslaValve("tube", sf.air, length=0.01, diameter=1e-11, diodicity=2.0),
     "diameter"),
    (lambda: sf.Orifice("tube", sf.air, diameter=1e-11, Cd=0.6), "diameter"),
    (lambda: sf.CheckValve("tube", sf.air, 1e-11), "diameter"),
])
def test_a_passage_below_an_atom_s_size_is_refused_when_built(make, name):
    """A 1 pm long tube (or a 0.01 nm wide valve): no flow law holds below a
    molecule's size. Refused when the component is built, naming it and the
    parameter (a 1 pm long, 1 cm wide tube between a 1.2 bar source and a
    tank failed at t = 0 after 248 residual evaluations, its flow out of
    reach of Newton's steps, the message a line search's); 1 nm passes
    (tests above), as does the same through params (the run's parameters
    are the constructor's)."""
    with pytest.raises(ValueError, match=rf"'tube': {name} = 1e-1[12] m is below an atom's "
                                         r"size \(1e-10 m\)"):
        make()
    s = _tube_tank(0.1, 1e-3, 1e-5)
    with pytest.raises(ValueError, match=r"CircularTube 'tube': length = 1e-12 m is below"):
        sf.Simulation(s, duration=0.01).run(params={"tube.length": 1e-12})


# -- run settings ---------------------------------------------------------------------------
@pytest.mark.parametrize("kw, match", [
    ({"duration": np.inf}, "duration must be > 0 s and finite, got inf"),
    ({"duration": np.nan}, "duration must be > 0 s and finite, got nan"),
    ({"step": np.inf}, "step must be > 0 s and finite, got inf"),
    ({"step": np.nan}, "step must be > 0 s and finite, got nan"),
])
def test_infinite_or_nan_times_are_refused_at_construction(kw, match):
    with pytest.raises(ValueError, match=match):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), **{"duration": 1.0, **kw})


def test_a_step_count_past_max_steps_is_refused_with_the_estimate():
    with pytest.raises(ValueError, match=r"step=1e-09 s over duration=1 s asks for 1e\+09 "
                                         r"steps, more than max_steps=1e\+07.*"
                                         r"max_steps=1010000000 to confirm"):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), duration=1.0, step=1e-9)
    with pytest.raises(ValueError, match=r"step_max=1e-10 s .* 1e\+08 steps"):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), duration=0.01, step_min=1e-12,
                      step_max=1e-10)
    with pytest.raises(ValueError, match="max_steps must be an integer >= 1, got 0"):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), duration=1.0, max_steps=0)


def test_max_steps_stops_a_run_that_takes_more():
    kw = {"duration": 0.5, "step": (None, 1e-3)}       # at most 1 ms: >= 500 steps
    full = sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), **kw).run()
    tried = full.stats["steps"] + full.stats["rejected_steps"]
    assert tried >= 500
    with pytest.raises(ValueError, match="asks for 500 steps, more than max_steps=20"):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), max_steps=20, **kw)
    kw = {"duration": 0.5, "step": (None, 1e-3 / 0.04)}    # the bound allows 20 steps
    sim = sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), max_steps=20, **kw)
    res = sim.run(raise_on_failure=False)
    assert res.status == "failed" and "more than max_steps = 20 steps" in res.message
    assert res.stats["steps"] + res.stats["rejected_steps"] <= 20
    assert res.times[-1] < 0.5
    assert sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), **kw).run().status == "success"


def test_unknown_atol_key_lists_the_quantities():
    with pytest.raises(KeyError, match="atol names unknown quantity 'presure'; the "
                                       "quantities are .*'massflow'.*'pressure'"):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), duration=1.0, atol={"presure": 1.0})


def test_unknown_record_label_lists_the_components():
    with pytest.raises(KeyError, match="record names unknown component 'tnak'; the "
                                       "components are 'src', 'tank', 'tube'"):
        sf.Simulation(_tube_tank(0.3, 1e-3, 1e-5), duration=1.0, record=["tnak"])
