"""Volumes that store fluid: rigid containers and linear accumulators."""
from __future__ import annotations

import functools
import inspect

from typing import TYPE_CHECKING

import numpy as np

from .._laws import law_module
from ..constants import pressure_atmospheric
from ..fluids.ideal import ConstantLiquid, IdealGas
from ..solve.thermal import THERMAL_VOLUME_DOC, thermal_volume_fields
from .base import FLUID_PORT, LibraryComponent, Params

if TYPE_CHECKING:
    from .._typing import HeatTransfer, Scalar
    from ..fluids.base import Fluid


#: dm/dt = mdot: the mass rate of a one-terminal volume depends on its mass flow (V[:, 1])
MASS_RATE_PATTERN = ((0, 1),)


def accumulator_volume(P, p):
    """The fluid volume of a linear accumulator at pressure p [m^3]: volume +
    compliance (p - reference_pressure). ``P``: its Params, or the component."""
    return P.volume + P.compliance * (p - P.reference_pressure)


#: the Jacobian argument of a compiled pass evaluated without one
NO_JACOBIAN = np.empty((0, 3))


volume_laws = functools.partial(law_module, "volumes")


def set_fluid_law(P):
    """How the group's compiled pass gets its fluid's density: ``P.rho_kind``
    and ``P.rho_c``, an ideal gas at its own temperature (R T: rho = p / (R T))
    or a liquid of constant density (rho), whose densities the pass computes
    itself, else densities given per instance from the fluid's own methods
    (table and eos levels, a custom fluid): the codes of
    :mod:`softflow.laws.volumes`, written out here so that making the Params
    does not import numba."""
    methods = type(P.fluid)
    if (methods.density is IdealGas.density and methods.density_dp is IdealGas.density_dp
            and isinstance(P.fluid, IdealGas)):
        P.rho_kind, P.rho_c = 0, float(P.fluid._RT)          # volumes.IDEAL_GAS
    elif (methods.density is ConstantLiquid.density
          and methods.density_dp is ConstantLiquid.density_dp
          and isinstance(P.fluid, ConstantLiquid)):
        P.rho_kind, P.rho_c = 1, float(P.fluid.rho0)         # volumes.CONSTANT_LIQUID
    else:
        P.rho_kind, P.rho_c = 2, 0.0                         # volumes.GIVEN
    return P


def given_densities(P, p, jac):
    """(rho, d rho/dp) of the group's fluid at p from its own methods, for a
    compiled pass of a fluid whose properties come from Python (else the
    pressures, unread); d rho/dp only with ``jac`` (else rho again)."""
    if P.rho_kind != 2:
        return p, p
    rho = P.fluid.density(p)
    return rho, (P.fluid.density_dp(p) if jac else rho)


def mass_rates(P, V, jac):
    """The mass balance of a one-terminal volume, dm/dt = mdot (the mass flow
    into its terminal), and its derivative: the one law every volume shares."""
    return V[:, 1:2], ((1.0,) if jac else None)


def _given(comp, name):
    """Whether the constructor argument ``name`` was given (not None) when
    ``comp`` was made."""
    args, kwargs = comp.__dict__.get("_definition", ((), {}))
    bound = inspect.signature(type(comp).__init__).bind(comp, *args, **kwargs)
    return bound.arguments.get(name) is not None


def initial_mass_jacobian(comp, name):
    """d(initial mass)/d theta of m0 = rho(p0)·V0 from the volume's initial point's
    derivatives (dp0/d theta, dV0/d theta) (:meth:`_initial_point_jacobian`, the one
    place each class states how its parameters move p0 and V0), or None."""
    d = comp._initial_point_jacobian(name)
    if d is None:
        return None
    from .thermal import initial_fluid_volume
    p0 = comp.initial_pressure
    return [float(comp.fluid.density_dp(p0)) * d[0] * initial_fluid_volume(comp)
            + float(comp.fluid.density(p0)) * d[1]]


def _volume_law_jacobian(P, V, name, dvolume, rigid_liquid=False):
    """(dF/d theta, dr/d theta) of a volume's law F = rho(p)·V_fluid - m, given
    d V_fluid/d theta per parameter name (``dvolume``); initial_pressure only
    sets the initial mass (0 here); None for other names. A rigid chamber of
    liquid (F = mdot) has none."""
    if name == "initial_pressure" or rigid_liquid and name in dvolume:
        return np.zeros((P.n, 1)), np.zeros((P.n, 1))
    if name not in dvolume:
        return None
    dF = P.fluid.density(V[:, 0]) * dvolume[name]
    return np.broadcast_to(dF, (P.n,))[:, None], np.zeros((P.n, 1))


class Container(LibraryComponent):
    """Rigid chamber with one terminal ``a``.

    A compressible fluid is stored as mass m (state, dm/dt = mdot) with
    density(p) · volume = m. With an incompressible fluid a rigid chamber
    admits no flow (mdot = 0).

    Parameters
    ----------
    label : str
    fluid : Fluid
    volume : float [m^3]
    initial_pressure : float [Pa], default 1 atm
        Absolute pressure at t = 0 (sets the initial mass; an evacuated tank is
        a volume at, say, 1 kPa).
    """

    terminal_spec = (("a", FLUID_PORT),)
    state_spec: tuple = (("mass", "mass"),)
    param_names = ("volume",)
    jac_pattern: tuple = ((0, 0), (0, 1))
    state_jac_pattern = ((0, 0),)
    rate_pattern = MASS_RATE_PATTERN

    def __init__(self, label: str, fluid: Fluid, volume: Scalar,
                 initial_pressure: Scalar = pressure_atmospheric, *,
                 thermal: str | None = None, initial_temperature: Scalar | None = None,
                 wall_temperature: Scalar | None = None,
                 heat_transfer_coefficient: HeatTransfer | None = None,
                 area: Scalar | None = None, hA: Scalar | None = None) -> None:
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        self.volume = self._si(volume, "m**3", "volume", positive=True)
        self.initial_pressure = self._si(initial_pressure, "Pa", "initial_pressure",
                                         positive=True)
        self.terminals[0].own_variable(0).initial_value = self.initial_pressure
        self._check_fluid_state(self.initial_pressure, "initial_pressure")
        thermal_volume_fields(self, initial_temperature, wall_temperature,
                              heat_transfer_coefficient, area, hA, thermal)

    def initial_states(self):
        return [float(self.fluid.density(self.initial_pressure)) * self.volume]

    def outputs(self):
        if self._thermal is not None:      # gas temperature, internal energy, work
            from .thermal import volume_outputs
            return volume_outputs(self)
        vol = self.volume
        return {"volume": ("volume", lambda get: np.full(np.shape(get("mass")), vol))}

    @staticmethod
    def volume_jacobian(P, p):
        """{parameter: d(fluid volume)/d theta} of the rigid wall (volume)."""
        return {"volume": 1.0}

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) for volume (F = rho(p)·volume - m) and
        initial_pressure (0: it sets the initial mass only); None for others."""
        return _volume_law_jacobian(P, V, name, cls.volume_jacobian(P, V[:, 0]),
                                    rigid_liquid=not P.fluid.compressible)

    def _initial_point_jacobian(self, name):
        """(dp0/d theta, dV0/d theta) of the initial pressure and fluid volume, or None."""
        return {"volume": (0.0, 1.0), "initial_pressure": (1.0, 0.0)}.get(name)

    def initial_state_jacobian(self, name):
        """d(initial mass)/d theta of m0 = rho(p0)·volume, or None."""
        return initial_mass_jacobian(self, name)

    @classmethod
    def make_params(cls, components):
        return set_fluid_law(Params(components))

    @classmethod
    def rates(cls, P, V, S, jac):
        return mass_rates(P, V, jac)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if not P.fluid.compressible:
            # a rigid chamber of liquid admits no flow (its mass stays the initial one)
            F = V[:, 1:2].copy()
            return F, (np.tile([0.0, 1.0, 0.0], (P.n, 1)) if jac else None)
        # F = rho(p) volume - m in one compiled pass (laws.volumes.rigid_residual)
        rho, rho_p = given_densities(P, V[:, 0], jac)
        F = np.empty((P.n, 1))
        J = np.empty((P.n, 3)) if jac else NO_JACOBIAN
        volume_laws().rigid_residual(P.rho_kind, P.rho_c, P.volume, V, S, rho, rho_p, F, J, jac)
        return F, (J if jac else None)


class LinearAccumulator(LibraryComponent):
    """Compliant chamber whose fluid volume grows linearly with pressure:
    V(p) = volume + compliance · (p - reference_pressure), terminal ``a``.

    The stored mass m (state, dm/dt = mdot) satisfies m = density(p) · V(p). With water and a
    laminar tube it forms the fluidic RC circuit (tau = R·C).

    Parameters
    ----------
    label : str
    fluid : Fluid
    volume : float [m^3]
        Fluid volume at the reference pressure.
    compliance : float [m^3/Pa]
        dV/dp.
    reference_pressure : float [Pa], default 1 atm
    initial_pressure : float [Pa], default reference_pressure
    """

    terminal_spec = (("a", FLUID_PORT),)
    state_spec: tuple = (("mass", "mass"),)
    param_names = ("volume", "compliance", "reference_pressure")
    jac_pattern: tuple = ((0, 0), (0, 1))
    residual_pattern: tuple | None = ((0, 0),)
    state_jac_pattern = ((0, 0),)
    rate_pattern = MASS_RATE_PATTERN

    def __init__(self, label: str, fluid: Fluid, volume: Scalar, compliance: Scalar,
                 reference_pressure: Scalar = pressure_atmospheric,
                 initial_pressure: Scalar | None = None, *, thermal: str | None = None,
                 initial_temperature: Scalar | None = None,
                 wall_temperature: Scalar | None = None,
                 heat_transfer_coefficient: HeatTransfer | None = None,
                 area: Scalar | None = None, hA: Scalar | None = None) -> None:
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        self.volume = self._si(volume, "m**3", "volume", positive=True)
        self.compliance = self._si(compliance, "m**4*s**2/kg", "compliance", positive=True)
        self.reference_pressure = self._si(reference_pressure, "Pa", "reference_pressure",
                                           positive=True)
        p0 = reference_pressure if initial_pressure is None else initial_pressure
        self.initial_pressure = self._si(p0, "Pa", "initial_pressure", positive=True)
        if self._fluid_volume(self.initial_pressure) <= 0:
            raise ValueError(f"{self.describe()}: the fluid volume at initial_pressure is <= 0")
        self.terminals[0].own_variable(0).initial_value = self.initial_pressure
        self._check_fluid_state(self.initial_pressure, "initial_pressure")
        thermal_volume_fields(self, initial_temperature, wall_temperature,
                              heat_transfer_coefficient, area, hA, thermal)

    def _fluid_volume(self, p):
        return accumulator_volume(self, p)

    def initial_states(self):
        p = self.initial_pressure
        return [float(self.fluid.density(p)) * self._fluid_volume(p)]

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) of F = rho(p)·(volume + compliance (p - p_ref)) - m
        for volume, compliance and reference_pressure, and initial_pressure (0);
        None for others."""
        return _volume_law_jacobian(P, V, name, cls.volume_jacobian(P, V[:, 0]))

    @staticmethod
    def volume_jacobian(P, p):
        """{parameter: d(fluid volume)/d theta} of vol = volume + compliance (p - p_ref)."""
        return {"volume": 1.0, "compliance": p - P.reference_pressure,
                "reference_pressure": -P.compliance}

    def _initial_point_jacobian(self, name):
        """(dp0/d theta, dV0/d theta) of the initial pressure p0 and fluid volume
        V0 = volume + compliance (p0 - p_ref) for volume, compliance,
        reference_pressure and initial_pressure (p0 is p_ref where
        initial_pressure was not given: then they move together), or None."""
        p0, pref, C = self.initial_pressure, self.reference_pressure, self.compliance
        if name == "volume":
            return 0.0, 1.0
        if name == "compliance":
            return 0.0, p0 - pref
        if name == "reference_pressure":
            return (0.0, -C) if _given(self, "initial_pressure") else (1.0, 0.0)
        if name == "initial_pressure":       # (given from then on, if it was not)
            return 1.0, C
        return None

    def initial_state_jacobian(self, name):
        """d(initial mass)/d theta of m0 = rho(p0)·V0 (:meth:`_initial_point_jacobian`),
        or None."""
        return initial_mass_jacobian(self, name)

    @classmethod
    def make_params(cls, components):
        return set_fluid_law(Params(components))

    @classmethod
    def rates(cls, P, V, S, jac):
        return mass_rates(P, V, jac)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        # F = rho(p) (volume + compliance (p - p_ref)) - m in one compiled pass
        # (laws.volumes.compliant_residual)
        rho, rho_p = given_densities(P, V[:, 0], jac)
        F = np.empty((P.n, 1))
        J = np.empty((P.n, 2)) if jac else NO_JACOBIAN
        volume_laws().compliant_residual(P.rho_kind, P.rho_c, P.volume, P.compliance,
                                         P.reference_pressure, V, S, rho, rho_p, F, J, jac)
        return F, (J if jac else None)

    def outputs(self):
        if self._thermal is not None:      # gas temperature, internal energy, work
            from .thermal import volume_outputs
            return volume_outputs(self)
        fl = self.fluid
        return {"volume": ("volume", lambda get: get("mass") / fl.density(get("pressure")))}


if Container.__doc__:   # None under python -OO
    Container.__doc__ += THERMAL_VOLUME_DOC
if LinearAccumulator.__doc__:   # None under python -OO
    LinearAccumulator.__doc__ += THERMAL_VOLUME_DOC
