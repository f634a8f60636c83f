"""Issue 40's small things a new user hits, each with the fix the message
gives checked to work."""
from __future__ import annotations

import pytest

import softflow as sf


def _check_valve_into(volume):
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.5, "bar"))
    s += sf.CheckValve("cv", sf.water, diameter=sf.Q_(1, "mm"))
    s += volume
    s.connect("cv", "src")
    s.connect("cv", volume.label)
    return s


def test_water_through_a_check_valve_into_a_rigid_container_names_it_and_the_fix():
    """A rigid Container of water admits no flow: behind a check valve at rest
    nothing sets its pressure. The error names the container and says to give
    the liquid a compliance; the scene with a LinearAccumulator runs."""
    with pytest.raises(sf.NetworkError) as info:
        sf.Simulation(_check_valve_into(sf.Container("tank", sf.water, volume=sf.Q_(10, "mL"))),
                      duration=0.05)
    msg = str(info.value)
    assert "Container 'tank'" in msg and "rigid" in msg and "LinearAccumulator" in msg
    fixed = _check_valve_into(sf.LinearAccumulator("tank", sf.water, volume=sf.Q_(10, "mL"),
                                                   compliance=sf.Q_(1e-3, "mL/kPa")))
    res = sf.Simulation(fixed, duration=0.05).run()
    assert res.success and res.get("tank", "pressure")[-1] > 1.2e5


def test_a_cli_run_that_fails_at_its_start_writes_no_output(tmp_path, capsys):
    """`softflow run` of a scene that stops at t = 0 (a flow source pushing
    10 kg/s into a node without volume whose one tube, 0.1 mm wide, passes
    less at any pressure) says so in one line and writes no CSV or plot,
    where a one-row table and an empty plot would pass for a result."""
    from softflow import scene
    from softflow.cli import main
    s = sf.System()
    s += sf.MassFlowSource("pump", massflow=10.0)
    s += sf.CircularTube("tube", sf.air, length=1.0, diameter=1e-4)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect("tube", "pump")
    s.connect("tube", "tank")
    path = scene.save(s, tmp_path / "stuck.toml", simulation={"duration": "0.1 s"})
    csv, png = tmp_path / "out.csv", tmp_path / "out.png"
    assert main(["run", str(path), "--output", str(csv), "--output", str(png),
                 "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert "no output written: it stopped at its start" in err and "pump" in err
    assert not csv.exists() and not png.exists()
