"""Scene files (softflow.scene, TOML): round trips that run step for step like
the original, units kept as written, curves inline or by path, waveforms, and
bad input named by file and key (and line)."""
import shutil
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow import paper_scenes, scene
from softflow.cli import main

CSV = Path(__file__).resolve().parents[1] / "examples" / "latex_balloon_60mm_pv.csv"

FILL = """\
# a pressure step fills a tank through a tube
format = 1
connections = [["source.a", "tube.a"], ["tube.b", "tank"]]

[simulation]
duration = "50 ms"

[components.source]
type = "PressureSource"
pressure = { waveform = "Step", time = "5 ms", before = "1 atm", after = "1.5 bar" }

[components.tube]
type = "CircularTube"
fluid = "air"
length = "30 cm"
diameter = "1 mm"

[components.tank]
type = "Container"
fluid = "air"
volume = "10 mL"
"""


def python_fill():
    system = sf.System()
    system += sf.PressureSource("source", pressure=sf.waveforms.Step(
        sf.Q_(5, "ms"), sf.Q_(1, "atm"), sf.Q_(1.5, "bar")))
    system += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=sf.Q_(1, "mm"))
    system += sf.Container("tank", sf.air, volume=sf.Q_(10, "mL"))
    system.connect("source", "tube")
    system.connect("tube", "tank")
    return system


def test_a_scene_file_runs_as_the_same_network_built_in_python(tmp_path):
    path = tmp_path / "fill.toml"
    path.write_text(FILL)
    sc = scene.read(path)
    assert sc.simulation["duration"] == sf.Q_(50, "ms")
    a = sc.simulate().run()
    b = sf.Simulation(python_fill(), duration=0.05).run()
    assert a.stats["steps"] == b.stats["steps"]
    np.testing.assert_allclose(a.get("tank", "pressure"), b.get("tank", "pressure"), rtol=1e-12)


@pytest.mark.filterwarnings("ignore:.*beyond the last sample")   # Fig. 5's actuators go past their data
@pytest.mark.parametrize("build, fig", [
    (lambda: paper_scenes.fig3("hysteretic"), 3),      # hysteresis loop, peak-valley curves
    (lambda: paper_scenes.fig4("snapping"), 4),        # snapping valve, plateau curves
    (lambda: paper_scenes.fig5(sf.ethylene_glycol), 5),  # accumulator, pump waveform
], ids=["fig3-hysteretic", "fig4-snapping", "fig5-glycol"])
def test_python_built_scenes_save_and_load_step_for_step(tmp_path, build, fig):
    system = build()
    path = scene.save(system, tmp_path / "s.toml", simulation={"duration": f"{paper_scenes.duration(fig)} s"})
    loaded = scene.read(path)
    a = sf.Simulation(system, duration=paper_scenes.duration(fig)).run()
    b = loaded.simulate().run()
    assert a.stats["steps"] == b.stats["steps"]
    for label in ("act1", "act2"):
        assert np.array_equal(a.get(label, "volume"), b.get(label, "volume"))


def test_a_loaded_scene_saves_its_units_as_written_and_moves_curve_paths(tmp_path):
    first = tmp_path / "a"
    first.mkdir()
    shutil.copy(CSV, first / "balloon.csv")
    (first / "s.toml").write_text(FILL.replace('connections = [["source.a", "tube.a"], ["tube.b", "tank"]]',
                                               'connections = [["source.a", "tube.a"], ["tube.b", "act"]]')
                                  .replace('''[components.tank]
type = "Container"
fluid = "air"
volume = "10 mL"''', '''[components.act]
type = "Actuator"
fluid = "warm"
curve = { csv = "balloon.csv" }
initial_volume = "12 mL"

[fluids.warm]
name = "air"
level = "table"
temperature = "40 degC"'''))
    system = scene.load(first / "s.toml")
    assert system.get("act").fluid.temperature == pytest.approx(313.15)
    elsewhere = tmp_path / "b" / "c"
    elsewhere.mkdir(parents=True)
    text = scene.save(system, elsewhere / "t.toml").read_text()
    assert 'length = "30 cm"' in text and 'initial_volume = "12 mL"' in text
    assert 'after = "1.5 bar"' in text and 'temperature = "40 degC"' in text
    assert 'csv = "../../a/balloon.csv"' in text
    again = scene.load(elsewhere / "t.toml")
    a = sf.Simulation(system, duration=0.05).run()
    b = sf.Simulation(again, duration=0.05).run()
    assert np.array_equal(a.get("act", "volume"), b.get("act", "volume"))


def test_inline_curve_and_tabulated_waveform_with_units(tmp_path):
    text = """\
connections = [["pump", "act"]]
[components.pump]
type = "VolumeFlowSource"
fluid = "water"
volumeflow = { waveform = "PiecewiseConstant", times = [0, 1, 2], times_unit = "s", values = [1.8, 0, -1.8], values_unit = "mL/s" }
[components.act]
type = "Actuator"
fluid = "water"
curve = { volume = [1, 5, 12], volume_unit = "mL", pressure = [0, 15, 22], pressure_unit = "kPa", gauge = true }
"""
    system = scene.loads(text).system
    res = sf.Simulation(system, duration=3.0).run()
    assert res.get("act", "volume")[-1] == pytest.approx(1e-6, rel=1e-6)   # 1.8 mL in, out
    assert res.get("act", "volume").max() == pytest.approx(2.8e-6, rel=1e-6)


def bad(tmp_path, text, *fragments):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(scene.SceneError) as info:
        scene.read(path)
    message = str(info.value)
    assert message.startswith(str(path) + ": "), message
    for f in fragments:
        assert f in message, message
    return message


def test_unknown_component_type_names_file_key_and_line(tmp_path):
    bad(tmp_path, FILL.replace('type = "CircularTube"', 'type = "CircularTub"'),
        "components.tube.type (line 13)", "unknown component type 'CircularTub'", "CircularTube")


def test_missing_field_names_the_component(tmp_path):
    bad(tmp_path, FILL.replace('diameter = "1 mm"\n', ""),
        "components.tube (line 12)", "missing field 'diameter' of CircularTube")
    bad(tmp_path, FILL.replace('type = "Container"\n', ""), "components.tank", "missing field 'type'")


def test_wrong_unit_names_the_key(tmp_path):
    bad(tmp_path, FILL.replace('length = "30 cm"', 'length = "30 bar"'),
        "components.tube.length (line 15)", "'30 bar' is not a length")
    bad(tmp_path, FILL.replace('length = "30 cm"', 'length = "30 furlongz"'),
        "components.tube.length", "unknown unit 'furlongz'")
    bad(tmp_path, FILL.replace('time = "5 ms"', 'time = "5 kg"'),
        "components.source.pressure.time", "not a time")


def test_dangling_connections(tmp_path):
    bad(tmp_path, FILL.replace('["tube.b", "tank"]', '["tube.b", "tnak"]'),
        "connections (line 3)", "dangling connection: no component 'tnak'", "tank")
    bad(tmp_path, FILL.replace('["tube.b", "tank"]', '["tube.c", "tank"]'),
        "connections", "CircularTube 'tube' has no terminal 'c' (terminals: a, b)")
    bad(tmp_path, FILL.replace(', ["tube.b", "tank"]', ""),
        "connections", "not connected to anything", "tube.b", "tank.a")


def test_other_bad_input(tmp_path):
    bad(tmp_path, FILL.replace('length = "30 cm"', 'lenght = "30 cm"'),
        "components.tube.lenght", "CircularTube has no parameter 'lenght'")
    bad(tmp_path, FILL.replace('fluid = "air"', 'fluid = "aire"', 1), "components.tube.fluid",
        "unknown fluid 'aire'")
    bad(tmp_path, FILL.replace('waveform = "Step"', 'waveform = "Stepp"'),
        "components.source.pressure.waveform", "unknown waveform 'Stepp'")
    bad(tmp_path, FILL.replace('length = "30 cm"', 'length = 30 cm'), "not valid TOML", "line 15")
    bad(tmp_path, FILL.replace('diameter = "1 mm"', 'diameter = "-1 mm"'),
        "components.tube", "diameter must be > 0")
    bad(tmp_path, FILL.replace("format = 1", "format = 2"), "format", "not supported")


def test_python_functions_cannot_be_saved_and_the_component_is_named(tmp_path):
    system = python_fill()
    system += sf.PressureSource("wobble", pressure=lambda t: 1e5 + 1e3 * t)
    system += sf.Container("box", sf.air, volume=1e-6)
    system += sf.CircularTube("t2", sf.air, length=0.1, diameter=1e-3)
    system.connect("wobble", "t2")
    system.connect("t2", "box")
    with pytest.raises(scene.SceneError, match=r"PressureSource 'wobble': pressure is a Python "
                                               r"function \(<lambda>\); a scene file cannot hold code"):
        scene.save(system, tmp_path / "x.toml")
    assert not (tmp_path / "x.toml").exists()

    user = sf.System()
    balloon = sf.Component("balloon")
    balloon.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across"),
                                            sf.Variable("massflow", "through")]))
    user += balloon
    with pytest.raises(scene.SceneError, match="Component 'balloon'.*user-written component"):
        scene.dumps(user)

    act = sf.System()
    act += sf.Actuator("act", sf.water, lambda v: 1e5 + 1e9 * v, initial_volume=1e-6)
    with pytest.raises(scene.SceneError, match="Actuator 'act': curve is a function"):
        scene.dumps(act)


def test_cli_run_writes_csv_netcdf_and_a_plot(tmp_path, capsys):
    pytest.importorskip("xarray")
    path = tmp_path / "fill.toml"
    path.write_text(FILL)
    outs = [tmp_path / "run.csv", tmp_path / "run.nc", tmp_path / "run.png"]
    args = ["run", str(path), "--duration", "20 ms", "--no-progress"]
    for o in outs:
        args += ["--output", str(o)]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "success after" in out and "t = 0 to 0.02 s" in out
    import pandas
    df = pandas.read_csv(outs[0])
    assert df["time [s]"].iloc[-1] == pytest.approx(0.02)
    import xarray
    with xarray.open_dataset(outs[1]) as ds:
        assert ds["tank.pressure"].attrs["units"] == "Pa"
    assert outs[2].stat().st_size > 10_000


def test_cli_run_reports_bad_scenes_in_one_line(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(FILL.replace('length = "30 cm"', 'length = "30 bar"'))
    assert main(["run", str(path)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith(f"softflow run: error: SceneError: {path}: components.tube.length")
    path.write_text(FILL.replace('duration = "50 ms"', ""))
    assert main(["run", str(path)]) == 1
    assert "no duration: give --duration" in capsys.readouterr().err
    assert main(["run", str(tmp_path / "none.toml"), "--duration", "1 s"]) == 1
    assert "cannot read" in capsys.readouterr().err
    assert main(["run", str(path), "--duration", "1 s", "--output", str(tmp_path / "x.xlsx")]) == 1
    assert ".csv, .nc for the data" in capsys.readouterr().err


def test_simulation_table_sets_beyond_limits_and_max_steps(tmp_path):
    """[simulation] takes beyond_limits and max_steps as Simulation does (issue
    40: a scene file could not set beyond_limits); a bad value is Simulation's
    own error."""
    path = tmp_path / "fill.toml"
    path.write_text(FILL.replace('duration = "50 ms"',
                                 'duration = "50 ms"\nbeyond_limits = "warn"\nmax_steps = 3'))
    sc = scene.read(path)
    assert sc.simulation["beyond_limits"] == "warn" and sc.simulation["max_steps"] == 3
    res = sc.simulate().run(raise_on_failure=False)
    assert res.status == "failed" and "more than max_steps = 3 steps" in res.message
    path.write_text(FILL.replace('duration = "50 ms"',
                                 'duration = "50 ms"\nbeyond_limits = "ignore"'))
    with pytest.raises(ValueError, match="beyond_limits must be 'error' or 'warn'"):
        scene.read(path).simulate()
    # and it is written back
    out = tmp_path / "again.toml"
    scene.save(sc.system, out, simulation=sc.simulation)
    assert scene.read(out).simulation["beyond_limits"] == "warn"
