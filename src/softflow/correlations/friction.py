"""Darcy friction factors, vectorized, each with its derivative in Re.

The reference implementations are ``fluids.friction`` (Caleb Bell); the tests
compare these array versions against them. Array versions exist because
the solver evaluates thousands of tubes per call and needs dF/dRe.
"""
from __future__ import annotations

import numpy as np

_LN10 = np.log(10.0)


def friction_laminar(Re):
    """Hagen–Poiseuille Darcy friction factor f = 64/Re (valid for Re < ~2300)."""
    return 64.0 / Re


def friction_Haaland(Re, eD):
    """Haaland (1983) explicit approximation to Colebrook, and df/dRe.

    f = [-1.8 log10((eD/3.7)^1.11 + 6.9/Re)]^-2, valid 4e3 < Re < 1e8,
    within about 2 % of Colebrook.

    Haaland, S.E., "Simple and Explicit Formulas for the Friction Factor in
    Turbulent Pipe Flow", J. Fluids Eng. 105 (1983) 89-90.

    Returns (f, df/dRe).
    """
    a = (eD / 3.7) ** 1.11
    arg = a + 6.9 / Re
    y = -1.8 * np.log(arg) / _LN10
    f = 1.0 / (y * y)
    dy = 1.8 / _LN10 * (6.9 / (Re * Re)) / arg
    df = -2.0 * f / y * dy
    return f, df


def smoothstep(x, lo, hi):
    """C1 step from 0 (x <= lo) to 1 (x >= hi): 3s^2 - 2s^3; returns (w, dw/dx)."""
    s = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    w = s * s * (3.0 - 2.0 * s)
    dw = 6.0 * s * (1.0 - s) / (hi - lo)
    return w, dw


def fRe_blended(Re, eD, Re_lo=2300.0, Re_hi=4000.0):
    """The product f·Re of the Darcy friction factor and the Reynolds number,
    laminar (64) below Re_lo, Haaland above Re_hi, and a C1 smoothstep blend
    between them; returns (f·Re, d(f·Re)/dRe).

    f·Re stays finite at Re = 0, which lets a tube write Δp = C·(f·Re)·ṁ with
    a derivative that never vanishes at zero flow.
    """
    Re = np.asarray(Re, dtype=float)
    w, dw = smoothstep(Re, Re_lo, Re_hi)
    Ret = np.maximum(Re, Re_lo)  # Haaland is only needed (and finite) above Re_lo
    ft, dft = friction_Haaland(Ret, eD)
    phit = ft * Ret
    dphit = np.where(Re > Re_lo, ft + Ret * dft, 0.0)
    phi = 64.0 + w * (phit - 64.0)
    dphi = dw * (phit - 64.0) + w * dphit
    return phi, dphi
