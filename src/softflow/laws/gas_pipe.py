"""Isothermal gas flow in a tube at any pressure ratio, compiled.

The law, its derivation and its references are in
:mod:`softflow.correlations.gas_pipe`, whose array functions loop over these
scalar functions.
"""
from __future__ import annotations

import math

from . import jit

INV_E = math.exp(-1.0)


@jit
def entry_z(a):
    """z in [0, 1] with z exp(-z) = a (the principal branch, z = -W0(-a)),
    held at 1 from a = 1/e on. Started from the series at the branch point
    (z = 1 - q + q^2/3 - 11 q^3/72, q = sqrt(2 (1 - e a))) near it and from
    a (1 + a + 3 a^2/2) near 0, then Halley's iteration on z - ln z = -ln a
    (its derivative 1 - 1/z vanishes only at the limit) to round-off."""
    if not a < INV_E:
        return 1.0 if a == a else a      # nan passes through
    if a <= 0.0:
        return 0.0 if a == 0.0 else math.nan
    if a < 0.25:
        z = a * (1.0 + a * (1.0 + 1.5 * a))
    else:
        q = math.sqrt(max(2.0 * (1.0 - a / INV_E), 0.0))
        z = 1.0 - q * (1.0 - q * (1.0 / 3.0 - q * 11.0 / 72.0))
        z = min(max(z, 1e-300), 1.0 - 1e-16)
    if a < 1e-8:
        return z        # the series' error O(a^4) is below round-off
    target = -math.log(a)
    for _ in range(20):
        g = z - math.log(z) - target
        d1 = 1.0 - 1.0 / z
        if d1 == 0.0:
            break
        d2 = 1.0 / (z * z)
        step = g / d1 / (1.0 - 0.5 * g * d2 / (d1 * d1))
        z_new = min(z - step, 1.0)
        if z_new <= 0.0:
            z_new = 0.5 * z
        if abs(z_new - z) <= 4e-16 * z:
            z = z_new
            break
        z = z_new
    return min(z, 1.0)


@jit
def isothermal_pipe(pa, mf, pb, area, c2, phi):
    """Residual R = F/(p_a + p_b) of isothermal tube flow and its partials:
    returns (R, dR/dpa, dR/dmf, dR/dpb, dR/dc2, dR/dphi, choked).

    pa, pb : node (stagnation) pressures [Pa]; mf : mass flow from a to b
    [kg/s]; area : flow area [m^2]; c2 : p/rho [m^2/s^2]; phi : friction term
    c_mu (f Re) mf [Pa kg/m^3] (signed with mf)."""
    forward = mf >= 0.0
    if forward:
        p0, pd, sign = pa, pb, 1.0
    else:
        p0, pd, sign = pb, pa, -1.0
    G = abs(mf) / area
    GG = G * G
    GGc2 = GG * c2
    c = math.sqrt(c2)
    Gc = G * c
    p0sq = p0 * p0
    a = GGc2 / p0sq
    inside = a < INV_E
    if inside:
        p1 = p0 * math.exp(-0.5 * entry_z(a))
    else:
        # past the entry's limit (an iterate only): the inlet held at Mach 1,
        # p1 = G c, which meets p0 e^-1/2 at the limit
        p1 = Gc
    p1sq = p1 * p1
    choked = pd < Gc
    pe = Gc if choked else pd
    log_ratio = math.log(p1 / pe)
    F_forward = p1sq - pe * pe - 2.0 * GGc2 * log_ratio
    if not inside:
        F_forward -= p0sq * (a - INV_E)
    F = sign * F_forward - 2.0 * c2 * phi
    S = pa + pb
    R = F / S
    # through z: dF/dz at fixed p0 times dz/da is -p0^2 (see the module); past
    # the limit the held inlet and the term -p0^2 (a - 1/e) give the same
    # dF/dG and dF/dc2
    if inside:
        dF_dp0 = 2.0 * (p1sq - GGc2) / p0 + 2.0 * a * p0
    else:
        dF_dp0 = 2.0 * INV_E * p0
    dF_dG = -2.0 * G * c2 * (2.0 * log_ratio + 1.0)
    dF_dc2 = -GG * (2.0 * log_ratio + 1.0)
    dF_dpe = 2.0 * (GGc2 - pe * pe) / pe        # zero where the exit chokes (M = 1)
    if choked:
        # pe = G c moves with G and c2
        dF_dpd = 0.0
        dF_dG += dF_dpe * c
        dF_dc2 += dF_dpe * 0.5 * G / c
    else:
        dF_dpd = dF_dpe
    if forward:
        dF_dpa, dF_dpb = dF_dp0, dF_dpd
    else:
        dF_dpa, dF_dpb = -dF_dpd, -dF_dp0
        dF_dc2 = -dF_dc2
    inv_S = 1.0 / S
    return (R, (dF_dpa - R) * inv_S, dF_dG * inv_S / area, (dF_dpb - R) * inv_S,
            (dF_dc2 - 2.0 * phi) * inv_S, -2.0 * c2 * inv_S, choked)


@jit
def isothermal_pipe_array(pa, mf, pb, area, c2, phi, R, R_pa, R_mf, R_pb, R_c2, R_phi,
                          choked):
    for i in range(pa.size):
        (R[i], R_pa[i], R_mf[i], R_pb[i], R_c2[i], R_phi[i],
         choked[i]) = isothermal_pipe(pa[i], mf[i], pb[i], area[i], c2[i], phi[i])


@jit
def entry_z_array(a, z):
    for i in range(a.size):
        z[i] = entry_z(a[i])
