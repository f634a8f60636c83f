"""Orifice and valve flow laws, vectorized, each with its derivatives.

Each law is written as mass flow from the pressures, with the square root
(or ISO 6358's root near pressure ratio 1) replaced by an odd cubic inside a
small band around zero flow. The cubic matches the exact law's value and slope
at the band edge, so the result is C1 and its slope at zero flow is finite and
non-zero: Newton neither divides by an infinite derivative nor stalls on a flat
one. The same idea as Modelica.Fluid's regularized roots, with its own formula.

Reference implementations for the tests: ``fluids.core.dP_from_K``,
``fluids.flow_meter.flow_meter_discharge`` and ``nozzle_expansibility``, and
``fluids.compressible.P_critical_flow`` (Caleb Bell).
"""
from __future__ import annotations

import numpy as np

#: ISO 6358 standard reference atmosphere (ANR): density [kg/m^3] and temperature [K].
ISO_6358_RHO0 = 1.185
ISO_6358_T0 = 293.15


def _odd_cubic(x, x_l, f_l, df_l):
    """y = x (alpha + beta x^2), the odd cubic with y(x_l) = f_l and y'(x_l) = df_l;
    returns (y, dy/dx). Monotone on [0, x_l] when 0 < df_l <= f_l/x_l."""
    beta = (df_l - f_l / x_l) / (2.0 * x_l * x_l)
    alpha = f_l / x_l - beta * x_l * x_l
    x2 = x * x
    return x * (alpha + beta * x2), alpha + 3.0 * beta * x2


def regularized_sqrt(x, x_small):
    """sign(x)·sqrt(|x|), made C1 with a finite slope at x = 0; returns (y, dy/dx).

    For |x| >= x_small it is exact. Inside, y = x/sqrt(x_small) · (5/4 - (x/x_small)^2/4),
    the odd cubic matching value and slope at ±x_small: slope 5/(4 sqrt(x_small)) at
    zero, never below 1/(2 sqrt(x_small)), so the law stays strictly increasing.

    x : float or array
    x_small : float or array (> 0)
    """
    x = np.asarray(x, dtype=float)
    ax = np.abs(x)
    inside = ax < x_small
    safe = np.where(inside, x_small, ax)    # keeps sqrt/division finite where unused
    r = np.sqrt(safe)
    y_out = np.sign(x) * r
    dy_out = 0.5 / r
    xs = np.broadcast_to(x_small, x.shape)
    rs = np.sqrt(xs)
    y_in, dy_in = _odd_cubic(x, xs, rs, 0.5 / rs)
    return np.where(inside, y_in, y_out), np.where(inside, dy_in, dy_out)


def massflow_loss_coefficient(dp, rho, K, area, dp_small):
    """Mass flow through a restriction of loss coefficient K (turbulent, Re >~ 100).

    Definition of the loss coefficient (Crane TP-410; Idelchik, Handbook of
    Hydraulic Resistance), with v = mdot/(rho·A):

        dp = K · rho · v^2 / 2   <=>   mdot = A · sqrt(2 rho dp / K)

    signed with dp, the square root regularized below |dp| = dp_small (see
    :func:`regularized_sqrt`). A discharge coefficient Cd is K = 1/Cd^2 (see
    :func:`loss_coefficient_from_discharge_coefficient`). Valid for liquids, and
    for gases while |dp| stays well below the upstream pressure (no expansion,
    no choking; use :func:`massflow_ISO_6358` beyond that).

    dp : pressure drop [Pa], rho : density [kg/m^3], K : loss coefficient [-],
    area : flow area [m^2], dp_small : regularization band [Pa]

    Returns (mdot [kg/s], d mdot/d dp, d mdot/d rho).
    """
    r, dr = regularized_sqrt(dp, dp_small)
    g = area * np.sqrt(2.0 / K)
    sq = np.sqrt(rho)
    return g * sq * r, g * sq * dr, g * r * 0.5 / sq


def loss_coefficient_from_discharge_coefficient(Cd):
    """K = 1/Cd^2: the loss coefficient equivalent to a discharge coefficient.

    Orifice equation mdot = Cd · A · sqrt(2 rho dp) (ISO 5167-1 with a small
    diameter ratio, beta -> 0, and expansibility 1), set equal to the loss
    coefficient form A·sqrt(2 rho dp / K). Cd is referred to the orifice area.
    """
    return 1.0 / (np.asarray(Cd, dtype=float) ** 2)


def critical_pressure_ratio(gamma):
    """pr* = (2/(gamma+1))^(gamma/(gamma-1)): the back-to-stagnation pressure
    ratio at which an isentropic nozzle of an ideal gas chokes (0.528 for
    gamma = 1.4; Anderson, Modern Compressible Flow, 3rd ed., sec. 5.4)."""
    gamma = np.asarray(gamma, dtype=float)
    return (2.0 / (gamma + 1.0)) ** (gamma / (gamma - 1.0))


def nozzle_flow_factor(s, gamma):
    """The isentropic nozzle's mass flow relative to the incompressible orifice
    equation at the same upstream density and pressure drop, Y(s), and dY/ds,
    with s = 1 - pr = (p0 - p_down)/p0 (0 <= s <= 1; p0: stagnation pressure):

        mdot = Cd A sqrt(2 rho0 (p0 - p_down)) · Y(s)

        Y^2 = gamma/(gamma-1) · pr^(2/gamma) · (1 - pr^((gamma-1)/gamma)) / (1 - pr)
                                                       pr > pr* (subsonic)
        Y   = Psi* / sqrt(2 s),  Psi*^2 = gamma (2/(gamma+1))^((gamma+1)/(gamma-1))
                                                       pr <= pr* (choked)

    Subsonic, Y is ISO 5167-3's expansibility factor of a nozzle at diameter
    ratio beta -> 0 (``fluids.flow_meter.nozzle_expansibility``); Y(0) = 1 and
    Y ~ 1 - 3 s/(4 gamma) for small s. Choked, it keeps the flow at its value at
    pr* (Y is C1 there: the subsonic flow has zero slope at pr*). Ideal gas,
    isentropic, one-dimensional, negligible approach velocity. The difference
    of two powers near pr = 1 is taken with log1p/expm1, so Y is accurate to
    round-off down to s -> 0, where it is given its limit.

    s : float or array [-]; gamma : ratio of specific heats (> 1) [-].
    Returns (Y [-], dY/ds [-]).
    """
    s = np.asarray(s, dtype=float)
    gamma = np.asarray(gamma, dtype=float)
    e = (gamma - 1.0) / gamma
    b = critical_pressure_ratio(gamma)
    choked = s >= 1.0 - b
    tiny = s < 1e-9
    s_sub = np.where(choked | tiny, 1e-3, s)      # keeps the logs finite where unused
    ln_pr = np.log1p(-s_sub)
    E = -np.expm1(e * ln_pr)                  # 1 - pr^e, to round-off near pr = 1
    pr = 1.0 - s_sub
    G = np.exp(2.0 / gamma * ln_pr) * (E / s_sub) / e        # Y^2
    # d ln G/d pr = 2/(gamma pr) - e pr^(e-1)/E + 1/s, -> 3/(2 gamma) as s -> 0
    dlnG = 2.0 / (gamma * pr) - e * np.exp((e - 1.0) * ln_pr) / E + 1.0 / s_sub
    Y = np.sqrt(G)
    dY = -0.5 * Y * dlnG                      # dY/ds = -dY/dpr
    s_ch = np.where(choked, s, 1.0)
    psi_star = np.sqrt(gamma * (2.0 / (gamma + 1.0)) ** ((gamma + 1.0) / (gamma - 1.0)))
    Y_ch = psi_star / np.sqrt(2.0 * s_ch)
    Y = np.where(choked, Y_ch, np.where(tiny, 1.0 - 0.75 / gamma * s, Y))
    dY = np.where(choked, -0.5 * Y_ch / s_ch, np.where(tiny, -0.75 / gamma, dY))
    return Y, dY


def massflow_nozzle(p_a, p_b, rho_up, gamma, Cd, area, dp_small, drho_up=None):
    """Mass flow of a gas through an orifice taken as an isentropic nozzle with
    a discharge coefficient, subsonic or choked, positive from a to b.

    With p0 the higher (upstream) and p_down the lower of p_a, p_b (node
    pressures are stagnation pressures: the volumes' gas is at rest),
    pr = p_down/p0 and pr* = (2/(gamma+1))^(gamma/(gamma-1)):

        mdot = Cd A p0 sqrt(2 gamma/((gamma-1) R T0)) sqrt(pr^(2/gamma) - pr^((gamma+1)/gamma))
                                                                   pr* < pr <= 1
        mdot = Cd A p0 sqrt(gamma/(R T0)) (2/(gamma+1))^((gamma+1)/(2(gamma-1)))
                                                                   pr <= pr* (choked)

    written as mdot = Cd A sqrt(2 rho0 dp) · Y(1 - pr), rho0 = p0/(R T0), with
    Y from :func:`nozzle_flow_factor` (C1 at pr*). For a gas that is not ideal
    (the 'table' and 'eos' fluid levels) R T0 is replaced by p0/rho0, rho0 the
    fluid's density at p0 and the run's temperature (``rho_up``), and gamma is
    the fluid's at one state: the ideal-gas nozzle at the real upstream density,
    an approximation that holds while the gas expands nearly as an ideal gas.

    Near pr = 1 the slope in p is infinite (the square root of dp). As for
    :func:`massflow_loss_coefficient`, sqrt(dp) is replaced by the odd cubic of
    :func:`regularized_sqrt` below |dp| = dp_small (the laminar-like band, placed
    at an orifice Reynolds number by :func:`dp_at_reynolds`), where Y = 1 to
    within 3 dp_small/(4 gamma p0): the flow reverses C1-smoothly through
    p_a = p_b with a finite, non-zero slope, and for small dp the law is the
    incompressible orifice equation.

    Anderson, Modern Compressible Flow, 3rd ed. (2003), sec. 5.4 (flow through
    a convergent nozzle); ISO 5167-3:2003 (nozzle expansibility factor) and
    ISO 9300:2005 (critical-flow nozzles: choked mass flow with a discharge
    coefficient). Valid for gases, steady flow through a short restriction
    (a sharp-edged orifice's Cd, about 0.6, folds in its vena contracta; its
    true choking is gradual, which this law does not model), gamma > 1.

    p_a, p_b : absolute pressures [Pa]; rho_up : density at the upstream
    pressure max(p_a, p_b) [kg/m^3]; gamma : ratio of specific heats [-];
    Cd : discharge coefficient [-]; area : throat area [m^2]; dp_small :
    regularization band [Pa]; drho_up : d rho_up / d p_up [kg/(m^3 Pa)]
    (None: an ideal gas at fixed temperature, rho_up/p_up).

    Returns (mdot [kg/s], d mdot/d p_a, d mdot/d p_b).
    """
    p_a = np.asarray(p_a, dtype=float)
    p_b = np.asarray(p_b, dtype=float)
    forward = p_a >= p_b
    p_up = np.where(forward, p_a, p_b)
    p_dn = np.where(forward, p_b, p_a)
    rho_up = np.asarray(rho_up, dtype=float)
    if drho_up is None:
        drho_up = rho_up / p_up
    dp = p_a - p_b
    s = (p_up - p_dn) / p_up
    Y, dY = nozzle_flow_factor(s, gamma)
    r, dr = regularized_sqrt(dp, dp_small)
    k = Cd * area * np.sqrt(2.0 * rho_up)
    q = k * r * Y
    base = k * dr * Y
    d_up = 0.5 * q * drho_up / rho_up + k * r * dY * p_dn / (p_up * p_up)
    d_dn = -k * r * dY / p_up
    return q, base + np.where(forward, d_up, d_dn), -base + np.where(forward, d_dn, d_up)


def iso_6358_of_nozzle(diameter, Cd, gamma, R, rho0=ISO_6358_RHO0, T0=ISO_6358_T0):
    """ISO 6358 sonic conductance C and critical pressure ratio b of the nozzle
    of :func:`massflow_nozzle`: b = pr* = (2/(gamma+1))^(gamma/(gamma-1)), and C
    from equal choked flows at every upstream state,

        C rho0 p0 sqrt(T0/T) = Cd A p0 sqrt(gamma/(R T)) (2/(gamma+1))^((gamma+1)/(2(gamma-1)))
        =>  C = Cd A sqrt(gamma/(R T0)) (2/(gamma+1))^((gamma+1)/(2(gamma-1))) / rho0,

    A = pi diameter^2/4. The upstream temperature T cancels (both laws scale
    with 1/sqrt(T)), so C depends on the reference state only. With these C, b
    and m = 0.5 the ISO 6358 law (:func:`massflow_ISO_6358`) has the nozzle's
    choked flow exactly; subsonic, its elliptic curve differs from the
    nozzle's by up to 0.15 % of the choked flow (air, m = 0.5, measured).

    diameter : throat diameter [m]; Cd : discharge coefficient [-]; gamma :
    ratio of specific heats [-]; R : specific gas constant [J/(kg K)]; rho0,
    T0 : ISO 6358 reference density [kg/m^3] and temperature [K].

    Returns (C [m^3/(s Pa)], b [-]).
    """
    gamma = np.asarray(gamma, dtype=float)
    area = np.pi * np.asarray(diameter, dtype=float) ** 2 / 4.0
    choked = np.sqrt(gamma / (R * T0)) * (2.0 / (gamma + 1.0)) ** (
        (gamma + 1.0) / (2.0 * (gamma - 1.0)))
    return Cd * area * choked / rho0, critical_pressure_ratio(gamma)


def dp_at_reynolds(Re, K, rho, mu, diameter):
    """Pressure drop [Pa] at which the loss-coefficient law reaches the Reynolds
    number Re = rho v D / mu: dp = K rho v^2 / 2 with v = Re mu / (rho D).
    Used to place the laminar-like regularization band of an orifice."""
    v = Re * mu / (rho * diameter)
    return 0.5 * K * rho * v * v


def _iso_6358_phi(s, b, m, s_lam):
    """Flow fraction phi(s) of the choked flow and dphi/ds, with
    s = (1 - p_down/p_up)/(1 - b) >= 0: 1 when choked (s >= 1),
    [s (2 - s)]^m subsonic, odd cubic below s_lam."""
    s = np.asarray(s, dtype=float)
    # clipped to [s_lam, 1]: at s >= 1 (choked) u = 1, so phi = 1 and dphi = 0
    # exactly; the laminar cubic is only evaluated where some s lies below s_lam
    # (np.minimum/np.maximum: np.clip's own overhead is ~3x theirs on a few values)
    s_c = np.minimum(np.maximum(s, s_lam), 1.0)
    u = s_c * (2.0 - s_c)
    phi = u ** m
    dphi = m * u ** (m - 1.0) * (2.0 - 2.0 * s_c)
    laminar = s < s_lam
    if laminar.any():
        u_l = s_lam * (2.0 - s_lam)
        phi_l = u_l ** m
        dphi_l = m * u_l ** (m - 1.0) * (2.0 - 2.0 * s_lam)
        y_in, dy_in = _odd_cubic(s, s_lam, phi_l, dphi_l)
        phi = np.where(laminar, y_in, phi)
        dphi = np.where(laminar, dy_in, dphi)
    return phi, dphi


def massflow_ISO_6358(p_a, p_b, T, C, b, m=0.5, pr_laminar=0.999,
                      rho0=ISO_6358_RHO0, T0=ISO_6358_T0):
    """Pneumatic flow through a component rated by ISO 6358 (sonic conductance).

    With p_up the higher and p_down the lower of p_a, p_b, pr = p_down/p_up:

        mdot = C rho0 p_up sqrt(T0/T)                                pr <= b (choked)
        mdot = C rho0 p_up sqrt(T0/T) [1 - ((pr - b)/(1 - b))^2]^m    b < pr < 1

    positive from a to b. Near pr = 1 the slope in p is infinite; above
    pr_laminar the law is replaced by an odd cubic in s = (1 - pr)/(1 - b),
    matching value and slope (a laminar-like, nearly linear region), so the flow
    reverses C1-smoothly through p_a = p_b.

    ISO 6358-1:2013, Pneumatic fluid power -- Determination of flow-rate
    characteristics of components using compressible fluids; the model is
    Sanville's (1971). Valid for gases, steady flow, 0 < b < 1, 0 < m <= 1
    (m = 0.5 is the standard's elliptic law).

    p_a, p_b : absolute pressures [Pa]; T : upstream temperature [K];
    C : sonic conductance [m^3/(s Pa)]; b : critical pressure ratio [-];
    m : subsonic index [-]; pr_laminar : pressure ratio where the cubic takes
    over [-] (b < pr_laminar < 1); rho0, T0 : reference density [kg/m^3] and
    temperature [K] at which C is rated.

    Returns (mdot [kg/s], d mdot/d p_a, d mdot/d p_b).
    """
    p_a = np.asarray(p_a, dtype=float)
    p_b = np.asarray(p_b, dtype=float)
    forward = p_a >= p_b
    # every flow one way (the usual case): the same numbers without the selections
    # (arrays only: a 0-d query keeps np.where's 0-d arrays)
    ahead = forward.ndim > 0 and bool(forward.all())
    if ahead:
        p_up, p_dn = p_a, p_b
    else:
        p_up = np.where(forward, p_a, p_b)
        p_dn = np.where(forward, p_b, p_a)
    k = C * rho0 * np.sqrt(T0 / T)
    one_b = 1.0 - b
    s = (1.0 - p_dn / p_up) / one_b
    s_lam = (1.0 - pr_laminar) / one_b
    phi, dphi = _iso_6358_phi(s, b, m, s_lam)
    q = k * p_up * phi
    d_up = k * (phi + dphi * p_dn / (p_up * one_b))
    d_dn = -k * dphi / one_b
    if ahead:
        return q, d_up, d_dn
    mdot = np.where(forward, q, -q)
    dpa = np.where(forward, d_up, -d_dn)
    dpb = np.where(forward, d_dn, -d_up)
    return mdot, dpa, dpb
