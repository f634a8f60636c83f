"""Forward sensitivities (issue 18): accuracy against central differences of
whole runs, and cost against the plain run.

    python benchmarks/bench_sensitivity.py [--repeat 5]

Scenes (smooth, no switches): (1) a laminar water tube charging a linear
accumulator (the RC circuit), parameters the tube's diameter and the
accumulator's compliance; (2) the air chain PressureSource -> (CircularTube
-> Container) x 8, parameters the first tube's diameter and the last
container's volume; (3) an adiabatic fill of an air tank through a tube,
parameters the tube's diameter and the tank's volume. Each at fixed 1 ms steps
(the sensitivities are those of the discrete solution: the reference is a
central difference of whole runs on the same steps, relative step 1e-4,
Newton held to 1e-12) and at BDF rtol 1e-6. Central differences of adaptive
runs are no reference (their step sequences differ, and interpolating one
onto the other's times divided by 2h is noise), so the BDF rows give the RC
circuit's error against its closed form (dp/dD, dp/dC of p = p1 - dp
exp(-t/RC)) and, for the others, the difference from the fixed-step
sensitivities at 0.1 ms (itself first-order accurate). Error: the largest
|sensitivity - reference| over the variables named, relative to the largest
|reference|. Cost: CPU time of a run with p parameters over the plain run's
(median over --repeat rounds of the run's time over the same round's plain
run, each round running the plain and the sensitivity runs in turn after one
untimed run of each; in brackets the range of those ratios); the last column
is p = 2 with the parameter derivatives taken by finite differences
(``softflow.solve.sensitivity.ANALYTIC = False``).
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import softflow as sf  # noqa: E402
import softflow.solve.sensitivity as sensitivity  # noqa: E402
from helpers import rc_circuit  # noqa: E402
from scenes import chain  # noqa: E402

P0 = sf.pressure_atmospheric


def tank_fill():
    s = sf.System()
    s += sf.PressureSource("source", pressure=P0 + 5e4)
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-4)
    s.connect("source", "tube")
    s.connect("tube", "tank")
    return s


SCENES = {
    "RC circuit (water)": (lambda: rc_circuit(), {}, 0.5,
                           {"tube.diameter": 0.5e-3, "acc.compliance": None},
                           [("acc", "pressure"), ("tube", "massflow_a")]),
    "air chain x 8": (lambda: chain(8), {}, 0.2, {"tube0.diameter": None, "cont7.volume": None},
                      [("cont7", "pressure"), ("cont3", "mass")]),
    "adiabatic tank fill": (tank_fill, {"thermal": "adiabatic"}, 0.3,
                            {"tube.diameter": None, "tank.volume": None},
                            [("tank", "pressure"), ("tank", "temperature")]),
}


def _value(sim, name):
    label, arg = name.rsplit(".", 1)
    return float(getattr(sim._compiled[label], arg))


def accuracy_fixed(build, kw, duration, params, outputs):
    """Against central differences of whole runs on the same 1 ms steps."""
    stepping = {"step": 1e-3, "newton_rtol": 1e-12}
    sim = sf.Simulation(build(), duration=duration, **kw, **stepping)
    res = sim.run(sensitivities=list(params))
    worst = 0.0
    for name in params:
        value = _value(sim, name)
        h = 1e-4 * value
        up, down = sim.run(params={name: value + h}), sim.run(params={name: value - h})
        for label, var in outputs:
            fd = (up.get(label, var) - down.get(label, var)) / (2 * h)
            s = res.sensitivity(label, var, name)
            worst = max(worst, float(np.max(np.abs(s - fd)) / np.max(np.abs(fd))))
    return worst


def accuracy_bdf(scene, build, kw, duration, params, outputs):
    sim = sf.Simulation(build(), duration=duration, rtol=1e-6, **kw)
    res = sim.run(sensitivities=list(params))
    worst = 0.0
    if scene.startswith("RC"):       # closed form (tests/helpers.rc_circuit's defaults)
        dp, tau, D, L = 1e4, 0.1, 0.5e-3, 1.0
        R = 128 * sf.water.mu * L / (math.pi * D ** 4)
        t = res.times
        dpdtau = -dp * np.exp(-t / tau) * t / tau ** 2
        for name, exact in (("tube.diameter", dpdtau * (-4 * tau / D)),
                            ("acc.compliance", dpdtau * R)):
            s = res.sensitivity("acc", "pressure", name)
            worst = max(worst, float(np.max(np.abs(s - exact)) / np.max(np.abs(exact))))
        return worst, "closed form"
    fine = sf.Simulation(build(), duration=duration, step=1e-4, **kw).run(
        sensitivities=list(params))
    for name in params:
        for label, var in outputs:
            ref = np.interp(res.times, fine.times, fine.sensitivity(label, var, name))
            s = res.sensitivity(label, var, name)
            worst = max(worst, float(np.max(np.abs(s - ref)) / np.max(np.abs(ref))))
    return worst, "fixed 0.1 ms"


def cost(build, kw, duration, params, stepping, repeat):
    """{p: (median ratio, lowest, highest)} for p = 1, 2 and 'fd' (p = 2, finite
    differences for the parameter derivatives), and the plain run's median [s]."""
    sim = sf.Simulation(build(), duration=duration, **kw, **stepping)
    kinds = (0, 1, 2, "fd")
    times = {p: [] for p in kinds}
    # one untimed run of each kind, then the kinds in turn in every round: the
    # plain run is timed warm and under the same load as the others
    for rnd in range(repeat + 1):
        for p in kinds:
            names = list(params)[:2 if p == "fd" else p]
            sensitivity.ANALYTIC = p != "fd"
            t0 = time.process_time()
            sim.run(sensitivities=names or None)
            if rnd:
                times[p].append(time.process_time() - t0)
    sensitivity.ANALYTIC = True
    out = {}
    for p in kinds[1:]:
        # each round's run over the same round's plain run: a load that drifts
        # over the rounds (other jobs on the machine) cancels out
        ratios = [t / t0 for t, t0 in zip(times[p], times[0])]
        out[p] = (statistics.median(ratios), min(ratios), max(ratios))
    return out, statistics.median(times[0])


def _ratio(r):
    return f"{r[0]:.2f}x ({r[1]:.2f}-{r[2]:.2f})"


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    warnings.simplefilter("ignore", sf.ModelWarning)
    print("| scene | stepping | error (reference) | plain run | cost, p = 1 | "
          "cost, p = 2 | target (1 + 0.5 p) | p = 2, FD parameter derivatives |")
    print("|---|---|---|---|---|---|---|---|")
    for scene, (build, kw, duration, params, outputs) in SCENES.items():
        err = accuracy_fixed(build, kw, duration, params, outputs)
        ratios, plain = cost(build, kw, duration, params, {"step": 1e-3}, args.repeat)
        print(f"| {scene} | fixed 1 ms | {err:.1e} (whole runs, same steps) | "
              f"{plain * 1e3:.1f} ms | {_ratio(ratios[1])} | {_ratio(ratios[2])} | "
              f"1.5x / 2.0x | {_ratio(ratios['fd'])} |")
        err, against = accuracy_bdf(scene, build, kw, duration, params, outputs)
        ratios, plain = cost(build, kw, duration, params, {"rtol": 1e-6}, args.repeat)
        print(f"| {scene} | BDF rtol 1e-6 | {err:.1e} ({against}) | {plain * 1e3:.1f} ms | "
              f"{_ratio(ratios[1])} | {_ratio(ratios[2])} | 1.5x / 2.0x | "
              f"{_ratio(ratios['fd'])} |")


if __name__ == "__main__":
    main()
