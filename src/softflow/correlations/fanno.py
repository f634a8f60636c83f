"""Adiabatic gas flow in a tube at any pressure ratio (Fanno flow), choked flow included.

The adiabatic counterpart of :mod:`softflow.correlations.gas_pipe` for thermal
scenes. An ideal gas (ratio of specific heats g, gas constant R) flows from the
upstream node, whose pressure p0 and temperature T0 are *stagnation* values
(the gas at rest), to the downstream one (p_d). With G = mdot/A, k = (g-1)/2,
K = (g+1)/2, z = M^2 and W = G^2 R T0/g (units Pa^2):

* entry: isentropic acceleration from rest to the inlet Mach M1,
  p1 = p0 (1 + k z1)^(-g/(g-1)),
  G = p0 M1 sqrt(g/(R T0)) (1 + k z1)^(-K/(g-1)), i.e. with n = K/k

      a := W/p0^2 = z1 (1 + k z1)^-n,

  largest, a* = K^-n, at M1 = 1 (the isentropic nozzle's choked flux);
* pipe: adiabatic flow with wall friction (Fanno; Shapiro, *The Dynamics and
  Thermodynamics of Compressible Fluid Flow*, ch. 6; Anderson, *Modern
  Compressible Flow*, ch. 3): T0 is constant and f L/D = F*(M1) - F*(M2),

      F*(M) = (1 - M^2)/(g M^2) + (g+1)/(2g) ln[(g+1) M^2/(2 + (g-1) M^2)],

  the exit static pressure p2 = p1 (M1/M2) sqrt((1 + k z1)/(1 + k z2));
* exit: p2 = max(p_d, p2*), p2* = sqrt(W/K) the exit pressure at Mach 1: the tube
  chokes there and its flow no longer depends on p_d.

As mass flux and stagnation temperature are the same at both ends, each end's
Mach number follows from its static pressure: b := W/p2^2 = z2 (1 + k z2), so
with r = sqrt(1 + 4 k b), 1 + k z2 = (1 + r)/2 and 1 + (g-1) z2 = r: explicit.
Only the entry's z1(a) is implicit: two Halley steps on ln z1 - n ln(1 + k z1)
= ln a from a starting value within about 1 % (exact to O(q^3) at the limit,
q^2 = ln(a*/a), and at rest) reach round-off. Multiplied by R T0 G^2 the Fanno
relation stays finite at zero flow (p0^2 A1 z1 = p2^2 B2 z2 = W):

    F = R T0 G^2 [F*(M1) - F*(M2)] - 2 R T0 Phi
      = p0^2 A1 - p2^2 B2 + K W ln[(rho2/rho1)^2] - 2 R T0 Phi,

A1 = a/z1 = (1 + k z1)^-n, B2 = b/z2 = 1 + k z2, rho2/rho1 = (p2/p0) B2
(1 + k z1)^(1/(g-1)), with the friction written through the term the tube
already has, Phi = c_mu (f Re) mdot (c_mu = mu L/(2 A D^2)), so that
G^2 f L/D = 2 Phi (Phi signed with the flow). The residual is R = F/(p_a + p_b),
in Pa: at low Mach it is p_a - p_b - Phi/rho_m - G^2/(2 rho_m) (1 + (g+1)/g
ln(p_a/p_b)) + O(M^2 G^2/rho_m), rho_m = p_m/(R T0): the mean-density Darcy
law, the exit's dynamic pressure and the acceleration along the tube (where
the isothermal law has 2 ln: the static temperature T0/(1 + k M^2) falls along
the tube as M^2 p^2 ~ W stays fixed, so the friction term at T0 misses a share
of the same order as the acceleration).

R is odd in the flow (the upstream end is the one the flow leaves; T0 is always
the upstream stagnation temperature, given by the caller), C1 at zero flow and
C1 across the choke: dF/dp2 = -2 p2 B2 (1 - z2)/(1 + (g-1) z2) vanishes at exit
Mach 1. Writing F = p0^2 h(a) - p2^2 k2(b) - 2 R T0 Phi, h = g a F*(M1), k2 = g b F*(M2),

    dF/dG = (2 G R T0/g) [K ln(X1/X2) - 1 - (g-1)(1 - z2)/(1 + (g-1) z2)] - 2 R T0 dPhi/dG,

X = K z/(1 + k z) increasing in z, is negative wherever z1 <= z2, hence at
every root (which needs F*(M1) >= F*(M2)): the root in mdot is unique. For
g below about 1.9 (every ideal gas) F falls with the flow wherever p_d <= p0;
against an adverse pressure ratio it is negative for all forward flow but
may rise with it, as the isothermal law's does. Past the entry's limit
(a > a*, an iterate only) the inlet is held at Mach 1 and h continued
linearly, h = -(a - a*) (h(a*) = 0, h'(a*) = -1): F stays C1 there, is
negative (h < 0, k2 >= 0), so it has no root there, and for p_d <= p0 falls
with the flow as at the limit. (Inside, h'(a) = K ln X1 - 1 approaches -1
like sqrt(a* - a), as z1 does: the slope is continuous at the limit but not
Lipschitz there, like the isothermal law's through Lambert's W.)

The law is evaluated by the compiled scalar functions of
:mod:`softflow.laws.fanno` (one place, callable from compiled code); the
functions here are loops over them for arrays (any shapes that broadcast;
floats give floats). :func:`fanno_parameter` and
:func:`adiabatic_choked_massflow` are closed forms of the textbook relations
for tests, the documentation and the model checks' estimates, not the law.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .._laws import law_module
from .friction import prepared, shaped


compiled = functools.partial(law_module, "fanno")


def _gamma(gamma):
    """gamma as a float, refused unless it exceeds 1."""
    g = float(gamma)
    if not g > 1.0:
        raise ValueError(f"gamma must exceed 1, got {g}")
    return g


def adiabatic_entry_z(a, gamma):
    """z1 = M1^2 in [0, 1] of an isentropic entry from rest passing the flux
    a = G^2 R T0/(gamma p0^2): z1 (1 + k z1)^-n = a, k = (gamma-1)/2,
    n = (gamma+1)/(gamma-1), the subsonic root; 1 from the entry's limit
    a* = ((gamma+1)/2)^-n on. Two Halley steps in ln z1 from a starting value
    good to about 1 % (in ln z1): round-off (checked for 1 < gamma <= 3). The
    compiled :func:`softflow.laws.fanno.adiabatic_entry_z`; gamma one float."""
    g = _gamma(gamma)
    shape, (a,) = prepared(a)
    z = np.empty(a.size)
    compiled().adiabatic_entry_z_array(a, g, z)
    return shaped(shape, z)[0]


def fanno_parameter(M, gamma):
    """The Fanno parameter 4 f_F L*/D = f L*/D (f Darcy's friction factor) of
    adiabatic flow with friction at Mach M, the length to the choke (Mach 1):
    F*(M) = (1 - M^2)/(g M^2) + (g+1)/(2g) ln[(g+1) M^2/(2 + (g-1) M^2)]
    (Shapiro, ch. 6; Anderson, *Modern Compressible Flow*, eq. 3.107)."""
    z = np.asarray(M, dtype=float) ** 2
    g = gamma
    return (1.0 - z) / (g * z) + (g + 1.0) / (2.0 * g) * np.log(
        (g + 1.0) * z / (2.0 + (g - 1.0) * z))


def adiabatic_pipe(pa, mf, pb, T0, area, R, gamma, phi, jac=True):
    """Residual R of adiabatic (Fanno) tube flow (see the module) and its partials.

    pa, pb : node (stagnation) pressures [Pa]; mf : mass flow from a to b [kg/s];
    T0 : stagnation temperature of the upstream node (a for mf >= 0, else b) [K];
    area : flow area [m^2]; R : gas constant [J/(kg K)]; gamma : ratio of
    specific heats [-] (one float); phi : friction term c_mu (f Re) mf
    [Pa kg/m^3] (signed with mf).

    Returns (R, dR/dpa, dR/dmf, dR/dpb, dR/dT0, dR/dphi, choked), the partials
    None without ``jac``; ``choked`` is True where the exit runs at Mach 1.
    dR/dT0 is at fixed phi (a viscosity that moves with T0 enters through phi).
    Arrays that broadcast (floats give floats), evaluated by the compiled
    :func:`softflow.laws.fanno.adiabatic_pipe`.
    """
    g = _gamma(gamma)
    shape, args = prepared(pa, mf, pb, T0, area, R, phi)
    n = args[0].size
    out = [np.empty(n) for _ in range(6)]
    choked = np.empty(n, dtype=np.bool_)
    compiled().adiabatic_pipe_array(*args[:6], g, args[6], *out, choked)
    Rs, R_pa, R_mf, R_pb, R_T0, R_phi = shaped(shape, *out)
    choked = choked.reshape(shape)
    if not jac:
        return Rs, None, None, None, None, None, choked
    return Rs, R_pa, R_mf, R_pb, R_T0, R_phi, choked


def adiabatic_choked_massflow(p0, T0, area, R, gamma, fLD):
    """The choked mass flow [kg/s] of an adiabatic tube of friction parameter
    fLD = f L/D (f Darcy's, held fixed) fed from stagnation pressure p0 [Pa] and
    temperature T0 [K]; area [m^2], R [J/(kg K)], gamma [-]. The inlet Mach
    solves F*(M1) = fLD (exit at Mach 1; :func:`fanno_parameter`), then the
    isentropic entry gives G = p0 M1 sqrt(gamma/(R T0))
    (1 + (gamma-1)/2 M1^2)^(-(gamma+1)/(2(gamma-1))). A closed form for tests and
    the documentation (the network solves the residual instead)."""
    from scipy.optimize import brentq

    g = float(gamma)
    k = 0.5 * (g - 1.0)

    def excess(z):
        return float(fanno_parameter(math.sqrt(z), g)) - fLD

    z1 = brentq(excess, 1e-300, 1.0, xtol=1e-300, rtol=1e-15) if fLD > 0 else 1.0
    G = (p0 * math.sqrt(z1 * g / (R * T0))
         * (1.0 + k * z1) ** (-(g + 1.0) / (2.0 * (g - 1.0))))
    return float(G * area)
