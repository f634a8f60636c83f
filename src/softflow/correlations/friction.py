"""Darcy friction factors, vectorized, each with its derivative in Re.

The laws themselves are the compiled scalar functions of
:mod:`softflow.laws.friction` (one place, callable from compiled code); the
functions here apply them to arrays (any shapes that broadcast; floats give
floats). The reference implementations are ``fluids.friction`` (Caleb Bell);
the tests compare against them.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .._laws import law_module

_LN10 = np.log(10.0)


compiled = functools.partial(law_module, "friction")


def prepared(*xs):
    """The arguments as 1-D C-contiguous float64 arrays of one length (their
    broadcast), and the result's shape (``()`` where all are scalars): one
    type signature for the compiled loops. Arrays of the result's shape are
    passed as they are (a view) or copied once; scalars are filled in."""
    shapes = [x.shape if type(x) is np.ndarray else np.shape(x) for x in xs]
    shape = shapes[0]
    if any(sh != shape for sh in shapes):
        shape = np.broadcast_shapes(*shapes)
    n = math.prod(shape)
    out = []
    for x, sh in zip(xs, shapes):
        if sh == shape and type(x) is np.ndarray:
            if x.dtype != np.float64 or not x.flags.c_contiguous:
                x = np.ascontiguousarray(x, dtype=np.float64)
            out.append(x.reshape(n))
        elif sh == ():
            out.append(np.full(n, float(x)))
        else:
            out.append(np.ascontiguousarray(
                np.broadcast_to(np.asarray(x, dtype=np.float64), shape)).reshape(n))
    return shape, out


def shaped(shape, *arrays):
    """The loops' outputs in the result's shape (floats for ``()``)."""
    if shape == ():
        return tuple(float(a[0]) for a in arrays)
    return tuple(a.reshape(shape) for a in arrays)


def friction_laminar(Re):
    """Hagen–Poiseuille Darcy friction factor f = 64/Re (valid for Re < ~2300)."""
    return 64.0 / Re


def _turbulent(kind, Re, eD, derivative, a=None):
    law = compiled()
    shape, (Re, eD) = prepared(Re, eD)
    a = eD if a is None else prepared(a, Re)[1][0]
    f, df = np.empty(Re.size), np.empty(Re.size)
    law.turbulent_array(kind, Re, eD, a, f, df)
    f, df = shaped(shape, f, df)
    return f, (df if derivative else None)


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
    return _turbulent(compiled().HAALAND, Re, eD, derivative, a)


def _haaland_terms(eD):
    return (eD / 3.7) ** 1.11


def smoothstep(x, lo, hi, derivative=True):
    """C1 step from 0 (x <= lo) to 1 (x >= hi): 3s^2 - 2s^3; returns (w, dw/dx),
    dw/dx None without ``derivative``."""
    shape, (x, lo, hi) = prepared(x, lo, hi)
    w, dw = np.empty(x.size), np.empty(x.size)
    compiled().smoothstep_array(x, lo, hi, w, dw)
    w, dw = shaped(shape, w, dw)
    return w, (dw if derivative else None)


def fRe_blended(Re, eD, Re_lo=2300.0, Re_hi=4000.0, turbulent=None, *, derivative=True,
                terms=None, transition="smooth"):
    """The product f·Re of the Darcy friction factor and the Reynolds number,
    laminar (64) below Re_lo, the turbulent correlation above Re_hi, and a C1
    smoothstep blend between them (``transition='linear'``: weighed linearly
    in Re, fonsim 0.6's transition, with kinks at Re_lo and Re_hi); returns
    (f·Re, d(f·Re)/dRe), the derivative None without ``derivative`` (the
    value is the same either way).

    ``turbulent(Re, eD, derivative=...) -> (f, df/dRe)`` defaults to
    :func:`friction_Haaland`; ``terms``, what :func:`roughness_terms` made for it
    and this eD, is passed on to it (``terms=``) where given. The analytic
    correlations (:data:`ANALYTIC_FRICTION`) are evaluated by the compiled law
    (:func:`softflow.laws.friction.fRe_blended`); another callable (a
    :class:`FrictionTable`) is called at max(Re, Re_lo) and blended by the
    same compiled blend.
    f·Re stays finite at Re = 0, which lets a tube write Δp = C·(f·Re)·ṁ with
    a derivative that never vanishes at zero flow.
    """
    law = compiled()
    linear = _linear_transition(transition)
    kind = compiled_kind(turbulent or friction_Haaland)
    shape, (Re, eD) = prepared(Re, eD)
    phi, dphi = np.empty(Re.size), np.empty(Re.size)
    if kind is not None:
        if kind == law.HAALAND:
            a = prepared(_haaland_terms(eD) if terms is None else terms, Re)[1][0]
        else:
            a = eD
        law.fRe_blended_array(kind + (law.LINEAR_BLEND if linear else 0), Re, eD, a,
                              float(Re_lo), float(Re_hi), phi, dphi)
    else:
        ft, dft = turbulent(np.maximum(Re, Re_lo), eD, derivative=True)
        ft, dft = prepared(ft, Re)[1][0], prepared(dft, Re)[1][0]
        law.blend_array(Re, ft, dft, float(Re_lo), float(Re_hi), linear, phi, dphi)
    phi, dphi = shaped(shape, phi, dphi)
    return phi, (dphi if derivative else None)


#: the laminar-turbulent transitions of the blended law
TRANSITIONS = ("smooth", "linear")


def _linear_transition(transition):
    if transition not in TRANSITIONS:
        raise ValueError(f"transition must be one of {TRANSITIONS}, got {transition!r}")
    return transition == "linear"


def transition_step(Re, lo, hi, transition="smooth"):
    """The blend's weight of the turbulent law at Re and its derivative in Re,
    (w, dw/dRe): the smoothstep or, for ``transition='linear'``, the straight
    step from lo to hi (arrays; lo and hi scalars)."""
    if not _linear_transition(transition):
        return smoothstep(Re, lo, hi)
    Re = np.asarray(Re, dtype=float)
    s = (Re - lo) / (hi - lo)
    inside = (s > 0.0) & (s < 1.0)
    return np.clip(s, 0.0, 1.0), np.where(inside, 1.0 / (hi - lo), 0.0)


def compiled_kind(turbulent, transition="smooth"):
    """The id of the correlation ``turbulent`` (one of :data:`ANALYTIC_FRICTION`'s
    functions, or None for 'laminar') in the compiled laws
    (:mod:`softflow.laws.friction`), with the ``transition='linear'`` flag
    added where asked for; None for another law (a table)."""
    law = compiled()
    if turbulent is None:
        return law.LAMINAR
    name = _KIND.get(turbulent)
    if name is None:
        return None
    return getattr(law, name) + (law.LINEAR_BLEND if _linear_transition(transition) else 0)


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
    return _turbulent(compiled().SWAMEE_JAIN, Re, eD, derivative)


def friction_Churchill_1977(Re, eD, *, derivative=True):
    """Churchill (1977) friction factor for all regimes, and df/dRe.

    f = 8 [(8/Re)^12 + (A + B)^-1.5]^(1/12),
    A = [2.457 ln(1/((7/Re)^0.9 + 0.27 eD))]^16, B = (37530/Re)^16.

    Churchill, S.W., "Friction-factor equation spans all fluid-flow regimes",
    Chem. Eng. 84 (1977) 91-92.

    Returns (f, df/dRe); df is None without ``derivative``.
    """
    return _turbulent(compiled().CHURCHILL, Re, eD, derivative)


def friction_Colebrook(Re, eD, *, derivative=True):
    """Colebrook (1939) implicit equation solved to round-off, and df/dRe.

    1/sqrt(f) = -2 log10(eD/3.7 + 2.51/(Re sqrt(f))), the reference turbulent
    law behind the Moody chart. Solved by Newton's method on x = 1/sqrt(f)
    from Haaland's value (within 2 %), so a handful of iterations reach
    round-off; df/dRe by implicit differentiation.

    Colebrook, C.F., "Turbulent flow in pipes, with particular reference to the
    transition region between the smooth and rough pipe laws",
    J. Inst. Civ. Eng. 11 (1939) 133-156.

    Returns (f, df/dRe); df is None without ``derivative``.
    """
    return _turbulent(compiled().COLEBROOK, Re, eD, derivative)


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

#: the analytic correlations' ids in the compiled laws (names of laws.friction's constants)
_KIND = {friction_Haaland: "HAALAND", friction_Colebrook: "COLEBROOK",
         friction_Churchill_1977: "CHURCHILL", friction_Swamee_Jain_1976: "SWAMEE_JAIN"}

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
