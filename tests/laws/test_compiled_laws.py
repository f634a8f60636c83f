"""The compiled laws (softflow.laws): the scalar functions themselves against
``fluids`` and scipy, their partials against differences, the array functions
of softflow.correlations as loops over them, the pure-Python mode
(NUMBA_DISABLE_JIT=1) giving the same numbers, and the cache keyed on the
package's text."""
from pathlib import Path

import fluids.friction
import numpy as np
import pytest
from scipy.special import lambertw

import softflow.laws as laws
from helpers import compiled_and_python, probe_json
from softflow.correlations.gas_pipe import entry_z as entry_z_array
from softflow.correlations.gas_pipe import isothermal_pipe as isothermal_pipe_array
from softflow.laws import friction as fl
from softflow.laws import gas_pipe as gl

RE = np.logspace(np.log10(4e3), 8, 25)
ROUGHNESS = (0.0, 1e-6, 1e-4, 1e-2, 0.05)


@pytest.mark.parametrize("scalar, reference", [
    (lambda Re, eD: fl.haaland(Re, fl.haaland_terms(eD)), fluids.friction.Haaland),
    (fl.colebrook, fluids.friction.Colebrook),
    (fl.churchill, fluids.friction.Churchill_1977),
    (fl.swamee_jain, fluids.friction.Swamee_Jain_1976),
], ids=["Haaland", "Colebrook", "Churchill_1977", "Swamee_Jain_1976"])
@pytest.mark.parametrize("eD", ROUGHNESS)
def test_scalar_friction_laws_match_fluids_with_their_derivative(scalar, reference, eD):
    for Re in RE:
        f, df = scalar(float(Re), eD)
        assert f == pytest.approx(reference(float(Re), eD), rel=1e-12)
        h = 1e-6 * Re
        fd = (scalar(Re + h, eD)[0] - scalar(Re - h, eD)[0]) / (2 * h)
        assert df == pytest.approx(fd, rel=1e-6, abs=1e-9 * abs(f) / Re)


@pytest.mark.parametrize("kind", [fl.HAALAND, fl.COLEBROOK, fl.CHURCHILL, fl.SWAMEE_JAIN])
@pytest.mark.parametrize("bounds", [(2300.0, 4000.0), (1000.0, 1500.0)])
def test_blended_law_is_laminar_below_turbulent_above_and_C1(kind, bounds):
    lo, hi = bounds
    eD = 1e-4
    a = fl.haaland_terms(eD)
    assert fl.fRe_blended(kind, 0.5 * lo, eD, a, lo, hi) == (64.0, 0.0)
    f, df = fl.turbulent(kind, 2.0 * hi, eD, a)
    phi, dphi = fl.fRe_blended(kind, 2.0 * hi, eD, a, lo, hi)
    assert (phi, dphi) == pytest.approx((f * 2.0 * hi, f + 2.0 * hi * df), rel=1e-15)
    for Re in np.linspace(0.9 * lo, 1.1 * hi, 41):
        h = 1e-3
        fd = (fl.fRe_blended(kind, Re + h, eD, a, lo, hi)[0]
              - fl.fRe_blended(kind, Re - h, eD, a, lo, hi)[0]) / (2 * h)
        assert fl.fRe_blended(kind, Re, eD, a, lo, hi)[1] == pytest.approx(fd, rel=1e-5,
                                                                             abs=1e-9)
    assert fl.fRe_blended(fl.LAMINAR, 1e6, eD, a, lo, hi) == (64.0, 0.0)


def test_entry_z_solves_z_exp_minus_z_on_the_principal_branch():
    a = np.logspace(-300, np.log10(0.36), 5001)
    z = np.array([gl.entry_z(float(x)) for x in a])
    np.testing.assert_allclose(z, -lambertw(-a).real, rtol=1e-14)
    # near the entry's limit z is ill-conditioned (dz/da infinite at a = 1/e:
    # a's round-off moves z by sqrt(2e da) ~ 2e-8): the equation holds to round-off
    near = np.exp(-1.0) * (1.0 - np.logspace(-15, -1, 200))
    zn = np.array([gl.entry_z(float(x)) for x in near])
    assert (zn <= 1.0).all()
    np.testing.assert_allclose(zn, -lambertw(-near).real, rtol=0, atol=3e-8)
    np.testing.assert_allclose(zn * np.exp(-zn), near, rtol=4e-16)
    assert gl.entry_z(0.0) == 0.0
    assert gl.entry_z(np.exp(-1.0)) == 1.0 and gl.entry_z(10.0) == 1.0
    assert np.isnan(gl.entry_z(float("nan")))
    np.testing.assert_array_equal(entry_z_array(a), z)


def _states(n=400, seed=7):
    rng = np.random.default_rng(seed)
    pa = rng.uniform(0.2e5, 10e5, n)
    pb = pa * rng.uniform(0.05, 1.5, n)
    area = np.pi * rng.uniform(2e-4, 5e-3, n) ** 2 / 4
    c2 = 287.05 * rng.uniform(250.0, 400.0, n)
    # flux up to past the entry's limit, either direction
    mf = rng.uniform(-1.3, 1.3, n) * np.maximum(pa, pb) / np.sqrt(c2) * area * 0.6
    phi = rng.uniform(0.0, 3.0, n) * mf / area ** 2 * 1e-3
    return pa, mf, pb, area, c2, phi


def test_isothermal_pipe_partials_match_central_differences():
    for pa, mf, pb, area, c2, phi in zip(*_states()):
        out = gl.isothermal_pipe(pa, mf, pb, area, c2, phi)
        args = [pa, mf, pb, area, c2, phi]
        for k, arg in ((1, 0), (2, 1), (3, 2), (4, 4), (5, 5)):
            h = 1e-7 * max(abs(args[arg]), 1e-9 if arg == 1 else 1.0)
            up, down = list(args), list(args)
            up[arg] += h
            down[arg] -= h
            fd = (gl.isothermal_pipe(*up)[0] - gl.isothermal_pipe(*down)[0]) / (2 * h)
            scale = abs(out[0]) / abs(args[arg]) if args[arg] else abs(fd)
            assert out[k] == pytest.approx(fd, rel=1e-5, abs=1e-7 * scale + 1e-12), (k, args)


def test_array_law_is_the_scalar_law_elementwise():
    states = _states()
    R, R_pa, R_mf, R_pb, R_c2, R_phi, choked = isothermal_pipe_array(*states)
    for i, args in enumerate(zip(*states)):
        assert (R[i], R_pa[i], R_mf[i], R_pb[i], R_c2[i], R_phi[i], choked[i]) == \
            gl.isothermal_pipe(*args)
    assert choked.any() and not choked.all()
    # scalars broadcast against arrays; floats give floats
    one = isothermal_pipe_array(2e5, 1e-3, 1e5, 1e-6, 287.0 * 293.0, 0.0)
    assert isinstance(one[0], float) and one[0] == gl.isothermal_pipe(
        2e5, 1e-3, 1e5, 1e-6, 287.0 * 293.0, 0.0)[0]


# -- the pure-Python mode and the cache ---------------------------------------------------
@pytest.mark.slow
def test_pure_python_mode_gives_the_compiled_numbers_and_the_cache_is_used():
    expression = ("[friction.colebrook(1e5, 1e-4), friction.fRe_blended(friction.HAALAND, "
                  "3000.0, 1e-4, friction.haaland_terms(1e-4), 2300.0, 4000.0), "
                  "gas_pipe.entry_z(0.2), "
                  "gas_pipe.isothermal_pipe(3e5, 2e-3, 1e5, 3e-6, 287.0 * 293.0, 1e3)[:6]]")
    compiled, python, _ = compiled_and_python(expression)
    _, _, hits = compiled_and_python(expression)
    assert hits > 0      # a second process loads the cache
    np.testing.assert_allclose(python, compiled, rtol=1e-15)


def test_cache_key_is_the_whole_package_text(tmp_path, monkeypatch):
    for path in Path(laws.__file__).parent.glob("*.py"):
        (tmp_path / path.name).write_bytes(path.read_bytes())
    monkeypatch.setattr(laws, "_PACKAGE", tmp_path)
    before = laws.source_stamp()
    assert laws.source_stamp() == before
    other = tmp_path / "gas_pipe.py"
    other.write_text(other.read_text() + "\n# an edit in another law's file\n")
    assert laws.source_stamp() != before
    # a law's stamp is the one its module was imported under, whatever the
    # files say later (what a long process compiles is what it imported)
    stamp = laws._STAMPS[fl.colebrook.py_func]
    assert stamp != laws.source_stamp()
    assert fl.colebrook._cache._impl.locator.get_source_stamp() == stamp
    # the locators take this package's functions only
    ours = [c for c in laws._numba_class("CacheImpl")._locator_classes
            if c.__name__.startswith("Softflow")]
    assert len(ours) == 3
    assert all(c.from_function(np.sum, np.__file__) is None for c in ours)


@pytest.mark.slow
def test_no_writable_cache_compiles_in_memory_with_a_warning():
    """Where numba finds no cache directory it can write, the laws compile in
    memory for the process, with one warning, instead of failing at import."""
    import subprocess
    import sys

    probe = (
        "import warnings\n"
        "import softflow.laws as laws\n"
        "laws._numba_class('CacheImpl')._locator_classes[:] = []\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    from softflow.laws import gas_pipe\n"
        "    z = gas_pipe.entry_z(0.2)\n"
        "assert abs(z * 2.718281828459045 ** -z - 0.2) < 1e-15, z\n"
        "mine = [w for w in caught if 'cannot be cached' in str(w.message)]\n"
        "assert len(mine) == 1, [str(w.message) for w in caught]\n"
        "print('ok')\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr


def test_no_law_or_loop_is_compiled_once_per_literal_argument():
    # A constant passed from compiled code (``residual(..., True, ...)``) types as
    # Literal[bool](True): numba then compiles the callee, and everything it calls,
    # once per constant value besides the plain type. The residual was compiled
    # three times over (a first compile of 88 s instead of 59). After runs that
    # take the adaptive and fixed-step loops through every Newton stage, no law
    # or loop holds a signature with a literal or omitted argument. (Callees
    # show their signatures where this process compiled their caller: a cold
    # cache, as in CI's first run; from a warm cache the callers' machine code
    # is loaded whole, and only the direct calls from Python are seen.)
    import importlib
    import pkgutil
    import warnings

    import numba

    import softflow as sf
    from softflow import paper_scenes as ps

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for scene, fig in (("snapping", 4), ("tesla", 4)):
            sf.Simulation(ps.fig4(scene), duration=ps.duration(fig)).run()
            sf.Simulation(ps.fig4(scene), duration=ps.duration(fig), step=1e-3).run()
        sf.Simulation(ps.fig5(sf.air), duration=ps.duration(5)).run()
    literal = []
    for info in pkgutil.iter_modules(laws.__path__):
        module = importlib.import_module(f"softflow.laws.{info.name}")
        for name, obj in vars(module).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher) \
                    and obj.__module__ == module.__name__:
                literal += [f"{info.name}.{name}{sig}" for sig in obj.signatures
                            if "Literal" in str(sig) or "Omitted" in str(sig)]
    assert not literal, literal


def test_borrowed_views_share_the_data_and_the_type():
    # laws.borrowed: views that hold no reference (the step loop's arguments);
    # the same numba type (no new compile), the same memory, writes seen by
    # the owner; tuples (nested, with scalars) borrowed item by item
    import numba

    from softflow.laws import borrowed

    @numba.njit
    def use(a, pair):
        b = borrowed(a)
        (c, k), d = borrowed(pair)
        b[1] = 7.0
        c[0, 1] = -1.0
        return b.sum() + d[0] + k, b.shape[0], c.shape

    a = np.arange(4.0)
    m = np.zeros((2, 3))
    total, size, shape = use(a, ((m, 5), np.array([0.5])))
    assert a.tolist() == [0.0, 7.0, 2.0, 3.0] and m[0, 1] == -1.0
    assert (total, size, shape) == (12.0 + 0.5 + 5, 4, (2, 3))
    assert len(use.signatures) == 1


def test_call_native_calls_a_function_compiled_on_its_own_by_its_address():
    # laws.call_native / native_address: a compiled callee reached through its
    # address (the step loop's residual and its banded and sparse LUs): the
    # arguments (a tuple, nested tuples of arrays and scalars) reach it as a
    # direct call passes them, writes into arrays are seen, its int64 comes
    # back, an exception it raises reaches Python; the address is found once for a set of types
    # and the callee is not compiled again; arguments of other types than
    # the callee's raise instead of reaching it; an array of another layout
    # than C-contiguous is refused where the caller is compiled
    import numba

    from softflow.laws import call_native, native_address

    @numba.njit
    def scaled(pair, s):
        a, b = pair
        for i in range(a.size):
            b[i] = a[i] * s
        if s < 0.0:
            raise ValueError("negative")
        return np.int64(b.sum())

    @numba.njit
    def caller(at, key, pair, s):
        return call_native(at, key, (pair, s))

    a, b = np.arange(5.0), np.zeros(5)
    at, key = native_address(scaled, ((a, b), 2.0))
    assert at and native_address(scaled, ((np.ones(3), np.ones(3)), 1.0)) == (at, key)
    assert caller(at, key, (a, b), 2.0) == 20 and b.tolist() == [0.0, 2.0, 4.0, 6.0, 8.0]
    with pytest.raises(ValueError, match="negative"):   # the callee's own error
        caller(at, key, (a, b), -1.0)
    assert len(scaled.signatures) == 1                  # compiled once, on its own
    with pytest.raises(RuntimeError, match="other argument types"):
        caller(at, key, (a, b), 2)                      # an int where it takes a float
    b[:] = 0.0
    with pytest.raises(RuntimeError, match="other argument types"):
        caller(at, key, (a.astype(np.int64), b), 2.0)
    assert not b.any()                                  # (not called)
    with pytest.raises(numba.core.errors.TypingError):
        caller(at, key, (a[::2], b[::2]), 1.0)


def test_the_step_loop_reaches_the_residual_and_far_lus_by_address():
    # the compiled loops call the network's residual, and the banded and sparse
    # LUs, through their addresses (compiled on their own: a dense run's first
    # compile leaves them out); the addresses ride in net[8] and lin[13]; a
    # dense lin has none, and the three runs take the Python steps' steps, to
    # the round-off of their linear algebra (measured 2e-10, 2e-10, 4e-9 of
    # each output's scale)
    import sys
    import warnings

    import softflow as sf
    from softflow.laws import stepper
    from softflow.solve import settings, steploop
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from scenes import chain

    seen = {}
    run = steploop.CompiledSteps.run

    def spy(self, *args):
        seen[int(self.lin[13][stepper.KIND])] = (self.net[8][0], self.lin[13].copy())
        return run(self, *args)

    results = {}
    for compiled in (True, False):
        saved = settings.COMPILED_STEPS
        settings.COMPILED_STEPS = compiled
        steploop.CompiledSteps.run = spy
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                for N, kw in ((4, {}), (30, dict(linear_solver="dense")), (40, {})):
                    res = sf.Simulation(chain(N), duration=0.02, rtol=1e-5, **kw).run()
                    results[compiled, N] = res.X
        finally:
            settings.COMPILED_STEPS = saved
            steploop.CompiledSteps.run = run
    assert sorted(seen) == [stepper.DENSE, stepper.BANDED, stepper.SPARSE]
    for kind, (residual_at, info) in seen.items():
        assert residual_at != 0
        far = info[[stepper.FACTOR_AT, stepper.SOLVE_AT, stepper.MAXIMA_AT]]
        assert (far == 0).all() if kind == stepper.DENSE else (far != 0).all()
    for N in (4, 30, 40):
        new, old = results[True, N], results[False, N]
        assert new.shape == old.shape
        scale = np.abs(old).max(axis=0)
        assert (np.abs(new - old) <= 1e-7 * scale).all(), N


def test_the_step_loop_runs_in_pure_python_mode_with_the_compiled_numbers():
    # NUMBA_DISABLE_JIT=1 runs the same step loop uncompiled (the functions
    # reached by address called directly): a dense, a banded and a sparse
    # chain give the compiled run's numbers
    bench = Path(__file__).resolve().parents[2] / "benchmarks"
    probe = (
        "import json, sys, warnings\n"
        f"sys.path.insert(0, {str(bench)!r})\n"
        "warnings.simplefilter('ignore')\n"
        "import softflow as sf\n"
        "from scenes import chain\n"
        "out = [sf.Simulation(chain(N), duration=0.005, **kw).run().X[-1].tolist()\n"
        "       for N, kw in ((3, {}), (30, dict(linear_solver='dense')), (40, {}))]\n"
        "print(json.dumps({'jit': not sf.laws.numba.config.DISABLE_JIT, 'x': out}))\n")

    compiled = probe_json(probe, NUMBA_DISABLE_JIT="0")
    python = probe_json(probe, NUMBA_DISABLE_JIT="1")
    assert compiled["jit"] and not python["jit"]
    for a, b in zip(compiled["x"], python["x"]):
        np.testing.assert_allclose(b, a, rtol=1e-9)
