"""The Fluid protocol: vectorized properties that every component uses."""
from __future__ import annotations

import numpy as np

from ..constants import pressure_atmospheric


class Fluid:
    """Base class of fluids. Properties take absolute pressure p [Pa] and
    temperature T [K] as floats or NumPy arrays; T defaults to the fluid's
    own temperature (isothermal scenes).

    Attributes
    ----------
    name : str
    compressible : bool
    temperature : float [K]
    """

    name = "fluid"
    compressible = False

    def density(self, p, T=None):
        """Density [kg/m^3]."""
        raise NotImplementedError

    def density_dp(self, p, T=None):
        """Derivative of density with respect to pressure at constant T [kg/(m^3 Pa)]."""
        raise NotImplementedError

    def viscosity(self, p, T=None):
        """Dynamic viscosity [Pa s]."""
        raise NotImplementedError

    @property
    def rho(self) -> float:
        """Density at 1 atm and the fluid's temperature [kg/m^3] (the paper's ``fluid.rho``)."""
        return float(self.density(pressure_atmospheric))

    @property
    def is_compressible(self) -> bool:
        return self.compressible

    def __repr__(self):
        return f"<{type(self).__name__} {self.name!r}>"

