"""A failure at a node's unknown (no component's equation) names the components
joined there (found by the randomized networks: a suction source through two
tubes failed at t = 0 with no component named)."""
import pytest

import softflow as sf

P0 = sf.pressure_atmospheric


def test_negative_pressure_at_a_node_names_its_components():
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0)
    s += sf.CircularTube("t0", sf.water, 1.0, 0.5e-3)
    s += sf.CircularTube("t1", sf.water, 1.0, 0.5e-3)
    s += sf.VolumeFlowSource("v1", volumeflow=-1e-5, fluid=sf.water)
    s.connect("src", "t0")
    s.connect("t0", "t1")
    s.connect("t1", "v1")
    with pytest.raises(sf.SimulationError, match=r"components at that node: 't1', 'v1'") as info:
        sf.Simulation(s, duration=0.1).run()
    assert info.value.component == "t1" and info.value.time == 0.0
