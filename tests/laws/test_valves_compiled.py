"""The compiled valve laws (softflow.laws.valves): the scalar laws' partials
against central differences in every regime (an orifice's band, subsonic and
choked flow, a check valve shut, opening and open, a Tesla valve's blend and
both directions, a snapping valve's passage and restrictor); each valve
group's compiled pass against the same law written here on the array
functions of softflow.correlations and softflow.components.tubes (ideal gas,
a gas at the table level, a liquid; groups of one and four; every regime);
the pure-Python mode (NUMBA_DISABLE_JIT=1) giving the compiled numbers."""
import math

import numpy as np
import pytest

import softflow as sf
from helpers import compiled_and_python
from softflow.components import tubes
from softflow.components.valves import CheckValve, Orifice, SnappingValve, TeslaValve
from softflow.correlations.friction import fRe_blended, smoothstep
from softflow.correlations.orifice import (ISO_6358_RHO0, ISO_6358_T0, massflow_ISO_6358,
                                           massflow_loss_coefficient, massflow_nozzle)
from softflow.laws import friction as fl
from softflow.laws import valves as law

P0 = sf.pressure_atmospheric
RT_AIR = float(sf.air.R * sf.air.temperature)
RHO_WATER = float(sf.water.rho)
HAALAND = fl.HAALAND


# ---------------------------------------------------------------------------------------
# the scalar laws' partials against central differences
# ---------------------------------------------------------------------------------------
def _check_partials(f, x, steps, rtol=1e-6, atol_rel=1e-8):
    """f(*x) -> (value, d/dx[0], d/dx[1], ...) for the first len(steps) arguments,
    against central differences with those steps (the step actually taken)."""
    got = f(*x)
    scale = max(abs(g) for g in got[1:1 + len(steps)])
    for k, h in enumerate(steps):
        up, down = list(x), list(x)
        up[k] += h
        down[k] -= h
        fd = (f(*up)[0] - f(*down)[0]) / (up[k] - down[k])
        assert got[1 + k] == pytest.approx(fd, rel=rtol, abs=atol_rel * scale + 1e-300), \
            (k, x, got, fd)


def _orifice_q(model, RT, rho):
    """mdot(p_a, p_b) of the orifice law ``model`` with its densities made as
    the compiled pass makes them, and its partials."""
    def q(pa, pb):
        r, dr = law.density(law.orifice_upstream(model, pa, pb), RT, rho)
        return law.orifice_flow(model, pa, pb, r, dr, 2.2, 7.9e-7, 40.0, 1.4, 0.65, 300.0,
                                1e-8, 0.35, 0.6, 0.999, ISO_6358_RHO0, ISO_6358_T0)
    return q


@pytest.mark.parametrize("model, RT, rho", [
    (law.LOSS, 0.0, RHO_WATER), (law.LOSS, RT_AIR, 0.0), (law.NOZZLE, RT_AIR, 0.0),
    (law.ISO_6358, RT_AIR, 0.0)], ids=["loss-liquid", "loss-gas", "nozzle", "iso-6358"])
@pytest.mark.parametrize("pa, pb", [
    (1e5 + 10.0, 1e5), (1e5 - 25.0, 1e5), (1e5 + 3e3, 1e5), (2e5, 3e5), (6e5, 1e5),
    (1e5, 7e5), (1e5 + 0.02, 1e5)],
    ids=["band", "band-back", "subsonic", "back", "choked", "choked-back", "iso-band"])
def test_orifice_flow_partials(model, RT, rho, pa, pb):
    # (inside the bands, |dp| < 40 Pa and, ISO 6358, p_b/p_a > 0.999: a cubic)
    h = 1e-6 * abs(pa - pb) if abs(pa - pb) > 1e3 else 1e-3
    _check_partials(_orifice_q(model, RT, rho), (pa, pb), (h, h))


def _check_valve_q(nozzle, RT, rho, cracking=2e3, band=1e3, leakage=1e-12):
    def q(pa, pb):
        ro, dro = law.density(max(pa, pb) if nozzle else pa, RT, rho)
        rm, drm = law.mean_density(pa, pb, RT, rho)
        return law.check_valve_flow(pa, pb, nozzle, ro, dro, rm, drm, 2.78, 0.6, 1.4, 7.9e-7,
                                    0.5, cracking, cracking + band, leakage)
    return q


@pytest.mark.parametrize("nozzle, RT, rho", [(True, RT_AIR, 0.0), (False, RT_AIR, 0.0),
                                             (False, 0.0, RHO_WATER)],
                         ids=["nozzle", "incompressible-gas", "liquid"])
@pytest.mark.parametrize("dp", [-5e4, -300.0, 0.0, 1e3, 2e3 + 1.0, 2.5e3, 2.99e3, 3.2e3, 5e4,
                                4e5],
                         ids=["back", "back-small", "zero", "shut", "band-bottom", "band",
                              "band-top", "open", "open-far", "choked"])
def test_check_valve_flow_partials(nozzle, RT, rho, dp):
    pb = 1e5
    h = 1e-4 if abs(dp - 2e3) < 10.0 else 1e-3
    _check_partials(_check_valve_q(nozzle, RT, rho), (pb + dp, pb), (h, h))


def _flow_step(mf, mf_blend):
    """A central difference's step in the flow: relative, and at zero flow a
    small part of the direction blend's width (the pressure-drop law's value
    carries p_a - p_b: a smaller step is round-off)."""
    return max(1e-6 * abs(mf), 1e-4 * mf_blend)


def _tesla_args():
    d = 1e-3
    mu = float(sf.air.mu)
    area = math.pi * d * d / 4
    re_per_mf = d / (mu * area)
    c_mu = mu * 0.1 / (2.0 * area * d * d)
    eD = 1.5e-6 / d
    return re_per_mf, c_mu, eD, fl.haaland_terms(eD), area, 10.0 / re_per_mf


@pytest.mark.parametrize("re", [0.0, 500.0, 3000.0, 8e3, 2e5, -4.0, -9.9, -500.0, -3e3, -8e4])
@pytest.mark.parametrize("diodicity", [1.0, 3.0])
def test_tesla_friction_partial(re, diodicity):
    re_per_mf, c_mu, eD, a, area, mf_blend = _tesla_args()
    mf = re / re_per_mf

    def f(m):
        return law.tesla_friction(HAALAND, 2300.0, 4000.0, m, re_per_mf, eD, a, mf_blend,
                                  diodicity)
    _check_partials(f, (mf,), (_flow_step(mf, mf_blend),))


@pytest.mark.parametrize("re", [0.0, 500.0, 3000.0, 8e3, 1.5e5, -4.0, -500.0, -3e3, -8e4])
@pytest.mark.parametrize("fluid", ["gas", "liquid"])
def test_tesla_drop_partials(re, fluid):
    re_per_mf, c_mu, eD, a, area, mf_blend = _tesla_args()
    mf = re / re_per_mf
    c2, rho = (RT_AIR, 0.0) if fluid == "gas" else (0.0, RHO_WATER)
    pa, pb = (3e5, 1e5) if mf >= 0 else (1e5, 3e5)

    def f(pa, m, pb):
        return law.tesla_drop(HAALAND, 2300.0, 4000.0, pa, m, pb, re_per_mf, c_mu, eD, a, area,
                              mf_blend, 3.0, c2, rho, 0.0)
    _check_partials(f, (pa, mf, pb), (1.0, _flow_step(mf, mf_blend), 1.0))


@pytest.mark.parametrize("re", [0.0, 500.0, 3000.0, 8e3, 1.5e5, -4.0, -500.0, -3e3, -8e4])
def test_tesla_adiabatic_drop_partials(re):
    re_per_mf, c_mu, eD, a, area, mf_blend = _tesla_args()
    mf = re / re_per_mf
    pa, pb = (3e5, 1e5) if mf >= 0 else (1e5, 3e5)
    gas = law.gas_constants(1.4)

    def f(pa, m, pb, T):
        return law.tesla_adiabatic_drop(HAALAND, 2300.0, 4000.0, pa, m, pb, T, re_per_mf, c_mu,
                                        eD, a, area, mf_blend, 3.0, float(sf.air.R), gas)
    _check_partials(f, (pa, mf, pb, 320.0), (1.0, _flow_step(mf, mf_blend), 1.0, 1e-3))


@pytest.mark.parametrize("re", [0.0, 500.0, 3000.0, 8e3, -3e3, -8e4])
@pytest.mark.parametrize("mode", ["open", "closed"])
@pytest.mark.parametrize("RT, rho", [(RT_AIR, 0.0), (0.0, RHO_WATER)], ids=["gas", "liquid"])
def test_snapping_rows_partials(re, mode, RT, rho):
    """The restrictor row of an open liquid passage (its friction term) or of
    the closed valve (X = mf/G), at the mean density (p_a = p_b: the row is the
    pressure drop itself, which a difference resolves)."""
    re_per_mf, c_mu, eD, a, area, mf_blend = _tesla_args()
    mf = re / re_per_mf
    G = 1e-11

    def f(pa, m, pb):
        if mode == "open":
            X, dX = law.friction_term(HAALAND, 2300.0, 4000.0, m, re_per_mf, c_mu, eD, a)
        else:
            X, dX = m / G, 1.0 / G
        return law.restrictor_row(pa, pb, X, dX, *law.mean_density(pa, pb, RT, rho))
    _check_partials(f, (1.2e5, mf, 1.2e5), (1.0, _flow_step(mf, mf_blend), 1.0))


def test_friction_term_partial_and_the_tubes_law():
    re_per_mf, c_mu, eD, a, area, _ = _tesla_args()
    for re in (0.0, 500.0, 3000.0, 8e3, -3e3, -8e4):
        mf = re / re_per_mf + 1e-9
        _check_partials(lambda m: law.friction_term(HAALAND, 2300.0, 4000.0, m, re_per_mf,
                                                    c_mu, eD, a), (mf,), (1e-6 * abs(mf),))
        # a Tesla valve of diodicity 1 is the tube's friction term over c_mu
        Phi, dPhi = law.friction_term(HAALAND, 2300.0, 4000.0, mf, re_per_mf, c_mu, eD, a)
        t, dt = law.tesla_friction(HAALAND, 2300.0, 4000.0, mf, re_per_mf, eD, a, 1e-6, 1.0)
        assert (c_mu * t, c_mu * dt) == pytest.approx((Phi, dPhi), rel=1e-15)


# ---------------------------------------------------------------------------------------
# each group's compiled pass against the same law on the array functions
# ---------------------------------------------------------------------------------------
def _mean_density(fluid, pa, pb):
    if not fluid.compressible:
        return fluid.rho, 0.0
    pm = 0.5 * (pa + pb)
    return fluid.density(pm), 0.5 * fluid.density_dp(pm)


def _rows(V, q=None, dq_pa=None, dq_pb=None, drop=None):
    """F (n, 2) and J (n, 5) of a two-port from its flow (F1 = mf - q) or its
    pressure drop (F1 = p_a - p_b - dp, drop = (dp, d_pa, d_mf, d_pb))."""
    pa, mf, pb = V[:, 0], V[:, 1], V[:, 2]
    F = np.column_stack([mf + V[:, 3], mf - q if drop is None else (pa - pb) - drop[0]])
    n = len(V)
    if drop is None:
        J = np.column_stack([np.ones(n), np.ones(n), -dq_pa, np.ones(n), -dq_pb])
    else:
        J = np.column_stack([np.ones(n), np.ones(n), 1.0 - drop[1] + 0 * pa, -drop[2],
                             -1.0 - drop[3] + 0 * pa])
    return F, J


def orifice_reference(P, V):
    fluid, pa, pb = P.fluid, V[:, 0], V[:, 2]
    if P.model == "ISO 6358":
        q, qa, qb = massflow_ISO_6358(pa, pb, fluid.temperature, P.C, P.b, P.subsonic_index,
                                      P.pr_laminar)
    elif P.model == "nozzle":
        p_up = np.maximum(pa, pb)
        q, qa, qb = massflow_nozzle(pa, pb, fluid.density(p_up), P.gamma, P.Cd, P.area,
                                    P.dp_small, fluid.density_dp(p_up))
    else:
        forward = pa >= pb
        p_up = np.where(forward, pa, pb)
        rho, drho = ((fluid.density(p_up), fluid.density_dp(p_up)) if fluid.compressible
                     else (fluid.rho, 0.0))
        q, q_dp, q_rho = massflow_loss_coefficient(pa - pb, rho, P.K, P.area, P.dp_small)
        qa = q_dp + np.where(forward, q_rho * drho, 0.0)
        qb = -q_dp + np.where(forward, 0.0, q_rho * drho)
    return _rows(V, q, qa, qb)


def check_valve_reference(P, V):
    fluid, pa, pb = P.fluid, V[:, 0], V[:, 2]
    dp = pa - pb
    if P.nozzle:
        p_up = np.maximum(pa, pb)
        q, qa, qb = massflow_nozzle(pa, pb, fluid.density(p_up), P.gamma, P.Cd, P.area,
                                    P.dp_small, fluid.density_dp(p_up))
    else:
        rho, drho = ((fluid.density(pa), fluid.density_dp(pa)) if fluid.compressible
                     else (fluid.rho, 0.0))
        q, q_dp, q_rho = massflow_loss_coefficient(dp, rho, P.K, P.area, P.dp_small)
        qa, qb = q_dp + q_rho * drho, -q_dp
    rho_m, drho_m = _mean_density(fluid, pa, pb)
    w, dw = smoothstep(dp, P.cracking_pressure, P.cracking_pressure + P.opening_band)
    d_dp = dw * q + rho_m * P.leakage
    d_rho = drho_m * P.leakage * dp
    return _rows(V, w * q + rho_m * P.leakage * dp, d_dp + d_rho + w * qa,
                 -d_dp + d_rho + w * qb)


def _tesla_friction(P, mf):
    Re = np.abs(mf) * P.re_per_mf
    phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi)
    w, dw = smoothstep(mf, -P.mf_blend, 0.0)
    extra = P.diodicity - 1.0
    mult = 1.0 + extra * (1.0 - w)
    return phi * mf * mult, (phi + Re * dphi) * mult - phi * mf * extra * dw


def tesla_drop_reference(P, pa, mf, pb):
    law_, dlaw = _tesla_friction(P, mf)
    if P.isothermal:
        return tubes.isothermal_drop(P, pa, mf, pb, P.c_mu * law_, P.c_mu * dlaw, None, True)
    rho, drho = _mean_density(P.fluid, pa, pb)
    dp = P.c_mu / rho * law_
    g = -dp / rho * drho
    return dp, g, P.c_mu / rho * dlaw, g


def tesla_thermal_reference(P, pa, mf, pb, T_up):
    law_, dlaw = _tesla_friction(P, mf)
    return tubes.adiabatic_drop(P, pa, mf, pb, T_up, P.c_mu * law_, P.c_mu * dlaw, True)


def _open_passage(P, mf):
    Re = np.abs(mf) * P.re_per_mf
    phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi)
    return P.c_mu * phi * mf, P.c_mu * (phi + Re * dphi)


def snapping_reference(P, V, S):
    pa, mf, pb = V[:, 0], V[:, 1], V[:, 2]
    is_open = S[:, 0] > 0.5
    rho, drho = _mean_density(P.fluid, pa, pb)
    X_open, dX_open = _open_passage(P, mf)
    X = np.where(is_open, X_open, mf / P.closed_conductance)
    dX = np.where(is_open, dX_open, 1.0 / P.closed_conductance)
    dp = X / rho
    g = dp / rho * drho
    drop = [dp, -g, dX / rho, -g]
    if P.isothermal:
        gas = tubes.isothermal_drop(P, pa, mf, pb, X_open, dX_open, None, True)
        drop = [np.where(is_open, a, b) for a, b in zip(gas, drop)]
    return _rows(V, drop=drop)


def snapping_thermal_reference(P, V, T_up):
    X_open, dX_open = _open_passage(P, V[:, 1])
    return tubes.adiabatic_drop(P, V[:, 0], V[:, 1], V[:, 2], T_up, X_open, dX_open, True)


FLUIDS = {"air": sf.air, "air-table": sf.air.with_level("table"), "water": sf.water}


def _groups(fluid):
    """(class, four instances, flows of each regime's row (n, 4) as Reynolds-like
    multiples, modes) per valve class of ``fluid``."""
    out = {"Orifice-K": [Orifice(f"o{i}", fluid, diameter=1e-3 * (1 + 0.3 * i), K=1.5 + i)
                         for i in range(4)],
           "CheckValve": [CheckValve(f"c{i}", fluid, diameter=1e-3 * (1 + 0.3 * i),
                                     cracking_pressure=2e3 * i, opening_band=1e3 * (i + 1),
                                     leakage=1e-12 * i) for i in range(4)],
           "TeslaValve": [TeslaValve(f"t{i}", fluid, 0.05 * (i + 1), 1e-3 * (1 + 0.3 * i),
                                     diodicity=1.0 + 2 * i) for i in range(4)],
           "SnappingValve": [SnappingValve(f"s{i}", fluid, 2e4, 5e3, 1e-11 * (i + 1),
                                           length=0.02 * (i + 1), diameter=1e-3 * (1 + i))
                             for i in range(4)]}
    if fluid.compressible:
        out["Orifice-nozzle"] = [Orifice(f"o{i}", fluid, diameter=1e-3 * (1 + 0.3 * i),
                                         Cd=0.5 + 0.1 * i) for i in range(4)]
        out["Orifice-ISO"] = [Orifice(f"o{i}", fluid, C=1e-9 * (i + 1), b=0.2 + 0.1 * i)
                              for i in range(4)]
        out["CheckValve-incompressible"] = [
            CheckValve(f"c{i}", fluid, diameter=1e-3 * (1 + 0.3 * i), cracking_pressure=2e3 * i,
                       opening_band=1e3 * (i + 1), gas_law="incompressible") for i in range(4)]
    return out


def _states(P, fluid):
    """V (n, 4) per regime: pressure differences from the regularization band to
    choked flow, either way; flows from zero to turbulent, either way."""
    pb = np.array([P0, 2e5, 1.5e5, 3e5])
    rpm = getattr(P, "re_per_mf", np.full(4, 1e5))
    out = {}
    for name, dp, re in [
            ("zero", [0.0] * 4, [0.0] * 4),
            ("band", [0.3, -0.5, 1e-3, 2.0], [1.0, -3.0, 0.5, -20.0]),
            ("small", [50.0, -80.0, 150.0, 900.0], [500.0, -800.0, 1500.0, 2500.0]),
            ("opening", [1.2e3, 2.5e3, 5.1e3, 7.9e3], [2400.0, 3000.0, 3900.0, -3000.0]),
            ("large", [3e4, -2e4, 5e4, -9e4], [8e3, -2e4, 6e4, -1e5]),
            ("choked", [3 * P0, -1.5e5, 4e5, -2.5e5], [2e5, -3e5, 4e5, -5e5])]:
        if name == "choked" and not fluid.compressible:
            continue
        dp = np.array(dp)
        out[name] = np.column_stack([pb + dp, np.array(re) / rpm, pb, -0.9 * np.array(re) / rpm])
    return out


def _close(got, want, scale):
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-13 * scale)


@pytest.mark.parametrize("fluid", list(FLUIDS), ids=list(FLUIDS))
def test_compiled_passes_are_the_array_law(fluid):
    """Each valve group's residual and Jacobian (one compiled pass; for a gas at
    the table level with its densities from the fluid) equal the same law on
    the array functions of softflow.correlations and the tube's array law, to
    round-off, for groups of four and of one, in every regime and mode; so do
    a Tesla valve's pressure drop and thermal law and a snapping valve's
    thermal rows."""
    fluid = FLUIDS[fluid]
    for name, comps in _groups(fluid).items():
        cls = type(comps[0])
        P4 = cls.make_params(comps)
        assert P4.compiled is (fluid.level == "ideal")
        for regime, V in _states(P4, fluid).items():
            for modes in ([0.0] * 4, [1.0] * 4, [1.0, 0.0, 0.0, 1.0]):
                S = np.array(modes)[:, None] if cls is SnappingValve else np.zeros((4, 0))
                if cls is Orifice:
                    want = orifice_reference(P4, V)
                elif cls is CheckValve:
                    want = check_valve_reference(P4, V)
                elif cls is TeslaValve:
                    want = _rows(V, drop=tesla_drop_reference(P4, V[:, 0], V[:, 1], V[:, 2]))
                else:
                    want = snapping_reference(P4, V, S)
                scale = np.abs(V[:, [0, 2]]).max() + 1.0
                for i, P in [(slice(None), P4)] + [
                        (slice(k, k + 1), cls.make_params([comps[k]])) for k in range(4)]:
                    F, J = cls.residual(P, V[i], S[i], 0.0, True)
                    F0, none = cls.residual(P, V[i], S[i], 0.0, False)
                    assert none is None
                    np.testing.assert_array_equal(F0, F)
                    _close(F[:, 0], want[0][i, 0], 1e-3)
                    _close(F[:, 1], want[0][i, 1], scale if cls in (TeslaValve, SnappingValve)
                           else 1e-3)
                    for j in range(5):
                        _close(J[:, j], want[1][i, j], np.abs(want[1][:, j]).max())
                if cls is TeslaValve:
                    got = cls.pressure_drop(P4, V[:, 0], V[:, 1], V[:, 2], True)
                    ref = tesla_drop_reference(P4, V[:, 0], V[:, 1], V[:, 2])
                    for a, b in zip(got, ref):
                        _close(a, np.broadcast_to(b, (4,)), np.abs(b).max())
                if cls in (TeslaValve, SnappingValve) and P4.R_gas is not None:
                    T_up = np.array([293.15, 250.0, 350.0, 400.0])
                    if cls is TeslaValve:
                        got = cls.thermal_drop(P4, V[:, 0], V[:, 1], V[:, 2], T_up, True)
                        ref = tesla_thermal_reference(P4, V[:, 0], V[:, 1], V[:, 2], T_up)
                    else:
                        mask, *got = cls.thermal_rows(P4, V, S, T_up, True)
                        np.testing.assert_array_equal(mask, S[:, 0] > 0.5)
                        ref = snapping_thermal_reference(P4, V, T_up)
                    for a, b in zip(got, ref):
                        _close(a, b, np.abs(b).max())


@pytest.mark.parametrize("name", sorted(_groups(sf.air)))
def test_an_ideal_gas_given_its_densities_is_its_compiled_pass(name):
    """The path of a gas whose densities come from its methods (P.compiled
    False), taken by an ideal gas, gives the compiled pass's numbers to
    round-off: the densities the pass makes are the fluid's."""
    comps = _groups(sf.air)[name]
    cls = type(comps[0])
    P = cls.make_params(comps)
    assert P.compiled
    for V in _states(P, sf.air).values():
        S = np.array([[1.0], [0.0], [1.0], [0.0]]) if cls is SnappingValve else np.zeros((4, 0))
        got = cls.residual(P, V, S, 0.0, True)
        P.compiled = False
        try:
            want = cls.residual(P, V, S, 0.0, True)
        finally:
            P.compiled = True
        _close(got[0], want[0], np.abs(V[:, [0, 2]]).max())
        for j in range(5):
            _close(got[1][:, j], want[1][:, j], np.abs(want[1][:, j]).max())


# ---------------------------------------------------------------------------------------
# the pure-Python mode
# ---------------------------------------------------------------------------------------
def test_pure_python_mode_gives_the_compiled_numbers():
    v = "__import__('softflow.laws.valves', fromlist=['v'])"
    expression = (
        f"[{v}.orifice_flow(1, 3e5, 2.5e5, 3.5, 1.1e-5, 2.2, 8e-7, 0.5, 1.4, 0.6, 300.0, 1e-8, "
        "0.3, 0.5, 0.999, 1.185, 293.15), "
        f"{v}.check_valve_flow(1.03e5, 1e5, False, 1.2, 1e-5, 1.2, 5e-6, 2.78, 0.6, 1.4, 8e-7, "
        "0.5, 2e3, 3e3, 1e-12), "
        f"{v}.tesla_drop(1, 2300.0, 4000.0, 1e5, -4e-4, 3e5, 1.6e7, 2.9e8, 1.5e-3, 3e-5, 8e-7, "
        "6e-7, 3.0, 84000.0, 0.0, 0.0), "
        f"{v}.tesla_adiabatic_drop(1, 2300.0, 4000.0, 3e5, 5e-4, 1e5, 310.0, 1.6e7, 2.9e8, "
        f"1.5e-3, 3e-5, 8e-7, 6e-7, 3.0, 287.0, fanno.gas_constants(1.4)), "
        f"{v}.friction_term(1, 2300.0, 4000.0, 3e-4, 1.6e7, 2.9e8, 1.5e-3, 3e-5), "
        f"{v}.restrictor_row(1.3e5, 1.1e5, 20.0, 1e11, 1.4, 6e-6)]")
    compiled, python, _ = compiled_and_python(expression)
    np.testing.assert_allclose(python, compiled, rtol=1e-15)
