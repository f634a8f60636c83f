"""Helpers shared by tests: a reference circuit, mass balances under every
time integrator."""
import math

import numpy as np

import softflow as sf


def rc_circuit(p1=sf.pressure_atmospheric + 1e4, tau=0.1, D=0.5e-3, L=1.0, source=None):
    """Laminar water tube charging a linear accumulator (the fluidic RC circuit):
    p = p1 + (P0 - p1) exp(-t / tau), with R = 128 mu L / (pi D^4), C = tau / R
    (``source``: another pressure for the source, e.g. a waveform, than p1)."""
    R = 128 * sf.water.mu * L / (math.pi * D ** 4)
    s = sf.System()
    s += sf.PressureSource("src", pressure=p1 if source is None else source)
    s += sf.CircularTube("tube", sf.water, length=L, diameter=D)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=tau / R)
    s.connect("tube", "src")
    s.connect("tube", "acc")
    return s


def assert_balance(res, stored_change, label, name="massflow", terminal=None, *, scale,
                   sign=1.0, rel=1e-9):
    """stored_change == sign * (time integral of ``label.name`` as the run formed
    it, :meth:`Result.integral`) to ``rel`` of ``scale``: exact but for round-off
    under backward Euler and under every BDF order."""
    supplied = sign * res.integral(label, name, terminal)
    gap = np.abs(stored_change - supplied).max()
    assert gap < rel * scale, (gap / scale, rel)


def tank_and_actuator(D=1e-3, V=1e-5):
    """Air at 1.3 bar through a tube (diameter D) into a tank (volume V), and on
    through a tighter tube into a 20 kPa plateau actuator: smooth, nonlinear,
    with states in two volumes (sensitivity and fitting tests)."""
    from softflow.paper_scenes import curve_plateau
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.Q_(1.3, "bar"))
    s += sf.CircularTube("tube", sf.air, 0.5, D)
    s += sf.Container("tank", sf.air, V)
    s += sf.CircularTube("r", sf.air, 0.3, 0.8e-3)
    s += sf.Actuator("act", sf.air, curve_plateau(20.0))
    s.connect("src", "tube")
    s.connect("tube", "tank")
    s.connect("tank", "r")
    s.connect("r", "act")
    return s


def source_tube_tank(pressure=2e5, tank_fluid=sf.air, **tube):
    """A PressureSource at ``pressure`` [Pa] fills a 10 mL tank of
    ``tank_fluid`` through 0.3 m of 1 mm air tube (``tube``: more CircularTube
    arguments)."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=pressure)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3, **tube)
    s += sf.Container("tank", tank_fluid, volume=1e-5)
    s.connect("tube", "src")
    s.connect("tube", "tank")
    return s


def snapping_valve_scene(pressure=None):
    """A tank filled through a tube from a PressureSource at ``pressure`` (a
    number [Pa] or a function of t; default 30 kPa gauge); a snapping valve
    opens at 20 kPa behind it into a second tank (bursts) and closes at 5 kPa."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.pressure_atmospheric + 3e4
                           if pressure is None else pressure)
    s += sf.CircularTube("tube", sf.air, 0.5, 1e-3)
    s += sf.Container("tank", sf.air, 1e-5)
    s += sf.SnappingValve("valve", sf.air, opening_pressure=2e4, closing_pressure=5e3,
                          closed_conductance=1e-12)
    s += sf.Container("out", sf.air, 1e-5)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    s.connect("tank", ("valve", "a"))
    s.connect(("valve", "b"), "out")
    return s


def chattering_valve_scene():
    """A mass-flow source (2e-5 kg/s) pushing into a snapping valve with no
    volume between them, a 20 mL tank behind: an ill-posed model whose valve
    chatters (opens, the node's pressure falls below its closing pressure at
    once, it closes, ...), each switch at the smallest step."""
    s = sf.System()
    s += sf.MassFlowSource("src", massflow=2e-5)
    s += sf.SnappingValve("valve", sf.air, opening_pressure=2e4, closing_pressure=5e3,
                          closed_conductance=1e-12)
    s += sf.Container("tank", sf.air, 20e-6)
    s.connect("src", "valve")
    s.connect("valve", "tank")
    return s


def filling_tank(source=None, fluid=sf.air, friction="Haaland", **tube):
    """A 10 mL tank of ``fluid`` filled through 0.5 m of 1 mm tube (``friction``,
    more CircularTube arguments in ``tube``) from ``source`` (default a
    PressureSource at 1.3 bar): the batched-variant tests' scene."""
    s = sf.System()
    s += source or sf.PressureSource("src", pressure=sf.Q_(1.3, "bar"))
    s += sf.CircularTube("tube", fluid, 0.5, 1e-3, friction=friction, **tube)
    s += sf.Container("tank", fluid, 1e-5)
    s.connect("src", "tube")
    s.connect("tube", "tank")
    return s


def gauge_reference(sim, variant, label="tank"):
    """(times, gauge pressure of ``label``) of ``variant`` run on ``sim``."""
    res = sim.run(params=variant)
    return res.times, res.get(label, "pressure") - sf.pressure_atmospheric


def gauge_error(res, ref, label="tank"):
    """Largest deviation of ``res``'s gauge pressure of ``label`` from ``ref``
    (:func:`gauge_reference`) at ``res``'s points, over ref's largest value."""
    t, p = ref
    mine = res.get(label, "pressure") - sf.pressure_atmospheric
    return np.max(np.abs(mine - np.interp(res.times, t, p))) / np.max(np.abs(p))


class UserChamber(sf.Component):
    """A user's stiff gas-like chamber written the paper's way (``evaluate`` and
    ``update_state``); ``squared``: its update_state is not affine in dt (a
    term in dt^2), which the adaptive BDF refuses."""

    def __init__(self, label, squared=False):
        super().__init__(label)
        P0 = sf.pressure_atmospheric
        p = sf.Variable("pressure", "across", label="p", initial_value=P0)
        mf = sf.Variable("massflow", "through", label="mf")
        m = sf.Variable("mass", "local", label="mass", initial_value=1e-3)
        self.set_terminals(sf.Terminal("a", [p, mf]))
        self.set_states(m)
        self.evaluate = self.auto(lambda t, p, mass: [p - (P0 + 1e9 * (mass - 1e-3))])
        if squared:
            self.update_state = self.auto_state(
                lambda dt, mass, mf: {"mass": mass + mf * dt + 1e3 * (mf * dt) ** 2})
        else:
            self.update_state = self.auto_state(lambda dt, mass, mf: {"mass": mass + mf * dt})


def crossing_time(t, y, level, i):
    """When y passes ``level`` between the points i - 1 and i (linear between
    them, not t[i]: two runs' adaptive steps differ)."""
    if i == 0:
        return t[0]
    return t[i - 1] + (level - y[i - 1]) / (y[i] - y[i - 1]) * (t[i] - t[i - 1])


def probe_json(source, **env):
    """The JSON the Python ``source`` prints last, run in a fresh interpreter
    with the environment variables ``env`` added (its errors shown where it
    fails)."""
    import json
    import os
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", source], capture_output=True, text=True,
                          env={**os.environ, **env}, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def compiled_and_python(expression, env=None):
    """The value of ``expression`` (Python source giving a list of numbers and
    tuples of numbers, with ``softflow.laws``' modules imported as ``laws``,
    ``friction``, ``gas_pipe``, ``fanno``, ``orifice``, ``tables``) evaluated in a fresh
    interpreter compiled and again with NUMBA_DISABLE_JIT=1: (compiled, python)
    as flat float arrays, after asserting that each process ran in its mode.
    Also returns the compiled process's cache hits of the laws it called."""
    probe = (
        "import json\n"
        "import softflow.laws as laws\n"
        "from softflow.laws import fanno, friction, gas_pipe, orifice, tables\n"
        f"out = {expression}\n"
        "hits = sum(len(f.stats.cache_hits) for m in (fanno, friction, gas_pipe, orifice, tables)\n"
        "           for f in vars(m).values() if hasattr(f, 'stats'))\n"
        "print(json.dumps({'values': out, 'jit': not laws.numba.config.DISABLE_JIT,\n"
        "                  'hits': hits}))\n")

    def run(**extra):
        return probe_json(probe, **(env or {}), **extra)

    compiled, python = run(NUMBA_DISABLE_JIT="0"), run(NUMBA_DISABLE_JIT="1")
    assert compiled["jit"] and not python["jit"]
    flat = [np.hstack(r["values"]).astype(float) for r in (compiled, python)]
    return flat[0], flat[1], compiled["hits"]


def four_point_curve(**kw):
    """A gauge PV curve from 1 to 6 mL (0 to 400 mbar, four samples), with
    PVCurve's keywords ``kw``: the actuator of the bad-input tests."""
    Q_ = sf.Q_
    return sf.PVCurve(volume=Q_([1, 2, 4, 6], "mL"), pressure=Q_([0, 100, 200, 400], "mbar"),
                      gauge=True, **kw)


def actuator_scene(act, source=2e5, fluid=sf.air):
    """A pressure source (``source`` [Pa]) filling the actuator ``act`` through
    a 0.3 m x 1 mm tube of ``fluid``."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=source)
    s += sf.CircularTube("tube", fluid, length=0.3, diameter=1e-3)
    s += act
    s.connect("tube", "src")
    s.connect("tube", act.label)
    return s


def check_valve_pulses():
    """Pulses of 1 bar through a tube and a check valve into a tank that
    leaks to the atmosphere through a thin tube: the valve opens and shuts
    at every pulse."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=sf.waveforms.Square(2e5, sf.pressure_atmospheric,
                                                                2.0))
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=2e-3)
    s += sf.CheckValve("cv", sf.air, cracking_pressure=5e3, diameter=2e-3)
    s += sf.Container("tank", sf.air, volume=1e-4)
    s += sf.CircularTube("leak", sf.air, length=0.5, diameter=0.3e-3)
    s += sf.PressureSource("atm", pressure=sf.pressure_atmospheric)
    s.connect("src", "tube")
    s.connect("tube", "cv")
    s.connect(("cv", "b"), "tank", ("leak", "a"))
    s.connect(("leak", "b"), "atm")
    return s


def assert_user_rows_are_the_python_paths(sim, seed, trials=20):
    """At random states, steps and times: the compiled network residual of
    ``sim`` (a scene with one user component) is the per-group Python
    path's to round-off, its Jacobian entries too, the user component's
    rows and entries bit for bit, and the end-of-step states the same."""
    asm = sim.asm
    g = next(g for g in asm.groups if g.row is not None)
    rng = np.random.default_rng(seed)
    for trial in range(trials):
        x = asm.x0 * (1 + 0.1 * rng.standard_normal(asm.n))
        S = asm.S0 * (1 + 0.05 * rng.standard_normal(asm.S0.size))
        t, dt = rng.uniform(0, 1), 10 ** rng.uniform(-6, -2)
        F = asm.residual(x, S, t, dt, True)
        raw = asm.raw.copy()
        Fp = asm.python_residual(x, S, t, dt, True)
        np.testing.assert_allclose(F, Fp, rtol=1e-13, atol=1e-12 * np.abs(Fp).max())
        np.testing.assert_allclose(raw, asm.raw, rtol=1e-13, atol=1e-300)
        assert np.array_equal(F[g.r0:g.r1], Fp[g.r0:g.r1]), trial
        assert np.array_equal(raw[g.j0:g.j1], asm.raw[g.j0:g.j1]), trial
        np.testing.assert_array_equal(asm.residual.network.update_states(x, S, dt),
                                      asm.update_states(x, S, dt))
