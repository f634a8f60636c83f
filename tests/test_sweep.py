"""sf.sweep: one compiled Simulation over many run-time parameter variants, on the
serial, process, Dask and batched engines (softflow.sweep)."""
import importlib.util
import logging
import pickle
import sys
import warnings

import numpy as np
import pytest

import softflow as sf

# the source-tube-tank scene's wider tubes pass Mach 0.3 at the start (a ModelWarning)
pytestmark = pytest.mark.filterwarnings("ignore::softflow.solve.validity.ModelWarning")

D = sf.Q_([0.8, 1.0, 1.3], "mm")
V = sf.Q_([5.0, 10.0], "mL")


def fill(diameter=1e-3, volume=10e-6):
    """The README's source-tube-tank scene."""
    system = sf.System()
    system += sf.PressureSource("source", pressure=sf.Q_(1.5, "bar"))
    system += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=diameter)
    system += sf.Container("tank", sf.air, volume=volume)
    system.connect("tube", "source")
    system.connect("tube", "tank")
    return system


def supply_lost(t):
    """A source pressure whose supply fails after 20 ms (module level: it pickles)."""
    if t > 0.02:
        raise ValueError("supply lost")
    return 1.5e5


@pytest.fixture(scope="module")
def fixed():
    return sf.Simulation(fill(), duration=sf.Q_(50, "ms"), step=sf.Q_(5, "ms"))


@pytest.fixture(scope="module")
def adaptive():
    return sf.Simulation(fill(), duration=sf.Q_(50, "ms"))


@pytest.fixture(scope="module")
def serial_fixed(fixed):
    return sf.sweep(fixed, {"tube.diameter": D, "tank.volume": V})


# -- the numbers ---------------------------------------------------------------------------
def test_serial_sweep_is_each_variant_run_on_its_own(fixed, serial_fixed):
    res = serial_fixed
    assert len(res) == 6 and res.status == ["success"] * 6 and res.messages == [""] * 6
    # the grid's order: the last key varies fastest
    assert res.variants[1] == {"tube.diameter": D[0], "tank.volume": V[1]}
    np.testing.assert_array_equal(res.times, np.arange(11) * 0.005)
    for i, (d, v) in enumerate([(d, v) for d in D for v in V]):
        fresh = sf.Simulation(fill(d, v), duration=0.05, step=0.005).run()
        np.testing.assert_array_equal(fresh.times, res.times)
        for output in res.outputs:          # bitwise: the same run, sampled on its own grid
            np.testing.assert_array_equal(res[output][i], fresh[output], err_msg=output)
    # a larger tube fills the tank faster; a larger tank fills slower
    p = res["tank.pressure"][:, 5].reshape(3, 2)
    assert np.all(np.diff(p, axis=0) > 0) and np.all(p[:, 0] > p[:, 1])


def test_sweep_leaves_the_simulation_at_its_compiled_values(fixed, serial_fixed):
    before = fixed.run()
    sf.sweep(fixed, {"tube.diameter": [2e-3]})
    after = fixed.run()
    np.testing.assert_array_equal(before["tank.pressure"], after["tank.pressure"])


def test_processes_and_dask_match_serial_bitwise_at_fixed_steps(fixed, serial_fixed):
    from distributed import Client, LocalCluster
    grid = {"tube.diameter": D, "tank.volume": V}
    by_processes = sf.sweep(fixed, grid, engine="processes", workers=2)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=None, silence_logs=logging.ERROR) as cluster, \
            Client(cluster) as client:
        by_dask = sf.sweep(fixed, grid, engine="dask", client=client)
    for res in (by_processes, by_dask):
        assert res.status == serial_fixed.status
        assert res.outputs == serial_fixed.outputs
        np.testing.assert_array_equal(res.times, serial_fixed.times)
        np.testing.assert_array_equal(res.data, serial_fixed.data)


def test_adaptive_sweeps_agree_across_engines_and_interpolate(adaptive):
    variants = [{"tube.diameter": d} for d in sf.Q_([0.7, 1.1, 1.6, 2.0], "mm")]
    serial = sf.sweep(adaptive, variants, outputs=["tank.pressure", "tube.massflow_b"])
    assert serial.data.shape == (4, 2, 201)
    np.testing.assert_allclose(serial.times, np.linspace(0, 0.05, 201), rtol=0, atol=0)
    by_processes = sf.sweep(adaptive, variants, outputs=["tank.pressure", "tube.massflow_b"],
                            engine="processes", workers=2)
    np.testing.assert_array_equal(by_processes.data, serial.data)
    # the run's own interpolant between its steps (Result.at), not straight
    # lines between its points
    run = adaptive.run(params=variants[2])
    expected = run.at(serial.times, "tank", "pressure")
    np.testing.assert_array_equal(serial["tank.pressure"][2], expected)


def test_default_dask_engine_starts_and_closes_a_local_cluster(fixed, serial_fixed,
                                                              monkeypatch):
    import distributed
    made = []

    class InProcess(distributed.LocalCluster):
        """The LocalCluster sweep asks for, with its workers as threads of this
        process (worker processes take 5-20 s to start on a loaded 2-core CI)."""

        def __init__(self, **kw):
            made.append(dict(kw))
            super().__init__(**dict(kw, processes=False))
            made.append(self)

    monkeypatch.setattr(distributed, "LocalCluster", InProcess)
    res = sf.sweep(fixed, {"tube.diameter": D, "tank.volume": V}, engine="dask", workers=2,
                   outputs=["tank.pressure"])
    asked, cluster = made
    assert asked["n_workers"] == 2 and asked["threads_per_worker"] == 1
    assert asked["processes"] is True
    assert cluster.status.name == "closed"
    k = serial_fixed.outputs.index("tank.pressure")
    np.testing.assert_array_equal(res.data[:, 0, :], serial_fixed.data[:, k, :])


@pytest.mark.skipif(importlib.util.find_spec("softflow.solve.batched") is None,
                    reason="the batched engine is not in this tree")
def test_batched_engine_within_tolerance_of_serial(adaptive):
    variants = {"tube.diameter": sf.Q_([0.7, 1.1, 1.6], "mm")}
    # compared where both runs have a step of their own (the end): in between, the
    # serial runs' few steps (~9) are interpolated linearly, the batched run's many not
    kw = dict(outputs=["tank.pressure"], times=[0.0, 0.05])
    serial = sf.sweep(adaptive, variants, **kw)
    batched = sf.sweep(adaptive, variants, engine="batched", **kw)
    assert batched.status == ["success"] * 3
    # each in its place, within a few tolerances (rtol 1e-3) of its own serial run (the
    # variants' end pressures differ by 15 % and more)
    np.testing.assert_allclose(batched.data, serial.data, rtol=3e-3)


@pytest.mark.skipif(importlib.util.find_spec("softflow.solve.batched") is None,
                    reason="the batched engine is not in this tree")
@pytest.mark.parametrize("was_enabled", [True, False])
def test_batched_sweep_leaves_the_garbage_collector_as_it_was(adaptive, was_enabled,
                                                             monkeypatch):
    """The batched engine pauses the collector while its batch lives (sweep.py):
    it is restored as the caller had it, enabled or not, also on an error."""
    import gc

    from softflow.solve import batched
    variants = {"tube.diameter": sf.Q_([0.7, 1.1], "mm")}
    (gc.enable if was_enabled else gc.disable)()
    try:
        sf.sweep(adaptive, variants, engine="batched", outputs=["tank.pressure"])
        assert gc.isenabled() is was_enabled

        def broken(*args, **kwargs):
            assert not gc.isenabled()          # paused while the batch runs
            raise RuntimeError("batch broke")
        monkeypatch.setattr(batched, "_run_batched", broken)
        with pytest.raises(RuntimeError, match="batch broke"):
            sf.sweep(adaptive, variants, engine="batched")
        assert gc.isenabled() is was_enabled
    finally:
        gc.enable()


# -- failures ------------------------------------------------------------------------------
@pytest.mark.parametrize("engine", ["serial", "processes"])
def test_a_failed_variant_is_recorded_and_the_sweep_goes_on(fixed, engine):
    variants = [{"source.pressure": 1.4e5}, {"source.pressure": supply_lost},
                {"tube.diameter": 2e-3}]
    res = sf.sweep(fixed, variants, outputs=["tank.pressure"], engine=engine,
                   **({"workers": 2} if engine == "processes" else {}))
    assert res.status == ["success", "failed", "success"]
    assert res.failed == [1]
    assert "supply lost" in res.messages[1] and "source" in res.messages[1]
    assert res.messages[0] == res.messages[2] == ""
    p = res["tank.pressure"]
    assert np.isfinite(p[[0, 2]]).all()
    # the failed run's values up to where it got, NaN after
    assert np.isfinite(p[1, :5]).all() and np.isnan(p[1, 5:]).all()
    ds = res.to_xarray()
    assert list(ds["status"].values) == res.status
    assert "supply lost" in ds["message"].values[1]


# -- exports -------------------------------------------------------------------------------
def test_to_xarray_of_a_grid(serial_fixed):
    ds = serial_fixed.to_xarray()
    # tank.volume is a parameter and a result column: the parameter's coordinate says so
    name = serial_fixed.coordinate_names["tank.volume"]
    assert name == "tank.volume (parameter)"
    assert serial_fixed.coordinate_names["tube.diameter"] == "tube.diameter"
    assert dict(ds.sizes) == {"tube.diameter": 3, name: 2, "time": 11}
    np.testing.assert_allclose(ds["tube.diameter"].values, [0.8e-3, 1e-3, 1.3e-3])
    assert ds["tube.diameter"].attrs == {"parameter": "tube.diameter", "units": "m"}
    np.testing.assert_allclose(ds[name].values, [5e-6, 10e-6])
    assert ds[name].attrs["units"] == "m**3"
    assert ds["time"].attrs["units"] == "s"
    assert set(ds.data_vars) == set(serial_fixed.outputs)
    p = ds["tank.pressure"]
    assert p.dims == ("tube.diameter", name, "time")
    assert p.attrs == {"units": "Pa", "component": "tank", "variable": "pressure"}
    assert ds["tube.massflow_b"].attrs["units"] == "kg/s"
    # the variant (1.0 mm, 5 mL) is variant 2 of the flat order
    np.testing.assert_array_equal(p.sel({"tube.diameter": 1e-3, name: 5e-6},
                                        method="nearest").values,
                                  serial_fixed["tank.pressure"][2])
    assert ds["status"].dims == ("tube.diameter", name)
    assert (ds["status"].values == "success").all()


def test_to_xarray_of_a_variant_list_and_labelled_values(fixed):
    low, high = sf.Q_(1.3, "bar"), sf.Q_(1.6, "bar")
    res = sf.sweep(fixed, [{"tube.diameter": sf.Q_(1, "mm")}, {"source.pressure": low},
                           {"source.pressure": high, "tube.diameter": 0.9e-3}],
                   outputs="tank.pressure")
    ds = res.to_xarray()
    assert dict(ds.sizes) == {"variant": 3, "time": 11}
    np.testing.assert_allclose(ds["tube.diameter"].values, [1e-3, np.nan, 0.9e-3])
    np.testing.assert_allclose(ds["source.pressure (parameter)"].values,
                               [np.nan, 1.3e5, 1.6e5])
    assert ds["source.pressure (parameter)"].attrs["units"] == "Pa"
    assert res["tank.pressure"][2, -1] > res["tank.pressure"][1, -1]
    # values that are not numbers: labelled by the user ({coordinate: value})
    res = sf.sweep(fixed, {"source.pressure": {"low": low, "high": supply_lost}},
                   outputs="tank.pressure")
    ds = res.to_xarray()
    assert list(ds["source.pressure (parameter)"].values) == ["low", "high"]
    assert list(ds["status"].values) == ["success", "failed"]


def test_to_dataframe_is_tidy(serial_fixed):
    df = serial_fixed.to_dataframe()
    assert len(df) == 6 * 11
    assert list(df.columns[:6]) == ["variant", "tube.diameter", "tank.volume (parameter)",
                                    "status", "message", "time"]
    assert list(df.columns[6:]) == serial_fixed.outputs
    row = df[(df["variant"] == 3)].iloc[4]
    assert row["tube.diameter"] == pytest.approx(1e-3)
    assert row["tank.volume (parameter)"] == pytest.approx(10e-6)
    assert row["time"] == pytest.approx(0.02)
    assert row["tank.pressure"] == serial_fixed["tank.pressure"][3, 4]
    assert df.attrs["units"]["tank.pressure"] == "Pa"
    assert df.attrs["units"]["tube.diameter"] == "m"
    assert df.attrs["units"]["time"] == "s"


def test_sweep_result_pickles(serial_fixed):
    back = pickle.loads(pickle.dumps(serial_fixed))
    np.testing.assert_array_equal(back.data, serial_fixed.data)
    assert back.to_xarray().identical(serial_fixed.to_xarray())


def test_validity_warnings_are_kept_per_variant_and_warned_once():
    from softflow import paper_scenes as ps
    system = ps.fig4("tube")
    sim = sf.Simulation(system, duration=ps.duration(4), step=0.25)
    # a curve measured to 4 mL only: actuator 2 inflates past its data
    short = sf.PVCurve.monotonic(*ps._pv([(1.0, 0.0), (2.0, 22.0), (4.0, 30.0)]), gauge=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sf.sweep(sim, {"act2.curve": {"short": short, "plateau": ps.curve_plateau(22.0)}},
                       outputs=["act2.volume"])
    assert res.status == ["success", "success"]
    # (the tube's inertia check reports on both variants; the curve's range on one)
    curve = [[m for m in found if "PV curve" in m] for found in res.warnings]
    assert len(curve[0]) == 1 and "beyond the last sample" in curve[0][0]
    assert curve[1] == []
    # one ModelWarning for the whole sweep, counting the variants that had any
    model = [str(w.message) for w in caught if issubclass(w.category, sf.ModelWarning)]
    k = sum(bool(found) for found in res.warnings)
    assert len(model) == 1 and model[0].startswith(f"sweep: {k} of 2 variants"), model


# -- bad input -----------------------------------------------------------------------------
@pytest.mark.parametrize("params, error, words", [
    ({"tube.diam": [1e-3]}, KeyError, ["variant 0", "'tube.diam'", "diameter", "length"]),
    ({"pipe.diameter": [1e-3]}, KeyError, ["'pipe'", "'source', 'tank', 'tube'"]),
    ({"tube.diameter": [1e-3, sf.Q_(1, "bar")]}, sf.UnitError,
     ["variant 1 of 2", "tube.diameter=1 bar", "a length [m]"]),
    ({"tube.diameter": [1e-3], "tank.volume": [1e-5, -1e-6]}, ValueError,
     ["variant 1 of 2", "tank.volume", "> 0"]),
    ({"tube.fluid": [sf.water]}, sf.NetworkError, ["structure", "new Simulation"]),
    ({"tube.diameter": []}, ValueError, ["'tube.diameter'", "empty"]),
    ({}, ValueError, ["empty grid"]),
    ([], ValueError, ["empty list"]),
    ({"tube.diameter": 1e-3}, TypeError, ["list of values", "[value]"]),
    ([{"tube.diameter": 1e-3}, 2e-3], TypeError, ["variant 1", "dict"]),
    ("tube.diameter", TypeError, ["grid", "list of variants"]),
])
def test_bad_params_are_refused_before_any_run(fixed, params, error, words):
    messages = []
    for engine in ("serial", "batched"):    # the batched engine checks on its own
        with pytest.raises(error) as info:
            sf.sweep(fixed, params, engine=engine)
        messages.append(info.value.args[0])
        for w in words:
            assert w in messages[-1], (engine, w, messages[-1])
    assert messages[0] == messages[1]


def test_batched_engine_refuses_values_that_split_a_group():
    """Two tubes evaluated together: another fluid for one of them is refused by
    the batched engine's check as by a run."""
    system = fill()
    system += sf.CircularTube("tube2", sf.air, length=0.3, diameter=1e-3)
    system += sf.Container("tank2", sf.air, volume=1e-5)
    system.connect("tube2", "source")
    system.connect("tube2", "tank2")
    sim = sf.Simulation(system, duration=0.01, step=0.005)
    variants = [{"tube.diameter": 1e-3}, {"tube.diameter": 1e-3, "tube2.Re_laminar": 1500.0}]
    for engine in ("serial", "batched"):
        with pytest.raises(sf.NetworkError, match="variant 1 of 2.*evaluated together"):
            sf.sweep(sim, variants, engine=engine)


def test_bad_arguments(fixed):
    grid = {"tube.diameter": [1e-3]}
    with pytest.raises(ValueError, match="unknown engine 'gpu'.*'serial', 'processes', "
                                         "'dask', 'batched'"):
        sf.sweep(fixed, grid, engine="gpu")
    with pytest.raises(KeyError, match="unknown output 'tank.presure'.*'tank.pressure'"):
        sf.sweep(fixed, grid, outputs=["tank.presure"])
    with pytest.raises(ValueError, match=r"times must lie within \[0, 0.05\]"):
        sf.sweep(fixed, grid, times=[0, 0.1])
    with pytest.raises(ValueError, match="increasing"):
        sf.sweep(fixed, grid, times=[0.02, 0.01])
    with pytest.raises(sf.UnitError, match="times"):
        sf.sweep(fixed, grid, times=sf.Q_([1, 2], "mm"))
    with pytest.raises(ValueError, match="workers= is for engine='processes' or 'dask'"):
        sf.sweep(fixed, grid, workers=2)
    with pytest.raises(ValueError, match="workers must be an integer >= 1"):
        sf.sweep(fixed, grid, engine="processes", workers=0)
    with pytest.raises(ValueError, match="client= is for engine='dask'"):
        sf.sweep(fixed, grid, client=object())
    with pytest.raises(TypeError, match="must be a softflow Simulation"):
        sf.sweep(fill(), grid)
    # a times grid in other units
    res = sf.sweep(fixed, grid, times=sf.Q_([0, 25, 50], "ms"), outputs="tank.pressure")
    np.testing.assert_allclose(res.times, [0, 0.025, 0.05])


def test_dask_engine_without_dask_names_the_extra(fixed, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)     # import distributed fails
    with pytest.raises(ImportError, match=r"softflow\[dask\]"):
        sf.sweep(fixed, {"tube.diameter": [1e-3]}, engine="dask")


def test_batched_engine_without_its_module_says_so(fixed, monkeypatch):
    import importlib.util as util
    real = util.find_spec
    monkeypatch.setattr(util, "find_spec", lambda name, *a: None
                        if name == "softflow.solve.batched" else real(name, *a))
    with pytest.raises(NotImplementedError, match="softflow.solve.batched"):
        sf.sweep(fixed, {"tube.diameter": [1e-3]}, engine="batched")


def test_a_simulation_that_does_not_pickle_is_refused_for_processes(fixed, monkeypatch):
    def refuse(self):
        raise pickle.PicklingError("a local function")
    monkeypatch.setattr(sf.Simulation, "__reduce_ex__", lambda self, proto: refuse(self))
    with pytest.raises(TypeError, match="engine='processes'.*does not pickle.*'serial'"):
        sf.sweep(fixed, {"tube.diameter": [1e-3]}, engine="processes", workers=1)


def test_sf_sweep_is_callable_where_it_is_the_module(fixed, monkeypatch):
    # `import softflow.sweep` before the first use of sf.sweep makes the package's
    # attribute the module (the import system sets it): that module runs the sweep
    module = sys.modules["softflow.sweep"]
    monkeypatch.setattr(sf, "sweep", module)
    assert sf.sweep.SweepResult is sf.SweepResult
    res = sf.sweep(fixed, {"tube.diameter": [1e-3]}, outputs="tank.pressure")
    assert isinstance(res, sf.SweepResult) and res.status == ["success"]


def test_progress_bar_counts_variants(fixed, capsys):
    sf.sweep(fixed, {"tube.diameter": D}, outputs="tank.pressure", progress=True)
    err = capsys.readouterr().err
    assert "3/3" in err and "variant" in err
    sf.sweep(fixed, {"tube.diameter": D}, outputs="tank.pressure", progress=False)
    assert capsys.readouterr().err == ""


def test_outputs_as_label_variable_pairs(fixed):
    """('tank', 'pressure'), as sf.assess and Result.get take it, names the
    column 'tank.pressure'; a pair that names no column says which exist."""
    grid = {"tube.diameter": [1e-3]}
    by_pair = sf.sweep(fixed, grid, outputs=[("tank", "pressure"), "tube.massflow_b"])
    assert by_pair.outputs == ["tank.pressure", "tube.massflow_b"]
    one = sf.sweep(fixed, grid, outputs=("tank", "pressure"))
    assert one.outputs == ["tank.pressure"]
    np.testing.assert_array_equal(one.data[:, 0], by_pair.data[:, 0])
    with pytest.raises(KeyError, match="unknown output 'tank.presure'.*tank.pressure"):
        sf.sweep(fixed, grid, outputs=[("tank", "presure")])
