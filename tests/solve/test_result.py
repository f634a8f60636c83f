"""Result access and export."""
import numpy as np
import pytest

import softflow as sf
from helpers import source_tube_tank


@pytest.fixture(scope="module")
def result():
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.5, "bar"))
    s += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=sf.Q_(1, "mm"))
    s += sf.Container("tank", sf.air, volume=sf.Q_(10, "mL"))
    s.connect("tube", "src")
    s.connect("tube", "tank")
    return sf.Simulation(s, duration=sf.Q_(50, "ms"), step=sf.Q_(1, "ms")).run()


def test_get_by_label_quantity_and_terminal(result):
    assert result.success and result.status == "success"
    p = result.get("tank", "pressure")
    assert np.array_equal(p, result.get("tank", "p"))
    assert p[0] == pytest.approx(sf.pressure_atmospheric)
    a = result.get("tube", "massflow", "a")
    b = result.get("tube", "mf_b")
    np.testing.assert_allclose(a, -b, atol=1e-15)
    with pytest.raises(KeyError, match="ambiguous"):
        result.get("tube", "pressure")
    with pytest.raises(KeyError, match="has no variable"):
        result.get("tank", "temperature")
    assert np.array_equal(result["tank.mass"], result.get("tank", "mass"))


def test_quantities(result):
    q = result.get("tank", "pressure", as_quantity=True)
    assert q.to("bar").magnitude[0] == pytest.approx(1.01325)
    m = result.get("tank", "mass", as_quantity=True)
    assert str(m.units) == "kilogram"


def test_exports(result, tmp_path):
    d = result.to_dict()
    assert set(d) >= {"time", "tank.pressure", "tank.mass", "tank.volume", "tube.pressure_a",
                      "tube.massflow_b", "src.massflow"}
    assert len(d["time"]) == 51
    path = tmp_path / "out.csv"
    result.to_csv(path)
    header = path.read_text().splitlines()[0].split(",")
    assert header[:1] == ["time [s]"] and "tank.pressure [Pa]" in header
    table = sf.read_table(path)            # softflow's own reader takes it too
    np.testing.assert_allclose(table.column("tank.pressure [Pa]", "Pa", default_unit="Pa"),
                               d["tank.pressure"])
    df = result.to_dataframe()
    assert df.index.name == "time" and df.shape == (51, len(d) - 1)


def test_component_get_after_run(result):
    # Simulation.run attaches the result to the components (the paper's API)
    assert result.get("tank", "p")[-1] > 1.2e5


def test_record_keeps_only_the_chosen_components():
    full = sf.Simulation(source_tube_tank(), duration=0.02, step=1e-3).run()
    part = sf.Simulation(source_tube_tank(), duration=0.02, step=1e-3, record=["tank"]).run()
    np.testing.assert_array_equal(part.get("tank", "pressure"), full.get("tank", "pressure"))
    np.testing.assert_array_equal(part.get("tank", "mass"), full.get("tank", "mass"))
    assert part.X.shape[1] == 2 and part.S.shape[1] == 1
    with pytest.raises(KeyError, match="record"):
        part.get("tube", "massflow", "a")
    with pytest.raises(KeyError, match="unknown component"):
        sf.Simulation(source_tube_tank(), duration=0.02, record=["nope"])
    assert set(part.to_dict()) == {"time", "tank.pressure", "tank.massflow", "tank.mass",
                                   "tank.volume"}
