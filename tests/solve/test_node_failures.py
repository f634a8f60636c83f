"""A failure at a node's unknown (no component's equation) names the components
joined there (found by the randomized networks: a suction source through two
tubes failed at t = 0 with no component named)."""
import pytest

import softflow as sf

P0 = sf.pressure_atmospheric


def _suction(volumeflow):
    """A pump drawing water from 1 atm through two 1 m x 0.5 mm tubes in series
    (laminar: 1e-7 m^3/s takes 1.3 bar across them)."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0)
    s += sf.CircularTube("t0", sf.water, 1.0, 0.5e-3)
    s += sf.CircularTube("t1", sf.water, 1.0, 0.5e-3)
    s += sf.VolumeFlowSource("v1", volumeflow=volumeflow, fluid=sf.water)
    s.connect("src", "t0")
    s.connect("t0", "t1")
    s.connect("t1", "v1")
    return s


def test_negative_pressure_at_a_node_names_its_components():
    # the pump's node balances alone (tube t0's end held at 1 atm: 36 kPa),
    # the two tubes in series do not: Newton's start ends below zero there
    with pytest.raises(sf.SimulationError, match=r"components at that node: 't1', 'v1'") as info:
        sf.Simulation(_suction(-1e-7), duration=0.1).run()
    # the culprit first (softflow.solve.culprit, issue 41): the pump, whose
    # node and the junction behind it no pressure balances together
    assert info.value.component == "v1" and info.value.time == 0.0
    assert ("VolumeFlowSource 'v1' draws 9.982e-05 kg/s from node(t1.b, v1.a), a node "
            "without volume (as is node(t0.b, t1.a) behind it)") in str(info.value)


def test_a_pump_drawing_more_than_its_node_can_supply_names_it_and_the_node():
    # 100 times that: not even the pump's node alone balances at any pressure
    # down to 1 Pa (softflow.solve.sourcenodes): refused, naming both
    with pytest.raises(sf.SimulationError, match=r"VolumeFlowSource 'v1' draws more from "
                       r"node\(t1.b, v1.a\), a node without volume") as info:
        sf.Simulation(_suction(-1e-5), duration=0.1).run()
    assert info.value.component == "v1" and info.value.time == 0.0


def _tube_then_orifice(length):
    """1.5 bar air through a 5 mm tube, a node without volume, a 1 mm Cd
    orifice into 1 mL (a well-posed network the randomized generator drew)."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.5, "bar"))
    s += sf.CircularTube("tube", sf.air, length, 5e-3)
    s += sf.Orifice("ori", sf.air, diameter=1e-3, Cd=0.6)
    s += sf.Container("tank", sf.air, 1e-6)
    s.connect("src", "tube")
    s.connect(("tube", "b"), ("ori", "a"))
    s.connect(("ori", "b"), ("tank", "a"))
    return s


@pytest.mark.parametrize("thermal", ["adiabatic", "isothermal"])
@pytest.mark.parametrize("length", [4.3e-3, 0.3])
def test_a_gas_law_in_p_squared_starts_at_its_physical_root(thermal, length):
    # the tube's law is in p^2 (p1^2 - p2^2 = ...: zero flow at p2 = -p1 too):
    # Newton's damped stage at t = 0 converged on the junction at -1.5 bar
    # (adiabatic, 0.3 m), which was refused as a pressure <= 0; a stage held
    # to positive pressures finds the physical root
    res = sf.Simulation(_tube_then_orifice(length), duration=0.01, thermal=thermal).run()
    assert res.status == "success"
    junction = res.get("tube", "pressure_b")
    p_tank = res.get("tank", "pressure")
    assert p_tank[0] == pytest.approx(P0, rel=1e-9)
    assert p_tank[-1] == pytest.approx(1.5e5, rel=1e-6)       # filled to the source
    assert junction.min() > 0.9 * P0


def _dead_end(valve, pressure):
    """A 10 mL container of air at ``pressure`` (absolute) and a two-port to a
    dead end (its terminal b joined to nothing)."""
    s = sf.System()
    s += sf.Container("tank", sf.air, 1e-5, initial_pressure=pressure)
    s += valve
    s.connect(("tank", "a"), ("v", "a"))
    return s


def _valve(kind):
    if kind == "check valve":
        return sf.CheckValve("v", sf.air, diameter=1e-3, leakage=1e-14)
    return sf.Orifice("v", sf.air, diameter=1e-3, Cd=0.6)


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
@pytest.mark.parametrize("kind, pressure", [
    ("check valve", 2.5e5), ("check valve", 5e5),
    ("orifice", 2.5e5), ("orifice", 5e5)])
def test_a_gas_restriction_before_a_dead_end_starts_at_its_upstream_pressure(
        kind, pressure, thermal):
    # the dead end starts at 1 atm, below the critical pressure ratio (0.528)
    # of the upstream pressure: the nozzle is choked there and its flow does
    # not depend on the dead end's pressure (a zero column of the Jacobian:
    # the Cd orifice's start stopped on a singular Jacobian at 5 bar, and at
    # 2.5 bar, where the column is exactly 0, Simulation() refused it as
    # undetermined). The structural check and the consistent start are
    # tried again from the dead end at the tank's pressure, the physical
    # answer (no flow)
    res = sf.Simulation(_dead_end(_valve(kind), pressure), duration=0.01,
                        allow_unconnected=True, thermal=thermal).run()
    assert res.status == "success"
    dead_end = res.get("v", "pressure_b")
    assert dead_end[0] == pytest.approx(pressure, rel=1e-6)
    assert dead_end[-1] == pytest.approx(pressure, rel=1e-6)
    assert res.get("tank", "pressure")[-1] == pytest.approx(pressure, rel=1e-6)


def test_a_chain_of_dead_ends_behind_choked_orifices_starts_at_rest():
    # a node without volume between two orifices and a check valve, each of
    # those two to a dead end: the tree of dead ends hangs from the tank
    s = sf.System()
    s += sf.Container("tank", sf.air, 1e-5, initial_pressure=5e5)
    s += sf.Orifice("o1", sf.air, diameter=1e-3, Cd=0.6)
    s += sf.Orifice("o2", sf.air, diameter=1e-3, Cd=0.6)
    s += sf.CheckValve("o3", sf.air, 1e-3, leakage=1e-14)
    s.connect(("tank", "a"), ("o1", "a"))
    s.connect(("o1", "b"), ("o2", "a"), ("o3", "a"))
    res = sf.Simulation(s, duration=0.01, allow_unconnected=True).run()
    assert res.status == "success"
    for label in ("o1", "o2", "o3"):
        assert res.get(label, "pressure_b")[0] == pytest.approx(5e5, rel=1e-6)


@pytest.mark.parametrize("compiled", [True, False], ids=["loop", "python"])
@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_an_orifice_into_a_dead_end_runs_without_crawling(compiled, thermal, monkeypatch):
    # nothing flows: the dead end's pressure is the tank's. The chord's
    # updates flipped +-2 Pa about it on the nozzle's square root (its linear
    # band ~0.03 Pa) and were called diverging: the steps shrank to ~6 ns,
    # 16 144 of them by t = 0.1 ms. Half of a flipping update is taken
    # (settings.FLIP_MATCH): the run's 0.1 s in a few dozen steps
    from softflow.solve import settings
    monkeypatch.setattr(settings, "COMPILED_STEPS", compiled)
    s = sf.System()
    s += sf.Container("tank", sf.air, volume=1e-4, initial_pressure=1.5e5)
    s += sf.Orifice("o", sf.air, diameter=1e-3, Cd=0.6)
    s.connect("tank", ("o", "a"))
    res = sf.Simulation(s, duration=0.1, allow_unconnected=True, thermal=thermal,
                        max_steps=200).run()
    assert res.status == "success"
    assert res.stats["steps"] < 50
    # the dead end's pressure within Newton's tolerance (rtol of its gauge
    # pressure), no flow: the tank's pressure stays
    assert res.get("o", "pressure", "b") == pytest.approx(1.5e5, abs=1e-3 * (1.5e5 - P0))
    assert abs(res.get("o", "massflow", "a")).max() < 1e-12
    assert res.get("tank", "pressure") == pytest.approx(1.5e5, rel=1e-9)
