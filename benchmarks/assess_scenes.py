"""The scenes of sf.assess's benchmark (bench_assess.py) and tests
(tests/test_assess.py): each builder returns (system, duration [s], outputs).
They span docs/guide/choosing-a-model.md's "Choosing a model level" table: one or two axes matter in
each. (The notebook examples/validation/assess.ipynb writes its three out, to
stand alone.)

``reference_overrides(name, system)`` gives the constructor overrides of a
scene's converged reference where its finest configuration on the axes
assess decides is not the physics (a wall-less volume that fills slowly: its
gas exchanges heat with the wall by free convection, neither adiabatic nor
held isothermal).
"""
from __future__ import annotations

import math

import softflow as sf

P = sf.pressure_atmospheric


def syringe():
    """Slow syringe fill (0.5 mL/s for 10 s) of an air actuator through a thin
    tube; the actuator's wall hA = 0.5 W/K."""
    s = sf.System()
    pump = sf.waveforms.PiecewiseConstant(sf.Q_([0, 10], "s"), sf.Q_([0.5, 0], "mL/s"))
    s += sf.VolumeFlowSource("pump", volumeflow=pump, fluid=sf.air)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    curve = sf.PVCurve.monotonic((5e-6, P), (8e-6, P + 0.2e5), (20e-6, P + 0.4e5))
    s += sf.Actuator("act", sf.air, curve, initial_pressure=P, hA=0.5)
    s.connect("pump", "tube")
    s.connect("tube", "act")
    return s, 12.0, [("act", "volume")]


def fast_fill():
    """A 1 L tank filled from 4 bar through an ISO 6358 valve in ~0.5 s (no wall)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(4, "bar"))
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    return s, 1.0, [("tank", "pressure")]


def bottle(supply=18e6, initial=12e6):
    """A 1 L air bottle (wall hA 0.5 W/K) filled from 12 to 18 MPa (``initial``
    to ``supply`` [Pa]) through 2 m of 1 mm tube."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=supply)
    s += sf.CircularTube("tube", sf.air, length=2.0, diameter=1e-3)
    s += sf.Container("bottle", sf.air, volume=1e-3, initial_pressure=initial, hA=0.5)
    s.connect("supply", "tube")
    s.connect("tube", "bottle")
    return s, 20.0, [("bottle", "pressure")]


def laminar_water():
    """Water at 2 bar into a stiff accumulator through 1 m of 2 mm tube given
    friction='laminar' (Re reaches ~25 000; the column and the accumulator
    ring with a period of ~0.4 s)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(2, "bar"))
    s += sf.CircularTube("tube", sf.water, length=1.0, diameter=2e-3, friction="laminar")
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-5, compliance=1e-11)
    s.connect("supply", "tube")
    s.connect("tube", "acc")
    return s, 0.5, [("tube", "massflow", "a"), ("acc", "pressure")]


def turbulent_air():
    """Air at 1.5 bar fills a 50 mL container (wall hA 0.05 W/K) through 0.5 m
    of 2 mm tube given friction='laminar' (Re reaches ~10 000) and the
    mean-density gas law (which chokes: the scene exercises assess's fallback)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(1.5, "bar"))
    s += sf.CircularTube("tube", sf.air, length=0.5, diameter=2e-3, friction="laminar",
                         compressible="mean_density")
    s += sf.Container("tank", sf.air, volume=50e-6, hA=0.05)
    s.connect("supply", "tube")
    s.connect("tube", "tank")
    return s, 2.0, [("tank", "pressure")]


def near_choking():
    """Air at 2.2 bar into a 1 L container (wall hA 0.3 W/K) through 1 m of 2 mm
    tube given the mean-density gas law: Mach ~0.7 at the tube's low-pressure
    end at first, past that law's 0.3 and short of the isothermal choking limit
    (0.845), which would stop the run (the scene exercises the tube-law axis)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(2.2, "bar"))
    s += sf.CircularTube("tube", sf.air, length=1.0, diameter=2e-3, compressible="mean_density")
    s += sf.Container("tank", sf.air, volume=1e-3, hA=0.3)
    s.connect("supply", "tube")
    s.connect("tube", "tank")
    return s, 10.0, [("tank", "pressure")]


def _water_line(diameter, compliance):
    s = sf.System()
    s += sf.PressureSource("supply", pressure=P + 1e4)
    s += sf.CircularTube("line", sf.water, length=1.0, diameter=diameter)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=compliance)
    s.connect("supply", "line")
    s.connect("line", "acc")
    return s


def water_hammer():
    """A 0.1 bar step of water into an accumulator (compliance 1e-9 m^3/Pa)
    through 1 m of 2 mm line: the column takes ~0.15 s to accelerate, against
    an accumulator filling in ~2 s; its inertia changes the pressure by ~4 %."""
    return _water_line(2e-3, 1e-9), 5.0, [("acc", "pressure")]


def slow_water():
    """The same step through 1 m of 0.5 mm line into a stiffer accumulator
    (1e-11 m^3/Pa): laminar, the column's inertia is ~0.15 % of the result."""
    return _water_line(0.5e-3, 1e-11), 10.0, [("acc", "pressure")]


def two_volumes():
    """One 4 bar supply fills a 1 L tank (wall hA 0.5 W/K) through an ISO 6358
    valve in ~0.5 s and, through 1 m of 0.1 mm capillary, a 5 mL vessel
    without a wall over ~30 s: the tank needs its heat transfer, the vessel
    stays close to isothermal (adiabatic would be 35 % off)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(4, "bar"))
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3, hA=0.5)
    s += sf.CircularTube("capillary", sf.air, length=1.0, diameter=0.1e-3)
    s += sf.Container("vessel", sf.air, volume=5e-6)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    s.connect("supply", "capillary")
    s.connect("capillary", "vessel")
    return s, 30.0, [("tank", "pressure"), ("vessel", "pressure")]


def two_pressures():
    """A 1 L air bottle at 180 bar discharges through an ISO 6358 valve and
    0.5 m of 4 mm line into a 2 L tank at 1 bar, over 2 s; both vessels are
    held at their wall temperature (``thermal='isothermal'``: the subject is
    the fluid level). The bottle's ideal-gas density is ~5 % off (Z = 1.05),
    the tank's (up to 1.4 bar) is not: the finer level is needed in the
    high-pressure part only."""
    s = sf.System()
    s += sf.Container("bottle", sf.air, volume=1e-3, initial_pressure=180e5,
                      thermal="isothermal")
    s += sf.Orifice("valve", sf.air, C=2e-11, b=0.3)
    s += sf.CircularTube("line", sf.air, length=0.5, diameter=4e-3)
    s += sf.Container("tank", sf.air, volume=2e-3, thermal="isothermal")
    s.connect("bottle", "valve")
    s.connect(("valve", "b"), ("line", "a"))
    s.connect(("line", "b"), "tank")
    return s, 2.0, [("bottle", "pressure"), ("tank", "pressure")]


SCENES = {f.__name__: f for f in (syringe, fast_fill, bottle, laminar_water, turbulent_air,
                                  near_choking, water_hammer, slow_water, two_volumes,
                                  two_pressures)}


def reference_overrides(name, system):
    """Constructor overrides of scene ``name``'s reference: a wall-less gas
    volume of two_volumes exchanges heat by free convection (a sphere of its
    volume)."""
    if name != "two_volumes":
        return {}
    vessel = system.get("vessel")
    radius = (3 * vessel.volume / (4 * math.pi)) ** (1 / 3)
    return {"vessel": {"heat_transfer_coefficient": sf.FreeConvection("sphere"),
                       "area": 4 * math.pi * radius ** 2}}
