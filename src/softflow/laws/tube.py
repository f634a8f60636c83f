"""A tube's pressure-drop law, compiled: the blended friction law
(:mod:`.friction`) with the tube's minor losses (:func:`friction_law`) feeding isothermal pipe flow (:mod:`.gas_pipe`), adiabatic
pipe flow in thermal scenes (:mod:`.fanno`), a liquid's Darcy law, or the
Darcy law at the mean density of an ideal gas (``compressible='mean_density'``,
fonsim's law).

Which law a group of tubes takes is its ``c2``: p/rho of an ideal gas on
isothermal pipe flow (c2 > 0; the coefficient c is c_mu), 0 for a liquid
(c = c_mu/rho), or minus R T of an ideal gas on the mean-density law
(c2 < 0; c = c_mu).

The one evaluation of a group of gas tubes with constant viscosity and an
analytic friction correlation (:func:`softflow.components.tubes.gas_pipe_drop`
chooses it): one compiled pass over the group instead of some forty NumPy
operations.
"""
from __future__ import annotations

from . import jit
from .fanno import adiabatic_pipe_gas, gas_constants
from .friction import fRe_blended
from .gas_pipe import isothermal_pipe


@jit
def friction_law(kind, Re, eD, a, lo, hi, kre):
    """f·Re of a tube with minor losses, and its derivative in Re: the blended
    friction law plus the loss coefficient K as K D/L · Re (``kre`` = K D / L),
    which is K added to f L/D, the practice of Crane TP-410 for incompressible
    and compressible pipe flow alike (the friction term c_mu (f Re) mf then
    carries K mf |mf| / (2 A^2))."""
    phi, dphi = fRe_blended(kind, Re, eD, a, lo, hi)
    return phi + kre * Re, dphi + kre


@jit
def isothermal_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, area, c2, kre):
    """p_a - p_b required by the flow mf through a gas tube (isothermal pipe
    flow, the friction term Phi = c_mu (f Re) mf with Re = |mf| re_per_mf and
    f Re with the minor losses ``kre`` of :func:`friction_law`), and its
    partials in p_a, mf, p_b: (dp, d_pa, d_mf, d_pb)."""
    Re = abs(mf) * re_per_mf
    phi, dphi = friction_law(kind, Re, eD, a, lo, hi, kre)
    Phi = c_mu * phi * mf
    R, R_pa, R_mf, R_pb, _, R_phi, _ = isothermal_pipe(pa, mf, pb, area, c2, Phi)
    return (pa - pb) - R, 1.0 - R_pa, -(R_mf + R_phi * c_mu * (phi + Re * dphi)), -1.0 - R_pb


@jit
def isothermal_drop_array(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, area, c2, kre,
                          dp, d_pa, d_mf, d_pb):
    for i in range(pa.size):
        dp[i], d_pa[i], d_mf[i], d_pb[i] = isothermal_drop(
            kind, lo, hi, pa[i], mf[i], pb[i], re_per_mf[i], c_mu[i], eD[i], a[i], area[i],
            c2, kre[i])


@jit
def darcy_drop(kind, lo, hi, mf, re_per_mf, c, eD, a, kre):
    """p_a - p_b required by the flow mf through a tube of a liquid of constant
    density and viscosity (the Darcy law, c = c_mu/rho, minor losses ``kre``
    as in :func:`friction_law`), and its partial in mf: (dp, d_mf); the
    pressures do not enter."""
    Re = abs(mf) * re_per_mf
    phi, dphi = friction_law(kind, Re, eD, a, lo, hi, kre)
    return c * phi * mf, c * (phi + Re * dphi)


@jit
def mean_density_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, RT, kre):
    """p_a - p_b required by the flow mf through a tube of an ideal gas by the
    Darcy law at the mean density rho = (p_a + p_b) / (2 R T) (fonsim's tube
    law, valid at low Mach numbers), and its partials in p_a, mf, p_b: (dp,
    d_pa, d_mf, d_pb). The arithmetic of the NumPy law it replaces
    (c_mu / rho, then the Darcy law; d(dp)/d(p_mean) = -dp / rho · (1 / R T))."""
    pm = 0.5 * (pa + pb)
    rho = pm / RT
    dp, d_mf = darcy_drop(kind, lo, hi, mf, re_per_mf, c_mu / rho, eD, a, kre)
    d_pm = -dp / rho * (1.0 / RT) * 0.5
    return dp, d_pm, d_mf, d_pm


@jit
def tube_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c, eD, a, area, c2, kre):
    """A tube's required p_a - p_b and its partials (dp, d_pa, d_mf, d_pb)
    by the law its ``c2`` names (module docstring)."""
    if c2 > 0.0:
        return isothermal_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c, eD, a, area, c2, kre)
    if c2 < 0.0:
        return mean_density_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c, eD, a, -c2, kre)
    dp, d_mf = darcy_drop(kind, lo, hi, mf, re_per_mf, c, eD, a, kre)
    return dp, 0.0, d_mf, 0.0


@jit
def tube_drop_array(kind, lo, hi, pa, mf, pb, re_per_mf, c, eD, a, area, c2, kre,
                    dp, d_pa, d_mf, d_pb):
    """:func:`tube_drop` of a group of tubes into the output arrays."""
    for i in range(mf.size):
        dp[i], d_pa[i], d_mf[i], d_pb[i] = tube_drop(
            kind, lo, hi, pa[i], mf[i], pb[i], re_per_mf[i], c[i], eD[i], a[i], area[i], c2,
            kre[i])


@jit
def darcy_drop_array(kind, lo, hi, mf, re_per_mf, c, eD, a, kre, dp, d_mf):
    for i in range(mf.size):
        dp[i], d_mf[i] = darcy_drop(kind, lo, hi, mf[i], re_per_mf[i], c[i], eD[i], a[i],
                                    kre[i])


@jit
def two_port_row(i, V, f1, j_pa, j_mf, j_pb, F, J, jac):
    """Row i of a two-port group's residual (mass balance mf_a + mf_b, and the
    flow law's equation f1) and, with ``jac``, its Jacobian's nonzeros in the
    two-port pattern (0, mf_a) (0, mf_b) (1, p_a) (1, mf_a) (1, p_b): 1, 1 and
    the law's partials j_pa, j_mf, j_pb."""
    F[i, 0] = V[i, 1] + V[i, 3]
    F[i, 1] = f1
    if jac:
        J[i, 0] = 1.0
        J[i, 1] = 1.0
        J[i, 2] = j_pa
        J[i, 3] = j_mf
        J[i, 4] = j_pb


@jit
def residual(kind, lo, hi, V, re_per_mf, c, eD, a, area, c2, kre, F, J, jac):
    """A group of tubes' residual F (n, 2) (mass balance; p_a - p_b minus the
    required drop) and, with ``jac``, its nonzeros J (n, 5) in the tube's
    pattern, from V = [p_a, mf_a, p_b, mf_b] (n, 4), by the law ``c2``
    names (module docstring), with the minor losses ``kre`` (:func:`friction_law`)."""
    for i in range(V.shape[0]):
        pa, mf, pb = V[i, 0], V[i, 1], V[i, 2]
        dp, d_pa, d_mf, d_pb = tube_drop(kind, lo, hi, pa, mf, pb, re_per_mf[i], c[i], eD[i],
                                         a[i], area[i], c2, kre[i])
        two_port_row(i, V, (pa - pb) - dp, 1.0 - d_pa, -d_mf, -1.0 - d_pb, F, J, jac)


@jit
def adiabatic_drop(kind, lo, hi, pa, mf, pb, T_up, re_per_mf, c_mu, eD, a, area, R, gas, kre):
    """p_a - p_b required by the flow mf through a gas tube in a thermal scene
    (adiabatic pipe flow from the upstream stagnation temperature T_up, the
    friction term Phi = c_mu (f Re) mf, minor losses ``kre`` as in
    :func:`friction_law`; ``gas``: :func:`.fanno.gas_constants`), and its
    partials in p_a, mf, p_b and T_up: (dp, d_pa, d_mf, d_pb, d_T)."""
    Re = abs(mf) * re_per_mf
    phi, dphi = friction_law(kind, Re, eD, a, lo, hi, kre)
    r = adiabatic_pipe_gas(pa, mf, pb, T_up, area, R, gas, c_mu * phi * mf)
    return ((pa - pb) - r[0], 1.0 - r[1], -(r[2] + r[5] * c_mu * (phi + Re * dphi)),
            -1.0 - r[3], -r[4])


@jit
def adiabatic_drop_array(kind, lo, hi, pa, mf, pb, T_up, re_per_mf, c_mu, eD, a, area, R, gamma,
                         kre, dp, d_pa, d_mf, d_pb, d_T):
    """:func:`adiabatic_drop` of a group of tubes into the output arrays."""
    gas = gas_constants(gamma)
    for i in range(pa.size):
        dp[i], d_pa[i], d_mf[i], d_pb[i], d_T[i] = adiabatic_drop(
            kind, lo, hi, pa[i], mf[i], pb[i], T_up[i], re_per_mf[i], c_mu[i], eD[i], a[i],
            area[i], R, gas, kre[i])
