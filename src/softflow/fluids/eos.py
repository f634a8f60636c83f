"""The 'eos' fidelity level: CoolProp's AbstractState, the reference.

One AbstractState per (backend, fluid, fraction, phase) is cached and updated
state by state. Measured on 10 000 random (p, T) states of air (CoolProp 8.0):
this Python loop costs 3.2-3.4 us per state, PropsSI's array form 3.3 us
(it builds a fresh state per call and cannot name a failing state), and
``update_with_guesses`` with an ideal-gas density guess 3.7 us; the loop is
kept. Water (HEOS, IAPWS-95) costs about 14 us per state, INCOMP::MEG 0.5 us.

Liquids named in the catalog (water, and any HEOS fluid that is liquid at
1 atm and the fluid's temperature) are evaluated with CoolProp's liquid phase
imposed: water stays liquid everywhere, also in the corner of the 0.05-20 MPa x
1-95 degC range below its vapour pressure (at most 85 kPa at 95 degC), where the
values are those of the slightly metastable liquid. softflow does not model
boiling or cavitation.
"""
from __future__ import annotations

from functools import lru_cache, partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ..constants import pressure_atmospheric
from .base import Fluid, FluidError, broadcast_state
from .catalog import FluidSpec

if TYPE_CHECKING:
    from .._typing import Array, SIArrayLike

GAS_CONSTANT = 8.314462618


@lru_cache(maxsize=None)
def abstract_state(spec: FluidSpec, liquid: bool) -> Any:
    """A cached CoolProp AbstractState for the fluid (liquid phase imposed if ``liquid``)."""
    import CoolProp.CoolProp as CP
    from CoolProp import AbstractState
    state = AbstractState(spec.backend, spec.coolprop_name)
    if spec.fraction is not None:
        state.set_mass_fractions([spec.fraction])
    if liquid and spec.backend == "HEOS":
        state.specify_phase(CP.iphase_liquid)
    return state


@lru_cache(maxsize=None)
def is_liquid(spec: FluidSpec, temperature: float) -> bool:
    """Liquid per the catalog, or else per CoolProp's phase at 1 atm and ``temperature``."""
    if spec.liquid is not None:
        return spec.liquid
    import CoolProp.CoolProp as CP
    state = abstract_state(spec, False)
    try:
        state.update(CP.PT_INPUTS, pressure_atmospheric, temperature)
    except ValueError as err:
        raise FluidError(f"fluid {spec.name!r}: CoolProp cannot evaluate it at 1 atm and "
                         f"{temperature:g} K: {err}") from None
    return state.phase() in (CP.iphase_liquid, CP.iphase_supercritical_liquid)


@lru_cache(maxsize=None)
def valid_range(spec: FluidSpec, liquid: bool) -> tuple[tuple[float, float], float]:
    """((T_min, T_max) [K], p_max [Pa]) that CoolProp accepts for this fluid."""
    import CoolProp.CoolProp as CP
    state = abstract_state(spec, liquid)
    T_lo, T_hi = state.Tmin(), state.Tmax()
    if spec.backend == "INCOMP":
        if spec.fraction is not None:   # a solution freezes above the data's own T_min
            T_lo = max(T_lo, CP.PropsSI("T_freeze", spec.coolprop_id))
        return (T_lo, T_hi), np.inf
    return (T_lo, T_hi), state.pmax()


def _distinct(value: float, *bounds: float) -> str:
    """value formatted short, or with more digits where short would equal a bound."""
    short = f"{value:g}"
    return f"{value:.12g}" if short in (f"{b:g}" for b in bounds) else short


def check_state_range(owner: object, p: Array, T: Array, T_range: tuple[float, float],
                      p_range: tuple[float, float], what: str) -> None:
    """Raise a FluidError naming the first bad quantity, its value and the valid range.
    ``owner``: a name, or the fluid (its repr is made only for a message)."""
    p_lo, p_hi = p_range
    T_lo, T_hi = T_range
    if p.size == 0:
        return
    if p.size == 1 and T.size == 1:   # a small network's usual call: no reductions
        pmin = pmax = p.item()
        Tmin = Tmax = T.item()
    else:
        pmin, pmax = p.min(), p.max()
        Tmin, Tmax = T.min(), T.max()
    # a hair of slack: unit conversions round (-40 degC is 233.14999999999998 K)
    slack_p, slack_T = (1e-9 * abs(p_lo), 1e-9 * abs(p_hi)), (1e-9 * abs(T_lo), 1e-9 * abs(T_hi))
    if (pmin > 0 and Tmin > 0 and pmin >= p_lo - slack_p[0] and pmax <= p_hi + slack_p[1]
            and Tmin >= T_lo - slack_T[0] and Tmax <= T_hi + slack_T[1]
            and np.isfinite(pmax) and np.isfinite(Tmax)):
        return
    name_of = owner if isinstance(owner, str) else repr(owner)
    if not pmin > 0:
        raise FluidError(f"{name_of}: pressure {pmin:g} Pa is not a positive absolute pressure "
                         f"(softflow pressures are absolute; valid {what} range "
                         f"{p_lo:g} ... {p_hi:g} Pa)")
    if not Tmin > 0:
        raise FluidError(f"{name_of}: temperature {Tmin:g} K is not a positive absolute "
                         f"temperature (valid {what} range {T_lo:g} ... {T_hi:g} K)")
    for name, unit, lo, hi, vmin, vmax, (s_lo, s_hi) in (
            ("pressure", "Pa", p_lo, p_hi, pmin, pmax, slack_p),
            ("temperature", "K", T_lo, T_hi, Tmin, Tmax, slack_T)):
        if vmin < lo - s_lo or vmax > hi + s_hi:
            bad = vmin if vmin < lo else vmax
            err = FluidError(f"{name_of}: {name} {_distinct(bad, lo, hi)} {unit} is outside "
                             f"the {what} range {lo:g} ... {hi:g} {unit}")
            # the edge crossed, for a search that can stop there
            err.quantity, err.limit = name, float(lo if vmin < lo - s_lo else hi)
            err.value = float(bad)
            raise err
        if not (np.isfinite(vmin) and np.isfinite(vmax)):
            raise FluidError(f"{name_of}: {name} is not finite")


class EosFluid(Fluid):
    """A fluid evaluated by CoolProp at every call (level ``'eos'``).

    Parameters
    ----------
    spec : FluidSpec
        From :func:`softflow.fluids.catalog.resolve`.
    temperature : float [K]
        The fluid's own temperature.
    """

    level = "eos"
    spec: FluidSpec                     # type: ignore[assignment]  # Fluid.spec = None

    def __reduce__(self) -> tuple[type[EosFluid], tuple[FluidSpec, float]]:
        # CoolProp's AbstractState does not pickle: a copy is made again from
        # its definition (and the state cache of the process that loads it)
        return (type(self), (self.spec, self.temperature))

    def __init__(self, spec: FluidSpec, temperature: float) -> None:
        import CoolProp.CoolProp as CP
        self.spec, self.name, self.temperature = spec, spec.name, float(temperature)
        self.liquid = is_liquid(spec, self.temperature)
        self.compressible = not self.liquid
        self._state = abstract_state(spec, self.liquid)
        self.T_range, p_max = valid_range(spec, self.liquid)
        self.p_range = (0.0, p_max)
        check_state_range(repr(self), np.array([pressure_atmospheric]),
                          np.array([self.temperature]), self.T_range, (0.0, np.inf),
                          "CoolProp")
        self._PT = CP.PT_INPUTS
        s = self._state
        d = s.first_partial_deriv
        self._getters = {
            "density": s.rhomass, "viscosity": s.viscosity, "conductivity": s.conductivity,
            "cp": s.cpmass, "cv": s.cvmass,
            "enthalpy": s.hmass, "speed_of_sound": s.speed_sound,
            "compressibility": s.compressibility_factor,
            "density_dp": partial(d, CP.iDmass, CP.iP, CP.iT),
            "density_dT": partial(d, CP.iDmass, CP.iT, CP.iP),
            "enthalpy_dp": partial(d, CP.iHmass, CP.iP, CP.iT),
            "enthalpy_dT": partial(d, CP.iHmass, CP.iT, CP.iP),
        }
        if spec.backend != "INCOMP":   # INCOMP has u but not its partial derivatives
            self._getters.update(internal_energy=s.umass,
                                 internal_energy_dp=partial(d, CP.iUmass, CP.iP, CP.iT),
                                 internal_energy_dT=partial(d, CP.iUmass, CP.iT, CP.iP))

    def _eval(self, prop: str, p: Any, T: Any) -> Any:   # p, T: SIArrayLike
        getter = self._getters[prop]
        p, T, scalar = broadcast_state(self, p, T)
        check_state_range(self, p, T, self.T_range, self.p_range, "CoolProp")
        out = np.empty(p.shape)
        flat = out.reshape(-1)
        update, PT = self._state.update, self._PT
        pl, Tl = p.ravel().tolist(), T.ravel().tolist()
        try:
            for k in range(len(pl)):
                update(PT, pl[k], Tl[k])
                flat[k] = getter()
        except ValueError as err:
            raise FluidError(f"{self!r}: CoolProp failed for {prop} at p = {pl[k]:g} Pa, "
                             f"T = {Tl[k]:g} K: {err}") from None
        return float(flat[0]) if scalar else out

    def density(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("density", p, T)

    def density_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("density_dp", p, T)

    def density_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("density_dT", p, T)

    def viscosity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("viscosity", p, T)

    def conductivity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("conductivity", p, T)

    def cp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("cp", p, T)

    def cv(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("cv", p, T)

    def enthalpy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("enthalpy", p, T)

    def enthalpy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._eval("enthalpy_dp", p, T)

    def enthalpy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if self.spec.backend != "INCOMP":
            return self._eval("enthalpy_dT", p, T)
        # CoolProp's INCOMP partial derivative returns cp, but its h carries a pressure
        # term whose T-dependence that leaves out (3e-3 off at 12 MPa for MEG-60 %):
        # differentiate the h this level returns instead (h is a polynomial in T)
        p, T, scalar = broadcast_state(self, p, T)
        lo, hi = self.T_range
        T_up, T_dn = np.minimum(T + 1e-3, hi), np.maximum(T - 1e-3, lo)  # type: ignore[operator]
        out = (self.enthalpy(p, T_up) - self.enthalpy(p, T_dn)) / (T_up - T_dn)
        return float(out) if scalar else out  # type: ignore[return-value]  # float if scalar

    def internal_energy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if "internal_energy" in self._getters:
            return self._eval("internal_energy", p, T)
        return self.enthalpy(p, T) - np.asarray(p) / self.density(p, T)

    def internal_energy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if "internal_energy_dp" in self._getters:
            return self._eval("internal_energy_dp", p, T)
        # u = h - p/rho
        rho = self.density(p, T)
        return self.enthalpy_dp(p, T) - 1.0 / rho + p * self.density_dp(p, T) / rho ** 2  # type: ignore[operator, return-value]

    def internal_energy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if "internal_energy_dT" in self._getters:
            return self._eval("internal_energy_dT", p, T)
        rho = self.density(p, T)
        return self.enthalpy_dT(p, T) + p * self.density_dT(p, T) / rho ** 2  # type: ignore[operator, return-value]

    def speed_of_sound(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if self.spec.backend == "INCOMP":
            raise NotImplementedError(f"{self!r}: CoolProp's INCOMP backend has no speed "
                                      f"of sound")
        return self._eval("speed_of_sound", p, T)

    def compressibility(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if self.spec.backend == "INCOMP":
            raise NotImplementedError(f"{self!r}: CoolProp's INCOMP backend has no molar "
                                      f"mass, so no compressibility factor")
        return self._eval("compressibility", p, T)

    @property
    def molar_mass(self) -> float:
        """Molar mass [kg/mol] (not defined for INCOMP fluids)."""
        return self._state.molar_mass()
