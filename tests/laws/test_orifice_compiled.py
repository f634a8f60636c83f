"""The compiled orifice laws (softflow.laws.orifice): the array functions of
softflow.correlations.orifice as loops over the scalar laws, elementwise and
bitwise; the partials against central differences in every regime (band,
subsonic, choked, laminar-like, both directions); the nozzle law against the
Mach-number form of an ideal gas's isentropic flow through a convergent
nozzle, written here; the pure-Python mode (NUMBA_DISABLE_JIT=1) giving the
compiled numbers."""
import math

import numpy as np
import pytest

from helpers import compiled_and_python

from softflow.correlations import orifice as arrays
from softflow.laws import orifice as law

RHO0, T0 = arrays.ISO_6358_RHO0, arrays.ISO_6358_T0


def _states(n=600, seed=11):
    """Random states: pressures over 3 decades, ratios 0.01-1 (inside the
    regularization band, subsonic, choked, equal), both directions, gases of
    gamma 1.05-1.67, Cd 0.1-1, the ISO 6358 parameters."""
    rng = np.random.default_rng(seed)
    p_up = 10 ** rng.uniform(4.0, 7.0, n)
    kind = rng.integers(0, 4, n)
    pr = np.select([kind == 0, kind == 1, kind == 2],
                   [rng.uniform(0.01, 1.0, n), 1.0 - 10 ** rng.uniform(-12, -2, n),
                    np.ones(n)], rng.uniform(0.01, 0.5, n))
    forward = rng.random(n) < 0.5
    p_dn = p_up * pr
    d = 10 ** rng.uniform(-3.7, -2.3, n)
    Cd = rng.uniform(0.1, 1.0, n)
    R, T = rng.uniform(200.0, 2100.0, n), rng.uniform(250.0, 450.0, n)
    s = np.concatenate([np.zeros(3), 10 ** rng.uniform(-14, -6, n // 3),
                        rng.uniform(0.0, 0.99, n - 3 - n // 3)])
    return {
        "pa": np.where(forward, p_up, p_dn), "pb": np.where(forward, p_dn, p_up),
        "p_up": p_up, "T": T, "R": R, "gamma": rng.uniform(1.05, 1.67, n), "Cd": Cd,
        "area": np.pi * d * d / 4, "K": 1 / Cd ** 2, "rho_liq": rng.uniform(700.0, 1100.0, n),
        "rho_gas": p_up / (R * T), "dp_small": 10 ** rng.uniform(-3, 1, n), "s": s,
        "C": 10 ** rng.uniform(-9, -7, n), "b": rng.uniform(0.05, 0.7, n),
        "m": rng.uniform(0.3, 1.0, n), "prl": 1.0 - 10 ** rng.uniform(-4, -2, n)}


def _drho(rho, p_up):
    """A real gas's slope of density in pressure (10 % off the ideal gas's)."""
    return 1.1 * rho / p_up


# ---------------------------------------------------------------------------------------
# the array functions are loops over the scalar laws
# ---------------------------------------------------------------------------------------
def _cases(S):
    """(array function, its arguments, scalar law, the scalar's arguments per state)."""
    dp = S["pa"] - S["pb"]
    drho = _drho(S["rho_gas"], S["p_up"])
    iso = (S["T"], S["C"], S["b"], S["m"], S["prl"])
    s_iso = (1.0 - np.minimum(S["pa"], S["pb"]) / S["p_up"]) / (1.0 - S["b"])
    s_lam = (1.0 - S["prl"]) / (1.0 - S["b"])
    nozzle = (S["pa"], S["pb"], S["rho_gas"], S["gamma"], S["Cd"], S["area"], S["dp_small"])
    return {
        "regularized_sqrt": (arrays.regularized_sqrt, (dp, S["dp_small"]),
                             law.regularized_sqrt, (dp, S["dp_small"])),
        "loss_coefficient": (arrays.massflow_loss_coefficient,
                             (dp, S["rho_liq"], S["K"], S["area"], S["dp_small"]),
                             law.massflow_loss_coefficient,
                             (dp, S["rho_liq"], S["K"], S["area"], S["dp_small"])),
        "critical_pressure_ratio": (lambda g: (arrays.critical_pressure_ratio(g),),
                                    (S["gamma"],), lambda g: (law.critical_pressure_ratio(g),),
                                    (S["gamma"],)),
        "nozzle_flow_factor": (arrays.nozzle_flow_factor, (S["s"], S["gamma"]),
                               law.nozzle_flow_factor, (S["s"], S["gamma"])),
        "nozzle-ideal": (arrays.massflow_nozzle, nozzle, law.massflow_nozzle,
                         (S["pa"], S["pb"], S["rho_gas"], S["rho_gas"] / S["p_up"], S["gamma"],
                          S["Cd"], S["area"], S["dp_small"])),
        "nozzle-real": (arrays.massflow_nozzle, (*nozzle, drho), law.massflow_nozzle,
                        (S["pa"], S["pb"], S["rho_gas"], drho, S["gamma"], S["Cd"], S["area"],
                         S["dp_small"])),
        "iso_6358_phi": (arrays._iso_6358_phi, (s_iso, S["b"], S["m"], s_lam),
                         law.iso_6358_phi, (s_iso, S["m"], s_lam)),
        "iso_6358": (arrays.massflow_ISO_6358, (S["pa"], S["pb"], *iso), law.massflow_iso_6358,
                     (S["pa"], S["pb"], *iso, np.full_like(S["pa"], RHO0),
                      np.full_like(S["pa"], T0))),
    }


@pytest.mark.parametrize("name", ["regularized_sqrt", "loss_coefficient",
                                  "critical_pressure_ratio", "nozzle_flow_factor",
                                  "nozzle-ideal", "nozzle-real", "iso_6358_phi", "iso_6358"])
def test_array_law_is_the_scalar_law_elementwise(name):
    S = _states()
    array_fn, array_args, scalar_fn, scalar_args = _cases(S)[name]
    got = array_fn(*array_args)
    for i in range(S["pa"].size):
        one = scalar_fn(*(float(a[i]) for a in scalar_args))
        assert tuple(float(g[i]) for g in got) == one, (name, i)
    # floats give floats, and a float with an array broadcasts
    first = array_fn(*(float(a[0]) for a in array_args))
    assert all(type(x) is float for x in first)
    assert first == scalar_fn(*(float(a[0]) for a in scalar_args))
    mixed = array_fn(array_args[0][:5], *(float(a[0]) for a in array_args[1:]))
    assert all(x.shape == (5,) for x in mixed)


def test_the_regimes_are_all_visited():
    S = _states()
    pa, pb, g = S["pa"], S["pb"], S["gamma"]
    pr = np.minimum(pa, pb) / S["p_up"]
    assert (pa < pb).sum() > 100 and (pa > pb).sum() > 100 and (pa == pb).sum() > 50
    assert (pr <= law.critical_pressure_ratio(1.67)).sum() > 100       # choked
    assert ((pr > (2 / (g + 1)) ** (g / (g - 1))) & (np.abs(pa - pb) > S["dp_small"])).sum() > 100
    assert ((np.abs(pa - pb) < S["dp_small"]) & (pa != pb)).sum() > 20  # the band
    assert (pr > S["prl"]).sum() > 100 and (pr <= S["b"]).sum() > 100  # ISO laminar, choked
    assert (S["s"] < 1e-9).sum() > 50                                  # the factor's limit


# ---------------------------------------------------------------------------------------
# partials against central differences
# ---------------------------------------------------------------------------------------
def _central(f, args, k, h):
    """The central difference of f(*args)[0] in args[k] with the step h,
    divided by the step as rounded."""
    up, down = list(args), list(args)
    up[k] += h
    down[k] -= h
    return (f(*up)[0] - f(*down)[0]) / (up[k] - down[k])


def _step(x, dp, band):
    """A step in the pressure x (dp the pressure difference): small against the
    band inside it (the cubic), else against x and the distance to the band's
    edge; None where it would come within 10 steps of the edge (the second
    derivative jumps there) or be under 10^4 ulps of x."""
    inside = abs(dp) < band
    h = 1e-4 * band if inside else min(1e-7 * abs(x), 3e-3 * (abs(dp) - band))
    if abs(abs(dp) - band) < 10 * h or h < 1e4 * math.ulp(x):
        return None
    return h


def _near_a_kink(pa, pb, h, *ratios):
    """Whether pa or pb is within a few steps of a pressure ratio where the
    second derivative jumps (choking, the laminar-like edge), so that a central
    difference straddles it."""
    lo, hi = min(pa, pb), max(pa, pb)
    return any(abs(lo - r * hi) < 10 * h * (1 + r) for r in ratios)


def _nozzle_of_gas(pa, pb, RT, real, gamma, Cd, area, dp_small):
    """The nozzle law with the density at the upstream pressure p of an ideal
    gas, p/RT, or of a real one, p/RT (1 + 1e-7 p)."""
    p = max(pa, pb)
    rho, drho = ((p / RT * (1.0 + 1e-7 * p), (1.0 + 2e-7 * p) / RT) if real
                 else (p / RT, 1.0 / RT))
    return law.massflow_nozzle(pa, pb, rho, drho, gamma, Cd, area, dp_small)


def test_nozzle_partials_match_central_differences_ideal_and_real_gas():
    S = _states(seed=3)
    checked = 0
    for i in range(S["pa"].size):
        pa, pb, g, Cd, A, xs = (float(S[k][i]) for k in ("pa", "pb", "gamma", "Cd", "area",
                                                          "dp_small"))
        h = _step(max(pa, pb), pa - pb, xs)
        if h is None or _near_a_kink(pa, pb, h, law.critical_pressure_ratio(g)):
            continue
        for real in (False, True):
            args = (pa, pb, float(S["R"][i] * S["T"][i]), real, g, Cd, A, xs)
            _, d_a, d_b = _nozzle_of_gas(*args)
            scale = abs(d_a) + abs(d_b)
            assert d_a == pytest.approx(_central(_nozzle_of_gas, args, 0, h), rel=1e-5,
                                        abs=1e-7 * scale), (i, real)
            assert d_b == pytest.approx(_central(_nozzle_of_gas, args, 1, h), rel=1e-5,
                                        abs=1e-7 * scale), (i, real)
            checked += 1
    assert checked > 500


def test_iso_6358_and_loss_coefficient_partials_match_central_differences():
    S = _states(seed=5)
    checked = 0
    for i in range(S["pa"].size):
        pa, pb, b, prl = (float(S[k][i]) for k in ("pa", "pb", "b", "prl"))
        args = (pa, pb, *(float(S[k][i]) for k in ("T", "C")), b, float(S["m"][i]), prl,
                RHO0, T0)
        h = 1e-7 * max(pa, pb) if pa != pb else 1e-6 * (1 - prl) * pa
        if not _near_a_kink(pa, pb, h, b, prl):
            _, d_a, d_b = law.massflow_iso_6358(*args)
            scale = abs(d_a) + abs(d_b)
            assert d_a == pytest.approx(_central(law.massflow_iso_6358, args, 0, h), rel=1e-5,
                                        abs=1e-7 * scale), i
            assert d_b == pytest.approx(_central(law.massflow_iso_6358, args, 1, h), rel=1e-5,
                                        abs=1e-7 * scale), i
            checked += 1
        # the loss coefficient's law, in dp and in rho
        args = (pa - pb, *(float(S[k][i]) for k in ("rho_liq", "K", "area", "dp_small")))
        _, w_dp, w_rho = law.massflow_loss_coefficient(*args)
        hd = _step(max(pa, pb), pa - pb, args[4])
        if hd is not None:
            assert w_dp == pytest.approx(_central(law.massflow_loss_coefficient, args, 0, hd),
                                         rel=1e-5), i
        assert w_rho == pytest.approx(_central(law.massflow_loss_coefficient, args, 1,
                                               1e-6 * args[1]), rel=1e-6, abs=1e-300), i
    assert checked > 400


def test_flow_factor_and_flow_fraction_slopes_match_central_differences():
    S = _states(seed=9)
    for s, g in zip(S["s"], S["gamma"]):
        dY = law.nozzle_flow_factor(s, g)[1]
        s_star = 1.0 - law.critical_pressure_ratio(g)
        # (Y is nearly linear at small s: a step of 1e-6 there, across s = 0 and
        # the switch to the limit at s = 1e-9, is off by O(1e-6) only)
        h = 1e-6 * min(s, 1 - s) if s > 1e-3 else 1e-6
        if abs(s - s_star) < 10 * h:
            continue
        fd = _central(law.nozzle_flow_factor, (float(s), float(g)), 0, h)
        assert dY == pytest.approx(fd, rel=1e-5), (s, g)
    for s, m, lam in zip(np.linspace(0.0, 1.5, 301), np.linspace(0.3, 1.0, 301),
                         np.geomspace(1e-4, 5e-2, 301)):
        dphi = law.iso_6358_phi(s, m, lam)[1]
        h = 1e-3 * lam
        if abs(s - lam) < 10 * h or abs(s - 1.0) < 10 * h:
            continue
        fd = _central(law.iso_6358_phi, (float(s), float(m), float(lam)), 0, h)
        assert dphi == pytest.approx(fd, rel=1e-5, abs=1e-9)


# ---------------------------------------------------------------------------------------
# the nozzle law against the isentropic flow of an ideal gas, written here
# ---------------------------------------------------------------------------------------
def convergent_nozzle_flux(p0, p_back, RT0, gamma):
    """Mass flux [kg/(s m^2)] of an ideal gas expanding isentropically from rest
    at p0 (R T0 = RT0) through a convergent nozzle into p_back, in the Mach form:
    the throat at the back pressure while that is above the critical ratio
    (2/(g+1))^(g/(g-1)), where the Mach number reaches 1, else at Mach 1,

        M^2 = 2/(g-1) ((p0/p_t)^((g-1)/g) - 1),
        flux = p0 sqrt(g/(R T0)) M (1 + (g-1)/2 M^2)^(-(g+1)/(2(g-1)))."""
    g = gamma
    critical = (2.0 / (g + 1.0)) ** (g / (g - 1.0))
    if p_back / p0 <= critical:
        M = 1.0
    else:
        # (p0/p_t)^((g-1)/g) - 1 through expm1/log1p, as the ratio nears 1
        M = math.sqrt(2.0 / (g - 1.0) * math.expm1(-(g - 1.0) / g
                                                    * math.log1p(-(p0 - p_back) / p0)))
    return p0 * math.sqrt(g / RT0) * M * (1.0 + 0.5 * (g - 1.0) * M * M) ** (
        -0.5 * (g + 1.0) / (g - 1.0))


def test_nozzle_law_is_cd_times_the_isentropic_convergent_nozzle():
    S = _states(seed=13)
    worst, n = 0.0, 0
    for i in range(S["pa"].size):
        pa, pb, g, Cd, A, xs, R, T = (float(S[k][i]) for k in (
            "pa", "pb", "gamma", "Cd", "area", "dp_small", "R", "T"))
        if abs(pa - pb) <= xs:
            continue            # (the regularization band: not the nozzle's law)
        p0, p_back = max(pa, pb), min(pa, pb)
        rho0 = p0 / (R * T)
        q = law.massflow_nozzle(pa, pb, rho0, rho0 / p0, g, Cd, A, xs)[0]
        want = Cd * A * convergent_nozzle_flux(p0, p_back, R * T, g)
        want = want if pa > pb else -want
        worst = max(worst, abs(q / want - 1))
        n += 1
    assert n > 300
    assert worst < 1e-12       # (measured: 2.0e-15)


def test_nozzle_chokes_at_the_critical_ratio_and_reverses_with_the_pressures():
    g, Cd, A, xs, RT = 1.4, 0.6, 1e-6, 0.05, 287.0 * 293.0
    p0 = 5e5
    rho0 = p0 / RT
    choked = Cd * A * convergent_nozzle_flux(p0, 0.0, RT, g)
    pr_star = law.critical_pressure_ratio(g)
    assert pr_star == pytest.approx(0.528281787717174, rel=1e-14)
    for pr in (0.01, 0.2, 0.5, pr_star):
        forward = law.massflow_nozzle(p0, pr * p0, rho0, rho0 / p0, g, Cd, A, xs)
        backward = law.massflow_nozzle(pr * p0, p0, rho0, rho0 / p0, g, Cd, A, xs)
        assert forward[0] == pytest.approx(choked, rel=1e-14)
        assert backward == pytest.approx((-forward[0], -forward[2], -forward[1]), rel=1e-14)
        # choked: the flow does not see the downstream pressure, and is p0 / sqrt(RT0)
        assert abs(forward[2]) < 1e-12 * forward[1]
        assert forward[1] == pytest.approx(choked / p0, rel=1e-12)


# ---------------------------------------------------------------------------------------
# the pure-Python mode
# ---------------------------------------------------------------------------------------
@pytest.mark.slow
def test_pure_python_mode_gives_the_compiled_numbers():
    expression = (
        "[orifice.regularized_sqrt(0.3, 2.0), orifice.regularized_sqrt(-7.0, 2.0), "
        "orifice.massflow_loss_coefficient(3e3, 998.0, 2.7, 1e-6, 0.5), "
        "orifice.nozzle_flow_factor(1e-11, 1.4), orifice.nozzle_flow_factor(0.2, 1.4), "
        "orifice.nozzle_flow_factor(0.8, 1.3), "
        "orifice.massflow_nozzle(3e5, 2.5e5, 3.5, 1.1e-5, 1.4, 0.6, 1e-6, 0.05), "
        "orifice.massflow_nozzle(1e5, 6e5, 7.1, 1.2e-5, 1.3, 0.8, 1e-6, 0.05), "
        "orifice.massflow_iso_6358(3e5, 2.9999e5, 300.0, 1e-8, 0.4, 0.5, 0.999, 1.185, "
        "293.15), "
        "orifice.massflow_iso_6358(1e5, 6e5, 300.0, 1e-8, 0.4, 0.7, 0.999, 1.185, 293.15)]")
    compiled, python, _ = compiled_and_python(expression)
    np.testing.assert_allclose(python, compiled, rtol=1e-15)
