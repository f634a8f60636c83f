"""Batched variants on clocks of their own (softflow.solve.clocks)."""
import math
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow.solve import clocks, settings
from softflow.solve.batched import _run_batched, build_batch
from softflow.solve.bdf import _rescale_matrix
from helpers import (UserChamber, chattering_valve_scene, crossing_time, filling_tank,
                     gauge_error, gauge_reference, snapping_valve_scene)

P0 = sf.pressure_atmospheric


@pytest.fixture(autouse=True)
def _vectorized_clocks(monkeypatch):
    """These tests are the vectorized BDF's: the compiled loop's variants
    (softflow.solve.variants, tests/solve/test_variants.py) off."""
    monkeypatch.setattr(settings, "COMPILED_VARIANTS", False)


def scene(source=None, friction="Haaland"):
    return filling_tank(source, friction=friction)


def _run(sim, variants):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return _run_batched(sim, variants, own_clocks=True)


def test_rescale_matrices_are_the_bdf_ones():
    """The batched rescaling (polynomials in the factor, identity past the
    order) gives the BDF's matrices, inside and outside the sampled factors."""
    C = clocks._rescale_polynomials(5)
    for order in range(1, 6):
        for f in (0.2, 0.55, 1.0, 1.3, 2.0, 3.0):
            M = sum(C[order, p] * f ** p for p in range(6))
            ref = np.eye(5)
            ref[:order, :order] = _rescale_matrix(order, f)[1:, 1:]
            np.testing.assert_allclose(M, ref, rtol=0, atol=1e-11 * np.abs(ref).max())


def test_each_instance_steps_at_its_own_time_and_step():
    """The batch's step equations with a time and a step per variant are, row
    for row, each variant's equations at its own (a ramp source reads t)."""
    ramp = sf.waveforms.Ramp(0.0, 0.05, sf.Q_(0.0, "bar"), sf.Q_(0.4, "bar"))
    src = sf.PressureSource("src", pressure=ramp, gauge=True)
    sim = sf.Simulation(scene(src), duration=0.1)
    variants = [{"tube.diameter": d} for d in (0.7e-3, 1e-3, 1.5e-3)]
    batch = build_batch(sim.system, variants, {"src", "tube", "tank"})
    bsim = sf.Simulation(batch, duration=0.1)
    integ = clocks.VariantBDF(bsim, 3)
    asm, lay = bsim.asm, integ.lay
    rng = np.random.default_rng(1)
    x = asm.x0 + rng.uniform(0.0, 1.0, asm.n) * np.where(
        np.array(asm.x_quantity) == "pressure", 2e4, 1e-5)
    S = asm.S0 * (1 + 0.1 * rng.uniform(size=asm.S0.size))
    tv, cv = np.array([0.01, 0.02, 0.07]), np.array([1e-4, 3e-3, 2e-5])
    F = integ._residual(x, S, tv, cv, True)
    J = bsim.asm.jacobian_csc().toarray()
    Sn = integ._update(x, S, cv)
    for v in range(3):
        rows = lay.rperm.reshape(3, -1)[v]
        cols = lay.xperm.reshape(3, -1)[v]
        states = lay.sperm.reshape(3, -1)[v]
        Fv = asm.residual(x, S, tv[v], cv[v], True)
        Jv = asm.jacobian_csc().toarray()
        np.testing.assert_allclose(F[rows], Fv[rows], rtol=1e-14, atol=0)
        np.testing.assert_allclose(J[np.ix_(rows, cols)], Jv[np.ix_(rows, cols)], rtol=1e-14)
        np.testing.assert_allclose(Sn[states], asm.update_states(x, S, cv[v])[states],
                                   rtol=1e-14)


def _reference(variant, duration, source=None):
    return gauge_reference(sf.Simulation(scene(source), duration=duration, rtol=1e-9), variant)


def test_a_stiff_variant_does_not_set_the_others_steps():
    """Tubes 0.4-2.5 mm: time constants ~1000x apart. Each variant takes about
    the steps its own run takes (one shared sequence took the union), and is as
    accurate as its own run."""
    sim = sf.Simulation(scene(), duration=0.1)
    variants = [{"tube.diameter": d} for d in np.geomspace(0.4e-3, 2.5e-3, 10)]
    out = _run(sim, variants)
    shared = None
    for v, b in zip(variants, out):
        assert b.success and b.stats["clocks"] == "own"
        serial = sim.run(params=v)
        assert abs(b.stats["steps"] - serial.stats["steps"]) <= max(3, 0.2 * serial.stats["steps"])
        assert len(b.times) == b.stats["steps"] + 1
        assert np.all(np.diff(b.times) > 0) and b.times[-1] == pytest.approx(0.1, rel=1e-12)
        ref = _reference(v, 0.1)
        assert gauge_error(b, ref) <= 2 * max(gauge_error(serial, ref), 1e-3), v
    from softflow.solve.batched import _run_batch
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        shared = _run_batch(sim, variants, False, own_clocks=False)
    assert shared[0].stats["clocks"] == "shared"
    assert shared[0].stats["steps"] > 1.3 * max(b.stats["steps"] for b in out)
    assert out[0].stats["steps"] < 0.2 * shared[0].stats["steps"]


def test_a_declared_jump_is_a_barrier_every_variant_restarts_at():
    """A source stepping at 20 ms: every variant lands on the jump, sees its
    left limit there, restarts after it, and matches its own run."""
    step = sf.waveforms.Step(0.02, sf.Q_(0.3, "bar"), sf.Q_(0.1, "bar"))
    sim = sf.Simulation(scene(sf.PressureSource("src", pressure=step, gauge=True)), duration=0.06)
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1e-3, 2e-3)]
    out = _run(sim, variants)
    for v, b in zip(variants, out):
        assert b.stats["clocks"] == "own"
        assert np.any(b.times == 0.02)
        serial = sim.run(params=v)
        r = _reference(v, 0.06, sf.PressureSource("src", pressure=step, gauge=True))
        assert gauge_error(b, r) <= 2 * max(gauge_error(serial, r), 1e-3), v


def test_validity_is_judged_on_each_variant_own_times():
    """friction='laminar' past Re 2 300 in the wide tubes only (3 500 and
    16 000): each of those warns at the time its own run finds, the narrow one
    does not."""
    src = sf.PressureSource("src", pressure=sf.Q_(1.1, "bar"))
    sim = sf.Simulation(scene(src, friction="laminar"), duration=0.05)
    variants = [{"tube.diameter": d} for d in (0.3e-3, 1.2e-3, 2e-3)]
    with pytest.warns(sf.ModelWarning, match="Reynolds") as caught:
        out = _run_batched(sim, variants, own_clocks=True)
    # the warning names the user's component, not its copy in the batch (v1/tube)
    assert all("CircularTube 'tube'" in str(w.message) for w in caught
               if "Reynolds" in str(w.message))
    assert out[0].stats["clocks"] == "own"
    for v, b in zip(variants, out):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            serial = sim.run(params=v)
        mine = [w for w in b.warnings if w.check == "tube_reynolds"]
        theirs = [w for w in serial.warnings if w.check == "tube_reynolds"]
        assert len(mine) == len(theirs)
        for a, s in zip(mine, theirs):
            assert a.component == "tube"
            assert a.message.startswith("CircularTube 'tube':")
            assert a.details["time"] in b.times
            assert a.details["time"] == pytest.approx(s.details["time"], rel=0.05, abs=1e-4)
            assert a.measured == pytest.approx(s.measured, rel=0.02)
    assert not [w for w in out[0].warnings if w.check == "tube_reynolds"]


def test_a_variant_past_choking_fails_on_its_own_and_the_others_go_on():
    # the mean-density law, which is refused past the choke
    sim = sf.Simulation(filling_tank(sf.PressureSource("src", pressure=sf.Q_(9, "bar"),
                                                       gauge=True), compressible="mean_density"),
                        duration=0.02)
    variants = [{"src.pressure": p} for p in (sf.Q_(0.2, "bar"), sf.Q_(9, "bar"),
                                             sf.Q_(0.3, "bar"))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        out = _run_batched(sim, variants, own_clocks=True)
        alone = sim.run(params=variants[1], raise_on_failure=False)
    assert [r.status for r in out] == ["success", "failed", "success"]
    assert out[1].message == alone.message and "chokes" in out[1].message
    assert out[0].stats["clocks"] == "own"


def _first_rise(res, label="out", by=1e3):
    """When the gauge pressure of ``label`` first passes ``by`` (linear between
    the points either side, not the first point past it: two runs' steps differ)."""
    p = res.get(label, "pressure") - P0
    if p.max() <= by:
        return np.nan
    return crossing_time(res.times, p, by, int(np.argmax(p > by)))


def test_snapping_valves_switch_on_their_own_clocks():
    """Opening pressure x tube diameter: each variant's valve snaps at its own
    time; each is located as its own run locates it (the steps its own run
    takes; one shared sequence restarted at every variant's snap: 178 steps
    against 37-80) and the downstream tank fills when its own run's does."""
    sim = sf.Simulation(snapping_valve_scene(), duration=0.2)
    variants = [{"valve.opening_pressure": p, "tube.diameter": d}
                for p in (1.2e4, 2e4, 2.4e4) for d in (0.8e-3, 1.3e-3)]
    out = _run(sim, variants)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        shared = _run_batched(sim, variants, own_clocks=False)
    for v, b in zip(variants, out):
        assert b.success and b.stats["clocks"] == "own"
        serial = sim.run(params=v)
        assert abs(b.stats["steps"] - serial.stats["steps"]) <= max(3, 0.2 * serial.stats["steps"])
        # each engine locates the snap within the tolerance: both within 0.6 % of
        # an rtol-1e-7 run's rise, at most 0.46 % apart (measured 2026-12-03)
        assert _first_rise(b) == pytest.approx(_first_rise(serial), rel=6e-3)
        np.testing.assert_allclose(b.get("out", "pressure")[-1], serial.get("out", "pressure")[-1],
                                   rtol=0, atol=1e-3 * 3e4)
    assert shared[0].stats["clocks"] == "shared"
    assert shared[0].stats["steps"] > 1.3 * max(b.stats["steps"] for b in out)
    assert shared[0].stats["steps"] > 3 * np.median([b.stats["steps"] for b in out])


@pytest.mark.parametrize("case", ["user", "fixed", "check valve"])
def test_scenes_it_does_not_cover_keep_the_shared_steps(case):
    if case == "check valve":
        # Newton's check of a check valve's pieces (CheckValve.regime) is the
        # one-network Newton's: a batch with one keeps the shared steps
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 3e4)
        s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
        s += sf.CheckValve("valve", sf.air, diameter=2e-3, cracking_pressure=1e4)
        s += sf.Container("tank", sf.air, volume=1e-5)
        s.connect("src", "tube")
        s.connect("tube", "valve")
        s.connect("valve", "tank")
        sim = sf.Simulation(s, duration=0.02)
        why = "has a piecewise law whose pieces Newton checks"
    elif case == "user":
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 1e4)
        s += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
        s += UserChamber("tank")
        s.connect("tube", "src")
        s.connect("tube", "tank")
        sim = sf.Simulation(s, duration=0.02)
        why = "not a library component"
    else:
        sim = sf.Simulation(scene(), duration=0.02, step=1e-3)
        why = "fixed steps"
    variants = [{"tube.diameter": d} for d in (1e-3, 1.5e-3)]
    assert why in clocks.reason_not(sim)
    out = _run(sim, variants)
    assert all(r.success for r in out)
    assert out[0].stats["clocks"] == "shared" and why in out[0].stats["shared_because"]


@pytest.mark.parametrize("thermal", ["adiabatic", "heat_transfer"])
def test_thermal_variants_keep_their_own_clocks(thermal):
    """Adiabatic tanks, and tanks whose wall's h A a free-convection correlation
    gives, frozen at each variant's own step start: each as its own run."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.3, "bar"))
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    extra = ({"heat_transfer_coefficient": sf.FreeConvection(), "area": 2.2e-3}
             if thermal == "heat_transfer" else {})
    s += sf.Container("tank", sf.air, 1e-5, **extra)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    # the steps alone (refine=1), compared at the serial run's steps
    sim = sf.Simulation(s, duration=0.2, thermal=thermal, refine=1)
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1e-3, 2e-3)]
    out = _run(sim, variants)
    for v, b in zip(variants, out):
        assert b.success and b.stats["clocks"] == "own"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            serial = sim.run(params=v)
        assert abs(b.stats["steps"] - serial.stats["steps"]) <= max(3, 0.3 * serial.stats["steps"])
        # within the tolerance of its own run (the batch's Newton refreshes its
        # factors at every pass, its own run keeps them: the iterates, and so
        # the steps, differ within the Newton tolerance; 2 mm, heat transfer:
        # 362 steps against 409, 67 Pa apart, each ~100 Pa from rtol 1e-8)
        for name in ("pressure", "temperature"):
            mine = np.interp(serial.times, b.times, b.get("tank", name))
            own = serial.get("tank", name)
            assert np.max(np.abs(mine - own)) <= sim.rtol * np.max(np.abs(own)), (v, name)


def test_small_sweeps_share_their_steps_unless_asked():
    """Below OWN_CLOCKS_MIN variants a batch shares one step sequence (cheaper
    there), and says so."""
    from softflow.solve import batched
    sim = sf.Simulation(scene(), duration=0.02)
    variants = [{"tube.diameter": d} for d in (1e-3, 1.5e-3)]
    assert len(variants) < batched.OWN_CLOCKS_MIN
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        out = _run_batched(sim, variants)
    assert out[0].stats["clocks"] == "shared"
    assert "fewer than" in out[0].stats["shared_because"]
    assert _run(sim, variants)[0].stats["clocks"] == "own"


def test_recorded_components_only_are_kept():
    """Simulation(record=[...]): each variant keeps the named components' columns
    only, with the values of a run that keeps all."""
    sim_all = sf.Simulation(scene(), duration=0.05)
    sim_rec = sf.Simulation(scene(), duration=0.05, record=["tank"])
    variants = [{"tube.diameter": d} for d in (0.6e-3, 1e-3, 2e-3)]
    full, part = _run(sim_all, variants), _run(sim_rec, variants)
    for a, b in zip(full, part):
        assert b.stats["clocks"] == "own"
        np.testing.assert_array_equal(a.times, b.times)
        np.testing.assert_array_equal(a.get("tank", "pressure"), b.get("tank", "pressure"))
        np.testing.assert_array_equal(a.integral("tank", "massflow"), b.integral("tank", "massflow"))
        with pytest.raises(KeyError):
            b.get("tube", "massflow_a")
    assert part[0]._result.X.shape[1] < full[0]._result.X.shape[1]


def test_newton_goes_on_to_its_full_stage_before_a_step_is_rejected(monkeypatch):
    """A variant whose chord iterations fail on fresh factors goes on with a
    fresh Jacobian at every iterate, as Newton.solve's full stage does, so its
    step is not cut where its own run's Newton converges with that stage at
    every step (that run has no Newton failure; by default BDF cuts steps
    longer than FULL_STAGE_STEPS x step_min instead); without that stage some
    steps are."""
    from softflow.solve import bdf
    monkeypatch.setattr(bdf, "FULL_STAGE_STEPS", math.inf)
    sim = sf.Simulation(filling_tank(sf.PressureSource("src", pressure=sf.Q_(1.5, "bar"))),
                        duration=0.05)
    variants = [{"tube.diameter": d} for d in np.linspace(1.2e-3, 2e-3, 8)]

    def newton_rejections():
        out = _run(sim, variants)
        assert all(r.success and r.stats["clocks"] == "own" for r in out)
        batch = out[0]._result.stats        # the batch's Newton counters
        return batch["rejected_steps"] - batch["error_test_failures"]

    serial = [sim.run(params=v).stats["newton_failures"] for v in variants]
    assert serial == [0] * len(variants)
    assert newton_rejections() == 0
    monkeypatch.setattr(clocks, "NEWTON_FULL_STAGE", 0)
    assert newton_rejections() > 0


def test_a_variant_whose_mode_chatters_fails_alone_and_says_so():
    """As BDF: a mass-flow source pushing into a snapping valve with no volume
    between them chatters; on their own clocks the variants fail after
    CHATTER_SWITCHES such steps (not at the step limit) and run alone, whose
    results name the valve."""
    from softflow.solve import bdf
    sim = sf.Simulation(chattering_valve_scene(), duration=0.5)
    out = _run(sim, [{"src.massflow": m} for m in (1e-5, 2e-5)])
    for r in out:
        assert r.status == "failed"
        assert "SnappingValve 'valve' switched its mode at each of the last " \
               f"{bdf.CHATTER_SWITCHES} steps" in r.message


def test_dense_blocks_by_planned_elimination_or_lapack_alike(monkeypatch):
    """The dense blocks are factored by one planned sparse elimination
    (blocklu); a variant whose multipliers leave threshold pivoting's bound is
    factored by LAPACK's inverse instead. With the bound at 0 every variant
    goes to LAPACK (after the replans allowed): the same steps, values within
    round-off. A snapping valve's blocks change their entries as it switches."""
    from softflow.solve import blocklu
    sim = sf.Simulation(snapping_valve_scene(), duration=0.2)
    variants = [{"valve.opening_pressure": p, "tube.diameter": d}
                for p in (1.2e4, 2.4e4) for d in (0.8e-3, 1.3e-3)]
    served = []
    real = clocks.VariantBDF._block_factor

    def spy(self, ids, start):
        out = real(self, ids, start)
        served.append((ids.size, out.size, self._replans))
        return out
    monkeypatch.setattr(clocks.VariantBDF, "_block_factor", spy)
    planned = _run(sim, variants)
    assert sum(s - f for s, f, _ in served) > 0.9 * sum(s for s, _, _ in served)
    served.clear()
    monkeypatch.setattr(blocklu, "PIVOT_THRESHOLD", np.inf)
    lapack = _run(sim, variants)
    spent = next(i for i, (_, _, r) in enumerate(served) if r == clocks.REPLANS_MAX)
    assert all(f == s for s, f, _ in served[spent:])    # all to LAPACK from there on
    for a, b in zip(planned, lapack):
        assert a.stats["steps"] == b.stats["steps"]
        np.testing.assert_allclose(a.get("out", "pressure"), b.get("out", "pressure"),
                                   rtol=1e-9, atol=1e-6)


def test_refine_keeps_the_shared_sequence():
    """refine= records points inside the one-network BDF's steps; the own-clock
    engine says so and the batch keeps one shared step sequence (each
    variant's result then has the refined points)."""
    sim = sf.Simulation(scene(), duration=0.05, refine=2)
    assert "refine" in clocks.reason_not(sim)
    out = _run(sim, [{"tube.diameter": d} for d in (1e-3, 2e-3)])
    for b in out:
        assert b.success and b.stats["clocks"] == "shared"
        assert len(b.times) == 2 * b.stats["steps"] + 1


def test_each_variants_newton_takes_the_damped_contraction_rate(monkeypatch):
    """The variants' own Newton judges its chord iterations on the damped rate
    of Newton.solve's (newton.CRDOWN, per variant, 1 on fresh factors): 64
    ISO 6358 fills, whose flows die out at the end, take more Newton passes
    with it (110 against 107 measured) and end where their own serial runs
    do."""
    s = sf.System()
    s += sf.PressureSource("supply", pressure=4e5)
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    sim = sf.Simulation(s, duration=1.0)
    variants = [{"valve.C": c} for c in np.geomspace(1e-8, 4e-8, 64)]

    def passes():
        out = _run_batched(sim, variants)
        assert out[0].stats["clocks"] == "own"
        return out, out[0]._result.stats["newton_iterations"]
    out, damped = passes()
    for k in (0, 21, 42, 63):
        serial = sim.run(params=variants[k])
        assert out[k].get("tank", "pressure")[-1] == pytest.approx(
            serial.get("tank", "pressure")[-1], abs=1e-3 * 3e5)
    monkeypatch.setattr(clocks, "CRDOWN", 0.0)
    assert passes()[1] < damped
