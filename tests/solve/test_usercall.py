"""User components and Python-function sources called back from the compiled
loop (softflow.solve.usercall): the same equations, runs and errors as the
per-group path and the Python step loop, which settings.COMPILED_USER = False
keeps. (The paper's actuator is compiled where numba can compile it,
softflow.solve.usercompile, tested in test_usercompile.py; the tests here
that need its call-back ask for it, or raise from a wrapper numba cannot
compile.)"""
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow.demo import paper_system
from softflow.solve import settings, steploop, usercall
from softflow.solve import variants as variants_mod
from helpers import UserChamber, assert_user_rows_are_the_python_paths

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from scenes import walled_tank  # noqa: E402

P0 = sf.pressure_atmospheric


def _both(make, monkeypatch, **kw):
    """(compiled loop with call-backs, Python path) runs of the scene ``make()``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(make(), **kw)
        assert steploop.not_served_because(sim._integrator()[0]) is None
        a = sim.run(raise_on_failure=False)
        monkeypatch.setattr(settings, "COMPILED_USER", False)
        py = sf.Simulation(make(), **kw)
        assert py.asm.residual is py.asm.python_residual
        b = py.run(raise_on_failure=False)
        monkeypatch.setattr(settings, "COMPILED_USER", True)
    return a, b


def test_the_papers_network_is_the_per_group_residual_to_round_off(monkeypatch):
    """The paper's scene (a Python-function source, a user actuator called
    back): the compiled residual's rows and Jacobian entries are the
    per-group path's at random states, steps and times; the actuator's rows
    bitwise (the same kernel called back)."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(paper_system(inertance=False), duration=1.0)
    net = sim.asm.residual.network
    assert len(net.callbacks) == 1 and not net.kernels
    assert_user_rows_are_the_python_paths(sim, seed=3)


@pytest.mark.parametrize("step", [1e-3, None])
def test_the_papers_listing_runs_as_in_the_python_loop(monkeypatch, step):
    """Fixed steps: the same numbers to 1e-10 relative; adaptive: the same
    steps, within the tolerance."""
    kw = {"duration": 1.0} if step is None else {"duration": 1.0, "step": step}
    a, b = _both(lambda: paper_system(inertance=False), monkeypatch, **kw)
    assert a.success and b.success
    assert a.stats["steps"] == b.stats["steps"]
    pa, pb = a.get("actu", "pressure"), b.get("actu", "pressure")
    rtol = 1e-10 if step is not None else 1e-6
    np.testing.assert_allclose(pa - P0, pb - P0, rtol=0, atol=rtol * np.ptp(pb))
    np.testing.assert_allclose(a.get("actu", "mass"), b.get("actu", "mass"), rtol=rtol)


def test_a_user_chamber_behind_library_components(monkeypatch):
    """A stiff user chamber at the end of a water tube, fed by a waveform:
    the same run in the loop (called back) and in Python."""
    def make():
        s = sf.System()
        s += sf.PressureSource("src", pressure=sf.waveforms.Step(0.01, P0 + 1e4, P0 + 3e4))
        s += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
        s += UserChamber("tank")
        s.connect("tube", "src")
        s.connect("tube", "tank")
        return s
    a, b = _both(make, monkeypatch, duration=0.05, step=1e-4)
    np.testing.assert_allclose(a.get("tank", "pressure"), b.get("tank", "pressure"),
                               rtol=1e-10)
    a, b = _both(make, monkeypatch, duration=0.05)
    assert a.stats["steps"] == b.stats["steps"]


def _raising(where, error=None):
    """The paper's scene whose actuator's evaluate or source's function
    raises past 0.3 s (``error``, or the test's own errors)."""
    s = paper_system(inertance=False)
    if where == "source":
        func = s.components[0].signal.func

        def signal(t):
            if t > 0.3:
                raise error or ValueError("the user's signal broke")
            return func(t)
        s.components[0].signal.func = signal
    else:
        actu = s.get("actu")
        own = actu.evaluate.func

        def evaluate(t, p, mass):
            if t > 0.3:
                raise error or ZeroDivisionError("the user's model broke")
            return own(t, p, mass)
        actu.evaluate = actu.auto(evaluate)
    return s


@pytest.mark.parametrize("where, culprit, said", [
    ("source", "PressureSource 'source'", "ValueError: the user's signal broke"),
    ("actuator", "'actu': evaluate raised", "ZeroDivisionError: the user's model broke")])
@pytest.mark.parametrize("step", [1e-3, None])
def test_an_error_in_user_code_names_the_component_and_the_time(monkeypatch, where, culprit,
                                                                said, step):
    """Raised inside a call-back, the error is the Python path's: the failed
    result names the component, the time and the error, after about the
    same work."""
    kw = {"duration": 1.0} if step is None else {"duration": 1.0, "step": step}
    a, b = _both(lambda: _raising(where), monkeypatch, **kw)
    assert a.status == b.status == "failed"
    assert culprit in a.message and said in a.message
    assert a.message == b.message
    assert a.times[-1] == pytest.approx(b.times[-1], rel=1e-12)
    assert a.stats["residual_evaluations"] <= b.stats["residual_evaluations"] + 5


def _user_group():
    """(asm, the actuator's group, its call-back key, x, S) of the paper's
    scene at a point off its initial values (called back: not compiled,
    softflow.solve.usercompile)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        settings.COMPILED_USER_CODE = False
        try:
            sim = sf.Simulation(paper_system(inertance=False), duration=1.0)
        finally:
            settings.COMPILED_USER_CODE = True
    asm = sim.asm
    net = asm.residual.network
    g = next(g for g in asm.groups if g.row is not None)
    key = int(net.groups[asm.groups.index(g), 10])
    return asm, g, key, asm.x0 * 1.01, asm.S0 * 1.02


def test_pure_python_dispatch_is_the_callback():
    """usercall.dispatch (the pure-Python mode's route, NUMBA_DISABLE_JIT=1)
    writes what the C callback writes; an unknown key or a raising kernel
    answers 1."""
    asm, g, key, x, S = _user_group()
    F1, raw1, S1 = np.zeros(asm.n), np.zeros(asm.raw.size), np.zeros(S.size)
    assert usercall.dispatch(key, 0.1, 1e-3, True, x, S, F1, raw1, S1) == 0
    F2 = asm.python_residual(x, S, 0.1, 1e-3, True)
    assert np.array_equal(F1[g.r0:g.r1], F2[g.r0:g.r1])
    assert np.array_equal(raw1[g.j0:g.j1], asm.raw[g.j0:g.j1])
    assert np.array_equal(S1[g.s0:g.s1], asm.update_states(x, S, 1e-3)[g.s0:g.s1])
    assert usercall.dispatch(10 ** 9, 0.1, 1e-3, True, x, S, F1, raw1, S1) == 1
    assert usercall.dispatch(key, 0.1, 1e-3, True, x[:1], S, F1, raw1, S1) == 1


def test_batches_of_user_scenes_share_their_steps(monkeypatch):
    """The batched variants' threads run on each variant's own arrays, which
    a call-back (on the batch network's) does not know: a user component's
    scene called back keeps the shared steps, and says why (compiled, its
    variants run on their own clocks: test_usercompile.py)."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(paper_system(inertance=False), duration=0.2)
        out = sf.sweep(sim, {"tube.diameter": [1e-3, 1.2e-3]}, engine="batched")
    assert "user component" in variants_mod.reason_not(sim)
    assert out.status == ["success", "success"]


@pytest.mark.parametrize("where", ["source", "actuator"])
def test_an_interrupt_inside_a_call_back_is_raised_not_swallowed(where):
    """Ctrl-C (KeyboardInterrupt) inside the user's code stops the run with
    that interrupt, at fixed steps and adaptive, as in the Python loop."""
    for kw in ({"step": 1e-3}, {}):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            sim = sf.Simulation(_raising(where, KeyboardInterrupt), duration=1.0, **kw)
        with pytest.raises(KeyboardInterrupt):
            sim.run(raise_on_failure=False)
        assert not usercall.PENDING


def test_the_first_compile_says_so(monkeypatch, caplog):
    """Where the compiled loop is in no cache yet, one INFO line on the
    'softflow' logger says it compiles now, once; where numba's cache
    internals are not as expected, nothing is said."""
    import logging
    import types

    from softflow.laws import stepper

    def cold(index):
        cache = types.SimpleNamespace(_cache_path="/somewhere",
                                      _cache_file=types.SimpleNamespace(_load_index=index))
        return types.SimpleNamespace(overloads={}, _cache=cache)
    for name in ("stretch", "fixed_stretch", "start_solve"):
        monkeypatch.setattr(stepper, name, cold(lambda: {}))
    with caplog.at_level(logging.INFO, logger="softflow"):
        steploop._compile_notice()
    assert any("compiling its step loop for this installation" in r.message
               and "/somewhere" in r.message for r in caplog.records)
    caplog.clear()
    # the banded and sparse LUs, compiled on their own at the first run that
    # needs one: said there, once a process; a dense run says nothing
    seen = []
    monkeypatch.setattr(steploop, "_FAR_LOOKED", [])
    for name in ("far_factor", "far_solve", "far_row_maxima"):
        monkeypatch.setattr(stepper, name, cold(lambda: {}))
    monkeypatch.setattr(stepper, "far_addresses", seen.append)
    dense, sparse = (None,) * 13 + (np.array([stepper.DENSE]),), (None,) * 13 + (
        np.array([stepper.SPARSE]),)
    with caplog.at_level(logging.INFO, logger="softflow"):
        steploop._far_addresses(stepper, dense)
        assert not caplog.records
        steploop._far_addresses(stepper, sparse)
        steploop._far_addresses(stepper, sparse)
    assert sum("banded and sparse LUs" in r.message and "/somewhere" in r.message
               for r in caplog.records) == 1
    assert seen == [dense, sparse, sparse]
    caplog.clear()

    def broken():
        raise AttributeError("numba moved it")
    for name in ("stretch", "fixed_stretch", "start_solve"):
        monkeypatch.setattr(stepper, name, cold(broken))
    with caplog.at_level(logging.INFO, logger="softflow"):
        steploop._compile_notice()
    assert not caplog.records


def test_a_copied_scenes_signal_is_its_own():
    """A deep copy of a System (as a thermal Simulation compiles from) calls
    back its own signal, and goes on doing so when the original is gone."""
    import copy
    import gc

    box = {"p": 1.3e5}

    def make():
        s = sf.System()
        s += sf.PressureSource("src", pressure=lambda t: box["p"])
        s += sf.CircularTube("tube", sf.air, 0.3, 1e-3)
        s += sf.Container("tank", sf.air, 1e-5)
        s.connect("src", "tube")
        s.connect("tube", "tank")
        return s
    original = make()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        first = sf.Simulation(original, duration=0.02).run()
        twin = copy.deepcopy(original)
        twin.components[0].signal.func = lambda t: 1.2e5
        del original
        gc.collect()
        second = sf.Simulation(twin, duration=0.02).run()
        box["p"] = 1.2e5
        again = sf.Simulation(make(), duration=0.02).run()
    assert second.get("tank", "pressure")[-1] == pytest.approx(
        again.get("tank", "pressure")[-1], rel=1e-9)
    assert first.get("tank", "pressure")[-1] > second.get("tank", "pressure")[-1] + 500


def test_the_c_callback_reads_the_sizes_it_is_given():
    """The C entry wraps each array at the address and size the loop passes:
    arrays as the loop's give the per-group path's rows; a row array too
    short for the component's rows is refused (1), not written past."""
    asm, g, key, x, S = _user_group()
    F, raw, Sout = np.zeros(asm.n), np.zeros(asm.raw.size), np.zeros(S.size)

    def pairs(*arrays):
        return [v for a in arrays for v in (a.ctypes.data, a.size)]
    assert usercall._entry(key, 0.1, 1e-3, 1, *pairs(x, S, F, raw, Sout)) == 0
    F2 = asm.python_residual(x, S, 0.1, 1e-3, True)
    assert np.array_equal(F[g.r0:g.r1], F2[g.r0:g.r1])
    short = np.zeros(g.r0)
    assert usercall._entry(key, 0.1, 1e-3, 1, *pairs(x, S, short, raw, Sout)) == 1


@pytest.mark.parametrize("step", [1e-3, None])
def test_a_wall_whose_h_a_a_correlation_sets_at_each_step_runs_in_the_loop(monkeypatch, step):
    """The correlation's h A, set at each step's start, called back from the
    compiled loop (usercall.Begin): the Python loop's numbers (fixed steps
    bitwise-close, adaptive the same steps)."""
    kw = {"duration": 0.2, "thermal": "heat_transfer"}
    if step is not None:
        kw["step"] = step
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(walled_tank(), **kw)
        assert steploop.not_served_because(sim._integrator()[0]) is None
        a = sim.run()
        monkeypatch.setattr(settings, "COMPILED_USER", False)
        py = sf.Simulation(walled_tank(), **kw)
        assert "sets coefficients at each step" in steploop.not_served_because(
            py._integrator()[0])
        b = py.run()
    assert a.stats["steps"] == b.stats["steps"]
    for name, scale in (("pressure", 1e5), ("temperature", 300.0)):
        np.testing.assert_allclose(a.get("tank", name), b.get("tank", name), rtol=0,
                                   atol=1e-12 * scale)


def test_an_error_in_the_step_start_coefficients_stops_the_run_as_in_python(monkeypatch):
    """A correlation that raises once the tank passes 1.2 bar: the run fails
    with that error, in the loop as in Python."""
    from softflow.components import thermal
    cls = next(c for c in vars(thermal).values()
               if isinstance(c, type) and "begin_step" in vars(c))
    own = cls.__dict__["begin_step"].__func__

    def begin_step(klass, P, V, S):
        if V[:, 0].max() > 1.2e5:
            raise ArithmeticError("the wall correlation broke")
        return own(klass, P, V, S)
    monkeypatch.setattr(cls, "begin_step", classmethod(begin_step))
    outs = []
    for on in (True, False):
        monkeypatch.setattr(settings, "COMPILED_USER", on)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            sim = sf.Simulation(walled_tank(), duration=0.2, thermal="heat_transfer")
            try:
                outs.append(sim.run(raise_on_failure=False))
            except ArithmeticError as err:
                outs.append(err)
        assert not usercall.PENDING
    a, b = outs
    assert type(a) is type(b)
    if isinstance(a, Exception):
        assert str(a) == str(b) == "the wall correlation broke"
    else:
        assert a.status == b.status == "failed" and a.message == b.message
        assert "the wall correlation broke" in a.message
        assert a.times[-1] == pytest.approx(b.times[-1], rel=1e-12)
