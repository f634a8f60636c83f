"""Orifice and valve flow laws, vectorized, each with its derivatives.

Each law is written as mass flow from the pressures, with the square root
(or ISO 6358's root near pressure ratio 1) replaced by an odd cubic inside a
small band around zero flow. The cubic matches the exact law's value and slope
at the band edge, so the result is C1 and its slope at zero flow is finite and
non-zero: Newton neither divides by an infinite derivative nor stalls on a flat
one. The same idea as Modelica.Fluid's regularized roots, with its own formula.

The laws that a residual evaluates (the regularized root, the loss-coefficient
orifice, the critical pressure ratio, the nozzle flow factor and law, ISO
6358's flow fraction and law) are evaluated by the compiled scalar functions
of :mod:`softflow.laws.orifice`, written once there; the functions here are
thin array wrappers over them (arguments that broadcast, floats for floats).
The closed forms used once at set-up (:func:`loss_coefficient_from_discharge_coefficient`,
:func:`iso_6358_of_nozzle`'s sonic conductance, :func:`dp_at_reynolds`) stay in NumPy.

Reference implementations for the tests: ``fluids.core.dP_from_K``,
``fluids.flow_meter.flow_meter_discharge`` and ``nozzle_expansibility``, and
``fluids.compressible.P_critical_flow`` (Caleb Bell).
"""
from __future__ import annotations

import functools

import numpy as np

from .._laws import law_module
from .friction import prepared, shaped

#: ISO 6358 standard reference atmosphere (ANR): density [kg/m^3] and temperature [K].
ISO_6358_RHO0 = 1.185
ISO_6358_T0 = 293.15


compiled = functools.partial(law_module, "orifice")


def _run(loop, n_out, *args):
    """``loop`` of :mod:`softflow.laws.orifice` over ``args`` broadcast to 1-D
    float64 arrays, with ``n_out`` preallocated outputs, in the result's shape."""
    shape, args = prepared(*args)
    out = [np.empty(args[0].size) for _ in range(n_out)]
    loop(*args, *out)
    return shaped(shape, *out)


def regularized_sqrt(x, x_small):
    """sign(x)·sqrt(abs(x)), made C1 with a finite slope at x = 0; returns (y, dy/dx).

    For abs(x) >= x_small it is exact. Inside, y = x/sqrt(x_small) · (5/4 - (x/x_small)^2/4),
    the odd cubic matching value and slope at ±x_small: slope 5/(4 sqrt(x_small)) at
    zero, never below 1/(2 sqrt(x_small)), so the law stays strictly increasing.

    x : float or array
    x_small : float or array (> 0)

    Evaluated by the compiled :func:`softflow.laws.orifice.regularized_sqrt`.
    """
    return _run(compiled().regularized_sqrt_array, 2, x, x_small)


def massflow_loss_coefficient(dp, rho, K, area, dp_small):
    """Mass flow through a restriction of loss coefficient K (turbulent, Re >~ 100).

    Definition of the loss coefficient (Crane TP-410; Idelchik, Handbook of
    Hydraulic Resistance), with v = mdot/(rho·A):

        dp = K · rho · v^2 / 2   <=>   mdot = A · sqrt(2 rho dp / K)

    signed with dp, the square root regularized below abs(dp) = dp_small (see
    :func:`regularized_sqrt`). A discharge coefficient Cd is K = 1/Cd^2 (see
    :func:`loss_coefficient_from_discharge_coefficient`). Valid for liquids, and
    for gases while abs(dp) stays well below the upstream pressure (no expansion,
    no choking; use :func:`massflow_ISO_6358` beyond that).

    dp : pressure drop [Pa], rho : density [kg/m^3], K : loss coefficient [-],
    area : flow area [m^2], dp_small : regularization band [Pa]

    Returns (mdot [kg/s], d mdot/d dp, d mdot/d rho), evaluated by the compiled
    :func:`softflow.laws.orifice.massflow_loss_coefficient`.
    """
    return _run(compiled().massflow_loss_coefficient_array, 3, dp, rho, K, area, dp_small)


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
    gamma = 1.4; Anderson, Modern Compressible Flow, 3rd ed., sec. 5.4); the
    compiled :func:`softflow.laws.orifice.critical_pressure_ratio`."""
    return _run(compiled().critical_pressure_ratio_array, 1, gamma)[0]


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
    Returns (Y [-], dY/ds [-]), evaluated by the compiled
    :func:`softflow.laws.orifice.nozzle_flow_factor`.
    """
    return _run(compiled().nozzle_flow_factor_array, 2, s, gamma)


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
    :func:`regularized_sqrt` below abs(dp) = dp_small (the laminar-like band, placed
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

    Returns (mdot [kg/s], d mdot/d p_a, d mdot/d p_b), evaluated by the compiled
    :func:`softflow.laws.orifice.massflow_nozzle`.
    """
    ideal = drho_up is None
    shape, args = prepared(p_a, p_b, rho_up, rho_up if ideal else drho_up, gamma, Cd, area,
                           dp_small)
    out = [np.empty(args[0].size) for _ in range(3)]
    compiled().massflow_nozzle_array(*args, ideal, *out)
    return shaped(shape, *out)


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
    [s (2 - s)]^m subsonic, odd cubic below s_lam (``b`` is not used); the
    compiled :func:`softflow.laws.orifice.iso_6358_phi`."""
    return _run(compiled().iso_6358_phi_array, 2, s, m, s_lam)


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

    Returns (mdot [kg/s], d mdot/d p_a, d mdot/d p_b), evaluated by the compiled
    :func:`softflow.laws.orifice.massflow_iso_6358`.
    """
    return _run(compiled().massflow_iso_6358_array, 3, p_a, p_b, T, C, b, m, pr_laminar,
                rho0, T0)
