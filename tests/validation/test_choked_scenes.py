"""Five pneumatic scenes whose tube chokes, softflow against an independent
reference (``gas_reference.py``: NumPy/SciPy/``fluids``, no softflow).

The reference implements the choked isothermal tube law (entry acceleration,
isothermal pipe flow with friction and acceleration, exit at max(p_down, G c))
and integrates each scene to rtol 1e-10; the tests here check the reference
itself (against ``fluids.compressible.isothermal_gas`` and closed forms) and
then softflow, at its default settings, against it: the largest pressure
difference over the run within 2 % of the scene's pressure range, a
successful run, and no ``tube_choked`` validity warning.
"""
from __future__ import annotations

import functools
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from fluids.compressible import isothermal_gas

# the reference and the scenes live beside the validation notebooks (choked_tube)
EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "validation"
sys.path.insert(0, str(EXAMPLES))
import gas_reference as ref  # noqa: E402
import gas_scenes  # noqa: E402

import softflow as sf  # noqa: E402

#: softflow within this share of the scene's pressure range of the reference
TOLERANCE = 0.02
SCENE_NAMES = tuple(ref.SCENE_FUNCTIONS)


# -- the reference itself -----------------------------------------------------------------
def test_reference_air_is_softflows_air():
    """The reference's constants are those of softflow's sf.air (ideal level)."""
    assert sf.air.R == pytest.approx(ref.R_AIR, rel=1e-14)
    assert sf.air.temperature == pytest.approx(ref.T_AIR, rel=1e-14)
    for p in (1e5, 1e6):
        assert float(sf.air.viscosity(p)) == pytest.approx(ref.MU_AIR, rel=1e-12)
        assert float(sf.air.gamma(p)) == pytest.approx(ref.GAMMA_AIR, rel=1e-12)
        assert float(sf.air.density(p)) == pytest.approx(p / ref.RT, rel=1e-12)


def test_reference_does_not_import_softflow():
    import subprocess
    code = ("import sys; sys.path.insert(0, sys.argv[1]); import gas_reference; "
            "gas_reference.tube_massflow(1e6, 1e5, 1.0, 4e-3); "
            "assert not any(m.split('.')[0] == 'softflow' for m in sys.modules)")
    subprocess.run([sys.executable, "-c", code, str(EXAMPLES)], check=True)


def test_reference_self_checks():
    """Friction, entry, pipe and choke of the reference: against fluids
    (Haaland, isothermal_gas, P_isothermal_critical_flow) and a second solution
    of the choke in the inlet Mach number (see gas_reference.self_check)."""
    rows = ref.self_check(verbose=False)
    assert len(rows) > 30


@pytest.mark.parametrize("p1, p2, L, D", [(1e6, 5e5, 1.0, 4e-3), (4e5, 3e5, 0.1, 4e-3),
                                          (2e5, 1.2e5, 2.0, 2e-3), (1.05e5, 1.01e5, 1.0, 1e-3)])
def test_pipe_part_matches_fluids_isothermal_gas(p1, p2, L, D):
    """The pipe part alone (no entry acceleration): fluids.isothermal_gas with the
    reference's friction factor gives the same mass flow."""
    m = ref.pipe_massflow(p1, p2, L, D)
    f = ref.friction_factor(m / (math.pi * D * D / 4) * D / ref.MU_AIR, ref.ROUGHNESS / D)
    assert m == pytest.approx(isothermal_gas(rho=p1 / ref.RT, fd=f, P1=p1, P2=p2, L=L, D=D),
                              rel=1e-10)


@pytest.mark.parametrize("p0, p_down, L, D", [(1e6, 8e5, 1.0, 4e-3), (3e5, 2.5e5, 0.3, 2e-3),
                                              (2e5, 1.9e5, 0.1, 4e-3)])
def test_tube_massflow_from_its_inlet_pressure_matches_fluids(p0, p_down, L, D):
    """tube_massflow, unchoked: from the inlet pressure p1 its entry reaches, it is
    fluids.isothermal_gas."""
    st = ref.tube_state(p0, p_down, L, D)
    mdot, choked = ref.tube_massflow(p0, p_down, L, D)
    assert not choked and mdot == st["mdot"]
    assert math.log(p0 / st["p1"]) == pytest.approx(st["M1"] ** 2 / 2, rel=1e-12)
    assert mdot == pytest.approx(isothermal_gas(rho=st["p1"] / ref.RT, fd=st["f"], P1=st["p1"],
                                                P2=p_down, L=L, D=D), rel=1e-10)


def test_long_tube_tends_to_fluids_isothermal_gas():
    """Where the entry's acceleration is negligible (a long tube), tube_massflow from
    the node pressure is fluids.isothermal_gas from it; the difference is the
    entry's first-order effect and shrinks as 1/L."""
    p0, pd, D = 2e5, 1.5e5, 4e-3
    errors = []
    for L in (50.0, 500.0, 5000.0):
        mdot, choked = ref.tube_massflow(p0, pd, L, D)
        st = ref.tube_state(p0, pd, L, D)
        assert not choked
        fluids_m = isothermal_gas(rho=p0 / ref.RT, fd=st["f"], P1=p0, P2=pd, L=L, D=D)
        errors.append(abs(mdot / fluids_m - 1))
        entry = p0 ** 2 * st["M1"] ** 2 / (2 * (p0 ** 2 - pd ** 2))
        assert errors[-1] == pytest.approx(entry, rel=0.2)
    assert errors[-1] < 1e-5 and errors[0] / errors[-1] > 50


@pytest.mark.parametrize("p0, L, D", [(401325.0, 0.1, 4e-3), (1e6, 1.0, 4e-3), (1e6, 0.3, 2e-3),
                                      (5e5, 0.2, 3e-3), (701325.0, 2.0, 2e-3)])
def test_choked_flow_is_the_isothermal_fanno_limit(p0, L, D):
    """Choked: the exit runs at c = sqrt(R T), f L/D equals the isothermal Fanno
    parameter of the inlet Mach number, and the flow no longer depends on p_down."""
    st = ref.tube_state(p0, 0.1 * p0, L, D)
    assert st["choked"]
    assert st["p2"] == pytest.approx(st["G"] * ref.C_ISO, rel=1e-14)
    assert ref.fanno_parameter(st["M1"]) == pytest.approx(st["f"] * L / D, rel=1e-9)
    assert st["G"] == pytest.approx(ref.choked_massflux_by_mach(p0, L, D), rel=1e-10)
    assert ref.tube_massflow(p0, 0.05 * p0, L, D) == ref.tube_massflow(p0, 0.1 * p0, L, D)
    # the same G* just below the choke and (to second order) just above it
    p_star = st["p2"]
    below, ch_below = ref.tube_massflow(p0, p_star * (1 - 1e-9), L, D)
    above, ch_above = ref.tube_massflow(p0, p_star * (1 + 1e-6), L, D)
    assert ch_below and not ch_above and above == pytest.approx(below, rel=1e-9)
    # flow from b to a is the mirror image
    assert ref.tube_massflow(0.1 * p0, p0, L, D) == (-st["mdot"], True)


def test_reference_scene_integrations():
    """The fill's choked phase in closed form, the two tanks' mass, each duration
    (1 % from equilibrium) and each scene against a second integrator."""
    rows = ref.scene_checks({name: _reference(name) for name in SCENE_NAMES}, verbose=False)
    assert len(rows) == 3 + 4 * len(SCENE_NAMES)


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_reference_scene_chokes_then_unchokes(name):
    r = _reference(name)
    assert r.choked_at_start and len(r.choke_events) == 1
    assert 0.0 < r.choked_fraction < 1.0
    assert r.distance_to_equilibrium() <= 0.01


def test_actuator_curve_is_softflows_pvcurve():
    """The reference's PCHIP curve is softflow's PVCurve of the same points (gauge
    bar, mL), extrapolation aside; an actuator at 1 atm starts at the first volume."""
    curve = gas_scenes.actuator_curve()
    pchip = ref.actuator_curve()
    v = np.linspace(ref.ACTUATOR_VOLUME_ML[0], ref.ACTUATOR_VOLUME_ML[-1], 1001) * 1e-6
    np.testing.assert_allclose(curve(v), pchip(v), rtol=1e-13)
    np.testing.assert_allclose(curve.fdf_volume(v)[1], pchip.derivative()(v), rtol=1e-9)
    act = sf.Actuator("actuator", sf.air, curve, initial_pressure=sf.Q_(1, "atm"))
    assert act.initial_volume == pytest.approx(ref.ACTUATOR_VOLUME_ML[0] * 1e-6, rel=1e-12)
    assert act.initial_pressure == pytest.approx(ref.P_ATM, rel=1e-14)



# -- the adiabatic reference itself ----------------------------------------------------------
ADIABATIC_SCENE_NAMES = tuple(ref.ADIABATIC_SCENE_FUNCTIONS)


@functools.lru_cache(maxsize=None)
def _reference_adiabatic(name):
    return ref.ADIABATIC_SCENE_FUNCTIONS[name]()


def test_adiabatic_reference_air_is_softflows_air():
    """cp, cv of the adiabatic reference are softflow's sf.air's (ideal level), and its
    u, h differ from the reference's cv T, cp T by constants only (the energy balances
    are the same)."""
    for p in (1e5, 1e6):
        assert float(sf.air.cp(p)) == pytest.approx(ref.CP_AIR, rel=1e-12)
        assert float(sf.air.cv(p)) == pytest.approx(ref.CV_AIR, rel=1e-12)
    T = np.array([150.0, 293.15, 400.0])
    for name, c in (("enthalpy", ref.CP_AIR), ("internal_energy", ref.CV_AIR)):
        offset = np.asarray(getattr(sf.air, name)(np.full(3, 3e5), T)) - c * T
        np.testing.assert_allclose(offset, offset[0], rtol=0, atol=1e-9 * c * 400.0)


def test_adiabatic_reference_self_checks():
    """Fanno function against gamma = 1.4 tables and its ODE, entry against fluids'
    stagnation relations, zero-length tube = isentropic nozzle (fluids' critical state),
    choke in the inlet Mach number, unchoked flux against the closed forms, continuity,
    low-Mach limit (see gas_reference.self_check_adiabatic)."""
    rows = ref.self_check_adiabatic(verbose=False)
    assert len(rows) > 80


@pytest.mark.parametrize("M, value", [(0.2, 14.5333), (0.5, 1.06906), (0.8, 0.07229),
                                      (0.10, 66.922), (0.16, 24.198)])
def test_fanno_function_matches_tables(M, value):
    """F*(M) = f L*/D (Darcy) for gamma = 1.4 against table values, and F*(1) = 0."""
    assert ref.fanno(M, 1.4) == pytest.approx(value, abs=5e-6 if value < 2 else 5e-4)
    assert ref.fanno(1.0, 1.4) == 0.0


@pytest.mark.parametrize("p0, T0", [(1e6, 293.15), (401325.0, 250.0)])
def test_adiabatic_zero_length_tube_is_the_isentropic_nozzle(p0, T0):
    from fluids.compressible import P_critical_flow
    g = ref.GAMMA_AIR
    nozzle = (p0 * math.sqrt(g / (ref.R_AIR * T0))
              * (2 / (g + 1)) ** ((g + 1) / (2 * (g - 1))))
    assert ref.adiabatic_choked_massflux(p0, T0, 0.0, 4e-3) == pytest.approx(nozzle, rel=1e-14)
    assert ref.adiabatic_tube_state(p0, T0, 0.1 * p0, 0.0, 4e-3)["p2"] == pytest.approx(
        P_critical_flow(p0, g), rel=1e-13)
    # a very short tube tends to it
    assert ref.adiabatic_choked_massflux(p0, T0, 1e-9, 4e-3) == pytest.approx(nozzle, rel=1e-7)


@pytest.mark.parametrize("p0, T0, L, D", [(401325.0, 293.15, 0.1, 4e-3),
                                          (1e6, 200.0, 1.0, 4e-3), (1e6, 293.15, 0.3, 2e-3),
                                          (5e5, 350.0, 0.2, 3e-3), (701325.0, 293.15, 2.0, 2e-3)])
def test_adiabatic_choked_flow_is_the_fanno_limit(p0, T0, L, D):
    """Choked: F*(M1) = f L/D at the exit Mach 1, G* the same in the inlet Mach number,
    independent of p_down, continuous at the choke, mirrored for b -> a; more flow than
    the isothermal law's choke (M = 1 at the exit instead of 1/sqrt(gamma))."""
    st = ref.adiabatic_tube_state(p0, T0, 0.1 * p0, L, D)
    assert st["choked"] and st["M2"] == 1.0
    assert ref.fanno(st["M1"]) == pytest.approx(st["f"] * L / D, rel=1e-9)
    assert st["G"] == pytest.approx(ref.adiabatic_choked_massflux_by_mach(p0, T0, L, D),
                                    rel=1e-10)
    assert ref.adiabatic_tube_massflux(p0, T0, 0.05 * p0, 300.0, L, D) == (st["G"], True)
    below = ref.adiabatic_tube_massflux(p0, T0, st["p2"] * (1 - 1e-9), T0, L, D)
    above = ref.adiabatic_tube_massflux(p0, T0, st["p2"] * (1 + 1e-6), T0, L, D)
    assert below[1] and not above[1] and above[0] == pytest.approx(below[0], rel=1e-9)
    assert ref.adiabatic_tube_massflux(0.1 * p0, 300.0, p0, T0, L, D) == (-st["G"], True)
    if T0 == ref.T_AIR:
        assert st["G"] > ref.choked_massflux(p0, L, D)


@pytest.mark.parametrize("p0, T0, p_down, L, D", [(1e6, 293.15, 8e5, 1.0, 4e-3),
                                                  (3e5, 250.0, 2.5e5, 0.3, 2e-3),
                                                  (1.05e5, 293.15, 1.01e5, 1.0, 1e-3)])
def test_adiabatic_unchoked_flow_satisfies_the_fanno_closed_forms(p0, T0, p_down, L, D):
    st = ref.adiabatic_tube_state(p0, T0, p_down, L, D)
    assert not st["choked"]
    assert ref.fanno(st["M1"]) - ref.fanno(st["M2"]) == pytest.approx(st["f"] * L / D,
                                                                      rel=1e-8)
    assert st["p1"] * ref.fanno_pressure_ratio(st["M1"], st["M2"]) == pytest.approx(
        p_down, rel=1e-12)
    # T0 is constant along the tube: the exit's static T from its Mach number
    assert st["T2"] == pytest.approx(T0 / (1 + (ref.GAMMA_AIR - 1) / 2 * st["M2"] ** 2),
                                     rel=1e-14)


def test_adiabatic_low_mach_limit_is_the_isothermal_law():
    """A long tube (low Mach): Fanno flow tends to the isothermal law, within M^2."""
    for L in (50.0, 500.0, 5000.0):
        st = ref.adiabatic_tube_state(2e5, ref.T_AIR, 1.5e5, L, 4e-3)
        iso = ref.tube_massflow(2e5, 1.5e5, L, 4e-3)[0]
        assert abs(st["mdot"] / iso - 1) < st["M2"] ** 2


def test_adiabatic_reference_scene_integrations():
    """The fill's choked phase in closed form, the isentropic blowdowns, the energy
    balances, the two tanks' mass and energy, each duration (pressures and temperatures
    1 % from equilibrium) and each scene against a second integrator."""
    rows = ref.scene_checks_adiabatic({name: _reference_adiabatic(name)
                                       for name in ADIABATIC_SCENE_NAMES}, verbose=False)
    assert len(rows) == 14 + 6 * len(ADIABATIC_SCENE_NAMES)


@pytest.mark.parametrize("name", ADIABATIC_SCENE_NAMES)
def test_adiabatic_reference_scene_chokes_then_unchokes(name):
    r = _reference_adiabatic(name)
    assert r.choked_at_start and len(r.choke_events) == 1
    assert 0.0 < r.choked_fraction < 1.0
    assert r.distance_to_equilibrium() <= 0.01
    assert r.temperature_distance_to_equilibrium() <= 0.01
    assert r.duration == ref.ADIABATIC_DURATIONS[name]
    for label, T in r.temperatures.items():
        assert T[0] == pytest.approx(ref.T_AIR, rel=1e-14)
        # monotone towards the closed-form equilibrium
        d = np.diff(T)
        assert np.all(d >= 0) or np.all(d <= 0), label


def test_adiabatic_two_tanks_conserve_mass_and_energy():
    """The tube is adiabatic and stores nothing: m_a + m_b and U_a + U_b stay constant;
    the tanks end at the isothermal scene's common pressure (U = cv p V / R), a cold and
    b warm."""
    r = _reference_adiabatic("two_tanks")
    m = r.masses["tank_a"] + r.masses["tank_b"]
    U = ref.CV_AIR * (r.masses["tank_a"] * r.temperatures["tank_a"]
                      + r.masses["tank_b"] * r.temperatures["tank_b"])
    np.testing.assert_allclose(m, m[0], rtol=1e-12)
    np.testing.assert_allclose(U, U[0], rtol=1e-12)
    p_eq, Ta, Tb = ref.two_tanks_equilibrium_adiabatic()
    assert p_eq == _reference("two_tanks").equilibrium["tank_a"]
    assert Ta < ref.T_AIR < Tb


# -- softflow against the reference ---------------------------------------------------------
@functools.lru_cache(maxsize=None)
def _reference(name):
    return ref.SCENE_FUNCTIONS[name]()


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_softflow_choked_scene_matches_reference(name):
    """softflow at its default settings (tube law, adaptive BDF, rtol 1e-3) runs the
    scene through its choked phase, says nothing of a choked tube, and stays within
    2 % of the pressure range of the reference over the whole run."""
    reference = _reference(name)
    system = gas_scenes.scene(name)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        result = sf.Simulation(system, duration=sf.Q_(reference.duration, "s")).run()
    assert result.success, result.status
    choked = [w.message for w in result.warnings if w.check == "tube_choked"]
    assert not choked, choked
    t = np.asarray(result.times)
    assert t[-1] == pytest.approx(reference.duration, rel=1e-9)
    expected = reference.pressure_at(t)
    for label, p_ref in expected.items():
        p = np.asarray(result.get(label, "pressure"))
        err = np.abs(p - p_ref)
        k = int(np.argmax(err))
        assert err[k] <= TOLERANCE * reference.pressure_range, (
            f"{name}: {label} off by {err[k]:.4g} Pa at t = {t[k]:.4g} s (softflow "
            f"{p[k]:.6g} Pa, reference {p_ref[k]:.6g} Pa), more than {TOLERANCE:.0%} of the "
            f"range {reference.pressure_range:.6g} Pa")


@pytest.mark.parametrize("name", SCENE_NAMES)
def test_softflow_adiabatic_scene_matches_the_fanno_reference(name):
    """thermal='adiabatic' at the default settings: the tube is adiabatic (Fanno)
    pipe flow from the upstream stagnation state, the volumes adiabatic; against
    the reference's Fanno tubes and energy balances, every pressure within 2 %
    of the scene's pressure range and every gas temperature within 2 % of its
    temperature range over the whole run (measured 0.04-0.08 % and
    0.02-0.29 %), no tube warned of."""
    reference = _reference_adiabatic(name)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        result = sf.Simulation(gas_scenes.scene(name), duration=reference.duration,
                               thermal="adiabatic").run()
    assert result.success, result.status
    assert not [w for w in result.warnings if w.component == "tube"]
    t = np.asarray(result.times)
    for label, p_ref in reference.pressure_at(t).items():
        err = np.max(np.abs(result.get(label, "pressure") - p_ref))
        assert err <= TOLERANCE * reference.pressure_range, (name, label, err)
    for label, T_ref in reference.temperature_at(t).items():
        err = np.max(np.abs(result.get(label, "temperature") - T_ref))
        assert err <= TOLERANCE * np.ptp(reference.temperatures[label]), (name, label, err)
