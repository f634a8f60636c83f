"""Fixed costs (issue 13, item 6 "Faster start"): building a large System,
compiling it into a Simulation, and the per-run overhead of a small scene.

    python benchmarks/bench_build.py                  # N = 10 000, 5 repeats
    python benchmarks/bench_build.py --n 2000 --repeat 3 --runs 200

(1) build: PressureSource -> (CircularTube('t{i}', air, 0.1, 1e-3) ->
    Container('c{i}', air, 1e-6)) x N, chained with connect(prev, 't{i}') and
    connect('t{i}', 'c{i}'): constructors + connect, per component;
(2) compile: sf.Simulation(s, duration=0.01, step=1e-3) on that System, per
    component;
(3) a small scene's fixed per-run cost: source-tube-container, one fixed 1 ms
    step, repeated sim.run() (from the second run on, each starts from the
    consistent point at t = 0 its predecessor left, which Newton confirms);
(4) the same with sim.run(params={"t.diameter": 1e-3}): the built value, but
    given as a run-time parameter, so every run solves for its consistent
    point from the initial values (a cold start, as each run of a serial
    sweep does); no target, for comparison.

Each figure is the median over --repeat repeats (a small-scene repeat is the
median of --runs runs) with the range of the repeats (min-max), in wall-clock
time and in this process's CPU time (steadier when other processes share the
cores; the load average is printed); the last columns are the ratios to the
issue's targets (<= 1 meets one).
"""
from __future__ import annotations

import argparse
import gc
import os
import statistics
import time
import warnings

import softflow as sf

#: issue 13 targets: build and compile [us per component], per-run cost [ms]
TARGET_BUILD_US = 20.0
TARGET_COMPILE_US = 10.0
TARGET_RUN_MS = 0.5


def build_chain(n):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    prev = "src"
    for i in range(n):
        s += sf.CircularTube(f"t{i}", sf.air, 0.1, 1e-3)
        s += sf.Container(f"c{i}", sf.air, 1e-6)
        s.connect(prev, f"t{i}")
        s.connect(f"t{i}", f"c{i}")
        prev = f"c{i}"
    return s


def small_scene():
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    s += sf.CircularTube("t", sf.air, 0.1, 1e-3)
    s += sf.Container("c", sf.air, 1e-6)
    s.connect("src", "t")
    s.connect("t", "c")
    return s


def summary(values):
    return statistics.median(values), min(values), max(values)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000, help="tube+container pairs")
    ap.add_argument("--repeat", type=int, default=5, help="repeats of build and compile")
    ap.add_argument("--runs", type=int, default=300, help="small-scene runs per repeat")
    args = ap.parse_args()

    # validity findings of these scenes (a fast-filling tank) are not the subject
    warnings.simplefilter("ignore", sf.ModelWarning)
    # warm up: imports, lazy modules, first-call caches
    sim = sf.Simulation(build_chain(10), duration=0.01, step=1e-3)
    sim.run()

    # each figure twice: wall clock, and this process's CPU time (steadier on
    # a shared machine, where other processes take turns on the cores)
    wall = {"build": [], "compile": [], "run": [], "cold": []}
    cpu = {"build": [], "compile": [], "run": [], "cold": []}

    def clocks():
        return time.perf_counter(), time.process_time()

    for _ in range(args.repeat):
        gc.collect()
        w0, c0 = clocks()
        s = build_chain(args.n)
        w1, c1 = clocks()
        sf.Simulation(s, duration=0.01, step=1e-3)
        w2, c2 = clocks()
        wall["build"].append((w1 - w0) / len(s) * 1e6)
        cpu["build"].append((c1 - c0) / len(s) * 1e6)
        wall["compile"].append((w2 - w1) / len(s) * 1e6)
        cpu["compile"].append((c2 - c1) / len(s) * 1e6)
        del s

    sim = sf.Simulation(small_scene(), duration=1e-3, step=1e-3)
    sim.run()
    cold = {"t.diameter": 1e-3}
    for _ in range(args.repeat):
        for key, params in (("run", None), ("cold", cold)):
            ws, cs = [], []
            for _ in range(args.runs):
                w0, c0 = clocks()
                sim.run(params=params)
                w1, c1 = clocks()
                ws.append(w1 - w0)
                cs.append(c1 - c0)
            wall[key].append(statistics.median(ws) * 1e3)
            # process_time ticks coarsely on some systems: the mean of many runs
            cpu[key].append(sum(cs) / len(cs) * 1e3)

    load = os.getloadavg()
    print(f"N = {args.n} pairs ({2 * args.n + 1} components), {args.repeat} repeats; "
          f"{os.cpu_count()} CPUs, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    print(f"{'':32s} {'wall':>8s} {'min-max':>15s} {'cpu':>8s} {'target':>7s} "
          f"{'wall/t':>6s} {'cpu/t':>6s}")
    rows = [("build System [us/component]", "build", TARGET_BUILD_US),
            ("Simulation(...) [us/component]", "compile", TARGET_COMPILE_US),
            ("small run() [ms/run]", "run", TARGET_RUN_MS),
            ("small run(params=), cold [ms]", "cold", None)]
    for name, key, target in rows:
        med, lo, hi = summary(wall[key])
        c = statistics.median(cpu[key])
        ratios = (f"{target:7.2f} {med / target:6.2f} {c / target:6.2f}" if target
                  else f"{'-':>7s} {'-':>6s} {'-':>6s}")
        print(f"{name:32s} {med:8.2f} {lo:7.2f}-{hi:<7.2f} {c:8.2f} {ratios}")


if __name__ == "__main__":
    main()
