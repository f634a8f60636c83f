"""Batched variants (softflow.solve.batched) and the per-sub-network error test."""
import numpy as np
import pytest

import softflow as sf
from softflow.solve.batched import _run_batched, build_batch
from helpers import filling_tank, gauge_error, gauge_reference

P0 = sf.pressure_atmospheric


def scene(fluid=sf.air, source=None):
    return filling_tank(source, fluid)


def _reference(variant, duration):
    return gauge_reference(sf.Simulation(scene(), duration=duration, rtol=1e-9), variant)


def test_batch_is_one_copy_of_the_scene_per_variant():
    variants = [{"tube.diameter": d} for d in (0.8e-3, 1e-3, 1.6e-3)]
    batch = build_batch(scene(), variants, {"src", "tube", "tank"})
    assert len(batch) == 9 and len(batch.nodes()) == 6
    assert [batch.get(f"v{k}/tube").diameter for k in range(3)] == [0.8e-3, 1e-3, 1.6e-3]
    assert batch.get("v2/tank").fluid is batch.get("v0/tank").fluid


@pytest.mark.parametrize("stepping", [{}, {"step": 1e-3}], ids=["bdf", "fixed"])
def test_each_variant_meets_the_tolerance_of_its_own_serial_run(stepping):
    """Diameters 0.5-2 mm: time constants 250x apart, one shared step sequence."""
    sim = sf.Simulation(scene(), duration=0.1, **stepping)
    variants = [{"tube.diameter": d} for d in np.geomspace(0.5e-3, 2e-3, 12)]
    batched = _run_batched(sim, variants)
    for v, b in zip(variants, batched):
        assert b.success and b.stats["batched"]
        serial = sim.run(params=v)
        ref = _reference(v, 0.1)
        if stepping:      # the same fixed steps: the same numbers, up to Newton's
            # tolerance (1e-6 of the 1.3e5 Pa scale per solve, 0.33 Pa after 100 steps
            # measured), 1e-4 of the 3e4 Pa rise: far below the 1 ms steps' own error
            np.testing.assert_allclose(b.get("tank", "pressure"), serial.get("tank", "pressure"),
                                       rtol=0, atol=1e-4 * 3e4)
        else:             # each within (a small multiple of) what its own run achieves
            assert gauge_error(b, ref) <= 2 * max(gauge_error(serial, ref), 1e-3), v


def test_a_failing_variant_is_isolated_and_reported():
    """A mass flow source overfilling a table-level tank past the table's 20 MPa."""
    air = sf.air.with_level("table")
    src = sf.MassFlowSource("src", massflow=1e-4)
    sim = sf.Simulation(scene(air, source=src), duration=0.2)
    variants = [{"src.massflow": m} for m in (1e-4, 2e-2, 2e-4)]
    out = _run_batched(sim, variants)
    assert [r.status for r in out] == ["success", "failed", "success"]
    assert "tank" in out[1].message or "tube" in out[1].message
    ok = sim.run(params=variants[2])
    np.testing.assert_allclose(out[2].get("tank", "pressure")[-1],
                               ok.get("tank", "pressure")[-1], rtol=1e-3)


def test_a_joint_failure_splits_the_batch_instead_of_dropping_one_variant_at_a_time(
        monkeypatch):
    """24 check-valve variants (cracking pressure 0-57.5 kPa, shared steps):
    each starts alone at t = 0, but the batch's consistent start fails (one
    damping and one continuation for all the sub-networks), naming v5. v5
    alone runs through, so the failure was the joint solve's: the others run
    in two halves (3 batches built), not dropped one at a time as before
    (9 builds, of 24 down to 16 variants, each failing at t = 0)."""
    from softflow.curves.waveforms import PiecewiseConstant
    from softflow.solve import batched
    s = sf.System()
    s += sf.PressureSource("source", pressure=PiecewiseConstant([0.0, 0.5], [2e5, P0]))
    # the mean-density law: the scene whose joint start failed (pinned to that law)
    s += sf.CircularTube("tube", sf.air, length=0.6, diameter=2e-3, compressible="mean_density")
    # (and the valve's incompressible law, the scene's then)
    s += sf.CheckValve("valve", sf.air, diameter=20e-3, cracking_pressure=5e3,
                       gas_law="incompressible")
    s += sf.Container("tank", sf.air, volume=50e-6)
    s.connect("source", "tube")
    s.connect("tube", "valve")
    s.connect("valve", "tank")
    sim = sf.Simulation(s, duration=1.0)
    variants = [{"valve.cracking_pressure": c} for c in np.arange(24) * 2.5e3]
    sizes = []
    build = batched.build_batch
    monkeypatch.setattr(batched, "build_batch",
                        lambda system, vs, *a: sizes.append(len(vs)) or build(system, vs, *a))
    out = _run_batched(sim, variants, own_clocks=False)
    assert sizes[0] == 24 and len(sizes) == 3 and sorted(sizes[1:]) == [11, 12]
    assert all(r.success for r in out)
    alone = [k for k, r in enumerate(out) if not isinstance(r, batched.VariantResult)]
    assert alone == [5]
    for v, r in zip(variants, out):       # the valve holds the tank at source - crack
        tank = r.get("tank", "pressure")
        assert tank[np.searchsorted(r.times, 0.45)] == pytest.approx(
            2e5 - v["valve.cracking_pressure"], abs=1.5e3)
        assert np.ptp(tank[r.times > 0.6]) < 1.0


def test_subnetworks_are_held_to_their_own_scales():
    """Two independent scenes in one System, one with 100x smaller pressures
    and flows: an error of twice its tolerance in the small one fails the
    error test (it is neither averaged with the large one's zero error nor
    judged at the large one's scale)."""
    from softflow.solve.bdf import BDF
    from softflow.solve.newton import Stats

    def pair(s, prefix, diameter, dp):
        s += sf.PressureSource(f"{prefix}src", pressure=P0 + dp)
        s += sf.CircularTube(f"{prefix}tube", sf.air, 0.5, diameter)
        s += sf.Container(f"{prefix}tank", sf.air, 1e-5)
        s.connect(f"{prefix}src", f"{prefix}tube")
        s.connect(f"{prefix}tube", f"{prefix}tank")
    both = sf.System()
    pair(both, "a/", 2e-3, 3e4)
    pair(both, "b/", 0.3e-3, 3e2)
    sim = sf.Simulation(both, duration=1.0)
    asm = sim.asm
    x_block, s_block, count = asm.subnetworks()
    assert count == 2
    bdf = BDF(asm, None, Stats(), duration=1.0, rtol=1e-3, atol_states=1e-15,
              atol_unknowns=1e-15, step_min=1e-9, step_max=1.0)
    x = asm.x0.copy()
    for label, dp in (("a/", 3e4), ("b/", 3e2)):
        for comp in ("src", "tank"):
            g, i = asm.where[label + comp]
            x[g.col[i, 0]] = P0 + dp
    S = asm.S0.copy()
    w = bdf._weights(S, S, x)
    g, i = asm.where["b/tank"]
    b = x_block == x_block[g.col[i, 0]]
    pressure = np.array(asm.x_quantity) == "pressure"
    # the small scene's two pressures off by 2 rtol of its own 300 Pa (its flows,
    # zero here, and its tank's mass exact): RMS over its 6 unknowns and 1 state
    dx = np.where(b & pressure, 2 * 1e-3 * 3e2, 0.0)
    assert bdf._norm(np.zeros_like(S), w, dx) == pytest.approx(np.sqrt(8 / 7), rel=1e-6)


def test_prepared_components_are_the_constructors_own():
    """The batched engine checks each variant once and builds its batch from the
    components that check rebuilt, the scene's Quantity arguments taken as SI
    numbers once: the same numbers as a constructor given the Quantities."""
    from softflow.solve.batched import prepare

    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.3, "bar"))
    s += sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"), diameter=sf.Q_(1, "mm"))
    s += sf.Container("tank", sf.air, volume=sf.Q_(10, "mL"))
    s.connect("src", "tube")
    s.connect("tube", "tank")
    sim = sf.Simulation(s, duration=0.01)
    variants = [{"tube.diameter": sf.Q_(d, "mm")} for d in (0.8, 1.2)]
    prepared = prepare(sim, variants)
    batch = build_batch(sim.system, variants, {"src", "tube", "tank"}, prepared.built)
    for k, d in enumerate((0.8, 1.2)):
        mine = batch.get(f"v{k}/tube")
        theirs = sf.CircularTube("tube", sf.air, length=sf.Q_(30, "cm"),
                                 diameter=sf.Q_(d, "mm"))
        floats = {key: v for key, v in vars(theirs).items() if isinstance(v, float)}
        assert floats and all(vars(mine)[key] == pytest.approx(v, rel=1e-15)
                              for key, v in floats.items())
        # the variant's own copy of the unchanged components, with its own variables
        assert batch.get(f"v{k}/tank").volume == pytest.approx(1e-5, rel=1e-15)
        assert batch.get(f"v{k}/tank").terminals[0].variables[0] is not \
            sim.system.get("tank").terminals[0].variables[0]
    with pytest.raises(ValueError, match="diameter") as info:
        prepare(sim, variants + [{"tube.diameter": -1e-3}])
    assert info.value.variant_index == 2


def test_sweep_reads_each_variants_outputs_as_its_own_result_reads_them():
    """sweep(engine='batched') samples every variant's outputs (unknowns, states,
    a terminal's variable, a derived output) at the sweep's times bitwise as
    np.interp of its own result's get(), NaN past the end of a failed run
    (read from the result that variant's own run left)."""
    import warnings
    from softflow.solve.batched import sample
    air = sf.air.with_level("table")
    sim = sf.Simulation(scene(air, source=sf.MassFlowSource("src", massflow=1e-4)),
                        duration=0.2)
    variants = [{"src.massflow": m} for m in (1e-4, 2e-2, 2e-4, 1.5e-4)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        out = _run_batched(sim, variants, own_clocks=True)
    assert [r.status for r in out] == ["success", "failed", "success", "success"]
    outputs = ["tank.pressure", "tank.mass", "tank.volume", "tube.massflow_a", "src.massflow"]
    times = np.concatenate([np.linspace(0.0, 0.2, 41), [0.1234567, 0.25]])
    got = sample(out, outputs, times)
    for r, values in zip(out, got):
        t = r.times
        reached = times <= t[-1] * (1 + 1e-12) if r.status != "success" else np.ones(len(times), bool)
        assert (~reached).any() == (r.status != "success")
        for row, column in zip(values, outputs):
            label, _, name = column.rpartition(".")
            np.testing.assert_array_equal(row[reached], np.interp(times[reached], t,
                                                                  r.get(label, name)))
            assert np.isnan(row[~reached]).all()


def test_a_check_found_in_several_batches_is_issued_once_for_the_sweep():
    """Six tube diameters in batches of three: the fast fill's thermal check
    fires in five variants across both batches, and is issued once, counting
    them all (each batch issued its own, with its own count, before)."""
    import warnings
    sim = sf.Simulation(scene(), duration=0.1)
    variants = [{"tube.diameter": d} for d in np.geomspace(1.6e-3, 3e-3, 6)]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = _run_batched(sim, variants, batch_size=3, own_clocks=False)
    thermal = [str(w.message) for w in caught if "time scale" in str(w.message)]
    assert len(thermal) == 1
    assert "4 more of the 6 variants" in thermal[0]
    assert sum(any(r.check == "thermal_time_scale" for r in o.warnings) for o in out) == 5
