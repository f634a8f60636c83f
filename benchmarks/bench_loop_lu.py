"""The compiled step loop's linear solvers side by side on air chains: its
banded LU, its sparse LU (softflow.laws.sparselu) and the Python loop.

    python benchmarks/bench_loop_lu.py                       # N = 128, 1 000; fixed 1 ms
    python benchmarks/bench_loop_lu.py --n 200 --rtol 1e-8   # adaptive

Each line is one configuration in a fresh process (the LU is chosen by
``softflow.solve.settings``: COMPILED_BAND_MAX = 0 leaves the sparse LU,
COMPILED_SPARSE = False the banded one, COMPILED_STEPS = False the Python
loop), a warm-up run, then ``--repeat`` runs: CPU (``process_time``) of
``run()``, median [min-max], with the steps and Newton iterations.
"""
from __future__ import annotations

import argparse
import subprocess
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent


def one(n, mode, rtol, repeat):
    sys.path.insert(0, str(HERE))
    import numpy as np

    import softflow as sf
    from scenes import chain
    from softflow.solve import settings
    warnings.simplefilter("ignore")
    if mode == "band":
        settings.COMPILED_SPARSE = False
    elif mode == "sparse":
        settings.COMPILED_BAND_MAX = 0
    else:
        settings.COMPILED_STEPS = False
    options = dict(step=1e-3) if rtol is None else dict(rtol=rtol, refine=1)
    sim = sf.Simulation(chain(n), duration=0.2, **options)
    sim.run()
    cpu = []
    for _ in range(repeat):
        c0 = time.process_time()
        res = sim.run()
        cpu.append(time.process_time() - c0)
    print(f"N = {n:6d} {mode:7s} {'fixed 1 ms' if rtol is None else f'rtol {rtol:g}':11s} "
          f"{np.median(cpu) * 1e3:9.1f} ms [{min(cpu) * 1e3:.1f}-{max(cpu) * 1e3:.1f}]  "
          f"steps {res.stats['steps']}, Newton {res.stats['newton_iterations']}", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[128, 1000])
    ap.add_argument("--rtol", type=float, default=None, help="adaptive at this rtol "
                    "(default: fixed 1 ms steps)")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)    # (N, mode): a child
    args = ap.parse_args(argv)
    if args.one:
        one(int(args.one[0]), args.one[1], args.rtol, args.repeat)
        return
    print("air chains, 0.2 s; CPU of run(), medians of", args.repeat, "[min-max]; "
          "each line a fresh process; this machine:", sys.platform)
    for n in args.n:
        for mode in ("band", "sparse", "python"):
            extra = [] if args.rtol is None else ["--rtol", str(args.rtol)]
            subprocess.run([sys.executable, __file__, "--one", str(n), mode,
                            "--repeat", str(args.repeat), *extra], check=True)


if __name__ == "__main__":
    main()
