"""The table level's interpolants evaluated at one point, compiled.

A tabulated property is stored per cell of a uniform grid as the power
coefficients of its Hermite polynomial in the cell's local coordinates
(built, and explained, in :mod:`softflow.fluids.hermite`):

* ``cells[i, j, 4 a + b]`` multiplies t^a u^b in cell (i, j) of a 2-D table
  (shape (nx - 1, ny - 1, 16)), t and u in [0, 1] across the cell;
* ``cells[i, a]`` multiplies t^a in cell i of a 1-D one (shape (n - 1, 4)).

An axis is given by its first node and its node spacing; its node count is
the cell count of the coefficient array plus one, so that the lookup cannot
index past the array. A point outside an axis is evaluated in the end cell's
polynomial (extended, not clamped); a NaN coordinate gives NaN in every part.

The functions take plain arguments (the coefficient arrays and floats), so
component code compiled later can call them as they are; the ``*_array``
functions are the loops :class:`softflow.fluids.hermite.Bicubic` and
:class:`~softflow.fluids.hermite.Cubic` call.
"""
from __future__ import annotations

import numpy as np

from . import jit


@jit
def cell(x, start, step, count):
    """The cell of x on a uniform axis (``count`` nodes from ``start``,
    ``step`` apart) and x's local coordinate in it, t = 0 at its first node
    and 1 at its last: (index, t). The index is held to the axis' cells
    (0 ... count - 2), so t is below 0 or above 1 past the ends; NaN takes
    cell 0 (and t NaN)."""
    s = (x - start) * (1.0 / step)
    k = np.floor(s)
    if k > count - 2.0:
        k = count - 2.0
    if not k >= 0.0:            # below the axis, and NaN
        k = 0.0
    return int(k), s - k


@jit
def _in_u(c, u):
    """A cell's cubics in u, by Horner's scheme: r_a(u), the coefficient of t^a."""
    return (((c[3] * u + c[2]) * u + c[1]) * u + c[0],
            ((c[7] * u + c[6]) * u + c[5]) * u + c[4],
            ((c[11] * u + c[10]) * u + c[9]) * u + c[8],
            ((c[15] * u + c[14]) * u + c[13]) * u + c[12])


@jit
def bicubic(cells, x_start, x_step, y_start, y_step, x, y):
    """The 2-D interpolant at (x, y): Horner's scheme in u, then in t."""
    i, t = cell(x, x_start, x_step, cells.shape[0] + 1)
    j, u = cell(y, y_start, y_step, cells.shape[1] + 1)
    c = cells[i, j]
    r0, r1, r2, r3 = _in_u(c, u)
    return ((r3 * t + r2) * t + r1) * t + r0


@jit
def bicubic_grad(cells, x_start, x_step, y_start, y_step, x, y):
    """The 2-D interpolant at (x, y) and its partials: (f, df/dx, df/dy)."""
    i, t = cell(x, x_start, x_step, cells.shape[0] + 1)
    j, u = cell(y, y_start, y_step, cells.shape[1] + 1)
    c = cells[i, j]
    # r_a(u): the coefficient of t^a; q_a = dr_a/du
    r0, r1, r2, r3 = _in_u(c, u)
    q0 = (3.0 * c[3] * u + 2.0 * c[2]) * u + c[1]
    q1 = (3.0 * c[7] * u + 2.0 * c[6]) * u + c[5]
    q2 = (3.0 * c[11] * u + 2.0 * c[10]) * u + c[9]
    q3 = (3.0 * c[15] * u + 2.0 * c[14]) * u + c[13]
    f = ((r3 * t + r2) * t + r1) * t + r0
    ft = (3.0 * r3 * t + 2.0 * r2) * t + r1
    fu = ((q3 * t + q2) * t + q1) * t + q0
    return f, ft / x_step, fu / y_step


@jit
def cubic(cells, x_start, x_step, x):
    """The 1-D interpolant at x."""
    i, t = cell(x, x_start, x_step, cells.shape[0] + 1)
    c = cells[i]
    return ((c[3] * t + c[2]) * t + c[1]) * t + c[0]


@jit
def cubic_grad(cells, x_start, x_step, x):
    """The 1-D interpolant at x and its derivative: (f, df/dx)."""
    i, t = cell(x, x_start, x_step, cells.shape[0] + 1)
    c = cells[i]
    f = ((c[3] * t + c[2]) * t + c[1]) * t + c[0]
    return f, ((3.0 * c[3] * t + 2.0 * c[2]) * t + c[1]) / x_step


# -- loops (1-D float64 arrays of one length; outputs written in place) ------------------
@jit
def cell_array(start, step, count, x, index, t):
    for k in range(x.size):
        index[k], t[k] = cell(x[k], start, step, count)


@jit
def bicubic_array(cells, x_start, x_step, y_start, y_step, x, y, f):
    for k in range(x.size):
        f[k] = bicubic(cells, x_start, x_step, y_start, y_step, x[k], y[k])


@jit
def bicubic_grad_array(cells, x_start, x_step, y_start, y_step, x, y, f, fx, fy):
    for k in range(x.size):
        f[k], fx[k], fy[k] = bicubic_grad(cells, x_start, x_step, y_start, y_step, x[k], y[k])


@jit
def cubic_array(cells, x_start, x_step, x, f):
    for k in range(x.size):
        f[k] = cubic(cells, x_start, x_step, x[k])


@jit
def cubic_grad_array(cells, x_start, x_step, x, f, fx):
    for k in range(x.size):
        f[k], fx[k] = cubic_grad(cells, x_start, x_step, x[k])


# -- the table's range (is every state inside it?) ----------------------------------------
@jit
def inside_span(x, lo, hi):
    """Whether lo <= x[k] <= hi for every k: False at a NaN, True for no points."""
    for k in range(x.size):
        if not (x[k] >= lo and x[k] <= hi):
            return False
    return True


@jit
def inside_box(x, y, x_lo, x_hi, y_lo, y_hi):
    """Whether every (x[k], y[k]) lies in [x_lo, x_hi] x [y_lo, y_hi] (as
    :func:`inside_span`)."""
    for k in range(x.size):
        if not (x[k] >= x_lo and x[k] <= x_hi and y[k] >= y_lo and y[k] <= y_hi):
            return False
    return True
