"""Isothermal gas flow in a tube at any pressure ratio, choked flow included.

The tube connects two nodes whose pressures are *stagnation* pressures (the
fluid at rest). With G = mdot/A the mass flux, c^2 = p/rho the isothermal
sound speed squared (R T for an ideal gas) and the flow from the upstream node
(p0) to the downstream one (p_d):

* entry: the gas accelerates from rest into the tube, isothermally and
  without loss: c^2 ln(p0/p1) = u1^2/2, u1 = G c^2/p1, i.e. with z = M1^2
  (M1 = u1/c):

      z exp(-z) = G^2 c^2 / p0^2,    p1 = p0 exp(-z/2);

* pipe: isothermal flow with wall friction and acceleration (Crane TP-410,
  eq. 1-6; Shapiro, *The Dynamics and Thermodynamics of Compressible Fluid
  Flow*, ch. 6; ``fluids.compressible.isothermal_gas``):

      p1^2 - p2^2 = G^2 c^2 [f L/D + 2 ln(p1/p2)];

* exit: p2 = max(p_d, G c). Isothermal pipe flow chokes where its velocity
  reaches c (Mach 1/sqrt(gamma)); past that the exit pressure is G c and the
  flow no longer depends on p_d.

The law is stated as one residual of (p_a, mdot, p_b),

      R = [p1^2 - p2^2 - 2 c^2 Phi - 2 G^2 c^2 ln(p1/p2)] / (p_a + p_b),

with the friction written through the term the tube already has,
Phi = c_mu (f Re) mdot (c_mu = mu L/(2 A D^2)), so that G^2 c^2 f L/D =
2 c^2 Phi (Phi signed with the flow). Dividing by p_a + p_b gives it units of
pressure: at low Mach it is p_a - p_b - Phi/rho_m - G^2/(2 rho_m) (1 + 2 ln(p_a/p_b))
(rho_m at the mean pressure), the mean-density Darcy law, the dynamic pressure
the flow carries out of the tube (dissipated in the volume downstream: not
small against the friction of a short, wide tube, whatever the Mach number)
and the acceleration along it. R is odd in the flow (the upstream end is
the one the flow leaves), C1 at zero flow, and C1 across the choke: dR/dp2 =
-2 p2 (1 - M2^2)/(p_a + p_b) vanishes where the exit Mach reaches 1, so the
hard max needs no smoothing. R has one root in the flow for any p_a, p_b > 0
(positive below it, negative above: checked on 2 000 random states); an iterate
past the entry's own limit (z e^-z at its maximum 1/e, a flux the entry cannot
pass, reached only by a tube of zero length) holds the inlet at Mach 1 there
and subtracts p0^2 (a - 1/e) from F (a = G^2 c^2/p0^2): R stays C1 across the
limit and falls beyond it as fast as at it, so Newton is sent back, and it
has no root there.

Each function works on floats and NumPy arrays alike.
"""
from __future__ import annotations

import numpy as np
from scipy.special import lambertw

_INV_E = float(np.exp(-1.0))
#: the largest a below 1/e (scipy's W0 is nan at the float nearest -1/e)
_A_MAX = float(np.nextafter(_INV_E, 0.0))


def entry_z(a):
    """z in [0, 1] with z exp(-z) = a: the isothermal entry's z = M1^2 from
    a = G^2 c^2 / p0^2, the principal branch z = -W0(-a) (scipy's Lambert W),
    held at 1 from a = 1/e on (the entry's limit, see the module)."""
    return np.minimum(-lambertw(-np.minimum(a, _A_MAX)).real, 1.0)


def isothermal_pipe(pa, mf, pb, area, c2, phi, jac=True, c2_partial=True):
    """Residual R of isothermal tube flow (see the module) and its partials.

    pa, pb : node (stagnation) pressures [Pa]; mf : mass flow from a to b [kg/s];
    area : flow area [m^2]; c2 : p/rho [m^2/s^2] (R T for an ideal gas);
    phi : friction term c_mu (f Re) mf [Pa kg/m^3] (signed with mf).

    Returns (R, dR/dpa, dR/dmf, dR/dpb, dR/dc2, dR/dphi, choked), the partials
    None without ``jac`` (dR/dc2 None without ``c2_partial``, for a constant
    c2); ``choked`` is True where the exit runs at Mach 1.
    The selections (reverse flow, the choke, the entry's limit) are made only
    where some instance needs them: the common case (all forward, none
    choked) costs a third fewer array operations.
    """
    # (the flags by the arrays' own methods: np.all's dispatch costs ~2 us a call)
    forward = np.asarray(mf >= 0.0)
    all_forward = bool(forward.all())
    if all_forward:
        p0, pd, sign = pa, pb, 1.0
    else:
        p0 = np.where(forward, pa, pb)
        pd = np.where(forward, pb, pa)
        sign = np.where(forward, 1.0, -1.0)
    G = np.abs(mf) / area
    GG = G * G
    GGc2 = GG * c2
    c = c2 ** 0.5
    Gc = G * c
    p0sq = p0 * p0
    a = GGc2 / p0sq
    inside = np.asarray(a < _INV_E)
    all_inside = bool(inside.all())
    z = entry_z(a)
    p1 = p0 * np.exp(-0.5 * z)
    if not all_inside:
        # past the entry's limit (an iterate only): the inlet held at Mach 1,
        # p1 = G c, which meets p0 e^-1/2 at the limit, less p0^2 (a - 1/e),
        # which makes F C1 there and keeps it falling beyond (see the module)
        p1 = np.where(inside, p1, Gc)
    p1sq = p1 * p1
    choked = np.asarray(pd < Gc)
    any_choked = bool(choked.any())
    pe = np.where(choked, Gc, pd) if any_choked else pd
    log_ratio = np.log(p1 / pe)
    # F: the forward residual in Pa^2 (phi enters with the flow's sign: -2 c2 phi is odd)
    F_forward = p1sq - pe * pe - 2.0 * GGc2 * log_ratio
    if not all_inside:
        F_forward = F_forward - np.where(inside, 0.0, p0sq * (a - _INV_E))
    F = sign * F_forward - 2.0 * c2 * phi
    S = pa + pb
    R = F / S
    if not jac:
        return R, None, None, None, None, None, choked
    # through z: dF/dz at fixed p0 (p1^2 = p0^2 e^-z and the -2 G^2 c2 ln p1 term)
    # is -p1^2 + G^2 c2 = -p1^2 (1 - z), times dz/da = e^z/(1 - z): -p0^2, finite
    # up to the entry's limit; with a = G^2 c2 / p0^2. Past the limit the held
    # inlet and the term -p0^2 (a - 1/e) give the same dF/dG and dF/dc2
    dF_dp0 = 2.0 * (p1sq - GGc2) / p0 + 2.0 * a * p0
    dF_dG = -2.0 * G * c2 * (2.0 * log_ratio + 1.0)
    dF_dc2 = -GG * (2.0 * log_ratio + 1.0) if c2_partial else None
    if not all_inside:
        dF_dp0 = np.where(inside, dF_dp0, 2.0 * _INV_E * p0)
    dF_dpe = 2.0 * (GGc2 - pe * pe) / pe        # zero where the exit chokes (M = 1)
    dF_dpd = dF_dpe
    if any_choked:
        # pe = G c moves with G and c2 (dF/dpe is zero at the choke itself)
        dF_dpd = np.where(choked, 0.0, dF_dpe)
        dF_dG = dF_dG + np.where(choked, dF_dpe * c, 0.0)
        if c2_partial:
            dF_dc2 = dF_dc2 + np.where(choked, dF_dpe * 0.5 * G / c, 0.0)
    # back to (pa, mf, pb) with the direction's sign; G = |mf|/A, so dG/dmf = sign/A
    if all_forward:
        dF_dpa, dF_dpb = dF_dp0, dF_dpd
    else:
        d_p0 = sign * dF_dp0
        d_pd = sign * dF_dpd
        dF_dpa = np.where(forward, d_p0, d_pd)
        dF_dpb = np.where(forward, d_pd, d_p0)
        if c2_partial:
            dF_dc2 = sign * dF_dc2
    inv_S = 1.0 / S
    return (R, (dF_dpa - R) * inv_S, dF_dG * inv_S / area, (dF_dpb - R) * inv_S,
            (dF_dc2 - 2.0 * phi) * inv_S if c2_partial else None, -2.0 * c2 * inv_S, choked)


def isothermal_choked_massflow(p0, area, c2, fLD):
    """The choked mass flow [kg/s] of an isothermal tube of friction parameter
    fLD = f L/D fed from stagnation pressure p0 (friction factor held fixed):
    the inlet Mach M1 (on sqrt(c2)) solves the isothermal Fanno relation
    fL/D = (1 - M1^2)/M1^2 + ln(M1^2) (exit at Mach 1), then the entry gives
    p1 = p0 exp(-M1^2/2) and G = M1 p1 / c. A closed form for tests and the
    documentation (the network solves the residual instead)."""
    from scipy.optimize import brentq

    def excess(m2):
        return (1.0 - m2) / m2 + np.log(m2) - fLD

    m2 = brentq(excess, 1e-300, 1.0, xtol=1e-300, rtol=1e-15) if fLD > 0 else 1.0
    p1 = p0 * np.exp(-0.5 * m2)
    return float(np.sqrt(m2) * p1 / np.sqrt(c2) * area)
