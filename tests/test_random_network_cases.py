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
    # found as a 0.45 bar source, below the air table's then 0.5 bar, with a tank at
    # 1 atm and the mean-density tube law (then the default; the 'pipe_flow' default
    # has no Mach check). The table now starts at 0.1 bar, so the same pressure
    # ratio (0.45) one level down: source at 0.9 x the table's lowest pressure,
    # tank at 0.2 bar. The tube's law (density at its mean pressure, inside the table)
    # solves; the Mach check at its end below the table cannot use the table
    p_lo = TABLE_AIR.p_range[0]
    p_src, p_tank = 0.9 * p_lo, 2.0 * p_lo
    s = sf.System()
    s += sf.PressureSource("src", pressure=p_src)
    s += sf.CircularTube("tube", TABLE_AIR, length=1.0, diameter=1e-3,
                         compressible="mean_density")
    s += sf.Container("tank", TABLE_AIR, volume=1e-5, initial_pressure=p_tank)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    try:
        res = _run(s, duration=0.01, step=1e-3)
    except sf.SimulationError as err:         # failing is fine, if it says where
        _assert_named(err, {"src", "tube", "tank"})
    else:
        assert res.status == "success"
        # the scene the case is about: the tube's mean pressure inside the table
        assert 0.5 * (p_src + res.get("tank", "pressure").min()) > p_lo
        # and the check found its answer (from the ideal gas below the table)
        # instead of a record that it could not be evaluated
        assert not [w for w in res.warnings if "could not be evaluated" in w.message], \
            [w.message for w in res.warnings]


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


def test_pump_into_a_node_without_volume_starts_at_its_balance():
    # randomized air networks #114-#120 (hypothesis seed 37, 200 examples): a
    # pump pushes 7.9 mL/s into a node without volume whose outlets (an ISO
    # 6358 orifice to a dead end, 0.48 m of 0.32 mm tube, a 0.2 mm check
    # valve with leakage) pass it at 23 bar; Newton's start from 1 atm
    # settled on a root at -0.19 bar and the run failed at t = 0. The node's
    # balance is now solved alone first (softflow.solve.sourcenodes)
    from softflow import waveforms as wf
    air = sf.air
    s = sf.System()
    s += sf.VolumeFlowSource("src0", wf.PiecewiseLinear(
        [0.0, 0.006841738765528295, 0.009109065361050118, 0.026870428586826586,
         0.04686180274982511],
        [7.892949441629093e-06, -9.73683986912505e-06, 8.06373680e-06, -1e-05, 1e-08]), air)
    s += sf.Actuator("v2", air, ps.curve_monotonic(3.00057))
    s += sf.VolumeFlowSource("src2", wf.Ramp(0.030375725362667246, 0.04074822131559955, 1e-08,
                                             -2.6525793871581894e-06), air)
    s += sf.LinearAccumulator("v3", air, volume=4.396639281710379e-05, compliance=1e-13,
                              initial_pressure=139093.25250394066)
    s += sf.VolumeFlowSource("src4", wf.Step(0.023156456770797137, 1e-08,
                                             -7.610657079123317e-06), air)
    s += sf.Orifice("e0", air, C=1.6137140187696122e-09, b=0.41281255401123507,
                    m=0.8069456109949742)
    s += sf.CircularTube("e1", air, length=0.4834596160426742, diameter=0.00031893601015331815,
                         friction="Swamee-Jain")
    s += sf.CheckValve("e2", air, 0.0002, cracking_pressure=1.9443640615657915e-200,
                       opening_band=3187.1236402892678, leakage=1e-12)
    s += sf.CircularTube("e3", air, length=0.46204034867095567, diameter=0.00026211765216227993,
                         friction="Swamee-Jain")
    s.connect(("src0", "a"), ("e0", "a"), ("e1", "b"), ("e2", "a"))
    s.connect(("v2", "a"), ("src2", "a"), ("e1", "a"), ("e3", "b"))
    s.connect(("v3", "a"), ("e2", "b"))
    s.connect(("src4", "a"), ("e3", "a"))
    res = _run(s, allow_unconnected=True, thermal="isothermal", duration=0.05, step=0.005,
               max_steps=200)
    assert res.status == "success"
    p0 = res.get("src0", "pressure")[0]
    assert 2.2e6 < p0 < 2.4e6
    assert min(res[c].min() for c in res.columns() if c.endswith("pressure")) > 0
