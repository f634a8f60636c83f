"""The 'table' fidelity level: C1 interpolation of CoolProp tables in ``fluid_tables/``.

Every property is the bicubic interpolant of its table (see ``hermite.py``), and
every derivative is the exact derivative of that interpolant, so Newton sees a
consistent, continuous Jacobian. Gases are tabulated as Z(p, T), density is
p / (Z R T). With T=None (isothermal scenes) a property costs one 1-D cubic
lookup: the interpolant restricted to the fluid's temperature, identical to the
2-D one there.

A state outside the table raises (``out_of_range='raise'``, the default), or is
handed to CoolProp (``out_of_range='eos'``); it is never extrapolated.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from .base import Fluid, FluidError, broadcast_state
from .eos import EosFluid, check_state_range
from .hermite import compiled
from .tables import load_table, table_files, tables_directory

if TYPE_CHECKING:
    from .._typing import Array, SIArrayLike
    from .catalog import FluidSpec


OUT_OF_RANGE = ("raise", "eos")


class TableFluid(Fluid):
    """A fluid interpolated from its property table (level ``'table'``).

    Parameters
    ----------
    spec : FluidSpec
    temperature : float [K]
        The fluid's own temperature; must lie in the table's range.
    out_of_range : {'raise', 'eos'}
        What a state outside the table does.
    tables_dir : str or Path, optional
        Directory of the table files (default: see ``tables_directory``).
    """

    level = "table"
    spec: FluidSpec                     # type: ignore[assignment]  # Fluid.spec = None

    def __reduce__(self) -> tuple[type[TableFluid], tuple[Any, ...]]:
        # rebuilt from its definition: the tables are read (and cached) where it
        # is loaded instead of travelling with every pickled scene
        return (type(self), (self.spec, self.temperature, self.out_of_range, self.tables_dir))

    def __init__(self, spec: FluidSpec, temperature: float, out_of_range: str = "raise",
                 tables_dir: str | Path | None = None) -> None:
        self.spec, self.name, self.temperature = spec, spec.name, float(temperature)
        if out_of_range not in OUT_OF_RANGE:
            raise FluidError(f"fluid {spec.name!r}: out_of_range must be 'raise' or 'eos', "
                             f"got {out_of_range!r}")
        self.out_of_range, self.tables_dir = out_of_range, tables_dir
        # a temperature outside the table is refused from its metadata, before
        # load_table checks the table against the installed CoolProp (importing
        # it: 2-3 s)
        self._check_temperature(_metadata_range(spec, tables_dir))
        self.table = load_table(spec, tables_dir)
        meta = self.table.meta
        self.liquid = bool(meta["liquid"])
        self.compressible = not self.liquid
        self.p_range, self.T_range = self.table.p_range, self.table.T_range
        self.molar_mass = meta["molar_mass"]
        self.R = meta["specific_gas_constant"]     # CoolProp's, so that Z matches it
        self._check_temperature(self.T_range)
        self._eos: EosFluid | None = None

    def _check_temperature(self, T_range: tuple[float, float] | None) -> None:
        if T_range is None:
            return
        T_lo, T_hi = T_range
        if not T_lo * (1 - 1e-9) <= self.temperature <= T_hi * (1 + 1e-9):   # round-off slack
            raise FluidError(f"{self!r}: temperature {self.temperature:g} K is outside the "
                             f"table range {T_lo:g} ... {T_hi:g} K (use out-of-table "
                             f"temperatures at level 'eos')")

    def _level_options(self) -> dict[str, Any]:
        return {"out_of_range": self.out_of_range, "tables_dir": self.tables_dir}

    @property
    def eos(self) -> EosFluid:
        """The CoolProp fluid behind the table (for out-of-range states)."""
        if self._eos is None:
            self._eos = EosFluid(self.spec, self.temperature)
        return self._eos

    # -- evaluation -------------------------------------------------------------------
    def _evaluate(self, prop: str, compute: Callable[[Any, Any], Any], p: Any,
                  T: Any) -> Any:    # p, T: SIArrayLike (Any: rebound to arrays below)
        """compute(p, T) on the table; out-of-range states raise or go to CoolProp.

        With ``out_of_range='eos'`` either part may be empty: the table is asked
        only for the states inside it, CoolProp only for the others, and a
        state's value does not depend on the other states of the call (with
        T=None the inside ones take the isothermal path, as when all are in)."""
        isothermal = T is None
        p_range, T_range = self.p_range, self.T_range
        if isothermal:
            pa = np.asarray(p, dtype=float)
            if pa.ndim == 0:
                pf = float(pa)
                if p_range[0] <= pf <= p_range[1]:
                    return float(compute(pf, None))
            elif _inside(pa, p_range):
                return compute(pa, None)
        p, T, scalar = broadcast_state(self, p, T)
        if scalar:
            # one state inside: computed on floats (NumPy scalars through the
            # interpolants), the numbers the 0-d arrays below give, sooner
            pf, Tf = float(p), float(T)
            if p_range[0] <= pf <= p_range[1] and T_range[0] <= Tf <= T_range[1]:
                return float(compute(pf, Tf))
        inside_all = _inside(p, p_range, T, T_range)
        if self.out_of_range == "raise":
            if not inside_all:      # raises, but for states within its round-off slack
                check_state_range(self, p, T, T_range, p_range, "table")
            out = compute(p, T)
        elif inside_all:                # the usual call: no selections, no copies
            out = compute(p, T)
        else:
            (p_lo, p_hi), (T_lo, T_hi) = p_range, T_range
            inside = (p >= p_lo) & (p <= p_hi) & (T >= T_lo) & (T <= T_hi)
            out = np.empty(p.shape)
            if inside.any():
                out[inside] = compute(p[inside], None if isothermal else T[inside])
            outside = ~inside
            out[outside] = getattr(self.eos, prop)(p[outside], T[outside])
        return float(out) if scalar else out

    def _get(self, key: str, p: float | Array, T: float | Array | None, grad: bool = False) -> Any:
        if key not in self.table.values:
            raise NotImplementedError(self._missing(key))
        if T is None:
            return self.table.slice(key, self.temperature)(p, grad=grad)
        return self.table.interpolant(key)(p, T, grad=grad)

    def _grad2(self, key: str, p: float | Array, T: float | Array | None) -> Any:
        # value, d/dp, d/dT of a tabulated property (2-D even when T is the fluid's own)
        if T is None:
            T = np.full(np.shape(p), self.temperature)
        if key not in self.table.values:
            raise NotImplementedError(self._missing(key))
        return self.table.interpolant(key)(p, T, grad=True)

    def _Tv(self, T: float | Array | None) -> float | Array:
        return self.temperature if T is None else T

    # density: rho = p / (Z R T) for gases
    def _gas_density(self, p: Any, Tv: Any, Z: Any) -> Any:
        return p / (Z * self.R * Tv)

    def _gas_density_dp(self, p: Any, Tv: Any, Z: Any, Zp: Any) -> Any:
        return (1.0 - p * Zp / Z) / (Z * self.R * Tv)

    def _gas_density_dT(self, p: Any, Tv: Any, Z: Any, ZT: Any) -> Any:
        return -p / (Z * self.R * Tv) * (1.0 / Tv + ZT / Z)

    def _density(self, p: float | Array, T: float | Array | None) -> float | Array:
        if self.liquid:
            return self._get("density", p, T)
        return self._gas_density(p, self._Tv(T), self._get("Z", p, T))

    def _density_dp(self, p: float | Array, T: float | Array | None) -> float | Array:
        if self.liquid:
            return self._get("density", p, T, grad=True)[1]
        Z, Zp = self._get("Z", p, T, grad=True)[:2]
        return self._gas_density_dp(p, self._Tv(T), Z, Zp)

    def _density_dT(self, p: float | Array, T: float | Array | None) -> float | Array:
        if self.liquid:
            return self._grad2("density", p, T)[2]
        Z, _, ZT = self._grad2("Z", p, T)
        return self._gas_density_dT(p, self._Tv(T), Z, ZT)

    def density(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("density", self._density, p, T)

    def density_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("density_dp", self._density_dp, p, T)

    def density_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("density_dT", self._density_dT, p, T)

    # -- value and derivatives from one lookup (components.thermal._parts) ----------------
    def _lookup3(self, key: str, p: Any, T: Any, jac: bool) -> tuple[Any, Any, Any] | None:
        """(value, d/dp, d/dT) of tabulated ``key`` at states within the table,
        from one interpolation (the public methods make one each), or None where
        the per-property methods decide (an out-of-range fallback to CoolProp,
        the fluid's own temperature, scalars)."""
        if self.out_of_range != "raise" or T is None:
            return None
        p, T, scalar = broadcast_state(self, p, T)
        if scalar:
            return None
        if not _inside(p, self.p_range, T, self.T_range):
            check_state_range(self, p, T, self.T_range, self.p_range, "table")
        if key not in self.table.values:
            raise NotImplementedError(self._missing(key))
        interp = self.table.interpolant(key)
        return interp(p, T, grad=True) if jac else (interp(p, T), None, None)

    def _public_parts(self, name: str, p: Any, T: Any, jac: bool) -> tuple[Any, Any, Any]:
        value = getattr(self, name)(p, T)
        if not jac:
            return value, None, None
        return value, getattr(self, f"{name}_dp")(p, T), getattr(self, f"{name}_dT")(p, T)

    def _enthalpy_parts(self, p: Any, T: Any, jac: bool) -> tuple[Any, Any, Any]:
        """(h, dh/dp, dh/dT) (None, None without ``jac``), the same numbers as
        :meth:`enthalpy`, :meth:`enthalpy_dp` and :meth:`enthalpy_dT`."""
        got = self._lookup3("enthalpy", p, T, jac)
        return self._public_parts("enthalpy", p, T, jac) if got is None else got

    def _internal_energy_parts(self, p: Any, T: Any, jac: bool) -> tuple[Any, Any, Any]:
        """(u, du/dp, du/dT) as :meth:`_enthalpy_parts`."""
        got = self._lookup3("internal_energy", p, T, jac)
        return self._public_parts("internal_energy", p, T, jac) if got is None else got

    def _density_parts(self, p: Any, T: Any, jac: bool) -> tuple[Any, Any, Any]:
        """(rho, drho/dp, drho/dT) as :meth:`_enthalpy_parts`; a gas's from Z and
        its gradient by the laws :meth:`_density` and its derivatives use."""
        got = self._lookup3("density" if self.liquid else "Z", p, T, jac)
        if got is None:
            return self._public_parts("density", p, T, jac)
        if self.liquid:
            return got
        Z, Zp, ZT = got
        p, T = broadcast_state(self, p, T)[:2]
        rho = self._gas_density(p, T, Z)
        if not jac:
            return rho, None, None
        return rho, self._gas_density_dp(p, T, Z, Zp), self._gas_density_dT(p, T, Z, ZT)

    def viscosity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("viscosity", lambda p, T: self._get("viscosity", p, T), p, T)

    def conductivity(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        """Thermal conductivity [W/(m K)], from CoolProp (not tabulated: heat-transfer
        correlations ask for it once per step, not per Newton iteration)."""
        return self.eos.conductivity(p, T)

    def cp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("cp", lambda p, T: self._get("cp", p, T), p, T)

    def cv(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("cv", lambda p, T: self._get("cv", p, T), p, T)

    def enthalpy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("enthalpy", lambda p, T: self._get("enthalpy", p, T), p, T)

    def enthalpy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("enthalpy_dp",
                              lambda p, T: self._get("enthalpy", p, T, grad=True)[1], p, T)

    def enthalpy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("enthalpy_dT", lambda p, T: self._grad2("enthalpy", p, T)[2],
                              p, T)

    def internal_energy(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("internal_energy",
                              lambda p, T: self._get("internal_energy", p, T), p, T)

    def internal_energy_dp(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("internal_energy_dp",
                              lambda p, T: self._get("internal_energy", p, T, grad=True)[1],
                              p, T)

    def internal_energy_dT(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("internal_energy_dT",
                              lambda p, T: self._grad2("internal_energy", p, T)[2], p, T)

    def speed_of_sound(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        return self._evaluate("speed_of_sound",
                              lambda p, T: self._get("speed_of_sound", p, T), p, T)

    def compressibility(self, p: SIArrayLike, T: SIArrayLike | None = None) -> Array:
        if self.liquid:
            if self.R is None:
                raise NotImplementedError(f"{self!r}: no molar mass (CoolProp INCOMP), so no "
                                          f"compressibility factor")
            return self._evaluate("compressibility", lambda p, T: p / (
                self._density(p, T) * self.R * self._Tv(T)), p, T)
        return self._evaluate("compressibility", lambda p, T: self._get("Z", p, T), p, T)


def _inside(p: Array, p_range: tuple[float, float], T: Array | None = None,
            T_range: tuple[float, float] | None = None) -> bool:
    """Whether every state lies in the table's closed ranges (no NaN; True for
    none), in one compiled pass instead of a reduction per bound."""
    law = compiled()
    if T is None or T_range is None:
        return bool(law.inside_span(p.ravel(), *p_range))
    return bool(law.inside_box(p.ravel(), T.ravel(), *p_range, *T_range))


def _metadata_range(spec: FluidSpec, tables_dir: str | Path | None) -> tuple[float, float] | None:
    """The temperature range [K] a table's metadata records, or None where it cannot be
    read (load_table then says why)."""
    try:
        _, json_path = table_files(spec.table_stem, tables_directory(tables_dir))
        lo, hi = json.loads(json_path.read_text())["temperature_range"]
        return float(lo), float(hi)
    except (OSError, ValueError, KeyError, TypeError):
        return None
