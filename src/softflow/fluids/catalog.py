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
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

import numpy as np
from pint import Quantity

from ..constants import temperature_standard
from ..units import UnitError, to_si
from .base import LEVELS, FluidError, check_temperature

if TYPE_CHECKING:
    from .._typing import Scalar
    from .base import Fluid

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


def resolve(name: str | FluidSpec) -> FluidSpec:
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


def check_fraction(spec: FluidSpec, value: Scalar) -> float:
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
    snap = _snapshot()
    if snap is not None and solution in snap[2]:
        return snap[2][solution]
    import CoolProp.CoolProp as CP
    fid = f"INCOMP::{solution}"
    return CP.PropsSI("fraction_min", fid), CP.PropsSI("fraction_max", fid)


def make_fluid(name: str | FluidSpec, level: str = "eos",
               temperature: Scalar = temperature_standard, fraction: Scalar | None = None,
               out_of_range: str = "raise", tables_dir: str | Path | None = None) -> Fluid:
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
# Importing CoolProp takes 2-3 s (its fluid library loads), most of an error's wait
# for a misspelt name or a fraction out of range. The lists below are CoolProp's own
# (written from it; tests/test_bad_input_catalogue.py checks them against the installed
# CoolProp): used when that is the version installed, which importlib.metadata says
# without importing it, so names and fractions are validated in milliseconds and
# CoolProp is loaded only for a fluid that exists.
@lru_cache(maxsize=None)
def _snapshot() -> tuple[dict[str, str], frozenset[str], dict[str, tuple[float, float]]] | None:
    """(names {lower: canonical}, incompressibles, {solution: (min, max)}) from the
    lists below, or None where another CoolProp version is installed."""
    from importlib import metadata
    try:
        installed = metadata.version("CoolProp")
    except metadata.PackageNotFoundError:
        return None
    if installed != _SNAPSHOT_VERSION:
        return None
    names = {}
    for entry in " ".join(_SNAPSHOT_FLUIDS.split()).split(";"):
        canonical, *aliases = entry.split()
        names[canonical.lower()] = canonical
        for alias in aliases:
            names.setdefault(alias.lower(), canonical)
    solutions = {}
    for item in _SNAPSHOT_SOLUTIONS.split():
        name, lo, hi = item.split(":")
        solutions[name] = (float(lo), float(hi))
    return names, frozenset(_SNAPSHOT_PURE.split()) | frozenset(solutions), solutions


@lru_cache(maxsize=None)
def _coolprop_names() -> dict[str, str]:
    """lower-case name or alias -> CoolProp's canonical fluid name."""
    snap = _snapshot()
    if snap is not None:
        return snap[0]
    return _coolprop_names_live()


def _coolprop_names_live() -> dict[str, str]:
    import CoolProp.CoolProp as CP
    names = {}
    for fluid in CP.get_global_param_string("FluidsList").split(","):
        names[fluid.lower()] = fluid
        for alias in CP.get_fluid_param_string(fluid, "aliases").split(","):
            if alias:
                names.setdefault(alias.lower(), fluid)
    return names


@lru_cache(maxsize=None)
def _incompressible_solutions() -> frozenset[str]:
    snap = _snapshot()
    if snap is not None:
        return frozenset(snap[2])
    import CoolProp.CoolProp as CP
    return frozenset(CP.get_global_param_string("incompressible_list_solution").split(","))


@lru_cache(maxsize=None)
def _incompressibles() -> frozenset[str]:
    snap = _snapshot()
    if snap is not None:
        return snap[1]
    import CoolProp.CoolProp as CP
    pure = CP.get_global_param_string("incompressible_list_pure").split(",")
    return frozenset(pure) | _incompressible_solutions()


def _unknown(name: str) -> NoReturn:
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


# -- CoolProp 8.0.0's lists (see _snapshot): 'Name alias ...;' per fluid, the pure
# incompressibles, and 'solution:min:max' mass fractions ---------------------------------
_SNAPSHOT_VERSION = "8.0.0"
_SNAPSHOT_FLUIDS = """
R1234ze(E) R1234ZE R1234ZEE; CarbonDioxide R744 co2; CycloHexane CYCLOHEX; R218;
ParaDeuterium; HFE143m HFE-143m RE143A; Neon R720; 1-Butene 1Butene Butene; MD3M
Dodecamethylpentasiloxane; R116; R236EA; R1123 Trifluoroethylene HFO1123; Toluene; R22;
IsoButane R600A ISOBUTAN; CycloPropane CYCLOPRO; HydrogenSulfide H2S; Propylene PROPYLEN
R1270; R143a; R11; R12; n-Perfluorobutane C4F10; p-Xylene pXylene PC8H10; OrthoHydrogen
ORTHOHYD; m-Xylene mXylene MC8H10; MethylLinolenate MLINOLEN; NitrousOxide N2O; Xenon
Xe; R115; Methanol; D6 Dodecamethylcyclohexasiloxane; HydrogenChloride HCl; n-Octane
nOctane Octane NC8H18 n-C8H18; Krypton; D5 Decamethylcyclopentasiloxane; R410A; R23;
Ammonia NH3 R717; RC318; Benzene; Argon R740 Ar; R1233zd(E) R-1233zd(E) R1233zdE
TRANS-1-CHLORO-3 3 3-TRIFLUOROPROPENE; R1336mzz(Z) R1336MZZZ HFO-1336mzz-Z cis-1 1 4
4-Hexafluoro-2-butene; R1234yf; R1243zf R-1243zf 3 3-trifluoroprop-1-ene; CarbonMonoxide
CO; Fluorine; R245fa; MD2M Decamethyltetrasiloxane; n-Dodecane nDodecane Dodecane C12
NC12H26 n-C12H26; Methane CH4 R50 n-C1H4; Isopentane ipentane R601a; R1224YDZ; R1130(E)
trans-1 2-dichloroethene trans-12-dichloroethene R1130E R-1130(E); R245ca; SES36;
n-Decane Decane NC10H22 n-C10H22; DiethylEther DEE; Ethylene R1150; R113; R123;
R1336mzz(E) (E)-1 1 4 4-HEXAFLUORO-2-BUTENE R1336MZZE; n-Perfluoropentane C5F12; Water
H2O R718; R114; R124; MDM Octamethyltrisiloxane; n-Hexane nHexane Hexane NC6H14 n-C6H14;
PropyleneGlycol 1 2-Propanediol PGLYCOL PG; R227EA; Dichloroethane 1 2-dichloroethane;
Helium He R704; o-Xylene oXylene OC8H10; MethylPalmitate MPALMITA; VinylChloride
Chloroethene; R13; R404A; EthyleneOxide; R40 MethylChloride; Ethane R170 n-C2H6; MM
Hexamethyldisiloxane; R125; R1234ze(Z) R1234ZEZ; R236FA; R142b; n-Propane Propane R290
C3H8 NC3H8 n-C3H8; R21; ParaHydrogen PARAHYD; SulfurHexafluoride SF6; Nitrogen N2 R728;
CarbonylSulfide COS; Hydrogen H2 R702; trans-2-Butene T2BUTENE; IsoButene IBUTENE;
Oxygen O2 R732; R41; OrthoDeuterium; R134a; SulfurDioxide SO2; Neopentane neopentn;
R507A; R1132(E) trans-1 2-difluoroethene R1132E R-1132E R-1132(E); Isohexane ihexane;
Cyclopentane CYCLOPEN; DimethylCarbonate DMC; Novec649 Novec1230; MD4M
Tetradecamethylhexasiloxane; MethylStearate MSTEARAT; n-Nonane nonane NC9H20 n-C9H20;
MethylOleate MOLEATE; DimethylEther DME RE170; HeavyWater D2O; Air R729; R13I1 CF3I;
MethylLinoleate MLINOLEA; R32; n-Heptane nHeptane Heptane NC7H16 n-C7H16; n-Butane
nButane butane R600 NC4H10 n-C4H10; Tetrahydrofuran THF; n-Pentane nPentane Pentane R601
NC5H12 n-C5H12; R14; n-Perfluorohexane C6F14; n-Undecane Undecane C11 NC11H24 n-C11H24;
Ethanol C2H6O; R161 Fluoroethane; Chlorine Cl2; Acetone; R407C; R141b; EthylBenzene
EBENZENE; R152A; D4 Octamethylcyclotetrasiloxane; Deuterium D2; Propyne; R365MFC;
cis-2-Butene C2BUTENE
"""
_SNAPSHOT_PURE = """
TY24 AS55 NBS PGLT HCB Hexane XLT AS30 PNF PCL HC10 ExampleDigitalPure PLR DowJ DowJ2
SAB HFE2 HC20 TVP1 HC30 AS20 LiqNa ZS45 AS40 FoodIce DSF FoodFiber PMS2 HY40 TY10 TCO
PCR TY20 PHR ZS25 HY30 DowQ Water DEB TVP1869 ExamplePure FoodProtein FoodAsh HCM
FoodFat T66 AS10 FoodWater ZS55 TY15 T72 DowQ2 S800 HC40 PHE ZS10 HFE FoodCarbohydrate
TX22 Air PBB HY45 PMR XLT2 Ethanol PMS1 HY50 Acetone TD12 ZS40 NaK HC50 HY20 PNF2
"""
_SNAPSHOT_SOLUTIONS = """
MEA:0:0.6 IceEA:0.05:0.35 MKA:0:0.45 AEG:0.1:0.6 ZMC:0.3:0.7 MKA2:0.11:0.41 AKF:0.4:1
ZLC:0.3:0.7 VMG:0.072:0.206 MEA2:0.11:0.6 ZFC:0.3:0.6 MPG2:0.15:0.57 VMA:0.1:0.9
ExampleSolution:0.05:0.35 VNA:0.07:0.231 MAM2:0.078:0.236 MAM:0:0.3 MNA2:0:0.23
APG:0.1:0.6 MKC:0:0.4 AL:0.1:0.6 MNA:0:0.23 MMG2:0:0.205 ZAC:0.06:0.5 VCA:0.147:0.299
MGL:0:0.6 MKF:0:0.48 MGL2:0.195:0.63 MLI:0:0.24 GKN:0.1:0.6 VKC:0.128:0.389 MITSW:0:0.12
LiBr:0:0.75 MMA2:0.078:0.474 PK2:0.3:1 AN:0.1:0.6 IcePG:0.05:0.35 MMG:0:0.3 MEG2:0:0.56
ExampleMelinder:0:0.6 ZM:0:1 MCA2:0.09:0.294 MEG:0:0.6 MKC2:0:0.39 ExampleSecCool:0:0.5
IceNA:0.05:0.35 MPG:0:0.6 MMA:0:0.6 MCA:0:0.3 FRE:0.19:0.5 PKL:0.1:0.6
ExampleDigital:0:1
"""
