"""fonsim's fluid classes (``fons.fluid``) as softflow fluids.

``IdealCompressible(name, rho, mu)`` is a gas given as fonsim gives one: by its
density ``rho`` at fonsim's reference state (``fons.pressure_atmospheric`` =
101 300 Pa, ``fons.temperature`` = 288.15 K) and its viscosity ``mu``. fonsim's
gas is isothermal and ideal, ``density(p) = rho * p / 101 300 Pa``; here it is a
:class:`softflow.IdealGas` at 288.15 K whose molar mass gives exactly that
density. ``IdealIncompressible(name, rho, mu)`` is a
:class:`softflow.ConstantLiquid`. Both are ordinary softflow fluids: every
softflow component takes them, and every fons component takes softflow's
fluids (``sf.air``, ``sf.water``) in their place.
"""
from __future__ import annotations

from ..constants import gas_constant as _sf_gas_constant
from ..fluids import ConstantLiquid, IdealGas
from ..units import to_si
from .constants import norm


class IdealCompressible(IdealGas):
    """Ideal gas given, as in fonsim, by its density at fonsim's reference
    state and its viscosity.

    Parameters
    ----------
    name : str
    rho : float [kg/m^3]
        Density at fonsim's reference state, 101 300 Pa and 288.15 K
        (``rho_stp``): ``density(p) = rho * p / 101 300 Pa``.
    mu : float [Pa s]
        Dynamic viscosity (constant).
    fallbacks : list, optional
        fonsim's fluids to use where a component does not take this one;
        kept as an attribute (every softflow component takes a gas).

    Attributes
    ----------
    rho_stp, rho : float [kg/m^3]
        ``rho`` as given: the density at fonsim's 1 atm.
    mu : float [Pa s]
    molar_mass : float [kg/mol]
        The molar mass that gives that density at 288.15 K (softflow's gas
        constant): 0.02909 kg/mol for ``fons.air``.
    """

    def __init__(self, name, rho, mu, fallbacks=None):
        owner = f"fons.fluid.IdealCompressible {name!r}"
        rho = to_si(rho, "kg/m**3", name="rho", owner=owner)
        if not rho > 0:
            raise ValueError(f"{owner}: rho must be > 0 kg/m^3, got {rho}")
        # rho = p M / (R T) at the reference state fixes M (with the R softflow's
        # gas law divides by, so that the density is rho exactly there)
        molar_mass = _sf_gas_constant * norm.temperature * rho / norm.pressure_atmospheric
        super().__init__(name, molar_mass, mu, norm.temperature)
        self.rho_stp = float(rho)
        self.fallbacks = list(fallbacks or [])

    @property
    def rho(self):
        """Density at fonsim's reference state (101 300 Pa) [kg/m^3]: ``rho_stp``."""
        return self.rho_stp

    def __repr__(self):
        return f"<fons IdealCompressible {self.name!r}: rho_stp {self.rho_stp:.6g} kg/m^3 " \
               f"at {norm.pressure_atmospheric:.6g} Pa, mu {self.mu:.4g} Pa s>"

    __str__ = __repr__


class IdealIncompressible(ConstantLiquid):
    """Constant-property liquid given, as in fonsim, by density and viscosity
    (at fonsim's 288.15 K).

    Parameters
    ----------
    name : str
    rho : float [kg/m^3]
    mu : float [Pa s]
    """

    def __init__(self, name, rho, mu):
        super().__init__(name, rho, mu, norm.temperature)
        self.fallbacks = []

    def __repr__(self):
        return f"<fons IdealIncompressible {self.name!r}: rho {self.rho:.6g} kg/m^3, " \
               f"mu {self.mu:.4g} Pa s>"

    __str__ = __repr__


def __getattr__(name):
    from ._unsupported import unsupported
    return unsupported(f"fluid.{name}", __name__)
