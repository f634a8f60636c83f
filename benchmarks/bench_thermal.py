"""Thermal benchmark (thermal issue): cost of the energy equation, and the
isothermal path before vs after it.

    python benchmarks/bench_thermal.py                  # thermal vs isothermal
    python benchmarks/bench_thermal.py --baseline DIR   # also the isothermal scenes
                                                        # on another checkout's src/

``--baseline`` runs the same scenes with the softflow found in ``DIR/src`` in a
subprocess, interleaved with this checkout: the isothermal ones (e.g. against
the commit before the thermal model: ``mkdir /tmp/base && git archive <commit>
| tar -x -C /tmp/base``) and, where the baseline has a thermal model, the
adiabatic ones too (before/after a thermal speed-up). Scenes: (c) of bench_core
(source + 4 x (tube, container), air, 1 ms, 1 s) and the chain of (b) with
N = 1000 (0.2 s). Medians of --repeat runs.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

SCENES = {"small (N=4, 1 s)": (4, 1.0), "chain N=1000 (0.2 s)": (1000, 0.2)}

TIMER = r"""
import json, statistics, sys, time
sys.path.insert(0, {here!r})
import softflow as sf
from scenes import chain
out = {{}}
for name, (N, T) in {scenes!r}.items():
    ts = []
    for _ in range({repeat}):
        sim = sf.Simulation(chain(N), duration=T, step=1e-3{kw})
        t0 = time.perf_counter(); sim.run(); ts.append(time.perf_counter() - t0)
    out[name] = (statistics.median(ts), sim.result.stats["steps"], sim.asm.n)
print(json.dumps(out))
"""


def timings(src, repeat, thermal=None):
    """{scene: (median s, steps, unknowns)} with the softflow under ``src``."""
    kw = "" if thermal is None else f", thermal={thermal!r}"
    code = TIMER.format(here=str(HERE), scenes=SCENES, repeat=repeat, kw=kw)
    env = dict(os.environ, PYTHONPATH=str(src))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--baseline", type=Path, default=None)
    args = ap.parse_args()
    here_src = HERE.parent / "src"
    iso = timings(here_src, args.repeat)
    adi = timings(here_src, args.repeat, "adiabatic")
    print("\nadiabatic vs isothermal (same scene, fixed 1 ms, air):")
    print(f"  {'scene':<22} {'isothermal':>11} {'adiabatic':>11} {'ratio':>6} {'unknowns':>13}")
    for name in SCENES:
        ti, _, ni = iso[name]
        ta, _, na = adi[name]
        print(f"  {name:<22} {ti * 1e3:>9.1f}ms {ta * 1e3:>9.1f}ms {ta / ti:>6.2f} "
              f"{ni:>6} -> {na:<6}")
    if args.baseline is not None:
        base_src = args.baseline / "src"
        modes = [None]
        try:                                # a baseline from before the thermal model
            timings(base_src, 1, "adiabatic")
            modes.append("adiabatic")
        except subprocess.CalledProcessError:
            pass
        medians = {}
        for mode in modes:
            # interleave baseline and current runs to share the machine's state
            base, cur = [], []
            for _ in range(3):
                base.append(timings(base_src, args.repeat, mode))
                cur.append(timings(here_src, args.repeat, mode))
            print(f"\n{mode or 'isothermal'} path, {args.baseline} vs this checkout "
                  f"(median of 3 x {args.repeat} runs):")
            print(f"  {'scene':<22} {'before':>9} {'after':>9} {'ratio':>6}")
            for name in SCENES:
                tb = statistics.median(b[name][0] for b in base)
                tc = statistics.median(c[name][0] for c in cur)
                medians[mode, name] = (tb, tc)
                print(f"  {name:<22} {tb * 1e3:>7.1f}ms {tc * 1e3:>7.1f}ms {tc / tb:>6.3f}")
        if "adiabatic" in modes:
            # the target (issue 38): thermal runs <= 2x isothermal, before and after
            print("\nadiabatic / isothermal, same sitting:")
            print(f"  {'scene':<22} {'before':>7} {'after':>7}")
            for name in SCENES:
                (ib, ic), (ab, ac) = medians[None, name], medians["adiabatic", name]
                print(f"  {name:<22} {ab / ib:>7.2f} {ac / ic:>7.2f}")

if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"\n({time.perf_counter() - t0:.0f} s)")
