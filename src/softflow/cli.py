"""Command line: ``softflow demo`` runs the FONS paper example and writes a plot;
``softflow figures`` runs the paper's Figs. 3-5 and writes their panels C and D;
``softflow run scene.toml --duration "2 s" --output run.csv`` runs a scene file."""
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
    from softflow.solve import settings

    if not args.no_plot:
        _check_output(args.output, "--output")
    system = paper_system()
    sim = sf.Simulation(system, duration=1.0)
    t0 = time.perf_counter()
    result = sim.run()
    elapsed = time.perf_counter() - t0
    first = None
    if elapsed > settings.DEMO_COMPILED_RUN:
        # the first run after installing compiled the step loop (cached now):
        # the run's own time is the next one's
        first = elapsed
        t0 = time.perf_counter()
        result = sim.run()
        elapsed = time.perf_counter() - t0
    p = result.get("actu", "pressure")
    print(f"softflow {sf.__version__}: FONS paper example (water, latex balloon actuator)")
    print(f"  solved {result.stats['steps']} steps in {elapsed * 1e3:.1f} ms "
          f"({result.stats['newton_iterations']} Newton iterations, "
          f"{result.stats['factorizations']} factorizations)")
    if first is not None:
        print(f"  (the first run took {first:.1f} s: it compiled softflow's step loop, once "
              "for this installation; later runs load it from numba's cache)")
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
        paper_scenes.run_figure(fig, prefix=str(out / f"fig{fig}"), physics=args.physics)
    return 0


#: --output suffixes of `softflow run` that are not images
_DATA_SUFFIXES = {".csv": "CSV (Result.to_csv)", ".nc": "netCDF (Result.to_xarray)"}


def _check_run_output(name: str) -> None:
    path = Path(name)
    if path.suffix.lower() in _DATA_SUFFIXES:
        if path.is_dir():
            raise CLIError(f"--output {str(path)!r} is a directory; give a file name")
        if not path.parent.is_dir():
            raise CLIError(f"--output {str(path)!r}: folder {str(path.parent)!r} does not exist")
        if path.suffix.lower() == ".nc":
            try:
                import xarray  # noqa: F401
            except ImportError:
                raise CLIError(f"--output {str(path)!r}: netCDF needs xarray "
                               "(pip install 'softflow[xarray]')") from None
        return
    try:
        _check_output(name, "--output")
    except CLIError as err:
        if "unknown image format" in str(err):
            raise CLIError(f"{err}, or {', '.join(_DATA_SUFFIXES)} for the data") from None
        raise


def _write_run_output(result: object, name: str) -> None:
    path = Path(name)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        result.to_csv(path)                                   # type: ignore[attr-defined]
    elif suffix == ".nc":
        result.to_xarray().to_netcdf(path)                    # type: ignore[attr-defined]
    else:
        import matplotlib.pyplot as plt
        columns = [c for c in result.columns()                # type: ignore[attr-defined]
                   if c.endswith((".pressure", ".volume"))]
        axes = result.plot(*columns, units={"pressure": "mbar",  # type: ignore[attr-defined]
                                            "volume": "mL"}, gauge=True)
        first = axes[0] if isinstance(axes, list) else axes
        first.figure.savefig(path, dpi=120)
        plt.close(first.figure)


def _run(args: argparse.Namespace) -> int:
    import softflow as sf
    from softflow import scene as scene_files

    for name in args.output:
        _check_run_output(name)
    scene = scene_files.read(args.scene)
    options: dict = {}
    if args.duration is not None:
        options["duration"] = sf.Q_(args.duration) if any(c.isalpha() for c in args.duration) \
            else float(args.duration)
    elif "duration" not in scene.simulation:
        raise CLIError(f"{args.scene}: no duration: give --duration (e.g. --duration '2 s') "
                       "or duration = \"2 s\" in the scene's [simulation] table")
    sim = scene.simulate(**options)
    t0 = time.perf_counter()
    result = sim.run(progress=False if args.no_progress else None, raise_on_failure=False)
    elapsed = time.perf_counter() - t0
    st = result.stats
    print(f"softflow run {args.scene}: {len(scene.system)} components, t = 0 to "
          f"{sim.duration:g} s: {result.status} after {st['steps']} steps "
          f"({st['rejected_steps']} rejected) in {elapsed:.2f} s")
    # a run that stopped at its start has nothing to plot or tabulate but its
    # initial state: no file then (an empty plot or a one-row table would pass
    # for a result)
    started = len(result.times) > 1                           # type: ignore[attr-defined]
    if result.success or started:
        for name in args.output:
            _write_run_output(result, name)
            print(f"  wrote {name}")
    if not result.success:
        where = ("" if not args.output else " (outputs hold the steps computed so far)"
                 if started else " (no output written: it stopped at its start)")
        raise CLIError(f"the run failed: {result.message}{where}")
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
    figs.add_argument("--physics", choices=("full", "paper"), default="full",
                      help="'full' (default): the scenes of examples/paper_fig*.py, which model "
                           "what the paper leaves out (the tube's inertia, the air's heat "
                           "exchange) and run without a model warning; 'paper': as the paper "
                           "models them (softflow then warns of what that leaves out)")
    run = sub.add_parser("run", help="run a scene file (softflow.scene; TOML)")
    run.add_argument("scene", help="scene file (.toml), e.g. written by softflow.scene.save")
    run.add_argument("--duration", help="simulated time, e.g. '2 s' or '500 ms' (default: "
                                        "the scene's [simulation] duration)")
    run.add_argument("--output", action="append", default=[],
                     help="file to write: .csv, .nc (netCDF) or an image (.png, .pdf, .svg: "
                          "pressures and volumes against time); may be repeated")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    command = {"demo": _demo, "figures": _figures, "run": _run}[args.command]
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
