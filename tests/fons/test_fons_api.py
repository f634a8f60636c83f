"""softflow.fons on its own (no fonsim needed): the scripts run, their
results follow the physics, and bad input gets errors that name the culprit."""
import json
from pathlib import Path

import numpy as np
import pytest

import fonsim_scripts as S
import softflow as sf
import softflow.fons as fons

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def _agg():
    import matplotlib
    matplotlib.use("Agg")


# -- the scripts, softflow's fluids --------------------------------------------------------
def test_first_network_fills_to_the_source_pressure():
    out = S.first_network(fons, fons.air)
    p = out["container gauge pressure [Pa]"]
    assert np.all(np.diff(p) > 0)
    assert p[-1] == pytest.approx(2e5 - fons.pressure_atmospheric, rel=2e-3)


def test_volumeflow_source_into_container_is_exponential():
    # isothermal: V dp/dt = p Q  ->  p = p_atm exp(Q t / V)
    out = S.volumeflow_into_container(fons, fons.air, step=(None, None))
    t = np.array([1.0, 2.5, 5.0])
    exact = fons.pressure_atmospheric * (np.exp(1e-6 * t / 10e-6) - 1)
    np.testing.assert_allclose(out["tank gauge pressure [Pa]"], exact, rtol=5e-3)


def test_accumulator_pressure_is_k_times_volume():
    out = S.accumulator(fons, fons.water)
    dm = out["acc mass gain [kg]"]                      # at 0.25 s and 1 s
    assert dm[0] == pytest.approx(0.25e-3, rel=1e-9)
    # p - p0 = k dV (+ the 1 mPa an empty accumulator starts with)
    np.testing.assert_allclose(out["acc gauge pressure [Pa]"][[0, 2]],
                               1e9 * dm / fons.water.rho + 1e-3, rtol=1e-9)


def test_custom_component_equals_the_library_container():
    out = S.custom_container(fons, fons.air)
    np.testing.assert_allclose(out["tank_0 pressure [Pa]"], out["tank_1 pressure [Pa]"],
                               rtol=1e-6)


def test_free_actuator_terminal_b_chains_and_curve_as_file_starts_empty():
    out = S.two_balloons(fons, fons.water, step=(None, None))
    for label in ("actu_0", "actu_1"):
        v = out[f"{label} volume [m^3]"]
        assert np.all(np.diff(v) >= -1e-12) and v[-1] > v[0]
    # a file name is read as fonsim reads it: shifted to 0 m^3 and 1 atm, so the
    # actuator starts empty (a tiny volume: softflow needs some fluid) at 1 atm
    by_file = fons.FreeActuator("a", fluid=fons.water, curve=str(S.DATA))
    shifted = fons.data.PVCurve(str(S.DATA), autocorrect=True)
    np.testing.assert_allclose(by_file.curve.v, shifted.v)
    np.testing.assert_allclose(by_file.curve.p, shifted.p)
    assert by_file.curve.extrapolate == "clamp" and by_file.pvcurve is by_file.curve
    assert by_file.initial_volume < 1e-12
    assert by_file.initial_pressure == pytest.approx(fons.pressure_atmospheric, abs=0.01)
    # no curve: fonsim's default, the same balloon (softflow ships it too)
    default = fons.FreeActuator("d", fluid=fons.water)
    np.testing.assert_allclose(default.curve.p, shifted.p)
    # a curve object is taken as it is: its data start at 1 mL, 22 mbar, above
    # 1 atm, so it starts at its first sample (the nearest to 1 atm)
    by_object = fons.FreeActuator("o", fluid=fons.water, curve=fons.data.PVCurve(str(S.DATA)))
    assert by_object.initial_volume == pytest.approx(1e-6)
    assert by_object.initial_pressure == pytest.approx(2200 + fons.pressure_atmospheric)


def test_free_actuator_initial_volume_options():
    curve = fons.data.PVCurve(str(S.DATA))
    water = {iv: fons.FreeActuator("w", fluid=fons.water, curve=curve, initial_volume=iv)
             for iv in (None, "auto", "minimum", 5e-6)}
    assert water[None].initial_volume == water["auto"].initial_volume == pytest.approx(1e-6)
    assert water["minimum"].initial_volume == pytest.approx(1e-6)
    assert water[5e-6].initial_volume == pytest.approx(5e-6)
    # a gas starts with the mass the volume holds at 1 atm: compressed on the curve
    air = fons.FreeActuator("a", fluid=fons.air, curve=curve, initial_volume=5e-6)
    m0 = 5e-6 * fons.air.rho_stp
    assert air.initial_states()[0] == pytest.approx(m0, rel=1e-9)
    assert air.initial_volume < 5e-6
    assert air.initial_pressure == pytest.approx(curve(air.initial_volume))
    with pytest.raises(ValueError, match="initial_volume must be None, 'auto', 'minimum'"):
        fons.FreeActuator("x", fluid=fons.water, curve=curve, initial_volume="maximum")
    with pytest.raises(TypeError, match="write the bytes to a CSV file"):
        fons.FreeActuator("x", fluid=fons.water, curve=b"Volume,Pressure")


def test_empty_linear_accumulator_and_one_off_the_atmosphere():
    empty = fons.LinearAccumulator("e", fluid=fons.air, k=1e9)
    assert empty.initial_pressure == pytest.approx(fons.pressure_atmospheric, abs=2e-3)
    assert empty.initial_states()[0] < 2e-12     # 1e-12 m^3 of air
    # v0 at p0 = 1.5 bar, filled with the mass v0 holds at 1 atm (fonsim's start)
    acc = fons.LinearAccumulator("g", fluid=fons.air, k=1e10, p0=1.5e5, v0=5e-6)
    p = acc.initial_pressure
    assert fons.pressure_atmospheric < p < 1.5e5
    assert p == pytest.approx(1.5e5 + 1e10 * (5e-6 * fons.pressure_atmospheric / p - 5e-6))
    assert acc.initial_states()[0] == pytest.approx(5e-6 * 1.23)
    liquid = fons.LinearAccumulator("w", fluid=fons.water, k=1e10, p0=1.5e5, v0=5e-6)
    assert liquid.initial_pressure == 1.5e5


@pytest.mark.parametrize("threshold", [0.0, 0.3e5])
def test_check_valve_holds_the_pressure_less_its_threshold(threshold):
    out = S.check_valve(fons, fons.air, threshold=threshold, step=(None, None))
    p = out["tank pressure [Pa]"]
    assert p[-1] == pytest.approx(2e5 - threshold, abs=300)   # within the opening band
    assert p[1] < p[-1]                                        # filled through the tube
    assert p[-1] == pytest.approx(p[-3], abs=1)                # closed after the pulse


def test_paper_listing_runs_under_softflow_fons_as_under_softflow():
    src = (ROOT / "examples" / "paper_example.py").read_text()
    assert "import softflow as fons" in src
    results = []
    for line in ("import softflow as fons", "import softflow.fons as fons"):
        ns = {"__file__": str(ROOT / "examples" / "paper_example.py")}
        cwd = Path.cwd()
        try:
            import os
            os.chdir(ROOT / "examples")
            exec(compile(src.replace("import softflow as fons", line), "paper", "exec"), ns)
        finally:
            os.chdir(cwd)
        results.append((np.asarray(ns["t"]), np.asarray(ns["p_actu"])))
    (t0, p0), (t1, p1) = results
    # same network, same solver, same curve data; softflow.fons's water is fonsim's
    # (0.977 mPa s, softflow's 1.0016 mPa s: a 2.5 % faster tube), so the gauge
    # pressures differ by a few percent while the pressure rises, less at its end
    np.testing.assert_allclose(np.interp(t0, t1, p1), p0, atol=0.03 * np.max(np.abs(p0)))
    assert p1[-1] == pytest.approx(p0[-1], rel=0.01)


# -- connect ------------------------------------------------------------------------------
def test_connect_chains_pairs_and_connect_common_joins_one_node():
    s = fons.System()
    s += fons.PressureSource("src", pressure=2e5)
    for i in range(3):
        s += fons.CircularTube(f"t{i}", fluid=fons.air)
    s.connect("src", "t0", "t1")
    nodes = {frozenset(t.name for t in n.terminals) for n in s.nodes()}
    assert frozenset({"src.a", "t0.a"}) in nodes and frozenset({"t0.b", "t1.a"}) in nodes
    s.connect_common(("t0", "b"), ("t2", "a"))
    nodes = {frozenset(t.name for t in n.terminals) for n in s.nodes()}
    assert frozenset({"t0.b", "t1.a", "t2.a"}) in nodes
    comp, term = s.get_component_and_terminal(("t2", "b"))
    assert comp is s.get("t2") and term.label == "b"


# -- unsupported names, bad input ----------------------------------------------------------
@pytest.mark.parametrize("name, says", [
    ("CircularTube_autodiff", "fons.CircularTube"),
    ("Dummy", "allow_unconnected"),
    ("circulartube_compressible", "use the component"),
    ("NoSuchThing", "not part of fonsim 0.6's public API"),
])
def test_unsupported_fonsim_name_says_what_to_use(name, says):
    with pytest.raises(fons.FonsimNameError) as info:
        getattr(fons, name)
    assert name in str(info.value) and says in str(info.value)
    assert not hasattr(fons, name)   # still an AttributeError


def test_unsupported_name_in_a_submodule():
    with pytest.raises(fons.FonsimNameError, match="'fluid.Bingham'.*Newtonian"):
        fons.fluid.Bingham


def test_wave_custom_not_time_ordered_names_the_row():
    with pytest.raises(ValueError, match=r"point 2 \(t = 0.25 s\) does not come after point 1"):
        fons.wave.Custom([(0, 1.0), (0.5, 2.0), (0.25, 3.0)])
    with pytest.raises(ValueError, match="relative time of row 1"):
        fons.wave.Custom([(0, 1.0), (0.0, 2.0)], time_notation="relative")
    with pytest.raises(ValueError, match="kind 'spline' is not supported; kind must be one of "
                                         "'previous', 'zero', 'next', 'nearest'"):
        fons.wave.Custom([(0, 1.0), (1.0, 2.0)], kind="spline")
    with pytest.raises(ValueError, match="kind='cubic' needs at least 4 points, got 3"):
        fons.wave.Custom([(0, 1.0), (1.0, 2.0), (2.0, 0.0)], kind="cubic")


def test_wave_custom_values_and_arithmetic_in_place():
    w = fons.wave.Custom([(0, 1.0), (0.5, 2.0), (0.25, 3.0)], time_notation="relative")
    assert [w(x) for x in (0.0, 0.49, 0.5, 0.74, 0.75, 9.0)] == [1, 1, 2, 2, 3, 3]
    assert w.breakpoints == (0.5, 0.75)
    lin = fons.wave.Custom([[0, 0.5, 1.0], [1, 3, 2]], kind="linear")   # 2 x N
    scaled = lin * 1e5 + fons.pressure_atmospheric
    # as fonsim's: * and + change the wave itself and return it
    assert scaled is lin
    assert lin(0.25) == pytest.approx(2e5 + fons.pressure_atmospheric)
    bare = fons.wave.Custom([(0, 1.0), (1.0, 2.0)])
    bare * 3          # a statement alone scales it, as in fonsim
    assert bare(0.5) == 3.0
    copy = bare.copy()
    assert (2 * copy - 1)(0.5) == pytest.approx(5.0) and bare(0.5) == 3.0
    per_point = fons.wave.Custom([(0, 1.0), (1.0, 2.0)]) + [10.0, 20.0]
    assert per_point(1.0) == 22.0
    with pytest.raises(ValueError, match="one value per point"):
        bare + [1.0, 2.0, 3.0]
    with pytest.raises(TypeError):
        bare + fons.wave.Custom([(0, 1.0), (1.0, 2.0)])


@pytest.mark.parametrize("kind, expected, breaks", [
    ("previous", [1, 1, 3, 3, 3, 2, 2], (0.5, 1.0)),
    ("next", [1, 3, 3, 2, 2, 2, 2], (0.0, 0.5)),
    ("nearest", [1, 1, 3, 3, 2, 2, 2], (0.25, 0.75)),
])
def test_wave_custom_held_kinds(kind, expected, breaks):
    w = fons.wave.Custom([(0, 1.0), (0.5, 3.0), (1.0, 2.0)], kind=kind)
    t = [0.0, 0.25, 0.5, 0.75, 0.76, 1.0, 2.0]
    assert [w(x) for x in t] == expected
    np.testing.assert_array_equal(w(np.array(t)), expected)
    assert w.breakpoints == breaks


@pytest.mark.parametrize("kind, k", [("quadratic", 2), ("cubic", 3)])
def test_wave_custom_spline_kinds_are_scipys_interpolating_splines(kind, k):
    from scipy.interpolate import make_interp_spline
    pts = np.array([(0, 1.0), (0.5, 3.0), (1.0, 2.0), (1.5, 5.0), (2.0, 4.0)])
    w = fons.wave.Custom(pts, kind=kind)
    t = np.linspace(0, 2, 41)
    np.testing.assert_allclose(w(t), make_interp_spline(pts[:, 0], pts[:, 1], k=k)(t),
                               rtol=1e-14, atol=1e-14)
    assert w(-1.0) == 1.0 and w(3.0) == 4.0 and w(0.3) == pytest.approx(w(np.array([0.3]))[0])
    assert w.breakpoints == (0.0, 2.0)


def _csv(tmp_path, rows):
    path = tmp_path / "pv.csv"
    path.write_text("Balloon,2024-01-01\nTime,Volume,Pressure\ns,ml,mbar\n" + "\n".join(rows))
    return path


def test_pv_csv_with_a_bad_row_names_the_line(tmp_path):
    path = _csv(tmp_path, ["1,1,20", "2,2,abc", "3,3,300"])
    with pytest.raises(sf.curves.csvdata.DataFileError, match=r"line 5.*'abc'"):
        fons.data.PVCurve(str(path))
    path = _csv(tmp_path, ["1,1,20", "2,2,250", "3,1.5,300"])
    with pytest.raises(sf.curves.csvdata.DataFileError, match="line 6"):
        fons.data.PVCurve(str(path))


def test_pv_curve_reference_and_falling_volumes(tmp_path):
    rel = fons.data.PVCurve(str(_csv(tmp_path, ["1,1,20", "2,2,250", "3,3,300"])))
    np.testing.assert_allclose(rel.p, np.array([20, 250, 300]) * 100 + 101300)
    np.testing.assert_allclose(rel.v, [1e-6, 2e-6, 3e-6])
    ab = fons.data.PVCurve(str(_csv(tmp_path, ["1,3,3000", "2,2,2500", "3,1,1020"])),
                           pressure_reference="absolute")
    np.testing.assert_allclose(ab.v, [1e-6, 2e-6, 3e-6])
    np.testing.assert_allclose(ab.p, [102000, 250000, 300000])
    assert ab.get_initial_volume(101325) == pytest.approx(1e-6)     # nearest sample
    assert ab.get_initial_volume(176000) == pytest.approx(1.5e-6)   # interpolated
    with pytest.raises(TypeError, match=r"\['fill_value'\] are not supported"):
        fons.data.PVCurve(str(S.DATA), fill_value=0)
    with pytest.raises(ValueError, match="pressure_reference"):
        fons.data.PVCurve(str(S.DATA), pressure_reference="gauge")


def test_pv_curve_holds_its_end_pressures_and_maps_fonsim_s_options():
    curve = fons.data.PVCurve(str(S.DATA))
    assert curve.extrapolate == "clamp"
    p, dp = curve.fdf_volume(0.2e-6)
    assert (p, dp) == (pytest.approx(curve.p[0]), 0.0)
    assert curve.fdf_volume(80e-6)[0] == pytest.approx(curve.p[-1])
    for opts in ({"extrapolate": True}, {"extrapolate_derivative": True},
                 {"extrapolate": False, "method": "linear"}, {"method": "pchip"}):
        assert fons.data.PVCurve(str(S.DATA), **opts).extrapolate == "clamp"
    assert fons.data.PVCurve(str(S.DATA), extrapolate="linear").extrapolate == "linear"
    with pytest.raises(ValueError, match="extrapolate=True with extrapolate_derivative=True"):
        fons.data.PVCurve(str(S.DATA), extrapolate=True, extrapolate_derivative=True)
    with pytest.raises(ValueError, match="method='quadratic' is not supported"):
        fons.data.PVCurve(str(S.DATA), method="quadratic")
    with pytest.raises(TypeError, match="extrapolate_derivative must be True or False"):
        fons.data.PVCurve(str(S.DATA), extrapolate_derivative="yes")


def test_pv_curve_autocorrect_as_fonsim():
    shifted = fons.data.PVCurve(str(S.DATA), autocorrect=True)
    assert shifted.v[0] == 0 and shifted.p[0] == fons.pressure_atmospheric
    raw = fons.data.PVCurve(str(S.DATA))
    np.testing.assert_allclose(np.diff(shifted.v), np.diff(raw.v))
    # a number shifts further; a function gets the absolute pressures (SI)
    more = fons.data.PVCurve(str(S.DATA), autocorrect=(1e-6, 500.0))
    assert more.v[0] == pytest.approx(1e-6) and more.p[0] == fons.pressure_atmospheric + 500
    f = fons.data.PVCurve(str(S.DATA), autocorrect=(False, lambda p: p - 1000.0))
    np.testing.assert_allclose(f.p, raw.p - 1000.0)
    assert fons.data.PVCurve(str(S.DATA), autocorrect=0).p[0] == raw.p[0]   # 0: none


def test_writeout_simulation_json_is_fonsim_s_layout_and_reads_back(tmp_path):
    s = fons.System()
    s += fons.PressureSource("src", pressure=2e5)
    s += fons.CircularTube("tube", fluid=fons.air)
    s += fons.FreeActuator("act", fluid=fons.air)
    s += fons.CircularTube("tube2", fluid=fons.air)
    s += fons.Container("tank", fluid=fons.air, volume=20e-6)
    s.connect("src", "tube", "act")
    s.connect(("act", "b"), "tube2", "tank")
    sim = fons.Simulation(s, duration=0.05)
    assert sim.run() is None
    path = tmp_path / "run.json"
    fons.data.writeout_simulation(str(path), sim)
    # a script reading its own export, as it would read fonsim's
    doc = json.loads(path.read_text())
    assert doc["scheme"] == "0.1-alpha"
    assert doc["simulation"]["system"] == {"label": "system", "nb_components": 5,
                                           "nb_nodes": 4}   # act.b is a node of its own
    assert doc["simulation"]["time"] == 0
    data = doc["data"]
    np.testing.assert_array_equal(data[str(doc["simulation"]["time"])], sim.times)
    tank = doc["components"]["tank"]
    assert set(tank) == {"terminals", "states"}
    assert set(tank["terminals"]["a"]) == {"over", "through"}
    np.testing.assert_array_equal(data[str(tank["terminals"]["a"]["over"]["pressure"])],
                                  s.get("tank").get("pressure"))
    np.testing.assert_array_equal(data[str(tank["states"]["mass"])],
                                  s.get("tank").get_state("mass"))
    # FreeActuator: fonsim's two terminals; the flow through b is the tube's
    act = doc["components"]["act"]["terminals"]
    assert set(act) == {"a", "b"}
    np.testing.assert_allclose(data[str(act["b"]["through"]["massflow"])],
                               -s.get("tube2").get("massflow", "a"))
    np.testing.assert_allclose(data[str(act["a"]["through"]["massflow"])],
                               -s.get("tube").get("massflow", "b"))
    with pytest.raises(ValueError, match="only JSON"):
        fons.data.writeout_simulation(str(tmp_path / "run.csv"), sim)


def test_variable_range_is_checked_on_the_results():
    class Tank(fons.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(fons.Terminal("a", fons.terminal_fluidic,
                                             {"pressure": "p", "massflow": "mf"}))
            self.set_states(fons.Variable("mass", "local", label="m",
                                          initial_value=20e-6 * fons.air.rho,
                                          range=(0, 30e-6 * fons.air.rho)))
            self.evaluate = self.auto(lambda p, m: [p - m / 20e-6 / fons.air.rho
                                                    * fons.pressure_atmospheric])
            self.update_state = self.auto_state(lambda dt, m, mf: {"m": m + dt * mf})

    s = fons.System()
    s += fons.PressureSource("src", pressure=2e5)
    s += fons.CircularTube("tube", fluid=fons.air)
    s += Tank("tank")
    s.connect("src", "tube", "tank")
    with pytest.warns(RuntimeWarning, match=r"Tank 'tank': variable 'm' left its range"):
        fons.Simulation(s, duration=0.2).run()


@pytest.mark.parametrize("discretization, says", [("tustin", "Tustin"),
                                                    ("forward", "forward Euler"),
                                                    ("central", "not one of fonsim's")])
def test_other_discretizations_are_refused_naming_them(discretization, says):
    s = fons.System()
    s += fons.PressureSource("src", pressure=2e5)
    s += fons.CircularTube("tube", fluid=fons.air)
    s += fons.Container("tank", fluid=fons.air, volume=1e-5)
    s.connect("src", "tube", "tank")
    with pytest.raises(ValueError, match=f"discretization={discretization!r} .*{says}.* "
                                         f"give discretization='backward'"):
        fons.Simulation(s, discretization=discretization)


def test_check_valve_without_a_fluid_nearby_is_named():
    s = fons.System()
    s += fons.PressureSource("src", pressure=2e5)
    s += fons.CheckValve("valve")
    s += fons.Sink("sink")
    s.connect("src", "valve", "sink")
    with pytest.raises(sf.NetworkError, match="CheckValve 'valve': no fluid given"):
        fons.Simulation(s, duration=0.1)


def test_fluids_and_constants_are_fonsim_s():
    assert fons.pressure_atmospheric == 101300.0 and fons.temperature == 288.15
    assert fons.gas_constant == 8.314459848
    assert fons.air.rho_stp == fons.air.rho == 1.23 and fons.air.mu == 1.82e-5
    assert fons.air.density(fons.pressure_atmospheric) == pytest.approx(1.23, rel=1e-14)
    assert fons.air.density(2e5) == pytest.approx(1.23 * 2e5 / 101300, rel=1e-14)
    assert fons.air.temperature == 288.15 and isinstance(fons.air, sf.IdealGas)
    assert fons.air.fallbacks[0].name == "air_incompressible"
    assert fons.water.rho == 999.0 and fons.water.viscosity(1e5) == 0.977e-3
    assert isinstance(fons.water, sf.ConstantLiquid)
    assert fons.fluids.IdealCompressible.air is fons.air
    assert fons.fluids.IdealIncompressible.water is fons.water
    gas = fons.fluid.IdealCompressible("helium", 0.167, 1.96e-5)
    assert gas.density(fons.pressure_atmospheric) == pytest.approx(0.167, rel=1e-14)
    liquid = fons.fluid.IdealIncompressible("oil", 870, 0.03)
    assert liquid.rho == 870 and liquid.viscosity(1e5) == 0.03
    # components start at fonsim's atmosphere; a Sink holds it
    assert fons.Container("c", fluid=fons.air, volume=1e-6).initial_pressure == 101300.0
    assert fons.Sink("s").signal.const == 101300.0
    assert fons.terminal_fluidic[0].initial_value == 101300.0


def test_fonsim_module_paths_import():
    import importlib
    for path, names in {"constants.norm": ("pressure_atmospheric", "temperature"),
                        "constants.physical": ("gas_constant",),
                        "data.pvcurve": ("PVCurve",), "data.dataseries": ("DataSeries",),
                        "data.writeout": ("writeout_simulation",),
                        "wave.custom": ("Custom",), "wave.wave": ("sine", "time_to_angle"),
                        "visual.plotting": ("plot", "plot_state")}.items():
        module = importlib.import_module(f"softflow.fons.{path}")
        for name in names:
            assert hasattr(module, name), (path, name)
    import softflow.fons.constants.norm as cnorm
    assert fons.cnorm is cnorm and fons.constants.norm is cnorm
    assert fons.cphy.gas_constant == fons.gas_constant
    assert fons.wave.wave.square is fons.wave.square and fons.visual.plotting.plot is fons.plot
    assert fons.pvcurve.PVCurve is fons.data.PVCurve
    with pytest.raises(fons.FonsimNameError, match="'data.interpolate'"):
        fons.data.interpolate


@pytest.mark.parametrize("pa, pb", [(1.5e5, 1.013e5), (1.0e5, 1.9e5), (101300.5, 101300.0),
                                    (3e5, 0.5e5)])
def test_flow_restrictor_mean_density_law_and_its_jacobian(pa, pb):
    r = fons.FlowRestrictor("r", fluid=fons.air, diameter=1e-3, k=0.6)
    P = r.make_params([r])
    V = np.array([[pa, 1e-4, pb, -1e-4]])
    F, J = r.residual(P, V, None, 0.0, True)
    # mdot = A sqrt(2 rho(p_mean) |dp| / k), signed (above the laminar band)
    rho_m = fons.air.density(0.5 * (pa + pb))
    area = np.pi * 1e-3 ** 2 / 4
    if abs(pa - pb) > 100:
        q = np.sign(pa - pb) * area * np.sqrt(2 * rho_m * abs(pa - pb) / 0.6)
        assert 1e-4 - F[0, 1] == pytest.approx(q, rel=1e-12)
    for j, col in ((0, 2), (2, 4)):            # d/dp_a, d/dp_b
        h = 1e-3
        up, down = V.copy(), V.copy()
        up[0, j] += h
        down[0, j] -= h
        fd = (r.residual(P, up, None, 0.0, False)[0][0, 1]
              - r.residual(P, down, None, 0.0, False)[0][0, 1]) / (2 * h)
        assert J[0, col] == pytest.approx(fd, rel=1e-5, abs=1e-14)
    # a liquid: the same density everywhere, softflow's Orifice unchanged
    w = fons.FlowRestrictor("w", fluid=fons.water, diameter=1e-3, k=0.6)
    o = sf.Orifice("o", fons.water, 1e-3, K=0.6)
    Fw, Jw = w.residual(w.make_params([w]), V, None, 0.0, True)
    Fo, Jo = o.residual(o.make_params([o]), V, None, 0.0, True)
    np.testing.assert_array_equal(Fw, Fo)
    np.testing.assert_array_equal(Jw, Jo)
