"""The Fluid protocol: vectorized properties that every component uses.

Every property takes absolute pressure ``p`` [Pa] and temperature ``T`` [K] as
floats or NumPy arrays (broadcast together) and returns a float or an array of
the same shape. ``T=None`` means the fluid's own temperature (isothermal scenes);
that path is the fastest one at every level.

Derivatives are partial derivatives in the protocol's own coordinates: ``*_dp``
at constant T, ``*_dT`` at constant p. So ``internal_energy_dT`` is (du/dT)_p,
which equals cv only for an ideal gas, and ``enthalpy_dT`` is (dh/dT)_p = cp.

``Fluid`` is also the public constructor: ``Fluid('Air', level='table',
temperature=Q_(20, 'degC'))`` returns the fluid object of the chosen fidelity
level (see :func:`softflow.fluids.catalog.make_fluid`), and every such object is
an instance of ``Fluid``.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..constants import pressure_atmospheric, temperature_standard
from ..units import Q_, to_si

if TYPE_CHECKING:
    import numpy.typing as npt

    from .._typing import Array, ArrayLike, Quantity, Scalar

#: Unit of each property that :meth:`Fluid.quantity` can return.
PROPERTY_UNITS = {
    "density": "kg/m**3", "density_dp": "kg/m**3/Pa", "density_dT": "kg/m**3/K",
    "viscosity": "Pa*s", "conductivity": "W/m/K", "cp": "J/kg/K", "cv": "J/kg/K", "gamma": "",
    "enthalpy": "J/kg", "enthalpy_dp": "J/kg/Pa", "enthalpy_dT": "J/kg/K",
    "internal_energy": "J/kg", "internal_energy_dp": "J/kg/Pa",
    "internal_energy_dT": "J/kg/K", "speed_of_sound": "m/s", "compressibility": "",
}

LEVELS = ("ideal", "table", "eos")


class FluidError(ValueError):
    """Bad fluid input: unknown name, a state outside the valid range, a bad table file.

    A state outside a fluid's range says which edge it crossed: ``quantity``
    ('pressure' or 'temperature'), ``limit`` (that edge, in Pa or K) and
    ``value`` (the value past it); all None otherwise."""

    quantity: str | None = None
    limit: float | None = None
    value: float | None = None


class _FluidConstructor(type):
    # Calling the base class itself builds a catalog fluid; subclasses construct normally.
    def __call__(cls, *args, **kwargs):
        if cls is Fluid:
            from .catalog import make_fluid
            return make_fluid(*args, **kwargs)
        return super().__call__(*args, **kwargs)


class Fluid(metaclass=_FluidConstructor):
    """A fluid at one fidelity level; calling ``Fluid(name, ...)`` makes one.

    Parameters
    ----------
    name : str
        ``'air'``, ``'nitrogen'``, ``'water'``, ``'ethylene_glycol'`` or any CoolProp
        fluid name (e.g. ``'CO2'``, ``'INCOMP::MPG'``).
    level : {'ideal', 'table', 'eos'}
        Fidelity: constant-property model, interpolated CoolProp table, or CoolProp.
        Default ``'eos'``.
    temperature : float [K] or Quantity
        The fluid's own temperature (used when a property is asked with T=None).
        Default 20 degC.
    fraction : float [-] or Quantity
        Mass fraction of the solute for CoolProp solutions (ethylene glycol).
    out_of_range : {'raise', 'eos'}
        Table level only: what a state outside the table does.
    tables_dir : str or Path
        Table level only: where the table files lie (default: see
        :func:`softflow.fluids.tables.tables_directory`).

    Attributes
    ----------
    name : str
    level : str
    compressible : bool
        True for gases (density follows pressure); liquids are False even at the
        table and eos levels, whose density_dp is nevertheless the true small value.
    temperature : float [K]
    """

    name = "fluid"
    level = "custom"
    compressible = False
    temperature = temperature_standard
    spec = None

    def __deepcopy__(self, memo):
        # fluids are values that never change (with_level, at make new ones):
        # copies of a System share them, and their property caches
        return self

    # -- the protocol ----------------------------------------------------------------
    def density(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Density [kg/m^3]."""
        raise NotImplementedError(self._missing("density"))

    def density_dp(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """(d rho / d p) at constant T [kg/(m^3 Pa)]."""
        raise NotImplementedError(self._missing("density_dp"))

    def density_dT(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """(d rho / d T) at constant p [kg/(m^3 K)]."""
        raise NotImplementedError(self._missing("density_dT"))

    def viscosity(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Dynamic viscosity [Pa s]."""
        raise NotImplementedError(self._missing("viscosity"))

    def conductivity(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Thermal conductivity [W/(m K)] (used by heat-transfer correlations)."""
        raise NotImplementedError(self._missing("conductivity"))

    def cp(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Specific isobaric heat capacity [J/(kg K)]."""
        raise NotImplementedError(self._missing("cp"))

    def cv(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Specific isochoric heat capacity [J/(kg K)]."""
        raise NotImplementedError(self._missing("cv"))

    def gamma(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Ratio of specific heats cp/cv [-]."""
        return self.cp(p, T) / self.cv(p, T)

    def enthalpy(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Specific enthalpy [J/kg] (reference state: CoolProp's for the fluid)."""
        raise NotImplementedError(self._missing("enthalpy"))

    def enthalpy_dp(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """(d h / d p) at constant T [J/(kg Pa)]."""
        raise NotImplementedError(self._missing("enthalpy_dp"))

    def enthalpy_dT(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """(d h / d T) at constant p [J/(kg K)] (= cp, up to interpolation error)."""
        raise NotImplementedError(self._missing("enthalpy_dT"))

    def internal_energy(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Specific internal energy [J/kg]."""
        raise NotImplementedError(self._missing("internal_energy"))

    def internal_energy_dp(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """(d u / d p) at constant T [J/(kg Pa)]."""
        raise NotImplementedError(self._missing("internal_energy_dp"))

    def internal_energy_dT(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """(d u / d T) at constant p [J/(kg K)] (= cv for an ideal gas only)."""
        raise NotImplementedError(self._missing("internal_energy_dT"))

    def speed_of_sound(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Speed of sound [m/s]."""
        raise NotImplementedError(self._missing("speed_of_sound"))

    def compressibility(self, p: npt.ArrayLike, T: npt.ArrayLike | None = None) -> Array:
        """Compressibility factor Z = p / (rho R T) [-]."""
        raise NotImplementedError(self._missing("compressibility"))

    # -- conveniences ----------------------------------------------------------------
    @property
    def rho(self) -> float:
        """Density at 1 atm and the fluid's temperature [kg/m^3] (the paper's ``fluid.rho``)."""
        cached = self.__dict__.get("_rho_atm")
        if cached is None:
            cached = self._rho_atm = float(self.density(pressure_atmospheric))
        return cached

    @property
    def is_compressible(self) -> bool:
        return self.compressible

    def quantity(self, prop: str, p: ArrayLike, T: ArrayLike | None = None) -> Quantity:
        """A property as a pint Quantity; ``p`` and ``T`` may be Quantities.

        Parameters
        ----------
        prop : str
            A property method name, e.g. ``'density'`` (see ``PROPERTY_UNITS``).
        p : float [Pa] or Quantity
            Absolute pressure.
        T : float [K] or Quantity, optional
            Temperature (default: the fluid's own).
        """
        if prop not in PROPERTY_UNITS:
            raise FluidError(f"{self!r}: unknown property {prop!r}; known: "
                             f"{', '.join(PROPERTY_UNITS)}")
        p_si = to_si(p, "Pa", name="p", owner=repr(self))
        T_si = None if T is None else to_si(T, "K", name="T", owner=repr(self))
        return Q_(getattr(self, prop)(p_si, T_si), PROPERTY_UNITS[prop])

    def with_level(self, level: str, **options: Any) -> "Fluid":
        """The same fluid (name, temperature, fraction) at another fidelity level."""
        if self.spec is None:
            raise FluidError(f"{self!r} was built by hand, not from the catalog, so it "
                             f"has no other levels; use sf.Fluid(name, level=...)")
        from .catalog import make_fluid
        return make_fluid(self.spec, level=level, temperature=self.temperature, **options)

    def at(self, temperature: Scalar | None = None, *,
           fraction: float | None = None) -> "Fluid":
        """The same fluid and level at another temperature [K] (and solute fraction [-])."""
        if self.spec is None:
            raise FluidError(f"{self!r} was built by hand; it has no catalog entry to "
                             f"re-evaluate at another temperature")
        from .catalog import make_fluid
        return make_fluid(self.spec, level=self.level,
                          temperature=self.temperature if temperature is None else temperature,
                          fraction=fraction, **self._level_options())

    def _level_options(self) -> dict:
        return {}

    def _missing(self, prop):
        return (f"{self!r} does not provide {prop}; try another level "
                f"(e.g. fluid.with_level('eos')) or a fluid that has it")

    def __repr__(self):
        return (f"<{type(self).__name__} {self.name!r} level={self.level!r} "
                f"T={self.temperature:g} K>")


def broadcast_state(fluid, p, T):
    """(p, T, scalar?) as float arrays of one shape; T None means the fluid's temperature."""
    if T is None:
        T = fluid.temperature
    p, T = np.asarray(p, dtype=float), np.asarray(T, dtype=float)
    scalar = p.ndim == 0 and T.ndim == 0
    if p.shape != T.shape:
        # read-only views (broadcast_arrays' are writeable with a warning on
        # write, and numba, asked whether they are writeable, warns too)
        shape = np.broadcast_shapes(p.shape, T.shape)
        p, T = np.broadcast_to(p, shape), np.broadcast_to(T, shape)
    return p, T, scalar


def check_temperature(value: Scalar, owner: str) -> float:
    """A fluid temperature from a Quantity or kelvin number; must be a finite absolute T > 0."""
    T = to_si(value, "K", name="temperature", owner=owner)
    if np.ndim(T) != 0 or not np.isfinite(T) or T <= 0:
        raise FluidError(f"{owner}: temperature must be one absolute temperature > 0 K, got "
                         f"{value!r} (plain numbers are kelvin; write sf.Q_(20, 'degC') "
                         f"for Celsius)")
    return float(T)
