"""Dense output: values between the steps from the integrator's own interpolant.

Every accepted step of the adaptive BDF ends with the difference table of the
polynomial it integrated on (:mod:`softflow.solve.bdf`): the backward
differences D_0..D_k at the step's end t_n, spacing h, order k, of the
polynomial through the new point and the (interpolated) earlier ones, in
Newton's backward form

    p(t) = D_0 + sum_{j=1..k} D_j phi_j(s),   s = (t - t_n) / h,
    phi_j(s) = s (s + 1) ... (s + j - 1) / j!

(the dense output of scipy's BDF and of MATLAB's ode15s). Between t_n - h and
t_n that polynomial is what the method knows of the solution: its values there
are as accurate as those at the steps. :class:`DenseRecorder` keeps, per step,
(t_n, h, k), the row of its end point among the recorded points (D_0: the
recorded values themselves, so that the interpolant passes through every
recorded step exactly) and D_1..D_k of the recorded columns (states, unknowns
and the run's quadratures of the unknowns, :meth:`Result.integral`); one copy
of k rows of the table per step.

Each step's polynomial serves only its own interval (t_n - h, t_n]: a
breakpoint, a mode switch or an actuator's fold jump ends a step, and the next
one starts from a table of its own, so no value is read across a
discontinuity. A step across which a law's kink lies (a check valve that
shuts inside it: ``kinks`` of its class) is read as the straight line between
its ends (D_0 and D_1 alone): its polynomial, smooth through the points
before the kink, overshoots it (a shut valve's flow read negative inside).
Where the solution is not smooth inside a step and nothing declares it (a
PV curve's knot), the polynomial is only as good as the step's end point
lets the error test judge it: measured on a hysteretic actuator filled at
a constant mass flow, 77 Pa off inside one step (the straight line: 24 Pa)
where both its ends are within 1 Pa.

At t_n itself the value is the step's end point (at a breakpoint: the
inputs' left limit, as recorded). Discrete states (a valve's mode) keep their
value at a step's start inside it (a switch takes effect at the step's end),
as in the points ``refine=`` records.

Backward Euler's own interpolant is the straight line between its two points
(its order 1 polynomial): :meth:`DenseOutput.linear_between` reads the
fixed-step runs' points so, the quadratures as the rectangle rule forms them.

:func:`refine_counts` chooses how many points a step's result records
(``Simulation(refine='auto')``): enough that the straight lines between them
stay within the run's tolerance of the step's polynomial.

Cost, measured (benchmarks/bench_dense_output.py): the record is k rows of
the recorded columns per step (the result's own point is one), 0.5-2 % of the
run time of the nine paper scenes; ``refine='auto'`` adds under 1 % there
and 1-9 % on runs of a few milliseconds (a fixed cost), and on a chain of
1 000 tubes and tanks with every column recorded (9 000) 7-15 % for the
record and as much again for the points (``record=`` a few components: 0.6
and 3 %).
"""
from __future__ import annotations

import math

import numpy as np

from .._laws import law_module
from .settings import (AUTO_REFINE_MAX, AUTO_REFINE_TARGET, EXPECT_GROWTH_MIN,
                       EXPECT_MARGIN)

#: where the polynomial's second derivative is sampled for refine='auto' (in
#: steps from the step's end): its ends and middle (p'' is of degree k - 2)
_SAMPLES = np.array([0.0, -0.5, -1.0])


def _second_derivatives(k):
    """(3, k - 1): phi_j''(s) at the samples s of :data:`_SAMPLES`, j = 2..k
    (phi_1'' is 0), C-contiguous (refine_counts' compiled pass)."""
    out = np.zeros((_SAMPLES.size, max(k - 1, 0)))
    for j in range(2, k + 1):
        # phi_j as a polynomial in s: prod_{m<j} (s + m) / j!
        poly = np.poly1d([1.0])
        for m in range(j):
            poly = poly * np.poly1d([1.0, float(m)])
        poly = poly / math.factorial(j)
        out[:, j - 2] = poly.deriv(2)(_SAMPLES)
    return out


#: phi_2''..phi_k'' at the samples, for each order k
_D2 = [None] + [_second_derivatives(k) for k in range(1, 7)]


def expected_rows(done, t, T):
    """The rows a run's records are expected to hold at its end T, at the
    pace of the ``done`` rows by time t (EXPECT_MARGIN more); None before
    the first step or at the end."""
    return EXPECT_MARGIN * done * T / t if 0.0 < t < T else None


def grown_rows(current, needed, expect=None):
    """The rows records of ``current`` rows grow to where ``needed`` exceed
    them: doubled (as often as needed), or ``expect`` rows
    (:func:`expected_rows`) where that is less, but EXPECT_GROWTH_MIN times
    the current rows at least and never fewer than needed."""
    size = 2 * current
    while size < needed:
        size *= 2
    if expect is not None:
        size = min(size, max(int(expect), int(EXPECT_GROWTH_MIN * current)))
    return max(size, needed)


class DenseRecorder:
    """Per accepted step: its end time, step, order, the row of its end point
    among the recorded points, and D_1..D_k of its difference table over the
    recorded columns (module docstring). The differences are kept in one array
    that grows by doubling, or to the rows expected (as
    :class:`softflow.solve.integrator.Recorder`).

    ``cols``: the columns of the difference table to keep (an index array), or
    None for its first ``width`` columns."""

    def __init__(self, cols, width, capacity=1024):
        self.cols = None if cols is None else np.asarray(cols, dtype=np.int64)
        self.width = width
        self.t, self.h, self.k, self.row = [], [], [], []
        # rows of differences (k a step): at most ~8 MB to begin with
        self._D = np.empty((max(16, min(capacity, 1_000_000 // max(width, 1))), width))
        self._n = 0

    def point(self, t, row):
        """A point of its own (t = 0, the far side of a fold jump): order 0."""
        self.t.append(t)
        self.h.append(0.0)
        self.k.append(0)
        self.row.append(row)

    def step(self, t, h, k, row, D):
        """The step ending at t (spacing h, order k), whose end point is row
        ``row`` of the recorded points, with difference table D."""
        n = self._n
        end = n + k
        if end > len(self._D):
            self._D = np.concatenate([self._D[:n], np.empty((max(len(self._D), k), self.width))])
        if self.cols is None:
            self._D[n:end] = D[1:k + 1, :self.width]
        else:
            np.take(D[1:k + 1], self.cols, axis=1, out=self._D[n:end])
        self._n = end
        self.t.append(t)
        self.h.append(h)
        self.k.append(k)
        self.row.append(row)

    @property
    def rows(self):
        """The difference rows recorded so far."""
        return self._n

    def extend(self, t, h, k, row, diffs, expect=None):
        """Steps at once (the compiled loop's): their end times, steps,
        orders, rows, and their differences one after the other.
        ``expect``: the rows expected in all (:func:`grown_rows`)."""
        n = self._n
        end = n + len(diffs)
        if end > len(self._D):
            grown = np.empty((grown_rows(len(self._D), end, expect), self.width))
            grown[:n] = self._D[:n]
            self._D = grown
        self._D[n:end] = diffs
        self._n = end
        self.t.extend(t.tolist())
        self.h.extend(h.tolist())
        self.k.extend(k.tolist())
        self.row.extend(row.tolist())

    @property
    def nbytes(self):
        """Memory the differences take [bytes] (allocated)."""
        return self._D.nbytes

    def output(self, X, S, Q, discrete):
        """The :class:`DenseOutput` of the entries recorded, on the recorded
        points X, S, Q (rows as :meth:`step` was told)."""
        n = self._n
        # the rows used, without a copy where they fill most of what was taken
        diffs = self._D[:n] if 2 * n >= len(self._D) else self._D[:n].copy()
        return DenseOutput(np.array(self.t, dtype=float), np.array(self.h, dtype=float),
                           np.array(self.k, dtype=np.int64), np.array(self.row, dtype=np.int64),
                           diffs, X, S, Q, discrete)


class DenseOutput:
    """The integrator's interpolant over a run (module docstring): per entry
    (a step, or a point of its own) its end time ``t_end``, step ``h``, order
    ``k`` (0: a point), the row ``row`` of its end point in X, S, Q and its
    backward differences D_1..D_k (rows ``off``.. of ``diffs``; columns the
    recorded states, then unknowns, then quadratures); ``linear``: backward
    Euler's straight line from the point before instead. ``discrete``: a mask
    of the columns of S that are discrete states (or None)."""

    def __init__(self, t_end, h, k, row, diffs, X, S, Q, discrete, linear=False):
        self.t_end, self.h, self.k, self.row = t_end, h, k, row
        # each entry's first row in diffs: the orders before it, summed
        off = self.off = np.zeros(max(k.size, 1), dtype=np.int64)
        np.cumsum(k[:-1], out=off[1:])
        self.diffs = diffs
        self.X, self.S, self._Q = X, S, Q
        self.discrete = (np.empty(0, dtype=np.int64) if discrete is None
                         else np.flatnonzero(discrete))
        self.linear = linear

    #: the quadratures are backward Euler's rectangle rule over the points,
    #: formed on first use (:meth:`linear_between`)
    _rectangle = False

    @classmethod
    def linear_between(cls, times, X, S, discrete):
        """Backward Euler's interpolant: the straight line between each point and
        the one before (its order 1 polynomial), the quadratures the rectangle
        rule's (each step's end value times the step, :meth:`Result.integral`),
        formed on first use."""
        n = len(times)
        times = np.asarray(times, dtype=float)
        h = np.zeros(n)
        h[1:] = np.diff(times)
        k = np.ones(n, dtype=np.int64)
        k[:1] = 0
        out = cls(times, h, k, np.arange(n), None, X, S, None, discrete, linear=True)
        out._rectangle = True
        return out

    @property
    def Q(self):
        """The recorded unknowns' time integrals at the points, or None."""
        if self._Q is None and self._rectangle:
            X = self.X
            self._Q = np.zeros_like(X)
            if len(X) > 1:
                np.cumsum(self.h[1:, None] * X[1:], axis=0, out=self._Q[1:])
        return self._Q

    @property
    def end(self):
        """The last time the interpolant covers [s]."""
        return float(self.t_end[-1])

    @property
    def nbytes(self):
        """Memory of its own (the differences and the per-entry arrays) [bytes];
        the points X, S, Q are the run's."""
        own = self.t_end.nbytes + self.h.nbytes + self.k.nbytes + self.row.nbytes
        diffs = self.diffs
        if diffs is not None and diffs.base is not None:     # a view of a larger buffer
            diffs = diffs.base
        return own + self.off.nbytes + (0 if diffs is None else diffs.nbytes)

    def _copy(self, **changes):
        out = object.__new__(DenseOutput)
        out.__dict__.update(self.__dict__)
        out.__dict__.update(changes)
        return out

    def until(self, t):
        """The interpolant of the entries that end up to time t (a run cut there)."""
        n = int(np.searchsorted(self.t_end, t, side="right"))
        return self._copy(t_end=self.t_end[:n], h=self.h[:n], k=self.k[:n],
                          row=self.row[:n], off=self.off[:n])

    def compact(self):
        """The same interpolant holding only its entries' own points (a result
        recorded at requested times keeps no other rows of the run)."""
        r = self.row
        if r.size == len(self.X):
            return self
        Q = self.Q
        return self._copy(row=np.arange(r.size), X=self.X[r], S=self.S[r],
                          _Q=None if Q is None else Q[r], _rectangle=False)

    def shifted(self, shift, X, S, Q):
        """The same interpolant on points with rows inserted: entry i's end point
        now at row + shift[i] of X, S, Q (:func:`insert_interior`)."""
        return self._copy(row=self.row + shift, X=X, S=S, _Q=Q)

    def entries(self, tau):
        """The entry whose step covers each time of ``tau``: the first ending at
        or after it (a time on a step's end is that step's end point)."""
        i = np.searchsorted(self.t_end, tau, side="left")
        return np.minimum(i, self.t_end.size - 1)

    def values(self, tau, cols=None, chunk=None):
        """(X, S, Q) at the times ``tau`` (1-D, each within [0, end]): rows of the
        recorded unknowns, states and quadratures (Q None where the run kept
        none); ``cols``: (state columns, unknown columns, quadrature columns),
        index arrays into S, X, Q, to evaluate those alone (None: all)."""
        tau = np.asarray(tau, dtype=float)
        width = (2 * self.X.shape[1] + self.S.shape[1] if cols is None
                 else sum(len(c) for c in cols))
        chunk = chunk or max(1, 2_000_000 // max(width, 1))
        if tau.size > chunk:
            parts = [self.values(tau[a:a + chunk], cols, chunk)
                     for a in range(0, tau.size, chunk)]
            return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                    None if parts[0][2] is None else np.concatenate([p[2] for p in parts]))
        return self.on(self.entries(tau), tau, cols)

    def on(self, i, tau, cols=None):
        """(X, S, Q) at the times tau[m], each on the polynomial of entry i[m]
        (``cols`` as :meth:`values`)."""
        k, t_end, h = self.k[i], self.t_end[i], self.h[i]
        with np.errstate(all="ignore"):
            s = np.where(k > 0, (tau - t_end) / np.where(h > 0.0, h, 1.0), 0.0)
        s = np.clip(s, -1.0, 0.0)
        r = self.row[i]
        Qall = self.Q
        nS, nX = self.S.shape[1], self.X.shape[1]
        if cols is None:
            cS, cX, cQ = slice(None), slice(None), slice(None)
            dcols = slice(None)
            disc = self.discrete
        else:
            cS, cX, cQ = (np.asarray(c, dtype=np.int64) for c in cols)
            if Qall is None:
                cQ = np.empty(0, dtype=np.int64)
            dcols = np.concatenate([cS, nS + cX, nS + nX + cQ])
            disc = np.flatnonzero(np.isin(cS, self.discrete))     # positions among cS
        X, S = self.X[r][:, cX], self.S[r][:, cS]
        Q = None if Qall is None else Qall[r][:, cQ]
        kmax = int(k.max(initial=0))
        if kmax:
            if self.linear:          # D_1: the step's end point minus its start
                prev = np.maximum(r - 1, 0)
                c = s[:, None]
                X += c * (self.X[r][:, cX] - self.X[prev][:, cX])
                S += c * (self.S[r][:, cS] - self.S[prev][:, cS])
                if Q is not None:
                    Q += c * (Qall[r][:, cQ] - Qall[prev][:, cQ])
            else:
                # phi_1..phi_kmax at s, zero above each entry's own order
                j = np.arange(1, kmax + 1)
                C = np.cumprod((s[:, None] + (j - 1)) / j, axis=1)
                C[j[None, :] > k[:, None]] = 0.0
                rows = np.minimum(self.off[i][:, None] + (j - 1),
                                  max(len(self.diffs) - 1, 0))
                # sum_j C_j D_j term by term, elementwise, in one compiled
                # pass: every column the same arithmetic whichever columns
                # are asked for (Result.at's one column equals the same
                # column of Result.interpolate)
                diffs = self.diffs
                picked = (np.empty(0, dtype=np.int64) if cols is None
                          else np.asarray(dcols, dtype=np.int64))
                d = np.empty((C.shape[0], diffs.shape[1] if cols is None else picked.size))
                law_module("output").dense_terms(np.ascontiguousarray(C),
                                                 np.ascontiguousarray(rows, dtype=np.int64),
                                                 diffs, picked, d)
                mS, mX = S.shape[1], X.shape[1]
                S += d[:, :mS]
                X += d[:, mS:mS + mX]
                if Q is not None:
                    Q += d[:, mS + mX:]
        if disc.size:
            # inside a step a discrete state holds its value at the step's start:
            # the end point of the entry before
            inside = np.flatnonzero((k > 0) & (s > -1.0) & (s < 0.0))
            if inside.size:
                start = self.row[i[inside] - 1]
                source = disc if cols is None else cS[disc]       # columns of self.S
                S[np.ix_(inside, disc)] = self.S[np.ix_(start, source)]
        return X, S, Q


def refine_counts(dense, weights, most=AUTO_REFINE_MAX, target=AUTO_REFINE_TARGET):
    """Points per entry of ``dense`` for ``refine='auto'``: the least r (1 to
    ``most``) for which straight lines between r + 1 points evenly spaced over
    the step stay within ``target`` of its polynomial in the weighted max norm
    (``weights``: one per column of the recorded states, then unknowns; inf
    leaves a column out). A line's error over a piece of 1/r of the step is at
    most (1/r)^2 / 8 max |p''| (p in steps), p'' = sum_{j=2..k} D_j phi_j''
    of degree k - 2, sampled at the step's ends and middle. A step of order 1
    is a line already: r = 1."""
    k = dense.k
    r = np.ones(k.size, dtype=np.int64)
    kmax = int(k.max(initial=0))
    if dense.linear or kmax < 2:
        return r
    with np.errstate(divide="ignore"):
        inv = 1.0 / np.asarray(weights, dtype=float)
    law_module("output").refine_counts(
        np.ascontiguousarray(k, dtype=np.int64), np.ascontiguousarray(dense.off, dtype=np.int64),
        np.ascontiguousarray(dense.diffs), int(weights.size), np.ascontiguousarray(inv),
        _D2[kmax], int(most), float(target), r)
    return r


def _contiguous(a):
    """``a`` as a C-contiguous float array (itself where it is one)."""
    return np.ascontiguousarray(a, dtype=float)


def insert_interior(dense, counts, t, X, S, Q, in_place=False):
    """The points t, X, S, Q (Q may be None) with counts[i] - 1 points inserted
    evenly inside each step of ``dense`` before its end point, on that step's
    polynomial (discrete states at the step's start), and ``dense`` on the new
    rows: (t, X, S, Q, dense). ``in_place``: X, S and Q are the first rows
    of arrays whose further rows are free (a run's records, grown ahead of
    their points): where those have room for the new rows, the points go
    into them (the rows below moved up), without a second copy of the
    records (a 2 000-component water network's 360 MB); else into new
    arrays."""
    counts = np.asarray(counts, dtype=np.int64)
    extra = np.where(dense.k > 0, np.maximum(counts - 1, 0), 0)
    total = int(extra.sum())
    if not total:
        return t, X, S, Q, dense
    rows = len(t) + total
    t_new = np.empty(rows)
    ints = [np.ascontiguousarray(a, dtype=np.int64)
            for a in (dense.k, dense.row, dense.off, dense.discrete, extra, counts)]
    head = (_contiguous(dense.t_end), _contiguous(dense.h), *ints[:3], _contiguous(dense.diffs),
            bool(dense.linear), *ints[3:], _contiguous(t))
    room = [_room(a, rows) if in_place else None for a in (X, S, Q)]
    if all(r is not None for r in room[:2]) and (Q is None or room[2] is not None):
        # the records' own arrays have the rows: the points go in there
        X_new, S_new = room[0], room[1]
        Q_new = room[2] if Q is not None else np.empty((rows, 0))
        law_module("output").interior_in_place(*head, X_new, S_new, Q_new, t_new)
    else:
        Q_new = np.empty((rows, 0 if Q is None else Q.shape[1]))
        X_new, S_new = np.empty((rows, X.shape[1])), np.empty((rows, S.shape[1]))
        law_module("output").interior(
            *head, _contiguous(X), _contiguous(S),
            np.empty((len(t), 0)) if Q is None else _contiguous(Q), t_new, X_new, S_new, Q_new)
    t, X, S, Q = t_new, X_new, S_new, (None if Q is None else Q_new)
    return t, X, S, Q, dense.shifted(np.cumsum(extra), X, S, Q)


def _room(a, rows):
    """The first ``rows`` rows of the array that ``a`` leads (a run's records:
    a view of their first rows, allocated with room to grow), where it has
    them and ``a`` starts it, C-contiguous, float; else None."""
    base = a.base if a is not None else None
    if (not isinstance(base, np.ndarray) or base.ndim != 2 or base.dtype != np.float64
            or not base.flags.c_contiguous or not base.flags.writeable
            or base.shape[1] != a.shape[1] or base.shape[0] < rows
            or not a.flags.c_contiguous
            or a.__array_interface__["data"][0] != base.__array_interface__["data"][0]):
        return None
    return base[:rows]


def check_times(values, end, *, owner, name, round_off=1e-9):
    """``values`` (seconds or a pint Quantity of time) as a float array of times:
    1-D, at least one, finite, sorted (non-decreasing) and within [0, end]
    (within ``round_off`` of ``end``, relative, and then taken as ``end``).
    Errors name ``owner``, ``name`` and the offending value."""
    from ..units import to_si
    if isinstance(values, (str, bytes)) or values is None:
        raise TypeError(f"{owner}: {name} must be a 1-D sequence of times [s], got {values!r}")
    t = to_si(values, "s", name=name, owner=owner)
    t = np.asarray(t, dtype=float)
    if t.ndim != 1:
        raise ValueError(f"{owner}: {name} must be a 1-D sequence of times [s], got "
                         + (f"the single number {float(t):.6g} (give [{float(t):.6g}])"
                            if t.ndim == 0 else f"an array of shape {t.shape}"))
    if not t.size:
        raise ValueError(f"{owner}: {name} is empty; give at least one time [s]")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{owner}: {name} must be finite; {name}[{i}] = {t[i]}")
    tol = round_off * end
    out = np.flatnonzero((t < -tol) | (t > end + tol))
    if out.size:
        i = int(out[0])
        raise ValueError(f"{owner}: {name} must lie within [0, {end:.6g}] s; "
                         f"{name}[{i}] = {t[i]:.6g} s")
    down = np.flatnonzero(np.diff(t) < 0)
    if down.size:
        i = int(down[0]) + 1
        raise ValueError(f"{owner}: {name} must be sorted (non-decreasing); {name}[{i}] = "
                         f"{t[i]:.6g} s comes after {name}[{i - 1}] = {t[i - 1]:.6g} s")
    return np.clip(t, 0.0, end)
