"""Violations found by the randomized networks (tests/test_random_networks.py, issue
17), each kept as a plain regression case: the smallest network found that shows
it. Each was marked xfail(strict=True) until the library was fixed (all three are), so that the fix
turns it into a passing test (and the marker must then go)."""
import warnings

import pytest

import softflow as sf
from softflow import paper_scenes as ps

TABLE_AIR = sf.air.with_level("table")


def _run(system, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return sf.Simulation(system, **options).run()


def _assert_named(err, labels):
    """A SimulationError that names a component (e.component) and a time, with no
    foreign exception as its cause."""
    assert err.time is not None
    assert err.component in labels, (err.component, str(err))
    assert err.__cause__ is None, repr(err.__cause__)


def test_validity_check_outside_the_table_range_does_not_escape_run():
    # source 0.45 bar < the air table's 0.5 bar: the tube's law (density at its mean
    # pressure, inside the table) solves; the check at its 0.45 bar end raises
    s = sf.System()
    s += sf.PressureSource("src", pressure=0.45e5)
    s += sf.CircularTube("tube", TABLE_AIR, length=1.0, diameter=1e-3)
    s += sf.Container("tank", TABLE_AIR, volume=1e-5)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    try:
        res = _run(s, duration=0.01, step=1e-3)
    except sf.SimulationError as err:         # failing is fine, if it says where
        _assert_named(err, {"src", "tube", "tank"})
    else:
        assert res.status == "success"


def test_adiabatic_actuator_below_the_table_temperature_names_the_actuator():
    # 1.5 bar of table air expanding into a 0.6 bar source through a short tube:
    # the gas cools below 233.15 K, the table's lowest temperature, at t ~ 0.07 s
    s = sf.System()
    s += sf.PressureSource("src", pressure=0.6e5)
    s += sf.CircularTube("tube", TABLE_AIR, length=0.1, diameter=2e-3)
    s += sf.Actuator("act", TABLE_AIR, ps.curve_monotonic(), initial_pressure=1.5e5)
    s.connect("tube", "src")
    s.connect("tube", "act")
    with pytest.raises(sf.SimulationError) as info:
        _run(s, duration=0.1, step=1e-3, thermal="adiabatic")
    _assert_named(info.value, {"src", "tube", "act"})


def test_pump_against_a_check_valve_names_the_culprit():
    # a volume-flow pump draws air through a check valve that only lets air towards
    # the source: no flow can reach it (a named failure is right). Without the tube
    # and tank the failure names the pump's node; with them it names nothing.
    s = sf.System()
    s += sf.PressureSource("src", 176722.2, gauge=True)
    s += sf.VolumeFlowSource("pump", -7.56e-6, sf.air)
    s += sf.CheckValve("valve", sf.air, 2e-4, opening_band=247.0)
    s += sf.CircularTube("tube", sf.air, length=0.176, diameter=2.28e-3)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect(("valve", "b"), "src")
    s.connect(("valve", "a"), "pump")
    s.connect(("tube", "a"), "src")
    s.connect(("tube", "b"), "tank")
    with pytest.raises(sf.SimulationError) as info:
        _run(s, duration=0.02, step=1e-3)
    err = info.value
    assert err.time == 0.0
    assert err.component is not None or "pump" in str(err) or "valve" in str(err), str(err)
