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
        self._x_all, self._s_all = isinstance(x_index, int), isinstance(s_index, int)
        n = x_index if self._x_all else len(x_index)
        ns = s_index if self._s_all else len(s_index)
        self._X = np.empty((capacity, n))
        self._S = np.empty((capacity, ns))

    def add(self, t, x, s):
        k = len(self.t)
        if k == len(self._X):
            self._X = np.concatenate([self._X, np.empty_like(self._X)])
            self._S = np.concatenate([self._S, np.empty_like(self._S)])
        self._X[k] = x if self._x_all else x[self.x_index]
        self._S[k] = s if self._s_all else s[self.s_index]
        self.t.append(t)

    def arrays(self):
        k = len(self.t)
        return np.array(self.t, dtype=float), self._X[:k], self._S[:k]


class FixedStep:
    """Constant step h0 on a grid t_k = k·h0, landing on breakpoints in between.
    A failed Newton solve cuts the step by 4 (substeps are recorded too) until
    ``step_min``; the next step aims at the grid again. The stepping itself is
    written into :meth:`ImplicitEuler._run_fixed`; this holds its settings and
    the index of the last grid point reached."""

    def __init__(self, step, step_min, duration):
        self.h0, self.step_min, self.T = step, step_min, duration
        self.n_grid = max(1, int(math.ceil(duration / step - 1e-9)))
        self.k = 0            # index of the last grid point reached


#: Up to this many continuous states the step controller's error norm is
#: computed on Python lists instead of NumPy arrays.
SMALL_STATES = 32


class AdaptiveStep:
    """Step size from the local error estimate of the continuous states
    (see the module docstring): reject when the scaled RMS error exceeds 1,
    grow or shrink by 0.9/sqrt(err) within [0.2, 5]. A failed Newton solve
    cuts the step by 4 and holds it from growing for the next 5 steps (a
    snap-through otherwise provokes a failure at every regrowth). After a
    breakpoint or a mode switch the step restarts from its initial size."""

    uses_prediction = True

    def __init__(self, h_start, step_min, step_max, rtol, atol, continuous, stats):
        self.h = self.h_start = h_start
        self.step_min, self.step_max = step_min, step_max
        self.rtol, self.atol = rtol, atol
        self.idx = continuous
        self.stats = stats
        # up to SMALL_STATES continuous states the error norm runs on lists; a
        # slice when they are all the states, in order
        small = continuous.size <= SMALL_STATES
        every = bool(np.array_equal(continuous, np.arange(len(atol))))
        self._small = (slice(None) if every else continuous) if small else None
        self._atol_list = np.asarray(atol)[continuous].tolist()
        self.forced_steps = 0
        self._factor = 2.0
        self.hold = 0

    def propose(self, t, limit):
        """(step, exact end point it aims at)"""
        h = min(self.h, self.step_max)
        if t + h >= limit or limit - (t + h) < self.step_min:
            return limit - t, limit
        return h, t + h

    def failed(self, t, h, out):
        if h <= self.step_min:
            raise StepFailure(t + h, h, out)
        self.h = max(h * 0.25, self.step_min)
        self.hold = 5     # after a failed solve, do not grow the step for a few steps

    def judge(self, S, S_new, S_pred, h, h_prev):
        """(accept?, error); sets the next step size."""
        if S_pred is None or not self.idx.size:
            self._factor = 2.0
            return True, 0.0
        k = h / (2 * h + h_prev)
        if self._small is not None:
            # few states: the RMS on Python lists (1 us against 6 us, measured)
            i, rtol, acc = self._small, self.rtol, 0.0
            for a, b, c, at in zip(S[i].tolist(), S_new[i].tolist(), S_pred[i].tolist(),
                                   self._atol_list):
                e = (b - c) * k / (at + rtol * max(abs(b), abs(a)))
                acc += e * e
            err = math.sqrt(acc / len(self._atol_list))
        else:
            i = self.idx
            a, b, c = S[i], S_new[i], S_pred[i]
            scale = self.atol[i] + self.rtol * np.maximum(np.abs(b), np.abs(a))
            err = float(np.sqrt(np.mean(((b - c) * k / scale) ** 2)))
        if err > 1.0:
            if h > self.step_min:
                self.stats.rejected_steps += 1
                self.stats.error_test_failures += 1
                self.h = max(h * max(0.2, 0.9 / math.sqrt(err)), self.step_min)
                return False, err
            self.forced_steps += 1
        self._factor = min(5.0, max(0.2, 0.9 / math.sqrt(max(err, 1e-10))))
        return True, err

    def accepted(self, t_new, h, at_break):
        if self.hold:
            self.hold -= 1
            self._factor = min(self._factor, 1.0)
        self.h = self.h_start if at_break else h * self._factor


class ImplicitEuler:
    """Backward Euler driven by a step controller (:class:`FixedStep` or
    :class:`AdaptiveStep`). Newton starts from a linear extrapolation of the
    last two points; after a breakpoint, a mode switch of a discrete state or a
    failed solve it starts from the last point instead."""

    def __init__(self, asm, newton, stats, *, duration, step, adaptive, step_min, step_max,
                 rtol, atol_states, breakpoints=(), record=None):
        self.asm, self.newton, self.stats = asm, newton, stats
        self.T = duration
        breaks = sorted(b for b in set(breakpoints) if 0.0 < b < duration)
        if adaptive:
            h_start = step if step is not None else min(step_max, duration * 1e-4)
            atol = np.broadcast_to(np.asarray(atol_states, dtype=float), asm.S0.shape)
            self.ctrl = AdaptiveStep(h_start, step_min, step_max, rtol, atol,
                                     asm.s_continuous, stats)
        else:
            # a breakpoint on a grid point must be that grid point's float exactly,
            # or the step lands twice (0.3 vs 3*0.1) with a ~1e-17 s step between
            snapped = []
            for b in breaks:
                k = round(b / step)
                snapped.append(k * step if abs(b - k * step) <= 1e-9 * step else b)
            breaks = sorted(set(snapped))
            self.ctrl = FixedStep(step, step_min, duration)
        self.breaks = breaks
        self._break_set = set(breaks)
        n_expected = int(duration / step) + 2 + len(self.breaks) if step else 256
        # record: (unknown indices, state indices, labels) to keep, or None for all
        x_index, s_index = record[:2] if record is not None else (asm.n, len(asm.S0))
        self.rec = Recorder(x_index, s_index, capacity=min(max(n_expected, 16), 100_000))

    @property
    def forced_steps(self):
        return getattr(self.ctrl, "forced_steps", 0)

    def _next_break(self, t, ib):
        """(index, time) of the first breakpoint after t, searching from index ib
        (the loops keep a pointer into the sorted breakpoints)."""
        breaks = self.breaks
        while ib < len(breaks) and breaks[ib] <= t * (1 + 1e-14) + 1e-300:
            ib += 1
        return ib, (breaks[ib] if ib < len(breaks) else math.inf)

    def initial(self):
        """Consistent algebraic unknowns at t = 0 (dt = 0, states at their initial values)."""
        asm = self.asm
        out = self.newton.solve(asm.x0.copy(), asm.S0, 0.0, 0.0)
        if not out.converged:
            raise StepFailure(0.0, 0.0, out)
        self.newton.invalidate()
        self.rec.add(0.0, out.x, asm.S0.copy())
        return out.x, asm.S0.copy()

    def run(self):
        x, S = self.initial()
        if isinstance(self.ctrl, FixedStep):
            return self._run_fixed(x, S)
        # the adaptive loop, on local variables (see _run_fixed)
        asm, ctrl, T, stats, rec = self.asm, self.ctrl, self.T, self.stats, self.rec
        solve, update, rec_add = self.newton.solve, asm.update_states, rec.add
        propose, judge, accepted = ctrl.propose, ctrl.judge, ctrl.accepted
        begin = asm.begin_step if asm.has_begin_step else None
        if begin is not None:
            begin(x, S)
        disc = asm.s_discrete if asm.has_discrete else None
        predict_states = ctrl.uses_prediction
        break_set = self._break_set
        ib, next_break = 0, (self.breaks[0] if self.breaks else math.inf)
        t = 0.0
        t_stop = T * (1 - 1e-14)
        x_prev = S_prev = h_prev = None   # the previous point, for the predictors
        extrapolate = True
        while t < t_stop:
            if next_break <= t * (1 + 1e-14) + 1e-300:
                ib, next_break = self._next_break(t, ib)
            h, end = propose(t, next_break if next_break < T else T)
            if x_prev is not None:
                r = h / h_prev
                x_pred = x + (x - x_prev) * r if extrapolate else x
                S_pred = S + (S - S_prev) * r if predict_states else None
            else:
                x_pred, S_pred = x, None
            t_new = t + h
            # at a breakpoint the step sees the inputs' left limit
            at_break = t_new in break_set
            out = solve(x_pred, S, math.nextafter(t_new, -math.inf) if at_break else t_new, h)
            if not out.converged:
                stats.rejected_steps += 1
                ctrl.failed(t, h, out)
                extrapolate = False
                continue
            S_new = update(out.x, S, h)
            ok, _ = judge(S, S_new, S_pred, h, h_prev)
            if not ok:
                continue
            if t_new != end and abs(t_new - end) <= 1e-12 * max(1.0, end):
                t_new = end
                at_break = t_new in break_set
            stats.steps += 1
            if disc is not None and not at_break:
                at_break = bool((S_new[disc] != S[disc]).any())
            x_prev, S_prev, h_prev = x, S, h
            x, S, t = out.x, S_new, t_new
            rec_add(t, x, S)
            if begin is not None:
                begin(x, S)
            accepted(t, h, at_break)
            extrapolate = True
            if at_break:
                x_prev = S_prev = None
                self.newton.invalidate()

    def _run_fixed(self, x, S):
        """The loop of :meth:`run` for a :class:`FixedStep` controller: the grid,
        the breakpoints (a pointer into the sorted list) and the step cut after
        a failed solve written in, on local variables (on the paper's
        three-component scene the calls of a generic loop into the controller
        cost ~1.5 us of each step). Same steps and arithmetic as that loop."""
        asm, ctrl, stats, rec = self.asm, self.ctrl, self.stats, self.rec
        solve, update, T = self.newton.solve, asm.update_states, self.T
        begin = asm.begin_step if asm.has_begin_step else None
        if begin is not None:
            begin(x, S)
        disc = asm.s_discrete if asm.has_discrete else None
        h0, n_grid, step_min = ctrl.h0, ctrl.n_grid, ctrl.step_min
        break_set = self._break_set
        ib, next_break = 0, (self.breaks[0] if self.breaks else math.inf)
        rec_add = rec.add
        t, k, h_cut = 0.0, 0, None
        t_stop = T * (1 - 1e-14)
        x_prev = h_prev = None
        extrapolate = True
        while t < t_stop:
            if next_break <= t * (1 + 1e-14) + 1e-300:
                ib, next_break = self._next_break(t, ib)
            grid_next = T if k + 1 >= n_grid else min((k + 1) * h0, T)
            end = next_break if next_break < grid_next else grid_next
            h = end - t
            if h_cut is not None and h_cut < h:
                h = h_cut
                end = t + h
            if x_prev is None or not extrapolate:
                x_pred = x
            else:
                r = h / h_prev
                x_pred = x + (x - x_prev) if r == 1.0 else x + (x - x_prev) * r
            t_new = t + h
            # at a breakpoint the step sees the inputs' left limit
            at_break = t_new in break_set
            out = solve(x_pred, S, math.nextafter(t_new, -math.inf) if at_break else t_new, h)
            if not out.converged:
                stats.rejected_steps += 1
                if h / 4 < step_min:
                    ctrl.k = k
                    raise StepFailure(t + h, h, out)
                h_cut = h / 4
                extrapolate = False
                continue
            S_new = update(out.x, S, h)
            if t_new != end and abs(t_new - end) <= 1e-12 * max(1.0, end):
                t_new = end
                at_break = t_new in break_set
            stats.steps += 1
            if disc is not None and not at_break:
                at_break = bool((S_new[disc] != S[disc]).any())
            x_prev, h_prev = x, h
            x, S, t = out.x, S_new, t_new
            rec_add(t, x, S)
            if begin is not None:
                begin(x, S)
            h_cut = None
            if t == grid_next:
                k += 1
            extrapolate = True
            if at_break:
                x_prev = None
                self.newton.invalidate()
        ctrl.k = k
