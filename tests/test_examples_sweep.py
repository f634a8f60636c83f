"""examples/design_sweep.py on a 2 x 2 grid: the lag map of the Fig. 4 network."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "design_sweep.py"

# the grid keeps actuator 1 within its curve's data and models R2's inertia: any
# ModelWarning is an error here (pyproject's filterwarnings would only show it)
pytestmark = pytest.mark.filterwarnings("error::softflow.solve.validity.ModelWarning")


@pytest.fixture(scope="module")
def example():
    spec = importlib.util.spec_from_file_location("design_sweep", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_design_sweep_runs_and_saves_the_map(example, tmp_path, capsys):
    png = tmp_path / "lag.png"
    res, lag = example.main(["--engine", "serial", "--diameters", "2", "--plateaus", "2",
                             "--output", str(png)])
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"
    out = capsys.readouterr().out
    assert "4 variants, engine 'serial'" in out and "0 failed" in out
    assert res.status == ["success"] * 4 and lag.shape == (2, 2)
    # actuator 2 follows actuator 1 by seconds: sooner through the wider restrictor
    # (rows: 2, 4 mm), later the higher its plateau (columns: 17, 30 kPa)
    assert np.all((lag > 1.0) & (lag < 8.0)), lag
    assert np.all(lag[0] > lag[1]) and np.all(lag[:, 1] > lag[:, 0]), lag
    # the map's coordinates: R2's diameter in SI, the plateaus as the example labels them
    ds = res.to_xarray()
    np.testing.assert_allclose(ds["R2.diameter"].values, [2e-3, 4e-3])
    assert ds["R2.diameter"].attrs["units"] == "m"
    np.testing.assert_allclose(ds["act2.curve"].values, [17.0, 30.0])


def test_design_sweep_on_processes_matches_serial(example):
    serial, lag_serial = example.study([2.0], [20.0, 26.0], engine="serial")
    procs, lag_procs = example.study([2.0], [20.0, 26.0], engine="processes", workers=2)
    np.testing.assert_array_equal(procs.data, serial.data)
    np.testing.assert_array_equal(lag_procs, lag_serial)


def test_half_swing_time_interpolates(example):
    t = np.array([0.0, 1.0, 2.0, 3.0])
    assert example.half_swing_time(t, np.array([1.0, 1.0, 2.0, 5.0])) == pytest.approx(7 / 3)
    assert np.isnan(example.half_swing_time(t, np.array([2.0, 2.0, 2.0, 2.0])))
    assert example.inflation_lag(t, np.array([0.0, 2.0, 2.0, 2.0]),
                                 np.array([0.0, 0.0, 0.0, 2.0])) == pytest.approx(2.0)
