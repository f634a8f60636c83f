"""softflow's own API changes made for fonsim scripts: System.connect reusing a
one-terminal component's only terminal, and Simulation(step=(min, max))."""
import re

import numpy as np
import pytest

import softflow as sf


def _chain():
    s = sf.System()
    s += sf.PressureSource("source", pressure=2e5)
    s += sf.CircularTube("tube1", sf.air, length=0.3, diameter=2e-3)
    s += sf.Container("tank", sf.air, volume=20e-6)
    s += sf.CircularTube("tube2", sf.air, length=0.3, diameter=2e-3)
    s += sf.Container("tank2", sf.air, volume=20e-6)
    return s


def test_connect_reuses_the_only_terminal_of_a_connected_one_terminal_component():
    s = _chain()
    s.connect("tube1", "source")
    s.connect("tube1", "tank")
    s.connect("tank", "tube2")          # tank.a is connected already: reused
    s.connect("tube2", "tank2")
    nodes = {frozenset(t.name for t in n.terminals) for n in s.nodes()}
    assert frozenset({"tube1.b", "tank.a", "tube2.a"}) in nodes
    assert not s.unconnected_terminals()
    res = sf.Simulation(s, duration=0.5).run()
    # the far tank fills through the near one
    assert res.get("tank2", "pressure")[-1] == pytest.approx(2e5, rel=1e-3)


def test_connect_full_multi_terminal_component_still_raises():
    s = _chain()
    s.connect("tube1", "source")
    s.connect("tube1", "tank")
    with pytest.raises(sf.NetworkError,
                       match=re.escape("CircularTube 'tube1' has no unconnected terminal left")
                       ) as info:
        s.connect("tube1", "tank2")
    assert "('tube1', 'a')" in str(info.value)   # suggests naming the terminal


def test_one_terminal_component_twice_in_one_connect_is_refused():
    s = _chain()
    with pytest.raises(sf.NetworkError, match="'tank.a' is given twice"):
        s.connect("tank", "tank")


def test_step_pair_is_an_adaptive_range():
    s = _chain()
    s.connect("tube1", "source")
    s.connect("tube1", "tank")
    s.connect("tank", "tube2")
    s.connect("tube2", "tank2")
    sim = sf.Simulation(s, duration=0.2, step=(1e-6, 2e-3))
    assert sim.adaptive and sim.step_min == 1e-6 and sim.step_max == 2e-3
    res = sim.run()
    assert np.diff(res.times).max() <= 2e-3 * (1 + 1e-9)
    sim = sf.Simulation(s, duration=0.2, step=(None, 1e-3))
    assert sim.step_min == 0.2 * 1e-9 and sim.step_max == 1e-3


@pytest.mark.parametrize("kwargs, match", [
    (dict(step=(1e-3, 1e-2, 1e-1)), "must be a pair"),
    (dict(step=(1e-4, None), step_max=1e-2), "not both"),
    (dict(step=(1e-2, 1e-4)), "step_min <= step_max"),
])
def test_step_pair_bad_input(kwargs, match):
    s = _chain()
    s.connect("tube1", "source")
    s.connect("tube1", "tank")
    s.connect("tank", "tube2")
    s.connect("tube2", "tank2")
    with pytest.raises(ValueError, match=match):
        sf.Simulation(s, duration=0.2, **kwargs)
