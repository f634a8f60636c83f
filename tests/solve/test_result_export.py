"""Exports share one naming: every column is ``component.name`` with ``get(component,
name)`` giving its values; CSV reads back as numbers, the DataFrame and the xarray
Dataset carry the units."""
import sys

import numpy as np
import pytest

import softflow as sf
from softflow.demo import paper_system

P0 = sf.pressure_atmospheric


def _actuator_scene(thermal="isothermal"):
    curve = sf.PVCurve(volume=sf.Q_([1, 2, 3], "mL"), pressure=sf.Q_([20, 60, 80], "mbar"),
                       gauge=True)
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 0.1e5)
    s += sf.CircularTube("tube", sf.air, length=0.2, diameter=1e-3)
    s += sf.Actuator("act", sf.air, curve=curve, initial_volume=sf.Q_(1, "mL"))
    s.connect("tube", "src")
    s.connect("tube", "act")
    return sf.Simulation(s, duration=0.05, step=1e-3, thermal=thermal).run()


@pytest.fixture(scope="module")
def result():
    return _actuator_scene()


def test_columns_are_get_names_and_include_the_actuator_volume(result):
    cols = result.columns()
    assert cols == ["src.pressure", "src.massflow", "tube.pressure_a", "tube.massflow_a",
                    "tube.pressure_b", "tube.massflow_b", "act.pressure", "act.massflow",
                    "act.mass", "act.volume"]
    d = result.to_dict()
    assert list(d) == ["time"] + cols
    for col in cols:
        label, name = col.split(".")
        np.testing.assert_array_equal(d[col], result.get(label, name))
        np.testing.assert_array_equal(d[col], result[col])
    np.testing.assert_array_equal(result["time"], result.times)
    # the derived volume: it grows from the initial 1 mL as the actuator fills
    assert d["act.volume"][0] == pytest.approx(1e-6)
    assert d["act.volume"][-1] > 1.5e-6


def test_units_and_quantities(result):
    units = result.units()
    assert units["time"] == "s" and units["act.pressure"] == "Pa"
    assert units["act.massflow"] == "kg/s" and units["act.volume"] == "m**3"
    assert set(units) == {"time", *result.columns()}
    t = result.get_times(as_quantity=True)
    assert t.to("ms").magnitude[-1] == pytest.approx(50.0)
    q = result.to_dict(as_quantity=True)
    assert q["act.volume"].to("mL").magnitude[0] == pytest.approx(1.0)
    assert str(q["time"].units) == "second"


def test_csv_reads_back_as_numbers_with_pandas(result, tmp_path):
    pd = pytest.importorskip("pandas")
    path = tmp_path / "run.csv"
    result.to_csv(path)
    df = pd.read_csv(path)
    assert list(df.columns) == [f"{c} [{u}]" for c, u in result.units().items()]
    assert all(dtype == np.float64 for dtype in df.dtypes), df.dtypes
    assert len(df) == len(result.times)
    np.testing.assert_array_equal(df["act.volume [m**3]"].to_numpy(), result["act.volume"])
    np.testing.assert_array_equal(df["time [s]"].to_numpy(), result.times)


def test_dataframe_names_values_and_units(result):
    pytest.importorskip("pandas")
    df = result.to_dataframe()
    assert list(df.columns) == result.columns()
    assert df.index.name == "time"
    np.testing.assert_array_equal(df.index.to_numpy(), result.times)
    np.testing.assert_array_equal(df["act.pressure"].to_numpy(), result.get("act", "pressure"))
    assert df.attrs["units"] == result.units()
    assert df.attrs["status"] == "success"


def test_xarray_dataset(result, tmp_path):
    pytest.importorskip("xarray")
    ds = result.to_xarray()
    assert list(ds.data_vars) == result.columns()
    assert ds["time"].attrs["units"] == "s"
    np.testing.assert_array_equal(ds["time"].to_numpy(), result.times)
    v = ds["act.volume"]
    assert v.dims == ("time",)
    assert v.attrs == {"units": "m**3", "component": "act", "variable": "volume",
                       "quantity": "volume"}
    np.testing.assert_array_equal(v.to_numpy(), result.get("act", "volume"))
    assert ds.attrs["status"] == "success" and ds.attrs["steps"] == result.stats["steps"]


@pytest.mark.parametrize("method, module, extra", [("to_xarray", "xarray", "xarray"),
                                                   ("to_dataframe", "pandas", "pandas")])
def test_missing_optional_dependency_says_what_to_install(result, monkeypatch, method,
                                                          module, extra):
    monkeypatch.setitem(sys.modules, module, None)       # import fails as if absent
    with pytest.raises(ImportError, match=rf"needs {module}.*softflow\[{extra}\]"):
        getattr(result, method)()


def test_thermal_and_user_component_names():
    res = _actuator_scene(thermal="adiabatic")
    cols = res.columns()
    # the thermal actuator's volume is a state; it appears once
    assert cols.count("act.volume") == 1
    assert {"act.temperature", "act.energyflow", "act.internal_energy",
            "tube.temperature_b"} <= set(cols)
    for col in cols:
        assert np.array_equal(res[col], res.get(*col.split(".")))
    # the paper's user-written actuator (variables labelled p, mf, mass)
    paper = sf.Simulation(paper_system(), duration=0.05, step=1e-3).run()
    assert paper.columns()[-3:] == ["actu.pressure", "actu.massflow", "actu.mass"]


def test_a_valve_mode_goes_by_its_label():
    s = sf.System()
    s += sf.PressureSource("src", pressure=3e5)
    s += sf.SnappingValve("valve", sf.air, opening_pressure=2e5, closing_pressure=1.5e5,
                          closed_conductance=1e-12, length=0.1, diameter=1e-3)
    s += sf.Container("tank", sf.air, volume=1e-6)
    s.connect("src", "valve")
    s.connect("valve", "tank")
    res = sf.Simulation(s, duration=0.01, step=1e-3).run()
    assert "valve.open" in res.columns()
    assert res.units()["valve.open"] == "1"


def test_unknown_component_lists_the_ones_there_are(result):
    with pytest.raises(KeyError, match=r"no component 'actuator'.*'act', 'src', 'tube'"):
        result.get("actuator", "volume")
