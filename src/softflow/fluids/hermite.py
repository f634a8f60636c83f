"""C1 (in fact C2) interpolation on uniform grids, stored as per-cell Hermite polynomials.

A property f(x, y) sampled on a uniform grid is interpolated by the tensor-product
cubic spline through the samples (not-a-knot ends). Inside each cell that spline
is the bicubic Hermite polynomial fixed by f, f_x, f_y and f_xy at the cell's four
corners; since neighbouring cells share those corner values, value and first
derivatives are continuous across cell borders, which Newton's method needs.

The per-cell polynomial is stored as 16 power-basis coefficients in local
coordinates t, u in [0, 1], so an evaluation is one gather plus a few multiply-adds
on NumPy vectors: no search (the grid is uniform) and no Python loop.
"""
from __future__ import annotations

import math

import numpy as np

#: Up to this many points an interpolant is evaluated point by point on Python
#: floats (the same operations in the same order, so the same numbers): on a
#: few points each NumPy operation costs ~1 us, and a bicubic value with its
#: gradient is ~40 of them (a thermal scene's residual asks for a dozen such).
FEW_POINTS = 4

# Maps [f(0), f(1), h f'(0), h f'(1)] to power coefficients [c0, c1, c2, c3] of a cubic
# on [0, 1] (the cubic Hermite basis).
_HERMITE = np.array([[1.0, 0.0, 0.0, 0.0],
                     [0.0, 0.0, 1.0, 0.0],
                     [-3.0, 3.0, -2.0, -1.0],
                     [2.0, -2.0, 1.0, 1.0]])


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
        """Cell index and local coordinate in [0, 1] of each x (x assumed in range)."""
        s = (x - self.lo) * (1.0 / self.step)
        i = np.minimum(np.maximum(np.floor(s), 0.0), self.n - 2).astype(np.intp)
        return i, s - i


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
        #: coefficients (16, n_cells): row 4 i + j multiplies t^i u^j
        self.coef = np.ascontiguousarray(A.reshape(-1, 16).T)
        self._ny_cells = y.n - 1

    def __call__(self, xq, yq, *, grad=False):
        """Value at (xq, yq) (arrays of one shape); with ``grad`` also d/dx and d/dy."""
        # no points at all go to the array path too: it keeps the query's
        # (empty) shape and, with grad, gives all three (empty) parts
        if 0 < np.size(xq) <= FEW_POINTS and np.shape(xq) == np.shape(yq) and \
                _as_float64(xq) and _as_float64(yq):
            few = self._few(xq, yq, grad)
            if few is not None:
                return few
        i, t = self.x.locate(xq)
        j, u = self.y.locate(yq)
        c = np.take(self.coef, i * self._ny_cells + j, axis=1)   # ~4x faster than c[:, k]
        return _bicubic(c, t, u, grad, self.x.step, self.y.step)

    def _few(self, xq, yq, grad):
        """:meth:`__call__` point by point on floats, or None where a point is
        not finite (the array path then decides what it gives)."""
        X, Y = self.x, self.y
        coef, ny = self.coef, self._ny_cells
        values = []
        for xv, yv in zip(np.ravel(xq).tolist(), np.ravel(yq).tolist()):
            i, t = _locate(X, xv)
            j, u = _locate(Y, yv)
            if i is None or j is None:
                return None
            values.append(_bicubic(coef[:, i * ny + j].tolist(), t, u, grad, X.step, Y.step))
        return _shaped_all(values, np.shape(xq), grad)

    def slice_at_y(self, y0: float) -> "Cubic":
        """The interpolant restricted to y = y0: a piecewise cubic in x (same values)."""
        j, u = self.y.locate(np.float64(y0))
        c = self.coef.reshape(4, 4, self.x.n - 1, self._ny_cells)[:, :, :, int(j)]
        powers = u ** np.arange(4)
        return Cubic(self.x, np.einsum("ijc,j->ic", c, powers))


class Cubic:
    """Piecewise cubic on a uniform axis with coefficients (4, n_cells) in local t."""

    def __init__(self, x: UniformAxis, coef):
        self.x = x
        self.coef = np.ascontiguousarray(coef)

    def __call__(self, xq, *, grad=False):
        if 0 < np.size(xq) <= FEW_POINTS and _as_float64(xq):     # (as Bicubic's)
            few = self._few(xq, grad)
            if few is not None:
                return few
        i, t = self.x.locate(xq)
        return _cubic(np.take(self.coef, i, axis=1), t, grad, self.x.step)

    def _few(self, xq, grad):
        """:meth:`__call__` point by point on floats (as :meth:`Bicubic._few`)."""
        X, coef = self.x, self.coef
        values = []
        for xv in np.ravel(xq).tolist():
            i, t = _locate(X, xv)
            if i is None:
                return None
            values.append(_cubic(coef[:, i].tolist(), t, grad, X.step))
        return _shaped_all(values, np.shape(xq), grad)


def _bicubic(c, t, u, grad, sx, sy):
    """A cell's bicubic at local coordinates (t, u) by Horner's scheme, from
    its 16 power coefficients ``c`` (row 4 i + j multiplies t^i u^j: rows of
    arrays, or floats: the same operations either way); with ``grad`` also
    d/dx and d/dy (sx, sy: the cells' sizes)."""
    # r_i(u) = sum_j A_ij u^j for each power i of t
    r = [((c[4 * k + 3] * u + c[4 * k + 2]) * u + c[4 * k + 1]) * u + c[4 * k]
         for k in range(4)]
    f = ((r[3] * t + r[2]) * t + r[1]) * t + r[0]
    if not grad:
        return f
    ft = (3.0 * r[3] * t + 2.0 * r[2]) * t + r[1]
    dr = [(3.0 * c[4 * k + 3] * u + 2.0 * c[4 * k + 2]) * u + c[4 * k + 1] for k in range(4)]
    fu = ((dr[3] * t + dr[2]) * t + dr[1]) * t + dr[0]
    return f, ft / sx, fu / sy


def _cubic(c, t, grad, sx):
    """A cell's cubic at local coordinate t from its 4 power coefficients
    (as :func:`_bicubic`); with ``grad`` also d/dx."""
    f = ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
    if not grad:
        return f
    return f, ((3.0 * c[3] * t + 2.0 * c[2]) * t + c[1]) / sx


def _as_float64(v):
    """Whether the array path computes ``v`` in float64 (as the float path
    does): Python numbers, float64, integer and boolean arrays; not float32."""
    dt = getattr(v, "dtype", None)
    return dt is None or dt == np.float64 or dt.kind in "iub"


def _locate(axis, v):
    """:meth:`UniformAxis.locate` of one float: (cell, local coordinate), or
    (None, None) where v is not finite."""
    s = (v - axis.lo) * (1.0 / axis.step)
    if not math.isfinite(s):
        return None, None
    i = min(max(math.floor(s), 0), axis.n - 2)
    return i, s - i


def _shaped(values, shape):
    """Floats as the array path returns them: a NumPy scalar for a 0-d query."""
    if not shape:
        return np.float64(values[0])
    return np.array(values).reshape(shape)


def _shaped_all(values, shape, grad):
    """The points' values (or, with ``grad``, their tuples) as the array path
    returns them (:func:`_shaped`)."""
    if not grad:
        return _shaped(values, shape)
    return tuple(_shaped(part, shape) for part in zip(*values))
