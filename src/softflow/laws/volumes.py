"""The volumes' laws, compiled: a PV curve's lookup, the stored mass of a
rigid or compliant chamber, and an actuator's wall law p = p_curve(m / rho).

A PV curve (:class:`softflow.curves.PVCurve`) reaches these functions as two
arrays: its knots (the sample volumes, strictly increasing) and its table,
one row per piece, ``[base, c0, c1, c2, c3]``: piece k = the number of knots
at or below V (row 0 and row -1 are the extensions before the first and past
the last sample) holds p = c0 + x (c1 + x (c2 + x c3)) with x = V - base.
A curve of straight pieces (``interpolation='linear'``) is the same table
with c2 = c3 = 0 and c1 each chord's slope. The extension's kind ('linear'
or 'clamp') is in the table's coefficients;
the extrapolation code (:data:`LINEAR`, :data:`CLAMP`, :data:`ERROR`) says
whether a volume beyond the knots is refused, which a group pass reports by
returning the index of the first such volume (the caller raises the curve's
own error).

A fluid reaches them as a kind and a constant: an ideal gas (the constant its
R T: rho = p / (R T)), a liquid of constant density (the constant rho), or
densities given per instance (:data:`GIVEN`: table and eos levels, whose
properties come from Python), with their derivatives in pressure.

The arithmetic is the array code's it replaced, operation for operation, so
the numbers are the same to the last bit.
"""
from __future__ import annotations

from . import jit

#: extrapolation codes of a PV curve (PVCurve.extrapolate)
LINEAR, CLAMP, ERROR = 0, 1, 2
#: fluid kinds: rho = p / c (c = R T), rho = c, or rho given per instance
IDEAL_GAS, CONSTANT_LIQUID, GIVEN = 0, 1, 2


@jit
def bisect_right(a, lo, hi, x):
    """The first index in [lo, hi) whose entry of the sorted a is above x, or
    hi (Python's ``bisect.bisect_right`` on a[lo:hi], offset by lo; a nan is
    past every entry)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if x < a[mid]:
            hi = mid
        else:
            lo = mid + 1
    return lo


@jit
def piece(knots, x):
    """The number of knots at or below x (a nan is past every knot): the row
    of the curve's table that holds x."""
    return bisect_right(knots, int(0), knots.size, x)    # int(): not a literal's own compile


@jit
def curve_point(knots, table, x):
    """The curve's pressure and dp/dV at the volume x: (p, dp)."""
    row = piece(knots, x)
    return _cubic(x - table[row, 0], table[row, 1], table[row, 2], table[row, 3],
                  table[row, 4])


@jit
def curve_point_flat(knots, flat, x):
    """:func:`curve_point` on the table's rows stored one after the other, 5
    floats a row (a network's parameter array holds them so: no 2-D view to
    make at each residual)."""
    j = 5 * piece(knots, x)
    return _cubic(x - flat[j], flat[j + 1], flat[j + 2], flat[j + 3], flat[j + 4])


@jit
def _cubic(u, p0, c1, c2, c3):
    """A piece of the curve at u past its start (p0 there, slopes c1, c2, c3):
    (p, dp/dV)."""
    return p0 + u * (c1 + u * (c2 + u * c3)), c1 + u * (2.0 * c2 + 3.0 * u * c3)


@jit
def refused(mode, knots, x):
    """Whether a curve of extrapolation code ``mode`` refuses the volume x
    (:data:`ERROR` beyond its knots; a nan is beyond them)."""
    return mode == ERROR and not (knots[0] <= x <= knots[-1])


@jit
def curve_array(knots, table, mode, x, p, dp):
    """The curve at the volumes x into p and dp; -1, or the index of the
    first volume the curve refuses (then the outputs are not filled)."""
    for i in range(x.size):
        if refused(mode, knots, x[i]):
            return i
    for i in range(x.size):
        p[i], dp[i] = curve_point(knots, table, x[i])
    return -1


@jit
def density(kind, c, p):
    """(rho, d rho/dp) of an ideal gas (c = R T) or a constant-density liquid
    (c = rho) at the pressure p."""
    if kind == IDEAL_GAS:
        return p / c, 1.0 / c
    return c, 0.0


@jit
def rigid_mass(rho, rho_p, volume):
    """The mass in a rigid volume of fluid at density rho, and its derivative
    in pressure (rho_p = d rho/dp)."""
    return rho * volume, rho_p * volume


@jit
def compliant_mass(rho, rho_p, p, volume, compliance, p_ref):
    """The mass in a linear accumulator, vol = volume + compliance (p - p_ref),
    and its derivative in pressure."""
    vol = volume + compliance * (p - p_ref)
    return rho * vol, rho_p * vol + rho * compliance


@jit
def scaled_curve(pc, dpc, scale, p_atm):
    """A curve's pressure and slope with its gauge part scaled by ``scale``."""
    return p_atm + scale * (pc - p_atm), scale * dpc


@jit
def curve_law(p, rho, rho_p, vol, pc, dpc):
    """The wall law of an actuator, p - p_curve(V) with V = m / rho(p), from the
    curve's pressure pc and slope dpc at V: (F, dF/dp, dF/dm)."""
    return p - pc, 1.0 + dpc * vol * (rho_p / rho), -dpc / rho


@jit
def curve_law_array(p, rho, rho_p, vol, pc, dpc, F, J):
    """:func:`curve_law` of a group into F (n, 1) and J (n, 2)."""
    for i in range(p.size):
        F[i, 0], J[i, 0], J[i, 1] = curve_law(p[i], rho[i], rho_p[i], vol[i], pc[i], dpc[i])


@jit
def _fluid(kind, c, p, rho_given, rho_p_given, i, jac):
    if kind == GIVEN:
        return rho_given[i], (rho_p_given[i] if jac else 0.0)
    return density(kind, c, p)


@jit
def rigid_residual(kind, c, volume, V, S, rho_given, rho_p_given, F, J, jac):
    """A group of rigid volumes of a compressible fluid: F = rho(p) volume - m
    into F (n, 1) and, with ``jac``, [dF/dp, dF/dmf, dF/dm] into J (n, 3)."""
    for i in range(V.shape[0]):
        rho, rho_p = _fluid(kind, c, V[i, 0], rho_given, rho_p_given, i, jac)
        m, m_p = rigid_mass(rho, rho_p, volume[i])
        F[i, 0] = m - S[i, 0]
        if jac:
            J[i, 0] = m_p
            J[i, 1] = 0.0
            J[i, 2] = -1.0


@jit
def compliant_residual(kind, c, volume, compliance, p_ref, V, S, rho_given, rho_p_given,
                       F, J, jac):
    """A group of linear accumulators: F = rho(p) (volume + compliance (p -
    p_ref)) - m into F (n, 1) and, with ``jac``, [dF/dp, dF/dm] into J (n, 2)."""
    for i in range(V.shape[0]):
        p = V[i, 0]
        rho, rho_p = _fluid(kind, c, p, rho_given, rho_p_given, i, jac)
        m, m_p = compliant_mass(rho, rho_p, p, volume[i], compliance[i], p_ref[i])
        F[i, 0] = m - S[i, 0]
        if jac:
            J[i, 0] = m_p
            J[i, 1] = -1.0


@jit
def actuator_residual(kind, c, V, S, rho_given, rho_p_given, knots, table, mode,
                      scaled, scale, p_atm, F, J, jac):
    """A group of actuators on one PV curve (gauge part scaled by each one's
    ``scale`` where ``scaled``): F = p - p_curve(m / rho(p)) into F (n, 1) and,
    with ``jac``, [dF/dp, dF/dm] into J (n, 2). Returns -1, or the index of
    the first actuator whose volume the curve refuses (outputs then partial)."""
    for i in range(V.shape[0]):
        p = V[i, 0]
        rho, rho_p = _fluid(kind, c, p, rho_given, rho_p_given, i, jac)
        vol = S[i, 0] / rho
        if refused(mode, knots, vol):
            return i
        pc, dpc = curve_point(knots, table, vol)
        if scaled:
            pc, dpc = scaled_curve(pc, dpc, scale[i], p_atm)
        F[i, 0], d_p, d_m = curve_law(p, rho, rho_p, vol, pc, dpc)
        if jac:
            J[i, 0] = d_p
            J[i, 1] = d_m
    return -1


@jit
def on_inflation(vol, inflating, v_hi, v_lo):
    """Whether a hysteretic actuator at the volume vol that started the step on
    the inflation branch (``inflating``) or not reads the inflation curve:
    below V_hi while inflating, at or below V_lo while deflating."""
    return vol < v_hi if inflating else vol <= v_lo


@jit
def hysteretic_residual(kind, c, V, S, branch, rho_given, rho_p_given, knots_up, table_up,
                        knots_down, table_down, v_hi, v_lo, F, J, jac):
    """A group of hysteretic actuators on one loop (the branch in S[:, branch],
    1 = inflation): the wall law of :func:`actuator_residual` on the curve
    :func:`on_inflation` picks, into F (n, 1) and, with ``jac``, J (n, 2)."""
    for i in range(V.shape[0]):
        p = V[i, 0]
        rho, rho_p = _fluid(kind, c, p, rho_given, rho_p_given, i, jac)
        vol = S[i, 0] / rho
        if on_inflation(vol, S[i, branch] > 0.5, v_hi, v_lo):
            pc, dpc = curve_point(knots_up, table_up, vol)
        else:
            pc, dpc = curve_point(knots_down, table_down, vol)
        F[i, 0], d_p, d_m = curve_law(p, rho, rho_p, vol, pc, dpc)
        if jac:
            J[i, 0] = d_p
            J[i, 1] = d_m
