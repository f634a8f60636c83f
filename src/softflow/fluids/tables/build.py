"""Building property tables from CoolProp (``python -m softflow.fluids.tables build``).

Grid: uniform in p and T. Gases store the compressibility factor Z (density is
p / (Z R T): Z is nearly linear in p, so a cubic reproduces it far better than
the density itself, which spans a factor 400 over the range); liquids store the
density. The interpolation error is then measured against CoolProp at points
that are not grid nodes: every cell centre, every edge midpoint and 20 000
random points; the largest error of each property is recorded, and twice that
as the bound the table level promises (the margin covers points not sampled;
at least 1e-12, above rounding).
"""
from __future__ import annotations

import datetime
import json
from pathlib import Path

import numpy as np

from ..catalog import BUILTIN
from ..hermite import Bicubic, UniformAxis
from ..vapour import SOLUTE_MOLAR_MASS, water_mole_fraction
from . import FORMAT, FluidTableError, coolprop_version, sha256_of, table_files

#: Range of each built-in table: ((p_lo, p_hi) [Pa], (T_lo, T_hi) [K]). The gases
#: start at 10 kPa (vacuum actuators run down to about 0.1 bar abs); on the same
#: 81 pressure nodes their error at 10-50 kPa is 8-140x below the recorded bounds
#: (set by high pressure). The liquids start at 50 kPa: below it water nears its
#: vapour pressure.
BUILTIN_RANGES = {
    "air": ((0.01e6, 20e6), (233.15, 423.15)),          # -40 ... 150 degC
    "nitrogen": ((0.01e6, 20e6), (233.15, 423.15)),
    "water": ((0.05e6, 20e6), (274.15, 368.15)),        # 1 ... 95 degC
    "ethylene_glycol": ((0.05e6, 20e6), (274.15, 368.15)),
}
PRESSURE_NODES = 81
TEMPERATURE_STEP = 2.0    # K
RANDOM_CHECK_POINTS = 20000

_UNITS = {"Z": "1", "density": "kg/m**3", "viscosity": "Pa*s", "cp": "J/kg/K",
          "cv": "J/kg/K", "enthalpy": "J/kg", "internal_energy": "J/kg",
          "speed_of_sound": "m/s"}
#: errors of these are relative to the table's span of values (they pass through zero)
_SPAN_RELATIVE = ("enthalpy", "internal_energy")


def table_properties(spec, liquid: bool) -> tuple:
    """Which properties a table of this fluid holds."""
    first = ("density",) if liquid else ("Z",)
    rest: tuple[str, ...] = ("viscosity", "cp", "cv", "enthalpy", "internal_energy")
    if spec.backend != "INCOMP":
        rest += ("speed_of_sound",)
    return first + rest


def _water_fraction(spec) -> float:
    """Mole fraction of water in the solution ``spec`` (water's molar mass from
    CoolProp)."""
    from ..eos import abstract_state
    M_water = abstract_state(BUILTIN["water"], True).molar_mass()
    return water_mole_fraction(spec.coolprop_name, spec.fraction, M_water)


def _saturation_pressures(spec, T) -> np.ndarray | None:
    """The vapour pressure [Pa] of the liquid ``spec`` at temperatures ``T``
    (:func:`vapour_pressure_record`), or None where there is none to give."""
    import CoolProp.CoolProp as CP
    T = np.asarray(T, dtype=float)
    if spec.backend == "HEOS":
        return np.array([CP.PropsSI("P", "T", t, "Q", 0, spec.coolprop_id) for t in T.tolist()])
    if spec.coolprop_name in SOLUTE_MOLAR_MASS and spec.fraction is not None:
        water = np.array([CP.PropsSI("P", "T", t, "Q", 0, "HEOS::Water") for t in T.tolist()])
        return _water_fraction(spec) * water
    return None


def vapour_pressure_record(spec, temperatures) -> dict | None:
    """The ``vapour_pressure`` entry of a liquid's table metadata: its vapour
    (saturation) pressure at ``temperatures`` [K] (the table's temperature
    nodes), read back by :func:`softflow.fluids.vapour.vapour_pressure`
    without CoolProp (importing it costs seconds), ln p interpolated linearly
    in 1/T (the Clausius-Clapeyron form, exact for a constant heat of
    vaporization); None for a fluid without one.

    Pure fluids (HEOS): CoolProp's saturated liquid (Q = 0). Water-glycol
    solutions (CoolProp's INCOMP::MEG has no saturation pressure below
    373.15 K): Raoult's law for an ideal solution, x_water times the vapour
    pressure of water (CoolProp HEOS::Water), x_water the mole fraction of
    water at the table's mass fraction of glycol
    (:data:`softflow.fluids.vapour.SOLUTE_MOLAR_MASS`); glycol's own vapour pressure is neglected
    (it boils at 197 degC at 1 atm). Water-glycol solutions are reported to
    deviate negatively from Raoult's law, which would make this an upper
    bound: a cavitation warning on it errs on the early side. The entry
    records its source and the largest relative error of the interpolation
    at the midpoints between the nodes, against the same source."""
    T = np.asarray(temperatures, dtype=float)
    p = _saturation_pressures(spec, T)
    if p is None:
        return None
    mid = 0.5 * (T[1:] + T[:-1])
    ref = _saturation_pressures(spec, mid)
    got = np.exp(np.interp(-1.0 / mid, -1.0 / T, np.log(p)))
    if spec.backend == "HEOS":
        source = (f"CoolProp {coolprop_version()} {spec.coolprop_id}, saturated liquid "
                  "(PropsSI('P', 'T', T, 'Q', 0))")
    else:
        x_w = _water_fraction(spec)
        source = (f"Raoult's law: x_water = {x_w:.6f} (mole fraction of water at mass "
                  f"fraction {spec.fraction:g} of {spec.coolprop_name}, molar mass "
                  f"{SOLUTE_MOLAR_MASS[spec.coolprop_name]} kg/mol) times the vapour "
                  f"pressure of water from CoolProp {coolprop_version()} HEOS::Water; "
                  "the solute's own vapour pressure neglected; CoolProp's INCOMP "
                  "backend has no saturation pressure below 373.15 K; an estimate "
                  "(an upper bound where the solution deviates negatively from "
                  "Raoult's law)")
    return {"unit": "Pa", "temperature": T.tolist(), "pressure": p.tolist(),
            "interpolation": "ln p linear in 1/T between the nodes (Clausius-Clapeyron "
                             "form), and along the end segments up to 5 K beyond them",
            "max_error": float(np.max(np.abs(got / ref - 1.0))),
            "error_measure": "relative, at the midpoints between the nodes",
            "source": source}


def add_vapour_pressure(names=None, directory=None, log=print) -> None:
    """Add (or renew) the ``vapour_pressure`` entry of existing liquid tables'
    metadata without rebuilding them (their npz and its SHA-256 stay as they
    are), for the built-in liquids by default. The shipped water and
    ethylene_glycol-0.6 tables got theirs so (CoolProp 8.0.0)."""
    from ..catalog import resolve
    from . import read_table, tables_directory
    directory = tables_directory(directory)
    for name in names or [n for n in BUILTIN_RANGES if BUILTIN[n].liquid]:
        spec = resolve(name)
        npz_path, json_path = table_files(spec.table_stem, directory)
        meta = read_table(npz_path, json_path).meta
        T = UniformAxis(*meta["temperature_range"], meta["grid"]["temperature_nodes"]).nodes
        record = vapour_pressure_record(spec, T)
        if record is None:
            log(f"{spec.name}: no vapour pressure to record")
            continue
        meta["vapour_pressure"] = record
        json_path.write_text(json.dumps(meta, indent=1) + "\n")
        log(f"{spec.name}: vapour pressure at {len(T)} temperatures, interpolation "
            f"error {record['max_error']:.1e} -> {json_path.name}")


def _getters(state):
    return {"Z": state.compressibility_factor, "density": state.rhomass,
            "viscosity": state.viscosity, "cp": state.cpmass, "cv": state.cvmass,
            "enthalpy": state.hmass, "internal_energy": state.umass,
            "speed_of_sound": state.speed_sound}


def sample(state, props, p, T):
    """CoolProp values of ``props`` at states (p, T) (arrays of one shape), and phases."""
    import CoolProp.CoolProp as CP
    get = _getters(state)
    out = {k: np.empty(p.size) for k in props}
    phases = np.empty(p.size, dtype=int)
    has_phase = state.backend_name() != "IncompressibleBackend"
    for n, (pk, Tk) in enumerate(zip(p.ravel().tolist(), T.ravel().tolist())):
        try:
            state.update(CP.PT_INPUTS, pk, Tk)
        except ValueError as err:
            raise FluidTableError(f"CoolProp failed at p = {pk:g} Pa, T = {Tk:g} K: {err}") \
                from None
        phases[n] = state.phase() if has_phase else CP.iphase_liquid
        for k in props:
            out[k][n] = get[k]()
    return {k: v.reshape(p.shape) for k, v in out.items()}, phases


def _check_points(p_axis, T_axis, rng, n_random):
    pn, Tn = p_axis.nodes, T_axis.nodes
    pm, Tm = 0.5 * (pn[1:] + pn[:-1]), 0.5 * (Tn[1:] + Tn[:-1])
    sets = [np.meshgrid(pm, Tm, indexing="ij"), np.meshgrid(pm, Tn, indexing="ij"),
            np.meshgrid(pn, Tm, indexing="ij"),
            (rng.uniform(p_axis.lo, p_axis.hi, n_random),
             rng.uniform(T_axis.lo, T_axis.hi, n_random))]
    return (np.concatenate([s[0].ravel() for s in sets]),
            np.concatenate([s[1].ravel() for s in sets]))


def build_table(spec, p_range, T_range, directory, *, pressure_nodes=PRESSURE_NODES,
                temperature_step=TEMPERATURE_STEP, random_points=RANDOM_CHECK_POINTS,
                log=print) -> dict:
    """Sample CoolProp on the grid, measure the interpolation error, write the files.

    Parameters
    ----------
    spec : FluidSpec
    p_range : (float, float) [Pa]
    T_range : (float, float) [K]
    directory : str or Path
    pressure_nodes : int
    temperature_step : float [K]
        Largest temperature spacing (the node count is rounded up).
    random_points : int
        Random off-grid states at which the error is measured, besides every cell
        centre and edge midpoint.

    Returns the metadata written.
    """
    import CoolProp.CoolProp as CP
    from ..eos import abstract_state, is_liquid, valid_range
    (p_lo, p_hi), (T_lo, T_hi) = map(float, p_range), map(float, T_range)
    if not (0 < p_lo < p_hi and 0 < T_lo < T_hi):
        raise FluidTableError(f"table range must have 0 < p_lo < p_hi and 0 < T_lo < T_hi, "
                              f"got p {p_range} Pa, T {T_range} K")
    liquid = is_liquid(spec, 0.5 * (T_lo + T_hi))
    (Tv_lo, Tv_hi), pv_hi = valid_range(spec, liquid)
    if T_lo < Tv_lo or T_hi > Tv_hi or p_hi > pv_hi:
        raise FluidTableError(f"fluid {spec.name!r}: table range p {p_lo:g} ... {p_hi:g} Pa, "
                              f"T {T_lo:g} ... {T_hi:g} K exceeds CoolProp's range "
                              f"T {Tv_lo:g} ... {Tv_hi:g} K, p <= {pv_hi:g} Pa")
    state = abstract_state(spec, liquid)
    props = table_properties(spec, liquid)
    p_axis = UniformAxis(p_lo, p_hi, pressure_nodes)
    T_axis = UniformAxis(T_lo, T_hi, max(4, int(np.ceil((T_hi - T_lo) / temperature_step)) + 1))
    P, T = np.meshgrid(p_axis.nodes, T_axis.nodes, indexing="ij")
    values, phases = sample(state, props, P, T)
    liquid_like = np.isin(phases, [CP.iphase_liquid, CP.iphase_supercritical_liquid])
    if spec.backend == "HEOS" and not liquid and liquid_like.any():
        raise FluidTableError(f"fluid {spec.name!r}: the table range crosses into the liquid "
                              f"phase (e.g. at p = {P.ravel()[liquid_like][0]:g} Pa, T = "
                              f"{T.ravel()[liquid_like][0]:g} K); choose a range in one phase")
    molar_mass = None if spec.backend == "INCOMP" else state.molar_mass()
    # CoolProp's own gas constant for this fluid (Z = p / (rho R T) with it)
    R = None if molar_mass is None else state.gas_constant() / molar_mass

    pc, Tc = _check_points(p_axis, T_axis, np.random.default_rng(20240601), random_points)
    ref, _ = sample(state, props + (() if liquid else ("density",)), pc, Tc)
    errors = {}
    for k in props:
        got = Bicubic(p_axis, T_axis, values[k])(pc, Tc)
        scale = np.ptp(values[k]) if k in _SPAN_RELATIVE else np.abs(ref[k])
        errors[k] = float(np.max(np.abs(got - ref[k]) / scale))
        if k == "Z":
            rho = pc / (got * R * Tc)
            errors["density"] = float(np.max(np.abs(rho - ref["density"]) / ref["density"]))

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    npz_path, json_path = table_files(spec.table_stem, directory)
    vapour = vapour_pressure_record(spec, T_axis.nodes) if liquid else None
    np.savez_compressed(npz_path, pressure=p_axis.nodes, temperature=T_axis.nodes, **values)
    meta = {
        "format": FORMAT,
        "fluid": spec.name,
        "coolprop_id": spec.coolprop_id,
        "backend": spec.backend,
        "coolprop_name": spec.coolprop_name,
        "fraction": spec.fraction,
        "liquid": liquid,
        "phase_imposed": "liquid" if liquid and spec.backend == "HEOS" else None,
        "molar_mass": molar_mass,
        "specific_gas_constant": R,
        "coolprop_version": coolprop_version(),
        "pressure_range": [p_lo, p_hi],
        "temperature_range": [T_lo, T_hi],
        "grid": {"pressure_nodes": p_axis.n, "temperature_nodes": T_axis.n,
                 "spacing": "uniform", "pressure_step": p_axis.step,
                 "temperature_step": T_axis.step},
        "interpolation": "bicubic Hermite per cell, node derivatives of the not-a-knot "
                         "tensor-product cubic spline (C2; value and first derivatives "
                         "continuous across cells)",
        "properties": {
            k: {"unit": _UNITS[k], "max_error": errors[k],
                "error_bound": max(2.0 * errors[k], 1e-12),
                "error_measure": ("absolute / span of the tabulated values"
                                  if k in _SPAN_RELATIVE else "relative"),
                **({"derived": True, "from": "Z"} if k == "density" and not liquid else {})}
            for k in errors},
        "error_check": {"points": int(pc.size),
                        "where": "cell centres, edge midpoints and "
                                 f"{random_points} random points"},
        **({} if vapour is None else {"vapour_pressure": vapour}),
        "built": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "built_with": "python -m softflow.fluids.tables build",
        "sha256": sha256_of(npz_path),
    }
    json_path.write_text(json.dumps(meta, indent=1) + "\n")
    log(f"{spec.name}: {p_axis.n} x {T_axis.n} nodes, p {p_lo:g} ... {p_hi:g} Pa, "
        f"T {T_lo:g} ... {T_hi:g} K -> {npz_path.name} "
        f"({npz_path.stat().st_size / 1024:.0f} KiB); max errors "
        + ", ".join(f"{k} {v:.1e}" for k, v in errors.items()))
    return meta


def build_builtin(names=None, directory=None, log=print):
    """(Re)build the tables of the built-in fluids (all of them by default)."""
    from . import tables_directory
    directory = tables_directory(directory)
    for name in names or BUILTIN_RANGES:
        p_range, T_range = BUILTIN_RANGES[name]
        build_table(BUILTIN[name], p_range, T_range, directory, log=log)
