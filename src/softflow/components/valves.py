"""Valves and restrictors: orifice (loss coefficient, discharge coefficient or
ISO 6358), check valve, Tesla valve (fluidic diode) and hysteretic snapping valve.

All have terminals ``a`` and ``b`` with V = [p_a, mf_a, p_b, mf_b]; equation 0
is the mass balance mf_a + mf_b = 0, equation 1 the flow law, where
mdot = mf_a > 0 is flow from a to b and dp = p_a - p_b.
"""
from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from .._laws import law_module
from ..constants import pressure_atmospheric
from ..correlations.friction import (compiled_kind, fRe_blended, friction_Haaland,
                                     roughness_terms, smoothstep)
from ..correlations.orifice import (ISO_6358_RHO0, ISO_6358_T0, _iso_6358_phi, dp_at_reynolds,
                                    loss_coefficient_from_discharge_coefficient,
                                    massflow_ISO_6358, massflow_loss_coefficient,
                                    massflow_nozzle, nozzle_flow_factor)
from ..fluids.ideal import IdealGas
from .base import FLUID_PORT, LibraryComponent
from .tubes import (BLEND_BOUNDS, TUBE_GEOMETRY, _tube_laws, friction_bound_derivative,
                    friction_roughness_derivative, isothermal_drop,
                    isothermal_drop_parameter_derivative, set_isothermal_law,
                    set_tube_coefficients, set_tube_geometry, tube_law_derivative)

if TYPE_CHECKING:
    from .._typing import Scalar
    from ..fluids.base import Fluid

TWO_PORTS = (("a", FLUID_PORT), ("b", FLUID_PORT))
# V = [p_a, mf_a, p_b, mf_b]; eq 0: mass balance, eq 1: flow law
TWO_PORT_PATTERN = ((0, 1), (0, 3), (1, 0), (1, 1), (1, 2))


#: the Jacobian argument of a compiled pass evaluated without one, and the
#: density arrays of a pass that makes its densities itself
_NO_JACOBIAN = np.empty((0, 5))
_NONE = np.empty(0)


_valve_laws = functools.partial(law_module, "valves")


def set_density_law(P):
    """Whether the group's flow law runs as one compiled pass that makes its
    densities itself (``P.compiled``): for an ideal gas (``P.law_RT`` = R T,
    rho = p/(R T)) or an incompressible fluid (``P.law_RT`` = 0, its constant
    density ``P.law_rho``); else (a gas at the table or eos level, or one whose
    density is its own) the component takes the densities from the fluid's
    methods and gives them to the same pass (:func:`_given_density`)."""
    fl, cls = P.fluid, type(P.fluid)
    P.law_RT = P.law_rho = 0.0
    if not fl.compressible:
        P.compiled, P.law_rho = True, float(fl.rho)
    elif (isinstance(fl, IdealGas) and cls.density is IdealGas.density
          and cls.density_dp is IdealGas.density_dp):
        P.compiled, P.law_RT = True, float(fl.R * fl.temperature)
    else:
        P.compiled = False


def _flat(x, n):
    """``x`` as a C-contiguous float64 array of n values."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(x, dtype=float), (n,)))


def _given_density(P, p, mean=False):
    """(rho, d rho/dp) of the group's fluid at the pressures p (arrays of n), from
    its own methods, for a compiled pass that does not make them
    (``P.compiled`` False); with ``mean`` at the mean pressure p = (p_a, p_b),
    its slope per p_a and p_b (half d rho/dp). An incompressible fluid's
    constant density and 0."""
    fl, n = P.fluid, P.n
    if mean:
        p = 0.5 * (p[0] + p[1])
    if not fl.compressible:
        return np.full(n, float(fl.rho)), np.zeros(n)
    slope = fl.density_dp(p)
    return _flat(fl.density(p), n), _flat(0.5 * slope if mean else slope, n)


def _mean_density(fluid, pa, pb):
    """Density at the mean pressure and d rho/d p_a (= d rho/d p_b)."""
    if not fluid.compressible:
        return fluid.rho, 0.0
    pm = 0.5 * (pa + pb)
    return fluid.density(pm), 0.5 * fluid.density_dp(pm)


def _tube_fRe(P, mf, terms=None):
    """f·Re of the tube law and its derivative in Re, skipping Haaland when all
    laminar (``terms``: Haaland's roughness terms, made once, or None)."""
    Re = np.abs(mf) * P.re_per_mf
    if Re.max(initial=0.0) <= P.Re_lo:
        return Re, np.full_like(Re, 64.0), np.zeros_like(Re)
    phi, dphi = fRe_blended(Re, P.eD, P.Re_lo, P.Re_hi, terms=terms)
    return Re, phi, dphi



def _flow_law_jacobian(P, dq):
    """(dF/d theta, dr/d theta) of a two-port whose flow law is F[:, 1] = mf_a - q,
    given dq/d theta (n,); None passes through."""
    if dq is None:
        return None
    dF = np.zeros((P.n, 2))
    dF[:, 1] = -dq
    return dF, np.zeros((P.n, 0))


def _loss_law_derivative(P, dp, rho, q, name):
    """dq/d theta of the loss-coefficient law q = A sqrt(2 rho/K) r(dp, dp_small)
    (:func:`massflow_loss_coefficient`) for theta = diameter (A ∝ D^2 and, at
    fixed Reynolds number, dp_small ∝ 1/D^2), K (dp_small ∝ K), Cd (K = 1/Cd^2:
    dK/dCd = -2 K^1.5) or Re_laminar (dp_small ∝ Re^2, :func:`dp_at_reynolds`);
    None else."""
    if name not in ("diameter", "K", "Cd", "Re_laminar"):
        return None
    g = P.area * np.sqrt(2.0 * rho / P.K) * _band_derivative(dp, P.dp_small)
    if name == "diameter":
        return (2.0 * q - 2.0 * g) / np.sqrt(4.0 * P.area / np.pi)
    if name == "Re_laminar":      # dp_small xs = K rho_n (Re mu / (rho_n D))^2 / 2
        return 2.0 * g / _laminar_reynolds(P)
    dq_dK = (g - 0.5 * q) / P.K
    return dq_dK if name == "K" else -2.0 * P.K ** 1.5 * dq_dK


def _band_derivative(dp, xs):
    """xs · d r/d xs of the regularized square root r(dp; xs)
    (:func:`~softflow.correlations.orifice.regularized_sqrt`): the odd cubic's,
    inside the band |dp| < xs; the square root outside has none."""
    u = dp / xs
    return np.where(np.abs(dp) < xs, -0.625 * dp * xs ** -0.5 * (1.0 - u * u), 0.0)


def _nozzle_flow(P, pa, pb):
    """:func:`~softflow.correlations.orifice.massflow_nozzle` of a group (P.Cd,
    P.gamma, P.area, P.dp_small), the gas's density at the upstream pressure;
    returns (mdot, d/dp_a, d/dp_b, density there)."""
    fl = P.fluid
    p_up = np.maximum(pa, pb)
    rho = fl.density(p_up)
    q, dq_pa, dq_pb = massflow_nozzle(pa, pb, rho, P.gamma, P.Cd, P.area, P.dp_small,
                                      fl.density_dp(p_up))
    return q, dq_pa, dq_pb, rho


def _nozzle_law_derivative(P, pa, pb, q, rho, name):
    """dq/d theta of the nozzle law q = Cd A sqrt(2 rho_up) r(dp; dp_small) Y(s)
    (:func:`_nozzle_flow`, ``q`` its flow, ``rho`` the upstream density) for
    theta = diameter (A ∝ D^2; at fixed Reynolds number dp_small ∝ 1/D^2),
    Cd (q ∝ Cd; dp_small ∝ K = 1/Cd^2) or Re_laminar (dp_small ∝ Re^2); None
    else. Y depends on the pressures and gamma only."""
    if name not in ("diameter", "Cd", "Re_laminar"):
        return None
    p_up = np.maximum(pa, pb)
    Y = nozzle_flow_factor((p_up - np.minimum(pa, pb)) / p_up, P.gamma)[0]
    g = P.Cd * P.area * np.sqrt(2.0 * rho) * Y * _band_derivative(pa - pb, P.dp_small)
    if name == "diameter":
        return (2.0 * q - 2.0 * g) / np.sqrt(4.0 * P.area / np.pi)
    if name == "Cd":
        return (q - 2.0 * g) / P.Cd
    return 2.0 * g / _laminar_reynolds(P, 1.0 / P.Cd ** 2)


def _laminar_reynolds(P, K=None):
    """The Reynolds number Re_laminar that placed dp_small (:func:`dp_at_reynolds`
    at the fluid's nominal density and the viscosity at 1 atm, loss coefficient
    K: P.K where None), from dp_small."""
    rho = P.fluid.rho
    mu = float(P.fluid.viscosity(pressure_atmospheric))
    diameter = np.sqrt(4.0 * P.area / np.pi)
    return np.sqrt(2.0 * P.dp_small / ((P.K if K is None else K) * rho)) * rho * diameter / mu


def _nozzle_gamma(comp):
    """The ratio of specific heats the nozzle law of ``comp`` (a gas) uses: the
    fluid's at 1 atm and its temperature; a clear error where it has none."""
    fl = comp.fluid
    try:
        gamma = float(np.asarray(fl.gamma(pressure_atmospheric)))
    except NotImplementedError:
        raise ValueError(f"{comp.describe()}: the nozzle law of a gas (Cd) needs the fluid's "
                         f"ratio of specific heats, which fluid {fl.name!r} does not give; "
                         "give K (incompressible law) or C and b (ISO 6358)") from None
    if not gamma > 1.0:
        raise ValueError(f"{comp.describe()}: the nozzle law of a gas (Cd) needs a ratio of "
                         f"specific heats > 1; fluid {fl.name!r} gives {gamma}")
    return gamma


def _iso_law_derivative(P, pa, pb, name):
    """dq/d theta of the ISO 6358 law (:func:`massflow_ISO_6358`) for theta = b
    (critical pressure ratio) or pr_laminar; None else.

    q = ±k p_up phi(s; s_l), s = (1 - p_dn/p_up)/(1 - b), s_l = (1 - pr_laminar)/(1 - b):
    ds/db = s/(1 - b), ds_l/db = s_l/(1 - b), ds_l/d(pr_laminar) = -1/(1 - b).
    phi depends on s_l only inside the laminar-like region s < s_l, through the
    odd cubic y = s (alpha + beta s^2) matched to f = u^m, u = s_l (2 - s_l), in
    value f_l and slope f'_l at s_l: beta = (f'_l - f_l/s_l)/(2 s_l^2),
    alpha = f_l/s_l - beta s_l^2, differentiated along s_l with f'' of u^m."""
    if name not in ("b", "pr_laminar", "m"):
        return None
    forward = pa >= pb
    p_up = np.where(forward, pa, pb)
    p_dn = np.where(forward, pb, pa)
    k = P.C * ISO_6358_RHO0 * np.sqrt(ISO_6358_T0 / P.T)
    m, one_b = P.subsonic_index, 1.0 - P.b
    s = (1.0 - p_dn / p_up) / one_b
    x = (1.0 - P.pr_laminar) / one_b                 # s_l
    _, dphi_ds = _iso_6358_phi(s, P.b, m, x)
    u = x * (2.0 - x)
    f = u ** m
    df = m * u ** (m - 1.0) * (2.0 - 2.0 * x)
    ddf = m * (m - 1.0) * u ** (m - 2.0) * (2.0 - 2.0 * x) ** 2 - 2.0 * m * u ** (m - 1.0)
    beta = (df - f / x) / (2.0 * x * x)
    dbeta = (ddf - df / x + f / (x * x)) / (2.0 * x * x) - 2.0 * beta / x
    dalpha = (df / x - f / (x * x)) - dbeta * x * x - 2.0 * beta * x
    dphi_dx = np.where(s < x, s * (dalpha + dbeta * s * s), 0.0)
    if name == "b":
        dphi = (dphi_ds * s + dphi_dx * x) / one_b
    elif name == "pr_laminar":
        dphi = -dphi_dx / one_b
    else:     # m: u^m ln u (subsonic), the cubic's coefficients along f_l, f'_l (laminar)
        s_c = np.clip(s, x, 1.0)
        uc = s_c * (2.0 - s_c)
        f_m = f * np.log(u)
        df_m = df * (1.0 / m + np.log(u))
        beta_m = (df_m - f_m / x) / (2.0 * x * x)
        alpha_m = f_m / x - beta_m * x * x
        dphi = np.where(s < x, s * (alpha_m + beta_m * s * s),
                        np.where(s >= 1.0, 0.0, uc ** m * np.log(uc)))
    dq = k * p_up * dphi
    return np.where(forward, dq, -dq)


def _tube_drop_derivative(P, name, c, mf):
    """d(c·phi(Re)·mf)/d theta at fixed c-scaling for theta in TUBE_GEOMETRY (the
    forward tube law of the Tesla and snapping valves, c = c_mu/rho), with
    phi and its parts; returns (derivative, dp)."""
    Re, phi, dphi = _tube_fRe(P, mf)
    dp = c * phi * mf
    d_eD = c * mf * friction_roughness_derivative(P, Re)
    return tube_law_derivative(P, name, dp, c * (phi + Re * dphi) * mf, d_eD), dp


def set_tube_like_law(P):
    """The compiled law of a group of Tesla or snapping valves (after
    :func:`set_tube_coefficients` and :func:`set_isothermal_law`): Haaland's
    blended friction law (``P.kind``, its id in the compiled laws, and
    ``P.friction_terms``, its roughness term made once), and whether the group
    runs as one compiled pass (``P.compiled``, :func:`set_density_law`) with
    p/rho of an ideal gas ``P.law_c2`` (0 for a liquid)."""
    P.kind = compiled_kind(friction_Haaland)
    # Haaland's roughness terms, made once on the group's array (as the array law
    # makes them: NumPy's ** on a scalar is not its ufunc on an array to the last bit)
    P.friction_terms = roughness_terms(friction_Haaland, P.eD)
    set_density_law(P)
    P.law_c2 = P.c2 if P.compiled and P.isothermal else 0.0


def _prepared(n, *columns):
    """The columns (arrays of n, or floats) as C-contiguous float64 arrays of n."""
    return [_flat(c, n) for c in columns]


class _TubeLike(LibraryComponent):
    """Shared checks of the tube-geometry parameters (length, diameter, roughness, blend)."""

    def _init_tube(self, fluid, length, diameter, roughness, Re_laminar, Re_turbulent):
        set_tube_geometry(self, fluid, length, diameter, roughness, Re_laminar, Re_turbulent)

    def group_key(self):
        return (type(self), id(self.fluid), self.Re_laminar, self.Re_turbulent)


# ---------------------------------------------------------------------------------------
class Orifice(LibraryComponent):
    """Flow restrictor between terminals ``a`` and ``b``, one of four models:

    * loss coefficient ``K`` with ``diameter``: dp = K rho v^2/2, v = mdot/(rho A)
      (incompressible, liquids and gases alike; ``model`` 'K');
    * discharge coefficient ``Cd`` with ``diameter``, a liquid:
      mdot = Cd A sqrt(2 rho dp), the same law with K = 1/Cd^2 (``model`` 'K');
    * discharge coefficient ``Cd`` with ``diameter``, a gas: the isentropic
      nozzle from the upstream (stagnation) pressure p0 to the downstream one,
      mdot = Cd A p0 sqrt(2 gamma/((gamma-1) R T0)) sqrt(pr^(2/gamma) - pr^((gamma+1)/gamma)),
      pr = p_down/p0, choked below pr* = (2/(gamma+1))^(gamma/(gamma-1)) (0.528
      for air) at mdot = Cd A p0 sqrt(gamma/(R T0)) (2/(gamma+1))^((gamma+1)/(2(gamma-1)))
      (``model`` 'nozzle'; :func:`softflow.correlations.orifice.massflow_nozzle`:
      a real gas, 'table' or 'eos', takes R T0 = p0/rho(p0), gamma the fluid's
      at 1 atm). T0 is the fluid's temperature, or in a thermal scene the
      upstream temperature. Its ISO 6358 equivalent (same choked flow):
      :func:`softflow.correlations.orifice.iso_6358_of_nozzle`;
    * ISO 6358 for gases, sonic conductance ``C`` with critical pressure ratio
      ``b`` (and subsonic index ``m``): choked flow mdot = C rho0 p_up sqrt(T0/T)
      for p_down/p_up <= b, elliptic subsonic law above (see
      :func:`softflow.correlations.orifice.massflow_ISO_6358`; ``model`` 'ISO 6358').

    K/Cd models take rho at the upstream pressure (continuous at dp = 0 because
    the flow vanishes there), and replace the square root by a linear-like odd
    cubic below the dp at which the orifice Reynolds number rho v D/mu equals
    ``Re_laminar`` (density at 1 atm; for a gas's nozzle law the same band, where
    it is the incompressible law to within 3 dp/(4 gamma p0)). A gas through a
    K orifice holds while ``|dp|`` is small against the upstream pressure (it
    never chokes: give Cd or C, b beyond). The ISO model turns laminar-like
    above the pressure ratio ``pr_laminar``.

    Parameters
    ----------
    label : str
    fluid : Fluid
    diameter : float [m]
        Orifice (throat) diameter; K and Cd refer to its area. Not used by ISO 6358.
    K : float [-], optional
        Loss coefficient (> 0).
    Cd : float [-], optional
        Discharge coefficient (0 < Cd <= 1; about 0.6 for a sharp-edged orifice,
        0.97-0.99 for a rounded nozzle, ISO 9300); a gas's chokes.
    C : float [m^3/(s Pa)], optional
        ISO 6358 sonic conductance at rho0 = 1.185 kg/m^3, T0 = 293.15 K
        (catalogues give dm^3/(s bar): pass ``sf.Q_(0.5, 'dm**3/(s*bar)')``).
    b : float [-], optional
        ISO 6358 critical pressure ratio, 0 < b < pr_laminar (about 0.5 for valves).
    m : float [-], default 0.5
        ISO 6358 subsonic index, 0 < m <= 1.
    Re_laminar : float [-], default 10
        K/Cd models: orifice Reynolds number below which the law is laminar-like.
    pr_laminar : float [-], default 0.999
        ISO model: pressure ratio above which the law is laminar-like.
    """

    terminal_spec = TWO_PORTS
    param_names = ("area", "K", "dp_small", "C", "b", "subsonic_index", "pr_laminar", "Cd",
                   "gamma")
    jac_pattern = TWO_PORT_PATTERN

    def __init__(self, label: str, fluid: Fluid, diameter: Scalar | None = None, *,
                 K: float | None = None, Cd: float | None = None, C: Scalar | None = None,
                 b: float | None = None, m: float = 0.5, Re_laminar: float = 10.0,
                 pr_laminar: float = 0.999) -> None:
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        given = [name for name, v in (("K", K), ("Cd", Cd), ("C", C)) if v is not None]
        if len(given) != 1:
            raise ValueError(f"{self.describe()}: give exactly one of K (loss coefficient), Cd "
                             f"(discharge coefficient) or C (ISO 6358 sonic conductance); "
                             f"got {given or 'none'}")
        nan = float("nan")
        self.area = self.K = self.dp_small = self.C = self.b = nan
        self.subsonic_index = self.pr_laminar = self.Cd = self.gamma = nan
        if C is not None:
            self.model = "ISO 6358"
            self._init_iso(C, b, m, pr_laminar, diameter)
        else:
            self.model = "K"
            if b is not None:
                raise ValueError(f"{self.describe()}: b (critical pressure ratio) belongs to the "
                                 "ISO 6358 model; give C with it, or leave it out")
            if diameter is None:
                raise ValueError(f"{self.describe()}: diameter [m] is required with {given[0]}")
            d = self._si(diameter, "m", "diameter", positive=True, size=True)
            if K is not None:
                self.K = self._si(K, "", "K", positive=True)
            else:
                cd = self._si(Cd, "", "Cd", positive=True)
                if cd > 1:
                    raise ValueError(f"{self.describe()}: Cd must be in (0, 1], got {cd}")
                self.Cd = cd
                self.K = float(loss_coefficient_from_discharge_coefficient(cd))
            re = self._si(Re_laminar, "", "Re_laminar", positive=True)
            self.Re_laminar = re
            self.area = np.pi * d * d / 4.0
            self.diameter = d
            rho = self.fluid.rho
            mu = float(self.fluid.viscosity(pressure_atmospheric))
            self.dp_small = float(dp_at_reynolds(re, self.K, rho, mu, d))
            if Cd is not None and self.fluid.compressible:
                # a gas with a discharge coefficient: the isentropic nozzle, which
                # has no loss coefficient (its band still placed with K = 1/Cd^2)
                self.model = "nozzle"
                self.gamma = _nozzle_gamma(self)
                self.K = nan

    def _init_iso(self, C, b, m, pr_laminar, diameter):
        if diameter is not None:
            raise ValueError(f"{self.describe()}: diameter is not used by the ISO 6358 model "
                             "(C and b describe the restriction); leave it out")
        if not self.fluid.compressible:
            raise ValueError(f"{self.describe()}: the ISO 6358 model (C, b) is for gases; "
                             f"fluid {self.fluid.name!r} is incompressible, use K or Cd")
        self.C = self._si(C, "m**3/(s*Pa)", "C", positive=True)
        if b is None:
            raise ValueError(f"{self.describe()}: b (critical pressure ratio, 0 < b < 1) is "
                             "required with C")
        self.b = self._si(b, "", "b")
        self.pr_laminar = self._si(pr_laminar, "", "pr_laminar")
        if not 0.0 < self.pr_laminar < 1.0:
            raise ValueError(f"{self.describe()}: pr_laminar must be in (0, 1), "
                             f"got {self.pr_laminar}")
        if not 0.0 < self.b < self.pr_laminar:
            raise ValueError(f"{self.describe()}: b (critical pressure ratio) must be in (0, 1) "
                             f"and below pr_laminar ({self.pr_laminar}), got {self.b}")
        self.subsonic_index = self._si(m, "", "m")
        if not 0.0 < self.subsonic_index <= 1.0:
            raise ValueError(f"{self.describe()}: m (subsonic index) must be in (0, 1], "
                             f"got {self.subsonic_index}")

    def group_key(self):
        return (type(self), id(self.fluid), self.model)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.model = components[0].model
        # the compiled law's id (laws.valves' LOSS, NOZZLE, ISO_6358, written out
        # here so that making the Params does not import numba)
        P.law = {"K": 0, "nozzle": 1, "ISO 6358": 2}[P.model]
        P.T = float(P.fluid.temperature) if P.model == "ISO 6358" else 0.0
        set_density_law(P)
        return P

    @classmethod
    def residual(cls, P, V, S, t, jac):
        """Mass balance and mf_a minus the law's flow, in one compiled pass
        (:func:`softflow.laws.valves.orifice_residual`); the upstream densities
        from the fluid's methods where the pass cannot make them (a gas at the
        table or eos level: :func:`set_density_law`). ISO 6358 takes none."""
        given = not P.compiled and P.model != "ISO 6358"
        rho_up = drho_up = _NONE
        if given:
            pa, pb = V[:, 0], V[:, 2]
            p_up = np.maximum(pa, pb) if P.model == "nozzle" else np.where(pa >= pb, pa, pb)
            rho_up, drho_up = _given_density(P, p_up)
        F = np.empty((P.n, 2))
        J = np.empty((P.n, 5)) if jac else _NO_JACOBIAN
        _valve_laws().orifice_residual(
            P.law, V, P.law_RT, P.law_rho, P.K, P.area, P.dp_small, P.gamma, P.Cd, P.T, P.C,
            P.b, P.subsonic_index, P.pr_laminar, ISO_6358_RHO0, ISO_6358_T0, given, rho_up,
            drho_up, F, J, jac)
        return F, (J if jac else None)


    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) for diameter, K, Cd and Re_laminar
        (loss-coefficient model, :func:`_loss_law_derivative`), diameter, Cd and
        Re_laminar (nozzle, :func:`_nozzle_law_derivative`) or C (ISO 6358,
        where the flow is proportional to it), b, pr_laminar and m (ISO 6358,
        :func:`_iso_law_derivative`); None for others."""
        pa, pb = V[:, 0], V[:, 2]
        if P.model == "nozzle":
            q, _, _, rho = _nozzle_flow(P, pa, pb)
            return _flow_law_jacobian(P, _nozzle_law_derivative(P, pa, pb, q, rho, name))
        if P.model == "ISO 6358":
            if name != "C":
                return _flow_law_jacobian(P, _iso_law_derivative(P, pa, pb, name))
            q = massflow_ISO_6358(pa, pb, P.T, P.C, P.b, P.subsonic_index, P.pr_laminar)[0]
            return _flow_law_jacobian(P, q / P.C)
        fl = P.fluid
        rho = fl.density(np.where(pa >= pb, pa, pb)) if fl.compressible else fl.rho
        q = massflow_loss_coefficient(pa - pb, rho, P.K, P.area, P.dp_small)[0]
        return _flow_law_jacobian(P, _loss_law_derivative(P, pa - pb, rho, q, name))


# ---------------------------------------------------------------------------------------
#: CheckValve.regime: the fraction of the opening band at either end whose
#: smoothstep slope is under 0.19 of its peak (the open end: the open law's own
#: slope takes over; the bottom: cut into LOW_PIECES pieces a factor 4 apart in
#: the band's position, the last from 0.05 / 4^15 = 4.7e-11 down to 0)
REGIME_EDGE = 0.05
LOW_PIECES = 16


def _piece(s):
    """CheckValve.regime of one valve at its band position s (a float)."""
    if s <= 0.0:
        return -LOW_PIECES - 1
    if s < REGIME_EDGE:
        return max(math.floor(math.log2(s / REGIME_EDGE) * 0.5), -LOW_PIECES)
    return 1 if s > 1.0 - REGIME_EDGE else 0     # (NaN: 0, as the array path)


class CheckValve(LibraryComponent):
    """Spring-loaded check valve: flow from ``a`` to ``b`` once dp = p_a - p_b
    exceeds the cracking pressure, none backwards (apart from leakage).

        mdot = w(dp) · q_open(p_a, p_b) + rho(p_mean) · leakage · dp

    with q_open :class:`Orifice`'s law for a discharge coefficient: a liquid's
    Cd A sqrt(2 rho dp), a gas's isentropic nozzle (subsonic, or choked below
    the critical pressure ratio, :func:`softflow.correlations.orifice.massflow_nozzle`),
    or with ``gas_law='incompressible'`` a gas's Cd A sqrt(2 rho(p_a) dp).
    The opening fraction w rises as a C1 smoothstep (3s^2 - 2s^3) from 0 at
    dp = cracking_pressure to 1 at cracking_pressure + opening_band: the open
    law is an orifice whose area grows with the spring's travel. The residual is
    one smooth function of dp; there is no open/closed switch to chatter between.
    The square root is regularized below the dp at which the orifice Reynolds
    number is Re_laminar, as in :class:`Orifice`. In a thermal scene the open
    law stays at the fluid's temperature (its energy transport is upwind).

    Without leakage a node enclosed only by closed check valves has an
    undetermined pressure (singular Jacobian); a tiny ``leakage`` fixes it.

    Parameters
    ----------
    label : str
    fluid : Fluid
    diameter : float [m]
        Diameter of the fully open flow passage.
    cracking_pressure : float [Pa], default 0
        Pressure difference at which the valve starts to open (>= 0).
    opening_band : float [Pa], default 1000
        Pressure rise above cracking over which it opens fully (> 0).
    Cd : float [-], default 0.6
        Discharge coefficient of the fully open passage, 0 < Cd <= 1.
    leakage : float [m^3/(s Pa)], default 0
        Volume-flow conductance when closed (both directions, >= 0).
    Re_laminar : float [-], default 10
    gas_law : {'nozzle', 'incompressible'}, default 'nozzle'
        A gas's open passage: the isentropic nozzle (chokes), or the
        incompressible orifice equation at the density at ``a`` (the law before
        the nozzle; it never chokes). Not used with a liquid.
    """

    terminal_spec = TWO_PORTS
    param_names = ("area", "K", "dp_small", "cracking_pressure", "opening_band", "leakage",
                   "Cd", "gamma")
    jac_pattern = TWO_PORT_PATTERN

    def __init__(self, label: str, fluid: Fluid, diameter: Scalar,
                 cracking_pressure: Scalar = 0.0, opening_band: Scalar = 1e3, Cd: float = 0.6,
                 leakage: Scalar = 0.0, Re_laminar: float = 10.0,
                 gas_law: str = "nozzle") -> None:
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        self.diameter = self._si(diameter, "m", "diameter", positive=True, size=True)
        self.cracking_pressure = self._si(cracking_pressure, "Pa", "cracking_pressure",
                                          nonnegative=True)
        self.opening_band = self._si(opening_band, "Pa", "opening_band", positive=True)
        cd = self._si(Cd, "", "Cd", positive=True)
        if cd > 1:
            raise ValueError(f"{self.describe()}: Cd must be in (0, 1], got {cd}")
        self.leakage = self._si(leakage, "m**3/(s*Pa)", "leakage", nonnegative=True)
        re = self._si(Re_laminar, "", "Re_laminar", positive=True)
        self.Re_laminar = re
        self.Cd = cd
        self.K = float(loss_coefficient_from_discharge_coefficient(cd))
        self.area = np.pi * self.diameter ** 2 / 4.0
        mu = float(self.fluid.viscosity(pressure_atmospheric))
        self.dp_small = float(dp_at_reynolds(re, self.K, self.fluid.rho, mu, self.diameter))
        if gas_law not in ("nozzle", "incompressible"):
            raise ValueError(f"{self.describe()}: gas_law must be 'nozzle' or 'incompressible', "
                             f"got {gas_law!r}")
        self.gas_law = gas_law
        nozzle = self.fluid.compressible and gas_law == "nozzle"
        self.gamma = _nozzle_gamma(self) if nozzle else float("nan")

    def group_key(self):
        return (type(self), id(self.fluid), self.gas_law)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.nozzle = bool(P.fluid.compressible) and components[0].gas_law == "nozzle"
        set_density_law(P)
        return P

    @staticmethod
    def _open_flow(P, pa, pb):
        """The open passage's flow, its derivatives in p_a, p_b, and the density
        the law takes (at the upstream pressure for the nozzle, at ``a`` for the
        incompressible law of a gas)."""
        if P.nozzle:
            return _nozzle_flow(P, pa, pb)
        fl = P.fluid
        if fl.compressible:
            rho_a, drho_a = fl.density(pa), fl.density_dp(pa)
        else:
            rho_a, drho_a = fl.rho, 0.0
        q, dq_dp, dq_rho = massflow_loss_coefficient(pa - pb, rho_a, P.K, P.area, P.dp_small)
        return q, dq_dp + dq_rho * drho_a, -dq_dp, rho_a

    @classmethod
    def residual(cls, P, V, S, t, jac):
        """Mass balance and mf_a minus the valve's flow, in one compiled pass
        (:func:`softflow.laws.valves.check_valve_residual`); the densities from
        the fluid's methods where the pass cannot make them (a gas at the table
        or eos level: :func:`set_density_law`)."""
        given = not P.compiled
        rho_open = drho_open = rho_m = drho_m = _NONE
        if given:
            pa, pb = V[:, 0], V[:, 2]
            rho_open, drho_open = _given_density(P, np.maximum(pa, pb) if P.nozzle else pa)
            rho_m, drho_m = _given_density(P, (pa, pb), mean=True)
        F = np.empty((P.n, 2))
        J = np.empty((P.n, 5)) if jac else _NO_JACOBIAN
        _valve_laws().check_valve_residual(
            P.nozzle, V, P.law_RT, P.law_rho, P.K, P.Cd, P.gamma, P.area, P.dp_small,
            P.cracking_pressure, P.opening_band, P.leakage, given, rho_open, drho_open, rho_m,
            drho_m, F, J, jac)
        return F, (J if jac else None)

    @classmethod
    def kinks(cls, P, V):
        """Where the law's second derivative jumps (LibraryComponent): 0 shut
        (dp at or below the cracking pressure), 1 inside the opening band
        (the smoothstep 3 s^2 - 2 s^3), 2 open."""
        dp = V[:, 0] - V[:, 2]
        return ((dp > P.cracking_pressure).astype(np.int8)
                + (dp >= P.cracking_pressure + P.opening_band))

    @classmethod
    def regime(cls, P, V):
        """The piece of the law at V (LibraryComponent), with s the position
        in the opening band (0 at the cracking pressure, 1 at its top):
        -LOW_PIECES - 1 shut (s <= 0: the leakage's slope alone); -LOW_PIECES
        ... -1 the band's bottom REGIME_EDGE cut into pieces a factor 4 apart
        in s (the smoothstep's slope grows as 6 s there, from nothing: a
        Jacobian from s = 0.01 read at s = 0.0001 is 100 times too steep);
        0 the steep middle of the band; 1 open or nearly (its last
        REGIME_EDGE, where the open law's own slope takes over)."""
        s = (V[:, 0] - V[:, 2] - P.cracking_pressure) / P.opening_band
        if s.size == 1:         # one valve (the usual): ~1 us against ~7 on arrays
            return np.array([_piece(float(s[0]))], dtype=np.int8)
        with np.errstate(divide="ignore", invalid="ignore"):
            low = np.maximum(np.floor(np.log2(s / REGIME_EDGE) * 0.5), -LOW_PIECES)
        return np.where(s <= 0.0, -LOW_PIECES - 1, np.where(
            s < REGIME_EDGE, low, (s > 1.0 - REGIME_EDGE).astype(float))).astype(np.int8)


    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) for diameter, Cd, Re_laminar (the open passage's
        law, :func:`_loss_law_derivative` or, for a gas, :func:`_nozzle_law_derivative`),
        cracking_pressure, opening_band and leakage; None for others."""
        pa, pb = V[:, 0], V[:, 2]
        fl = P.fluid
        dp = pa - pb
        q_open, _, _, rho = cls._open_flow(P, pa, pb)
        w, dw = smoothstep(dp, P.cracking_pressure, P.cracking_pressure + P.opening_band)
        if name == "cracking_pressure":
            dq = -dw * q_open
        elif name == "opening_band":
            dq = -dw * (dp - P.cracking_pressure) / P.opening_band * q_open
        elif name == "leakage":
            dq = _mean_density(fl, pa, pb)[0] * dp
        elif name in ("diameter", "Cd", "Re_laminar") and P.nozzle:
            dq = w * _nozzle_law_derivative(P, pa, pb, q_open, rho, name)
        elif name in ("diameter", "Cd", "Re_laminar"):
            dq = w * _loss_law_derivative(P, dp, rho, q_open, name)
        else:
            return None
        return _flow_law_jacobian(P, dq)


# ---------------------------------------------------------------------------------------
class TeslaValve(_TubeLike):
    """Fluidic diode: a tube forward (a -> b), ``diodicity`` times more resistive
    backward, as the FONS paper's Tesla valve.

    Forward the pressure drop is :class:`~softflow.components.tubes.CircularTube`'s
    (Hagen–Poiseuille / Haaland, density at the mean pressure), dp_t(mdot).
    Backward, at equal ``|mdot|``, it is Di·dp_t. For a gas the friction term
    D(mdot)·c_mu (f Re) mdot enters the tube's pipe-flow law instead (isothermal;
    adiabatic, Fanno, in a thermal scene of an ideal gas), whose acceleration
    terms the diodicity leaves as they are. The direction is blended on the
    backward side only:

        dp = D(mdot)·dp_t(mdot),  D = 1 + (Di - 1)·(1 - w(mdot)),

    with w the C1 smoothstep from 0 at mdot = -mdot_blend to 1 at mdot = 0
    (mdot_blend: the flow at Reynolds number Re_blend). So dp is exactly the tube
    for mdot >= 0 and Di times it for mdot <= -mdot_blend, passes through zero at
    zero flow, is C1, and is strictly increasing (D >= 1 and mdot·dD/dmdot >= 0),
    so the law has one solution for every dp.

    Parameters
    ----------
    label : str
    fluid : Fluid
    length : float [m]
        Length of the equivalent forward tube.
    diameter : float [m]
        Inner diameter of the equivalent forward tube.
    diodicity : float [-], default 2
        Backward over forward pressure drop at equal flow (Di >= 1; 1 is a tube).
    roughness : float [m], default 1.5e-6
    Re_laminar, Re_turbulent : float [-], default 2300, 4000
        Laminar–turbulent blend of the tube law.
    Re_blend : float [-], default 10
        Reynolds number of backward flow over which the resistance rises from the
        forward to the backward one.
    """

    terminal_spec = TWO_PORTS
    param_names = ("length", "diameter", "roughness", "Re_laminar", "Re_turbulent",
                   "diodicity", "Re_blend")
    jac_pattern = TWO_PORT_PATTERN

    def __init__(self, label: str, fluid: Fluid, length: Scalar, diameter: Scalar,
                 diodicity: float = 2.0, roughness: Scalar = 1.5e-6,
                 Re_laminar: float = 2300.0, Re_turbulent: float = 4000.0,
                 Re_blend: float = 10.0) -> None:
        super().__init__(label)
        self._init_tube(fluid, length, diameter, roughness, Re_laminar, Re_turbulent)
        self.diodicity = self._si(diodicity, "", "diodicity")
        if not self.diodicity >= 1.0:
            raise ValueError(f"{self.describe()}: diodicity must be >= 1 (backward over forward "
                             f"resistance), got {self.diodicity}")
        self.Re_blend = self._si(Re_blend, "", "Re_blend", positive=True)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        set_tube_coefficients(P)
        set_isothermal_law(P, P.fluid.compressible)
        P.mf_blend = P.Re_blend / P.re_per_mf
        set_tube_like_law(P)
        return P

    @classmethod
    def pressure_drop(cls, P, pa, mfa, pb, jac):
        """p_a - p_b required by the flow mfa entering at ``a`` and its partials in
        p_a, mfa, p_b (None without ``jac``): a gas's isothermal pipe-flow law with
        the friction term times D (:func:`softflow.components.tubes.isothermal_drop`),
        else the Darcy law at the mean density. An ideal gas or a liquid runs as
        one compiled pass (:func:`softflow.laws.valves.tesla_drop`); a gas at the
        table or eos level takes p/rho at the mean pressure from its methods."""
        n = P.n
        laws = _valve_laws()
        if P.compiled or not P.isothermal:
            out = np.empty((4, n))
            laws.tesla_drop_array(P.kind, P.Re_lo, P.Re_hi, *_prepared(n, pa, mfa, pb),
                                  P.re_per_mf, P.c_mu, P.eD, P.friction_terms, P.area,
                                  P.mf_blend, P.diodicity, P.law_c2, P.law_rho, *out)
            return tuple(out) if jac else (out[0], None, None, None)
        # a gas whose p/rho comes from its methods: the friction term, compiled,
        # into the tube's isothermal law
        law, dlaw = np.empty(n), np.empty(n)
        laws.tesla_friction_array(P.kind, P.Re_lo, P.Re_hi, _flat(mfa, n), P.re_per_mf, P.eD,
                                  P.friction_terms, P.mf_blend, P.diodicity, law, dlaw)
        return isothermal_drop(P, pa, mfa, pb, P.c_mu * law, P.c_mu * dlaw if jac else None,
                               None, jac)

    @classmethod
    def thermal_drop(cls, P, pa, mfa, pb, T_up, jac):
        """In a thermal scene, for an ideal gas: the adiabatic (Fanno) pipe-flow
        law with the valve's friction term (:func:`softflow.components.tubes.adiabatic_drop`),
        p_a - p_b required and its partials in p_a, mfa, p_b and the upstream
        temperature, in one compiled pass (:func:`softflow.laws.valves.tesla_adiabatic_drop`);
        None otherwise (the thermal variant scales the isothermal law)."""
        if P.R_gas is None:
            return None
        n = P.n
        out = np.empty((5, n))
        _valve_laws().tesla_adiabatic_drop_array(
            P.kind, P.Re_lo, P.Re_hi, *_prepared(n, pa, mfa, pb, T_up), P.re_per_mf, P.c_mu,
            P.eD, P.friction_terms, P.area, P.mf_blend, P.diodicity, P.R_gas, P.gamma, *out)
        return tuple(out) if jac else (out[0], None, None, None, None)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if P.compiled or not P.isothermal:
            # the law in one compiled pass (laws.valves.tesla_residual)
            F = np.empty((P.n, 2))
            J = np.empty((P.n, 5)) if jac else _NO_JACOBIAN
            _valve_laws().tesla_residual(P.kind, P.Re_lo, P.Re_hi, V, P.re_per_mf, P.c_mu,
                                         P.eD, P.friction_terms, P.area, P.mf_blend,
                                         P.diodicity, P.law_c2, P.law_rho, F, J, jac)
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
        J[:, 2], J[:, 3], J[:, 4] = 1.0 - d_pa, -d_mf, -1.0 - d_pb
        return F, J

    @classmethod
    def _friction_parameter_derivative(cls, P, V, name, c):
        """(c (f Re) mdot D, its derivative in theta) for length, diameter,
        roughness, diodicity, Re_blend (the blend's width scales the flow
        mf_blend ∝ Re_blend·D) and the laminar-turbulent bounds; None for
        others. ``c``: c_mu (the gas laws' friction term) or c_mu/rho (the
        Darcy law's pressure drop)."""
        mfa = V[:, 1]
        w, dw = smoothstep(mfa, -P.mf_blend, 0.0)
        extra = P.diodicity - 1.0
        mult = 1.0 + extra * (1.0 - w)
        geometry = name in TUBE_GEOMETRY
        d_tube, dp = _tube_drop_derivative(P, name if geometry else "length", c, mfa)
        # d mult / d(mf_blend) · mf_blend: mult moves with the blend's width
        d_blend = dp * extra * mfa * dw
        if geometry:
            d = mult * d_tube + (d_blend / P.diameter if name == "diameter" else 0.0)
        elif name == "diodicity":
            d = dp * (1.0 - w)
        elif name == "Re_blend":
            d = d_blend / P.Re_blend
        elif name in BLEND_BOUNDS:
            Re = np.abs(mfa) * P.re_per_mf
            d = c * mfa * mult * friction_bound_derivative(P, Re, name)
        else:
            return None
        return dp * mult, d

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) for length, diameter, roughness, diodicity,
        Re_blend and the laminar-turbulent bounds Re_laminar, Re_turbulent."""
        pa, pb = V[:, 0], V[:, 2]
        # the gas law takes the friction term itself (c_mu), the Darcy law over rho
        c = P.c_mu if P.isothermal else P.c_mu / _mean_density(P.fluid, pa, pb)[0]
        out = cls._friction_parameter_derivative(P, V, name, c)
        if out is None:
            return None
        Phi, d = out
        if P.isothermal:
            d = isothermal_drop_parameter_derivative(P, V, Phi, d, name)
        return _flow_law_jacobian(P, d)

    @classmethod
    def thermal_drop_parameter_derivative(cls, P, V, T_up, name):
        """d(p_a - p_b required)/d theta of :meth:`thermal_drop`; None where that
        is not the adiabatic law or for other parameters."""
        if P.R_gas is None:
            return None
        out = cls._friction_parameter_derivative(P, V, name, P.c_mu)
        if out is None:
            return None
        return isothermal_drop_parameter_derivative(P, V, out[0], out[1], name, T_up)


# ---------------------------------------------------------------------------------------
class SnappingValve(_TubeLike):
    """Hysteretic snapping valve (the FONS paper's Fig. 4, green): closed until
    dp = p_a - p_b exceeds ``opening_pressure``, then open until dp falls below
    ``closing_pressure``.

    Closed, it is a tight linear restrictor in both directions,
    mdot = rho(p_mean) · closed_conductance · dp: on inflation pressure builds
    up behind it until it snaps open and releases a burst; on deflation (dp < 0,
    below the closing threshold) it stays closed and acts as a tight restrictor,
    as in the paper. Open, it is a low-resistance tube (``length``,
    ``diameter``; the CircularTube law, both directions: a gas's pipe-flow law,
    adiabatic in a thermal scene of an ideal gas).

    The mode is the discrete state ``open`` (0 or 1): each step uses the mode
    from its start, and :meth:`switch` changes it from the converged dp at the
    end of the step, so results do not depend on Newton's iterates. Read it as
    ``result.get(label, 'open')``: the value recorded at t is the mode decided
    from dp at t, used by the step that follows.

    For a closed valve equal to a laminar tube of length L and diameter D, take
    closed_conductance = pi D^4 / (128 mu L).

    Parameters
    ----------
    label : str
    fluid : Fluid
    opening_pressure : float [Pa]
        Pressure difference p_a - p_b above which the closed valve opens (> 0).
    closing_pressure : float [Pa]
        Pressure difference below which the open valve closes (< opening_pressure;
        may be negative).
    closed_conductance : float [m^3/(s Pa)]
        Volume-flow conductance of the closed valve (> 0).
    length : float [m], default 0.01
        Length of the open flow passage.
    diameter : float [m], default 0.002
        Diameter of the open flow passage.
    initially_open : bool, default False
    roughness : float [m], default 1.5e-6
    Re_laminar, Re_turbulent : float [-], default 2300, 4000
    """

    terminal_spec = TWO_PORTS
    state_spec = (("open", "dimensionless"),)
    discrete_states = ("open",)
    param_names = ("length", "diameter", "roughness", "Re_laminar", "Re_turbulent",
                   "opening_pressure", "closing_pressure", "closed_conductance")
    jac_pattern = TWO_PORT_PATTERN

    def __init__(self, label: str, fluid: Fluid, opening_pressure: Scalar,
                 closing_pressure: Scalar, closed_conductance: Scalar, length: Scalar = 0.01,
                 diameter: Scalar = 0.002, initially_open: bool = False,
                 roughness: Scalar = 1.5e-6, Re_laminar: float = 2300.0,
                 Re_turbulent: float = 4000.0) -> None:
        super().__init__(label)
        self._init_tube(fluid, length, diameter, roughness, Re_laminar, Re_turbulent)
        self.opening_pressure = self._si(opening_pressure, "Pa", "opening_pressure",
                                         positive=True)
        self.closing_pressure = self._si(closing_pressure, "Pa", "closing_pressure")
        if not self.closing_pressure < self.opening_pressure:
            raise ValueError(f"{self.describe()}: closing_pressure ({self.closing_pressure} Pa) "
                             f"must be below opening_pressure ({self.opening_pressure} Pa) for "
                             "the valve to have hysteresis")
        self.closed_conductance = self._si(closed_conductance, "m**3/(s*Pa)",
                                           "closed_conductance", positive=True)
        self.initially_open = bool(initially_open)

    def initial_states(self):
        return [1.0 if self.initially_open else 0.0]

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        set_tube_coefficients(P)
        set_isothermal_law(P, P.fluid.compressible)
        set_tube_like_law(P)
        return P

    @classmethod
    def switch(cls, P, V, S):
        if P.n == 1:
            # one valve (the usual): on its floats, the array path's numbers
            dp = V[0, 0] - V[0, 2]
            mode = (1.0 if dp > P.opening_pressure[0] else
                    0.0 if dp < P.closing_pressure[0] else S[0, 0])
            return np.array([[mode]])
        dp = V[:, 0] - V[:, 2]
        mode = np.where(dp > P.opening_pressure, 1.0,
                        np.where(dp < P.closing_pressure, 0.0, S[:, 0]))
        return mode[:, None]

    @classmethod
    def switching(cls, P, V, S):
        """Closed: dp - opening_pressure; open: closing_pressure - dp."""
        dp = V[:, 0] - V[:, 2]
        return np.where(S[:, 0] > 0.5, P.closing_pressure - dp,
                        dp - P.opening_pressure)[:, None]

    @classmethod
    def switching_jacobian(cls, P, V, S):
        """d(switching)/dV (n, 1, 4) and d/dS (n, 1, 1) of :meth:`switching`: +-1
        on p_a and p_b (sensitivities across a switch, softflow.solve.sensitivity)."""
        sign = np.where(S[:, 0] > 0.5, -1.0, 1.0)
        GV = np.zeros((P.n, 1, V.shape[1]))
        GV[:, 0, 0], GV[:, 0, 2] = sign, -sign
        return GV, np.zeros((P.n, 1, S.shape[1]))

    @classmethod
    def switching_param_jacobian(cls, P, V, S, name):
        """d(switching)/d theta (n, 1): -1 (closed) for opening_pressure, +1 (open)
        for closing_pressure, 0 for the parameters of the flow laws."""
        is_open = S[:, 0] > 0.5
        if name == "opening_pressure":
            return np.where(is_open, 0.0, -1.0)[:, None]
        if name == "closing_pressure":
            return np.where(is_open, 1.0, 0.0)[:, None]
        return np.zeros((P.n, 1))

    @classmethod
    def residual(cls, P, V, S, t, jac):
        """Mass balance and the flow law of each valve's mode, in one compiled
        pass (:func:`softflow.laws.valves.snapping_residual`): open, the
        passage's tube law (a gas's isothermal pipe flow, a liquid's Darcy law),
        closed, the linear restrictor, both at the mean density. A gas at the
        table or eos level (:func:`set_density_law`) gives the pass its
        densities from its methods, and its open valves take the tube's
        isothermal law with p/rho from them
        (:func:`softflow.components.tubes.isothermal_drop`)."""
        laws = _valve_laws()
        n = P.n
        given = not P.compiled
        rho_m = drho_m = _NONE
        if given:
            rho_m, drho_m = _given_density(P, (V[:, 0], V[:, 2]), mean=True)
        F = np.empty((n, 2))
        J = np.empty((n, 5)) if jac else _NO_JACOBIAN
        laws.snapping_residual(P.kind, P.Re_lo, P.Re_hi, V, S, P.re_per_mf, P.c_mu, P.eD,
                               P.friction_terms, P.area, P.closed_conductance, P.law_c2,
                               P.law_RT, P.law_rho, given, rho_m, drho_m, F, J, jac)
        is_open = S[:, 0] > 0.5 if given and P.isothermal else None
        if is_open is not None and is_open.any():
            # open with a gas of the table or eos level: the tube's isothermal
            # pipe-flow law, its friction term compiled
            pa, mfa, pb = V[:, 0], V[:, 1], V[:, 2]
            Phi, dPhi = np.empty(n), np.empty(n)
            laws.friction_term_array(P.kind, P.Re_lo, P.Re_hi, _flat(mfa, n), P.re_per_mf,
                                     P.c_mu, P.eD, P.friction_terms, Phi, dPhi)
            dp, d_pa, d_mf, d_pb = isothermal_drop(P, pa, mfa, pb, Phi, dPhi, None, jac)
            F[:, 1] = np.where(is_open, (pa - pb) - dp, F[:, 1])
            if jac:
                J[:, 2] = np.where(is_open, 1.0 - d_pa, J[:, 2])
                J[:, 3] = np.where(is_open, -d_mf, J[:, 3])
                J[:, 4] = np.where(is_open, -1.0 - d_pb, J[:, 4])
        return F, (J if jac else None)

    @classmethod
    def thermal_rows(cls, P, V, S, T_up, jac):
        """In a thermal scene, for an ideal gas: (open, dp, its partials in p_a,
        mfa, p_b and T_up) of the open passage's adiabatic (Fanno) pipe-flow law
        (:func:`softflow.components.tubes.adiabatic_drop`), for the instances
        ``open`` (the closed restrictor keeps its law scaled by the upstream
        temperature); None otherwise."""
        if P.R_gas is None:
            return None
        # the tube's law in one compiled pass (laws.tube.adiabatic_drop_array)
        n = P.n
        out = np.empty((5, n))
        _tube_laws().adiabatic_drop_array(P.kind, P.Re_lo, P.Re_hi,
                                          *_prepared(n, V[:, 0], V[:, 1], V[:, 2], T_up),
                                          P.re_per_mf, P.c_mu, P.eD, P.friction_terms, P.area,
                                          P.R_gas, P.gamma, P.kre, *out)
        return (S[:, 0] > 0.5, *(out if jac else (out[0], None, None, None, None)))

    @classmethod
    def thermal_rows_parameter_derivative(cls, P, V, S, T_up, name):
        """(open, d(p_a - p_b required)/d theta) of :meth:`thermal_rows`' law: the
        open passage's geometry and blend bounds through its friction term, none
        for the closed restrictor's and the switch's parameters; None where
        that law does not apply."""
        if P.R_gas is None:
            return None
        mfa = V[:, 1]
        if name in TUBE_GEOMETRY:
            Phi_theta, Phi = _tube_drop_derivative(P, name, P.c_mu, mfa)
        elif name in BLEND_BOUNDS:
            Re, phi, _ = _tube_fRe(P, mfa)
            Phi_theta = P.c_mu * mfa * friction_bound_derivative(P, Re, name)
            Phi = P.c_mu * phi * mfa
        else:
            return S[:, 0] > 0.5, np.zeros(P.n)
        return S[:, 0] > 0.5, isothermal_drop_parameter_derivative(P, V, Phi, Phi_theta, name,
                                                                   T_up)

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) for the open passage's length, diameter and
        roughness, the closed_conductance, and the opening and closing pressures
        (0 in the equations: they act through the switch time, which the
        sensitivities carry with :meth:`switching_param_jacobian` under BDF) and
        the open passage's laminar-turbulent bounds."""
        pa, mfa, pb = V[:, 0], V[:, 1], V[:, 2]
        is_open = S[:, 0] > 0.5
        rho = _mean_density(P.fluid, pa, pb)[0]
        # the open passage's law: the gas law takes the friction term itself (c_mu)
        c = P.c_mu if P.isothermal else P.c_mu / rho
        if name in TUBE_GEOMETRY:
            d_open, dp = _tube_drop_derivative(P, name, c, mfa)
        elif name in BLEND_BOUNDS:
            Re = np.abs(mfa) * P.re_per_mf
            d_open, dp = c * mfa * friction_bound_derivative(P, Re, name), None
        elif name == "closed_conductance":
            return _flow_law_jacobian(
                P, np.where(is_open, 0.0, -mfa / (P.closed_conductance ** 2 * rho)))
        elif name in ("opening_pressure", "closing_pressure"):
            return _flow_law_jacobian(P, np.zeros(P.n))
        else:
            return None
        if P.isothermal:
            Phi = dp if dp is not None else c * _tube_fRe(P, mfa, P.friction_terms)[1] * mfa
            d_open = isothermal_drop_parameter_derivative(P, V, Phi, d_open, name)
        return _flow_law_jacobian(P, np.where(is_open, d_open, 0.0))
