"""Core solver benchmark (foundation issue): prints timings and ratios.

    python benchmarks/bench_core.py            # all cases, N up to 100 000
    python benchmarks/bench_core.py --max-n 10000 --repeat 3
    python benchmarks/bench_core.py --parts a     # the paper scene only
    python benchmarks/bench_core.py --parts d --repeat 5   # compiled step loop on / off

(a) the FONS paper example scene; (b) the chain
PressureSource -> (CircularTube -> Container) x N with air, 1 ms steps, 0.2 s;
(c) a small scene (~10 components), (b) and (c) also with the compiled step loop
on and off where the installed softflow has the fixed-step loop (FixedSteps);
(d) the adaptive BDF on air chains with the
compiled step loop (softflow.solve.steploop, issue 38) on and off
(settings.COMPILED_STEPS), run by run in turns: CPU of run(), us per accepted
step, the loop's share of the steps and the CPU inside it, at rtol 1e-3 and
1e-8, and the marginal cost of a step between them (the difference of the run
times over the difference of the steps: a run's fixed costs cancel). These
runs record one point per step (refine=1: the steps' cost, not the dense
output's); the default refine='auto' is timed beside them (loop on), with the
points it records. The paper example's adaptive run in (a) is also timed with
the loop off. If fonsim is installed
(pip install fonsim==0.6.0) the paper scene and chains with N <= 128 also run
on it in the same process, and the speed ratio and the largest difference in
results are printed. Medians over --repeat runs.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import splu

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import softflow as sf  # noqa: E402
from softflow.demo import paper_system  # noqa: E402
from scenes import chain  # noqa: E402
from accuracy_reference import air_chain  # noqa: E402
from bench_paper_scenes import LoopSpy, compiled_loop, print_serves  # noqa: E402

CSV = HERE.parent / "examples" / "latex_balloon_60mm_pv.csv"


def have_fonsim():
    try:
        import fonsim_scenes  # noqa: F401
        import importlib.util
        return importlib.util.find_spec("fonsim") is not None
    except ImportError:
        return False


def timed(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def splu_floor(sim, repeat=3):
    """Median seconds of one splu(COLAMD) factor + solve of the scene's Jacobian."""
    asm = sim.asm
    res = sim.result
    asm.residual(res.X[-1], res.S[-2] if len(res.S) > 1 else res.S[-1], res.times[-1],
                 1e-3, jac=True)
    A = asm.jacobian_csc()
    b = np.ones(asm.n)
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        splu(A, permc_spec="COLAMD").solve(b)
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def peak_memory_mb(build, duration):
    """Peak traced memory (MB) of building and running a scene for ``duration``."""
    tracemalloc.start()
    sim = sf.Simulation(build(), duration=duration, step=1e-3)
    sim.run()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak / 1e6


def fons_listing(csv, step=1e-3):
    """The paper's listing as a fonsim script runs it under softflow.fons
    (``import softflow.fons as fons``): fonsim's constants, fons's
    components, the listing's Actuator in fonsim's labelled form."""
    import softflow.fons as fons
    p0 = fons.pressure_atmospheric

    class Actuator(fons.Component):
        def __init__(self, label, fluid, pvcurve):
            super().__init__(label)
            p_ = fons.Variable("pressure", "across", label="p", initial_value=p0)
            mf_ = fons.Variable("massflow", "through", label="mf")
            m_ = fons.Variable("mass", "local", label="mass", initial_value=1e-3)
            self.set_terminals(fons.Terminal("a", [p_, mf_]))
            self.set_states(m_)

            def evaluate(t, p, mass):
                return [p - pvcurve.fdf_volume(volume=mass / fluid.rho)[0]]
            self.evaluate = self.auto(evaluate)

            def update_state(dt, mass, mf):
                return {"mass": mass + mf * dt}
            self.update_state = self.auto_state(update_state)

    system = fons.System()
    system += fons.PressureSource("source", pressure=lambda t: p0 + (.3e5 if t < .5 else 0))
    system += fons.CircularTube(label="tube", fluid=fons.water, length=0.60, diameter=1e-3)
    system += Actuator("actu", fluid=fons.water, pvcurve=fons.pvcurve.PVCurve(str(csv)))
    system.connect("tube", "source")
    system.connect("tube", "actu")
    sim = fons.Simulation(system, duration=1.0, step=step)
    sim.run()
    return sim


def bench_paper(repeat, fonsim):
    print("\n(a) FONS paper example scene: 1 s, water, balloon actuator (user component)")
    # softflow with fonsim's constants (p_atm 101300 Pa, water 999 kg/m3, 9.77e-4 Pa s),
    # both at a fixed 1 ms step, so that the comparison isolates the solvers. Each
    # run builds the whole listing, reading the PV file included (fonsim_scenes does)
    water_f = sf.ConstantLiquid("water (fonsim constants)", density=999.0, viscosity=9.77e-4)

    def run_sf(step=1e-3):
        # the listing's model (no tube inertance), as fonsim runs it
        system = paper_system(fluid=water_f, p0=101300.0, pvcurve=sf.PVCurve(CSV),
                              inertance=False)
        sim = sf.Simulation(system, duration=1.0, step=step)
        sim.run()
        return sim

    def run_fo(step=1e-3):
        import fonsim_scenes
        return fonsim_scenes.run_paper_example(str(CSV), 1.0, step)

    def side_by_side(step, ours=None):
        """Medians of softflow and fonsim runs taken in turn (machine noise hits
        both alike), and the median of the per-pair ratios."""
        ours = ours or run_sf
        t_sf, t_fo, ratios, out = [], [], [], None
        for _ in range(repeat):
            a, out_sf = timed(lambda: ours(step), 1)
            b, out_fo = timed(lambda: run_fo(step), 1) if fonsim else (None, None)
            t_sf.append(a)
            if fonsim:
                t_fo.append(b)
                ratios.append(b / a)
            out = (out_sf, out_fo)
        med = statistics.median
        return (med(t_sf), med(t_fo) if fonsim else None,
                med(ratios) if fonsim else None, *out)

    t_sf, t_fo, r_fixed, sim, ref = side_by_side(1e-3)
    t_ad, t_fd, r_ad, sim_ad, ref_ad = side_by_side(None)
    # the same listing as a fonsim script under softflow.fons, in turns with fonsim
    t_fons, t_fo2, r_fons, _, _ = side_by_side(1e-3, lambda step: fons_listing(CSV, step))
    # the adaptive run with the compiled step loop on and off, in turns (CPU)
    cpu_on, cpu_off = [], []
    for i in range(repeat):
        for on in ((True, False) if i % 2 == 0 else (False, True)):
            with compiled_loop(on):
                c0 = time.process_time()
                run_sf(None)
                (cpu_on if on else cpu_off).append(time.process_time() - c0)
    # the user component and the Python signal compiled (the default,
    # settings.COMPILED_USER_CODE, issue 38 item 4), called back from the
    # compiled loop (COMPILED_USER_CODE off), or every step in Python
    # (COMPILED_USER off), in turns (CPU of run() alone, the Simulation built
    # once per setting)
    callbacks = None
    modes = {"compiled": (True, True), "called back": (True, False),
             "Python steps": (False, False)}
    try:
        from softflow.solve import settings as _settings
        if hasattr(_settings, "COMPILED_USER_CODE"):
            callbacks = {}
            for i in range(repeat):
                order = list(modes) if i % 2 == 0 else list(modes)[::-1]
                for mode in order:
                    _settings.COMPILED_USER, _settings.COMPILED_USER_CODE = modes[mode]
                    for step in (1e-3, None):
                        sim_cb = run_sf(step)
                        c0 = time.process_time()
                        sim_cb.run()
                        callbacks.setdefault((mode, step), []).append(time.process_time() - c0)
            _settings.COMPILED_USER = _settings.COMPILED_USER_CODE = True
    except ImportError:
        pass
    with LoopSpy() as spy:
        n_ad = run_sf(None).result.stats["steps"]
    st = sim.result.stats
    print(f"  softflow fixed 1 ms : {t_sf * 1e3:8.1f} ms  ({st['steps']} steps, "
          f"{st['steps'] / t_sf:,.0f} steps/s, {st['newton_iterations']} Newton it., "
          f"{st['factorizations']} LU)")
    print(f"  softflow adaptive   : {t_ad * 1e3:8.1f} ms  ({sim_ad.result.stats['steps']} steps)")
    m_on, m_off = statistics.median(cpu_on), statistics.median(cpu_off)
    print(f"  softflow adaptive, CPU, compiled step loop on / off (in turns): "
          f"{m_on * 1e3:.1f} / {m_off * 1e3:.1f} ms ({m_on / m_off:.2f}); the loop took "
          f"{spy.share(n_ad)} of the steps ({spy.exits_text()})")
    if callbacks:
        med = statistics.median
        for step, name in ((1e-3, "fixed 1 ms"), (None, "adaptive")):
            got = {mode: med(callbacks[(mode, step)]) for mode in modes}
            print(f"  run() CPU, {name}: user component compiled {got['compiled'] * 1e3:.2f} ms"
                  f" / called back from the compiled loop (COMPILED_USER_CODE off) "
                  f"{got['called back'] * 1e3:.2f} ms / every step in Python (COMPILED_USER "
                  f"off) {got['Python steps'] * 1e3:.2f} ms")
    if fonsim:
        p_sf = sim.result.get("actu", "pressure")
        n = min(len(p_sf), len(ref["p_actu"]))
        gauge = ref["p_actu"][:n].max() - 101300.0
        dev = np.max(np.abs(p_sf[:n] - ref["p_actu"][:n])) / gauge
        # fonsim's listing actuator lags its pressure one step behind its volume
        # (FD Jacobian without the mass dependence): compare with softflow one step back too
        dev_lag = np.max(np.abs(p_sf[:n - 1] - ref["p_actu"][1:n])) / gauge
        p_ad = np.interp(ref["times"][:n], sim_ad.result.times, sim_ad.result.get("actu", "pressure"))
        dev_ad = np.max(np.abs(p_ad - ref["p_actu"][:n])) / gauge
        print(f"  fonsim 0.6 fixed 1 ms: {t_fo * 1e3:8.1f} ms")
        print(f"  fonsim 0.6 adaptive  : {t_fd * 1e3:8.1f} ms  ({ref_ad['steps']} steps, its default)")
        print(f"  speed-up, both fixed 1 ms          : {t_fo / t_sf:6.1f} x (median of run pairs "
              f"{r_fixed:.1f} x); max |p_softflow - p_fonsim| / gauge peak {dev * 100:.3f} % "
              f"(fonsim shifted one step: {dev_lag * 100:.3f} %)")
        print(f"  softflow.fons listing (fonsim's script, import changed), fixed 1 ms: "
              f"{t_fons * 1e3:.1f} ms against fonsim's {t_fo2 * 1e3:.1f} ms in turns: "
              f"{t_fo2 / t_fons:.1f} x (median of run pairs {r_fons:.1f} x)")
        print(f"  speed-up, softflow adaptive vs fonsim fixed 1 ms: {t_fo / t_ad:6.1f} x; "
              f"max deviation {dev_ad * 100:.3f} %")
        print(f"  speed-up, both at their adaptive defaults       : {t_fd / t_ad:6.1f} x "
              f"(median of run pairs {r_ad:.1f} x)")


def loop_on_off(run, repeat):
    """'run() CPU with the compiled step loop on / off ...': ``run`` (a
    Simulation's, run again) timed with settings.COMPILED_STEPS on and off in
    turns, medians of ``repeat``, and the loop's share of the steps (spied)."""
    cpu = {True: [], False: []}
    for i in range(repeat):
        for on in ((True, False) if i % 2 == 0 else (False, True)):
            with compiled_loop(on):
                c0 = time.process_time()
                run()
                cpu[on].append(time.process_time() - c0)
    with LoopSpy() as spy:
        steps = run().stats["steps"]
    a, b = statistics.median(cpu[True]), statistics.median(cpu[False])
    return (f"run() CPU, compiled step loop on / off (in turns): {a * 1e3:.1f} / "
            f"{b * 1e3:.1f} ms ({a / b:.2f}); the loop took {spy.share(steps)} of the steps "
            f"({spy.exits_text()})")


def bench_chain(Ns, repeat, fonsim, duration=0.2):
    print(f"\n(b) chain PressureSource -> (CircularTube -> Container) x N, air, 1 ms, {duration} s")
    head = (f"  {'N':>7} {'unknowns':>9} {'build+compile':>13} {'run':>9} {'steps/s':>9} "
            f"{'Newton it':>9} {'LU':>4} {'t/iter':>9} {'splu f+s':>9} {'ratio':>6} {'peak MB':>8}")
    print(head)
    rows = []
    for N in Ns:
        rep = repeat if N <= 10_000 else 1
        t0 = time.perf_counter()
        sim = sf.Simulation(chain(N), duration=duration, step=1e-3)
        t_build = time.perf_counter() - t0
        t_run, _ = timed(sim.run, rep)
        if N >= 10_000:
            # the same run keeping only the ends of the chain (Simulation(record=...))
            sim_r = sf.Simulation(chain(N), duration=duration, step=1e-3,
                                  record=["source", "cont0", f"cont{N - 1}"])
            t_rec, _ = timed(sim_r.run, rep)
            print(f"  {N:>7} recording 3 components only: run {t_rec:.3f}s, "
                  f"{sim_r.result.stats['steps'] / t_rec:,.0f} steps/s")
        st = sim.result.stats
        t_it = t_run / st["newton_iterations"]
        floor = splu_floor(sim)
        mem = peak_memory_mb(lambda: chain(N), 0.02) if N <= 100_000 else float("nan")
        print(f"  {N:>7} {st['unknowns']:>9} {t_build:>12.2f}s {t_run:>8.3f}s "
              f"{st['steps'] / t_run:>9,.0f} {st['newton_iterations']:>9} "
              f"{st['factorizations']:>4} {t_it * 1e3:>7.3f}ms {floor * 1e3:>7.2f}ms "
              f"{t_it / floor:>6.2f} {mem:>8.1f}")
        rows.append((N, sim, t_run))
        if N <= 1000:
            print(f"  {'':>7} {loop_on_off(sim.run, rep)}")
    if fonsim:
        import fonsim_scenes
        print("  side by side with fonsim 0.6 (same scene, fixed 1 ms):")
        for N, sim, t_run in rows:
            if N > 128:
                continue
            t_fo, ref = timed(lambda: fonsim_scenes.run_chain(N, duration, 1e-3), 1)
            p_sf = sim.result.get(f"cont{N - 1}", "pressure")
            p0_sf = sim.result.get("cont0", "pressure")
            n = min(len(p_sf), len(ref["p_last"]))
            rise = 0.2e5
            dev = max(np.max(np.abs(p_sf[:n] - ref["p_last"][:n])),
                      np.max(np.abs(p0_sf[:n] - ref["p_first"][:n]))) / rise
            print(f"    N = {N:>4}: fonsim {t_fo:7.2f} s, softflow {t_run:7.4f} s, "
                  f"speed-up {t_fo / t_run:7.0f} x, max pressure difference "
                  f"{dev * 100:.2f} % of the 0.2 bar step")


def bench_small(repeat):
    print("\n(c) small scene: source + 4 x (tube, container), 9 components, air, 1 ms, 1 s")
    t, sim = timed(lambda: (lambda s: (s.run(), s)[1])(
        sf.Simulation(chain(4), duration=1.0, step=1e-3)), repeat)
    st = sim.result.stats
    print(f"  {t * 1e3:.1f} ms for {st['steps']} steps: {st['steps'] / t:,.0f} steps/s "
          f"({st['newton_iterations']} Newton it., {st['factorizations']} LU, "
          f"{st['linear_solver']} LU)")
    print(f"  {loop_on_off(sim.run, repeat)}")


def bench_adaptive(repeat, rtols=(1e-3, 1e-8), duration=0.2):
    """(d): the adaptive BDF with the compiled step loop on and off."""
    print(f"\n(d) adaptive BDF (default method), air chains, {duration} s: compiled step loop on "
          "/ off (settings.COMPILED_STEPS),\n    run by run in turns; CPU (process_time) of "
          f"run() alone, medians of {repeat} [min-max], refine=1; us/step = run / accepted "
          "steps;\n    loop: the compiled loop's share of the steps and its CPU per step taken "
          "(spy on CompiledSteps.run, one more run);\n    'auto': the same run (loop on) at the "
          "default refine='auto', CPU ms and the points it records")
    print_serves("    ")
    cases = [(f"chain N = {N}, Haaland, pipe-flow", lambda N=N: chain(N)) for N in (8, 31, 200)]
    cases.append(("air chain N = 8, laminar, mean-density (bench_accuracy's)",
                  lambda: air_chain(8)))
    print(f"  {'scene':57s} {'n':>4s} {'rtol':>5s} {'steps':>5s} {'Sim()':>6s} "
          f"{'run on ms':>17s} {'run off ms':>17s} {'on/off':>6s} {'us/step on':>10s} "
          f"{'off':>6s} {'loop share':>15s} {'us/loop step':>12s} {'auto ms (points)':>17s}")

    def cpu_run(build, rtol, on, builds=None, refine=1):
        with compiled_loop(on), warnings.catch_warnings():
            warnings.simplefilter("ignore")     # the air chain's first tube passes Mach 1
            c0 = time.process_time()
            sim = sf.Simulation(build(), duration=duration, rtol=rtol, beyond_limits="warn",
                                refine=refine)
            c1 = time.process_time()
            res = sim.run()
            c2 = time.process_time()
        if builds is not None:
            builds.append(c1 - c0)
        return c2 - c1, res

    for name, build in cases:
        cpu_run(build, rtols[-1], True)              # compile caches, CoolProp's import
        marg = []
        for rtol in rtols:
            on, off, builds, auto = [], [], [], []
            for i in range(repeat):
                for flag in ((True, False) if i % 2 == 0 else (False, True)):
                    c, res = cpu_run(build, rtol, flag, builds)
                    (on if flag else off).append(c)
                c, res_auto = cpu_run(build, rtol, True, refine="auto")
                auto.append(c)
            with LoopSpy() as spy:
                res = cpu_run(build, rtol, True)[1]
            n_off = cpu_run(build, rtol, False)[1].stats["steps"]
            n = res.stats["steps"]
            m_on, m_off = statistics.median(on), statistics.median(off)
            marg.append((n, n_off, m_on, m_off))
            steps = f"{n}" if n == n_off else f"{n}/{n_off}"
            loop = (f"{spy.cpu / spy.steps * 1e6:12.1f}" if spy.steps
                    else f"{'-':>12s}")
            print(f"  {name:57s} {res.stats['unknowns']:4d} {rtol:5.0e} {steps:>5s} "
                  f"{statistics.median(builds) * 1e3:5.1f}m "
                  f"{m_on * 1e3:6.1f} [{min(on) * 1e3:.1f}-{max(on) * 1e3:.1f}] "
                  f"{m_off * 1e3:6.1f} [{min(off) * 1e3:.1f}-{max(off) * 1e3:.1f}] "
                  f"{m_on / m_off:6.2f} {m_on / n * 1e6:10.1f} {m_off / n_off * 1e6:6.1f} "
                  f"{spy.share(n):>15s} {loop} {statistics.median(auto) * 1e3:8.1f} "
                  f"({len(res_auto.times):>6d})", flush=True)
        (n0, n0_off, a0, b0), (n1, n1_off, a1, b1) = marg[0], marg[-1]
        print(f"  {'':57s} marginal us/step, rtol {rtols[0]:.0e} -> {rtols[-1]:.0e}: on "
              f"{(a1 - a0) / max(n1 - n0, 1) * 1e6:.1f}, off "
              f"{(b1 - b0) / max(n1_off - n0_off, 1) * 1e6:.1f}; loop "
              f"{spy.exits_text()} (rtol {rtols[-1]:.0e})")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--max-n", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-fonsim", action="store_true")
    ap.add_argument("--parts", default="abcd", help="which cases to run, e.g. 'a' or 'bcd'")
    args = ap.parse_args(argv)
    fonsim = have_fonsim() and not args.no_fonsim
    # the scenes' model checks (the paper tube's left-out inertia, the chains' fast
    # isothermal fills) warn once per run: the same findings every repeat
    warnings.simplefilter("ignore", sf.ModelWarning)
    print(f"softflow {sf.__version__}; fonsim {'found' if fonsim else 'not installed'}; "
          f"medians of {args.repeat} runs (1 run for N > 10 000); ModelWarnings silenced")
    if "a" in args.parts:
        bench_paper(args.repeat, fonsim)
    if "b" in args.parts:
        bench_chain([n for n in (8, 128, 1000, 10_000, 100_000) if n <= args.max_n], args.repeat,
                    fonsim)
    if "c" in args.parts:
        bench_small(args.repeat)
    if "d" in args.parts:
        bench_adaptive(args.repeat)


if __name__ == "__main__":
    main()
