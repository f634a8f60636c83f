"""Core solver benchmark (foundation issue): prints timings and ratios.

    python benchmarks/bench_core.py            # all cases, N up to 100 000
    python benchmarks/bench_core.py --max-n 10000 --repeat 3
    python benchmarks/bench_core.py --parts a     # the paper scene only

(a) the FONS paper example scene; (b) the chain
PressureSource -> (CircularTube -> Container) x N with air, 1 ms steps, 0.2 s;
(c) a small scene (~10 components). If fonsim is installed
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
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import splu

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import softflow as sf  # noqa: E402
from softflow.demo import paper_system  # noqa: E402
from scenes import chain  # noqa: E402

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

    def side_by_side(step):
        """Medians of softflow and fonsim runs taken in turn (machine noise hits
        both alike), and the median of the per-pair ratios."""
        t_sf, t_fo, ratios, out = [], [], [], None
        for _ in range(repeat):
            a, out_sf = timed(lambda: run_sf(step), 1)
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
    st = sim.result.stats
    print(f"  softflow fixed 1 ms : {t_sf * 1e3:8.1f} ms  ({st['steps']} steps, "
          f"{st['steps'] / t_sf:,.0f} steps/s, {st['newton_iterations']} Newton it., "
          f"{st['factorizations']} LU)")
    print(f"  softflow adaptive   : {t_ad * 1e3:8.1f} ms  ({sim_ad.result.stats['steps']} steps)")
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
        print(f"  speed-up, softflow adaptive vs fonsim fixed 1 ms: {t_fo / t_ad:6.1f} x; "
              f"max deviation {dev_ad * 100:.3f} %")
        print(f"  speed-up, both at their adaptive defaults       : {t_fd / t_ad:6.1f} x "
              f"(median of run pairs {r_ad:.1f} x)")


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


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--max-n", type=int, default=100_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-fonsim", action="store_true")
    ap.add_argument("--parts", default="abc", help="which cases to run, e.g. 'a' or 'bc'")
    args = ap.parse_args(argv)
    fonsim = have_fonsim() and not args.no_fonsim
    print(f"softflow {sf.__version__}; fonsim {'found' if fonsim else 'not installed'}; "
          f"medians of {args.repeat} runs (1 run for N > 10 000)")
    if "a" in args.parts:
        bench_paper(args.repeat, fonsim)
    if "b" in args.parts:
        bench_chain([n for n in (8, 128, 1000, 10_000, 100_000) if n <= args.max_n], args.repeat,
                    fonsim)
    if "c" in args.parts:
        bench_small(args.repeat)


if __name__ == "__main__":
    main()
