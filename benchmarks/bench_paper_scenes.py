"""The nine FONS paper scenes (Figs. 3-5, softflow.paper_scenes) at default settings:
time per scene against issue 12's target of 0.05 s, and where the steps go.

Each scene runs as ``paper_scenes.run`` runs it: ``Simulation(system, duration,
beyond_limits='warn').run()`` with the adaptive BDF at its defaults; the System is
built before the clock starts (the Simulation, i.e. compiling, is inside). Printed
per scene: wall (perf_counter) and CPU (process_time) medians of ``--repeat`` runs
with [min-max], accepted steps, rejected steps split by cause (error test, Newton,
mode switch being located), Newton iterations, factorizations, BDF restarts (t = 0,
breakpoints, mode switches), mode switches, accepted steps per order, and the CPU
time per accepted step. The counts come from one more, untimed run whose progress
reporter counts the solver's events.

``--compare OLD.py`` times a second BDF module (e.g. an older
``src/softflow/solve/bdf.py``, copied out of a ``git worktree``) against the
installed one, interleaved run by run (the machine's noise hits both alike), and
prints the ratio of the medians per scene. ``--profile SCENE`` prints a cProfile
of one scene (``fig3:hysteretic`` ...) instead.

    python benchmarks/bench_paper_scenes.py                 # ~10 s
    python benchmarks/bench_paper_scenes.py --repeat 9
    python benchmarks/bench_paper_scenes.py --compare /tmp/bdf_old.py
    python benchmarks/bench_paper_scenes.py --profile fig4:snapping
"""
from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time
import warnings

import softflow as sf
from softflow import paper_scenes as ps
from softflow.solve import progress as progress_mod
from softflow.solve import simulation as simulation_mod

TARGET = 0.05     # s, issue 12


def scenes():
    """[(name, fig, builder)]: the nine scenes, each builder making a fresh System."""
    out = []
    for case in ps.FIG3_CASES:
        out.append((f"fig3:{case}", 3, lambda c=case: ps.fig3(c)))
    for case in ps.FIG4_CASES:
        out.append((f"fig4:{case}", 4, lambda c=case: ps.fig4(c)))
    for name, fluid in zip(ps.FIG5_FLUIDS, (sf.air, sf.water, sf.ethylene_glycol)):
        out.append((f"fig5:{name}", 5, lambda f=fluid: ps.fig5(f)))
    return out


def load_bdf(path):
    """The BDF class of another bdf.py, loaded as a module of softflow.solve (its
    relative imports resolve there)."""
    spec = importlib.util.spec_from_file_location("softflow.solve._bdf_compare", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod.BDF


def timed(build, fig, bdf_class=None):
    """(wall s, cpu s, result) of Simulation(...) + run() on a fresh system."""
    system = build()
    saved = simulation_mod.BDF
    if bdf_class is not None:
        simulation_mod.BDF = bdf_class
    try:
        w0, c0 = time.perf_counter(), time.process_time()
        sim = sf.Simulation(system, duration=ps.duration(fig), beyond_limits="warn")
        res = sim.run()
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    finally:
        simulation_mod.BDF = saved
    assert res.success, res.message
    return wall, cpu, res


class Counts:
    """Counters patched into the progress reporter for one untimed run."""

    def __enter__(self):
        P = progress_mod.Progress
        self.saved = {n: getattr(P, n) for n in ("rejected", "restarted", "switched")}
        self.why = {"error": 0, "newton": 0, "switch": 0}
        self.restarts = self.switches = 0
        me = self

        def rejected(s, t, h, why, detail=None):
            me.why[why] = me.why.get(why, 0) + 1
            return me.saved["rejected"](s, t, h, why, detail)

        def restarted(s, t, h):
            me.restarts += 1

        def switched(s, t, before, after, discrete):
            me.switches += 1

        P.rejected, P.restarted, P.switched = rejected, restarted, switched
        return self

    def __exit__(self, *exc):
        for n, f in self.saved.items():
            setattr(progress_mod.Progress, n, f)


def spread(values, scale=1e3):
    """'median [min-max]' of values times scale."""
    return (f"{statistics.median(values) * scale:.1f} "
            f"[{min(values) * scale:.1f}-{max(values) * scale:.1f}]")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--compare", metavar="OLD_BDF_PY")
    ap.add_argument("--profile", metavar="SCENE")
    ap.add_argument("--scene", nargs="*", help="only these scenes (names as printed)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    todo = [s for s in scenes() if not args.scene or s[0] in args.scene]
    for _, fig, build in todo:          # imports, fluid tables, compile caches
        timed(build, fig)

    if args.profile:
        import cProfile
        import pstats
        (name, fig, build), = [s for s in scenes() if s[0] == args.profile]
        pr = cProfile.Profile()
        pr.enable()
        for _ in range(args.repeat):
            timed(build, fig)
        pr.disable()
        pstats.Stats(pr).sort_stats("tottime").print_stats(30)
        return

    old = load_bdf(args.compare) if args.compare else None
    print(f"nine paper scenes, default settings; medians of {args.repeat} [min-max]; "
          f"target {TARGET * 1e3:.0f} ms")
    print("rejected: error test / Newton / switch located; orders: accepted steps at 1..5")
    head = (f"{'scene':20s} {'wall ms':>19s} {'cpu ms':>19s} {'steps':>5s} {'rejected':>9s} "
            f"{'Newton':>6s} {'LU':>4s} {'rest.':>5s} {'sw.':>3s} {'orders':>19s} "
            f"{'us/step':>7s}")
    if old is not None:
        head += f" {'old cpu ms':>19s} {'new/old cpu':>17s}"
    print(head)
    met = 0
    for name, fig, build in todo:
        walls, cpus, ocpus = [], [], []
        for i in range(args.repeat):
            # taking turns, the order alternating: load from elsewhere hits both
            if old is not None and i % 2 == 0:
                ocpus.append(timed(build, fig, old)[1])
            w, c, res = timed(build, fig)
            walls.append(w)
            cpus.append(c)
            if old is not None and i % 2 == 1:
                ocpus.append(timed(build, fig, old)[1])
        with Counts() as n:
            _, _, res = timed(build, fig)
        st = res.stats
        rej = f"{n.why['error']}/{n.why['newton']}/{n.why['switch']}"
        orders = " ".join(str(k) for k in st["order_steps"][1:])
        per_step = statistics.median(cpus) / st["steps"] * 1e6
        met += statistics.median(walls) <= TARGET
        line = (f"{name:20s} {spread(walls):>19s} {spread(cpus):>19s} {st['steps']:5d} "
                f"{rej:>9s} {st['newton_iterations']:6d} {st['factorizations']:4d} "
                f"{n.restarts:5d} {n.switches:3d} {orders:>19s} {per_step:7.1f}")
        if old is not None:
            ratio = [a / b for a, b in zip(cpus, ocpus)]
            line += (f" {spread(ocpus):>19s} "
                     f"{statistics.median(cpus) / statistics.median(ocpus):5.3f} "
                     f"[{min(ratio):.2f}-{max(ratio):.2f}]")
        print(line, flush=True)
    print(f"within {TARGET * 1e3:.0f} ms (wall median): {met}/{len(todo)}")


if __name__ == "__main__":
    main()
