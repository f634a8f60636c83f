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


def friction_Haaland(Re, eD, *, derivative=True, terms=None):
    """Haaland (1983) explicit approximation to Colebrook, and df/dRe.

    f = [-1.8 log10((eD/3.7)^1.11 + 6.9/Re)]^-2, valid 4e3 < Re < 1e8,
    within about 2 % of Colebrook.

    Haaland, S.E., "Simple and Explicit Formulas for the Friction Factor in
    Turbulent Pipe Flow", J. Fluids Eng. 105 (1983) 89-90.

    ``terms`` may hold (eD/3.7)^1.11 made beforehand for this eD
    (:func:`roughness_terms`): a group of tubes makes it once, not per call.

    Returns (f, df/dRe); df is None without ``derivative``.
    """
    a = _haaland_terms(eD) if terms is None else terms
    arg = a + 6.9 / Re
    y = -1.8 * np.log(arg) / _LN10
    f = 1.0 / (y * y)
    if not derivative:
        return f, None
    dy = 1.8 / _LN10 * (6.9 / (Re * Re)) / arg
    df = -2.0 * f / y * dy
    return f, df


def _haaland_terms(eD):
    return (eD / 3.7) ** 1.11


def smoothstep(x, lo, hi, derivative=True):
    """C1 step from 0 (x <= lo) to 1 (x >= hi): 3s^2 - 2s^3; returns (w, dw/dx),
    dw/dx None without ``derivative``."""
    # minimum(maximum()): np.clip's values, without its dispatch (~2 us a call on
    # the one-tube arrays of small scenes)
    s = np.minimum(np.maximum((x - lo) / (hi - lo), 0.0), 1.0)
    w = s * s * (3.0 - 2.0 * s)
    if not derivative:
        return w, None
    dw = 6.0 * s * (1.0 - s) / (hi - lo)
    return w, dw


def fRe_blended(Re, eD, Re_lo=2300.0, Re_hi=4000.0, turbulent=None, *, derivative=True,
                terms=None):
    """The product f·Re of the Darcy friction factor and the Reynolds number,
    laminar (64) below Re_lo, the turbulent correlation above Re_hi, and a C1
    smoothstep blend between them; returns (f·Re, d(f·Re)/dRe), the derivative
    None without ``derivative`` (the value is the same either way).

    ``turbulent(Re, eD, derivative=...) -> (f, df/dRe)`` defaults to
    :func:`friction_Haaland`; ``terms``, what :func:`roughness_terms` made for it
    and this eD, is passed on to it (``terms=``) where given.
    f·Re stays finite at Re = 0, which lets a tube write Δp = C·(f·Re)·ṁ with
    a derivative that never vanishes at zero flow.
    """
    if isinstance(Re, float):     # one value stays a scalar (a 0-d array costs more)
        lowest = Re
    else:
        Re = np.asarray(Re, dtype=float)
        lowest = Re.item() if Re.size == 1 else Re.min(initial=np.inf)
    law = turbulent or friction_Haaland
    kw = {"derivative": derivative} if terms is None else {"derivative": derivative,
                                                          "terms": terms}
    if Re_lo <= Re_hi and lowest >= Re_hi:
        # all past the blend (w = 1, dw = 0): f·Re of the turbulent law itself, the
        # blend's value bitwise (64 + (phit - 64) is exact for phit >= 32, and f·Re
        # of a turbulent law is far above that), without the smoothstep's arithmetic
        ft, dft = law(Re, eD, **kw)
        return ft * Re, (ft + Re * dft if derivative else None)
    w, dw = smoothstep(Re, Re_lo, Re_hi, derivative)
    Ret = np.maximum(Re, Re_lo)  # the turbulent law is only needed (and finite) above Re_lo
    ft, dft = law(Ret, eD, **kw)
    phit = ft * Ret
    phi = 64.0 + w * (phit - 64.0)
    if not derivative:
        return phi, None
    dphit = np.where(Re > Re_lo, ft + Ret * dft, 0.0)
    dphi = dw * (phit - 64.0) + w * dphit
    return phi, dphi


def roughness_terms(turbulent, eD):
    """What the turbulent correlation ``turbulent`` computes from the relative
    roughness eD alone, for its ``terms=`` argument: made once per group of
    tubes (at compile, and again when a run changes a roughness or diameter),
    not at every residual. None where there is nothing worth keeping."""
    if turbulent is friction_Haaland:
        return _haaland_terms(eD)      # as friction_Haaland would make it: bitwise
    return None


def friction_Swamee_Jain_1976(Re, eD, *, derivative=True):
    """Swamee & Jain (1976) explicit approximation to Colebrook, and df/dRe.

    f = 0.25 / [log10((6.97/Re)^0.9 + eD/3.7)]^2, stated range 5e3 <= Re <= 1e8,
    1e-6 <= eD <= 0.05, within about 1 % of Colebrook (form as in ``fluids``).

    Swamee, P.K., Jain, A.K., "Explicit equations for pipe-flow problems",
    J. Hydraul. Div. ASCE 102 (1976) 657-664.

    Returns (f, df/dRe); df is None without ``derivative``.
    """
    s = (6.97 / Re) ** 0.9
    arg = s + eD / 3.7
    y = np.log(arg) / _LN10
    f = 0.25 / (y * y)
    if not derivative:
        return f, None
    dy = -0.9 * s / Re / (arg * _LN10)
    df = -2.0 * f / y * dy
    return f, df


def friction_Churchill_1977(Re, eD, *, derivative=True):
    """Churchill (1977) friction factor for all regimes, and df/dRe.

    f = 8 [(8/Re)^12 + (A + B)^-1.5]^(1/12),
    A = [2.457 ln(1/((7/Re)^0.9 + 0.27 eD))]^16, B = (37530/Re)^16.

    Churchill, S.W., "Friction-factor equation spans all fluid-flow regimes",
    Chem. Eng. 84 (1977) 91-92.

    Returns (f, df/dRe); df is None without ``derivative``.
    """
    s = (7.0 / Re) ** 0.9
    u = s + 0.27 * eD
    L = -np.log(u)
    A = (2.457 * L) ** 16
    B = (37530.0 / Re) ** 16
    T = (A + B) ** -1.5
    lam = (8.0 / Re) ** 12
    X = lam + T
    f = 8.0 * X ** (1.0 / 12.0)
    if not derivative:
        return f, None
    dL = 0.9 * s / Re / u                 # d/dRe of -ln(u)
    dA = 16.0 * A / L * dL
    dB = -16.0 * B / Re
    dT = -1.5 * T / (A + B) * (dA + dB)
    dX = -12.0 * lam / Re + dT
    df = f / 12.0 * dX / X
    return f, df


def friction_Colebrook(Re, eD, *, iterations=8, derivative=True):
    """Colebrook (1939) implicit equation solved to round-off, and df/dRe.

    1/sqrt(f) = -2 log10(eD/3.7 + 2.51/(Re sqrt(f))), the reference turbulent
    law behind the Moody chart. Solved by Newton's method on x = 1/sqrt(f),
    vectorized, from Haaland's value (within 2 %), so a fixed handful of
    iterations reach round-off; df/dRe by implicit differentiation.

    Colebrook, C.F., "Turbulent flow in pipes, with particular reference to the
    transition region between the smooth and rough pipe laws",
    J. Inst. Civ. Eng. 11 (1939) 133-156.

    Returns (f, df/dRe); df is None without ``derivative``.
    """
    Re = np.asarray(Re, dtype=float)
    a = np.asarray(eD, dtype=float) / 3.7
    b = 2.51 / Re
    x = 1.0 / np.sqrt(friction_Haaland(Re, eD)[0])
    c = 2.0 / _LN10
    for _ in range(iterations):
        w = a + b * x
        g = x + c * np.log(w)
        dx = g / (1.0 + c * b / w)
        x = x - dx
        if np.all(np.abs(dx) <= 1e-15 * x):
            break
    if not derivative:
        return 1.0 / (x * x), None
    w = a + b * x
    dg_dx = 1.0 + c * b / w
    dg_dRe = -c * b * x / (w * Re)          # db/dRe = -b/Re
    dx_dRe = -dg_dRe / dg_dx
    f = 1.0 / (x * x)
    df = -2.0 * f / x * dx_dRe
    return f, df


class FrictionTable:
    """Any friction correlation of ``fluids.friction`` as a vectorized C2 spline.

    The ``fluids`` functions are scalar Python; evaluating them per tube and
    Newton iteration would dominate a simulation. One cubic spline in ln(Re)
    per distinct relative roughness is built once, over Re_min ... Re_max, and
    evaluated with its exact derivative. Above Re_max the value is held.

    Parameters
    ----------
    method : str
        Name of a function in ``fluids.friction`` taking (Re, eD).
    eD : array [-]
        Relative roughness of each instance.
    Re_min, Re_max : float [-]
    per_decade : int
        Spline nodes per decade of Re (40 give ~1e-8 relative error).
    """

    def __init__(self, method, eD, Re_min, Re_max=1e8, per_decade=40):
        import fluids.friction
        from scipy.interpolate import CubicSpline

        func = getattr(fluids.friction, method)
        self.eD = np.atleast_1d(np.asarray(eD, dtype=float))
        # one spline per distinct roughness: networks repeat the same tubing
        unique, self._cols = np.unique(self.eD, return_inverse=True)
        k = max(8, int(np.ceil(per_decade * np.log10(Re_max / Re_min))) + 1)
        self.x = np.linspace(np.log(Re_min), np.log(Re_max), k)
        Re_grid = np.exp(self.x)
        table = np.empty((k, len(unique)))
        for j, e in enumerate(unique):
            for i, r in enumerate(Re_grid):
                try:
                    table[i, j] = func(float(r), float(e))
                except (ValueError, ZeroDivisionError, OverflowError) as err:
                    raise ValueError(f"friction correlation {method!r} fails at Re = {r:.3g}, "
                                     f"eD = {e:.3g}: {err}") from None
                if not (np.isfinite(table[i, j]) and table[i, j] > 0):
                    raise ValueError(f"friction correlation {method!r} gives f = "
                                     f"{table[i, j]:.4g} at Re = {r:.3g}, eD = {e:.3g} "
                                     f"(outside its range); choose another correlation")
        self.coef = CubicSpline(self.x, table, axis=0).c     # (4, k-1, n_unique)
        self.h = self.x[1] - self.x[0]

    def __call__(self, Re, eD=None, *, derivative=True):
        """(f, df/dRe) for an array Re with one entry per instance (eD is fixed);
        df is None without ``derivative``."""
        x = np.clip(np.log(np.maximum(Re, 1e-300)), self.x[0], self.x[-1])
        k = np.minimum(((x - self.x[0]) / self.h).astype(np.int64), len(self.x) - 2)
        s = x - self.x[k]
        c0, c1, c2, c3 = self.coef[:, k, self._cols]
        f = ((c0 * s + c1) * s + c2) * s + c3
        if not derivative:
            return f, None
        dfdx = (3.0 * c0 * s + 2.0 * c1) * s + c2
        held = np.log(np.maximum(Re, 1e-300)) >= self.x[-1]
        return f, np.where(held, 0.0, dfdx / Re)


#: Correlations with closed-form (or exactly solved) vectorized versions here.
ANALYTIC_FRICTION = {
    "Haaland": friction_Haaland,
    "Colebrook": friction_Colebrook,
    # fluids' Clamond is a fast exact solver of the Colebrook equation
    "Clamond": friction_Colebrook,
    "Churchill_1977": friction_Churchill_1977,
    "Swamee_Jain_1976": friction_Swamee_Jain_1976,
}

_ALIASES = {"churchill": "Churchill_1977", "swamee_jain": "Swamee_Jain_1976",
            "hagen_poiseuille": "laminar", "poiseuille": "laminar"}


def friction_names():
    """Names accepted by :func:`resolve_friction` (``fluids.friction`` methods, 'laminar')."""
    import fluids.friction
    return sorted(set(fluids.friction.fmethods) | set(ANALYTIC_FRICTION) | {"laminar"})


#: names already resolved (every tube of a network asks for the same one or two)
_RESOLVED: dict = {}


def resolve_friction(name):
    """Canonical name of a friction correlation given loosely ('Swamee-Jain',
    'churchill', 'Colebrook'); raises KeyError listing close matches."""
    if type(name) is str:
        known = _RESOLVED.get(name)
        if known is not None:
            return known
    import difflib

    if not isinstance(name, str):
        raise KeyError(f"a correlation name (str), got {name!r}")
    key = name.strip().replace("-", "_").replace(" ", "_").lower()
    names = friction_names()
    lowered = {n.lower(): n for n in names}
    lowered.update(_ALIASES)
    if key in lowered:
        _RESOLVED[name] = lowered[key]
        return lowered[key]
    starts = [n for n in names if n.lower().startswith(key + "_")]
    if len(starts) == 1:
        _RESOLVED[name] = starts[0]
        return starts[0]
    close = difflib.get_close_matches(key, list(lowered), n=4, cutoff=0.6)
    hint = (f"; did you mean {', '.join(repr(lowered[c]) for c in close)}?" if close
            else f"; known names: {', '.join(names)}")
    raise KeyError(f"unknown friction correlation {name!r}{hint}")
