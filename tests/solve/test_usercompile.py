"""User components compiled with numba as written (softflow.solve.usercompile):
the compiled kernel's rows, Jacobian entries and states are the Python
path's, runs agree with the call-back's, errors are the Python path's, and a
kernel is compiled once, keyed on the user's code and the values it reads."""
import logging
import math
import sys
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow.demo import balloon_csv, paper_system
from softflow.laws.network import OPTION, U0
from softflow.solve import settings, usercall, usercompile
from helpers import assert_user_rows_are_the_python_paths

P0 = sf.pressure_atmospheric


def _sim(system, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return sf.Simulation(system, **kw)


def _user_row(sim):
    """(the user group, its row of the compiled network's groups)."""
    asm = sim.asm
    net = asm.residual.network
    g = next(g for g in asm.groups if g.row is not None)
    return g, net.groups[asm.groups.index(g)]


def test_the_papers_actuator_is_compiled_and_its_rows_are_the_python_paths():
    """The paper's actuator (a PV curve and a fluid's rho in its closure, a
    dict from update_state) runs as a compiled kernel, not a call-back; at
    random states, steps and times its residual rows, Jacobian entries and
    end-of-step states are those of the per-group Python path, bit for bit."""
    sim = _sim(paper_system(inertance=False), duration=1.0)
    g, row = _user_row(sim)
    assert row[U0] != usercall.ADDRESS
    net = sim.asm.residual.network
    assert len(net.kernels) == 1 and not net.callbacks
    assert_user_rows_are_the_python_paths(sim, seed=5)


def _both(make, monkeypatch, **kw):
    """(compiled kernel, call-back) runs of the scene ``make()``."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        a = _sim(make(), **kw).run(raise_on_failure=False)
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
        sim = _sim(make(), **kw)
        assert _user_row(sim)[1][U0] == usercall.ADDRESS
        b = sim.run(raise_on_failure=False)
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    return a, b


@pytest.mark.parametrize("step", [1e-3, None])
def test_the_papers_listing_compiled_runs_as_called_back(monkeypatch, step):
    """Fixed steps: the same numbers to 1e-10 relative; adaptive: the same
    steps, within the tolerance."""
    kw = {"duration": 1.0} if step is None else {"duration": 1.0, "step": step}
    a, b = _both(lambda: paper_system(inertance=False), monkeypatch, **kw)
    assert a.success and b.success
    assert a.stats["steps"] == b.stats["steps"]
    rtol = 1e-10 if step is not None else 1e-6
    np.testing.assert_allclose(a.get("actu", "pressure") - P0, b.get("actu", "pressure") - P0,
                               rtol=0, atol=rtol * np.ptp(b.get("actu", "pressure")))
    np.testing.assert_allclose(a.get("actu", "mass"), b.get("actu", "mass"), rtol=rtol)


class _Actuator(sf.Component):
    """The paper's actuator, its evaluate raising past ``after`` seconds
    (compiled as written: the raise is numba's)."""

    def __init__(self, label, fluid, pvcurve, after=np.inf):
        super().__init__(label)
        p_ = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf_ = sf.Variable("massflow", "through", label="mf")
        m_ = sf.Variable("mass", "local", label="mass", initial_value=1e-3)
        self.set_terminals(sf.Terminal("a", [p_, mf_]))
        self.set_states(m_)

        def evaluate(t, p, mass):
            if t > after:
                raise ZeroDivisionError("the user's model broke")
            return [p - pvcurve.fdf_volume(volume=mass / fluid.rho)[0]]

        def update_state(dt, mass, mf):
            return {"mass": mass + mf * dt}
        self.evaluate = self.auto(evaluate)
        self.update_state = self.auto_state(update_state)


def _scene(curve, after=np.inf, amplitude=0.3e5):
    s = sf.System()
    s += sf.PressureSource("source", pressure=lambda t: P0 + (amplitude if t < 0.5 else 0.0))
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += _Actuator("actu", sf.water, curve, after)
    s.connect("tube", "source")
    s.connect("tube", "actu")
    return s


@pytest.mark.parametrize("step", [1e-3, None])
def test_an_error_raised_in_compiled_user_code_is_the_python_paths(monkeypatch, step):
    """Raised inside the compiled kernel, the error reaches the user as from
    the call-back: the failed result names the component, the time and the
    error."""
    curve = sf.PVCurve(balloon_csv())
    kw = {"duration": 1.0} if step is None else {"duration": 1.0, "step": step}
    sim = _sim(_scene(curve, after=0.3), **kw)
    assert _user_row(sim)[1][U0] != usercall.ADDRESS
    a, b = _both(lambda: _scene(curve, after=0.3), monkeypatch, **kw)
    assert a.status == b.status == "failed"
    assert "'actu': evaluate raised" in a.message
    assert "ZeroDivisionError: the user's model broke" in a.message
    assert a.message == b.message
    assert a.times[-1] == pytest.approx(b.times[-1], rel=1e-12)


def test_a_volume_beyond_a_refusing_curve_is_handled_as_in_python(monkeypatch):
    """A PV curve made with extrapolate='error' refuses volumes beyond its
    data: inside the compiled kernel too (the Python path then raises the
    curve's error, which cuts the step or names the curve)."""
    v = np.linspace(0.0, 2e-6, 9)
    curve = sf.PVCurve(volume=v, pressure=P0 + 2e9 * v + 1e15 * v ** 2, extrapolate="error")
    a, b = _both(lambda: _scene(curve, amplitude=2e5), monkeypatch, duration=0.5)
    assert a.status == b.status
    assert a.message == b.message
    assert "PVCurve" in a.message and "beyond its data" in a.message
    assert len(a.times) == len(b.times)
    np.testing.assert_allclose(a.X, b.X, rtol=1e-9, atol=1e-12)


class _Leak(sf.Component):
    """A leak to the atmosphere, mf = k (p - p0), written by a user; with
    ``numba_refuses`` its evaluate calls what numba cannot compile."""

    def __init__(self, label, k, numba_refuses=False):
        super().__init__(label)
        p_ = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf_ = sf.Variable("massflow", "through", label="mf")
        self.set_terminals(sf.Terminal("a", [p_, mf_]))
        if numba_refuses:
            self.evaluate = self.auto(lambda p, mf: [mf - k * (p - P0) + 0 * eval("1")])
        else:
            self.evaluate = self.auto(lambda p, mf: [mf - k * (p - P0)])


def _leaky(k=1e-9, numba_refuses=False):
    s = sf.System()
    s += sf.PressureSource("source", pressure=1.5e5)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s += _Leak("leak", k, numba_refuses)
    s.connect("tube", "source")
    s.connect("tube", "tank")
    s.connect("tank", "leak")
    return s


def _kernel_of(system):
    sim = _sim(system, duration=0.05)
    return next(g for g in sim.asm.groups if g.row is not None).row


@pytest.fixture
def fresh_root(tmp_path, monkeypatch):
    """Kernels written under a new directory, none loaded in this process."""
    monkeypatch.setattr(usercompile, "cache_root", lambda: tmp_path / "kernels")
    monkeypatch.setattr(usercompile, "_LOADED", {})
    monkeypatch.setattr(usercompile, "_FAILED", {})
    monkeypatch.setattr(usercompile, "_COMPILES", {})
    monkeypatch.setattr(usercompile, "_PRUNED", set())
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)   # built as call-backs
    yield tmp_path / "kernels"


def test_a_kernel_is_compiled_once_then_loaded_keyed_on_the_values_it_reads(fresh_root,
                                                                           monkeypatch,
                                                                           caplog):
    """The first call compiles (said once, INFO) and writes the kernel's
    module; in a process that has not loaded it, the kernel comes from
    numba's cache; other values compiled in as constants are another
    kernel; the same values the same one."""
    uk = _kernel_of(_leaky(1e-9))
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    monkeypatch.setattr(settings, "USER_RUNTIME_VALUES", False)     # k a constant
    monkeypatch.setattr(settings, "COMPILE_NOTICE", 0.0)
    with caplog.at_level(logging.INFO, logger="softflow"):
        first = usercompile.kernel_address(uk)
    assert first and "compiled the user component _Leak 'leak'" in caplog.text
    (name, (module, address)), = usercompile._LOADED.items()
    assert address == first and module.kernel.cache_hits == 0
    assert (fresh_root / f"{name}.py").exists()
    assert usercompile.kernel_address(_kernel_of(_leaky(1e-9))) == first   # the same values
    # another process: nothing loaded yet
    usercompile._LOADED.clear()
    sys.modules.pop(name)
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="softflow"):
        again = usercompile.kernel_address(uk)
    assert again and usercompile._LOADED[name][0].kernel.cache_hits == 1
    assert "compiled the user component" not in caplog.text
    other = usercompile.kernel_address(_kernel_of(_leaky(2e-9)))
    assert other and other != again and len(usercompile._LOADED) == 2


def test_a_design_loop_over_a_closure_value_stops_compiling(fresh_root, monkeypatch, caplog):
    """Each new value a function reads compiled in as a constant is a
    compile of its own: past settings.USER_COMPILES_MAX compiles of one code
    in a process, new values are called back (said once); kernels already
    compiled still load."""
    kernels = [_kernel_of(_leaky(k)) for k in (1e-9, 2e-9, 3e-9, 4e-9)]
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    monkeypatch.setattr(settings, "USER_RUNTIME_VALUES", False)     # k a constant
    monkeypatch.setattr(settings, "USER_COMPILES_MAX", 2)
    with caplog.at_level(logging.INFO, logger="softflow"):
        got = [usercompile.kernel_address(uk) for uk in kernels]
    assert got[0] and got[1] and got[2] is None and got[3] is None
    assert caplog.text.count("is called back in Python from now on") == 1
    assert usercompile.kernel_address(kernels[0]) == got[0]


def test_what_numba_cannot_compile_is_called_back_and_remembered(fresh_root, monkeypatch,
                                                                 caplog):
    """A function numba refuses is called back (the reason logged, DEBUG),
    runs as before, and is not tried again, in this process or the next
    (tried twice: its closure's float k as a run-time value, then as a
    constant)."""
    uk = _kernel_of(_leaky(numba_refuses=True))
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    with caplog.at_level(logging.DEBUG, logger="softflow"):
        assert usercompile.kernel_address(uk) is None
    assert "_Leak 'leak' is called back in Python, not compiled: numba cannot" in caplog.text
    assert len(list(fresh_root.glob("*.failed"))) == 2
    usercompile._FAILED.clear()
    monkeypatch.setattr(usercompile, "_write_once", None)      # not written, not imported
    assert usercompile.kernel_address(uk) is None
    res = _sim(_leaky(numba_refuses=True), duration=0.05).run()
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    ref = _sim(_leaky(numba_refuses=True), duration=0.05).run()
    np.testing.assert_array_equal(res.X, ref.X)


class _Reads(sf.Component):
    """A leak whose evaluate reads what compiled code cannot (a dict), or
    uses the component other than by reading its attributes (a method)."""

    def __init__(self, label, how):
        super().__init__(label)
        p_ = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf_ = sf.Variable("massflow", "through", label="mf")
        self.set_terminals(sf.Terminal("a", [p_, mf_]))
        self.k = 1e-9
        table = {"k": 1e-9}
        if how == "dict":
            self.evaluate = self.auto(lambda p, mf: [mf - table["k"] * (p - P0)])
        else:
            self.evaluate = self.auto(lambda p, mf: [mf - self.leak(p)])

    def leak(self, p):
        return self.k * (p - P0)


@pytest.mark.parametrize("how, why", [
    ("dict", "<lambda>'s table is a dict, which compiled code cannot read"),
    ("method", "<lambda>'s self.leak is a method, which compiled code cannot read"),
])
def test_values_compiled_code_cannot_read_are_called_back(caplog, how, why):
    """A closure over an object other than numbers, arrays, a PV curve, a
    fluid or an object whose attributes it reads (here a dict; a method of
    the component) is called back, the reason logged."""
    s2 = sf.System()
    s2 += sf.PressureSource("source", pressure=1.5e5)
    s2 += _Reads("reads", how)
    s2.connect("source", "reads")
    with caplog.at_level(logging.DEBUG, logger="softflow"):
        sim = _sim(s2, duration=0.01)
    assert "_Reads 'reads' is called back in Python, not compiled: " in caplog.text
    assert why in caplog.text
    assert _user_row(sim)[1][U0] == usercall.ADDRESS
    assert sim.run().success


def test_an_unwritable_cache_compiles_in_a_temporary_directory(tmp_path, monkeypatch):
    """Where the cache directory cannot be written, one RuntimeWarning, and
    the kernel is compiled in a temporary directory for this process."""
    blocked = tmp_path / "a-file"
    blocked.write_text("")
    monkeypatch.setattr(usercompile, "cache_root", lambda: blocked / "kernels")
    monkeypatch.setattr(usercompile, "_LOADED", {})
    with pytest.warns(RuntimeWarning, match="cannot write compiled user components"):
        assert usercompile.kernel_address(_kernel_of(_leaky(3e-9)))


def test_no_kernel_where_numba_is_off(monkeypatch):
    """Pure-Python mode (NUMBA_DISABLE_JIT=1) and COMPILED_USER_CODE = False
    call the component back."""
    uk = _kernel_of(_leaky())
    monkeypatch.setattr(usercompile.numba.config, "DISABLE_JIT", True)
    assert usercompile.kernel_address(uk) is None
    monkeypatch.setattr(usercompile.numba.config, "DISABLE_JIT", False)
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    assert usercompile.kernel_address(uk) is None


def test_a_python_function_signal_is_compiled_and_gives_its_values():
    """The paper's source (``lambda t: p0 + (0.3e5 if t < 0.5 else 0)``, p0
    in its closure) is compiled: its C function gives the signal's values,
    bit for bit, on both sides of its step."""
    import ctypes
    source = paper_system(inertance=False).get("source")
    signal = source.signal
    address, key = usercompile.signal_address(signal)
    assert address and key          # p0, a run-time float: the key its array's address
    assert list(signal._softflow_runtime[1]) == [sf.pressure_atmospheric]
    call = ctypes.CFUNCTYPE(ctypes.c_double, ctypes.c_int64, ctypes.c_double)(address)
    for t in (0.0, 0.1, 0.4999999, 0.5, 0.7, 3.0):
        assert call(key, t) == signal(t)


def _step_source(amplitude):
    return lambda t: P0 + (amplitude if t < 0.02 else 0.0)


def test_a_signal_loop_over_closure_floats_compiles_once(fresh_root, monkeypatch):
    """A source's function over a closure's float: one compile for every
    value, each run its own value, the call-back's numbers."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    monkeypatch.setattr(settings, "USER_COMPILES_MAX", 1)
    for amplitude in (1e4, 2e4, 3e4):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            sim = sf.Simulation(_signalled(_step_source(amplitude)), duration=0.05, step=1e-3)
            floats = sim.asm.residual.network.source_arrays()[5]
            assert floats[1] != usercall.SIGNAL_ADDRESS          # compiled, not called back
            a = sim.run()
            monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
            b = sf.Simulation(_signalled(_step_source(amplitude)), duration=0.05,
                              step=1e-3).run()
            monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
        np.testing.assert_array_equal(a.X, b.X)
    assert len(usercompile._LOADED) == 1


def _signalled(signal):
    s = sf.System()
    s += sf.PressureSource("source", pressure=signal)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    s += sf.Container("tank", sf.air, volume=1e-5)
    s.connect("tube", "source")
    s.connect("tube", "tank")
    return s


def _breaking(t):
    if t > 0.02:
        raise ValueError("the user's signal broke")
    return P0 + 3e4 * min(t / 0.01, 1.0)


@pytest.mark.parametrize("step", [1e-3, None])
def test_an_error_raised_in_a_compiled_signal_is_the_python_paths(monkeypatch, step):
    """A compiled signal that raises: the run fails with the Python path's
    message, naming the source; before that, the same numbers."""
    assert usercompile.signal_address(sf.PressureSource("s", pressure=_breaking).signal)
    kw = {"duration": 0.05} if step is None else {"duration": 0.05, "step": step}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        a = sf.Simulation(_signalled(_breaking), **kw).run(raise_on_failure=False)
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
        b = sf.Simulation(_signalled(_breaking), **kw).run(raise_on_failure=False)
    assert a.status == b.status == "failed"
    assert "PressureSource 'source'" in a.message and "the user's signal broke" in a.message
    assert a.message == b.message
    assert len(a.times) == len(b.times)
    np.testing.assert_allclose(a.X, b.X, rtol=1e-10, atol=0)


def test_a_signal_returning_quantities_is_called_back(caplog):
    """A function returning pint Quantities (its units checked at each call)
    is not compiled: called back, and it runs."""
    source = sf.PressureSource("source", pressure=lambda t: sf.Q_(1.2 + t, "bar"))
    with caplog.at_level(logging.DEBUG, logger="softflow"):
        assert usercompile.signal_address(source.signal) is None
    assert "PressureSource 'source': pressure is called back in Python" in caplog.text
    res = sf.Simulation(_signalled(lambda t: sf.Q_(1.2 + t, "bar")), duration=0.02).run()
    assert res.success


def _chamber_scene():
    from helpers import UserChamber
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 1e4)
    s += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
    s += UserChamber("tank")
    s.connect("tube", "src")
    s.connect("tube", "tank")
    return s


def test_variants_of_a_compiled_user_scene_run_on_their_own_clocks():
    """A compiled user component reads the arrays it is given: a batched
    sweep of its scene runs each variant in the compiled loop on its own
    clock (softflow.solve.variants), each with its own serial run's steps
    and end."""
    from softflow.solve import variants
    from softflow.solve.batched import _run_batched
    sim = _sim(_chamber_scene(), duration=0.05)
    assert variants.reason_not(sim) is None
    chosen = [{"tube.diameter": d} for d in (0.8e-3, 1.2e-3)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        out = _run_batched(sim, chosen, own_clocks=True)
        serial = [sim.run(params=v) for v in chosen]
    for b, run in zip(out, serial):
        assert b.success and b.stats.get("engine") == "compiled loop", b.stats
        assert b.stats["steps"] == run.stats["steps"]
        np.testing.assert_allclose(b.get("tank", "pressure")[-1],
                                   run.get("tank", "pressure")[-1], rtol=1e-9)


def test_components_alike_but_for_their_labels_share_one_kernel(fresh_root, monkeypatch):
    """Six chambers of one class and values: one kernel (its text names no
    component), however many there are."""
    from helpers import UserChamber
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 1e4)
    for i in range(6):
        s += sf.CircularTube(f"tube{i}", sf.water, length=0.3, diameter=1e-3)
        s += UserChamber(f"tank{i}")
        s.connect(f"tube{i}", "src")
        s.connect(f"tube{i}", f"tank{i}")
    sim = _sim(s, duration=0.01)
    net = sim.asm.residual.network
    assert len(net.kernels) == 6 and not net.callbacks
    assert len(usercompile._LOADED) == 1 and len(list(fresh_root.glob("*.py"))) == 1
    assert sim.run().success


def _conductance(dp):
    """A user's helper function (compiled with the function that calls it)."""
    return 1e-9 * math.tanh(dp / 1e3) * 1e3 / np.maximum(np.abs(dp), 1e3) * np.sign(dp) ** 2


def test_helper_functions_numpy_and_math_compile_with_the_component(monkeypatch):
    """An evaluate that calls the user's own helper function, NumPy and
    math (module globals) is compiled, and runs as called back."""
    def leaky():
        s = _leaky()
        leak = s.get("leak")
        leak.evaluate = leak.auto(lambda p, mf: [mf - _conductance(p - P0) * (p - P0)])
        return s
    sim = _sim(leaky(), duration=0.05)
    assert _user_row(sim)[1][U0] != usercall.ADDRESS
    a, b = _both(leaky, monkeypatch, duration=0.05)
    assert a.success and b.success and a.stats["steps"] == b.stats["steps"]
    np.testing.assert_allclose(a.X, b.X, rtol=1e-12, atol=0)


def test_an_update_states_dict_is_compiled_as_a_tuple_of_the_same_values():
    """update_state's ``return {'state': value}`` (every return, a lambda's
    body) is compiled as a tuple of the same expressions in the same order
    (numba's typed dict takes seconds to compile); anything else keeps its
    dict."""
    def two_returns(dt, a, b, mf):
        if mf > 0:
            return {"b": b + dt, "a": a + mf * dt}
        return {"b": b - dt, "a": a}

    def other_orders(dt, a, b, mf):
        if mf > 0:
            return {"b": b + dt, "a": a + mf * dt}
        return {"a": a, "b": b}

    def named(dt, a, b, mf):
        d = {"a": a, "b": b}
        return d

    def rewritten(f):
        return usercompile.tuple_update(f, usercompile.imaged(f)[0], ["a", "b"])
    fn, order = rewritten(two_returns)
    assert order == [1, 0]
    assert fn(0.1, 1.0, 2.0, 3.0) == (2.1, 1.0 + 3.0 * 0.1)
    assert fn(0.1, 1.0, 2.0, -3.0) == (2.0 - 0.1, 1.0)
    assert rewritten(other_orders) is None and rewritten(named) is None
    up = lambda dt, mass, mf: {"mass": mass + mf * dt}    # noqa: E731
    fn, order = usercompile.tuple_update(up, usercompile.imaged(up)[0], ["mass"])
    assert fn(0.5, 1.0, 2.0) == (2.0,) and order == [0]
    # a function whose source is not its code (no source, or edited since)
    space: dict = {}
    exec("def made(dt, a, b, mf):\n    return {'a': a, 'b': b}\n", space)
    assert rewritten(space["made"]) is None
    node = __import__("ast").parse("def two_returns(dt, a, b, mf):\n    return {'a': a}\n")
    assert not usercompile._compiles_to(node.body[0], two_returns.__code__)


def _kept(label, after):
    """A chamber whose update_state returns a dict made before its return
    (compiled as numba's typed dict), with an extra key past ``after``."""
    from helpers import UserChamber

    def update_state(dt, mass, mf):
        out = {"mass": mass + mf * dt}
        if mass > after:
            out["extra"] = 0.0
        return out
    tank = UserChamber(label)
    tank.update_state = tank.auto_state(update_state)
    return tank


def test_a_dict_kept_as_written_runs_and_an_extra_state_is_refused(monkeypatch):
    """update_state's dict compiled as numba's dict gives the call-back's
    run; an answer with a state the component does not have stops the run
    with the Python path's message."""
    def scene(after):
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 1e4)
        s += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
        s += _kept("tank", after)
        s.connect("tube", "src")
        s.connect("tube", "tank")
        return s
    sim = _sim(scene(np.inf), duration=0.05)
    assert _user_row(sim)[1][U0] != usercall.ADDRESS
    a, b = _both(lambda: scene(np.inf), monkeypatch, duration=0.05)
    assert a.success and b.success
    np.testing.assert_allclose(a.X, b.X, rtol=1e-12, atol=0)
    a, b = _both(lambda: scene(1.0e-3 + 1e-9), monkeypatch, duration=0.05)
    assert a.status == b.status == "failed"
    assert "unknown ['extra']" in a.message and a.message == b.message


def _sqrt_scene(limit):
    """A tank whose user-written leak takes math.sqrt of limit - p: negative
    (Python raises, numba gives nan) once the tank's pressure passes it."""
    s = _leaky()
    leak = s.get("leak")
    leak.evaluate = leak.auto(lambda p, mf: [mf - 1e-12 * math.sqrt(limit - p)])
    return s


def test_what_numbas_math_gives_for_pythons_errors_is_handed_back(monkeypatch):
    """math.sqrt of a negative number: nan in numba, ValueError in Python;
    a residual that is not finite is handed back, and the run stops with the
    Python path's message."""
    assert _user_row(_sim(_sqrt_scene(1.3e5), duration=0.05))[1][U0] != usercall.ADDRESS
    a, b = _both(lambda: _sqrt_scene(1.3e5), monkeypatch, duration=0.05)
    assert a.status == b.status == "failed"
    assert "math domain error" in a.message and a.message == b.message


def test_a_nonlocal_in_update_state_builds_and_runs(monkeypatch):
    """Source that does not compile on its own (``nonlocal``) is not
    rewritten: the component is compiled or called back, and runs."""
    from helpers import UserChamber
    def scene():
        count = 0

        def update_state(dt, mass, mf):
            nonlocal count
            return {"mass": mass + mf * dt}
        s = sf.System()
        s += sf.PressureSource("src", pressure=P0 + 1e4)
        s += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
        tank = UserChamber("own")
        tank.update_state = tank.auto_state(update_state)
        s += tank
        s.connect("tube", "src")
        s.connect("tube", "own")
        return s
    a, b = _both(scene, monkeypatch, duration=0.02)
    assert a.success and b.success
    np.testing.assert_allclose(a.X, b.X, rtol=1e-12, atol=0)


def test_a_value_changed_after_the_simulation_was_built_is_seen(monkeypatch):
    """The kernel holds the values its functions read as constants: where
    one changes between building the Simulation and running it (or between
    two runs), the run takes the kernel of the values now, as the call-back
    reads them; a value compiled code cannot read is called back."""
    def scene():
        s = _leaky()
        leak = s.get("leak")
        leak.evaluate = leak.auto(lambda p, mf: [mf - K_LEAK * (p - P0)])
        return s
    monkeypatch.setitem(globals(), "K_LEAK", 1e-9)
    sim = _sim(scene(), duration=0.05)
    first = sim.run()
    monkeypatch.setitem(globals(), "K_LEAK", 3e-9)
    second = sim.run()
    fresh = _sim(scene(), duration=0.05).run()
    tank = second.get("tank", "pressure")
    np.testing.assert_allclose(tank, fresh.get("tank", "pressure"), rtol=1e-6)
    assert abs(tank[-1] - first.get("tank", "pressure")[-1]) > 100.0
    net = sim.asm.residual.network
    assert not net.callbacks
    monkeypatch.setitem(globals(), "K_LEAK", {"not": "a number"})     # not compiled
    for _ in range(3):
        with pytest.raises(Exception):
            sim.run()
    assert len(net.callbacks) == 1          # one call-back, not one a run
    monkeypatch.setitem(globals(), "K_LEAK", 3e-9)                    # compiled again
    again = sim.run()
    np.testing.assert_allclose(again.get("tank", "pressure"), tank, rtol=1e-6)
    (gi, g, key, lay, plan), = net.watched
    assert net.groups[gi, U0] != usercall.ADDRESS and net.groups[gi, OPTION] == lay.ctypes.data


def _curve(scale):
    """The balloon's PV curve with its pressures' rise scaled by ``scale``."""
    base = sf.PVCurve(str(balloon_csv()))
    v = base._knots
    p = np.array([base.fdf_volume(volume=x)[0] for x in v])
    return sf.PVCurve(volume=v, pressure=P0 + scale * (p - P0), gauge=False)


def test_closure_floats_fluids_and_curves_are_run_time_values_of_one_kernel(fresh_root,
                                                                           monkeypatch):
    """The paper's actuator reads a curve, a fluid and a float from its
    closure: actuators of other curves, fluids and floats share one kernel
    (one compile), each reading its own values from its layout, and each
    run is the call-back's bit for bit at fixed steps."""
    glycol = sf.ConstantLiquid("glycol", density=1110.0, viscosity=1.6e-2)
    cases = [(sf.water, 1.0, np.inf), (glycol, 1.0, 5.0), (sf.water, 1.3, np.inf),
             (glycol, 0.8, 7.0)]

    def make(fluid, scale, after):
        def build():
            s = sf.System()
            s += sf.PressureSource("source", pressure=P0 + 0.3e5)
            s += sf.CircularTube("tube", fluid, length=0.6, diameter=1e-3)
            s += _Actuator("actu", fluid, _curve(scale), after)
            s.connect("tube", "source")
            s.connect("tube", "actu")
            return s
        return build

    monkeypatch.setattr(settings, "USER_COMPILES_MAX", 1)
    ends = set()
    for fluid, scale, after in cases:
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
        a, b = _both(make(fluid, scale, after), monkeypatch, duration=0.3, step=1e-3)
        assert a.success and b.success
        np.testing.assert_array_equal(a.X, b.X)
        np.testing.assert_array_equal(a.S, b.S)
        ends.add(round(float(a.get("actu", "pressure")[-1]), 3))
    assert len(ends) == len(cases)                  # each its own values
    assert len(usercompile._LOADED) == 1            # one kernel (one compile) for all
    name, = usercompile._LOADED
    assert not list(fresh_root.glob("*.failed"))


def test_a_closure_value_changed_between_runs_is_read_again_or_compiled(fresh_root,
                                                                        monkeypatch):
    """A run-time float changed between runs (the closure's cell set anew) is
    read into the layout at the next run, the kernel kept; where the value
    becomes another kind (a tuple, compiled in as a constant) the run takes
    a kernel of its own, and the answers are the call-back's."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    sim = _sim(_leaky(1e-9), duration=0.05)
    net = sim.asm.residual.network
    (gi, g, key, lay, plan), = net.watched
    assert [var for _, var, _ in plan] == ["k", "P0"]      # (P0: the module's float)
    first = sim.run()
    func = g.row.ev.func
    cell = func.__closure__[func.__code__.co_freevars.index("k")]
    cell.cell_contents = 4e-9
    second = sim.run()
    assert net.watched[0][3] is lay and len(usercompile._LOADED) == 1
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    ref = _sim(_leaky(4e-9), duration=0.05).run()
    # (the second run starts from the first's consistent point, solved again)
    np.testing.assert_allclose(second.X, ref.X, rtol=1e-9, atol=1e-15)
    assert abs(second.get("tank", "pressure")[-1] - first.get("tank", "pressure")[-1]) > 1.0
    # a float no longer: a kernel of its own, which reads it as a constant
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    cell.cell_contents = np.array([4e-9])[0].astype(np.float32)
    third = sim.run()
    assert len(usercompile._LOADED) == 2 and not net.callbacks
    assert [var for _, var, _ in net.watched[0][4]] == ["P0"]     # k now a constant
    np.testing.assert_allclose(third.get("tank", "pressure"), ref.get("tank", "pressure"),
                               rtol=1e-6)


def test_a_design_loop_over_closure_floats_compiles_once(fresh_root, monkeypatch):
    """Past settings.USER_COMPILES_MAX values of a closure's float, every
    run is still compiled: one kernel, each value its own answer."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    monkeypatch.setattr(settings, "USER_COMPILES_MAX", 1)
    ends = []
    for k in (1e-9, 2e-9, 3e-9, 5e-9, 8e-9):
        sim = _sim(_leaky(k), duration=0.05)
        assert not sim.asm.residual.network.callbacks
        ends.append(sim.run().get("tank", "pressure")[-1])
    assert len(usercompile._LOADED) == 1
    assert np.all(np.diff(ends) < 0)                # more leak, less pressure


class _GainChamber(sf.Component):
    """A user's chamber whose update_state reads a float from its closure
    (and returns the paper's dict)."""

    def __init__(self, label, gain):
        super().__init__(label)
        p = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf = sf.Variable("massflow", "through", label="mf")
        m = sf.Variable("mass", "local", label="mass", initial_value=1e-3)
        self.set_terminals(sf.Terminal("a", [p, mf]))
        self.set_states(m)
        self.evaluate = self.auto(lambda t, p, mass: [p - (P0 + 1e9 * (mass - 1e-3))])

        def update_state(dt, mass, mf):
            return {"mass": mass + gain * mf * dt}
        self.update_state = self.auto_state(update_state)


def _gain_scene(gain):
    def build():
        s = sf.System()
        s += sf.PressureSource("src", pressure=1.3e5)
        s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
        s += _GainChamber("tank", gain)
        s.connect("tube", "src")
        s.connect("tube", "tank")
        return s
    return build


def test_an_update_states_closure_float_is_a_run_time_value(fresh_root, monkeypatch):
    """update_state's closure float is its run-time argument (its dict still
    compiled as a tuple): one kernel for two gains, each run the
    call-back's bit for bit at fixed steps."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    for gain in (1.0, 0.5):
        sim = _sim(_gain_scene(gain)(), duration=0.02, step=1e-3)
        (gi, g, key, lay, plan), = sim.asm.residual.network.watched
        assert plan == ((0, "P0", "float"), (1, "gain", "float"))
        text = next(fresh_root.glob("*.py")).read_text()
        assert "o = up(dt, o0, v1, a1)" in text         # gain: read from the layout
        a = sim.run()
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
        b = _sim(_gain_scene(gain)(), duration=0.02, step=1e-3).run()
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
        np.testing.assert_array_equal(a.X, b.X)
        np.testing.assert_array_equal(a.S, b.S)
    assert len(usercompile._LOADED) == 1
    assert "n0 = float(o[0])" in text                   # the dict as a tuple


def test_kernels_unused_for_a_month_are_deleted_at_a_processs_first_compile(fresh_root,
                                                                          monkeypatch):
    """Modules, numba's cache files of them and refusal markers not used for
    settings.USER_CACHE_DAYS days go at the first compile of a process; those
    used since stay, and a kernel loaded is marked used (a marker beside it:
    the module's own time is left alone, which numba before 0.68 checks its
    cache against)."""
    import os
    import time
    fresh_root.mkdir(parents=True)
    (fresh_root / "__pycache__").mkdir()
    month = time.time() - 31 * 86400.0
    old = [fresh_root / "softflow_user_old.py", fresh_root / "softflow_user_gone.failed",
           fresh_root / "__pycache__" / "softflow_user_old.kernel-70.py311.nbi",
           fresh_root / "__pycache__" / "softflow_user_old.kernel-70.py311.1.nbc"]
    kept = [fresh_root / "softflow_user_new.py",
            fresh_root / "__pycache__" / "softflow_user_new.kernel-70.py311.nbi",
            fresh_root / "other.txt"]
    for p in old + kept:
        p.write_text("", encoding="utf-8")
    for p in old + [kept[2]]:
        os.utime(p, (month, month))
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    uk = _kernel_of(_leaky(1e-9))
    assert usercompile.kernel_address(uk)
    assert not any(p.exists() for p in old) and all(p.exists() for p in kept)
    (name, _), = usercompile._LOADED.items()
    module = fresh_root / f"{name}.py"
    used = fresh_root / f"{name}.py.used"
    for p in (module, used):
        os.utime(p, (month, month))
    usercompile._LOADED.clear()
    sys.modules.pop(name)
    assert usercompile.kernel_address(uk)            # loaded from numba's cache: marked
    assert usercompile._LOADED[name][0].kernel.cache_hits == 1
    assert used.stat().st_mtime > time.time() - 3600.0
    assert module.stat().st_mtime == pytest.approx(month)


class _Balloon(sf.Component):
    """writing-a-component's example: state_rates, and a module's number
    (sf.pressure_atmospheric) and a closure's float read by evaluate."""

    def __init__(self, label, stiffness=1e10):      # [Pa/kg]
        super().__init__(label)
        self.set_terminals(sf.Terminal("a", [sf.Variable("pressure", "across", label="p"),
                                             sf.Variable("massflow", "through", label="mf")]))
        self.set_states(sf.Variable("mass", "local", label="mass", initial_value=1e-6))
        self.evaluate = self.auto(
            lambda p, mass: [p - (sf.pressure_atmospheric + stiffness * (mass - 1e-6))])
        self.state_rates = self.auto_rates(lambda mf: {"mass": mf})   # d(mass)/dt


def _balloon_scene():
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.3e5)
    s += sf.CircularTube("tube", sf.water, length=0.3, diameter=1e-3)
    s += _Balloon("balloon")
    s.connect("tube", "src")
    s.connect("tube", "balloon")
    return s


@pytest.mark.parametrize("step", [1e-3, None])
def test_state_rates_and_a_modules_numbers_are_compiled(monkeypatch, step):
    """A component giving state_rates (the guide's Balloon, which also reads
    sf.pressure_atmospheric) is compiled, and runs as called back: bit for
    bit, at fixed steps and adaptive."""
    kw = {"duration": 0.2} if step is None else {"duration": 0.2, "step": step}
    sim = _sim(_balloon_scene(), **kw)
    assert _user_row(sim)[1][U0] != usercall.ADDRESS
    assert_user_rows_are_the_python_paths(sim, seed=3)
    a, b = _both(_balloon_scene, monkeypatch, **kw)
    assert a.success and b.success and a.stats["steps"] == b.stats["steps"]
    np.testing.assert_array_equal(a.X, b.X)
    np.testing.assert_array_equal(a.S, b.S)


class _Method(sf.Component):
    """The paper's actuator written with methods that read the component's
    attributes (a curve, a fluid, a float)."""

    def __init__(self, label, fluid, curve, gain=1.0):
        super().__init__(label)
        p_ = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf_ = sf.Variable("massflow", "through", label="mf")
        m_ = sf.Variable("mass", "local", label="mass", initial_value=1e-3)
        self.set_terminals(sf.Terminal("a", [p_, mf_]))
        self.set_states(m_)
        self.fluid, self.curve, self.gain = fluid, curve, gain
        self.evaluate = self.auto(self.residual)
        self.update_state = self.auto_state(self.update)

    def residual(self, t, p, mass):
        return [p - self.curve.fdf_volume(volume=mass / self.fluid.rho)[0]]

    def update(self, dt, mass, mf):
        return {"mass": mass + self.gain * mf * dt}


def _method_scene(comp):
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 0.3e5)
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += comp
    s.connect("tube", "src")
    s.connect("tube", comp.label)
    return s


def test_methods_and_closures_reading_the_components_attributes_are_compiled(fresh_root,
                                                                            monkeypatch):
    """Bound methods (``self.auto(self.residual)``) and lambdas that read
    ``self.k`` are compiled, the attributes read as the closures' values
    are (curves, fluids and floats at run time, one kernel for all): bit for
    bit the call-back's runs; an attribute changed between runs is seen."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    curve = sf.PVCurve(str(balloon_csv()))
    for gain in (1.0, 0.7):
        make = lambda: _method_scene(_Method("act", sf.water, curve, gain))  # noqa: E731
        sim = _sim(make(), duration=0.3, step=1e-3)
        (gi, g, key, lay, plan), = sim.asm.residual.network.watched
        assert {(i, var, kind) for i, var, kind in plan} == {
            (0, "_sf_4_self_curve", "curve"), (0, "_sf_4_self_fluid", "fluid"),
            (1, "_sf_4_self_gain", "float")}
        a, b = _both(make, monkeypatch, duration=0.3, step=1e-3)
        np.testing.assert_array_equal(a.X, b.X)
        np.testing.assert_array_equal(a.S, b.S)
    assert len(usercompile._LOADED) == 1
    # an attribute changed between runs: read again (the kernel kept)
    comp = _Method("act", sf.water, curve, 1.0)
    sim = _sim(_method_scene(comp), duration=0.3, step=1e-3)
    first = sim.run()
    comp.gain = 0.7
    second = sim.run()
    assert len(usercompile._LOADED) == 1
    np.testing.assert_allclose(second.get("act", "mass"), a.get("act", "mass"), rtol=1e-9)
    assert abs(second.get("act", "mass")[-1] - first.get("act", "mass")[-1]) > 1e-6
    # a lambda over self reading self.k
    leaky = _leaky()
    leak = leaky.get("leak")
    leak.k = 2e-9
    leak.evaluate = leak.auto(lambda p, mf: [mf - leak.k * (p - P0)])
    sim = _sim(leaky, duration=0.05, step=1e-3)
    assert not sim.asm.residual.network.callbacks
    assert sim.asm.residual.network.watched[0][4] == ((0, "_sf_4_leak_k", "float"),
                                                      (0, "P0", "float"))


def _leak_with(ev):
    """_leaky's scene with the leak's evaluate ``ev``."""
    s = _leaky()
    leak = s.get("leak")
    leak.evaluate = leak.auto(ev)
    return s


def _annotated_helper(k):
    def ev(p, mf):
        def g(x: float) -> float:         # (annotations compiled as the user's file does)
            return k * x
        return [mf - g(p - P0)]
    return ev


COEF = (1.0,)


def _with_global(k):
    def ev(p, mf):
        return [mf - k * COEF[0] * (p - P0)]
    return ev


def test_review_cases_of_run_time_values(fresh_root, monkeypatch):
    """A nested annotated helper keeps k a run-time value; constants past
    USER_COMPILES_MAX are called back, not compiled again as constants
    instead of run-time values; a fluid whose density cannot be read at a
    run's start fails that run naming the component, as the call-back."""
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
    sim = _sim(_leak_with(_annotated_helper(1e-9)), duration=0.02, step=1e-3)
    assert sim.asm.residual.network.watched[0][4] == ((0, "k", "float"), (0, "P0", "float"))
    monkeypatch.setattr(settings, "USER_COMPILES_MAX", 2)
    for i in range(1, 5):
        monkeypatch.setitem(globals(), "COEF", (float(i),))
        net = _sim(_leak_with(_with_global(1e-9)), duration=0.01).asm.residual.network
        assert bool(net.callbacks) == (i > 2)
    assert len(list(fresh_root.glob("*.py"))) == 3        # the helper's, COEF 1 and 2

    class Flaky(sf.ConstantLiquid):
        broken = False

        @property
        def rho(self):
            if self.broken:
                raise RuntimeError("rho unavailable")
            return 1000.0
    for compiled in (True, False):
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", compiled)
        fluid = Flaky("flaky", density=1000.0, viscosity=1e-3)
        sim = _sim(_scene_of(fluid), duration=0.05, step=1e-3)
        fluid.broken = True
        res = sim.run(raise_on_failure=False)
        assert res.status == "failed"
        assert res.message == "_Actuator 'actu': evaluate raised at t = 0 s: RuntimeError: " \
            "rho unavailable"


def _scene_of(fluid):
    s = sf.System()
    s += sf.PressureSource("source", pressure=P0 + 0.3e5)
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += _Actuator("actu", fluid, sf.PVCurve(str(balloon_csv())))
    s.connect("tube", "source")
    s.connect("tube", "actu")
    return s


def test_a_nested_functions_parameter_of_a_holders_name_is_not_rewritten(monkeypatch):
    """``obj.rho`` inside a nested function whose parameter is named ``obj``
    reads that parameter, not the closure's object: such a function is
    called back (not rewritten), and runs as the call-back."""
    class Holder:
        rho = 1.0

    def make():
        obj = Holder()

        def ev(p, mf):
            def f(obj):
                return obj.rho
            return [mf - 1e-9 * f(sf.water) * (p - P0) / 1000.0 - 0.0 * obj.rho]
        return _leak_with(ev)
    sim = _sim(make(), duration=0.02, step=1e-3)
    assert sim.asm.residual.network.callbacks
    a = sim.run()
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    np.testing.assert_array_equal(a.X, _sim(make(), duration=0.02, step=1e-3).run().X)


K_SCRIPT = 1e-9


def test_a_loop_over_a_module_global_float_compiles_once(fresh_root, monkeypatch):
    """A script's loop that rebinds a module-level float its component reads
    (``for K in ...:``): the float is a run-time value, one kernel for
    every value, each run the call-back's bit for bit."""
    monkeypatch.setattr(settings, "USER_COMPILES_MAX", 1)
    for k in (1e-9, 2e-9, 4e-9):
        monkeypatch.setitem(globals(), "K_SCRIPT", k)
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", True)
        sim = _sim(_leak_with(lambda p, mf: [mf - K_SCRIPT * (p - P0)]), duration=0.05,
                   step=1e-3)
        assert not sim.asm.residual.network.callbacks
        a = sim.run()
        monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
        b = _sim(_leak_with(lambda p, mf: [mf - K_SCRIPT * (p - P0)]), duration=0.05,
                 step=1e-3).run()
        np.testing.assert_array_equal(a.X, b.X)
    assert len(usercompile._LOADED) == 1
