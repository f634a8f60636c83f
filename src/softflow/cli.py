"""Command line: ``softflow demo`` runs the FONS paper example and writes a plot;
``softflow figures`` runs the paper's Figs. 3-5 and writes their panels C and D."""
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


def _figures(args):
    from pathlib import Path

    from softflow import paper_scenes

    out = Path(args.output_dir)
    out.mkdir(parents=True, exist_ok=True)
    for fig in args.fig:
        paper_scenes.run_figure(fig, prefix=str(out / f"fig{fig}"))
    return 0


def main(argv=None):
    from softflow import __version__

    parser = argparse.ArgumentParser(prog="softflow", description=__doc__)
    parser.add_argument("--version", action="version", version=f"softflow {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the FONS paper example and plot it")
    demo.add_argument("--output", default="softflow_demo.png", help="PNG file to write")
    demo.add_argument("--no-plot", action="store_true", help="skip the plot")
    figs = sub.add_parser("figures", help="run the FONS paper's Figs. 3-5 and plot panels C, D")
    figs.add_argument("--fig", type=int, nargs="+", choices=(3, 4, 5), default=[3, 4, 5],
                      help="which figures (default: all three)")
    figs.add_argument("--output-dir", default=".", help="folder for fig<N>_C.png, fig<N>_D.png")
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _demo(args)
    if args.command == "figures":
        return _figures(args)
    return 1


if __name__ == "__main__":
    sys.exit(main())
