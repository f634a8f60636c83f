"""The five pneumatic scenes of ``gas_reference.py`` built in softflow, at its
default settings (the validation notebook ``choked_tube`` and
tests/validation/test_choked_scenes.py run them): each number is given as a
Quantity and checked equal to the reference's SI number, so that the two stay
one scene."""
from __future__ import annotations

import numpy as np

import gas_reference as ref
import softflow as sf


def actuator_curve():
    """The reference's actuator curve as a softflow PVCurve (gauge pressure, PCHIP)."""
    return sf.PVCurve(volume=sf.Q_(np.array(ref.ACTUATOR_VOLUME_ML), "mL"),
                      pressure=sf.Q_(np.array(ref.ACTUATOR_GAUGE_BAR), "bar"), gauge=True)


def _same(quantity, si_value):
    """``quantity``, asserted equal to the reference's SI number."""
    got = quantity.to_base_units().magnitude
    if abs(got - si_value) > 1e-12 * abs(si_value):
        raise AssertionError(f"{quantity} is not the reference's {si_value}")
    return quantity


def scene(name):
    """The scene ``name`` (a key of ``gas_reference.SCENES``) as a softflow System;
    its volumes are labelled as the reference's pressures are."""
    sc = ref.SCENES[name]
    tube = sc["tube"]
    s = sf.System()
    s += sf.CircularTube("tube", sf.air,
                         length=_same(sf.Q_(tube.length * 100, "cm"), tube.length),
                         diameter=_same(sf.Q_(tube.diameter * 1000, "mm"), tube.diameter))
    if name == "fill":           # 3 bar gauge supply into a 50 mL tank at 1 atm
        s += sf.PressureSource("supply", pressure=_same(sf.Q_(401325, "Pa"), sc["supply"]))
        s += sf.Container("tank", sf.air, volume=_same(sf.Q_(50, "mL"), sc["volume"]),
                          initial_pressure=_same(sf.Q_(101325, "Pa"), sc["initial"]))
        s.connect("tube", "supply")
        s.connect("tube", "tank")
    elif name.startswith("blowdown"):   # 1 L at 10 bar abs to the atmosphere
        s += sf.Container("tank", sf.air, volume=_same(sf.Q_(1, "L"), sc["volume"]),
                          initial_pressure=_same(sf.Q_(10, "bar"), sc["initial"]))
        s += sf.PressureSource("ambient", pressure=_same(sf.Q_(101325, "Pa"), sc["ambient"]))
        s.connect("tube", "tank")
        s.connect("tube", "ambient")
    elif name == "two_tanks":    # 100 mL at 5 bar abs and 100 mL at 1 bar abs
        s += sf.Container("tank_a", sf.air, volume=_same(sf.Q_(100, "mL"), sc["volume_a"]),
                          initial_pressure=_same(sf.Q_(5, "bar"), sc["initial_a"]))
        s += sf.Container("tank_b", sf.air, volume=_same(sf.Q_(100, "mL"), sc["volume_b"]),
                          initial_pressure=_same(sf.Q_(1, "bar"), sc["initial_b"]))
        s.connect("tube", "tank_a")
        s.connect("tube", "tank_b")
    elif name == "actuator":     # 6 bar gauge supply into a soft actuator from 0 gauge
        s += sf.PressureSource("supply", pressure=_same(sf.Q_(701325, "Pa"), sc["supply"]))
        s += sf.Actuator("actuator", sf.air, actuator_curve(),
                         initial_pressure=_same(sf.Q_(1, "atm"), sc["initial"]))
        s.connect("tube", "supply")
        s.connect("tube", "actuator")
    else:
        raise KeyError(name)
    return s
