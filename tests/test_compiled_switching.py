"""The compiled switching functions, kinks and pieces
(softflow.laws.network's switching, kinks and regimes on a CompiledNetwork's
arrays): the assembly's ``switching(x, S)``, ``kinks(x)`` and
``regimes(x)``, bitwise, in the same order, for every class of the compiled
loop that states them (snapping valves and hysteretic actuators,
isothermal and thermal, free and held; check valves, isothermal and
thermal, one to a group (the classes' scalar path) and two (their array
path)), at random states and on both sides of every switch, kink and
piece; the counts CompiledNetwork states are the ones written."""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow.components import valves
from softflow.laws import network as net
from softflow.solve import netcore

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent / "solve"))
from test_compiled_update import _across_switches, _random_point  # noqa: E402
from test_netcore import SCENES, THERMAL_SCENES, _sim, _with  # noqa: E402

P0 = sf.pressure_atmospheric


def _two_loops(held=False):
    """Two hysteretic actuators on one loop (the paper's), one group, and a
    snapping valve alone in its group, behind chain(2); ``held``: the
    actuators held at their wall temperature in a thermal scene."""
    from softflow.paper_scenes import loop_hysteretic
    loop = loop_hysteretic()
    kw = {"thermal": "isothermal"} if held else {}
    s = _with(sf.HystereticActuator("h1", sf.air, *loop, initial_volume=2e-6, **kw))
    s += sf.HystereticActuator("h2", sf.air, *loop, initial_volume=5e-6,
                               initial_branch="deflation", **kw)
    s += sf.CircularTube("ty", sf.air, 0.1, 1e-3)
    s.connect(("cont1", "a"), ("ty", "a"))
    s.connect(("ty", "b"), ("h2", "a"))
    s += sf.SnappingValve("sv", sf.air, opening_pressure=2e3, closing_pressure=500.0,
                          closed_conductance=1e-12, length=0.01, diameter=1e-3)
    s.connect(("sv", "a"), ("cont0", "a"))
    s.connect(("sv", "b"), ("cont1", "a"))
    return s


#: scenes of this file's own: a check valve alone in its group (nozzle and
#: incompressible gas laws), isothermal and thermal; two hysteretic actuators in
#: one group and a snapping valve alone, isothermal and thermal (free and held)
OWN = {
    "air check valve": (lambda: _with(sf.CheckValve("cv", sf.air, diameter=1e-3,
                                                    cracking_pressure=300.0), two_port=True),
                        {}),
    "air incompressible check valve": (
        lambda: _with(sf.CheckValve("cv", sf.air, diameter=1e-3, opening_band=250.0,
                                    gas_law="incompressible"), two_port=True), {}),
    "air check valve adiabatic": (lambda: _with(sf.CheckValve("cv", sf.air, diameter=1e-3,
                                                              cracking_pressure=300.0),
                                                two_port=True), {"thermal": "adiabatic"}),
    "air two loops": (_two_loops, {}),
    "air two loops adiabatic": (_two_loops, {"thermal": "adiabatic"}),
    "air two loops held": (lambda: _two_loops(held=True), {"thermal": "adiabatic"}),
}

NAMES = list(SCENES) + list(THERMAL_SCENES) + list(OWN)


def _asm(name):
    if name in OWN:
        build, kw = OWN[name]
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)
            return sf.Simulation(build(), duration=0.05, **kw).asm
    return _sim(name).asm


def _network(asm):
    network = asm.residual.network
    assert isinstance(network, netcore.CompiledNetwork)
    return network


def _is_switching(cls_id, option):
    return (cls_id in (net.SNAPPING_VALVE, net.THERMAL_SNAPPING_VALVE, net.HYSTERETIC_ACTUATOR)
            or cls_id in (net.FREE_VOLUME, net.HELD_VOLUME) and option == 3)


def _bits(a):
    """The array's float64 bits (bitwise: -0.0 is not 0.0, nan's payload counts)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def _compiled_switching(network, x, S, groups=None):
    """The compiled switching functions into an array one longer than they
    are (its last entry must stay unwritten), and how many were written."""
    groups = network.groups if groups is None else groups
    g_out = np.full(network.n_switching + 1, 1234.5)
    count = network.switching_loop(x, S, groups, network.cols, network.fpar, g_out)
    assert g_out[-1] == 1234.5
    return g_out[:count], count


def test_every_class_that_states_them_is_exercised():
    """The scenes hold every class of the loop that states switching
    functions (snapping valves and hysteretic actuators, isothermal and
    thermal, a loop wall free and held) and every one that states kinks and
    pieces (check valves, isothermal and thermal), one and two to a group;
    and the loop's classes that state them are those."""
    switching, pieces = set(), set()
    for name in NAMES:
        for g in _asm(name).groups:
            cls_id, option = netcore._covered(g)[:2]
            if g.switching is not None:
                switching.add((cls_id, option if cls_id in (net.FREE_VOLUME,
                                                            net.HELD_VOLUME) else None, g.n))
                assert _is_switching(cls_id, option)
            else:
                assert not _is_switching(cls_id, option)
            assert (g.kinks is not None) == (g.regime is not None)
            if g.kinks is not None:
                pieces.add((cls_id, g.n))
            assert (g.kinks is not None) == (cls_id in (net.CHECK_VALVE,
                                                        net.THERMAL_CHECK_VALVE))
    assert switching == {(c, o, n) for c, o in ((net.SNAPPING_VALVE, None),
                                                (net.THERMAL_SNAPPING_VALVE, None),
                                                (net.HYSTERETIC_ACTUATOR, None),
                                                (net.FREE_VOLUME, 3), (net.HELD_VOLUME, 3))
                         for n in (1, 2)}
    assert pieces == {(c, n) for c in (net.CHECK_VALVE, net.THERMAL_CHECK_VALVE) for n in (1, 2)}


@pytest.mark.parametrize("name", NAMES)
def test_the_counts_are_the_assemblys(name):
    """n_switching, n_kinks and n_regimes: the sizes of the assembly's
    arrays (0 where it answers None); each group writes as many values as
    its class's own function gives (a free loop wall two per instance: its
    branch and work offset)."""
    asm = _asm(name)
    network = _network(asm)
    x, S = asm.x0, asm.S0
    for n, want in ((network.n_switching, asm.switching(x, S)), (network.n_kinks, asm.kinks(x)),
                    (network.n_regimes, asm.regimes(x))):
        assert isinstance(n, int)
        assert n == (0 if want is None else want.size)
    for g, group in enumerate(asm.groups):
        sub = network.groups[g:g + 1]
        V, Sg = x[group.col], S[group.s0:group.s1].reshape(group.n, group.ns)
        want_sw = 0 if group.switching is None else np.asarray(group.switching(V, Sg)).size
        assert _compiled_switching(network, x, S, sub)[1] == want_sw
        want_k = 0 if group.kinks is None else group.kinks(V).size
        out = np.zeros(max(network.n_kinks, 1), dtype=np.int64)
        assert network.kinks_loop(x, sub, network.cols, network.fpar, out) == want_k
        assert network.regimes_loop(x, sub, network.cols, network.fpar, out) == want_k


#: the mode's place among an instance's states (else 0: a snapping valve's)
MODE_AT = {net.FREE_VOLUME: 2, net.HELD_VOLUME: 1, net.HYSTERETIC_ACTUATOR: 1}


def _switching_sides(asm, x, S, got, seen):
    """Record (class, mode, sign) of each compiled switching function."""
    k = 0
    for g in asm.groups:
        if g.switching is None:
            continue
        cls_id = netcore._covered(g)[0]
        per = 2 if cls_id == net.FREE_VOLUME else 1
        branch = MODE_AT.get(cls_id, 0)
        for i in range(g.n):
            mode = S[g.s0 + g.ns * i + branch] > 0.5
            for _ in range(per):
                seen.add((cls_id, mode, bool(got[k] > 0)))
                k += 1
    assert k == got.size


@pytest.mark.parametrize("name", NAMES)
def test_the_compiled_switching_is_the_assemblys(name):
    """switching(x, S, groups, cols, fpar, g_out) == asm.switching(x, S),
    bitwise, at random states with every mode on either side of its switch
    (a snapping valve open or shut, p_a - p_b above its opening pressure,
    below its closing one or between; a hysteretic actuator on either
    branch, its volume past V_hi, below V_lo or between), and once with a
    nan pressure; CompiledNetwork.switching the same (None without any)."""
    asm = _asm(name)
    network = _network(asm)
    rng = np.random.default_rng(23)
    seen: set = set()
    for k in range(30):
        x, S, c = _random_point(asm, rng)
        _across_switches(asm, x, S, c, k, rng)
        if k == 29:         # a nan pressure at the first group that states them
            first = next((g for g in asm.groups if g.switching is not None), None)
            if first is not None:
                x[first.col[0, 0]] = np.nan
        want = asm.switching(x, S)
        got, count = _compiled_switching(network, x, S)
        if want is None:
            assert count == 0 and network.switching(x, S) is None
            continue
        assert count == want.size == network.n_switching
        np.testing.assert_array_equal(_bits(got), _bits(want))
        np.testing.assert_array_equal(_bits(network.switching(x, S)), _bits(want))
        if k < 29:
            _switching_sides(asm, x, S, got, seen)
    assert {c for c, _, _ in seen} == {netcore._covered(g)[0] for g in asm.groups
                                       if g.switching is not None}
    for cls_id in {c for c, _, _ in seen}:
        assert {(m, s) for c, m, s in seen if c == cls_id} == {
            (m, s) for m in (False, True) for s in (False, True)}, cls_id


#: band positions s = (dp - cracking) / band: shut, the kink at 0, each piece of
#: the band's bottom from either side (pieces a factor 4 apart), the middle, the
#: kink and the piece at the top from either side, open; the nan piece
EDGE = valves.REGIME_EDGE
POSITIONS = ([-3.0, -1e-9, 1e-300, 1e-12, 0.5 * EDGE, 0.999 * EDGE, 1.001 * EDGE, 0.3, 0.5,
              1.0 - 1.001 * EDGE, 1.0 - 0.999 * EDGE, 0.999999, 1.000001, 1.5, 40.0, np.nan]
             + [EDGE * 4.0 ** j * f for j in range(-17, 0) for f in (0.9, 1.1)])


#: band positions met exactly (p_b = 0, p_a = cracking + s band): the kinks and
#: the edges of the pieces themselves, where < meets <=
EXACT = [0.0, 1.0, EDGE / 16.0, EDGE / 4.0, EDGE, 1.0 - EDGE]


def _place_check_valves(asm, x, k, exact):
    """Put check valve i of draw k at the band position POSITIONS[(k + i) % ...]
    (p_b as drawn, p_a = p_b + dp); with ``exact``, at EXACT[(k + i) % ...]
    with p_b = 0."""
    for g in asm.groups:
        if g.kinks is None:
            continue
        thermal = netcore._covered(g)[0] == net.THERMAL_CHECK_VALVE
        P = g.params
        for i in range(g.n):
            col = g.col[i]
            a, b = col[0], col[4 if thermal else 2]
            crack, band = P.cracking_pressure[i], P.opening_band[i]
            if exact:
                x[b] = 0.0
                x[a] = crack + EXACT[(k + i) % len(EXACT)] * band
            else:
                x[a] = x[b] + (crack + POSITIONS[(k + i) % len(POSITIONS)] * band)


@pytest.mark.parametrize("name", [n for n in NAMES if "valve" in n])
@pytest.mark.parametrize("dtype", [np.int64, np.float64])
def test_the_compiled_kinks_and_pieces_are_the_assemblys(name, dtype):
    """kinks(x, groups, cols, fpar, out) == asm.kinks(x) and regimes(...) ==
    asm.regimes(x), every entry, into int64 or float64 arrays (the same
    integers), at every band position of POSITIONS and at the kinks
    exactly: every kink side (0 shut, 1 in the band, 2 open) and every piece
    (-LOW_PIECES - 1 ... 1) met by each check valve class, isothermal and
    thermal; CompiledNetwork.kinks and .regimes the same (int64)."""
    asm = _asm(name)
    network = _network(asm)
    if network.n_kinks == 0:
        pytest.skip("no check valve")
    rng = np.random.default_rng(31)
    met_kinks, met_pieces = set(), set()
    draws = len(POSITIONS) + len(EXACT)
    for k in range(draws):
        x = _random_point(asm, rng)[0]
        _place_check_valves(asm, x, k, exact=k >= len(POSITIONS))
        for fn, loop, method, met in ((asm.kinks, network.kinks_loop, network.kinks, met_kinks),
                                      (asm.regimes, network.regimes_loop, network.regimes,
                                       met_pieces)):
            want = fn(x)
            out = np.full(network.n_kinks + 1, 99, dtype=dtype)
            count = loop(x, network.groups, network.cols, network.fpar, out)
            assert count == want.size == network.n_kinks and out[-1] == 99
            np.testing.assert_array_equal(out[:count], want.astype(dtype))
            by_method = method(x)
            assert by_method.dtype == np.int64
            np.testing.assert_array_equal(by_method, want)
            met.update(int(v) for v in want)
    assert met_kinks == {0, 1, 2}
    assert met_pieces == set(range(-valves.LOW_PIECES - 1, 2))


def test_the_cut_of_the_pieces_is_read_from_the_class_module(monkeypatch):
    """REGIME_EDGE and LOW_PIECES reach the compiled regimes as floats of
    the check valves' groups (no copy frozen into its cache): a network
    described with other values follows them, as the class does."""
    monkeypatch.setattr(valves, "REGIME_EDGE", 0.2)
    monkeypatch.setattr(valves, "LOW_PIECES", 3)
    for name in ("air valves", "air check valve", "air valves heat transfer"):
        asm = _asm(name)
        network = _network(asm)
        rng = np.random.default_rng(3)
        met = set()
        for k in range(len(POSITIONS)):
            x = _random_point(asm, rng)[0]
            _place_check_valves(asm, x, k, exact=False)
            want = asm.regimes(x)
            np.testing.assert_array_equal(network.regimes(x), want)
            met.update(int(v) for v in want)
        assert met == set(range(-4, 2))


def test_no_switching_kinks_or_pieces():
    """A network without any: the counts 0, nothing written, None."""
    asm = _asm("air chain 8")
    network = _network(asm)
    assert (network.n_switching, network.n_kinks, network.n_regimes) == (0, 0, 0)
    x, S = asm.x0, asm.S0
    out = np.full(1, 7.0)
    assert network.switching_loop(x, S, network.groups, network.cols, network.fpar, out) == 0
    assert network.kinks_loop(x, network.groups, network.cols, network.fpar, out) == 0
    assert network.regimes_loop(x, network.groups, network.cols, network.fpar, out) == 0
    assert out[0] == 7.0
    assert network.switching(x, S) is None and network.kinks(x) is None
    assert network.regimes(x) is None
    assert net.sizes(network.groups) == (0, 0, 0)
