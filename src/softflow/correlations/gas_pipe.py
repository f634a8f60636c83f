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

import functools

import numpy as np

from .._laws import law_module
from .friction import prepared, shaped


compiled = functools.partial(law_module, "gas_pipe")


def entry_z(a):
    """z in [0, 1] with z exp(-z) = a: the isothermal entry's z = M1^2 from
    a = G^2 c^2 / p0^2, the principal branch z = -W0(-a) of Lambert's W,
    held at 1 from a = 1/e on (the entry's limit, see the module); the
    compiled :func:`softflow.laws.gas_pipe.entry_z`."""
    shape, (a,) = prepared(a)
    z = np.empty(a.size)
    compiled().entry_z_array(a, z)
    return shaped(shape, z)[0]


def isothermal_pipe(pa, mf, pb, area, c2, phi, jac=True, c2_partial=True):
    """Residual R of isothermal tube flow (see the module) and its partials.

    pa, pb : node (stagnation) pressures [Pa]; mf : mass flow from a to b [kg/s];
    area : flow area [m^2]; c2 : p/rho [m^2/s^2] (R T for an ideal gas);
    phi : friction term c_mu (f Re) mf [Pa kg/m^3] (signed with mf).

    Returns (R, dR/dpa, dR/dmf, dR/dpb, dR/dc2, dR/dphi, choked), the partials
    None without ``jac`` (dR/dc2 None without ``c2_partial``, for a constant
    c2); ``choked`` is True where the exit runs at Mach 1. Arrays that
    broadcast (floats give floats), evaluated by the compiled
    :func:`softflow.laws.gas_pipe.isothermal_pipe`.
    """
    shape, args = prepared(pa, mf, pb, area, c2, phi)
    n = args[0].size
    out = [np.empty(n) for _ in range(6)]
    choked = np.empty(n, dtype=np.bool_)
    compiled().isothermal_pipe_array(*args, *out, choked)
    R, R_pa, R_mf, R_pb, R_c2, R_phi = shaped(shape, *out)
    choked = choked.reshape(shape)
    if not jac:
        return R, None, None, None, None, None, choked
    return R, R_pa, R_mf, R_pb, (R_c2 if c2_partial else None), R_phi, choked


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
