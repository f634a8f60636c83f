"""sf.assess and Simulation(model='auto'): the recommendation on small scenes where
one axis matters, its error against a fine reference, the user's System left
unchanged, and bad input."""
import copy
import pickle
import warnings

import pytest

import softflow as sf
from softflow.assess import AssessmentError, difference, variant_system

P = sf.pressure_atmospheric
TOL = 0.01


def syringe():
    """A slow syringe-like fill (0.5 mL/s for 10 s) of an air actuator through a
    thin tube; its wall is given (hA), so heat transfer is the reference."""
    s = sf.System()
    pump = sf.waveforms.PiecewiseConstant(sf.Q_([0, 10], "s"), sf.Q_([0.5, 0], "mL/s"))
    s += sf.VolumeFlowSource("pump", volumeflow=pump, fluid=sf.air)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    curve = sf.PVCurve.monotonic((5e-6, P), (8e-6, P + 0.2e5), (20e-6, P + 0.4e5))
    s += sf.Actuator("act", sf.air, curve, initial_pressure=P, hA=0.5)
    s.connect("pump", "tube")
    s.connect("tube", "act")
    return s


def fast_fill():
    """A 1 L tank filled from 4 bar through an ISO 6358 valve in ~0.5 s."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(4, "bar"))
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    return s


def bottle():
    """A 1 L air bottle (wall hA 0.5 W/K) filled from 12 to 18 MPa."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=18e6)
    s += sf.CircularTube("tube", sf.air, length=2.0, diameter=1e-3)
    s += sf.Container("bottle", sf.air, volume=1e-3, initial_pressure=12e6, hA=0.5)
    s.connect("supply", "tube")
    s.connect("tube", "bottle")
    return s


def laminar_water():
    """Water through a friction='laminar' tube at Re ~ 25 000."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(2, "bar"))
    s += sf.CircularTube("tube", sf.water, length=1.0, diameter=2e-3, friction="laminar")
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-5, compliance=1e-11)
    s.connect("supply", "tube")
    s.connect("tube", "acc")
    return s


def reference(system, duration, thermal, fluid_level, overrides=None):
    sim = sf.Simulation(variant_system(system, fluid_level, overrides), duration,
                        thermal=thermal, rtol=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return sim.run()


def recommended_run(assessment):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return assessment.simulation().run()


def test_slow_syringe_fill_stays_isothermal():
    s = syringe()
    a = sf.assess(s, 12.0, tolerance=TOL, outputs=[("act", "volume"), ("act", "pressure")])
    assert a.recommended["thermal"] == "isothermal"
    assert a.recommended["fluid_level"] == "ideal"
    assert a.recommended["overrides"] == {}
    # the wall the user gave was measured, and found small
    row = a.table.set_index("axis").loc["thermal"]
    assert row["level tried"] == "isothermal -> heat_transfer"
    assert row["effect"] < TOL / 2
    ref = reference(s, 12.0, "heat_transfer", "table")
    assert difference(recommended_run(a), ref, a.outputs) < TOL


def test_fast_fill_recommends_adiabatic():
    s = fast_fill()
    a = sf.assess(s, 1.0, tolerance=TOL, outputs=["tank.pressure"])
    assert a.recommended["thermal"] == "adiabatic"
    assert any(w.check == "thermal_time_scale" for w in a.warnings)
    assert a.table.set_index("axis").loc["thermal", "effect"] > TOL
    ref = reference(s, 1.0, "adiabatic", "table")
    assert difference(recommended_run(a), ref, a.outputs) < TOL


def test_high_pressure_bottle_recommends_table():
    s = bottle()
    a = sf.assess(s, 20.0, tolerance=TOL)
    assert a.outputs == [("bottle", "pressure", None)]
    assert a.recommended["fluid_level"] == "table"
    assert a.recommended["thermal"] == "heat_transfer"     # its wall, measured
    ref = reference(s, 20.0, "heat_transfer", "table")
    assert difference(recommended_run(a), ref, a.outputs) < TOL
    # the isothermal ideal-gas base run was not: both axes were needed
    base = next(r for r in a.runs if r.config.thermal == "isothermal"
                and r.config.fluid_level == "ideal" and r.config.rtol == a.config.rtol)
    assert difference(base.result, ref, a.outputs) > TOL


def test_laminar_tube_at_high_reynolds_recommends_haaland():
    s = laminar_water()
    a = sf.assess(s, 0.5, tolerance=TOL, outputs=[("tube", "massflow", "a")])
    assert a.recommended["friction"] == "Haaland"
    assert a.recommended["overrides"] == {"tube": {"friction": "Haaland"}}
    sim = a.simulation()
    assert sim.system.get("tube").friction != "laminar"
    ref = reference(s, 0.5, "isothermal", "ideal", {"tube": {"friction": "Haaland"}})
    assert difference(recommended_run(a), ref, a.outputs) < TOL
    assert s.get("tube").friction == "laminar"         # the user's tube is not touched


def test_the_users_system_is_unchanged():
    s = bottle()
    before = pickle.dumps(s)
    comps = list(s.components)
    fluids = [getattr(c, "fluid", None) for c in comps]
    a = sf.assess(s, 20.0)
    assert pickle.dumps(s) == before
    assert list(s.components) == comps
    assert [getattr(c, "fluid", None) for c in s.components] == fluids
    assert s.get("bottle").fluid.level == "ideal"
    assert a.system_recommended().get("bottle").fluid.level == "table"


def test_table_and_simulation():
    a = sf.assess(fast_fill(), 1.0)
    table = a.table
    assert list(table.columns) == ["axis", "level tried", "effect", "cost [s]", "cost ratio",
                                   "verdict"]
    assert {"base", "time tolerance", "thermal"} <= set(table["axis"])
    assert (table["cost [s]"] >= 0).all()
    assert a.cost >= sum(r.cpu for r in a.runs) * 0.99
    sim = a.simulation()
    assert sim.thermal == "adiabatic" and sim.rtol == a.recommended["rtol"]
    assert "adiabatic" in repr(a)


def test_simulation_model_auto_in_one_line():
    s = fast_fill()
    sim = sf.Simulation(s, 1.0, model="auto", tolerance=TOL)
    assert sim.thermal == "adiabatic"
    assert sim.assessment.recommended["thermal"] == "adiabatic"
    assert sim.system is not s
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sim.run()
        again = pickle.loads(pickle.dumps(sim))       # rebuilt from the recommendation
        assert again.thermal == "adiabatic"
        assert again._definition["model"] is None
        assert (again.run().get("tank", "pressure") == res.get("tank", "pressure")).all()


@pytest.mark.parametrize("kw, culprit", [
    (dict(thermal="adiabatic"), "thermal="),
    (dict(rtol=1e-4), "rtol="),
    (dict(step=0.01), "step="),
])
def test_model_auto_refuses_conflicting_choices(kw, culprit):
    with pytest.raises(ValueError, match=culprit):
        sf.Simulation(fast_fill(), 1.0, model="auto", **kw)


def test_model_must_be_auto():
    with pytest.raises(ValueError, match="model must be None or 'auto'.*'manual'"):
        sf.Simulation(fast_fill(), 1.0, model="manual")
    with pytest.raises(ValueError, match="tolerance= applies to model='auto'"):
        sf.Simulation(fast_fill(), 1.0, tolerance=0.05)


@pytest.mark.parametrize("tolerance", [0, -0.1, 1, 1.5, float("nan")])
def test_bad_tolerance(tolerance):
    with pytest.raises(ValueError, match="tolerance must be > 0 and < 1"):
        sf.assess(fast_fill(), 1.0, tolerance=tolerance)


def test_tolerance_not_a_number():
    with pytest.raises(TypeError, match="tolerance must be a number"):
        sf.assess(fast_fill(), 1.0, tolerance="1 %")


def test_unknown_output_label():
    with pytest.raises(KeyError, match="'tnak'.*did you mean.*'tank'"):
        sf.assess(fast_fill(), 1.0, outputs=[("tnak", "pressure")])


def test_unknown_output_variable():
    with pytest.raises(KeyError, match="output \\('tank', 'volumeflow'\\).*no variable "
                                       "'volumeflow'"):
        sf.assess(fast_fill(), 1.0, outputs=[("tank", "volumeflow")])


def test_bad_output_spec():
    with pytest.raises(ValueError, match="'tankpressure' is not 'label.variable'"):
        sf.assess(fast_fill(), 1.0, outputs=["tankpressure"])


def test_assess_refuses_what_it_chooses():
    with pytest.raises(ValueError, match="thermal given, but that is what assess chooses"):
        sf.assess(fast_fill(), 1.0, thermal="adiabatic")


def test_scene_failing_in_every_configuration_reports_each():
    # air from 10 bar to 1 bar through 1 m of 4 mm tube chokes in every model
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(10, "bar"))
    s += sf.CircularTube("tube", sf.air, length=1.0, diameter=4e-3)
    s += sf.PressureSource("exhaust", pressure=sf.Q_(1, "bar"))
    s.connect("supply", "tube")
    s.connect("tube", "exhaust")
    with pytest.raises(AssessmentError, match="failed in every configuration") as err:
        sf.assess(s, 0.1, outputs=[("tube", "massflow", "a")])
    failures = err.value.failures
    assert len(failures) >= 4
    configs = [cfg for cfg, _ in failures]
    assert len(set(configs)) == len(configs)
    assert any(cfg.startswith("adiabatic") for cfg in configs)
    assert any("table" in cfg for cfg in configs)
    for _, message in failures:
        assert "'tube'" in message and "chokes" in message
    assert str(err.value).count("\n  - ") == len(failures)


def test_variant_system_is_a_copy():
    s = laminar_water()
    v = variant_system(s, "table", {"tube": {"friction": "Haaland"}})
    assert v.get("tube") is not s.get("tube")
    assert v.get("tube").fluid.level == "table" and s.get("tube").fluid.level == "ideal"
    assert len(v.nodes()) == len(s.nodes())
    with pytest.raises(KeyError, match="'pipe'"):
        variant_system(s, None, {"pipe": {"friction": "Haaland"}})
