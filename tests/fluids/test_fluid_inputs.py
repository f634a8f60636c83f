"""Fluid parameters with units, and every kind of bad fluid input."""
import re

import numpy as np
import pytest

import softflow as sf


# -- units ------------------------------------------------------------------------------
@pytest.mark.parametrize("temperature, kelvin", [
    (sf.Q_(20, "degC"), 293.15),
    (sf.Q_(-10, "degC"), 263.15),
    (sf.Q_(68, "degF"), 293.15),
    (sf.Q_(300, "K"), 300.0),
    (310.0, 310.0),
])
def test_temperature_accepts_quantities_including_offset_units(temperature, kelvin):
    for level in ("ideal", "eos"):
        f = sf.Fluid("nitrogen", level=level, temperature=temperature)
        assert f.temperature == pytest.approx(kelvin, rel=1e-12)
    assert sf.air.at(temperature=temperature).temperature == pytest.approx(kelvin, rel=1e-12)


def test_fraction_accepts_quantities():
    assert sf.Fluid("ethylene_glycol", fraction=sf.Q_(25, "percent")).spec.fraction == 0.25
    assert sf.ethylene_glycol.at(fraction=0.25).spec.fraction == 0.25


def test_properties_as_quantities():
    rho = sf.air.with_level("eos").quantity("density", sf.Q_(2, "bar"), sf.Q_(40, "degC"))
    assert rho.units == sf.ureg("kg/m**3").units
    want = sf.air.with_level("eos").density(2e5, 313.15)
    assert rho.magnitude == pytest.approx(want, rel=1e-12)
    mu = sf.water.quantity("viscosity", sf.Q_(1, "atm"))
    assert mu.to("mPa*s").magnitude == pytest.approx(1.0016, rel=1e-3)


def test_wrong_dimension_names_the_parameter():
    with pytest.raises(sf.UnitError, match=re.escape("fluid 'air': temperature expects a "
                                                     "temperature [K], got 2 bar")):
        sf.Fluid("air", temperature=sf.Q_(2, "bar"))
    with pytest.raises(sf.UnitError, match="p expects a pressure"):
        sf.air.quantity("density", sf.Q_(2, "m"))
    with pytest.raises(sf.UnitError, match="fraction expects a dimensionless mass fraction"):
        sf.Fluid("ethylene_glycol", fraction=sf.Q_(1, "kg"))


# -- bad input --------------------------------------------------------------------------
@pytest.mark.parametrize("name, suggestion", [
    ("Ari", "'air'"),
    ("nitrogn", "'nitrogen'"),
    ("CarbonDioxde", "'CarbonDioxide'"),
    ("etylene_glycol", "'ethylene_glycol'"),
    ("INCOMP::MEX", "'INCOMP::MEA'"),
])
def test_unknown_fluid_suggests_close_matches(name, suggestion):
    with pytest.raises(sf.FluidError, match=rf"unknown fluid '{re.escape(name)}'.*did you "
                                            rf"mean .*{re.escape(suggestion)}"):
        sf.Fluid(name)


def test_unknown_level_and_option():
    with pytest.raises(sf.FluidError, match="level must be one of ideal, table, eos, got "
                                            "'tabel'; did you mean 'table'"):
        sf.Fluid("air", level="tabel")
    with pytest.raises(sf.FluidError, match="out_of_range must be 'raise' or 'eos'"):
        sf.Fluid("air", level="table", out_of_range="clip")


@pytest.mark.parametrize("fraction", [0.7, -0.1, sf.Q_(80, "percent")])
def test_glycol_fraction_outside_coolprop_range(fraction):
    with pytest.raises(sf.FluidError, match=r"fraction .* is outside CoolProp's range for "
                                            r"INCOMP::MEG: 0 \.\.\. 0\.6"):
        sf.Fluid("ethylene_glycol", fraction=fraction)


def test_fraction_of_a_pure_fluid_is_refused():
    with pytest.raises(sf.FluidError, match="fraction applies to CoolProp solutions"):
        sf.Fluid("air", fraction=0.2)


@pytest.mark.parametrize("temperature", [-5.0, 0.0, sf.Q_(-300, "degC"), float("nan")])
def test_fluid_temperature_must_be_absolute_and_positive(temperature):
    with pytest.raises(sf.FluidError, match="temperature must be one absolute temperature "
                                            "> 0 K"):
        sf.Fluid("air", level="eos", temperature=temperature)
    with pytest.raises(sf.FluidError, match="temperature must be one absolute temperature"):
        sf.IdealGas("gas", molar_mass=0.029, viscosity=1.8e-5, temperature=temperature)


@pytest.mark.parametrize("level", ["table", "eos"])
def test_negative_absolute_pressure_or_temperature_in_a_call(level):
    f = sf.air.with_level(level)
    with pytest.raises(sf.FluidError, match=r"pressure -1e\+06 Pa is not a positive absolute "
                                            r"pressure"):
        f.density(np.array([1e5, -1e6]), 300.0)
    with pytest.raises(sf.FluidError, match=r"temperature -20 K is not a positive absolute "
                                            r"temperature"):
        f.viscosity(1e5, -20.0)


def test_state_outside_the_eos_range_names_quantity_and_range():
    air = sf.air.with_level("eos")
    with pytest.raises(sf.FluidError, match=r"temperature 5000 K is outside the CoolProp range "
                                            r"59\.75 \.\.\. 2000 K"):
        air.density(1e5, 5000.0)
    with pytest.raises(sf.FluidError, match=r"pressure 3e\+09 Pa is outside the CoolProp range"):
        air.density(3e9, 300.0)
    glycol = sf.ethylene_glycol.with_level("eos")
    with pytest.raises(sf.FluidError, match=r"temperature 210 K is outside the CoolProp range "
                                            r"221\.9.* \.\.\. 373\.15 K"):
        glycol.density(1e5, 210.0)
    with pytest.raises(sf.FluidError, match=r"temperature 400 K is outside the CoolProp range"):
        sf.Fluid("ethylene_glycol", temperature=400.0)


def test_properties_a_level_does_not_have():
    with pytest.raises(NotImplementedError, match="no speed of sound"):
        sf.ethylene_glycol.with_level("eos").speed_of_sound(1e5)
    with pytest.raises(NotImplementedError, match="does not provide speed_of_sound"):
        sf.ethylene_glycol.with_level("table").speed_of_sound(1e5)
    with pytest.raises(NotImplementedError, match="without cp"):
        sf.ConstantLiquid("oil", density=900, viscosity=0.1).cp(1e5)


def test_hand_built_fluids_have_no_other_levels():
    gas = sf.IdealGas("gas", molar_mass=0.029, viscosity=1.8e-5)
    with pytest.raises(sf.FluidError, match="built by hand"):
        gas.with_level("eos")
    assert gas.at(temperature=350.0).temperature == 350.0
    with pytest.raises(sf.FluidError, match="give cp or gamma, not both"):
        sf.IdealGas("gas", molar_mass=0.029, viscosity=1.8e-5, gamma=1.4, cp=1000.0)
