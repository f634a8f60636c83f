"""Near misses of the validity checks (softflow.solve.validity.NEAR_FRACTION):
each check on three sides of its limit, far (no record), near (a record with
status 'near' in result.validity, not warned, not in result.warnings) and
beyond (a warning)."""
import warnings

import pytest

import softflow as sf
from softflow.solve.validity import NEAR_FRACTION, table

P0 = sf.pressure_atmospheric


def _between(a, b, make, fluid=sf.air):
    s = sf.System()
    s += sf.PressureSource("src", pressure=a)
    s += make(fluid)
    s += sf.PressureSource("out", pressure=b)
    s.connect("src", s.components[1].label)
    s.connect(s.components[1].label, "out")
    return s


def _into(p, make, volume):
    s = sf.System()
    s += sf.PressureSource("src", pressure=p)
    s += make
    s += volume
    s.connect("src", make.label)
    s.connect(make.label, volume.label)
    return s


def laminar_water(dp):
    return _between(P0 + dp, P0, lambda f: sf.CircularTube("tube", f, 1.0, 2e-3,
                                                           friction="laminar"), sf.water)


def short_air_tube(p1):
    # the mean-density law (the default isothermal pipe flow has no Mach limit)
    return _between(p1, P0, lambda f: sf.CircularTube("tube", f, 0.2, 4e-3,
                                                       compressible="mean_density"))


def k_orifice(p1):
    return _between(p1, 1e5, lambda f: sf.Orifice("o", f, diameter=1e-3, K=2.0))


def dense_air(bar):
    return _into(bar * 1e5, sf.CircularTube("tube", sf.air, 0.5, 1e-3),
                 sf.Container("tank", sf.air, 1e-4, initial_pressure=bar * 1e5))


def valve_fill(C):
    return _into(4e5, sf.Orifice("valve", sf.air, C=C, b=0.3), sf.Container("tank", sf.air, 1e-3))


def water_rc(compliance):
    return _into(P0 + 1e4, sf.CircularTube("tube", sf.water, 1.0, 2e-3),
                 sf.LinearAccumulator("acc", sf.water, 1e-6, compliance))


CASES = [  # (check, scene, figures giving no record / near / beyond, duration)
    ("tube_reynolds", laminar_water, (3e3, 6e3, 2e4), 0.01),           # Re 750 / 1500 / 5000
    ("tube_mach", short_air_tube, (1.03e5, 1.08e5, 1.25e5), 0.01),
    ("orifice_choked", k_orifice, (1.3e5, 1.6e5, 3e5), 0.01),
    ("gas_compressibility", dense_air, (5.0, 25.0, 60.0), 0.01),
    ("thermal_time_scale", valve_fill, (1e-9, 5e-9, 1e-8), 1.0),
    ("tube_inertia", water_rc, (3e-8, 7e-9, 1e-9), 5.0),
]


def _run(system, duration):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", sf.ModelWarning)
        res = sf.Simulation(system, duration=duration).run(raise_on_failure=False)
    return res, [str(w.message) for w in caught if issubclass(w.category, sf.ModelWarning)]


@pytest.mark.parametrize("check, scene, figures, duration", CASES,
                         ids=[c[0] for c in CASES])
@pytest.mark.parametrize("side", [0, 1, 2], ids=["far", "near", "beyond"])
def test_each_check_on_three_sides_of_its_limit(check, scene, figures, duration, side):
    if figures[side] is None:
        pytest.skip("past its limit this check stops the run (test_model_checks.py)")
    res, warned = _run(scene(figures[side]), duration)
    mine = [r for r in res.validity if r.check == check]
    if side == 0:
        assert mine == []
        return
    (rec,) = mine
    if side == 1:
        assert rec.status == "near"
        assert NEAR_FRACTION <= rec.fraction < 1
        assert rec not in res.warnings
        assert not any(rec.message == m for m in warned)      # not warned
        assert "near miss" in rec.message and rec.component in rec.message
        assert rec.suggestion.startswith("if the scene is pushed further")
    else:
        assert rec.status == "beyond" and rec.fraction > 1
        assert rec in res.warnings and rec.message in warned


def test_validity_table_lists_warnings_and_near_misses():
    res, _ = _run(valve_fill(5e-9), 1.0)
    df = table(res.validity)
    assert list(df.columns) == ["component", "check", "status", "measured", "limit", "unit",
                                "fraction", "suggestion"]
    row = df.set_index("check").loc["thermal_time_scale"]
    assert row["status"] == "near" and row["component"] == "tank"
    assert len(table(res.warnings)) == len(res.warnings) == 0


def test_thermal_check_takes_the_wall_the_volume_was_given():
    """The fill that is past the limit with the free-convection estimate of a
    bare tank is quiet where the tank was given a strong wall, and past it
    with a weak one."""
    def fill(**wall):
        return _into(4e5, sf.Orifice("valve", sf.air, C=1e-8, b=0.3),
                     sf.Container("tank", sf.air, 1e-3, **wall))
    fractions = {}
    for name, wall in (("bare", {}), ("strong", {"hA": 10.0}), ("weak", {"hA": 0.01})):
        res, _ = _run(fill(**wall), 1.0)
        rec = [r for r in res.validity if r.check == "thermal_time_scale"]
        fractions[name] = rec[0].fraction if rec else 0.0
        if rec:
            assert ("its own h A" in rec[0].message) is bool(wall)
    assert fractions["bare"] > 1 and fractions["strong"] == 0.0
    assert fractions["weak"] > fractions["bare"]


def test_carbon_dioxide_near_miss_at_low_pressure_is_reported():
    """CO2 at 1.6 bar and 20 C: Z - 1 = -0.0087, near the limit 0.01 (rtol
    1e-3): a near miss, though CoolProp is asked only where Z - 1 may reach one
    (a bound below the near threshold would hide it)."""
    co2 = sf.Fluid("CO2", level="ideal")
    res, warned = _run(_into(1.6e5, sf.CircularTube("tube", co2, 0.5, 1e-3),
                             sf.Container("tank", co2, 1e-4, initial_pressure=1.6e5)), 0.01)
    (rec,) = [r for r in res.validity if r.check == "gas_compressibility"]
    assert rec.status == "near" and rec.component == "tank"
    z = float(sf.Fluid("CO2", level="eos").compressibility(1.6e5))
    assert rec.measured == pytest.approx(z - 1, rel=1e-3)
    assert not warned


def test_compressibility_bound_of_the_built_in_gases_holds_against_coolprop():
    """Where the bound says |Z - 1| is small (it is below 0.1), CoolProp agrees:
    air and nitrogen from 1.2 Tc to 800 K, 0.1 bar to 500 bar."""
    import numpy as np
    from softflow.solve.model_checks import compressibility_bound
    for name in ("air", "nitrogen"):
        eos = sf.Fluid(name, level="eos")
        tc = {"air": 132.53, "nitrogen": 126.19}[name]
        assert compressibility_bound(name, 1.1 * tc, 300.0, [1e5]) is None
        for T in np.linspace(1.2 * tc, 800.0, 25):
            p = np.geomspace(1e4, 5e7, 40)
            bound = compressibility_bound(name, T, T, p)
            z = np.array([abs(float(eos.compressibility(x, T)) - 1) for x in p])
            small = bound < 0.1
            assert np.all(z[small] <= bound[small] / 1.4), (name, T)
    assert compressibility_bound("CO2", 250.0, 300.0, [1e5]) is None


def _adiabatic_hold(duration):
    """A 100 mL wall-less tank filled adiabatically through 0.5 m of 1 mm tube
    in ~0.1 s, then held: its free-convection thermal time constant is ~1.5 s."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", sf.ModelWarning)
        res = sf.Simulation(_into(1.5e5, sf.CircularTube("tube", sf.air, 0.5, 1e-3),
                                  sf.Container("tank", sf.air, 1e-4)),
                            duration=duration, thermal="adiabatic").run()
    return res, [str(w.message) for w in caught if issubclass(w.category, sf.ModelWarning)]


@pytest.mark.parametrize("duration, side", [(0.3, "far"), (1.5, "near"), (3.0, "beyond")])
def test_adiabatic_volume_held_longer_than_its_wall_allows(duration, side):
    """The reverse of thermal_time_scale: the adiabatic model keeps the heat of
    a fast fill for as long as the run holds it; a real wall takes it back
    within a few thermal time constants."""
    res, warned = _adiabatic_hold(duration)
    mine = [r for r in res.validity if r.check == "adiabatic_time_scale"]
    if side == "far":
        assert mine == []
        return
    (rec,) = mine
    assert rec.component == "tank" and rec.unit == "s"
    assert 1.0 < rec.limit < 3.0                     # the thermal time constant
    if side == "near":
        assert rec.status == "near" and NEAR_FRACTION <= rec.fraction < 1
        assert rec.message not in warned
    else:
        assert rec.status == "beyond" and rec.fraction > 1
        assert rec.message in warned and "heat_transfer" in rec.suggestion
        assert "a real wall would have taken back" in rec.message


def test_adiabatic_check_leaves_isothermal_and_walled_volumes_alone():
    s = _into(1.5e5, sf.CircularTube("tube", sf.air, 0.5, 1e-3),
              sf.Container("tank", sf.air, 1e-4, hA=0.05))
    for thermal in ("isothermal", "heat_transfer"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            res = sf.Simulation(s, duration=5.0, thermal=thermal).run()
        assert "adiabatic_time_scale" not in {r.check for r in res.validity}
