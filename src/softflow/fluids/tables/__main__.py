"""Command line: build or check the property tables of the 'table' level.

    python -m softflow.fluids.tables build                 # the built-in fluids
    python -m softflow.fluids.tables build water           # one of them
    python -m softflow.fluids.tables build ethylene_glycol --fraction 0.4
    python -m softflow.fluids.tables build CO2 --pressure "0.5 bar" "30 bar" \\
        --temperature "0 degC" "150 degC"
    python -m softflow.fluids.tables check                 # verify every table

Limits may carry units (quoted, e.g. "20 MPa", "-40 degC"); plain numbers are Pa and K.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from ...units import Q_, to_si
from ..base import FluidError
from ..catalog import check_fraction, resolve
from . import read_table, table_files, tables_directory
from .build import BUILTIN_RANGES, PRESSURE_NODES, TEMPERATURE_STEP, build_table


def _value(text: str, unit: str, name: str) -> float:
    number, _, rest = text.strip().partition(" ")
    try:
        value = float(number) if not rest else Q_(float(number), rest.strip())
    except ValueError:
        raise FluidError(f"{name}: cannot read {text!r} (write e.g. '20 MPa' or 2e7)") from None
    return to_si(value, unit, name=name)


def _build(args) -> int:
    names = args.fluids or list(BUILTIN_RANGES)
    for name in names:
        spec = resolve(name)
        if args.fraction is not None:
            spec = replace(spec, fraction=check_fraction(spec, args.fraction))
        default = BUILTIN_RANGES.get(spec.name)
        if args.pressure:
            p_range = tuple(_value(v, "Pa", "pressure") for v in args.pressure)
        elif default:
            p_range = default[0]
        else:
            raise FluidError(f"{name}: give --pressure LO HI (no default range)")
        if args.temperature:
            T_range = tuple(_value(v, "K", "temperature") for v in args.temperature)
        elif default:
            T_range = default[1]
        else:
            raise FluidError(f"{name}: give --temperature LO HI (no default range)")
        build_table(spec, p_range, T_range, tables_directory(args.dir),
                    pressure_nodes=args.pressure_nodes,
                    temperature_step=args.temperature_step)
    return 0


def _check(args) -> int:
    directory = tables_directory(args.dir)
    stems = sorted(p.stem for p in directory.glob("*.json"))
    if not stems:
        print(f"no tables in {directory}")
        return 1
    bad = 0
    for stem in stems:
        npz_path, json_path = table_files(stem, directory)
        try:
            table = read_table(npz_path, json_path)
        except FluidError as err:
            print(f"FAIL {stem}: {err}")
            bad += 1
            continue
        m = table.meta
        worst = ", ".join(f"{k} {v['max_error']:.1e}" for k, v in m["properties"].items())
        print(f"ok   {stem}: {m['coolprop_id']}, CoolProp {m['coolprop_version']}, "
              f"p {m['pressure_range'][0]:g} ... {m['pressure_range'][1]:g} Pa, "
              f"T {m['temperature_range'][0]:g} ... {m['temperature_range'][1]:g} K, "
              f"{m['grid']['pressure_nodes']} x {m['grid']['temperature_nodes']}; {worst}")
    return 1 if bad else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m softflow.fluids.tables",
                                     description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    b = sub.add_parser("build", help="(re)build tables from CoolProp")
    b.add_argument("fluids", nargs="*", help=f"fluid names (default: {' '.join(BUILTIN_RANGES)})")
    b.add_argument("--dir", help="output directory (default: the tables directory)")
    b.add_argument("--fraction", type=float, help="solute mass fraction (solutions)")
    b.add_argument("--pressure", nargs=2, metavar=("LO", "HI"), help="absolute pressure range")
    b.add_argument("--temperature", nargs=2, metavar=("LO", "HI"), help="temperature range")
    b.add_argument("--pressure-nodes", type=int, default=PRESSURE_NODES)
    b.add_argument("--temperature-step", type=float, default=TEMPERATURE_STEP,
                   help="largest temperature spacing [K]")
    c = sub.add_parser("check", help="verify every table (hash, format, CoolProp version)")
    c.add_argument("--dir", help="tables directory")
    args = parser.parse_args(argv)
    try:
        return _build(args) if args.command == "build" else _check(args)
    except FluidError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
