"""Validity checks of the physical models (softflow.solve.model_checks): each
limit from both sides, against independent references where there is one."""
import warnings

import numpy as np
import pytest
from fluids.compressible import P_isothermal_critical_flow, isothermal_gas
from fluids.friction import friction_factor
from scipy.optimize import brentq

import softflow as sf
from helpers import source_tube_tank

P0 = sf.pressure_atmospheric


def _checks(res):
    return {w.check for w in res.warnings}


def _tube(p1, p2, *, length=1.0, diameter=4e-3, **kw):
    s = sf.System()
    s += sf.PressureSource("src", pressure=p1)
    s += sf.CircularTube("tube", sf.air, length, diameter, **kw)
    s += sf.PressureSource("out", pressure=p2)
    s.connect("src", "tube")
    s.connect("tube", "out")
    return s


def _run(system, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return sf.Simulation(system, duration=0.01, **kw).run(raise_on_failure=False)


def _inlet_pressure(p0, G, c2):
    """The pressure after isothermal acceleration from rest at p0 into a tube
    (c2 ln(p0/p1) = u1^2/2, u1 = G c2/p1), solved here on its own."""
    return brentq(lambda p1: c2 * np.log(p0 / p1) - 0.5 * (G * c2 / p1) ** 2,
                  p0 * np.exp(-0.5), p0, xtol=1e-12 * p0, rtol=1e-15)


@pytest.mark.parametrize("factor", [0.97, 0.5, 0.1])
def test_choked_tube_flow_against_the_isothermal_critical_flow_of_fluids(factor):
    """The default law past the choke: the same flow at any outlet pressure below
    the critical one, which is fluids' isothermal critical outlet pressure from
    the tube's own inlet pressure (after the entry), with Haaland's friction;
    a successful run, whose only warning is that adiabatic flow would pass more
    (tube_isothermal_flow: f L/D ~ 5 here)."""
    p0, L, D = 3e5, 1.0, 4e-3
    area = np.pi * D ** 2 / 4
    c2 = sf.air.R * sf.air.temperature
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(_tube(p0, factor * 0.95e5), duration=0.01).run()
    assert res.success and {w.check for w in res.warnings} == {"tube_isothermal_flow"}
    mf = res.get("tube", "massflow_a")[-1]
    G = mf / area
    p1 = _inlet_pressure(p0, G, c2)
    fd = friction_factor(Re=mf * D / (float(sf.air.viscosity(P0)) * area), eD=1.5e-6 / D,
                         Method="Haaland")
    p2 = P_isothermal_critical_flow(P=p1, fd=fd, D=D, L=L)
    assert factor * 0.95e5 < p2
    assert G * np.sqrt(c2) == pytest.approx(p2, rel=1e-7)       # exit at sqrt(R T)
    want = isothermal_gas(rho=p1 / c2, fd=fd, P1=p1, P2=p2 * (1 + 1e-12), L=L, D=D)
    assert mf == pytest.approx(want, rel=1e-6)


@pytest.mark.parametrize("factor, choked", [(0.97, True), (1.03, False)])
def test_mean_density_law_is_refused_past_the_choke(factor, choked):
    """The mean-density law keeps giving more flow past the choke: refused there,
    with the default law as the way out."""
    p1, p2 = 3e5, factor * 1.245e5     # its own choke, Mach 0.845 at the outlet: ~1.245 bar
    res = _run(_tube(p1, p2, compressible="mean_density"))
    assert ("tube_choked" in _checks(res)) is choked
    if choked:       # no result from past the model's maximum
        assert res.status == "failed"
        assert "tube" in res.message and "pressure ratio" in res.message
        assert "0.845" in res.message      # the limit, Mach 1/sqrt(1.4)
        assert "compressible='pipe_flow'" in res.message
        with pytest.raises(sf.SimulationError, match="gas flow chokes"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", sf.ModelWarning)
                sf.Simulation(_tube(p1, p2, compressible="mean_density"), duration=0.01).run()
    else:
        assert res.success


def test_a_choked_tube_can_be_returned_with_a_warning_instead():
    with pytest.warns(sf.ModelWarning, match="gas flow chokes"):
        res = sf.Simulation(_tube(1e6, 1e5, compressible="mean_density"), duration=0.01,
                            beyond_limits="warn").run()
    assert res.success and "tube_choked" in _checks(res)
    with pytest.raises(ValueError, match="beyond_limits must be 'error' or 'warn'"):
        sf.Simulation(_tube(1e6, 1e5), duration=0.01, beyond_limits="ignore")


@pytest.mark.parametrize("p1, warned", [(1.25e5, True), (1.02e5 + 1e3, False)])
def test_mean_density_law_past_mach_0_3_suggests_the_isothermal_law(p1, warned):
    res = _run(_tube(p1, P0, length=0.2, compressible="mean_density"))
    assert res.success
    assert ("tube_mach" in _checks(res)) is warned
    if warned:
        w = next(w for w in res.warnings if w.check == "tube_mach")
        assert 0.3 < w.measured < 0.845 and "compressible='pipe_flow'" in w.suggestion


@pytest.mark.parametrize("dp, warned", [(2e4, True), (2e3, False)])
def test_laminar_law_past_its_reynolds_range(dp, warned):
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + dp)
    s += sf.CircularTube("tube", sf.water, 1.0, 2e-3, friction="laminar")
    s += sf.PressureSource("out", pressure=P0)
    s.connect("src", "tube")
    s.connect("tube", "out")
    res = _run(s)
    re = res.get("tube", "massflow_a")[-1] * 2e-3 / (sf.water.mu * np.pi * 1e-6)
    assert bool(re > 2300) is warned     # Re ~5 000 and ~500
    assert ("tube_reynolds" in _checks(res)) is warned


@pytest.mark.parametrize("p1, warned", [(3e5, True), (1.3e5, False)])
def test_incompressible_orifice_below_the_critical_pressure_ratio(p1, warned):
    s = sf.System()
    s += sf.PressureSource("src", pressure=p1)
    s += sf.Orifice("o", sf.air, diameter=1e-3, K=2.0)
    s += sf.PressureSource("out", pressure=1e5)
    s.connect("src", "o")
    s.connect("o", "out")
    res = _run(s)
    assert ("orifice_choked" in _checks(res)) is warned
    iso = sf.System()
    iso += sf.PressureSource("src", pressure=p1)
    iso += sf.Orifice("o", sf.air, C=1e-8, b=0.3)
    iso += sf.PressureSource("out", pressure=1e5)
    iso.connect("src", "o")
    iso.connect("o", "out")
    assert "orifice_choked" not in _checks(_run(iso))      # ISO 6358 models choking


def _tank_at(bar):
    """0.1 L of air held at ``bar`` by a source through 0.5 m of 1 mm tube."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=bar * 1e5)
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-4, initial_pressure=bar * 1e5)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    return s


@pytest.mark.parametrize("bar, rtol, warned", [(200.0, 1e-3, True), (5.0, 1e-3, False),
                                               (20.0, 1e-4, True)])
def test_ideal_gas_density_against_coolprop_z(bar, rtol, warned):
    s = _tank_at(bar)
    res = _run(s, rtol=rtol)
    assert ("gas_compressibility" in _checks(res)) is warned
    z = float(sf.Fluid("air", level="eos").compressibility(bar * 1e5))
    if warned:
        w = next(w for w in res.warnings if w.check == "gas_compressibility")
        assert w.measured == pytest.approx(z - 1, rel=1e-6)
        assert "'table'" in w.suggestion
    table = s   # the same scene at the table level: no finding
    for c in table:
        if getattr(c, "fluid", None) is not None:
            c.fluid = sf.air.with_level("table")
    assert "gas_compressibility" not in _checks(_run(table, rtol=rtol))


@pytest.mark.parametrize("bar, rtol, cleared", [(1.2, 1e-4, True), (1.5, 1e-5, False),
                                               (8.0, 1e-3, True), (20.0, 1e-4, False)])
def test_the_table_screen_gives_coolprops_records(monkeypatch, bar, rtol, cleared):
    """gas_compressibility reads the gas's property table before CoolProp and
    stops where its |Z - 1| stays short of a near miss: the records are those
    the CoolProp grid gives (none there), and near misses still ask CoolProp."""
    from softflow.solve import model_checks
    s = _tank_at(bar)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(s, duration=0.01, rtol=rtol)
        res = sim.run(raise_on_failure=False)
    asked, table_clears = [], model_checks._table_clears

    def screen(*args):
        asked.append(table_clears(*args))
        return asked[-1]
    monkeypatch.setattr(model_checks, "_table_clears", screen)
    (g,) = [g for g in sim.asm.groups if type(g.comps[0]).__name__ == "Container"]
    with_table = model_checks.gas_compressibility(g, res)
    assert asked == [cleared] and (with_table == []) is cleared
    monkeypatch.setattr(model_checks, "_table_clears", lambda *args: False)
    assert model_checks.gas_compressibility(g, res) == with_table


@pytest.mark.parametrize("diameter, warned", [(4e-3, True), (0.1e-3, False)])
def test_isothermal_volume_filled_faster_than_its_wall_exchanges_heat(diameter, warned):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.5e5)
    s += sf.CircularTube("tube", sf.air, 0.1, diameter)
    s += sf.Container("tank", sf.air, 1e-3)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    res = _run(s)
    assert ("thermal_time_scale" in _checks(res)) is warned
    adiabatic = _run(s, thermal="adiabatic")
    assert "thermal_time_scale" not in _checks(adiabatic)


@pytest.mark.parametrize("compliance, warned", [(1e-9, True), (1e-8, False)])
def test_liquid_tube_without_inertance_against_its_inertial_time_constant(compliance, warned):
    """A water RC circuit 20x slower than its tube's column (inertance changes
    the result by ~4 %) is reported; 200x slower (~0.4 %) is not."""
    runs = []
    for inertance in (False, True):
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 1e4)
        s += sf.CircularTube("tube", sf.water, 1.0, 2e-3, inertance=inertance)
        s += sf.LinearAccumulator("acc", sf.water, 1e-6, compliance)
        s.connect("src", "tube")
        s.connect("tube", "acc")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            runs.append(sf.Simulation(s, duration=5.0).run())
    plain, inertial = runs
    assert ("tube_inertia" in _checks(plain)) is warned
    effect = np.max(np.abs(np.interp(inertial.times, plain.times, plain.get("acc", "pressure"))
                           - inertial.get("acc", "pressure"))) / 1e4
    assert bool(effect > 0.01) is warned
    assert "tube_inertia" not in _checks(inertial)


def test_a_run_refused_from_its_start_stops_at_once():
    """A tube choked at t = 0 refuses the run from its first point: the run
    stops after the consistent start instead of computing to the end and
    being cut back (same status and message as the full run would give)."""
    def scene():
        return source_tube_tank(pressure=5e5, compressible="mean_density")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(scene(), duration=0.5).run(raise_on_failure=False)
        assert res.status == "failed" and res.stats["steps"] == 0 and len(res.times) == 1
        assert res.message.startswith("stopped at t = 0 s: CircularTube 'tube': gas flow chokes")
        # with beyond_limits='warn' the same scene runs to its end, warned
        warned = sf.Simulation(scene(), duration=0.5, beyond_limits="warn").run()
    assert warned.status == "success" and warned.stats["steps"] > 10
    assert any(w.check == "tube_choked" for w in warned.warnings)


def test_largest_on_ranges_is_the_per_range_search():
    """gas_compressibility's Z - 1 of largest magnitude over each volume's own
    pressure range, found for all the volumes at once, equals the search made
    range by range (ends interpolated, grid points strictly inside)."""
    from softflow.solve.model_checks import _largest_on_ranges
    rng = np.random.default_rng(5)
    grid = np.unique(np.geomspace(1e5, 2e7, 12))
    rows = rng.normal(scale=0.02, size=(2, grid.size))
    lo = rng.uniform(5e4, 2e7, 40)
    hi = np.minimum(lo * rng.uniform(1.0, 50.0, 40), 3e7)
    lo[0] = hi[0] = grid[2]                              # one point, a grid point
    lo[1], hi[1] = grid[2], grid[5]                      # ends on grid points
    lo[3], hi[3] = np.nan, np.nan                        # a volume without pressures
    got = _largest_on_ranges(grid, rows, lo, hi)
    for j in range(lo.size):
        inside = grid[(grid > lo[j]) & (grid < hi[j])]
        at = np.concatenate([[lo[j], hi[j]], inside])
        z = np.concatenate([np.interp(at, grid, row) for row in rows])
        want = z[np.argmax(np.abs(z))]
        assert got[j] == want or (np.isnan(want) and np.isnan(got[j])), j


def test_a_short_choked_tube_of_an_isothermal_scene_is_warned_of_its_adiabatic_flow():
    """A 10 cm x 4 mm tube filling a tank from 3 bar gauge chokes (f L/D ~ 0.6):
    as isothermal pipe flow its choked flow is ~9 % below the adiabatic (Fanno)
    one, past max(10 rtol, 1 %): a warning whose figure is the two closed forms'
    ratio at the tube's f L/D, suggesting thermal='adiabatic'. Run so, the tube
    is Fanno flow and the warning is gone (the suggestion moves the scene to a
    model without it). A 20 m x 2 mm tube from 10 to 0.5 bar (f L/D ~ 200)
    chokes too, within 0.3 %: no record."""
    from softflow.correlations.fanno import adiabatic_choked_massflow
    from softflow.correlations.gas_pipe import isothermal_choked_massflow

    def fill(length, diameter, **kw):
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 3e5)
        s += sf.CircularTube("tube", sf.air, length=length, diameter=diameter)
        s += sf.Container("tank", sf.air, volume=50e-6)
        s.connect("src", "tube")
        s.connect("tube", "tank")
        return _run(s, **kw)
    res = fill(0.1, 4e-3)
    (w,) = [w for w in res.validity if w.check == "tube_isothermal_flow"]
    assert w.status == "beyond" and w in res.warnings
    R, T = sf.air.R, sf.air.temperature
    ratio = (adiabatic_choked_massflow(1.0, T, 1.0, R, sf.air.gamma0, w.details["fLD"])
             / isothermal_choked_massflow(1.0, 1.0, R * T, w.details["fLD"]))
    assert 0.3 < w.details["fLD"] < 1.0 and w.measured == pytest.approx(ratio - 1, rel=1e-12)
    assert 0.07 < w.measured < 0.11 and "thermal='adiabatic'" in w.suggestion
    assert "tube_isothermal_flow" not in {r.check for r in fill(0.1, 4e-3,
                                                                thermal="adiabatic").validity}
    long = _run(_tube(10e5, 0.5e5, length=20.0, diameter=2e-3))
    G = long.get("tube", "massflow_a")[-1] / (np.pi * 2e-3 ** 2 / 4)
    assert 0.5e5 < G * np.sqrt(R * T)                                     # it choked
    assert "tube_isothermal_flow" not in {r.check for r in long.validity}


def test_isothermal_tank_warning_says_by_how_much_against_a_measured_run():
    """thermal_time_scale gives the isothermal model's error as isothermal_error
    estimates it, (gamma - 1) t_thermal / t_fill at most gamma - 1; a 1 L tank
    blown down from 10 bar in ~1 s: the estimate (0.4, the cap) and the measured
    difference against free-convection walls (thermal='heat_transfer': 23 % of
    the pressure during the choked phase) are of one order."""
    import math

    def blowdown(walls):
        s = sf.System()
        kw = dict(heat_transfer_coefficient=sf.FreeConvection("sphere"),
                  area=math.pi ** (1 / 3) * (6e-3) ** (2 / 3)) if walls else {}
        s += sf.Container("tank", sf.air, volume=1e-3, initial_pressure=10e5, **kw)
        s += sf.Orifice("valve", sf.air, C=1e-8, b=0.3)
        s += sf.PressureSource("atm", pressure=P0)
        s.connect("tank", "valve")
        s.connect("valve", "atm")
        return s

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        iso = sf.Simulation(blowdown(False), duration=3.0).run()
        real = sf.Simulation(blowdown(True), duration=3.0, thermal="heat_transfer").run()
    w = next(w for w in iso.warnings if w.check == "thermal_time_scale")
    gamma1 = sf.air.gamma0 - 1
    t_fill, t_thermal = w.measured, w.details["thermal_time_constant"]
    assert w.details["estimated_error"] == pytest.approx(min(gamma1 * t_thermal / t_fill,
                                                             gamma1))
    assert f"by up to ~{w.details['estimated_error']:.0%}" in w.message
    t = np.linspace(0.0, 1.0, 101)             # the choked phase
    measured = np.max(np.abs(np.interp(t, real.times, real.get("tank", "pressure"))
                             / np.interp(t, iso.times, iso.get("tank", "pressure")) - 1))
    assert 0.1 < measured < 0.35
    assert measured <= w.details["estimated_error"] < 10 * measured
    assert "thermal_time_scale" not in _checks(real)
