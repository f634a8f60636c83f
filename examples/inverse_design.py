"""Inverse design with sensitivities: the restrictor that makes actuator 2 lag
actuator 1 by a wanted time.

The FONS paper's Fig. 4 network (a pump, actuator 1 with a 15 kPa plateau,
a tight tube R2, actuator 2 with a 22 kPa plateau; ``softflow.paper_scenes``)
sequences the two actuators through R2 alone; R2 carries its water column's
inertia (``fig4('tube', physics='full')``: left out, it changes the pressures
by 4.7 %, and softflow warns of it). The lag is the time between
the moments the two actuators reach half their largest volume. Given a
target lag (here the lag of the paper's 2.5 mm tube), this finds R2's diameter
from a start 30 % off with ``scipy.optimize.least_squares``, its derivative
from the run's own forward sensitivities:

    d lag / dD = -s2(t2) / V2'(t2) + s1(t1) / V1'(t1),   s = dV/dD at the crossing

(the crossing time of V(t) = V_half moves by -dV/dD / dV/dt).

Then both R2's diameter and actuator 2's plateau (its curve's
``pressure_scale``: the plateau at 22 kPa x scale) are designed together for
the same lag, both started 30 % off; one target and two parameters, so
least squares moves both and stops on one of the designs that meet it.

    python examples/inverse_design.py            # prints the iterations
"""
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
    derivative with respect to ``parameter`` with those volumes held fixed
    (None without a parameter: a run made without sensitivities)."""
    t = res.times
    out = []
    for label in ("act1", "act2"):
        v = res.get(label, "volume")
        s = (np.zeros_like(v) if parameter is None
             else res.sensitivity(label, "volume", parameter))
        level = 0.5 * (v[0] + v.max()) if half is None else half[label]
        out.append(crossing(t, v, s, level))
    (t1, d1), (t2, d2) = out
    return t2 - t1, (None if parameter is None else d2 - d1)


def half_levels(res):
    """{label: half-way volume} of both actuators in run ``res``."""
    return {lab: 0.5 * (res.get(lab, "volume")[0] + res.get(lab, "volume").max())
            for lab in ("act1", "act2")}


def design_simulation(rtol=1e-5):
    """(the Fig. 4 tube network's Simulation, the half-volume levels of its
    compiled design, held fixed while the parameters move)."""
    sim = sf.Simulation(fig4("tube", physics="full"), duration=duration(4) / 2, rtol=rtol)
    return sim, half_levels(sim.run())


def find_diameter(target_lag, start, *, rtol=1e-5, verbose=True):
    sim, half = design_simulation(rtol)
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


def find_design(target_lag, start, *, rtol=1e-5, verbose=True):
    """R2's diameter and actuator 2's ``pressure_scale`` for ``target_lag``
    from ``start`` = (diameter, scale): (diameter, scale, lag reached, runs)."""
    names = ("R2.diameter", "act2.pressure_scale")
    sim, half = design_simulation(rtol)
    cache = {}

    def evaluate(u):
        key = tuple(float(a) for a in u)
        if key not in cache:
            params = {n: k * s0 for n, k, s0 in zip(names, key, start)}
            res = sim.run(params=params, sensitivities=list(names))
            (value, d_diameter), (_, d_scale) = (lag(res, parameter=n, half=half)
                                                 for n in names)
            cache[key] = (value, [d_diameter * start[0], d_scale * start[1]])
            if verbose:
                print(f"  D = {params[names[0]] * 1e3:.4f} mm, act2 scale "
                      f"{params[names[1]]:.4f}: lag {value:.4f} s")
        return cache[key]

    # the tolerances of find_diameter: each lag, from a run at rtol 1e-5, is known
    # to ~1e-4 s, and tighter ones (xtol 1e-6, ftol 1e-8) only chase that noise
    # (20 runs instead of 14 from the 0.7 start, the lag met to 0.002 % either way)
    opt = least_squares(lambda u: [evaluate(u)[0] - target_lag], [1.0, 1.0],
                        jac=lambda u: [evaluate(u)[1]],
                        bounds=([0.2, 0.5], [5.0, 2.0]), xtol=1e-5, ftol=1e-6)
    reached = evaluate(opt.x)[0]
    return float(opt.x[0] * start[0]), float(opt.x[1] * start[1]), reached, len(cache)


def main():
    true_d = 2.5e-3
    sim = sf.Simulation(fig4("tube", physics="full"), duration=duration(4) / 2, rtol=1e-5)
    res = sim.run(sensitivities=["R2.diameter"])
    target, slope = lag(res)
    print(f"target lag {target:.4f} s (R2 = {true_d * 1e3} mm); "
          f"d lag / dD = {slope:.4g} s/m")
    for start in (0.7 * true_d, 1.3 * true_d):
        print(f"start at D = {start * 1e3:.3f} mm:")
        found, runs, _ = find_diameter(target, start)
        print(f"  found D = {found * 1e3:.4f} mm in {runs} runs "
              f"({(found / true_d - 1) * 100:+.3f} % from {true_d * 1e3} mm)")
    for factor in (0.7, 1.3):
        start = (factor * true_d, factor)
        print(f"diameter and act2 plateau together, from D = {start[0] * 1e3:.3f} mm, "
              f"scale {start[1]:.2f}:")
        d, scale, reached, runs = find_design(target, start)
        print(f"  found D = {d * 1e3:.4f} mm, act2 plateau {22 * scale:.2f} kPa in {runs} "
              f"runs: lag {reached:.4f} s ({(reached / target - 1) * 100:+.3f} % from the "
              "target)")


if __name__ == "__main__":
    main()
