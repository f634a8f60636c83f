"""The volumes' compiled laws (softflow.laws.volumes): the PV curve's lookup
against scipy's splines and the curve's arithmetic through NumPy, at thousands
of volumes, its ends and beyond; the laws' partials against central
differences; each group's compiled pass against the same law through NumPy
arrays; the pure-Python mode."""
import numpy as np
import pytest
from helpers import compiled_and_python
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator

import softflow as sf
from softflow.components.actuators import Actuator, HystereticActuator
from softflow.components.chambers import Container, LinearAccumulator
from softflow.curves.hysteresis import HysteresisLoop
from softflow.curves.pvcurve import EXTRAPOLATE, CurveRangeError
from softflow.laws import volumes as law

V_DATA = np.array([1e-6, 2.5e-6, 3e-6, 6e-6, 7e-6, 1.4e-5])
P_DATA = np.array([1.01e5, 1.28e5, 1.3e5, 1.2e5, 1.21e5, 1.5e5])
FLUIDS = [sf.air, sf.air.with_level("table"), sf.water]
FLUID_IDS = ["air", "air-table", "water"]


def _volumes():
    """4000 volumes across and beyond the data, every knot, its neighbours in
    the last bit, the ends exactly."""
    span = V_DATA[-1] - V_DATA[0]
    inside = np.linspace(V_DATA[0], V_DATA[-1], 3001)
    outside = np.concatenate([np.linspace(V_DATA[0] - 0.5 * span, V_DATA[0], 400),
                              np.linspace(V_DATA[-1], V_DATA[-1] + 0.5 * span, 400)])
    knots = np.concatenate([V_DATA, np.nextafter(V_DATA, 0.0), np.nextafter(V_DATA, 1.0)])
    return np.concatenate([inside, outside, knots, [0.0, -1e-6]])


def _numpy_lookup(curve, x):
    """The curve's piecewise cubic through NumPy: the piece by searchsorted, the
    polynomial and its derivative in Horner form (the array code the compiled
    lookup replaced)."""
    base, c0, c1, c2, c3 = curve._table.T
    k = np.searchsorted(curve.volume, x, side="right")
    x = x - base[k]
    return (c0[k] + x * (c1[k] + x * (c2[k] + x * c3[k])),
            c1[k] + x * (2 * c2[k] + 3 * x * c3[k]))


def _compiled(curve, x):
    p, d = np.empty_like(x), np.empty_like(x)
    bad = law.curve_array(curve._knots, curve._table, curve._mode, x, p, d)
    return bad, p, d


def test_codes_are_the_curve_and_fluid_codes():
    """The extrapolation codes are PVCurve's policies in order; the Params'
    fluid kinds (written out in chambers.set_fluid_law) are the laws'."""
    assert [EXTRAPOLATE.index(m) for m in ("linear", "clamp", "error")] == [
        law.LINEAR, law.CLAMP, law.ERROR]
    kinds = [Container.make_params([Container("c", f, 1e-5)]).rho_kind for f in FLUIDS]
    assert kinds == [law.IDEAL_GAS, law.GIVEN, law.CONSTANT_LIQUID]
    assert Container.make_params([Container("c", sf.air, 1e-5)]).rho_c == sf.air._RT
    assert (Container.make_params([Container("c", sf.water, 1e-5)]).rho_c
            == float(sf.water.density(1e5)))


@pytest.mark.parametrize("extrapolate", ["linear", "clamp"])
@pytest.mark.parametrize("smoothing", [None, 1e-6], ids=["pchip", "smoothing"])
def test_lookup_is_scipys_spline_and_the_numpy_arithmetic(extrapolate, smoothing):
    """Inside the data the compiled lookup is scipy's PCHIP (or, smoothed, the
    cubic Hermite spline through the smoothing spline's values and slopes,
    which is that spline) to round-off, and the NumPy arithmetic bitwise;
    beyond it the end's tangent ('linear') or the end pressure with zero slope
    ('clamp')."""
    vs = np.linspace(V_DATA[0], V_DATA[-1], 12) if smoothing else V_DATA
    ps = np.interp(vs, V_DATA, P_DATA) + (2e3 * np.sin(vs * 1e6) if smoothing else 0.0)
    curve = sf.PVCurve(volume=vs, pressure=ps, extrapolate=extrapolate, smoothing=smoothing)
    x = _volumes()
    bad, p, d = _compiled(curve, x)
    assert bad == -1
    want_p, want_d = _numpy_lookup(curve, x)
    assert p.tobytes() == want_p.tobytes() and d.tobytes() == want_d.tobytes()
    spline = (PchipInterpolator(vs, ps) if smoothing is None
              else CubicHermiteSpline(vs, curve.pressure, curve.slope))
    inside = (x >= vs[0]) & (x <= vs[-1])
    scale = np.ptp(curve.pressure) + np.abs(curve.pressure).max() * 1e-3
    np.testing.assert_allclose(p[inside], spline(x[inside]), rtol=1e-13, atol=1e-12 * scale)
    if extrapolate == "clamp":
        # the last sample is on the held extension's side (the piece to its
        # right, as bisect_right places it): its slope there is the extension's 0
        assert (d[x == vs[-1]] == 0.0).all() and (p[x == vs[-1]] == curve.pressure[-1]).all()
        inside &= x < vs[-1]
    np.testing.assert_allclose(d[inside], spline(x[inside], 1), rtol=1e-9,
                               atol=1e-9 * np.abs(curve.slope).max())
    for end, sel in ((0, x < vs[0]), (-1, x > vs[-1])):
        assert sel.sum() > 300
        if extrapolate == "clamp":
            assert (p[sel] == curve.pressure[end]).all() and (d[sel] == 0.0).all()
        else:
            line = curve.pressure[end] + curve.slope[end] * (x[sel] - vs[end])
            np.testing.assert_allclose(p[sel], line, rtol=1e-14)
            assert (d[sel] == curve.slope[end]).all()
    # the curve's own interface is the compiled lookup, on floats and arrays of any shape
    assert curve.fdf_volume(x[:3800].reshape(-1, 2))[0].tobytes() == p[:3800].tobytes()
    for k in range(0, x.size, 397):
        assert curve.fdf_volume(float(x[k])) == (p[k], d[k])


def test_lookup_refuses_beyond_the_data_where_error():
    curve = sf.PVCurve(volume=V_DATA, pressure=P_DATA, extrapolate="error")
    x = _volumes()
    inside = (x >= V_DATA[0]) & (x <= V_DATA[-1])
    bad, p, d = _compiled(curve, x[inside])
    assert bad == -1
    want = _numpy_lookup(curve, x[inside])
    assert p.tobytes() == want[0].tobytes() and d.tobytes() == want[1].tobytes()
    for v in (np.nextafter(V_DATA[0], 0.0), np.nextafter(V_DATA[-1], 1.0), np.nan, 1.0):
        y = np.array([2e-6, v, 3e-6])
        assert _compiled(curve, y)[0] == 1
        assert law.refused(law.ERROR, curve._knots, v)
        assert not law.refused(law.LINEAR, curve._knots, v)
        with pytest.raises(CurveRangeError, match="beyond its data"):
            curve.fdf_volume(y)


def test_nan_and_infinite_volumes_are_the_numpy_arithmetic():
    curve = sf.PVCurve(volume=V_DATA, pressure=P_DATA)
    x = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0])
    with np.errstate(all="ignore"):
        _, p, d = _compiled(curve, x)
        want = _numpy_lookup(curve, x)
    np.testing.assert_array_equal(p, want[0])
    np.testing.assert_array_equal(d, want[1])


def test_lookup_partial_is_the_central_difference():
    curve = sf.PVCurve(volume=V_DATA, pressure=P_DATA)
    h = 1e-6 * np.ptp(V_DATA)
    for v in _volumes()[::7]:
        if np.min(np.abs(v - V_DATA)) < 2 * h:
            continue          # (a difference across a knot sees the jump of p'')
        _, d = law.curve_point(curve._knots, curve._table, v)
        fd = (law.curve_point(curve._knots, curve._table, v + h)[0]
              - law.curve_point(curve._knots, curve._table, v - h)[0]) / (2 * h)
        assert d == pytest.approx(fd, rel=1e-6, abs=1e-7 * np.abs(curve.slope).max())


def _fd(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def _check_partials(p, RT, vol, C, pref, b, c, m):
    rho, rho_p = law.density(law.IDEAL_GAS, RT, p)
    assert rho == p / RT and rho_p == pytest.approx(_fd(lambda q: q / RT, p, 1.0), rel=1e-7)
    assert law.density(law.CONSTANT_LIQUID, 998.0, p) == (998.0, 0.0)

    def mass(q):
        return law.compliant_mass(q / RT, 1.0 / RT, q, vol, C, pref)[0]
    assert law.compliant_mass(rho, rho_p, p, vol, C, pref)[1] == pytest.approx(
        _fd(mass, p, 1e-3 * p), rel=1e-7)
    assert law.rigid_mass(rho, rho_p, vol)[1] == pytest.approx(
        _fd(lambda q: law.rigid_mass(q / RT, 1.0 / RT, vol)[0], p, 1e-3 * p), rel=1e-7)

    # the wall law at a curve p_c(V) = a + b V + c V^2, V = m / rho(p)
    def F(q, mm):
        r = q / RT
        v = mm / r
        return law.curve_law(q, r, 1.0 / RT, v, 1e5 + b * v + c * v * v, b + 2 * c * v)

    _, d_p, d_m = F(p, m)
    # (d_p = 1 + ...: its truncation error ~ (h/p)^2 d_m m)
    assert d_p == pytest.approx(_fd(lambda q: F(q, m)[0], p, 1e-4 * p), rel=1e-6,
                                abs=1e-6 * (1.0 + abs(d_m) * m))
    assert d_m == pytest.approx(_fd(lambda mm: F(p, mm)[0], m, 1e-4 * m), rel=1e-6)


def test_scalar_laws_partials_are_central_differences():
    rng = np.random.default_rng(3)
    for _ in range(200):
        p, RT = rng.uniform(2e4, 1e6), rng.uniform(2e4, 1e5)
        _check_partials(p, RT, rng.uniform(1e-6, 1e-4), rng.uniform(1e-12, 1e-10),
                        rng.uniform(5e4, 2e5), rng.uniform(-1e10, 1e10),
                        rng.uniform(-1e15, 1e15), rng.uniform(0.5, 2.0) * p / RT * 1e-5)


def _group_fd_jacobian(cls, P, V, S):
    """Central differences of the residual in p (V[:, 0]) and the mass (S[:, 0])."""
    out = []
    for where, h in (("V", 1e-3 * V[:, 0]), ("S", 1e-6 * S[:, 0])):
        up, down = V.copy(), V.copy()
        Su, Sd = S.copy(), S.copy()
        if where == "V":
            up[:, 0] += h
            down[:, 0] -= h
        else:
            Su[:, 0] += h
            Sd[:, 0] -= h
        out.append((cls.residual(P, up, Su, 0.0, False)[0][:, 0]
                    - cls.residual(P, down, Sd, 0.0, False)[0][:, 0]) / (2 * h))
    return np.column_stack(out)


def _loop():
    return HysteresisLoop.snapping((1e-6, 1.02e5), (6e-6, 1.4e5), (5e-6, 1.1e5),
                                   (1.4e-5, 1.5e5), snap_volume=1.5e-6)


def _numpy_law(kind, P, V, S):
    """The group's law through NumPy arrays and the fluid's own methods: (F, J)."""
    p, m = V[:, 0], S[:, 0]
    fl = P.fluid
    rho, rho_p = fl.density(p), fl.density_dp(p)
    if kind == "container":
        return rho * P.volume - m, np.column_stack([rho_p * P.volume, 0 * p, -1 + 0 * p])
    if kind == "accumulator":
        vol = P.volume + P.compliance * (p - P.reference_pressure)
        return rho * vol - m, np.column_stack([rho_p * vol + rho * P.compliance, -1 + 0 * p])
    vol = m / rho
    if kind == "actuator":
        pc, dpc = _numpy_lookup(P.pv, vol)
        s = P.pressure_scale
        pc, dpc = sf.pressure_atmospheric + s * (pc - sf.pressure_atmospheric), s * dpc
    else:
        loop = P.loop
        up = np.where(S[:, 1] > 0.5, vol < loop.volume_high, vol <= loop.volume_low)
        a, b = _numpy_lookup(loop.inflation, vol), _numpy_lookup(loop.deflation, vol)
        pc, dpc = np.where(up, a[0], b[0]), np.where(up, a[1], b[1])
    return p - pc, np.column_stack([1.0 + dpc * vol * (rho_p / rho), -dpc / rho])


def _group(kind, fluid, n=4):
    curve = sf.PVCurve(volume=V_DATA, pressure=P_DATA)
    if kind == "container":
        cls, comps = Container, [Container(f"c{k}", fluid, 1e-5 * (k + 1)) for k in range(n)]
    elif kind == "accumulator":
        cls = LinearAccumulator
        comps = [LinearAccumulator(f"l{k}", fluid, 1e-6 * (k + 1), 1e-11 * (k + 2),
                                   reference_pressure=1e5 + 1e3 * k) for k in range(n)]
    elif kind == "actuator":
        cls = Actuator
        comps = [Actuator(f"a{k}", fluid, curve, pressure_scale=1.0 + 0.3 * k)
                 for k in range(n)]
    else:
        cls, comps = HystereticActuator, [HystereticActuator(f"h{k}", fluid, *_loop())
                                          for k in range(n)]
    return cls, cls.make_params(comps)


@pytest.mark.parametrize("fluid", FLUIDS, ids=FLUID_IDS)
@pytest.mark.parametrize("kind", ["container", "accumulator", "actuator", "hysteretic"])
def test_group_pass_is_the_array_law_and_its_jacobian_the_differences(kind, fluid):
    """Each group's compiled pass gives the law through NumPy arrays (to
    round-off: the same operations) at volumes inside, below and beyond the
    curves' data and on either branch, and a Jacobian that central differences
    confirm (a rigid chamber of liquid admits no flow: F = mdot)."""
    cls, P = _group(kind, fluid)
    if kind == "container" and not fluid.compressible:
        V = np.array([[1.2e5, 1e-5]] * 4)
        F, J = cls.residual(P, V, np.ones((4, 1)), 0.0, True)
        assert (F[:, 0] == V[:, 1]).all() and (J == [0.0, 1.0, 0.0]).all()
        return
    rng = np.random.default_rng(5)
    for trial in range(40):
        p = rng.uniform(0.9e5, 2.5e5, 4)
        vol = rng.uniform(0.2e-6, 2e-5, 4) if trial % 2 else rng.uniform(1e-6, 1.4e-5, 4)
        rho = np.asarray(fluid.density(p)) * rng.uniform(0.95, 1.05, 4)
        V = np.column_stack([p, rng.normal(0.0, 1e-5, 4)])
        S = (rho * vol)[:, None]
        if kind == "hysteretic":
            S = np.column_stack([S, rng.integers(0, 2, 4).astype(float)])
        F, J = cls.residual(P, V, S, 0.0, True)
        F0, _ = cls.residual(P, V, S, 0.0, False)
        want_F, want_J = _numpy_law(kind, P, V, S)
        scale = np.abs(V[:, 0]).max() if kind in ("actuator", "hysteretic") else np.abs(S).max()
        np.testing.assert_allclose(F[:, 0], want_F, rtol=1e-13, atol=1e-13 * scale)
        assert F0.tobytes() == F.tobytes()
        got_J = J[:, [0, 2]] if kind == "container" else J
        np.testing.assert_allclose(got_J, want_J[:, [0, -1]] if kind == "container" else want_J,
                                   rtol=1e-13, atol=1e-300)
        if trial < 6:
            fd = _group_fd_jacobian(cls, P, V, S)
            if kind == "hysteretic":
                # a difference across the hand-over between the branches sees their jump
                keep = np.abs(vol - _loop().volume_high) > 1e-8
                keep &= np.abs(vol - _loop().volume_low) > 1e-8
                fd, got_J = fd[keep], got_J[keep]
            for j in range(2):
                np.testing.assert_allclose(got_J[:, j], fd[:, j], rtol=2e-5,
                                           atol=1e-6 * np.abs(got_J[:, j]).max())


def test_refused_volume_in_a_group_raises_the_curves_error():
    """A group pass that meets a volume its 'error' curve refuses raises the
    curve's CurveRangeError, as the curve's interface does."""
    curve = sf.PVCurve(volume=V_DATA, pressure=P_DATA, extrapolate="error")
    P = Actuator.make_params([Actuator(f"a{k}", sf.air, curve) for k in range(3)])
    p = np.full(3, 1.2e5)
    V = np.column_stack([p, np.zeros(3)])
    S = (np.asarray(sf.air.density(p)) * np.array([2e-6, 2e-5, 3e-6]))[:, None]
    with pytest.raises(CurveRangeError, match="beyond its data"):
        Actuator.residual(P, V, S, 0.0, True)


def test_pure_python_mode_gives_the_same_numbers():
    """NUMBA_DISABLE_JIT=1 runs the same functions as plain Python: the lookup,
    the refusal and the group passes give the compiled numbers."""
    expression = (
        "(lambda v: (lambda np, k, t: ["
        "list(v.curve_point(k, t, x)) for x in (5e-7, 1e-6, 2e-6, 3e-6, 6.5e-6, 1.4e-5, 3e-5)]"
        " + [float(v.refused(v.ERROR, k, 2e-5)), float(v.piece(k, 3e-6)),"
        " list(v.compliant_mass(1.2, 1e-5, 1.2e5, 1e-6, 1e-11, 1e5)),"
        " list(v.curve_law(1.2e5, 1.4, 1e-5, 3e-6, 1.1e5, 3e9))])"
        "(__import__('numpy'), __import__('numpy').array([1e-6, 3e-6, 6e-6, 1.4e-5]),"
        " __import__('softflow').PVCurve(volume=[1e-6, 3e-6, 6e-6, 1.4e-5],"
        " pressure=[1.01e5, 1.3e5, 1.2e5, 1.5e5])._table))"
        "(__import__('softflow.laws.volumes', fromlist=['volumes']))")
    compiled, python, _ = compiled_and_python(expression)
    np.testing.assert_array_equal(python, compiled)
