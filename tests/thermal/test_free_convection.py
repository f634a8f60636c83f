"""Wall heat transfer from a free-convection correlation (FreeConvection)."""
import numpy as np
import pytest
from CoolProp.CoolProp import PropsSI
from ht.conv_free_immersed import Nu_sphere_Churchill, Nu_vertical_plate_Churchill

import softflow as sf
from softflow.components.thermal import initial_fluid_volume
from softflow.solve.thermal import energy_balance

AIR = sf.air
T0 = AIR.temperature
G = 9.80665


def _h_reference(p, T, Tw, L, nusselt=Nu_sphere_Churchill):
    """h from CoolProp properties at the film temperature and ht, written out."""
    Tf = 0.5 * (T + Tw)
    rho = PropsSI("D", "P", p, "T", Tf, "Air")
    mu = PropsSI("V", "P", p, "T", Tf, "Air")
    k = PropsSI("L", "P", p, "T", Tf, "Air")
    cp = PropsSI("C", "P", p, "T", Tf, "Air")
    beta = PropsSI("isobaric_expansion_coefficient", "P", p, "T", Tf, "Air")
    Gr = G * beta * abs(T - Tw) * L**3 * rho**2 / mu**2
    return nusselt(mu * cp / k, Gr) * k / L


@pytest.mark.parametrize("shape, nusselt", [("sphere", Nu_sphere_Churchill),
                                             ("vertical_plate", Nu_vertical_plate_Churchill)])
def test_coefficient_matches_coolprop_and_ht(shape, nusselt):
    air = sf.Fluid("air", level="eos")
    corr = sf.FreeConvection(shape, length=0.1)
    p, T, Tw = np.array([2e5, 1e6]), np.array([360.0, 250.0]), np.array([293.15, 293.15])
    h = corr.coefficient(air, p, T, Tw, 0.1)
    want = [_h_reference(*args, 0.1, nusselt) for args in zip(p, T, Tw)]
    np.testing.assert_allclose(h, want, rtol=1e-9)
    assert 2.0 < h[0] < 20.0           # free convection in air: a few W/(m^2 K)


def test_conduction_limit_and_default_length():
    corr = sf.FreeConvection()
    L = corr.characteristic_length(1e-3)
    assert L == pytest.approx((6e-3 / np.pi) ** (1 / 3))
    h = corr.coefficient(AIR, 1e5, T0, T0, L)       # no temperature difference: Nu = 2
    assert h == pytest.approx(2 * AIR.conductivity(1e5) / L, rel=1e-12)
    assert sf.FreeConvection(length=sf.Q_(5, "cm")).characteristic_length(1.0) == 0.05


# The cooling curve against an independent solve_ivp integration is case 7 of
# examples/validation/thermal.ipynb, executed by tests/validation.


def test_fill_heats_then_cools_with_exact_energy_balance():
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.pressure_atmospheric + 3e5)
    s += sf.Orifice("valve", AIR, diameter=0.5e-3, Cd=0.7)
    s += sf.Container("tank", AIR, volume=1e-3, area=0.0484,
                      heat_transfer_coefficient=sf.FreeConvection())
    s.connect("valve", "src")
    s.connect("valve", "tank")
    res = sf.Simulation(s, duration=20.0, thermal="adiabatic").run()
    T = res.get("tank", "temperature")
    assert T.max() > T0 + 20 and T[-1] < T.max() - 5
    assert energy_balance(res, s)["relative_error"] < 1e-8


def test_bad_input():
    with pytest.raises(ValueError, match="shape must be one of"):
        sf.FreeConvection("cube")
    with pytest.raises(ValueError, match="needs its characteristic length"):
        sf.FreeConvection("vertical_cylinder")
    with pytest.raises(sf.UnitError):
        sf.FreeConvection(length=sf.Q_(1, "kg"))
    with pytest.raises(sf.UnitError, match="conductivity"):
        sf.IdealGas("gas", molar_mass=0.029, viscosity=1.8e-5, conductivity=sf.Q_(1, "W/m"))
    with pytest.raises(sf.FluidError, match="conductivity must be > 0"):
        sf.ConstantLiquid("oil", density=900, viscosity=0.1, conductivity=0.0)
    assert sf.IdealGas("gas", molar_mass=0.029, viscosity=1.8e-5,
                       conductivity=sf.Q_(26, "mW/m/K")).conductivity(1e5) == pytest.approx(0.026)
    with pytest.raises(ValueError, match="area"):
        sf.Container("tank", AIR, volume=1e-3, heat_transfer_coefficient=sf.FreeConvection())
    gas = sf.IdealGas("gas", molar_mass=0.029, viscosity=1.8e-5)     # no conductivity
    s = sf.System()
    s += sf.MassFlowSource("plug", massflow=0.0)
    s += sf.Container("tank", gas, volume=1e-3, area=0.05,
                      heat_transfer_coefficient=sf.FreeConvection())
    s.connect("plug", "tank")
    with pytest.raises(ValueError, match="'tank'.*thermal conductivity"):
        sf.Simulation(s, duration=1.0, thermal="heat_transfer")


def test_deformable_volumes_take_their_initial_volume_as_length_scale():
    from softflow.curves.waveforms import Step
    curve = sf.PVCurve.monotonic((1e-5, sf.pressure_atmospheric), (3e-5, 1.5e5), (6e-5, 1.8e5))
    fc = sf.FreeConvection()
    s = sf.System()
    s += sf.PressureSource("src", pressure=Step(0.1, 2e5, 1.2e5), temperature=330.0)
    s += sf.CircularTube("tube", AIR, length=0.3, diameter=1.5e-3)
    s += sf.Actuator("act", AIR, curve, area=5e-4, heat_transfer_coefficient=fc)
    s += sf.CircularTube("tube2", AIR, length=0.1, diameter=1e-3)
    s += sf.LinearAccumulator("acc", AIR, volume=2e-5, compliance=1e-10, area=4e-4,
                              heat_transfer_coefficient=fc)
    s.connect("src", ("tube", "a"), ("tube2", "a"))
    s.connect(("tube", "b"), "act")
    s.connect(("tube2", "b"), "acc")
    sim = sf.Simulation(s, duration=1.0, thermal="adiabatic")
    g, _ = sim.asm.where["act"]
    act = g.comps[0]
    assert act._h_corr is fc
    # the actuator starts at atmospheric pressure: the curve's first volume
    assert initial_fluid_volume(act) == pytest.approx(1e-5, rel=1e-6)
    res = sim.run()
    bal = energy_balance(res, s)
    assert bal["relative_error"] < 1e-8 and abs(bal["wall_heat"]) > 1e-4
