"""Vapour pressures of the liquids, for the cavitation check
(:func:`softflow.solve.model_checks.cavitation`), without CoolProp.

A liquid below its vapour pressure boils (cavitates); softflow models liquids
as one phase. The check needs the vapour pressure at the liquid's temperature
for every run of a liquid scene, at any fluid level ('ideal' included), and
importing CoolProp costs seconds: so the built-in liquids carry it in their
table metadata (``fluid_tables/<stem>.json``, entry ``vapour_pressure``,
written by :func:`softflow.fluids.tables.build.vapour_pressure_record`, which
documents the sources: CoolProp's saturation pressure for water, Raoult's law
on it for water-glycol solutions). Between its nodes (the table's temperatures,
2 K apart) ln p is interpolated linearly in 1/T, the Clausius-Clapeyron form:
3.3e-5 relative error for water against CoolProp at the midpoints; up to
:data:`EXTRAPOLATION_K` beyond the ends along the end segments (water: 1e-4
at 273.16 K, 1 K below the table, and 5e-4 at 373.15 K, 5 K above it).

A solution of glycol in water at another mass fraction than a table's gets
Raoult's law on water's record (the mole fraction of water times its vapour
pressure), as the table's own record is made. A liquid without a record (a
user's ConstantLiquid, another CoolProp liquid) is asked of CoolProp only where
CoolProp is loaded already (an 'eos' level fluid) and it has an answer; else
its vapour pressure is unknown (None) and the check is not made.
"""
from __future__ import annotations

import json
import math
import os
import sys
from functools import cache, lru_cache
from typing import Any

import numpy as np

#: How far [K] beyond a record's temperature range its end segments are extrapolated.
EXTRAPOLATION_K = 5.0

#: Molar masses [kg/mol] of the solutes whose solutions in water get a vapour
#: pressure by Raoult's law: ethylene glycol (CoolProp's MEG), C2H6O2, from
#: the standard atomic weights (C 12.011, H 1.008, O 15.999).
SOLUTE_MOLAR_MASS = {"MEG": 0.062068}


def water_mole_fraction(solute: str, mass_fraction: float, water_molar_mass: float) -> float:
    """Mole fraction of water in a solution of ``mass_fraction`` (by mass) of
    ``solute`` (a key of :data:`SOLUTE_MOLAR_MASS`) in water."""
    n_water = (1.0 - mass_fraction) / water_molar_mass
    return n_water / (n_water + mass_fraction / SOLUTE_MOLAR_MASS[solute])


@cache
def _record(stem: str, directory: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(1/T, ln p) of the ``vapour_pressure`` entry of table ``stem``'s metadata in
    ``directory``, or None where there is none."""
    from .tables import table_files
    _, json_path = table_files(stem, directory)
    try:
        entry = json.loads(json_path.read_text()).get("vapour_pressure")
    except (OSError, ValueError, AttributeError):
        return None
    if not entry:
        return None
    T = np.asarray(entry["temperature"], dtype=float)
    p = np.asarray(entry["pressure"], dtype=float)
    order = np.argsort(-1.0 / T)            # increasing in -1/T, i.e. in T
    return -1.0 / T[order], np.log(p[order])


def _lookup(stem: str) -> tuple[np.ndarray, np.ndarray] | None:
    """A record of table ``stem``: in the tables directory the table level reads,
    else in the package's own (a directory of older tables may lack the entry)."""
    from .tables import TABLES_ENV
    return _lookup_in(stem, os.environ.get(TABLES_ENV))


@cache
def _lookup_in(stem: str, env: str | None) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_lookup` with ``$SOFTFLOW_FLUID_TABLES`` = ``env``."""
    from .tables import default_directory, tables_directory
    for directory in dict.fromkeys((str(tables_directory()), str(default_directory()))):
        found = _record(stem, directory)
        if found is not None:
            return found
    return None


def _at(record: tuple[np.ndarray, np.ndarray], T: float) -> float | None:
    """The vapour pressure [Pa] of ``record`` at T [K] (module docstring), or None
    further than EXTRAPOLATION_K outside its range."""
    x, y = record
    lo, hi = -1.0 / x[0], -1.0 / x[-1]
    if not lo - EXTRAPOLATION_K <= T <= hi + EXTRAPOLATION_K:
        return None
    u = -1.0 / T
    if u < x[0]:
        i = 0
    elif u > x[-1]:
        i = x.size - 2
    else:
        return float(np.exp(np.interp(u, x, y)))
    slope = (y[i + 1] - y[i]) / (x[i + 1] - x[i])
    return float(math.exp(y[i] + slope * (u - x[i])))


def vapour_pressure(fluid: Any, temperature: float | None = None) -> float | None:
    """The vapour pressure [Pa] of a liquid ``fluid`` at ``temperature`` [K]
    (default: the fluid's own), or None where it is not known (module
    docstring). Never imports CoolProp."""
    if getattr(fluid, "compressible", False):
        return None
    T = float(fluid.temperature if temperature is None else temperature)
    spec = getattr(fluid, "spec", None)
    if spec is not None:
        record = _lookup(spec.table_stem)
        if record is not None:
            return _at(record, T)
        water = _lookup("water") if spec.coolprop_name in SOLUTE_MOLAR_MASS else None
        if water is not None and spec.fraction is not None:
            p = _at(water, T)
            return None if p is None else _water_fraction(spec) * p
    if "CoolProp" in sys.modules and spec is not None:
        return _from_coolprop(spec.coolprop_id, T)
    return None


def _water_fraction(spec: Any) -> float:
    """Mole fraction of water in the solution ``spec`` (molar mass of water from the
    water table's metadata, as the tables' records were made)."""
    from .tables import default_directory, table_files
    _, path = table_files("water", default_directory())
    M_water = float(json.loads(path.read_text())["molar_mass"])
    return water_mole_fraction(spec.coolprop_name, spec.fraction, M_water)


@lru_cache(maxsize=64)
def _from_coolprop(coolprop_id: str, T: float) -> float | None:
    """CoolProp's saturated-liquid pressure at T, or None where it has none."""
    try:
        import CoolProp.CoolProp as CP
        p = float(CP.PropsSI("P", "T", T, "Q", 0, coolprop_id))
    except Exception:       # no saturation data (INCOMP), T above the critical point
        return None
    return p if math.isfinite(p) and p > 0 else None
