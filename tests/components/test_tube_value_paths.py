"""The tube law's cheaper evaluations give the same numbers: its value without
derivatives (jac=False), the Haaland roughness term made once per group, the
fully turbulent shortcut past the blend, the compiled law against the same law
through NumPy arrays; and a run-time change of roughness or diameter remakes
what the group precomputed."""
import numpy as np
import pytest

import softflow as sf
from softflow.components.tubes import CircularTube
from softflow.correlations.friction import (ANALYTIC_FRICTION, FrictionTable, fRe_blended,
                                            friction_Haaland, roughness_terms, smoothstep)

P0 = sf.pressure_atmospheric
# laminar, the blend, its bounds and past it
RE = np.concatenate([[0.0, 1.0, 2299.9, 2300.0, 2300.1, 3999.9, 4000.0, 4000.1],
                     np.linspace(0.0, 6000.0, 601), np.logspace(3.5, 8, 200)])
LAWS = sorted(ANALYTIC_FRICTION)


def _blend(Re, eD, lo, hi, law):
    """f·Re and its derivative by the blend's formula at every Re (no shortcut)."""
    w, dw = smoothstep(Re, lo, hi)
    Ret = np.maximum(Re, lo)
    ft, dft = law(Ret, eD)
    phit = ft * Ret
    dphit = np.where(Re > lo, ft + Ret * dft, 0.0)
    return 64.0 + w * (phit - 64.0), dw * (phit - 64.0) + w * dphit


@pytest.mark.parametrize("name", LAWS)
@pytest.mark.parametrize("eD", [0.0, 1.5e-3, 0.05])
@pytest.mark.parametrize("bounds", [(2300.0, 4000.0), (1000.0, 1001.0)])
def test_fRe_blended_value_paths_are_bitwise_the_blend(name, eD, bounds):
    law = ANALYTIC_FRICTION[name]
    terms = roughness_terms(law, eD)
    # all of RE, and single values (Colebrook's iteration stops on the whole
    # array's convergence: each is compared with the blend of the same array)
    for Re in [RE] + [RE[k:k + 1] for k in range(0, len(RE), 7)]:
        w, dw = _blend(Re, eD, *bounds, law)
        phi, dphi = fRe_blended(Re, eD, *bounds, law)
        np.testing.assert_array_equal(phi, w)
        np.testing.assert_array_equal(dphi, dw)
        value, none = fRe_blended(Re, eD, *bounds, law, derivative=False, terms=terms)
        assert none is None
        np.testing.assert_array_equal(value, w)
        # all past the blend: the shortcut, on arrays as on one value
        past = Re[Re >= bounds[1]]
        if past.size:
            np.testing.assert_array_equal(fRe_blended(past, eD, *bounds, law)[0],
                                          _blend(past, eD, *bounds, law)[0])


def test_haaland_terms_are_the_roughness_term_and_only_haalands():
    eD = np.array([0.0, 1e-4, 0.02])
    np.testing.assert_array_equal(roughness_terms(friction_Haaland, eD), (eD / 3.7) ** 1.11)
    Re = np.array([5e3, 1e5, 1e7])
    f, df = friction_Haaland(Re, eD)
    f2, df2 = friction_Haaland(Re, eD, terms=roughness_terms(friction_Haaland, eD))
    np.testing.assert_array_equal(f, f2)
    np.testing.assert_array_equal(df, df2)
    assert friction_Haaland(Re, eD, derivative=False)[1] is None
    for name in LAWS:
        if ANALYTIC_FRICTION[name] is not friction_Haaland:
            assert roughness_terms(ANALYTIC_FRICTION[name], eD) is None


@pytest.mark.parametrize("name", LAWS)
def test_correlations_without_derivative_give_the_same_f(name):
    law = ANALYTIC_FRICTION[name]
    Re = np.logspace(3.4, 8, 50)
    f, df = law(Re, 1e-4)
    f2, none = law(Re, 1e-4, derivative=False)
    assert none is None and df is not None
    np.testing.assert_array_equal(f, f2)


def test_friction_table_without_derivative_gives_the_same_f():
    table = FrictionTable("Serghides_2", np.array([1e-4, 1e-3]), Re_min=2300.0)
    Re = np.array([3e3, 2e6])
    f, df = table(Re)
    f2, none = table(Re, derivative=False)
    assert none is None
    np.testing.assert_array_equal(f, f2)


def _tubes(fluid, n, **kw):
    return [CircularTube(f"t{i}", fluid, 0.3 + 0.1 * i, 1e-3 * (1 + 0.2 * i), **kw)
            for i in range(n)]


def _massflows(tubes, re):
    P = CircularTube.make_params(tubes)
    return np.asarray(re, float) / P.re_per_mf


@pytest.mark.parametrize("fluid", ["air", "water"])
@pytest.mark.parametrize("options", [{}, {"friction": "Colebrook"}, {"roughness": 5e-5},
                                     {"compressible": "isothermal"}, {"friction": "Chen_1979"},
                                     {"Re_laminar": 1000.0, "Re_turbulent": 1100.0}],
                         ids=["haaland", "colebrook", "rough", "isothermal", "table", "bounds"])
@pytest.mark.parametrize("re", [[5e3], [3e3], [1e3], [1e5], [-6e3], [5e3, 3e3, -1e3],
                                [4e3, 5e4, 1e6], [1e3, 2e3, 2299.0]],
                         ids=["turbulent", "blend", "laminar", "fast", "backward",
                              "mixed", "all-turbulent", "all-laminar"])
def test_tube_residual_without_jacobian_is_bitwise_the_one_with(fluid, options, re):
    """jac=False takes the value-only paths (one tube and groups); its residual is
    the one jac=True gives, bit for bit, and the Jacobian matches finite differences."""
    tubes = _tubes(getattr(sf, fluid), len(re), **options)
    P = CircularTube.make_params(tubes)
    mf = _massflows(tubes, re)
    n = len(re)
    pa = np.full(n, 2.0e5)
    pb = pa - 1e3 * np.sign(mf + 1e-30)
    V = np.column_stack([pa, mf, pb, -mf])
    S = np.zeros((n, 0))
    F, J = CircularTube.residual(P, V, S, 0.0, True)
    F2, J2 = CircularTube.residual(P, V, S, 0.0, False)
    assert J2 is None
    if P.lin_map is not None and (np.abs(mf) * P.re_per_mf <= P.Re_lo).all():
        # a constant-property liquid in laminar flow: jac=False is its affine form,
        # one matrix product (equal to the rounding of the pressures)
        np.testing.assert_allclose(F, F2, rtol=0, atol=1e-15 * pa.max())
    else:
        np.testing.assert_array_equal(F, F2)
    # the pressure-drop column of the Jacobian against central differences
    for j, k in [(2, 0), (3, 1), (4, 2)]:
        h = 1e-6 * np.maximum(np.abs(V[:, k]), 1e-9 if k == 1 else 1e3)
        Vp, Vm = V.copy(), V.copy()
        Vp[:, k] += h
        Vm[:, k] -= h
        fd = (CircularTube.residual(P, Vp, S, 0.0, False)[0][:, 1]
              - CircularTube.residual(P, Vm, S, 0.0, False)[0][:, 1]) / (2 * h)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-5, atol=1e-9 * np.abs(fd).max())


def _turbulent_scene(roughness=1.5e-6, diameter=1e-3):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    s += sf.CircularTube("t", sf.air, 0.1, diameter, roughness=roughness)
    s += sf.Container("c", sf.air, 1e-6)
    s.connect("src", "t")
    s.connect("t", "c")
    return s


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
@pytest.mark.parametrize("change, built", [
    ({"t.roughness": 5e-5}, {"roughness": 5e-5}),
    ({"t.diameter": 1.3e-3}, {"diameter": 1.3e-3}),
], ids=["roughness", "diameter"])
def test_run_params_remake_the_precomputed_roughness_term(change, built):
    """A run that changes the roughness or the diameter (eD = roughness/D) uses the
    Haaland term of the new eD: its result is a fresh build's, bitwise, and the
    next plain run is back to the first."""
    sim = sf.Simulation(_turbulent_scene(), duration=3e-3, step=1e-3)
    base = sim.run()
    changed = sim.run(params=change)
    fresh = sf.Simulation(_turbulent_scene(**built), duration=3e-3, step=1e-3).run()
    for name in ("c.pressure", "t.massflow_a"):
        np.testing.assert_array_equal(changed[name], fresh[name])
        assert not np.array_equal(changed[name], base[name])
        np.testing.assert_array_equal(sim.run()[name], base[name])
    # the scene is turbulent, so the term is in use
    P = CircularTube.make_params([CircularTube("t", sf.air, 0.1, **{"diameter": 1e-3,
                                                                    **built})])
    assert (np.abs(fresh["t.massflow_a"]).max() * P.re_per_mf > 4000).all()
    np.testing.assert_array_equal(P.friction_terms, (P.eD / 3.7) ** 1.11)


@pytest.mark.parametrize("fluid", ["air", "water", "air mean-density"])
@pytest.mark.parametrize("friction", ["laminar", "Haaland", "Colebrook", "Churchill",
                                      "Swamee-Jain"])
def test_compiled_paths_are_the_array_law(fluid, friction):
    """A group of gas tubes (isothermal pipe flow, or the mean-density law) or
    of liquid tubes of constant properties (the Darcy law) runs its residual
    and pressure drop as one compiled pass (P.kind); the same law through
    NumPy arrays (P.kind = None) gives the same numbers to round-off, laminar,
    in the blend, turbulent and choked, either direction."""
    options = {"compressible": "mean_density"} if "mean" in fluid else {}
    fluid = sf.water if fluid == "water" else sf.air
    tubes = [CircularTube(f"t{k}", fluid, 0.02 * (k + 1), 1e-3 * (1 + 0.3 * k),
                          friction=friction, **options) for k in range(4)]
    P = CircularTube.make_params(tubes)
    assert P.kind is not None
    S = np.zeros((4, 0))
    for re in (0.0, 1e3, 2300.0, 3e3, 4000.0, 5e3, 2e5, 2e6):
        mf = re / P.re_per_mf * np.array([1.0, -1.0, 0.5, -2.0])
        V = np.column_stack([np.full(4, 3e5), mf, np.array([1e5, 2.9e5, 0.3e5, 2e5]), -mf])
        got = [CircularTube.residual(P, V, S, 0.0, jac) for jac in (False, True)]
        drop = CircularTube.pressure_drop(P, V[:, 0], V[:, 1], V[:, 2], True)
        P.kind, kind = None, P.kind
        try:
            want = [CircularTube.residual(P, V, S, 0.0, jac) for jac in (False, True)]
            want_drop = CircularTube.pressure_drop(P, V[:, 0], V[:, 1], V[:, 2], True)
        finally:
            P.kind = kind
        scale = np.abs(V[:, [0, 2]]).max()
        np.testing.assert_allclose(got[0][0], want[0][0], rtol=1e-13, atol=1e-13 * scale)
        np.testing.assert_allclose(got[1][0], want[1][0], rtol=1e-13, atol=1e-13 * scale)
        np.testing.assert_allclose(got[1][1], want[1][1], rtol=1e-12, atol=1e-15)
        for a, b in zip(drop, want_drop):
            np.testing.assert_allclose(np.broadcast_to(a, (4,)), np.broadcast_to(b, (4,)),
                                       rtol=1e-12, atol=1e-13 * scale)


@pytest.mark.parametrize("V", [[0.0, 0.0, 0.0, 0.0], [0.0, 1e-4, 1e5, -1e-4],
                               [1e5, 1e-4, 0.0, -1e-4], [np.nan, 1e-4, 1e5, -1e-4]],
                         ids=["zero", "pa-zero", "pb-zero", "nan"])
@pytest.mark.parametrize("compressible", ["mean_density"])
def test_one_tube_at_degenerate_points_is_the_array_law(V, compressible):
    """Zero or NaN pressures give the array law's inf/nan, never an exception
    (a Newton iterate may pass there; the solver rejects non-finite
    residuals): the compiled law as the NumPy one."""
    P = CircularTube.make_params([CircularTube("t", sf.air, 0.1, 1e-3,
                                               compressible=compressible)])
    assert P.kind is not None
    V = np.array([V])
    S = np.zeros((1, 0))
    with np.errstate(all="ignore"):
        got = [CircularTube.residual(P, V, S, 0.0, jac) for jac in (False, True)]
        P.kind, kind = None, P.kind
        try:
            want = [CircularTube.residual(P, V, S, 0.0, jac) for jac in (False, True)]
        finally:
            P.kind = kind
    np.testing.assert_array_equal(got[0][0], want[0][0])
    np.testing.assert_array_equal(got[1][0], want[1][0])
    np.testing.assert_array_equal(got[1][1], want[1][1])


@pytest.mark.parametrize("V", [[0.0, 0.0, 0.0, 0.0], [0.0, 1e-4, 1e5, -1e-4],
                               [1e5, 1e-4, 0.0, -1e-4], [np.nan, 1e-4, 1e5, -1e-4]],
                         ids=["zero", "pa-zero", "pb-zero", "nan"])
def test_gas_pipe_law_at_degenerate_points_gives_no_exception(V):
    """The isothermal pipe-flow law at zero or NaN pressures: inf/nan for the
    solver to reject, never an exception."""
    P = CircularTube.make_params([CircularTube("t", sf.air, 0.1, 1e-3)])
    with np.errstate(all="ignore"):
        for jac in (False, True):
            F, J = CircularTube.residual(P, np.array([V]), np.zeros((1, 0)), 0.0, jac)
            assert F.shape == (1, 2) and (J is None or J.shape == (1, 5))


@pytest.mark.parametrize("friction", ["laminar", "Haaland", "Colebrook", "Churchill",
                                      "Swamee-Jain"])
def test_compiled_thermal_path_is_the_array_law(friction):
    """In a thermal scene a group of ideal-gas tubes runs adiabatic pipe flow
    (friction + Fanno) as one compiled pass; the same law through the array
    functions (P.kind = None) gives the same numbers to round-off, laminar,
    in the blend, turbulent and choked, either direction."""
    tubes = [CircularTube(f"t{k}", sf.air, 0.02 * (k + 1), 1e-3 * (1 + 0.3 * k),
                          friction=friction) for k in range(4)]
    P = CircularTube.make_params(tubes)
    assert P.kind is not None and P.R_gas is not None
    T_up = np.array([293.15, 250.0, 350.0, 400.0])
    for re in (0.0, 1e3, 2300.0, 3e3, 4000.0, 5e3, 2e5, 2e6):
        mf = re / P.re_per_mf * np.array([1.0, -1.0, 0.5, -2.0])
        pa, pb = np.full(4, 3e5), np.array([1e5, 2.9e5, 0.3e5, 2e5])
        got = CircularTube.thermal_drop(P, pa, mf, pb, T_up, True)
        P.kind, kind = None, P.kind
        try:
            want = CircularTube.thermal_drop(P, pa, mf, pb, T_up, True)
        finally:
            P.kind = kind
        for a, b in zip(got, want):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13 * 3e5)
        assert CircularTube.thermal_drop(P, pa, mf, pb, T_up, False)[1] is None
