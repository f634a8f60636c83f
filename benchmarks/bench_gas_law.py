"""The gas tube law's cost and effect: the default isothermal pipe-flow law
(entry, acceleration, choking) against the mean-density law it replaced as the
default, on the air scenes users run.

For each scene, both laws are run in turns in one process (``--repeats`` times,
CPU time), and the script prints the median CPU of each with its spread
(min-max), their ratio, the steps (default/mean-density), the largest Mach
number at a gas tube's exit with the default law, and the largest pressure
difference between the two laws relative to the scene's pressure range (how
far a scene that ran before moved).

    python benchmarks/bench_gas_law.py [--repeats 7]

Scenes: the paper's Fig. 5 with air (its accumulator's tube passes Mach 0.89
with the mean-density law, which runs with beyond_limits='warn' wherever it
passes its choke) and Fig. 3's first case in air, README's first network,
assess_scenes' near_choking, a choked 10 bar blowdown.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import softflow as sf
from softflow import paper_scenes as ps

sys.path.insert(0, str(Path(__file__).resolve().parent))
import assess_scenes  # noqa: E402


def first_network():
    s = sf.System()
    s += sf.PressureSource("source", pressure=sf.Q_(1.5, "bar"))
    s += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=sf.Q_(1, "mm"))
    s += sf.Container("tank", sf.air, volume=sf.Q_(10, "mL"))
    s.connect("tube", "source")
    s.connect("tube", "tank")
    return s, 0.05


def fig5_air():
    return ps.fig5(sf.air), ps.duration(5)


def fig3_air():
    return ps.fig3(ps.FIG3_CASES[0], fluid=sf.air), ps.duration(3)


def blowdown():
    """1 L at 10 bar abs to the atmosphere through 1 m of 4 mm tube (choked
    ~46 % of the run: the mean-density law runs past its limit, warned)."""
    s = sf.System()
    s += sf.Container("tank", sf.air, volume=1e-3, initial_pressure=1e6)
    s += sf.CircularTube("tube", sf.air, length=1.0, diameter=4e-3)
    s += sf.PressureSource("ambient", pressure=sf.pressure_atmospheric)
    s.connect("tank", "tube")
    s.connect("tube", "ambient")
    return s, 2.1


def near_choking():
    """assess_scenes.near_choking with the default law (Mach ~0.7 at first)."""
    s, duration, _ = assess_scenes.near_choking()
    return s, duration


SCENES = {"Fig. 5, air": fig5_air, "Fig. 3 (first case), air": fig3_air,
          "README first network": first_network, "assess near_choking": near_choking,
          "10 bar blowdown, 1 m x 4 mm": blowdown}


def with_law(system, law):
    for c in system.components:
        if isinstance(c, sf.CircularTube) and c.fluid.compressible:
            c.compressible = law
    return system


def peak_mach(res, system):
    """The largest Mach number at a gas tube's exit, where the exit pressure is
    the downstream node's or, choked, G c (c^2 = p/rho), the larger."""
    peak = 0.0
    for c in system.components:
        if isinstance(c, sf.CircularTube) and c.fluid.compressible:
            pa, pb = res.get(c.label, "pressure_a"), res.get(c.label, "pressure_b")
            low = np.minimum(pa, pb)
            G = np.abs(res.get(c.label, "massflow_a")) / (np.pi * c.diameter ** 2 / 4)
            exit_p = np.maximum(low, G * np.sqrt(low / c.fluid.density(low)))
            mach = G / c.fluid.density(exit_p) / c.fluid.speed_of_sound(exit_p)
            peak = max(peak, float(np.max(mach)))
    return peak


def run(build, law):
    system, duration = build()
    with_law(system, law)
    kw = {"beyond_limits": "warn"} if law == "mean_density" else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        t0 = time.process_time()
        res = sf.Simulation(system, duration=duration, **kw).run()
        cpu = time.process_time() - t0
    return res, system, cpu


def pressures(res):
    return {c: res[c] for c in res.columns() if c.split(".")[1] == "pressure"}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args(argv)
    print(f"softflow {sf.__version__}; CPU seconds, median [min-max] of {args.repeats} runs "
          "in turns")
    print(f"{'scene':26s} {'isothermal (default)':>24s} {'mean_density':>24s} {'ratio':>6s} "
          f"{'steps':>9s} {'exit Mach':>9s} {'moved':>7s}")
    for name, build in SCENES.items():
        cpu = {"isothermal": [], "mean_density": []}
        for _ in range(args.repeats):
            for law in cpu:
                res, system, t = run(build, law)
                cpu[law].append(t)
        new, sys_new, _ = run(build, "isothermal")
        old, _, _ = run(build, "mean_density")
        times = new.times
        moved = 0.0
        for col, p in pressures(new).items():
            q = np.interp(times, old.times, old[col])
            span = max(np.ptp(p), np.ptp(q), 1.0)
            moved = max(moved, float(np.max(np.abs(p - q)) / span))
        med = {k: statistics.median(v) for k, v in cpu.items()}
        cells = [f"{med[k] * 1e3:7.1f} ms [{min(v) * 1e3:.1f}-{max(v) * 1e3:.1f}]"
                 for k, v in cpu.items()]
        print(f"{name:26s} {cells[0]:>24s} {cells[1]:>24s} "
              f"{med['isothermal'] / med['mean_density']:6.2f} "
              f"{new.stats['steps']:4d}/{old.stats['steps']:<4d} {peak_mach(new, sys_new):9.2f} "
              f"{moved:7.2%}")


if __name__ == "__main__":
    main()
