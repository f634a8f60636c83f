"""A randomized water network of ~2 000 components (issue 38's target: "the
randomized 2 000-component water network of the test generator <= 10 s").

    python benchmarks/bench_water_network.py --warm                # ~2 000 components
    python benchmarks/bench_water_network.py --compare --repeat 3 --components 500
    python benchmarks/bench_water_network.py --profile 30          # cProfile of one run
    python benchmarks/bench_water_network.py --seed 39 --log-rejections   # a run that stalls

The network is drawn by the component builders of tests/test_random_networks.py
(``volume``, ``two_port``, ``flow_source``, ``pressure_source`` and through
them ``signal``: imported, not copied), driven by :class:`RngDraws`, an object
with the methods of that module's ``Draws`` (uniform, log, choice, integer,
flag) on a NumPy generator seeded by ``--seed`` instead of hypothesis (which
does not draw networks this large comfortably). The structure is that of its
``networks()`` strategy: a spanning tree of nodes (node k hangs from a node
drawn below it), a few loop edges (``--loops`` per node, default 0.01), a role
per node (volume, volume, junction, source, volume + flow source; node 0 holds
the main pressure source), one two-port per edge; water at the 'ideal' level
(``--level table``), isothermal, the adaptive BDF at its default rtol, for
``--duration`` (0.05 s), ``--max-steps`` at most. The node count is chosen so
that the components number about ``--components`` (the roles give ~1
component a node, the edges one more).

Well-posed draws. A draw that ``Simulation()`` refuses (NetworkError) or that
fails at t = 0 (a consistent start of the first 1e-9 of the run, tried
first) is skipped, the next seed tried, and the skip printed. At 2 000
components nearly every raw draw holds a node the generator's small networks
only now and then hold, so the draws are *screened* (off: ``--no-screen``;
``--signed-flows`` keeps flow sources that draw): a draw is repeated, from the
same generator, where it is

- a node whose pressure nothing sets at t = 0: its two-ports drawn again until
  a path of two-ports that conduct at rest (no closed snapping valve, check
  valve without leakage or inertial tube) leads to a pressure source or a
  compliant volume (Simulation() refuses the network otherwise: "the network
  equations are singular");
- a flow source at a node without a compliant volume (a 'source' role's flow
  source; a rigid water Container beside one): its flow must pass the
  two-ports there at any rate (a 0.3 mm x 1.6 m tube needs 1.1 GPa for 10 mL/s:
  "no consistent start");
- a flow source whose flow draws from its node (negative anywhere in the run):
  it drains its volume empty;
- a pressure source below 1 atm anywhere in the run, an accumulator starting
  below 1 atm or empty 0.5 bar below it (an actuator's curve holds no fluid
  15 kPa below 1 atm): "its fluid volume reached zero";
- an inertial tube at a node without volume (a water hammer there draws the
  node below vacuum when a source steps down: "absolute pressure <= 0");
- a snapping valve that closes at dp > 0 (behind it a small volume fills in
  1e-10 s, and it chatters: "switched its mode at each of the last 50 steps").

The counts of repeated draws are printed. Seeds 38, 39, 40, 42, 43 (2 000
components) then run into a stall of the BDF at a breakpoint (the same step
rejected by the error test thousands of times: ``--log-rejections`` shows it);
the default seed, 41, runs to the end.

Printed: components, unknowns, states, the linear solver, the CPU
(``time.process_time``) of ``Simulation()`` (the first in the process
apart) and of ``run()``, steps, rejected steps, us a step, the result's
status, Newton's counters, the BDF's restarts against the sources'
breakpoints in the run and the rejections by cause (bench_paper_scenes'
``Counts``), the compiled step loop's share (a spy on
``softflow.solve.steploop.CompiledSteps.run``: the steps it took, its calls,
why it handed back, or why it was not bound to the run: bench_paper_scenes'
``LoopSpy``), the Jacobian's band in ``steploop.band_layout``'s order (width
limit lifted) against ``settings.COMPILED_BAND_MAX``, warnings caught (by
category), and the invariants of the test module's ``check``: all values
finite, absolute pressures > 0, mass conserved (stored against delivered, to
1e-11 of the masses moved). ``--python-steps`` sets
``softflow.solve.settings.COMPILED_STEPS = False`` before building (every
step the Python BDF's); ``--compare`` runs both in turns, ``--repeat`` times
each, and prints medians [min-max] and the ratio on/off. ``--band-max N``
sets ``settings.COMPILED_BAND_MAX`` for the run (an experiment: the compiled
loop's banded LU on a wider band). ``--record-balance`` records the volumes
and sources only (``Simulation(record=...)``: the mass balance's columns; the
pressure check then covers their nodes). ``--log-rejections`` counts the
rejected steps by message (the logger at DEBUG, where the compiled loop hands
back at each mode switch to log it). ``--profile N`` prints the top N entries
of a cProfile of one run, by cumulative and by own time.

Numbers are CPU seconds of this process (2-core VM, shared). The first run
after softflow's laws changed compiles them with numba (minutes on a cold
cache); ``--warm`` runs a 60-component network, both loops, first.
"""
from __future__ import annotations

import argparse
import collections
import contextlib
import cProfile
import io
import logging
import os
import pstats
import statistics
import sys
import time
import warnings
from pathlib import Path

_HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(_HERE.parent / "tests"))
sys.path.insert(0, str(_HERE))

import numpy as np  # noqa: E402
import test_random_networks as trn  # noqa: E402
from bench_paper_scenes import Counts, LoopSpy  # noqa: E402

import softflow as sf  # noqa: E402
from softflow.solve import linalg  # noqa: E402
from softflow.solve import settings as settings_mod  # noqa: E402
from softflow.solve import steploop  # noqa: E402

TARGET = 10.0        # s, issue 38: the whole run of the 2 000-component network
#: the default seed: the first from 38 whose 2 000-component network runs to
#: the end (module docstring)
SEED = 41
#: the steps a run may take (accepted and rejected): four times what the
#: default network takes (~4 700), a bound on a run that stalls (~15 ms a
#: step in Python: 5 min)
MAX_STEPS = 20_000
#: [Pa] how far below 1 atm a screened accumulator holds fluid still: the
#: undershoot of a water hammer (an inertial tube into a small, stiff volume)
UNDERSHOOT = 0.5e5


class RngDraws:
    """The methods of tests/test_random_networks.py's ``Draws`` on a NumPy
    generator: uniform, log-uniform, a choice, an integer in [lo, hi], a flag."""

    def __init__(self, rng):
        self.rng = rng

    def uniform(self, lo, hi):
        return lo + (hi - lo) * float(self.rng.random())

    def log(self, lo, hi):
        return lo * (hi / lo) ** float(self.rng.random())

    def choice(self, options):
        return options[int(self.rng.integers(len(options)))]

    def integer(self, lo, hi):
        return lo + int(self.rng.integers(hi - lo + 1))

    def flag(self):
        return bool(self.rng.integers(2))


# -- the network ----------------------------------------------------------------------------
def nodes_for(components, loop_share):
    """Nodes whose draw gives about ``components`` components: ~1 per node from
    the roles (volume 2/5, source 1/5, volume + flow 1/5 x 2), 1 per tree edge,
    ``loop_share`` per node from the loops."""
    return max(2, round(components / (2.0 + loop_share)))


def _inertial(comp):
    return bool(getattr(comp, "inertance", False))


def conducts_at_rest(comp):
    """Whether two-port ``comp`` ties its nodes' pressures at t = 0: not a closed
    snapping valve, not a check valve without leakage (shut at rest), not an
    inertial tube (its flow is a state, at rest: no slope in the pressures)."""
    if isinstance(comp, sf.SnappingValve) and not comp.initially_open:
        return False
    if isinstance(comp, sf.CheckValve) and not comp.leakage:
        return False
    return not _inertial(comp)


def sets_pressure(comp, fluid):
    """Whether a node's component sets its pressure at t = 0 by itself: a
    pressure source, or a volume that holds the liquid with some compliance (a
    rigid Container of a liquid admits no flow: its node is a junction)."""
    if isinstance(comp, sf.PressureSource):
        return True
    return not isinstance(comp, (sf.MassFlowSource, sf.VolumeFlowSource)) and not (
        isinstance(comp, sf.Container) and not fluid.compressible)


def undetermined(n, setters, ports):
    """The nodes whose pressure nothing sets at t = 0: the parts of the graph of
    two-ports that conduct at rest (``ports``: (component, node a, node b) per
    edge) that hold no node of ``setters``. The network's regularity test at
    Simulation() refuses them (NetworkError), or the consistent start fails."""
    parent = list(range(n))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for comp, a, b in ports:
        if conducts_at_rest(comp):
            parent[root(a)] = root(b)
    held = {root(k) for k in setters}
    return [k for k in range(n) if root(k) not in held]


def signal_min(comp, duration):
    """A source's smallest value over the run: its constant, or its waveform
    sampled at 4 001 points (its breakpoints' sides within 1/4 000 of the run)."""
    value = comp._definition[0][1]
    if isinstance(value, trn.wf.Waveform):
        return float(np.min(value(np.linspace(0.0, duration, 4001))))
    return float(value)


class Drawn:
    """A drawn network: ``system``, ``volumes``, ``sources`` (labels), ``nodes``
    (per node the (label, terminal) pairs meeting there), ``options`` of the
    Simulation, and how it was drawn (``notes``, ``redrawn``: two-ports drawn
    again)."""

    def __init__(self, system, volumes, sources, nodes, options, notes, redrawn):
        self.system, self.volumes, self.sources, self.nodes = system, volumes, sources, nodes
        self.options, self.notes, self.redrawn = options, notes, redrawn
        self.components = len(system.components)


def lowest_pressure(comp, duration):
    """[Pa] the lowest absolute pressure a pressure source sets over the run (a
    gauge source's offset added)."""
    return signal_min(comp, duration) + float(getattr(comp, "offset", 0.0) or 0.0)


def chatters(comp):
    """Whether a snapping valve may close while it is open and flows forward
    (closing_pressure > 0): behind it a small volume fills within a step of
    1e-10 s and it chatters (the run stops); closing at dp < 0, it closes
    only on a reversed flow."""
    return isinstance(comp, sf.SnappingValve) and comp.closing_pressure > 0.0


def draw_network(seed, components=2000, level="ideal", duration=0.05, loop_share=0.01,
                 screened=True, signed=False, max_steps=MAX_STEPS, record_balance=False):
    """A random water network of about ``components`` components, drawn as
    ``trn.networks()`` draws (module docstring), from ``seed``; ``screened``:
    the draws that make it ill-posed drawn again (module docstring); ``signed``:
    flow sources as drawn (else pushing only)."""
    r = RngDraws(np.random.default_rng(seed))
    fluid = trn.fluid_at("water", level)
    n = nodes_for(components, loop_share)
    redrawn = collections.Counter()     # draws refused by the screen, by why
    # as networks(): roles, the spanning tree and the loops, each node's
    # components, each edge's two-port; node 0 holds the main pressure source
    roles = ["source"] + [r.choice(trn.ROLES) for _ in range(n - 1)]
    edges = [(r.integer(0, k - 1), k) for k in range(1, n)]           # spanning tree
    for _ in range(round(loop_share * n)):                              # loops
        i, j = r.integer(0, n - 1), r.integer(0, n - 1)
        if i != j:
            edges.append((i, j))

    def pressure_source(label):
        while True:
            comp = trn.pressure_source(r, label, duration)
            if not screened or lowest_pressure(comp, duration) >= sf.pressure_atmospheric:
                return comp
            redrawn["pressure source below 1 atm"] += 1

    def volume(label):
        while True:
            comp = trn.volume(r, label, fluid)
            if not (screened and isinstance(comp, sf.LinearAccumulator)):
                return comp
            if comp.initial_pressure < sf.pressure_atmospheric:
                redrawn["accumulator starting below 1 atm"] += 1
            elif comp.volume < UNDERSHOOT * comp.compliance:
                redrawn[f"accumulator empty {UNDERSHOOT / 1e5:g} bar below 1 atm"] += 1
            else:
                return comp

    def flow_source(label):
        while True:
            comp = trn.flow_source(r, label, fluid, duration)
            if signed or not screened or signal_min(comp, duration) >= 0.0:
                return comp
            redrawn["flow source drawing from its node"] += 1

    def two_port(label):
        while True:
            comp = trn.two_port(r, label, fluid)
            if not screened or not chatters(comp):
                return comp
            redrawn["snapping valve closing at dp > 0"] += 1

    placed = []          # (node, component, 'source' | 'volume')
    for k, role in enumerate(roles):
        if role == "source":
            label = f"src{k}"
            while True:
                flow = k != 0 and not r.integer(0, 2)
                if not (screened and flow):
                    break
                # a flow source at a node without volume: its flow must pass
                # the two-ports there at once at any rate, up to 1e9 Pa
                redrawn["flow source at a node without volume"] += 1
            placed.append((k, flow_source(label) if flow else pressure_source(label), "source"))
        if role.startswith("volume"):
            comp = volume(f"v{k}")
            while screened and role == "volume+flow" and not sets_pressure(comp, fluid):
                # a rigid liquid volume takes no flow: as without volume
                redrawn["rigid container beside a flow source"] += 1
                comp = volume(f"v{k}")
            placed.append((k, comp, "volume"))
        if role == "volume+flow":
            placed.append((k, flow_source(f"src{k}"), "source"))
    setters = sorted({k for k, comp, _ in placed if sets_pressure(comp, fluid)})

    def draw_edge(j):
        i, k = edges[j]
        comp = two_port(f"e{j}")
        a, b = (i, k) if r.flag() else (k, i)
        return comp, a, b

    ports = [draw_edge(j) for j in range(len(edges))]
    if screened:
        # the two-ports at nodes whose pressure nothing sets drawn again, from
        # the same generator, until every node's is set
        free = set(range(n)) - set(setters)
        for _ in range(1000):
            bad = set(undetermined(n, setters, ports))
            # an inertial tube at a node without volume: its flow, held up
            # when a source steps down, draws the node below vacuum
            hammer = [j for j, (comp, a, b) in enumerate(ports)
                      if _inertial(comp) and (a in free or b in free)]
            if not bad and not hammer:
                break
            for j in hammer:
                ports[j] = draw_edge(j)
                redrawn["inertial tube at a node without volume"] += 1
            for j, (i, k) in enumerate(edges):
                if i in bad or k in bad:
                    ports[j] = draw_edge(j)
                    redrawn["two-port at a node whose pressure nothing sets"] += 1
        else:
            raise RuntimeError(f"seed {seed}: nodes without pressure after 1000 redraws")

    s = sf.System()
    at = [[] for _ in range(n)]
    volumes, sources = [], []
    kinds = collections.Counter()
    for k, comp, what in placed:
        s += comp
        at[k].append((comp.label, "a"))
        (sources if what == "source" else volumes).append(comp.label)
        kinds[type(comp).__name__] += 1
    kinds["junction"] = roles.count("junction")
    for comp, a, b in ports:
        s += comp
        at[a].append((comp.label, "a"))
        at[b].append((comp.label, "b"))
    for terminals in at:
        if len(terminals) > 1:
            s.connect(*terminals)
    options = dict(duration=duration, max_steps=max_steps)
    if record_balance:
        # the mass balance's columns only: the volumes and the sources
        options["record"] = volumes + sources
    two = collections.Counter(type(c).__name__ for c, _, _ in ports)
    notes = (f"water ({level}), {n} nodes: "
             + ", ".join(f"{v} {k}" for k, v in kinds.most_common())
             + f"; {len(edges)} edges ({len(edges) - n + 1} loops): "
             + ", ".join(f"{v} {k}" for k, v in two.most_common()) + f"; seed {seed}")
    return Drawn(s, volumes, sources, at, options, notes, redrawn)


# -- running it -----------------------------------------------------------------------------
def build_sim(net, compiled=True):
    """``Simulation(...)`` as the test's ``check`` builds it, with the compiled
    step loop on or off: (sim, CPU seconds)."""
    saved = settings_mod.COMPILED_STEPS
    settings_mod.COMPILED_STEPS = bool(compiled)
    try:
        c0 = time.process_time()
        sim = sf.Simulation(net.system, allow_unconnected=True, thermal="isothermal",
                            **net.options)
        return sim, time.process_time() - c0
    finally:
        settings_mod.COMPILED_STEPS = saved


def run_sim(sim, compiled=True):
    """One run, warnings caught and counted: (result, SimulationError or None,
    CPU seconds, Counter of the warnings by category)."""
    saved = settings_mod.COMPILED_STEPS
    settings_mod.COMPILED_STEPS = bool(compiled)
    caught = collections.Counter()
    try:
        with warnings.catch_warnings(record=True) as got:
            warnings.simplefilter("always")
            c0 = time.process_time()
            try:
                res, err = sim.run(progress=False), None
            except sf.SimulationError as e:
                res, err = e.result, e
            cpu = time.process_time() - c0
        for w in got:
            caught[w.category.__name__] += 1
    finally:
        settings_mod.COMPILED_STEPS = saved
    return res, err, cpu, caught


def usable(args, log):
    """The first well-posed draw from ``args.seed`` on (module docstring):
    (net, Simulation() CPU of its first build), the skips logged."""
    for s in range(args.seed, args.seed + args.tries):
        net = draw_network(s, args.components, args.level, args.duration, args.loops,
                           not args.no_screen, args.signed_flows, args.max_steps,
                           args.record_balance)
        try:
            cpu = build_sim(net, not args.python_steps)[1]
        except sf.NetworkError as err:
            log(f"  seed {s}: refused by Simulation() (NetworkError), next seed: "
                f"{str(err)[:200]}")
            continue
        # the consistent start alone: a run of the first 1e-9 of the duration
        probe = dict(net.options, duration=args.duration * 1e-9, max_steps=100)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sf.Simulation(net.system, allow_unconnected=True, thermal="isothermal",
                              **probe).run(progress=False)
        except sf.SimulationError as err:
            if err.time is not None and err.time <= probe["duration"]:
                log(f"  seed {s}: fails at t = 0, next seed: {str(err)[:240]}")
                continue
        return net, cpu
    raise SystemExit(f"no well-posed draw in seeds {args.seed}..{args.seed + args.tries - 1}")


def invariants(net, res):
    """The test module's ``check`` invariants on a successful result: (all
    finite, the lowest absolute pressure [Pa], mass gap / masses moved)."""
    finite = all(np.isfinite(v).all() for v in res.to_dict().values())
    pressures = [res[c] for c in res.columns() if c.split(".")[1].startswith("pressure")]
    p_min = min(float(p.min()) for p in pressures)
    gap, scale = trn.mass_gap(net, res)
    return finite, p_min, float(gap) / scale


def band_of(sim):
    """(kl, ku) of the Jacobian's band in steploop.band_layout's order with the
    width limit lifted, or None where no matching exists (the layout the run
    keeps on its Assembly is left as it was)."""
    asm = sim.asm
    saved_max, cached = settings_mod.COMPILED_BAND_MAX, asm.__dict__.pop("_band_layout", False)
    settings_mod.COMPILED_BAND_MAX = 1 << 30
    try:
        layout = steploop.band_layout(asm)
        return None if layout is None else (layout.kl, layout.ku)
    finally:
        settings_mod.COMPILED_BAND_MAX = saved_max
        asm.__dict__.pop("_band_layout", None)
        if cached is not False:
            asm.__dict__["_band_layout"] = cached


def breakpoints(net):
    """The sources' breakpoints within the run (as Simulation asks them: a
    periodic waveform's up to the duration), distinct: the BDF restarts at each."""
    duration, out = net.options["duration"], set()
    for c in net.system.components:
        until = getattr(c, "breakpoints_until", None)
        found = until(duration) if until else getattr(c, "breakpoints", tuple)()
        out.update(float(b) for b in found if 0.0 < float(b) <= duration)
    return len(out)


class Rejections(logging.Handler):
    """``--log-rejections``: the solver's rejected steps (logger 'softflow' at
    DEBUG), counted by message; the most repeated are a stall's signature.
    (At DEBUG the compiled loop hands back at each mode switch to log it.)"""

    def __init__(self):
        super().__init__(logging.DEBUG)
        self.counts = collections.Counter()

    def emit(self, record):
        message = record.getMessage()
        if message.startswith("step rejected"):
            self.counts[message] += 1

    def __enter__(self):
        log = logging.getLogger("softflow")
        self._level = log.level
        log.setLevel(logging.DEBUG)
        log.addHandler(self)
        return self

    def __exit__(self, *exc):
        log = logging.getLogger("softflow")
        log.removeHandler(self)
        log.setLevel(self._level)


def spread(values, fmt="{:.2f}"):
    """'median [min-max]'."""
    return (fmt.format(statistics.median(values)) + " [" + fmt.format(min(values)) + "-"
            + fmt.format(max(values)) + "]")


def report(net, sim_cpu, res, err, cpu, caught, spy, label, counts=None):
    """A run's lines."""
    st = res.stats if res is not None else {}
    steps, rejected = st.get("steps", 0), st.get("rejected_steps", 0)
    print(f"{label}: Simulation() {sim_cpu:.2f} s, run {cpu:.2f} s CPU (issue 38's target: "
          f"{TARGET:.0f} s), status {res.status if res is not None else 'none'}"
          + ("" if res is None or res.status == "success" else f" at t = {res.times[-1]:.6g} s"))
    if err is not None:
        print(f"  error: {str(err)[:300]}")
    print(f"  steps {steps}, rejected {rejected} (error test {st.get('error_test_failures')}), "
          f"{cpu / max(steps, 1) * 1e3:.2f} ms a step; Newton iterations "
          f"{st.get('newton_iterations')}, residuals {st.get('residual_evaluations')}, "
          f"Jacobians {st.get('jacobian_evaluations')}, factorizations "
          f"{st.get('factorizations')}, Newton failures {st.get('newton_failures')}, forced "
          f"{st.get('forced_steps')}; steps per order {st.get('order_steps', [])[1:]}")
    if counts is not None:
        why = ", ".join(f"{k} {v}" for k, v in counts.why.items())
        print(f"  BDF restarts {counts.restarts} (breakpoints in the run {breakpoints(net)}), "
              f"mode switches {counts.switches}; rejections by cause: {why}")
    if spy is not None:
        print(f"  compiled loop: {spy.share(steps)} accepted steps, {spy.calls} calls, "
              f"{spy.cpu:.2f} s CPU inside; hand-backs: {spy.exits_text()}")
        if hasattr(spy, "lu_text") and spy.lu_text():
            print(f"  {spy.lu_text()}")
    print("  warnings caught: " + (", ".join(f"{k} {v}" for k, v in caught.items()) or "none"))
    if res is not None and res.status == "success":
        finite, p_min, gap = invariants(net, res)
        print(f"  invariants (test's check): finite {finite}; lowest absolute pressure "
              f"{p_min:.4g} Pa (> 0: {p_min > 0}); mass gap {gap:.2e} of the masses moved "
              f"(<= 1e-11: {gap <= 1e-11})")


def profile(net, args):
    """``--profile N``: one run (a fresh Simulation) under cProfile."""
    sim, sim_cpu = build_sim(net, not args.python_steps)
    prof = cProfile.Profile()
    with LoopSpy() as spy, Counts() as counts:
        prof.enable()
        res, err, cpu, caught = run_sim(sim, not args.python_steps)
        prof.disable()
    report(net, sim_cpu, res, err, cpu, caught, spy, "profiled run (CPU with cProfile's "
           "overhead)" + (", Python steps" if args.python_steps else ""), counts)
    for key in ("cumulative", "tottime"):
        out = io.StringIO()
        pstats.Stats(prof, stream=out).sort_stats(key).print_stats(args.profile)
        lines = out.getvalue().splitlines()
        start = next(i for i, line in enumerate(lines) if "ncalls" in line)
        print(f"\n-- top {args.profile} by {key} --")
        print("\n".join(line.replace(str(_HERE.parent) + "/", "") for line in lines[start:]
                        if line.strip()))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--components", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--tries", type=int, default=20, help="seeds tried at most")
    ap.add_argument("--level", default="ideal", choices=("ideal", "table"))
    ap.add_argument("--duration", type=float, default=0.05)
    ap.add_argument("--max-steps", type=int, default=MAX_STEPS)
    ap.add_argument("--loops", type=float, default=0.01,
                    help="loop edges drawn per node (default %(default)s)")
    ap.add_argument("--no-screen", action="store_true", help="draws as they come")
    ap.add_argument("--signed-flows", action="store_true",
                    help="flow sources as drawn, drawing from their nodes too")
    ap.add_argument("--record-balance", action="store_true",
                    help="record the volumes and sources only (Simulation(record=...))")
    ap.add_argument("--python-steps", action="store_true",
                    help="settings.COMPILED_STEPS = False before building")
    ap.add_argument("--compare", action="store_true",
                    help="compiled loop on and off, in turns")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--band-max", type=int, help="settings.COMPILED_BAND_MAX for the runs")
    ap.add_argument("--warm", action="store_true",
                    help="run a 60-component network first, both loops (numba's cache)")
    ap.add_argument("--log-rejections", action="store_true",
                    help="count the rejected steps by message (logger at DEBUG)")
    ap.add_argument("--profile", type=int, metavar="N", default=0,
                    help="cProfile one run; print the top N by cumulative and own time")
    args = ap.parse_args(argv)
    if args.band_max is not None:
        settings_mod.COMPILED_BAND_MAX = args.band_max
    print(f"randomized water network (issue 38: <= {TARGET:.0f} s); CPU = time.process_time "
          f"of this process, {os.cpu_count()}-core machine; numpy {np.__version__}")
    if args.warm:
        c0 = time.process_time()
        small = draw_network(args.seed, 60, args.level, 0.01)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for on in (True, False):
                try:
                    build_sim(small, on)[0].run(progress=False)
                except (sf.SimulationError, sf.NetworkError):
                    pass
        print(f"warm-up (60 components, loop on and off): {time.process_time() - c0:.1f} s CPU")
    net, first_sim = usable(args, print)
    sim, sim_cpu = build_sim(net, not args.python_steps)
    asm = sim.asm
    print(f"network: {net.components} components, {asm.n} unknowns, {len(asm.S0)} states; "
          f"{net.notes}")
    if net.redrawn:
        print("  drawn again (screen): "
              + ", ".join(f"{k} {v}" for k, v in net.redrawn.most_common()))
    band = band_of(sim)
    print(f"  Simulation(): {first_sim:.2f} s CPU the first in this process, {sim_cpu:.2f} s "
          f"the next; Jacobian's band (steploop.band_layout, limit lifted): "
          + ("no matching" if band is None else f"kl {band[0]}, ku {band[1]}")
          + f" (settings.COMPILED_BAND_MAX {settings_mod.COMPILED_BAND_MAX}; dense LU up to "
          f"linalg.DENSE_MAX = {linalg.DENSE_MAX} unknowns); independent sub-networks "
          f"{asm.subnetworks()[2]}")
    if args.profile:
        profile(net, args)
        return
    modes = [True, False] if args.compare else [not args.python_steps]
    cpus, builds, last = {m: [] for m in modes}, {m: [] for m in modes}, {}
    for i in range(args.repeat):
        for on in (modes if i % 2 == 0 else modes[::-1]):
            sim, sim_cpu = build_sim(net, on)
            with LoopSpy() as spy, Counts() as counts, (
                    Rejections() if args.log_rejections else contextlib.nullcontext()) as log:
                res, err, cpu, caught = run_sim(sim, on)
            cpus[on].append(cpu)
            builds[on].append(sim_cpu)
            last[on] = (sim_cpu, res, err, cpu, caught, spy, counts, log)
    print(f"linear solver: {res.stats.get('linear_solver')}")
    for on in modes:
        sim_cpu, res, err, cpu, caught, spy, counts, log = last[on]
        label = "compiled loop on" if on else "Python steps (COMPILED_STEPS = False)"
        report(net, sim_cpu, res, err, cpu, caught, spy,
               label + (" (last run)" if args.repeat > 1 else ""), counts)
        if log is not None and log.counts:
            print("  most repeated rejections:")
            for message, count in log.counts.most_common(3):
                print(f"    {count} x {message}")
    if args.repeat > 1 or args.compare:
        print(f"CPU s, medians of {args.repeat} [min-max]:")
        for on in modes:
            print(f"  {'on ' if on else 'off'}: Simulation() {spread(builds[on], '{:.3f}')}, "
                  f"run {spread(cpus[on])}")
        if args.compare:
            pair = [a / b for a, b in zip(cpus[True], cpus[False])]
            ratio = statistics.median(cpus[True]) / statistics.median(cpus[False])
            print(f"  run on/off: {ratio:.3f} (pairs {min(pair):.3f}-{max(pair):.3f})")


if __name__ == "__main__":
    main()
