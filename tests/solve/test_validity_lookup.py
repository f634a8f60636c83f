"""How the validity checks read a run: group_values finds each name's columns
once per compiled group (validity._FOUND) and gives what result.get gives,
recorded or not, after run-time parameters too; group_times; the
compressibility bound on floats and arrays."""
import numpy as np
import pytest

import softflow as sf
from softflow.paper_scenes import curve_peak_valley
from softflow.solve.model_checks import compressibility_bound
from softflow.solve.validity import group_times, group_values


def scene():
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.3e5)
    s += sf.CircularTube("t0", sf.air, 0.3, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5)
    s += sf.CircularTube("t1", sf.air, 0.3, 0.8e-3)
    s += sf.Actuator("act", sf.air, curve_peak_valley())
    s.connect("src", "t0")
    s.connect("t0", "tank")
    s.connect("tank", "t1")
    s.connect("t1", "act")
    return s


NAMES = ["pressure", "pressure_a", "pressure_b", "massflow_a", "massflow", "mass", "volume"]


def _group_of(sim, label):
    return sim.asm.where[label][0]


def _expected(res, g, name):
    """(members, values) as result.get gives them, for the recorded members."""
    keep, cols = [], []
    for i, c in enumerate(g.comps):
        if c.label not in res._where:
            continue
        try:
            v = res.get(c.label, name)
        except KeyError:
            return None
        keep.append(i)
        cols.append(v)
    return keep, (np.stack(cols, axis=1) if cols else None)


def _check_all(sim, res):
    for g in sim.asm.groups:
        for name in NAMES:
            want = _expected(res, g, name)
            for _ in range(2):          # the lookup, then the remembered columns
                if want is None:
                    with pytest.raises(KeyError) as first:
                        group_values(g, res, name)
                    with pytest.raises(KeyError) as again:
                        group_values(g, res, name)
                    assert str(first.value) == str(again.value)
                    continue
                keep, values = group_values(g, res, name)
                assert keep == want[0]
                if keep:
                    np.testing.assert_array_equal(values, want[1])


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_group_values_is_result_get_on_every_run():
    sim = sf.Simulation(scene(), duration=0.05)
    _check_all(sim, sim.run())
    _check_all(sim, sim.run())                       # the remembered columns
    _check_all(sim, sim.run(params={"tank.volume": 2e-5, "t0.diameter": 1.2e-3}))
    res = sim.run()
    keep, _ = group_values(_group_of(sim, "tank"), res, "pressure")
    keep.append(99)        # a caller's list is its own
    assert group_values(_group_of(sim, "tank"), res, "pressure")[0] == [0]


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_group_values_of_a_recorded_subset():
    sim = sf.Simulation(scene(), duration=0.05, record=["tank", "t1"])
    for _ in range(2):
        res = sim.run()
        _check_all(sim, res)
        assert group_values(_group_of(sim, "act"), res, "pressure")[0] == []


@pytest.mark.filterwarnings("ignore::softflow.ModelWarning")
def test_group_times_are_the_result_times_per_member():
    sim = sf.Simulation(scene(), duration=0.05)
    res = sim.run()
    g = _group_of(sim, "t0")
    for keep in ([0], [0, 1]):
        tt = group_times(g, res, keep)
        assert tt.shape == (len(res.times), len(keep))
        for j in range(len(keep)):
            np.testing.assert_array_equal(tt[:, j], res.times)
        with pytest.raises(ValueError):
            tt[0, 0] = -1.0          # read-only: the result's times stay as they are


def test_compressibility_bound_on_floats_and_arrays():
    p = np.geomspace(1e4, 5e7, 9)
    for name in ("air", "nitrogen"):
        one = compressibility_bound(name, 300.0, 300.0, p)
        assert one.shape == p.shape
        for k, pk in enumerate(p):
            assert compressibility_bound(name, 300.0, 300.0, float(pk)) == pytest.approx(
                one[k], rel=1e-12)
        assert compressibility_bound(name, 300.0, 300.0, [1e5]).shape == (1,)
        # a temperature range: the largest over it, at least that at either end
        both = compressibility_bound(name, 250.0, 400.0, p)
        assert both.shape == p.shape
        assert np.all(both >= compressibility_bound(name, 250.0, 250.0, p) * (1 - 1e-12))
        assert np.all(both >= compressibility_bound(name, 400.0, 400.0, p) * (1 - 1e-12))
