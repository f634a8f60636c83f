"""A gas's orifice given by its discharge coefficient: the isentropic nozzle law
(softflow.correlations.orifice.massflow_nozzle, the compiled
softflow.laws.orifice.massflow_nozzle), subsonic and choked, against an
independent textbook formula written here and against ``fluids``; the
residual as the compiled scalar law, state by state; its smoothness at the
critical ratio and at zero flow; its analytic Jacobians; a 10 bar blowdown
against an independent ODE; its ISO 6358 equivalent; bad input."""
import math
import warnings

import fluids
import numpy as np
import pytest
from fluids.compressible import P_critical_flow
from scipy.integrate import solve_ivp

import softflow as sf
from softflow.components.valves import CheckValve, Orifice
from softflow.correlations.orifice import (critical_pressure_ratio, iso_6358_of_nozzle,
                                           massflow_ISO_6358, massflow_nozzle)
from softflow.laws import orifice as law
from softflow.solve.params import rebuild

AIR = sf.air
GAMMA, R, T_AIR = AIR.gamma0, AIR.R, AIR.temperature
P0 = sf.pressure_atmospheric


def nozzle_reference(p_a, p_b, Cd, diameter, gamma=GAMMA, R=R, T=T_AIR):
    """Anderson, Modern Compressible Flow (3rd ed.), sec. 5.4, with a discharge
    coefficient: the isentropic convergent nozzle from rest at the higher
    pressure p0, choked below pr* (written out here, independently of softflow)."""
    p0, p_down = max(p_a, p_b), min(p_a, p_b)
    A = math.pi * diameter ** 2 / 4
    pr = p_down / p0
    pr_star = (2 / (gamma + 1)) ** (gamma / (gamma - 1))
    if pr <= pr_star:
        m = Cd * A * p0 * math.sqrt(gamma / (R * T)) * (2 / (gamma + 1)) ** (
            (gamma + 1) / (2 * (gamma - 1)))
    else:
        m = Cd * A * p0 * math.sqrt(2 * gamma / ((gamma - 1) * R * T)) * math.sqrt(
            pr ** (2 / gamma) - pr ** ((gamma + 1) / gamma))
    return m if p_a >= p_b else -m


def _kernel(orifices, pa, pb):
    """(mdot, d mdot/d p_a, d mdot/d p_b) of a group of orifices at (pa, pb),
    from its residual (F1 = mf_a - mdot) and Jacobian."""
    pa, pb = np.broadcast_arrays(np.asarray(pa, dtype=float), np.asarray(pb, dtype=float))
    V = np.column_stack([pa, np.zeros_like(pa), pb, np.zeros_like(pa)])
    cls = type(orifices[0])
    P = cls.make_params(orifices)
    F, J = cls.residual(P, V, np.zeros((len(orifices), 0)), 0.0, True)
    return -F[:, 1], -J[:, 2], -J[:, 4]


PRESSURE_RATIOS = np.linspace(0.05, 0.95, 37)


# ---------------------------------------------------------------------------------------
# the law against independent formulas
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("forward", [True, False], ids=["a->b", "b->a"])
def test_flow_matches_the_textbook_nozzle_over_pressure_ratios(forward):
    """Within 0.5 % over pr 0.05-0.95 both ways (measured: 4e-15)."""
    d, Cd, p_up = 2e-3, 0.6, 6e5
    o = Orifice("o", AIR, diameter=d, Cd=Cd)
    assert o.model == "nozzle"
    n = len(PRESSURE_RATIOS)
    p_dn = p_up * PRESSURE_RATIOS
    pa, pb = (np.full(n, p_up), p_dn) if forward else (p_dn, np.full(n, p_up))
    got = _kernel([o] * n, pa, pb)[0]
    want = np.array([nozzle_reference(x, y, Cd, d) for x, y in zip(pa, pb)])
    err = np.abs(got / want - 1)
    assert err.max() < 5e-3
    assert err.max() < 1e-12           # (the same law: round-off)


def test_flow_matches_fluids_subsonic_and_its_critical_ratio():
    """Subsonic: ISO 5167-3's nozzle expansibility (``fluids``) times the
    orifice equation; the critical ratio: ``fluids.compressible.P_critical_flow``."""
    d, Cd, p_up = 1e-3, 0.62, 3e5
    o = Orifice("o", AIR, diameter=d, Cd=Cd)
    for pr in (0.55, 0.7, 0.85, 0.95, 0.99):
        p_dn = pr * p_up
        incompressible = fluids.flow_meter_discharge(
            D=1e3 * d, Do=d, P1=p_up, P2=p_dn, rho=float(AIR.density(p_up)), C=Cd)
        eps = fluids.nozzle_expansibility(D=1e3 * d, Do=d, P1=p_up, P2=p_dn, k=GAMMA)
        assert _kernel([o], p_up, p_dn)[0][0] == pytest.approx(incompressible * eps, rel=1e-10)
    pr_star = P_critical_flow(P=1.0, k=GAMMA)
    assert critical_pressure_ratio(GAMMA) == pytest.approx(pr_star, rel=1e-12)
    choked = [_kernel([o], p_up, p)[0][0] for p in (1e4, 5e4, 0.999 * pr_star * p_up)]
    np.testing.assert_allclose(choked, nozzle_reference(p_up, 1e4, Cd, d), rtol=1e-12)


def test_a_real_gas_takes_its_density_at_the_upstream_pressure():
    """'table' level: R T0 replaced by p0/rho(p0), gamma the fluid's at 1 atm."""
    gas = AIR.with_level("table")
    d, Cd = 1e-3, 0.6
    o = Orifice("o", gas, diameter=d, Cd=Cd)
    assert o.model == "nozzle" and o.gamma == pytest.approx(float(gas.gamma(P0)))
    for p_up, p_dn in [(2e7, 5e6), (2e7, 1.8e7), (5e6, 2e7)]:
        p0 = max(p_up, p_dn)
        RT = p0 / float(gas.density(p0))
        want = nozzle_reference(p_up, p_dn, Cd, d, gamma=o.gamma, R=RT / T_AIR)
        assert _kernel([o], p_up, p_dn)[0][0] == pytest.approx(want, rel=1e-12)


def test_steady_flow_in_a_network_is_the_nozzle_both_ways():
    d, Cd = 0.8e-3, 0.7
    for pa, pb in [(5e5, P0), (P0, 1.6e5), (2e5, 1.9e5)]:
        s = sf.System()
        s += sf.PressureSource("pa", pressure=pa)
        s += Orifice("o", AIR, diameter=d, Cd=Cd)
        s += sf.PressureSource("pb", pressure=pb)
        s.connect(("o", "a"), "pa")
        s.connect(("o", "b"), "pb")
        with warnings.catch_warnings():
            warnings.simplefilter("error", sf.ModelWarning)     # no orifice_choked
            res = sf.Simulation(s, duration=1e-2, step=5e-3).run()
        got = res.get("o", "massflow", "a")[-1]
        assert got == pytest.approx(nozzle_reference(pa, pb, Cd, d), rel=1e-9)


@pytest.mark.parametrize("fluid", [AIR, AIR.with_level("table"), sf.water],
                         ids=["nozzle", "nozzle-table", "liquid-Cd"])
def test_the_residual_evaluates_the_compiled_scalar_law(fluid):
    """The group's flow and its partials are the compiled law of
    softflow.laws.orifice at each state, bitwise, both ways and in every regime."""
    group = _group(fluid)
    for pa, pb in _regime_pressures(group).values():
        q, d_a, d_b = _kernel(group, pa, pb)
        for i, o in enumerate(group):
            if o.model == "nozzle":
                p_up = max(pa[i], pb[i])
                want = law.massflow_nozzle(pa[i], pb[i], float(fluid.density(p_up)),
                                           float(fluid.density_dp(p_up)), o.gamma, o.Cd,
                                           o.area, o.dp_small)
            else:
                w, w_dp, _ = law.massflow_loss_coefficient(pa[i] - pb[i], fluid.rho, o.K,
                                                           o.area, o.dp_small)
                want = (w, w_dp, -w_dp)
            assert (q[i], d_a[i], d_b[i]) == want


# ---------------------------------------------------------------------------------------
# smoothness: C1 at the critical ratio and through zero flow
# ---------------------------------------------------------------------------------------
def test_c1_at_the_critical_pressure_ratio():
    o = Orifice("o", AIR, diameter=1e-3, Cd=0.6)
    p_up = 4e5
    pr_star = float(critical_pressure_ratio(o.gamma))
    eps = 1e-9
    q, d_up, d_dn = _kernel([o] * 2, p_up, p_up * pr_star * np.array([1 - eps, 1 + eps]))
    assert q[1] == pytest.approx(q[0], rel=1e-12)
    assert d_up[1] == pytest.approx(d_up[0], rel=1e-7)
    # the subsonic flow's slope in the back pressure vanishes there, as the choked one's
    assert abs(d_dn[1]) < 1e-7 * d_up[0] * pr_star and abs(d_dn[0]) < 1e-14 * d_up[0]


@pytest.mark.parametrize("p_mid", [P0, 8e5])
def test_c1_with_a_finite_non_zero_slope_through_zero_flow(p_mid):
    o = Orifice("o", AIR, diameter=1e-3, Cd=0.6)
    xs = o.dp_small
    # inside the band, on either side of zero, and across the band's edge
    dp = np.array([-1e-9, 0.0, 1e-9, -(1 - 1e-9), -(1 + 1e-9), 1 - 1e-9, 1 + 1e-9]) * xs
    q, d_a, d_b = _kernel([o] * dp.size, p_mid + dp / 2, p_mid - dp / 2)
    assert q[1] == 0.0
    assert 0.0 < d_a[1] < np.inf and d_b[1] == pytest.approx(-d_a[1], rel=1e-12)
    np.testing.assert_allclose(d_a[[0, 2]], d_a[1], rtol=1e-8)      # through zero
    np.testing.assert_allclose(d_a[4], d_a[3], rtol=1e-6)            # band edge, reversed
    np.testing.assert_allclose(d_a[6], d_a[5], rtol=1e-6)            # band edge, forward
    np.testing.assert_allclose(q[[4, 6]], q[[3, 5]], rtol=1e-6)      # and its value
    # the slope at zero flow is the incompressible band's, 5/4 of the root's at its edge
    k = 0.6 * math.pi * 1e-6 / 4 * math.sqrt(2 * float(AIR.density(p_mid)))
    assert d_a[1] == pytest.approx(1.25 * k / math.sqrt(xs), rel=1e-6)


def test_flow_is_monotone_in_the_pressure_difference():
    o = Orifice("o", AIR, diameter=1e-3, Cd=0.6)
    pa = np.concatenate([np.linspace(0.02e5, 0.99e5, 400), P0 + np.linspace(-5, 5, 201),
                         np.linspace(1.02e5, 20e5, 400)])
    q, d_a, d_b = _kernel([o] * pa.size, pa, P0)
    # (strictly but where it is choked backwards: there q stays put, to round-off)
    assert (np.diff(q) > -1e-14 * np.abs(q).max()).all()
    subsonic = pa > 0.53 * P0
    assert (np.diff(q[subsonic]) > 0).all() and (d_a[subsonic] > 0).all()
    assert (d_b <= 1e-14 * np.abs(d_a).max()).all()


# ---------------------------------------------------------------------------------------
# analytic Jacobians against finite differences
# ---------------------------------------------------------------------------------------
def _group(fluid=AIR):
    return [Orifice("o0", fluid, diameter=1e-3, Cd=0.6),
            Orifice("o1", fluid, diameter=sf.Q_(0.5, "mm"), Cd=0.8, Re_laminar=50),
            Orifice("o2", fluid, diameter=2e-3, Cd=0.98, Re_laminar=30)]


def _regime_pressures(group):
    """(pa, pb) per regime: zero flow, inside the band (both ways), subsonic,
    choked, both ways."""
    xs = np.array([o.dp_small for o in group])
    pb = np.array([P0, 2e5, 1.5e5])
    out = {"zero": (pb, pb), "band": (pb + 0.4 * xs, pb), "band-reversed": (pb - 0.7 * xs, pb)}
    for name, pr in {"subsonic": [0.8, 0.6, 0.95], "choked": [0.3, 0.1, 0.5]}.items():
        out[name] = (pb / np.array(pr), pb)
        out[f"{name}-reversed"] = (pb * np.array(pr), pb)
    return out


@pytest.mark.parametrize("level", ["ideal", "table"])
@pytest.mark.parametrize("regime", ["zero", "band", "band-reversed", "subsonic", "choked",
                                    "subsonic-reversed", "choked-reversed"])
def test_jacobian_matches_finite_differences(regime, level):
    group = _group(AIR if level == "ideal" else AIR.with_level("table"))
    pa, pb = _regime_pressures(group)[regime]
    q, d_a, d_b = _kernel(group, pa, pb)
    xs = np.array([o.dp_small for o in group])
    h = np.where(np.abs(pa - pb) > 2 * xs, 1e-6 * pa, 1e-3 * xs)
    # (divided by the steps as rounded: 1e-3 of a 0.03 Pa band is ~1e6 ulps of 2 bar)
    fd_a = ((_kernel(group, pa + h, pb)[0] - _kernel(group, pa - h, pb)[0])
            / ((pa + h) - (pa - h)))
    fd_b = ((_kernel(group, pa, pb + h)[0] - _kernel(group, pa, pb - h)[0])
            / ((pb + h) - (pb - h)))
    scale = np.abs(d_a) + np.abs(d_b)
    np.testing.assert_allclose(d_a, fd_a, rtol=1e-5, atol=1e-8 * scale.max())
    np.testing.assert_allclose(d_b, fd_b, rtol=1e-5, atol=1e-8 * scale.max())
    # the kernel's own Jacobian (mass balance row included) is the law's
    cls = Orifice
    V = np.column_stack([pa, q, pb, -q])
    F, J = cls.kernel(cls.make_params(group), V, np.zeros((3, 0)), 0.0, 1e-3, True)
    np.testing.assert_allclose(F, 0.0, atol=1e-15)
    np.testing.assert_allclose(J[:, 2], -d_a, rtol=1e-14)


@pytest.mark.parametrize("regime", ["zero", "band", "band-reversed", "subsonic", "choked",
                                    "subsonic-reversed", "choked-reversed"])
@pytest.mark.parametrize("name", ["diameter", "Cd", "Re_laminar"])
def test_param_jacobian_matches_central_differences_of_rebuilt_orifices(name, regime):
    group = _group()
    pa, pb = _regime_pressures(group)[regime]
    V = np.column_stack([pa, np.full(3, 1e-5), pb, np.full(3, -1e-5)])
    S = np.zeros((3, 0))
    dF, dr = Orifice.param_jacobian(Orifice.make_params(group), V, S, 0.0, name)
    assert dF.shape == (3, 2) and dr.shape == (3, 0) and (dF[:, 0] == 0).all()
    value = np.array([{"diameter": o.diameter, "Cd": o.Cd}.get(name, [10.0, 50.0, 30.0][i])
                      for i, o in enumerate(group)])
    h = 1e-6 * value
    F = []
    for sign in (1, -1):
        moved = [rebuild(o, {name: v + sign * d}) for o, v, d in zip(group, value, h)]
        F.append(Orifice.residual(Orifice.make_params(moved), V, S, 0.0, False)[0][:, 1])
    fd = (F[0] - F[1]) / (2 * h)
    np.testing.assert_allclose(dF[:, 1] * value, fd * value, rtol=2e-5,
                               atol=1e-7 * np.abs(fd * value).max() + 1e-300)


@pytest.mark.parametrize("dp", [0.0, 3e3, 1e4, 5e4, 3e5, -2e4])
def test_gas_check_valve_opens_onto_the_nozzle_law(dp):
    """A gas check valve's open passage is the same nozzle (w = 1 above its
    band), chokes, and its analytic Jacobian matches finite differences."""
    cv = CheckValve("c", AIR, diameter=1e-3, cracking_pressure=2e3, opening_band=5e3)
    pb = 1.2e5
    q, d_a, d_b = _kernel([cv], pb + dp, pb)
    if dp >= 7e3:
        assert q[0] == pytest.approx(nozzle_reference(pb + dp, pb, 0.6, 1e-3), rel=1e-12)
    elif dp <= 2e3:
        assert q[0] == 0.0
    h = 1e-2
    fd_a = (_kernel([cv], pb + dp + h, pb)[0] - _kernel([cv], pb + dp - h, pb)[0]) / (2 * h)
    fd_b = (_kernel([cv], pb + dp, pb + h)[0] - _kernel([cv], pb + dp, pb - h)[0]) / (2 * h)
    np.testing.assert_allclose([d_a[0], d_b[0]], [fd_a[0], fd_b[0]], rtol=1e-5,
                               atol=1e-7 * abs(d_a[0]) + 1e-20)


def test_gas_check_valve_can_keep_the_incompressible_law():
    """gas_law='incompressible': Cd A sqrt(2 rho(p_a) dp) when open (never
    chokes); the two laws are kept in separate groups of one network."""
    inc = CheckValve("i", AIR, diameter=1e-3, cracking_pressure=2e3, opening_band=5e3,
                     gas_law="incompressible")
    assert math.isnan(inc.gamma)
    pa, pb = 4e5, 1e5
    want = 0.6 * math.pi * 1e-6 / 4 * math.sqrt(2 * float(AIR.density(pa)) * (pa - pb))
    assert _kernel([inc], pa, pb)[0][0] == pytest.approx(want, rel=1e-12)
    noz = CheckValve("n", AIR, diameter=1e-3, cracking_pressure=2e3, opening_band=5e3)
    assert noz.group_key() != inc.group_key()
    s = sf.System()
    s += sf.PressureSource("src", pressure=pa)
    s += inc
    s += noz
    s += sf.PressureSource("out", pressure=pb)
    for v in ("i", "n"):
        s.connect("src", (v, "a"))
        s.connect((v, "b"), "out")
    res = sf.Simulation(s, duration=1e-2, step=5e-3).run()
    assert res.get("i", "massflow", "a")[-1] == pytest.approx(want, rel=1e-9)
    assert res.get("n", "massflow", "a")[-1] == pytest.approx(
        nozzle_reference(pa, pb, 0.6, 1e-3), rel=1e-9)


# ---------------------------------------------------------------------------------------
# a 10 bar blowdown against an independent ODE
# ---------------------------------------------------------------------------------------
def test_blowdown_of_a_10_bar_tank_matches_an_independent_ode():
    """1 L of air at 10 bar abs through a 2 mm, Cd 0.6 orifice to 1 atm,
    isothermal: p V = m R T, dm/dt = -mdot(p, p_atm). Within 1 % of the
    pressure range (measured: 0.02 %), choked for the first ~4.4 s; no
    orifice_choked finding."""
    V, p_tank, d, Cd = 1e-3, 10e5, 2e-3, 0.6
    s = sf.System()
    s += sf.Container("tank", AIR, volume=V, initial_pressure=p_tank)
    s += Orifice("o", AIR, diameter=d, Cd=Cd)
    s += sf.PressureSource("atm", pressure=P0)
    s.connect("tank", ("o", "a"))
    s.connect(("o", "b"), "atm")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)   # (the isothermal tank's time scale)
        res = sf.Simulation(s, duration=10.0).run()
    assert res.success
    assert "orifice_choked" not in {w.check for w in res.warnings}
    t, p = res.times, res.get("tank", "pressure")

    def rhs(_, y):
        return [-R * T_AIR / V * nozzle_reference(y[0], P0, Cd, d)]

    ode = solve_ivp(rhs, (0.0, 10.0), [p_tank], method="LSODA", rtol=1e-10, atol=1e-6,
                    dense_output=True)
    err = np.abs(p - ode.sol(t)[0]).max() / (p_tank - P0)
    assert err < 1e-2
    assert p[-1] < 1.05 * P0            # (it got there)
    # choked while p > p_atm / 0.528, for 4.41 s (the ODE's event; the first
    # step below it, at the default rtol, is at 5.1 s): read off the run's
    # own interpolant between its steps, Result.at
    unchoked = P0 / critical_pressure_ratio(GAMMA)
    fine = np.linspace(0.0, 10.0, 100_001)
    crossing = fine[np.argmax(res.at(fine, "tank", "pressure") < unchoked)]
    assert crossing == pytest.approx(fine[np.argmax(ode.sol(fine)[0] < unchoked)], abs=0.01)
    assert 4.38 < crossing < 4.44


# ---------------------------------------------------------------------------------------
# ISO 6358 equivalent, model checks, thermal scenes
# ---------------------------------------------------------------------------------------
def test_iso_6358_equivalent_has_the_nozzles_choked_flow():
    d, Cd = 2e-3, 0.6
    C, b = iso_6358_of_nozzle(d, Cd, GAMMA, R)
    assert b == pytest.approx(P_critical_flow(P=1.0, k=GAMMA), rel=1e-12)
    nozzle = Orifice("n", AIR, diameter=d, Cd=Cd)
    iso = Orifice("i", AIR, C=float(C), b=float(b))
    for p_up in (2e5, 10e5):
        for p_dn in (P0 / 10, 0.5 * p_up * b, 0.999 * b * p_up):
            want = _kernel([nozzle], p_up, p_dn)[0][0]
            assert _kernel([iso], p_up, p_dn)[0][0] == pytest.approx(want, rel=1e-12)
    # T cancels: at another temperature both scale as 1/sqrt(T)
    hot = AIR.at(350.0)
    q_iso = massflow_ISO_6358(5e5, 1e5, 350.0, C, b)[0]
    q_noz = massflow_nozzle(5e5, 1e5, float(hot.density(5e5)), GAMMA, Cd,
                            math.pi * d * d / 4, 1.0)[0]
    assert q_iso == pytest.approx(q_noz, rel=1e-12)
    # subsonic, the elliptic law differs from the nozzle's by 0.15 % of the choked flow
    choked = _kernel([nozzle], 5e5, 1e5)[0][0]
    gap = [abs(_kernel([iso], 5e5, pr * 5e5)[0][0] - _kernel([nozzle], 5e5, pr * 5e5)[0][0])
           for pr in np.linspace(0.53, 0.999, 400)]
    assert max(gap) < 2e-3 * choked


@pytest.mark.parametrize("kw, warned", [({"Cd": 0.6}, False), ({"K": 1 / 0.36}, True)])
def test_orifice_choked_check_only_for_the_incompressible_gas_law(kw, warned):
    s = sf.System()
    s += sf.PressureSource("src", pressure=10e5)
    s += sf.Orifice("o", AIR, diameter=1e-3, **kw)
    s += sf.PressureSource("out", pressure=1e5)
    s.connect("src", "o")
    s.connect("o", "out")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(s, duration=0.01).run()
    found = [w for w in res.warnings if w.check == "orifice_choked"]
    assert bool(found) is warned
    if warned:
        assert "Cd=" in found[0].suggestion and "choke" in found[0].suggestion


def test_thermal_scene_takes_the_upstream_temperature_as_T0():
    """In an adiabatic scene the nozzle's T0 is the upstream gas's temperature
    (a reservoir at 350 K), whichever way the flow goes."""
    d, Cd, T_hot = 1e-3, 0.6, 350.0
    for p_hot, p_cold in [(3e5, 1e5), (1.8e5, 2e5)]:
        s = sf.System()
        s += sf.PressureSource("hot", pressure=p_hot, temperature=T_hot)
        s += Orifice("o", AIR, diameter=d, Cd=Cd)
        s += sf.PressureSource("cold", pressure=p_cold)
        s.connect("hot", ("o", "a"))
        s.connect(("o", "b"), "cold")
        res = sf.Simulation(s, duration=1e-2, step=5e-3, thermal="adiabatic").run()
        T_up = T_hot if p_hot > p_cold else T_AIR
        want = nozzle_reference(p_hot, p_cold, Cd, d, T=T_up)
        assert res.get("o", "massflow", "a")[-1] == pytest.approx(want, rel=1e-9)


@pytest.mark.parametrize("make", [
    lambda: Orifice("o", AIR, diameter=1e-3, Cd=0.7, Re_laminar=30),
    lambda: Orifice("o", sf.water, diameter=1e-3, Cd=0.7),
    lambda: Orifice("o", AIR, C=1e-8, b=0.3, m=0.7, pr_laminar=0.99),
    lambda: CheckValve("o", AIR, 1e-3, Cd=0.8, Re_laminar=20, gas_law="incompressible"),
    lambda: CheckValve("o", sf.water, 1e-3),
], ids=["nozzle", "liquid-Cd", "iso-6358", "check-valve-incompressible", "check-valve-liquid"])
def test_a_python_built_orifice_saves_to_a_scene_file_and_reads_back(make):
    """(a Cd orifice was written as its K, which without the diameter did not
    rebuild; the unused parameters, NaN, were written as NaN)"""
    from softflow import scene
    s = sf.System()
    s += sf.PressureSource("p", pressure=2e5)
    s += make()
    s += sf.PressureSource("q", pressure=1e5)
    s.connect(("o", "a"), "p")
    s.connect(("o", "b"), "q")
    twin = next(c for c in scene.loads(scene.dumps(s)).system.components if c.label == "o")
    orig = next(c for c in s.components if c.label == "o")
    assert getattr(twin, "model", None) == getattr(orig, "model", None)
    for name in type(orig).param_names:
        np.testing.assert_allclose(getattr(twin, name), getattr(orig, name), rtol=1e-12)


# ---------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------
class _GasWithoutGamma(sf.Fluid):
    name = "mystery gas"
    compressible = True

    def density(self, p, T=None):
        return np.asarray(p) / 8e4

    def viscosity(self, p, T=None):
        return np.full(np.shape(p), 1.8e-5)


@pytest.mark.parametrize("make, match", [
    (lambda: Orifice("o", AIR, diameter=1e-3, Cd=0.0), r"Orifice 'o'.*Cd"),
    (lambda: Orifice("o", AIR, diameter=1e-3, Cd=1.2), r"Orifice 'o'.*Cd must be in \(0, 1\]"),
    (lambda: Orifice("o", AIR, diameter=1e-3, Cd=-0.6), r"Orifice 'o'.*Cd"),
    (lambda: Orifice("o", AIR, diameter=0.0, Cd=0.6), r"Orifice 'o'.*diameter"),
    (lambda: Orifice("o", AIR, diameter=-2e-3, Cd=0.6), r"Orifice 'o'.*diameter"),
    (lambda: Orifice("o", AIR, Cd=0.6), r"Orifice 'o'.*diameter"),
    (lambda: Orifice("o", sf.water, C=1e-9, b=0.5), r"Orifice 'o'.*for gases.*incompressible"),
    (lambda: Orifice("o", _GasWithoutGamma(), diameter=1e-3, Cd=0.6),
     r"Orifice 'o'.*ratio of specific heats.*mystery gas"),
    (lambda: CheckValve("c", AIR, diameter=1e-3, Cd=1.5), r"CheckValve 'c'.*Cd"),
    (lambda: CheckValve("c", AIR, diameter=-1e-3), r"CheckValve 'c'.*diameter"),
    (lambda: CheckValve("c", AIR, diameter=1e-3, gas_law="ideal"), r"CheckValve 'c'.*gas_law"),
])
def test_bad_input_names_the_component_and_the_parameter(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_a_liquid_with_cd_keeps_the_incompressible_law_and_a_gas_with_k_too():
    w = Orifice("w", sf.water, diameter=1e-3, Cd=0.6)
    k = Orifice("k", AIR, diameter=1e-3, K=1 / 0.36)
    assert w.model == k.model == "K" and math.isnan(k.Cd) and w.Cd == 0.6
    q = _kernel([k], 3e5, 1e5)[0][0]
    assert q == pytest.approx(0.6 * math.pi * 1e-6 / 4
                              * math.sqrt(2 * float(AIR.density(3e5)) * 2e5), rel=1e-12)
