"""fonsim-0.6-style scripts run under fonsim itself and under softflow.fons
(``tests/fons/fonsim_scripts.py``), key results compared.

Fluids at equal properties: fonsim's own air (rho 1.23 kg/m^3 at its 1 atm of
101 300 Pa, mu 1.82e-5 Pa s) and water (999 kg/m^3, 0.977 mPa s) against the
same constants in softflow.fons.fluid classes. Pressures are compared as gauge
pressures against each library's own atmosphere (fonsim 101 300 Pa, softflow
101 325 Pa), or absolute where the script fixes them. A result agrees when it
is within 2 % of fonsim's full scale (the largest magnitude of that result).
The fonsim runs take seconds each, so most are marked slow.
"""
import contextlib
import io

import numpy as np
import pytest

import fonsim_scripts as S

fonsim = pytest.importorskip("fonsim")
with contextlib.redirect_stdout(io.StringIO()):   # fonsim prints a notice on import
    import fonsim  # noqa: F811
import softflow.fons as sfons  # noqa: E402

TOLERANCE = 0.02
FONSIM_ATM = fonsim.pressure_atmospheric
# fonsim's fluids, with softflow's 1 atm as the density's reference pressure
SF_AIR = sfons.fluid.IdealCompressible("air", 1.23 * sfons.pressure_atmospheric / FONSIM_ATM,
                                       1.82e-5)
SF_WATER = sfons.fluid.IdealIncompressible("water", 999.0, 0.977e-3)


@pytest.fixture(autouse=True)
def _agg(monkeypatch):
    import matplotlib
    matplotlib.use("Agg")


def deviations(ref, got):
    """Largest deviation of each result, relative to fonsim's full scale."""
    return {k: float(np.max(np.abs(np.asarray(got[k]) - np.asarray(ref[k])))
                     / np.max(np.abs(ref[k]))) for k in ref}


def compare(script, kind, fonsim_kw=None, softflow_kw=None):
    ref = script(fonsim, fonsim.air if kind == "air" else fonsim.water, **(fonsim_kw or {}))
    got = script(sfons, SF_AIR if kind == "air" else SF_WATER, **(softflow_kw or {}))
    assert ref.keys() == got.keys()
    return deviations(ref, got), ref, got


def test_first_network():
    dev, _, _ = compare(S.first_network, "air")   # both at their adaptive defaults
    assert max(dev.values()) < TOLERANCE, dev


def test_first_network_at_fonsim_fixed_step_agrees_closely():
    dev, _, _ = compare(S.first_network, "air", dict(step=1e-3), dict(step=1e-3))
    assert max(dev.values()) < 2e-3, dev    # same scheme, same step: same numbers


@pytest.mark.slow
def test_more_complex_network():
    dev, _, _ = compare(S.more_complex_network, "air")
    assert max(dev.values()) < TOLERANCE, dev


@pytest.mark.slow
def test_two_balloons():
    dev, _, _ = compare(S.two_balloons, "water")
    assert max(dev.values()) < TOLERANCE, dev


@pytest.mark.slow
def test_custom_component():
    dev, ref, got = compare(S.custom_container, "air")
    assert max(dev.values()) < TOLERANCE, dev
    # the custom container is the library one, in both libraries
    np.testing.assert_allclose(got["tank_0 pressure [Pa]"], got["tank_1 pressure [Pa]"],
                               rtol=1e-6)


def test_massflow_source_and_linear_accumulator():
    dev, ref, got = compare(S.accumulator, "water")
    assert max(dev.values()) < 1e-4, dev


@pytest.mark.slow
def test_volumeflow_source():
    dev, _, _ = compare(S.volumeflow_into_container, "air")
    assert max(dev.values()) < TOLERANCE, dev


def test_flow_restrictor_and_sink_water():
    dev, _, _ = compare(S.restrictor_to_sink, "water")
    assert max(dev.values()) < TOLERANCE, dev


def test_flow_restrictor_gas_differs_by_the_density_it_takes():
    # documented difference: softflow's orifice takes the upstream density,
    # fonsim's the density at the mean pressure; the flows differ by the
    # square root of their ratio (9 % at 1.5 bar into the atmosphere)
    p_up = 1.5e5
    ref = S.restrictor_to_sink(fonsim, fonsim.air, pressure=p_up)["massflow [kg/s]"][0]
    got = S.restrictor_to_sink(sfons, SF_AIR, pressure=p_up)["massflow [kg/s]"][0]
    expected = np.sqrt(p_up / (0.5 * (p_up + FONSIM_ATM)))
    assert got / ref == pytest.approx(expected, rel=5e-3)


@pytest.mark.slow
def test_flow_restrictor_filling_a_container():
    dev, _, _ = compare(S.restrictor_fill, "air", softflow_kw=dict(step=(None, None)))
    assert max(dev.values()) < TOLERANCE, dev


@pytest.mark.slow
def test_check_valve():
    ref = S.check_valve(fonsim, fonsim.air, step=5e-3)["tank pressure [Pa]"]
    got = S.check_valve(sfons, SF_AIR, step=(None, None))["tank pressure [Pa]"]
    # while the source pushes (t <= 0.45 s) both follow the tube's charging
    charging = slice(0, 4)
    gauge_ref, gauge_got = ref[charging] - FONSIM_ATM, got[charging] - sfons.pressure_atmospheric
    assert np.max(np.abs(gauge_got - gauge_ref)) / np.max(gauge_ref) < TOLERANCE
    # after the source drops, fonsim 0.6's valve lets some back (1.88 bar at step 5 ms);
    # the documented intent, followed here, is that it holds the 2 bar
    assert got[-1] == pytest.approx(2e5, abs=200)
