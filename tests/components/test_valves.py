"""Valves and restrictors: analytic Jacobians against finite differences, the
orifice correlations against closed forms and ``fluids``, small network runs,
and bad input."""
import math

import fluids
import numpy as np
import pytest

import softflow as sf
from softflow.components.valves import CheckValve, Orifice, SnappingValve, TeslaValve
from softflow.correlations.orifice import (ISO_6358_RHO0, ISO_6358_T0, dp_at_reynolds,
                                           loss_coefficient_from_discharge_coefficient,
                                           massflow_ISO_6358, massflow_loss_coefficient,
                                           regularized_sqrt)

P0 = sf.pressure_atmospheric
RTOL = 1e-5        # analytic vs finite-difference entries
ATOL_ROW = 1e-8    # floor relative to the largest scaled entry of the row


# ---------------------------------------------------------------------------------------
# analytic Jacobians vs central differences
# ---------------------------------------------------------------------------------------
class Case:
    """Instances of one class evaluated at V (n, 4) and S; ``steps`` are the
    finite-difference steps per variable [p_a, mf_a, p_b, mf_b] and ``scale``
    their typical sizes (for the tolerance)."""

    def __init__(self, cls, instances, V, steps, scale, S=None):
        self.cls, self.instances = cls, instances
        self.V = np.asarray(V, dtype=float)
        n = len(instances)
        self.S = (np.zeros((n, len(cls.state_spec))) if S is None
                  else np.asarray(S, dtype=float).reshape(n, -1))
        self.steps = np.asarray(steps, dtype=float)
        self.scale = np.asarray(scale, dtype=float)

    def evaluate(self, V, jac):
        P = self.cls.make_params(self.instances)
        return self.cls.kernel(P, V, self.S.copy(), 0.1, 1e-3, jac)


def _two_port_V(pa, pb, mf):
    pa, pb, mf = (np.asarray(x, dtype=float) for x in np.broadcast_arrays(pa, pb, mf))
    return np.column_stack([pa, mf, pb, -mf * 1.1])   # mass balance off on purpose


def _orifice_cases():
    cases = {}
    for fluid in (sf.air, sf.water):
        # (one group, one model: a gas's Cd is the nozzle law, test_orifice_nozzle.py)
        first = {"K": 1 / 0.6 ** 2} if fluid.compressible else {"Cd": 0.6}
        make = lambda: [Orifice("o0", fluid, diameter=1e-3, **first),
                        Orifice("o1", fluid, diameter=sf.Q_(0.5, "mm"), K=2.5),
                        Orifice("o2", fluid, diameter=2e-3, K=1.2, Re_laminar=50)]
        small = np.array([o.dp_small for o in make()])
        for regime, dp in {"zero": 0.0 * small, "laminar-band": 0.4 * small,
                           "laminar-band-reversed": -0.7 * small, "small": 30 * small,
                           "large": np.array([2e4, 5e3, 3e4]),
                           "reversed": np.array([-1e4, -200.0, -3e4])}.items():
            pb = np.array([P0, 2e5, 1.5e5])
            h = np.minimum(1e-3 * small, 1e-6 * np.maximum(np.abs(dp), 1.0)).min()
            cases[f"Orifice-{fluid.name}-{regime}"] = Case(
                Orifice, make(), _two_port_V(pb + dp, pb, 1e-4), steps=[h, 1e-9, h, 1e-9],
                scale=[1e5, 1e-3, 1e5, 1e-3])
    iso = lambda: [Orifice("i0", sf.air, C=1e-8, b=0.3),
                   Orifice("i1", sf.air, C=sf.Q_(0.2, "dm**3/(s*bar)"), b=0.5, m=0.7),
                   Orifice("i2", sf.air, C=4e-9, b=0.2, m=0.4, pr_laminar=0.99)]
    pb = np.array([P0, 2e5, 1.2e5])
    for regime, pr in {"zero": [1.0, 1.0, 1.0], "laminar-band": [0.9995, 0.9998, 0.995],
                       "subsonic": [0.8, 0.7, 0.5], "choked": [0.25, 0.3, 0.1],
                       "subsonic-reversed": [1 / 0.8, 1 / 0.7, 1 / 0.5],
                       "choked-reversed": [1 / 0.25, 1 / 0.3, 1 / 0.1],
                       "laminar-band-reversed": [1 / 0.9995, 1 / 0.9998, 1 / 0.995]}.items():
        pa = pb / np.array(pr)
        cases[f"Orifice-ISO6358-{regime}"] = Case(
            Orifice, iso(), _two_port_V(pa, pb, 1e-4), steps=[1e-3, 1e-9, 1e-3, 1e-9],
            scale=[1e5, 1e-3, 1e5, 1e-3])
    return cases


def _check_valve_cases():
    cases = {}
    for fluid in (sf.air, sf.water):
        make = lambda: [CheckValve("c0", fluid, diameter=1e-3, cracking_pressure=5e3,
                                   opening_band=2e3),
                        CheckValve("c1", fluid, diameter=2e-3, cracking_pressure=0.0,
                                   opening_band=sf.Q_(10, "mbar"), leakage=1e-12),
                        CheckValve("c2", fluid, diameter=0.5e-3, cracking_pressure=sf.Q_(0.1, "bar"),
                                   opening_band=5e3, Cd=0.8, leakage=sf.Q_(1e-3, "ml/(s*bar)"))]
        for regime, dp in {"zero": [0.0, 0.0, 0.0], "closed": [2e3, -500.0, 5e3],
                           "opening": [6e3, 500.0, 1.2e4], "open": [2e4, 3e3, 5e4],
                           "reversed": [-1e4, -2e4, -5e4]}.items():
            pb = np.array([P0, 1.5e5, 2e5])
            cases[f"CheckValve-{fluid.name}-{regime}"] = Case(
                CheckValve, make(), _two_port_V(pb + np.array(dp), pb, 1e-4),
                steps=[1e-3, 1e-9, 1e-3, 1e-9], scale=[1e5, 1e-3, 1e5, 1e-3])
    return cases


def _re_per_mf(d, fluid):
    return d / (fluid.viscosity(P0) * math.pi * d * d / 4)


def _tesla_cases():
    cases = {}
    for fluid in (sf.air, sf.water):
        make = lambda: [TeslaValve("t0", fluid, length=0.1, diameter=1e-3, diodicity=3.0),
                        TeslaValve("t1", fluid, length=sf.Q_(5, "cm"), diameter=2e-3,
                                   diodicity=1.0),
                        TeslaValve("t2", fluid, length=0.3, diameter=0.8e-3, diodicity=12.0,
                                   Re_blend=50)]
        rpm = np.array([_re_per_mf(t.diameter, fluid) for t in make()])
        for regime, re in {"zero": [0.0, 0.0, 0.0], "forward-laminar": [500, 50, 1000],
                           "forward-turbulent": [8e3, 2e4, 3000],
                           "blend": [-3.0, -0.5, -20.0], "backward-laminar": [-500, -50, -1000],
                           "backward-turbulent": [-8e3, -2e4, -3000]}.items():
            mf = np.array(re) / rpm
            cases[f"TeslaValve-{fluid.name}-{regime}"] = Case(
                TeslaValve, make(), _two_port_V([1.3e5, 2e5, P0], [1.1e5, 2.5e5, P0], mf),
                steps=[1.0, 1e-6 * np.abs(mf).max() + 1e-13, 1.0, 1e-9],
                scale=[1e5, np.abs(mf).max() + 1e-9, 1e5, 1e-3])
    return cases


def _snapping_cases():
    cases = {}
    for fluid in (sf.air, sf.water):
        make = lambda: [SnappingValve("s0", fluid, opening_pressure=2e4, closing_pressure=5e3,
                                      closed_conductance=1e-11),
                        SnappingValve("s1", fluid, opening_pressure=sf.Q_(0.3, "bar"),
                                      closing_pressure=-1e3, closed_conductance=3e-12,
                                      length=0.02, diameter=3e-3)]
        rpm = np.array([_re_per_mf(s.diameter, fluid) for s in make()])
        for mode in (0.0, 1.0):
            for regime, re in {"zero": [0.0, 0.0], "forward": [300.0, 6000.0],
                               "backward": [-2000.0, -100.0]}.items():
                mf = np.array(re) / rpm
                cases[f"SnappingValve-{fluid.name}-{'open' if mode else 'closed'}-{regime}"] = Case(
                    SnappingValve, make(), _two_port_V([1.6e5, 1.2e5], [1.2e5, 1.6e5], mf),
                    S=[mode, mode], steps=[1.0, 1e-6 * np.abs(mf).max() + 1e-13, 1.0, 1e-9],
                    scale=[1e5, np.abs(mf).max() + 1e-9, 1e5, 1e-3])
    return cases


CASES = {**_orifice_cases(), **_check_valve_cases(), **_tesla_cases(), **_snapping_cases()}


def _fd_jacobian(case):
    V0 = case.V
    n, nv = V0.shape
    F0, _ = case.evaluate(V0.copy(), False)
    D = np.zeros((n, F0.shape[1], nv))
    for k in range(nv):
        h = case.steps[k]
        Vp, Vm = V0.copy(), V0.copy()
        Vp[:, k] += h
        Vm[:, k] -= h
        # divide by the step actually taken: p + h is rounded to the pressure's ulp
        step = (Vp[:, k] - Vm[:, k])[:, None]
        D[:, :, k] = (case.evaluate(Vp, False)[0] - case.evaluate(Vm, False)[0]) / step
    return D


def test_every_valve_class_is_covered():
    assert {c.cls for c in CASES.values()} == {Orifice, CheckValve, TeslaValve, SnappingValve}


@pytest.mark.parametrize("name", sorted(CASES))
def test_valve_jacobian_matches_finite_differences(name):
    case = CASES[name]
    F, J = case.evaluate(case.V.copy(), True)
    F2, J2 = case.evaluate(case.V.copy(), False)
    n = len(case.instances)
    assert F.shape == (n, 2) and J.shape == (n, len(case.cls.jac_pattern)) and J2 is None
    np.testing.assert_array_equal(F, F2)
    assert np.isfinite(F).all() and np.isfinite(J).all()
    # equation 0 is the mass balance
    np.testing.assert_allclose(F[:, 0], case.V[:, 1] + case.V[:, 3])
    D = _fd_jacobian(case)
    Ds = D * case.scale[None, None, :]
    row_max = np.abs(Ds).max(axis=2)
    listed = set()
    for j, (e, k) in enumerate(case.cls.jac_pattern):
        listed.add((e, k))
        got, want = J[:, j] * case.scale[k], Ds[:, e, k]
        tol = RTOL * np.abs(want) + ATOL_ROW * row_max[:, e] + 1e-300
        assert (np.abs(got - want) <= tol).all(), (name, e, k, J[:, j], D[:, e, k])
    for e in range(2):
        for k in range(4):
            if (e, k) not in listed:
                assert (np.abs(Ds[:, e, k]) <= ATOL_ROW * row_max[:, e] + 1e-300).all()
    # the flow law never loses its grip on the flow (Newton needs it at zero flow)
    assert (np.abs(J[:, 3]) > 0).all()


def test_jacobian_cases_hit_their_regimes():
    """Guards the set-up: ISO cases really are choked/subsonic/laminar, Tesla blend
    cases lie in the blend band, orifice band cases lie inside dp_small."""
    for name in ("choked", "choked-reversed"):
        V = CASES[f"Orifice-ISO6358-{name}"].V
        pr = np.minimum(V[:, 0], V[:, 2]) / np.maximum(V[:, 0], V[:, 2])
        assert (pr <= np.array([0.3, 0.5, 0.2])).all()
    V = CASES["Orifice-ISO6358-subsonic"].V
    pr = V[:, 2] / V[:, 0]
    assert ((pr > np.array([0.3, 0.5, 0.2])) & (pr < np.array([0.999, 0.999, 0.99]))).all()
    case = CASES["Orifice-water-laminar-band"]
    assert (np.abs(case.V[:, 0] - case.V[:, 2]) < [o.dp_small for o in case.instances]).all()
    case = CASES["TeslaValve-air-blend"]
    re = -case.V[:, 1] * np.array([_re_per_mf(t.diameter, sf.air) for t in case.instances])
    assert ((re > 0) & (re < [t.Re_blend for t in case.instances])).all()


# ---------------------------------------------------------------------------------------
# correlations
# ---------------------------------------------------------------------------------------
def test_regularized_sqrt_is_exact_outside_and_C1_at_the_band_edge():
    xs = 2.0
    x = np.concatenate([-np.logspace(4, np.log10(xs), 20), np.logspace(np.log10(xs), 4, 20)])
    y, dy = regularized_sqrt(x, xs)
    np.testing.assert_allclose(y, np.sign(x) * np.sqrt(np.abs(x)), rtol=1e-14)
    np.testing.assert_allclose(dy, 0.5 / np.sqrt(np.abs(x)), rtol=1e-14)
    for edge in (xs, -xs):
        d = 1e-9
        (ym, yp), (dm, dp) = regularized_sqrt(np.array([edge - d, edge + d]), xs)
        assert abs(yp - ym) < 1e-8 and abs(dp - dm) < 1e-7
    inner = np.linspace(-xs, xs, 201)
    y, dy = regularized_sqrt(inner, xs)
    assert (np.diff(y) > 0).all() and (dy >= 0.5 / np.sqrt(xs) - 1e-15).all()
    assert dy[100] == pytest.approx(1.25 / np.sqrt(xs))
    np.testing.assert_allclose(y, -y[::-1], atol=1e-15)
    h = 1e-6
    fd = (regularized_sqrt(inner + h, xs)[0] - regularized_sqrt(inner - h, xs)[0]) / (2 * h)
    np.testing.assert_allclose(dy, fd, rtol=1e-6)


@pytest.mark.parametrize("K", [0.5, 2.78, 40.0])
def test_loss_coefficient_law_matches_fluids_dP_from_K(K):
    area = math.pi * 1e-3 ** 2 / 4
    dp = np.logspace(1, 5, 9)
    for rho in (998.2, 1.2, 3.5):
        mdot, d_dp, d_rho = massflow_loss_coefficient(dp, rho, K, area, 1e-3)
        v = mdot / (rho * area)
        want = np.array([fluids.dP_from_K(K=K, rho=rho, V=vi) for vi in v])
        np.testing.assert_allclose(want, dp, rtol=1e-12)
        np.testing.assert_allclose(d_dp, mdot / (2 * dp), rtol=1e-12)
        np.testing.assert_allclose(d_rho, mdot / (2 * rho), rtol=1e-12)


@pytest.mark.parametrize("Cd", [0.61, 0.8, 1.0])
def test_discharge_coefficient_law_matches_fluids_flow_meter(Cd):
    """fluids' ISO 5167 orifice equation with a tiny diameter ratio (beta -> 0)."""
    d = 1.2e-3
    K = loss_coefficient_from_discharge_coefficient(Cd)
    assert K == pytest.approx(1 / Cd ** 2)
    for rho, P1 in ((998.2, 3e5), (1.8, 1.5e5)):
        for dp in (50.0, 3e3, 8e4):
            got, _, _ = massflow_loss_coefficient(dp, rho, K, math.pi * d * d / 4, 1e-2)
            want = fluids.flow_meter_discharge(D=1e3 * d, Do=d, P1=P1, P2=P1 - dp, rho=rho,
                                               C=Cd, expansibility=1.0)
            assert got == pytest.approx(want, rel=1e-10)


def test_dp_at_reynolds_gives_that_reynolds_number():
    K, rho, mu, d = 2.5, 998.2, 1e-3, 1e-3
    dp = dp_at_reynolds(10.0, K, rho, mu, d)
    mdot, _, _ = massflow_loss_coefficient(dp, rho, K, math.pi * d * d / 4, 1e-9)
    assert 4 * mdot / (math.pi * d * mu) == pytest.approx(10.0, rel=1e-12)


def _iso_closed_form(p_up, p_dn, T, C, b, m):
    k = C * ISO_6358_RHO0 * math.sqrt(ISO_6358_T0 / T) * p_up
    pr = p_dn / p_up
    return k if pr <= b else k * (1 - ((pr - b) / (1 - b)) ** 2) ** m


@pytest.mark.parametrize("b,m", [(0.5, 0.5), (0.3, 0.5), (0.2, 0.35), (0.45, 1.0)])
def test_iso_6358_matches_closed_form(b, m):
    C, T = 2e-9, 303.0
    p_up = 6e5
    for pr in (0.05, b * 0.99, b, b * 1.01 + 0.01, 0.6, 0.9, 0.99, 0.998):
        got, _, _ = massflow_ISO_6358(p_up, pr * p_up, T, C, b, m)
        assert got == pytest.approx(_iso_closed_form(p_up, pr * p_up, T, C, b, m), rel=1e-12)
        back, _, _ = massflow_ISO_6358(pr * p_up, p_up, T, C, b, m)
        assert back == pytest.approx(-got, rel=1e-14)
    # choked: independent of the downstream pressure, proportional to the upstream one
    q = [massflow_ISO_6358(p_up, x, T, C, b, m)[0] for x in (0.0, 0.1 * b * p_up, b * p_up)]
    assert q[0] == q[1] == q[2] == pytest.approx(C * 1.185 * p_up * math.sqrt(293.15 / T))


def test_iso_6358_is_C1_and_reverses_through_zero():
    C, b, T, pb = 3e-9, 0.4, 293.15, 2e5
    prl = 0.999
    # pressures across zero flow, the laminar-band edge and the choking point
    pa = np.concatenate([np.linspace(pb * 0.98, pb * 1.02, 401),
                         pb / prl * np.array([1 - 1e-9, 1 + 1e-9]),
                         pb / b * np.array([1 - 1e-9, 1 + 1e-9])])
    q, dqa, dqb = massflow_ISO_6358(pa, pb, T, C, b, 0.5, prl)
    assert q[200] == 0.0 and (np.diff(q[:401]) > 0).all()
    for i in (401, 403):   # both sides of each edge: value and slope continuous
        step = pa[i + 1] - pa[i]
        assert abs(q[i + 1] - q[i]) <= 1.01 * max(abs(dqa[i]), abs(dqa[i + 1])) * step
        assert abs(dqa[i + 1] - dqa[i]) <= 1e-5 * abs(dqa).max()
    h = 1e-2
    fd_a = (massflow_ISO_6358(pa + h, pb, T, C, b)[0] - massflow_ISO_6358(pa - h, pb, T, C, b)[0]) / (2 * h)
    fd_b = (massflow_ISO_6358(pa, pb + h, T, C, b)[0] - massflow_ISO_6358(pa, pb - h, T, C, b)[0]) / (2 * h)
    sl = np.abs(dqa).max()
    # (rtol 1e-4: one point of the grid sits on the band edge, where f'' jumps)
    np.testing.assert_allclose(dqa[:401], fd_a[:401], rtol=1e-4, atol=1e-7 * sl)
    np.testing.assert_allclose(dqb[:401], fd_b[:401], rtol=1e-4, atol=1e-7 * sl)
    # the slope at zero flow is finite and positive
    assert 0 < dqa[200] < np.inf


# ---------------------------------------------------------------------------------------
# network runs
# ---------------------------------------------------------------------------------------
def _between_sources(comp, p_a, p_b):
    s = sf.System()
    s += sf.PressureSource("pa", pressure=p_a)
    s += comp
    s += sf.PressureSource("pb", pressure=p_b)
    s.connect((comp.label, "a"), "pa")
    s.connect((comp.label, "b"), "pb")
    return s


def _steady_flow(comp, p_a, p_b):
    res = sf.Simulation(_between_sources(comp, p_a, p_b), duration=1e-2, step=5e-3).run()
    mf_a, mf_b = res.get(comp.label, "massflow", "a"), res.get(comp.label, "massflow", "b")
    np.testing.assert_allclose(mf_a + mf_b, 0.0, atol=1e-15)
    return mf_a[-1]


@pytest.mark.parametrize("fluid", [sf.water, sf.air], ids=lambda f: f.name)
def test_orifice_steady_flow_matches_the_orifice_equation(fluid):
    d, Cd, dp = 0.8e-3, 0.62, 2e3
    got = _steady_flow(Orifice("o", fluid, diameter=d, Cd=Cd), P0 + dp, P0)
    incompressible = fluids.flow_meter_discharge(D=1e3 * d, Do=d, P1=P0 + dp, P2=P0,
                                                 rho=float(fluid.density(P0 + dp)), C=Cd)
    # a gas's Cd orifice is the isentropic nozzle: the same equation times ISO
    # 5167-3's expansibility factor of a nozzle (beta -> 0; 0.989 here)
    eps = (fluids.nozzle_expansibility(D=1e3 * d, Do=d, P1=P0 + dp, P2=P0,
                                       k=float(fluid.gamma(P0)))
           if fluid.compressible else 1.0)
    want = incompressible * eps
    assert got == pytest.approx(want, rel=1e-9)
    # reversed: same magnitude (water), upstream density at b (air)
    back = _steady_flow(Orifice("o", fluid, diameter=d, Cd=Cd), P0, P0 + dp)
    assert back == pytest.approx(-want, rel=1e-9)
    # K form with K = 1/Cd^2 is the incompressible law: the same device for a liquid
    assert _steady_flow(Orifice("o", fluid, diameter=d, K=1 / Cd ** 2), P0 + dp, P0) == \
        pytest.approx(incompressible, rel=1e-9)


def test_iso_orifice_choked_flow_is_independent_of_downstream_pressure():
    C, b = sf.Q_(0.3, "dm**3/(s*bar)"), 0.45
    p_up = 6e5
    choked = [_steady_flow(Orifice("o", sf.air, C=C, b=b), p_up, p) for p in (1e5, 2e5, 2.6e5)]
    want = 0.3e-3 / 1e5 * 1.185 * p_up * math.sqrt(293.15 / sf.air.temperature)
    np.testing.assert_allclose(choked, want, rtol=1e-9)
    sub = _steady_flow(Orifice("o", sf.air, C=C, b=b), p_up, 4.5e5)
    assert sub == pytest.approx(want * math.sqrt(1 - ((0.75 - b) / (1 - b)) ** 2), rel=1e-9)
    assert sub < 0.9 * want


def test_iso_orifice_discharges_a_tank_to_equilibrium_conserving_mass():
    s = sf.System()
    s += sf.Container("c1", sf.air, volume=5e-6, initial_pressure=5e5)
    s += Orifice("o", sf.air, C=1e-9, b=0.4)
    s += sf.Container("c2", sf.air, volume=10e-6, initial_pressure=P0)
    s.connect(("o", "a"), "c1")
    s.connect(("o", "b"), "c2")
    res = sf.Simulation(s, duration=1.0).run()
    m = res.get("c1", "mass") + res.get("c2", "mass")
    assert np.abs(m - m[0]).max() < 1e-9 * m[0]
    p1, p2 = res.get("c1", "pressure"), res.get("c2", "pressure")
    p_eq = (5e5 * 5e-6 + P0 * 10e-6) / 15e-6
    assert p1[-1] == pytest.approx(p_eq, rel=1e-4) and p2[-1] == pytest.approx(p_eq, rel=1e-4)
    # choked at first: the initial flow is C rho0 p_up sqrt(T0/T), whatever c2 holds
    mf = res.get("o", "massflow", "a")
    assert mf[0] == pytest.approx(1e-9 * 1.185 * 5e5, rel=1e-9)


def _sine_source(amplitude, period):
    return lambda t: P0 + amplitude * math.sin(2 * math.pi * t / period)


@pytest.mark.parametrize("fluid", [sf.air, sf.water], ids=lambda f: f.name)
def test_check_valve_blocks_reverse_flow(fluid):
    s = sf.System()
    s += sf.PressureSource("src", pressure=_sine_source(3e4, 0.2))
    s += CheckValve("cv", fluid, diameter=0.3e-3, cracking_pressure=2e3, opening_band=1e3)
    if fluid.compressible:
        s += sf.Container("c", fluid, volume=2e-6)
    else:
        s += sf.LinearAccumulator("c", fluid, volume=1e-6, compliance=2e-13)
    s.connect(("cv", "a"), "src")
    s.connect(("cv", "b"), "c")
    res = sf.Simulation(s, duration=0.6).run()
    mf = res.get("cv", "massflow", "a")
    assert mf.max() > 1e-6
    # no backflow (no leakage) beyond Newton's tolerance (rtol / 20 = 5e-5 of
    # the largest flow)
    assert mf.min() >= -5e-5 * mf.max()
    m = res.get("c", "mass")
    # the chamber only fills (higher BDF orders overshoot where the valve closes:
    # within the error test's tolerance, rtol 1e-3 of the mass)
    assert (np.diff(m) >= -1e-3 * m.max()).all()
    # it ends within the opening band below the source's peak minus the cracking pressure
    p_end = res.get("c", "pressure")[-1]
    assert P0 + 3e4 - 2e3 - 1e3 <= p_end <= P0 + 3e4 - 2e3


def test_check_valve_leakage_lets_a_little_flow_back():
    tight = _steady_flow(CheckValve("cv", sf.water, diameter=1e-3), P0, P0 + 1e4)
    leaky = _steady_flow(CheckValve("cv", sf.water, diameter=1e-3, leakage=1e-12), P0,
                         P0 + 1e4)
    assert tight == 0.0
    assert leaky == pytest.approx(-sf.water.rho * 1e-12 * 1e4, rel=1e-12)


@pytest.mark.parametrize("fluid", [sf.water, sf.air], ids=lambda f: f.name)
def test_tesla_valve_is_more_resistive_backward(fluid):
    kw = dict(length=0.2, diameter=0.5e-3, diodicity=4.0)
    dp = 2e4 if fluid is sf.water else 2e3      # laminar both ways, backward Re > Re_blend
    fwd = _steady_flow(TeslaValve("tv", fluid, **kw), P0 + dp, P0)
    bwd = _steady_flow(TeslaValve("tv", fluid, **kw), P0, P0 + dp)
    tube = _steady_flow(sf.CircularTube("t", fluid, length=0.2, diameter=0.5e-3), P0 + dp, P0)
    assert fwd == pytest.approx(tube, rel=1e-9)
    assert bwd < 0 and abs(bwd) < fwd
    # laminar and beyond the blend band: the backward friction is exactly Di times
    # the forward one, that of a tube Di times as long
    long_tube = _steady_flow(sf.CircularTube("t", fluid, length=0.8, diameter=0.5e-3),
                             P0 + dp, P0)
    assert abs(bwd) == pytest.approx(long_tube, rel=1e-9)
    # so the flow is Di times smaller, up to a gas's entry acceleration, which the
    # diodicity leaves as it is (rho u^2/2, 0.54 % of the 2 kPa here)
    assert abs(bwd) == pytest.approx(fwd / 4.0, rel=1e-6 if fluid is sf.water else 6e-3)
    # turbulent: dp_back = Di dp_fwd at equal flow, so the flow falls less than Di-fold
    dpt = 2e5
    fwd_t = _steady_flow(TeslaValve("tv", sf.water, **kw), P0 + dpt, P0)
    bwd_t = _steady_flow(TeslaValve("tv", sf.water, **kw), P0, P0 + dpt)
    assert fwd_t / 4.0 < abs(bwd_t) < fwd_t
    back_dp = _steady_flow(TeslaValve("tv", sf.water, **kw), P0, P0 + 4.0 * dpt)
    assert back_dp == pytest.approx(-fwd_t, rel=1e-6)


def _two_tanks(restrictor):
    s = sf.System()
    s += sf.Container("c1", sf.air, volume=5e-6, initial_pressure=3e5)
    s += restrictor
    s += sf.Container("c2", sf.air, volume=20e-6, initial_pressure=P0)
    s.connect((restrictor.label, "a"), "c1")
    s.connect((restrictor.label, "b"), "c2")
    return s


def test_tesla_valve_with_diodicity_one_is_a_circular_tube():
    kw = dict(length=0.5, diameter=1e-3)
    a = sf.Simulation(_two_tanks(TeslaValve("r", sf.air, diodicity=1.0, **kw)),
                      duration=0.2, step=1e-3).run()
    b = sf.Simulation(_two_tanks(sf.CircularTube("r", sf.air, **kw)), duration=0.2,
                      step=1e-3).run()
    for label in ("c1", "c2"):
        np.testing.assert_allclose(a.get(label, "pressure"), b.get(label, "pressure"),
                                   rtol=1e-12)
    np.testing.assert_allclose(a.get("r", "massflow", "a"), b.get("r", "massflow", "a"),
                               rtol=1e-9, atol=1e-15)


def test_tesla_valve_empties_backward_more_slowly():
    def final_gap(a_side_high):
        tv = TeslaValve("r", sf.air, length=0.5, diameter=1e-3, diodicity=3.0)
        s = sf.System()
        s += sf.Container("c1", sf.air, volume=5e-6, initial_pressure=3e5 if a_side_high else P0)
        s += tv
        s += sf.Container("c2", sf.air, volume=5e-6, initial_pressure=P0 if a_side_high else 3e5)
        s.connect(("r", "a"), "c1")
        s.connect(("r", "b"), "c2")
        res = sf.Simulation(s, duration=0.05).run()
        return abs(res.get("c1", "pressure")[-1] - res.get("c2", "pressure")[-1])
    assert final_gap(False) > 2 * final_gap(True)


def _triangle(peak, t_up, t_end):
    def p(t):
        return P0 + peak * (t / t_up if t < t_up else max(0.0, (t_end - t) / (t_end - t_up)))
    p.breakpoints = (t_up,)
    return p


def snapping_scene(fluid=sf.air, **kw):
    """Source pressure ramps up and down; the valve feeds a chamber."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=_triangle(6e4, 1.0, 2.0))
    params = dict(opening_pressure=1e4, closing_pressure=2e3, closed_conductance=2e-12,
                  length=0.01, diameter=1e-3)
    params.update(kw)
    s += SnappingValve("sv", fluid, **params)
    s += sf.Container("c", fluid, volume=10e-6)
    s.connect(("sv", "a"), "src")
    s.connect(("sv", "b"), "c")
    return s


def test_snapping_valve_bursts_on_inflation_with_hysteresis():
    res = sf.Simulation(snapping_scene(), duration=2.0).run()
    t = res.times
    dp = res.get("src", "pressure") - res.get("c", "pressure")
    mode = res.get("sv", "open")
    assert set(np.unique(mode)) == {0.0, 1.0}
    # the mode after each step follows the hysteresis rule from that step's dp
    for i in range(1, len(t)):
        want = 1.0 if dp[i] > 1e4 else 0.0 if dp[i] < 2e3 else mode[i - 1]
        assert mode[i] == want, (t[i], dp[i], mode[i - 1], mode[i])
    # a hysteresis loop: inside the band the valve is seen both open and closed
    band = (dp > 2e3) & (dp < 1e4)
    assert (mode[band] == 1).any() and (mode[band] == 0).any()
    # bursts: several openings while the source rises, none while it falls
    openings = t[1:][np.diff(mode) > 0]
    assert len(openings) >= 4 and (openings < 1.0).all()
    # the step ending at t[i] ran with the mode recorded at t[i - 1]
    mf = res.get("sv", "massflow", "a")[1:]
    ran_open, rising = mode[:-1] == 1, t[1:] < 1.0
    assert mf[ran_open].max() > 100 * np.abs(mf[~ran_open & rising]).max()
    # mass balance: what left the source is in the chamber
    supplied = -res.integral("src", "massflow")
    m = res.get("c", "mass")
    assert np.abs((m - m[0]) - supplied).max() < 1e-9 * m[0]
    np.testing.assert_allclose(mf + res.get("sv", "massflow", "b")[1:], 0.0, atol=1e-15)


def test_snapping_valve_is_a_tight_restrictor_on_deflation():
    res = sf.Simulation(snapping_scene(), duration=2.0).run()
    t = res.times
    pa, pb = res.get("src", "pressure"), res.get("c", "pressure")
    dp = pa - pb
    mode = res.get("sv", "open")
    late = t > 1.2
    assert (dp[late] < 0).all() and (mode[late] == 0).all()
    # backflow through the closed valve follows the tight linear law
    mf = res.get("sv", "massflow", "a")
    rho_m = sf.air.density(0.5 * (pa + pb))
    # (to the Newton tolerance, rtol / 20 of the gauge pressures: within 1e-3 of
    # the largest backflow)
    want = rho_m[late] * 2e-12 * dp[late]
    np.testing.assert_allclose(mf[late], want, rtol=0, atol=1e-3 * np.abs(want).max())
    # so the chamber lags far behind the source when it deflates
    assert pb[-1] - pa[-1] > 3e4


def test_snapping_valve_kernel_uses_the_mode_from_the_start_of_the_step():
    sv = SnappingValve("sv", sf.water, opening_pressure=1e4, closing_pressure=2e3,
                       closed_conductance=1e-12)
    P = SnappingValve.make_params([sv, sv])
    V = np.array([[P0 + 5e4, 1e-3, P0, -1e-3]] * 2)   # far above the opening threshold
    S = np.array([[0.0], [1.0]])
    F, _ = SnappingValve.kernel(P, V, S, 0.0, 1e-3, False)
    # closed instance: the tight law, whatever dp says
    assert F[0, 1] == pytest.approx(5e4 - 1e-3 / (sf.water.rho * 1e-12))
    assert F[1, 1] != F[0, 1]
    S_new = SnappingValve.update(P, V, S, 1e-3)
    np.testing.assert_array_equal(S_new, [[1.0], [1.0]])
    V[:, 0] = P0 + 5e3                                  # inside the band: keep the mode
    np.testing.assert_array_equal(SnappingValve.update(P, V, S, 1e-3), S)
    V[:, 0] = P0 - 1e3                                  # below closing
    np.testing.assert_array_equal(SnappingValve.update(P, V, S, 1e-3), [[0.0], [0.0]])


def test_snapping_valve_results_do_not_depend_on_newton_tolerance():
    a = sf.Simulation(snapping_scene(), duration=1.0, step=2e-3).run()
    b = sf.Simulation(snapping_scene(), duration=1.0, step=2e-3, newton_rtol=1e-10).run()
    np.testing.assert_array_equal(a.get("sv", "open"), b.get("sv", "open"))
    np.testing.assert_allclose(a.get("c", "pressure"), b.get("c", "pressure"), rtol=1e-5)


# ---------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------
W = sf.water
BAD = [
    (lambda: Orifice("o", W, diameter=0.0, Cd=0.6), "diameter"),
    (lambda: Orifice("o", W, diameter=-1e-3, K=2.0), "diameter"),
    (lambda: Orifice("o", W, diameter=1e-3, K=0.0), "K"),
    (lambda: Orifice("o", W, diameter=1e-3, Cd=1.2), "Cd"),
    (lambda: Orifice("o", W, diameter=1e-3, Cd=-0.6), "Cd"),
    (lambda: Orifice("o", W, diameter=1e-3), "exactly one of K"),
    (lambda: Orifice("o", W, diameter=1e-3, K=2.0, Cd=0.6), "exactly one of K"),
    (lambda: Orifice("o", W, Cd=0.6), "diameter"),
    (lambda: Orifice("o", W, diameter=sf.Q_(1, "bar"), Cd=0.6), "diameter"),
    (lambda: Orifice("o", W, diameter=1e-3, Cd=0.6, b=0.5), "b"),
    (lambda: Orifice("o", W, C=1e-9, b=0.5), "incompressible"),
    (lambda: Orifice("o", sf.air, C=1e-9), "b"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=0.0), "b"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=1.0), "b"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=-0.2), "b"),
    (lambda: Orifice("o", sf.air, C=-1e-9, b=0.5), "C"),
    (lambda: Orifice("o", sf.air, C=sf.Q_(1, "m**3/s"), b=0.5), "C"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=0.5, m=0.0), "m"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=0.5, m=1.5), "m"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=0.5, pr_laminar=1.0), "pr_laminar"),
    (lambda: Orifice("o", sf.air, C=1e-9, b=0.5, diameter=1e-3), "diameter"),
    (lambda: Orifice("o", "water", diameter=1e-3, Cd=0.6), "fluid"),
    (lambda: CheckValve("o", W, diameter=1e-3, cracking_pressure=-1.0), "cracking_pressure"),
    (lambda: CheckValve("o", W, diameter=1e-3, cracking_pressure=sf.Q_(-0.1, "bar")),
     "cracking_pressure"),
    (lambda: CheckValve("o", W, diameter=0.0), "diameter"),
    (lambda: CheckValve("o", W, diameter=1e-3, opening_band=0.0), "opening_band"),
    (lambda: CheckValve("o", W, diameter=1e-3, leakage=-1e-12), "leakage"),
    (lambda: CheckValve("o", W, diameter=1e-3, Cd=1.5), "Cd"),
    (lambda: TeslaValve("o", W, length=0.1, diameter=1e-3, diodicity=0.5), "diodicity"),
    (lambda: TeslaValve("o", W, length=0.0, diameter=1e-3), "length"),
    (lambda: TeslaValve("o", W, length=0.1, diameter=-1e-3), "diameter"),
    (lambda: TeslaValve("o", W, length=0.1, diameter=1e-3, Re_blend=0.0), "Re_blend"),
    (lambda: TeslaValve("o", W, length=0.1, diameter=1e-3, Re_laminar=5e3), "Re_turbulent"),
    (lambda: SnappingValve("o", W, opening_pressure=1e4, closing_pressure=2e4,
                           closed_conductance=1e-12), "closing_pressure.*opening_pressure"),
    (lambda: SnappingValve("o", W, opening_pressure=1e4, closing_pressure=1e4,
                           closed_conductance=1e-12), "closing_pressure.*opening_pressure"),
    (lambda: SnappingValve("o", W, opening_pressure=-1e4, closing_pressure=-2e4,
                           closed_conductance=1e-12), "opening_pressure"),
    (lambda: SnappingValve("o", W, opening_pressure=1e4, closing_pressure=0.0,
                           closed_conductance=0.0), "closed_conductance"),
    (lambda: SnappingValve("o", W, opening_pressure=1e4, closing_pressure=0.0,
                           closed_conductance=1e-12, diameter=0.0), "diameter"),
]


@pytest.mark.parametrize("make,param", BAD, ids=[f"{i}-{p}" for i, (_, p) in enumerate(BAD)])
def test_bad_input_names_component_and_parameter(make, param):
    with pytest.raises((ValueError, TypeError)) as err:
        make()
    msg = str(err.value)
    assert "'o'" in msg
    assert __import__("re").search(param, msg), msg


def test_parameters_accept_quantities():
    sv = SnappingValve("s", W, opening_pressure=sf.Q_(0.2, "bar"),
                       closing_pressure=sf.Q_(50, "mbar"),
                       closed_conductance=sf.Q_(1, "ml/(s*bar)"), length=sf.Q_(1, "cm"),
                       diameter=sf.Q_(2, "mm"))
    assert sv.opening_pressure == pytest.approx(2e4)
    assert sv.closing_pressure == pytest.approx(5e3)
    assert sv.closed_conductance == pytest.approx(1e-11)
    cv = CheckValve("c", W, diameter=sf.Q_(1, "mm"), cracking_pressure=sf.Q_(0.1, "bar"),
                    leakage=sf.Q_(1e-3, "ml/(s*bar)"))
    assert cv.cracking_pressure == pytest.approx(1e4) and cv.leakage == pytest.approx(1e-14)
    o = Orifice("o", sf.air, C=sf.Q_(1, "dm**3/(s*bar)"), b=0.5)
    assert o.C == pytest.approx(1e-8)


def test_iso_6358_law_on_a_mixed_batch_equals_each_flow_on_its_own():
    """Flows that all go one way take a shorter path through the law (no
    selections), one that goes the other way or a laminar one the full path:
    bitwise the same numbers either way, flow by flow."""
    rng = np.random.default_rng(4)
    n = 24
    p_a = rng.uniform(1e5, 8e5, n)
    ratio = np.concatenate([rng.uniform(0.0, 0.4, 6),          # choked
                            rng.uniform(0.4, 0.99, 6),         # subsonic
                            rng.uniform(0.9995, 1.0, 6),       # laminar band
                            rng.uniform(1.0, 3.0, 6)])         # reversed
    p_b = p_a * ratio
    C, b = rng.uniform(1e-9, 1e-7, n), rng.uniform(0.1, 0.6, n)
    m, prl = rng.uniform(0.3, 1.0, n), np.full(n, 0.999)
    batch = massflow_ISO_6358(p_a, p_b, 293.15, C, b, m, prl)
    for i in range(n):
        one = massflow_ISO_6358(p_a[i:i + 1], p_b[i:i + 1], 293.15, C[i:i + 1], b[i:i + 1],
                                m[i:i + 1], prl[i:i + 1])
        for whole, alone in zip(batch, one):
            assert whole[i] == alone[0]


def _custom_gas():
    """An ideal gas whose density is a method of its own (its values the ideal
    gas's): the valves take it from the fluid, not from R T."""
    class OwnDensity(sf.IdealGas):
        def density(self, p, T=None):
            return super().density(p, T)
    return OwnDensity("own", sf.air.molar_mass, sf.air.mu)


@pytest.mark.parametrize("fluid, compiled", [
    (sf.air, True), (sf.water, True), (sf.ethylene_glycol, True),
    (sf.water.with_level("table"), True), (sf.air.with_level("table"), False),
    (_custom_gas(), False)], ids=["air", "water", "glycol", "water-table", "air-table", "own"])
def test_valves_make_their_densities_where_the_fluid_allows(fluid, compiled):
    """A valve group's flow law makes its densities in its compiled pass for an
    ideal gas (p/(R T)) and an incompressible fluid (its constant density)
    (P.compiled), else takes them from the fluid's methods (table, eos, a
    density of the fluid's own); ISO 6358 takes none."""
    groups = [[Orifice("o", fluid, diameter=1e-3, K=2.0)],
              [CheckValve("c", fluid, diameter=1e-3)],
              [TeslaValve("t", fluid, 0.1, 1e-3)],
              [SnappingValve("s", fluid, 2e4, 5e3, 1e-11)]]
    if fluid.compressible:
        groups += [[Orifice("o", fluid, diameter=1e-3, Cd=0.6)],
                   [Orifice("o", fluid, C=1e-9, b=0.3)]]
    for comps in groups:
        P = type(comps[0]).make_params(comps)
        assert P.compiled is compiled
        if compiled:
            assert (P.law_RT > 0) is fluid.compressible
            assert P.law_RT == (fluid.R * fluid.temperature if fluid.compressible else 0.0)
            assert P.law_rho == (0.0 if fluid.compressible else fluid.rho)


@pytest.mark.parametrize("fluid", [sf.water, sf.ethylene_glycol, sf.air,
                                   sf.air.with_level("table")],
                         ids=["water", "glycol", "air", "air-table"])
def test_one_snapping_valve_is_its_row_of_a_group_bitwise(fluid):
    """A group of one snapping valve runs the group's compiled pass: its residual,
    Jacobian and switch are its row of a larger group's, bitwise (signed zeros
    and NaN included), in both modes, at flows laminar, in the blend and
    turbulent, at zero and (but for the table, which refuses them) non-finite
    values, for roughnesses whose Haaland term NumPy's scalar ** gives one ulp
    off its ufunc (made once, on the group's array)."""
    for roughness in (1.5e-6, 9.60775e-07, 4.11875e-07, 2.71e-5):
        def valve(label):
            return SnappingValve(label, fluid, opening_pressure=5e3, closing_pressure=1e3,
                                 closed_conductance=1e-10, length=0.05, diameter=2e-3,
                                 roughness=roughness)
        one = SnappingValve.make_params([valve("v")])
        three = SnappingValve.make_params([valve("u"), valve("v"), valve("w")])
        _one_valve_matches_its_row(one, three, finite=fluid.level == "table")


def _same_bits(a, b):
    """Equal shape, dtype and bytes (0.0 against -0.0 differ), NaN where NaN."""
    a, b = np.asarray(a), np.asarray(b)
    nan = np.isnan(a) & np.isnan(b)
    return (a.shape == b.shape and a.dtype == b.dtype
            and np.where(nan, 0.0, a).tobytes() == np.where(nan, 0.0, b).tobytes())


def _one_valve_matches_its_row(one, three, finite):
    reynolds = [0.0, 1e3, 2300.0, 3e3, 4000.0, -2e5] + np.geomspace(5e3, 1e6, 40).tolist()
    points = [(2.0e5, re / one.re_per_mf[0], 1.9e5) for re in reynolds]
    points += [(1.0e5, 1e-4, 1.0e5 + 3e3), (1e5 + 5e3, 0.0, 1e5), (1e5 + 1e3, 0.0, 1e5),
               (1e5, -0.0, 1e5)]
    if not finite:
        points += [(0.0, 1e-4, 0.0), (np.nan, 1e-4, 1e5), (1e5, np.nan, 1e5)]
    with np.errstate(all="ignore"):
        for pa, mf, pb in points:
            V = np.array([[pa, mf, pb, -0.9 * mf]])
            V3 = np.array([[1.3e5, 1e-4, 1.1e5, 0.0], V[0], [1.1e5, -1e-5, 1.3e5, 0.0]])
            for mode in (0.0, 1.0):
                S = np.array([[mode]])
                S3 = np.array([[1.0 - mode], [mode], [1.0 - mode]])
                got = [SnappingValve.residual(one, V, S, 0.0, jac) for jac in (False, True)]
                got.append((SnappingValve.switch(one, V, S), None))
                want = [SnappingValve.residual(three, V3, S3, 0.0, jac) for jac in (False, True)]
                want.append((SnappingValve.switch(three, V3, S3), None))
                for (a, da), (b, db) in zip(got, want):
                    assert _same_bits(a, b[1:2]), (pa, mf, pb, mode, a, b)
                    assert (da is None) == (db is None)
                    if da is not None:
                        assert _same_bits(da, db[1:2]), (pa, mf, pb, mode, da, db)


def test_check_valve_regime_separates_shut_opening_and_open():
    """CheckValve.regime (the pieces Newton keeps a Jacobian on): shut (s <= 0,
    s the position in the opening band), the band's bottom REGIME_EDGE in
    pieces a factor 4 apart in s (the smoothstep's slope grows as 6 s there:
    a Jacobian from one of them is within 4x of the slope anywhere in it), its
    steep middle, open past 1 - REGIME_EDGE; the thermal variant reads the
    same pressures from its own columns."""
    from softflow.components.thermal import thermal_class
    from softflow.components.valves import LOW_PIECES, REGIME_EDGE
    v = CheckValve("c", sf.air, diameter=1e-3, cracking_pressure=1e4, opening_band=1e3)
    s = np.array([-50.0, 0.0, 1e-11, 1e-9, REGIME_EDGE / 4.1, REGIME_EDGE / 3.9,
                  0.99 * REGIME_EDGE, REGIME_EDGE, 0.5, 1 - 1.1 * REGIME_EDGE,
                  1 - 0.9 * REGIME_EDGE, 1.0, 20.0, np.nan])
    P = CheckValve.make_params([v] * s.size)
    pb = 1e5
    V = np.array([[pb + 1e4 + x * 1e3, 1e-4, pb, -1e-4] for x in s])
    pieces = CheckValve.regime(P, V)
    assert pieces.tolist() == [-LOW_PIECES - 1, -LOW_PIECES - 1, -LOW_PIECES, -13, -2, -1,
                               -1, 0, 0, 0, 1, 1, 1, 0]
    # each piece of the bottom spans a factor 4 in s, its slope 6 s (1 - s) < 4.2x
    inside = (s > 0) & (s < REGIME_EDGE)
    for k in set(pieces[inside].tolist()) - {-LOW_PIECES}:
        lo, hi = REGIME_EDGE * 4.0 ** k, REGIME_EDGE * 4.0 ** (k + 1)
        ends = np.array([[pb + 1e4 + x * 1e3, 0.0, pb, 0.0] for x in (1.001 * lo, 0.999 * hi)])
        assert CheckValve.regime(CheckValve.make_params([v] * 2), ends).tolist() == [k, k]
        assert (6 * hi * (1 - hi)) / (6 * lo * (1 - lo)) < 4.2
    thermal = thermal_class(CheckValve)
    Vt = np.zeros((s.size, 8))
    Vt[:, [0, 1, 4, 5]] = V
    Vt[:, [2, 6]] = 293.15          # temperatures where the isothermal V has p_b
    assert thermal.regime(P, Vt).tolist() == pieces.tolist()


def test_check_valve_kinks_are_where_the_smoothstep_ends():
    """CheckValve.kinks: shut (dp at or below the cracking pressure), inside the
    opening band, open (at or past its top): the points where the law's
    second derivative jumps; the thermal variant reads its own columns."""
    from softflow.components.thermal import thermal_class
    v = CheckValve("c", sf.air, diameter=1e-3, cracking_pressure=1e4, opening_band=1e3)
    dp = np.array([-3e4, 1e4, 1e4 + 1e-6, 1.05e4, 1.1e4 - 1e-6, 1.1e4, 5e4])
    P = CheckValve.make_params([v] * dp.size)
    V = np.array([[1e5 + d, 0.0, 1e5, 0.0] for d in dp])
    assert CheckValve.kinks(P, V).tolist() == [0, 0, 1, 1, 1, 2, 2]
    Vt = np.zeros((dp.size, 8))
    Vt[:, [0, 1, 4, 5]] = V
    Vt[:, [2, 6]] = 293.15
    assert thermal_class(CheckValve).kinks(P, Vt).tolist() == [0, 0, 1, 1, 1, 2, 2]


def test_check_valve_regime_of_one_valve_is_the_array_paths():
    """CheckValve.regime's one-valve path (Python floats) gives the array
    path's piece at 4 000 random band positions, the bottom's log pieces and
    the edges (0, -0, REGIME_EDGE, 1 - REGIME_EDGE, NaN, 1e-300)."""
    from softflow.components.valves import REGIME_EDGE
    v = CheckValve("c", sf.air, diameter=1e-3, cracking_pressure=1e4, opening_band=1e3)
    rng = np.random.default_rng(1)
    s = np.r_[rng.uniform(-2, 2, 2000), 10 ** rng.uniform(-14, 0, 2000) * REGIME_EDGE * 1.5,
              [0.0, -0.0, REGIME_EDGE, 1 - REGIME_EDGE, np.nan, 1e-300]]
    V = np.array([[1.1e5 + x * 1e3, 0.0, 1e5, 0.0] for x in s])
    every = CheckValve.regime(CheckValve.make_params([v] * s.size), V)
    one = CheckValve.make_params([v])
    assert [int(CheckValve.regime(one, V[i:i + 1])[0]) for i in range(s.size)] == every.tolist()
    assert len(set(every.tolist())) > 10


def _tesla_fill(valve, pressure=None):
    s = sf.System()
    s += sf.PressureSource("src", pressure=pressure or (lambda t: 3e5 if t < 0.01 else 0.5e5))
    s += valve
    s += sf.Container("tank", sf.air, volume=2e-5)
    s.connect("src", (valve.label, "a"))
    s.connect((valve.label, "b"), "tank")
    return s


def _same_adiabatic_run_as_its_tube(valve):
    """``valve`` (a passage 0.1 m x 1.5 mm) and the tube of that passage fill a
    tank and let it back out (_tesla_fill) in an adiabatic scene: the same run,
    to 1e-6 of the tank's pressure and temperature. Returns the valve's run."""
    runs = [sf.Simulation(_tesla_fill(v), duration=0.03, thermal="adiabatic").run()
            for v in (valve, sf.CircularTube("tv", sf.air, length=0.1, diameter=1.5e-3))]
    for name in ("pressure", "temperature"):
        np.testing.assert_allclose(runs[0].get("tank", name), runs[1].get("tank", name),
                                   rtol=1e-6)
    return runs[0]


def _thermal_sensitivities_match_differences(valve, names):
    """The adiabatic fill's sensitivities to ``names`` ((parameter, value)) against
    central differences of whole runs at fixed steps (relative step 1e-5): the
    tank's pressure and temperature and the valve's flow within 1e-6 of the
    largest."""
    sim = sf.Simulation(_tesla_fill(valve), duration=0.03, step=1e-3, newton_rtol=1e-12,
                        thermal="adiabatic")
    res = sim.run(sensitivities=[n for n, _ in names])
    for key, value in names:
        h = 1e-5 * value
        up, down = sim.run(params={key: value + h}), sim.run(params={key: value - h})
        for label, var in (("tank", "pressure"), ("tank", "temperature"), ("tv", "massflow_a")):
            fd = (up.get(label, var) - down.get(label, var)) / (2 * h)
            err = np.abs(res.sensitivity(label, var, key) - fd).max() / np.abs(fd).max()
            assert err < 1e-6, (key, label, var, err)


def test_a_thermal_tesla_valve_is_the_tubes_adiabatic_law():
    """In an adiabatic scene a gas's Tesla valve is adiabatic (Fanno) pipe flow
    with its friction term, as a tube is: with diodicity 1 it is the tube, to
    Newton's tolerance, forward and back (the source falls below the tank)."""
    mf = _same_adiabatic_run_as_its_tube(
        TeslaValve("tv", sf.air, length=0.1, diameter=1.5e-3, diodicity=1.0)
    ).get("tv", "massflow_a")
    assert mf.max() > 0 > mf.min()


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_a_thermal_tesla_valves_sensitivities_are_its_adiabatic_laws():
    """The thermal Tesla valve's parameter derivatives (through its friction
    term, into the adiabatic law), forward and back: length, diameter and
    diodicity within 1e-6 (measured <= 1.6e-7)."""
    _thermal_sensitivities_match_differences(
        TeslaValve("tv", sf.air, length=0.1, diameter=1.5e-3, diodicity=3.0),
        [("tv.length", 0.1), ("tv.diameter", 1.5e-3), ("tv.diodicity", 3.0)])


def _open_snapping_valve():
    # opens at 1 kPa, closes below -10 bar: open all through the runs below
    return SnappingValve("tv", sf.air, opening_pressure=1e3, closing_pressure=-1e6,
                         closed_conductance=1e-12, length=0.1, diameter=1.5e-3,
                         initially_open=True)


def test_an_open_thermal_snapping_valve_is_the_tubes_adiabatic_law():
    """In an adiabatic scene an open snapping valve of a gas is its passage's
    adiabatic (Fanno) pipe flow, as a tube of that passage is: the same run to
    1e-6, forward and back."""
    run = _same_adiabatic_run_as_its_tube(_open_snapping_valve())
    assert np.all(run.get("tv", "open") == 1.0)


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_an_open_thermal_snapping_valves_sensitivities_are_its_adiabatic_laws():
    """Its passage's length and diameter through the adiabatic law's friction
    term: within 1e-6."""
    _thermal_sensitivities_match_differences(
        _open_snapping_valve(), [("tv.length", 0.1), ("tv.diameter", 1.5e-3)])
