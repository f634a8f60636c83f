"""A tube's laminar-turbulent transition: the default C1 smoothstep or the
straight weighing of the two laws in Re (``transition='linear'``, fonsim
0.6's), checked against the formula written out with fluids' Haaland, on
every path of the law (compiled passes, NumPy, a single tube, table fluids)."""
from __future__ import annotations

import numpy as np
import pytest
from fluids.friction import Haaland

import softflow as sf
from softflow.correlations.friction import fRe_blended

L, D, EPS = 1.0, 1e-3, 1.5e-6


def _expected(Re, transition):
    s = np.clip((Re - 2300.0) / 1700.0, 0.0, 1.0)
    w = s if transition == "linear" else s * s * (3.0 - 2.0 * s)
    turb = np.array([Haaland(max(r, 2300.0), EPS / D) * max(r, 2300.0) for r in Re])
    return 64.0 + w * (turb - 64.0)


@pytest.mark.parametrize("transition", ["smooth", "linear"])
def test_the_blend_is_the_formula(transition):
    Re = np.array([100.0, 2300.0, 2500.0, 3150.0, 3999.0, 4000.0, 1e5])
    phi, dphi = fRe_blended(Re, np.full(Re.size, EPS / D), transition=transition)
    np.testing.assert_allclose(phi, _expected(Re, transition), rtol=1e-12)
    # its derivative, by central differences inside the pieces
    h = 1e-3
    inside = np.array([2500.0, 3150.0, 3900.0, 1e5])
    up = fRe_blended(inside + h, np.full(4, EPS / D), transition=transition)[0]
    down = fRe_blended(inside - h, np.full(4, EPS / D), transition=transition)[0]
    d = fRe_blended(inside, np.full(4, EPS / D), transition=transition)[1]
    np.testing.assert_allclose(d, (up - down) / (2 * h), rtol=1e-6)


@pytest.mark.parametrize("fluid", ["air", "water", "air-table"])
@pytest.mark.parametrize("tubes", [1, 3])
def test_every_path_of_the_tube_law_takes_the_transition(fluid, tubes):
    """The drop of a tube in the band at one flow: linear against smooth by the
    ratio of their f Re (the Darcy part; a gas's drop is not proportional, so
    only its sign and size are checked there)."""
    fl = {"air": sf.air, "water": sf.water, "air-table": sf.Fluid("air", level="table")}[fluid]
    drops = {}
    for transition in ("smooth", "linear"):
        comps = [sf.CircularTube(f"t{i}", fl, L, D, transition=transition)
                 for i in range(tubes)]
        P = sf.CircularTube.make_params(comps)
        mu = float(fl.viscosity(sf.pressure_atmospheric))
        mf = np.full(tubes, 2700.0 * mu * np.pi * D / 4.0)     # Re = 2700, in the band
        pa, pb = np.full(tubes, 3e5), np.full(tubes, 2.5e5)
        drops[transition] = sf.CircularTube.pressure_drop(P, pa, mf, pb, False)[0]
    ratio = _expected(np.array([2700.0]), "linear")[0] / _expected(np.array([2700.0]),
                                                                   "smooth")[0]
    assert ratio > 1.01                       # the two differ here
    if not fl.compressible:
        np.testing.assert_allclose(drops["linear"] / drops["smooth"], ratio, rtol=1e-9)
    else:
        assert np.all(drops["linear"] > drops["smooth"])


def test_a_bad_transition_is_refused_by_name():
    with pytest.raises(ValueError, match=r"CircularTube 't'.*transition.*'smooth', 'linear'"):
        sf.CircularTube("t", sf.air, L, D, transition="cubic")


def test_softflow_fons_tubes_take_fonsims_transition():
    import softflow.fons as fons
    t = fons.CircularTube("t", fluid=fons.air, length=1.0, diameter=1e-3)
    assert t.transition == "linear"
    assert sf.CircularTube("u", sf.air, L, D).transition == "smooth"
