"""The compiled step loop's linear solvers side by side on air chains: its
banded LU, its sparse LU (softflow.laws.sparselu) and the Python loop.

    python benchmarks/bench_loop_lu.py                       # N = 128, 1 000; fixed 1 ms
    python benchmarks/bench_loop_lu.py --n 200 --rtol 1e-8   # adaptive

Each line is one configuration in a fresh process (the LU is chosen by
``softflow.solve.settings``: COMPILED_BAND_MAX = 0 leaves the sparse LU,
COMPILED_SPARSE = False the banded one, COMPILED_STEPS = False the Python
loop), a warm-up run, then ``--repeat`` runs: CPU (``process_time``) of
``run()``, median [min-max], with the steps and Newton iterations.

    python benchmarks/bench_loop_lu.py --profile             # the dense LU alone

``--profile``: the compiled dense LU (``softflow.laws.stepper.lu_factor`` and
``lu_solve``) on the Jacobian of an air chain of N = 8 tubes (34 unknowns, the
size the loop factors densely) at its initial point, with its factors'
profile (pivots with room for it, as the loop allocates them) and without
(the full loops), each timed in a compiled loop of calls: the best of 7
repeats, ns a call.
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


def profile_lu(n_tubes=8):
    """The dense LU with and without its factors' profile (module docstring)."""
    sys.path.insert(0, str(HERE))
    import numba
    import numpy as np

    import softflow as sf
    from scenes import chain
    from softflow.solve.netcore import law_module
    st = law_module("stepper")
    warnings.simplefilter("ignore")
    asm = sf.Simulation(chain(n_tubes), duration=0.05).asm
    asm.residual(asm.x0.copy(), asm.S0, 0.0, 1e-3, jac=True)
    J = np.array(asm.dense_jacobian())
    n = J.shape[0]

    @numba.njit
    def solves(A, piv, b, out, reps):
        one = np.ones(A.shape[0])
        for _ in range(reps):
            st.lu_solve(A, piv, one, one, b, out)
            b[0] += 1e-9 * out[0]

    @numba.njit
    def factors(J, A, piv, reps):
        for _ in range(reps):
            A[:, :] = J
            st.lu_factor(A, piv)

    def best(f, reps, *args):
        f(*args, 10)
        times = []
        for _ in range(7):
            t0 = time.perf_counter()
            f(*args, reps)
            times.append(time.perf_counter() - t0)
        return min(times) / reps * 1e9

    print(f"air chain of {n_tubes} tubes: Jacobian {n} x {n}, {np.count_nonzero(J)} nonzeros")
    for name, size in (("full loops", n), ("profile", 3 * n)):
        A, piv = J.copy(), np.zeros(size, dtype=np.int64)
        st.lu_factor(A, piv)
        f = best(factors, 20000, J, J.copy(), np.zeros(size, dtype=np.int64))
        s = best(solves, 100000, A, piv, np.ones(n), np.zeros(n))
        print(f"  {name:10s}  factor {f:7.0f} ns   solve {s:7.0f} ns")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, nargs="+", default=[128, 1000])
    ap.add_argument("--rtol", type=float, default=None, help="adaptive at this rtol "
                    "(default: fixed 1 ms steps)")
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)    # (N, mode): a child
    ap.add_argument("--profile", action="store_true",
                    help="the dense LU with and without its factors' profile")
    args = ap.parse_args(argv)
    if args.profile:
        profile_lu()
        return
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
