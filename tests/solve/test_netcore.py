"""The network residual in one compiled call (softflow.solve.netcore,
softflow.laws.network): where it serves, its F and Jacobian entries are the
per-group path's to round-off (at random states, steps and times, every
covered class), whole runs agree, a new parameter value reaches it, and
networks with a group it does not cover keep the per-group path."""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow.curves.waveforms import Ramp, Sine

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "thermal"))
from network_scenes import SCENES as THERMAL_SCENES  # noqa: E402
from scenes import chain  # noqa: E402

P0 = sf.pressure_atmospheric


def _mixed(fluid):
    """Every covered class once at least: a pressure source on a waveform
    (gauge), tubes of two correlations and with minor losses, a rigid
    container, a linear accumulator, mass and volume flow sources."""
    s = sf.System()
    s += sf.PressureSource("ps", pressure=Sine(0.02, 2e4, 1e4), gauge=True)
    s += sf.CircularTube("t1", fluid, 0.3, 1e-3)
    s += sf.CircularTube("t2", fluid, 0.2, 2e-3, friction="Colebrook", K=0.8)
    s += sf.CircularTube("t3", fluid, 0.5, 1.5e-3)
    s += sf.Container("c", fluid, 2e-5, initial_pressure=P0 + 5e3)
    s += sf.LinearAccumulator("acc", fluid, 1e-5, 1e-10)
    s += sf.MassFlowSource("ms", massflow=Ramp(0.0, 0.05, 0.0, 2e-6))
    s += sf.VolumeFlowSource("vs", volumeflow=-1e-7, fluid=fluid)
    s.connect(("t1", "a"), ("ps", "a"))
    s.connect(("t1", "b"), ("c", "a"))
    s.connect(("t2", "a"), ("c", "a"))
    s.connect(("t2", "b"), ("acc", "a"))
    s.connect(("ms", "a"), ("acc", "a"))
    s.connect(("t3", "a"), ("c", "a"))
    s.connect(("t3", "b"), ("vs", "a"))
    return s


def _valves(fluid):
    """Orifices of each law the fluid takes and check valves (both
    directions: one opens, one stays shut) between tanks."""
    gas = fluid.compressible
    s = sf.System()
    s += sf.PressureSource("ps", pressure=P0 + 3e4)
    s += sf.Orifice("oK", fluid, diameter=1e-3, K=1.5)
    s += sf.Orifice("oCd", fluid, diameter=0.8e-3, Cd=0.62)
    s += sf.CheckValve("cv1", fluid, diameter=1e-3)
    s += sf.CheckValve("cv2", fluid, diameter=1e-3, cracking_pressure=500.0)
    vol = (lambda n: sf.Container(n, fluid, 2e-5)) if gas else (
        lambda n: sf.LinearAccumulator(n, fluid, 1e-6, 1e-11))
    s += vol("v1")
    s += vol("v2")
    s.connect(("oK", "a"), ("ps", "a"))
    s.connect(("oK", "b"), ("v1", "a"))
    s.connect(("oCd", "a"), ("v1", "a"))
    s.connect(("oCd", "b"), ("v2", "a"))
    s.connect(("cv1", "a"), ("v1", "a"))
    s.connect(("cv1", "b"), ("v2", "a"))
    s.connect(("cv2", "a"), ("v2", "a"))
    s.connect(("cv2", "b"), ("v1", "a"))
    # a Tesla valve, snapping valves open and shut, an inertial tube
    s += sf.TeslaValve("tv", fluid, 0.02, 1e-3, diodicity=3.0)
    s += sf.SnappingValve("sv1", fluid, opening_pressure=2e3, closing_pressure=500.0,
                          closed_conductance=1e-12, length=0.01, diameter=1e-3,
                          initially_open=True)
    s += sf.SnappingValve("sv2", fluid, opening_pressure=2e3, closing_pressure=500.0,
                          closed_conductance=1e-12, length=0.01, diameter=1e-3)
    s += sf.CircularTube("ti", fluid, 0.2, 1.5e-3, inertance=True)
    s.connect(("tv", "a"), ("ps", "a"))
    s.connect(("tv", "b"), ("v1", "a"))
    s.connect(("sv1", "a"), ("ps", "a"))
    s.connect(("sv1", "b"), ("v2", "a"))
    s.connect(("sv2", "a"), ("v1", "a"))
    s.connect(("sv2", "b"), ("v2", "a"))
    s.connect(("ti", "a"), ("ps", "a"))
    s.connect(("ti", "b"), ("v2", "a"))
    if gas:
        s += sf.Orifice("oIso", fluid, C=sf.Q_(0.2, "L/(s*bar)"), b=0.3)
        s.connect(("oIso", "a"), ("ps", "a"))
        s.connect(("oIso", "b"), ("v2", "a"))
    return s


def _actuators(fluid):
    """Actuators on a PV curve (one scaled) and a hysteretic actuator, the
    paper's curves, filled through tubes by a pressure source."""
    from softflow.paper_scenes import curve_peak_valley, loop_hysteretic
    s = sf.System()
    s += sf.PressureSource("ps", pressure=P0 + 2.5e4)
    s += sf.Actuator("a1", fluid, curve_peak_valley())
    s += sf.Actuator("a2", fluid, curve_peak_valley(), pressure_scale=1.2)
    s += sf.HystereticActuator("h", fluid, *loop_hysteretic(), initial_volume=2e-6)
    for k, end in enumerate(("a1", "a2", "h")):
        s += sf.CircularTube(f"t{k}", fluid, 0.3, 1e-3)
        s.connect((f"t{k}", "a"), ("ps", "a"))
        s.connect((f"t{k}", "b"), (end, "a"))
    return s


SCENES = {
    "air chain 8": lambda: chain(8),
    # fonsim's gas law (softflow.fons's tubes)
    "air chain 8 mean-density": lambda: chain(8, compressible="mean_density"),
    "water chain 3": lambda: chain(3, fluid=sf.water, p_source=P0 + 2e3),
    "air mixed": lambda: _mixed(sf.air),
    "water mixed": lambda: _mixed(sf.water),
    "air valves": lambda: _valves(sf.air),
    "water valves": lambda: _valves(sf.water),
    "air actuators": lambda: _actuators(sf.air),
    "water actuators": lambda: _actuators(sf.water),
}


def _sim(name, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        if name in THERMAL_SCENES:      # tests/thermal/network_scenes.py
            build, options, duration = THERMAL_SCENES[name]
            return sf.Simulation(build(), duration=duration, **options, **kw)
        return sf.Simulation(SCENES[name](), duration=0.05, **kw)


@pytest.mark.parametrize("name", list(SCENES) + list(THERMAL_SCENES))
def test_the_compiled_residual_is_the_per_group_one(name):
    """Thermal scenes too: every thermal class of an ideal gas, h·A of the
    heat-transfer correlations set at each state as a step's start sets it."""
    sim = _sim(name)
    asm = sim.asm
    assert asm.residual is not asm.python_residual
    rng = np.random.default_rng(7)
    x0, S0 = asm.x0, asm.S0
    for k in range(20):
        x = x0 * (1.0 + 0.05 * rng.standard_normal(asm.n)) + 1e-6 * rng.standard_normal(asm.n)
        S = S0 * (1.0 + 0.05 * rng.standard_normal(S0.size))
        t, dt = float(rng.uniform(0, 0.05)), float(10.0 ** rng.uniform(-6, -2))
        if asm.has_begin_step:
            asm.begin_step(x, S)
        for jac in (False, True):
            asm.raw[:] = np.nan
            F1 = asm.residual(x, S, t, dt, jac)
            raw1 = asm.raw.copy()
            asm.raw[:] = np.nan
            F2 = asm.python_residual(x, S, t, dt, jac)
            raw2 = asm.raw.copy()
            # the node rows sum in another order: round-off of their terms
            scale = np.abs(x).max(initial=1.0) * 1e-14 + 1e-14 * np.abs(F2).max()
            np.testing.assert_allclose(F1, F2, rtol=1e-13, atol=scale)
            if jac:
                np.testing.assert_allclose(raw1, raw2, rtol=1e-13, atol=0.0)


@pytest.mark.parametrize("name", list(SCENES) + list(THERMAL_SCENES))
@pytest.mark.parametrize("step", [None, 1e-3])
def test_whole_runs_agree_with_the_per_group_path(name, step):
    """Fixed steps to 1e-10 relative, adaptive within the run's tolerance
    (thermal scenes: pressures and temperatures, a fixed step of 1/50 of the
    run)."""
    thermal = name in THERMAL_SCENES
    if thermal and step is not None:
        step = THERMAL_SCENES[name][2] / 50
    kw = {} if step is None else {"step": step}
    ours, theirs = _sim(name, **kw), _sim(name, **kw)
    theirs.asm.residual = theirs.asm.python_residual
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        a, b = ours.run(), theirs.run()
    assert a.success and b.success
    compared = 0
    labels = (("c", "cont2", "cont7", "acc", "v1", "v2", "a1", "a2", "a3", "h", "hh", "held",
               "act1", "act2", "accumulator") if thermal else
              ("c", "cont2", "acc", "v1", "v2", "a1", "a2", "h"))
    for label in labels:
        for quantity in ("pressure", "temperature") if thermal else ("pressure",):
            try:
                pa, pb = a.get(label, quantity), b.get(label, quantity)
            except KeyError:
                continue
            compared += 1
            if step is not None:
                np.testing.assert_allclose(pa, pb, rtol=1e-10)
            else:
                assert abs(pa[-1] - pb[-1]) <= 1e-3 * abs(pb[-1])
    assert compared


def test_a_parameter_run_reaches_the_compiled_residual():
    """run(params=...) rebuilds the groups' numbers: the compiled residual
    follows (a wider first tube fills the last tank faster), and a later run
    without params is the first again."""
    sim = _sim("air chain 8", step=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        base = sim.run().get("cont7", "pressure")[-1]
        wide = sim.run(params={"tube0.diameter": 3e-3}).get("cont7", "pressure")[-1]
        again = sim.run().get("cont7", "pressure")[-1]
        check = _sim("air chain 8", step=1e-3)
        check.asm.residual = check.asm.python_residual
        ref = check.run(params={"tube0.diameter": 3e-3}).get("cont7", "pressure")[-1]
    assert wide > base
    assert wide == pytest.approx(ref, rel=1e-10)
    assert again == base
    assert sim.asm.residual is not sim.asm.python_residual


def _with(extra, two_port=False):
    """chain(2) with ``extra`` at its last tank (and a tank behind it)."""
    s = chain(2)
    s += extra
    if two_port:
        s.connect(("cont1", "a"), (extra.label, "a"))
    else:           # a volume: behind a tube of its own
        s += sf.CircularTube("tx", extra.fluid, 0.1, 1e-3)
        s.connect(("cont1", "a"), ("tx", "a"))
        s.connect(("tx", "b"), (extra.label, "a"))
    if two_port:
        s += sf.Container("end", extra.fluid, 1e-5)
        s.connect((extra.label, "b"), ("end", "a"))
    return s


@pytest.mark.parametrize("make, kw", [
    (lambda: _with(sf.CheckValve("cv", sf.Fluid("air", level="table"), diameter=1e-3),
                   two_port=True), {}),
    (lambda: chain(2, fluid=sf.Fluid("air", level="table")), {}),
    (lambda: chain(2, fluid=sf.Fluid("air", level="table")), {"thermal": "adiabatic"}),
    (lambda: chain(2, compressible="mean_density"), {"thermal": "adiabatic"}),
])
def test_a_network_with_an_uncovered_group_keeps_the_per_group_path(make, kw):
    """A real fluid (isothermal or thermal), the mean-density law (isothermal
    or thermal): not (yet) in the compiled loop, so the whole network keeps
    the per-group path (a user component is called back from it:
    tests/solve/test_usercall.py)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(make(), duration=0.01, **kw)
    assert sim.asm.residual is sim.asm.python_residual


def test_a_thermal_parameter_run_reaches_the_compiled_residual():
    """run(params=...) in a thermal scene: the tubes' and the volumes' new
    numbers (a wider first tube, a container's h·A) reach the compiled loop,
    as the per-group path has them."""
    def build():
        s = chain(4)
        for c in s.components:
            if isinstance(c, sf.Container):
                c.hA = 0.01
        return s

    params = {"tube0.diameter": 3e-3, "cont1.hA": 0.05}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        ours = sf.Simulation(build(), duration=0.05, step=1e-3, thermal="heat_transfer")
        theirs = sf.Simulation(build(), duration=0.05, step=1e-3, thermal="heat_transfer")
        theirs.asm.residual = theirs.asm.python_residual
        base = ours.run().get("cont3", "temperature")[-1]
        a = ours.run(params=params)
        b = theirs.run(params=params)
    assert ours.asm.residual is not ours.asm.python_residual
    for q in ("pressure", "temperature"):
        np.testing.assert_allclose(a.get("cont3", q), b.get("cont3", q), rtol=1e-10)
    assert a.get("cont3", "temperature")[-1] != base


@pytest.mark.parametrize("fluid, thermal", [("water", None), ("air", "adiabatic")])
def test_a_volume_a_curve_refuses_raises_the_curves_error(fluid, thermal):
    """An actuator whose curve does not extrapolate (extrapolate='error'),
    driven past its data, isothermal (water) and in an adiabatic scene (air):
    the compiled loop hands that evaluation to the per-group path, which
    raises the curve's own error, the same as without the compiled loop."""
    fl = getattr(sf, fluid)

    def build():
        s = sf.System()
        s += sf.PressureSource("ps", pressure=P0 + 2e5)
        s += sf.CircularTube("t", fl, 0.3, 1e-3)
        curve = sf.PVCurve(volume=[1e-6, 2e-6, 3e-6], pressure=[P0, P0 + 2e4, P0 + 3e4],
                           extrapolate="error")
        s += sf.Actuator("act", fl, curve, initial_volume=1.5e-6)
        s.connect("t", "ps")
        s.connect("t", "act")
        return s

    kw = {} if thermal is None else {"thermal": thermal}
    messages = []
    for compiled in (True, False):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            sim = sf.Simulation(build(), duration=0.5, **kw)
            assert sim.asm.residual is not sim.asm.python_residual
            if not compiled:
                sim.asm.residual = sim.asm.python_residual
            res = sim.run(raise_on_failure=False)
        assert not res.success
        messages.append(res.message)
    assert "act" in messages[0] and messages[0] == messages[1]
