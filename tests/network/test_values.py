"""Objects a user builds are values: a System (actuators, PV curves, waveforms,
module-level user components, fluids at every level) pickles and deep-copies
with its connections, and runs to bitwise the same results; compiling and
running a Simulation leaves the System as it was."""
import copy
import pickle

import numpy as np
import pytest

import softflow as sf
from softflow.paper_scenes import curve_peak_valley, loop_hysteretic

P0 = sf.pressure_atmospheric


class Balloon(sf.Component):
    """A user component at module level (what pickle can find by name)."""

    def __init__(self, label, stiffness=2e9):
        super().__init__(label)
        self.stiffness = stiffness
        self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across", label="p",
                                                         initial_value=P0),
                                             sf.Variable("massflow", "through", label="mf")]))
        self.set_states(sf.Variable("mass", "local", label="mass", initial_value=2e-6))
        self.evaluate = self.auto(self.residual)
        self.state_rates = self.auto_rates(self.rates)

    def residual(self, p, mass):
        return [p - (P0 + self.stiffness * (mass - 2e-6))]

    @staticmethod
    def rates(mf):
        return {"mass": mf}


def scene(fluid=sf.air):
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.waveforms.Square(P0, P0 + 3e4, 2.0))
    s += sf.CircularTube("tube", fluid, 0.5, 1e-3)
    s += sf.Actuator("act", fluid, curve_peak_valley())
    s += sf.CircularTube("t2", fluid, 0.3, 1e-3)
    s += sf.HystereticActuator("h", fluid, *loop_hysteretic())
    s += sf.CircularTube("t3", fluid, 0.3, 1e-3)
    s += Balloon("b")
    s.connect("src", "tube")
    s.connect("tube", "act")
    s.connect("act", "t2")          # the actuator's only terminal, reused
    s.connect("t2", "h")
    s.connect("h", "t3")
    s.connect("t3", "b")
    return s


def _run(system, **kw):
    return sf.Simulation(system, duration=0.6, **kw).run()


def _same(a, b):
    np.testing.assert_array_equal(a.times, b.times)
    for label, name in (("act", "pressure"), ("h", "mass"), ("b", "pressure"),
                        ("tube", "massflow_a")):
        np.testing.assert_array_equal(a.get(label, name), b.get(label, name))


@pytest.mark.parametrize("level", ["ideal", "table", "eos"])
@pytest.mark.parametrize("how", ["pickle", "deepcopy"])
def test_system_round_trip_runs_bitwise_the_same(level, how):
    fluid = sf.air if level == "ideal" else sf.air.with_level(level)
    s = scene(fluid)
    twin = pickle.loads(pickle.dumps(s)) if how == "pickle" else copy.deepcopy(s)
    assert [sorted(t.name for t in n.terminals) for n in twin.nodes()] == \
        [sorted(t.name for t in n.terminals) for n in s.nodes()]
    assert twin.get("tube").fluid.level == level
    if level == "ideal" or how == "deepcopy":
        # eos runs are slow; one pickled eos scene is checked by compiling it
        _same(_run(s, step=2e-3), _run(twin, step=2e-3))
    else:
        sf.Simulation(twin, duration=0.1)


def test_connections_survive_copies_and_can_be_extended():
    s = scene()
    twin = copy.deepcopy(s)
    twin += sf.Container("tank", sf.air, 1e-5)
    twin += sf.CircularTube("t4", sf.air, 0.2, 1e-3)
    twin.connect("b", "t4")
    twin.connect("t4", "tank")
    assert len(twin.nodes()) == len(s.nodes()) + 1
    assert "tank" not in s


@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_compiling_and_running_leave_the_system_unchanged(thermal):
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 2e4)
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    before = pickle.dumps(s)
    n_vars = [len(t.variables) for c in s for t in c.terminals]
    for _ in range(2):
        sim = sf.Simulation(s, duration=0.05, thermal=thermal)
        sim.run()
    assert [len(t.variables) for c in s for t in c.terminals] == n_vars
    assert pickle.dumps(s) == before
    # the paper's way to read results still finds the last run
    np.testing.assert_array_equal(s.get("tank").get("pressure"),
                                  sim.result.get("tank", "pressure"))
    assert P0 + 1e3 < s.get("tank").get("pressure")[-1] < P0 + 2e4
