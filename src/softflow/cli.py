"""Command line: ``softflow demo`` runs the FONS paper example and writes a plot."""
from __future__ import annotations

import argparse
import sys
import time


def _demo(args):
    import softflow as sf
    from softflow.demo import paper_system, plot

    system = paper_system()
    sim = sf.Simulation(system, duration=1.0)
    t0 = time.perf_counter()
    result = sim.run()
    elapsed = time.perf_counter() - t0
    p = result.get("actu", "pressure")
    print(f"softflow {sf.__version__}: FONS paper example (water, latex balloon actuator)")
    print(f"  solved {result.stats['steps']} steps in {elapsed * 1e3:.1f} ms "
          f"({result.stats['newton_iterations']} Newton iterations, "
          f"{result.stats['factorizations']} factorizations)")
    print(f"  peak actuator gauge pressure {(p.max() - sf.pressure_atmospheric) / 1e2:.1f} mbar")
    if not args.no_plot:
        plot(result, args.output)
        print(f"  plot written to {args.output}")
    return 0


def main(argv=None):
    parser = argparse.ArgumentParser(prog="softflow", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the FONS paper example and plot it")
    demo.add_argument("--output", default="softflow_demo.png", help="PNG file to write")
    demo.add_argument("--no-plot", action="store_true", help="skip the plot")
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _demo(args)
    return 1


if __name__ == "__main__":
    sys.exit(main())
