"""Issue 12's open question: does a one-step method measure better than the
variable-order BDF on snapping scenes? TR-BDF2 against softflow's BDF.

TR-BDF2 (Bank et al. 1985; Hosea & Shampine 1996, "Analysis and
implementation of TR-BDF2", Appl. Numer. Math. 20) takes each step h in two
stages: a trapezoidal stage to t + gamma h, then a BDF2 stage through t,
t + gamma h and t + h. With gamma = 2 - sqrt(2) both stages have the same
leading coefficient d h (d = gamma / 2), so they share Newton's factors, as
softflow's BDF steps do. It is a one-step method: the step may change at every
step (by 0.2x to MAX_GROW x here) and nothing is restarted at a snap or a
switch but the rate at its start. L-stable, second order; local error
estimated from the stages' rates (Hosea & Shampine's estimate: 2 C h times
the second divided difference of the states' rates over the stages, C the
method's error constant (-3 gamma^2 + 4 gamma - 2) / (12 (2 - gamma))), on the
continuous states, in the BDF's own error weights.

The prototype lives here, not in softflow: it is what this benchmark measures
(the class plugs into Simulation in place of the BDF, with its restart probes,
breakpoints, fold jumps, mode-switch location and weights; no sensitivities,
no refine, no kinks). Fig. 4's snapping valve is left out by default: there
the prototype's switch location (the BDF's secant and bisection, reused)
loops against its step growth (rtol 1e-3, measured once: 2 214 steps, 8 467
steps rejected at the switch, 3.1 s, against the BDF's 317 steps, 53 ms).
Each scene runs at rtol 1e-2, 1e-3 and 1e-4 with both methods; the error of
each run is the largest difference of the actuators' volumes from a reference
(softflow's BDF at rtol 1e-6, step_max 0.01 s) at the run's own times,
relative to each volume's range; CPU is process_time of Simulation + run
(median of --repeat runs).

Measured (benchmarks/README.md, 2026-12-03): half the steps, 30 % more
Newton iterations, 15 % more CPU over eight scenes x three rtols; 3-10x less
accurate on Fig. 3's snapping actuators at rtol 1e-3 and 1e-4 for about the
same CPU, 1.3-1.9x the CPU on Fig. 5 with air: the BDF stays softflow's
adaptive method.

    python benchmarks/bench_one_step.py [--repeat 3] [--scene fig5:air ...]   # ~5 min
"""
from __future__ import annotations

import argparse
import math
import statistics
import time
import warnings

import numpy as np

import softflow as sf
from softflow import paper_scenes as ps
from softflow.solve import simulation as simulation_mod
from bench_paper_scenes import scenes
from softflow.solve.bdf import BDF, FAIL_HOLD, FULL_STAGE_STEPS, MIN_FACTOR, SAFETY

GAMMA = 2.0 - math.sqrt(2.0)
D = GAMMA / 2.0                                   # both stages: c = D h
W1 = 1.0 / (GAMMA * (2.0 - GAMMA))                # BDF2 stage: psi = W1 S_g + W0 S_n
W0 = -(1.0 - GAMMA) ** 2 / (GAMMA * (2.0 - GAMMA))
ERR = (-3.0 * GAMMA ** 2 + 4.0 * GAMMA - 2.0) / (6.0 * (2.0 - GAMMA))   # 2 C
MAX_GROW = 4.0
REF_RTOL = 1e-6
SKIPPED = ("fig4:snapping",)      # see the module doc


class TRBDF2(BDF):
    """TR-BDF2 as a controller of softflow's integration loop (module doc):
    each step is two passes of the loop, the first (the trapezoidal stage)
    judged "not yet" (None, counted as nothing)."""

    def _setup(self, x, S):
        super()._setup(x, S)
        self._stage = 1
        self._r = self._xdot = None

    def _propose(self, t, x, S):
        self._point = (x, S)
        if self._stage == 2:
            h = self._h
            psi = W1 * self._S_g + W0 * S
            x_pred = x + (self._x_g - x) / GAMMA
            t_new = self._t_new
            t_eval = math.nextafter(t_new, -math.inf) if self._at_break else t_new
            return x_pred, psi, t_new, t_eval, D * h
        if self._next <= t * (1 + 1e-14) + 1e-300:
            self._ib, self._next = self._next_break(t, self._ib)
        limit = min(self._next, self.T)
        if self._restart_due:
            x_right, r0, xdot, h = self._restart(x, S, t, limit)
            self.progress.restarted(t, h)
            self._r, self._xdot, self._h = r0, xdot, h
            self._D[:] = 0.0
            self._D[0, self._iS], self._D[1, self._iS] = S, h * r0     # (a fold jump's rate)
            self._restart_due = False
        h = min(self._h, self.step_max, self._h_cap, self._fail_cap)
        if t + h >= limit or limit - (t + h) < 0.2 * h:
            h = limit - t
        self._h = h
        self._t_new = t_new = t + h
        self._at_break = t_new == self._next
        self.newton.full_stage = h <= FULL_STAGE_STEPS * self.step_min
        return x + GAMMA * h * self._xdot, S + D * h * self._r, t_new, t + GAMMA * h, D * h

    def _shrink(self, factor):
        self._h *= factor
        self._stage = 1

    def _newton_failed(self, t, t_new, out):
        self._stage = 1
        return super()._newton_failed(t, t_new, out)

    def _judge(self, t, x, S, x_new, S_new, t_new):
        h = self._h
        if self._stage == 1:
            self._x_g, self._S_g = x_new, S_new
            self._r_g = (S_new - (S + D * h * self._r)) / (D * h)
            self._stage = 2
            return None
        self._stage = 1
        r_new = (S_new - (W1 * self._S_g + W0 * S)) / (D * h)
        est = (ERR * h) * (self._r / GAMMA - self._r_g / (GAMMA * (1.0 - GAMMA))
                           + r_new / (1.0 - GAMMA))
        ns = S.size
        w = self._weights(S, S_new, x_new)[:ns]
        e = est / w
        cont = self.cont
        err = self._err = (float(math.sqrt(e[cont].dot(e[cont]) / max(cont.size, 1)))
                           if cont.size else 0.0)
        smin = self.step_min * 1.0000001
        if err > 1.0 and h > smin:
            self.stats.rejected_steps += 1
            self.stats.error_test_failures += 1
            self.progress.rejected(t_new, h, "error", err)
            self._fail_cap, self._fail_hold = 0.9 * h, FAIL_HOLD
            self._shrink(max(MIN_FACTOR, SAFETY * err ** (-1.0 / 3.0), self.step_min / h))
            return None
        disc = self._disc
        switched = self._switched = disc is not None and bool((S_new[disc] != S[disc]).any())
        # a switch located as the BDF locates it (BDF._switch_rejected)
        if switched and h > smin and self._switch_rejected(
                t_new, h, x, S, x_new, S_new, self._weights(S, S_new, x_new)):
            return None
        self._secant_tries = 0
        self._r_new = r_new
        return t_new

    def _take(self, t, x, S, x_new, psi, c, S_new, t_new):
        h = self._h
        if self._fail_hold:
            self._fail_hold -= 1
            if not self._fail_hold:
                self._fail_cap = math.inf
        if self._cap_hold:
            self._cap_hold -= 1
            if not self._cap_hold:
                self._h_cap = math.inf
        self.order_counts[2] += 1
        q = self._q_sel
        self._Q = self._Q + 0.5 * h * (x[q] + x_new[q])
        self.rec.add(t_new, x_new, S_new, self._Q)
        self._r = self._r_new
        self._xdot = (x_new - self._x_g) / ((1.0 - GAMMA) * h)
        self._D[0, self._iS], self._D[1, self._iS] = S_new, h * self._r
        if self._at_break or self._switched:
            self._restart_due = True
            self._h_cap = self._fail_cap = math.inf
            self._fail_hold = self._cap_hold = 0
            self.newton.invalidate()
            if self._switched:
                self.progress.switched(t_new, S, S_new, self._disc)
            return x_new, S_new, t_new
        factor = min(MAX_GROW, max(MIN_FACTOR, SAFETY * max(self._err, 1e-16) ** (-1.0 / 3.0)))
        if factor > 1.2 or factor < 1.0:
            self._h = h * factor
        return x_new, S_new, t_new


def run(build, fig, rtol, cls=None, **options):
    """(cpu s, Result) of Simulation + run on a fresh System, with ``cls`` in
    place of the BDF (None: softflow's own)."""
    system = build()
    saved = simulation_mod.BDF
    if cls is not None:
        simulation_mod.BDF = cls
    try:
        t0 = time.process_time()
        res = sf.Simulation(system, duration=ps.duration(fig), rtol=rtol,
                            beyond_limits="warn", **options).run(raise_on_failure=False)
        cpu = time.process_time() - t0
    finally:
        simulation_mod.BDF = saved
    return cpu, res


def error(res, ref):
    t_ref, refs = ref
    return max(float(np.abs(v - np.interp(res.times, t_ref, vr)).max() / np.ptp(vr))
               for v, vr in zip(ps.volumes(res), refs))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--scene", nargs="*", default=None)
    ap.add_argument("--rtols", nargs="*", type=float, default=[1e-2, 1e-3, 1e-4])
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    print("scene | rtol | BDF: error / CPU ms / steps / Newton / LU | TR-BDF2: same")
    totals = {"bdf": [0.0, 0, 0], "trbdf2": [0.0, 0, 0]}
    for name, fig, build in scenes():
        if (args.scene and name not in args.scene) or (not args.scene and name in SKIPPED):
            continue
        _, rref = run(build, fig, REF_RTOL, step_max=0.01)
        ref = (rref.times, ps.volumes(rref))
        for rtol in args.rtols:
            cells = []
            for key, cls in (("bdf", None), ("trbdf2", TRBDF2)):
                cpus = []
                for _ in range(args.repeat):
                    cpu, res = run(build, fig, rtol, cls)
                    cpus.append(cpu)
                st = res.stats
                cpu = statistics.median(cpus) * 1e3
                if res.status != "success":
                    cells.append(f"failed at {res.times[-1]:.4g} s ({res.message[:60]})")
                    continue
                e = error(res, ref)
                totals[key][0] += cpu
                totals[key][1] += st["steps"]
                totals[key][2] += st["newton_iterations"]
                cells.append(f"{e:.1e} / {cpu:.1f} / {st['steps']} / {st['newton_iterations']}"
                             f" / {st['factorizations']}")
            print(f"{name} | {rtol:.0e} | " + " | ".join(cells), flush=True)
    for key, (cpu, steps, its) in totals.items():
        print(f"total {key}: CPU {cpu:.0f} ms, steps {steps}, Newton iterations {its}")


if __name__ == "__main__":
    main()
