"""Fitting a model to a measurement: a tube's effective diameter and a balloon
curve's pressure scale from a noisy pressure trace.

The "measurement" is made here: the measured latex balloon curve (the FONS
paper's, shipped with softflow) inflated with water through a 1.0 mm tube,
its gauge pressure 15 % stiffer than measured (pressure_scale 1.15), sampled
every 5 ms with 100 Pa of noise. ``sf.fit`` then recovers the diameter and
the scale from a start 30 % off, by least squares with the Jacobian from the
runs' own forward sensitivities.

The tube carries the water column's inertia (``inertance=True``): without it
a 1.0 mm tube's fill differs by 2.5 % of the 30 kPa step in pressure
(measured at rtol 1e-7 with and without it), more than the 100 Pa noise,
and softflow warns of it (ModelWarning ``'tube_inertia'``).

    python examples/fit_balloon.py
"""
import numpy as np

import softflow as sf
from softflow.demo import balloon_csv

P0 = sf.pressure_atmospheric
CURVE = sf.PVCurve(balloon_csv())


def scene(diameter=0.6e-3, scale=1.0):
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 3e4)
    s += sf.CircularTube("tube", sf.water, 0.6, diameter, inertance=True)
    s += sf.Actuator("act", sf.water, CURVE, initial_volume=1e-6, pressure_scale=scale)
    s.connect("src", "tube")
    s.connect("tube", "act")
    return s


def measurement(diameter=1.0e-3, scale=1.15, noise=100.0, seed=1):
    truth = sf.Simulation(scene(diameter, scale), duration=1.0, rtol=1e-7).run()
    t = np.linspace(0.0, 1.0, 201)
    rng = np.random.default_rng(seed)
    return t, np.interp(t, truth.times, truth.get("act", "pressure")) + rng.normal(0, noise,
                                                                                    t.size)


def main():
    t, p = measurement()
    sim = sf.Simulation(scene(), duration=1.0, rtol=1e-5)
    out = sf.fit(sim, {"act.pressure": (t, p)}, ["tube.diameter", "act.pressure_scale"],
                 x0={"tube.diameter": 0.7e-3, "act.pressure_scale": 0.8},
                 bounds={"tube.diameter": (1e-4, 5e-3), "act.pressure_scale": (0.2, 5.0)})
    d, s = out.params["tube.diameter"], out.params["act.pressure_scale"]
    print(f"fitted in {out.runs} runs: diameter {d * 1e3:.4f} mm (true 1.0), "
          f"pressure scale {s:.4f} (true 1.15); {out.message}")
    return out


if __name__ == "__main__":
    main()
