"""Dense LAPACK LU vs SuperLU on chains of growing size: where is the crossover?

    python benchmarks/bench_linear_solver.py

Prints the median run time of the same scene with each solver and their ratio;
softflow's 'auto' picks dense up to linear.DENSE_MAX unknowns.
"""
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import softflow as sf  # noqa: E402
from scenes import chain  # noqa: E402


def run(N, kind, repeat=5):
    ts = []
    for _ in range(repeat):
        sim = sf.Simulation(chain(N), duration=0.1, step=1e-3, linear_solver=kind)
        t0 = time.perf_counter()
        sim.run()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), sim.asm.n


def main():
    print(f"{'N':>5} {'unknowns':>9} {'dense ms':>9} {'sparse ms':>10} {'sparse/dense':>13}")
    for N in (2, 5, 10, 15, 25, 40, 60, 100):
        td, n = run(N, "dense")
        ts, _ = run(N, "sparse")
        print(f"{N:>5} {n:>9} {td * 1e3:>9.1f} {ts * 1e3:>10.1f} {ts / td:>13.2f}")


if __name__ == "__main__":
    main()
