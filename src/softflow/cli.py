"""Command line: ``softflow demo`` runs the FONS paper example and writes a plot;
``softflow figures`` runs the paper's Figs. 3-5 and writes their panels C and D."""
from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path


class CLIError(Exception):
    """A mistake on the command line (a path, a format): reported in one line."""


def _check_output(name: str, option: str) -> None:
    """Fail before any work if matplotlib cannot write file ``name``: its folder must
    exist and its suffix be a format matplotlib writes."""
    path = Path(name)
    if path.is_dir():
        raise CLIError(f"{option} {str(path)!r} is a directory; give a file name, "
                       f"e.g. {str(path / 'softflow_demo.png')!r}")
    folder = path.parent
    if not folder.is_dir():
        raise CLIError(f"{option} {str(path)!r}: folder {str(folder)!r} does not exist")
    from matplotlib.backend_bases import FigureCanvasBase
    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = path.suffix.lower().lstrip(".")
    if suffix not in formats:
        known = ", ".join(f".{f}" for f in sorted(formats))
        raise CLIError(f"{option} {str(path)!r}: unknown image format "
                       f"{'.' + suffix if suffix else '(no suffix)'}; use one of {known}")


def _demo(args: argparse.Namespace) -> int:
    import softflow as sf
    from softflow.demo import paper_system, plot

    if not args.no_plot:
        _check_output(args.output, "--output")
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


def _figures(args: argparse.Namespace) -> int:
    from softflow import paper_scenes

    out = Path(args.output_dir)
    if out.exists() and not out.is_dir():
        raise CLIError(f"--output-dir {str(out)!r} is a file, not a folder")
    out.mkdir(parents=True, exist_ok=True)
    for fig in args.fig:
        paper_scenes.run_figure(fig, prefix=str(out / f"fig{fig}"))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 1 an error, reported in
    one line on stderr; argparse exits with 2 on a usage error)."""
    from softflow import __version__

    parser = argparse.ArgumentParser(prog="softflow", description=__doc__)
    parser.add_argument("--version", action="version", version=f"softflow {__version__}")
    parser.add_argument("--traceback", action="store_true",
                        help="on an error, show the full Python traceback")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the FONS paper example and plot it")
    demo.add_argument("--output", default="softflow_demo.png",
                      help="image file to write (.png, .pdf, .svg, ...)")
    demo.add_argument("--no-plot", action="store_true", help="skip the plot")
    figs = sub.add_parser("figures", help="run the FONS paper's Figs. 3-5 and plot panels C, D")
    figs.add_argument("--fig", type=int, nargs="+", choices=(3, 4, 5), default=[3, 4, 5],
                      help="which figures (default: all three)")
    figs.add_argument("--output-dir", default=".", help="folder for fig<N>_C.png, fig<N>_D.png")
    args = parser.parse_args(argv)
    command = {"demo": _demo, "figures": _figures}[args.command]
    try:
        return command(args)
    except KeyboardInterrupt:
        print(f"softflow {args.command}: interrupted", file=sys.stderr)
        return 130
    except Exception as err:     # noqa: BLE001 - every failure is reported in one line
        if args.traceback:
            raise
        message = " ".join(str(err).split()) or repr(err)
        if not isinstance(err, CLIError):
            message = f"{type(err).__name__}: {message} (softflow --traceback ... shows where)"
        print(f"softflow {args.command}: error: {message}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
