"""Units at the package boundary: sf.units.to_si and component parameters."""
import re

import numpy as np
import pytest

import softflow as sf
from softflow.units import to_si

P0 = sf.pressure_atmospheric


# ---------------------------------------------------------------------------------------
# to_si
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("value, unit, expected", [
    (sf.Q_(60, "cm"), "m", 0.6),
    (sf.Q_(1, "mm"), "m", 1e-3),
    (sf.Q_(2, "bar"), "Pa", 2e5),
    (sf.Q_(500, "ms"), "s", 0.5),
    (sf.Q_(3, "ml"), "m**3", 3e-6),
    (sf.Q_(1.8, "ml/s"), "m**3/s", 1.8e-6),
    (sf.Q_(5, "g/s"), "kg/s", 5e-3),
    (sf.Q_(1, "ml/bar"), "m**4*s**2/kg", 1e-11),
    (sf.Q_(20, "degC"), "K", 293.15),
    (sf.Q_(1, "psi"), "Pa", 6894.757293168361),
])
def test_to_si_converts_quantities(value, unit, expected):
    got = to_si(value, unit, name="x")
    assert isinstance(got, float)
    assert got == pytest.approx(expected, rel=1e-12)


def test_to_si_plain_numbers_are_taken_as_si():
    assert to_si(0.25, "m", name="x") == 0.25
    assert to_si(3, "Pa", name="x") == 3.0
    assert isinstance(to_si(3, "Pa", name="x"), float)
    assert to_si(np.float32(2.5), "s", name="x") == 2.5


def test_to_si_arrays():
    got = to_si(sf.Q_([1, 2, 3], "ml"), "m**3", name="v")
    assert isinstance(got, np.ndarray)
    np.testing.assert_allclose(got, [1e-6, 2e-6, 3e-6], rtol=1e-12)
    got = to_si([1.0, 2.0], "Pa", name="p")
    np.testing.assert_array_equal(got, [1.0, 2.0])


def test_to_si_wrong_dimension_names_owner_parameter_and_dimension():
    with pytest.raises(sf.UnitError) as info:
        to_si(sf.Q_(2, "bar"), "m", name="diameter", owner="CircularTube 'tube'")
    msg = str(info.value)
    assert msg.startswith("CircularTube 'tube': diameter expects a length")
    assert "bar" in msg


@pytest.mark.parametrize("unit, words", [
    ("Pa", "a pressure"), ("m**3", "a volume"), ("kg/s", "a mass flow"),
    ("s", "a time"), ("m**3/s", "a volume flow"), ("K", "a temperature"),
])
def test_to_si_describes_expected_dimension(unit, words):
    with pytest.raises(sf.UnitError, match=re.escape(f"x expects {words}")):
        to_si(sf.Q_(1, "m**2"), unit, name="x")


def test_to_si_rejects_strings_and_non_numbers():
    with pytest.raises(sf.UnitError, match="string"):
        to_si("2 bar", "Pa", name="pressure")
    with pytest.raises(sf.UnitError, match="pressure"):
        to_si(object(), "Pa", name="pressure")


def test_unit_error_is_a_value_error():
    assert issubclass(sf.UnitError, ValueError)


# ---------------------------------------------------------------------------------------
# component parameters
# ---------------------------------------------------------------------------------------
def test_circular_tube_accepts_quantities():
    t = sf.CircularTube("t", sf.water, length=sf.Q_(60, "cm"), diameter=sf.Q_(1, "mm"))
    assert t.length == pytest.approx(0.6, rel=1e-12)
    assert t.diameter == pytest.approx(1e-3, rel=1e-12)
    t2 = sf.CircularTube("t2", sf.water, length=0.6, diameter=1e-3,
                         roughness=sf.Q_(5, "um"))
    assert t2.roughness == pytest.approx(5e-6, rel=1e-12)


def test_quantity_and_si_numbers_give_identical_kernels():
    a = sf.CircularTube("a", sf.water, length=sf.Q_(60, "cm"), diameter=sf.Q_(1, "mm"))
    b = sf.CircularTube("b", sf.water, length=0.6, diameter=1e-3)
    V = np.array([[2e5, 1e-3, 1e5, -1e-3]])
    Fa, _ = sf.CircularTube.kernel(sf.CircularTube.make_params([a]), V, np.zeros((1, 0)),
                                   0.0, 1e-3, False)
    Fb, _ = sf.CircularTube.kernel(sf.CircularTube.make_params([b]), V, np.zeros((1, 0)),
                                   0.0, 1e-3, False)
    np.testing.assert_allclose(Fa, Fb, rtol=1e-12)


def test_wrong_dimension_names_component_parameter_and_dimension():
    with pytest.raises(sf.UnitError,
                       match=re.escape("CircularTube 'tube': diameter expects a length")):
        sf.CircularTube("tube", sf.water, length=0.6, diameter=sf.Q_(2, "bar"))
    with pytest.raises(sf.UnitError,
                       match=re.escape("CircularTube 'tube': length expects a length")):
        sf.CircularTube("tube", sf.water, length=sf.Q_(1, "s"), diameter=1e-3)


@pytest.mark.parametrize("make, text", [
    (lambda: sf.Container("box", sf.air, volume=sf.Q_(1, "m")),
     "Container 'box': volume expects a volume"),
    (lambda: sf.Container("box", sf.air, volume=1e-6, initial_pressure=sf.Q_(1, "kg")),
     "Container 'box': initial_pressure expects a pressure"),
    (lambda: sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=sf.Q_(1, "ml")),
     "LinearAccumulator 'acc': compliance expects a compliance"),
    (lambda: sf.PressureSource("src", pressure=sf.Q_(1, "m")),
     "PressureSource 'src': pressure expects a pressure"),
    (lambda: sf.MassFlowSource("src", massflow=sf.Q_(1, "ml/s")),
     "MassFlowSource 'src': massflow expects a mass flow"),
    (lambda: sf.VolumeFlowSource("src", volumeflow=sf.Q_(1, "g/s"), fluid=sf.water),
     "VolumeFlowSource 'src': volumeflow expects a volume flow"),
])
def test_wrong_dimensions_in_other_components(make, text):
    with pytest.raises(sf.UnitError, match=re.escape(text)):
        make()


def test_other_components_convert_quantities():
    c = sf.Container("c", sf.air, volume=sf.Q_(50, "ml"), initial_pressure=sf.Q_(1.5, "bar"))
    assert c.volume == pytest.approx(5e-5, rel=1e-12)
    assert c.initial_pressure == pytest.approx(1.5e5, rel=1e-12)
    a = sf.LinearAccumulator("a", sf.water, volume=sf.Q_(2, "ml"),
                             compliance=sf.Q_(1, "ml/bar"))
    assert a.compliance == pytest.approx(1e-11, rel=1e-12)
    assert sf.PressureSource("p", pressure=sf.Q_(1.3, "bar")).signal(0.0) == pytest.approx(1.3e5)
    assert sf.MassFlowSource("m", massflow=sf.Q_(2, "g/s")).signal(1.0) == pytest.approx(2e-3)
    q = sf.VolumeFlowSource("q", volumeflow=sf.Q_(1.8, "ml/s"), fluid=sf.water)
    assert q.signal(0.0) == pytest.approx(1.8e-6, rel=1e-12)


def test_waveform_returning_quantities_is_converted():
    src = sf.PressureSource("p", pressure=lambda t: sf.Q_(1 + t, "bar"))
    assert src.signal(0.5) == pytest.approx(1.5e5, rel=1e-12)


def test_waveform_with_wrong_dimension_fails_at_construction():
    with pytest.raises(sf.UnitError, match=re.escape("PressureSource 'p': pressure(t=0)")):
        sf.PressureSource("p", pressure=lambda t: sf.Q_(1, "m"))


@pytest.mark.parametrize("kw, name", [
    (dict(length=0.0, diameter=1e-3), "length"),
    (dict(length=-0.6, diameter=1e-3), "length"),
    (dict(length=0.6, diameter=0.0), "diameter"),
    (dict(length=0.6, diameter=sf.Q_(-1, "mm")), "diameter"),
    (dict(length=0.6, diameter=1e-3, roughness=-1e-6), "roughness"),
])
def test_nonpositive_tube_geometry_raises_value_error(kw, name):
    with pytest.raises(ValueError, match=rf"CircularTube 'tube': {name} must be"):
        sf.CircularTube("tube", sf.water, **kw)


def test_zero_roughness_is_allowed():
    assert sf.CircularTube("t", sf.water, length=0.6, diameter=1e-3, roughness=0).roughness == 0


@pytest.mark.parametrize("make, name", [
    (lambda: sf.Container("c", sf.air, volume=0.0), "volume"),
    (lambda: sf.Container("c", sf.air, volume=-1e-6), "volume"),
    (lambda: sf.LinearAccumulator("c", sf.water, volume=0.0, compliance=1e-10), "volume"),
    (lambda: sf.LinearAccumulator("c", sf.water, volume=1e-6, compliance=0.0), "compliance"),
    (lambda: sf.LinearAccumulator("c", sf.water, volume=1e-6, compliance=-1e-10),
     "compliance"),
])
def test_nonpositive_chamber_geometry_raises_value_error(make, name):
    with pytest.raises(ValueError, match=rf"'c': {name} must be > 0"):
        make()


def test_nan_parameter_raises_value_error():
    with pytest.raises(ValueError, match="length must be finite"):
        sf.CircularTube("t", sf.water, length=float("nan"), diameter=1e-3)


def test_array_parameter_is_rejected():
    with pytest.raises(ValueError, match="length must be a scalar"):
        sf.CircularTube("t", sf.water, length=sf.Q_([1, 2], "m"), diameter=1e-3)


def test_variable_initial_value_quantity():
    v = sf.Variable("pressure", "across", label="p", initial_value=sf.Q_(1.5, "bar"))
    assert v.initial_value == pytest.approx(1.5e5, rel=1e-12)
    with pytest.raises(sf.UnitError, match=re.escape("Variable 'p': initial_value expects a "
                                                     "pressure")):
        sf.Variable("pressure", "across", label="p", initial_value=sf.Q_(1, "m"))


def test_fluid_parameters_accept_quantities():
    gas = sf.IdealGas("testgas", molar_mass=sf.Q_(28.97, "g/mol"),
                      viscosity=sf.Q_(18.2, "uPa*s"), temperature=sf.Q_(20, "degC"))
    assert gas.molar_mass == pytest.approx(0.02897, rel=1e-12)
    assert gas.mu == pytest.approx(1.82e-5, rel=1e-12)
    assert gas.temperature == pytest.approx(293.15, rel=1e-12)
    with pytest.raises(sf.UnitError, match=re.escape("IdealGas 'testgas': viscosity expects a "
                                                     "dynamic viscosity")):
        sf.IdealGas("testgas", molar_mass=0.029, viscosity=sf.Q_(1, "Pa"))


# ---------------------------------------------------------------------------------------
# Simulation
# ---------------------------------------------------------------------------------------
def _rc_system():
    s = sf.System()
    s += sf.PressureSource("source", pressure=P0 + 1e4)
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-10)
    s.connect("tube", "source")
    s.connect("tube", "acc")
    return s


def test_simulation_duration_quantity():
    sim = sf.Simulation(_rc_system(), duration=sf.Q_(500, "ms"))
    assert sim.duration == pytest.approx(0.5, rel=1e-12)
    res = sim.run()
    assert res.status == "success"
    assert res.times[-1] == pytest.approx(0.5, rel=1e-12)


def test_simulation_step_quantity():
    sim = sf.Simulation(_rc_system(), duration=sf.Q_(0.1, "s"), step=sf.Q_(10, "ms"))
    assert sim.step == pytest.approx(0.01, rel=1e-12)
    assert sim.adaptive is False
    res = sim.run()
    np.testing.assert_allclose(res.times, np.linspace(0, 0.1, 11), atol=1e-12)


def test_simulation_duration_wrong_dimension():
    with pytest.raises(sf.UnitError, match=re.escape("Simulation: duration expects a time")):
        sf.Simulation(_rc_system(), duration=sf.Q_(1, "m"))


def test_the_registry_cache_is_used_and_a_broken_one_is_built_around(tmp_path):
    """pint's parsed definitions are cached in the user's cache directory
    (XDG_CACHE_HOME here); a truncated cache file (pint writes in place: a
    process may read one still being written) and an unwritable cache
    directory each give the registry built without the cache, the same units."""
    import os
    import subprocess
    import sys
    code = "import softflow as sf; print(sf.Q_(2.5, 'bar').to('Pa').magnitude)"

    def run(cache):
        env = dict(os.environ, XDG_CACHE_HOME=str(cache))
        out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                             text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        return float(out.stdout.strip().splitlines()[-1])

    assert run(tmp_path) == 2.5e5
    pickles = list(tmp_path.rglob("*.pickle"))
    if not pickles:
        pytest.skip("pint's cache directory does not follow XDG_CACHE_HOME on this platform")
    for p in pickles:
        p.write_bytes(p.read_bytes()[:100])
    assert run(tmp_path) == 2.5e5
    blocked = tmp_path / "a_file"
    blocked.write_text("not a directory")
    assert run(blocked) == 2.5e5
