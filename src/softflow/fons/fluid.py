"""fonsim's fluid classes (``fons.fluid``) as softflow fluids.

``IdealCompressible(name, rho, mu)`` is an ideal gas at softflow's fluid
temperature whose density is ``rho`` at 1 atm (``rho_stp``), so that
``density(p) = rho * p / p_atm`` as in fonsim; ``IdealIncompressible(name, rho,
mu)`` is a constant-property liquid. Both are ordinary softflow fluids
(:class:`softflow.IdealGas`, :class:`softflow.ConstantLiquid`): every softflow
component takes them.
"""
from __future__ import annotations

from ..constants import gas_constant, pressure_atmospheric, temperature_standard
from ..fluids import ConstantLiquid, IdealGas
from ..units import to_si


class IdealCompressible(IdealGas):
    """Ideal gas given, as in fonsim, by its density at 1 atm and its viscosity.

    Parameters
    ----------
    name : str
    rho : float [kg/m^3]
        Density at 1 atm (softflow's 101 325 Pa) and 20 degC: ``rho_stp``.
    mu : float [Pa s]
        Dynamic viscosity (constant).
    fallbacks : list, optional
        Accepted for fonsim scripts; softflow's components handle gases
        themselves and never fall back to another fluid.
    """

    def __init__(self, name, rho, mu, fallbacks=None):
        owner = f"fons.fluid.IdealCompressible {name!r}"
        rho = to_si(rho, "kg/m**3", name="rho", owner=owner)
        if not rho > 0:
            raise ValueError(f"{owner}: rho must be > 0 kg/m^3, got {rho}")
        # rho = p / (R T) at 1 atm fixes R T; the molar mass follows at softflow's T
        molar_mass = gas_constant * temperature_standard * rho / pressure_atmospheric
        super().__init__(name, molar_mass, mu, temperature_standard)
        self.rho_stp = float(rho)
        self.fallbacks = list(fallbacks or [])

    @classmethod
    def from_fluid(cls, fluid):
        """The softflow gas ``fluid`` itself (all its constants), with fonsim's
        ``rho_stp`` and ``fallbacks`` attributes."""
        new = cls.__new__(cls)
        new.__dict__.update(fluid.__dict__)
        new.rho_stp = float(fluid.rho)
        new.fallbacks = []
        return new

    def __repr__(self):
        return f"<fons IdealCompressible {self.name!r}: rho_stp {self.rho_stp:.6g} kg/m^3, " \
               f"mu {self.mu:.4g} Pa s>"


class IdealIncompressible(ConstantLiquid):
    """Constant-property liquid given, as in fonsim, by density and viscosity.

    Parameters
    ----------
    name : str
    rho : float [kg/m^3]
    mu : float [Pa s]
    """

    def __init__(self, name, rho, mu):
        super().__init__(name, rho, mu, temperature_standard)
        self.fallbacks = []

    @classmethod
    def from_fluid(cls, fluid):
        """The softflow liquid ``fluid`` itself, with fonsim's ``fallbacks`` attribute."""
        new = cls.__new__(cls)
        new.__dict__.update(fluid.__dict__)
        new.fallbacks = []
        return new

    def __repr__(self):
        return f"<fons IdealIncompressible {self.name!r}: rho {self.rho:.6g} kg/m^3, " \
               f"mu {self.mu:.4g} Pa s>"


def __getattr__(name):
    from ._unsupported import unsupported
    return unsupported(f"fluid.{name}", __name__)
