"""Analytic Jacobians of every thermal kernel against central finite differences."""
import numpy as np
import pytest

import softflow as sf
from softflow.components.thermal import HELD_CLASSES, THERMAL_CLASSES, UPWIND_BAND
from softflow.components.tubes import InertialCircularTube
from softflow.paper_scenes import loop_hysteretic
from softflow.solve.thermal import configure_thermal

P0 = sf.pressure_atmospheric
RTOL = 1e-5
ATOL_ROW = 1e-8
REL_STEP = 1e-6
AIR_EOS = sf.Fluid("air", level="eos")


def _configure(comps, model="adiabatic"):
    """Put the components into a thermal scene; a tube gives each source its gas."""
    s = sf.System()
    s.add(*comps)
    for c in comps:
        if isinstance(c, (sf.PressureSource, sf.MassFlowSource)):
            tube = sf.CircularTube(f"tube_{c.label}", sf.air, length=0.1, diameter=1e-3)
            s.add(tube)
            s.connect(c, (tube.label, "a"))
    configure_thermal(s, model)
    return comps


class Case:
    def __init__(self, comps, V, S, scale, dt=1e-3, t=0.2):
        self.comps = comps
        self.cls = comps[0].kernel_class()
        self.P = self.cls.make_params(comps)
        self.V = np.asarray(V, dtype=float)
        self.S = np.asarray(S, dtype=float).reshape(len(comps), len(self.cls.state_spec))
        self.scale = np.asarray(scale, dtype=float)[:self.V.shape[1]]
        self.dt, self.t = dt, t

    def eval(self, V, jac):
        return self.cls.kernel(self.P, V, self.S, self.t, self.dt, jac)


def _flow_V(rng, n, mf, T_lo=250.0, T_hi=400.0):
    pa, pb = rng.uniform(1.2e5, 3e5, n), rng.uniform(1.2e5, 3e5, n)
    Ta, Tb = rng.uniform(T_lo, T_hi, n), rng.uniform(T_lo, T_hi, n)
    Ea, Eb = rng.uniform(-50, 50, n), rng.uniform(-50, 50, n)
    return np.column_stack([pa, mf, Ta, Ea, pb, -mf * 0.9, Tb, Eb])


FLOW_MF = {
    "forward": np.array([1e-4, 3e-5, 2e-4, 5e-6]),
    "backward": -np.array([1e-4, 3e-5, 2e-4, 5e-6]),
    "in_band": UPWIND_BAND * np.array([-0.7, -0.2, 0.3, 0.8]),
}


def _flow_elements(fluid):
    return {
        "Orifice-ISO": [sf.Orifice(f"o{i}", fluid, C=1e-8 * (1 + i), b=0.3) for i in range(4)],
        "Orifice-K": [sf.Orifice(f"k{i}", fluid, diameter=1e-3 * (1 + i), Cd=0.6)
                      for i in range(4)],
        "CircularTube": [sf.CircularTube(f"t{i}", fluid, length=0.3, diameter=1e-3 * (1 + i))
                         for i in range(4)],
        "InertialCircularTube": [InertialCircularTube(f"it{i}", fluid, length=0.3,
                                                      diameter=2e-3) for i in range(4)],
        "CheckValve": [sf.CheckValve(f"c{i}", fluid, diameter=1e-3, cracking_pressure=1e3,
                                     leakage=1e-10) for i in range(4)],
        "TeslaValve": [sf.TeslaValve(f"tv{i}", fluid, length=0.05, diameter=1e-3)
                       for i in range(4)],
        "SnappingValve": [sf.SnappingValve(f"s{i}", fluid, opening_pressure=2e4,
                                           closing_pressure=5e3, closed_conductance=1e-10)
                          for i in range(4)],
    }


def _cases():
    rng = np.random.default_rng(7)
    cases = {}
    for fluid in (sf.air, AIR_EOS):
        for name, comps in _flow_elements(fluid).items():
            if fluid is AIR_EOS and name not in ("Orifice-ISO", "CircularTube"):
                continue
            for regime, mf in FLOW_MF.items():
                comps_r = _flow_elements(fluid)[name]
                _configure(comps_r)
                ns = len(comps_r[0].kernel_class().state_spec)
                S = np.column_stack([[0.0, 1.0, 0.0, 1.0]] * ns) if name == "SnappingValve" \
                    else rng.uniform(-1e-4, 1e-4, (4, ns))
                cases[f"{name}-{fluid.level}-{regime}"] = Case(
                    comps_r, _flow_V(rng, 4, mf), S,
                    scale=[1e5, max(abs(mf).max(), 1e-9), 300, 10, 1e5, 1e-4, 300, 10])
    # sources
    n = 3
    V = np.column_stack([rng.uniform(1e5, 3e5, n), [-1e-4, 2e-5, 3e-10], rng.uniform(250, 400, n),
                         rng.uniform(-30, 30, n)])
    scale = [1e5, 1e-9, 300, 10]   # small mf scale: steps inside the upwind band
    cases["PressureSource"] = Case(_configure([sf.PressureSource(f"ps{i}", pressure=2e5,
                                                                 temperature=300.0 + i)
                                               for i in range(n)]), V, np.zeros((n, 0)), scale)
    cases["MassFlowSource"] = Case(_configure([sf.MassFlowSource(f"ms{i}", massflow=1e-4,
                                                                 temperature=280.0 + 20 * i)
                                               for i in range(n)]), V, np.zeros((n, 0)), scale)
    for sign in (1, -1):
        srcs = [sf.VolumeFlowSource(f"vs{i}", volumeflow=sign * 1e-5 * (i + 1), fluid=sf.air,
                                    temperature=320.0) for i in range(n)]
        cases[f"VolumeFlowSource{'+' if sign > 0 else '-'}"] = Case(
            _configure(srcs), V, np.zeros((n, 0)), scale)
    # volumes: free ones (adiabatic, heat transfer) carry their wall heat as a local
    # unknown, V = [p, mf, T, E, Q], states (mass, stored_energy); held ones V = [p,
    # mf, T, E], state mass
    Vv = np.column_stack([rng.uniform(1e5, 4e5, n), rng.uniform(-1e-4, 1e-4, n),
                          rng.uniform(250, 400, n), rng.uniform(-30, 30, n),
                          rng.uniform(-5, 5, n)])
    for fluid in (sf.air, AIR_EOS):
        for model, kw in (("adiabatic", {}), ("heat_transfer", {"hA": 0.3}),
                          ("isothermal", {"wall_temperature": 310.0})):
            tanks = [sf.Container(f"c{i}", fluid, volume=1e-3 * (i + 1), hA=kw.get("hA"),
                                  wall_temperature=kw.get("wall_temperature"),
                                  thermal=model, initial_pressure=2e5) for i in range(n)]
            _configure(tanks)
            held = model == "isothermal"
            S = np.column_stack([[2e-3, 5e-3, 7e-3], [500.0, 1500.0, 2000.0]])
            cases[f"Container-{fluid.level}-{model}"] = Case(
                tanks, Vv[:, :4] if held else Vv, S[:, :1] if held else S,
                [1e5, 1e-4, 300, 10, 10])
    accs = [sf.LinearAccumulator(f"a{i}", sf.air, volume=1e-4, compliance=1e-10 * (i + 1),
                                 hA=0.2) for i in range(n)]
    _configure(accs, "heat_transfer")
    S = np.column_stack([[1e-4, 2e-4, 3e-4], [30.0, 60.0, 90.0]])
    cases["LinearAccumulator"] = Case(accs, Vv, S, [1e5, 1e-4, 300, 10, 10])
    accs = [sf.LinearAccumulator(f"a{i}", sf.air, volume=1e-4, compliance=1e-10 * (i + 1),
                                 thermal="isothermal") for i in range(n)]
    _configure(accs, "heat_transfer")
    cases["LinearAccumulator-held"] = Case(accs, Vv[:, :4], S[:, :1], [1e5, 1e-4, 300, 10])
    curve = sf.PVCurve.monotonic((1e-5, P0), (3e-5, 1.5e5), (6e-5, 1.8e5))
    Va = Vv.copy()
    Va[:, 0] = [1.2e5, 1.6e5, 1.9e5]
    S = np.column_stack([[3e-5, 5e-5, 8e-5], [10.0, 20.0, 30.0]])
    acts = [sf.Actuator(f"act{i}", sf.air, curve) for i in range(n)]
    _configure(acts)
    cases["Actuator"] = Case(acts, Va, S, [1e5, 1e-5, 300, 10, 10])
    acts = [sf.Actuator(f"act{i}", sf.air, curve, thermal="isothermal") for i in range(n)]
    _configure(acts)
    cases["Actuator-held"] = Case(acts, Va[:, :4], S[:, :1], [1e5, 1e-5, 300, 10])
    # hysteretic actuator (the paper's snapping loop, V_lo 3.7 mL, V_hi 6.3 mL) on each
    # branch; end-of-step volumes away from the loop ends, one inside each snap
    loop = loop_hysteretic()
    for branch, vols, model, kw in ((1.0, [2e-6, 5e-6, 6.15e-6], "adiabatic", {}),
                                    (0.0, [3.8e-6, 5e-6, 9e-6], "heat_transfer", {"hA": 0.1}),
                                    (1.0, [2e-6, 5e-6, 6.15e-6], "held",
                                     {"thermal": "isothermal"})):
        hyst = [sf.HystereticActuator(f"h{i}", sf.air, *loop, **kw) for i in range(n)]
        _configure(hyst, "adiabatic" if model == "held" else model)
        Vh = Vv.copy()
        Vh[:, 0] = [1.1e5, 1.25e5, 1.3e5]
        dt = 1e-3
        mass = sf.air.density(Vh[:, 0], Vh[:, 2]) * np.array(vols) - dt * Vh[:, 1]
        if model == "held":
            Vh = Vh[:, :4]
            S = np.column_stack([mass, [branch] * n])
        else:
            S = np.column_stack([mass, [10.0, 20.0, 30.0], [branch] * n, [0.1, 0.2, 0.3]])
        case = Case(hyst, Vh, S, [1e5, 1e-5, 300, 10, 10], dt=dt)
        # the kernel sees the intended branch and end-of-step volumes
        vol = (case.S[:, 0] + dt * case.V[:, 1]) / sf.air.density(case.V[:, 0], case.V[:, 2])
        np.testing.assert_allclose(vol, vols, rtol=1e-12)
        assert (loop.on_inflation_curve(vol, branch > 0.5) == (branch > 0.5)).all()
        cases[f"HystereticActuator-{model}-{'inflation' if branch else 'deflation'}"] = case
    return cases


CASES = _cases()


def test_every_thermal_class_is_covered():
    assert {c.cls for c in CASES.values()} == (set(THERMAL_CLASSES.values())
                                               | set(HELD_CLASSES.values()))


@pytest.mark.parametrize("name", list(CASES))
def test_thermal_jacobian_matches_finite_differences(name):
    case = CASES[name]
    F, Jv = case.eval(case.V.copy(), True)
    n, nv = case.V.shape
    neq = F.shape[1]
    pattern = case.cls.jac_pattern
    assert len(set(pattern)) == len(pattern)
    J = np.zeros((n, neq, nv))
    for col, (e, k) in enumerate(pattern):
        J[:, e, k] = Jv[:, col]
    D = np.zeros_like(J)
    for i in range(n):
        for k in range(nv):
            h = REL_STEP * max(abs(case.V[i, k]), case.scale[k])
            Vp, Vm = case.V.copy(), case.V.copy()
            Vp[i, k] += h
            Vm[i, k] -= h
            D[i, :, k] = (case.eval(Vp, False)[0][i] - case.eval(Vm, False)[0][i]) / (2 * h)
    scaled_J = J * case.scale[None, None, :]
    scaled_D = D * case.scale[None, None, :]
    row_max = np.maximum(np.abs(scaled_D).max(axis=2, keepdims=True), 1e-300)
    err = np.abs(scaled_J - scaled_D) / (RTOL * np.abs(scaled_D) + ATOL_ROW * row_max + 1e-300)
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= 1.0, (f"{name}: instance {worst[0]}, eq {worst[1]}, var {worst[2]}: "
                              f"analytic {J[worst]:.6g}, FD {D[worst]:.6g}")


@pytest.mark.parametrize("jac", [False, True])
def test_upwind_weight_of_a_few_flows_equals_the_array_path(jac):
    """Up to 32 flows the blend runs on floats; it must give the array path's
    numbers exactly (inside, outside and across the band, and at its edges)."""
    from softflow.components.thermal import UPWIND_BAND, _upwind_weight
    band = UPWIND_BAND
    few = np.array([-2 * band, -band, -0.3 * band, 0.0, 0.7 * band, band, 3 * band])
    many = np.tile(few, 6)                       # 42 flows: the array path
    w_few, dw_few = _upwind_weight(few.copy(), jac)
    w_many, dw_many = _upwind_weight(many.copy(), jac)
    np.testing.assert_array_equal(w_few, w_many[:few.size])
    assert w_few[0] == 0.0 and w_few[-1] == 1.0 and w_few[3] == 0.5
    if jac:
        np.testing.assert_array_equal(dw_few, dw_many[:few.size])
    # all outside the band: plain upwind on both paths
    out = np.array([-3 * band, 5 * band])
    np.testing.assert_array_equal(_upwind_weight(out.copy(), jac)[0], [0.0, 1.0])
    assert np.isnan(_upwind_weight(np.array([np.nan, 0.0]), jac)[0][0])
