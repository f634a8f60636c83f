"""A tube's minor losses K (``CircularTube(..., K=)``): K added to f L/D in
every law, checked against independent solutions of the textbook relations
(examples/validation/gas_reference.py: NumPy, SciPy and fluids only, never
softflow) with K G^2 added to their friction term: the Darcy law of a liquid,
isothermal pipe flow with its entry and choke, adiabatic (Fanno) pipe flow;
plus the parameter's checks and its effect on the paths a tube has."""
from __future__ import annotations

import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from fluids.friction import Haaland
from scipy.optimize import brentq

import softflow as sf

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "validation"
sys.path.insert(0, str(EXAMPLES))
import gas_reference as ref  # noqa: E402

L, D = 0.1, 2e-3
AREA = math.pi * D * D / 4.0


def _steady_flow(fluid, K, pa, pb, thermal=None, **tube):
    """Mass flow entering the tube at a between two pressure sources (one fixed
    step: both ends are given, the flow is algebraic)."""
    s = sf.System()
    s += sf.PressureSource("a", pressure=pa)
    s += sf.PressureSource("b", pressure=pb)
    s += sf.CircularTube("t", fluid, L, D, K=K, **tube)
    s.connect("t", "a")
    s.connect("t", "b")
    kw = {} if thermal is None else {"thermal": thermal}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        r = sf.Simulation(s, duration=1e-3, step=1e-3, newton_rtol=1e-13, **kw).run()
    assert r.success, r.message
    return float(r.get("t", "massflow", "a")[-1])


# -- independent references with K G^2 added to the friction term ----------------------
def _iso_residual(G, p0, p2, K):
    return ref.pipe_residual(G, ref.entry_pressure(p0, G), p2, L, D) - ref.RT * K * G * G


def _iso_massflow(p0, p_down, K):
    g_max = ref._ENTRY_LIMIT * p0 / ref.C_ISO
    G_star = brentq(lambda G: _iso_residual(G, p0, G * ref.C_ISO, K), 1e-12 * g_max, g_max,
                    xtol=1e-18 * g_max, rtol=1e-14)
    if p_down <= G_star * ref.C_ISO:
        return G_star * AREA, True
    G = brentq(lambda G: _iso_residual(G, p0, p_down, K), 0.0, G_star,
               xtol=1e-18 * G_star, rtol=1e-14)
    return G * AREA, False


def _fanno_massflow(p0, p_down, K, T0=ref.T_AIR):
    G_noz = ref.nozzle_massflux(p0, T0)
    G_star = brentq(lambda G: ref._choked_residual(G, p0, T0, L, D, ref.ROUGHNESS) - K * G * G,
                    0.0, G_noz, xtol=1e-18 * G_noz, rtol=1e-14)
    if p_down <= ref.choke_pressure(G_star, T0):
        return G_star * AREA, True
    G = brentq(lambda G: (ref._unchoked_residual(G, p0, T0, p_down, L, D, ref.ROUGHNESS)
                          - K * G * G), 0.0, G_star, xtol=1e-18 * G_star, rtol=1e-14)
    return G * AREA, False


def _darcy_massflow(fluid, dp, K, p):
    """A liquid: dp = (f L/D + K) rho u^2 / 2, f = 64/Re laminar or Haaland
    (fluids) turbulent; the cases stay outside the blend."""
    rho, mu = float(fluid.density(p)), float(fluid.viscosity(p))

    def res(m):
        Re = m * D / (mu * AREA)
        f = 64.0 / Re if Re < 2300.0 else Haaland(Re, 1.5e-6 / D)
        return (f * L / D + K) * (m / AREA) ** 2 / (2.0 * rho) - dp

    m = brentq(res, 1e-12, 10.0, xtol=1e-18, rtol=1e-14)
    Re = m * D / (mu * AREA)
    assert Re < 2300.0 or Re > 4000.0, Re
    return m


@pytest.mark.parametrize("K", [0.0, 0.5, 3.0])
@pytest.mark.parametrize("p_down", [2.7e5, 2.0e5, 1.0e5])
def test_isothermal_pipe_flow_with_minor_losses_is_the_reference(K, p_down):
    """Air, isothermal pipe flow from 3 bar: subsonic and choked (at 1 bar), the
    reference's K G^2 in the friction term; within 1e-7 (the laws are exact,
    this is the root solves' agreement)."""
    ours = _steady_flow(sf.air, K, 3e5, p_down)
    theirs, choked = _iso_massflow(3e5, p_down, K)
    assert ours == pytest.approx(theirs, rel=1e-7), (ours, theirs, choked)
    if p_down == 1.0e5:
        assert choked


@pytest.mark.parametrize("K", [0.0, 0.5, 3.0])
@pytest.mark.parametrize("p_down", [2.7e5, 2.0e5, 1.0e5])
def test_fanno_flow_with_minor_losses_is_the_reference(K, p_down):
    """The same tube in an adiabatic scene (Fanno flow, isentropic entry)."""
    ours = _steady_flow(sf.air, K, 3e5, p_down, thermal="adiabatic")
    theirs, _ = _fanno_massflow(3e5, p_down, K)
    assert ours == pytest.approx(theirs, rel=1e-7)


@pytest.mark.parametrize("dp", [30.0, 5e4])          # laminar (Re ~ 1 500), turbulent
@pytest.mark.parametrize("K", [0.0, 0.5, 3.0])
def test_darcy_law_with_minor_losses_is_the_reference(K, dp):
    p = 2e5
    ours = _steady_flow(sf.water, K, p + dp, p)
    theirs = _darcy_massflow(sf.water, dp, K, p + 0.5 * dp)
    assert ours == pytest.approx(theirs, rel=1e-7)


def test_minor_losses_lower_the_flow_by_the_amount_they_add():
    """K matters where it is comparable to f L/D: a short tube's turbulent
    water flow with K = 3 against none (f L/D ~ 1.6 here)."""
    q0 = _steady_flow(sf.water, 0.0, 2.5e5, 2e5)
    q3 = _steady_flow(sf.water, 3.0, 2.5e5, 2e5)
    assert q3 < 0.7 * q0


@pytest.mark.parametrize("tube", [dict(), dict(compressible="mean_density"),
                                  dict(friction="Colebrook"), dict(friction="laminar"),
                                  dict(friction="Serghides_2"), dict(inertance=True)])
@pytest.mark.parametrize("fluid", ["air", "water", "air-table"])
def test_every_path_of_the_law_carries_the_minor_losses(fluid, tube):
    """The compiled passes, the NumPy path, a single tube's scalar path, the
    table fluids' path, tabulated correlations and the inertial tube all give
    the flow of the same law: a tube with K carries what a tube of the same law
    whose f L/D is larger by K carries, checked through the ratio of the
    drops at one flow (each path's pressure_drop against the compiled one)."""
    fl = {"air": sf.air, "water": sf.water,
          "air-table": sf.Fluid("air", level="table")}[fluid]
    inertial = tube.pop("inertance", False)
    c = sf.CircularTube("t", fl, L, D, K=1.7, inertance=inertial, **tube)
    c0 = sf.CircularTube("t", fl, L, D, inertance=inertial, **tube)
    P, P0 = type(c).make_params([c]), type(c0).make_params([c0])
    for mf in (1e-6, 3e-4, -2e-3):
        pa, pb = np.array([3e5]), np.array([2.2e5])
        m = np.array([mf])
        dp = type(c).pressure_drop(P, pa, m, pb, False)[0]
        dp0 = type(c0).pressure_drop(P0, pa, m, pb, False)[0]
        assert np.all(np.isfinite(dp))
        # the minor losses add K mf|mf|/(2 A^2) to the friction term: more drop
        # the same way as the flow, and nothing more at zero flow
        assert np.sign(dp - dp0) == np.sign(mf)
        if not fl.compressible:
            rho = float(fl.density(3e5))
            extra = 1.7 * mf * abs(mf) / (2.0 * AREA ** 2 * rho)
            assert (dp - dp0).item() == pytest.approx(extra, rel=1e-9)


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_a_bad_loss_coefficient_is_refused_by_name(bad):
    with pytest.raises(ValueError, match=r"CircularTube 't'.*K"):
        sf.CircularTube("t", sf.air, L, D, K=bad)


def test_minor_losses_take_the_liquids_affine_path_away():
    """A laminar liquid tube is affine in its variables, one product a step;
    with K it is not (quadratic in the flow): the group says so."""
    P = sf.CircularTube.make_params([sf.CircularTube("t", sf.water, L, D)])
    assert sf.CircularTube.affine(P) is not None
    P = sf.CircularTube.make_params([sf.CircularTube("t", sf.water, L, D, K=0.5)])
    assert sf.CircularTube.affine(P) is None
