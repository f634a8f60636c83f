"""The rate-form contract of the library components: analytic dr/dV of every
``rates`` and dF/dV, dF/dX of every ``residual`` against central finite
differences, rates free of the continuous states, and the step equations as
F(V, S + dt·r(V)) (softflow.solve.discretize)."""
import numpy as np
import pytest

import softflow as sf
from softflow.components.base import LibraryComponent
from softflow.components.tubes import InertialCircularTube
from softflow.paper_scenes import curve_peak_valley, loop_hysteretic
from softflow.solve.discretize import step_plan
from softflow.solve.thermal import configure_thermal

P0 = sf.pressure_atmospheric
REL_STEP = 1e-6
RTOL, ATOL_ROW = 1e-5, 1e-8
#: typical size of each quantity: finite-difference steps and tolerance floors
SCALE = {"pressure": 1e5, "massflow": 1e-4, "temperature": 300.0, "energyflow": 30.0,
         "heatflow": 30.0,
         "mass": 1e-5, "energy": 10.0, "volume": 1e-5, "dimensionless": 1.0}


def _instances():
    """(name, components) covering every rate-form library class."""
    air, water = sf.air, sf.water
    pv = curve_peak_valley()
    loop = loop_hysteretic()
    out = [
        ("PressureSource", [sf.PressureSource(f"ps{i}", pressure=1.5e5 + i) for i in range(3)]),
        ("MassFlowSource", [sf.MassFlowSource(f"ms{i}", massflow=1e-4 * i) for i in range(3)]),
        ("VolumeFlowSource", [sf.VolumeFlowSource(f"vs{i}", volumeflow=1e-6 * (i - 1),
                                                  fluid=air) for i in range(3)]),
        ("CircularTube-air", [sf.CircularTube(f"t{i}", air, 0.5, 1e-3 * (i + 1))
                              for i in range(3)]),
        ("CircularTube-isothermal", [sf.CircularTube(f"t{i}", air, 1.0, 2e-3,
                                                     compressible="isothermal")
                                     for i in range(3)]),
        ("InertialCircularTube-water", [sf.CircularTube(f"t{i}", water, 0.5, 1e-3 * (i + 1),
                                                        inertance=True) for i in range(3)]),
        ("InertialCircularTube-air", [sf.CircularTube(f"t{i}", air, 0.5, 1e-3, inertance=True,
                                                      compressible="isothermal")
                                      for i in range(3)]),
        ("Orifice-K", [sf.Orifice(f"o{i}", air, diameter=1e-3, K=2.0) for i in range(3)]),
        ("Orifice-ISO", [sf.Orifice(f"o{i}", air, C=1e-8, b=0.3) for i in range(3)]),
        ("CheckValve", [sf.CheckValve(f"c{i}", air, 1e-3, cracking_pressure=5e3,
                                      leakage=1e-12) for i in range(3)]),
        ("TeslaValve", [sf.TeslaValve(f"v{i}", air, 0.05, 1e-3) for i in range(3)]),
        ("SnappingValve", [sf.SnappingValve(f"s{i}", air, 2e4, 5e3, 1e-11,
                                            initially_open=bool(i % 2)) for i in range(3)]),
        ("Container-air", [sf.Container(f"k{i}", air, 1e-4 * (i + 1)) for i in range(3)]),
        ("Container-water", [sf.Container(f"k{i}", water, 1e-4) for i in range(3)]),
        ("LinearAccumulator-water", [sf.LinearAccumulator(f"a{i}", water, 1e-5, 1e-11 * (i + 1))
                                     for i in range(3)]),
        ("LinearAccumulator-air", [sf.LinearAccumulator(f"a{i}", air, 1e-5, 1e-11)
                                   for i in range(3)]),
        ("Actuator-pvcurve", [sf.Actuator(f"act{i}", air, pv) for i in range(3)]),
        ("Actuator-scaled", [sf.Actuator(f"act{i}", air, pv, pressure_scale=0.8 + 0.3 * i)
                             for i in range(3)]),
        ("Actuator-callable", [sf.Actuator(f"act{i}", water, lambda v: P0 + 1e9 * v,
                                           initial_volume=1e-6) for i in range(3)]),
        ("HystereticActuator", [sf.HystereticActuator(f"h{i}", air, *loop) for i in range(3)]),
    ]
    return out


def _thermal_instances():
    """Thermal variants in rate form: the flow elements and the sources."""
    out = []
    for name, comps in _instances():
        cls = type(comps[0])
        if "water" in name or "callable" in name or cls in (sf.Container, sf.LinearAccumulator,
                                                            sf.Actuator, sf.HystereticActuator):
            continue
        s = sf.System()
        s.add(*comps)
        if isinstance(comps[0], (sf.PressureSource, sf.MassFlowSource)):
            for c in comps:
                tube = sf.CircularTube(f"tube_{c.label}", sf.air, length=0.1, diameter=1e-3)
                s.add(tube)
                s.connect(c, (tube.label, "a"))
        configure_thermal(s, "adiabatic")
        out.append((f"thermal-{name}", comps))
    return out


def _thermal_volume_instances():
    """Thermal volumes in rate form: free (adiabatic, heat transfer) and held at
    their wall temperature, at the ideal and the eos level."""
    air, eos = sf.air, sf.Fluid("air", level="eos")
    pv = curve_peak_valley()
    loop = loop_hysteretic()
    makers = {
        "Container": lambda i, fl, kw: sf.Container(f"k{i}", fl, 1e-4 * (i + 1), 2e5, **kw),
        "LinearAccumulator": lambda i, fl, kw: sf.LinearAccumulator(
            f"a{i}", fl, 1e-5, 1e-11 * (i + 1), initial_pressure=1.5e5, **kw),
        "Actuator": lambda i, fl, kw: sf.Actuator(f"act{i}", fl, pv, **kw),
        "Actuator-scaled": lambda i, fl, kw: sf.Actuator(f"act{i}", fl, pv,
                                                         pressure_scale=0.8 + 0.3 * i, **kw),
        "Actuator-callable": lambda i, fl, kw: sf.Actuator(
            f"act{i}", fl, lambda v: P0 + 1e10 * v + 3e14 * v * v, initial_volume=1e-6,
            **kw),
        "HystereticActuator": lambda i, fl, kw: sf.HystereticActuator(f"h{i}", fl, *loop,
                                                                      **kw),
    }
    modes = {"adiabatic": {}, "heat_transfer": {"hA": 0.3},
             "held": {"thermal": "isothermal", "wall_temperature": 310.0}}
    out = []
    for name, make in makers.items():
        for mode, kw in modes.items():
            for fl in ((air, eos) if name == "Container" else (air,)):
                comps = [make(i, fl, kw) for i in range(3)]
                s = sf.System()
                s.add(*comps)
                configure_thermal(s, "adiabatic")
                out.append((f"thermal-{name}-{mode}-{fl.level}", comps))
    return out


class Case:
    def __init__(self, comps, seed):
        rng = np.random.default_rng(seed)
        self.cls = comps[0].kernel_class()
        self.P = self.cls.make_params(comps)
        n = len(comps)
        quantities = [v.quantity for _, v in comps[0].interface_variables()]
        cols = []
        for q in quantities:
            if q == "pressure":
                cols.append(rng.uniform(1.1e5, 2.5e5, n))
            elif q == "massflow":
                cols.append(rng.uniform(-1, 1, n) * (1e-3 if getattr(comps[0].fluid, 'rho', 1.0) > 100 else 1e-4))
            elif q == "temperature":
                cols.append(rng.uniform(260, 380, n))
            else:
                cols.append(rng.uniform(-30, 30, n))
        self.V = np.column_stack(cols)
        self.vscale = np.array([SCALE[q] for q in quantities])
        S = np.array([c.initial_state_values() for c in comps], dtype=float).reshape(n, -1)
        plan = step_plan(self.cls)
        S[:, plan.cont] *= 1 + 0.05 * rng.random((n, plan.cont.size))
        self.S = S
        self.cont = plan.cont
        self.sscale = np.array([max(abs(S[:, i]).max(), SCALE[self.cls.state_spec[i][1]])
                                for i in plan.cont])


CASES = {name: Case(comps, k) for k, (name, comps) in
         enumerate(_instances() + _thermal_instances() + _thermal_volume_instances())}


def _check(name, got_cols, pattern, D, scale, what):
    """got_cols (n, len(pattern)) against D (n, n_out, n_in), scaled by the inputs."""
    Ds = D * scale[None, None, :]
    row_max = np.abs(Ds).max(axis=2)
    listed = set()
    for j, (e, k) in enumerate(pattern):
        listed.add((e, k))
        got = np.broadcast_to(got_cols[j], (D.shape[0],)) * scale[k]
        want = Ds[:, e, k]
        bad = np.abs(got - want) > RTOL * np.abs(want) + ATOL_ROW * row_max[:, e] + 1e-300
        assert not bad.any(), f"{name}: {what}[{e}, {k}] analytic {got} vs FD {want}"
    for e in range(D.shape[1]):
        for k in range(D.shape[2]):
            if (e, k) not in listed:
                assert (np.abs(Ds[:, e, k]) <= ATOL_ROW * row_max[:, e] + 1e-300).all(), (
                    f"{name}: {what}[{e}, {k}] = {D[:, e, k]} but not in the pattern")


def _fd(f, x0, scale):
    """Central differences of f (n, m) in each column of x0 (n, k), instance by instance."""
    n, k = x0.shape
    m = f(x0).shape[1]
    D = np.zeros((n, m, k))
    for i in range(n):
        for j in range(k):
            h = REL_STEP * max(abs(x0[i, j]), scale[j])
            xp, xm = x0.copy(), x0.copy()
            xp[i, j] += h
            xm[i, j] -= h
            D[i, :, j] = (f(xp)[i] - f(xm)[i]) / (2 * h)
    return D


def test_every_library_class_states_rates_and_residuals():
    import softflow.components as comps
    classes = {c for c in vars(comps).values()
               if isinstance(c, type) and issubclass(c, LibraryComponent)
               and c is not LibraryComponent}
    covered = {type(c.P.components[0]) for c in CASES.values()}
    assert classes <= covered | {InertialCircularTube}, classes - covered
    for cls in covered:
        assert cls.kernel.__func__ is LibraryComponent.kernel.__func__, cls
        assert "dt" not in cls.residual.__code__.co_varnames, cls
        assert "dt" not in cls.rates.__code__.co_varnames, cls


@pytest.mark.parametrize("name", list(CASES))
def test_rates_jacobian_matches_finite_differences(name):
    c = CASES[name]
    R, dR = c.cls.rates(c.P, c.V, c.S, True)
    assert R.shape == (c.V.shape[0], c.cont.size)
    np.testing.assert_array_equal(R, c.cls.rates(c.P, c.V, c.S, False)[0])
    if not c.cont.size:
        return
    D = _fd(lambda V: c.cls.rates(c.P, V, c.S, False)[0], c.V, c.vscale)
    _check(name, dR, c.cls.rate_pattern, D, c.vscale, "dr/dV")
    # rates do not depend on the continuous states (explicit step updates)
    S2 = c.S.copy()
    S2[:, c.cont] *= 1.3
    np.testing.assert_array_equal(c.cls.rates(c.P, c.V, S2, False)[0], R)


@pytest.mark.parametrize("name", list(CASES))
def test_residual_jacobian_matches_finite_differences(name):
    c = CASES[name]
    F, J = c.cls.residual(c.P, c.V, c.S, 0.3, True)
    nr = len(c.cls.residual_pattern)
    assert J.shape == (F.shape[0], nr + len(c.cls.state_jac_pattern))
    np.testing.assert_array_equal(F, c.cls.residual(c.P, c.V, c.S, 0.3, False)[0])
    D = _fd(lambda V: c.cls.residual(c.P, V, c.S, 0.3, False)[0], c.V, c.vscale)
    _check(name, J[:, :nr].T, c.cls.residual_pattern, D, c.vscale, "dF/dV")
    if c.cont.size:
        def of_states(X):
            S = c.S.copy()
            S[:, c.cont] = X
            return c.cls.residual(c.P, c.V, S, 0.3, False)[0]
        D = _fd(of_states, c.S[:, c.cont], c.sscale)
        _check(name, J[:, nr:].T, c.cls.state_jac_pattern, D, c.sscale, "dF/dX")


@pytest.mark.parametrize("name", list(CASES))
def test_step_equations_are_the_residual_at_the_updated_states(name):
    c = CASES[name]
    dt = 2e-3
    R, _ = c.cls.rates(c.P, c.V, c.S, False)
    X = c.S.copy()
    X[:, c.cont] += dt * R
    F_step, _ = c.cls.kernel(c.P, c.V, c.S, 0.3, dt, False)
    np.testing.assert_array_equal(F_step, c.cls.residual(c.P, c.V, X, 0.3, False)[0])
    new = c.cls.update(c.P, c.V, c.S, dt)
    np.testing.assert_array_equal(new[:, c.cont], X[:, c.cont])


@pytest.mark.parametrize("name", [n for n, c in CASES.items()
                                  if c.cls.discrete_states and hasattr(c.cls, "switching")])
def test_switching_functions_cross_zero_where_switch_changes_the_mode(name):
    """switching(P, V, S) >= 0 exactly where switch(P, V, S) changes a mode,
    over a sweep of the interface variables that crosses the thresholds."""
    case = CASES[name]
    plan = step_plan(case.cls)
    changed_any = held_any = False
    for scale, grow in zip(np.linspace(0.5, 1.5, 41), np.geomspace(0.2, 20.0, 41)):
        V = case.V.copy()
        V[:, 0] *= scale                 # the first pressure: a valve's dp
        S = case.S.copy()
        S[:, plan.cont] *= grow          # the stored mass: a volume's size
        g = case.cls.switching(case.P, V, S)
        new = case.cls.switch(case.P, V, S)
        changed = new != S[:, plan.disc]
        np.testing.assert_array_equal(g >= 0, changed, err_msg=f"{name} at scale {scale}")
        changed_any |= bool(changed.any())
        held_any |= bool((~changed).any())
    assert changed_any and held_any      # both sides of a threshold were seen
