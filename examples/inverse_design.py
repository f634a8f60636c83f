"""Inverse design with sensitivities: the restrictor that makes actuator 2 lag
actuator 1 by a wanted time.

The FONS paper's Fig. 4 network (a pump, actuator 1 with a 15 kPa plateau,
a tight tube R2, actuator 2 with a 22 kPa plateau; ``softflow.paper_scenes``)
sequences the two actuators through R2 alone. The lag is the time between
the moments the two actuators reach half their largest volume. Given a
target lag (here the lag of the paper's 2.5 mm tube), this finds R2's diameter
from a start 30 % off with ``scipy.optimize.least_squares``, its derivative
from the run's own forward sensitivities:

    d lag / dD = -s2(t2) / V2'(t2) + s1(t1) / V1'(t1),   s = dV/dD at the crossing

(the crossing time of V(t) = V_half moves by -dV/dD / dV/dt).

    python examples/inverse_design.py            # prints the iterations
"""
import warnings

import numpy as np
from scipy.optimize import least_squares

import softflow as sf
from softflow.paper_scenes import duration, fig4


def crossing(t, v, s, level):
    """(time, d time / d parameter) where v first reaches ``level``, linear
    between samples; s is dv/d parameter."""
    k = int(np.argmax(v >= level))
    w = (level - v[k - 1]) / (v[k] - v[k - 1])
    t_c = t[k - 1] + w * (t[k] - t[k - 1])
    slope = (v[k] - v[k - 1]) / (t[k] - t[k - 1])
    s_c = s[k - 1] + w * (s[k] - s[k - 1])
    return t_c, -s_c / slope


def lag(res, parameter="R2.diameter", half=None):
    """The lag [s] of actuator 2 behind actuator 1 at the volumes ``half``
    ({label: volume}; default: half of each one's largest in this run), and its
    derivative with respect to ``parameter`` with those volumes held fixed."""
    t = res.times
    out = []
    for label in ("act1", "act2"):
        v = res.get(label, "volume")
        s = res.sensitivity(label, "volume", parameter)
        level = 0.5 * (v[0] + v.max()) if half is None else half[label]
        out.append(crossing(t, v, s, level))
    (t1, d1), (t2, d2) = out
    return t2 - t1, d2 - d1


def find_diameter(target_lag, start, *, rtol=1e-5, verbose=True):
    sim = sf.Simulation(fig4("tube"), duration=duration(4) / 2, rtol=rtol)
    ref = sim.run()      # half-volume levels from the compiled design, held fixed
    half = {lab: 0.5 * (ref.get(lab, "volume")[0] + ref.get(lab, "volume").max())
            for lab in ("act1", "act2")}
    cache = {}

    def evaluate(u):
        key = float(u[0])
        if key not in cache:
            res = sim.run(params={"R2.diameter": key * start},
                          sensitivities=["R2.diameter"])
            cache[key] = lag(res, half=half)
            if verbose:
                print(f"  D = {key * start * 1e3:.4f} mm: lag {cache[key][0]:.4f} s")
        return cache[key]

    opt = least_squares(lambda u: [evaluate(u)[0] - target_lag], [1.0],
                        jac=lambda u: [[evaluate(u)[1] * start]],
                        bounds=([0.2], [5.0]), xtol=1e-5, ftol=1e-6)
    return float(opt.x[0] * start), len(cache), opt


def main():
    warnings.simplefilter("ignore", sf.ModelWarning)
    true_d = 2.5e-3
    sim = sf.Simulation(fig4("tube"), duration=duration(4) / 2, rtol=1e-5)
    res = sim.run(sensitivities=["R2.diameter"])
    target, slope = lag(res)
    print(f"target lag {target:.4f} s (R2 = {true_d * 1e3} mm); "
          f"d lag / dD = {slope:.4g} s/m")
    for start in (0.7 * true_d, 1.3 * true_d):
        print(f"start at D = {start * 1e3:.3f} mm:")
        found, runs, _ = find_diameter(target, start)
        print(f"  found D = {found * 1e3:.4f} mm in {runs} runs "
              f"({(found / true_d - 1) * 100:+.3f} % from {true_d * 1e3} mm)")


if __name__ == "__main__":
    main()
