"""The speed-accuracy trade on one representative scene.

Scene: a pressure source steps by 0.3 bar (gauge) at t = 10 ms and fills two
air actuators through tubes (both 2 mm ID; 0.5 m to actuator 1, 0.3 m from
actuator 1 on to actuator 2), over 1 s:

    source --tube 1--> actuator 1 (balloon: peak, valley) --tube 2--> actuator 2 (monotonic)

The flow in the tubes is turbulent during the step (Re up to 1.1e4 in the low
case, 2.4e6 in the high one), so the friction correlation matters, and
actuator 1 snaps through its peak. Two
pressure cases with the same curves' shapes: ``low`` (a soft robot: from the
atmosphere to +0.3 bar) and ``high`` (pre-charged to 12 MPa, stepping to
18 MPa, pressures scaled x200, where air is a real gas).

Every configuration is fluid level (ideal / table / eos) x thermal model
(isothermal / adiabatic) x friction (laminar only / Haaland / Colebrook) x
time stepping (every model over the adaptive rtol sweep; fixed steps for
FIXED_STEP_MODELS and the finest models). Its error is the largest deviation of either actuator's
volume from the reference over the run, relative to that volume's range in the
reference (the run's values interpolated linearly onto the reference's times,
as a user would read them). The reference is the finest models at adaptive
rtol 1e-8; rtol 1e-6 and 1e-7 are run too, to show that it has converged.

Wall time: Simulation set-up and run (scene building excluded), median of 3
repeats (1 for runs over REPEAT_BELOW = 0.3 s).

    python benchmarks/bench_speed_accuracy.py            # both cases, ~2.2 min on 2 cores
    python benchmarks/bench_speed_accuracy.py --quick    # fewer points, low case, ~25 s
    python benchmarks/bench_speed_accuracy.py --case high --plot out.png

Prints markdown tables and writes the Pareto plot (wall time vs error) to
``benchmarks/speed_accuracy.png``.
"""
from __future__ import annotations

import argparse
import itertools
import statistics
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import softflow as sf
from softflow.curves.waveforms import Step

ML = 1e-6                  # m^3 per mL
DURATION = 1.0             # s
STEP_TIME = 0.01           # s
#: Model axes; thermal models that this softflow's Simulation rejects are dropped
#: (with a note) at run time, so adding one is adding it here.
FLUID_LEVELS = ("ideal", "table", "eos")
THERMAL_MODELS = ("isothermal", "adiabatic")
FRICTIONS = ("laminar", "Haaland", "Colebrook")
RTOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
FIXED_STEPS = (1e-2, 3e-3, 1e-3, 3e-4, 1e-4)
#: models swept in fixed steps besides the finest: the library's defaults, and
#: the same with the adiabatic model
FIXED_STEP_MODELS = (("ideal", "isothermal", "Haaland"), ("ideal", "adiabatic", "Haaland"))
REFERENCE_RTOLS = (1e-6, 1e-7, 1e-8)
REFERENCE_STEP_MAX = 1e-3  # s: keeps the reference's output dense
REPEAT_BELOW = 0.3        # s: runs longer than this are timed once
TOLERANCE = 0.01           # "good enough": 1 % of the volume range


@dataclass(frozen=True)
class Case:
    name: str
    base: float            # Pa absolute: pre-charge and source pressure before the step
    scale: float           # gauge pressures of the curves and the step, x this
    title: str


CASES = {
    "low": Case("low", sf.pressure_atmospheric, 1.0, "soft robot: 1 atm -> +0.3 bar"),
    "high": Case("high", 12e6, 200.0, "high pressure: 12 MPa -> 18 MPa"),
}


@dataclass(frozen=True)
class Config:
    fluid: str
    thermal: str
    friction: str
    stepping: str          # 'adaptive' or 'fixed'
    value: float           # rtol or step [s]

    @property
    def models(self):
        return (self.fluid, self.thermal, self.friction)

    def label(self):
        how = f"rtol {self.value:.0e}" if self.stepping == "adaptive" else f"dt {self.value:.0e}"
        return f"{self.fluid}/{self.thermal[:5]}/{self.friction}/{how}"


def fluid_at(level):
    return sf.air if level == "ideal" else sf.air.with_level(level)


def scene(case, fluid, friction):
    """The representative scene (see module doc). Actuators are added first, so
    that their initial pressures are the Newton start at their nodes."""
    kpa = 1e3 * case.scale

    def points(*vp):
        return [(v * ML, case.base + p * kpa) for v, p in vp]

    s = sf.System()
    s += sf.Actuator("act1", fluid, sf.PVCurve.peak_valley(*points((5, 0), (15, 25), (30, 18),
                                                                   (60, 40))))
    s += sf.Actuator("act2", fluid, sf.PVCurve.monotonic(*points((5, 0), (15, 20), (60, 40))))
    s += sf.PressureSource("source", Step(STEP_TIME, case.base, case.base + 30 * kpa))
    s += sf.CircularTube("tube1", fluid, length=0.5, diameter=2e-3, friction=friction)
    s += sf.CircularTube("tube2", fluid, length=0.3, diameter=2e-3, friction=friction)
    s.connect(("source", "a"), ("tube1", "a"))
    s.connect(("tube1", "b"), ("act1", "a"))
    s.connect(("act1", "a"), ("tube2", "a"))
    s.connect(("tube2", "b"), ("act2", "a"))
    return s


def simulate(case, cfg, step_max=None):
    """One run: (wall time [s], Result)."""
    system = scene(case, fluid_at(cfg.fluid), cfg.friction)
    kw = dict(duration=DURATION, thermal=cfg.thermal)
    if cfg.stepping == "adaptive":
        kw.update(rtol=cfg.value)
        if step_max is not None:
            kw.update(step_max=step_max)
    else:
        kw.update(step=cfg.value)
    t0 = time.perf_counter()
    result = sf.Simulation(system, **kw).run()
    return time.perf_counter() - t0, result


def timed(case, cfg, repeats, step_max=None):
    """Median wall time over ``repeats`` runs (one when the first takes over
    REPEAT_BELOW), the trajectory (t, V1, V2) and the run's counters."""
    wall, res = simulate(case, cfg, step_max)
    walls = [wall]
    while len(walls) < repeats and wall < REPEAT_BELOW:
        walls.append(simulate(case, cfg, step_max)[0])
    traj = (res.times, res.get("act1", "volume"), res.get("act2", "volume"))
    return statistics.median(walls), traj, res.stats


def error(traj, ref):
    """Largest deviation of either actuator volume from the reference, relative
    to its range in the reference."""
    t_ref = ref[0]
    worst = 0.0
    for k in (1, 2):
        v = np.interp(t_ref, traj[0], traj[k])
        span = np.ptp(ref[k])
        worst = max(worst, float(np.max(np.abs(v - ref[k]))) / span)
    return worst


def available_thermal_models(case):
    """The entries of THERMAL_MODELS that run on this softflow (a 20 ms smoke run)."""
    ok = []
    for model in THERMAL_MODELS:
        try:
            sf.Simulation(scene(case, sf.air, "Haaland"), duration=0.02, step=1e-3,
                          thermal=model).run()
            ok.append(model)
        except Exception as err:       # an unknown or unfinished model: drop it, say why
            print(f"note: thermal={model!r} left out: {type(err).__name__}: {err}")
    return ok


# -- the sweep ----------------------------------------------------------------------------
def reference(case, thermal_models, rtols, repeats):
    """Finest models at decreasing rtol; the last is the reference. Returns
    (reference trajectory, rows of the convergence table)."""
    finest = (FLUID_LEVELS[-1], thermal_models[-1], FRICTIONS[-1])
    runs = []
    for rtol in rtols:
        cfg = Config(*finest, "adaptive", rtol)
        wall, traj, stats = timed(case, cfg, 1 if rtol < 1e-6 else repeats, REFERENCE_STEP_MAX)
        runs.append((cfg, wall, traj, stats))
    ref = runs[-1][2]
    rows = [(cfg.label(), wall, stats.get("steps", len(traj[0]) - 1), error(traj, ref))
            for cfg, wall, traj, stats in runs]
    return ref, rows


def sweep(case, thermal_models, rtols, steps, repeats, ref):
    """Every model combination over the rtol sweep; the fixed-step sweep for
    FIXED_STEP_MODELS and the finest models. Returns [(Config, wall, error, steps)]."""
    out = []
    models = list(itertools.product(FLUID_LEVELS, thermal_models, FRICTIONS))
    for fluid, thermal, friction in models:
        for rtol in rtols:
            out.append(Config(fluid, thermal, friction, "adaptive", rtol))
    fixed_models = [m for m in FIXED_STEP_MODELS if m[1] in thermal_models]
    fixed_models.append(models[-1])
    for fluid, thermal, friction in dict.fromkeys(fixed_models):
        for dt in steps:
            out.append(Config(fluid, thermal, friction, "fixed", dt))
    rows, tight = [], {}
    for cfg in out:
        try:
            wall, traj, stats = timed(case, cfg, repeats)
        except sf.SimulationError as err:
            print(f"  {cfg.label()}: failed ({err})")
            continue
        rows.append((cfg, wall, error(traj, ref), stats.get("steps", len(traj[0]) - 1)))
        if cfg.stepping == "adaptive" and cfg.value == min(rtols):
            tight[cfg.models] = traj
    return rows, tight


def model_effects(tight, thermal_models):
    """What each single model switch changes, at the sweep's tightest rtol:
    [(switch, held fixed, difference)]."""
    fl, th, fr = FLUID_LEVELS[-1], thermal_models[-1], FRICTIONS[-1]
    pairs = [(f"fluid {a} -> {fl}", f"{th}, {fr}", (a, th, fr), (fl, th, fr))
             for a in FLUID_LEVELS[:-1]]
    pairs += [(f"thermal {a} -> {th}", f"{fl}, {fr}", (fl, a, fr), (fl, th, fr))
              for a in thermal_models[:-1]]
    pairs += [(f"friction {a} -> {fr}", f"{fl}, {th}", (fl, th, a), (fl, th, fr))
              for a in FRICTIONS[:-1]]
    return [(name, held, error(tight[a], tight[b])) for name, held, a, b in pairs
            if a in tight and b in tight]


def pareto(rows):
    """Rows on the front: no other row is both faster and more accurate."""
    front, best = [], np.inf
    for r in sorted(rows, key=lambda r: (r[1], r[2])):
        if r[2] < best:
            front.append(r)
            best = r[2]
    return front


# -- reporting ----------------------------------------------------------------------------
def pct(e):
    return f"{100 * e:.3g} %"


def report(case, conv, rows, tight_runs, thermal_models):
    print(f"\n### Case `{case.name}` ({case.title})\n")
    print("Reference convergence (finest models, adaptive, step_max 1 ms):\n")
    print("| run | wall | steps | error vs reference |")
    print("|---|---|---|---|")
    for label, wall, steps, err in conv:
        print(f"| {label} | {wall:.2f} s | {steps} | {pct(err) if err else 'reference'} |")

    tight = min(r[0].value for r in rows if r[0].stepping == "adaptive")
    print(f"\nModel levels at the tightest rtol of the sweep, {tight:.0e} (time-stepping "
          "error about that of the same rtol above): the rest is the model's\n")
    print("| fluid | thermal | friction | wall ms | error |")
    print("|---|---|---|---|---|")
    for cfg, wall, err, _ in rows:
        if cfg.stepping == "adaptive" and cfg.value == tight:
            print(f"| {cfg.fluid} | {cfg.thermal} | {cfg.friction} | {1e3 * wall:.0f} | "
                  f"{pct(err)} |")

    print("\nEach model switch alone (difference between the two runs at that rtol):\n")
    print("| switch | held at | volume difference |")
    print("|---|---|---|")
    for name, held, diff in model_effects(tight_runs, thermal_models):
        print(f"| {name} | {held} | {pct(diff)} |")

    fixed = [r for r in rows if r[0].stepping == "fixed"]
    fixed_models = list(dict.fromkeys(r[0].models for r in fixed))
    print("\nFixed steps (backward Euler, first order): error, wall ms\n")
    print("| dt | " + " | ".join("/".join(m) for m in fixed_models) + " |")
    print("|---" * (len(fixed_models) + 1) + "|")
    for dt in dict.fromkeys(r[0].value for r in fixed):
        cells = [next((f"{pct(r[2])}, {1e3 * r[1]:.0f}" for r in fixed
                       if r[0].models == m and r[0].value == dt), "") for m in fixed_models]
        print(f"| {dt:.0e} s | " + " | ".join(cells) + " |")

    front = pareto(rows)
    print("\nPareto front (wall time vs error):\n")
    print("| configuration | wall ms | steps | error |")
    print("|---|---|---|---|")
    for cfg, wall, err, steps in front:
        print(f"| {cfg.label()} | {1e3 * wall:.1f} | {steps} | {pct(err)} |")

    cheap, accurate = headline(rows, thermal_models)
    default = next((r for r in rows if r[0].models == accurate[0].models
                    and r[0].stepping == "adaptive" and r[0].value == 1e-3), None)
    print()
    if cheap is None:
        print(f"No configuration is within {pct(TOLERANCE)} of the reference.")
        return
    runners_up = sorted((r for r in rows if r[2] <= TOLERANCE), key=lambda r: r[1])[1:3]
    print(f"- Cheapest within {pct(TOLERANCE)}: **{cheap[0].label()}**, {1e3 * cheap[1]:.1f} ms, "
          f"error {pct(cheap[2])} (next: "
          + "; ".join(f"{r[0].label()} {1e3 * r[1]:.1f} ms, {pct(r[2])}" for r in runners_up)
          + ").")
    print(f"- Most accurate level (finest models at the sweep's tightest rtol): "
          f"{accurate[0].label()}, {1e3 * accurate[1]:.1f} ms, error {pct(accurate[2])}: "
          f"speed-up **{accurate[1] / cheap[1]:.1f}x**.")
    plain = next((r for r in rows if r[0].models == FIXED_STEP_MODELS[0]
                  and r[0].stepping == "adaptive" and r[0].value == 1e-3), None)
    if plain is not None:
        print(f"- softflow's defaults ({plain[0].label()}): {1e3 * plain[1]:.1f} ms, error "
              f"{pct(plain[2])}.")
    if default is not None:
        print(f"- Finest models at the default rtol 1e-3: {1e3 * default[1]:.1f} ms, error "
              f"{pct(default[2])}: speed-up {default[1] / cheap[1]:.1f}x.")


def headline(rows, thermal_models):
    """(cheapest row within TOLERANCE or None, the most accurate level's row): the
    finest models at the tightest rtol of the sweep."""
    good = [r for r in rows if r[2] <= TOLERANCE]
    cheap = min(good, key=lambda r: r[1]) if good else None
    finest = (FLUID_LEVELS[-1], thermal_models[-1], FRICTIONS[-1])
    tight = min(r[0].value for r in rows if r[0].stepping == "adaptive")
    accurate = next(r for r in rows if r[0].models == finest and r[0].stepping == "adaptive"
                    and r[0].value == tight)
    return cheap, accurate


def plot(results, path, thermal_models):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    colors = {"ideal": "tab:blue", "table": "tab:orange", "eos": "tab:red"}
    markers = {"laminar": "s", "Haaland": "o", "Colebrook": "^"}
    fig, axes = plt.subplots(1, len(results), figsize=(7.5 * len(results), 6.2), squeeze=False)
    for ax, (case, rows) in zip(axes[0], results):
        for cfg, wall, err, _ in rows:
            filled = cfg.thermal != "isothermal"
            ax.scatter(1e3 * wall, max(err, 1e-7), s=22 if cfg.stepping == "adaptive" else 34,
                       marker=markers[cfg.friction], edgecolors=colors[cfg.fluid],
                       facecolors=colors[cfg.fluid] if filled else "none",
                       linewidths=1.0, alpha=0.75)
        front = pareto(rows)
        ax.step([1e3 * r[1] for r in front], [max(r[2], 1e-7) for r in front], where="post",
                color="k", lw=1.2, label="Pareto front")
        for i, (cfg, wall, err, _) in enumerate(front):
            # alternate above/below: neighbours on the front are close in both axes
            ax.annotate(cfg.label(), (1e3 * wall, max(err, 1e-7)), fontsize=6,
                        xytext=(5, 4 if i % 2 else -9), textcoords="offset points")
        cheap, accurate = headline(rows, thermal_models[case.name])
        for row, text, mark in ((cheap, "cheapest within 1 %", "*"),
                                (accurate, "most accurate level", "D")):
            if row is not None:
                ax.scatter(1e3 * row[1], max(row[2], 1e-7), s=260 if mark == "*" else 110,
                           marker=mark, facecolors="none", edgecolors="k", linewidths=0.9,
                           label=text)
        ax.axhline(TOLERANCE, color="gray", ls="--", lw=0.8, label="1 % of the volume range")
        ax.set(xscale="log", yscale="log", xlabel="wall time [ms]",
               ylabel="max volume error / volume range", title=f"{case.name}: {case.title}")
        ax.grid(True, which="both", alpha=0.25)
        handles = [plt.Line2D([], [], ls="", marker="o", color=c, label=f"fluid {k}")
                   for k, c in colors.items()]
        handles += [plt.Line2D([], [], ls="", marker=m, color="gray", mfc="none",
                               label=f"friction {k}") for k, m in markers.items()]
        handles += [plt.Line2D([], [], ls="", marker="o", color="gray", mfc="none",
                               label="isothermal (open)"),
                    plt.Line2D([], [], ls="", marker="o", color="gray", label="adiabatic (filled)")]
        handles += ax.get_legend_handles_labels()[0]
        ax.legend(handles=handles, fontsize=7, loc="lower left")
    fig.suptitle("Two air actuators behind tubes, pressure step, 1 s: wall time vs error "
                 "(small markers: adaptive rtol; large: fixed dt)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=130)
    print(f"\nPareto plot written to {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help="low case, 3 rtols, 3 fixed steps, 1 repeat, reference rtol 1e-7")
    parser.add_argument("--case", choices=("low", "high", "both"), default=None)
    parser.add_argument("--plot", default=str(Path(__file__).with_name("speed_accuracy.png")))
    args = parser.parse_args(argv)
    which = args.case or ("low" if args.quick else "both")
    names = ("low", "high") if which == "both" else (which,)
    rtols = (1e-2, 1e-3, 1e-4, 1e-5) if args.quick else RTOLS
    steps = (1e-2, 1e-3, 1e-4) if args.quick else FIXED_STEPS
    ref_rtols = (1e-6, 1e-7) if args.quick else REFERENCE_RTOLS
    repeats = 1 if args.quick else 3

    t_start = time.perf_counter()
    for level in FLUID_LEVELS:          # load tables and CoolProp states before timing
        fluid_at(level).density(np.array([2e5, 1e7]))
    results, thermal = [], {}
    for name in names:
        case = CASES[name]
        thermal[name] = available_thermal_models(case)
        ref, conv = reference(case, thermal[name], ref_rtols, repeats)
        rows, tight_runs = sweep(case, thermal[name], rtols, steps, repeats, ref)
        report(case, conv, rows, tight_runs, thermal[name])
        results.append((case, rows))
    if args.plot:
        plot(results, args.plot, thermal)
    print(f"\nTotal benchmark time {time.perf_counter() - t_start:.0f} s")


if __name__ == "__main__":
    main()
