"""The adiabatic (Fanno) pipe-flow law of :mod:`softflow.correlations.fanno`:
the Fanno parameter against tables and a quadrature of its differential form,
the entry's Mach number, the mass flow against an independent solution of the
same equations, the choke, the isentropic nozzle bound, smoothness (C1 at zero
flow, across the choke and at the entry's limit), analytic partials against
central differences, a unique root along the flow, the low-Mach limit, oddness,
and the isothermal law as gamma -> 1."""
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from softflow.correlations.fanno import (adiabatic_choked_massflow, adiabatic_entry_z,
                                         adiabatic_pipe, fanno_parameter)
from softflow.correlations.gas_pipe import isothermal_pipe

R_AIR = 287.05
AREA = 1e-5
GAMMAS = (1.4, 1.3, 5.0 / 3.0)


# ---------------------------------------------------------------------------------------
# an independent solution of the same equations (scipy's brentq on Mach numbers)
# ---------------------------------------------------------------------------------------
def _fstar_quad(M, g):
    """f L*/D by quadrature of the differential Fanno relation (Anderson, Modern
    Compressible Flow, eq. 3.106): f dx/D = 2 (1 - M^2)/(g M^2 (1 + (g-1)/2 M^2)) dM/M."""
    k = 0.5 * (g - 1.0)
    val, _ = quad(lambda m: 2.0 * (1.0 - m * m) / (g * m ** 3 * (1.0 + k * m * m)), M, 1.0,
                  epsabs=0.0, epsrel=1e-13, limit=200)
    return val


def _fstar(M, g):
    return ((1.0 - M * M) / (g * M * M)
            + (g + 1.0) / (2.0 * g) * math.log((g + 1.0) * M * M / (2.0 + (g - 1.0) * M * M)))


def _nozzle_flux(p0, T0, g, M=1.0):
    """G of the isentropic entry from rest at Mach M."""
    k = 0.5 * (g - 1.0)
    return (p0 * M * math.sqrt(g / (R_AIR * T0))
            * (1.0 + k * M * M) ** (-(g + 1.0) / (2.0 * (g - 1.0))))


def _reference_massflow(p0, pd, T0, fLD, g):
    """(mdot, choked) from the textbook equations: isentropic entry to M1, Fanno
    pipe to M2 (fL/D = F*(M1) - F*(M2)), exit at p_d or at Mach 1."""
    k = 0.5 * (g - 1.0)

    def p1(M1):
        return p0 * (1.0 + k * M1 * M1) ** (-g / (g - 1.0))

    def exit_mach(M1):
        excess = _fstar(M1, g) - fLD
        if excess <= 0.0:
            return 1.0
        return brentq(lambda M: excess - _fstar(M, g), M1, 1.0, xtol=1e-16, rtol=1e-15)

    def p2(M1):
        M2 = exit_mach(M1)
        return p1(M1) * (M1 / M2) * math.sqrt((1.0 + k * M1 * M1) / (1.0 + k * M2 * M2))

    M1c = brentq(lambda M: _fstar(M, g) - fLD, 1e-12, 1.0, xtol=1e-16, rtol=1e-15)
    if pd <= p2(M1c):
        return _nozzle_flux(p0, T0, g, M1c) * AREA, True
    M1 = brentq(lambda M: p2(M) - pd, 1e-10, M1c, xtol=1e-16, rtol=1e-15)
    return _nozzle_flux(p0, T0, g, M1) * AREA, False


def _phi_turbulent(mf, fLD):
    """The friction term for a fixed f L/D: G^2 f L/D = 2 Phi, signed with the flow."""
    G = mf / AREA
    return 0.5 * fLD * G * np.abs(G)


def _root(pa, pb, T0, fLD, g):
    """mdot from a to b where the residual vanishes (brentq between zero flow and
    just past the isentropic nozzle's flow, where the residual is negative)."""
    def r(m):
        return float(adiabatic_pipe(pa, m, pb, T0, AREA, R_AIR, g, _phi_turbulent(m, fLD),
                                    jac=False)[0])
    if pa >= pb:
        return brentq(r, 0.0, 1.01 * _nozzle_flux(pa, T0, g) * AREA, xtol=1e-300, rtol=1e-15)
    return brentq(r, -1.01 * _nozzle_flux(pb, T0, g) * AREA, 0.0, xtol=1e-300, rtol=1e-15)


# ---------------------------------------------------------------------------------------
# the pieces
# ---------------------------------------------------------------------------------------
def test_fanno_parameter_matches_tables_and_the_differential_form():
    """gamma = 1.4, f L*/D (Darcy; 4 f L*/D with Fanning's f) as tabulated (Anderson,
    Modern Compressible Flow, table A.4; NACA 1135) to their printed digits, and
    the closed form against a quadrature of the differential relation."""
    for M, table in [(0.2, "14.533"), (0.3, "5.2993"), (0.5, "1.0691"), (0.8, "0.07229"),
                     (0.9, "0.01451")]:
        decimals = len(table.split(".")[1])
        assert round(float(fanno_parameter(M, 1.4)), decimals) == float(table)
        assert round(_fstar_quad(M, 1.4), decimals) == float(table)
    for g in GAMMAS + (1.01, 2.0):
        M = np.array([0.02, 0.05, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 0.999])
        quadrature = np.array([_fstar_quad(m, g) for m in M])
        np.testing.assert_allclose(fanno_parameter(M, g), quadrature, rtol=1e-11, atol=1e-15)
    assert float(fanno_parameter(1.0, 1.4)) == 0.0


@pytest.mark.parametrize("g", GAMMAS + (1.0001, 1.05, 2.5))
def test_entry_mach_solves_the_isentropic_mass_flux(g):
    """z1 = M1^2 of the entry against brentq on the logarithm of the isentropic mass
    flux, ln G = ln(p0 sqrt(g/(R T0))) + ln M1 - (g+1)/(2(g-1)) ln(1 + (g-1)/2 M1^2),
    over 1e-300 <= a/a* <= 0.999, to round-off: the relative error eps |ln a| of
    e^(ln z1) and eps/(1 - z1) of the limit's conditioning (dz1/da ~ (a* - a)^-1/2);
    and 1 from the limit on."""
    k, n = 0.5 * (g - 1.0), (g + 1.0) / (g - 1.0)
    a_max = (1.0 + k) ** -n
    t = np.concatenate([10.0 ** -np.linspace(0.01, 299.0, 60), np.linspace(0.01, 0.999, 60)])
    a = t * a_max
    z = adiabatic_entry_z(a, g)
    for ai, zi in zip(a, z):
        # a = G^2 R T0/(g p0^2) = M1^2 (1 + k M1^2)^-n, and M1 >= sqrt(a)
        ln_a = math.log(ai)
        M = brentq(lambda m: math.log(m) - 0.5 * n * math.log1p(k * m * m) - 0.5 * ln_a,
                   0.5 * math.sqrt(ai), 1.0, xtol=1e-300, rtol=1e-15)
        assert zi == pytest.approx(M * M, rel=1e-15 * (abs(ln_a) + 10.0 + 1.0 / (1.0 - M * M)))
    np.testing.assert_array_equal(adiabatic_entry_z(np.array([1.5 * a_max, 10.0]), g), 1.0)
    assert float(adiabatic_entry_z(a_max * (1.0 - 1e-16), g)) == pytest.approx(1.0, abs=1e-7)
    assert float(adiabatic_entry_z(0.0, g)) < 1e-299


# ---------------------------------------------------------------------------------------
# the mass flow
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("g", (1.4, 5.0 / 3.0))
@pytest.mark.parametrize("reverse", (False, True), ids=("a-to-b", "b-to-a"))
def test_massflow_matches_an_independent_solution(g, reverse):
    """The residual's root against the textbook equations solved by nested brentq
    on the Mach numbers, over pressure ratios 0.05-0.95 and f L/D 0.1-100, choked
    or not, in both directions: within 1e-8 (measured: ~1e-14)."""
    rng = np.random.default_rng(7 + reverse)
    worst, seen_choked = 0.0, set()
    for ratio in (0.05, 0.2, 0.5, 0.8, 0.95):
        for fLD in (0.1, 1.0, 10.0, 100.0):
            p0, T0 = rng.uniform(1.5e5, 1e6), rng.uniform(250.0, 500.0)
            pd = ratio * p0
            want, choked = _reference_massflow(p0, pd, T0, fLD, g)
            if reverse:
                got = -_root(pd, p0, T0, fLD, g)
                flag = adiabatic_pipe(pd, -got, p0, T0, AREA, R_AIR, g,
                                      _phi_turbulent(-got, fLD))[6]
            else:
                got = _root(p0, pd, T0, fLD, g)
                flag = adiabatic_pipe(p0, got, pd, T0, AREA, R_AIR, g,
                                      _phi_turbulent(got, fLD))[6]
            worst = max(worst, abs(got / want - 1.0))
            assert got == pytest.approx(want, rel=1e-8), (ratio, fLD)
            assert bool(flag) == choked, (ratio, fLD)
            seen_choked.add(choked)
    assert seen_choked == {True, False}
    assert worst < 1e-12


@pytest.mark.parametrize("g", GAMMAS)
@pytest.mark.parametrize("fLD", (0.0, 0.01, 1.0, 30.0, 300.0))
def test_choked_flow_is_independent_of_the_outlet(g, fLD):
    """Below the exit's Mach-1 pressure the flow is adiabatic_choked_massflow, whatever
    p_down; at f L/D = 0 that is the isentropic nozzle's."""
    p0, T0 = 4e5, 320.0
    m_choked = adiabatic_choked_massflow(p0, T0, AREA, R_AIR, g, fLD)
    if fLD == 0.0:
        assert m_choked == pytest.approx(_nozzle_flux(p0, T0, g) * AREA, rel=1e-15)
    else:
        assert m_choked == pytest.approx(_reference_massflow(p0, 1.0, T0, fLD, g)[0],
                                         rel=1e-12)
    # the exit pressure at Mach 1: p2* = G sqrt(R T0/(g (g+1)/2))
    p_star = m_choked / AREA * math.sqrt(R_AIR * T0 / (g * 0.5 * (g + 1.0)))
    for frac in (1e-3, 0.3, 0.9, 0.999):
        pd = frac * p_star
        m = _root(p0, pd, T0, fLD, g)
        assert m == pytest.approx(m_choked, rel=1e-12)
        out = adiabatic_pipe(p0, m, pd, T0, AREA, R_AIR, g, _phi_turbulent(m, fLD))
        assert bool(out[6])
        # dR/dpb: only the 1/(pa + pb) scaling, dF/dp_down = 0
        assert out[3] == pytest.approx(-out[0] / (p0 + pd), abs=1e-15)
    # just above p2* the flow falls below the choked one
    m_above = _root(p0, 1.01 * p_star, T0, fLD, g)
    assert m_above < m_choked


def test_no_tube_passes_more_than_the_isentropic_nozzle_of_its_bore():
    """The root never exceeds p0 A sqrt(g/(R T0)) (2/(g+1))^((g+1)/(2(g-1))), reached
    as f L/D -> 0 and p_down -> 0."""
    rng = np.random.default_rng(11)
    for g in GAMMAS:
        for _ in range(60):
            p0, T0 = rng.uniform(1e5, 1e6), rng.uniform(200.0, 600.0)
            pd = p0 * rng.uniform(0.0, 0.999)
            fLD = 10.0 ** rng.uniform(-8.0, 2.0)
            m = _root(p0, pd, T0, fLD, g)
            assert 0.0 < m <= _nozzle_flux(p0, T0, g) * AREA * (1.0 + 1e-14)
        assert _root(2e5, 1.0, 300.0, 1e-12, g) == pytest.approx(
            _nozzle_flux(2e5, 300.0, g) * AREA, rel=1e-6)


# ---------------------------------------------------------------------------------------
# smoothness, partials, uniqueness
# ---------------------------------------------------------------------------------------
def _one_sided(f, x, h):
    """(left, right) difference quotients of f at x."""
    f0 = f(x)
    return (f0 - f(x - h)) / h, (f(x + h) - f0) / h


@pytest.mark.parametrize("g", GAMMAS)
def test_residual_is_C1_at_zero_flow_across_the_choke_and_at_the_entrys_limit(g):
    """One-sided difference quotients (relative step h = 1e-7) agree within O(h) of
    the slope's scale at zero flow (in mdot, with a laminar friction term) and at
    the choke (in p_down and in mdot), and the analytic partials on both sides
    agree; a kink would part them by O(1). At the entry's limit (in mdot and p0)
    the slope is continuous too but approaches its value there like sqrt(a* - a),
    so the gaps shrink like sqrt(h)."""
    T0, c = 300.0, 3e6            # Phi = c mdot: laminar f Re = 64
    rel = 1e-7

    def R_of(pa, mf, pb):
        return float(adiabatic_pipe(pa, mf, pb, T0, AREA, R_AIR, g, c * mf, jac=False)[0])

    def dR_dmf(pa, mf, pb):
        out = adiabatic_pipe(pa, mf, pb, T0, AREA, R_AIR, g, c * mf)
        return float(out[2] + out[5] * c)

    K = 0.5 * (g + 1.0)
    a_max = K ** (-(g + 1.0) / (g - 1.0))
    for pa, pb in [(3e5, 1e5), (1e5, 3e5), (2e5, 2e5)]:
        # zero flow
        m_scale = _nozzle_flux(max(pa, pb), T0, g) * AREA
        left, right = _one_sided(lambda m: R_of(pa, m, pb), 0.0, rel * m_scale)
        slope = (pa + pb) / m_scale
        assert abs(left - right) < 1e-5 * slope
        assert abs(dR_dmf(pa, 1e-12 * m_scale, pb) - dR_dmf(pa, -1e-12 * m_scale, pb)) \
            < 1e-9 * slope
    p0 = 3e5
    for frac in (0.3, 0.7, 0.95):
        # the choke in p_down: p2* = sqrt(W/K) at this flow
        m = frac * _nozzle_flux(p0, T0, g) * AREA
        W = (m / AREA) ** 2 * R_AIR * T0 / g
        p_star = math.sqrt(W / K)
        left, right = _one_sided(lambda pd: R_of(p0, m, pd), p_star, rel * p_star)
        assert abs(left - right) < 1e-5
        below = adiabatic_pipe(p0, m, p_star * (1 - 1e-9), T0, AREA, R_AIR, g, c * m)
        above = adiabatic_pipe(p0, m, p_star * (1 + 1e-9), T0, AREA, R_AIR, g, c * m)
        assert bool(below[6]) and not bool(above[6])
        for i, scale in ((1, 1.0), (2, p0 / m), (3, 1.0), (4, p0 / T0)):
            assert abs(below[i] - above[i]) < 1e-6 * scale
        # the choke in mdot at this p_down
        m_star = p_star * AREA * math.sqrt(g * K / (R_AIR * T0))
        assert m_star == pytest.approx(m, rel=1e-12)
        left, right = _one_sided(lambda mf: R_of(p0, mf, p_star), m_star, rel * m_star)
        assert abs(left - right) < 1e-5 * (p0 / m_star)
    # the entry's limit, a = a*: C1, the slope approaching its limit like sqrt(a* - a)
    # (z1 does; as the isothermal law's Lambert W does): one-sided quotients and the
    # partials on either side part by O(sqrt(h)), measured <= 2e-4 at h = 1e-9
    m_lim = math.sqrt(a_max * g / (R_AIR * T0)) * p0 * AREA
    for pd in (0.1 * p0, 0.9 * p0, 1.5 * p0):
        for f, x, scale in [(lambda mf: R_of(p0, mf, pd), m_lim, p0 / m_lim),
                            (lambda pa: R_of(pa, m_lim, pd), p0, 1.0)]:
            coarse = abs(np.subtract(*_one_sided(f, x, 1e-5 * x)))
            fine = abs(np.subtract(*_one_sided(f, x, 1e-9 * x)))
            assert fine < 0.02 * coarse and fine < 1e-4 * scale
        gaps = []
        for d in (1e-4, 1e-8):
            inside = adiabatic_pipe(p0, m_lim * (1 - d), pd, T0, AREA, R_AIR, g, c * m_lim)
            beyond = adiabatic_pipe(p0, m_lim * (1 + d), pd, T0, AREA, R_AIR, g, c * m_lim)
            gaps.append(max(abs(inside[i] / beyond[i] - 1.0) for i in (1, 2, 3, 4)))
        assert gaps[1] < 0.02 * gaps[0] and gaps[1] < 2e-3


@pytest.mark.parametrize("g", GAMMAS + (1.05,))
def test_analytic_partials_match_central_differences(g):
    """dR/dpa, dR/dmf, dR/dpb, dR/dT0 and dR/dphi against central differences
    (relative step 1e-6) on 6000 random states: both directions, choked or not,
    past the entry's limit, away (1e-3 relative) from the choke's kink, the
    entry's limit and zero flow. Measured: within 5e-10 of |difference| + the
    residual's scale over the variable's."""
    rng = np.random.default_rng(int(100 * g))
    N = 6000
    K = 0.5 * (g + 1.0)
    a_max = K ** (-(g + 1.0) / (g - 1.0))
    pa = 10.0 ** rng.uniform(4.0, 6.3, N)
    pb = np.where(rng.uniform(size=N) < 0.2, pa * (1.0 + rng.uniform(-0.01, 0.01, N)),
                  10.0 ** rng.uniform(4.0, 6.3, N))
    T0 = rng.uniform(150.0, 900.0, N)
    mf = rng.uniform(-1.0, 1.0, N) ** 3 * 1.3
    forward = mf >= 0
    p0 = np.where(forward, pa, pb)
    pd = np.where(forward, pb, pa)
    mf = mf * p0 * np.sqrt(g * a_max / (R_AIR * T0)) * AREA
    phi = rng.uniform(0.0, 1e3, N) * mf / AREA * 10.0 ** rng.uniform(0, 4, N)
    G = np.abs(mf) / AREA
    W = G * G * R_AIR * T0 / g
    a = W / p0 ** 2
    keep = ((np.abs(pd * pd / np.maximum(W / K, 1e-300) - 1.0) > 1e-3)
            & (np.abs(a / a_max - 1.0) > 1e-3) & (np.abs(mf) > 1e-5 * AREA * p0 / 300.0))
    pa, pb, T0, mf, phi = pa[keep], pb[keep], T0[keep], mf[keep], phi[keep]
    out = adiabatic_pipe(pa, mf, pb, T0, AREA, R_AIR, g, phi)
    assert 0.1 < np.mean(out[6]) < 0.9 and np.mean(a[keep] > a_max) > 0.05
    args = [pa, mf, pb, T0, phi]
    for j in range(5):
        x = args[j]
        h = 1e-6 * np.abs(x)
        up, down = list(args), list(args)
        up[j], down[j] = x + h, x - h
        r_up = adiabatic_pipe(up[0], up[1], up[2], up[3], AREA, R_AIR, g, up[4], jac=False)[0]
        r_down = adiabatic_pipe(down[0], down[1], down[2], down[3], AREA, R_AIR, g, down[4],
                                jac=False)[0]
        fd = (r_up - r_down) / (2.0 * h)
        scale = (pa + pb + np.abs(out[0])) / np.abs(x)   # the residual's over the variable's
        err = np.abs(out[1 + j] - fd)
        assert np.all(err <= 1e-8 * (np.abs(fd) + scale)), \
            (j, float(np.max(err / (np.abs(fd) + scale))))


@pytest.mark.parametrize("g", GAMMAS)
@pytest.mark.parametrize("friction", ("laminar", "fixed_f"))
def test_a_single_root_along_the_flow(g, friction):
    """For 1000 random (p_a, p_b, T0, friction) the residual changes sign exactly
    once over a dense grid of mdot from 1.6x the nozzle flow of b to 1.6x that of a
    (so into the extension past both entries' limits), and its root lies in the
    bracketing cell."""
    rng = np.random.default_rng(5 if friction == "laminar" else 6)
    n_states, n_grid = 1000, 1601
    pa = 10.0 ** rng.uniform(4.0, 6.3, n_states)
    pb = np.where(rng.uniform(size=n_states) < 0.1, pa, 10.0 ** rng.uniform(4.0, 6.3, n_states))
    T0 = rng.uniform(150.0, 900.0, n_states)
    fLD = 10.0 ** rng.uniform(-3.0, 3.0, n_states)
    a_max = (0.5 * (g + 1.0)) ** (-(g + 1.0) / (g - 1.0))
    m_a = pa * np.sqrt(g * a_max / (R_AIR * T0)) * AREA
    m_b = pb * np.sqrt(g * a_max / (R_AIR * T0)) * AREA
    s = np.linspace(-1.0, 1.0, n_grid)
    mf = np.where(s[None, :] >= 0, s[None, :] * 1.6 * m_a[:, None], s[None, :] * 1.6 * m_b[:, None])
    if friction == "laminar":     # Phi = c mdot, c such that fLD applies at the nozzle flow
        c = 0.5 * fLD * (m_a / AREA) / AREA
        phi = c[:, None] * mf
    else:
        phi = _phi_turbulent(mf, fLD[:, None])
    full = lambda x: np.broadcast_to(x[:, None], mf.shape).ravel()      # noqa: E731
    R = adiabatic_pipe(full(pa), mf.ravel(), full(pb), full(T0), AREA, R_AIR, g, phi.ravel(),
                       jac=False)[0].reshape(mf.shape)
    assert np.all(np.isfinite(R))
    positive = R > 0.0                 # (at p_a = p_b the root is the grid's zero flow)
    changes = np.sum(positive[:, 1:] != positive[:, :-1], axis=1)
    assert np.all(changes == 1), np.flatnonzero(changes != 1)[:5]
    # the cell against brentq on the residual itself for a few states
    for i in range(0, n_states, 97):
        j = int(np.flatnonzero(positive[i, 1:] != positive[i, :-1])[0])

        def r(m, i=i):
            ph = (0.5 * fLD[i] * m_a[i] / AREA ** 2 * m if friction == "laminar"
                  else float(_phi_turbulent(m, fLD[i])))
            return float(adiabatic_pipe(pa[i], m, pb[i], T0[i], AREA, R_AIR, g, ph, jac=False)[0])
        root = brentq(r, mf[i, j], mf[i, j + 1], xtol=1e-300)
        assert mf[i, j] <= root <= mf[i, j + 1]
        assert (root >= 0) == (pa[i] >= pb[i]) or pa[i] == pb[i]


# ---------------------------------------------------------------------------------------
# limits and symmetry
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("length, diameter, dp", [(1.0, 2e-3, 100.0), (1.0, 2e-3, 500.0),
                                                  (0.1, 4e-3, 20.0), (5.0, 1e-3, 5e3),
                                                  (0.3, 1e-3, 2e3)])
def test_low_mach_limit_is_darcy_plus_the_exit_dynamic_pressure(length, diameter, dp):
    """At low Mach the law is the mean-density Darcy law (rho_m = p_m/(R T0)) plus
    the exit's dynamic pressure and the acceleration: p_a - p_b = Phi/rho_m +
    G^2/(2 rho_m) (1 + (g+1)/g ln(p_a/p_b)), here within M^2 of the dynamic
    pressure (measured: 0.8 M^2). The isothermal law's acceleration, 2 ln(p_a/p_b),
    is off by (1 - 1/g) ln(p_a/p_b) of it (the static temperature falls along the
    tube), which is more than M^2 in the long tubes here."""
    g, T0, mu = 1.4, 293.15, 1.81e-5
    area = math.pi * diameter ** 2 / 4
    c_mu = mu * length / (2 * area * diameter ** 2)
    pa, pb = 1e5 + dp, 1e5
    m = brentq(lambda m: float(adiabatic_pipe(pa, m, pb, T0, area, R_AIR, g, 64 * c_mu * m,
                                              jac=False)[0]), 0.0, 1.0, xtol=1e-300, rtol=1e-15)
    G = m / area
    assert G * diameter / mu < 2300                              # laminar: f Re = 64
    rho_m = 0.5 * (pa + pb) / (R_AIR * T0)
    dynamic = G * G / (2 * rho_m)
    mach2 = (G * R_AIR * T0 / pb) ** 2 / (g * R_AIR * T0)
    assert mach2 < 0.01 ** 2 * 30
    friction = 64 * c_mu * m / rho_m
    deviation = dp - friction - dynamic * (1 + (g + 1) / g * math.log(pa / pb))
    assert abs(deviation) < mach2 * dynamic
    if dp / pb > 0.01:
        isothermal_deviation = dp - friction - dynamic * (1 + 2 * math.log(pa / pb))
        assert abs(isothermal_deviation) > 3 * abs(deviation)


@pytest.mark.parametrize("g", GAMMAS)
def test_residual_is_odd_in_the_flow(g):
    """Swapping the ends and reversing flow and friction term negates R (the
    upstream end is the one the flow leaves) and mirrors its partials."""
    rng = np.random.default_rng(3)
    N = 500
    pa, pb = 10.0 ** rng.uniform(4, 6, N), 10.0 ** rng.uniform(4, 6, N)
    T0 = rng.uniform(200, 600, N)
    mf = rng.uniform(-1.2, 1.2, N) * np.maximum(pa, pb) * np.sqrt(0.58 / (R_AIR * T0)) * AREA
    phi = rng.uniform(0, 1e4, N) * mf
    mf[:5] = 0.0
    fwd = adiabatic_pipe(pa, mf, pb, T0, AREA, R_AIR, g, phi)
    rev = adiabatic_pipe(pb, -mf, pa, T0, AREA, R_AIR, g, -phi)
    scale = pa + pb
    np.testing.assert_allclose(rev[0], -fwd[0], rtol=0, atol=1e-15 * scale.max())
    np.testing.assert_allclose(rev[1], -fwd[3], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(rev[3], -fwd[1], rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(rev[2], fwd[2], rtol=1e-13, atol=1e-15 * np.abs(fwd[2]).max())
    np.testing.assert_allclose(rev[4], -fwd[4], rtol=1e-12, atol=1e-15 * np.abs(fwd[4]).max())
    np.testing.assert_array_equal(rev[6][5:], fwd[6][5:])


def test_gamma_to_one_is_the_isothermal_law():
    """As gamma -> 1 the isentropic entry becomes isothermal, Fanno flow becomes
    isothermal pipe flow choking at u = sqrt(R T), and the two laws (written
    independently) agree to O(gamma - 1), residuals, partials and choke flags."""
    rng = np.random.default_rng(2)
    N = 2000
    pa, pb = 10.0 ** rng.uniform(4.5, 6, N), 10.0 ** rng.uniform(4.5, 6, N)
    T0 = rng.uniform(250, 400, N)
    mf = (rng.uniform(-1, 1, N) * np.maximum(pa, pb) * np.sqrt(math.exp(-1) / (R_AIR * T0))
          * AREA * 0.99)
    phi = rng.uniform(0, 2000, N) * mf / AREA
    iso = isothermal_pipe(pa, mf, pb, AREA, R_AIR * T0, phi)
    for eps in (1e-4, 1e-6):
        ad = adiabatic_pipe(pa, mf, pb, T0, AREA, R_AIR, 1.0 + eps, phi)
        assert np.max(np.abs(ad[0] - iso[0]) / (pa + pb)) < eps          # measured 0.34 eps
        for i in (1, 2, 3, 5):
            assert np.max(np.abs(ad[i] - iso[i])) < 10 * eps * np.max(np.abs(iso[i]))
        np.testing.assert_allclose(ad[4], iso[4] * R_AIR, rtol=0,
                                   atol=10 * eps * np.max(np.abs(iso[4] * R_AIR)))
        np.testing.assert_array_equal(ad[6], iso[6])


def test_scalars_zero_flow_and_bad_gamma():
    """Floats in, floats out; at zero flow R = p_a - p_b exactly-ish and every
    partial finite; gamma <= 1 is refused."""
    out = adiabatic_pipe(3e5, 0.0, 1e5, 300.0, AREA, R_AIR, 1.4, 0.0)
    assert out[0] == pytest.approx(2e5, rel=1e-15)
    assert all(np.isfinite(v) for v in out[:6])
    assert out[1] == pytest.approx(1.0) and out[3] == pytest.approx(-1.0)
    # zero flow: dR/dmf is the friction's alone (the acceleration terms are O(G^2))
    assert out[2] == 0.0
    noj = adiabatic_pipe(3e5, 1e-3, 1e5, 300.0, AREA, R_AIR, 1.4, 1e3, jac=False)
    assert noj[1:6] == (None,) * 5
    assert float(noj[0]) == pytest.approx(
        float(adiabatic_pipe(3e5, 1e-3, 1e5, 300.0, AREA, R_AIR, 1.4, 1e3)[0]), rel=0)
    with pytest.raises(ValueError, match="gamma"):
        adiabatic_pipe(3e5, 1e-3, 1e5, 300.0, AREA, R_AIR, 1.0, 0.0)
