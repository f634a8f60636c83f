"""Issue 41, unphysical states: a liquid drawn below its vapour pressure (a
warning that cavitation is not modelled, with the lowest pressure, where, when
and the vapour pressure, which comes from the fluid tables' metadata without
CoolProp), and a chamber or actuator whose volume or mass reaches zero (the
run stops there with an error naming it and the time, unless its PV curve's
data define that volume)."""
import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow import paper_scenes as ps
from softflow.curves.waveforms import PiecewiseConstant
from softflow.fluids.tables import default_directory

ML = 1e-6
#: CoolProp 8.0 HEOS::Water, saturated liquid at 20 degC [Pa]
P_SAT_WATER_20C = 2339.3181834056754


def vapour_pressure(fluid, temperature=None):
    # (imported here: before issue 41 the module did not exist, and the other
    # tests of this file must fail on their own assertions there)
    from softflow.fluids.vapour import vapour_pressure
    return vapour_pressure(fluid, temperature)


def _run(system, **options):
    """(result, messages of the ModelWarnings issued) of a run that may fail."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sf.Simulation(system, **options).run(raise_on_failure=False)
    return res, [str(w.message) for w in caught if issubclass(w.category, sf.ModelWarning)]


def _cavitation(records):
    return [r for r in records if r.check == "cavitation"]


# -- cavitation ----------------------------------------------------------------------
def _suction(fluid, pressure):
    """A liquid accumulator behind a tube whose far end a source holds at ``pressure``."""
    s = sf.System()
    s += sf.PressureSource("vac", pressure=pressure)
    s += sf.CircularTube("tube", fluid, length=0.3, diameter=1e-3)
    s += sf.LinearAccumulator("acc", fluid, volume=1e-5, compliance=1e-11)
    s.connect("tube", "vac")
    s.connect("tube", "acc")
    return s


def test_water_sucked_below_its_vapour_pressure_warns_that_cavitation_is_not_modelled():
    # the issue's case: water (the 'ideal' level, a ConstantLiquid) at 1 kPa abs
    res, caught = _run(_suction(sf.water, 1e3), duration=0.5)
    assert res.status == "success"
    (rec,) = _cavitation(res.warnings)
    assert rec.component == "tube" and rec.status == "beyond" and rec.unit == "Pa"
    assert rec.measured == pytest.approx(1e3) and rec.limit == pytest.approx(P_SAT_WATER_20C,
                                                                              rel=1e-4)
    assert rec.fraction == pytest.approx(rec.limit / rec.measured)
    assert rec.details["time"] == 0.0 and rec.details["node"] == "node(vac.a, tube.a)"
    for text in ("1000 Pa", "2339 Pa", "node(vac.a, tube.a)", "t = 0 s", "293.15 K",
                 "cavitate", "does not model", "Suggestion:"):
        assert text in rec.message, text
    assert [m for m in caught if "cavitate" in m] == [rec.message]


def test_the_lowest_pressure_is_reported_with_its_node_and_time():
    # a pump draws 0.5 mL/s of water for 4 s from a compliant volume (then stops):
    # the accumulator falls 25 kPa/s to 1.3 kPa, the pump's node lies the tube's
    # drop (0.4 kPa) below it until the pump stops
    s = sf.System()
    s += sf.VolumeFlowSource("pump", PiecewiseConstant([0.0, 4.0], [-0.5 * ML, 0.0]),
                             fluid=sf.water)
    s += sf.CircularTube("tube", sf.water, length=0.3, diameter=2e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=5 * ML, compliance=2e-11)
    s.connect("tube", "pump")
    s.connect("tube", "acc")
    res, _ = _run(s, duration=5.0)
    (rec,) = _cavitation(res.warnings)
    p_node = res.get("tube", "pressure", terminal="a")
    k = int(np.argmin(p_node))
    assert rec.measured == pytest.approx(p_node[k]) and rec.measured < P_SAT_WATER_20C
    assert rec.details["time"] == pytest.approx(res.times[k]) == pytest.approx(4.0, abs=1e-6)
    assert rec.details["node"] == "node(pump.a, tube.a)" and rec.component == "pump"
    assert "VolumeFlowSource 'pump': the pressure of its liquid" in rec.message
    assert f"t = {res.times[k]:.6g} s" in rec.message


@pytest.mark.parametrize("T", [274.15, 293.15, 330.0, 368.15, 273.16, 373.0])
def test_the_tables_vapour_pressure_of_water_matches_coolprop(T):
    cp = pytest.importorskip("CoolProp.CoolProp")
    ref = cp.PropsSI("P", "T", T, "Q", 0, "HEOS::Water")
    # 3.3e-5 between the table's nodes; up to 5e-4 at 5 K beyond its range (368.15 K)
    assert vapour_pressure(sf.water, T) == pytest.approx(ref, rel=1e-4 if T < 370 else 1e-3)


def test_glycol_vapour_pressure_is_raoults_law_on_water():
    cp = pytest.importorskip("CoolProp.CoolProp")
    for fraction, fluid in ((0.6, sf.ethylene_glycol),
                            (0.3, sf.ethylene_glycol.at(fraction=0.3))):
        n_water = (1 - fraction) / 0.018015268
        x_water = n_water / (n_water + fraction / 0.062068)
        ref = x_water * cp.PropsSI("P", "T", 293.15, "Q", 0, "HEOS::Water")
        assert vapour_pressure(fluid) == pytest.approx(ref, rel=1e-4)
    meta = json.loads((default_directory()
                       / "ethylene_glycol-0.6.json").read_text())["vapour_pressure"]
    assert "Raoult" in meta["source"] and meta["max_error"] < 1e-4


def test_unknown_vapour_pressures_are_none():
    assert vapour_pressure(sf.air) is None                       # a gas
    assert vapour_pressure(sf.water, 400.0) is None              # far beyond the record
    mine = sf.ConstantLiquid("oil", density=870.0, viscosity=0.03)
    assert vapour_pressure(mine) is None                         # no record, no spec


def test_the_check_needs_no_coolprop():
    code = ("import sys, warnings\nimport softflow as sf\n"
            "warnings.simplefilter('ignore')\n"
            "from test_issue41_states import _suction\n"
            "res = sf.Simulation(_suction(sf.water, 1e3), duration=0.2).run()\n"
            "print([r.check for r in res.warnings if r.check == 'cavitation'],"
            " 'CoolProp' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=str(__import__("pathlib").Path(__file__).parent))
    assert out.stdout.split("\n")[-2] == "['cavitation'] False", out.stdout + out.stderr


def test_glycol_and_the_table_level_get_the_check_and_near_misses_are_kept():
    res, _ = _run(_suction(sf.ethylene_glycol, 1e3), duration=0.2)
    (rec,) = _cavitation(res.warnings)
    assert rec.limit == pytest.approx(vapour_pressure(sf.ethylene_glycol))
    # table water at 90 degC (vapour pressure 70 kPa, inside the table's 50 kPa floor)
    hot = sf.Fluid("water", level="table", temperature=363.15)
    res, _ = _run(_suction(hot, 6e4), duration=0.2)
    (rec,) = _cavitation(res.warnings)
    assert rec.limit == pytest.approx(70182, rel=1e-3) and "363.15 K" in rec.message
    # at 80 degC (47.4 kPa) and 80 kPa: a near miss, kept, not warned
    warm = sf.Fluid("water", level="table", temperature=353.15)
    res, caught = _run(_suction(warm, 8e4), duration=0.2)
    assert not _cavitation(res.warnings) and not [m for m in caught if "vapour" in m]
    (near,) = _cavitation(res.validity)
    assert near.status == "near" and near.fraction == pytest.approx(near.limit / 8e4)


@pytest.mark.parametrize("fig, case", [(3, c) for c in ps.FIG3_CASES]
                         + [(4, c) for c in ps.FIG4_CASES] + [(5, c) for c in ps.FIG5_FLUIDS])
def test_no_paper_scene_comes_near_its_vapour_pressure(fig, case):
    system = dict(ps.figure(fig))[case]
    res, _ = ps.run(system, fig, beyond_limits="warn")
    assert res.status == "success" and not _cavitation(res.validity)


# -- a chamber or actuator that empties ----------------------------------------------
def _curve():
    return sf.PVCurve(volume=sf.Q_([1, 2, 4, 6], "mL"), pressure=sf.Q_([0, 100, 200, 400],
                                                                      "mbar"), gauge=True)


def _drained(rate, curve=None, v0=3 * ML, fluid=sf.water):
    """A pump drawing ``rate`` [m^3/s] from an actuator holding ``v0`` through a tube."""
    s = sf.System()
    s += sf.VolumeFlowSource("pump", volumeflow=-rate, fluid=fluid)
    s += sf.CircularTube("tube", fluid, length=0.3, diameter=1e-3)
    s += sf.Actuator("act", fluid, curve or _curve(), initial_volume=v0)
    s.connect("tube", "pump")
    s.connect("tube", "act")
    return s


STEPPERS = [pytest.param({}, id="bdf"), pytest.param({"step": 0.01}, id="euler")]


@pytest.mark.parametrize("options", STEPPERS)
def test_an_actuator_drained_to_no_volume_stops_there_naming_it_and_the_time(options):
    # 3 mL at 0.7 mL/s: empty at 4.2857 s (its curve's data start at 1 mL; before
    # issue 41 the run went on to -0.5 mL with only a 'beyond the first sample' warning)
    t_empty = 3.0 / 0.7
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(_drained(0.7 * ML), duration=6.0, **options).run()
    err = info.value
    assert err.component == "act" and err.time == pytest.approx(t_empty, rel=1e-9)
    assert err.__cause__ is None
    msg = str(err)
    assert msg.startswith("Actuator 'act': its fluid volume reached zero at t = 4.28571 s")
    res = err.result
    assert res.status == "failed" and res.message == msg
    # the result is kept up to there: its last step ends just short of the crossing
    assert t_empty - 1e-4 < res.times[-1] < t_empty
    assert res.get("act", "volume").min() > -1e-12
    # two tries: the step past the crossing, retried to end just short of it
    # (taken), and the one after (a step of the same length) crosses again
    stats = res.stats
    assert stats["rejected_steps"] - stats["error_test_failures"] == 2


@pytest.mark.parametrize("options", STEPPERS)
def test_a_gas_container_drained_by_a_mass_flow_source_stops_with_its_mass(options):
    # a rigid volume of gas cannot reach zero volume, but its mass can; before,
    # the run failed at the smallest step on 'absolute pressure <= 0' after
    # 90 (adaptive) and 227 (fixed steps) residual evaluations
    m0 = float(sf.air.density(sf.pressure_atmospheric)) * 1e-5
    s = sf.System()
    s += sf.MassFlowSource("drain", massflow=-1e-4)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect("drain", "tank")
    res, _ = _run(s, duration=1.0, **options)
    assert res.status == "failed"
    assert res.message.startswith("Container 'tank': its stored mass reached zero at t = ")
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(s, duration=1.0, **options).run()
    assert info.value.component == "tank"
    assert info.value.time == pytest.approx(m0 / 1e-4, rel=1e-6)
    # the last step taken ends 1e-3 of itself short of the crossing
    assert res.times[-1] == pytest.approx(m0 / 1e-4, rel=2e-3) and res.times[-1] < m0 / 1e-4
    assert res.stats["residual_evaluations"] <= 30


def test_a_liquid_accumulator_drained_to_no_volume_is_named():
    s = sf.System()
    s += sf.VolumeFlowSource("pump", volumeflow=-1 * ML, fluid=sf.water)
    s += sf.CircularTube("tube", sf.water, length=0.3, diameter=3e-3)
    # 1 mL at 1 atm, 1e-11 m^3/Pa: empty at 1325 Pa abs, after 1 s (the pump's
    # node 0.15 kPa lower; through a 1 mm tube, 12 kPa lower, it reaches zero
    # pressure first, a failure there)
    s += sf.LinearAccumulator("acc", sf.water, volume=1 * ML, compliance=1e-11)
    s.connect("tube", "pump")
    s.connect("tube", "acc")
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(s, duration=2.0).run()
    assert info.value.component == "acc" and info.value.time == pytest.approx(1.0, rel=1e-6)
    assert "LinearAccumulator 'acc': its fluid volume reached zero" in str(info.value)


def test_a_curve_whose_data_start_below_zero_defines_those_volumes():
    # volumes given as changes from a rest volume: data from -2 mL
    curve = sf.PVCurve(volume=sf.Q_([-2, 0, 2, 4], "mL"),
                       pressure=sf.Q_([-100, 0, 100, 300], "mbar"), gauge=True)
    for options in ({}, {"step": 0.01}):
        res, _ = _run(_drained(1 * ML, curve, v0=1 * ML), duration=2.5, **options)
        assert res.status == "success"                    # down to -1.5 mL: defined
        assert res.get("act", "volume").min() == pytest.approx(-1.5 * ML)
        res, _ = _run(_drained(1 * ML, curve, v0=1 * ML), duration=5.0, **options)
        assert res.status == "failed" and res.times[-1] == pytest.approx(3.0, abs=1e-3)
        assert ("its fluid volume reached the first sample of its PV curve's data, -2e-06 "
                "m^3 (the least volume the curve defines) at t = 3 s") in res.message


@pytest.mark.parametrize("options", [{}, {"rtol": 1e-2}, {"rtol": 1e-5}, {"step": 0.01}])
def test_a_volume_that_levels_off_at_zero_runs_on(options):
    # a gas actuator whose curve's data start at 0 mL and 1 atm, let out to the
    # atmosphere: its volume decays towards 0 without reaching it; the adaptive
    # steps overshoot it within the tolerance, which is no emptying
    curve = sf.PVCurve(volume=sf.Q_([0, 1, 2, 4], "mL"),
                       pressure=sf.Q_([0, 100, 150, 300], "mbar"), gauge=True)
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.pressure_atmospheric)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=0.5e-3)
    s += sf.Actuator("act", sf.air, curve, initial_volume=3 * ML)
    s.connect("tube", "src")
    s.connect("tube", "act")
    res, _ = _run(s, duration=20.0, **options)
    assert res.status == "success", res.message
    v = res.get("act", "volume")
    assert v[-1] < 1e-12 and v.min() > -1e-12


def test_the_fixed_step_is_shortened_to_the_crossing_before_the_run_stops():
    # at a fixed step of 10 ms the crossing at 4.2857 s lies inside a step: the
    # step is retried to end just short of it (off the grid), then the next one
    # crosses again and the run stops
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(_drained(0.7 * ML), duration=6.0, step=0.01).run()
    t = info.value.result.times
    assert t[-2] == pytest.approx(4.28) and 0 < info.value.time - t[-1] < 1e-5
    assert not math.isclose(t[-1] / 0.01, round(t[-1] / 0.01), abs_tol=1e-6)


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_the_step_after_the_located_one_is_short_and_the_stop_comes_at_once(thermal):
    # (a random air network's, reduced): a hysteretic actuator at 1 atm let
    # down through a short wide tube to 0.6 bar abs empties within the first
    # 1 ms step. Once a step ends just short of the located crossing, the
    # next one ends a few times that distance past it (EMPTY_AHEAD), not at
    # the grid's next point: adiabatic, that step's Newton failed twice
    # before a quarter of it showed the crossing (161 residual evaluations
    # after the last step; now 2)
    s = sf.System()
    s += sf.PressureSource("vac", 60562.3)
    s += sf.CircularTube("tube", sf.air, length=6.4e-3, diameter=3.87e-3)
    s += sf.HystereticActuator(
        "act", sf.air,
        sf.PVCurve(volume=[1e-6, 3.5e-6, 6e-6, 6.3e-6], pressure=[101325, 114325, 127325, 117887]),
        sf.PVCurve(volume=[3.7e-6, 4e-6, 9e-6, 1.4e-5], pressure=[115442, 113325, 127325, 141325]),
        initial_volume=1e-6)
    s.connect("vac", ("tube", "a"))
    s.connect(("tube", "b"), "act")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        with pytest.raises(sf.SimulationError, match="HystereticActuator 'act': its fluid "
                           "volume reached zero at t = 0.000") as info:
            sf.Simulation(s, duration=0.01, step=1e-3, thermal=thermal).run()
    stats = info.value.result.stats
    assert stats["residual_evaluations"] - stats["residuals_at_last_step"] <= 5
    assert 0 < info.value.time - info.value.result.times[-1] < 1e-6
