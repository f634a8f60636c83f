"""Run-time parameters (Simulation.run(params=...)) and Simulations and Results
as values (pickle round trips)."""
import pickle

import numpy as np
import pytest

import softflow as sf
from softflow.network.system import NetworkError
from softflow.paper_scenes import curve_peak_valley, curve_plateau

P0 = sf.pressure_atmospheric


def scene(diameter=1e-3, volume=1e-5, p_tank=P0, pressure=sf.Q_(1.3, "bar"),
          curve=None, actuators=1):
    s = sf.System()
    s += sf.PressureSource("src", pressure=pressure)
    s += sf.CircularTube("tube", sf.air, 0.5, diameter)
    s += sf.Container("tank", sf.air, volume, initial_pressure=p_tank)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    curve = curve or curve_peak_valley()
    for k in range(actuators):
        s += sf.CircularTube(f"r{k}", sf.air, 0.3, 0.8e-3)
        s += sf.Actuator(f"act{k}", sf.air, curve)
        s.connect("tank", f"r{k}")
        s.connect(f"r{k}", f"act{k}")
    return s


def _same(a, b):
    np.testing.assert_array_equal(a.times, b.times)
    for label in ("tank", "act0"):
        np.testing.assert_array_equal(a.get(label, "pressure"), b.get(label, "pressure"))


@pytest.mark.parametrize("stepping", [{}, {"step": 2e-3}], ids=["bdf", "fixed"])
@pytest.mark.parametrize("change", [
    {"tube.diameter": sf.Q_(1.5, "mm")},
    {"tank.volume": 3e-5, "tank.initial_pressure": sf.Q_(1.1, "bar")},
    {"act0.curve": curve_plateau(18.0)},
    {"src.pressure": sf.waveforms.Square(P0, P0 + 3e4, 4.0)},
], ids=["diameter", "volume-initial", "curve", "waveform"])
def test_params_run_equals_a_fresh_build_and_the_next_run_is_back(stepping, change):
    built = {"tube.diameter": dict(diameter=1.5e-3),
             "tank.volume": dict(volume=3e-5, p_tank=1.1e5),
             "act0.curve": dict(curve=curve_plateau(18.0)),
             "src.pressure": dict(pressure=sf.waveforms.Square(P0, P0 + 3e4, 4.0))}
    fresh_kw = built[next(iter(change))]
    sim = sf.Simulation(scene(), duration=0.5, **stepping)
    base = sim.run()
    changed = sim.run(params=change)
    _same(changed, sf.Simulation(scene(**fresh_kw), duration=0.5, **stepping).run())
    with pytest.raises(AssertionError):
        _same(changed, base)
    _same(sim.run(), base)


def test_params_leave_the_system_unchanged():
    s = scene()
    before = pickle.dumps(s)
    sim = sf.Simulation(s, duration=0.2)
    sim.run(params={"tube.diameter": 2e-3, "act0.curve": curve_plateau(20.0)})
    assert pickle.dumps(s) == before
    assert s.get("tube").diameter == 1e-3


@pytest.mark.parametrize("params, error, match", [
    ({"tube.diam": 1e-3}, KeyError, r"'tube.diam'.*has no parameter 'diam'.*diameter"),
    ({"tub.diameter": 1e-3}, KeyError, r"no component 'tub'.*'tube'"),
    ({"diameter": 1e-3}, KeyError, r"not 'label.parameter'"),
    ({"tube.diameter": -1.0}, ValueError, r"'tube.diameter'.*diameter must be > 0"),
    ({"tube.diameter": sf.Q_(1, "s")}, ValueError, r"'tube.diameter'.*length"),
    ({"tube.fluid": sf.water}, NetworkError, r"'tube.fluid'.*structure"),
    ({"tube.label": "x"}, NetworkError, r"structure"),
])
def test_bad_params_name_the_key(params, error, match):
    sim = sf.Simulation(scene(), duration=0.1)
    with pytest.raises(error, match=match):
        sim.run(params=params)
    # a refused set leaves the compiled values in force
    _same(sim.run(), sf.Simulation(scene(), duration=0.1).run())


def test_a_new_curve_for_one_of_two_sharing_it_is_structural():
    sim = sf.Simulation(scene(actuators=2), duration=0.1)
    with pytest.raises(NetworkError, match=r"'act0', 'act1'.*give them all the same"):
        sim.run(params={"act0.curve": curve_plateau(18.0)})
    new = curve_plateau(18.0)
    res = sim.run(params={"act0.curve": new, "act1.curve": new})
    assert res.success


def test_user_components_refuse_params():
    import sys
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from test_user_rates import scene as user_scene
    sim = sf.Simulation(user_scene("rates"), duration=0.1)
    with pytest.raises(NetworkError, match="user component's parameters are fixed"):
        sim.run(params={"act.p": 1.0})


@pytest.mark.parametrize("change, built", [
    ({"tube.diameter": 1.5e-3}, dict(diameter=1.5e-3)),
    ({"tank.volume": 3e-5, "tank.initial_pressure": 1.1e5}, dict(volume=3e-5, p_tank=1.1e5)),
])
def test_thermal_scenes_take_params_too(change, built):
    """An adiabatic scene: the rebuilt components are put into the scene's
    thermal model as the compiled ones were; bitwise a fresh thermal build."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(scene(), duration=0.3, thermal="adiabatic")
        base = sim.run()
        changed = sim.run(params=change)
        fresh = sf.Simulation(scene(**built), duration=0.3, thermal="adiabatic").run()
        _same(changed, fresh)
        np.testing.assert_array_equal(changed.get("tank", "temperature"),
                                      fresh.get("tank", "temperature"))
        _same(sim.run(), base)


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_simulation_and_result_pickle_and_rerun_bitwise(thermal):
    sim = sf.Simulation(scene(), duration=0.3, thermal=thermal)
    res = sim.run()
    twin = pickle.loads(pickle.dumps(sim))
    np.testing.assert_array_equal(twin.result.get("act0", "volume"), res.get("act0", "volume"))
    _same(twin.run(), res)
    back = pickle.loads(pickle.dumps(res))
    np.testing.assert_array_equal(back.get("act0", "volume"), res.get("act0", "volume"))
    assert back.to_dataframe().shape == res.to_dataframe().shape
    assert back.stats == res.stats and back.status == res.status


def test_check_params_and_without_result():
    sim = sf.Simulation(scene(), duration=0.1)
    base = sim.run()
    sim.check_params({"tube.diameter": 2e-3}, {"tank.volume": 2e-5})
    _same(sim.run(), base)                       # the compiled values stay in force
    with pytest.raises(ValueError, match="diameter must be > 0") as info:
        sim.check_params({"tube.diameter": 2e-3}, {"tube.diameter": -1.0})
    assert info.value.variant_index == 1
    light = pickle.dumps(sim.without_result())
    assert len(light) < len(pickle.dumps(sim)) and sim.result is not None
    _same(pickle.loads(light).run(), base)


def test_params_move_a_valves_switching_threshold_as_a_fresh_build_does():
    """A snapping valve's opening_pressure set at run time: the switches are
    located with the new threshold (its switching function is made anew with
    the kernel), the run equal to a fresh build's."""
    def valve_scene(opening=2e4):
        s = sf.System()
        s += sf.PressureSource("src", pressure=lambda t: P0 + 1e5 * t)
        s += sf.SnappingValve("valve", sf.air, opening_pressure=opening, closing_pressure=5e3,
                              closed_conductance=1e-12, length=0.05, diameter=2e-3)
        s += sf.Container("tank", sf.air, volume=1e-4)
        s.connect("src", "valve")
        s.connect("valve", "tank")
        return s
    sim = sf.Simulation(valve_scene(), duration=0.5, rtol=1e-6)
    sim.run()
    changed = sim.run(params={"valve.opening_pressure": 3e4})
    fresh = sf.Simulation(valve_scene(3e4), duration=0.5, rtol=1e-6).run()
    np.testing.assert_array_equal(changed.times, fresh.times)
    np.testing.assert_array_equal(changed.X, fresh.X)
    np.testing.assert_array_equal(changed.S, fresh.S)
