"""A snapping valve in a thermal scene switches on its pressure difference
(its thermal variant reads the isothermal law's columns of V: p_a and p_b,
not p_a and T_a), and the sensitivities carry its switch as in an
isothermal scene."""
import warnings

import numpy as np
import pytest

import softflow as sf
from helpers import snapping_valve_scene



@pytest.mark.parametrize("thermal", ["isothermal", "adiabatic"])
def test_snapping_valve_switches_at_its_pressures(thermal):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sf.Simulation(snapping_valve_scene(), duration=0.2, rtol=1e-6, thermal=thermal).run()
    k = np.flatnonzero(np.diff(res.get("valve", "open"))) + 1
    assert len(k) >= 2
    dp = res.get("tank", "pressure") - res.get("out", "pressure")
    opened = res.get("valve", "open")[k] > 0.5
    # located where the difference reaches the opening / closing pressure
    np.testing.assert_allclose(dp[k][opened], 2e4, rtol=1e-3)
    np.testing.assert_allclose(dp[k][~opened], 5e3, rtol=1e-2)
    assert res.times[k[0]] > 0.02        # the tank fills first (it opened at 8e-8 s)


def test_thermal_valve_sensitivity_to_its_opening_pressure():
    """d p_tank / d opening_pressure after the first switch against central
    differences of whole runs (BDF, tight tolerances)."""
    sim = sf.Simulation(snapping_valve_scene(), duration=0.06, rtol=1e-8, thermal="adiabatic",
                        newton_rtol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        res = sim.run(sensitivities=["valve.opening_pressure"])
        h = 2.0
        up = sim.run(params={"valve.opening_pressure": 2e4 + h})
        down = sim.run(params={"valve.opening_pressure": 2e4 - h})
    t_end = res.times[-1]
    s = res.sensitivity("tank", "pressure", "valve.opening_pressure")[-1]
    fd = (up.get("tank", "pressure")[-1] - down.get("tank", "pressure")[-1]) / (2 * h)
    assert up.times[-1] == down.times[-1] == t_end
    assert abs(fd) > 0.1                 # the switch time moves the end pressure
    assert s == pytest.approx(fd, rel=2e-3)
