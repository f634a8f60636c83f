"""The energy terms of thermal scenes of an ideal gas, compiled.

The equations are documented in :mod:`softflow.components.thermal`; here
are the laws its kernels evaluate for an ideal gas (h = cp T + c,
u = cv T + c, rho = p / (R T)), as scalar functions of floats returning
their value and partials, with group loops that the components' kernels
call (one compiled pass per group) and that the network loop
(:mod:`.network`) calls instance by instance:

* the upwind enthalpy flow of a flow element or flow source
  (:func:`upwind_energy`, its smooth blend :func:`upwind_weight`);
* a volume's walls (:func:`wall_law`: rigid, linear compliance, a PV curve
  with its work; :func:`loop_wall`: a hysteresis loop's branch, its work
  :func:`loop_work` and the work offset a change of branch sets,
  :func:`loop_offset`) and its rows
  (:func:`free_rows`: mass, stored energy and wall heat Q - hA (T_wall - T)
  at a constant hA per call; :func:`held_rows`: held at its wall
  temperature);
* a two-port's rows around its flow law (:func:`pressure_drop_rows` for the
  pressure-drop form, :func:`sqrt_density_rows` for an orifice's mass flow
  scaled by sqrt(T_ref/T_up), :func:`plain_rows` for a law at the nominal
  temperature), and the flow sources' rows.

Constants reach the laws as arguments: the blend's band and the zero-flow
conductance (:data:`softflow.components.thermal.UPWIND_BAND`,
``ZERO_FLOW_CONDUCTANCE``), the gas's R, cp, cv and c (the enthalpy's
constant, the same in u), the scene's energy reference h0 (as ``ch = c - h0``
where the enthalpy is taken relative to it). The arithmetic is the NumPy
kernels' it replaced, operation for operation.
"""
from __future__ import annotations

import math

from . import jit
from .fanno import gas_constants
from .orifice import _maximum
from .tube import adiabatic_drop
from .valves import (ISO_6358, check_valve_flow, density, mean_density, orifice_flow,
                     orifice_upstream, restrictor_row, tesla_adiabatic_drop)
from .volumes import curve_point, piece, refused

#: wall kinds of :func:`wall_law` (and LOOP: a hysteresis loop, :func:`loop_wall`)
RIGID, LINEAR, CURVE, LOOP = 0, 1, 2, 3


# -- upwind energy ---------------------------------------------------------------------
@jit
def upwind_weight(mf, band):
    """smoothstep(mf, -band, band) and its derivative in mf: 0 upstream at
    ``b``, 1 at ``a``, blended C1 within the band."""
    c = mf * (0.5 / band)
    c += 0.5
    c = 0.0 if c < 0.0 else (1.0 if c > 1.0 else c)
    c2 = c * c
    return c2 * (3.0 - 2.0 * c), (3.0 / band) * (c - c2)


@jit
def upwind_energy(mf, Ta, Tb, cp, ch, band, G):
    """Energy flow into ``a`` carried by the mass flow mf (into ``a``) of an
    ideal gas, h = cp T + c, counted from h0 (``ch`` = c - h0): the enthalpy
    of the blended upstream temperature T_up = Tb + w (Ta - Tb), plus the
    zero-flow conductance G (Ta - Tb). Returns (E, w, dw/dmf, T_up, dE/dmf,
    dE/dTa, dE/dTb); dE/dp is 0."""
    w, dw = upwind_weight(mf, band)
    dT = Ta - Tb
    T_up = Tb + w * dT
    h = cp * T_up + ch
    E = mf * h + G * dT
    mcp = mf * cp
    mwcp = w * mcp
    return E, w, dw, T_up, h + (dw * dT) * mcp, mwcp + G, (mcp - mwcp) - G


@jit
def upwind_weight_array(mf, band, w, dw):
    for i in range(mf.size):
        w[i], dw[i] = upwind_weight(mf[i], band)


@jit
def upwind_energy_array(mf, Ta, Tb, cp, ch, band, G, E, w, dw, T_up, d_mf, d_Ta, d_Tb):
    for i in range(mf.size):
        E[i], w[i], dw[i], T_up[i], d_mf[i], d_Ta[i], d_Tb[i] = upwind_energy(
            mf[i], Ta[i], Tb[i], cp, ch, band, G)


# -- volumes ---------------------------------------------------------------------------
@jit
def ideal_density(p, T, R):
    """(rho, d rho/dp, d rho/dT) of an ideal gas."""
    RT = R * T
    rho = p / RT
    return rho, 1.0 / RT, -rho / T


@jit
def curve_work(knots, table, w0, x):
    """The integral of a PV curve's pressure over volume up to x (from its
    first volume; ``w0`` the integral at each piece's base), exact for its
    cubic pieces: :meth:`softflow.curves.PVCurve.work`."""
    row = piece(knots, x)
    x = x - table[row, 0]
    c0, c1, c2, c3 = table[row, 1], table[row, 2], table[row, 3], table[row, 4]
    return w0[row] + x * (c0 + x * (c1 / 2.0 + x * (c2 / 3.0 + x * c3 / 4.0)))


@jit
def wall_law(wall, p, T, m, R, fl, f, knots, table, w0, mode, scaled, p_atm, work):
    """A volume's wall at the pressure p, gas temperature T and mass m:
    (F0, dF0/dp, dF0/dT, dF0/dm, dvol/dp, dvol/dT, dvol/dm, W, p_wall, ok),
    F0 the wall's law, W the work the gas has done on it since t = 0 (with
    ``work``; else 0) and p_wall = dW/dvol; ``ok`` False where the curve
    refuses the volume. The wall's constants at fl[f:]: RIGID (volume),
    LINEAR (volume, compliance, p_ref, p_0: vol = volume + compliance
    (p - p_ref), W = compliance ((p - p_ref)^2 - (p_0 - p_ref)^2)/2 +
    p_ref (vol - vol_0)), CURVE (pressure scale, the work at the initial
    volume: vol = m / rho, p = curve(vol), gauge part scaled where
    ``scaled``)."""
    rho, rho_p, rho_T = ideal_density(p, T, R)
    if wall == RIGID:
        volume = fl[f]
        return (rho * volume - m, rho_p * volume, rho_T * volume, -1.0, 0.0, 0.0, 0.0, 0.0,
                0.0, True)
    if wall == LINEAR:
        volume, C, p_ref, p_i = fl[f], fl[f + 1], fl[f + 2], fl[f + 3]
        vol = volume + C * (p - p_ref)
        W = 0.0
        if work:
            g, g0 = p - p_ref, p_i - p_ref
            W = C * (0.5 * (g * g - g0 * g0) + p_ref * (g - g0))
        return (rho * vol - m, rho_p * vol + rho * C, rho_T * vol, -1.0, C, 0.0, 0.0, W, p,
                True)
    vol = m / rho
    if refused(mode, knots, vol):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    pc, dpc = curve_point(knots, table, vol)
    s = fl[f]
    if scaled:
        pc = p_atm + s * (pc - p_atm)
        dpc = s * dpc
    W = 0.0
    if work:
        W = curve_work(knots, table, w0, vol)
        if scaled:
            base = p_atm * vol
            W = base + s * (W - base)
        W = W - fl[f + 1]
    dv_p, dv_T, dv_m = -vol * rho_p / rho, -vol * rho_T / rho, 1.0 / rho
    return (p - pc, 1.0 - dpc * dv_p, -dpc * dv_T, -dpc * dv_m, dv_p, dv_T, dv_m, W, pc, True)


@jit
def loop_wall(p, T, m, R, inflating, offset, knots_up, table_up, w0_up, mode_up, knots_down,
              table_down, w0_down, mode_down, v_hi, v_lo, shift_up, shift_down, work):
    """:func:`wall_law` of a hysteretic actuator on the branch it started the
    step on (``inflating``): the inflation curve below V_hi while inflating,
    at or below V_lo while deflating, else the deflation curve
    (:meth:`softflow.curves.HysteresisLoop.fdf_volume`); the work along that
    branch (:meth:`~softflow.curves.HysteresisLoop.work`, its shifts continuing
    each branch past its end on the other) less ``offset`` (the discrete state
    work_offset). Not ok where either curve refuses the volume."""
    rho, rho_p, rho_T = ideal_density(p, T, R)
    vol = m / rho
    if refused(mode_up, knots_up, vol) or refused(mode_down, knots_down, vol):
        return 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, False
    up = vol < v_hi if inflating else vol <= v_lo
    if up:
        pc, dpc = curve_point(knots_up, table_up, vol)
    else:
        pc, dpc = curve_point(knots_down, table_down, vol)
    W = 0.0
    if work:
        W = loop_work(vol, inflating, knots_up, table_up, w0_up, knots_down, table_down,
                      w0_down, v_hi, v_lo, shift_up, shift_down) - offset
    dv_p, dv_T, dv_m = -vol * rho_p / rho, -vol * rho_T / rho, 1.0 / rho
    return (p - pc, 1.0 - dpc * dv_p, -dpc * dv_T, -dpc * dv_m, dv_p, dv_T, dv_m, W, pc, True)


@jit
def loop_work(vol, inflating, knots_up, table_up, w0_up, knots_down, table_down, w0_down,
              v_hi, v_lo, shift_up, shift_down):
    """The work along the branch a hysteretic actuator started the step on
    (``inflating``) up to the volume vol, continued past the branch's end on
    the other by its shift (:meth:`softflow.curves.HysteresisLoop.work`)."""
    w_up = curve_work(knots_up, table_up, w0_up, vol)
    w_down = curve_work(knots_down, table_down, w0_down, vol)
    if inflating:
        return w_up if vol < v_hi else w_down + shift_up
    return w_down if vol > v_lo else w_up + shift_down


@jit
def loop_offset(offset, vol, inflating, was_inflating, knots_up, table_up, w0_up, knots_down,
                table_down, w0_down, v_hi, v_lo, shift_up, shift_down):
    """The work offset (a discrete state) after a step that ended at the
    volume vol on the branch ``inflating``, having started it on
    ``was_inflating`` with ``offset``: the new branch's work counted from
    where the old one's ended, so the stored energy stays
    (:meth:`softflow.components.thermal._LoopCurve.switch`; on the same
    branch, the offset to round-off, as there)."""
    w_new = loop_work(vol, inflating, knots_up, table_up, w0_up, knots_down, table_down,
                      w0_down, v_hi, v_lo, shift_up, shift_down)
    w_old = loop_work(vol, was_inflating, knots_up, table_up, w0_up, knots_down, table_down,
                      w0_down, v_hi, v_lo, shift_up, shift_down)
    return (offset + w_new) - w_old


@jit
def free_rows(F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, T, Q, m, Es, cv, c, h0, hA, T_wall,
              any_heat):
    """The rows of a volume whose gas is free (adiabatic or with wall heat) at
    its end-of-step states m, Es, from its wall's (:func:`wall_law`): the
    wall's law, m (u(T) - h0) + W - Es and Q - hA (T_wall - T) (Q where no
    volume of the group has heat), u = cv T + c. Returns (F0, F1, F2, J0..J8),
    J in the residual's columns (p, T) of row 0, (p, T) of row 1, (T, Q) of
    row 2, then (row 0, m), (row 1, m), (row 1, Es)."""
    u = cv * T + c
    u = u - h0
    F1 = m * u + W - Es
    F2 = Q - hA * (T_wall - T) if any_heat else Q
    return (F0, F1, F2, d_p, d_T, m * 0.0 + p_wall * v_p, m * cv + p_wall * v_T, hA, 1.0, d_m,
            u + p_wall * v_m, -1.0)


@jit
def held_rows(F0, d_p, d_T, d_m, T, T_wall):
    """The rows of a volume held at its wall temperature from its wall's:
    the wall's law and T - T_wall; (F0, F1, J0..J3), J in the columns
    (row 0, p), (row 0, T), (row 1, T), (row 0, m)."""
    return F0, T - T_wall, d_p, d_T, 1.0, d_m


@jit
def volume_residual(wall, free, V, S, R, cv, c, h0, hA, T_wall, any_heat, fl, k, knots, table,
                    w0, mode, scaled, p_atm, F, J, jac):
    """A group of volumes' residual (free: V = [p, mf, T, E, Q], states
    [m, Es]; held: V = [p, mf, T, E], state m) at the states S, into F (n, 3
    or 2) and, with ``jac``, J (n, 9 or 4) in the class's residual columns;
    the wall's constants of instance i at fl[k i:]. Returns -1, or the index
    of the first volume the curve refuses."""
    for i in range(V.shape[0]):
        p, T = V[i, 0], V[i, 2]
        F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, ok = wall_law(
            wall, p, T, S[i, 0], R, fl, k * i, knots, table, w0, mode, scaled, p_atm, free)
        if not ok:
            return i
        _volume_rows(F, J, i, jac, free, F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, V, S, cv,
                     c, h0, hA, T_wall, any_heat)
    return -1


@jit
def loop_residual(free, V, S, R, cv, c, h0, hA, T_wall, any_heat, knots_up, table_up, w0_up,
                  mode_up, knots_down, table_down, w0_down, mode_down, v_hi, v_lo, shift_up,
                  shift_down, F, J, jac):
    """:func:`volume_residual` of hysteretic actuators (:func:`loop_wall`; the
    branch in S[:, 2], the work offset in S[:, 3] where ``free``, else the
    branch in S[:, 1])."""
    for i in range(V.shape[0]):
        p, T = V[i, 0], V[i, 2]
        if free:
            inflating, offset = S[i, 2] > 0.5, S[i, 3]
        else:
            inflating, offset = S[i, 1] > 0.5, 0.0
        F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, ok = loop_wall(
            p, T, S[i, 0], R, inflating, offset, knots_up, table_up, w0_up, mode_up,
            knots_down, table_down, w0_down, mode_down, v_hi, v_lo, shift_up, shift_down, free)
        if not ok:
            return i
        _volume_rows(F, J, i, jac, free, F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, V, S, cv,
                     c, h0, hA, T_wall, any_heat)
    return -1


@jit
def _volume_rows(F, J, i, jac, free, F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, V, S, cv, c,
                 h0, hA, T_wall, any_heat):
    """Instance i's rows into F[i] and J[i] (:func:`free_rows`, :func:`held_rows`)."""
    if free:
        (F[i, 0], F[i, 1], F[i, 2], j0, j1, j2, j3, j4, j5, j6, j7,
         j8) = free_rows(F0, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, V[i, 2], V[i, 4],
                         S[i, 0], S[i, 1], cv, c, h0, hA[i], T_wall[i], any_heat)
        if jac:
            J[i, 0], J[i, 1], J[i, 2], J[i, 3], J[i, 4] = j0, j1, j2, j3, j4
            J[i, 5], J[i, 6], J[i, 7], J[i, 8] = j5, j6, j7, j8
    else:
        F[i, 0], F[i, 1], j0, j1, j2, j3 = held_rows(F0, d_p, d_T, d_m, V[i, 2], T_wall[i])
        if jac:
            J[i, 0], J[i, 1], J[i, 2], J[i, 3] = j0, j1, j2, j3


# -- flow elements: V = [p_a, mf_a, T_a, E_a, p_b, mf_b, T_b, E_b] -----------------------
@jit
def energy_entries(J, j, e_mf, e_Ta, e_Tb):
    """The energy rows' entries (2, E_a) (2, E_b) (3, p_a) (3, mf) (3, T_a)
    (3, E_a) (3, p_b) (3, T_b) at J[j:] (dE/dp = 0 for an ideal gas)."""
    J[j] = 1.0
    J[j + 1] = 1.0
    J[j + 2] = -0.0
    J[j + 3] = -e_mf
    J[j + 4] = -e_Ta
    J[j + 5] = 1.0
    J[j + 6] = -0.0
    J[j + 7] = -e_Tb


@jit
def pressure_drop_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, dp, d_pa, d_mf, d_pb,
                       d_T, theta, E, w, dw, e_mf, e_Ta, e_Tb):
    """A two-port's rows at F[r:r+4] (mass balance, p_a - p_b - theta dp, the
    energy balance E_a + E_b, E_a - E) and, with ``jac``, its 15 entries at
    J[j:] in the pattern (0,mf_a) (0,mf_b) (1,p_a) (1,mf) (1,p_b) (1,T_a)
    (1,T_b), then the energy rows': the flow law dp(p_a, mf, p_b, T_up) with
    its partials (d_T in the upstream temperature T_up), theta its scale."""
    F[r] = mf + mfb
    F[r + 1] = (pa - pb) - theta * dp
    F[r + 2] = Ea + Eb
    F[r + 3] = Ea - E
    if jac:
        J[j] = 1.0
        J[j + 1] = 1.0
        J[j + 2] = 1.0 - theta * d_pa
        coef = -d_T
        J[j + 3] = coef * dw * (Ta - Tb) - theta * d_mf
        J[j + 4] = -1.0 - theta * d_pb
        cw = coef * w
        J[j + 5] = cw
        J[j + 6] = coef - cw
        energy_entries(J, j + 7, e_mf, e_Ta, e_Tb)


@jit
def adiabatic_tube_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, kind, lo, hi,
                        re_per_mf, c_mu, eD, a, area, kre, R, gas, cp, ch, band, G):
    """A gas tube's rows in a thermal scene (adiabatic pipe flow,
    :func:`.tube.adiabatic_drop`, from the upstream temperature)."""
    E, w, dw, T_up, e_mf, e_Ta, e_Tb = upwind_energy(mf, Ta, Tb, cp, ch, band, G)
    dp, d_pa, d_mf, d_pb, d_T = adiabatic_drop(kind, lo, hi, pa, mf, pb, T_up, re_per_mf, c_mu,
                                               eD, a, area, R, gas, kre)
    pressure_drop_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, dp, d_pa, d_mf, d_pb,
                       d_T, 1.0, E, w, dw, e_mf, e_Ta, e_Tb)


@jit
def adiabatic_tesla_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, kind, lo, hi,
                         re_per_mf, c_mu, eD, a, area, mf_blend, diodicity, R, gas, cp, ch,
                         band, G):
    """A Tesla valve's rows in a thermal scene (adiabatic pipe flow,
    :func:`.valves.tesla_adiabatic_drop`)."""
    E, w, dw, T_up, e_mf, e_Ta, e_Tb = upwind_energy(mf, Ta, Tb, cp, ch, band, G)
    dp, d_pa, d_mf, d_pb, d_T = tesla_adiabatic_drop(kind, lo, hi, pa, mf, pb, T_up, re_per_mf,
                                                     c_mu, eD, a, area, mf_blend, diodicity, R,
                                                     gas)
    pressure_drop_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, dp, d_pa, d_mf, d_pb,
                       d_T, 1.0, E, w, dw, e_mf, e_Ta, e_Tb)


@jit
def tube_residual(V, kind, lo, hi, re_per_mf, c_mu, eD, a, area, kre, R, gamma, cp, ch, band,
                  G, F, J, jac):
    """A group of gas tubes in a thermal scene (:func:`adiabatic_tube_rows`)
    into F (n·4) and, with ``jac``, J (n·15)."""
    gas = gas_constants(gamma)
    for i in range(V.shape[0]):
        adiabatic_tube_rows(F, 4 * i, J, 15 * i, jac, V[i, 0], V[i, 1], V[i, 2], V[i, 3],
                            V[i, 4], V[i, 5], V[i, 6], V[i, 7], kind, lo, hi, re_per_mf[i],
                            c_mu[i], eD[i], a[i], area[i], kre[i], R, gas, cp, ch, band, G)


@jit
def tesla_residual(V, kind, lo, hi, re_per_mf, c_mu, eD, a, area, mf_blend, diodicity, R, gamma,
                   cp, ch, band, G, F, J, jac):
    """A group of Tesla valves in a thermal scene (:func:`adiabatic_tesla_rows`)
    into F (n·4) and, with ``jac``, J (n·15)."""
    gas = gas_constants(gamma)
    for i in range(V.shape[0]):
        adiabatic_tesla_rows(F, 4 * i, J, 15 * i, jac, V[i, 0], V[i, 1], V[i, 2], V[i, 3],
                             V[i, 4], V[i, 5], V[i, 6], V[i, 7], kind, lo, hi, re_per_mf[i],
                             c_mu[i], eD[i], a[i], area[i], mf_blend[i], diodicity[i], R, gas,
                             cp, ch, band, G)


@jit
def scaled_drop_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, f1, j_pa, j_mf, j_pb,
                     T_ref, E, w, dw, T_up, e_mf, e_Ta, e_Tb):
    """A two-port whose flow law's row f1 = (p_a - p_b) - dp (partials j_pa,
    j_mf, j_pb) at the nominal temperature T_ref has its pressure drop scaled
    by theta = T_up/T_ref (the density at the upstream temperature): rows at
    F[r:], the 15 entries of :func:`pressure_drop_rows`' pattern at J[j:]."""
    dp = (pa - pb) - f1
    theta = T_up * (1.0 / T_ref)
    F[r] = mf + mfb
    F[r + 1] = f1 - (theta - 1.0) * dp
    F[r + 2] = Ea + Eb
    F[r + 3] = Ea - E
    if jac:
        coef = dp * (-1.0 / T_ref)
        one_theta = 1.0 - theta
        J[j] = 1.0
        J[j + 1] = 1.0
        J[j + 2] = theta * j_pa + one_theta
        J[j + 3] = theta * j_mf + coef * dw * (Ta - Tb)
        J[j + 4] = theta * j_pb - one_theta
        cw = coef * w
        J[j + 5] = cw
        J[j + 6] = coef - cw
        energy_entries(J, j + 7, e_mf, e_Ta, e_Tb)


@jit
def snapping_rows(F, r, J, j, jac, is_open, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, kind, lo, hi,
                  re_per_mf, c_mu, eD, a, area, kre, conductance, RT, rho, R, gas, T_ref, cp,
                  ch, band, G):
    """A snapping valve's rows in a thermal scene of an ideal gas: open, the
    passage's adiabatic pipe flow (:func:`.tube.adiabatic_drop`); closed, the
    linear restrictor at the mean density of the nominal temperature, its
    drop scaled by T_up/T_ref (:func:`scaled_drop_rows`)."""
    E, w, dw, T_up, e_mf, e_Ta, e_Tb = upwind_energy(mf, Ta, Tb, cp, ch, band, G)
    if is_open:
        dp, d_pa, d_mf, d_pb, d_T = adiabatic_drop(kind, lo, hi, pa, mf, pb, T_up, re_per_mf,
                                                   c_mu, eD, a, area, R, gas, kre)
        pressure_drop_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, dp, d_pa, d_mf,
                           d_pb, d_T, 1.0, E, w, dw, e_mf, e_Ta, e_Tb)
    else:
        rm, drm = mean_density(pa, pb, RT, rho)
        dX = 1.0 / conductance
        f1, j_pa, j_mf, j_pb = restrictor_row(pa, pb, dX * mf, dX, rm, drm)
        scaled_drop_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, f1, j_pa, j_mf, j_pb,
                         T_ref, E, w, dw, T_up, e_mf, e_Ta, e_Tb)


@jit
def snapping_residual(V, S, kind, lo, hi, re_per_mf, c_mu, eD, a, area, kre, conductance, RT,
                      rho, R, gamma, T_ref, cp, ch, band, G, F, J, jac):
    """A group of snapping valves in a thermal scene of an ideal gas
    (:func:`snapping_rows`, the mode S[:, 0] > 0.5 open) into F (n·4) and,
    with ``jac``, J (n·15)."""
    gas = gas_constants(gamma)
    for i in range(V.shape[0]):
        snapping_rows(F, 4 * i, J, 15 * i, jac, S[i, 0] > 0.5, V[i, 0], V[i, 1], V[i, 2],
                      V[i, 3], V[i, 4], V[i, 5], V[i, 6], V[i, 7], kind, lo, hi, re_per_mf[i],
                      c_mu[i], eD[i], a[i], area[i], kre[i], conductance[i], RT, rho, R, gas,
                      T_ref, cp, ch, band, G)


@jit
def sqrt_density_rows(F, r, J, j, jac, mf, Ta, Ea, mfb, Tb, Eb, q_iso, q_pa, q_pb, T_ref, cp,
                      ch, band, G):
    """A two-port whose mass flow q_iso(p_a, p_b) (partials q_pa, q_pb) at the
    nominal temperature T_ref scales with sqrt(T_ref/T_up) (an orifice): rows
    (mass balance, mf - theta q, energy) at F[r:] and the 15 entries of
    :func:`pressure_drop_rows`' pattern at J[j:]."""
    E, w, dw, T_up, e_mf, e_Ta, e_Tb = upwind_energy(mf, Ta, Tb, cp, ch, band, G)
    f1 = mf - q_iso                      # the isothermal law's row, as it is made
    q = mf - f1
    theta = math.sqrt(T_ref / T_up)
    F[r] = mf + mfb
    F[r + 1] = mf - theta * q
    F[r + 2] = Ea + Eb
    F[r + 3] = Ea - E
    if jac:
        coef = (0.5 * q) * theta / T_up
        J[j] = 1.0
        J[j + 1] = 1.0
        J[j + 2] = theta * -q_pa
        J[j + 3] = theta * 1.0 + ((1.0 - theta) + coef * dw * (Ta - Tb))
        J[j + 4] = theta * -q_pb
        cw = coef * w
        J[j + 5] = cw
        J[j + 6] = coef - cw
        energy_entries(J, j + 7, e_mf, e_Ta, e_Tb)


@jit
def orifice_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, model, RT, rho, T, rho0, T0,
                 K, area, dp_small, gamma, Cd, C, b, m, pr_laminar, T_ref, cp, ch, band, G):
    """An orifice's rows in a thermal scene: its law ``model``
    (:func:`.valves.orifice_flow`, the upstream density of the gas at its
    nominal temperature) scaled by sqrt(T_ref/T_up) (:func:`sqrt_density_rows`)."""
    if model == ISO_6358:                   # ISO 6358 takes no density
        rho_up, drho_up = 0.0, 0.0
    else:
        rho_up, drho_up = density(orifice_upstream(model, pa, pb), RT, rho)
    q, q_pa, q_pb = orifice_flow(model, pa, pb, rho_up, drho_up, K, area, dp_small, gamma, Cd,
                                 T, C, b, m, pr_laminar, rho0, T0)
    sqrt_density_rows(F, r, J, j, jac, mf, Ta, Ea, mfb, Tb, Eb, q, q_pa, q_pb, T_ref, cp, ch,
                      band, G)


@jit
def check_valve_rows(F, r, J, j, jac, pa, mf, Ta, Ea, pb, mfb, Tb, Eb, nozzle, RT, rho, K, Cd,
                     gamma, area, dp_small, cracking, band_open, leakage, cp, ch, band, G):
    """A check valve's rows in a thermal scene: its law at the nominal
    temperature (:func:`.valves.check_valve_flow`, :func:`plain_rows`)."""
    ro, dro = density(_maximum(pa, pb) if nozzle else pa, RT, rho)
    rm, drm = mean_density(pa, pb, RT, rho)
    q, q_pa, q_pb = check_valve_flow(pa, pb, nozzle, ro, dro, rm, drm, K, Cd, gamma, area,
                                     dp_small, cracking, cracking + band_open, leakage)
    plain_rows(F, r, J, j, jac, mf, Ta, Ea, mfb, Tb, Eb, mf - q, -q_pa, 1.0, -q_pb, cp, ch,
               band, G)


@jit
def orifice_residual(V, model, RT, rho, T, rho0, T0, K, area, dp_small, gamma, Cd, C, b, m,
                     pr_laminar, T_ref, cp, ch, band, G, F, J, jac):
    """A group of orifices in a thermal scene (:func:`orifice_rows`) into F
    (n·4) and, with ``jac``, J (n·15)."""
    for i in range(V.shape[0]):
        orifice_rows(F, 4 * i, J, 15 * i, jac, V[i, 0], V[i, 1], V[i, 2], V[i, 3], V[i, 4],
                     V[i, 5], V[i, 6], V[i, 7], model, RT, rho, T, rho0, T0, K[i], area[i],
                     dp_small[i], gamma[i], Cd[i], C[i], b[i], m[i], pr_laminar[i], T_ref, cp,
                     ch, band, G)


@jit
def check_valve_residual(V, nozzle, RT, rho, K, Cd, gamma, area, dp_small, cracking, band_open,
                         leakage, cp, ch, band, G, F, J, jac):
    """A group of check valves in a thermal scene (:func:`check_valve_rows`)
    into F (n·4) and, with ``jac``, J (n·13)."""
    for i in range(V.shape[0]):
        check_valve_rows(F, 4 * i, J, 13 * i, jac, V[i, 0], V[i, 1], V[i, 2], V[i, 3],
                         V[i, 4], V[i, 5], V[i, 6], V[i, 7], nozzle, RT, rho, K[i], Cd[i],
                         gamma[i], area[i], dp_small[i], cracking[i], band_open[i],
                         leakage[i], cp, ch, band, G)


@jit
def plain_rows(F, r, J, j, jac, mf, Ta, Ea, mfb, Tb, Eb, f1, j_pa, j_mf, j_pb, cp, ch, band, G):
    """A two-port whose flow law (row f1, partials j_pa, j_mf, j_pb) keeps its
    nominal temperature (a check valve): rows at F[r:], 13 entries at J[j:]
    ((0,mf_a) (0,mf_b) (1,p_a) (1,mf) (1,p_b), then the energy rows')."""
    E, _, _, _, e_mf, e_Ta, e_Tb = upwind_energy(mf, Ta, Tb, cp, ch, band, G)
    F[r] = mf + mfb
    F[r + 1] = f1
    F[r + 2] = Ea + Eb
    F[r + 3] = Ea - E
    if jac:
        J[j] = 1.0
        J[j + 1] = 1.0
        J[j + 2] = j_pa
        J[j + 3] = j_mf
        J[j + 4] = j_pb
        energy_entries(J, j + 5, e_mf, e_Ta, e_Tb)


# -- sources: V = [p, mf, T, E] ----------------------------------------------------------
@jit
def source_energy(E, mf, T, T_source, cp, ch, band, G):
    """The energy row E - E_flow of a flow source (E its energy variable; the
    outflow, mf < 0, carries the source's enthalpy, an inflow the node's) and
    its entries in (p, mf, T, E): (F, J0, J1, J2, J3)."""
    Es, _, _, _, e_mf, e_Ta, _ = upwind_energy(mf, T, T_source, cp, ch, band, G)
    return E - Es, -(0.0 + 0.0), -e_mf, -e_Ta, 1.0


@jit
def volume_flow_law(p, T, q, T_source, R):
    """mf + rho(p, T_q) q of a volume flow source (T_q the source's
    temperature while it delivers, q >= 0, the node's while it draws):
    (rho q, d/dp, d/dT)."""
    out = q >= 0.0
    T_q = T_source if out else T
    RT = R * T_q
    return (p / RT) * q, (1.0 / RT) * q, 0.0 if out else (-p / (R * T_q * T_q)) * q


@jit
def source_residual(volume, V, q, T_source, R, cp, ch, band, G, F, J, jac):
    """A group of mass (mf + q) or ``volume`` (mf + rho(p, T_q) q) flow
    sources of an ideal gas with their energy rows (:func:`source_energy`)
    into F (n·2) and, with ``jac``, J (n·5 or n·7) in the class's pattern;
    q the values, T_source each one's temperature."""
    nj = 7 if volume else 5
    for i in range(V.shape[0]):
        p, mf, T, E = V[i, 0], V[i, 1], V[i, 2], V[i, 3]
        fe, e_p, e_mf, e_T, e_E = source_energy(E, mf, T, T_source[i], cp, ch, band, G)
        F[2 * i + 1] = fe
        j = nj * i
        if volume:
            rq, rq_p, rq_T = volume_flow_law(p, T, q[i], T_source[i], R)
            F[2 * i] = mf + rq
            if jac:
                J[j], J[j + 1], J[j + 2] = rq_p, 1.0, rq_T
                j += 3
        else:
            F[2 * i] = mf + q[i]
            if jac:
                J[j] = 1.0
                j += 1
        if jac:
            J[j], J[j + 1], J[j + 2], J[j + 3] = e_p, e_mf, e_T, e_E
