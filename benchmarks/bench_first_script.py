"""A tiny first script, whole process: softflow against fonsim 0.6.

The README's first network (a 1.5 bar source fills a 10 mL tank of air through
30 cm of 1 mm tube, 50 ms) run as a user runs it, ``python script.py`` in a
fresh interpreter, and the same scene written for fonsim 0.6 (its own default
steps). Each repeat runs both, in turns, and the CPU time of each child
process (user + system, from ``resource.getrusage``) is what counts: imports,
building the network, the run, and, for softflow, loading its compiled laws
from the cache. Printed: the median CPU of each with its spread (min-max), and
the ratio of the medians (issue 38's target: softflow <= fonsim once the
compile cache exists).

``--cold`` also runs softflow once with an empty numba cache directory (the
first run after installation: the compile) and reports it separately.

``--python-steps`` also runs the softflow script with
``softflow.solve.settings.COMPILED_STEPS = False`` (every adaptive step the
Python BDF's instead of the compiled step loop's, issue 38), in the same
turns, and prints its CPU and the ratio of the two softflow medians.

Usage: python benchmarks/bench_first_script.py [--repeats 7] [--cold] [--python-steps]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import textwrap

SOFTFLOW = textwrap.dedent("""
    import softflow as sf
    s = sf.System()
    s += sf.PressureSource("source", pressure=sf.Q_(1.5, "bar"))
    s += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=sf.Q_(1, "mm"))
    s += sf.Container("tank", sf.air, volume=sf.Q_(10, "mL"))
    s.connect("tube", "source")
    s.connect("tube", "tank")
    r = sf.Simulation(s, duration=sf.Q_(50, "ms")).run()
    print(r.get("tank", "pressure")[-1])
""")

#: the same script with the compiled step loop off
SOFTFLOW_PY_STEPS = SOFTFLOW.replace(
    "import softflow as sf\n",
    "import softflow as sf\nimport softflow.solve.settings\n"
    "softflow.solve.settings.COMPILED_STEPS = False\n", 1)

FONSIM = textwrap.dedent("""
    import contextlib, io
    import fonsim as fons
    s = fons.System()
    s.add(fons.PressureSource("source", pressure=1.5e5))
    s.add(fons.CircularTube("tube", fluid=fons.air, length=0.30, diameter=1e-3))
    s.add(fons.Container("tank", fluid=fons.air, volume=10e-6))
    s.connect("tube", "source")
    s.connect("tube", "tank")
    sim = fons.Simulation(s, duration=0.05)
    with contextlib.redirect_stdout(io.StringIO()):
        sim.run()
    print(s.get("tank").get("pressure")[-1])
""")


def cpu_of(code: str, env: dict | None = None) -> tuple[float, str]:
    """CPU seconds (user + system) of one fresh interpreter running ``code``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, out.stdout.strip().splitlines()[-1]


def spread(xs: list[float]) -> str:
    return f"{statistics.median(xs):.3f} s [{min(xs):.3f}-{max(xs):.3f}]"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--cold", action="store_true",
                    help="also time one softflow run with an empty numba cache")
    ap.add_argument("--python-steps", action="store_true",
                    help="also time the softflow script with COMPILED_STEPS = False")
    args = ap.parse_args()
    try:
        import fonsim  # noqa: F401
        have_fonsim = True
    except ImportError:
        have_fonsim = False
    cpu_of(SOFTFLOW)            # warm the compile cache and the OS file cache
    if have_fonsim:
        cpu_of(FONSIM)
    if args.python_steps:
        cpu_of(SOFTFLOW_PY_STEPS)
    ours, theirs, py_steps = [], [], []
    for _ in range(args.repeats):
        t, p_ours = cpu_of(SOFTFLOW)
        ours.append(t)
        if args.python_steps:
            t, p_py = cpu_of(SOFTFLOW_PY_STEPS)
            py_steps.append(t)
        if have_fonsim:
            t, p_theirs = cpu_of(FONSIM)
            theirs.append(t)
    print(f"tiny first script, whole process, CPU (user + system), {args.repeats} repeats, "
          f"{os.cpu_count()} cores")
    print(f"  softflow {spread(ours)}   tank ends at {float(p_ours):.6g} Pa")
    if args.python_steps:
        print(f"  softflow, COMPILED_STEPS = False {spread(py_steps)}   tank ends at "
              f"{float(p_py):.6g} Pa; compiled loop / Python steps (medians): "
              f"{statistics.median(ours) / statistics.median(py_steps):.3f}")
    if have_fonsim:
        print(f"  fonsim   {spread(theirs)}   tank ends at {float(p_theirs):.6g} Pa")
        print(f"  ratio softflow / fonsim (medians): "
              f"{statistics.median(ours) / statistics.median(theirs):.2f}")
    else:
        print("  fonsim not installed (pip install fonsim==0.6.0): no comparison")
    if args.cold:
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, NUMBA_CACHE_DIR=cache)
            t, _ = cpu_of(SOFTFLOW, env)
        print(f"  softflow with an empty compile cache (first run after installing): {t:.2f} s")


if __name__ == "__main__":
    main()
