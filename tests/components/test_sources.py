"""Sources with constants, callables and waveforms: units, gauge pressure,
evaluation once per time, and simulations landing on waveform breakpoints."""
import numpy as np
import pytest

import softflow as sf
from softflow.curves.waveforms import PiecewiseConstant, Ramp, Sine, Square, Step
from softflow.units import UnitError

P0 = sf.pressure_atmospheric
Q_ = sf.Q_


def _values(cls, sources, t):
    return cls.make_params(sources).values(t)


def test_waveform_values_reach_the_kernel_in_si():
    srcs = [sf.PressureSource("a", pressure=Step(0.1, Q_(1, "atm"), Q_(1.5, "bar"))),
            sf.PressureSource("b", pressure=Q_(2, "bar")),
            sf.PressureSource("c", pressure=lambda t: Q_(1 + t, "bar"))]
    P = sf.PressureSource.make_params(srcs)
    np.testing.assert_allclose(P.values(0.0), [P0, 2e5, 1e5])
    np.testing.assert_allclose(P.values(0.5), [1.5e5, 2e5, 1.5e5])
    V = np.array([[1.6e5, 0.0], [2e5, 0.0], [1.5e5, 0.0]])
    F, _ = sf.PressureSource.kernel(P, V, np.zeros((3, 0)), 0.5, 1e-3, False)
    np.testing.assert_allclose(F[:, 0], [1e4, 0.0, 0.0], atol=1e-9)


def test_flow_sources_convert_waveform_units():
    q = sf.VolumeFlowSource("q", volumeflow=Ramp(0, 1, Q_(0, "mL/s"), Q_(2, "L/min")),
                            fluid=sf.water)
    assert _values(sf.VolumeFlowSource, [q], 1.0)[0] == pytest.approx(2e-3 / 60)
    m = sf.MassFlowSource("m", massflow=Sine(Q_(5, "g/s"), 1.0, offset=Q_(1, "kg/min")))
    assert _values(sf.MassFlowSource, [m], 0.25)[0] == pytest.approx(5e-3 + 1 / 60)


def test_plain_number_waveforms_are_si_of_the_source():
    s = sf.PressureSource("s", pressure=Step(0.5, 2e5, 3e5))
    assert _values(sf.PressureSource, [s], 1.0)[0] == 3e5


@pytest.mark.parametrize("make, match", [
    (lambda: sf.PressureSource("s", pressure=Step(0.1, Q_(1, "mL/s"), Q_(2, "mL/s"))),
     r"PressureSource 's': pressure expects a pressure \[Pa\], got a Step in"),
    (lambda: sf.VolumeFlowSource("q", volumeflow=Step(0.1, Q_(0, "g/s"), Q_(1, "g/s")),
                                 fluid=sf.water),
     r"VolumeFlowSource 'q': volumeflow expects a volume flow"),
    (lambda: sf.MassFlowSource("m", massflow=lambda t: Q_(1, "bar")),
     r"MassFlowSource 'm': massflow\(t=0\) expects a mass flow"),
])
def test_wrong_dimension_is_a_unit_error_naming_source_and_parameter(make, match):
    with pytest.raises(UnitError, match=match):
        make()


def test_gauge_pressure_is_explicit():
    absolute = sf.PressureSource("abs", pressure=Q_(1.3, "bar"))
    gauge = sf.PressureSource("g", pressure=Q_(0.3, "bar"), gauge=True)
    wave = sf.PressureSource("w", pressure=Step(0.1, 0.0, Q_(0.3, "bar")), gauge=True)
    v = _values(sf.PressureSource, [absolute, gauge, wave], 1.0)
    np.testing.assert_allclose(v, [1.3e5, P0 + 0.3e5, P0 + 0.3e5])
    assert _values(sf.PressureSource, [wave], 0.0)[0] == P0
    # a gauge value given as absolute is caught where it is nonsense (<= 0 Pa)
    with pytest.raises(ValueError, match=r"PressureSource 'x': pressure must be > 0 Pa "
                                         r"absolute.*gauge=True"):
        sf.PressureSource("x", pressure=Step(0.1, 0.0, Q_(0.3, "bar")))
    with pytest.raises(TypeError, match="gauge must be True or False"):
        sf.PressureSource("y", pressure=2e5, gauge="yes")


def test_signals_evaluated_once_per_distinct_time_and_shared_waveform_once():
    calls = []

    def f(t):
        calls.append(t)
        return 1e-6

    shared = Square(0.0, 1e-6, frequency=1.0)
    counted = []
    orig = shared._scalar

    def counting(t):
        counted.append(t)
        return orig(t)

    shared._scalar = counting
    srcs = [sf.VolumeFlowSource(f"q{i}", volumeflow=shared, fluid=sf.water) for i in range(50)]
    srcs.append(sf.VolumeFlowSource("f", volumeflow=f, fluid=sf.water))
    srcs.append(sf.VolumeFlowSource("c", volumeflow=2e-6, fluid=sf.water))
    P = sf.VolumeFlowSource.make_params(srcs)
    calls.clear()
    counted.clear()
    for t in (0.1, 0.1, 0.1, 0.7, 0.7):
        v = P.values(t)
    assert calls == [0.1, 0.7] and counted == [0.1, 0.7]
    assert v[0] == 0.0 and v[-2] == 1e-6 and v[-1] == 2e-6


def pump_scene(volumeflow):
    """The paper's Figs. 3-5 input into a linear accumulator through a tube."""
    s = sf.System()
    s += sf.VolumeFlowSource("pump", volumeflow=volumeflow, fluid=sf.water)
    s += sf.CircularTube("tube", sf.water, length=0.1, diameter=2e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=50e-6, compliance=Q_(10, "mL/bar"))
    s.connect("pump", "tube")
    s.connect("tube", "acc")
    return s


def test_paper_pump_in_pause_out_lands_on_breakpoints():
    pump = PiecewiseConstant(Q_([0, 10, 15], "s"), Q_([1.8, 0, -1.8], "mL/s"))
    res = sf.Simulation(pump_scene(pump), duration=25.0).run()   # adaptive
    times = res.times.tolist()
    assert 10.0 in times and 15.0 in times
    v = res.get("acc", "volume")
    i10, i15 = times.index(10.0), times.index(15.0)
    # 1.8 mL/s for 10 s in, nothing during the pause, all of it out again
    assert v[i10] - v[0] == pytest.approx(18e-6, rel=1e-9)
    assert v[i15] - v[0] == pytest.approx(18e-6, rel=1e-9)
    assert abs(v[-1] - v[0]) < 1e-12
    # the step ending on t = 10 s still pumps, the next one does not
    q = -res.get("pump", "mf") / sf.water.rho
    assert q[i10] == pytest.approx(1.8e-6) and q[i10 + 1] == pytest.approx(0.0, abs=1e-15)
    assert res.stats["steps"] < 400


def test_periodic_waveform_breakpoints_within_the_run_are_all_hit():
    wave = Square(Q_(-1, "mL/s"), Q_(1, "mL/s"), frequency=Q_(2, "Hz"), duty=0.3, start=0.05)
    scene = pump_scene(wave)
    expected = [b for k in range(4) for b in (0.05 + 0.5 * k, 0.2 + 0.5 * k)]
    np.testing.assert_allclose(scene.get("pump").breakpoints_until(2.0), expected)
    res = sf.Simulation(scene, duration=2.0, step_max=0.1).run()   # adaptive
    times = res.times
    hits = [int(np.argmin(np.abs(times - b))) for b in expected]
    np.testing.assert_allclose(times[hits], expected, rtol=0, atol=1e-12)
    # the flow is constant between breakpoints, so backward Euler landing on them
    # integrates the pumped volume exactly
    fine = np.linspace(0.0, 2.0, 2_000_001)
    q = wave(0.5 * (fine[1:] + fine[:-1]))
    pumped = np.concatenate([[0.0], np.cumsum(q * np.diff(fine))])
    v = res.get("acc", "volume")
    np.testing.assert_allclose(v[hits] - v[0], np.interp(times[hits], fine, pumped),
                               rtol=0, atol=1e-12)
    assert v[-1] - v[0] == pytest.approx(-0.8e-6, rel=1e-6)
