"""The compiled loop's end-of-step states (the ``Sout`` of
softflow.laws.network.residual, softflow.solve.netcore's compiled_update and
CompiledNetwork): in every scene of the compiled residual's tests (every
class it covers, isothermal and thermal), at random states and steps, they
are the assembly's ``update_states(x, psi, c)`` bitwise, the discrete ones
on both sides of their switches (snapping valves across their opening and
closing pressures, hysteretic actuators past V_hi and V_lo, free and held in
thermal scenes, with the work offset a change of branch moves)."""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow.laws import network as net
from softflow.solve import netcore

sys.path.insert(0, str(Path(__file__).resolve().parent / "solve"))
from test_netcore import SCENES, THERMAL_SCENES, _sim  # noqa: E402

NAMES = list(SCENES) + list(THERMAL_SCENES)
P0 = sf.pressure_atmospheric

#: the classes whose groups hold states (each must appear in the scenes)
WITH_STATES = {net.RIGID_GAS, net.RIGID_LIQUID, net.ACCUMULATOR, net.SNAPPING_VALVE,
               net.INERTIAL_TUBE, net.ACTUATOR, net.HYSTERETIC_ACTUATOR, net.FREE_VOLUME,
               net.HELD_VOLUME, net.THERMAL_SNAPPING_VALVE, net.THERMAL_INERTIAL_TUBE}


def _random_point(asm, rng):
    """Unknowns and states near the initial ones (as the residual's tests
    draw them), a step coefficient c of 1e-6 ... 1e-2 s."""
    x = asm.x0 * (1.0 + 0.05 * rng.standard_normal(asm.n)) + 1e-6 * rng.standard_normal(asm.n)
    S = asm.S0 * (1.0 + 0.05 * rng.standard_normal(asm.S0.size))
    return x, S, float(10.0 ** rng.uniform(-6, -2))


def _across_switches(asm, x, S, c, k, rng):
    """Put every discrete state of draw ``k`` on one side of its switch, the
    draws cycling through all: a snapping valve open or shut with p_a - p_b
    above its opening pressure, below its closing one or between; a
    hysteretic actuator on either branch ending the step above V_hi, below
    V_lo or between (its mass at the step's start set for that volume), a
    free gas's work offset drawn. Returns [(class id, mode before, region)]."""
    set_up = []
    for g in asm.groups:
        cls_id, option = netcore._covered(g)[:2]
        P = g.params
        for i in range(g.n):
            V = g.col[i]
            s = g.s0 + g.ns * i
            old = float((k + i) % 2)
            region = (k // 2 + i) % 3              # 0 above, 1 below, 2 between
            if cls_id in (net.SNAPPING_VALVE, net.THERMAL_SNAPPING_VALVE):
                hi, lo = P.opening_pressure[i], P.closing_pressure[i]
                dp = (hi + 500.0, lo - 500.0, 0.5 * (hi + lo))[region]
                pb = x[V[4 if cls_id == net.THERMAL_SNAPPING_VALVE else 2]]
                x[V[0]] = pb + dp
                S[s] = old
                set_up.append((cls_id, old, region))
            loop = (cls_id == net.HYSTERETIC_ACTUATOR
                    or cls_id in (net.FREE_VOLUME, net.HELD_VOLUME) and option == 3)
            if loop:
                v_hi, v_lo = P.loop.volume_high, P.loop.volume_low
                vol = (1.05 * v_hi, 0.95 * v_lo, 0.5 * (v_hi + v_lo))[region]
                p, mf = x[V[0]], x[V[1]]
                rho = (P.fluid.density(p) if cls_id == net.HYSTERETIC_ACTUATOR
                       else P.fluid.density(p, x[V[2]]))
                S[s] = vol * rho - c * mf
                free = cls_id == net.FREE_VOLUME
                S[s + (2 if free else 1)] = old
                if free:
                    S[s + 3] = 1e-3 * rng.standard_normal()
                set_up.append((cls_id, old, region))
    return set_up


def _both_sides(seen):
    """Each switching class met each mode before the step in each region."""
    for cls_id in {c for c, _, _ in seen}:
        cases = {(old, region) for c, old, region in seen if c == cls_id}
        assert cases == {(o, r) for o in (0.0, 1.0) for r in range(3)}, cls_id


@pytest.mark.parametrize("name", NAMES)
def test_the_compiled_update_is_update_states(name):
    """compiled_update(asm)(x, psi, c) == asm.update_states(x, psi, c), every
    entry, bitwise: the continuous states are psi + c·rate with the rate's
    own arithmetic (a tube's inertance 1/(L/A) the class's own k, p / (R T)
    the gas's own density), the modes the same comparisons."""
    asm = _sim(name).asm
    update = netcore.compiled_update(asm)
    assert update is not None
    rng = np.random.default_rng(11)
    seen = []
    for k in range(24):
        x, S, c = _random_point(asm, rng)
        seen += _across_switches(asm, x, S, c, k, rng)
        want = asm.update_states(x, S, c)
        got = update(x, S, c)
        assert got is not S and got.shape == want.shape
        np.testing.assert_array_equal(got, want)
    _both_sides(seen)


@pytest.mark.parametrize("name", NAMES)
def test_the_loop_called_directly(name):
    """CompiledNetwork's arrays called as the compiled step loop will: every
    entry of Sout written (none left at its nan), F and the Jacobian's
    entries those of the assembly's residual whether Sout is asked for or
    not (NO_STATES), after set_time where the scene varies with time."""
    asm = _sim(name).asm
    network = asm.residual.network
    assert isinstance(network, netcore.CompiledNetwork)
    assert network.no_states is netcore.NO_STATES and netcore.NO_STATES.size == 0
    rng = np.random.default_rng(5)
    for k in range(6):
        x, S, c = _random_point(asm, rng)
        _across_switches(asm, x, S, c, k, rng)
        t = float(rng.uniform(0, 0.05))
        if asm.has_begin_step:
            asm.begin_step(x, S)
        asm.raw[:] = np.nan                   # (the node rows' entries are set once)
        F_ref = asm.residual(x, S, t, c, True)
        raw_ref = asm.raw.copy()
        network.set_time(t)
        for Sout in (np.full(S.size, np.nan), network.no_states):
            F = np.full(network.n, np.nan)
            asm.raw[:] = np.nan
            assert network.loop(x, S, t, c, True, F, *network.arrays, Sout) == -1
            np.testing.assert_array_equal(F, F_ref)
            np.testing.assert_array_equal(asm.raw, raw_ref)
            if Sout.size:
                np.testing.assert_array_equal(Sout, asm.update_states(x, S, c))


def test_every_class_with_states_is_exercised():
    """The scenes above hold every class of the loop that has states, and
    every wall of a thermal volume, free and held."""
    classes, walls = set(), set()
    for name in NAMES:
        for g in _sim(name).asm.groups:
            cls_id, option = netcore._covered(g)[:2]
            if g.ns:
                classes.add(cls_id)
            if cls_id in (net.FREE_VOLUME, net.HELD_VOLUME):
                walls.add((cls_id, option))
    assert classes == WITH_STATES
    assert walls == {(v, w) for v in (net.FREE_VOLUME, net.HELD_VOLUME) for w in range(4)}


def test_a_state_a_curve_refuses_is_updated_on_the_per_group_path():
    """An actuator past the data of a curve that does not extrapolate: the
    loop stops there (its Sout incomplete), and compiled_update gives the
    per-group path's states (which only add the mass flow)."""
    def build():
        s = sf.System()
        s += sf.PressureSource("ps", pressure=P0 + 2e4)
        s += sf.CircularTube("t", sf.water, 0.3, 1e-3)
        curve = sf.PVCurve(volume=[1e-6, 2e-6, 3e-6], pressure=[P0, P0 + 2e4, P0 + 3e4],
                           extrapolate="error")
        s += sf.Actuator("act", sf.water, curve, initial_volume=1.5e-6)
        s.connect("t", "ps")
        s.connect("t", "act")
        return s

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        asm = sf.Simulation(build(), duration=0.1).asm
    network = asm.residual.network
    x, S = asm.x0.copy(), asm.S0 * 3.0          # three times the initial volume
    Sout = np.full(S.size, np.nan)
    F = np.empty(network.n)
    assert network.loop(x, S, 0.0, 1e-3, False, F, *network.arrays, Sout) >= 0
    np.testing.assert_array_equal(netcore.compiled_update(asm)(x, S, 1e-3),
                                  asm.update_states(x, S, 1e-3))


def test_no_compiled_update_on_the_per_group_path():
    """A network the loop does not cover (a real fluid) has none."""
    from scenes import chain
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        asm = sf.Simulation(chain(2, fluid=sf.Fluid("air", level="table")), duration=0.01).asm
    assert asm.residual is asm.python_residual
    assert netcore.compiled_update(asm) is None


@pytest.mark.parametrize("name", ["air mixed", "water mixed", "air mixed heat transfer",
                                  "air valves"])
def test_the_source_arrays_fill_u_as_set_time_does(name):
    """CompiledNetwork.source_arrays(): the compiled source_values into a copy
    of u at a time t gives what set_time(t) writes there (sources on a Sine
    and a Ramp, constants; thermal sources with their temperatures)."""
    wavecodes = pytest.importorskip("softflow.solve.wavecodes")
    network = _sim(name).asm.residual.network
    described = network.source_arrays()
    assert described is not None
    for t in (0.0, 0.0123, 0.04):
        network.set_time(t)
        np.testing.assert_array_equal(wavecodes.values(described, t), network.u)
