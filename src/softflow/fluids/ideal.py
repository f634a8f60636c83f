"""The 'ideal' fidelity level: ideal gas with constant properties, or a
constant-property liquid (the FONS paper's model, the fastest)."""
from __future__ import annotations

import numpy as np

from ..constants import gas_constant, temperature_standard
from ..units import to_si
from .base import Fluid


class IdealGas(Fluid):
    """Isothermal ideal gas: rho = p / (R T).

    Parameters
    ----------
    name : str
    molar_mass : float [kg/mol]
    viscosity : float [Pa s]
    temperature : float [K]
    gamma : float [-]
        Ratio of specific heats (used by thermal scenes).
    """

    compressible = True

    def __init__(self, name, molar_mass, viscosity, temperature=temperature_standard,
                 gamma=1.4):
        owner = f"IdealGas {name!r}"
        self.name = name
        self.molar_mass = to_si(molar_mass, "kg/mol", name="molar_mass", owner=owner)
        self.mu = to_si(viscosity, "Pa*s", name="viscosity", owner=owner)
        self.temperature = to_si(temperature, "K", name="temperature", owner=owner)
        if self.temperature <= 0:
            raise ValueError(f"{owner}: temperature must be > 0 K, got {self.temperature}")
        self.gamma = to_si(gamma, "", name="gamma", owner=owner)
        if not (self.molar_mass > 0 and self.mu > 0 and self.gamma > 1):
            raise ValueError(f"{owner}: need molar_mass > 0, viscosity > 0 and gamma > 1")
        self.R = gas_constant / self.molar_mass
        self._RT = self.R * self.temperature

    def density(self, p, T=None):
        RT = self._RT if T is None else self.R * np.asarray(T)
        return p / RT

    def density_dp(self, p, T=None):
        RT = self._RT if T is None else self.R * np.asarray(T)
        return np.ones_like(p) / RT if np.ndim(p) else 1.0 / RT

    def viscosity(self, p, T=None):
        return np.full_like(p, self.mu, dtype=float) if np.ndim(p) else self.mu


class ConstantLiquid(Fluid):
    """Incompressible liquid with constant density and viscosity.

    Parameters
    ----------
    name : str
    density : float [kg/m^3]
    viscosity : float [Pa s]
    temperature : float [K]
    """

    compressible = False

    def __init__(self, name, density, viscosity, temperature=temperature_standard):
        owner = f"ConstantLiquid {name!r}"
        self.name = name
        self.rho0 = to_si(density, "kg/m**3", name="density", owner=owner)
        self.mu = to_si(viscosity, "Pa*s", name="viscosity", owner=owner)
        self.temperature = to_si(temperature, "K", name="temperature", owner=owner)
        if self.rho0 <= 0 or self.mu <= 0:
            raise ValueError(f"{owner}: density and viscosity must be > 0")

    def density(self, p, T=None):
        return np.full_like(p, self.rho0, dtype=float) if np.ndim(p) else self.rho0

    def density_dp(self, p, T=None):
        return np.zeros_like(p, dtype=float) if np.ndim(p) else 0.0

    def viscosity(self, p, T=None):
        return np.full_like(p, self.mu, dtype=float) if np.ndim(p) else self.mu

    @property
    def rho(self):
        return self.rho0


# Property values at 20 degC and 101325 Pa, from CoolProp 8.0 (HEOS::Air,
# HEOS::Water, HEOS::Nitrogen); the fluids issue replaces these constants by
# CoolProp-backed 'table' and 'eos' levels.
air = IdealGas("air", molar_mass=0.02896546, viscosity=1.8205e-5)
nitrogen = IdealGas("nitrogen", molar_mass=0.0280134, viscosity=1.7586e-5)
water = ConstantLiquid("water", density=998.2067, viscosity=1.0016e-3)
