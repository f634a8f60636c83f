"""Analytic Jacobians of the library components against finite differences,
and the friction correlations against the ``fluids`` package."""
import math

import fluids.friction
import numpy as np
import pytest

import softflow as sf
from softflow.correlations.friction import (fRe_blended, friction_Haaland, friction_laminar,
                                            smoothstep)

P0 = sf.pressure_atmospheric
RTOL = 1e-5          # relative tolerance of analytic vs finite-difference entries
ATOL_ROW = 1e-8      # absolute floor, relative to the largest scaled entry of the row
REL_STEP = 1e-6      # finite-difference step relative to the variable's scale


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------
def _re_per_mf(tube):
    area = math.pi * tube.diameter ** 2 / 4
    return tube.diameter / (tube.fluid.mu * area)


def _massflow_for_re(tubes, re):
    """Mass flow through each tube giving the Reynolds number re (signed)."""
    return np.array([r / _re_per_mf(t) for t, r in zip(tubes, re)])


class Case:
    """One kernel evaluation point: a class, its instances, V, S, t, dt and the
    typical size of each interface variable (for steps and tolerances)."""

    def __init__(self, cls, instances, V, S, t=0.37, dt=1e-3, scale=None):
        self.cls = cls
        self.instances = instances
        self.V = np.asarray(V, dtype=float)
        self.S = np.asarray(S, dtype=float).reshape(len(instances), len(cls.state_spec))
        self.t = t
        self.dt = dt
        self.scale = np.asarray(scale, dtype=float)
        assert self.V.shape == (len(instances), len(instances[0].interface_variables()))
        assert self.scale.shape == (self.V.shape[1],)


def _random_pressures(rng, n):
    return rng.uniform(1.0e5, 3.0e5, n)


def _source_cases(rng):
    cases = {}
    n = 4
    srcs = [sf.PressureSource("ps0", pressure=1.2e5),
            sf.PressureSource("ps1", pressure=sf.Q_(2.5, "bar")),
            sf.PressureSource("ps2", pressure=lambda t: P0 + 3e4 * math.sin(3 * t)),
            sf.PressureSource("ps3", pressure=lambda t: sf.Q_(1.5 + t, "bar"))]
    V = np.column_stack([_random_pressures(rng, n), rng.uniform(-1e-3, 1e-3, n)])
    cases["PressureSource"] = Case(sf.PressureSource, srcs, V, np.zeros((n, 0)),
                                   scale=[1e5, 1e-3])
    srcs = [sf.MassFlowSource("m0", massflow=1e-4),
            sf.MassFlowSource("m1", massflow=-3e-5),
            sf.MassFlowSource("m2", massflow=lambda t: 2e-4 * math.cos(t)),
            sf.MassFlowSource("m3", massflow=sf.Q_(5, "g/s"))]
    V = np.column_stack([_random_pressures(rng, n), rng.uniform(-1e-3, 1e-3, n)])
    cases["MassFlowSource"] = Case(sf.MassFlowSource, srcs, V, np.zeros((n, 0)),
                                   scale=[1e5, 1e-3])
    for fluid in (sf.air, sf.water):
        srcs = [sf.VolumeFlowSource("q0", volumeflow=1.8e-6, fluid=fluid),
                sf.VolumeFlowSource("q1", volumeflow=-1e-6, fluid=fluid),
                sf.VolumeFlowSource("q2", volumeflow=lambda t: 1e-6 * (1 + t), fluid=fluid),
                sf.VolumeFlowSource("q3", volumeflow=sf.Q_(2, "ml/s"), fluid=fluid)]
        mf = rng.uniform(-1e-3, 1e-3, n) * fluid.rho / 1000
        V = np.column_stack([_random_pressures(rng, n), mf])
        cases[f"VolumeFlowSource-{fluid.name}"] = Case(
            sf.VolumeFlowSource, srcs, V, np.zeros((n, 0)), scale=[1e5, 1e-6 * fluid.rho])
    return cases


def _tube_instances(fluid, **kw):
    return [sf.CircularTube("t0", fluid, length=0.6, diameter=1e-3, **kw),
            sf.CircularTube("t1", fluid, length=0.05, diameter=2e-3, roughness=0.0, **kw),
            sf.CircularTube("t2", fluid, length=2.0, diameter=4e-3, roughness=5e-5, **kw),
            sf.CircularTube("t3", fluid, length=sf.Q_(25, "cm"), diameter=sf.Q_(0.8, "mm"),
                            roughness=1e-5, **kw)]


TUBE_REGIMES = {
    "laminar": lambda rng, n: rng.uniform(100, 2000, n),
    "transition": lambda rng, n: rng.uniform(2700, 3300, n),     # Re ~ 3000
    "turbulent": lambda rng, n: rng.uniform(1.5e4, 2.5e4, n),    # Re ~ 2e4
    "zero": lambda rng, n: np.zeros(n),
    "negative": lambda rng, n: -np.array([800.0, 3000.0, 2e4, 6e4])[:n],
}


def _tube_cases(rng):
    cases = {}
    for fluid in (sf.water, sf.air):
        for regime, draw in TUBE_REGIMES.items():
            tubes = _tube_instances(fluid)
            n = len(tubes)
            re = draw(rng, n)
            mf = _massflow_for_re(tubes, re)
            pa = _random_pressures(rng, n)
            pb = _random_pressures(rng, n)
            V = np.column_stack([pa, mf, pb, -mf * rng.uniform(0.5, 1.5, n)])
            mf_scale = max(np.abs(mf).max(), _massflow_for_re(tubes[:1], [1000.0])[0])
            cases[f"CircularTube-{fluid.name}-{regime}"] = Case(
                sf.CircularTube, tubes, V, np.zeros((n, 0)), scale=[1e5, mf_scale, 1e5, mf_scale])
    # a group with its own blend range, evaluated inside it
    tubes = _tube_instances(sf.water, Re_laminar=1800, Re_turbulent=5000)
    mf = _massflow_for_re(tubes, [2500.0, 3500.0, 4500.0, -3000.0])
    V = np.column_stack([_random_pressures(rng, 4), mf, _random_pressures(rng, 4), -mf])
    cases["CircularTube-water-custom-blend"] = Case(
        sf.CircularTube, tubes, V, np.zeros((4, 0)), scale=[1e5, 1e-3, 1e5, 1e-3])
    cases.update(_tube_option_cases())
    return cases


TUBE_OPTIONS = {
    # friction correlations: closed form, exact Colebrook, tabulated fluids method, laminar
    "Colebrook": (dict(friction="Colebrook"), (sf.water,)),
    "Churchill": (dict(friction="Churchill"), (sf.water,)),
    "Swamee-Jain": (dict(friction="Swamee-Jain"), (sf.water,)),
    "Serghides_2": (dict(friction="Serghides_2"), (sf.water,)),
    "laminar-only": (dict(friction="laminar"), (sf.water,)),
    # isothermal compressible flow (the acceleration term depends on p_a, p_b and mdot)
    "isothermal": (dict(compressible="isothermal"), (sf.air,)),
    "isothermal-Colebrook": (dict(compressible="isothermal", friction="Colebrook"), (sf.air,)),
}


def _tube_option_cases():
    """CircularTube options in every flow regime (own generator: the draws of the
    cases above stay as they were)."""
    rng = np.random.default_rng(4096)
    cases = {}
    for option, (kw, fluids_) in TUBE_OPTIONS.items():
        for fluid in fluids_:
            for regime, draw in TUBE_REGIMES.items():
                tubes = _tube_instances(fluid, **kw)
                n = len(tubes)
                mf = _massflow_for_re(tubes, draw(rng, n))
                V = np.column_stack([_random_pressures(rng, n), mf, _random_pressures(rng, n),
                                     -mf * rng.uniform(0.5, 1.5, n)])
                mf_scale = max(np.abs(mf).max(), _massflow_for_re(tubes[:1], [1000.0])[0])
                cases[f"CircularTube-{option}-{fluid.name}-{regime}"] = Case(
                    sf.CircularTube, tubes, V, np.zeros((n, 0)),
                    scale=[1e5, mf_scale, 1e5, mf_scale])
    return cases


def _chamber_cases(rng):
    cases = {}
    for fluid in (sf.air, sf.water):
        cont = [sf.Container("c0", fluid, volume=1e-6),
                sf.Container("c1", fluid, volume=sf.Q_(50, "ml"), initial_pressure=2e5),
                sf.Container("c2", fluid, volume=3e-3, initial_pressure=sf.Q_(1.5, "bar"))]
        n = len(cont)
        S = np.array([c.initial_states() for c in cont]) * rng.uniform(0.9, 1.1, (n, 1))
        V = np.column_stack([_random_pressures(rng, n), rng.uniform(-1e-4, 1e-4, n)])
        cases[f"Container-{fluid.name}"] = Case(sf.Container, cont, V, S, dt=2e-3,
                                                scale=[1e5, 1e-4])
        acc = [sf.LinearAccumulator("a0", fluid, volume=1e-6, compliance=1e-10),
               sf.LinearAccumulator("a1", fluid, volume=2e-5, compliance=sf.Q_(1, "ml/bar"),
                                    reference_pressure=1.2e5),
               sf.LinearAccumulator("a2", fluid, volume=sf.Q_(5, "ml"), compliance=3e-11,
                                    initial_pressure=1.5e5)]
        S = np.array([a.initial_states() for a in acc]) * rng.uniform(0.9, 1.1, (n, 1))
        V = np.column_stack([_random_pressures(rng, n), rng.uniform(-1e-4, 1e-4, n)])
        cases[f"LinearAccumulator-{fluid.name}"] = Case(sf.LinearAccumulator, acc, V, S,
                                                        dt=5e-4, scale=[1e5, 1e-4])
    return cases


def _all_cases():
    rng = np.random.default_rng(20240611)
    cases = {}
    cases.update(_source_cases(rng))
    cases.update(_tube_cases(rng))
    cases.update(_chamber_cases(rng))
    return cases


CASES = _all_cases()
LIBRARY_CLASSES = (sf.PressureSource, sf.MassFlowSource, sf.VolumeFlowSource, sf.CircularTube,
                   sf.Container, sf.LinearAccumulator)


def _evaluate(case, V, jac):
    P = case.cls.make_params(case.instances)
    return case.cls.kernel(P, V, case.S.copy(), case.t, case.dt, jac)


def _fd_jacobian(case):
    """Central differences: D[i, e, k] = dF_e/dV_k of instance i, perturbing one
    instance at a time; also checks that the other instances do not move."""
    V0 = case.V
    n, nv = V0.shape
    F0, _ = _evaluate(case, V0.copy(), False)
    neq = F0.shape[1]
    D = np.zeros((n, neq, nv))
    for i in range(n):
        for k in range(nv):
            h = REL_STEP * max(abs(V0[i, k]), case.scale[k])
            Vp = V0.copy()
            Vm = V0.copy()
            Vp[i, k] += h
            Vm[i, k] -= h
            Fp, _ = _evaluate(case, Vp, False)
            Fm, _ = _evaluate(case, Vm, False)
            others = np.arange(n) != i
            np.testing.assert_array_equal(Fp[others], F0[others],
                                          err_msg="instances of a kernel call are coupled")
            D[i, :, k] = (Fp[i] - Fm[i]) / (2 * h)
    return D


# ---------------------------------------------------------------------------------------
# kernels
# ---------------------------------------------------------------------------------------
def test_every_library_class_is_covered():
    covered = {c.cls for c in CASES.values()}
    assert covered == set(LIBRARY_CLASSES)


@pytest.mark.parametrize("cls", LIBRARY_CLASSES, ids=lambda c: c.__name__)
def test_jac_pattern_is_well_formed(cls):
    inst = CASES[next(k for k, c in CASES.items() if c.cls is cls)].instances[0]
    nv = len(inst.interface_variables())
    neq = inst.n_equations
    pat = list(cls.jac_pattern)
    assert len(set(pat)) == len(pat), "duplicate entries in jac_pattern"
    for e, k in pat:
        assert 0 <= e < neq and 0 <= k < nv
    # every equation depends on something
    assert {e for e, _ in pat} == set(range(neq))


@pytest.mark.parametrize("name", sorted(CASES))
def test_kernel_shapes_and_jac_false(name):
    case = CASES[name]
    n = len(case.instances)
    F, J = _evaluate(case, case.V.copy(), True)
    F2, J2 = _evaluate(case, case.V.copy(), False)
    assert F.shape == (n, case.instances[0].n_equations)
    assert J.shape == (n, len(case.cls.jac_pattern))
    assert J2 is None
    np.testing.assert_array_equal(F, F2)
    assert np.isfinite(F).all() and np.isfinite(J).all()


@pytest.mark.parametrize("name", sorted(CASES))
def test_jacobian_matches_finite_differences(name):
    case = CASES[name]
    _, J = _evaluate(case, case.V.copy(), True)
    D = _fd_jacobian(case)
    scale = case.scale
    Ds = D * scale[None, None, :]                      # dF per typical change of V
    row_max = np.abs(Ds).max(axis=2)                   # (n, neq)
    listed = set()
    for j, (e, k) in enumerate(case.cls.jac_pattern):
        listed.add((e, k))
        got = J[:, j] * scale[k]
        want = Ds[:, e, k]
        tol = RTOL * np.abs(want) + ATOL_ROW * row_max[:, e] + 1e-300
        bad = np.abs(got - want) > tol
        assert not bad.any(), (
            f"{name}: dF{e}/dV{k} analytic {J[bad, j]} vs finite differences {D[bad, e, k]}")
    neq, nv = D.shape[1:]
    for e in range(neq):
        for k in range(nv):
            if (e, k) in listed:
                continue
            off = np.abs(Ds[:, e, k])
            assert (off <= ATOL_ROW * row_max[:, e] + 1e-300).all(), (
                f"{name}: dF{e}/dV{k} = {D[:, e, k]} is not zero but ({e}, {k}) is not in "
                f"jac_pattern")


def test_tube_cases_hit_the_intended_regimes():
    """Guards the test set-up itself: the tube cases cover each flow regime."""
    for fluid in ("water", "air"):
        for regime, (lo, hi) in {"laminar": (0, 2300), "transition": (2300, 4000),
                                 "turbulent": (4000, 1e6), "zero": (0, 0)}.items():
            case = CASES[f"CircularTube-{fluid}-{regime}"]
            re = np.abs(case.V[:, 1]) * np.array([_re_per_mf(t) for t in case.instances])
            assert ((re >= lo) & (re <= hi)).all(), (fluid, regime, re)
        case = CASES[f"CircularTube-{fluid}-negative"]
        assert (case.V[:, 1] < 0).all()


def test_tube_laminar_residual_is_hagen_poiseuille():
    """At low Re the pressure equation is the Hagen–Poiseuille law."""
    t = sf.CircularTube("t", sf.water, length=0.6, diameter=1e-3)
    P = sf.CircularTube.make_params([t])
    q = 1e-7  # m^3/s, Re ~ 127
    mf = q * sf.water.rho
    dp_hp = 128 * sf.water.mu * 0.6 * q / (math.pi * 1e-3 ** 4)
    V = np.array([[P0 + dp_hp, mf, P0, -mf]])
    F, _ = sf.CircularTube.kernel(P, V, np.zeros((1, 0)), 0.0, 1e-3, False)
    np.testing.assert_allclose(F[0], [0.0, 0.0], atol=1e-9 * dp_hp)


# ---------------------------------------------------------------------------------------
# friction correlations
# ---------------------------------------------------------------------------------------
RE_TURB = np.logspace(np.log10(4e3), 8, 41)
ED_VALUES = (0.0, 1e-6, 1.5e-3, 1e-4, 1e-2, 0.05)


def test_friction_laminar_matches_fluids():
    Re = np.logspace(-2, np.log10(2300), 31)
    got = friction_laminar(Re)
    want = np.array([fluids.friction.friction_laminar(r) for r in Re])
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=0)


@pytest.mark.parametrize("eD", ED_VALUES)
def test_haaland_matches_fluids(eD):
    got, _ = friction_Haaland(RE_TURB, eD)
    want = np.array([fluids.friction.Haaland(Re=r, eD=eD) for r in RE_TURB])
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=0)


def test_haaland_vectorized_over_roughness():
    eD = np.array(ED_VALUES)
    Re = np.full(len(eD), 3e4)
    got, dgot = friction_Haaland(Re, eD)
    for i, e in enumerate(ED_VALUES):
        f1, d1 = friction_Haaland(3e4, e)
        assert got[i] == pytest.approx(f1, rel=1e-14)
        assert dgot[i] == pytest.approx(d1, rel=1e-14)


@pytest.mark.parametrize("eD", ED_VALUES)
def test_haaland_derivative_matches_finite_differences(eD):
    h = 1e-6 * RE_TURB
    f, df = friction_Haaland(RE_TURB, eD)
    fp, _ = friction_Haaland(RE_TURB + h, eD)
    fm, _ = friction_Haaland(RE_TURB - h, eD)
    fd = (fp - fm) / (2 * h)
    assert (df < 0).all()   # friction falls with Re
    # compare the dimensionless sensitivities Re/f df/dRe: when f flattens out (rough
    # pipes, high Re) the difference quotient is limited by round-off in f
    np.testing.assert_allclose(RE_TURB * df / f, RE_TURB * fd / f, rtol=1e-6, atol=1e-8)


def test_smoothstep_values_and_derivative():
    x = np.linspace(-1.0, 3.0, 401)
    w, dw = smoothstep(x, 0.5, 2.0)
    assert (w[x <= 0.5] == 0).all() and (w[x >= 2.0] == 1).all()
    assert (np.diff(w) >= 0).all()
    inner = (x > 0.51) & (x < 1.99)
    h = 1e-6
    fd = (smoothstep(x + h, 0.5, 2.0)[0] - smoothstep(x - h, 0.5, 2.0)[0]) / (2 * h)
    np.testing.assert_allclose(dw[inner], fd[inner], rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("eD", (0.0, 1e-4, 1e-2))
def test_fRe_blended_limits(eD):
    Re_lam = np.array([0.0, 1e-3, 1.0, 500.0, 2299.0])
    phi, dphi = fRe_blended(Re_lam, eD)
    np.testing.assert_array_equal(phi, 64.0)
    np.testing.assert_array_equal(dphi, 0.0)
    Re_t = np.array([4000.0, 4001.0, 2e4, 1e6])
    phi, dphi = fRe_blended(Re_t, eD)
    want = np.array([fluids.friction.Haaland(Re=r, eD=eD) * r for r in Re_t])
    np.testing.assert_allclose(phi, want, rtol=1e-10)
    f, df = friction_Haaland(Re_t, eD)
    np.testing.assert_allclose(dphi, f + Re_t * df, rtol=1e-10)


@pytest.mark.parametrize("eD", (0.0, 1e-4, 1e-2))
@pytest.mark.parametrize("bounds", [(2300.0, 4000.0), (1800.0, 5000.0)])
def test_fRe_blended_derivative_matches_finite_differences(eD, bounds):
    lo, hi = bounds
    Re = np.concatenate([np.linspace(10, lo * 0.99, 7), np.linspace(lo * 1.01, hi * 0.99, 23),
                         np.linspace(hi * 1.01, 1e6, 11)])
    h = 1e-6 * Re
    phi, dphi = fRe_blended(Re, eD, lo, hi)
    fd = (fRe_blended(Re + h, eD, lo, hi)[0] - fRe_blended(Re - h, eD, lo, hi)[0]) / (2 * h)
    np.testing.assert_allclose(dphi, fd, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("eD", (0.0, 1e-4, 1e-2))
@pytest.mark.parametrize("bounds", [(2300.0, 4000.0), (1800.0, 5000.0)])
def test_fRe_blended_is_C1_at_blend_bounds(eD, bounds):
    lo, hi = bounds
    for edge in (lo, hi):
        d = 1e-7 * edge
        (pm, pp), (dm, dp) = fRe_blended(np.array([edge - d, edge + d]), eD, lo, hi)
        slope_scale = abs(fRe_blended(hi * 1.5, eD, lo, hi)[1]) + abs(
            fRe_blended(0.5 * (lo + hi), eD, lo, hi)[1])
        # value continuous: jump no larger than slope * 2d
        assert abs(pp - pm) <= 2 * d * slope_scale * 1.01 + 1e-12, (edge, pm, pp)
        # slope continuous
        assert abs(dp - dm) <= 1e-4 * slope_scale, (edge, dm, dp)
        # and consistent with the one-sided difference quotients
        h = 1e-4 * edge
        left = (fRe_blended(edge, eD, lo, hi)[0] - fRe_blended(edge - h, eD, lo, hi)[0]) / h
        right = (fRe_blended(edge + h, eD, lo, hi)[0] - fRe_blended(edge, eD, lo, hi)[0]) / h
        assert abs(right - left) <= 1e-2 * slope_scale, (edge, left, right)


def test_fRe_blended_scalar_and_array_agree():
    Re = np.array([0.0, 1000.0, 3000.0, 5000.0, 1e5])
    phi, dphi = fRe_blended(Re, 1e-4)
    for i, r in enumerate(Re):
        p1, d1 = fRe_blended(float(r), 1e-4)
        assert float(p1) == phi[i] and float(d1) == dphi[i]
