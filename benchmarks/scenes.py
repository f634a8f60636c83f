"""softflow versions of the benchmark scenes (the fonsim versions are in fonsim_scenes.py)."""
from __future__ import annotations

import softflow as sf

P_ATM = sf.pressure_atmospheric


def chain(N, fluid=None, p_source=None, length=0.2, diameter=2e-3, volume=5e-6,
          friction="Haaland", compressible="pipe_flow"):
    """PressureSource -> (CircularTube -> Container) x N; tube i+1 starts at container i
    (``compressible``: the tubes' gas law, the default's or 'mean_density')."""
    fluid = sf.air if fluid is None else fluid
    p_source = P_ATM + 0.2e5 if p_source is None else p_source
    s = sf.System()
    s += sf.PressureSource("source", pressure=p_source)
    for i in range(N):
        s += sf.CircularTube(f"tube{i}", fluid, length=length, diameter=diameter,
                             friction=friction, compressible=compressible)
        s += sf.Container(f"cont{i}", fluid, volume=volume, initial_pressure=P_ATM)
    s.connect(("tube0", "a"), ("source", "a"))
    for i in range(N):
        s.connect((f"tube{i}", "b"), (f"cont{i}", "a"))
        if i + 1 < N:
            s.connect((f"cont{i}", "a"), (f"tube{i + 1}", "a"))
    return s


def walled_tank():
    """A 1.3 bar source fills a 10 mL tank through 50 cm of 1 mm tube, air;
    the tank's wall (2.2e-3 m^2) exchanges heat by free convection, whose
    h A a correlation sets at each step (thermal='heat_transfer')."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.3, "bar"))
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5, heat_transfer_coefficient=sf.FreeConvection(),
                      area=2.2e-3)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    return s
