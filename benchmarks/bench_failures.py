"""How fast a failed run fails (issue 41: "a failure comes within 50 residual
evaluations, and <= 2 s CPU, after the last accepted step").

    python benchmarks/bench_failures.py            # medians of 3
    python benchmarks/bench_failures.py --repeat 7

Runs every case of the bad-input catalogue (tests/test_bad_input_catalogue.py)
that ends in a SimulationError and prints, per case: the CPU time of the whole
run (building the Simulation included; median of --repeat, with the range),
the residual evaluations of the run, those made after its last accepted point
(``result.stats["residual_evaluations"] - result.stats["residuals_at_last_
step"]``: after the last step, or after the consistent start where the first
step fails; a run whose start fails counts all its work), the
steps taken, and the time the run stopped at. The suite checks the counts
(never the times): tests/test_bad_input_catalogue.py, AFTER_LAST_STEP.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import softflow as sf                                   # noqa: E402
from test_bad_input_catalogue import CASES, AFTER_LAST_STEP     # noqa: E402


def one(case, tmp):
    """(CPU seconds, the SimulationError) of one run of ``case``."""
    t0 = time.process_time()
    try:
        case[1](tmp)
    except sf.SimulationError as err:
        return time.process_time() - t0, err
    raise RuntimeError(f"{case[0]}: no SimulationError")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    runs = [c for c in CASES if c[2] is sf.SimulationError]
    print(f"failed runs of the bad-input catalogue ({len(runs)} cases); CPU ms: median of "
          f"{args.repeat} [min-max], this process (the first run of each case warm: "
          "one run before timing)")
    print(f"{'case':58s} {'cpu ms':>22s} {'res.':>6s} {'after':>6s} {'steps':>6s}  stopped at")
    worst_after, worst_cpu = 0, 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for case in runs:
            one(case, Path(tmp))                    # warm (compile, tables)
            times, err = [], None
            for _ in range(args.repeat):
                cpu, err = one(case, Path(tmp))
                times.append(cpu * 1e3)
            st = err.result.stats
            after = st["residual_evaluations"] - st["residuals_at_last_step"]
            worst_after = max(worst_after, after)
            worst_cpu = max(worst_cpu, statistics.median(times))
            cpu = f"{statistics.median(times):.1f} [{min(times):.1f}-{max(times):.1f}]"
            print(f"{case[0][:58]:58s} {cpu:>22s} {st['residual_evaluations']:6d} "
                  f"{after:6d} {st['steps']:6d}  {err.time:.6g} s")
    print(f"failures: at most {worst_after} residual evaluations after the last accepted point "
          f"(target {AFTER_LAST_STEP}); slowest failed run {worst_cpu:.1f} ms CPU "
          "(target 2 000 ms)")


if __name__ == "__main__":
    main()
