"""Simulation(max_steps=) counts a run's steps, accepted and rejected, as
result.stats reports them: not the solves that are no steps (the
consistent start's, BDF's restart probes at t = 0 and at every breakpoint,
continuation's). The batched engine on its own clocks counts alike."""
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow.solve.batched import _run_batched
from softflow.solve.newton import Newton
from helpers import filling_tank

#: a square wave of 250 Hz: 10 edges in 20 ms, a restart (3 probe solves) at each
SQUARE = sf.waveforms.Square(sf.Q_(0.3, "bar"), sf.Q_(0.0, "bar"), 250.0)
DURATION = 0.02


def _scene():
    return filling_tank(sf.PressureSource("src", pressure=SQUARE, gauge=True))


def _tried(res):
    return res.stats["steps"] + res.stats["rejected_steps"]


def test_a_run_of_many_breakpoints_goes_through_on_its_own_step_count(monkeypatch, python_steps):
    # (every step in Python: the solves counted are Newton.solve's)
    solves = []
    solve = Newton.solve

    def counted(self, *args):
        solves.append(args[2])
        return solve(self, *args)

    monkeypatch.setattr(Newton, "solve", counted)
    free = sf.Simulation(_scene(), duration=DURATION).run()
    n = _tried(free)
    edges = [b for b in sf.PressureSource("s", SQUARE, gauge=True).breakpoints_until(DURATION)
             if 0 < b < DURATION]
    assert len(edges) == 9 and all(np.any(free.times == b) for b in edges)
    # the probes' solves are many more than the steps' own: max_steps = n
    # counted them too, and stopped the run (at ~ t = 0.017 s)
    assert len(solves) >= n + 3 * len(edges)
    solves.clear()
    exact = sf.Simulation(_scene(), duration=DURATION, max_steps=n).run()
    assert exact.success and _tried(exact) == n
    np.testing.assert_array_equal(exact.times, free.times)
    np.testing.assert_array_equal(exact.get("tank", "pressure"), free.get("tank", "pressure"))
    short = sf.Simulation(_scene(), duration=DURATION, max_steps=n - 1).run(
        raise_on_failure=False)
    assert short.status == "failed"
    assert f"more than max_steps = {n - 1} steps (accepted and rejected)" in short.message
    assert _tried(short) == n - 1 and short.times[-1] < DURATION


def test_the_compiled_loops_steps_count_alike(monkeypatch):
    """The steps the compiled loop takes (softflow.solve.steploop) count as
    the BDF's own: max_steps = n lets the run through unchanged, n - 1 stops
    it with the same message, after n - 1 tries."""
    from softflow.solve import steploop
    calls = []
    run = steploop.CompiledSteps.run

    def spy(self, *args):
        out = run(self, *args)
        calls.append(out[4])
        return out
    monkeypatch.setattr(steploop.CompiledSteps, "run", spy)
    free = sf.Simulation(_scene(), duration=DURATION).run()
    n = _tried(free)
    assert sum(calls) > n // 2          # most steps were the compiled loop's
    exact = sf.Simulation(_scene(), duration=DURATION, max_steps=n).run()
    assert exact.success and _tried(exact) == n
    np.testing.assert_array_equal(exact.times, free.times)
    for m in (n - 1, n // 2):
        short = sf.Simulation(_scene(), duration=DURATION, max_steps=m).run(
            raise_on_failure=False)
        assert short.status == "failed"
        assert f"more than max_steps = {m} steps (accepted and rejected)" in short.message
        assert _tried(short) == m and short.times[-1] < DURATION


def test_fixed_steps_count_the_grid_steps_only():
    # 10 steps of 1 ms: the consistent start's solve is no step
    res = sf.Simulation(_scene(), duration=0.01, step=1e-3, max_steps=10).run()
    assert res.success and _tried(res) == 10


def test_the_batched_engine_counts_each_variants_steps_alike():
    variants = [{"tube.diameter": d} for d in np.geomspace(0.8e-3, 1.2e-3, 16)]
    sim = sf.Simulation(_scene(), duration=DURATION)
    counts = [_tried(sim.run(params=v)) for v in variants]

    def batched(max_steps):
        bsim = sf.Simulation(_scene(), duration=DURATION, max_steps=max_steps)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            return _run_batched(bsim, variants, own_clocks=True)

    out = batched(max(counts))
    assert all(o.success and o.stats["clocks"] == "own" for o in out)
    assert [_tried(o) for o in out] == counts
    # the same budget serially (the counting of a variant run alone)
    budget = sf.Simulation(_scene(), duration=DURATION, max_steps=max(counts))
    assert all(budget.run(params=v).success for v in variants[::8])
    # one step fewer than the fewest: every variant stops, on its own clock
    # and on its own (a variant that fails on its clock runs alone)
    out = batched(min(counts) - 1)
    assert all(o.status == "failed" and "more than max_steps" in o.message for o in out)


@pytest.mark.parametrize("kw, limit", [({}, 5),
                                       # 14 steps of 1.5 ms and the 9 edges between
                                       ({"step": 1.5e-3}, 14)])
def test_steps_past_max_steps_raise_a_step_limit_error(kw, limit):
    from softflow.solve.newton import StepLimitError
    with pytest.raises(sf.SimulationError) as info:
        sf.Simulation(_scene(), duration=DURATION, max_steps=limit, **kw).run()
    assert isinstance(info.value.__cause__, StepLimitError)
    assert f"more than max_steps = {limit} steps (accepted and rejected)" in str(info.value)
    assert _tried(info.value.result) == limit
