"""Issue 41, silent inputs: an actuator starting beyond its PV curve's data, a fixed
step longer than the duration, breakpoints outside the run, and a tube whose flow
is negligible (1 nm x 1 km). The bad-input catalogue
(tests/test_bad_input_catalogue.py) holds one case of each; here the details:
where the limits lie, what the records hold, how often they warn."""
import functools
import math
import warnings

import numpy as np
import pytest

import softflow as sf
from helpers import actuator_scene, four_point_curve
from softflow.components.actuators import INITIAL_VOLUME_SLACK
from softflow.components.tubes import laminar_conductance
from softflow.curves.pvcurve import CurveRangeError
from softflow.solve.input_checks import NEGLIGIBLE_TUBE
from softflow.solve.simulation import ROUND_OFF

Q_ = sf.Q_
ATM = sf.pressure_atmospheric


#: the actuator scenes here are of water unless they say otherwise
_actuator_scene = functools.partial(actuator_scene, fluid=sf.water)


def _tube_scene(length, diameter, fluid=sf.air, tank=None, source=ATM + 1e5):
    s = sf.System()
    s += sf.PressureSource("src", pressure=source)
    s += sf.CircularTube("tube", fluid, length=length, diameter=diameter)
    s += tank or sf.Container("tank", fluid, volume=1e-5)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    return s


def _run(sim, **kw):
    """(result, messages of the ModelWarnings the run issued)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sim.run(**kw)
    return res, [str(w.message) for w in caught if issubclass(w.category, sf.ModelWarning)]


def _checked(res, check):
    return [r for r in res.warnings if r.check == check]


# -- 1. an actuator whose initial volume is outside its curve's data ---------------------
def test_an_initial_volume_100x_beyond_the_data_warns_with_the_volume_and_the_range():
    act = sf.Actuator("act", sf.water, four_point_curve(), initial_volume=Q_(600, "mL"))
    res, caught = _run(sf.Simulation(_actuator_scene(act), duration=0.1))
    assert res.status == "success"
    (rec,) = _checked(res, "initial_volume_range")
    assert rec.component == "act" and rec.status == "beyond" and rec.unit == "m^3"
    assert rec.measured == pytest.approx(600e-6) and rec.limit == pytest.approx(6e-6)
    assert rec.details["side"] == "last" and rec.details["policy"] == "linear"
    assert rec.details["data_range"] == pytest.approx((1e-6, 6e-6))
    assert rec.details["initial_pressure"] == pytest.approx(act.initial_pressure)
    assert ("Actuator 'act': initial volume 600 mL is outside its PV curve's data, "
            "1 ... 6 mL (arrays): 594 mL") in rec.message
    assert f"starts there at {act.initial_pressure / 1e5:.6g} bar (absolute)" in rec.message
    assert "continued in a straight line" in rec.message
    # warned once, and the record after the run (volume reached 600 mL, first at
    # t = 0) is not repeated: the actuator went no further out than its start
    assert caught.count(rec.message) == 1
    assert not _checked(res, "pv_curve_range")
    assert res.validity[0] is rec


def test_the_warning_comes_at_the_start_of_the_run_even_where_it_fails():
    """Warned before the run's time is spent (already there when the run's first
    step asks for its input), and a run that fails has it too."""
    seen = []

    def source(t):
        if t > 0:
            seen.append(sum("initial volume 600 mL" in str(w.message) for w in caught))
        if t > 0.01:
            raise ValueError("waveform broke")
        return 2e5

    act = sf.Actuator("act", sf.water, four_point_curve(), initial_volume=Q_(600, "mL"))
    sim = sf.Simulation(_actuator_scene(act, source=source), duration=0.1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(sf.SimulationError, match="waveform broke") as info:
            sim.run()
    assert seen and seen[0] == 1
    assert sum("initial volume 600 mL" in str(w.message) for w in caught) == 1
    assert _checked(info.value.result, "initial_volume_range")


def test_an_actuator_left_out_of_the_record_still_warns():
    """The check after the run reads recorded volumes only (record=): the start
    is judged on the inputs, recorded or not (it was silent before)."""
    act = sf.Actuator("act", sf.water, four_point_curve(), initial_volume=Q_(600, "mL"))
    res, caught = _run(sf.Simulation(_actuator_scene(act), duration=0.1, record=["tube"]))
    assert [r.component for r in _checked(res, "initial_volume_range")] == ["act"]
    assert sum("initial volume 600 mL" in m for m in caught) == 1


def test_a_run_that_goes_further_out_keeps_both_records():
    """Starting just past the data and pushed further: the start and how far it went
    are two findings."""
    act = sf.Actuator("act", sf.air, four_point_curve(), initial_volume=Q_(6.1, "mL"))
    res, caught = _run(sf.Simulation(_actuator_scene(act, fluid=sf.air), duration=0.1))
    (start,) = _checked(res, "initial_volume_range")
    (reached,) = _checked(res, "pv_curve_range")
    assert start.measured == pytest.approx(6.1e-6)
    assert reached.measured > 6.1e-6 + 0.5e-6
    assert start.message in caught and reached.message in caught


@pytest.mark.parametrize("v0", [Q_(1, "mL"), Q_(3.5, "mL"), Q_(6, "mL"), 6e-6,
                                6e-6 * (1 + INITIAL_VOLUME_SLACK / 10)])
def test_an_initial_volume_within_the_data_or_its_round_off_is_no_finding(v0):
    act = sf.Actuator("act", sf.water, four_point_curve(), initial_volume=v0)
    res, _ = _run(sf.Simulation(_actuator_scene(act, source=1.1e5), duration=0.05))
    assert not _checked(res, "initial_volume_range")


@pytest.mark.parametrize("v0, side", [(Q_(0.5, "mL"), "first"), (Q_(6.01, "mL"), "last")])
def test_any_volume_outside_the_data_warns(v0, side):
    """Past the round-off, a little is enough: the start is the user's number, not an
    adaptive step's overshoot (the check after the run allows 1 % of the range)."""
    act = sf.Actuator("act", sf.water, four_point_curve(), initial_volume=v0)
    res, _ = _run(sf.Simulation(_actuator_scene(act, source=1.1e5), duration=0.05))
    (rec,) = _checked(res, "initial_volume_range")
    assert rec.details["side"] == side and f"beyond its {side} sample" in rec.message


def test_an_initial_pressure_beyond_the_data_warns_naming_it():
    act = sf.Actuator("act", sf.water, four_point_curve(), initial_pressure=Q_(2, "bar"))
    assert act.initial_volume > 6e-6          # on the curve's linear extension
    res, _ = _run(sf.Simulation(_actuator_scene(act), duration=0.05))
    (rec,) = _checked(res, "initial_volume_range")
    assert "(from its initial_pressure)" in rec.message


def test_a_clamped_curve_says_it_holds_the_end_pressure():
    act = sf.Actuator("act", sf.water, four_point_curve(extrapolate="clamp"), initial_volume=Q_(60, "mL"))
    res, _ = _run(sf.Simulation(_actuator_scene(act, source=1.3e5), duration=0.05))
    (rec,) = _checked(res, "initial_volume_range")
    assert "held at its end pressure" in rec.message


def test_a_strict_curve_refuses_the_initial_volume_naming_the_actuator():
    with pytest.raises(CurveRangeError) as info:
        sf.Actuator("act", sf.air, four_point_curve(extrapolate="error"), initial_volume=Q_(600, "mL"))
    msg = str(info.value)
    assert msg.startswith("Actuator 'act': initial_volume 600 mL (0.0006 m^3) is outside")
    assert "1 ... 6 mL (arrays)" in msg and "extrapolate='error'" in msg
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value.__cause__, CurveRangeError)      # the curve's own error


def test_a_hysteretic_actuator_is_judged_on_both_curves():
    loop = sf.HysteresisLoop.snapping((1e-6, 1.0e5), (3e-6, 1.3e5), (5e-6, 1.1e5),
                                      (7e-6, 1.4e5), snap_volume=2.5e-6)
    act = sf.HystereticActuator("act", sf.water, *loop, initial_volume=Q_(70, "mL"))
    res, _ = _run(sf.Simulation(_actuator_scene(act), duration=0.05))
    (rec,) = _checked(res, "initial_volume_range")
    assert rec.component == "act" and rec.details["data_range"] == pytest.approx((1e-6, 7e-6))
    assert "inflation/deflation curves" in rec.message


def test_a_callable_curve_has_no_data_to_leave():
    act = sf.Actuator("act", sf.water, lambda v: 1e5 + 1e10 * v, initial_volume=Q_(600, "mL"))
    res, _ = _run(sf.Simulation(_actuator_scene(act, source=1.1e5), duration=0.05))
    assert not _checked(res, "initial_volume_range")


def test_run_time_parameters_are_judged_per_run():
    act = sf.Actuator("act", sf.water, four_point_curve(), initial_volume=Q_(2, "mL"))
    sim = sf.Simulation(_actuator_scene(act, source=1.1e5), duration=0.05)
    res, _ = _run(sim)
    assert not _checked(res, "initial_volume_range")
    res, caught = _run(sim, params={"act.initial_volume": Q_(600, "mL")})
    assert [r.measured for r in _checked(res, "initial_volume_range")] == pytest.approx([6e-4])
    assert sum("initial volume 600 mL" in m for m in caught) == 1
    res, _ = _run(sim)                    # the compiled value again
    assert not _checked(res, "initial_volume_range")


# -- 2. a fixed step longer than the duration ------------------------------------------------
def _tank():
    return _tube_scene(0.3, 1e-3)


def test_a_fixed_step_longer_than_the_duration_is_refused_with_both_values():
    with pytest.raises(ValueError, match=r"Simulation: step=0\.2 s is longer than "
                                         r"duration=0\.1 s; expected a fixed step of at most "
                                         r"the duration"):
        sf.Simulation(_tank(), duration=0.1, step=0.2)
    with pytest.raises(ValueError, match=r"step=0\.1 s is longer than duration=0\.05 s"):
        sf.Simulation(_tank(), duration=Q_(50, "ms"), step=Q_(100, "ms"), adaptive=False)


def test_a_step_just_past_the_tolerance_shows_the_digits_that_differ():
    with pytest.raises(ValueError, match=r"step=0\.1000000002 s is longer than duration=0\.1 s"):
        sf.Simulation(_tank(), duration=0.1, step=0.1 * (1 + 2e-9))


@pytest.mark.parametrize("duration, step", [(0.3, 0.3), (0.3, 0.1 * 3),
                                            (0.1, 0.1 * (1 + ROUND_OFF / 2))])
def test_a_step_of_the_duration_or_its_round_off_takes_one_step(duration, step):
    assert step >= duration
    res = sf.Simulation(_tank(), duration=duration, step=step).run()
    assert res.status == "success" and res.times.tolist() == [0.0, duration]


def test_an_adaptive_first_step_longer_than_the_duration_is_only_a_first_step():
    """With adaptive=True, ``step`` is the first step, which the run cuts to the
    duration as it does any step: no error."""
    res = sf.Simulation(_tank(), duration=0.1, step=0.2, adaptive=True).run()
    assert res.status == "success" and res.times[-1] == 0.1


# -- 3. breakpoints outside [0, duration] -----------------------------------------------------
@pytest.mark.parametrize("bad, shown", [([-0.01], "-0.01"), ([0.05, 0.2], "0.2"),
                                        ([Q_(-1, "ms"), Q_(150, "ms")], "-0.001, 0.15"),
                                        ([math.nan], "nan"), ([math.inf], "inf")])
def test_breakpoints_outside_the_run_are_refused_naming_them(bad, shown):
    with pytest.raises(ValueError) as info:
        sf.Simulation(_tank(), duration=0.1, breakpoints=bad)
    assert str(info.value) == ("Simulation: breakpoints must lie within the run, [0, duration] "
                               f"= [0, 0.1] s; got {shown} s")


def test_breakpoints_at_the_start_and_the_end_are_accepted_and_change_nothing():
    plain = sf.Simulation(_tank(), duration=0.1).run()
    ends = sf.Simulation(_tank(), duration=0.1, breakpoints=[0.0, 0.1]).run()
    np.testing.assert_array_equal(ends.times, plain.times)
    np.testing.assert_array_equal(ends.get("tank", "pressure"), plain.get("tank", "pressure"))
    fixed = sf.Simulation(_tank(), duration=0.1, step=0.01, breakpoints=[0, 0.1]).run()
    assert len(fixed.times) == 11


def test_breakpoints_within_round_off_of_the_ends_are_accepted():
    sim = sf.Simulation(_tank(), duration=0.3, step=0.1,
                        breakpoints=[-1e-18, 0.1 * 3, 0.3 * (1 + ROUND_OFF / 2)])
    assert sim.run().times.tolist() == pytest.approx([0.0, 0.1, 0.2, 0.3], abs=1e-15)


def test_a_single_number_for_breakpoints_says_to_give_a_sequence():
    for bad in (0.05, Q_(50, "ms"), "0.05"):
        with pytest.raises(TypeError, match=r"Simulation: breakpoints must be a sequence of "
                                            r"times \[s\].*breakpoints=\[t\]"):
            sf.Simulation(_tank(), duration=0.1, breakpoints=bad)


# -- 4. a tube whose flow is negligible ---------------------------------------------------------
def test_the_measured_flow_of_a_1nm_x_1km_tube_is_hagen_poiseuille_and_nothing_moves():
    """What the run gives (the reason for the warning below): at 1 bar the tube
    passes its Hagen–Poiseuille flow, ~1e-31 kg/s of air and ~2e-30 kg/s of water,
    in as few steps as an ordinary tube, and the tank's pressure does not move."""
    for fluid, tank, expected in (
            (sf.air, None, 2.4e-31),
            (sf.water, sf.LinearAccumulator("tank", sf.water, volume=1e-5, compliance=1e-11),
             2.4e-30)):
        res, caught = _run(sf.Simulation(_tube_scene(1e3, 1e-9, fluid, tank), duration=1.0))
        mf = res.get("tube", "massflow", terminal="a")
        rho = float(fluid.density(ATM + 0.5e5))
        hp = rho * math.pi * 1e-36 * 1e5 / (128 * float(fluid.viscosity(ATM)) * 1e3)
        assert mf[-1] == pytest.approx(hp, rel=0.02) and mf[-1] == pytest.approx(expected,
                                                                                 rel=0.05)
        assert res.get("tank", "pressure")[-1] == ATM
        assert res.stats["steps"] < 40 and res.stats["rejected_steps"] == 0
        assert [r.check for r in res.warnings] == ["tube_negligible_flow"]
        assert len(caught) == 1


def test_a_1nm_x_1km_tube_warns_that_its_flow_is_negligible_with_its_time_constant():
    res, caught = _run(sf.Simulation(_tube_scene(1e3, 1e-9), duration=1.0))
    (rec,) = _checked(res, "tube_negligible_flow")
    G = float(laminar_conductance(sf.air, 1e3, 1e-9, ATM))
    C = 1e-5 * float(sf.air.density_dp(ATM))             # the tank's capacitance
    assert rec.component == "tube" and rec.unit == "s" and rec.status == "beyond"
    assert rec.details["conductance"] == pytest.approx(G)
    assert rec.details["capacitance"] == pytest.approx(C, rel=1e-6)
    assert rec.details["volume"] == "tank"
    assert rec.measured == pytest.approx(C / G, rel=1e-6) and rec.measured > 1e25
    assert rec.limit == pytest.approx(1.0 / (NEGLIGIBLE_TUBE * 1e-3))
    assert rec.fraction == pytest.approx(rec.measured / rec.limit)
    assert rec.message.startswith("CircularTube 'tube': its flow is negligible. With length = "
                                  "1e+03 m and diameter = 1e-09 m its laminar "
                                  "(Hagen–Poiseuille) conductance is 1.62e-36 kg/s per Pa")
    assert "time constant with Container 'tank' (capacitance 1.19e-10 kg/Pa)" in rec.message
    assert "the result is that of a closed tube" in rec.message
    assert caught.count(rec.message) == 1


@pytest.mark.parametrize("diameter, warned", [(1e-9, True), (1e-6, True), (1e-5, False),
                                              (1e-3, False)])
def test_the_limit_is_the_time_constant_against_the_duration_not_a_size(diameter, warned):
    """A 0.3 m tube into a 10 mL tank, 1 s: tau = 2e10 s at 1 um (a diameter given in
    m for mm), which can equalize 5e-11 of the difference, below 1e-6 rtol: warned;
    at 10 um, 5e-7 (0.07 Pa of 1 bar), above it: not warned."""
    res, _ = _run(sf.Simulation(_tube_scene(0.3, diameter), duration=1.0))
    assert bool(_checked(res, "tube_negligible_flow")) is warned


def test_the_limit_follows_rtol_and_the_duration():
    """The 1 um tube equalizes ~5e-11 of the difference in 1 s: below 1e-6 rtol at the
    default rtol, not at rtol = 1e-8 (limit 1e-14), nor over 1e6 s."""
    scene = _tube_scene(0.3, 1e-6)
    assert _checked(_run(sf.Simulation(scene, duration=1.0))[0], "tube_negligible_flow")
    assert not _checked(_run(sf.Simulation(scene, duration=1.0, rtol=1e-8))[0],
                        "tube_negligible_flow")
    assert not _checked(_run(sf.Simulation(scene, duration=1e6))[0], "tube_negligible_flow")


def test_a_tube_reaches_its_volumes_through_other_components():
    s = sf.System()
    s += sf.PressureSource("src", pressure=2e5)
    s += sf.CircularTube("feed", sf.air, length=0.1, diameter=1e-3)
    s += sf.CircularTube("tube", sf.air, length=1e3, diameter=1e-9)
    s += sf.CircularTube("after", sf.air, length=0.1, diameter=1e-3)
    s += sf.Container("big", sf.air, volume=1e-3)
    s += sf.Container("small", sf.air, volume=1e-6)
    s.connect(("feed", "a"), "src")
    s.connect(("feed", "b"), ("tube", "a"))
    s.connect(("tube", "b"), ("after", "a"))
    s.connect(("after", "b"), "small")
    s.connect(("feed", "b"), "big")
    res, _ = _run(sf.Simulation(s, duration=1.0))
    (rec,) = _checked(res, "tube_negligible_flow")
    assert rec.component == "tube" and rec.details["volume"] == "small"   # the smaller


def test_a_tube_between_sources_only_is_not_judged():
    """Its flow is then the answer itself (no volume to change): no finding."""
    s = sf.System()
    s += sf.PressureSource("s1", pressure=2e5)
    s += sf.PressureSource("s2", pressure=1e5)
    s += sf.CircularTube("tube", sf.air, length=1e3, diameter=1e-9)
    s.connect(("tube", "a"), "s1")
    s.connect(("tube", "b"), "s2")
    res, _ = _run(sf.Simulation(s, duration=1.0))
    assert not _checked(res, "tube_negligible_flow")


def test_a_tube_reaching_a_user_volume_is_not_judged():
    """A user component's capacitance is unknown: no claim is made."""

    class Tank(sf.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across", label="p"),
                                                 sf.Variable("massflow", "through",
                                                             label="mf")]))
            self.set_states(sf.Variable("mass", "local", label="mass", initial_value=1e-6))
            self.evaluate = self.auto(lambda p, mass: [p - (ATM + 1e10 * (mass - 1e-6))])
            self.update_state = self.auto_state(lambda mass, mf, dt: {"mass": mass + mf * dt})

    res, _ = _run(sf.Simulation(_tube_scene(1e3, 1e-9, tank=Tank("tank")), duration=0.01))
    assert not _checked(res, "tube_negligible_flow")


def test_a_negligible_tube_warns_in_a_thermal_scene_too():
    res, _ = _run(sf.Simulation(_tube_scene(1e3, 1e-9), duration=1.0, thermal="adiabatic"))
    assert [r.component for r in _checked(res, "tube_negligible_flow")] == ["tube"]


def test_laminar_conductance_is_hagen_poiseuille():
    rho, mu = float(sf.water.density(ATM)), float(sf.water.viscosity(ATM))
    got = laminar_conductance(sf.water, np.array([0.3, 1.0]), np.array([1e-3, 2e-3]), ATM)
    want = rho * np.pi * np.array([1e-12, 16e-12]) / (128 * mu * np.array([0.3, 1.0]))
    np.testing.assert_allclose(got, want, rtol=1e-12)
    # the tube's own law at a small flow: the same pressure drop per kg/s
    res = sf.Simulation(_tube_scene(0.3, 1e-3, sf.water, sf.LinearAccumulator(
        "tank", sf.water, volume=1e-5, compliance=1e-11), source=ATM + 10.0),
        duration=1e-3, step=1e-3).run()
    mf = res.get("tube", "massflow", terminal="a")[-1]
    dp = ATM + 10.0 - res.get("tank", "pressure")[-1]
    assert mf / dp == pytest.approx(got[0], rel=1e-6)
