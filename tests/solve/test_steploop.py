"""The BDF's usual steps in the compiled loop (softflow.solve.steploop,
softflow.laws.stepper): the same run as the BDF's steps in Python, to the
round-off of the linear algebra and within the run's tolerance; its dense
linear algebra against LAPACK; where it serves and where it does not."""
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow import paper_scenes as ps
from softflow.laws import stepper
from softflow.solve import bdf, settings, steploop
from helpers import check_valve_pulses, filling_tank, rc_circuit

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scenes import chain  # noqa: E402


def _spied(monkeypatch):
    """A list that collects the steps each call of the compiled loop took."""
    taken = []
    for cls in (steploop.CompiledSteps, steploop.FixedSteps):
        def spy(self, *args, run=cls.run):
            out = run(self, *args)
            taken.append(out[4])
            return out
        monkeypatch.setattr(cls, "run", spy)
    return taken


def _bound_spy(monkeypatch):
    """A list that collects each compiled loop bound to a run (its _Bound)."""
    bound = []
    init = steploop._Bound.__init__

    def spy(self, *args):
        init(self, *args)
        bound.append(self)
    monkeypatch.setattr(steploop._Bound, "__init__", spy)
    return bound


def _both(build, duration, monkeypatch, **options):
    """(Python's run, the compiled loop's run, the compiled loop's steps)."""
    taken = _spied(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        monkeypatch.setattr(settings, "COMPILED_STEPS", False)
        py = sf.Simulation(build(), duration=duration, refine=1, **options).run()
        assert not taken
        monkeypatch.setattr(settings, "COMPILED_STEPS", True)
        comp = sf.Simulation(build(), duration=duration, refine=1, **options).run()
    return py, comp, sum(taken)


SCENES = {
    "fig3:peak-valley": (lambda: ps.fig3("peak-valley"), ps.duration(3)),
    "fig3:hysteretic": (lambda: ps.fig3("hysteretic"), ps.duration(3)),
    "fig4:snapping": (lambda: ps.fig4("snapping"), ps.duration(4)),
    "fig5:air": (lambda: ps.fig5(sf.air), ps.duration(5)),
    "fig5:air adiabatic": (lambda: ps.fig5(sf.air), ps.duration(5)),
    "fig5:water": (lambda: ps.fig5(sf.water), ps.duration(5)),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_the_compiled_loop_takes_the_bdfs_steps(name, monkeypatch):
    """Paper scenes (actuators, hysteresis, a snapping valve, air and an
    accumulator; the full-physics Fig. 5 with air is thermal): the compiled
    loop takes most steps, the run takes the same steps as in Python (the
    same count; times that drift apart only by round-off through the step
    size controller) and its values, read at the Python run's times, agree
    within a few times the tolerance (rtol 1e-3) of each output's range
    (flows: of the largest flow): the two runs are two solutions at that
    tolerance, whose round-off differences the step size control and the
    actuators' snaps carry on (Fig. 5 with air, adiabatic: 1.1e-3 of the
    pump's pressure range, inside a snap's 3 kPa in 0.2 ms)."""
    build, duration = SCENES[name]
    options = {"thermal": "adiabatic"} if "adiabatic" in name else {}
    py, comp, taken = _both(build, duration, monkeypatch, **options)
    assert py.success and comp.success
    assert taken >= 0.5 * comp.stats["steps"]
    assert abs(comp.stats["steps"] - py.stats["steps"]) <= 0.02 * py.stats["steps"]
    a, b = py.to_dict(), comp.to_dict()
    flows = max(np.max(np.abs(v)) for k, v in a.items() if "massflow" in k)
    for key, va in a.items():
        if key == "time" or key.endswith(("branch", "mode", "open")):
            continue
        scale = flows if "massflow" in key else max(np.ptp(va), 1e-300)
        vb = np.interp(a["time"], b["time"], b[key])
        assert np.max(np.abs(vb - va)) <= 3e-3 * scale, key


def test_the_same_steps_as_the_python_loop_on_a_fill(monkeypatch):
    """A tank filled through a tube from a square wave (a restart at each
    edge): the same accepted steps, the same values to 1e-9 of their range."""
    square = sf.waveforms.Square(sf.Q_(0.3, "bar"), sf.Q_(0.0, "bar"), 250.0)
    py, comp, taken = _both(
        lambda: filling_tank(sf.PressureSource("src", pressure=square, gauge=True)), 0.02,
        monkeypatch, rtol=1e-5)
    assert taken > 0.5 * comp.stats["steps"]
    assert comp.stats["steps"] == py.stats["steps"]
    np.testing.assert_allclose(comp.times, py.times, rtol=1e-9, atol=0)
    p0 = py.get("tank", "pressure")
    np.testing.assert_allclose(comp.get("tank", "pressure"), p0, rtol=0,
                               atol=1e-9 * np.ptp(p0))


def test_it_does_not_serve_what_it_does_not_cover(monkeypatch):
    """Sensitivities, and a source given as a Python function where
    settings.COMPILED_USER is off, take every step in Python (fixed steps
    and check valves are served: the tests below; a Python function is
    called back from the loop by default)."""
    taken = _spied(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        s = rc_circuit()
        sf.Simulation(s, duration=0.2).run()
        assert taken                      # (served: the control case)
        taken.clear()
        sf.Simulation(rc_circuit(), duration=0.2).run(sensitivities=["tube.diameter"])
        ramp = rc_circuit(source=lambda t: 1.1e5 + 1e4 * min(t, 0.01) / 0.01)
        sf.Simulation(ramp, duration=0.2).run()
        assert taken
        taken.clear()
        monkeypatch.setattr(settings, "COMPILED_USER", False)
        sf.Simulation(ramp, duration=0.2).run()
    assert not taken


def test_check_valves_in_the_compiled_loop(monkeypatch):
    """A check valve that opens and shuts at every pulse: the compiled loop
    takes the steps between, hands back the steps across its kinks and the
    solves that land on another piece of its law, and the run is the Python
    loop's within the tolerance."""
    py, comp, taken = _both(check_valve_pulses, 2.0, monkeypatch)
    assert py.success and comp.success
    assert taken >= 0.3 * comp.stats["steps"]
    assert abs(comp.stats["steps"] - py.stats["steps"]) <= 0.05 * py.stats["steps"]
    for label in ("tank", "cv"):
        a = py.get(label, "pressure", *(("b",) if label == "cv" else ()))
        b = np.interp(py.times, comp.times,
                      comp.get(label, "pressure", *(("b",) if label == "cv" else ())))
        assert np.max(np.abs(b - a)) <= 3e-3 * np.ptp(a)


def test_switching_it_off_runs_the_bdf_in_python(monkeypatch):
    taken = _spied(monkeypatch)
    monkeypatch.setattr(settings, "COMPILED_STEPS", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        assert sf.Simulation(rc_circuit(), duration=0.2).run().success
    assert not taken


# -- the compiled linear algebra and difference tables ---------------------------------------
def test_the_lu_solves_as_lapack():
    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 14, 40):
        J = rng.normal(size=(n, n)) * 10.0 ** rng.integers(-6, 6, size=(n, 1))
        b = rng.normal(size=n)
        raw = J.ravel().copy()
        flat = np.arange(n * n, dtype=np.int64)
        Jd, LU = np.zeros((n, n)), np.zeros((n, n))
        piv, ir, ic = np.zeros(n, dtype=np.int64), np.ones(n), np.ones(n)
        assert stepper.factor(raw, flat, Jd, LU, piv, ir, ic, 1e-14) == 0
        out = np.empty(n)
        stepper.lu_solve(LU, piv, ir, ic, b, out)
        np.testing.assert_allclose(out, np.linalg.solve(J, b), rtol=1e-8)
        np.testing.assert_array_equal(Jd, J)


def _full_lu(A):
    """The LU of ``lu_factor`` without skipping anything: partial pivoting,
    each multiplier times the whole pivot row past the diagonal (one product
    and one difference an entry, as the compiled loops compute them)."""
    A = A.copy()
    n = A.shape[0]
    piv = np.zeros(n, dtype=np.int64)
    for j in range(n):
        p = j + int(np.argmax(np.abs(A[j:, j])))
        piv[j] = p
        A[[j, p]] = A[[p, j]]
        if A[j, j] != 0.0:
            A[j + 1:, j] *= 1.0 / A[j, j]
        A[j + 1:, j + 1:] -= np.multiply.outer(A[j + 1:, j], A[j, j + 1:])
    return A, piv


def test_the_lu_keeps_to_the_factors_profile_with_the_same_numbers():
    """The LU skips the exact zeros past each pivot row's last nonzero, and
    with room for the factors' profile (3 n pivots) its solves keep to it (a
    chain's banded Jacobian: most of the work): the factors and solutions
    are those of the full loops, bit for bit, and the profile of factors
    made elsewhere (LAPACK's, which the step loop adopts) is the one the
    factorization found."""
    from scipy.linalg.lapack import dgetrf
    rng = np.random.default_rng(11)
    for trial in range(40):
        n = int(rng.integers(1, 40))
        kl, ku = int(rng.integers(0, 6)), int(rng.integers(0, 6))
        A = np.zeros((n, n))
        for i in range(n):
            for j in range(max(0, i - kl), min(n, i + ku + 1)):
                if rng.random() < 0.7 or i == j:
                    A[i, j] = rng.normal()
        if trial % 4 == 0:
            A += (rng.random((n, n)) < 0.1) * rng.normal(size=(n, n))   # off the band
        b = rng.normal(size=n)
        full, piv_full = _full_lu(A)
        mine, piv = A.copy(), np.zeros(3 * n, dtype=np.int64)
        stepper.lu_factor(mine, piv)
        np.testing.assert_array_equal(mine, full)
        np.testing.assert_array_equal(piv[:n], piv_full)
        plain, piv_plain = A.copy(), np.zeros(n, dtype=np.int64)    # (no room: no profile)
        stepper.lu_factor(plain, piv_plain)
        np.testing.assert_array_equal(plain, full)
        assert (piv[n:2 * n] <= np.arange(n)).all() and (piv[2 * n:] > np.arange(n)).all()
        ir, ic = rng.uniform(0.5, 2.0, n), rng.uniform(0.5, 2.0, n)
        x_full, x = np.empty(n), np.empty(n)
        stepper.lu_solve(full, piv_full, ir, ic, b, x_full)
        stepper.lu_solve(mine, piv, ir, ic, b, x)
        np.testing.assert_array_equal(x, x_full)
        if np.linalg.cond(A) < 1e10:
            np.testing.assert_allclose(x, ic * np.linalg.solve(A, ir * b), rtol=1e-7)
        got = np.zeros(3 * n, dtype=np.int64)
        stepper.lu_profile(mine, got)
        np.testing.assert_array_equal(got[n:], piv[n:])
        lu, p_lapack, _ = dgetrf(A)
        np.testing.assert_array_equal(p_lapack, piv[:n])
        stepper.lu_profile(np.ascontiguousarray(lu), got)
        np.testing.assert_array_equal(got[n:], piv[n:])
        # outside the profile every entry of the factors is an exact zero
        for i in range(n):
            assert not mine[i, :piv[n + i]].any() and not mine[i, piv[2 * n + i]:].any()


def test_the_lu_equilibrates_where_units_make_pivots_small_and_refuses_the_singular():
    # a row 1e-11 against 1: singular by its pivots, not after scaling
    J = np.array([[2e-11, 1e-11], [1.0, -1.0]])
    raw, flat = J.ravel().copy(), np.arange(4, dtype=np.int64)
    Jd, LU = np.zeros((2, 2)), np.zeros((2, 2))
    piv, ir, ic = np.zeros(2, dtype=np.int64), np.ones(2), np.ones(2)
    assert stepper.factor(raw, flat, Jd, LU, piv, ir, ic, 1e-10) == 0
    assert not (ir == 1.0).all()
    out = np.empty(2)
    stepper.lu_solve(LU, piv, ir, ic, np.array([1e-11, 3.0]), out)
    np.testing.assert_allclose(J @ out, [1e-11, 3.0], rtol=1e-12)
    singular = np.array([1.0, 2.0, 2.0, 4.0])
    assert stepper.factor(singular, flat, Jd, LU, piv, ir, ic, 1e-14) == 2
    assert stepper.factor(np.array([1.0, np.nan, 0.0, 1.0]), flat, Jd, LU, piv, ir, ic,
                          1e-14) == 1
    # entries of one place are summed
    assert stepper.factor(np.array([1.0, 2.0, 3.0]), np.array([0, 0, 3], dtype=np.int64),
                          Jd, LU, piv, ir, ic, 1e-14) == 0
    np.testing.assert_array_equal(Jd, [[3.0, 0.0], [0.0, 3.0]])


def _band_system(rng, n, kl, ku, scale_rows=False):
    """A random matrix of band (kl, ku), its raw entries and their places in
    band storage (stepper.band_factor), and a right-hand side."""
    A = np.zeros((n, n))
    for i in range(n):
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            if rng.random() < 0.8 or i == j:
                A[i, j] = rng.normal()
    if scale_rows:                # units far apart: pivots small before scaling
        A *= 10.0 ** rng.integers(-12, 3, size=(n, 1))
    w = 2 * kl + ku + 1
    i, j = np.nonzero(A)
    return A, A[i, j].copy(), (i * w + (j - i + kl)).astype(np.int64), w, rng.normal(size=n)


@pytest.mark.parametrize("scale_rows", [False, True], ids=["plain", "equilibrated"])
def test_the_band_lu_solves_as_lapack(scale_rows):
    """The banded LU (LAPACK's gbtrf layout: partial pivoting within the
    band, the fill of its swaps in kl more columns) solves as a dense solve
    does, with rows scaled 1e-12 .. 1e2 too (equilibrated where its pivots
    fail the test), and refuses a singular matrix."""
    rng = np.random.default_rng(5)
    equilibrated = 0
    for trial in range(60):
        n, kl, ku = int(rng.integers(1, 40)), int(rng.integers(0, 5)), int(rng.integers(0, 5))
        A, raw, flat, w, b = _band_system(rng, n, kl, ku, scale_rows)
        if np.linalg.cond(A / np.abs(A).max(axis=1, keepdims=True)) > 1e8:
            continue
        J, LU = np.zeros((n, w)), np.zeros((n, w))
        piv, ir, ic = np.zeros(n, dtype=np.int64), np.ones(n), np.ones(n)
        assert stepper.band_factor(raw, flat, J, LU, piv, ir, ic, kl, 1e-14) == 0
        equilibrated += not (ir == 1.0).all()
        out = np.empty(n)
        stepper.band_solve(LU, piv, ir, ic, kl, b, out)
        want = np.linalg.solve(A, b)
        np.testing.assert_allclose(out, want, rtol=0, atol=1e-6 * np.abs(want).max())
    assert equilibrated > (10 if scale_rows else -1)
    J, LU = np.zeros((2, 4)), np.zeros((2, 4))
    piv, ir, ic = np.zeros(2, dtype=np.int64), np.ones(2), np.ones(2)
    singular = np.array([1.0, 2.0, 2.0, 4.0])       # [[1, 2], [2, 4]], kl = ku = 1
    flat = np.array([1, 2, 4, 5], dtype=np.int64)
    assert stepper.band_factor(singular, flat, J, LU, piv, ir, ic, 1, 1e-14) == 2


def test_the_solves_store_subnormal_values_as_zero():
    """Both solves store values below the smallest normal float as 0 (the
    far tail of a step response down a long chain, whose subnormal
    arithmetic cost five times the solve's own), and carry a NaN through."""
    tiny = np.finfo(float).tiny
    A = np.array([[2.0, 0.0], [1.0, 4.0]])
    raw, flat = A.ravel().copy(), np.arange(4, dtype=np.int64)
    J, LU = np.zeros((2, 2)), np.zeros((2, 2))
    piv, ir, ic = np.zeros(2, dtype=np.int64), np.ones(2), np.ones(2)
    assert stepper.factor(raw, flat, J, LU, piv, ir, ic, 1e-14) == 0
    out = np.empty(2)
    for b, want in (([tiny * 0.25, 1.0], [0.0, 0.25]), ([2.0, tiny], [1.0, -0.25]),
                    ([np.nan, 1.0], [np.nan, np.nan])):
        stepper.lu_solve(LU, piv, ir, ic, np.array(b), out)
        np.testing.assert_array_equal(out, want)
    # the band layout of the same matrix (kl = 1, ku = 0: width 3)
    bflat = np.array([1, 3, 4], dtype=np.int64)
    Jb, LUb = np.zeros((2, 3)), np.zeros((2, 3))
    assert stepper.band_factor(np.array([2.0, 1.0, 4.0]), bflat, Jb, LUb, piv, ir, ic, 1,
                               1e-14) == 0
    for b, want in (([tiny * 0.25, 1.0], [0.0, 0.25]), ([np.nan, 1.0], [np.nan, np.nan])):
        stepper.band_solve(LUb, piv, ir, ic, 1, np.array(b), out)
        np.testing.assert_array_equal(out, want)


def test_a_chain_is_ordered_as_a_narrow_band():
    """A chain of tubes and tanks, its unknowns grouped by kind in the
    assembly (a band as wide as the network), is ordered as a band a few
    unknowns wide whatever its length; the order pairs each equation with
    an unknown it has a slope in."""
    for N in (40, 300):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            sim = sf.Simulation(chain(N), duration=0.1)
        asm = sim.asm
        assert np.max(np.abs(asm.pattern_rows - asm.pattern_cols)) > N
        layout = steploop.band_layout(asm)
        assert layout is not None and max(layout.kl, layout.ku) <= 4
        rows, unknowns, place = layout.order
        assert sorted(rows) == list(range(asm.n)) == sorted(unknowns)
        np.testing.assert_array_equal(place[rows], np.arange(asm.n))
        J = np.zeros((asm.n, asm.n))
        J[asm.pattern_rows, asm.pattern_cols] = 1.0
        assert (J[rows, unknowns] == 1.0).all()


@pytest.mark.parametrize("sparse", [True, False], ids=["sparse-lu", "banded-lu"])
def test_a_network_too_large_for_dense_factors_runs_in_the_compiled_loop(monkeypatch, sparse):
    """A chain of 60 tubes and tanks (242 unknowns: the Python Newton's factors
    are condensed) behind a square wave (a restart at each edge) and a check
    valve at its end (steps across its kinks handed back, taken by the
    Python loop on its own factors): the compiled loop takes most steps on
    its sparse LU (or, with COMPILED_SPARSE off, its banded LU), the same
    steps as the Python loop, the same pressures to 1e-6 of their range
    (round-off: rtol 1e-5)."""
    monkeypatch.setattr(settings, "COMPILED_SPARSE", sparse)
    bound = _bound_spy(monkeypatch)

    def build():
        s = chain(60, p_source=sf.waveforms.Square(sf.pressure_atmospheric + 3e4,
                                                   sf.pressure_atmospheric, 20.0))
        s += sf.CheckValve("cv", sf.air, diameter=1e-3, cracking_pressure=2e3)
        s += sf.Container("end", sf.air, volume=1e-5)
        s.connect(("cv", "a"), ("cont59", "a"))
        s.connect(("cv", "b"), ("end", "a"))
        return s
    py, comp, taken = _both(build, 0.1, monkeypatch, rtol=1e-5)
    assert py.success and comp.success
    assert py.stats["linear_solver"] != "dense"
    assert len(bound) == 1
    assert (bound[0].sparse is not None, bound[0].band is not None) == (sparse, not sparse)
    assert taken >= 0.5 * comp.stats["steps"]
    assert comp.stats["steps"] == py.stats["steps"]
    for key, va in py.to_dict().items():
        if key.endswith("pressure"):
            vb = np.interp(py.times, comp.times, comp.to_dict()[key])
            assert np.max(np.abs(vb - va)) <= 1e-6 * max(np.ptp(va), 1.0), key


def test_a_narrow_band_is_factored_as_a_band_below_the_dense_limit(monkeypatch):
    """A chain of 31 tubes (126 unknowns: dense factors in the Python Newton)
    has a band 11 wide, under a quarter of the matrix: the loop factors it
    as a band of its own (not shared with the Python Newton), a chain of 8
    (34 unknowns) densely; either run takes the Python loop's steps, the
    same pressures to 1e-6 of their range."""
    bound = _bound_spy(monkeypatch)
    for N, banded in ((31, True), (8, False)):
        bound.clear()
        py, comp, taken = _both(lambda: chain(N), 0.1, monkeypatch, rtol=1e-5)
        assert py.stats["linear_solver"] == "dense"
        assert [b.band is not None for b in bound] == [banded]
        assert taken == comp.stats["steps"] == py.stats["steps"]
        for key, va in py.to_dict().items():
            if key.endswith("pressure"):
                vb = np.interp(py.times, comp.times, comp.to_dict()[key])
                assert np.max(np.abs(vb - va)) <= 1e-6 * max(np.ptp(va), 1.0), key


def _hub(branches):
    """A pressure source stepping up into a junction (no volume) that feeds
    ``branches`` tubes, each into an accumulator and on through a second
    tube into a container: ~6 unknowns a branch, in no narrow band (the
    junction's balance meets every branch's first flow)."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.waveforms.Step(0.002, sf.Q_(1.0, "bar"),
                                                              sf.Q_(1.4, "bar")))
    s += sf.CircularTube("feed", sf.water, 0.3, 2e-3)
    s.connect("src", "feed")
    hub = [("feed", "b")]
    for k in range(branches):
        d = 0.6e-3 + 0.4e-3 * (k % 5) / 4
        s += sf.CircularTube(f"a{k}", sf.water, 0.2 + 0.01 * k, d)
        s += sf.LinearAccumulator(f"acc{k}", sf.water, volume=1e-6,
                                  compliance=(1 + k % 3) * 1e-11)
        s += sf.CircularTube(f"b{k}", sf.water, 0.3, 0.8e-3)
        s += sf.Container(f"c{k}", sf.water, 2e-6)
        hub.append((f"a{k}", "a"))
        s.connect((f"a{k}", "b"), (f"acc{k}", "a"), (f"b{k}", "a"))
        s.connect((f"b{k}", "b"), (f"c{k}", "a"))
    s.connect(*hub)
    return s


def test_a_network_without_a_narrow_band_is_factored_sparse_in_the_loop(monkeypatch):
    """A junction feeding 40 branches (325 unknowns: SuperLU's in the Python
    Newton; a band far wider than COMPILED_BAND_MAX): the loop binds with
    its own sparse LU (softflow.laws.sparselu), refactors on its row order
    nearly always, and takes the Python loop's steps, the same pressures
    to 1e-6 of their range; with the sparse LU off, the Python loop takes
    the run."""
    bound = _bound_spy(monkeypatch)
    py, comp, taken = _both(lambda: _hub(40), 0.02, monkeypatch, rtol=1e-5)
    assert py.stats["linear_solver"] != "dense"
    assert steploop.band_layout(sf.Simulation(_hub(40), duration=0.02).asm) is None
    assert len(bound) == 1 and bound[0].sparse is not None and bound[0].band is None
    state = bound[0].lin[16][11]
    assert state[3] > 10 * state[2] > 0         # refactorizations, new row orders
    assert taken >= 0.9 * comp.stats["steps"]
    assert comp.stats["steps"] == py.stats["steps"]
    assert comp.stats["rejected_steps"] == py.stats["rejected_steps"]
    for key, va in py.to_dict().items():
        if key.endswith("pressure"):
            vb = np.interp(py.times, comp.times, comp.to_dict()[key])
            assert np.max(np.abs(vb - va)) <= 1e-6 * max(np.ptp(va), 1.0), key
    bound.clear()
    monkeypatch.setattr(settings, "COMPILED_SPARSE", False)
    taken_off = _spied(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        off = sf.Simulation(_hub(40), duration=0.02, refine=1, rtol=1e-5).run()
    assert not bound and not taken_off and off.stats["steps"] == py.stats["steps"]


def test_fixed_steps_on_a_wide_band_take_the_loops_sparse_lu(monkeypatch):
    """Backward Euler at 1 ms on the 40-branch junction: the fixed-step loop
    binds with the sparse LU and gives the Python loop's pressures (to 1e-6
    of their range)."""
    bound = _bound_spy(monkeypatch)
    taken = _spied(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        monkeypatch.setattr(settings, "COMPILED_STEPS", False)
        py = sf.Simulation(_hub(40), duration=0.02, step=1e-3).run()
        monkeypatch.setattr(settings, "COMPILED_STEPS", True)
        comp = sf.Simulation(_hub(40), duration=0.02, step=1e-3).run()
    assert len(bound) == 1 and bound[0].sparse is not None
    assert sum(taken) >= 0.9 * comp.stats["steps"] and comp.stats["steps"] == py.stats["steps"]
    for key, va in py.to_dict().items():
        if key.endswith("pressure"):
            assert np.max(np.abs(comp.to_dict()[key] - va)) <= 1e-6 * max(np.ptp(va), 1.0), key


@pytest.mark.parametrize("k", range(1, bdf.MAX_ORDER + 1))
def test_the_rescaled_table_is_the_bdfs(k):
    rng = np.random.default_rng(k)
    for factor in (0.2, 0.9, 1.3, 2.0):
        D = rng.normal(size=(bdf.MAX_ORDER + 3, 6))
        ref = D.copy()
        M = bdf._rescale_matrix(k, factor)[1:, 1:]
        ref[1:k + 1] = M @ ref[1:k + 1]
        stepper._rescale(D, k, factor)
        np.testing.assert_allclose(D, ref, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("name", ["fig3:hysteretic", "fig5:air", "fig5:water"])
def test_fixed_steps_in_the_compiled_loop_are_backward_eulers(name, monkeypatch):
    """Backward Euler at a fixed 1 ms (the FONS paper's scheme): the compiled
    loop takes the grid's steps, the same steps as the Python loop, values
    within 1e-10 of each output's scale (pressures: their magnitude; flows:
    the largest flow)."""
    build, duration = SCENES[name]
    py, comp, taken = _both(build, duration, monkeypatch, step=1e-3)
    assert py.success and comp.success and taken >= 0.9 * comp.stats["steps"]
    np.testing.assert_array_equal(comp.times, py.times)
    a, b = py.to_dict(), comp.to_dict()
    flows = max(np.max(np.abs(v)) for k, v in a.items() if "massflow" in k)
    for key, va in a.items():
        scale = flows if "massflow" in key else max(np.max(np.abs(va)), 1e-300)
        assert np.max(np.abs(b[key] - va)) <= 1e-10 * scale, key


def test_a_progress_bar_moves_while_the_compiled_loop_runs(monkeypatch):
    """The loop hands back at each look of the bar at the clock
    (Progress.steps_to_look): the bar looks after the same steps as where
    every step is the Python loop's (here at every step: no wall time
    between looks)."""
    from softflow.solve import progress
    from softflow.solve.progress import Progress
    monkeypatch.setattr(progress, "DELAY", 1e9)       # (the bar itself never opens)
    monkeypatch.setattr(progress, "CHECK_INTERVAL", 0.0)
    seen = []
    look = Progress._look

    def spy(self, t):
        seen.append(self.steps)
        return look(self, t)
    monkeypatch.setattr(Progress, "_look", spy)
    looks = {}
    for compiled in (False, True):
        monkeypatch.setattr(settings, "COMPILED_STEPS", compiled)
        seen.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            sf.Simulation(rc_circuit(), duration=0.3).run(progress=True)
        looks[compiled] = list(seen)
    assert len(looks[True]) >= 3 and looks[True] == looks[False]


def test_mode_switches_are_located_in_the_compiled_loop(monkeypatch):
    """Fig. 4's snapping valve and Fig. 3's hysteretic actuator: the switches
    are located (the step shortened to end just past each crossing) and the
    method restarted in the compiled loop, which hands back none of them
    nor their restarts (only the run's end); the same steps as the BDF in
    Python."""
    exits = []
    for cls in (steploop.CompiledSteps,):
        def spy(self, *args, run=cls.run):
            out = run(self, *args)
            exits.append(stepper.EXITS[out[0]])
            return out
        monkeypatch.setattr(cls, "run", spy)
    for name in ("fig4:snapping", "fig3:hysteretic"):
        build, duration = SCENES[name]
        exits.clear()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            monkeypatch.setattr(settings, "COMPILED_STEPS", False)
            py = sf.Simulation(build(), duration=duration, refine=1).run()
            monkeypatch.setattr(settings, "COMPILED_STEPS", True)
            comp = sf.Simulation(build(), duration=duration, refine=1).run()
        assert "switch" not in exits and exits[-1] == "done"
        # the restarts after the switches too (the snapping valve's first
        # probes need Newton's damped stage, taken in the loop)
        assert "restart" not in exits
        assert comp.stats["steps"] == py.stats["steps"]
        assert comp.stats["rejected_steps"] == py.stats["rejected_steps"]


def _exits(monkeypatch):
    """A list that collects why each call of the compiled BDF loop handed back."""
    exits = []

    def spy(self, *args, run=steploop.CompiledSteps.run):
        out = run(self, *args)
        exits.append(stepper.EXITS[out[0]])
        return out
    monkeypatch.setattr(steploop.CompiledSteps, "run", spy)
    return exits


@pytest.mark.parametrize("name", ["fig5:air", "fig3:peak-valley", "fig3:hysteretic"])
def test_failed_solves_are_rejected_in_the_compiled_loop(name, monkeypatch):
    """Newton's failures on the BDF's steps (chord iterations diverging, or
    contracting too slowly and then an undamped full Newton that would need
    damping) are rejected in the compiled loop as BDF._newton_failed rejects
    them (a quarter of the step), and the undamped full stage that follows
    slow chord iterations is the loop's too: the same steps, the same
    rejections by cause and the same failed solves as the BDF in Python;
    the loop hands back none (the flow sources' nodes that the culprit
    finder looks into are found at the first failure, and that step tried
    again in the loop)."""
    from softflow.solve import progress as progress_mod
    causes = []

    def rejected(self, t, h, why, detail=None):
        causes.append(why)
    monkeypatch.setattr(progress_mod.Progress, "rejected", rejected)
    monkeypatch.setattr(progress_mod._Silent, "rejected", rejected)
    build, duration = SCENES[name]
    exits = _exits(monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        monkeypatch.setattr(settings, "COMPILED_STEPS", False)
        py = sf.Simulation(build(), duration=duration, refine=1).run()
        py_causes = sorted(causes)
        causes.clear()
        monkeypatch.setattr(settings, "COMPILED_STEPS", True)
        comp = sf.Simulation(build(), duration=duration, refine=1).run()
    assert py.success and comp.success
    assert py_causes.count("newton") >= 5
    assert sorted(causes) == py_causes
    for key in ("steps", "rejected_steps", "newton_failures", "error_test_failures"):
        assert comp.stats[key] == py.stats[key], key
    assert "newton" not in exits


def test_a_failure_in_a_flow_sources_region_is_the_culprit_finders(monkeypatch):
    """The compiled loop rejects a failed solve itself only where the
    culprit finder would find nothing to name: its worst equation outside
    every region of a node without volume that carries a flow source (Fig.
    5's pump). With every equation marked as such a region's, each failure
    is handed back to the BDF, and the run is the same."""
    build, duration = SCENES["fig5:air"]
    exits = _exits(monkeypatch)
    real = steploop._source_rows

    def everywhere(culprit, rows, point=None):
        known = real(culprit, rows, point)
        rows[:] = 1
        return known
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        base = sf.Simulation(build(), duration=duration, refine=1).run()
        n_base = exits.count("newton")
        exits.clear()
        monkeypatch.setattr(steploop, "_source_rows", everywhere)
        marked = sf.Simulation(build(), duration=duration, refine=1).run()
    assert exits.count("newton") == base.stats["newton_failures"] > n_base
    assert marked.stats["steps"] == base.stats["steps"]
    assert marked.stats["rejected_steps"] == base.stats["rejected_steps"]


def _stepped_water_network():
    """A draw of the randomized water networks (benchmarks/bench_water_network.py,
    8 components, seed 5), written out: an actuator filled by a volume flow
    source drains through a check valve into a node held by a pressure
    source that steps down at 21.7 ms (a Tesla valve to a second source,
    an inertial tube to an accumulator on the same node)."""
    water = sf.water
    s = sf.System()
    s += sf.PressureSource("src0", 209615.9690128768)
    s += sf.PressureSource("src1", sf.waveforms.Step(0.021747377611257102, 193546.54831481384,
                                                     174419.4020271372), gauge=True)
    s += sf.Actuator("v2", water, ps.curve_plateau(25.36706586708236))
    s += sf.VolumeFlowSource("src2", sf.waveforms.Ramp(0.04755114905978997, 0.06758246961257242,
                                                       9.365056197801611e-06,
                                                       -2.4089519297447306e-06), water)
    s += sf.LinearAccumulator("v3", water, volume=1.0547976284063877e-05,
                              compliance=5.455327773899976e-11,
                              initial_pressure=135658.92321000405)
    s += sf.TeslaValve("e0", water, length=0.020673308353805032,
                       diameter=0.0015740765992712951, diodicity=1.9638054652355783)
    s += sf.CheckValve("e1", water, 0.001117642368825763, cracking_pressure=7530.250511753844,
                       opening_band=2273.3547550170533, leakage=0.0)
    s += sf.CircularTube("e2", water, length=0.05701486902942089,
                         diameter=0.001986651549947214, friction="Colebrook", inertance=True)
    s.connect(("e0", "b"), ("src0", "a"))
    s.connect(("e0", "a"), ("src1", "a"), ("e1", "b"), ("e2", "a"))
    s.connect(("e1", "a"), ("v2", "a"), ("src2", "a"))
    s.connect(("e2", "b"), ("v3", "a"))
    return s


def test_restart_probes_solve_as_the_bdfs(monkeypatch):
    """The restart's backward Euler probes in the compiled loop are solved
    as BDF._probe solves them: Newton held to 1e-12 with its damped full
    stage before the tolerance is loosened to the run's. The loop solved
    the first two probes after a breakpoint by the chord stages alone, and
    where those contracted too slowly at 1e-12 it went on at the run's
    tolerance, whose chord converged on another point than the BDF's
    damped stage: states' rates 1e-3 off the BDF's, and a first step whose
    predictor Newton could not solve (the 63-component water network of
    benchmarks/bench_water_network.py: 562 steps and 77 failed solves in
    the loop, 276 and 2 in Python). Here the loop took 64 steps, 1
    rejected, 1 failed solve, against Python's 57, 0, 0; now the same
    steps and times (to round-off), the restarts in the loop."""
    exits = _exits(monkeypatch)
    py, comp, taken = _both(_stepped_water_network, 0.05, monkeypatch)
    assert py.success and comp.success
    assert taken >= 0.5 * comp.stats["steps"]
    assert "restart" not in exits
    for key in ("steps", "rejected_steps", "newton_failures", "error_test_failures",
                "order_steps"):
        assert comp.stats[key] == py.stats[key], key
    np.testing.assert_allclose(comp.times, py.times, rtol=1e-9, atol=0)


def test_record_buffers_hold_a_small_runs_steps_and_hand_over_when_full(monkeypatch):
    """The loop's record buffers take as many rows as
    settings.COMPILED_RECORD_BYTES hold, between COMPILED_RECORD_ROWS and
    COMPILED_RECORD_ROWS_MAX: fig5:air's 385 steps in one call of the loop
    (two before); buffers of 8 rows hand over every 8 steps, adaptive and at
    fixed steps, with the same numbers."""
    assert steploop.record_rows(1) == settings.COMPILED_RECORD_ROWS_MAX
    assert steploop.record_rows(10 ** 9) == settings.COMPILED_RECORD_ROWS
    assert (settings.COMPILED_RECORD_ROWS < steploop.record_rows(500)
            < settings.COMPILED_RECORD_ROWS_MAX)
    calls = []
    st = steploop.law_module("stepper")
    for name in ("stretch", "fixed_stretch"):
        original = getattr(st, name)

        def counted(*args, _original=original, _name=name):
            calls.append(_name)
            return _original(*args)
        monkeypatch.setattr(st, name, counted)

    def run(**kw):
        calls.clear()
        r = sf.Simulation(ps.fig5(sf.air), duration=ps.duration(5), beyond_limits="warn",
                          **kw).run()
        return r, list(calls)

    adaptive, big = run()
    fixed, big_fixed = run(step=1e-3)
    assert adaptive.stats["steps"] > 300 and big.count("stretch") <= 2
    monkeypatch.setattr(settings, "COMPILED_RECORD_ROWS", 8)
    monkeypatch.setattr(settings, "COMPILED_RECORD_ROWS_MAX", 8)
    adaptive8, small = run()
    fixed8, small_fixed = run(step=1e-3)
    assert small.count("stretch") >= adaptive.stats["steps"] // 8
    assert small_fixed.count("fixed_stretch") >= len(fixed.times) // 8 > 0
    for a, b in ((adaptive, adaptive8), (fixed, fixed8)):
        np.testing.assert_array_equal(a.times, b.times)
        np.testing.assert_array_equal(a.X, b.X)
        np.testing.assert_array_equal(a.S, b.S)
