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

``--python-steps`` times each scene with the compiled step loop
(:mod:`softflow.solve.steploop`, issue 38) and with
``softflow.solve.settings.COMPILED_STEPS = False`` (every step the Python
BDF's), run by run in turns with the order alternating, and prints both CPU
medians with [min-max], the ratio of the medians (compiled / Python, with the
range of the per-pair ratios), the share of the accepted steps the compiled
loop took (a spy on ``CompiledSteps.run``, whose return's 5th element is the
steps it took, in one more untimed run), why it handed back to Python
(``softflow.laws.stepper.EXITS``, counted over its calls) or why it was not
bound to the run at all, and how many scenes meet issue 38's target of 5 ms
CPU a scene.

``--compare OLD.py`` times a second BDF module (e.g. an older
``src/softflow/solve/bdf.py``, copied out of a ``git worktree``) against the
installed one, interleaved run by run (the machine's noise hits both alike), and
prints the ratio of the medians per scene. ``--profile SCENE`` prints a cProfile
of one scene (``fig3:hysteretic`` ...) instead.

    python benchmarks/bench_paper_scenes.py                 # ~10 s
    python benchmarks/bench_paper_scenes.py --repeat 9
    python benchmarks/bench_paper_scenes.py --python-steps --repeat 5   # ~40 s
    python benchmarks/bench_paper_scenes.py --compare /tmp/bdf_old.py
    python benchmarks/bench_paper_scenes.py --profile fig4:snapping
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import importlib.util
import statistics
import sys
import textwrap
import time
import warnings

import softflow as sf
from softflow import paper_scenes as ps
from softflow.solve import progress as progress_mod
from softflow.solve import settings as settings_mod
from softflow.solve import simulation as simulation_mod
from softflow.solve import steploop

TARGET = 0.05     # s, issue 12
TARGET_38 = 5e-3  # s of CPU a scene at the default settings, warm: issue 38

#: which runs the compiled step loop serves (softflow.solve.steploop's docstring);
#: printed by the benchmarks that compare it with the Python steps
SERVES = ("The compiled step loop (softflow.solve.steploop, issue 38) serves the "
          "adaptive BDF{fixed}, where: every group is in the compiled network residual "
          "(softflow.solve.netcore: not user components, callable curves, table or eos "
          "fluids, the mean-density gas law in thermal scenes); the LU is dense (n <= 128 "
          "unknowns with linear_solver='auto') or, beyond, the Jacobian orders as a band "
          "at most settings.COMPILED_BAND_MAX wide (the loop's banded LU); no begin_step "
          "(heat-transfer correlations); sources constant or waveforms (no Python "
          "callables); no sensitivities or batched sub-networks. Inside a served run it "
          "hands back to Python for {hands}.")


def serves():
    """SERVES for the installed steploop (the fixed-step loop came later)."""
    if hasattr(steploop, "FixedSteps"):
        return SERVES.format(
            fixed=" and backward Euler at fixed steps (FixedSteps; adaptive backward "
                  "Euler never)",
            hands="a failed solve that Newton reports itself (not finite, a law's refusal, "
                  "singular, pressure <= 0) or that the culprit finder looks into (one in "
                  "a flow source's region), forced steps, mode "
                  "switches logged or chattering, emptied volumes, restarts whose probes fail")
    return SERVES.format(
        fixed=" only (fixed-step runs never)",
        hands="the step to each breakpoint and to the end, restarts, Newton's damped "
              "stages, forced steps, mode switches, emptied volumes")


def print_serves(indent=""):
    print(textwrap.fill(serves(), 100, initial_indent=indent, subsequent_indent=indent))


@contextlib.contextmanager
def compiled_loop(on):
    """``settings.COMPILED_STEPS = on`` inside (restored after)."""
    saved = settings_mod.COMPILED_STEPS
    settings_mod.COMPILED_STEPS = bool(on)
    try:
        yield
    finally:
        settings_mod.COMPILED_STEPS = saved


def why_not_served(integ):
    """Why ``steploop.compiled_steps`` (or ``fixed_steps``) gave no loop for this
    run (its tests, read back from the run's objects; 'not served' where they
    cannot be read)."""
    try:
        asm, newton = integ.asm, integ.newton
        if not settings_mod.COMPILED_STEPS:
            return "COMPILED_STEPS off"
        if getattr(asm.residual, "network", None) is None:
            return "residual not compiled"
        if newton is None:
            return "no Newton"
        if newton.lin.kind != "dense":
            return f"{newton.lin.kind} LU"
        if asm.has_regimes or asm.has_kinks:
            return "check valve"
        if asm.has_begin_step:
            return "begin_step"
        if getattr(integ, "sens", None) is not None:
            return "sensitivities"
        if getattr(integ, "_n_blocks", 1) > 1:
            return "sub-networks"
        if newton.offset is not None:
            return "continuation"
        if asm.residual.network.source_arrays() is None:
            return "callable source"
    except AttributeError:
        pass
    return "not served"


class LoopSpy:
    """Spies, for the runs made inside it, on the compiled step loops
    (``CompiledSteps`` for the adaptive BDF, ``FixedSteps`` for backward Euler at
    fixed steps where the installed steploop has it): the runs a loop was bound
    to (or why not), the calls of their ``run``, the accepted steps they took
    (its return's 5th element), the CPU spent in them (the compiled loop with
    the copies of the stepper's state in and out) and why each call handed back
    (``softflow.laws.stepper.EXITS``)."""

    def __enter__(self):
        from softflow.laws.stepper import EXITS
        self.runs = self.bound = self.calls = self.steps = 0
        self.cpu = 0.0
        self.exits, self.why_not = collections.Counter(), collections.Counter()
        self.sparse_state = None      # the sparse LU's state (laws.sparselu), where bound so
        me = self
        self._saved = []

        def bind_spy(original):
            def bind(integ):
                out = original(integ)
                me.runs += 1
                if out is None:
                    me.why_not[why_not_served(integ)] += 1
                else:
                    me.bound += 1
                return out
            return bind

        def run_spy(original):
            def run(s, *args, **kwargs):
                c0 = time.process_time()
                out = original(s, *args, **kwargs)
                me.cpu += time.process_time() - c0
                me.calls += 1
                me.steps += int(out[4])
                me.exits[EXITS[int(out[0])]] += 1
                if getattr(s, "sparse", None) is not None:
                    me.sparse_state = s.lin[16][11]
                return out
            return run

        for owner, name, spy in ((steploop, "compiled_steps", bind_spy),
                                 (steploop, "fixed_steps", bind_spy),
                                 (getattr(steploop, "CompiledSteps", None), "run", run_spy),
                                 (getattr(steploop, "FixedSteps", None), "run", run_spy)):
            if owner is not None and hasattr(owner, name):
                original = getattr(owner, name)
                self._saved.append((owner, name, original))
                setattr(owner, name, spy(original))
        return self

    def __exit__(self, *exc):
        for owner, name, original in reversed(self._saved):
            setattr(owner, name, original)

    def share(self, steps):
        """'taken/steps (pct %)' of ``steps`` accepted steps in all."""
        return f"{self.steps}/{steps} ({100.0 * self.steps / max(steps, 1):.0f} %)"

    def lu_text(self):
        """The loop's sparse LU's factorizations (with a new row order /
        refactorizations on the last), or '' where it had none."""
        st = self.sparse_state
        if st is None:
            return ""
        return f"sparse LU: {int(st[2])} new row orders, {int(st[3])} refactorizations"

    def exits_text(self):
        """Why the loop handed back ('done 3 newton 2'), or why it was not bound."""
        if not self.bound:
            return "not bound: " + ", ".join(self.why_not) if self.why_not else "no run"
        return " ".join(f"{k} {n}" for k, n in self.exits.most_common())


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


def timed(build, fig, bdf_class=None, compiled=None, builds=None):
    """(wall s, cpu s, result) of Simulation(...) + run() on a fresh system;
    ``compiled`` True/False sets settings.COMPILED_STEPS for it (None: as set);
    ``builds``, a list, gets the CPU of Simulation(...) alone appended."""
    system = build()
    saved = simulation_mod.BDF
    if bdf_class is not None:
        simulation_mod.BDF = bdf_class
    flag = compiled_loop(compiled) if compiled is not None else contextlib.nullcontext()
    try:
        with flag:
            w0, c0 = time.perf_counter(), time.process_time()
            sim = sf.Simulation(system, duration=ps.duration(fig), beyond_limits="warn")
            c1 = time.process_time()
            res = sim.run()
            cpu, wall = time.process_time() - c0, time.perf_counter() - w0
            if builds is not None:
                builds.append(c1 - c0)
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


def python_steps_table(todo, repeat):
    """``--python-steps``: the compiled loop against the Python steps, per scene."""
    print(f"nine paper scenes, default settings: compiled step loop (on) against "
          f"settings.COMPILED_STEPS = False (off),\nrun by run in turns; CPU (process_time) of "
          f"Simulation + run, medians of {repeat} [min-max]; issue 38's target "
          f"{TARGET_38 * 1e3:.0f} ms a scene")
    print_serves()
    print("on/off: ratio of the medians [range of the per-pair ratios]; Sim(): CPU of "
          "Simulation(...) alone (median, on);\nloop steps: accepted steps the compiled loop "
          "took, in loop: CPU inside CompiledSteps.run, calls and hand-backs: why\nthey "
          "returned (stepper.EXITS; spy in one more run, on); us/step: whole CPU (on, off) and "
          "in loop / loop steps")
    print(f"{'scene':20s} {'on: cpu ms':>19s} {'off: cpu ms':>19s} {'on/off':>17s} "
          f"{'Sim()':>5s} {'steps':>7s} {'loop steps':>14s} {'in loop':>7s} "
          f"{'us/step on':>10s} {'off':>6s} {'loop':>5s} {'calls':>5s}  hand-backs")
    met_on = met_off = 0
    ratios_all = []
    for name, fig, build in todo:
        on, off, builds = [], [], []
        for i in range(repeat):
            # taking turns, the order alternating: load from elsewhere hits both
            for flag in ((True, False) if i % 2 == 0 else (False, True)):
                (on if flag else off).append(
                    timed(build, fig, compiled=flag, builds=builds if flag else None)[1])
        with LoopSpy() as spy:
            res_on = timed(build, fig, compiled=True)[2]
        res_off = timed(build, fig, compiled=False)[2]
        n_on, n_off = res_on.stats["steps"], res_off.stats["steps"]
        steps = f"{n_on}" if n_on == n_off else f"{n_on}/{n_off}"
        m_on, m_off = statistics.median(on), statistics.median(off)
        pair = [a / b for a, b in zip(on, off)]
        ratios_all.append(m_on / m_off)
        met_on += m_on <= TARGET_38
        met_off += m_off <= TARGET_38
        print(f"{name:20s} {spread(on):>19s} {spread(off):>19s} "
              f"{m_on / m_off:5.3f} [{min(pair):.2f}-{max(pair):.2f}] "
              f"{statistics.median(builds) * 1e3:5.1f} {steps:>7s} "
              f"{spy.share(n_on):>14s} {spy.cpu * 1e3:7.1f} {m_on / n_on * 1e6:10.1f} "
              f"{m_off / n_off * 1e6:6.1f} {spy.cpu / max(spy.steps, 1) * 1e6:5.1f} "
              f"{spy.calls:5d}  {spy.exits_text()}", flush=True)
    print(f"within {TARGET_38 * 1e3:.0f} ms CPU (median): on {met_on}/{len(todo)}, off "
          f"{met_off}/{len(todo)}; on/off {min(ratios_all):.2f}-{max(ratios_all):.2f} "
          f"(geometric mean {statistics.geometric_mean(ratios_all):.2f})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--compare", metavar="OLD_BDF_PY")
    ap.add_argument("--profile", metavar="SCENE")
    ap.add_argument("--python-steps", action="store_true",
                    help="compiled step loop against COMPILED_STEPS = False, in turns")
    ap.add_argument("--scene", nargs="*", help="only these scenes (names as printed)")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    todo = [s for s in scenes() if not args.scene or s[0] in args.scene]
    for _, fig, build in todo:          # imports, fluid tables, compile caches
        timed(build, fig)
        if args.python_steps:
            timed(build, fig, compiled=False)

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

    if args.python_steps:
        python_steps_table(todo, args.repeat)
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
