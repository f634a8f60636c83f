"""Dense output (issue 40): values between the steps, and what recording them costs.

(a) Accuracy, against references independent of softflow: an exponential fill
(water from a pressure source through a laminar tube into a linear
accumulator: p = p1 + (p0 - p1) exp(-t / tau), closed form) and a blowdown
(1 L of isothermal air at 10 bar through a 2 mm, Cd 0.6 orifice to the
atmosphere, for 6 s: choked, then not; the isentropic nozzle's mass flow
written out here, integrated by scipy's DOP853 at rtol 1e-13). For each rtol,
with ``refine=1`` (the steps alone): the largest error at the steps, the
largest between them read with ``Result.at`` (8 times inside every step), the
worst ratio of an interval's error between its steps to the larger error at
its two ends (issue 40's target: at most 1.5), and reading linearly
(``np.interp``) between the steps and between the points ``refine='auto'``
records (with their number). Errors in units of the pressure's range.

(b) Overhead: CPU time of ``Simulation(...).run()`` (build included) with
  * ``none``: no dense output at all (its recording patched out, the result
    the steps alone: what softflow did before issue 40),
  * ``dense``: the steps' difference tables recorded (``refine=1``), and
  * ``auto``: the default (``refine='auto'``: the points inside the steps as
    well),
interleaved run by run, medians of ``--repeat``; and the memory of the dense
record (its differences) against the result's own arrays (X, S, integrals).
Scenes: the nine paper scenes (summed), the fill and the blowdown at rtol
1e-3 and 1e-6, and an air chain of N tubes and tanks (adaptive, 0.05 s).

    python benchmarks/bench_dense_output.py                 # ~1-2 min
    python benchmarks/bench_dense_output.py --repeat 9 --chain 2000
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
from softflow.solve import bdf as bdf_mod
from softflow.solve import dense as dense_mod
from softflow.solve.integrator import Integrator

sys.path.insert(0, str(Path(__file__).resolve().parent))
TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(TESTS), str(TESTS / "solve")]
from scenes import chain  # noqa: E402
import test_dense_output as dense_tests  # noqa: E402



# -- scenes and their references: the tests' (tests/solve/test_dense_output.py) -------------
def fill():
    """(system, reference p(t), variable, duration): the exponential fill."""
    return (*dense_tests.fill(), ("acc", "pressure"), 0.3)


def blowdown():
    """(system, reference p(t), variable, duration): the isothermal blowdown."""
    return (*dense_tests.blowdown(), ("tank", "pressure"), 6.0)


# -- (a) accuracy ---------------------------------------------------------------------------
def accuracy(rtols=(1e-3, 1e-4, 1e-5, 1e-6)):
    print("(a) accuracy against independent references; errors / pressure range")
    print(f"  {'scene':9} {'rtol':>6} {'steps':>5} {'at steps':>9} {'between':>9} "
          f"{'worst':>6} {'linear':>9} {'auto pts':>8} {'linear':>9}")
    print(f"  {'':9} {'':>6} {'':>5} {'':>9} {'(at)':>9} {'ratio':>6} {'(steps)':>9} "
          f"{'':>8} {'(auto)':>9}")
    for name, scene in (("fill", fill), ("blowdown", blowdown)):
        system, ref, var, duration = scene()
        for rtol in rtols:
            res = sf.Simulation(system, duration=duration, rtol=rtol, refine=1).run()
            auto = sf.Simulation(system, duration=duration, rtol=rtol).run()
            t, y = res.times, res.get(*var)
            scale = np.ptp(y)
            at_steps = np.abs(y - ref(t)) / scale
            m = 9
            inside = (t[:-1, None] + np.diff(t)[:, None] * (np.arange(1, m) / m)).ravel()
            between = (np.abs(res.at(inside, *var) - ref(inside)) / scale).reshape(-1, m - 1)
            between = between.max(axis=1)
            ends = np.maximum(at_steps[:-1], at_steps[1:])
            ratio = float(np.max(between / np.maximum(ends, 1e-300)))
            lin = np.abs(np.interp(inside, t, y) - ref(inside)).max() / scale
            lin_auto = np.abs(np.interp(inside, auto.times, auto.get(*var))
                              - ref(inside)).max() / scale
            print(f"  {name:9} {rtol:6.0e} {res.stats['steps']:5d} {at_steps.max():9.2e} "
                  f"{between.max():9.2e} {ratio:6.2f} {lin:9.2e} {len(auto.times):8d} "
                  f"{lin_auto:9.2e}")


# -- (b) overhead ---------------------------------------------------------------------------
class NoDense:
    """The dense record patched out (what softflow did before issue 40)."""

    def __enter__(self):
        self.saved = (dense_mod.DenseRecorder.step, bdf_mod.BDF.finish)
        dense_mod.DenseRecorder.step = lambda self, t, h, k, row, D: None
        bdf_mod.BDF.finish = Integrator.finish
        return self

    def __exit__(self, *exc):
        dense_mod.DenseRecorder.step, bdf_mod.BDF.finish = self.saved


def cpu(build, duration, **kw):
    """(CPU seconds of Simulation(...).run(), the result)."""
    system = build()
    c0 = time.process_time()
    res = sf.Simulation(system, duration=duration, beyond_limits="warn", **kw).run()
    return time.process_time() - c0, res


def overhead(repeat, n_chain):
    print(f"\n(b) overhead: CPU s of Simulation + run, medians of {repeat} (interleaved); "
          "memory of the dense record")
    cases = []
    paper = [(lambda c=c: ps.fig3(c), ps.duration(3)) for c in ps.FIG3_CASES]
    paper += [(lambda c=c: ps.fig4(c), ps.duration(4)) for c in ps.FIG4_CASES]
    paper += [(lambda f=f: ps.fig5(f), ps.duration(5))
              for f in (sf.air, sf.water, sf.ethylene_glycol)]
    cases.append(("9 paper scenes", paper, {}))
    for name, scene in (("fill", fill), ("blowdown", blowdown)):
        system, _, _, duration = scene()
        for rtol in (1e-3, 1e-6):
            cases.append((f"{name} rtol {rtol:.0e}", [(lambda s=system: s, duration)],
                          {"rtol": rtol}))
    if n_chain:
        cases.append((f"air chain N={n_chain}", [(lambda: chain(n_chain), 0.05)], {}))
        cases.append((f"  record= 3 of them", [(lambda: chain(n_chain), 0.05)],
                      {"record": ["source", "cont0", f"cont{n_chain - 1}"]}))
    print(f"  {'scene':22} {'steps':>6} {'none':>8} {'dense':>8} {'auto':>8} "
          f"{'dense':>7} {'auto':>7} {'points':>11} {'result MB':>9} {'dense MB':>8}")
    for name, runs, kw in cases:
        for build, duration in runs:          # warm: imports, tables, compile caches
            cpu(build, duration, **kw)
        times = {"none": [], "dense": [], "auto": []}
        for _ in range(repeat):
            for how in times:
                total = 0.0
                for build, duration in runs:
                    if how == "none":
                        with NoDense():
                            dt, _ = cpu(build, duration, refine=1, **kw)
                    else:
                        dt, _ = cpu(build, duration, refine=1 if how == "dense" else "auto",
                                    **kw)
                    total += dt
                times[how].append(total)
        steps = points = steps_pts = 0
        mb_result = mb_dense = 0.0
        for build, duration in runs:
            _, res = cpu(build, duration, **kw)
            steps += res.stats["steps"]
            points += len(res.times)
            steps_pts += res.stats["steps"] + 1
            mb_result += (res.X.nbytes + res.S.nbytes
                          + (0 if res._Q is None else res._Q.nbytes)) / 1e6
            mb_dense += res._dense.nbytes / 1e6
        med = {k: statistics.median(v) for k, v in times.items()}
        print(f"  {name:22} {steps:6d} {med['none']:8.3f} {med['dense']:8.3f} "
              f"{med['auto']:8.3f} {100 * (med['dense'] / med['none'] - 1):+6.1f}% "
              f"{100 * (med['auto'] / med['none'] - 1):+6.1f}% "
              f"{steps_pts:5d}->{points:<5d} {mb_result:9.2f} {mb_dense:8.2f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--chain", type=int, default=1000, help="N of the air chain (0: none)")
    ap.add_argument("--skip-accuracy", action="store_true")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    if not args.skip_accuracy:
        accuracy()
    overhead(args.repeat, args.chain)


if __name__ == "__main__":
    main()
