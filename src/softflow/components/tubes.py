"""Tubes: Darcy–Weisbach with a selectable friction correlation, optional
isothermal compressible flow and optional fluid inertance."""
from __future__ import annotations

import copy
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ..constants import pressure_atmospheric
from ..correlations.friction import (ANALYTIC_FRICTION, FrictionTable, fRe_blended,
                                     friction_Haaland, resolve_friction, roughness_terms,
                                     smoothstep)
from .base import FLUID_PORT, Affine, LibraryComponent

if TYPE_CHECKING:
    from typing_extensions import Self

    from .._typing import Scalar
    from ..fluids.base import Fluid

_COMPRESSIBLE_MODES = ("mean_density", "isothermal")
#: groups up to this size test laminarity by a dot product (single-threaded in BLAS)
_DOT_MAX = 1000


def set_tube_geometry(comp, fluid, length, diameter, roughness, Re_laminar, Re_turbulent):
    """Checked SI tube parameters on ``comp`` (shared by tubes and tube-like valves)."""
    comp.fluid = comp._check_fluid(fluid)
    comp.length = comp._si(length, "m", "length", positive=True)
    comp.diameter = comp._si(diameter, "m", "diameter", positive=True)
    comp.roughness = comp._si(roughness, "m", "roughness", nonnegative=True)
    comp.Re_laminar = comp._si(Re_laminar, "", "Re_laminar", positive=True)
    comp.Re_turbulent = comp._si(Re_turbulent, "", "Re_turbulent", positive=True)
    if comp.Re_turbulent <= comp.Re_laminar:
        raise ValueError(f"{comp.describe()}: Re_turbulent ({comp.Re_turbulent}) must exceed "
                         f"Re_laminar ({comp.Re_laminar})")


def set_tube_coefficients(P):
    """Laminar/turbulent law coefficients of a group of tubes (or tube-like valves)
    on its Params namespace: Re = |mdot| re_per_mf, dp = c_mu/rho (f Re) mdot,
    with mu at 1 atm."""
    P.area = np.pi * P.diameter ** 2 / 4.0
    P.eD = P.roughness / P.diameter
    P.mu = P.fluid.viscosity(np.full(P.n, pressure_atmospheric))
    P.Re_lo = float(P.Re_laminar[0])
    P.Re_hi = float(P.Re_turbulent[0])
    P.re_per_mf = P.diameter / (P.mu * P.area)
    P.c_mu = P.mu * P.length / (2.0 * P.area * P.diameter ** 2)



def one_instance(P):
    """For a group of one: a copy of its Params with each per-instance value (an
    array of shape (1,)) as a NumPy scalar, for a residual written on scalars
    with the array path's arithmetic (``P.one``); None for larger groups."""
    if P.n != 1:
        return None
    one = copy.copy(P)
    for key, value in vars(P).items():
        if type(value) is np.ndarray and value.shape == (1,):
            setattr(one, key, value[0])
    one.one = None
    return one


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
    w, _ = smoothstep(Re, P.Re_lo, P.Re_hi)
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
    dw = 6.0 * s * (1.0 - s) / (hi - lo)
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

    For a gas (``fluid.compressible``) rho is the density at the mean pressure
    (p_a + p_b)/2. With a real fluid (level ``table`` or ``eos``) mu is taken at
    the mean pressure too; at level ``ideal`` it is the fluid's constant. With ``compressible='isothermal'`` the gas's acceleration
    along the tube is added, which makes the law the complete isothermal pipe
    flow equation (Crane TP-410; ``fluids.compressible.isothermal_gas``):

        A^2 (p_a^2 - p_b^2) / (R T) = mdot^2 (f L/D + 2 ln(p_a/p_b))

    exact for an ideal gas, for which (p_a^2 - p_b^2)/(R T) = 2 rho_mean (p_a - p_b).
    It is valid below the isothermal choking limit (velocity < sqrt(R T) at
    ``b``); choked tube flow is not modelled. For liquids the option has no effect.

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
    compressible : {'mean_density', 'isothermal'}, default 'mean_density'
        Gas model (see above).
    inertance : bool, default False
        Add the fluid inertance L/A · d(mdot)/dt (rho L / A per volume flow)
        to the pressure drop, with the mass flow as a state.
    """

    terminal_spec = (("a", FLUID_PORT), ("b", FLUID_PORT))
    param_names = ("length", "diameter", "roughness", "Re_laminar", "Re_turbulent")
    # V = [p_a, mf_a, p_b, mf_b]; eq 0: mass balance, eq 1: pressure drop
    jac_pattern = ((0, 1), (0, 3), (1, 0), (1, 1), (1, 2))

    def __new__(cls, *args: Any, inertance: bool = False, **kwargs: Any) -> Self:
        if inertance and cls is CircularTube:
            cls = InertialCircularTube  # type: ignore[assignment]
        return super().__new__(cls)

    def __init__(self, label: str, fluid: Fluid, length: Scalar, diameter: Scalar,
                 roughness: Scalar = 1.5e-6, Re_laminar: float = 2300.0,
                 Re_turbulent: float = 4000.0, *, friction: str = "Haaland",
                 compressible: str = "mean_density", inertance: bool = False) -> None:
        super().__init__(label, fluid=None)
        set_tube_geometry(self, fluid, length, diameter, roughness, Re_laminar, Re_turbulent)
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
                mode)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        first = P.components[0]
        set_tube_coefficients(P)
        P.compressible = P.fluid.compressible
        # real-fluid levels: viscosity at the tube's mean pressure (air at 15 MPa
        # is 20 % more viscous than at 1 atm); the ideal level keeps it constant
        P.variable_mu = getattr(P.fluid, "level", "ideal") != "ideal"
        P.isothermal = P.compressible and first.compressible == "isothermal"
        P.length_per_area = P.length / P.area
        P.c_per_rho = (None if P.compressible or P.variable_mu
                       else P.c_mu / P.fluid.rho)
        P.c64_per_rho = None if P.c_per_rho is None else P.c_per_rho * 64.0
        # a liquid at constant properties in laminar flow: both equations are
        # linear in V = [p_a, mf_a, p_b, mf_b], F = V @ lin_map (a single tube:
        # one product, 0.3 us against 2.2 us for the general path, measured)
        P.lin_map = None
        # (not for a subclass with its own pressure-drop law)
        if (P.c_per_rho is not None and not P.isothermal
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
        # one tube: its residual evaluates the law on NumPy scalars (P.one: this P
        # with its per-instance values as np.float64), ~31 k instead of ~106 k
        # instructions a call without Jacobian. The same arithmetic, bitwise: +-*/
        # are IEEE either way and np.log is NumPy's on a scalar as on an array
        # (math.log and ** are not, hence Haaland or laminar only, and no
        # real-fluid mu); np.float64, not float, so that a division by zero gives
        # inf or nan, as on arrays, instead of raising
        P.one = (one_instance(P) if P.turbulent in (None, friction_Haaland) and not P.variable_mu
                 and cls.pressure_drop.__func__ is CircularTube.pressure_drop.__func__ else None)
        return P

    @classmethod
    def pressure_drop(cls, P, pa, mf, pb, jac):
        """p_a - p_b required by the flow mf entering at ``a`` (friction, and gas
        acceleration if isothermal), and its partial derivatives in p_a, mf, p_b
        (None without ``jac``)."""
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
        if P.turbulent is None:
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
        else:
            # without jac, the value alone (the same arithmetic)
            phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi, P.turbulent, derivative=jac,
                                    terms=P.friction_terms)
        # a liquid at constant viscosity: c_mu / rho is a constant of the group,
        # and so is c·64 when all flow is laminar (the same product, made once)
        c = P.c_per_rho if P.c_per_rho is not None else c_mu / rho
        c_phi = P.c64_per_rho if laminar and P.c_per_rho is not None else c * phi
        dp = c_phi * mf
        if P.isothermal:
            log_ratio = np.log(pa / pb)
            k_acc = mf * mf / (P.area * P.area * rho)
            dp_acc = log_ratio * k_acc
            dp = dp + dp_acc
        if not jac:
            return dp, None, None, None
        d_mf = c_phi if dphi is None else c * (phi + Re * dphi)
        if P.compressible:
            # dp ∝ 1/rho(p_mean) in both terms
            d_pm = -dp / rho * P.fluid.density_dp(pm) * 0.5
        else:
            d_pm = 0.0
        if P.variable_mu:
            # friction dp = c(mu) phi(Re(mu)) mf with c ∝ mu, Re ∝ 1/mu; dmu/dp by a
            # central difference of the fluid's viscosity (the protocol has no mu_dp)
            # (kept inside the fluid's valid range: a table ends at its last point)
            lo, hi = getattr(P.fluid, "p_range", (0.0, np.inf))
            p1 = np.maximum(pm * (1 - 1e-6), lo)
            p2 = np.minimum(pm * (1 + 1e-6), hi)
            dmu_dp = (P.fluid.viscosity(p2) - P.fluid.viscosity(p1)) / (p2 - p1)
            mu = mu_ratio * P.mu
            phi_less = phi if dphi is None else phi - Re * dphi
            d_pm = d_pm + 0.5 * c * mf * phi_less / mu * dmu_dp
        d_pa = d_pm
        d_pb = d_pm
        if P.isothermal:
            d_mf = d_mf + 2.0 * log_ratio * mf / (P.area * P.area * rho)
            d_pa = d_pa + k_acc / pa
            d_pb = d_pb - k_acc / pb
        return dp, d_pa, d_mf, d_pb

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
        if P.one is not None:
            # one tube: the same law on NumPy scalars (see make_params)
            pa, mfa, pb, mfb = V[0]
            dp, d_pa, d_mf, d_pb = cls.pressure_drop(P.one, pa, mfa, pb, jac)
            F = np.array([[mfa + mfb, (pa - pb) - dp]])
            if not jac:
                return F, None
            return F, np.array([[1.0, 1.0, 1.0 - d_pa, -d_mf, -1.0 - d_pb]])
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


    @classmethod
    def drop_parameter_derivative(cls, P, V, name):
        """d(p_a - p_b required)/d theta of the group's pressure-drop law for a
        parameter of :data:`TUBE_GEOMETRY` or :data:`BLEND_BOUNDS` (each instance's
        own bound moved: its row depends on its own law alone); None for others
        and, for the geometry, for a tabulated friction correlation (made for the
        roughness; its table starts at Re_laminar, which the bounds' derivative
        leaves out: the table interpolates the same correlation)."""
        if name in BLEND_BOUNDS:
            pa, mf, pb = V[:, 0], V[:, 1], V[:, 2]
            rho = P.fluid.density(0.5 * (pa + pb)) if P.compressible else P.fluid.rho
            re_per_mf, c_mu = P.re_per_mf, P.c_mu
            if P.variable_mu:
                mu_ratio = P.fluid.viscosity(0.5 * (pa + pb)) / P.mu
                re_per_mf, c_mu = re_per_mf / mu_ratio, c_mu * mu_ratio
            # dp = c_mu/rho (f Re) mdot (+ the isothermal acceleration, which has no Re)
            return c_mu / rho * mf * friction_bound_derivative(P, np.abs(mf) * re_per_mf, name)
        if name not in TUBE_GEOMETRY or isinstance(P.turbulent, FrictionTable):
            return None
        pa, mf, pb = V[:, 0], V[:, 1], V[:, 2]
        dp, _, d_mf, _ = cls.pressure_drop(P, pa, mf, pb, True)
        pm = 0.5 * (pa + pb)
        rho = P.fluid.density(pm) if P.compressible else P.fluid.rho
        re_per_mf, c_mu = P.re_per_mf, P.c_mu
        if P.variable_mu:
            mu_ratio = P.fluid.viscosity(pm) / P.mu
            re_per_mf, c_mu = re_per_mf / mu_ratio, c_mu * mu_ratio
        # the gas's acceleration (isothermal model) scales as 1/A^2 and has no L
        acc = (np.log(pa / pb) * mf * mf / (P.area * P.area * rho) if P.isothermal
               else np.zeros(P.n))
        d_eD = c_mu / rho * mf * friction_roughness_derivative(P, np.abs(mf) * re_per_mf)
        # mdot d(dp)/d(mdot) of the friction part: the acceleration's is 2 acc
        friction = tube_law_derivative(P, name, dp - acc, mf * d_mf - 2.0 * acc, d_eD)
        return friction - (4.0 * acc / P.diameter if name == "diameter" else 0.0)

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta (n, 2), dr/d theta (n, 0)) for length, diameter, roughness,
        Re_laminar, Re_turbulent; None for other parameters (see :func:`softflow.solve.discretize.param_step_derivative`)."""
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
        dq/dt = A/L (p_a - p_b - dp_friction) for length, diameter, roughness and
        the blend's bounds."""
        d = cls.drop_parameter_derivative(P, V, name)
        if d is None:
            return None
        k = 1.0 / P.length_per_area
        R = cls.rates(P, V, S, False)[0][:, 0]
        # A/L: d/dL = -(A/L)/L, d/dD = 2 (A/L)/D
        dk = {"length": -1.0 / P.length, "diameter": 2.0 / P.diameter}.get(name, 0.0)
        return np.zeros((P.n, 2)), (dk * R - k * d)[:, None]
