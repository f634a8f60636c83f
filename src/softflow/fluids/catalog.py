"""Which fluid a name means, and the constructor behind ``sf.Fluid(name, level=...)``.

Built-in names (case-insensitive, with aliases): ``air``, ``nitrogen`` (N2),
``water`` (H2O), ``ethylene_glycol`` (MEG: CoolProp ``INCOMP::MEG``, mass fraction
of glycol in water, default 0.6, the largest CoolProp allows). Any other CoolProp
name works at the ``eos`` level (and ``ideal``, from CoolProp at 1 atm), e.g.
``'CO2'``, ``'HEOS::Argon'``, ``'INCOMP::MPG[0.3]'``; at the ``table`` level once a
table has been built for it (``python -m softflow.fluids.tables build --help``).
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from pint import Quantity

from ..constants import temperature_standard
from ..units import UnitError, to_si
from .base import LEVELS, FluidError, check_temperature

#: Default mass fraction of ethylene glycol in water: CoolProp's INCOMP::MEG maximum.
GLYCOL_FRACTION = 0.6


@dataclass(frozen=True)
class FluidSpec:
    """What CoolProp calls a fluid and how softflow treats it.

    Attributes
    ----------
    name : str
        softflow's name (``'air'``) or the CoolProp name for other fluids.
    backend : str
        CoolProp backend, ``'HEOS'`` or ``'INCOMP'``.
    coolprop_name : str
        CoolProp's fluid name (``'Air'``, ``'MEG'``).
    liquid : bool or None
        Liquid (incompressible in the network sense) or gas; None: decided from
        CoolProp's phase at 1 atm and the fluid's temperature.
    fraction : float [-] or None
        Mass fraction of the solute (CoolProp solutions only).
    """

    name: str
    backend: str
    coolprop_name: str
    liquid: bool | None = None
    fraction: float | None = None

    @property
    def coolprop_id(self) -> str:
        """The string PropsSI would take, e.g. ``'INCOMP::MEG[0.6]'``."""
        tail = "" if self.fraction is None else f"[{self.fraction:g}]"
        return f"{self.backend}::{self.coolprop_name}{tail}"

    @property
    def table_stem(self) -> str:
        """File name (without suffix) of this fluid's table in ``fluid_tables/``."""
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", self.name).lower()
        return stem if self.fraction is None else f"{stem}-{self.fraction:g}"


BUILTIN = {
    "air": FluidSpec("air", "HEOS", "Air", liquid=False),
    "nitrogen": FluidSpec("nitrogen", "HEOS", "Nitrogen", liquid=False),
    "water": FluidSpec("water", "HEOS", "Water", liquid=True),
    "ethylene_glycol": FluidSpec("ethylene_glycol", "INCOMP", "MEG", liquid=True,
                                 fraction=GLYCOL_FRACTION),
}

_ALIASES = {
    "n2": "nitrogen", "r728": "nitrogen", "r729": "air",
    "h2o": "water", "r718": "water", "heos::air": "air", "heos::nitrogen": "nitrogen",
    "heos::water": "water", "meg": "ethylene_glycol", "incomp::meg": "ethylene_glycol",
    "ethylene glycol": "ethylene_glycol", "ethyleneglycol": "ethylene_glycol",
    "glycol": "ethylene_glycol",
}


def resolve(name: str) -> FluidSpec:
    """The FluidSpec a name stands for; unknown names raise with close matches."""
    if isinstance(name, FluidSpec):
        return name
    if not isinstance(name, str) or not name.strip():
        raise FluidError(f"fluid name must be a non-empty string, got {name!r}")
    key = name.strip().lower()
    key = _ALIASES.get(key, key)
    if key in BUILTIN:
        return BUILTIN[key]
    m = re.fullmatch(r"INCOMP::([A-Za-z0-9_]+)(?:\[([0-9.eE+-]+)\])?", name.strip(),
                     flags=re.IGNORECASE)
    if m:
        base = m.group(1)
        if base not in _incompressibles():
            _unknown(name)
        spec = FluidSpec(f"INCOMP::{base}", "INCOMP", base, liquid=True)
        if base in _incompressible_solutions():
            return replace(spec, fraction=check_fraction(spec, float(m.group(2) or 0.0)))
        return spec
    bare = name.strip().split("::", 1)[-1] if name.upper().startswith("HEOS::") else name.strip()
    canonical = _coolprop_names().get(bare.lower())
    if canonical is None:
        _unknown(name)
    return FluidSpec(canonical, "HEOS", canonical, liquid=None)


def check_fraction(spec: FluidSpec, value) -> float:
    """Validated solute mass fraction [-] for a CoolProp solution."""
    owner = f"fluid {spec.name!r}"
    if isinstance(value, Quantity) and not value.dimensionless:
        raise UnitError(f"{owner}: fraction expects a dimensionless mass fraction (0.3 or "
                        f"Q_(30, 'percent')), got {value:~P}")
    x = to_si(value, "", name="fraction", owner=owner)
    if spec.backend != "INCOMP" or spec.coolprop_name not in _incompressible_solutions():
        raise FluidError(f"{owner}: fraction applies to CoolProp solutions (e.g. "
                         f"'ethylene_glycol', 'INCOMP::MPG'), not to a pure fluid")
    lo, hi = fraction_range(spec.coolprop_name)
    if np.ndim(x) != 0 or not lo <= x <= hi:
        raise FluidError(f"{owner}: fraction {value!r} is outside CoolProp's range for "
                         f"INCOMP::{spec.coolprop_name}: {lo:g} ... {hi:g} (mass fraction "
                         f"of solute)")
    return float(x)


@lru_cache(maxsize=None)
def fraction_range(solution: str) -> tuple[float, float]:
    """CoolProp's (min, max) mass fraction of an INCOMP solution."""
    import CoolProp.CoolProp as CP
    fid = f"INCOMP::{solution}"
    return CP.PropsSI("fraction_min", fid), CP.PropsSI("fraction_max", fid)


def make_fluid(name, level: str = "eos", temperature=temperature_standard, fraction=None,
               out_of_range: str = "raise", tables_dir=None):
    """Build a fluid at a fidelity level (what ``sf.Fluid(...)`` calls).

    Parameters
    ----------
    name : str or FluidSpec
        Built-in name or any CoolProp fluid name.
    level : {'ideal', 'table', 'eos'}
        ``'ideal'``: ideal gas with constant cp, or constant-property liquid, its
        constants from CoolProp at 1 atm and ``temperature``. ``'table'``: C1
        interpolation of tables in ``fluid_tables/``. ``'eos'``: CoolProp itself.
    temperature : float [K] or Quantity
        The fluid's own temperature. Default 293.15 K (20 degC).
    fraction : float [-] or Quantity, optional
        Solute mass fraction (solutions such as ethylene_glycol only).
    out_of_range : {'raise', 'eos'}
        Table level: raise on a state outside the table, or evaluate it with CoolProp.
    tables_dir : str or Path, optional
        Table level: directory holding the tables.
    """
    spec = resolve(name)
    if fraction is not None:
        spec = replace(spec, fraction=check_fraction(spec, fraction))
    T = check_temperature(temperature, f"fluid {spec.name!r}")
    if level not in LEVELS:
        close = difflib.get_close_matches(str(level), LEVELS, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise FluidError(f"fluid {spec.name!r}: level must be one of {', '.join(LEVELS)}, "
                         f"got {level!r}{hint}")
    if level == "ideal":
        from .ideal import ideal_from_coolprop
        return ideal_from_coolprop(spec, T)
    if level == "eos":
        from .eos import EosFluid
        return EosFluid(spec, T)
    from .tabulated import TableFluid
    return TableFluid(spec, T, out_of_range=out_of_range, tables_dir=tables_dir)


# -- CoolProp's name lists (read once, only when a non-built-in name is used) -------------
@lru_cache(maxsize=None)
def _coolprop_names() -> dict:
    """lower-case name or alias -> CoolProp's canonical fluid name."""
    import CoolProp.CoolProp as CP
    names = {}
    for fluid in CP.get_global_param_string("FluidsList").split(","):
        names[fluid.lower()] = fluid
        for alias in CP.get_fluid_param_string(fluid, "aliases").split(","):
            if alias:
                names.setdefault(alias.lower(), fluid)
    return names


@lru_cache(maxsize=None)
def _incompressible_solutions() -> frozenset:
    import CoolProp.CoolProp as CP
    return frozenset(CP.get_global_param_string("incompressible_list_solution").split(","))


@lru_cache(maxsize=None)
def _incompressibles() -> frozenset:
    import CoolProp.CoolProp as CP
    pure = CP.get_global_param_string("incompressible_list_pure").split(",")
    return frozenset(pure) | _incompressible_solutions()


def _unknown(name):
    choices = {}
    for key in list(BUILTIN) + list(_ALIASES):
        choices[key] = _ALIASES.get(key, key)
    for low, canonical in _coolprop_names().items():
        choices.setdefault(low, canonical)
    for inc in _incompressibles():
        choices.setdefault(f"incomp::{inc.lower()}", f"INCOMP::{inc}")
    close = difflib.get_close_matches(name.strip().lower(), list(choices), n=4, cutoff=0.6)
    suggestions = list(dict.fromkeys(choices[c] for c in close))
    hint = f"; did you mean {', '.join(map(repr, suggestions))}?" if suggestions else ""
    raise FluidError(f"unknown fluid {name!r}: neither a softflow built-in "
                     f"({', '.join(BUILTIN)}) nor a CoolProp fluid name{hint}")
