"""Randomized networks (issue 17, hypothesis).

Random graphs of library components: a spanning tree of nodes, extra edges
that close loops (parallel branches included), junctions where several
components meet. Each node holds at most one storage volume (Container,
LinearAccumulator, Actuator with a monotonic, peak-valley or plateau curve,
HystereticActuator: the curves of :mod:`softflow.paper_scenes` with random key
points) or a pressure source, a flow source possibly beside a volume; each
edge is a two-port (CircularTube with random friction law and inertance, a
gas's at its default law, the isothermal pipe flow that chokes at the
isothermal sound speed; Orifice with K, Cd (a gas's: the compressible nozzle)
or ISO 6358; CheckValve, TeslaValve, SnappingValve). Sources drive constants or
waveforms. Fluids: air, water, ethylene glycol at level 'ideal' or 'table'
('eos' in a handful of examples, its own test); fixed or adaptive steps;
isothermal or, with air, adiabatic.

Each run either succeeds with finite values, positive absolute pressures and
mass conserved (what the sources delivered is what the volumes gained, to
1e-12 relative, as the run integrated it), or fails with a SimulationError
naming a component and a time, or stops at ``max_steps``; a network refused at
compile time (NetworkError) names its components. Never an exception from
inside NumPy, SciPy or CoolProp, never an unbounded run. Air networks never
stop on choking (issue 37: the gas laws model choked flow; the old low-Mach
``compressible='mean_density'`` tube law, which refuses a run past its choke,
is not drawn): ``networks(fluids=("air",))`` draws air only, for the slow air
test here and benchmarks/bench_random_air.py, which counts the outcomes.

The default draws include networks without a solution in a lumped model (a
flow source at a node without volume against inertial tubes at rest, closed
valves or dead ends; a node joined only by inertial tubes; a dead end behind a
leak-free check valve; sources that empty an actuator below its curve or leave
a fluid's table): they must be refused, naming a component, and they count
against completion (about 2 in 3 default draws complete, air and water alike).
``networks(..., well_posed=True)`` draws only networks as a careful modeller
builds them (the rules, each with its physical reason, in its docstring); the
slow test test_random_well_posed_networks_complete runs EXAMPLES_WELL_POSED of
them for air and for water and asserts issue 41's completion targets (air
>= 95 %, water >= 99 %) besides check's invariants; benchmarks/
bench_random_networks.py counts both kinds of draws by cause.

Examples per CI run: EXAMPLES (default suite) + EXAMPLES_SLOW (slow test,
still run in CI) + EXAMPLES_AIR + EXAMPLES_EOS + 2 x EXAMPLES_WELL_POSED =
2 603, derandomized (the same examples every run, for the same code: a
change in the outcomes can change hypothesis' later draws). Violations found
are kept as plain cases in test_random_network_cases.py (fixed since;
``_known`` would name any kept open so that the rest still runs).
"""
import math
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow import paper_scenes as ps
from softflow import waveforms as wf
from softflow.curves.pvcurve import PVCurve
from softflow.solve.newton import StepLimitError

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, seed, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

#: examples per run of the default suite; the slow test brings the total to >= 2 000
EXAMPLES = 300
EXAMPLES_SLOW = 1_700
#: air networks only (issue 37's target: >= 200, none stopping on choking), drawn
#: from a fixed seed rather than derandomize's digest of the test's source, so that
#: benchmarks/bench_random_air.py runs the same networks
EXAMPLES_AIR = 200
AIR_SEED = 37
EXAMPLES_EOS = 3
#: well-posed draws (``networks(..., well_posed=True)``), air and water each: the slow
#: test test_random_well_posed_networks_complete and benchmarks/bench_random_networks.py
EXAMPLES_WELL_POSED = 200
WELL_POSED_SEED = 41
#: their step budget: fast modes (10 us LC and RC time constants of small volumes
#: behind short tubes) and a source's jumps make a few well-posed networks take
#: 250-400 steps; MAX_STEPS stops them (a budget, not a failure)
MAX_STEPS_WELL_POSED = 2_000

#: short runs, bounded: fixed steps take 10 or 20 steps, adaptive ones at most this
MAX_STEPS = 200

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

_FLUIDS = {"air": sf.air, "water": sf.water, "ethylene_glycol": sf.ethylene_glycol}
_fluid_cache = {}


def fluid_at(name, level):
    """One fluid object per (name, level), shared by all examples (tables load once)."""
    key = (name, level)
    if key not in _fluid_cache:
        base = _FLUIDS[name]
        _fluid_cache[key] = base if level == "ideal" else base.with_level(level)
    return _fluid_cache[key]


# Draws through a few strategies built once: building a strategy per draw (st.floats(lo,
# hi) with new bounds) costs hypothesis more than running a small network
_UNIT = st.floats(0.0, 1.0)
_BOOL = st.booleans()
_INDEX = {n: st.integers(0, n - 1) for n in range(1, 17)}


class Draws:
    """Random values from hypothesis' ``draw``: uniform, log-uniform, choices
    (hypothesis also tries the ends of each range)."""

    def __init__(self, draw):
        self.draw = draw

    def uniform(self, lo, hi):
        return lo + (hi - lo) * self.draw(_UNIT)

    def log(self, lo, hi):
        return lo * (hi / lo) ** self.draw(_UNIT)

    def choice(self, options):
        return options[self.draw(_INDEX[len(options)])]

    def integer(self, lo, hi):
        return lo + self.draw(_INDEX[hi - lo + 1])

    def flag(self):
        return self.draw(_BOOL)


# -- sources -------------------------------------------------------------------------------
SIGNALS = ("constant", "constant", "step", "ramp", "sine", "square", "trapezoid",
           "piecewise linear", "piecewise constant")


def signal(r, low, high, *, signed=False, duration, negative_max=math.inf):
    """A constant or a waveform between ``low`` and ``high`` (or +-, ``signed``;
    negative values no larger than ``negative_max`` in magnitude)."""
    def value():
        v = r.uniform(low, high)
        return -min(v, negative_max) if signed and r.flag() else v

    kind = r.choice(SIGNALS)
    t = lambda: r.uniform(0.0, duration)   # noqa: E731
    if kind == "constant":
        return value()
    if kind == "step":
        return wf.Step(t(), value(), value())
    if kind == "ramp":
        t0 = t()
        return wf.Ramp(t0, t0 + r.uniform(1e-4, duration), value(), value())
    if kind == "sine":
        a, b = value(), value()
        return wf.Sine(abs(a - b) / 2, r.log(1.0, 2e3), offset=(a + b) / 2,
                       phase=r.uniform(0, 2 * math.pi))
    if kind == "square":
        return wf.Square(value(), value(), r.log(5.0, 2e3), duty=r.uniform(0.1, 0.9),
                         start=t())
    if kind == "trapezoid":
        period = duration / r.choice((1, 2, 4))
        return wf.Trapezoid(value(), value(), r.uniform(0, period / 3),
                            r.uniform(0, period / 3), r.uniform(0, period / 3), start=t(),
                            period=period)
    n = r.integer(2, 5)
    times = np.sort(np.array([0.0] + [t() for _ in range(n - 1)]))
    if len(np.unique(times)) < len(times):
        return value()
    values = [value() for _ in range(n)]
    cls = wf.PiecewiseLinear if kind == "piecewise linear" else wf.PiecewiseConstant
    return cls(times, values)


def pressure_source(r, label, duration, floor=0.0):
    """Gauge -0.5 .. +2 bar or absolute 0.4 .. 3 bar, never below ``floor`` (absolute)."""
    if r.flag():          # gauge, -0.5 .. +2 bar
        low = max(-0.5e5, floor - sf.pressure_atmospheric)
        return sf.PressureSource(label, signal(r, low, 2e5, duration=duration), gauge=True)
    return sf.PressureSource(label, signal(r, max(0.4e5, floor), 3e5, duration=duration))


def flow_source(r, label, fluid, duration, held=None):
    """A mass or volume flow source, either sign; ``held`` (the (mass [kg], volume
    [m^3]) of fluid in the volume beside it, well-posed draws): its withdrawals
    take no more than a quarter of that over the run."""
    mass_max = volume_max = math.inf
    if held is not None:
        mass_max, volume_max = (0.25 * h / duration for h in held)
    if r.flag():
        scale = 1e-5 if fluid.compressible else 1e-4     # kg/s
        return sf.MassFlowSource(label, signal(r, scale * 1e-3, scale, signed=True,
                                               duration=duration, negative_max=mass_max))
    return sf.VolumeFlowSource(label, signal(r, 1e-8, 1e-5, signed=True, duration=duration,
                                             negative_max=volume_max), fluid)


# -- volumes -------------------------------------------------------------------------------
VOLUMES = ("container", "accumulator", "monotonic", "peak-valley", "plateau", "hysteretic")


ACTUATORS = ("monotonic", "peak-valley", "plateau", "hysteretic")


def volume(r, label, fluid, kind=None, floor=None):
    """A storage volume of ``kind`` (drawn if None). ``floor`` (well-posed draws,
    the lowest absolute pressure the network's sources impose): no rigid liquid
    container, initial pressures at or above ``floor``, and an accumulator stiff
    enough to hold half its volume at ``floor``."""
    kind = r.choice(VOLUMES) if kind is None else kind
    well_posed = floor is not None
    if kind == "container":
        if not fluid.compressible and (well_posed or r.integer(0, 7)):
            kind = "accumulator"     # a rigid liquid volume takes no flow: now and then only
        else:
            return sf.Container(label, fluid, volume=r.log(1e-7, 1e-3),
                                initial_pressure=r.uniform(max(0.5e5, floor or 0), 2.5e5))
    if kind == "accumulator":
        if well_posed:
            v = r.log(1e-7, 1e-4)
            c_max = 0.5 * v / max(sf.pressure_atmospheric - floor, 1.0)
            c = r.log(1e-13, min(1e-9, c_max))
            p0 = r.uniform(max(0.8e5, floor), 2e5)
            return sf.LinearAccumulator(label, fluid, volume=v, compliance=c,
                                        initial_pressure=p0)
        v, c = r.log(1e-7, 1e-4), r.log(1e-13, 1e-9)
        p0 = max(r.uniform(0.8e5, 2e5), sf.pressure_atmospheric - 0.5 * v / c)
        return sf.LinearAccumulator(label, fluid, volume=v, compliance=c, initial_pressure=p0)
    if kind == "monotonic":
        curve = ps.curve_monotonic(r.uniform(3.0, 60.0))
    elif kind == "peak-valley":
        peak = r.uniform(10.0, 60.0)
        curve = ps.curve_peak_valley(peak, peak * r.uniform(0.2, 0.9))
    elif kind == "plateau":
        curve = ps.curve_plateau(r.uniform(3.0, 60.0))
    else:
        return sf.HystereticActuator(label, fluid, *ps.loop_hysteretic())
    return sf.Actuator(label, fluid, curve)


# -- two-ports -----------------------------------------------------------------------------
TWO_PORTS = ("tube", "tube", "tube", "orifice", "check valve", "tesla", "snapping")
FRICTION = ("Haaland", "Colebrook", "Churchill", "Swamee-Jain", "laminar")


def two_port(r, label, fluid, conducting=False):
    """A random two-port; ``conducting`` (well-posed draws): one whose flow follows
    the pressures across it at every instant: no inertial tube (its flow is a
    state), no check valve without leakage (closed, it passes nothing)."""
    kind = r.choice(TWO_PORTS)
    if kind == "tube":
        # a gas's tube at its default law (compressible='pipe_flow': choked flow modelled)
        options = {"friction": r.choice(FRICTION),
                   "inertance": r.integer(0, 3) == 0 and not conducting}
        return sf.CircularTube(label, fluid, length=r.log(5e-3, 3.0),
                               diameter=r.log(2e-4, 5e-3), **options)
    if kind == "orifice":
        law = r.choice(("K", "Cd", "ISO 6358") if fluid.compressible else ("K", "Cd"))
        if law == "K":
            return sf.Orifice(label, fluid, r.log(2e-4, 3e-3), K=r.log(0.5, 50.0))
        if law == "Cd":
            return sf.Orifice(label, fluid, r.log(2e-4, 3e-3), Cd=r.uniform(0.3, 1.0))
        return sf.Orifice(label, fluid, C=r.log(1e-10, 3e-8), b=r.uniform(0.1, 0.6),
                          m=r.uniform(0.3, 1.0))
    if kind == "check valve":
        return sf.CheckValve(label, fluid, r.log(2e-4, 3e-3),
                             cracking_pressure=r.uniform(0.0, 2e4),
                             opening_band=r.log(1e2, 5e3),
                             leakage=r.choice((1e-14, 1e-12, 1e-10) if conducting else
                                              (0.0, 1e-14, 1e-12, 1e-10)))
    if kind == "tesla":
        return sf.TeslaValve(label, fluid, length=r.log(5e-3, 3.0), diameter=r.log(2e-4, 5e-3),
                             diodicity=r.uniform(1.0, 10.0))
    opening = r.uniform(1e3, 3e4)
    return sf.SnappingValve(label, fluid, opening_pressure=opening,
                            closing_pressure=opening - r.uniform(5e2, 3e4),
                            closed_conductance=r.log(1e-14, 1e-11),
                            length=r.log(5e-3, 5e-2), diameter=r.log(5e-4, 3e-3),
                            initially_open=r.flag())


# -- networks ------------------------------------------------------------------------------
def _show(obj):
    """A waveform or a PV curve, its numbers written out (their reprs name the kind only)."""
    def num(v):
        v = np.asarray(v, dtype=float)
        return f"{float(v):.6g}" if v.ndim == 0 else "[" + ", ".join(f"{x:.6g}" for x in v) + "]"

    if isinstance(obj, (float, int)):
        return num(obj)
    if isinstance(obj, PVCurve):
        return f"PVCurve(volume={num(obj.volume)}, pressure={num(obj.pressure)})"
    fields = {k: v for k, v in vars(obj).items()
              if not k.startswith("_") and k != "unit" and v is not None}
    return f"{type(obj).__name__}(" + ", ".join(f"{k}={num(v)}" for k, v in fields.items()) + ")"


class Network:
    """A drawn scene and how to run it; ``describe()`` lists it for a failure report."""

    def __init__(self, system, volumes, sources, options, thermal, notes, nodes=()):
        self.system, self.volumes, self.sources = system, volumes, sources
        self.options, self.thermal, self.notes = options, thermal, notes
        self.nodes = nodes     # per node: the (label, terminal) pairs that meet there
        self.error = None      # check(): the NetworkError or SimulationError met, if any

    def describe(self):
        lines = [f"{self.notes}; thermal={self.thermal}; {self.options}"]
        for c in self.system.components:
            params = {k: v for k, v in vars(c).items()
                      if isinstance(v, (int, float, str, bool)) and not k.startswith("_")}
            # a source's value or waveform, a volume's curves: the constructor's arguments
            shown = [_show(a) for a in c._definition[0][1:]
                     if isinstance(a, (float, int, wf.Waveform, PVCurve))]
            lines.append(f"  {type(c).__name__} {c.label!r} {params}"
                         + "".join(f" {x}" for x in shown))
        if self.nodes:
            lines.append("  nodes: " + "; ".join(
                ", ".join(f"{label}.{t}" for label, t in node) for node in self.nodes))
        return "\n".join(lines)

    __repr__ = describe


ROLES = ("volume", "volume", "junction", "source", "volume+flow")


#: the fluids drawn by default: air half the time
FLUIDS = ("air", "air", "water", "ethylene_glycol")


@st.composite
def networks(draw, levels=("ideal", "ideal", "table"), max_nodes=5, adaptive=True,
             fluids=FLUIDS, well_posed=False):
    """A random :class:`Network` of one fluid drawn from ``fluids`` (names of
    ``_FLUIDS``, repeats weigh them) at a level drawn from ``levels``.

    ``well_posed=False`` (the default) draws anything the components accept,
    networks without a solution in a lumped model included (they must be
    refused, naming a component). ``well_posed=True`` draws only networks as a
    careful modeller builds them, by construction (the same graphs, roles and
    components otherwise; no draw is rejected). Each rule, with its reason:

    1. A flow source always stands beside a volume. An ideal flow source imposes
       its flow whatever the pressure; at a node without volume the node's
       pressure must pass that flow through its two-ports at once, and none does
       where they are inertial tubes at rest (their flow is a state: rho(p) Q =
       0 needs p = 0), closed valves, dead ends, or restrictions at their choked
       flow: no pressure balances the node. A real pump has a compliance and a
       pressure limit; the volume stands for them.
    2. Every node without volume or pressure source (a junction or a closed end)
       reaches a volume or a pressure source through conducting two-ports: its
       tree edge towards node 0 (which holds a source, and a volume beside a flow
       source) is neither an inertial tube nor a check valve without leakage. A
       node joined only by inertial tubes has no equation for its pressure (the
       columns' flows, states, must sum to zero: an index-2 constraint; in a real
       line the columns in series are one column, or the junction's volume is
       their coupling), and the pressure of a dead end behind a closed,
       leak-free check valve is undetermined (a real seat leaks).
    3. Liquids have no rigid containers (an incompressible liquid in a rigid
       volume is a node without compliance: rule 1's and 2's trouble again;
       real walls are compliant), and an accumulator is stiff enough to hold at
       least half its volume at the lowest pressure the sources impose (a
       linear compliance below its empty point has no physical meaning).
    4. The network's pressures stay within what its volumes and fluid describe:
       where it holds an actuator, the sources and initial pressures are at or
       above atmospheric (the actuators' curves start empty at 0 gauge: below,
       a real soft actuator collapses, which the curves do not describe), and a
       flow source beside an actuator only fills it; elsewhere a flow source
       withdraws over the run at most a quarter of what the volume beside it
       holds (a container) or holds above the sources' lowest pressure (an
       accumulator): an ideal sink would empty it and push its pressure to
       zero, or below the fluid's table. At the
       'table' level the sources stay 20 % above the table's lowest pressure.
    5. Adiabatic gas runs use the 'ideal' level where 'table' is drawn: the
       drawn pressure ratios (up to 7.5) expand or compress the gas
       isentropically from 20 degC to -110 .. +240 degC, beyond the air table's
       233-423 K (a modeller chooses a fluid model that covers the states).
    """
    r = Draws(draw)
    name = r.choice(tuple(fluids))
    level = r.choice(levels)
    fluid = fluid_at(name, level)
    gas = fluid.compressible
    adaptive = adaptive and r.integer(0, 5) == 0
    duration = r.choice((0.01, 0.02, 0.05))
    steps = r.choice((10, 20))
    thermal = r.choice(("isothermal", "isothermal", "adiabatic")) if gas else "isothermal"
    if well_posed and thermal == "adiabatic" and level == "table":
        level = "ideal"                                                  # rule 5
        fluid = fluid_at(name, level)

    n = r.integer(2, max_nodes)
    # roles: node 0 holds the main source; others a volume, nothing (a junction or a
    # closed end), another source, or a flow source beside a volume
    roles = ["source"] + [r.choice(ROLES) for _ in range(n - 1)]
    edges = [(r.integer(0, k - 1), k) for k in range(1, n)]              # spanning tree
    for _ in range(r.integer(0, 2)):                                     # loops
        i, j = r.integer(0, n - 1), r.integer(0, n - 1)
        if i != j:
            edges.append((i, j))

    s = sf.System()
    at = [[] for _ in range(n)]          # terminals meeting at each node
    volumes, sources, pressure_fixed = [], [], False
    if well_posed:
        volumes, sources, pressure_fixed, roles = _well_posed_nodes(
            r, s, at, roles, fluid, duration)
    else:
        for k, role in enumerate(roles):
            if role == "source":
                label = f"src{k}"
                if r.integer(0, 2):
                    s += pressure_source(r, label, duration)
                    pressure_fixed = True
                else:
                    s += flow_source(r, label, fluid, duration)
                sources.append(label)
                at[k].append((label, "a"))
            if role.startswith("volume"):
                label = f"v{k}"
                s += volume(r, label, fluid)
                volumes.append(label)
                at[k].append((label, "a"))
            if role == "volume+flow":
                label = f"src{k}"
                s += flow_source(r, label, fluid, duration)
                sources.append(label)
                at[k].append((label, "a"))
    if not pressure_fixed and not volumes:
        # flow sources only: something must take the flow
        s += sf.Container("v_end", fluid, volume=1e-5) if gas else \
            sf.LinearAccumulator("v_end", fluid, volume=1e-6, compliance=1e-11)
        volumes.append("v_end")
        at[n - 1].append(("v_end", "a"))
    for j, (i, k) in enumerate(edges):
        label = f"e{j}"
        # rule 2: a junction's tree edge towards node 0 conducts
        conducting = well_posed and j < n - 1 and roles[k] == "junction"
        s += two_port(r, label, fluid, conducting=conducting)
        a, b = (i, k) if r.flag() else (k, i)
        at[a].append((label, "a"))
        at[b].append((label, "b"))
    for terminals in at:
        if len(terminals) > 1:
            s.connect(*terminals)

    if adaptive:
        options = dict(duration=duration, max_steps=MAX_STEPS)
    else:
        options = dict(duration=duration, step=duration / steps, max_steps=MAX_STEPS)
    notes = (f"{name} ({level}), {n} nodes, edges {edges}, roles {roles}"
             + (", well-posed" if well_posed else ""))
    return Network(s, volumes, sources, options, thermal, notes, nodes=at)


def _held(component, fluid, floor):
    """(mass [kg], volume [m^3]) of fluid a drawn volume can give at its start: a
    container what it holds, an accumulator what it holds above ``floor``."""
    if isinstance(component, sf.Container):
        v, p = component.volume, component.initial_pressure
    elif isinstance(component, sf.LinearAccumulator):
        p = component.initial_pressure
        v = component.compliance * (p - floor)
    else:
        return 0.0, 0.0        # an actuator: starts empty (its curve's first point)
    return float(v * fluid.density(p)), float(v)


def _well_posed_nodes(r, s, at, roles, fluid, duration):
    """The sources and volumes of a well-posed draw (rules 1, 3 and 4 of
    :func:`networks`): which source each source node holds, then the volumes'
    kinds, the pressure floor they allow, the volumes, the sources. Returns
    (volumes, sources, pressure_fixed, roles), roles naming 'source+volume'
    where a flow source got its volume."""
    roles = list(roles)
    pressure = {k: bool(r.integer(0, 2)) for k, role in enumerate(roles) if role == "source"}
    for k, is_pressure in pressure.items():
        if not is_pressure:
            roles[k] = "source+volume"                                   # rule 1
    kinds = {k: r.choice(VOLUMES) for k, role in enumerate(roles)
             if role.startswith("volume") or role == "source+volume"}
    floor = 0.0
    if getattr(fluid, "level", "ideal") == "table":
        floor = 1.2 * fluid.p_range[0]                                   # rule 4
    if any(kind in ACTUATORS for kind in kinds.values()):
        floor = max(floor, sf.pressure_atmospheric)                      # rule 4
    volumes, sources, held = [], [], {}
    for k, kind in kinds.items():
        label = f"v{k}"
        component = volume(r, label, fluid, kind=kind, floor=floor)
        s += component
        volumes.append(label)
        held[k] = _held(component, fluid, floor)
        at[k].append((label, "a"))
    for k, role in enumerate(roles):
        if role == "source" or role.endswith("flow") or role == "source+volume":
            label = f"src{k}"
            if pressure.get(k, False):
                s += pressure_source(r, label, duration, floor=floor)
            else:
                s += flow_source(r, label, fluid, duration, held=held[k])
            sources.append(label)
            at[k].append((label, "a"))
    return volumes, sources, any(pressure.values()), roles


# -- the invariants ------------------------------------------------------------------------
def _frames(err):
    tb, names = err.__traceback__, []
    while tb is not None:
        names.append(tb.tb_frame.f_code.co_name)
        tb = tb.tb_next
    return names


def _known(err):
    """A violation kept as a regression case (test_random_network_cases.py) and not
    fixed yet: its name, or None. (The three found so far are fixed.)"""
    return None


def mass_gap(net, res):
    """(largest gap between what the volumes of ``net`` stored and what its
    sources delivered over the run ``res``, its scale: the masses held and
    the largest masses moved, flows that cancel included; a network without
    volumes moves round-off only: 1e-20 kg is the floor) [kg]."""
    masses = {c: res.get(c, "mass") for c in net.volumes}
    stored = sum((m - m[0] for m in masses.values()), np.zeros(len(res.times)))
    delivered = [-res.integral(c, "massflow") for c in net.sources]
    supplied = sum(delivered, np.zeros(len(res.times)))
    scale = max(np.abs(stored).max(), sum(np.abs(d).max() for d in delivered),
                sum(abs(m[0]) for m in masses.values()), 1e-20)
    return np.abs(stored - supplied).max(), scale


def check(net):
    """Run one network; return its outcome, asserting the invariants."""
    system = net.system
    labels = [c.label for c in system.components]
    net.error = None
    try:
        sim = sf.Simulation(system, allow_unconnected=True, thermal=net.thermal,
                            **net.options)
    except sf.NetworkError as err:       # refused at compile time: says where
        net.error = err
        assert any(label in str(err) for label in labels), str(err)
        return "refused: " + str(err)[:60]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        try:
            res = sim.run()
        except sf.SimulationError as err:
            net.error = err
            if isinstance(err.__cause__, StepLimitError):
                return "max_steps"
            known = _known(err)
            if known is not None:
                return known
            # named: the component, or the node by its components' terminals
            # ("conservation of massflow at node(src1.a, e0.a)") where a node's
            # equation is the worst; never a wrapped foreign exception
            assert err.__cause__ is None, (str(err), repr(err.__cause__))
            assert err.time is not None and 0 <= err.time <= net.options["duration"], str(err)
            assert err.component is not None or any(
                f"{label}." in str(err) or f"'{label}'" in str(err) for label in labels), str(err)
            assert err.result is not None and err.result.status == "failed"
            return "failed" if err.component is not None else "failed, named in the message"
        except Exception as err:
            net.error = err
            known = _known(err)
            if known is None:
                raise
            return known
    assert res.status == "success"
    for column, values in res.to_dict().items():
        assert np.isfinite(values).all(), column
    pressures = [res[c] for c in res.columns() if c.split(".")[1].startswith("pressure")]
    assert min(p.min() for p in pressures) > 0, "non-positive absolute pressure"
    gap, scale = mass_gap(net, res)
    # round-off: the nodes' balances hold to the linear solve's round-off, which
    # a drawn network's conditioning amplifies (a 0.2 mm x 3 m tube beside
    # 0.1 mL of gas: 1.3e-12 of the masses once, in a full CI run, where the
    # same example alone gave less; round-off moves with memory alignment);
    # the closed networks of tests/solve/test_bdf.py hold 1e-12
    assert gap <= 1e-11 * scale, (gap / scale, "mass not conserved")
    return "success"


@settings(max_examples=EXAMPLES, **SETTINGS)
@given(networks())
def test_random_networks_succeed_conserving_mass_or_fail_naming_a_component(net):
    check(net)


@pytest.mark.slow
@settings(max_examples=EXAMPLES_SLOW, **SETTINGS)
@given(networks())
def test_random_networks_many(net):
    check(net)


@pytest.mark.slow
@settings(max_examples=EXAMPLES_EOS, **SETTINGS)
@given(networks(levels=("eos",), max_nodes=3, adaptive=False))   # CoolProp itself: slow
def test_random_networks_eos(net):
    check(net)


@pytest.mark.slow
@seed(AIR_SEED)
@settings(max_examples=EXAMPLES_AIR, **SETTINGS)
@given(networks(fluids=("air",)))
def test_random_air_networks_never_stop_on_choking(net):
    # issue 37: gas tubes and Cd orifices model choked flow; a failure is any
    # other, named one (bench_random_air.py lists them with their causes)
    check(net)
    assert net.error is None or "chok" not in str(net.error).lower(), str(net.error)


#: issue 41's targets: the share of networks that run to completion
COMPLETION_TARGET = {"air": 0.95, "water": 0.99}


@pytest.mark.slow
@pytest.mark.parametrize("fluid", sorted(COMPLETION_TARGET))
def test_random_well_posed_networks_complete(fluid):
    # networks as a careful modeller builds them (networks' well_posed rules):
    # each keeps check()'s invariants, and at least issue 41's share completes
    # (benchmarks/bench_random_networks.py counts more of them, by cause)
    outcomes = []

    @seed(WELL_POSED_SEED)
    @settings(max_examples=EXAMPLES_WELL_POSED, **SETTINGS)
    @given(networks(fluids=(fluid,), well_posed=True))
    def run(net):
        net.options["max_steps"] = MAX_STEPS_WELL_POSED
        outcome = check(net)
        outcomes.append((outcome, net))

    run()
    failed = [f"{outcome}: {net.error}\n{net.describe()}"
              for outcome, net in outcomes if outcome != "success"]
    assert len(outcomes) >= 0.9 * EXAMPLES_WELL_POSED
    assert len(outcomes) - len(failed) >= COMPLETION_TARGET[fluid] * len(outcomes), \
        "\n\n".join(failed)
