"""Fluid property cost and accuracy at the three fidelity levels.

For each built-in fluid and level: microseconds per call on a vector of 10 000
states (density and viscosity at given (p, T), and density at the fluid's own
temperature, the isothermal path), and the largest relative error of density and
viscosity against the eos level over the tables' ranges (air, nitrogen:
0.01-20 MPa x -40...150 degC; water, ethylene glycol: 0.05-20 MPa x 1...95 degC),
on those 10 000 random states plus a 60 x 60 grid that includes the corners.
Last column: the ideal level's density error at 20 MPa and 20 degC.

    python benchmarks/bench_fluids.py
"""
from __future__ import annotations

import statistics
import time

import numpy as np

import softflow as sf
from softflow.fluids.tables.build import BUILTIN_RANGES

N = 10_000
FLUIDS = {"air": sf.air, "nitrogen": sf.nitrogen, "water": sf.water,
          "ethylene_glycol": sf.ethylene_glycol}


def per_call_us(fn, repeats):
    fn()    # warm-up: builds interpolants, caches CoolProp states
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e6


def states(name, rng):
    (p_lo, p_hi), (T_lo, T_hi) = BUILTIN_RANGES[name]
    p, T = rng.uniform(p_lo, p_hi, N), rng.uniform(T_lo, T_hi, N)
    gp, gT = np.meshgrid(np.linspace(p_lo, p_hi, 60), np.linspace(T_lo, T_hi, 60))
    return p, T, np.concatenate([p, gp.ravel()]), np.concatenate([T, gT.ravel()])


def main():
    rng = np.random.default_rng(1)
    rows = []
    for name, ideal in FLUIDS.items():
        p, T, pe, Te = states(name, rng)
        eos = ideal.with_level("eos")
        ref_rho, ref_mu = eos.density(pe, Te), eos.viscosity(pe, Te)
        ideal_20MPa = abs(ideal.density(20e6) / eos.density(20e6) - 1)
        results = {}
        for level in ("ideal", "table", "eos"):
            f = ideal if level == "ideal" else ideal.with_level(level)
            reps = 3 if level == "eos" else 50
            t_rho = per_call_us(lambda: f.density(p, T), reps)
            t_mu = per_call_us(lambda: f.viscosity(p, T), reps)
            t_iso = per_call_us(lambda: f.density(p), reps)
            err_rho = np.max(np.abs(f.density(pe, Te) / ref_rho - 1))
            err_mu = np.max(np.abs(f.viscosity(pe, Te) / ref_mu - 1))
            results[level] = (t_rho, t_mu, t_iso, err_rho, err_mu)
        for level, (t_rho, t_mu, t_iso, e_rho, e_mu) in results.items():
            e_ref = results["eos"]
            speed = (f"{e_ref[0] / t_rho:,.0f}x / {e_ref[2] / t_iso:,.0f}x"
                     if level != "eos" else "1x")
            rows.append((name, level, t_rho, t_mu, t_iso, speed, e_rho, e_mu,
                         ideal_20MPa if level == "ideal" else None))

    print(f"Fluid properties on a vector of {N} states (median; us per call, "
          f"ns per state = us / 10)\n")
    print("| fluid | level | density(p, T) µs | viscosity(p, T) µs | density(p) isothermal µs "
          "| speed-up vs eos (p, T / isothermal) | max rel. error density | max rel. error "
          "viscosity | ideal density error at 20 MPa, 20 °C |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, level, t_rho, t_mu, t_iso, speed, e_rho, e_mu, e20 in rows:
        ref = level == "eos"
        print(f"| {name} | {level} | {t_rho:,.0f} | {t_mu:,.0f} | {t_iso:,.0f} | {speed} "
              f"| {'reference' if ref else f'{e_rho:.1e}'} "
              f"| {'reference' if ref else f'{e_mu:.1e}'} "
              f"| {'' if e20 is None else f'{100 * e20:.2f} %'} |")
    total = sum(f.stat().st_size for f in
                sf.fluids.tables.tables_directory().iterdir() if f.is_file())
    print(f"\nfluid_tables/: {total / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
