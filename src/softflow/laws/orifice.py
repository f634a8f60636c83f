"""Orifice and valve flow laws, compiled: the regularized square root, the
incompressible (loss-coefficient) orifice, the isentropic nozzle with a
discharge coefficient, and ISO 6358.

The laws, their derivations and their references are in
:mod:`softflow.correlations.orifice`, whose array functions loop over these
scalar functions. Each returns its value and its partial derivatives.
"""
from __future__ import annotations

import math

from . import jit


@jit
def _sign(x):
    """NumPy's sign: -1, 0 or 1, +0.0 for either zero, nan for nan."""
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return 0.0 if x == 0.0 else x


@jit
def _maximum(a, b):
    """NumPy's maximum of two floats (nan where either is)."""
    return a if (a >= b or math.isnan(a)) else b


@jit
def _minimum(a, b):
    """NumPy's minimum of two floats (nan where either is)."""
    return a if (a <= b or math.isnan(a)) else b


@jit
def odd_cubic(x, x_l, f_l, df_l):
    """y = x (alpha + beta x^2), the odd cubic with y(x_l) = f_l and
    y'(x_l) = df_l: returns (y, dy/dx). Monotone on [0, x_l] where
    0 < df_l <= f_l/x_l."""
    beta = (df_l - f_l / x_l) / (2.0 * x_l * x_l)
    alpha = f_l / x_l - beta * x_l * x_l
    x2 = x * x
    return x * (alpha + beta * x2), alpha + 3.0 * beta * x2


@jit
def regularized_sqrt(x, x_small):
    """sign(x) sqrt(|x|), exact for |x| >= x_small and the odd cubic matching
    its value and slope at +-x_small inside: returns (y, dy/dx)."""
    ax = abs(x)
    if ax < x_small:
        rs = math.sqrt(x_small)
        return odd_cubic(x, x_small, rs, 0.5 / rs)
    r = math.sqrt(ax)
    return _sign(x) * r, 0.5 / r


@jit
def massflow_loss_coefficient(dp, rho, K, area, dp_small):
    """Mass flow A sqrt(2 rho dp / K) through a loss coefficient K, signed with
    dp and regularized below |dp| = dp_small: returns (mdot, d mdot/d dp,
    d mdot/d rho)."""
    r, dr = regularized_sqrt(dp, dp_small)
    g = area * math.sqrt(2.0 / K)
    sq = math.sqrt(rho)
    return g * sq * r, g * sq * dr, g * r * 0.5 / sq


@jit
def critical_pressure_ratio(gamma):
    """(2/(gamma+1))^(gamma/(gamma-1)): the pressure ratio at which an ideal
    gas's isentropic nozzle chokes."""
    return (2.0 / (gamma + 1.0)) ** (gamma / (gamma - 1.0))


@jit
def nozzle_flow_factor(s, gamma):
    """The isentropic nozzle's flow relative to the incompressible orifice's at
    the same upstream density and pressure drop, Y(s), and dY/ds, with
    s = 1 - p_down/p0: the choked value below the critical ratio, the limit
    1 - 3 s/(4 gamma) for s < 1e-9, the subsonic formula (powers of the
    pressure ratio through log1p/expm1) between."""
    e = (gamma - 1.0) / gamma
    if s >= 1.0 - critical_pressure_ratio(gamma):
        psi_star = math.sqrt(gamma * (2.0 / (gamma + 1.0)) ** ((gamma + 1.0) / (gamma - 1.0)))
        Y = psi_star / math.sqrt(2.0 * s)
        return Y, -0.5 * Y / s
    if s < 1e-9:
        return 1.0 - 0.75 / gamma * s, -0.75 / gamma
    ln_pr = math.log1p(-s)
    E = -math.expm1(e * ln_pr)                  # 1 - pr^e
    pr = 1.0 - s
    G = math.exp(2.0 / gamma * ln_pr) * (E / s) / e        # Y^2
    dlnG = 2.0 / (gamma * pr) - e * math.exp((e - 1.0) * ln_pr) / E + 1.0 / s
    Y = math.sqrt(G)
    return Y, -0.5 * Y * dlnG


@jit
def massflow_nozzle(p_a, p_b, rho_up, drho_up, gamma, Cd, area, dp_small):
    """Mass flow from a to b of a gas through an isentropic nozzle with a
    discharge coefficient, Cd A sqrt(2 rho_up) r(p_a - p_b) Y(s) (r the
    regularized root, Y the flow factor, s = 1 - p_down/p_up): returns
    (mdot, d mdot/d p_a, d mdot/d p_b).

    rho_up, drho_up: the density at the upstream pressure max(p_a, p_b) and
    its derivative in that pressure (rho_up/p_up for an ideal gas at a fixed
    temperature)."""
    forward = p_a >= p_b
    if forward:
        p_up, p_dn = p_a, p_b
    else:
        p_up, p_dn = p_b, p_a
    s = (p_up - p_dn) / p_up
    Y, dY = nozzle_flow_factor(s, gamma)
    r, dr = regularized_sqrt(p_a - p_b, dp_small)
    k = Cd * area * math.sqrt(2.0 * rho_up)
    q = k * r * Y
    base = k * dr * Y
    d_up = 0.5 * q * drho_up / rho_up + k * r * dY * p_dn / (p_up * p_up)
    d_dn = -k * r * dY / p_up
    if forward:
        return q, base + d_up, -base + d_dn
    return q, base + d_dn, -base + d_up


@jit
def iso_6358_phi(s, m, s_lam):
    """ISO 6358's flow fraction phi(s) of the choked flow and dphi/ds, with
    s = (1 - p_down/p_up)/(1 - b): 1 from s = 1 (choked), [s (2 - s)]^m below,
    the odd cubic matched at s_lam below s_lam."""
    if s < s_lam:
        u_l = s_lam * (2.0 - s_lam)
        return odd_cubic(s, s_lam, u_l ** m, m * u_l ** (m - 1.0) * (2.0 - 2.0 * s_lam))
    s_c = _minimum(_maximum(s, s_lam), 1.0)
    u = s_c * (2.0 - s_c)
    return u ** m, m * u ** (m - 1.0) * (2.0 - 2.0 * s_c)


@jit
def massflow_iso_6358(p_a, p_b, T, C, b, m, pr_laminar, rho0, T0):
    """ISO 6358 mass flow from a to b, C rho0 p_up sqrt(T0/T) phi(s): returns
    (mdot, d mdot/d p_a, d mdot/d p_b)."""
    forward = p_a >= p_b
    if forward:
        p_up, p_dn = p_a, p_b
    else:
        p_up, p_dn = p_b, p_a
    k = C * rho0 * math.sqrt(T0 / T)
    one_b = 1.0 - b
    s = (1.0 - p_dn / p_up) / one_b
    s_lam = (1.0 - pr_laminar) / one_b
    phi, dphi = iso_6358_phi(s, m, s_lam)
    q = k * p_up * phi
    d_up = k * (phi + dphi * p_dn / (p_up * one_b))
    d_dn = -k * dphi / one_b
    if forward:
        return q, d_up, d_dn
    return -q, -d_dn, -d_up


# -- the array loops (1-D arrays of one length; the outputs preallocated) ---------------
@jit
def regularized_sqrt_array(x, x_small, y, dy):
    for i in range(x.size):
        y[i], dy[i] = regularized_sqrt(x[i], x_small[i])


@jit
def massflow_loss_coefficient_array(dp, rho, K, area, dp_small, q, q_dp, q_rho):
    for i in range(dp.size):
        q[i], q_dp[i], q_rho[i] = massflow_loss_coefficient(dp[i], rho[i], K[i], area[i],
                                                            dp_small[i])


@jit
def critical_pressure_ratio_array(gamma, pr):
    for i in range(gamma.size):
        pr[i] = critical_pressure_ratio(gamma[i])


@jit
def nozzle_flow_factor_array(s, gamma, Y, dY):
    for i in range(s.size):
        Y[i], dY[i] = nozzle_flow_factor(s[i], gamma[i])


@jit
def massflow_nozzle_array(p_a, p_b, rho_up, drho_up, gamma, Cd, area, dp_small, ideal,
                          q, q_pa, q_pb):
    """``ideal``: drho_up is rho_up/p_up (an ideal gas at a fixed temperature)
    and the array ``drho_up`` is not read."""
    for i in range(p_a.size):
        if not ideal:
            drho = drho_up[i]
        elif p_a[i] >= p_b[i]:
            drho = rho_up[i] / p_a[i]
        else:
            drho = rho_up[i] / p_b[i]
        q[i], q_pa[i], q_pb[i] = massflow_nozzle(p_a[i], p_b[i], rho_up[i], drho, gamma[i],
                                                 Cd[i], area[i], dp_small[i])


@jit
def iso_6358_phi_array(s, m, s_lam, phi, dphi):
    for i in range(s.size):
        phi[i], dphi[i] = iso_6358_phi(s[i], m[i], s_lam[i])


@jit
def massflow_iso_6358_array(p_a, p_b, T, C, b, m, pr_laminar, rho0, T0, q, q_pa, q_pb):
    for i in range(p_a.size):
        q[i], q_pa[i], q_pb[i] = massflow_iso_6358(p_a[i], p_b[i], T[i], C[i], b[i], m[i],
                                                   pr_laminar[i], rho0[i], T0[i])
