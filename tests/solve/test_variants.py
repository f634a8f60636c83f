"""Batched variants on the compiled loop (softflow.solve.variants): each
variant's own run of the BDF, in the compiled step loop."""
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow.solve import settings
from softflow.solve import variants as variants_mod
from softflow.solve.batched import _run_batched, build_batch, sample
from helpers import check_valve_pulses, filling_tank, snapping_valve_scene

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scenes import chain  # noqa: E402


def _run(sim, variants, own_clocks=True, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return _run_batched(sim, variants, own_clocks=own_clocks, **kw)


def _alone(sim, variant):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return sim.run(params=variant, raise_on_failure=False)


def _compiled(result):
    return result.stats.get("engine") == "compiled loop"


def _as_own_runs(sim, variants, out, label="tank", name="pressure", rtol=1e-9):
    """Each of ``out`` in the compiled loop, with its own run's accepted steps
    and its value of ``label``'s ``name`` at the end (to ``rtol``); the end
    values."""
    ends = []
    for v, b in zip(variants, out):
        assert _compiled(b), b.stats
        own = _alone(sim, v)
        assert b.stats["steps"] == own.stats["steps"], v
        np.testing.assert_allclose(b.get(label, name)[-1], own.get(label, name)[-1], rtol=rtol)
        ends.append(float(b.get(label, name)[-1]))
    return ends


def test_each_variant_takes_the_steps_of_its_own_run():
    """20 tube diameters 0.5-2 mm (time constants ~250x apart), over two
    threads: every variant takes exactly the accepted and rejected steps of
    its own run and ends where it ends."""
    sim = sf.Simulation(filling_tank(), duration=0.1)
    variants = [{"tube.diameter": d} for d in np.geomspace(0.5e-3, 2e-3, 20)]
    assert len(variants) >= settings.VARIANT_THREADS_MIN
    out = _run(sim, variants)
    for v, b in zip(variants, out):
        assert b.success and _compiled(b), b.stats
        own = _alone(sim, v)
        assert (b.stats["steps"], b.stats["rejected_steps"]) == (
            own.stats["steps"], own.stats["rejected_steps"]), v
        assert len(b.times) == b.stats["steps"] + 1 and b.times[-1] == 0.1
        np.testing.assert_allclose(b.get("tank", "pressure")[-1], own.get("tank", "pressure")[-1],
                                   rtol=1e-9)
    steps = [b.stats["steps"] for b in out]
    assert max(steps) > 3 * min(steps)          # each on its own clock


def test_threads_and_record_room_leave_the_numbers_as_they_are(monkeypatch):
    """One thread or two, records given room for every step at once or grown
    variant by variant (each variant that did not fit run again): the same
    points, bitwise, and the same work counted."""
    sim = sf.Simulation(filling_tank(), duration=0.05)
    variants = [{"tube.diameter": d} for d in np.geomspace(0.5e-3, 2e-3, 17)]
    runs, work = [], []
    for threads_from, rows in ((1, 64), (10 ** 9, 64), (1, 1)):
        monkeypatch.setattr(settings, "VARIANT_THREADS_MIN", threads_from)
        monkeypatch.setattr(settings, "VARIANT_ROWS", rows)
        out = _run(sim, variants)
        assert all(_compiled(b) for b in out)
        runs.append([(b.times, b.get("tank", "pressure"), b.get("tube", "massflow", "a"))
                     for b in out])
        # (the batch's counters: a variant run again for room counted once)
        work.append({k: v for k, v in out[0]._result.stats.items()
                     if k in ("steps", "newton_iterations", "residual_evaluations",
                              "factorizations")})
    assert work[0] == work[1] == work[2]
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            for x, y in zip(a, b):
                np.testing.assert_array_equal(x, y)


def test_a_jump_is_a_point_of_every_variant_and_a_restart():
    """A source stepping at 20 ms: each variant lands on the jump and takes
    its own run's steps."""
    step = sf.waveforms.Step(0.02, sf.Q_(0.3, "bar"), sf.Q_(0.1, "bar"))
    sim = sf.Simulation(filling_tank(sf.PressureSource("src", pressure=step, gauge=True)),
                        duration=0.06)
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1e-3, 2e-3)]
    out = _run(sim, variants)
    assert all(np.any(b.times == 0.02) for b in out)
    _as_own_runs(sim, variants, out)


def test_each_variant_follows_its_own_source_signal():
    """The source's waveform a run-time parameter (ramps of three heights,
    sines of two frequencies): each variant's signal is its own."""
    ramps = [sf.waveforms.Ramp(0.0, 0.03, sf.Q_(0.0, "bar"), sf.Q_(h, "bar")) for h in (0.1, 0.3)]
    sines = [sf.waveforms.Sine(sf.Q_(0.2, "bar"), f, offset=sf.Q_(0.2, "bar")) for f in (20, 50)]
    sim = sf.Simulation(filling_tank(sf.PressureSource("src", pressure=ramps[0], gauge=True)),
                        duration=0.06)
    variants = [{"src.pressure": w} for w in ramps + sines]
    ends = _as_own_runs(sim, variants, _run(sim, variants))
    assert len(set(np.round(ends, 3))) == 4


def test_snapping_valves_switch_within_each_variants_run():
    """Opening pressure x tube diameter: each valve snaps in its own run (the
    compiled loop locates the switch as it does for one run)."""
    sim = sf.Simulation(snapping_valve_scene(), duration=0.2)
    variants = [{"valve.opening_pressure": p, "tube.diameter": d}
                for p in (1.2e4, 2.4e4) for d in (0.8e-3, 1.3e-3)]
    _as_own_runs(sim, variants, _run(sim, variants), "out", rtol=1e-7)


def test_a_run_the_loop_hands_back_is_run_alone():
    """max_steps = 12: the wide tubes' runs need more steps, their loops stop
    at the budget and they run alone, where they fail saying so; the narrow
    ones complete in the batch."""
    sim = sf.Simulation(filling_tank(), duration=0.1, max_steps=12)
    variants = [{"tube.diameter": d} for d in (0.5e-3, 2e-3, 0.6e-3, 1.8e-3)]
    out = _run(sim, variants)
    assert [b.status for b in out] == ["success", "failed", "success", "failed"]
    assert _compiled(out[0]) and _compiled(out[2])
    assert not out[1].stats.get("batched") and "max_steps" in out[1].message


def test_recorded_components_only():
    """Simulation(record=...): the batch keeps the tank alone, each variant's
    outputs read as its own run's."""
    sim = sf.Simulation(filling_tank(), duration=0.05, record=["tank"])
    variants = [{"tube.diameter": d} for d in (0.7e-3, 1.5e-3)]
    out = _run(sim, variants)
    for v, b in zip(variants, out):
        assert _compiled(b)
        own = _alone(sim, v)
        np.testing.assert_allclose(b.get("tank", "pressure")[-1], own.get("tank", "pressure")[-1],
                                   rtol=1e-9)
        with pytest.raises(Exception):
            b.get("tube", "massflow", "a")


def test_sampling_a_batch_is_np_interp_of_each_variant():
    """batched.sample reads each variant's outputs at given times as
    np.interp between its own points, bitwise, in a few array operations for
    all the variants at once (a flow and a state here); NaN past the end
    of a failed run."""
    sim = sf.Simulation(filling_tank(), duration=0.05, max_steps=12)
    variants = [{"tube.diameter": d} for d in (0.5e-3, 0.7e-3, 2e-3)]
    out = _run(sim, variants)
    times = np.array([-1.0, 0.0, 1e-3, 0.0123, 0.03, 0.05, 0.07])
    got = sample(out, ["src.massflow", "tank.mass"], times)
    for r, values in zip(out, got):
        for row, (label, name) in zip(values, [("src", "massflow"), ("tank", "mass")]):
            want = np.interp(times, r.times, r.get(label, name))
            if not r.success:
                want = np.where(times <= r.times[-1], want, np.nan)
            np.testing.assert_array_equal(row, want)


@pytest.mark.parametrize("case", ["pump", "adiabatic", "wall hA"])
def test_flow_sources_and_thermal_scenes_run_in_the_loop(case):
    """A mass flow source (its start solved without the culprit finder's
    hooks: a start that does not converge runs alone), adiabatic tanks and
    tanks with a constant wall h A: each variant's own run's steps."""
    s = sf.System()
    s += (sf.MassFlowSource("src", massflow=1e-5) if case == "pump"
          else sf.PressureSource("src", pressure=sf.Q_(1.3, "bar")))
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5, **({"hA": 1e-3} if case == "wall hA" else {}))
    s.connect("src", "tube")
    s.connect("tube", "tank")
    thermal = {"pump": "isothermal", "adiabatic": "adiabatic", "wall hA": "heat_transfer"}[case]
    sim = sf.Simulation(s, duration=0.2, thermal=thermal)
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1e-3, 2e-3)]
    for v, b in zip(variants, _run(sim, variants)):
        assert _compiled(b)
        own = _alone(sim, v)
        assert b.stats["steps"] == own.stats["steps"]
        names = ("pressure",) if thermal == "isothermal" else ("pressure", "temperature")
        for name in names:
            np.testing.assert_allclose(b.get("tank", name)[-1], own.get("tank", name)[-1],
                                       rtol=1e-9)


def test_check_valves_that_open_and_shut_run_in_the_loop():
    """Pulses of 1 bar through a check valve into a tank that leaks (the
    valve opens and shuts at every pulse; the loop takes the steps across
    its kinks as the BDF takes them): a variant the loop runs through takes
    its own run's steps; one it hands back (a solve on another piece of the
    valve's law, a restart probe that needs the BDF's continuation) runs
    alone: every variant is its own run."""
    sim = sf.Simulation(check_valve_pulses(), duration=1.0)
    variants = [{"cv.cracking_pressure": p} for p in (1e3, 2e3, 4e3, 8e3, 1.6e4)]
    out = _run(sim, variants)
    compiled = [k for k, b in enumerate(out) if _compiled(b)]
    assert compiled and len(compiled) < len(out)
    for k, (v, b) in enumerate(zip(variants, out)):
        own = _alone(sim, v)
        if k in compiled:
            assert b.stats["steps"] == own.stats["steps"]
        np.testing.assert_allclose(b.get("tank", "pressure")[-1],
                                   own.get("tank", "pressure")[-1], rtol=1e-7)


def _tank_scene(pressure, **wall):
    s = sf.System()
    s += sf.PressureSource("src", pressure=pressure)
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5, **wall)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    return s


@pytest.mark.parametrize("case", ["wall", "user", "fixed", "refine"])
def test_scenes_outside_the_loop_share_one_step_sequence(case, monkeypatch):
    """A wall whose h A a correlation sets at each step (the loop takes no
    per-step coefficients), a user's component called back (on the batch
    network's arrays, not a variant's; one numba compiles runs in the loop:
    tests/solve/test_usercompile.py), fixed steps and refine=: not in the
    loop; the batch shares one step sequence, says why, and each variant
    meets the tolerance of its own run."""
    from helpers import UserChamber
    from softflow.solve import settings
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    thermal, kw = "isothermal", {}
    if case == "wall":
        system = _tank_scene(sf.Q_(1.3, "bar"), heat_transfer_coefficient=sf.FreeConvection(),
                             area=2.2e-3)
        thermal, why = "heat_transfer", "Container 'tank' sets coefficients at each step"
    elif case == "user":
        system = sf.System()
        system += sf.PressureSource("src", pressure=sf.pressure_atmospheric + 1e4)
        system += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
        system += UserChamber("tank")
        system.connect("tube", "src")
        system.connect("tube", "tank")
        why = "a user component"
    elif case == "fixed":
        system, kw, why = _tank_scene(sf.Q_(1.3, "bar")), {"step": 1e-3}, "fixed steps"
    else:
        system, kw, why = _tank_scene(sf.Q_(1.3, "bar")), {"refine": 2}, "refine"
    sim = sf.Simulation(system, duration=0.05, thermal=thermal, **kw)
    variants = [{"tube.diameter": d} for d in (1e-3, 2e-3)]
    if case == "wall":
        # the scene passes reason_not; its compiled batch is refused
        batch = build_batch(system, variants, {c.label for c in system.components})
        with pytest.raises(variants_mod.Unsupported, match=why):
            variants_mod.run(sim, sf.Simulation(batch, duration=0.05, thermal=thermal), 2)
    else:
        assert why in variants_mod.reason_not(sim)
    out = _run(sim, variants)
    for v, b in zip(variants, out):
        assert b.success and b.stats["clocks"] == "shared", b.stats
        assert why in b.stats["shared_because"]
        own = _alone(sim, v)
        np.testing.assert_allclose(b.get("tank", "pressure")[-1], own.get("tank", "pressure")[-1],
                                   rtol=2 * sim.rtol)
        if case == "refine":
            assert len(b.times) == 2 * b.stats["steps"] + 1


def test_a_source_given_as_a_python_function_runs_in_the_loop():
    """Its function called back from each variant's run (the threads take
    the interpreter's lock for it): each variant its own run."""
    sim = sf.Simulation(_tank_scene(lambda t: 1.2e5 + 1e4 * min(t, 0.01) / 0.01),
                        duration=0.05)
    variants = [{"tube.diameter": d} for d in (0.8e-3, 1e-3, 2e-3)]
    _as_own_runs(sim, variants, _run(sim, variants))


def test_a_stiff_variant_does_not_set_the_others_steps():
    """Tubes 0.4-2.5 mm: time constants ~1000x apart. Each variant takes its
    own run's steps in the loop; the shared sequence takes far more."""
    sim = sf.Simulation(filling_tank(), duration=0.1)
    variants = [{"tube.diameter": d} for d in np.geomspace(0.4e-3, 2.5e-3, 10)]
    out = _run(sim, variants)
    _as_own_runs(sim, variants, out)
    for b in out:
        assert len(b.times) == b.stats["steps"] + 1
        assert np.all(np.diff(b.times) > 0) and b.times[-1] == pytest.approx(0.1, rel=1e-12)
    shared = _run(sim, variants, own_clocks=False)
    assert shared[0].stats["clocks"] == "shared"
    assert shared[0].stats["steps"] > 1.3 * max(b.stats["steps"] for b in out)
    assert out[0].stats["steps"] < 0.2 * shared[0].stats["steps"]


def test_validity_is_judged_on_each_variant_own_times():
    """friction='laminar' past Re 2 300 in the wide tubes only: each of those
    warns at the time its own run finds, naming the user's component (not its
    copy in the batch, v1/tube); the narrow one does not."""
    src = sf.PressureSource("src", pressure=sf.Q_(1.1, "bar"))
    sim = sf.Simulation(filling_tank(src, friction="laminar"), duration=0.05)
    variants = [{"tube.diameter": d} for d in (0.3e-3, 1.2e-3, 2e-3)]
    with pytest.warns(sf.ModelWarning, match="Reynolds") as caught:
        out = _run_batched(sim, variants, own_clocks=True)
    assert all("CircularTube 'tube'" in str(w.message) for w in caught
               if "Reynolds" in str(w.message))
    for v, b in zip(variants, out):
        assert _compiled(b)
        serial = _alone(sim, v)
        mine = [w for w in b.warnings if w.check == "tube_reynolds"]
        theirs = [w for w in serial.warnings if w.check == "tube_reynolds"]
        assert len(mine) == len(theirs)
        for a, w in zip(mine, theirs):
            assert a.component == "tube" and a.message.startswith("CircularTube 'tube':")
            assert a.details["time"] in b.times
            assert a.details["time"] == pytest.approx(w.details["time"], rel=1e-9)
            assert a.measured == pytest.approx(w.measured, rel=1e-6)
    assert not [w for w in out[0].warnings if w.check == "tube_reynolds"]
    assert [w for w in out[2].warnings if w.check == "tube_reynolds"]


def test_a_variant_past_choking_fails_on_its_own_and_the_others_go_on():
    """The mean-density law is refused past the choke: that variant fails with
    its own run's message, the others complete in the loop."""
    sim = sf.Simulation(filling_tank(sf.PressureSource("src", pressure=sf.Q_(9, "bar"),
                                                       gauge=True), compressible="mean_density"),
                        duration=0.02)
    variants = [{"src.pressure": p} for p in (sf.Q_(0.2, "bar"), sf.Q_(9, "bar"),
                                             sf.Q_(0.3, "bar"))]
    out = _run(sim, variants)
    alone = _alone(sim, variants[1])
    assert [r.status for r in out] == ["success", "failed", "success"]
    assert out[1].message == alone.message and "chokes" in out[1].message
    assert _compiled(out[0]) and _compiled(out[2])


def test_a_variant_whose_mode_chatters_fails_alone_and_says_so():
    """As BDF: a mass-flow source pushing into a snapping valve with no volume
    between them chatters; each variant's run fails naming the valve."""
    from helpers import chattering_valve_scene
    from softflow.solve import bdf
    sim = sf.Simulation(chattering_valve_scene(), duration=0.5)
    out = _run(sim, [{"src.massflow": m} for m in (1e-5, 2e-5)])
    for r in out:
        assert r.status == "failed"
        assert "SnappingValve 'valve' switched its mode at each of the last " \
               f"{bdf.CHATTER_SWITCHES} steps" in r.message


def test_orifice_fills_whose_flows_die_out_end_as_their_own_runs():
    """64 ISO 6358 fills (flows dying out at the end, an orifice's square-root
    law at rest): each variant's steps and end pressure are its own run's."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=4e5)
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    sim = sf.Simulation(s, duration=1.0)
    variants = [{"valve.C": c} for c in np.geomspace(1e-8, 4e-8, 64)]
    out = _run(sim, variants)
    picked = [0, 21, 42, 63]
    _as_own_runs(sim, [variants[k] for k in picked], [out[k] for k in picked])


def test_actuator_curves_of_their_own_split_the_batch_group():
    """The Fig. 4 network (a pump into two actuators behind a restrictor of
    water with its inertia) over restrictor diameter x actuator 2's curve:
    the batch puts each variant's actuator 2 in a group of its own (its
    curve), which each variant's run reads as the scene's one group."""
    from softflow import paper_scenes as ps
    sim = sf.Simulation(ps.fig4("tube", physics="full"), duration=2.0)
    variants = [{"R2.diameter": d, "act2.curve": ps.curve_plateau(p)}
                for d in (2e-3, 3e-3) for p in (17.0, 30.0)]
    ends = _as_own_runs(sim, variants, _run(sim, variants), "act2", "volume", rtol=1e-7)
    assert len(set(np.round(ends, 12))) == 4


def test_a_sweep_reads_each_variants_own_interpolant():
    """sf.sweep at times inside the steps: each variant's values are its own
    run's interpolant's (Result.at), to round-off; at its points, its points."""
    sim = sf.Simulation(filling_tank(), duration=0.05)
    variants = [{"tube.diameter": d} for d in (0.5e-3, 0.9e-3, 2e-3)]
    times = np.linspace(0.0, 0.05, 41)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        out = sf.sweep(sim, variants, outputs=["tank.pressure", "src.massflow"], times=times,
                       engine="batched")
    for v, p, m in zip(variants, out["tank.pressure"], out["src.massflow"]):
        own = _alone(sim, v)
        np.testing.assert_allclose(p, own.at(times, "tank", "pressure"), rtol=1e-10)
        # (the consistent start's flows agree within Newton's tolerance, its
        # point confirmed on fresh factors here, in the Python start there)
        np.testing.assert_allclose(m[0], own.at(times, "src", "massflow")[0], rtol=1e-5)
        np.testing.assert_allclose(m[1:], own.at(times, "src", "massflow")[1:], rtol=1e-7)


def test_a_chain_on_the_loops_banded_lu():
    """A chain of 12 tube-and-container pairs, whose Jacobian the loop solves
    as a band: each variant's own run's steps (each start on a dense LU)."""
    sim = sf.Simulation(chain(12), duration=0.05)
    variants = [{"tube0.diameter": d} for d in (1e-3, 2e-3, 3e-3)]
    assert variants_mod._Template(sim).steps.band is not None
    _as_own_runs(sim, variants, _run(sim, variants), "cont11")


def test_the_bar_counts_the_variants_run(monkeypatch, capsys):
    """progress=True: the bar (after DELAY s, here at once) moves with the
    share of the variants run, each thread's calls a few dozen variants."""
    from softflow.solve import progress
    monkeypatch.setattr(progress, "DELAY", 0.0)
    monkeypatch.setattr(progress, "CHECK_INTERVAL", 1e-4)
    monkeypatch.setattr(settings, "VARIANT_CHUNK", 2)
    sim = sf.Simulation(filling_tank(), duration=0.2)
    variants = [{"tube.diameter": d} for d in np.geomspace(0.5e-3, 2e-3, 40)]
    out = _run(sim, variants, progress=True)
    assert all(_compiled(b) for b in out)
    assert "softflow" in capsys.readouterr().err


def test_the_batchs_interpolant_reads_every_column_or_the_asked_ones_alike():
    """Result.at on the batch (every column, or one component's) and the
    sweeps' read of the named components give the same numbers."""
    sim = sf.Simulation(filling_tank(), duration=0.05)
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1.2e-3, 2e-3)]
    out = _run(sim, variants)
    held = out[0]._result
    times = np.linspace(0.0, 0.05, 17)
    every = held._at_times(times)
    some = held._at_times(times, ["v1/tank", "v2/tube"])
    for label, name, term in (("v1/tank", "pressure", None), ("v1/tank", "mass", None),
                              ("v2/tube", "massflow", "a")):
        np.testing.assert_array_equal(every.get(label, name, term), some.get(label, name, term))
    assert np.isnan(some.get("v0/tank", "mass")).all()
    np.testing.assert_array_equal(held.at(times, "v1/tank", "pressure"),
                                  every.get("v1/tank", "pressure"))


def test_the_interpolant_at_a_variants_own_points_is_those_points():
    """Times on a variant's step ends (where a time is placed among its own
    entries, the lifted search made exact): its recorded points."""
    sim = sf.Simulation(filling_tank(), duration=0.05)
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1.2e-3, 2e-3)]
    out = _run(sim, variants)
    held = out[1]._result
    times = np.asarray(out[1].times)
    at = held._at_times(times, ["v1/tank"])
    np.testing.assert_allclose(at.get("v1/tank", "mass"), out[1].get("tank", "mass"),
                               rtol=1e-13)
