"""fonsim-0.6-style scripts run under fonsim itself and under softflow.fons
(``tests/fons/fonsim_scripts.py``), key results compared.

Each library runs the script with its own fluids and constants (``fons.air``,
``fons.water``, ``fons.pressure_atmospheric``): softflow.fons's are fonsim's.

- The tutorials: both at their default steps (or the step the script fixes);
  a result agrees within 2 % of fonsim's full scale (its largest magnitude).
- One script per convention of fonsim's model: fonsim at 10x below its
  default step range (converged: within 0.08 % of its run at 100x below) and
  softflow.fons at rtol 1e-7; every output within 0.5 % of its range
  (``CONVERGED``).
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
#: converged runs of both libraries: every output within this fraction of its range
CONVERGED = 0.005
FONSIM_ATM = fonsim.pressure_atmospheric


@pytest.fixture(autouse=True)
def _agg(monkeypatch):
    import matplotlib
    matplotlib.use("Agg")


def deviations(ref, got):
    """Largest deviation of each result, relative to fonsim's full scale."""
    return {k: float(np.max(np.abs(np.asarray(got[k]) - np.asarray(ref[k])))
                     / np.max(np.abs(ref[k]))) for k in ref}


def compare(script, kind, fonsim_kw=None, softflow_kw=None):
    ref = script(fonsim, getattr(fonsim, kind), **(fonsim_kw or {}))
    got = script(sfons, getattr(sfons, kind), **(softflow_kw or {}))
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


@pytest.mark.parametrize("pressure", [1.02e5, 1.5e5, 3e5, 0.6e5])
def test_flow_restrictor_gas_takes_the_density_at_the_mean_pressure(pressure):
    # fonsim's FlowRestrictor takes the density at the mean pressure (softflow's
    # Orifice: upstream, 9 % more flow from 1.5 bar into the atmosphere)
    ref = S.restrictor_to_sink(fonsim, fonsim.air, pressure=pressure)["massflow [kg/s]"][0]
    got = S.restrictor_to_sink(sfons, sfons.air, pressure=pressure)["massflow [kg/s]"][0]
    assert got == pytest.approx(ref, rel=1e-6)


@pytest.mark.slow
def test_flow_restrictor_filling_a_container():
    dev, _, _ = compare(S.restrictor_fill, "air", softflow_kw=dict(step=(None, None)))
    assert max(dev.values()) < TOLERANCE, dev


@pytest.mark.slow
def test_check_valve():
    ref = S.check_valve(fonsim, fonsim.air, step=5e-3)["tank pressure [Pa]"]
    got = S.check_valve(sfons, sfons.air, step=(None, None))["tank pressure [Pa]"]
    # while the source pushes (t <= 0.45 s) both follow the tube's charging
    charging = slice(0, 4)
    gauge_ref, gauge_got = ref[charging] - FONSIM_ATM, got[charging] - sfons.pressure_atmospheric
    assert np.max(np.abs(gauge_got - gauge_ref)) / np.max(gauge_ref) < TOLERANCE
    # after the source drops, fonsim 0.6's valve lets some back (1.88 bar at step 5 ms);
    # the documented intent, followed here, is that it holds the 2 bar
    assert got[-1] == pytest.approx(2e5, abs=200)


# -- fonsim's model, one convention at a time: both libraries converged --------------------
def range_deviations(ref, got):
    """Largest deviation of each output, relative to the range of fonsim's (its
    largest magnitude where it is constant)."""
    out = {}
    for key, r in ref.items():
        r, g = np.asarray(r, dtype=float), np.asarray(got[key], dtype=float)
        assert r.shape == g.shape, key
        span = np.ptp(r) or np.max(np.abs(r)) or 1.0
        out[key] = float(np.max(np.abs(g - r)) / span)
    return out


def converged(script, duration, *args):
    """Run ``script`` under fonsim at 10x below its default step range and under
    softflow.fons at rtol 1e-7; the deviation of each output."""
    ref = script(fonsim, *args, step=(duration * 1e-5, duration * 1e-3))
    got = script(sfons, *args, rtol=1e-7)
    assert ref.keys() == got.keys()
    return range_deviations(ref, got)


#: (script, duration [s], arguments)
FLUIDS = {
    "air tank with a leak to a Sink": (S.air_tank_with_leak, 1.0, ()),
    "water into an accumulator": (S.water_into_accumulator, 1.0, ()),
}
ACCUMULATORS = {
    "empty accumulator, water": (S.empty_accumulator, 1.0, ("water",)),
    "empty accumulator, air": (S.empty_accumulator, 1.0, ("air",)),
    "air accumulator off the atmosphere": (S.gas_accumulator_off_atmosphere, 0.5, ()),
}
ACTUATORS = {
    "actuator drained below its data": (S.actuator_drained_below_its_data, 8.0, ()),
    "actuator, curve file, water": (S.actuator_curve_file_water, 3.0, ()),
    "actuator, curve file, air": (S.actuator_curve_file_air, 0.4, ()),
    "actuator, default curve": (S.actuator_default_curve, 3.0, ()),
    "actuator, initial_volume='minimum', air": (S.actuator_initial_volume_minimum_air, 0.4, ()),
    "actuator, initial_volume='auto', water": (S.actuator_initial_volume_auto_water, 3.0, ()),
}
VALVES = {
    # fonsim's FlowRestrictor takes the density at the mean pressure (0.058 %;
    # with softflow's upstream density: 4.7 %)
    "restrictors, air, mean density": (S.restrictor_mean_density, 0.5, ()),
    # fonsim's ideal CheckValve while it passes flow (0.12 %: the fons valve's
    # 300 Pa opening band)
    "check valve, charging": (S.check_valve_charging, 0.4, ()),
}
#: fonsim interpolates its PV curves linearly between samples, and so does
#: softflow.fons (softflow's PVCurve(interpolation='linear')): the actuator scripts
#: agree within 0.08 % (0.3 to 1 % with softflow's monotone cubics)
assert sfons.data.pvcurve.LINEAR_INTERPOLATION


@pytest.mark.parametrize("name", list(FLUIDS) + list(ACCUMULATORS) + list(VALVES))
def test_convention_fluids_atmosphere_accumulators_and_valves(name):
    script, duration, args = {**FLUIDS, **ACCUMULATORS, **VALVES}[name]
    dev = converged(script, duration, *args)
    assert max(dev.values()) < CONVERGED, dev


@pytest.mark.parametrize("name", list(ACTUATORS))
def test_convention_pv_curves_and_actuators(name):
    script, duration, args = ACTUATORS[name]
    dev = converged(script, duration, *args)
    assert max(dev.values()) < CONVERGED, dev


def test_constants_fluids_and_module_paths_are_fonsim_s():
    ref, got = S.constants_and_module_paths(fonsim), S.constants_and_module_paths(sfons)
    for key in ref:
        np.testing.assert_allclose(got[key], ref[key], rtol=1e-15, err_msg=key)
    for p in (0.5e5, FONSIM_ATM, 3e5):    # fonsim's gas: rho_stp p / p_atm, isothermal
        assert sfons.air.density(p) == pytest.approx(1.23 * p / FONSIM_ATM, rel=1e-14)


def test_pv_curve_conventions_are_fonsim_s():
    ref, got = S.pv_curve_conventions(fonsim), S.pv_curve_conventions(sfons)
    dev = range_deviations(ref, got)
    assert max(dev.values()) < 1e-6, dev      # fonsim keeps its data as float32


def test_pv_curve_between_samples():
    dev = range_deviations(S.pv_curve_between_samples(fonsim),
                           S.pv_curve_between_samples(sfons))
    # straight lines, both (softflow's monotone cubics: 1.37 % of the range apart)
    assert dev["pressure between samples [Pa]"] < 1e-6, dev


@pytest.mark.parametrize("opts", [{}, {"method": "linear"}, {"autocorrect": True}])
def test_pv_curve_slopes_are_fonsim_s_chords(opts):
    ref, got = fonsim.data.PVCurve(str(S.DATA), **opts), sfons.data.PVCurve(str(S.DATA), **opts)
    assert got.interpolation == "linear"
    v = np.asarray(got.v, dtype=float)
    x = np.concatenate([0.5 * (v[:-1] + v[1:]), v[:-1] + 0.1 * np.diff(v)])
    p_ref, d_ref = np.array([[float(a) for a in ref.fdf_volume(float(xi))] for xi in x]).T
    p, d = got.fdf_volume(x)
    np.testing.assert_allclose(p, p_ref, rtol=1e-6)          # fonsim: float32 data
    np.testing.assert_allclose(d, d_ref, rtol=1e-4)         # (chords of float32 data)


def test_initial_volume_interpolates_and_fixes_fonsim_s_last_sample():
    rel_f = fonsim.data.PVCurve(str(S.DATA))
    rel_s = sfons.data.PVCurve(str(S.DATA))
    for p in (1.2e5, FONSIM_ATM + 0.05e5, FONSIM_ATM + 0.85e5, 0.9e5):
        assert rel_s.get_initial_volume(p) == pytest.approx(rel_f.get_initial_volume(p),
                                                            rel=1e-6)
    assert rel_s.get_initial_volume(1.2e5) == pytest.approx(1.6459e-6, rel=1e-4)
    # above every sample: fonsim 0.6 leaves the last sample out of its nearest search
    assert rel_f.get_initial_volume(5e5) == pytest.approx(rel_f.v[-2])
    assert rel_s.get_initial_volume(5e5) == pytest.approx(rel_s.v[-1])


def test_tube_laminar_turbulent_band_follows_fonsim():
    """In Re 2300..4000 fonsim weighs the laminar and turbulent laws linearly in
    Re; softflow.fons's tubes do too (transition='linear'; softflow's default
    smoothstep differed by up to 2.6 % of the flow in the band): steady flows
    from laminar across the band, within 1e-6, in the band as outside it."""
    for kind in ("air", "water"):
        ref = S.tube_transition(fonsim, kind)["massflow [kg/s]"]
        got = S.tube_transition(sfons, kind)["massflow [kg/s]"]
        rel = np.abs(got / ref - 1)
        Re = 4 * ref / (np.pi * 0.8e-3 * getattr(fonsim, kind).mu)
        band = (Re > 2300) & (Re < 4000)
        assert band.sum() >= 2, (kind, Re)           # the band is crossed
        assert np.all(rel < 1e-6), (kind, rel, Re)
