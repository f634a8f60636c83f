"""Tubes: Darcy–Weisbach with a selectable friction correlation, gas flow at
any pressure ratio (isothermal pipe flow with choking) and optional fluid
inertance."""
from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from .._laws import law_module
from ..constants import pressure_atmospheric
from ..correlations.friction import (ANALYTIC_FRICTION, TRANSITIONS, FrictionTable,
                                     compiled_kind, fRe_blended, friction_Haaland,
                                     resolve_friction, roughness_terms, transition_step)
from ..correlations.fanno import adiabatic_pipe
from ..correlations.gas_pipe import isothermal_pipe
from ..fluids.ideal import IdealGas
from .base import FLUID_PORT, Affine, LibraryComponent

if TYPE_CHECKING:
    from typing_extensions import Self

    from .._typing import Scalar
    from ..fluids.base import Fluid

_COMPRESSIBLE_MODES = ("pipe_flow", "isothermal", "mean_density")
#: groups up to this size test laminarity by a dot product (single-threaded in BLAS)
_DOT_MAX = 1000


def set_tube_geometry(comp, fluid, length, diameter, roughness, Re_laminar, Re_turbulent):
    """Checked SI tube parameters on ``comp`` (shared by tubes and tube-like valves)."""
    comp.fluid = comp._check_fluid(fluid)
    comp.length = comp._si(length, "m", "length", positive=True, size=True)
    comp.diameter = comp._si(diameter, "m", "diameter", positive=True, size=True)
    comp.roughness = comp._si(roughness, "m", "roughness", nonnegative=True)
    comp.Re_laminar = comp._si(Re_laminar, "", "Re_laminar", positive=True)
    comp.Re_turbulent = comp._si(Re_turbulent, "", "Re_turbulent", positive=True)
    if comp.Re_turbulent <= comp.Re_laminar:
        raise ValueError(f"{comp.describe()}: Re_turbulent ({comp.Re_turbulent}) must exceed "
                         f"Re_laminar ({comp.Re_laminar})")


def laminar_conductance(fluid, length, diameter, pressure):
    """Hagen–Poiseuille mass conductance [kg/(s Pa)] of circular tubes, mdot / (p_a -
    p_b) = rho pi D^4 / (128 mu L), with rho and mu of ``fluid`` at ``pressure``
    [Pa] (arrays broadcast). At the higher of a tube's end pressures it bounds
    the tube's flow per pascal of difference from above: turbulence, the
    gas's acceleration and entry, and choking only lower the flow at a given
    difference, and a gas is densest at the higher end. A validation helper (a
    tube whose flow is negligible, :mod:`softflow.solve.simulation`), not the
    tube's law."""
    p = np.asarray(pressure, dtype=float)
    d = np.asarray(diameter, dtype=float)
    return (np.asarray(fluid.density(p), dtype=float) * np.pi * d ** 4
            / (128.0 * np.asarray(fluid.viscosity(p), dtype=float)
               * np.asarray(length, dtype=float)))


def set_tube_coefficients(P):
    """Laminar/turbulent law coefficients of a group of tubes (or tube-like valves)
    on its Params namespace: Re = |mdot| re_per_mf, dp = c_mu/rho (f Re) mdot,
    with mu at 1 atm; the minor losses K of tubes that state them (``P.K``) as
    ``P.kre`` = K D / L, the term kre·Re they add to f Re
    (:func:`softflow.laws.tube.friction_law`), zero for the tube-like valves,
    and ``P.minor``, whether any is nonzero."""
    P.area = np.pi * P.diameter ** 2 / 4.0
    P.eD = P.roughness / P.diameter
    P.mu = P.fluid.viscosity(np.full(P.n, pressure_atmospheric))
    P.Re_lo = float(P.Re_laminar[0])
    P.Re_hi = float(P.Re_turbulent[0])
    P.re_per_mf = P.diameter / (P.mu * P.area)
    P.c_mu = P.mu * P.length / (2.0 * P.area * P.diameter ** 2)
    K = getattr(P, "K", None)
    P.kre = np.zeros(P.n) if K is None else K * P.diameter / P.length
    P.minor = bool(np.any(P.kre > 0.0))



#: Parameters of the tube law whose derivatives :func:`tube_law_derivative` states.
TUBE_GEOMETRY = ("length", "diameter", "roughness")


def friction_roughness_derivative(P, Re):
    """d(f·Re)/d(roughness/diameter) of the group's blended friction law at Re:
    zero where laminar, w(Re)·Re·df/d(eD) of the turbulent correlation above
    Re_laminar (df/d(eD) by a central difference of the correlation, a pure
    function of (Re, eD); relative step 1e-4, one-sided at eD = 0)."""
    turbulent = P.turbulent if hasattr(P, "turbulent") else friction_Haaland
    if turbulent is None or Re.max(initial=0.0) <= P.Re_lo:
        return np.zeros_like(Re)
    w, _ = transition_step(Re, P.Re_lo, P.Re_hi, _transition(P))
    Ret = np.maximum(Re, P.Re_lo)
    h = 1e-4 * np.maximum(P.eD, 1e-6)
    lo = np.maximum(P.eD - h, 0.0)
    df = ((turbulent(Ret, P.eD + h, derivative=False)[0]
           - turbulent(Ret, lo, derivative=False)[0]) / (P.eD + h - lo))
    return w * Ret * df


#: The laminar-turbulent blend's bounds, whose derivatives :func:`friction_bound_derivative` states.
BLEND_BOUNDS = ("Re_laminar", "Re_turbulent")


def friction_bound_derivative(P, Re, name):
    """d(f·Re)/d(Re_laminar) or d/d(Re_turbulent) of the group's blended friction
    law (:func:`softflow.correlations.friction.fRe_blended`) at Re.

    f·Re = 64 + w(s)·(phi_t(Re) - 64), w = 3s^2 - 2s^3, s = (Re - lo)/(hi - lo)
    clipped to [0, 1], so with dw/dRe = 6 s (1 - s)/(hi - lo):
    dw/dlo = -(1 - s) dw/dRe, dw/dhi = -s dw/dRe, and the turbulent law itself
    does not move (it enters only where Re > lo). Zero where laminar (w = 0) or
    fully turbulent (w = 1), and for a 'laminar' tube."""
    turbulent = P.turbulent if hasattr(P, "turbulent") else friction_Haaland
    if turbulent is None or Re.max(initial=0.0) <= P.Re_lo:
        return np.zeros_like(Re)
    lo, hi = P.Re_lo, P.Re_hi
    s = np.minimum(np.maximum((Re - lo) / (hi - lo), 0.0), 1.0)
    dw = transition_step(Re, lo, hi, _transition(P))[1]
    Ret = np.maximum(Re, lo)
    phit = turbulent(Ret, P.eD, derivative=False)[0] * Ret
    dw_dbound = -dw * ((1.0 - s) if name == "Re_laminar" else s)
    return dw_dbound * (phit - 64.0)


def tube_law_derivative(P, name, dp, mf_d_mf, d_eD):
    """d(dp)/d theta of a friction pressure drop dp = c(L, D)·phi(Re, eD)·mdot with
    c ∝ L/D^4, Re ∝ 1/D and eD = roughness/D, for theta in :data:`TUBE_GEOMETRY`,
    from dp, mdot·d(dp)/d(mdot) and d(dp)/d(eD) at fixed geometry:
    dp/L; -(3 dp + mdot·d(dp)/d(mdot) + eD·d(dp)/d(eD))/D; d(dp)/d(eD)/D."""
    if name == "length":
        return dp / P.length
    if name == "diameter":
        return -(3.0 * dp + mf_d_mf + P.eD * d_eD) / P.diameter
    return d_eD / P.diameter


def _transition(P):
    """The group's laminar-turbulent transition ('smooth' for the tube-like
    valves, which have no option)."""
    return getattr(P, "transition", "smooth")


def viscosity_log_slope(P, pm, mu):
    """d(mu)/dp / mu of the group's fluid at pressures pm (viscosity mu there), by a
    central difference (the fluid protocol has no mu_dp), kept inside the
    fluid's valid range (a table ends at its last point)."""
    lo, hi = getattr(P.fluid, "p_range", (0.0, np.inf))
    p1 = np.maximum(pm * (1 - 1e-6), lo)
    p2 = np.minimum(pm * (1 + 1e-6), hi)
    return (P.fluid.viscosity(p2) - P.fluid.viscosity(p1)) / (p2 - p1) / mu


def _friction_term(P, pa, mf, pb, jac):
    """The friction term Phi = c_mu (f Re) mf of a group of tubes (f Re by the
    group's blended law plus its minor losses kre·Re, as
    :func:`softflow.laws.tube.friction_law`; for a real fluid mu at the mean
    pressure, else at 1 atm), with the pieces its derivatives need: (Phi, pm,
    c_mu, mu_ratio, Re, f Re, d(f Re)/dRe)."""
    pm = 0.5 * (pa + pb)
    re_per_mf, c_mu, mu_ratio = P.re_per_mf, P.c_mu, None
    if P.variable_mu:
        mu_ratio = P.fluid.viscosity(pm) / P.mu       # relative to mu at 1 atm
        re_per_mf, c_mu = re_per_mf / mu_ratio, c_mu * mu_ratio
    Re = np.abs(mf) * re_per_mf
    if P.turbulent is None or Re.max(initial=0.0) <= P.Re_lo:
        phi, dphi = 64.0, 0.0         # all laminar: f Re = 64 exactly
    else:
        phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi, P.turbulent, derivative=jac,
                                terms=P.friction_terms, transition=_transition(P))
    if P.minor:
        phi, dphi = phi + P.kre * Re, (None if dphi is None else dphi + P.kre)
    return c_mu * phi * mf, pm, c_mu, mu_ratio, Re, phi, dphi


def _isothermal_residual(P, pa, mf, pb, Phi, jac):
    """R of :func:`softflow.correlations.gas_pipe.isothermal_pipe` for a group
    of gas tubes (or tube-like valves) with friction term Phi, c^2 = p/rho at
    the mean pressure (R T for an ideal gas); returns (R's tuple, rho(pm) or
    None for an ideal gas, c^2)."""
    if P.c2 is None:
        pm = 0.5 * (pa + pb)
        rho = P.fluid.density(pm)
        c2 = pm / rho
    else:       # an ideal gas: p/rho = R T, whatever the pressure
        rho, c2 = None, P.c2
    return isothermal_pipe(pa, mf, pb, P.area, c2, Phi, jac, c2_partial=rho is not None), rho, c2


def isothermal_drop(P, pa, mf, pb, Phi, Phi_mf, Phi_pm, jac):
    """The isothermal pipe-flow law of a gas (:mod:`softflow.correlations.gas_pipe`)
    in pressure-drop form, dp = p_a - p_b - R, so that a tube's residual
    (p_a - p_b) - dp is R itself, and its partials in p_a, mf, p_b. ``Phi`` is
    the friction term c_mu (f Re) mf (a Tesla valve's times its direction
    factor), ``Phi_mf`` its derivative in mf, ``Phi_pm`` in the mean pressure
    (None where mu is constant). The one law of gas tubes, Tesla valves and
    open snapping valves."""
    (R, R_pa, R_mf, R_pb, R_c2, R_phi, _), rho, c2 = _isothermal_residual(
        P, pa, mf, pb, Phi, jac)
    dp = (pa - pb) - R
    if not jac:
        return dp, None, None, None
    # through the mean pressure: c^2 = pm/rho(pm), and Phi's viscosity for real fluids
    if rho is None:
        R_pm = 0.0
    else:
        pm = 0.5 * (pa + pb)
        R_pm = R_c2 * (1.0 - c2 * P.fluid.density_dp(pm)) / rho
    if Phi_pm is not None:
        R_pm = R_pm + R_phi * Phi_pm
    return dp, 1.0 - R_pa - 0.5 * R_pm, -(R_mf + R_phi * Phi_mf), -1.0 - R_pb - 0.5 * R_pm


def isothermal_drop_parameter_derivative(P, V, Phi, Phi_theta, name, T_up=None):
    """d(p_a - p_b required)/d theta of :func:`isothermal_drop` (or, given the
    upstream temperature ``T_up``, of :func:`adiabatic_drop`) from d(Phi)/d theta
    (``Phi_theta``) and, for the diameter, the flux G = mf/A of the acceleration
    terms: R depends on A only through G, dR/dA = -(mf/A) dR/dmf, dA/dD = 2A/D."""
    pa, mf, pb = V[:, 0], V[:, 1], V[:, 2]
    if T_up is None:
        (_, _, R_mf, _, _, R_phi, _), _, _ = _isothermal_residual(P, pa, mf, pb, Phi, True)
    else:
        _, _, R_mf, _, _, R_phi, _ = adiabatic_pipe(pa, mf, pb, T_up, P.area, P.R_gas,
                                                    P.gamma, Phi, True)
    d = -R_phi * Phi_theta
    return d + 2.0 * mf * R_mf / P.diameter if name == "diameter" else d


def adiabatic_drop(P, pa, mf, pb, T_up, Phi, Phi_mf, jac):
    """The adiabatic (Fanno) pipe-flow law of an ideal gas in a thermal scene
    (:mod:`softflow.correlations.fanno`) in pressure-drop form, dp = p_a - p_b - R,
    with the upstream (stagnation) temperature ``T_up`` and the friction term
    ``Phi`` (its derivative in mf ``Phi_mf``); returns dp and its partials in
    p_a, mf, p_b and T_up (None without ``jac``). The thermal law of gas tubes
    and Tesla valves."""
    R, R_pa, R_mf, R_pb, R_T, R_phi, _ = adiabatic_pipe(pa, mf, pb, T_up, P.area, P.R_gas,
                                                        P.gamma, Phi, jac)
    dp = (pa - pb) - R
    if not jac:
        return dp, None, None, None, None
    return dp, 1.0 - R_pa, -(R_mf + R_phi * Phi_mf), -1.0 - R_pb, -R_T


def gas_pipe_drop(P, pa, mf, pb, jac):
    """:func:`isothermal_drop` of a group of gas tubes, with their friction term;
    for an ideal gas with an analytic friction correlation (``P.kind``, see
    :func:`set_compiled_law`) in one compiled pass over the group
    (:func:`softflow.laws.tube.isothermal_drop`, the same laws)."""
    if P.kind is not None:
        n = P.n
        out = np.empty((4, n))
        _tube_laws().isothermal_drop_array(P.kind, P.Re_lo, P.Re_hi, pa, mf, pb, P.re_per_mf,
                                           P.c_mu, P.eD, P.kind_terms, P.area, P.c2, P.kre,
                                           *out)
        return (out[0], out[1], out[2], out[3]) if jac else (out[0], None, None, None)
    Phi, pm, c_mu, mu_ratio, Re, phi, dphi = _friction_term(P, pa, mf, pb, jac)
    if not jac:
        return isothermal_drop(P, pa, mf, pb, Phi, None, None, False)
    Phi_pm = (c_mu * mf * (phi - Re * dphi) * viscosity_log_slope(P, pm, mu_ratio * P.mu)
              if P.variable_mu else None)
    return isothermal_drop(P, pa, mf, pb, Phi, c_mu * (phi + Re * dphi), Phi_pm, True)


def friction_parameter_derivative(P, V, name):
    """(Phi, d(Phi)/d theta, the mean pressure) of a group of tubes' friction term
    Phi = c_mu (f Re) mf, for a parameter of :data:`TUBE_GEOMETRY`,
    :data:`BLEND_BOUNDS` or the minor-loss coefficient ``K``: the friction part
    scales as a Darcy pressure drop does (c_mu ∝ L/D^4, Re ∝ 1/D, eD =
    roughness/D), the minor losses' part Phi_K = K mf |mf| / (2 A^2) as D^-4
    and not with L, so both gas laws and the mean-density law take their
    parameter derivatives from it."""
    pa, mf, pb = V[:, 0], V[:, 1], V[:, 2]
    Phi, pm, c_mu, _, Re, phi, dphi = _friction_term(P, pa, mf, pb, True)
    if name in BLEND_BOUNDS:
        return Phi, c_mu * mf * friction_bound_derivative(P, Re, name), pm
    # the minor losses' share of Phi (kre Re of f Re) and of mf dPhi/dmf (2 kre Re)
    Phi_K = c_mu * P.kre * Re * mf
    if name == "K":
        return Phi, c_mu * (P.diameter / P.length) * Re * mf, pm
    d_eD = c_mu * mf * friction_roughness_derivative(P, Re)
    d = tube_law_derivative(P, name, Phi - Phi_K, mf * c_mu * (phi + Re * dphi) - 2.0 * Phi_K,
                            d_eD)
    if name == "diameter":
        d = d - 4.0 * Phi_K / P.diameter
    return Phi, d, pm


def gas_pipe_parameter_derivative(P, V, name, T_up=None):
    """d(p_a - p_b required)/d theta of a gas tube's :func:`gas_pipe_drop` (or,
    given ``T_up``, :func:`adiabatic_drop`) for a parameter of
    :data:`TUBE_GEOMETRY` or :data:`BLEND_BOUNDS`."""
    Phi, Phi_theta, _ = friction_parameter_derivative(P, V, name)
    return isothermal_drop_parameter_derivative(P, V, Phi, Phi_theta, name, T_up)


def set_compiled_law(P, own_law=True):
    """Whether the group's law runs as one compiled pass (:func:`gas_pipe_drop`,
    :meth:`CircularTube.pressure_drop`, :meth:`CircularTube.residual`):
    ``P.kind``, the compiled id of its friction correlation, for an ideal gas
    on the isothermal pipe-flow law or the mean-density law, or a liquid of
    constant properties, each with a constant viscosity and an analytic
    correlation, else None; ``P.kind_terms`` what the correlation takes from
    the roughness (Haaland's term, or eD); ``P.kind_c`` the law's coefficient
    (c_mu for the gas, c_mu/rho for the liquid) and ``P.kind_c2`` the law
    (:mod:`softflow.laws.tube`): p/rho of the gas on the pipe-flow law, 0 for
    the liquid, minus R T of the gas on the mean-density law. None where the
    class has a pressure-drop law of its own (``own_law`` False)."""
    P.kind = None
    if not own_law:
        return
    if P.isothermal and P.c2 is not None and not P.variable_mu:
        P.kind_c, P.kind_c2 = P.c_mu, P.c2
    elif not P.isothermal and getattr(P, "c_per_rho", None) is not None:
        P.kind_c, P.kind_c2 = P.c_per_rho, 0.0
    elif (not P.isothermal and P.compressible and isinstance(P.fluid, IdealGas)
          and not P.variable_mu):
        P.kind_c, P.kind_c2 = P.c_mu, -float(P.fluid.R * P.fluid.temperature)
    else:
        return
    P.kind = compiled_kind(P.turbulent, _transition(P))
    P.kind_terms = P.eD if P.friction_terms is None else P.friction_terms


_NO_JACOBIAN = np.empty((0, 5))


_tube_laws = partial(law_module, "tube")


def set_isothermal_law(P, isothermal, adiabatic=True):
    """The group's gas law on its Params: ``P.isothermal`` (the pipe-flow law),
    ``P.c2``, p/rho where it is a constant (R T of an ideal gas; else None,
    taken at the mean pressure), and for an ideal gas whose law is adiabatic in
    a thermal scene (``adiabatic``) its R and gamma (``P.R_gas``, ``P.gamma``;
    None otherwise), which that law takes."""
    P.isothermal = bool(isothermal)
    ideal = P.isothermal and isinstance(P.fluid, IdealGas)
    P.c2 = float(P.fluid.R * P.fluid.temperature) if ideal else None
    P.R_gas = float(P.fluid.R) if ideal and adiabatic else None
    P.gamma = float(P.fluid.gamma0) if ideal and adiabatic else None


class CircularTube(LibraryComponent):
    """Straight circular tube between terminals ``a`` and ``b``.

    Darcy–Weisbach pressure drop with the Darcy friction factor from
    Hagen–Poiseuille (f = 64/Re) for laminar flow and a turbulent correlation
    (Haaland by default, as in the FONS paper), blended C1-smoothly between
    Re_laminar and Re_turbulent:

        p_a - p_b = (f Re) · mu L / (2 rho A D^2) · mdot,   Re = ``|mdot|`` D / (mu A)

    where mdot is the mass flow entering at ``a``. Mass is conserved:
    mdot_a + mdot_b = 0. Writing the law with f·Re keeps it linear in mdot at
    zero flow, so its derivative never vanishes there.

    For a gas (``fluid.compressible``) the default, ``compressible='pipe_flow'``,
    is, in an isothermal scene, isothermal pipe flow at any pressure ratio
    (:mod:`softflow.correlations.gas_pipe`): the node pressures are stagnation
    pressures; the gas accelerates from rest into the tube (c^2 ln(p0/p1) =
    u1^2/2, c^2 = p/rho, R T for an ideal gas), then flows with friction and
    acceleration (Crane TP-410; ``fluids.compressible.isothermal_gas``)

        p1^2 - p2^2 = G^2 c^2 (f L/D + 2 ln(p1/p2)),   G = mdot/A,

    and chokes where its exit velocity reaches c (Mach 1/sqrt(gamma), 0.845
    for air): the exit pressure is then G c, and a lower downstream pressure
    passes no more flow. At low Mach it is the Darcy law above with rho at the
    mean pressure plus the dynamic pressure the flow carries out of the tube,
    rho u^2/2 (lost in the volume downstream), and O(M^2) acceleration terms:
    where f L/D >> 1 the flow is the Darcy law's to O(M^2), a short, wide tube's
    differs at any Mach (10 cm x 4 mm at 20 Pa: -37 %). For a real fluid (level
    ``table`` or ``eos``) c^2 = p/rho and mu are taken at the mean pressure (an
    ideal gas with the compressibility of the mean pressure); at level
    ``ideal`` mu is the fluid's constant. ``compressible='mean_density'`` keeps
    the Darcy law with rho at the mean pressure and no acceleration: cheaper,
    valid below about Mach 0.3 (a validity warning past it) and refused past
    the choking Mach, where it over-predicts the flow. For liquids the option
    has no effect. In a thermal scene (``thermal='adiabatic'`` or
    ``'heat_transfer'``) ``'pipe_flow'`` is, for an ideal gas, adiabatic pipe
    flow (:mod:`softflow.correlations.fanno`): isentropic entry from the
    upstream stagnation state (p0, T0 of the node), Fanno flow with the same
    friction term, choked at exit Mach 1, the stagnation enthalpy carried
    through; for a real fluid (``table``, ``eos``), with
    ``compressible='isothermal'`` (isothermal pipe flow in every scene) and
    the mean-density law, the isothermal law scaled by the upstream temperature (see
    :mod:`softflow.components.thermal`).

    With ``inertance=True`` the constructor returns an
    :class:`InertialCircularTube`, which adds the fluid's inertia as a state.

    Parameters
    ----------
    label : str
    fluid : Fluid
    length : float [m]
    diameter : float [m]
        Inner diameter.
    roughness : float [m], default 1.5e-6
        Absolute wall roughness (drawn tubing).
    Re_laminar, Re_turbulent : float [-], default 2300, 4000
        Bounds of the laminar–turbulent blend.
    friction : str, default 'Haaland'
        Turbulent friction correlation: 'Haaland', 'Colebrook' (solved
        exactly), 'Churchill' (1977), 'Swamee-Jain' (1976) are evaluated in
        closed form; any other name of ``fluids.friction.friction_factor``'s
        methods (e.g. 'Serghides_2') is tabulated once as a spline in Re.
        'laminar' uses Hagen–Poiseuille at every Re.
    compressible : {'pipe_flow', 'isothermal', 'mean_density'}, default 'pipe_flow'
        Gas model (see above): pipe flow with entry, acceleration and choking,
        isothermal in isothermal scenes and adiabatic in thermal scenes of an
        ideal gas ('pipe_flow'), or isothermal in every scene ('isothermal'),
        or the low-Mach mean-density Darcy law ('mean_density').
    inertance : bool, default False
        Add the fluid inertance L/A · d(mdot)/dt (rho L / A per volume flow)
        to the pressure drop, with the mass flow as a state.
    transition : {'smooth', 'linear'}, default 'smooth'
        How the laminar and turbulent laws are weighed between Re_laminar and
        Re_turbulent: a C1 smoothstep in Re (the default), or linearly in Re,
        with kinks at both bounds ('linear': fonsim 0.6's transition, which
        ``softflow.fons`` selects; up to 2.6 % of the flow apart in the band).
    K : float [-], default 0
        Minor losses: the sum of the loss coefficients of the tube's entrance,
        bends and fittings, each referred to the velocity in the bore (a
        sharp-edged entrance about 0.5, a well-rounded one 0.04; Crane
        TP-410, Idelchik). K is added to f L/D in every law (the Darcy law of
        a liquid gains K rho u^2/2; the gas laws' friction term K G^2/2, the
        practice of Crane TP-410 for compressible flow), with K constant in
        Re (loss coefficients grow at low Reynolds numbers: below ~10^3 take
        K from data at the flow's Re). Leave out the exit's loss for a gas
        with the pipe-flow law, which already loses the exit's dynamic
        pressure in the volume downstream; the liquid's Darcy law has no
        entrance or exit loss of its own (an exit into a volume is K = 1).
    """

    terminal_spec = (("a", FLUID_PORT), ("b", FLUID_PORT))
    param_names = ("length", "diameter", "roughness", "Re_laminar", "Re_turbulent", "K")
    # V = [p_a, mf_a, p_b, mf_b]; eq 0: mass balance, eq 1: pressure drop
    jac_pattern = ((0, 1), (0, 3), (1, 0), (1, 1), (1, 2))

    def __new__(cls, *args: Any, inertance: bool = False, **kwargs: Any) -> Self:
        if inertance and cls is CircularTube:
            cls = InertialCircularTube  # type: ignore[assignment]
        return super().__new__(cls)

    def __init__(self, label: str, fluid: Fluid, length: Scalar, diameter: Scalar,
                 roughness: Scalar = 1.5e-6, Re_laminar: float = 2300.0,
                 Re_turbulent: float = 4000.0, *, friction: str = "Haaland",
                 compressible: str = "pipe_flow", inertance: bool = False,
                 K: float = 0.0, transition: str = "smooth") -> None:
        super().__init__(label, fluid=None)
        set_tube_geometry(self, fluid, length, diameter, roughness, Re_laminar, Re_turbulent)
        self.K = self._si(K, "", "K", nonnegative=True)
        if transition not in TRANSITIONS:
            raise ValueError(f"{self.describe()}: transition must be one of {TRANSITIONS}, "
                             f"got {transition!r}")
        self.transition = transition
        try:
            self.friction = resolve_friction(friction)
        except KeyError as err:
            raise ValueError(f"{self.describe()}: friction: {err.args[0]}") from None
        mode = compressible.strip().replace("-", "_").lower() if isinstance(compressible, str) \
            else compressible
        if mode not in _COMPRESSIBLE_MODES:
            raise ValueError(f"{self.describe()}: compressible must be one of "
                             f"{_COMPRESSIBLE_MODES}, got {compressible!r}")
        self.compressible = mode
        self.inertance = isinstance(self, InertialCircularTube)
        if inertance and not self.inertance:
            raise ValueError(f"{self.describe()}: inertance=True needs the CircularTube "
                             "class itself (or InertialCircularTube)")

    def group_key(self):
        # one blend range, correlation and gas model per group: the kernel makes one call each
        mode = self.compressible if self.fluid.compressible else "mean_density"
        return (type(self), id(self.fluid), self.Re_laminar, self.Re_turbulent, self.friction,
                mode, self.transition)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        first = P.components[0]
        P.transition = first.transition
        set_tube_coefficients(P)
        P.compressible = P.fluid.compressible
        # real-fluid levels: viscosity at the tube's mean pressure (air at 15 MPa
        # is 20 % more viscous than at 1 atm); the ideal level keeps it constant
        P.variable_mu = getattr(P.fluid, "level", "ideal") != "ideal"
        set_isothermal_law(P, P.compressible and first.compressible in ("pipe_flow", "isothermal"),
                           adiabatic=first.compressible == "pipe_flow")
        P.length_per_area = P.length / P.area
        P.c_per_rho = (None if P.compressible or P.variable_mu
                       else P.c_mu / P.fluid.rho)
        P.c64_per_rho = None if P.c_per_rho is None else P.c_per_rho * 64.0
        # a liquid at constant properties in laminar flow: both equations are
        # linear in V = [p_a, mf_a, p_b, mf_b], F = V @ lin_map (a single tube:
        # one product, 0.3 us against 2.2 us for the general path, measured)
        P.lin_map = None
        # (not for a subclass with its own pressure-drop law)
        if (P.c_per_rho is not None and not P.isothermal and not P.minor
                and cls.pressure_drop.__func__ is CircularTube.pressure_drop.__func__):
            P.lin_map = np.array([[0.0, 1.0], [1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])
            P.lam_map = P.lin_map.copy()
            P.lam_map[1, 1] = -P.c64_per_rho[0]
            P.re0 = float(P.re_per_mf[0])
        name = first.friction
        if name == "laminar":
            P.turbulent = None
        elif name in ANALYTIC_FRICTION:
            P.turbulent = ANALYTIC_FRICTION[name]
        else:
            try:
                P.turbulent = FrictionTable(name, P.eD, Re_min=P.Re_lo)
            except ValueError as err:
                labels = ", ".join(repr(c.label) for c in P.components)
                raise ValueError(f"CircularTube {labels}: friction: {err}") from None
        # what the turbulent law computes from the roughness alone, once per group
        # (make_params runs again for a run that changes a roughness or diameter)
        P.friction_terms = roughness_terms(P.turbulent, P.eD)
        set_compiled_law(P, own_law=cls._own_law())
        return P

    @classmethod
    def pressure_drop(cls, P, pa, mf, pb, jac):
        """p_a - p_b required by the flow mf entering at ``a`` and its partial
        derivatives in p_a, mf, p_b (None without ``jac``): the Darcy law at the
        mean density, or for a gas with the pipe-flow law (the default) the
        isothermal pipe flow of :func:`gas_pipe_drop` (entry, acceleration,
        choking), as p_a - p_b minus its residual. A liquid of constant
        properties, or an ideal gas on the mean-density law, with an analytic
        correlation (``P.kind``) runs as one compiled pass
        (:func:`softflow.laws.tube.tube_drop`)."""
        if P.isothermal:
            return gas_pipe_drop(P, pa, mf, pb, jac)
        if P.kind is not None:
            if P.kind_c2 == 0.0:
                dp, d_mf = np.empty(P.n), np.empty(P.n)
                _tube_laws().darcy_drop_array(P.kind, P.Re_lo, P.Re_hi, mf, P.re_per_mf,
                                              P.kind_c, P.eD, P.kind_terms, P.kre, dp, d_mf)
                return (dp, 0.0, d_mf, 0.0) if jac else (dp, None, None, None)
            out = np.empty((4, P.n))
            n1 = np.ones(P.n)
            _tube_laws().tube_drop_array(P.kind, P.Re_lo, P.Re_hi, pa * n1, mf * n1, pb * n1,
                                         P.re_per_mf, P.kind_c, P.eD, P.kind_terms, P.area,
                                         P.kind_c2, P.kre, *out)
            return tuple(out) if jac else (out[0], None, None, None)
        if P.compressible or P.variable_mu:
            pm = 0.5 * (pa + pb)
        if P.compressible:
            rho = P.fluid.density(pm)
        else:
            rho = P.fluid.rho
        re_per_mf, c_mu = P.re_per_mf, P.c_mu
        if P.variable_mu:
            mu_ratio = P.fluid.viscosity(pm) / P.mu       # relative to mu at 1 atm
            re_per_mf, c_mu = re_per_mf / mu_ratio, c_mu * mu_ratio
        abs_mf = abs(mf)        # (arrays and scalars: see residual)
        # all laminar: f Re = 64 exactly. On small groups the sum of the Reynolds
        # numbers, which bounds the largest, is one dot product (~0.3 us against
        # ~0.8 us for a max); the max decides when the sum exceeds Re_lo. Large
        # groups skip the dot: OpenBLAS threads it, which is slow on a loaded machine.
        # One tube compares its Reynolds number itself
        if P.minor:
            laminar = False      # f Re = 64 + kre Re: not the constant below
            Re = abs_mf * re_per_mf
        elif P.turbulent is None:
            laminar = True
        elif P.n == 1:
            Re = abs_mf * re_per_mf
            laminar = bool(Re <= P.Re_lo)
        else:
            laminar = P.n <= _DOT_MAX and abs_mf.dot(re_per_mf) <= P.Re_lo
            if not laminar:
                Re = abs_mf * re_per_mf
                laminar = Re.max() <= P.Re_lo
        if laminar:
            phi, dphi = 64.0, None
        elif P.turbulent is None:         # 'laminar' with minor losses
            phi, dphi = 64.0 + P.kre * Re, P.kre
        else:
            # without jac, the value alone (the same arithmetic)
            phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi, P.turbulent, derivative=jac,
                                    terms=P.friction_terms, transition=P.transition)
            if P.minor:
                phi, dphi = phi + P.kre * Re, (0.0 if dphi is None else dphi) + P.kre
        # a liquid at constant viscosity: c_mu / rho is a constant of the group,
        # and so is c·64 when all flow is laminar (the same product, made once)
        c = P.c_per_rho if P.c_per_rho is not None else c_mu / rho
        c_phi = P.c64_per_rho if laminar and P.c_per_rho is not None else c * phi
        dp = c_phi * mf
        if not jac:
            return dp, None, None, None
        d_mf = c_phi if dphi is None else c * (phi + Re * dphi)
        if P.compressible:
            # dp ∝ 1/rho(p_mean)
            d_pm = -dp / rho * P.fluid.density_dp(pm) * 0.5
        else:
            d_pm = 0.0
        if P.variable_mu:
            phi_less = phi if dphi is None else phi - Re * dphi
            d_pm = d_pm + 0.5 * c * mf * phi_less * viscosity_log_slope(P, pm, mu_ratio * P.mu)
        return dp, d_pm, d_mf, d_pm

    @classmethod
    def thermal_drop(cls, P, pa, mf, pb, T_up, jac):
        """In a thermal scene: p_a - p_b required and its partials in p_a, mf,
        p_b and the upstream (stagnation) temperature T_up, for an ideal gas with
        the pipe-flow law the adiabatic (Fanno) one (:func:`adiabatic_drop`);
        None for the other laws, which the thermal variant scales by T_up/T_ref
        (:mod:`softflow.components.thermal`)."""
        if P.R_gas is None or not cls._own_law():
            return None
        if P.kind is not None:
            # in one compiled pass (laws.tube.adiabatic_drop_array; set_compiled_law)
            out = np.empty((5, P.n))
            _tube_laws().adiabatic_drop_array(P.kind, P.Re_lo, P.Re_hi, pa, mf, pb, T_up,
                                              P.re_per_mf, P.c_mu, P.eD, P.kind_terms, P.area,
                                              P.R_gas, P.gamma, P.kre, *out)
            return tuple(out) if jac else (out[0], None, None, None, None)
        Phi, _, c_mu, _, Re, phi, dphi = _friction_term(P, pa, mf, pb, jac)
        return adiabatic_drop(P, pa, mf, pb, T_up, Phi,
                              c_mu * (phi + Re * dphi) if jac else None, jac)

    @classmethod
    def _own_law(cls):
        """Whether the class keeps CircularTube's pressure-drop law (a subclass
        with a law of its own keeps it in thermal scenes too, scaled)."""
        return cls.pressure_drop.__func__ is CircularTube.pressure_drop.__func__

    @classmethod
    def thermal_drop_parameter_derivative(cls, P, V, T_up, name):
        """d(p_a - p_b required)/d theta of :meth:`thermal_drop`; None where that
        law is not the adiabatic one or states no derivative for ``name``."""
        if P.R_gas is None or not cls._own_law() or not cls._has_derivative(P, name):
            return None
        return gas_pipe_parameter_derivative(P, V, name, T_up)

    @classmethod
    def _laminar(cls, P, V):
        """Every tube of the group below Re_laminar (a cheap test: on small
        groups the sum of the Reynolds numbers bounds the largest)."""
        if P.n == 1:
            return abs(V[0, 1]) * P.re0 <= P.Re_lo
        return P.n <= _DOT_MAX and np.abs(V[:, 1]).dot(P.re_per_mf) <= P.Re_lo

    @classmethod
    def affine(cls, P):
        # a constant-property liquid in laminar flow (see make_params); only for
        # this kernel, not for subclasses that replace it
        if P.lin_map is None or cls.residual.__func__ is not CircularTube.residual.__func__:
            return None
        coef = np.empty((P.n, 2, 4))
        coef[:] = P.lin_map.T
        coef[:, 1, 1] = -P.c64_per_rho
        return Affine(coef, valid=None if P.turbulent is None else partial(cls._laminar, P))

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if P.lin_map is not None and not jac:
            if P.turbulent is None or cls._laminar(P, V):
                if P.n == 1:
                    return V.dot(P.lam_map), None
                F = V.dot(P.lin_map)
                F[:, 1] -= P.c64_per_rho * V[:, 1]
                return F, None
        if P.kind is not None:
            # the law in one compiled pass (set_compiled_law)
            F = np.empty((P.n, 2))
            J = np.empty((P.n, 5)) if jac else _NO_JACOBIAN
            _tube_laws().residual(P.kind, P.Re_lo, P.Re_hi, V, P.re_per_mf, P.kind_c, P.eD,
                                  P.kind_terms, P.area, P.kind_c2, P.kre, F, J, jac)
            return F, (J if jac else None)
        pa, mfa, pb, mfb = V[:, 0], V[:, 1], V[:, 2], V[:, 3]
        dp, d_pa, d_mf, d_pb = cls.pressure_drop(P, pa, mfa, pb, jac)
        F = np.empty((P.n, 2))
        F[:, 0] = mfa + mfb
        F[:, 1] = (pa - pb) - dp
        if not jac:
            return F, None
        J = np.empty((P.n, 5))
        J[:, 0] = 1.0
        J[:, 1] = 1.0
        J[:, 2] = 1.0 - d_pa
        J[:, 3] = -d_mf
        J[:, 4] = -1.0 - d_pb
        return F, J


    @staticmethod
    def _has_derivative(P, name):
        """Whether the law states d/d ``name``: the blend's bounds, the minor
        losses K, and the geometry where the friction correlation is analytic
        (a tabulated one is made for the roughness; its table starts at
        Re_laminar, which the bounds' derivative leaves out: the table
        interpolates the same correlation)."""
        return name in BLEND_BOUNDS or name == "K" or (
            name in TUBE_GEOMETRY and not isinstance(P.turbulent, FrictionTable))

    @classmethod
    def drop_parameter_derivative(cls, P, V, name):
        """d(p_a - p_b required)/d theta of the group's pressure-drop law for a
        parameter of :data:`TUBE_GEOMETRY`, :data:`BLEND_BOUNDS` (each instance's
        own bound moved: its row depends on its own law alone) or the minor
        losses ``K``; None for others (see :meth:`_has_derivative`)."""
        if not cls._has_derivative(P, name):
            return None
        if P.isothermal:
            return gas_pipe_parameter_derivative(P, V, name)
        # dp = Phi / rho, rho at the mean pressure for a gas
        _, Phi_theta, pm = friction_parameter_derivative(P, V, name)
        return Phi_theta / (P.fluid.density(pm) if P.compressible else P.fluid.rho)

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta (n, 2), dr/d theta (n, 0)) for length, diameter, roughness,
        Re_laminar, Re_turbulent, K; None for other parameters (see :func:`softflow.solve.discretize.param_step_derivative`)."""
        d = cls.drop_parameter_derivative(P, V, name)
        if d is None:
            return None
        dF = np.zeros((P.n, 2))
        dF[:, 1] = -d
        return dF, np.zeros((P.n, 0))

class InertialCircularTube(CircularTube):
    """A :class:`CircularTube` with the inertia of its fluid column:

        p_a - p_b = dp_friction(mdot) + (L/A) · d(mdot)/dt

    (an inertance rho L / A in volume-flow terms). The mass flow is a state q
    with rate dq/dt = A/L · (p_a - p_b - dp_friction(mdot)), and the flow
    entering at ``a`` equals it (residual mdot - q = 0), starting at 0. The
    step equations mdot - q_old - c A/L · (...) = 0 stay regular at a zero
    step, where they fix the initial flow.
    With a compliance it forms the fluidic LC circuit, f = 1 / (2 pi sqrt(L C)).
    ``CircularTube(..., inertance=True)`` returns this class; parameters as there.
    """

    state_spec = (("inertial_massflow", "massflow"),)
    # eq 1 ties the terminal flow to the state; the state's rate brings in p_a, mf, p_b
    residual_pattern = ((0, 1), (0, 3), (1, 1))
    state_jac_pattern = ((1, 0),)
    rate_pattern = ((0, 0), (0, 1), (0, 2))

    @classmethod
    def rates(cls, P, V, S, jac):
        pa, mfa, pb = V[:, 0], V[:, 1], V[:, 2]
        dp, d_pa, d_mf, d_pb = cls.pressure_drop(P, pa, mfa, pb, jac)
        k = 1.0 / P.length_per_area
        R = (k * ((pa - pb) - dp))[:, None]
        if not jac:
            return R, None
        return R, (k * (1.0 - d_pa), -k * d_mf, -k * (1.0 + d_pb))

    @classmethod
    def residual(cls, P, V, S, t, jac):
        F = np.empty((P.n, 2))
        F[:, 0] = V[:, 1] + V[:, 3]
        F[:, 1] = V[:, 1] - S[:, 0]
        if not jac:
            return F, None
        J = np.empty((P.n, 4))
        J[:, :3] = 1.0
        J[:, 3] = -1.0
        return F, J

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta (n, 2) = 0, dr/d theta (n, 1)) of the flow's rate
        dq/dt = A/L (p_a - p_b - dp_friction) for length, diameter, roughness,
        the blend's bounds and K."""
        d = cls.drop_parameter_derivative(P, V, name)
        if d is None:
            return None
        k = 1.0 / P.length_per_area
        R = cls.rates(P, V, S, False)[0][:, 0]
        # A/L: d/dL = -(A/L)/L, d/dD = 2 (A/L)/D
        dk = {"length": -1.0 / P.length, "diameter": 2.0 / P.diameter}.get(name, 0.0)
        return np.zeros((P.n, 2)), (dk * R - k * d)[:, None]
