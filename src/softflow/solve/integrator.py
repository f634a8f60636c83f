"""Implicit (backward) Euler time stepping: fixed or adaptive step.

The adaptive controller estimates the local error of the states from the
difference between the backward-Euler solution and a linear predictor
through the two previous points. Backward Euler errs by +h²/2·S'' and the
predictor by -h(h + h_prev)/2·S'', so their difference is h(2h + h_prev)/2·S''
and  LTE ≈ h/(2h + h_prev) · (S_new - S_pred). Algebraic unknowns (pressures, flows) follow from the states and the
inputs, so only states enter the error test; an input jump then does not
force the step down to its minimum.
"""
from __future__ import annotations

import bisect
import math

import numpy as np


class StepFailure(Exception):
    def __init__(self, t, dt, outcome):
        self.t, self.dt, self.outcome = t, dt, outcome


class Recorder:
    """Accepted steps, written into preallocated arrays that grow by doubling
    (no stacking of a list of rows at the end: for large networks that copy
    alone cost as much as the solve)."""

    def __init__(self, x_index, s_index, capacity=64):
        self.t = []
        # index arrays of the unknowns/states to keep, or plain sizes to keep all
        self.x_index, self.s_index = x_index, s_index
        n = x_index if isinstance(x_index, int) else len(x_index)
        ns = s_index if isinstance(s_index, int) else len(s_index)
        self._X = np.empty((capacity, n))
        self._S = np.empty((capacity, ns))

    def add(self, t, x, s):
        k = len(self.t)
        if k == len(self._X):
            self._X = np.concatenate([self._X, np.empty_like(self._X)])
            self._S = np.concatenate([self._S, np.empty_like(self._S)])
        self._X[k] = x if isinstance(self.x_index, int) else x[self.x_index]
        self._S[k] = s if isinstance(self.s_index, int) else s[self.s_index]
        self.t.append(t)

    def arrays(self):
        k = len(self.t)
        return np.array(self.t, dtype=float), self._X[:k], self._S[:k]


class ImplicitEuler:
    """Backward Euler with a constant step (landing on breakpoints) or an
    adaptive step (error control on the states, step rejection and retry)."""

    def __init__(self, asm, newton, stats, *, duration, step, adaptive, step_min, step_max,
                 rtol, atol_states, breakpoints=(), record=None):
        self.asm, self.newton, self.stats = asm, newton, stats
        self.T = duration
        self.step = step
        self.adaptive = adaptive
        self.step_min = step_min
        self.step_max = step_max
        self.rtol = rtol
        self.atol_s = atol_states
        breaks = sorted(b for b in set(breakpoints) if 0.0 < b < duration)
        if not adaptive:
            # a breakpoint on a grid point must be that grid point's float exactly,
            # or the step lands twice (0.3 vs 3*0.1) with a ~1e-17 s step between
            snapped = []
            for b in breaks:
                k = round(b / step)
                snapped.append(k * step if abs(b - k * step) <= 1e-9 * step else b)
            breaks = sorted(set(snapped))
        self.breaks = breaks
        self._break_set = set(breaks)
        n_expected = int(duration / step) + 2 + len(self.breaks) if step else 256
        # record: (unknown indices, state indices, labels) to keep, or None for all
        x_index, s_index = record[:2] if record is not None else (asm.n, len(asm.S0))
        self.rec = Recorder(x_index, s_index, capacity=min(max(n_expected, 16), 100_000))
        self.forced_steps = 0

    def _next_break(self, t):
        i = bisect.bisect_right(self.breaks, t * (1 + 1e-14) + 1e-300)
        return self.breaks[i] if i < len(self.breaks) else math.inf

    def initial(self):
        """Consistent algebraic unknowns at t = 0 (dt = 0, states at their initial values)."""
        asm = self.asm
        out = self.newton.solve(asm.x0.copy(), asm.S0, 0.0, 0.0)
        if not out.converged:
            raise StepFailure(0.0, 0.0, out)
        self.newton.invalidate()
        self.rec.add(0.0, out.x, asm.S0.copy())
        return out.x, asm.S0.copy()

    def _attempt(self, x_pred, S, t_new, h):
        if t_new in self._break_set:
            t_new = math.nextafter(t_new, -math.inf)   # left limit of the inputs
        out = self.newton.solve(x_pred, S, t_new, h)
        if not out.converged:
            return out, None
        return out, self.asm.update_states(out.x, S, h)

    def run(self):
        x, S = self.initial()
        if self.adaptive:
            self._run_adaptive(x, S)
        else:
            self._run_fixed(x, S)

    # -- constant step ----------------------------------------------------------------------
    def _run_fixed(self, x, S):
        T, h0 = self.T, self.step
        n_grid = max(1, int(math.ceil(T / h0 - 1e-9)))
        t = 0.0
        k = 0           # index of the last grid point reached
        x_prev = None
        h_prev = None
        while t < T * (1 - 1e-14):
            grid_next = min((k + 1) * h0, T)
            if k + 1 >= n_grid:
                grid_next = T
            target = min(grid_next, self._next_break(t))
            h = target - t
            # try the whole step; on failure cut it (substeps are recorded too)
            while True:
                if x_prev is not None:
                    x_pred = x + (x - x_prev) * (h / h_prev)
                else:
                    x_pred = x
                out, S_new = self._attempt(x_pred, S, t + h, h)
                if S_new is not None:
                    break
                self.stats.rejected_steps += 1
                if h / 4 < self.step_min:
                    raise StepFailure(t + h, h, out)
                h /= 4
                x_prev = None
            t_new = t + h
            if abs(t_new - target) <= 1e-12 * max(1.0, target):
                t_new = target
            self.stats.steps += 1
            x_prev, h_prev = x, h
            x, S, t = out.x, S_new, t_new
            self.rec.add(t, x, S)
            if t == grid_next:
                k += 1
            if t in self._break_set:
                x_prev = None
                self.newton.invalidate()

    # -- adaptive step ----------------------------------------------------------------------
    def _run_adaptive(self, x, S):
        T = self.T
        h = self.step if self.step is not None else min(self.step_max, T * 1e-4)
        h_start = h
        t = 0.0
        x_prev = S_prev = None
        h_prev = None
        while t < T * (1 - 1e-14):
            nb = min(self._next_break(t), T)
            h = min(h, self.step_max)
            if t + h >= nb or nb - (t + h) < self.step_min:
                h = nb - t
            if x_prev is not None:
                r = h / h_prev
                x_pred = x + (x - x_prev) * r
                S_pred = S + (S - S_prev) * r
            else:
                x_pred, S_pred = x, None
            out, S_new = self._attempt(x_pred, S, t + h, h)
            if S_new is None:
                self.stats.rejected_steps += 1
                if h <= self.step_min:
                    raise StepFailure(t + h, h, out)
                h = max(h * 0.25, self.step_min)
                continue
            if S_pred is not None and S.size:
                scale = self.atol_s + self.rtol * np.maximum(np.abs(S_new), np.abs(S))
                err = float(np.sqrt(np.mean(((S_new - S_pred) * (h / (2 * h + h_prev)) / scale) ** 2)))
                if err > 1.0:
                    if h > self.step_min:
                        self.stats.rejected_steps += 1
                        self.stats.error_test_failures += 1
                        h = max(h * max(0.2, 0.9 / math.sqrt(err)), self.step_min)
                        continue
                    self.forced_steps += 1
                factor = min(5.0, max(0.2, 0.9 / math.sqrt(max(err, 1e-10))))
            else:
                factor = 2.0
            t_new = t + h
            if abs(t_new - nb) <= 1e-12 * max(1.0, nb):
                t_new = nb
            self.stats.steps += 1
            x_prev, S_prev, h_prev = x, S, h
            x, S, t = out.x, S_new, t_new
            self.rec.add(t, x, S)
            if t in self._break_set:
                x_prev = S_prev = None
                self.newton.invalidate()
                h = h_start
            else:
                h = h * factor
