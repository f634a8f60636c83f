"""Call-backs from the compiled loop (issue 38, softflow.solve.usercall): run()
CPU with ``settings.COMPILED_USER`` on (the compiled step loop calling Python
back) and off (every step in the Python loop), in turns, medians of --repeat
[min-max], and the largest difference of the results.

    python benchmarks/bench_callbacks.py --repeat 9

Scenes: a tank whose wall's h A a free-convection correlation sets at each
step's start (thermal='heat_transfer', 0.2 s), and a tank filled through a
tube by a source whose pressure is a Python function (0.05 s), each at a
fixed 1 ms step and adaptive. The paper's listing (a user component) is
timed the same way by ``bench_core.py --parts a``.
"""
from __future__ import annotations

import argparse
import statistics
import time
import warnings

import numpy as np

import softflow as sf
from softflow.solve import settings
from scenes import walled_tank


def function_source():
    s = sf.System()
    s += sf.PressureSource("src", pressure=lambda t: 1.2e5 + 1e4 * min(t, 0.01) / 0.01)
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    return s


CASES = {"wall h A by a correlation": (walled_tank, 0.2, "heat_transfer"),
         "Python-function source": (function_source, 0.05, "isothermal")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=9)
    args = ap.parse_args()
    warnings.simplefilter("ignore", sf.ModelWarning)
    print("| scene | steps | call-backs, ms | Python loop, ms | ratio | max rel. difference |")
    print("|---|---|---|---|---|---|")
    for name, (build, duration, thermal) in CASES.items():
        for step in (1e-3, None):
            kw = {"duration": duration, "thermal": thermal}
            if step is not None:
                kw["step"] = step
            sims, cpu, last = {}, {True: [], False: []}, {}
            for on in (True, False):
                settings.COMPILED_USER = on
                sims[on] = sf.Simulation(build(), **kw)
                sims[on].run()                      # compiled and warm before timing
            for i in range(args.repeat):
                for on in ((True, False) if i % 2 == 0 else (False, True)):
                    settings.COMPILED_USER = on
                    c0 = time.process_time()
                    last[on] = sims[on].run()
                    cpu[on].append(time.process_time() - c0)
            settings.COMPILED_USER = True
            a, b = last[True], last[False]
            p_a, p_b = a.get("tank", "pressure"), b.get("tank", "pressure")
            diff = (np.max(np.abs(p_a - p_b)) / np.max(np.abs(p_b)) if p_a.shape == p_b.shape
                    else float("nan"))
            on, off = (statistics.median(cpu[k]) for k in (True, False))
            spread = {k: f"[{min(v) * 1e3:.2f}-{max(v) * 1e3:.2f}]" for k, v in cpu.items()}
            label = f"{name}, {'fixed 1 ms' if step else 'adaptive'}"
            print(f"| {label} | {a.stats['steps']} | {on * 1e3:.2f} {spread[True]} | "
                  f"{off * 1e3:.2f} {spread[False]} | {on / off:.2f} | {diff:.1e} |")


if __name__ == "__main__":
    main()
