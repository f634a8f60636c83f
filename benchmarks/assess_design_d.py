"""sf.assess as it is (the base and the probes at 10 rtol0, "design D")
against the design before 2026-12-03 (everything at rtol0), in turns.

rtol0 = tolerance / 10. Since 2026-12-03 assess runs its base and its probes
at 10 rtol0 (their validity checks judged at rtol0; a probe whose effect there
is near the adopt threshold is measured again at rtol0) and only the
recommended models at rtol0, for the time tolerance, whose 10 rtol0 run is
the last adopted probe's. Before, the base and the probes ran at rtol0:
``softflow.assess.LOOSE_FACTOR = 1`` gives that design back (the base at
rtol0, so no probe is measured again, and the time tolerance's pair as
before). The design was first prototyped here by a reviewing helper, by
monkeypatching; the numbers of that prototype are in benchmarks/README.md.

For each scene of assess_scenes.py: sf.assess now, sf.assess as before and
one run of the cheapest adequate configuration (``CHEAPEST``:
bench_assess.py's exhaustive search, 2026-12-03 19:06) in turns,
``--repeats`` times; prints whether the two recommend the same, the runs and
rows of today's, and the medians of now / cheapest and before / cheapest
with their ranges.

    python benchmarks/assess_design_d.py [--repeats 7] [--scene fast_fill bottle]
"""
from __future__ import annotations

import argparse
import contextlib
import statistics
import sys
import warnings
from pathlib import Path

import softflow as sf
import softflow.assess as A
from softflow.assess import Config

sys.path.insert(0, str(Path(__file__).resolve().parent))
from assess_scenes import SCENES  # noqa: E402
from bench_assess import simulate  # noqa: E402

TOLERANCE = 0.01
_ISO_TUBE = {"tube": {"compressible": "pipe_flow"}}
#: the cheapest adequate configuration of each scene (bench_assess.py, 19:06)
CHEAPEST = {
    "syringe": Config("isothermal", "ideal", 1e-2).with_overrides(_ISO_TUBE),
    "fast_fill": Config("adiabatic", "ideal", 1e-2),
    "bottle": Config("heat_transfer", "table", 1e-2).with_overrides(_ISO_TUBE),
    "near_choking": Config("heat_transfer", "ideal", 1e-2).with_overrides(_ISO_TUBE),
    "water_hammer": Config("isothermal", "ideal", 1e-2).with_overrides(
        {"line": {"inertance": True}}),
    "slow_water": Config("isothermal", "ideal", 1e-2),
}


@contextlib.contextmanager
def design_before():
    """sf.assess as before 2026-12-03 inside the block: everything at rtol0."""
    saved = A.LOOSE_FACTOR
    A.LOOSE_FACTOR = 1.0
    try:
        yield
    finally:
        A.LOOSE_FACTOR = saved


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--scene", nargs="*", choices=list(SCENES), default=list(CHEAPEST))
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore", sf.ModelWarning)
    for name in args.scene:
        system, duration, outputs = SCENES[name]()
        sf.assess(system, duration, tolerance=TOLERANCE, outputs=outputs)    # warm
        now, before = [], []
        for _ in range(args.repeats):
            a = sf.assess(system, duration, tolerance=TOLERANCE, outputs=outputs)
            with design_before():
                b = sf.assess(system, duration, tolerance=TOLERANCE, outputs=outputs)
            cheap = (simulate(system, duration, CHEAPEST[name])[1] if name in CHEAPEST
                     else float("nan"))
            now.append(a.cost / cheap)
            before.append(b.cost / cheap)
        print(f"== {name}: now {a.config.describe()}; before {b.config.describe()}; "
              f"the same: {a.config == b.config}")
        for r in a.runs:
            print(f"   {'ok ' if r.ok else 'ERR'} {1e3 * r.cpu:7.1f} ms  {r.config.describe()}")
        for row in a.rows[1:]:
            effect = "nan" if row[2] != row[2] else f"{row[2]:.4f}"
            print(f"   row: {row[0]} | {effect} | {row[5][:100]}")
        if name in CHEAPEST:
            print(f"   assess / cheapest now {statistics.median(now):.2f}x [{min(now):.2f}-"
                  f"{max(now):.2f}], before {statistics.median(before):.2f}x "
                  f"[{min(before):.2f}-{max(before):.2f}]")


if __name__ == "__main__":
    main()
