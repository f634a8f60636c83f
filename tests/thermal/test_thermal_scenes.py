"""Thermal scenes: closed-form cases, energy balance, results, bad input."""
import math
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow.curves.waveforms import Step
from softflow.solve.thermal import energy_balance

AIR = sf.air
T0 = AIR.temperature
GAMMA = AIR.gamma0
R = AIR.R
P_ATM = sf.pressure_atmospheric


def _fill_scene(fluid=AIR, p_res=5e5, p0=1e3, C=1e-8, b=0.3, **tank):
    s = sf.System()
    s += sf.PressureSource("res", pressure=p_res)
    s += sf.Orifice("valve", fluid, C=C, b=b)
    s += sf.Container("tank", fluid, volume=1e-3, initial_pressure=p0, **tank)
    s.connect("res", "valve")
    s.connect("valve", "tank")
    return s


def test_evacuated_tank_fills_to_gamma_T0():
    s = _fill_scene()
    res = sf.Simulation(s, duration=5.0, thermal="adiabatic", rtol=1e-4).run()
    T = res.get("tank", "temperature")
    p = res.get("tank", "pressure")
    assert abs(p[-1] - 5e5) < 1.0
    assert abs(T[-1] / (GAMMA * T0) - 1) < 5e-3
    # exact energy balance with the initial gas: m_f cv T_f = m0 cv T0 + (m_f - m0) cp T0
    m0, mf = res.get("tank", "mass")[[0, -1]]
    T_exact = (m0 * T0 + (mf - m0) * GAMMA * T0) / mf
    assert abs(T[-1] / T_exact - 1) < 1e-5
    assert energy_balance(res, s)["relative_error"] < 1e-8


def test_isothermal_scene_has_no_temperature_unknowns_and_switches_back():
    s = _fill_scene()
    sim_a = sf.Simulation(s, duration=0.1, thermal="adiabatic")
    sim_i = sf.Simulation(s, duration=0.1)
    assert "temperature" not in sim_i.asm.x_quantity
    assert "temperature" in sim_a.asm.x_quantity
    res_i = sim_i.run()
    res_a = sim_a.run()          # compiled before the isothermal one: still thermal
    assert res_a.get("tank", "temperature").max() > T0 + 10
    with pytest.raises(KeyError):
        res_i.get("tank", "temperature")


def test_temperature_results_as_quantities_and_nodes():
    s = _fill_scene()
    res = sf.Simulation(s, duration=1.0, thermal="adiabatic").run()
    q = res.get("tank", "temperature", as_quantity=True)
    assert str(q.units) == "kelvin"
    # the node between valve and tank has the tank's temperature
    np.testing.assert_allclose(res.get("valve", "temperature", "b"), res.get("tank", "temperature"))
    assert res.get("tank", "internal_energy", as_quantity=True).units == sf.ureg.J


def test_relaxation_to_wall_temperature():
    hA = 0.05
    s = sf.System()
    s += sf.MassFlowSource("pump", massflow=Step(0.2, 5e-3, 0.0))
    s += sf.Container("tank", AIR, volume=1e-3, hA=hA)
    s.connect("pump", "tank")
    res = sf.Simulation(s, duration=20.0, thermal="heat_transfer", rtol=1e-5,
                        step_max=0.05).run()
    t, T, m = res.times, res.get("tank", "temperature"), res.get("tank", "mass")
    sel = t > 1.0
    slope = np.polyfit(t[sel], np.log(T[sel] - T0), 1)[0]
    tau = m[-1] * AIR.cv0 / hA
    assert abs(-1 / slope / tau - 1) < 1e-2
    assert T.max() > T0 + 40
    assert energy_balance(res, s)["relative_error"] < 1e-8


def test_choked_fill_time_adiabatic_is_isothermal_over_gamma():
    def fill_time(model):
        s = _fill_scene(p_res=6e5, p0=1e5, b=0.5)
        res = sf.Simulation(s, duration=3.0, thermal=model).run()
        return np.interp(3e5, res.get("tank", "pressure"), res.times)
    mdot = 1e-8 * 1.185 * 6e5 * math.sqrt(293.15 / T0)
    t_iso = 2e5 * 1e-3 / (R * T0 * mdot)
    assert fill_time("isothermal") == pytest.approx(t_iso, rel=1e-3)
    assert fill_time("adiabatic") == pytest.approx(t_iso / GAMMA, rel=1e-3)


def test_junction_mixes_mass_weighted_enthalpy():
    s = sf.System()
    s += sf.PressureSource("hot", pressure=3e5, temperature=400.0)
    s += sf.PressureSource("cold", pressure=2.5e5, temperature=280.0)
    s += sf.PressureSource("sink", pressure=1e5)
    s += sf.Orifice("o1", AIR, C=1e-8, b=0.3)
    s += sf.Orifice("o2", AIR, C=2e-8, b=0.3)
    s += sf.Orifice("o3", AIR, C=3e-8, b=0.3)
    s.connect("hot", ("o1", "a"))
    s.connect("cold", ("o2", "a"))
    s.connect(("o1", "b"), ("o2", "b"), ("o3", "a"))
    s.connect(("o3", "b"), "sink")
    res = sf.Simulation(s, duration=0.01, thermal="adiabatic").run()
    m1, m2 = res.get("o1", "massflow", "a")[-1], res.get("o2", "massflow", "a")[-1]
    Tj = res.get("o3", "temperature", "a")[-1]
    assert Tj == pytest.approx((m1 * 400 + m2 * 280) / (m1 + m2), rel=1e-7)
    # energy leaving through o3 is what the two streams bring
    E3 = res.get("o3", "energyflow", "a")[-1]
    # (up to the zero-flow conductance: 1e-6 W/K x 30 K against 220 W)
    # energies count from the scene's reference enthalpy h0 = h(1 atm, T_fluid)
    h0 = AIR.enthalpy(P_ATM, T0)
    assert E3 == pytest.approx(m1 * (AIR.enthalpy(3e5, 400.0) - h0)
                               + m2 * (AIR.enthalpy(2.5e5, 280.0) - h0), rel=1e-6)


def test_energy_balance_with_work_and_heat():
    curve = sf.PVCurve.monotonic((1e-5, P_ATM), (3e-5, 1.5e5), (6e-5, 1.8e5))
    s = sf.System()
    s += sf.PressureSource("src", pressure=Step(0.1, 2e5, 1.2e5), temperature=330.0)
    s += sf.Orifice("valve", AIR, C=3e-9, b=0.4)
    s += sf.Container("tank", AIR, volume=2e-4, hA=0.02)
    s += sf.CircularTube("tube", AIR, length=0.3, diameter=1.5e-3)
    s += sf.Actuator("act", AIR, curve, thermal="adiabatic")
    s += sf.CircularTube("tube2", AIR, length=0.1, diameter=1e-3)
    s += sf.LinearAccumulator("acc", AIR, volume=2e-5, compliance=1e-10, hA=0.01)
    s.connect("src", ("valve", "a"))
    s.connect(("valve", "b"), "tank", ("tube", "a"), ("tube2", "a"))
    s.connect(("tube", "b"), "act")
    s.connect(("tube2", "b"), "acc")
    res = sf.Simulation(s, duration=1.0, thermal="heat_transfer").run()
    bal = energy_balance(res, s)
    assert bal["relative_error"] < 1e-8
    assert abs(bal["work"]) > 1e-3 and abs(bal["wall_heat"]) > 1e-3


def test_adiabatic_blowdown_matches_closed_form():
    V, p0, C, b = 1e-3, 10e5, 1e-8, 0.3
    s = sf.System()
    s += sf.Container("tank", AIR, volume=V, initial_pressure=p0)
    s += sf.Orifice("valve", AIR, C=C, b=b)
    s += sf.PressureSource("atm", pressure=P_ATM)
    s.connect("tank", "valve")
    s.connect("valve", "atm")
    res = sf.Simulation(s, duration=8.0, rtol=1e-5, thermal="adiabatic").run()
    t, p = res.times, res.get("tank", "pressure")
    tau = V / (R * T0 * C * 1.185 * math.sqrt(293.15 / T0))
    exact = p0 * (1 + (GAMMA - 1) / 2 * t / tau) ** (-2 * GAMMA / (GAMMA - 1))
    choked = p > P_ATM / b * 1.01
    assert np.max(np.abs(p[choked] / exact[choked] - 1)) < 5e-3


# ---------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------
def test_unknown_model_suggests_close_match():
    with pytest.raises(ValueError, match="did you mean 'adiabatic'"):
        sf.Simulation(_fill_scene(), duration=1.0, thermal="adiabatc")
    with pytest.raises(ValueError, match="did you mean 'heat_transfer'"):
        sf.Container("c", AIR, volume=1e-3, thermal="heat transfr", hA=1.0)


def test_heat_transfer_without_coefficient_or_area():
    with pytest.raises(ValueError, match="Container 'tank'.*heat transfer needs"):
        sf.Simulation(_fill_scene(), duration=1.0, thermal="heat_transfer")
    with pytest.raises(ValueError, match="area"):
        sf.Container("c", AIR, volume=1e-3, heat_transfer_coefficient=10.0)
    with pytest.raises(ValueError, match="thermal='heat_transfer' needs"):
        sf.Container("c", AIR, volume=1e-3, thermal="heat_transfer")


def test_initial_temperature_outside_fluid_range():
    eos = sf.Fluid("air", level="eos")
    with pytest.raises(ValueError, match="initial_temperature 20 K is outside"):
        sf.Container("c", eos, volume=1e-3, initial_temperature=20.0)
    with pytest.raises(ValueError, match="initial_temperature"):
        sf.Container("c", AIR, volume=1e-3, initial_temperature=-5.0)


def test_liquid_in_adiabatic_scene_is_rejected():
    s = sf.System()
    s += sf.PressureSource("src", pressure=2e5)
    s += sf.CircularTube("tube", sf.water, length=0.1, diameter=1e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-5, compliance=1e-11)
    s.connect("src", "tube")
    s.connect("tube", "acc")
    with pytest.raises(ValueError, match="liquid.*models gases.*not modelled"):
        sf.Simulation(s, duration=1.0, thermal="adiabatic")


def test_component_override_in_isothermal_scene_is_rejected():
    s = _fill_scene(thermal="adiabatic")
    with pytest.raises(ValueError, match="the Simulation is isothermal"):
        sf.Simulation(s, duration=1.0)


def test_unsupported_component_in_thermal_scene():
    from softflow.curves.hysteresis import HysteresisLoop  # noqa: F401
    s = sf.System()

    class Dummy(sf.Component):
        def __init__(self, label):
            super().__init__(label)
            self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across"),
                                                 sf.Variable("massflow", "through")]))
            self.evaluate = self.auto(lambda massflow: massflow)
    s += Dummy("user")
    s += sf.Orifice("valve", AIR, C=1e-8, b=0.3)
    s += sf.PressureSource("src", pressure=2e5)
    s.connect("user", "valve")
    s.connect("valve", "src")
    with pytest.raises(sf.NetworkError, match="user component in a thermal scene"):
        sf.Simulation(s, duration=1.0, thermal="adiabatic")


def _hot_fill(**tank_kw):
    s = sf.System()
    s += sf.PressureSource("supply", pressure=5e5)
    s += sf.Orifice("valve", sf.air, C=1e-9, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3, initial_pressure=1e5, **tank_kw)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    return s


def test_a_volume_given_its_wall_heat_transfer_uses_it_in_an_adiabatic_scene():
    adiabatic = sf.Simulation(_hot_fill(), duration=20.0, thermal="adiabatic").run()
    cooled = sf.Simulation(_hot_fill(hA=5.0), duration=20.0, thermal="adiabatic").run()
    T_wall = sf.air.temperature
    assert adiabatic.get("tank", "temperature")[-1] > T_wall + 30
    assert cooled.get("tank", "temperature")[-1] == pytest.approx(T_wall, abs=0.5)
    with pytest.raises(ValueError, match="contradicts"):
        sf.Simulation(_hot_fill(hA=5.0, thermal="adiabatic"), duration=1.0, thermal="adiabatic")


def test_moving_an_ideal_gas_to_another_temperature_keeps_its_enthalpy_function():
    g = sf.IdealGas("mygas", molar_mass=0.029, viscosity=1.8e-5)
    h = g.at(sf.Q_(126.85, "degC"))
    assert h.temperature == pytest.approx(400.0)
    for T in (250.0, 400.0):
        assert h.enthalpy(2e5, T) == pytest.approx(g.enthalpy(2e5, T), rel=1e-12)
        assert h.internal_energy(2e5, T) == pytest.approx(g.internal_energy(2e5, T), rel=1e-12)


def test_energy_flow_tolerance_follows_the_mass_flow_it_carries():
    """Newton resolves energy flows (counted from a reference enthalpy, so
    small) no more finely than mass flow times cp T."""
    from softflow.solve.linalg import make_linear_solver
    from softflow.solve.newton import Newton, Stats
    sim = sf.Simulation(_hot_fill(), duration=0.1, thermal="adiabatic")
    asm = sim.asm
    newton = Newton(asm, make_linear_solver(asm), Stats(), atol=np.full(asm.n, 1e-12))
    x = asm.x0.copy()
    q = np.array(asm.x_quantity)
    x[q == "massflow"] = 1e-3
    x[q == "energyflow"] = 1e-2
    newton._set_scale(x)
    tol_E = newton.tol[q == "energyflow"].max()
    cpT = sf.air.cp(1e5, sf.air.temperature) * sf.air.temperature
    newton.set_magnitude_link("energyflow", "massflow", cpT)
    newton._set_scale(x)
    assert newton.tol[q == "energyflow"].max() == pytest.approx(1e-6 * 1e-3 * cpT, rel=1e-6)
    assert newton.tol[q == "energyflow"].max() > 1000 * tol_E


# ---------------------------------------------------------------------------------------
# hysteretic actuator
# ---------------------------------------------------------------------------------------
ML, KPA = 1e-6, 1e3
# the paper's snapping loop with a wider snap (0.5 mL instead of 0.3 mL): V_lo 3.5 mL,
# V_hi 6.5 mL. (The 0.3 mL snap is a fold the adiabatic gas cannot follow: Newton
# fails there, for an Actuator with the same single curve too.)
SNAP_LOOP = sf.HysteresisLoop.snapping((1 * ML, 0.0), (6 * ML, 26 * KPA), (4 * ML, 12 * KPA),
                                       (14 * ML, 40 * KPA), snap_volume=0.5 * ML, gauge=True)


def _hysteretic_fill(**act_kw):
    s = sf.System()
    s += sf.PressureSource("src", pressure=Step(1.0, 1.35e5, P_ATM))
    s += sf.Orifice("valve", AIR, C=2e-10, b=0.3)
    s += sf.HystereticActuator("act", AIR, *SNAP_LOOP, **act_kw)
    s.connect("src", "valve")
    s.connect("valve", "act")
    return s


def test_hysteretic_actuator_fills_and_empties_adiabatically():
    s = _hysteretic_fill()
    res = sf.Simulation(s, duration=2.0, thermal="adiabatic").run()
    assert res.success
    t, br = res.times, res.get("act", "branch")
    vol, T, m = res.get("act", "volume"), res.get("act", "temperature"), res.get("act", "mass")
    # the branch switches once at each loop end: to deflation past V_hi while filling,
    # back to inflation below V_lo while emptying, from the step's converged volume
    switch = np.flatnonzero(np.diff(br) != 0)
    assert len(switch) == 2
    up, down = switch
    assert (br[up], br[up + 1], br[down], br[down + 1]) == (1.0, 0.0, 0.0, 1.0)
    assert vol[up] < SNAP_LOOP.volume_high <= vol[up + 1] and t[up + 1] < 1.0
    assert vol[down] > SNAP_LOOP.volume_low >= vol[down + 1] and t[down + 1] > 1.0
    np.testing.assert_array_equal(br[1:], SNAP_LOOP.next_inflating(vol[1:], br[:-1] > 0.5))
    # mass: what the source delivered (the run's own quadrature), and the gas fills the volume
    delivered = -res.integral("src", "massflow")[-1]
    assert abs(m[-1] - m[0] - delivered) < 1e-10 * m.max()
    np.testing.assert_allclose(AIR.density(res.get("act", "pressure"), T) * vol, m, rtol=1e-10)
    # energy: inflow, compression work and stored energy balance
    bal = energy_balance(res, s)
    assert bal["relative_error"] < 1e-8
    assert bal["work"] > 1e-3
    # fast compression heats the gas (measured +10 K), the fast expansion cools it
    fill = t <= 1.0
    assert T[fill].max() > T0 + 8.0
    assert T[-1] < T0 - 8.0


def test_hysteretic_actuator_thermal_parameters():
    s = _hysteretic_fill(initial_temperature=350.0, hA=0.5, wall_temperature=300.0)
    res = sf.Simulation(s, duration=0.2, thermal="adiabatic").run()
    T = res.get("act", "temperature")
    assert T[0] == pytest.approx(350.0)
    assert energy_balance(res, s)["wall_heat"] < 0      # hotter than its wall: loses heat
    assert energy_balance(res, s)["relative_error"] < 1e-8
    with pytest.raises(ValueError, match="HystereticActuator 'act'.*area"):
        sf.HystereticActuator("act", AIR, *SNAP_LOOP, heat_transfer_coefficient=10.0)
    with pytest.raises(ValueError, match="HystereticActuator 'act'.*heat transfer needs"):
        sf.Simulation(_hysteretic_fill(), duration=1.0, thermal="heat_transfer")


def _discharge(fluid):
    """A 180 bar bottle discharging through an ISO 6358 valve and a line into a
    1 bar tank: the first Newton iterates of the thermal start put the valve's
    node at 590 and 780 K before coming back."""
    s = sf.System()
    s += sf.Container("bottle", fluid, volume=1e-3, initial_pressure=180e5)
    s += sf.Orifice("valve", fluid, C=2e-11, b=0.3)
    s += sf.CircularTube("line", fluid, length=0.5, diameter=4e-3)
    s += sf.Container("tank", fluid, volume=2e-3)
    s.connect("bottle", "valve")
    s.connect(("valve", "b"), ("line", "a"))
    s.connect(("line", "b"), "tank")
    return s


def test_newton_keeps_temperatures_inside_a_tables_range():
    """Table air covers 233-423 K: Newton's iterates stay inside, so the start
    that eos air runs through (its range is wider) runs with the table too, to
    the same result."""
    table = sf.Simulation(_discharge(sf.air.with_level("table")), duration=0.5,
                          thermal="adiabatic").run()
    eos = sf.Simulation(_discharge(sf.air.with_level("eos")), duration=0.5,
                        thermal="adiabatic").run()
    for label in ("tank", "bottle"):
        for name in ("pressure", "temperature"):
            assert table.get(label, name)[-1] == pytest.approx(eos.get(label, name)[-1],
                                                               rel=1e-4)


def test_a_solution_beyond_the_tables_range_says_so():
    """Table air expanding below 233 K: the failure names the node temperature
    held at the range's edge and the wider level."""
    s = sf.System()
    table = sf.air.with_level("table")
    s += sf.PressureSource("src", pressure=0.6e5)
    s += sf.CircularTube("tube", table, length=0.1, diameter=2e-3)
    # a rigid tank (24 mL at 1.5 bar): an actuator on curve_monotonic() here, as
    # this scene had it, is emptied first, at t = 0.064 s (its curve's straight
    # continuation below 1 mL reaches zero volume above the source's 0.6 bar;
    # tests/test_issue41_states.py), before its gas reached 233 K
    s += sf.Container("tank", table, volume=2.4e-5, initial_pressure=1.5e5)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    # (the tube chokes from t = 0; the gas reaches 233 K at t ~ 0.04 s)
    res = sf.Simulation(s, duration=0.1, step=1e-3,
                        thermal="adiabatic").run(raise_on_failure=False)
    assert res.status == "failed" and res.times[-1] > 0.03
    assert "temperature at the edge of the temperature range" in res.message
    assert "233.15 ... 423.15 K" in res.message and "'eos'" in res.message


def _pump_tank(tube=True):
    """A volume-flow pump (in 1.8 mL/s for 2 s, pause 2 s, out for 2 s) on a
    20 mL air tank, through a short tube or straight."""
    from softflow.paper_scenes import pump_waveform
    s = sf.System()
    s += sf.VolumeFlowSource("pump", volumeflow=pump_waveform(2.0), fluid=sf.air)
    s += sf.Container("tank", sf.air, 20e-6)
    if tube:
        s += sf.CircularTube("R1", sf.air, 0.1, 2e-3)
        s.connect("pump", "R1")
        s.connect("R1", "tank")
    else:
        s.connect("pump", "tank")
    return s


def test_a_pump_that_reverses_on_a_node_at_rest_draws_the_tanks_gas():
    """At the reversal the pump starts to draw gas from a node at rest: there
    the node's temperature is set only by the zero-flow conductance and the
    upwind blend, and plain Newton drove it to ~1e5 K and failed
    (Newton._flows_first: pressures and flows first, temperatures held). The
    run goes through; the node then carries the tank's temperature, mass is
    conserved, and the end state is within 0.1 % of the swing of an rtol 1e-6
    run."""
    sim = sf.Simulation(_pump_tank(), duration=6.0, thermal="adiabatic")
    res = sim.run()
    t = res.times
    T_node, T_tank = res.get("R1", "temperature_a"), res.get("tank", "temperature")
    out = (t > 4.05) & (t < 6.0)
    assert out.sum() > 3 and (res.get("pump", "massflow")[out] > 0).all()   # drawn out
    assert np.max(np.abs(T_node[out] - T_tank[out])) < 0.05
    m = res.get("tank", "mass")
    drawn = res.integral("pump", "massflow")[-1]
    assert abs((m[-1] - m[0]) + drawn) <= 1e-12 * m[0]
    ref = sf.Simulation(_pump_tank(), duration=6.0, thermal="adiabatic", rtol=1e-6).run()
    p, p_ref = res.get("tank", "pressure"), ref.get("tank", "pressure")
    assert abs(p[-1] - p_ref[-1]) <= 1e-3 * np.ptp(p_ref)
    assert abs(T_tank[-1] - ref.get("tank", "temperature")[-1]) <= 1e-3 * np.ptp(T_tank)


def test_the_papers_fig3_scene_with_air_runs_adiabatic():
    """The paper's Fig. 3 architecture (pump in, pause, pump out; two actuators)
    filled with air and run adiabatic: it failed at the pump's reversal
    (t = 10 s) for every case before Newton._flows_first."""
    from softflow import paper_scenes as ps
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(ps.fig3("monotonic", fluid=sf.air), duration=ps.duration(3),
                            thermal="adiabatic", beyond_limits="warn").run()
    assert res.success and res.times[-1] == ps.duration(3)
    v1 = res.get("act1", "volume")
    assert v1.max() > 2 * v1[0] and v1[-1] < 1.2 * v1[0]     # inflated, then deflated


def test_fixed_steps_through_a_pump_reversal_of_air_adiabatic():
    """The same reversal at fixed steps (Fig. 4's tube scene with air): Newton
    met a singular Jacobian at the node at rest (the pivots of a gas volume's
    dm/dp ~1e-10 beside a tube's ~1e6), and stopped naming the tube as of
    extreme scale; the flows-first stage takes it. The deflation then
    returns the actuators towards their start."""
    from softflow import paper_scenes as ps
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(ps.fig4("tube", fluid=sf.air), duration=ps.duration(4),
                            thermal="adiabatic", step=2e-3, beyond_limits="warn").run()
    assert res.success and res.times[-1] == ps.duration(4)
    v1 = res.get("act1", "volume")
    assert v1.max() > 2 * v1[0] and v1[-1] < 1.2 * v1[0]


@pytest.mark.parametrize("kind", ["massflow", "volumeflow"])
def test_a_flow_source_that_reverses_without_a_pause(kind):
    """A flow source that pushes air into a tank for 1 s, then draws the same
    out for 1 s, adiabatic: at the reversal the flows pass through the upwind
    blend's band at once, and the other Newton stages stopped there (half of
    60 such runs, sources x flow elements x thermal models x steppers, failed
    before the flows-first stage). The run goes on, conserves mass, and
    stays within 1 % of the swing of an rtol 1e-7 run."""
    from softflow.curves.waveforms import PiecewiseConstant

    def scene():
        s = sf.System()
        if kind == "massflow":
            s += sf.MassFlowSource("src", massflow=PiecewiseConstant([0, 1, 2], [2e-5, -2e-5, 0.0]))
        else:
            s += sf.VolumeFlowSource("src", volumeflow=PiecewiseConstant(
                [0, 1, 2], [1e-5, -1e-5, 0.0]), fluid=AIR)
        s += sf.CircularTube("tube", AIR, 0.3, 1e-3)
        s += sf.Container("tank", AIR, 20e-6)
        s.connect("src", "tube")
        s.connect("tube", "tank")
        return s

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(scene(), duration=3.0, thermal="adiabatic").run()
        ref = sf.Simulation(scene(), duration=3.0, thermal="adiabatic", rtol=1e-7).run()
    m, into = res.get("tank", "mass"), res.integral("tank", "massflow")
    assert np.max(np.abs((m - m[0]) - into)) <= 1e-12 * m[0]
    if kind == "massflow":          # 2e-5 kg/s in for 1 s, then out again
        assert m[np.searchsorted(res.times, 1.0)] - m[0] == pytest.approx(2e-5, rel=1e-9)
        assert abs(m[-1] - m[0]) <= 1e-12 * m[0]
    for name in ("pressure", "temperature"):
        mine = np.interp(ref.times, res.times, res.get("tank", name))
        theirs = ref.get("tank", name)
        assert np.max(np.abs(mine - theirs)) <= 1e-2 * np.ptp(theirs), name


def test_restart_probes_fall_back_to_the_runs_newton_tolerance():
    """The restart probes hold Newton to 1e-12; at a pump's reversal into two
    tanks with free-convection walls (rtol 1e-5) the flows leave rest beside
    a gas volume's ~1e-10 kg/Pa dm/dp, and their update stalls at ~2e-14 kg/s
    of round-off against a 1e-14 tolerance: the probe then solves to the
    run's own Newton tolerance, where it failed the run before."""
    from softflow.curves.waveforms import PiecewiseConstant
    s = sf.System()
    s += sf.VolumeFlowSource("src", volumeflow=PiecewiseConstant([0, 1, 1.5, 2.5],
                                                                 [1e-5, 0.0, -1e-5, 0.0]),
                             fluid=AIR)
    walls = {"heat_transfer_coefficient": sf.FreeConvection(), "area": 4e-3}
    s += sf.CircularTube("t1", AIR, 0.3, 1e-3)
    s += sf.Container("tank", AIR, 20e-6, **walls)
    s += sf.Orifice("o2", AIR, C=2e-9, b=0.3)
    s += sf.Container("tank2", AIR, 50e-6, **walls)
    s.connect("src", "t1")
    s.connect("t1", "tank")
    s.connect("tank", "o2")
    s.connect("o2", "tank2")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(s, duration=3.0, thermal="heat_transfer", rtol=1e-5).run()
    assert res.success
    total = res.get("tank", "mass") + res.get("tank2", "mass")
    pumped = -res.integral("src", "massflow")      # what left the source into the tanks
    assert np.max(np.abs((total - total[0]) - pumped)) <= 1e-12 * total[0]
