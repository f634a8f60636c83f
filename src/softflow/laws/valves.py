"""The valves' laws, compiled: an orifice's residual (loss coefficient,
isentropic nozzle or ISO 6358), a check valve's opening flow, a Tesla valve's
friction term with its direction factor (in isothermal or adiabatic pipe flow,
or a liquid's Darcy law) and a snapping valve's open passage and closed
restrictor.

Each law is a scalar function that returns its value and its partial
derivatives, built on the laws of :mod:`.orifice`, :mod:`.friction`,
:mod:`.gas_pipe`, :mod:`.fanno` and :mod:`.tube`; the components
(:mod:`softflow.components.valves`) say what each means. A group pass
(``*_residual``) fills a group's residual F (n, 2) and, with ``jac``, its
Jacobian's nonzeros J (n, 5) in the two-port pattern (0, mf_a) (0, mf_b)
(1, p_a) (1, mf_a) (1, p_b) from V = [p_a, mf_a, p_b, mf_b] (n, 4).

The densities: where the fluid is an ideal gas (``RT`` = R T > 0, rho = p/RT)
or a liquid of constant density (``RT`` = 0, ``rho``), the passes make them
themselves; for another gas the component takes them from the fluid and gives
them as arrays (``given``), and the passes use those instead.
"""
from __future__ import annotations

from . import jit
from .fanno import adiabatic_pipe_gas, gas_constants
from .friction import fRe_blended, smoothstep
from .gas_pipe import isothermal_pipe
from .orifice import (_maximum, massflow_iso_6358, massflow_loss_coefficient,
                      massflow_nozzle)
from .tube import isothermal_drop, two_port_row

#: an orifice's law (Orifice.model): the loss coefficient (K, or a liquid's Cd),
#: the isentropic nozzle (a gas's Cd), ISO 6358 (C, b)
LOSS, NOZZLE, ISO_6358 = 0, 1, 2


@jit
def density(p, RT, rho):
    """(rho, d rho/dp) at p of an ideal gas (RT > 0: p/RT) or of a liquid of
    constant density rho (RT = 0)."""
    if RT > 0.0:
        return p / RT, 1.0 / RT
    return rho, 0.0


@jit
def mean_density(pa, pb, RT, rho):
    """(rho, d rho/d p_a) at the mean pressure (p_a + p_b)/2 (d rho/d p_b is the
    same), as :func:`density`."""
    if RT > 0.0:
        return 0.5 * (pa + pb) / RT, 0.5 * (1.0 / RT)
    return rho, 0.0


# -- orifices ---------------------------------------------------------------------------
@jit
def loss_orifice(pa, pb, rho_up, drho_up, K, area, dp_small):
    """Mass flow from a to b through a loss coefficient K at the upstream
    density rho_up (d rho_up/d p_up = drho_up; upstream: a where p_a >= p_b),
    regularized below |p_a - p_b| = dp_small: (mdot, d/dp_a, d/dp_b)."""
    q, q_dp, q_rho = massflow_loss_coefficient(pa - pb, rho_up, K, area, dp_small)
    q_up = q_rho * drho_up
    if pa >= pb:
        return q, q_dp + q_up, -q_dp + 0.0
    return q, q_dp + 0.0, -q_dp + q_up


@jit
def orifice_upstream(model, pa, pb):
    """The pressure at which the orifice law ``model`` takes its density: the
    larger of p_a, p_b (nan where either is) for the nozzle, else p_a where
    p_a >= p_b, p_b otherwise."""
    if model == NOZZLE:
        return _maximum(pa, pb)
    return pa if pa >= pb else pb


@jit
def orifice_flow(model, pa, pb, rho_up, drho_up, K, area, dp_small, gamma, Cd, T, C, b, m,
                 pr_laminar, rho0, T0):
    """Mass flow from a to b of the orifice law ``model`` (LOSS, NOZZLE,
    ISO_6358), with the density rho_up at the upstream pressure and its slope
    drho_up (not read by ISO 6358): (mdot, d/dp_a, d/dp_b)."""
    if model == ISO_6358:
        return massflow_iso_6358(pa, pb, T, C, b, m, pr_laminar, rho0, T0)
    if model == NOZZLE:
        return massflow_nozzle(pa, pb, rho_up, drho_up, gamma, Cd, area, dp_small)
    return loss_orifice(pa, pb, rho_up, drho_up, K, area, dp_small)


@jit
def orifice_residual(model, V, RT, rho, K, area, dp_small, gamma, Cd, T, C, b, m, pr_laminar,
                     rho0, T0, given, rho_up, drho_up, F, J, jac):
    """A group of orifices' residual, mass balance and mf_a - mdot, and its
    Jacobian; ``given``: the upstream densities are rho_up, drho_up (arrays)."""
    for i in range(V.shape[0]):
        pa, mf, pb = V[i, 0], V[i, 1], V[i, 2]
        if model == ISO_6358:
            r, dr = 0.0, 0.0
        elif given:
            r, dr = rho_up[i], drho_up[i]
        else:
            r, dr = density(orifice_upstream(model, pa, pb), RT, rho)
        q, q_pa, q_pb = orifice_flow(model, pa, pb, r, dr, K[i], area[i], dp_small[i],
                                     gamma[i], Cd[i], T, C[i], b[i], m[i], pr_laminar[i],
                                     rho0, T0)
        two_port_row(i, V, mf - q, -q_pa, 1.0, -q_pb, F, J, jac)


# -- check valves -----------------------------------------------------------------------
@jit
def check_valve_flow(pa, pb, nozzle, rho_open, drho_open, rho_m, drho_m, K, Cd, gamma, area,
                     dp_small, cracking, top, leakage):
    """Mass flow from a to b through a check valve, w(dp) q_open + rho_m
    leakage dp, with the opening fraction w the smoothstep from the cracking
    pressure to ``top`` (cracking + opening band), q_open the nozzle
    (``nozzle``) or the loss-coefficient orifice at the density rho_open
    (slope drho_open in the pressure it is taken at: the upstream one for the
    nozzle, p_a for the loss coefficient) and rho_m the mean density (slope
    drho_m in p_a and in p_b): (mdot, d/dp_a, d/dp_b)."""
    if nozzle:
        q, q_pa, q_pb = massflow_nozzle(pa, pb, rho_open, drho_open, gamma, Cd, area,
                                        dp_small)
    else:
        q, q_dp, q_rho = massflow_loss_coefficient(pa - pb, rho_open, K, area, dp_small)
        q_pa, q_pb = q_dp + q_rho * drho_open, -q_dp
    dp = pa - pb
    w, dw = smoothstep(dp, cracking, top)
    d_dp = dw * q + rho_m * leakage           # through dp
    d_rho = drho_m * leakage * dp             # through rho_m, per p_a or p_b
    return w * q + rho_m * leakage * dp, d_dp + d_rho + w * q_pa, -d_dp + d_rho + w * q_pb


@jit
def check_valve_residual(nozzle, V, RT, rho, K, Cd, gamma, area, dp_small, cracking, band,
                         leakage, given, rho_open, drho_open, rho_m, drho_m, F, J, jac):
    """A group of check valves' residual, mass balance and mf_a - mdot
    (:func:`check_valve_flow`), and its Jacobian; ``given``: the densities are
    the arrays rho_open, drho_open, rho_m, drho_m."""
    for i in range(V.shape[0]):
        pa, mf, pb = V[i, 0], V[i, 1], V[i, 2]
        if given:
            ro, dro, rm, drm = rho_open[i], drho_open[i], rho_m[i], drho_m[i]
        else:
            ro, dro = density(_maximum(pa, pb) if nozzle else pa, RT, rho)
            rm, drm = mean_density(pa, pb, RT, rho)
        q, q_pa, q_pb = check_valve_flow(pa, pb, nozzle, ro, dro, rm, drm, K[i], Cd[i],
                                         gamma[i], area[i], dp_small[i], cracking[i],
                                         cracking[i] + band[i], leakage[i])
        two_port_row(i, V, mf - q, -q_pa, 1.0, -q_pb, F, J, jac)


# -- Tesla valves -----------------------------------------------------------------------
@jit
def tesla_friction(kind, lo, hi, mf, re_per_mf, eD, a, mf_blend, diodicity):
    """A Tesla valve's friction term over c_mu, (f Re) mf D(mf), and its
    derivative in mf: f Re the blended law of the correlation ``kind``
    (:func:`.friction.fRe_blended`) at Re = |mf| re_per_mf, the direction
    factor D = 1 + (diodicity - 1)(1 - w), w the smoothstep from -mf_blend to
    0."""
    Re = abs(mf) * re_per_mf
    phi, dphi = fRe_blended(kind, Re, eD, a, lo, hi)
    w, dw = smoothstep(mf, -mf_blend, 0.0)
    extra = diodicity - 1.0
    mult = 1.0 + extra * (1.0 - w)
    return phi * mf * mult, (phi + Re * dphi) * mult - phi * mf * extra * dw


@jit
def tesla_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, area, mf_blend, diodicity,
               c2, rho, drho):
    """p_a - p_b required by the flow mf through a Tesla valve and its partials
    in p_a, mf, p_b: (dp, d_pa, d_mf, d_pb). An ideal gas (c2 = p/rho > 0):
    isothermal pipe flow with the friction term c_mu :func:`tesla_friction`;
    else (c2 = 0) the Darcy law c_mu/rho times it, rho the mean density (drho
    its slope in p_a and in p_b: 0 for a liquid)."""
    law, dlaw = tesla_friction(kind, lo, hi, mf, re_per_mf, eD, a, mf_blend, diodicity)
    if c2 > 0.0:
        R, R_pa, R_mf, R_pb, _, R_phi, _ = isothermal_pipe(pa, mf, pb, area, c2, c_mu * law)
        return (pa - pb) - R, 1.0 - R_pa, -(R_mf + R_phi * (c_mu * dlaw)), -1.0 - R_pb
    c = c_mu / rho
    dp = c * law
    g = -dp / rho * drho
    return dp, g, c * dlaw, g


@jit
def tesla_residual(kind, lo, hi, V, re_per_mf, c_mu, eD, a, area, mf_blend, diodicity, c2, rho,
                   F, J, jac):
    """A group of Tesla valves' residual, mass balance and p_a - p_b minus
    :func:`tesla_drop`, and its Jacobian."""
    for i in range(V.shape[0]):
        pa, mf, pb = V[i, 0], V[i, 1], V[i, 2]
        dp, d_pa, d_mf, d_pb = tesla_drop(kind, lo, hi, pa, mf, pb, re_per_mf[i], c_mu[i],
                                          eD[i], a[i], area[i], mf_blend[i], diodicity[i],
                                          c2, rho, 0.0)
        two_port_row(i, V, (pa - pb) - dp, 1.0 - d_pa, -d_mf, -1.0 - d_pb, F, J, jac)


@jit
def tesla_adiabatic_drop(kind, lo, hi, pa, mf, pb, T_up, re_per_mf, c_mu, eD, a, area,
                         mf_blend, diodicity, R, gas):
    """p_a - p_b required by the flow mf through a Tesla valve of an ideal gas
    in a thermal scene, adiabatic (Fanno) pipe flow from the upstream
    stagnation temperature T_up with the friction term c_mu
    :func:`tesla_friction` (``gas``: :func:`.fanno.gas_constants`), and its
    partials in p_a, mf, p_b and T_up."""
    law, dlaw = tesla_friction(kind, lo, hi, mf, re_per_mf, eD, a, mf_blend, diodicity)
    r = adiabatic_pipe_gas(pa, mf, pb, T_up, area, R, gas, c_mu * law)
    return (pa - pb) - r[0], 1.0 - r[1], -(r[2] + r[5] * (c_mu * dlaw)), -1.0 - r[3], -r[4]


# -- snapping valves --------------------------------------------------------------------
@jit
def friction_term(kind, lo, hi, mf, re_per_mf, c_mu, eD, a):
    """A tube's friction term c_mu (f Re) mf and its derivative in mf (the
    blended law of ``kind`` at Re = |mf| re_per_mf)."""
    Re = abs(mf) * re_per_mf
    phi, dphi = fRe_blended(kind, Re, eD, a, lo, hi)
    return c_mu * phi * mf, c_mu * (phi + Re * dphi)


@jit
def restrictor_row(pa, pb, X, dX, rho, drho):
    """The flow law p_a - p_b - X/rho of a passage whose pressure drop is X/rho
    (X a function of the flow, dX its derivative; rho the mean density, drho
    its slope in p_a and in p_b) and its partials in p_a, mf, p_b."""
    dp = X / rho
    g = dp / rho * drho
    return (pa - pb) - dp, 1.0 + g, -dX / rho, -1.0 + g


@jit
def snapping_residual(kind, lo, hi, V, S, re_per_mf, c_mu, eD, a, area, conductance, c2, RT,
                      rho, given, rho_m, drho_m, F, J, jac):
    """A group of snapping valves' residual, mass balance and the flow law of
    the mode S[:, 0] (> 0.5 open), and its Jacobian. Open: the passage's tube
    law, for an ideal gas (c2 = R T > 0) the tube's isothermal pipe flow
    (:func:`.tube.isothermal_drop`), else its Darcy law X/rho with X the
    friction term (:func:`friction_term`); closed: the linear restrictor
    X = mf/conductance. rho at the mean pressure (:func:`mean_density`, or
    the arrays rho_m, drho_m where ``given``)."""
    for i in range(V.shape[0]):
        pa, mf, pb = V[i, 0], V[i, 1], V[i, 2]
        is_open = S[i, 0] > 0.5
        if is_open and c2 > 0.0:
            dp, d_pa, d_mf, d_pb = isothermal_drop(kind, lo, hi, pa, mf, pb, re_per_mf[i],
                                                   c_mu[i], eD[i], a[i], area[i], c2, 0.0)
            f1, j_pa, j_mf, j_pb = (pa - pb) - dp, 1.0 - d_pa, -d_mf, -1.0 - d_pb
        else:
            if given:
                r, dr = rho_m[i], drho_m[i]
            else:
                r, dr = mean_density(pa, pb, RT, rho)
            if is_open:
                X, dX = friction_term(kind, lo, hi, mf, re_per_mf[i], c_mu[i], eD[i], a[i])
            else:
                dX = 1.0 / conductance[i]
                X = dX * mf
            f1, j_pa, j_mf, j_pb = restrictor_row(pa, pb, X, dX, r, dr)
        two_port_row(i, V, f1, j_pa, j_mf, j_pb, F, J, jac)


# -- array loops (the arrays' shapes are made equal by the caller) ----------------------
@jit
def tesla_friction_array(kind, lo, hi, mf, re_per_mf, eD, a, mf_blend, diodicity, law, dlaw):
    for i in range(mf.size):
        law[i], dlaw[i] = tesla_friction(kind, lo, hi, mf[i], re_per_mf[i], eD[i], a[i],
                                         mf_blend[i], diodicity[i])


@jit
def tesla_drop_array(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu, eD, a, area, mf_blend,
                     diodicity, c2, rho, dp, d_pa, d_mf, d_pb):
    for i in range(pa.size):
        dp[i], d_pa[i], d_mf[i], d_pb[i] = tesla_drop(
            kind, lo, hi, pa[i], mf[i], pb[i], re_per_mf[i], c_mu[i], eD[i], a[i], area[i],
            mf_blend[i], diodicity[i], c2, rho, 0.0)


@jit
def tesla_adiabatic_drop_array(kind, lo, hi, pa, mf, pb, T_up, re_per_mf, c_mu, eD, a, area,
                               mf_blend, diodicity, R, gamma, dp, d_pa, d_mf, d_pb, d_T):
    gas = gas_constants(gamma)
    for i in range(pa.size):
        dp[i], d_pa[i], d_mf[i], d_pb[i], d_T[i] = tesla_adiabatic_drop(
            kind, lo, hi, pa[i], mf[i], pb[i], T_up[i], re_per_mf[i], c_mu[i], eD[i], a[i],
            area[i], mf_blend[i], diodicity[i], R, gas)


@jit
def friction_term_array(kind, lo, hi, mf, re_per_mf, c_mu, eD, a, Phi, dPhi):
    for i in range(mf.size):
        Phi[i], dPhi[i] = friction_term(kind, lo, hi, mf[i], re_per_mf[i], c_mu[i], eD[i], a[i])
