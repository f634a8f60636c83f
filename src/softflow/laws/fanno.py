"""Adiabatic (Fanno) gas flow in a tube at any pressure ratio, compiled.

The law, its derivation and its references are in
:mod:`softflow.correlations.fanno`, whose array functions loop over these
scalar functions. The constants that depend on gamma alone are made by
:func:`gas_constants`; the ``*_gas`` functions take them made (a loop over
many instances of one gas makes them once), the others take gamma.
"""
from __future__ import annotations

import math

from . import jit

#: a floor for a = W/p0^2 under the logarithm (zero flow): z1 = 1e-300 there
A_FLOOR = 1e-300

_NAN = math.nan


@jit
def gas_constants(gamma):
    """The law's constants for a ratio of specific heats gamma:
    (k, K, K/2, -n, n - 1, ln a*, a*, 1/gamma, P, s/P, beta, 2k, 4k), with
    k = (gamma-1)/2, K = (gamma+1)/2, n = K/k, a* = K^-n the entry's limit,
    s = sqrt(gamma + 1), P = n ln K = -ln a*; P, s/P and beta give the entry's
    starting value (see :func:`entry_ln`). All nan unless gamma > 1."""
    if not gamma > 1.0:
        return (_NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN, _NAN,
                _NAN)
    k = 0.5 * (gamma - 1.0)
    K = 0.5 * (gamma + 1.0)
    n = K / k
    ln_a_max = -n * math.log1p(k)
    s = math.sqrt(gamma + 1.0)
    P = n * math.log(K)
    beta = ((1.0 - k) / 3.0 - 1.0 + s * s / (2.0 * P)) / P
    return (k, K, 0.5 * K, -n, n - 1.0, ln_a_max, math.exp(ln_a_max), 1.0 / gamma, P,
            s / P, beta, 2.0 * k, 4.0 * k)


@jit
def entry_ln(lna, gas):
    """ln(1 + k z1) of the isentropic entry from ln a (a = W/p0^2, ``gas`` from
    :func:`gas_constants`); ln K past the entry's limit.

    The start: with q^2 = ln(a*/a), -ln z1 = v ~ s q + (1 - k)/3 q^2 near the
    limit and v ~ q^2 + P at rest; v0 = q^2 + P (1 - exp(-(s/P) q - beta q^2))
    has both and the series to q^2. For gamma in (1, 3] u0 = -v0 lies above the
    root u = ln z1 by at most 1.1 % of |u|, where f > 0 and Halley's denominator
    exceeds 1. Then two Halley steps on f(u) = u - n ln(1 + k e^u) - ln a
    (f' = (1 - z)/(1 + k z), f'' = -K z/(1 + k z)^2; concave and increasing for
    u <= 0) reach round-off: the first moves down from u0 <= 0, the second by
    round-off-sized amounts near the limit. The floor on 1 - z makes the step
    0/0 -> 0 at the limit itself (q = 0, f = 0 there); past it q = 0 too: z1 = 1."""
    k, _, half_K, minus_n, _, ln_a_max, _, _, P, s_P, beta, _, _ = gas
    q = math.sqrt(max(ln_a_max - lna, 0.0))
    u = -(q * q + P * (1.0 - math.exp(-q * (s_P + beta * q))))
    for _ in range(2):
        z = math.exp(u)
        kz = k * z
        f = u + minus_n * math.log1p(kz) - lna
        omz = max(1.0 - z, 1e-150)
        u = u - f * (1.0 + kz) / (omz + half_K * f * z / omz)
    return math.log1p(k * math.exp(u))


@jit
def adiabatic_entry_z_gas(a, gas):
    """:func:`adiabatic_entry_z` with the gas's constants made
    (:func:`gas_constants`)."""
    return math.expm1(entry_ln(math.log(max(a, A_FLOOR)), gas)) / gas[0]


@jit
def adiabatic_entry_z(a, gamma):
    """z1 = M1^2 in [0, 1] of an isentropic entry from rest passing the flux
    a = G^2 R T0/(gamma p0^2): the subsonic root of z1 (1 + k z1)^-n = a,
    k = (gamma-1)/2, n = (gamma+1)/(gamma-1); 1 from the entry's limit
    a* = ((gamma+1)/2)^-n on (see :func:`entry_ln`)."""
    return adiabatic_entry_z_gas(a, gas_constants(gamma))


@jit
def adiabatic_pipe_gas(pa, mf, pb, T0, area, R, gas, phi):
    """:func:`adiabatic_pipe` with the gas's constants made
    (:func:`gas_constants`)."""
    _, K, _, minus_n, n1, ln_a_max, _, inv_g, _, _, _, k2, k4 = gas
    forward = mf >= 0.0
    if forward:
        p0, pd = pa, pb
    else:
        p0, pd = pb, pa
    RT = R * T0
    G = abs(mf) / area
    GRT_g = G * RT * inv_g
    W = G * GRT_g                               # G^2 R T0/g [Pa^2]
    p0sq = p0 * p0
    lna = math.log(max(W / p0sq, A_FLOOR))
    L1 = entry_ln(lna, gas)                     # ln(1 + k z1)
    # the exit: static pressure p_d, or p2* = sqrt(W/K) where p_d is below it
    pdsq = pd * pd
    pstar_sq = W / K
    choked = pdsq < pstar_sq
    pesq = pstar_sq if choked else pdsq
    # z2 (1 + k z2) = b: with r = sqrt(1 + 4 k b), 1 + k z2 = (1 + r)/2 and
    # 1 + (g-1) z2 = r
    b = W / pesq
    r = math.sqrt(1.0 + k4 * b)
    B2 = 0.5 + 0.5 * r
    # ln X1 - ln X2 = ln[(rho2/rho1)^2], finite at zero flow (X = K z/(1 + k z))
    dlnX = math.log(pesq * B2 * B2 / p0sq) + n1 * L1
    A1 = math.exp(minus_n * L1)                 # a/z1; a* at and past the limit
    if ln_a_max < lna:
        # past the entry's limit z1 = 1 (A1 = a*) makes the formula's ln X1 ln(a/a*):
        # held at 0 instead; then with h = -(a - a*), p0^2 h = p0^2 a* - W is what
        # the first term below gives as it stands
        dlnX = dlnX + (ln_a_max - lna)
    # p0^2 A1 (1 - z1) - p2^2 B2 (1 - z2) + K W dlnX, with p0^2 A1 z1 = p2^2 B2 z2 = W
    K_dlnX = K * dlnX
    F = p0sq * A1 - pesq * B2 + W * K_dlnX
    if not forward:
        F = -F
    F = F - 2.0 * RT * phi
    S = pa + pb
    Rs = F / S
    # h'(a) - k2'(b) (see the module): dF/dG = 2 G R T0/g (...), dF/d(R T0) = G^2/g (...)
    Bb_r = (B2 - b) / r                         # B2 (1 - z2)/(1 + (g-1) z2)
    D = K_dlnX - 1.0 - k2 * Bb_r / B2
    dF_dG = 2.0 * GRT_g * D
    dF_dRT = G * G * inv_g * D
    dF_dp0 = 2.0 * A1 * p0
    # zero at the choke (exit Mach 1), so p2* moving with G and T0 adds nothing
    dF_dpd = 0.0 if choked else -2.0 * Bb_r * pd
    if forward:
        dF_dpa, dF_dpb = dF_dp0, dF_dpd
    else:
        dF_dpa, dF_dpb = -dF_dpd, -dF_dp0
        dF_dRT = -dF_dRT
    inv_S = 1.0 / S
    return (Rs, (dF_dpa - Rs) * inv_S, dF_dG * inv_S / area, (dF_dpb - Rs) * inv_S,
            (dF_dRT - 2.0 * phi) * (R * inv_S), -2.0 * RT * inv_S, choked)


@jit
def adiabatic_pipe(pa, mf, pb, T0, area, R, gamma, phi):
    """Residual R = F/(p_a + p_b) of adiabatic (Fanno) tube flow and its partials:
    returns (R, dR/dpa, dR/dmf, dR/dpb, dR/dT0, dR/dphi, choked).

    pa, pb : node (stagnation) pressures [Pa]; mf : mass flow from a to b
    [kg/s]; T0 : stagnation temperature of the upstream node [K]; area : flow
    area [m^2]; R : gas constant [J/(kg K)]; gamma : ratio of specific heats
    [-] (nan results unless gamma > 1); phi : friction term c_mu (f Re) mf
    [Pa kg/m^3] (signed with mf). dR/dT0 is at fixed phi."""
    return adiabatic_pipe_gas(pa, mf, pb, T0, area, R, gas_constants(gamma), phi)


# -- array loops (the arrays' shapes are made equal by the caller; one gamma) -----------
@jit
def adiabatic_pipe_array(pa, mf, pb, T0, area, R, gamma, phi, res, res_pa, res_mf, res_pb,
                         res_T0, res_phi, choked):
    gas = gas_constants(gamma)
    for i in range(pa.size):
        (res[i], res_pa[i], res_mf[i], res_pb[i], res_T0[i], res_phi[i],
         choked[i]) = adiabatic_pipe_gas(pa[i], mf[i], pb[i], T0[i], area[i], R[i], gas,
                                         phi[i])


@jit
def adiabatic_entry_z_array(a, gamma, z):
    gas = gas_constants(gamma)
    for i in range(a.size):
        z[i] = adiabatic_entry_z_gas(a[i], gas)
