"""C1 (in fact C2) interpolation on uniform grids, stored as per-cell Hermite polynomials.

A property f(x, y) sampled on a uniform grid is interpolated by the tensor-product
cubic spline through the samples (not-a-knot ends). Inside each cell that spline
is the bicubic Hermite polynomial fixed by f, f_x, f_y and f_xy at the cell's four
corners; since neighbouring cells share those corner values, value and first
derivatives are continuous across cell borders, which Newton's method needs.

The per-cell polynomial is stored as 16 power-basis coefficients in local
coordinates t, u in [0, 1], contiguous per cell, so that an evaluation is a cell
index (no search: the grid is uniform), one gather and a few multiply-adds. That
evaluation is compiled, one point at a time (:mod:`softflow.laws.tables`, which
compiled component code can call too); the classes here build the coefficients
and apply it to scalars and arrays.
"""
from __future__ import annotations

import functools

import numpy as np

from .._laws import law_module

# Maps [f(0), f(1), h f'(0), h f'(1)] to power coefficients [c0, c1, c2, c3] of a cubic
# on [0, 1] (the cubic Hermite basis).
_HERMITE = np.array([[1.0, 0.0, 0.0, 0.0],
                     [0.0, 0.0, 1.0, 0.0],
                     [-3.0, 3.0, -2.0, -1.0],
                     [2.0, -2.0, 1.0, 1.0]])


compiled = functools.partial(law_module, "tables")


class UniformAxis:
    """A uniform grid axis: ``n`` nodes from ``lo`` to ``hi``."""

    def __init__(self, lo: float, hi: float, n: int):
        if not (hi > lo and n >= 4):
            raise ValueError(f"uniform axis needs hi > lo and at least 4 nodes, got "
                             f"lo={lo}, hi={hi}, n={n}")
        self.lo, self.hi, self.n = float(lo), float(hi), int(n)
        self.step = (self.hi - self.lo) / (self.n - 1)
        self.nodes = np.linspace(self.lo, self.hi, self.n)

    def locate(self, x):
        """Cell index and local coordinate of each x: t in [0, 1] inside the
        axis, below 0 or above 1 in the end cells past its ends (the
        compiled :func:`softflow.laws.tables.cell`)."""
        shape, xs = _points(x)
        i, t = np.empty(xs.size, dtype=np.intp), np.empty(xs.size)
        compiled().cell_array(self.lo, self.step, self.n, xs, i, t)
        return i.reshape(shape), t.reshape(shape)


def _spline_slopes(values, nodes, axis):
    from scipy.interpolate import CubicSpline    # lazy: only the table level builds these
    return CubicSpline(nodes, values, axis=axis, bc_type="not-a-knot")(nodes, 1)


class Bicubic:
    """Tensor-product cubic spline of ``values`` (shape (x.n, y.n)) on two uniform axes."""

    def __init__(self, x: UniformAxis, y: UniformAxis, values):
        values = np.asarray(values, dtype=float)
        if values.shape != (x.n, y.n):
            raise ValueError(f"values have shape {values.shape}, grid is {(x.n, y.n)}")
        self.x, self.y = x, y
        fx = _spline_slopes(values, x.nodes, 0) * x.step
        fy = _spline_slopes(values, y.nodes, 1) * y.step
        fxy = _spline_slopes(fx, y.nodes, 1) * y.step
        # corner matrix G per cell in Hermite order: rows (f(x0), f(x1), h f_x(x0), h f_x(x1)),
        # columns likewise in y; the (x-derivative?, y-derivative?) blocks come from
        # values, fx, fy and fxy
        nx, ny = x.n - 1, y.n - 1
        G = np.empty((nx, ny, 4, 4))
        for (dx, dy), arr in (((0, 0), values), ((1, 0), fx), ((0, 1), fy), ((1, 1), fxy)):
            for ax in (0, 1):
                for ay in (0, 1):
                    G[:, :, 2 * dx + ax, 2 * dy + ay] = arr[ax:ax + nx, ay:ay + ny]
        A = np.einsum("ik,xykl,jl->xyij", _HERMITE, G, _HERMITE)
        #: coefficients (x cells, y cells, 16), each cell's contiguous: entry 4 i + j
        #: multiplies t^i u^j (the layout :mod:`softflow.laws.tables` reads)
        self.cells = np.ascontiguousarray(A.reshape(nx, ny, 16))

    @property
    def coef(self):
        """The coefficients as (16, n_cells), cell k = i * (y cells) + j (a view)."""
        return self.cells.reshape(-1, 16).T

    def __call__(self, xq, yq, *, grad=False):
        """Value at (xq, yq) (scalars, or arrays that broadcast); with ``grad``
        also d/dx and d/dy. Scalars give NumPy floats, arrays arrays of the
        broadcast shape (float64; no points: empty parts)."""
        law, X, Y = compiled(), self.x, self.y
        if _scalar(xq) and _scalar(yq):
            if grad:
                f, fx, fy = law.bicubic_grad(self.cells, X.lo, X.step, Y.lo, Y.step,
                                             float(xq), float(yq))
                return np.float64(f), np.float64(fx), np.float64(fy)
            return np.float64(law.bicubic(self.cells, X.lo, X.step, Y.lo, Y.step,
                                          float(xq), float(yq)))
        shape, xs, ys = _points(xq, yq)
        f = np.empty(xs.size)
        if not grad:
            law.bicubic_array(self.cells, X.lo, X.step, Y.lo, Y.step, xs, ys, f)
            return f.reshape(shape)
        fx, fy = np.empty(xs.size), np.empty(xs.size)
        law.bicubic_grad_array(self.cells, X.lo, X.step, Y.lo, Y.step, xs, ys, f, fx, fy)
        return f.reshape(shape), fx.reshape(shape), fy.reshape(shape)

    def slice_at_y(self, y0: float) -> "Cubic":
        """The interpolant restricted to y = y0: a piecewise cubic in x (same values)."""
        j, u = compiled().cell(float(y0), self.y.lo, self.y.step, self.y.n)
        c = self.cells[:, j, :].reshape(-1, 4, 4)           # (cell, power of t, power of u)
        w = np.float64(u) ** np.arange(4)
        # the coefficient of t^i: sum_k c_ik u^k, summed in the order k = 0, 1, 2, 3
        return Cubic(self.x, (c[:, :, 0] * w[0] + c[:, :, 1] * w[1] + c[:, :, 2] * w[2]
                              + c[:, :, 3] * w[3]).T)


class Cubic:
    """Piecewise cubic on a uniform axis with coefficients (4, n_cells) in local t."""

    def __init__(self, x: UniformAxis, coef):
        self.x = x
        #: coefficients (cells, 4), each cell's contiguous: entry i multiplies t^i
        self.cells = np.ascontiguousarray(np.asarray(coef, dtype=float).T)

    @property
    def coef(self):
        """The coefficients as (4, n_cells) (a view)."""
        return self.cells.T

    def __call__(self, xq, *, grad=False):
        """Value at xq (as :meth:`Bicubic.__call__`); with ``grad`` also d/dx."""
        law, X = compiled(), self.x
        if _scalar(xq):
            if grad:
                f, fx = law.cubic_grad(self.cells, X.lo, X.step, float(xq))
                return np.float64(f), np.float64(fx)
            return np.float64(law.cubic(self.cells, X.lo, X.step, float(xq)))
        shape, xs = _points(xq)
        f = np.empty(xs.size)
        if not grad:
            law.cubic_array(self.cells, X.lo, X.step, xs, f)
            return f.reshape(shape)
        fx = np.empty(xs.size)
        law.cubic_grad_array(self.cells, X.lo, X.step, xs, f, fx)
        return f.reshape(shape), fx.reshape(shape)


def _scalar(v):
    """Whether ``v`` is one number (a Python or NumPy scalar, or a 0-d array)."""
    kind = type(v)
    if kind is float or kind is np.float64:
        return True
    return v.ndim == 0 if kind is np.ndarray else np.ndim(v) == 0


def _points(x, y=None):
    """The broadcast shape of the queries x (and y) and each as a 1-D
    C-contiguous float64 array of that many points (a view where it can be):
    one type signature for the compiled loops. (Written out for one and two
    queries: a few-point call pays its overhead, comparable to the loop's.)"""
    x = np.asarray(x, dtype=np.float64)
    shape = x.shape
    if y is None:
        return shape, x.ravel()
    y = np.asarray(y, dtype=np.float64)
    if y.shape != shape:
        # (only the smaller is broadcast: a read-only view of a full-shape
        # query would be another type to compile for)
        shape = np.broadcast_shapes(shape, y.shape)
        if x.shape != shape:
            x = np.broadcast_to(x, shape)
        if y.shape != shape:
            y = np.broadcast_to(y, shape)
    return shape, x.ravel(), y.ravel()
