"""Design-study throughput: 1 000 variants of the source-tube-tank scene (issue 13).

PressureSource (1.5 bar) -> CircularTube (30 cm, diameter swept 0.5-2 mm) ->
Container (10 mL), air, 50 ms simulated, adaptive BDF at the default tolerance.
Each way of running the variants is timed end to end (checks, runs, sampling):

* serial:          sf.sweep(engine='serial'), a loop of sim.run(params=v)
* fresh builds:    a loop of System + Simulation + run per variant (the old way)
* processes (N):   sf.sweep(engine='processes', workers=N), the pool started inside
* dask (N):        sf.sweep(engine='dask', client=...) on a LocalCluster of N
                   single-threaded worker processes started beforehand (its start-up
                   is printed apart: a session keeps its cluster)
* batched:         sf.sweep(engine='batched'), where softflow.solve.batched exists

Prints variants/s (median of the repeats, with min-max) and the ratio to the
serial loop, the ways taken in turn within each repeat so that machine noise
hits them alike; then how far each engine's end pressures are from serial's.

Two phases. A LocalCluster's scheduler runs in a thread of the process that
starts it, and its periodic work (heartbeats, bookkeeping) takes the
interpreter's lock from whatever else that process does: with a cluster up,
1 000 batched variants took ~25 % more CPU in this process (min of 7: 481-494
against 363-399 ms without). So the ways that do not use Dask are timed
first, with no cluster in the process; then the cluster starts and the Dask
way is timed in turns with the serial loop again, its ratio taken to that
serial loop (the one timed beside it).

On a shared machine wall time follows the load, so the CPU seconds each way
spends per variant are printed too (this process, the pool's workers, the Dask
workers and nannies: psutil), and what that work would give on the workers'
cores alone (variants/s = cores used / CPU seconds per variant), an estimate.

    python benchmarks/bench_sweep.py [--variants 1000] [--repeat 5] [--workers 2]
"""
from __future__ import annotations

import argparse
import importlib.util
import logging
import os
import platform
import statistics
import time
import warnings

import numpy as np

import softflow as sf


def scene(diameter=1e-3):
    system = sf.System()
    system += sf.PressureSource("source", pressure=sf.Q_(1.5, "bar"))
    system += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=diameter)
    system += sf.Container("tank", sf.air, volume=sf.Q_(10, "mL"))
    system.connect("tube", "source")
    system.connect("tube", "tank")
    return system


DURATION = 0.05


def fresh_builds(diameters):
    """The old way: one System and one Simulation per variant."""
    out = []
    for d in diameters:
        res = sf.Simulation(scene(d), duration=DURATION).run(raise_on_failure=False)
        out.append(res.get("tank", "pressure")[-1])
    return np.array(out)


def cpu_seconds():
    """CPU time [s] of this process and all its children, live or ended."""
    import resource

    import psutil
    me = psutil.Process()
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    total = sum(me.cpu_times()[:2]) + ended.ru_utime + ended.ru_stime
    for child in me.children(recursive=True):
        try:
            total += sum(child.cpu_times()[:2])
        except psutil.Error:
            pass
    return total


def take_turns(ways, repeat, ends):
    """Wall and CPU seconds of each way per repeat, the ways in turn; the first
    repeat's end pressures go into ``ends``."""
    walls = {name: [] for name in ways}
    cpus = {name: [] for name in ways}
    for r in range(repeat):
        for name, way in ways.items():
            c = cpu_seconds()
            t = time.perf_counter()
            out = way()
            walls[name].append(time.perf_counter() - t)
            cpus[name].append(cpu_seconds() - c)
            if r == 0:
                ends[name] = (out if isinstance(out, np.ndarray) else out.data[:, 0, -1])
                if not isinstance(out, np.ndarray) and out.failed:
                    print(f"  {name}: {len(out.failed)} variants failed")
            print(f"  repeat {r + 1}: {name:38s} {walls[name][-1]:7.2f} s wall, "
                  f"{cpus[name][-1]:7.2f} s CPU, load {os.getloadavg()[0]:.1f}", flush=True)
    return walls, cpus


def machine():
    try:
        with open("/proc/cpuinfo") as fh:
            model = next((line.split(":", 1)[1].strip() for line in fh
                          if line.startswith("model name")), platform.processor())
    except OSError:
        model = platform.processor()
    return (f"{os.cpu_count()} cores ({model}), Python {platform.python_version()}, "
            f"NumPy {np.__version__}, load average {os.getloadavg()[0]:.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=1000)
    # one batched sweep (~0.5 s) varies up to 2x from repeat to repeat on a
    # shared VM, where the serial loop (~9 s) varies ~10 %: 5 repeats
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--no-dask", action="store_true", help="skip phase 2 (Dask)")
    args = ap.parse_args()
    warnings.simplefilter("ignore", sf.ModelWarning)    # wide tubes pass Mach 0.3 at t = 0

    diameters = np.linspace(0.5e-3, 2e-3, args.variants)
    variants = {"tube.diameter": diameters}
    sim = sf.Simulation(scene(), duration=DURATION)
    end = dict(outputs=["tank.pressure"], times=[DURATION])   # the end pressure of each
    sim.run()               # imports and first-call costs paid before any timing
    fresh_builds(diameters[:2])
    print(f"machine: {machine()}")
    print(f"{args.variants} variants, {args.repeat} repeats, {args.workers} workers\n")

    serial = "serial: loop of run(params=)"
    ways = {
        serial: lambda: sf.sweep(sim, variants, **end),
        "fresh builds (old way)": lambda: fresh_builds(diameters),
        f"processes ({args.workers} workers)":
            lambda: sf.sweep(sim, variants, engine="processes", workers=args.workers, **end),
    }
    if importlib.util.find_spec("softflow.solve.batched") is not None:
        if importlib.util.find_spec("softflow.solve.variants") is not None:
            from softflow.solve import settings

            def shared():
                # the same engine with its variants on one shared step
                # sequence per batch instead of the compiled loop
                settings.COMPILED_VARIANTS = False
                try:
                    return sf.sweep(sim, variants, engine="batched", **end)
                finally:
                    settings.COMPILED_VARIANTS = True
            ways["batched (compiled loop, 2 threads)"] = (
                lambda: sf.sweep(sim, variants, engine="batched", **end))
            ways["batched (shared steps)"] = shared
        else:
            ways["batched"] = lambda: sf.sweep(sim, variants, engine="batched", **end)
    else:
        print("batched: softflow.solve.batched is not in this tree\n")
    ends = {}
    print("phase 1: no Dask cluster in this process")
    walls, cpus = take_turns(ways, args.repeat, ends)
    walls2, cpus2 = {}, {}
    if not args.no_dask:
        walls2, cpus2 = phase_dask(args, sim, variants, end, ways[serial], ends, serial)
    table(args, walls, cpus, walls2, cpus2, serial, ends, diameters)


def phase_dask(args, sim, variants, end, serial_way, ends, serial):
    """Phase 2: the Dask engine timed in turns with a serial loop of its own."""
    from distributed import Client, LocalCluster
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    client = Client(cluster)
    print(f"\nphase 2: LocalCluster ({args.workers} worker processes) started in "
          f"{time.perf_counter() - t0:.1f} s (not counted), timed in turns with the serial loop")
    dask = f"dask LocalCluster ({args.workers} workers)"
    beside = {serial + " (beside Dask)": serial_way,
              dask: lambda: sf.sweep(sim, variants, engine="dask", client=client, **end)}
    walls2, cpus2 = take_turns(beside, args.repeat, ends)
    client.close()
    cluster.close()
    return walls2, cpus2


def table(args, walls, cpus, walls2, cpus2, serial, ends, diameters):
    """The throughput table and the end pressures' errors."""
    print("\n| way | variants/s, wall (median) | range | ratio to serial | CPU ms per "
          "variant | variants/s on its cores alone (est.) | ratio |")
    print("|---|---|---|---|---|---|---|")
    for rows, reference in ((walls, serial), (walls2, serial + " (beside Dask)")):
        if not rows:
            continue
        cpu_of = cpus if rows is walls else cpus2
        base = statistics.median(rows[reference])
        cpu_base = statistics.median(cpu_of[reference])
        for name, w in rows.items():
            rates = [args.variants / x for x in w]
            cpu = statistics.median(cpu_of[name])
            cores = args.workers if ("workers" in name or "2 threads" in name) else 1
            print(f"| {name} | {args.variants / statistics.median(w):.1f} | "
                  f"{min(rates):.1f}-{max(rates):.1f} | {base / statistics.median(w):.2f}x | "
                  f"{1e3 * cpu / args.variants:.1f} | {cores * args.variants / cpu:.1f} | "
                  f"{cores * cpu_base / cpu:.2f}x |")
    ref = ends[serial]
    rise = ref - sf.pressure_atmospheric
    # a tight reference (rtol 1e-8) for every 50th variant
    picks = np.arange(0, args.variants, 50)
    tight = sf.Simulation(scene(), duration=DURATION, rtol=1e-8)
    exact = np.array([tight.run(params={"tube.diameter": diameters[k]})["tank.pressure"][-1]
                      for k in picks])
    print("\nend pressure: largest |difference| / pressure rise, against serial (all "
          f"variants) and against rtol 1e-8 ({len(picks)} variants):")
    for name, e in ends.items():
        print(f"  {name:38s} {np.max(np.abs(e - ref) / rise):.2e}   "
              f"{np.max(np.abs(e[picks] - exact) / rise[picks]):.2e}")
    print(f"\nmachine at the end: load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
