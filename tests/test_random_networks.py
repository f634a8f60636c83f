"""Randomized networks (issue 17, hypothesis): random trees of library components
behind a pressure source, random sizes across physical ranges, air or water,
adaptive or fixed steps. Each run either succeeds with finite values, positive
absolute pressures and mass conserved (what left the source is what the volumes
hold, to 1e-12 relative as the run integrated it), or fails with a
SimulationError naming a component and a time: never an exception from inside
NumPy, SciPy or CoolProp, never an unbounded run (max_steps)."""
import warnings

import numpy as np
import pytest

import softflow as sf

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: examples per run of the default suite (a few seconds); the slow test runs more
EXAMPLES = 10
EXAMPLES_SLOW = 300

log_uniform = st.floats(min_value=-1.0, max_value=1.0).map(lambda x: 10.0 ** x)


@st.composite
def networks(draw):
    fluid = draw(st.sampled_from([sf.air, sf.water]))
    s = sf.System()
    s += sf.PressureSource("src", pressure=draw(st.floats(1.05e5, 1.8e5)))
    volumes = []
    # a tree: each new tube hangs off the source or off the far end of an earlier tube
    ends = [("src", None)]
    for k in range(draw(st.integers(1, 4))):
        parent = draw(st.sampled_from(ends))
        tube = f"t{k}"
        s += sf.CircularTube(tube, fluid, length=0.3 * draw(log_uniform),
                             diameter=1e-3 * draw(log_uniform))
        s.connect((tube, "a"), parent if parent[1] else parent[0])
        kind = draw(st.sampled_from(["volume", "actuator", "tube end"]))
        if kind == "tube end" and k < 3:
            ends.append((tube, "b"))
            continue
        label = f"v{k}"
        if kind == "actuator":
            curve = sf.PVCurve.monotonic((1e-6, 1.0e5), (3e-6, 1.3e5), (8e-6, 1.6e5))
            s += sf.Actuator(label, fluid, curve)
        elif fluid.compressible:
            s += sf.Container(label, fluid, volume=1e-5 * draw(log_uniform))
        else:
            s += sf.LinearAccumulator(label, fluid, volume=1e-6, compliance=1e-11 *
                                      draw(log_uniform))
        s.connect((tube, "b"), label)
        volumes.append(label)
    if not volumes:                    # every tube ends somewhere: close the last one
        s += sf.Container("cap", fluid, volume=1e-5) if fluid.compressible else \
            sf.LinearAccumulator("cap", fluid, volume=1e-6, compliance=1e-11)
        s.connect((ends[-1][0], "b"), "cap")
        volumes.append("cap")
    step = draw(st.sampled_from([None, 1e-3]))
    return s, volumes, step


def check(network):
    system, volumes, step = network
    try:
        sim = sf.Simulation(system, duration=0.05, step=step, max_steps=20_000,
                            allow_unconnected=True)
    except sf.NetworkError as err:       # refused at compile time: says where
        assert "'" in str(err)
        return "refused"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        try:
            res = sim.run()
        except sf.SimulationError as err:
            assert err.component is not None and err.time is not None, str(err)
            return "failed"
    assert res.status == "success"
    for column, values in res.to_dict().items():
        assert np.isfinite(values).all(), column
    pressures = [res.get(c, "pressure") for c in volumes]
    assert min(p.min() for p in pressures) > 0
    stored = sum(res.get(c, "mass") - res.get(c, "mass")[0] for c in volumes)
    supplied = -res.integral("src", "massflow")
    scale = max(np.abs(stored).max(), sum(res.get(c, "mass")[0] for c in volumes))
    assert np.abs(stored - supplied).max() <= 1e-12 * scale + 1e-300
    return "success"


@settings(max_examples=EXAMPLES, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(networks())
def test_random_trees_succeed_conserving_mass_or_fail_naming_a_component(network):
    check(network)


@pytest.mark.slow
@settings(max_examples=EXAMPLES_SLOW, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(networks())
def test_random_trees_many(network):
    check(network)
