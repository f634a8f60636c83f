"""sf.assess against an exhaustive search (issue 15's targets).

Six scenes spanning README's "Choosing a model level" table. For each:
an exhaustive search over the axes assess decides (thermal: isothermal or the
scene's thermal model, adiabatic or heat transfer where the volumes have walls;
fluid level ideal or table; the laminar tubes' friction as given or Haaland;
gas tubes' law as given or compressible='isothermal'; rtol 1e-2, 1e-3, 1e-4)
finds the cheapest configuration within the tolerance (1 %) of a converged
fine reference (every axis at its finest, table fluids, rtol 1e-7); then
sf.assess's recommendation, its error against the reference, its cost against
the cheapest adequate one (target <= 1.5x), and assess's own cost against one
run of the cheapest adequate configuration (target <= 3x). Error: largest
difference of each output over the run's own time points, relative to the
output's range in the reference. Costs: CPU time (time.process_time) of
building and running a Simulation, best of --repeats.

    python benchmarks/bench_assess.py [--repeats 3] [--scene NAME ...]
"""
from __future__ import annotations

import argparse
import itertools
import time
import warnings

import softflow as sf
from softflow.assess import Config, difference, variant_system, _gas_volumes, _has_wall

P = sf.pressure_atmospheric
TOLERANCE = 0.01
RTOLS = (1e-2, 1e-3, 1e-4)
REFERENCE_RTOL = 1e-7


def syringe():
    """Slow syringe fill (0.5 mL/s for 10 s) of an air actuator through a thin
    tube; the actuator's wall hA = 0.5 W/K."""
    s = sf.System()
    pump = sf.waveforms.PiecewiseConstant(sf.Q_([0, 10], "s"), sf.Q_([0.5, 0], "mL/s"))
    s += sf.VolumeFlowSource("pump", volumeflow=pump, fluid=sf.air)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    curve = sf.PVCurve.monotonic((5e-6, P), (8e-6, P + 0.2e5), (20e-6, P + 0.4e5))
    s += sf.Actuator("act", sf.air, curve, initial_pressure=P, hA=0.5)
    s.connect("pump", "tube")
    s.connect("tube", "act")
    return s, 12.0, [("act", "volume")]


def fast_fill():
    """A 1 L tank filled from 4 bar through an ISO 6358 valve in ~0.5 s (no wall)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(4, "bar"))
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    return s, 1.0, [("tank", "pressure")]


def bottle():
    """A 1 L air bottle (wall hA 0.5 W/K) filled from 12 to 18 MPa through 2 m of 1 mm tube."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=18e6)
    s += sf.CircularTube("tube", sf.air, length=2.0, diameter=1e-3)
    s += sf.Container("bottle", sf.air, volume=1e-3, initial_pressure=12e6, hA=0.5)
    s.connect("supply", "tube")
    s.connect("tube", "bottle")
    return s, 20.0, [("bottle", "pressure")]


def laminar_water():
    """Water at 2 bar into an accumulator through 1 m of 2 mm tube given
    friction='laminar' (Re reaches ~25 000)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(2, "bar"))
    s += sf.CircularTube("tube", sf.water, length=1.0, diameter=2e-3, friction="laminar")
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-5, compliance=1e-11)
    s.connect("supply", "tube")
    s.connect("tube", "acc")
    return s, 0.5, [("tube", "massflow", "a"), ("acc", "pressure")]


def turbulent_air():
    """Air at 1.5 bar fills a 50 mL container (wall hA 0.05 W/K) through 0.5 m
    of 2 mm tube given friction='laminar' (Re reaches ~10 000)."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(1.5, "bar"))
    s += sf.CircularTube("tube", sf.air, length=0.5, diameter=2e-3, friction="laminar")
    s += sf.Container("tank", sf.air, volume=50e-6, hA=0.05)
    s.connect("supply", "tube")
    s.connect("tube", "tank")
    return s, 2.0, [("tank", "pressure")]


def near_choking():
    """Air at 2.2 bar into a 1 L container (wall hA 0.3 W/K) through 1 m of 2 mm
    tube: Mach ~0.7 at the tube's low-pressure end at first, short of the
    isothermal choking limit (0.845), which would stop the run."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(2.2, "bar"))
    s += sf.CircularTube("tube", sf.air, length=1.0, diameter=2e-3)
    s += sf.Container("tank", sf.air, volume=1e-3, hA=0.3)
    s.connect("supply", "tube")
    s.connect("tube", "tank")
    return s, 10.0, [("tank", "pressure")]


SCENES = {f.__name__: f for f in (syringe, fast_fill, bottle, laminar_water, turbulent_air,
                                  near_choking)}


def axes(system):
    """The levels of each axis for this scene: (thermal, fluid, override sets)."""
    volumes = _gas_volumes(system)
    thermal = ["isothermal"]
    if volumes:
        thermal.append("heat_transfer" if all(_has_wall(c) for c in volumes) else "adiabatic")
    gases = any(getattr(c, "fluid", None) is not None and c.fluid.compressible
                for c in system.components)
    fluid = ["ideal", "table"] if gases else ["ideal"]
    laminar = [c.label for c in system.components if getattr(c, "friction", None) == "laminar"]
    tubes = [c.label for c in system.components if type(c).__name__ == "CircularTube"
             and c.fluid.compressible]
    friction = [{}] + ([{lab: {"friction": "Haaland"} for lab in laminar}] if laminar else [])
    law = [{}] + ([{lab: {"compressible": "isothermal"} for lab in tubes}] if tubes else [])
    overrides = []
    for f, g in itertools.product(friction, law):
        merged = {}
        for part in (f, g):
            for lab, args in part.items():
                merged.setdefault(lab, {}).update(args)
        overrides.append(merged)
    return thermal, fluid, overrides


def simulate(system, duration, config):
    t0 = time.process_time()
    sim = sf.Simulation(variant_system(system, config.fluid_level, config.overrides_dict()),
                        duration, thermal=config.thermal, rtol=config.rtol)
    result = sim.run(raise_on_failure=False, progress=False)
    return result, time.process_time() - t0


def best_cost(system, duration, config, repeats):
    costs, result = [], None
    for _ in range(repeats):
        result, cpu = simulate(system, duration, config)
        costs.append(cpu)
    return result, min(costs)


def bench(name, repeats):
    system, duration, outputs = SCENES[name]()
    thermal, fluid, overrides = axes(system)
    finest = Config(thermal[-1], fluid[-1], REFERENCE_RTOL).with_overrides(overrides[-1])
    reference, _ = simulate(system, duration, finest)
    assert reference.status == "success", reference.message
    rows = []
    for th, fl, ov, rtol in itertools.product(thermal, fluid, overrides, RTOLS):
        cfg = Config(th, fl, rtol).with_overrides(ov)
        result, cpu = best_cost(system, duration, cfg, repeats)
        err = (difference(result, reference, outputs) if result.status == "success"
               else float("inf"))
        rows.append((cfg, err, cpu))
    adequate = [r for r in rows if r[1] <= TOLERANCE]
    cheapest = min(adequate, key=lambda r: r[2]) if adequate else None
    costs = []
    for _ in range(repeats):
        a = sf.assess(system, duration, tolerance=TOLERANCE, outputs=outputs)
        costs.append(a.cost)
    rec, rec_cpu = best_cost(system, duration, a.config, repeats)
    rec_err = difference(rec, reference, outputs)
    return dict(scene=name, cheapest=cheapest, recommended=a.config, rec_err=rec_err,
                rec_cpu=rec_cpu, assess_cpu=min(costs), n_configs=len(rows), assessment=a)


def short(cfg):
    parts = [cfg.thermal.replace("heat_transfer", "heat tr."), cfg.fluid_level,
             f"rtol {cfg.rtol:.0e}"]
    ov = cfg.overrides_dict()
    if any(args.get("friction") for args in ov.values()):
        parts.append("Haaland")
    if any(args.get("compressible") for args in ov.values()):
        parts.append("isoth. tube")
    return ", ".join(parts)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scene", nargs="*", choices=list(SCENES), default=list(SCENES))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", sf.ModelWarning)
    sf.assess(*SCENES["fast_fill"]()[:2])          # imports and table loading out of the way
    simulate(*bottle()[:2], Config("isothermal", "table", 1e-3))
    print(f"tolerance {TOLERANCE:.0%}; CPU ms, best of {args.repeats}\n")
    print("| scene | configs | cheapest adequate | ms | recommended | error | ms | "
          "cost / cheapest | assess ms | assess / cheapest |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    met = {"within": 0, "cost": 0, "assess": 0}
    for name in args.scene:
        r = bench(name, args.repeats)
        c = r["cheapest"]
        if c is None:
            print(f"| {name} | {r['n_configs']} | none within {TOLERANCE:.0%} | | "
                  f"{short(r['recommended'])} | {r['rec_err']:.2%} | | | | |")
            continue
        ratio = r["rec_cpu"] / c[2]
        assess_ratio = r["assess_cpu"] / c[2]
        met["within"] += r["rec_err"] <= TOLERANCE
        met["cost"] += ratio <= 1.5
        met["assess"] += assess_ratio <= 3
        print(f"| {name} | {r['n_configs']} | {short(c[0])} ({c[1]:.2%}) | {1e3 * c[2]:.1f} | "
              f"{short(r['recommended'])} | {r['rec_err']:.2%} | {1e3 * r['rec_cpu']:.1f} | "
              f"{ratio:.2f}x | {1e3 * r['assess_cpu']:.1f} | {assess_ratio:.2f}x |")
    n = len(args.scene)
    print(f"\nrecommended within {TOLERANCE:.0%} of the reference: {met['within']}/{n}; "
          f"cost <= 1.5x the cheapest adequate: {met['cost']}/{n}; assess <= 3x one run of "
          f"the cheapest adequate: {met['assess']}/{n}")


if __name__ == "__main__":
    main()
