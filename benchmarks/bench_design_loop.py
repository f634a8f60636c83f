"""A design loop over a user component's closure values (issue 38, item 4):
the paper's listing (its ``Actuator`` a user component reading a PV curve,
a fluid's density and, here, the source's amplitude from closures) built and
run at a fixed 1 ms step for --designs designs, each a PV curve of its own
(the balloon's pressure rise scaled) and a step amplitude of its own.

    python benchmarks/bench_design_loop.py --designs 12

Each way runs in a fresh process whose compiled user components are written
under an empty directory of their own (the step loop's cache is the
install's: only the user components' compiles are counted):

* run-time values (``settings.USER_RUNTIME_VALUES``, the default): the
  closures' floats, fluids and curves are read from the component's layout
  at each call, one kernel for every design;
* constants: each design's values compiled into a kernel of its own, the
  way softflow compiled them before; past ``settings.USER_COMPILES_MAX``
  (4) designs the actuator and the source are called back in Python.

Printed per way: the whole loop's CPU, each design's CPU (build + run:
the first, the median of the others with their range), the kernels
compiled, the designs called back, and the largest difference of the
actuator's pressure from the call-back's run of the same design (relative
to its rise).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


def child(ways, designs):
    import softflow as sf
    from softflow.demo import PaperActuator, balloon_csv
    from softflow.solve import settings, usercompile
    root = Path(tempfile.mkdtemp(prefix="bench-design-loop-"))
    usercompile.cache_root = lambda: root
    settings.USER_RUNTIME_VALUES = ways == "run-time values"
    warnings.simplefilter("ignore", sf.ModelWarning)
    p0 = sf.pressure_atmospheric
    base = sf.PVCurve(str(balloon_csv()))
    v = base._knots
    rise = np.array([base.fdf_volume(volume=x)[0] for x in v]) - p0

    def build(k):
        scale, amplitude = 0.7 + 0.05 * k, 2.5e4 + 1e3 * k
        curve = sf.PVCurve(volume=v, pressure=p0 + scale * rise, gauge=False)
        s = sf.System()
        s += sf.PressureSource("source",
                               pressure=lambda t: p0 + (amplitude if t < 0.5 else 0.0))
        s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
        s += PaperActuator("actu", sf.water, curve)
        s.connect("tube", "source")
        s.connect("tube", "actu")
        return s

    times, called_back, diffs = [], 0, []
    start = time.process_time()
    for k in range(designs):
        t0 = time.process_time()
        sim = sf.Simulation(build(k), duration=1.0, step=1e-3)
        res = sim.run()
        times.append(time.process_time() - t0)
        called_back += bool(sim.asm.residual.network.callbacks)
        p = res.get("actu", "pressure")
        settings.COMPILED_USER_CODE = False
        ref = sf.Simulation(build(k), duration=1.0, step=1e-3).run().get("actu", "pressure")
        settings.COMPILED_USER_CODE = True
        diffs.append(float(np.max(np.abs(p - ref)) / np.ptp(ref)))
    total = time.process_time() - start - 0.0
    print(json.dumps({"times": times, "called_back": called_back,
                      "kernels": len(list(root.glob("*.py"))), "diff": max(diffs),
                      "total_runs": sum(times)}))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", type=int, default=12)
    ap.add_argument("--child", default=None)
    args = ap.parse_args()
    if args.child:
        child(args.child, args.designs)
        return
    print(f"{args.designs} designs of the paper's listing at a fixed 1 ms step, each a "
          "curve and an amplitude of its own; CPU seconds (build + run, the reference "
          "runs aside)\n")
    print("| way | loop total | first design | others: median [min-max] | kernels compiled "
          "| designs called back | max diff. to call-back |")
    print("|---|---|---|---|---|---|---|")
    for way in ("run-time values", "constants"):
        out = subprocess.run([sys.executable, __file__, "--designs", str(args.designs),
                              "--child", way], capture_output=True, text=True, check=True,
                             env=dict(os.environ))
        got = json.loads(out.stdout.strip().splitlines()[-1])
        t = got["times"]
        rest = t[1:] or t
        print(f"| {way} | {got['total_runs']:.2f} s | {t[0]:.2f} s | "
              f"{statistics.median(rest) * 1e3:.1f} ms [{min(rest) * 1e3:.1f}-"
              f"{max(rest) * 1e3:.1f}] | {got['kernels']} | {got['called_back']} | "
              f"{got['diff']:.1e} |")


if __name__ == "__main__":
    main()
