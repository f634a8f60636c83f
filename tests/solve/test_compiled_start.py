"""The consistent start solved in one compiled call (settings.COMPILED_START,
softflow.solve.steploop.start_solver, softflow.laws.stepper.start_solve):
the same Newton stages as the Python solve, so the same point to round-off
and the same counts; the Python solve where it does not serve the run or
does not converge."""
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow.solve import settings, steploop


def _chain(n=8, fluid=sf.air):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    prev = "src"
    for i in range(n):
        s += sf.CircularTube(f"t{i}", fluid, 0.1, 1e-3)
        s += sf.Container(f"c{i}", fluid, 1e-6)
        s.connect(prev, f"t{i}")
        s.connect(f"t{i}", f"c{i}")
        prev = f"c{i}"
    return s


def _run(system, compiled, **options):
    saved = settings.COMPILED_START
    settings.COMPILED_START = compiled
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            return sf.Simulation(system, **options).run()
    finally:
        settings.COMPILED_START = saved


def _served(monkeypatch):
    got = []
    real = steploop.start_solver

    def spy(integ, lin0):
        solve = real(integ, lin0)
        got.append(solve is not None)
        return solve
    monkeypatch.setattr(steploop, "start_solver", spy)
    return got


@pytest.mark.parametrize("options, rtol", [(dict(duration=1e-3, step=1e-3), 1e-12),
                                           (dict(duration=0.05), 1e-8)],
                         ids=["fixed", "adaptive"])
def test_the_compiled_start_is_the_python_start(monkeypatch, options, rtol):
    # the N = 8 chain's start needs the damped stage (the tubes' slopes at
    # rest): 10 residual evaluations, 6 factorizations, in either; the start
    # the same to round-off (LAPACK's LU there, the compiled one here), which
    # the adaptive run's 33 steps carry to ~2e-9 of each unknown's range
    served = _served(monkeypatch)
    a = _run(_chain(), True, **options)
    b = _run(_chain(), False, **options)
    assert served == [True, False]         # (the second: COMPILED_START off)
    assert a.stats == b.stats
    scale = np.abs(b.X).max(axis=0) + 1e-30
    assert np.max(np.abs(a.X[0] - b.X[0]) / scale) < 1e-12
    assert np.max(np.abs(a.X - b.X) / scale) < rtol


def test_networks_with_flow_sources_or_temperatures_start_in_python(monkeypatch):
    # the culprit finder's hooks before the damped stage and the continuation
    # (a flow source may ask what no pressure gives), the thermal solve's
    # flows-first stage: the Python solve's
    served = _served(monkeypatch)
    s = sf.System()
    s += sf.MassFlowSource("pump", 1e-6)
    s += sf.CircularTube("tube", sf.air, 0.1, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5)
    s.connect("pump", ("tube", "a"))
    s.connect(("tube", "b"), "tank")
    _run(s, True, duration=1e-3, step=1e-3)
    _run(_chain(2), True, duration=1e-3, step=1e-3, thermal="adiabatic")
    assert served == [False, False]


def test_a_start_the_compiled_solve_does_not_reach_is_the_python_solves(monkeypatch):
    # a 2 bar pulse through a CheckValve cracking at 70 kPa: Newton's steps
    # from the initial values land far past the valve's opening band, the
    # compiled solve (no continuation) fails, and the Python solve reaches
    # the start by continuation, as it does without the compiled attempt; the
    # attempt's work is counted (84 residual evaluations, measured)
    from test_integrator import _check_valve_pulse
    served = _served(monkeypatch)
    reached = []
    real = steploop.start_solver

    def spy(integ, lin0):
        solve = real(integ, lin0)
        if solve is None:
            return None

        def attempt(x0):
            x = solve(x0)
            reached.append(x is not None)
            return x
        return attempt
    monkeypatch.setattr(steploop, "start_solver", spy)
    runs = [_run(_check_valve_pulse(70e3, False), compiled, duration=1.0)
            for compiled in (True, False)]
    assert served == [True, False]         # (the second: COMPILED_START off)
    assert reached == [False]
    a, b = runs
    assert a.stats["steps"] == b.stats["steps"]
    np.testing.assert_array_equal(a.times, b.times)
    np.testing.assert_array_equal(a.get("tank", "pressure"), b.get("tank", "pressure"))
    more = a.stats["residual_evaluations"] - b.stats["residual_evaluations"]
    assert 0 < more <= 120
