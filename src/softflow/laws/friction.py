"""Darcy friction factors, compiled, each with its derivative in Re.

Scalar functions (Re, relative roughness eD) -> (f, df/dRe); the formulas,
validity ranges and references are in :mod:`softflow.correlations.friction`,
whose array functions loop over these. The reference implementations are
``fluids.friction`` (Caleb Bell); the tests compare against them.
"""
from __future__ import annotations

import math

from . import jit

_LN10 = math.log(10.0)

#: the turbulent correlations by id (the ``kind`` of :func:`turbulent`)
LAMINAR, HAALAND, COLEBROOK, CHURCHILL, SWAMEE_JAIN = 0, 1, 2, 3, 4
#: added to a correlation's id in :func:`fRe_blended`'s ``kind``: the
#: laminar-turbulent blend weighs the two laws linearly in Re (fonsim's
#: transition) instead of by the C1 smoothstep
LINEAR_BLEND = 8


@jit
def haaland_terms(eD):
    """(eD/3.7)^1.11, Haaland's roughness term."""
    return (eD / 3.7) ** 1.11


@jit
def haaland(Re, a):
    """Haaland (1983) with its roughness term ``a`` = (eD/3.7)^1.11 given."""
    arg = a + 6.9 / Re
    y = -1.8 * math.log(arg) / _LN10
    f = 1.0 / (y * y)
    dy = 1.8 / _LN10 * (6.9 / (Re * Re)) / arg
    return f, -2.0 * f / y * dy


@jit
def swamee_jain(Re, eD):
    """Swamee & Jain (1976)."""
    s = (6.97 / Re) ** 0.9
    arg = s + eD / 3.7
    y = math.log(arg) / _LN10
    f = 0.25 / (y * y)
    dy = -0.9 * s / Re / (arg * _LN10)
    return f, -2.0 * f / y * dy


@jit
def churchill(Re, eD):
    """Churchill (1977), all regimes."""
    s = (7.0 / Re) ** 0.9
    u = s + 0.27 * eD
    L = -math.log(u)
    A = (2.457 * L) ** 16
    B = (37530.0 / Re) ** 16
    T = (A + B) ** -1.5
    lam = (8.0 / Re) ** 12
    X = lam + T
    f = 8.0 * X ** (1.0 / 12.0)
    dL = 0.9 * s / Re / u
    dA = 16.0 * A / L * dL
    dB = -16.0 * B / Re
    dT = -1.5 * T / (A + B) * (dA + dB)
    dX = -12.0 * lam / Re + dT
    return f, f / 12.0 * dX / X


@jit
def colebrook(Re, eD):
    """Colebrook (1939) solved by Newton's method on x = 1/sqrt(f) from
    Haaland's value (within 2 %) to round-off; df/dRe by implicit
    differentiation."""
    a = eD / 3.7
    b = 2.51 / Re
    f0, _ = haaland(Re, haaland_terms(eD))
    x = 1.0 / math.sqrt(f0)
    c = 2.0 / _LN10
    for _ in range(8):
        w = a + b * x
        dx = (x + c * math.log(w)) / (1.0 + c * b / w)
        x = x - dx
        if abs(dx) <= 1e-15 * x:
            break
    w = a + b * x
    dx_dRe = (c * b * x / (w * Re)) / (1.0 + c * b / w)
    f = 1.0 / (x * x)
    return f, -2.0 * f / x * dx_dRe


@jit
def turbulent(kind, Re, eD, a):
    """(f, df/dRe) of the turbulent correlation ``kind`` (an id above; ``a``
    Haaland's roughness term, used by Haaland only)."""
    if kind == HAALAND:
        return haaland(Re, a)
    if kind == COLEBROOK:
        return colebrook(Re, eD)
    if kind == CHURCHILL:
        return churchill(Re, eD)
    return swamee_jain(Re, eD)


@jit
def smoothstep(x, lo, hi):
    """C1 step 3 s^2 - 2 s^3 from 0 (x <= lo) to 1 (x >= hi), s = (x - lo)/(hi - lo)
    clipped to [0, 1]; returns (w, dw/dx)."""
    s = min(max((x - lo) / (hi - lo), 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s), 6.0 * s * (1.0 - s) / (hi - lo)


@jit
def linear_step(x, lo, hi):
    """Step s = (x - lo)/(hi - lo) clipped to [0, 1], continuous but with kinks
    at lo and hi; returns (w, dw/dx) (dw/dx zero outside (lo, hi))."""
    s = (x - lo) / (hi - lo)
    if s <= 0.0:
        return 0.0, 0.0
    if s >= 1.0:
        return 1.0, 0.0
    return s, 1.0 / (hi - lo)


@jit
def blend(Re, ft, dft, lo, hi, linear=False):
    """f·Re of the laminar–turbulent blend, 64 + w (ft Ret - 64), and its
    derivative in Re, from the turbulent law's (f, df/dRe) = (ft, dft) at
    Ret = max(Re, lo); w the smoothstep from lo to hi (C1), or with
    ``linear`` the straight step (fonsim 0.6's weighing of the two laws)."""
    if linear:
        w, dw = linear_step(Re, lo, hi)
    else:
        w, dw = smoothstep(Re, lo, hi)
    Ret = max(Re, lo)
    phit = ft * Ret
    dphit = ft + Ret * dft if Re > lo else 0.0
    return 64.0 + w * (phit - 64.0), dw * (phit - 64.0) + w * dphit


@jit
def fRe_blended(kind, Re, eD, a, lo, hi):
    """(f·Re, d(f·Re)/dRe) of the blended friction law: 64 below ``lo``, the
    turbulent correlation ``kind`` above ``hi`` (its f·Re itself there), the
    C1 :func:`blend` between (straight, where ``kind`` has
    :data:`LINEAR_BLEND` added); 64 at every Re for ``kind`` = LAMINAR."""
    linear = kind >= LINEAR_BLEND
    if linear:
        kind = kind - LINEAR_BLEND
    if kind == LAMINAR:
        return 64.0, 0.0
    if lo <= hi and Re >= hi:
        f, df = turbulent(kind, Re, eD, a)
        return f * Re, f + Re * df
    ft, dft = turbulent(kind, max(Re, lo), eD, a)
    return blend(Re, ft, dft, lo, hi, linear)


# -- array loops (the arrays' shapes are made equal by the caller) ----------------------
@jit
def turbulent_array(kind, Re, eD, a, f, df):
    for i in range(Re.size):
        f[i], df[i] = turbulent(kind, Re[i], eD[i], a[i])


@jit
def fRe_blended_array(kind, Re, eD, a, lo, hi, phi, dphi):
    for i in range(Re.size):
        phi[i], dphi[i] = fRe_blended(kind, Re[i], eD[i], a[i], lo, hi)


@jit
def blend_array(Re, ft, dft, lo, hi, linear, phi, dphi):
    for i in range(Re.size):
        phi[i], dphi[i] = blend(Re[i], ft[i], dft[i], lo, hi, linear)


@jit
def smoothstep_array(x, lo, hi, w, dw):
    for i in range(x.size):
        w[i], dw[i] = smoothstep(x[i], lo[i], hi[i])


__all__ = ["LAMINAR", "HAALAND", "COLEBROOK", "CHURCHILL", "SWAMEE_JAIN", "LINEAR_BLEND", "haaland",
           "haaland_terms", "swamee_jain", "churchill", "colebrook", "turbulent",
           "smoothstep", "blend", "fRe_blended"]
