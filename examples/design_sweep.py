"""Design study: how the restrictor and actuator 2's plateau set the inflation lag.

The FONS paper's Fig. 4 network (water; a pump that pushes 1.8 mL/s in for
8 s, then pauses; actuator 1 with a 15 kPa plateau, then a 1 m restrictor
tube, then actuator 2 with a higher plateau; the inflation half of the
paper's cycle, 10 s) is compiled once
and run for every pair of restrictor diameter x actuator 2's plateau pressure
with ``sf.sweep``. For each variant the *inflation lag* is the time actuator 2
takes, after actuator 1, to reach half of its own volume swing; the lags are
drawn as a map and saved as a PNG.

The scene models what the paper's leaves out and softflow would warn of
(``paper_scenes.fig4('tube', physics='full')``): R2's water column's inertia,
which changes the pressures by 4.7 % and actuator 2's volume by 1.2 % of its
swing at the paper's 2.5 mm (measured with and without it, rtol 1e-7). The
diameters start at 2 mm: through a 1.5 or 1.6 mm R2, actuator 2 lags so far
behind that the pump pushes actuator 1 past the 10 mL its curve is drawn to
(by 1.8 % and 5 % of the curve's range at the two highest plateaus: check
``'pv_curve_range'``); from 1.75 mm it stays inside at every plateau.

    python examples/design_sweep.py                       # processes, all cores
    python examples/design_sweep.py --engine dask         # a Dask LocalCluster
    python examples/design_sweep.py --engine dask --scheduler tcp://host:8786
    python examples/design_sweep.py --diameters 12 --plateaus 10 --output lag.png

About 10 s for the default 6 x 5 grid on 2 cores with engine 'processes'.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import softflow as sf
from softflow import paper_scenes as ps

#: actuator 1's plateau [kPa gauge]; actuator 2's are swept above it
PLATEAU_1 = 15.0


#: the inflation half of the paper's cycle: pumping in (8 s), then the pause (2 s)
DURATION = ps.T_IN[4] + ps.T_PAUSE


def build():
    """The Fig. 4 scene with a tube as restrictor R2, compiled once (adaptive BDF),
    over the inflation and the pause."""
    # act1 (15 kPa plateau) --R2: 1 m x 2.5 mm, with its water column's inertia-- act2 (22 kPa)
    system = ps.fig4("tube", physics="full")
    return sf.Simulation(system, duration=DURATION)


def half_swing_time(times, volume):
    """First time ``volume`` reaches half-way from its start to its largest
    value (linear between samples); NaN where it never rises."""
    v0, top = volume[0], np.nanmax(volume)
    if not np.isfinite(top) or top <= v0:
        return np.nan
    half = v0 + 0.5 * (top - v0)
    k = int(np.argmax(volume >= half))
    if k == 0:
        return times[0]
    t0, t1, a, b = times[k - 1], times[k], volume[k - 1], volume[k]
    return t0 + (half - a) / (b - a) * (t1 - t0)


def inflation_lag(times, v1, v2):
    """How long after actuator 1 actuator 2 reaches half of its volume swing [s]."""
    return half_swing_time(times, v2) - half_swing_time(times, v1)


def study(diameters_mm, plateaus_kpa, engine="processes", workers=None, client=None,
          progress=None):
    """Sweep R2's diameter x actuator 2's plateau; returns (SweepResult, lag [s] as an
    array of shape (len(diameters_mm), len(plateaus_kpa)))."""
    sim = build()
    params = {
        "R2.diameter": sf.Q_(np.asarray(diameters_mm, dtype=float), "mm"),
        # curves are not numbers: label each by its plateau [kPa]
        "act2.curve": {float(p): ps.curve_plateau(float(p)) for p in plateaus_kpa},
    }
    times = np.linspace(0.0, DURATION, 1001)      # 10 ms resolution for the lag
    kw = dict(outputs=["act1.volume", "act2.volume"], engine=engine, times=times,
              progress=progress)
    if engine == "dask" and client is not None:
        kw["client"] = client
    elif engine in ("processes", "dask"):
        kw["workers"] = workers
    res = sf.sweep(sim, params, **kw)
    v1, v2 = res["act1.volume"], res["act2.volume"]
    lag = np.array([inflation_lag(res.times, a, b) if status == "success" else np.nan
                    for a, b, status in zip(v1, v2, res.status)])
    return res, lag.reshape(len(diameters_mm), len(plateaus_kpa))


def plot(diameters_mm, plateaus_kpa, lag, path):
    """The lag map (matplotlib), saved to ``path``."""
    import matplotlib
    if "matplotlib.pyplot" not in sys.modules:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    mesh = ax.pcolormesh(plateaus_kpa, diameters_mm, lag, shading="nearest", cmap="viridis")
    fig.colorbar(mesh, ax=ax, label="inflation lag of actuator 2 [s]")
    for i, d in enumerate(diameters_mm):
        for j, p in enumerate(plateaus_kpa):
            if np.isfinite(lag[i, j]):
                bright = mesh.norm(lag[i, j]) > 0.6        # viridis: dark text on yellow
                ax.text(p, d, f"{lag[i, j]:.2f}", ha="center", va="center", fontsize=7,
                        color="k" if bright else "w")
    ax.set_xlabel("actuator 2 plateau pressure [kPa gauge]")
    ax.set_ylabel("restrictor R2 inner diameter [mm] (1 m tube)")
    ax.set_title(f"Fig. 4 network: actuator 2 behind actuator 1 ({PLATEAU_1:.0f} kPa plateau)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--engine", default="processes",
                    choices=["processes", "dask", "serial", "batched"])
    ap.add_argument("--workers", type=int, default=None,
                    help="worker processes (processes, or the Dask LocalCluster)")
    ap.add_argument("--scheduler", default=None,
                    help="address of a running Dask scheduler (engine dask)")
    ap.add_argument("--diameters", type=int, default=6, help="restrictor diameters, 2-4 mm")
    ap.add_argument("--plateaus", type=int, default=5,
                    help="actuator 2 plateaus, 17-30 kPa")
    ap.add_argument("--output", default="design_sweep.png", help="PNG to write")
    args = ap.parse_args(argv)
    diameters = np.round(np.linspace(2.0, 4.0, args.diameters), 3)
    plateaus = np.round(np.linspace(17.0, 30.0, args.plateaus), 2)
    client = None
    if args.scheduler:
        if args.engine != "dask":
            ap.error("--scheduler is for --engine dask")
        from distributed import Client
        client = Client(args.scheduler)
    t0 = time.perf_counter()
    try:
        res, lag = study(diameters, plateaus, engine=args.engine, workers=args.workers,
                         client=client)
    finally:
        if client is not None:
            client.close()
    wall = time.perf_counter() - t0
    print(f"{len(res)} variants, engine {args.engine!r}: {wall:.1f} s "
          f"({len(res) / wall:.1f} variants/s), {len(res.failed)} failed")
    for i in res.failed:
        print(f"  failed: {res.variants[i]}: {res.messages[i]}")
    print("inflation lag [s]; rows: diameter [mm], columns: plateau [kPa]")
    print("        " + " ".join(f"{p:6.1f}" for p in plateaus))
    for d, row in zip(diameters, lag):
        print(f"{d:6.2f}  " + " ".join(f"{x:6.2f}" for x in row))
    print("saved", plot(diameters, plateaus, lag, args.output))
    return res, lag


if __name__ == "__main__":
    main()
