"""The 'ideal' fidelity level: ideal gas with constant cp, or a constant-property
liquid (the FONS paper's model, the fastest).

The built-ins ``air``, ``nitrogen``, ``water`` and ``ethylene_glycol`` are at this
level, with constants that CoolProp 8.0 gives at 20 degC and 1 atm (written out
below so that importing softflow does not import CoolProp; a test checks them).
``fluid.at(temperature=...)`` re-evaluates the constants at another temperature;
``fluid.with_level('table')`` or ``'eos'`` switches to real-fluid properties.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..constants import gas_constant, pressure_atmospheric, temperature_standard
from ..units import to_si
from .base import Fluid, FluidError, check_temperature
from .catalog import BUILTIN

if TYPE_CHECKING:
    from .._typing import Array, Scalar, SIArrayLike
    from .catalog import FluidSpec


def _const(value: float, p: SIArrayLike, T: SIArrayLike | None = None) -> Any:
    """value broadcast to the shape of (p, T): a float for scalar input (float | Array:
    Any, as the Fluid protocol's methods that return it declare Array)."""
    shape = np.shape(p)
    if T is not None:
        shape_T = np.shape(T)
        if shape_T != shape:   # broadcast_shapes only when needed: kernels call this a lot
            shape = np.broadcast_shapes(shape, shape_T)
    if not shape:
        return float(value)
    out = np.empty(shape)      # empty + fill: a few microseconds less than np.full
    out.fill(value)
    return out


def _T(fluid: Fluid, p: SIArrayLike, T: SIArrayLike | None) -> Any:
    # T=None: the fluid's temperature, broadcast to p's shape
    return _const(fluid.temperature, p) if T is None else np.asarray(T, dtype=float)


class IdealGas(Fluid):
    """Ideal gas with constant cp and viscosity: rho = p / (R T).

    Enthalpy is linear in T through the reference point (the fluid's temperature,
    ``enthalpy_reference``): h = h_ref + cp (T - T_fluid), u = h - R T.

    Parameters
    ----------
    name : str
    molar_mass : float [kg/mol]
    viscosity : float [Pa s]
    temperature : float [K]
    gamma : float [-], optional
        Ratio of specific heats (default 1.4 unless ``cp`` is given).
    cp : float [J/(kg K)], optional
        Specific isobaric heat capacity; give cp or gamma, not both.
    enthalpy_reference : float [J/kg], optional
        Specific enthalpy at the fluid's temperature (default cp * temperature).
    conductivity : float [W/(m K)], optional
        Thermal conductivity, constant (needed only by heat-transfer correlations).
    spec : FluidSpec, optional
        Catalog entry the constants came from (enables ``at`` and ``with_level``).
    """

    compressible = True
    level = "ideal"

    def __init__(self, name: str, molar_mass: Scalar, viscosity: Scalar,
                 temperature: Scalar = temperature_standard, gamma: Scalar | None = None, *,
                 cp: Scalar | None = None, enthalpy_reference: Scalar | None = None,
                 conductivity: Scalar | None = None, spec: FluidSpec | None = None) -> None:
        owner = f"IdealGas {name!r}"
        self.name, self.spec = name, spec  # type: ignore[assignment]  # Fluid.spec = None
        self.k = _optional_positive(conductivity, "W/m/K", "conductivity", owner)
        self.molar_mass = to_si(molar_mass, "kg/mol", name="molar_mass", owner=owner)
        self.mu = to_si(viscosity, "Pa*s", name="viscosity", owner=owner)
        self.temperature = check_temperature(temperature, owner)
        if not (self.molar_mass > 0 and self.mu > 0):
            raise FluidError(f"{owner}: need molar_mass > 0 and viscosity > 0, got "
                             f"{self.molar_mass} kg/mol and {self.mu} Pa s")
        self.R = gas_constant / self.molar_mass
        if cp is not None and gamma is not None:
            raise FluidError(f"{owner}: give cp or gamma, not both")
        if cp is not None:
            self.cp0 = to_si(cp, "J/kg/K", name="cp", owner=owner)
            if not self.cp0 > self.R:
                raise FluidError(f"{owner}: cp must exceed R = {self.R:.6g} J/(kg K), "
                                 f"got {self.cp0}")
            self.gamma0 = self.cp0 / (self.cp0 - self.R)
        else:
            self.gamma0 = 1.4 if gamma is None else to_si(gamma, "", name="gamma", owner=owner)
            if not self.gamma0 > 1:
                raise FluidError(f"{owner}: gamma must be > 1, got {self.gamma0}")
            self.cp0 = self.gamma0 * self.R / (self.gamma0 - 1.0)
        self.cv0 = self.cp0 - self.R
        self.h_ref = (self.cp0 * self.temperature if enthalpy_reference is None else
                      to_si(enthalpy_reference, "J/kg", name="enthalpy_reference", owner=owner))
        self._RT = self.R * self.temperature

    def density(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        RT = self._RT if T is None else self.R * np.asarray(T)
        return p / RT

    def density_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if T is None:
            return _const(1.0 / self._RT, p)
        return _const(1.0, p) / (self.R * np.asarray(T, dtype=float))

    def density_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        T = _T(self, p, T)
        return -p / (self.R * T * T)  # type: ignore[operator]  # p: a float or an ndarray

    def viscosity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self.mu, p, T)

    def conductivity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(_conductivity(self), p, T)

    def cp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self.cp0, p, T)

    def cv(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self.cv0, p, T)

    def gamma(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self.gamma0, p, T)

    def enthalpy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.h_ref + self.cp0 * (_T(self, p, T) - self.temperature) + _const(0.0, p, T)

    def enthalpy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(0.0, p, T)

    def enthalpy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.cp(p, T)

    def internal_energy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        T = _T(self, p, T)
        return (self.h_ref + self.cp0 * (T - self.temperature)  # type: ignore[operator]
                - self.R * T + _const(0.0, p))                   # (T: a float or an ndarray)

    def internal_energy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.enthalpy_dp(p, T)

    def internal_energy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.cv(p, T)

    # -- private fast paths for the thermal kernels: value and derivatives in one
    # call, arrays p and T of one shape in, constant derivatives as plain floats
    # (they broadcast); the public methods above stay array in -> array out.
    def _enthalpy_linear(self) -> tuple[float, float]:
        """(cp, c) with h(p, T) = cp T + c for every p [J/(kg K), J/kg]."""
        return self.cp0, self.h_ref - self.cp0 * self.temperature

    def _internal_energy_parts(self, p: Array, T: Array, jac: bool
                               ) -> tuple[Array, float, float]:
        """(u, du/dp, du/dT) [J/kg, J/(kg Pa), J/(kg K)]."""
        return self.cv0 * T + (self.h_ref - self.cp0 * self.temperature), 0.0, self.cv0

    def _density_parts(self, p: Array, T: Array, jac: bool
                       ) -> tuple[Array, Array | None, Array | None]:
        """(rho, drho/dp, drho/dT) [kg/m^3, kg/(m^3 Pa), kg/(m^3 K)]; derivatives only with jac."""
        RT = self.R * T
        rho = p / RT
        if not jac:
            return rho, None, None
        return rho, 1.0 / RT, -rho / T

    def speed_of_sound(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return np.sqrt(self.gamma0 * self.R * _T(self, p, T)) + _const(0.0, p)

    def compressibility(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(1.0, p, T)

    def at(self, temperature: Scalar | None = None, *,
           fraction: float | None = None) -> Fluid:
        if self.spec is not None:
            return super().at(temperature, fraction=fraction)
        T = self.temperature if temperature is None else _kelvin(temperature, self)
        # same h(T) function: the reference moves with the temperature it belongs to
        return IdealGas(self.name, self.molar_mass, self.mu, T, cp=self.cp0,
                        enthalpy_reference=float(self.enthalpy(pressure_atmospheric, T)),
                        conductivity=self.k)


class ConstantLiquid(Fluid):
    """Incompressible liquid with constant density, viscosity and heat capacity.

    u = h_ref - p_atm/rho + c (T - T_fluid) and h = u + p/rho, so h equals
    ``enthalpy_reference`` at 1 atm and the fluid's temperature; cv = cp = c.

    Parameters
    ----------
    name : str
    density : float [kg/m^3]
    viscosity : float [Pa s]
    temperature : float [K]
    cp : float [J/(kg K)], optional
        Specific heat capacity (needed only by thermal properties).
    enthalpy_reference : float [J/kg], optional
        Specific enthalpy at 1 atm and the fluid's temperature (default cp * temperature).
    conductivity : float [W/(m K)], optional
        Thermal conductivity (needed only by heat-transfer correlations).
    spec : FluidSpec, optional
        Catalog entry the constants came from (enables ``at`` and ``with_level``).
    """

    compressible = False
    level = "ideal"

    def __init__(self, name: str, density: Scalar, viscosity: Scalar,
                 temperature: Scalar = temperature_standard, *, cp: Scalar | None = None,
                 enthalpy_reference: Scalar | None = None, conductivity: Scalar | None = None,
                 spec: FluidSpec | None = None) -> None:
        owner = f"ConstantLiquid {name!r}"
        self.name, self.spec = name, spec  # type: ignore[assignment]  # Fluid.spec = None
        self.k = _optional_positive(conductivity, "W/m/K", "conductivity", owner)
        self.rho0 = to_si(density, "kg/m**3", name="density", owner=owner)
        self.mu = to_si(viscosity, "Pa*s", name="viscosity", owner=owner)
        self.temperature = check_temperature(temperature, owner)
        if self.rho0 <= 0 or self.mu <= 0:
            raise FluidError(f"{owner}: density and viscosity must be > 0, got "
                             f"{self.rho0} kg/m^3 and {self.mu} Pa s")
        self.c = None if cp is None else to_si(cp, "J/kg/K", name="cp", owner=owner)
        if self.c is not None and not self.c > 0:
            raise FluidError(f"{owner}: cp must be > 0, got {self.c}")
        self.h_ref = None
        if self.c is not None:
            self.h_ref = (self.c * self.temperature if enthalpy_reference is None else
                          to_si(enthalpy_reference, "J/kg", name="enthalpy_reference",
                                owner=owner))

    def density(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self.rho0, p, T)

    def density_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(0.0, p, T)

    def density_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(0.0, p, T)

    def viscosity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self.mu, p, T)

    def conductivity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(_conductivity(self), p, T)

    @property
    def rho(self) -> float:
        return self.rho0

    def _heat_capacity(self) -> float:
        if self.c is None:
            raise NotImplementedError(f"{self!r} was made without cp; give cp=... for "
                                      f"thermal properties")
        return self.c

    def cp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(self._heat_capacity(), p, T)

    cv = cp

    def gamma(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(1.0, p, T)

    def internal_energy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        c = self._heat_capacity()
        u_ref = self.h_ref - pressure_atmospheric / self.rho0
        return u_ref + c * (_T(self, p, T) - self.temperature) + _const(0.0, p)

    def enthalpy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.internal_energy(p, T) + p / self.rho0

    def enthalpy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(1.0 / self.rho0, p, T)

    def enthalpy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.cp(p, T)

    def internal_energy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return _const(0.0, p, T)

    def internal_energy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self.cp(p, T)

    def speed_of_sound(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        """Infinite: the liquid is incompressible at this level."""
        return _const(np.inf, p, T)

    def at(self, temperature: Scalar | None = None, *,
           fraction: float | None = None) -> Fluid:
        if self.spec is not None:
            return super().at(temperature, fraction=fraction)
        T = self.temperature if temperature is None else _kelvin(temperature, self)
        h_ref = self.h_ref if self.c is None else float(self.enthalpy(pressure_atmospheric, T))
        return ConstantLiquid(self.name, self.rho0, self.mu, T, cp=self.c, enthalpy_reference=h_ref,
                              conductivity=self.k)


def _optional_positive(value: Scalar | None, unit: str, name: str, owner: str) -> float | None:
    if value is None:
        return None
    v = to_si(value, unit, name=name, owner=owner)
    if not v > 0:
        raise FluidError(f"{owner}: {name} must be > 0 [{unit}], got {v}")
    return v


def _conductivity(fluid: IdealGas | ConstantLiquid) -> float:
    if fluid.k is None:
        raise NotImplementedError(f"{fluid!r} was made without a thermal conductivity; give "
                                  "conductivity=... [W/(m K)] (heat-transfer correlations "
                                  "need it)")
    return fluid.k


def _kelvin(temperature: Scalar, fluid: Fluid) -> float:
    return to_si(temperature, "K", name="temperature", owner=repr(fluid))


def ideal_from_coolprop(spec: FluidSpec, temperature: float) -> Fluid:
    """The ideal-level fluid with constants from CoolProp at 1 atm and ``temperature`` [K]."""
    from .eos import EosFluid
    ref = EosFluid(spec, temperature)
    p = pressure_atmospheric
    # (float(): the properties are floats already at a scalar p; the protocol says Array)
    k: float | None
    try:
        k = float(ref.conductivity(p))
    except FluidError:    # CoolProp has no conductivity model for some fluids
        k = None
    if ref.liquid:
        return ConstantLiquid(spec.name, float(ref.density(p)), float(ref.viscosity(p)),
                              temperature, cp=float(ref.cp(p)),
                              enthalpy_reference=float(ref.enthalpy(p)), conductivity=k,
                              spec=spec)
    return IdealGas(spec.name, ref.molar_mass, float(ref.viscosity(p)), temperature,
                    cp=float(ref.cp(p)), enthalpy_reference=float(ref.enthalpy(p)),
                    conductivity=k, spec=spec)


# -- built-ins: constants from CoolProp 8.0 at 20 degC and 101325 Pa (HEOS::Air,
# HEOS::Nitrogen, HEOS::Water, INCOMP::MEG[0.6]); tests/fluids checks them against
# CoolProp, and ideal_from_coolprop(spec, 293.15) reproduces them.
air = IdealGas("air", molar_mass=0.02896546, viscosity=1.8205675178515367e-05,
               cp=1006.1440320870352, enthalpy_reference=419404.921755863,
               conductivity=0.025873828302933142, spec=BUILTIN["air"])
nitrogen = IdealGas("nitrogen", molar_mass=0.02801348, viscosity=1.7572933092982923e-05,
                    cp=1041.338570569452, enthalpy_reference=304060.2292320199,
                    conductivity=0.02547268398994132, spec=BUILTIN["nitrogen"])
water = ConstantLiquid("water", density=998.2071504679437, viscosity=0.001001596143120583,
                       cp=4184.050924522974, enthalpy_reference=84007.300850631,
                       conductivity=0.5980123555234516, spec=BUILTIN["water"])
#: 60 % (by mass) ethylene glycol in water, CoolProp's INCOMP::MEG (its largest fraction);
#: ``ethylene_glycol.at(fraction=0.3)`` or ``sf.Fluid('ethylene_glycol', fraction=...)``
#: for other mixtures.
ethylene_glycol = ConstantLiquid("ethylene_glycol", density=1077.1377806082166,
                                 viscosity=0.004844812876665472, cp=3097.9741698247576,
                                 enthalpy_reference=0.0, conductivity=0.35665210597646413,
                                 spec=BUILTIN["ethylene_glycol"])
