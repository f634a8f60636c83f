"""Thermal scenes of an ideal gas (air) that use every class the compiled
network residual covers in thermal scenes (softflow.solve.netcore), for the
tests that compare it with the per-group path and with results stored from
the NumPy kernels (tests/thermal/test_thermal_reference.py)."""
from __future__ import annotations

import sys
from pathlib import Path

import softflow as sf
from softflow.curves.waveforms import Ramp, Sine

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scenes import chain  # noqa: E402

P0 = sf.pressure_atmospheric


def _tubed(s, source, end, k, fluid, **kw):
    """A tube from ``source`` to ``end`` (labels), the k-th."""
    s += sf.CircularTube(f"t{k}", fluid, kw.pop("length", 0.3), kw.pop("diameter", 1e-3), **kw)
    s.connect((f"t{k}", "a"), (source, "a"))
    s.connect((f"t{k}", "b"), (end, "a"))


def mixed(fluid=sf.air):
    """A pressure source on a waveform (gauge, its own temperature), tubes of
    two correlations, with minor losses and with inertance, containers with a constant hA,
    adiabatic and held at their wall temperature, a linear accumulator with a
    free-convection wall (h·A set each step), mass and volume flow sources
    (delivering and drawing)."""
    s = sf.System()
    s += sf.PressureSource("ps", pressure=Sine(0.02, 2e4, 1e4), gauge=True, temperature=310.0)
    s += sf.Container("c", fluid, 2e-5, initial_pressure=P0 + 5e3, hA=0.05,
                      initial_temperature=300.0, wall_temperature=290.0)
    s += sf.Container("cad", fluid, 1e-5, thermal="adiabatic")
    s += sf.Container("held", fluid, 1e-5, thermal="isothermal", wall_temperature=285.0)
    s += sf.LinearAccumulator("acc", fluid, 1e-5, 1e-10,
                              heat_transfer_coefficient=sf.FreeConvection("sphere"),
                              area=4e-3)
    s += sf.MassFlowSource("ms", massflow=Ramp(0.0, 0.05, 0.0, 2e-6), temperature=330.0)
    s += sf.VolumeFlowSource("vs", volumeflow=-1e-7, fluid=fluid)
    s += sf.VolumeFlowSource("vs2", volumeflow=Ramp(0.0, 0.05, 0.0, 1e-7), fluid=fluid,
                             temperature=300.0)
    _tubed(s, "ps", "c", 1, fluid)
    _tubed(s, "c", "acc", 2, fluid, length=0.2, diameter=2e-3, friction="Colebrook", K=0.8)
    _tubed(s, "c", "cad", 3, fluid, length=0.5, diameter=1.5e-3)
    _tubed(s, "cad", "held", 4, fluid)
    _tubed(s, "ps", "held", 5, fluid, length=0.2, diameter=1.5e-3, inertance=True)
    s.connect(("ms", "a"), ("acc", "a"))
    s.connect(("vs", "a"), ("cad", "a"))
    s.connect(("vs2", "a"), ("held", "a"))
    return s


def actuators(fluid=sf.air):
    """Actuators on a PV curve (one scaled, one held at its wall temperature,
    one with a constant hA), hysteretic actuators (free and held) and a linear
    accumulator held at its wall's, filled through tubes and a Tesla valve by
    a pressure source."""
    from softflow.paper_scenes import curve_peak_valley, loop_hysteretic
    s = sf.System()
    s += sf.PressureSource("ps", pressure=P0 + 2.5e4)
    s += sf.Actuator("a1", fluid, curve_peak_valley())
    s += sf.Actuator("a2", fluid, curve_peak_valley(), pressure_scale=1.2, hA=0.02)
    s += sf.Actuator("a3", fluid, curve_peak_valley(), thermal="isothermal")
    s += sf.LinearAccumulator("acc", fluid, 1e-5, 1e-10, thermal="isothermal")
    s += sf.HystereticActuator("h", fluid, *loop_hysteretic(), initial_volume=2e-6)
    s += sf.HystereticActuator("hh", fluid, *loop_hysteretic(), initial_volume=2e-6,
                               thermal="isothermal")
    for k, end in enumerate(("a1", "a2", "a3", "h", "hh")):
        _tubed(s, "ps", end, k, fluid)
    s += sf.TeslaValve("tv", fluid, 0.02, 1e-3, diodicity=3.0)
    s.connect(("tv", "a"), ("a1", "a"))
    s.connect(("tv", "b"), ("acc", "a"))
    return s


def valves(fluid=sf.air):
    """Orifices of each law (loss coefficient, nozzle, ISO 6358), check valves
    (one opens, one stays shut) and snapping valves (open and shut) between
    containers, a pressure source filling them."""
    s = sf.System()
    s += sf.PressureSource("ps", pressure=P0 + 3e4)
    s += sf.Orifice("oK", fluid, diameter=1e-3, K=1.5)
    s += sf.Orifice("oCd", fluid, diameter=0.8e-3, Cd=0.62)
    s += sf.Orifice("oIso", fluid, C=sf.Q_(0.2, "L/(s*bar)"), b=0.3)
    s += sf.CheckValve("cv1", fluid, diameter=1e-3)
    s += sf.CheckValve("cv2", fluid, diameter=1e-3, cracking_pressure=500.0)
    s += sf.Container("v1", fluid, 2e-5, thermal="adiabatic")
    s += sf.Container("v2", fluid, 2e-5, hA=0.01)
    s += sf.SnappingValve("sv1", fluid, opening_pressure=2e3, closing_pressure=500.0,
                          closed_conductance=1e-12, length=0.01, diameter=1e-3,
                          initially_open=True)
    s += sf.SnappingValve("sv2", fluid, opening_pressure=2e3, closing_pressure=500.0,
                          closed_conductance=1e-12, length=0.01, diameter=1e-3)
    for label, a, b in (("oK", "ps", "v1"), ("oCd", "v1", "v2"), ("oIso", "ps", "v2"),
                        ("cv1", "v1", "v2"), ("cv2", "v2", "v1"), ("sv1", "ps", "v2"),
                        ("sv2", "v1", "v2")):
        s.connect((label, "a"), (a, "a"))
        s.connect((label, "b"), (b, "a"))
    return s


def fig5_air():
    """The paper's Fig. 5 with air, its walls exchanging heat by free convection."""
    from softflow.paper_scenes import fig5
    return fig5(sf.air, physics="full")


#: name: (build, Simulation keywords, duration [s])
SCENES = {
    "air chain 8 adiabatic": (lambda: chain(8), {"thermal": "adiabatic"}, 0.05),
    "air mixed heat transfer": (mixed, {"thermal": "heat_transfer"}, 0.05),
    "air actuators adiabatic": (actuators, {"thermal": "adiabatic"}, 0.05),
    "air valves heat transfer": (valves, {"thermal": "heat_transfer"}, 0.05),
    "fig5 air heat transfer": (fig5_air, {"thermal": "heat_transfer"}, 2.0),
}
