"""Let softflow choose the model: the cheapest configuration adequate for a scene.

``sf.assess(system, duration, tolerance=0.01, outputs=[("act1", "volume")])`` runs
the scene in its cheapest configuration (isothermal, ideal fluids, the
components' own friction and tube laws, no inertance, ``rtol = 10 rtol0 =
tolerance``, with ``rtol0 = tolerance / 10``) and reads the validity records
of that run (:mod:`softflow.solve.model_checks`), judged as for a run at
``rtol0`` (the limits that follow the tolerance are 10 rtol): on each axis whose check is near its
limit (a figure at half the limit or more, status 'near') or past it, it runs
the scene one level up, on top of the levels adopted so far, and measures
what that changes in the outputs: the largest difference over time, relative
to each output's range. An axis whose effect is a noticeable part of the
tolerance gets the level up; the others stay cheap, and cost no run where
their check is quiet. The probes run at ``10 rtol0`` too; a probe whose
effect there is at most :data:`REMEASURE_FRACTION` of the tolerance (near
the adopt threshold, where the loose runs' time errors could decide) is
measured again at ``rtol0``, base and probe, and decided on that. Only the
recommended models then run at ``rtol0``, for the time tolerance, whose
``10 rtol0`` run is the last adopted probe's (or the base's).

Axes and their levels, in the order they are tried
--------------------------------------------------
friction
    the tubes given ``friction='laminar'`` whose Reynolds number passed their
    ``Re_laminar`` -> ``'Haaland'`` (check ``tube_reynolds``): an override of
    those tubes only (below ``Re_laminar`` the two laws are the same, so a
    near miss is not run).
tube law
    gas tubes given the low-Mach ``compressible='mean_density'`` law near or
    past Mach 0.3 -> the default ``compressible='pipe_flow'`` law
    (check ``tube_mach``), those tubes only. Tubes with the default law, which
    models acceleration and choking, have nothing on this axis.
inertance
    liquid tubes whose column's inertia is near or past its limit (check
    ``tube_inertia``) -> ``inertance=True``, those tubes only.
fluid level
    ``'ideal'`` -> ``'table'`` (-> ``'eos'`` where a state leaves the tables),
    when a gas's ``|Z - 1|`` is near or past its limit (check
    ``gas_compressibility``; at rtol0 the limit is the tolerance).
thermal
    ``'isothermal'`` -> per volume, in the volumes whose fill time is near or
    past its limit (check ``thermal_time_scale``) and the volumes with a wall
    (``hA``, or a coefficient and an area) whose isothermal error is estimated
    past NEAR_FRACTION of the tolerance
    (:func:`~softflow.solve.model_checks.isothermal_error`, (gamma - 1) times
    the thermal time constant over the fill time: the check's limit, "closer
    to adiabatic", is coarse for a 1 % tolerance): their heat transfer where
    they have a wall, else adiabatic; the other volumes held isothermal
    (``thermal='isothermal'`` overrides in a thermal scene).
(clear-cut axes last, in one run)
    where the last axes to probe are each far past their limit
    (:data:`CLEAR_FACTOR` times it, or an isothermal error estimated at that
    many tolerances), each would be adopted, and their run is the
    recommended models' run at ``10 rtol0``, which the time tolerance needs
    anyway. That run also takes the levels up of the axes whose checks are
    past their limit ("past" lifts, which would otherwise cost a probe of
    their own): the tube laws (friction past ``Re_laminar``, Mach past 0.3:
    one law for another in the tubes named, no state added, about the same
    cost a step; the tube law past Mach 0.3 changed near_choking's pressure
    by 1.9 %, and by 0.6-1.3 % already between Mach 0.16 and 0.26, near its
    limit) and the fluid level where ``|Z - 1|`` is past the tolerance in
    every volume flagged (the ideal level is then outside its validity for
    the tolerance asked, and a recommendation that kept it would warn on
    every run; the table level costs more a step, 2.2x the ideal one in the
    bottle's heat-transfer runs, the price where its effect alone would have
    been small: measured alone on seven air bottle fills between 4 and 18
    MPa with ``|Z - 1|`` 1.19-1.48 times its limit, it changed the outputs by
    0.54-3.7 %, each past the adopt threshold, 0.5 %). Where this makes two or
    more lifts, they are adopted in one run and their effect is reported
    together; a lift whose check is only near its limit, or that no
    clear-cut axis follows, is measured on its own as any other.
time tolerance
    on the models chosen (their time errors differ: a friction law's
    transition, a thermal scene's slow modes): their run at ``10 rtol0``
    (the last adopted probe's) against one at ``rtol0``: within what the neglected axes leave of
    ``LOOSE_FRACTION`` of the tolerance, ``10 rtol0`` is recommended; within
    twice that, ``rtol0`` is kept (errors shrink at least 3x per decade of
    rtol); else ``rtol0`` against ``rtol0 / 10``, the tighter recommended
    where they differ by more than ``LOOSE_FRACTION``.

Where the cheapest configuration fails (a laminar tube at high Reynolds
number chokes), the levels up are tried one at a time, those whose check
the failed run found near or past its limit first; the first that runs is
the base. A laminar tube that choked gets its friction and its tube law
lifted together (its flow ran far past Mach 0.3: one run instead of a base
run and a tube-law probe).

Variants are built from a copy of the System (components rebuilt from their
recorded constructor arguments, with the overrides); the user's System is
never changed. The same models at another rtol (the time tolerance's runs)
run on the Simulation compiled for them, set to that rtol (``_set_rtol``:
bitwise the run of a Simulation built at it). Costs are CPU times
(``time.process_time``) of building and running each Simulation.

What it costs: the base run and one run per probe, at ``10 rtol0`` (the
last adopted probe's run is the recommended models' ``10 rtol0`` run, the
cheapest adequate configuration where it is recommended), the recommended
models at ``rtol0``, and two runs at ``rtol0`` for each probe measured again.
Where the models chosen differ from the base and no probe is measured again,
that is the base at ``10 rtol0`` plus one run of the cheapest adequate
configuration plus about 1.3-1.5 such runs (``rtol0``'s). The time tolerance
needs the pair: a model's time error is not another's (laminar water: ``10
rtol0`` is 0.51 % from ``rtol0`` in the base models, 0.77 % in the models
chosen). Until 2026-12-03 the base and the probes ran at ``rtol0``: the same
recommendations and adopt decisions on the ten scenes of
``benchmarks/bench_assess.py``, the effects within 0.9 points, at 5-15 % more
CPU on the thermal scenes (fast fill 3.1-3.2x the cheapest adequate run,
against 2.75-3.0x now: ``benchmarks/assess_design_d.py`` measured the two
in turns).
"""
from __future__ import annotations

import copy
import dataclasses
import inspect
import math
import sys
import time
import types
import warnings
from typing import Any

import numpy as np

#: An axis whose measured effect on the outputs exceeds this fraction of the
#: tolerance is given its level up (the neglected effects of several axes and
#: the time error add up: see BUDGET_FRACTION).
ADOPT_FRACTION = 0.5
#: The neglected effects together may use this much of the tolerance (the time
#: error up to LOOSE_FRACTION more); past it, the largest neglected axis is
#: given its level up too.
BUDGET_FRACTION = 0.5
#: The time error allowed: 10 rtol0 is recommended where it differs from rtol0
#: by at most this fraction of the tolerance less the neglected effects;
#: rtol0 is kept where it differs from 10 rtol0 by at most twice this, or
#: from rtol0 / 10 by at most this (else rtol0 / 10 is recommended).
LOOSE_FRACTION = 0.4
#: The base run and the probes run at rtol0 x LOOSE_FACTOR (10: the loose
#: member of the time tolerance's pair), their validity checks judged at
#: rtol0; only the recommended models run at rtol0 as well (module
#: docstring). 1 gives the design before 2026-12-03, everything at rtol0
#: (benchmarks/assess_design_d.py compares the two).
LOOSE_FACTOR = 10.0
#: A probe whose effect, measured on those loose runs, is at most this
#: fraction of the tolerance is measured again at rtol0 (base and probe), and
#: decided on that: near the adopt threshold the loose runs' time errors
#: could hide an effect (on the ten scenes of bench_assess.py the effects at
#: 10 rtol0 were within 0.9 points of those at rtol0).
REMEASURE_FRACTION = 3 * ADOPT_FRACTION
#: A check this many times past its limit (or, for the thermal axis, an
#: isothermal error estimated at this many tolerances) is clear-cut: the last
#: probes, where two or more are, are run as one (module docstring).
CLEAR_FACTOR = 10.0

_THERMAL_CHECK = "thermal_time_scale"
_INERTIA_CHECK = "tube_inertia"
_FLUID_CHECK = "gas_compressibility"
_FRICTION_CHECK = "tube_reynolds"
_MACH_CHECK = "tube_mach"
_CHOKED_CHECK = "tube_choked"


class AssessmentError(RuntimeError):
    """No configuration of the scene ran. ``failures`` lists (configuration,
    message) for each one tried."""

    def __init__(self, message, failures=()):
        super().__init__(message)
        self.failures = list(failures)


@dataclasses.dataclass(frozen=True)
class Config:
    """One configuration of a scene: the Simulation's thermal model and rtol,
    the fluids' level, and per-component constructor overrides
    (``((label, ((argument, value), ...)), ...)``)."""

    thermal: str = "isothermal"
    fluid_level: str = "ideal"
    rtol: float = 1e-3
    overrides: tuple = ()

    def replace(self, **changes):
        return dataclasses.replace(self, **changes)

    def with_overrides(self, extra):
        merged = self.overrides_dict()
        for label, args in extra.items():
            merged.setdefault(label, {}).update(args)
        return self.replace(overrides=_freeze(merged))

    def overrides_dict(self):
        return {label: dict(args) for label, args in self.overrides}

    def describe(self):
        text = f"{self.thermal}/{self.fluid_level}/rtol {self.rtol:.0e}"
        if self.overrides:
            text += " with " + ", ".join(
                f"{label}." + ",".join(f"{k}={v!r}" for k, v in args)
                for label, args in self.overrides)
        return text


def _freeze(overrides):
    return tuple(sorted((label, tuple(sorted(args.items())))
                        for label, args in overrides.items() if args))


@dataclasses.dataclass
class Run:
    """One run of the assessment: its configuration, its Result (a failed
    run's too, None where the Simulation could not be built), the error that
    stopped it (None for a run that succeeded) and its CPU time [s]."""

    config: Config
    result: Any
    error: str | None
    cpu: float

    @property
    def ok(self):
        return self.error is None


# -- building variants ---------------------------------------------------------------
def _rebuilt(comp, changes):
    """``comp`` made again from its constructor arguments with ``changes``
    (structural ones too: a fluid, a friction law, a tube law)."""
    definition = comp.__dict__.get("_definition")
    if definition is None:
        raise ValueError(f"{comp.describe()}: a user component cannot be rebuilt with "
                         f"{', '.join(changes)}; give it the model yourself")
    args, kwargs = definition
    bound = inspect.signature(type(comp).__init__).bind(comp, *args, **kwargs)
    bound.arguments.update(changes)
    return type(comp)(*bound.args[1:], **bound.kwargs)


def variant_system(system, fluid_level=None, overrides=None):
    """A new System like ``system``: every catalogued fluid at ``fluid_level``
    (None keeps each one's level) and the constructor ``overrides``
    ``{label: {argument: value}}`` applied, where the argument
    ``fluid_level`` gives that component's fluid a level of its own (the
    high-pressure part of a network at 'table' or 'eos', the rest ideal).
    ``system`` is not changed."""
    from .network import System
    overrides = overrides or {}
    unknown = sorted(set(overrides) - {c.label for c in system.components})
    if unknown:
        raise KeyError(f"overrides name no component of the system: {unknown}")
    work = copy.deepcopy(system)
    fluids = {}

    def level(fluid, wanted):
        if (fluid is None or wanted is None or fluid.level == wanted
                or getattr(fluid, "spec", None) is None):
            return fluid
        key = (id(fluid), wanted)
        if key not in fluids:
            fluids[key] = fluid.with_level(wanted)
        return fluids[key]

    out = System(work.label)
    for comp in work.components:
        changes = dict(overrides.get(comp.label, {}))
        fluid = comp.__dict__.get("fluid")
        new_fluid = level(fluid, changes.pop("fluid_level", fluid_level))
        if new_fluid is not fluid and "fluid" in inspect.signature(type(comp).__init__).parameters:
            changes["fluid"] = new_fluid
        out.add(_rebuilt(comp, changes) if changes else comp)
    for node in work.nodes():
        if len(node.terminals) > 1:
            out.connect(*[(t.component.label, t.label) for t in node.terminals])
    return out


def _gas_volumes(system):
    """The gas volumes whose thermal model assess chooses (not those the user
    holds at their wall temperature with ``thermal='isothermal'``)."""
    from .components.thermal import VOLUME_CLASSES
    return [c for c in system.components if isinstance(c, VOLUME_CLASSES)
            and getattr(c, "fluid", None) is not None and c.fluid.compressible
            and getattr(c, "thermal", None) != "isothermal"]


def _has_wall(comp):
    from .solve.model_checks import has_wall      # (softflow.solve imports this module)
    return has_wall(comp)


def _catalogued(comp):
    """Whether ``comp`` holds a gas of the catalogue (one that has other levels)."""
    fluid = getattr(comp, "fluid", None)
    return (fluid is not None and fluid.compressible
            and getattr(fluid, "spec", None) is not None)


def _catalogued_gases(system):
    return [c.fluid for c in system.components if _catalogued(c)]


# -- comparing runs -------------------------------------------------------------------
def _normalize_outputs(system, outputs):
    if outputs is None:
        found = [(c.label, "pressure") for c in system.components if c.states
                 and any(v.quantity == "pressure" for t in c.terminals for v in t.variables)]
        if not found:
            raise ValueError("assess: the system has no volume whose pressure could serve as "
                             "output; name the outputs, e.g. outputs=[('tube', 'massflow', 'b')]")
        return [(label, name, None) for label, name in found]
    if isinstance(outputs, (str, tuple)):
        outputs = [outputs]
    out = []
    for spec in outputs:
        if isinstance(spec, str):
            if "." not in spec:
                raise ValueError(f"assess: output {spec!r} is not 'label.variable' or "
                                 "(label, variable[, terminal])")
            spec = tuple(spec.split(".", 1))
        if not isinstance(spec, tuple) or len(spec) not in (2, 3):
            raise ValueError(f"assess: output {spec!r} is not (label, variable[, terminal])")
        if spec[0] not in system:
            raise KeyError(f"assess: output {spec!r} names no component: "
                           + system._unknown_label(spec[0]))
        out.append(spec if len(spec) == 3 else (spec[0], spec[1], None))
    if not out:
        raise ValueError("assess: outputs is empty")
    return out


def _series(result, output):
    label, name, terminal = output if len(output) == 3 else (*output, None)
    return np.asarray(result.get(label, name, terminal), dtype=float)


def difference(result, reference, outputs):
    """Largest difference over time between a run's outputs and a reference's,
    each relative to the reference output's range: at the run's own time
    points (the values it returns), the reference interpolated linearly onto
    them. (A comparison at points in between would measure the linear
    interpolation of a run's few large steps, not its solution.)"""
    worst = 0.0
    for output in outputs:
        ref = _series(reference, output)
        y = _series(result, output)
        at = np.interp(result.times, reference.times, ref)
        span = float(np.ptp(ref)) or float(np.max(np.abs(ref))) or 1.0
        worst = max(worst, float(np.max(np.abs(y - at))) / span)
    return worst


# -- the assessment -------------------------------------------------------------------
class Assessment:
    """What :func:`assess` measured and what it recommends.

    Attributes
    ----------
    recommended : dict
        ``thermal`` (the scene's model), ``fluid_level``, ``friction`` ('as
        given' or 'Haaland' for the tubes named in ``overrides``),
        ``tube_law``, ``inertance``, ``rtol``, and ``overrides`` ``{label:
        {argument: value}}`` for the components that need a level of their
        own: ``{'thermal': 'isothermal'}`` for a volume held at its wall
        temperature where others fill fast, ``{'friction': 'Haaland'}``,
        ``{'compressible': 'pipe_flow'}``, ``{'inertance': True}`` for tubes,
        ``{'fluid_level': 'table'}`` for the high-pressure part of a network
        (the volumes whose ``|Z - 1|`` is near or past its limit and the
        components sharing a node with them) where the rest stays ideal.
    table : pandas.DataFrame
        One row per axis: axis, level tried, effect (largest output
        difference relative to its range), cost (CPU s of that run, and as a
        multiple of the base run), verdict.
    runs : list of Run
        Every run made (configuration, Result or error, CPU time).
    warnings : list of ValidityRecord
        The base run's validity warnings (checks past their limit).
    validity : list of ValidityRecord
        All the base run's validity records, the near misses too (they decide
        which axes are run one level up).
    cost : float
        CPU time of the whole assessment [s].
    """

    def __init__(self, system, duration, tolerance, outputs, options, rows, recommended,
                 config, runs, warnings_, cost, validity=()):
        self.system, self.duration, self.tolerance = system, duration, tolerance
        self.outputs, self.options = outputs, options
        self.rows, self.recommended, self.config = rows, recommended, config
        self.runs, self.warnings, self.cost = runs, warnings_, cost
        self.validity = list(validity)

    @property
    def table(self):
        import pandas as pd
        return pd.DataFrame(self.rows, columns=["axis", "level tried", "effect", "cost [s]",
                                                "cost ratio", "verdict"])

    def system_recommended(self):
        """A new System with the recommended fluid level and overrides."""
        return variant_system(self.system, self.config.fluid_level,
                              self.config.overrides_dict())

    def simulation(self, **options):
        """A Simulation of the recommended configuration (``options`` add to or
        replace the Simulation keywords given to assess)."""
        from .solve.simulation import Simulation
        kw = {**self.options, **options}
        kw.setdefault("thermal", self.config.thermal)
        kw.setdefault("rtol", self.config.rtol)
        return Simulation(self.system_recommended(), self.duration, **kw)

    def __repr__(self):
        r = self.recommended
        return (f"<Assessment tolerance {self.tolerance:g}: thermal={r['thermal']!r}, "
                f"fluid_level={r['fluid_level']!r}, friction={r['friction']!r}, "
                f"tube_law={r['tube_law']!r}, rtol={r['rtol']:.0e}, "
                f"{len(r['overrides'])} overrides; {len(self.runs)} runs, {self.cost:.3g} s CPU>")


class _Assessor:
    def __init__(self, system, duration, tolerance, outputs, options, checks_rtol=None):
        self.system, self.duration, self.tolerance = system, duration, tolerance
        self.outputs, self.options = outputs, options
        #: the rtol every run's validity checks are judged at (rtol0)
        self.checks_rtol = checks_rtol
        self.runs = []
        self._systems = {}
        self._simulations = {}

    def run(self, config):
        from .solve.simulation import Simulation
        from .solve.validity import ModelWarning
        for done in self.runs:
            if done.config == config:
                return done
        t0 = time.process_time()
        result = error = None
        try:
            key = (config.fluid_level, config.overrides)
            if key not in self._systems:
                self._systems[key] = variant_system(self.system, config.fluid_level,
                                                    config.overrides_dict())
            # the same models at another rtol (the time tolerance's runs): the
            # Simulation compiled for them, set to that rtol, not a new one
            sim = self._simulations.get((key, config.thermal))
            if sim is None:
                # (compared at the steps, refine=1: difference() reads the
                # points a run returns, which refine='auto' adds inside them)
                sim = Simulation(self._systems[key], self.duration, thermal=config.thermal,
                                 rtol=config.rtol, **{"refine": 1, **self.options})
                self._simulations[(key, config.thermal)] = sim
            else:
                _set_rtol(sim, config.rtol, self.options.get("atol"))
            sim._checks_rtol = self.checks_rtol
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ModelWarning)
                result = sim.run(raise_on_failure=False, progress=False)
            if result.status != "success":
                error = result.message
        except Exception as err:       # a variant that cannot be built: reported, not fatal
            error = f"{type(err).__name__}: {err}"
        done = Run(config, result, error, time.process_time() - t0)
        self.runs.append(done)
        return done


def _set_rtol(sim, rtol, given_atol=None):
    """Set the Simulation ``sim`` to run at ``rtol`` as ``Simulation(...,
    rtol=rtol)`` would: its absolute tolerances not given (``given_atol``,
    the ``atol=`` it was built with) are the Simulation's own defaults at
    that rtol (``default_atol``); those given stay. What a run reads of rtol
    is read at the run (Newton's tolerance, the integrator's, the consistent
    start's key), so the run is the one a Simulation built at ``rtol`` makes,
    without compiling the models again (a test checks it bitwise)."""
    from .solve.simulation import default_atol
    given = set(given_atol or ())
    defaults = default_atol(rtol)
    sim.atol = {q: (v if q in given or q not in defaults else defaults[q])
                for q, v in sim.atol.items()}
    sim.rtol = float(rtol)


def _check_tolerance(tolerance):
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.floating)):
        raise TypeError(f"assess: tolerance must be a number between 0 and 1 (a fraction of "
                        f"each output's range), got {tolerance!r}")
    if not (0 < tolerance < 1) or not math.isfinite(tolerance):
        raise ValueError(f"assess: tolerance must be > 0 and < 1 (a fraction of each output's "
                         f"range, 0.01 = 1 %), got {tolerance!r}")
    return float(tolerance)


_CONFLICTS = ("thermal", "rtol")


def assess(system, duration, tolerance=0.01, outputs=None, **simulation_options):
    """Find the cheapest adequate model of ``system`` for ``duration``.

    Parameters
    ----------
    system : System
        Not changed; variants are built from copies.
    duration : float [s] or Quantity
    tolerance : float [-], default 0.01
        Accepted error of each output, as a fraction of its range over the run.
    outputs : sequence of (label, variable[, terminal]) or 'label.variable', optional
        What must be within the tolerance; default the pressure of every
        component with states (the volumes).
    **simulation_options
        Further Simulation keywords (``record``, ``beyond_limits``, ...);
        ``thermal`` and ``rtol`` are what assess chooses and are refused.

    Returns
    -------
    Assessment
    """
    tolerance = _check_tolerance(tolerance)
    given = sorted(set(_CONFLICTS) & set(simulation_options))
    if given:
        raise ValueError(f"assess: {', '.join(given)} given, but that is what assess chooses; "
                         "leave it out, or run Simulation(...) with it yourself")
    if simulation_options.get("step") is not None or simulation_options.get("adaptive") is False:
        raise ValueError("assess: a fixed step was given, but assess chooses the adaptive "
                         "integrator's rtol; leave step= out")
    outputs = _normalize_outputs(system, outputs)
    from .units import to_si
    duration = to_si(duration, "s", name="duration", owner="assess")
    t_start = time.process_time()
    rtol0 = tolerance / 10
    a = _Assessor(system, duration, tolerance, outputs, simulation_options, checks_rtol=rtol0)
    scene = _Scene(system)

    base = a.run(Config("isothermal", "ideal", rtol0 * LOOSE_FACTOR))
    verdict = "run"
    if not base.ok:
        failed = base
        base = _fallback(a, base, scene, rtol0)
        why = failed.error if len(failed.error) <= 160 else failed.error[:160] + "..."
        verdict = (f"the cheapest configuration ({failed.config.describe()}) failed: "
                   f"{why}; this is the first one up that ran")
    for output in outputs:
        try:
            _series(base.result, output)
        except KeyError as err:
            raise KeyError(f"assess: output {output[:2] if output[2] is None else output}: "
                           f"{err.args[0]}") from None
    records = base.result.validity
    rows = [("base", base.config.describe(), math.nan, base.cpu, 1.0, verdict)]
    lifted = sorted(lab for lab, args in base.config.overrides if dict(args).get("compressible"))
    if lifted:
        rows.append(("tube law", f"{', '.join(lifted)}: compressible='pipe_flow'", math.nan,
                     0.0, 0.0, "adopted with the friction law: the cheapest configuration "
                     "choked there (the base run is this level's)"))

    def cost_row(axis, tried, effect, run, verdict):
        rows.append((axis, tried, effect, run.cpu, run.cpu / base.cpu if base.cpu else math.nan,
                     verdict))

    # each axis near or past its limit, one level up on top of the levels adopted
    # so far (the last adopted run is then the recommended configuration's)
    current, neglected = base, {}
    from .solve.model_checks import isothermal_error
    errors = isothermal_error(base.result)
    probes = scene.probes(base.config, records, rows, errors, tolerance)
    together = _together(probes)

    def probe(axis, tried, lift, reason):
        """Run ``lift`` on the current configuration; adopt it where it changes
        the outputs by more than ADOPT_FRACTION of the tolerance."""
        nonlocal current
        up = a.run(lift(current.config))
        if not up.ok and axis == "fluid level":
            cost_row(axis, tried, math.nan, up, f"failed: {up.error}")
            lift = _fluid_lift("eos", lift.part)
            tried = _fluid_tried("eos", lift.part)
            up = a.run(lift(current.config))
        if not up.ok:
            cost_row(axis, tried, math.nan, up, f"failed: {up.error}; kept the lower level")
            return
        effect = difference(current.result, up.result, outputs)
        how = ""
        if effect <= REMEASURE_FRACTION * tolerance and up.config.rtol != rtol0:
            # near the threshold the loose runs' time errors could decide: again at rtol0
            here = a.run(current.config.replace(rtol=rtol0))
            there = a.run(up.config.replace(rtol=rtol0))
            if here.ok and there.ok:
                how = (f" (measured again at rtol {rtol0:.0e}: {effect:.2%} at rtol "
                       f"{up.config.rtol:.0e})")
                effect = difference(here.result, there.result, outputs)
            else:       # decided on the loose runs, and the row says so
                how = (f" (at rtol {up.config.rtol:.0e}; again at rtol {rtol0:.0e} it "
                       f"failed: {(here.error or there.error)[:120]})")
        if effect > ADOPT_FRACTION * tolerance:
            current = up
            cost_row(axis, tried, effect, up, f"adopted ({reason}): changes the outputs by "
                                              f"{effect:.2%}{how}")
        else:
            neglected[axis] = (effect, lift, len(rows))
            cost_row(axis, tried, effect, up,
                     f"kept the lower level ({reason}): {effect:.2%}{how}")

    for args in probes:
        if not any(args is t for t in together):
            probe(*args)
    if together:
        cfg = current.config
        for _, _, lift, _ in together:
            cfg = lift(cfg)
        up = a.run(cfg)
        if up.ok:
            effect = difference(current.result, up.result, outputs)
            names = [axis for axis, _, _, _ in together]
            for axis, tried, lift, reason in together:
                why = (f"clear-cut: {CLEAR_FACTOR:g} x past its limit or more"
                       if getattr(lift, "clear", False) else
                       "not measured on its own: the ideal level is outside its validity "
                       "for this tolerance there" if axis == "fluid level" else
                       "not measured on its own: one law for another in the tubes named, "
                       "about the same cost and no state added")
                cost_row(axis, tried, effect, up,
                         f"adopted ({reason}, {why}) together with "
                         f"{', '.join(n for n in names if n != axis)}, "
                         f"in one run: they change the outputs by {effect:.2%}")
            current = up
        else:          # one at a time, as any other probe
            for args in together:
                probe(*args)
    config = current.config
    # the errors left add up: keep them within the budget (the time error is
    # measured below, on the configuration chosen)
    while neglected and (sum(e for e, _, _ in neglected.values())
                         > BUDGET_FRACTION * tolerance):
        axis = max(neglected, key=lambda k: neglected[k][0])
        effect, lift, row = neglected.pop(axis)
        config = lift(config)
        rows[row] = rows[row][:5] + (f"adopted: {effect:.2%}, and the neglected effects "
                                     f"together pass {BUDGET_FRACTION:g} x tolerance",)
    config = _time_tolerance(a, config.replace(rtol=rtol0),
                             base_config=base.config.replace(rtol=rtol0), spare=(
        LOOSE_FRACTION * tolerance - sum(e for e, _, _ in neglected.values())),
        cost_row=cost_row)
    recommended = _recommendation(config, scene.laminar)
    cost = time.process_time() - t_start
    return Assessment(system, duration, tolerance, outputs, simulation_options, rows,
                      recommended, config, a.runs, base.result.warnings, cost,
                      validity=records)


def _together(probes):
    """The probes adopted in one run: the last ones, where they are clear-cut
    (``lift.clear``), with the lifts past their limit (``lift.past``: a tube
    law past Mach 0.3 or ``Re_laminar``, the fluid level past ``|Z - 1|``'s
    limit) from among the others, where that makes two or more. Each of them
    would be adopted (a lift past its limit: the lower level is outside its
    validity there; a tube law for another costs about nothing where finer
    than needed, the table level a price per step), and their run is the
    recommended models' run at 10 rtol0, which the time tolerance needs
    anyway. A lift past its limit that no clear-cut probe follows is
    measured on its own."""
    n_clear = 0
    while n_clear < len(probes) and getattr(probes[-1 - n_clear][2], "clear", False):
        n_clear += 1
    if not n_clear:
        return []
    clear = probes[len(probes) - n_clear:]
    past = [p for p in probes[:len(probes) - n_clear] if getattr(p[2], "past", False)]
    together = past + clear
    return together if len(together) >= 2 else []


def _time_tolerance(a, config, base_config, spare, cost_row):
    """The rtol of the models chosen (their time errors differ: a friction
    law's transition, a thermal scene's slower modes). A run at 10 rtol0,
    cheaper than rtol0, is compared with rtol0: where it is within what the
    neglected axes left of LOOSE_FRACTION of the tolerance, 10 rtol0 is
    recommended; within twice LOOSE_FRACTION, rtol0 is kept (the error of a run
    shrinks at least 3x per decade of rtol, so rtol0's is at most half that
    difference); past it, rtol0 is compared with rtol0 / 10 and the tighter is
    recommended where they differ by more than LOOSE_FRACTION."""
    tol = a.tolerance
    chosen = a.run(config)
    if not chosen.ok:
        cost_row("models chosen", config.describe(), math.nan, chosen,
                 f"failed together: {chosen.error}; kept the base configuration")
        return base_config
    rtol0 = config.rtol
    loose = a.run(config.replace(rtol=rtol0 * 10))
    tried = f"rtol {rtol0:.0e} -> {rtol0 * 10:.0e}"
    d = difference(loose.result, chosen.result, a.outputs) if loose.ok else math.inf
    if d <= spare:
        cost_row("time tolerance", tried, d, loose,
                 f"adopted rtol {rtol0 * 10:.0e}: {d:.2%} from rtol {rtol0:.0e}")
        return loose.config
    if d <= 2 * LOOSE_FRACTION * tol:
        cost_row("time tolerance", tried, d, loose,
                 f"kept rtol {rtol0:.0e}: rtol {rtol0 * 10:.0e} is {d:.2%} from it"
                 if loose.ok else f"kept rtol {rtol0:.0e}: {loose.error}")
        return config
    cost_row("time tolerance", tried, d, loose,
             f"rtol {rtol0 * 10:.0e} is {d:.2%} from rtol {rtol0:.0e}" if loose.ok
             else f"failed: {loose.error}")
    tight = a.run(config.replace(rtol=rtol0 / 10))
    tried = f"rtol {rtol0:.0e} -> {rtol0 / 10:.0e}"
    if not tight.ok:
        cost_row("time tolerance", tried, math.nan, tight, f"failed: {tight.error}")
        return config
    d = difference(chosen.result, tight.result, a.outputs)
    if d > LOOSE_FRACTION * tol:
        cost_row("time tolerance", tried, d, tight, f"adopted: rtol {rtol0:.0e} is {d:.2%} off")
        return tight.config
    cost_row("time tolerance", tried, d, tight,
             f"kept rtol {rtol0:.0e}: {d:.2%} from rtol {rtol0 / 10:.0e}")
    return config


class _Scene:
    """What a System offers each axis: its gas volumes (and which have walls),
    catalogued gases, tubes given friction='laminar', liquid tubes."""

    def __init__(self, system):
        self.system = system
        self.volumes = _gas_volumes(system)
        self.gases = _catalogued_gases(system)
        self.laminar = [c.label for c in system.components
                        if getattr(c, "friction", None) == "laminar"]
        self.liquid_tubes = [c.label for c in system.components
                             if hasattr(c, "inertance") and getattr(c, "fluid", None) is not None
                             and not c.fluid.compressible and not c.inertance]

    def high_pressure_part(self, labels):
        """The components a finer fluid level serves where the volumes
        ``labels`` need it: those volumes and every component with a catalogued
        gas that shares a node with one of them (the tube or orifice that fills
        it sees its pressure). None where that is every such component (the
        whole scene's level then)."""
        flagged, part = set(labels), set(labels)
        for node in self.system.nodes():
            comps = [t.component for t in node.terminals]
            if flagged & {c.label for c in comps}:      # a neighbour, not further
                part |= {c.label for c in comps if _catalogued(c)}
        gas = {c.label for c in self.system.components if _catalogued(c)}
        return None if gas <= part else sorted(part)

    def lifted_volumes(self, records, errors, tolerance):
        """The volumes one thermal level up would lift: those whose
        thermal_time_scale check is near or past its limit, and those with a
        wall whose isothermal error is estimated past NEAR_FRACTION of the
        tolerance (:func:`softflow.solve.model_checks.isothermal_error`; a
        wall-less volume's level up is adiabatic, which only a fill near or
        past the check's limit is closer to)."""
        from .solve.validity import NEAR_FRACTION
        hot = {r.component for r in records if r.check == _THERMAL_CHECK}
        return [c for c in self.volumes if c.label in hot or (
            _has_wall(c) and errors.get(c.label, math.inf) > NEAR_FRACTION * tolerance)]

    def thermal_lift(self, lifted):
        """Config -> config one thermal level up in the volumes ``lifted``:
        those with a wall their heat transfer, the others adiabatic; the
        other volumes held isothermal (a per-volume override, where some
        volumes fill fast and others do not)."""
        held = [c.label for c in self.volumes if c not in lifted]
        model = "heat_transfer" if all(_has_wall(c) for c in lifted) else "adiabatic"

        def lift(cfg):
            return cfg.replace(thermal=model).with_overrides(
                {lab: {"thermal": "isothermal"} for lab in held})
        tried = f"isothermal -> {model}"
        if held:
            tried += f" in {', '.join(c.label for c in lifted)} (held isothermal: " \
                     f"{', '.join(held)})"
        return tried, lift

    def probes(self, base_cfg, records, rows, errors, tolerance):
        """(axis, level tried, lift: config -> config, reason) for each axis a
        check finds near or past its limit, in the order they are run (the
        cheap ones first, the thermal model last); a row for each axis kept
        without a run."""
        from .solve.validity import NEAR_FRACTION
        by_check = {}
        for r in records:
            by_check.setdefault(r.check, []).append(r)
        out = []

        def per_tube(check, arg, value, status=("near", "beyond"), law=False):
            found = [r for r in by_check.get(check, ()) if r.status in status]
            labels = sorted({r.component for r in found})

            def lift(cfg):
                return cfg.with_overrides({lab: {arg: value} for lab in labels})
            # clear-cut where every tube lifted is CLEAR_FACTOR past its limit
            lift.clear = bool(found) and min(r.fraction for r in found) >= CLEAR_FACTOR
            # past: a law for another (no state added) in tubes all past the limit
            lift.past = law and bool(found) and all(r.status == "beyond" for r in found)
            return labels, lift

        labels, lift = per_tube(_FRICTION_CHECK, "friction", "Haaland", ("beyond",), law=True)
        if labels:
            out.append(("friction", f"{', '.join(labels)}: friction='Haaland'", lift,
                        "Re past Re_laminar"))
        elif [lab for lab in self.laminar
              if "friction" not in base_cfg.overrides_dict().get(lab, {})]:
            rows.append(("friction", "laminar", math.nan, 0.0, 0.0,
                         "kept: every laminar tube stays below its Re_laminar, where the "
                         "laminar law and the default blend are the same"))
        labels, lift = per_tube(_MACH_CHECK, "compressible", "pipe_flow", law=True)
        if labels:
            out.append(("tube law", f"{', '.join(labels)}: compressible='pipe_flow'", lift,
                        "Mach past 0.3" if lift.past else "Mach near or past 0.3"))
        labels, lift = per_tube(_INERTIA_CHECK, "inertance", True)
        if labels:
            out.append(("inertance", f"{', '.join(labels)}: inertance=True", lift,
                        "the liquid column's inertia near or past its limit"))
        elif self.liquid_tubes:
            rows.append(("inertance", "none", math.nan, 0.0, 0.0,
                         f"kept: the liquid columns' inertia below {NEAR_FRACTION:g} x "
                         "its limit"))
        if base_cfg.fluid_level == "ideal" and self.gases:
            if _FLUID_CHECK in by_check:
                part = self.high_pressure_part(sorted({r.component
                                                       for r in by_check[_FLUID_CHECK]}))
                lift = _fluid_lift("table", part)
                lift.clear = min(r.fraction for r in by_check[_FLUID_CHECK]) >= CLEAR_FACTOR
                lift.past = all(r.status == "beyond" for r in by_check[_FLUID_CHECK])
                out.append(("fluid level", _fluid_tried("table", part), lift,
                            "|Z - 1| past the tolerance" if lift.past
                            else "|Z - 1| near or past the tolerance"))
            else:
                rows.append(("fluid level", "ideal", math.nan, 0.0, 0.0,
                             f"kept: |Z - 1| below {NEAR_FRACTION:g} x tolerance"))
        if base_cfg.thermal == "isothermal":
            # a volume with a wall is measured where its isothermal error is
            # estimated near the tolerance even if the check (a fill time
            # against a tenth of the thermal time constant: "closer to
            # adiabatic", coarse for a 1 % tolerance) is quiet
            lifted = self.lifted_volumes(records, errors, tolerance)
            if lifted:
                tried, lift = self.thermal_lift(lifted)
                lift.clear = min(errors.get(c.label, 0.0) for c in lifted) >= \
                    CLEAR_FACTOR * tolerance
                hot = sorted({r.component for r in by_check.get(_THERMAL_CHECK, ())})
                warm = sorted(c.label for c in lifted if c.label not in hot)
                out.append(("thermal", tried, lift, "; ".join(
                    ([f"fill time near or past its limit in {', '.join(hot)}"] if hot else [])
                    + ([f"isothermal error estimated {max(errors[x] for x in warm):.2%} in "
                        f"{', '.join(warm)}"] if warm else []))))
            else:
                rows.append(("thermal", "isothermal", math.nan, 0.0, 0.0, (
                    f"kept: no volume fills near a tenth of its thermal time constant, the "
                    f"isothermal error estimated at most "
                    f"{max(errors.values(), default=0.0):.2%}")
                    if self.volumes else "kept: no gas volume whose model is to choose "
                    "(volumes given thermal='isothermal' stay held at their wall)"))
        return out


def _fluid_lift(level, part=None):
    """Config -> config with the fluids at ``level``: the whole scene's, or only
    the components ``part`` (a per-component override)."""
    def lift(cfg):
        if part is None:
            return cfg.replace(fluid_level=level)
        return cfg.with_overrides({lab: {"fluid_level": level} for lab in part})
    lift.part = part
    return lift


def _fluid_tried(level, part):
    return f"ideal -> {level}" + ("" if part is None else f" in {', '.join(part)}")


def _recommendation(config, laminar):
    overrides = config.overrides_dict()

    def named(arg, value):
        return [lab for lab, args in overrides.items() if args.get(arg) == value]
    haaland = named("friction", "Haaland")
    fine = [lab for lab, args in overrides.items() if "fluid_level" in args]
    return {"thermal": config.thermal,
            "fluid_level": (f"{config.fluid_level}, finer where overridden" if fine
                            else config.fluid_level),
            "friction": ("Haaland" if laminar and sorted(haaland) == sorted(laminar)
                         else "as given, Haaland where overridden" if haaland else "as given"),
            "tube_law": ("as given, isothermal where overridden"
                         if named("compressible", "pipe_flow") else "as given"),
            "inertance": ("as given, True where overridden" if named("inertance", True)
                          else "as given"),
            "rtol": config.rtol, "overrides": overrides}


def _fallback(a, failed, scene, rtol0):
    """The base configuration failed: try one level up on each axis, those
    whose check the failed run found near or past its limit first (a laminar
    tube past Re_laminar chokes: Haaland, not a finer rtol: rtol0, then
    rtol0 / 10, the base having run at 10 rtol0), then all at once; the first
    that runs becomes the base. None runs: AssessmentError."""
    base_cfg = failed.config
    records = failed.result.validity if failed.result is not None else []
    flagged = {r.check for r in records}
    thermal_up = "heat_transfer" if scene.volumes and all(
        _has_wall(c) for c in scene.volumes) else "adiabatic"
    haaland = {lab: {"friction": "Haaland"} for lab in scene.laminar}
    # finer rtols: rtol0 (the base ran at 10 rtol0), then rtol0 / 10
    first, then = [], [base_cfg.replace(rtol=rtol0), base_cfg.replace(rtol=rtol0 / 10)]
    if haaland and _FRICTION_CHECK in flagged:
        # a laminar tube past Re_laminar that choked (its flow far too large)
        # ran past Mach 0.3 too: its law is lifted with its friction, and the
        # run that gets past the choke needs no tube-law probe of its own
        choked = {r.component for r in records if r.check == _CHOKED_CHECK
                  and r.component in haaland and r.status == "beyond"}
        first.append(base_cfg.with_overrides(
            {lab: dict(args, **({"compressible": "pipe_flow"} if lab in choked else {}))
             for lab, args in haaland.items()}))
    (first if _FRICTION_CHECK in flagged else then).extend(
        [base_cfg.with_overrides(haaland)] if haaland else [])
    (first if _THERMAL_CHECK in flagged else then).append(base_cfg.replace(thermal=thermal_up))
    if scene.gases:
        (first if _FLUID_CHECK in flagged else then).extend(
            [base_cfg.replace(fluid_level="table"), base_cfg.replace(fluid_level="eos")])
    every = base_cfg.replace(thermal=thermal_up, fluid_level="eos" if scene.gases else "ideal",
                             rtol=rtol0 / 10).with_overrides(haaland)
    for cfg in first + then + [every]:
        done = a.run(cfg)
        if done.ok:
            return done
    failures = [(r.config.describe(), r.error) for r in a.runs]
    lines = "\n".join(f"  - {cfg}: {msg}" for cfg, msg in failures)
    raise AssessmentError(f"assess: the scene failed in every configuration tried "
                          f"({len(failures)}):\n{lines}", failures)


def resolve_auto(keywords):
    """``Simulation(..., model='auto', tolerance=...)``: ``keywords`` are the
    Simulation's arguments; returns (system, thermal, rtol, model, tolerance,
    assessment) to compile, model and tolerance set back to None (so that a
    pickled Simulation is rebuilt from the recommendation, not assessed again).
    Choices that model='auto' makes itself, given too (``thermal``, ``rtol``,
    ``step``, ``adaptive=False``), raise."""
    from .solve.simulation import Simulation
    model, tolerance = keywords["model"], keywords["tolerance"]
    if model != "auto":
        raise ValueError(f"Simulation: model must be None or 'auto' (let softflow choose), got "
                         f"{model!r}" + ("; tolerance= applies to model='auto'"
                                         if model is None else ""))
    defaults = {name: p.default for name, p in
                inspect.signature(Simulation.__init__).parameters.items()}
    conflicts = [name for name in ("thermal", "rtol", "step", "adaptive")
                 if keywords[name] is not None and keywords[name] != defaults[name]]
    if conflicts:
        raise ValueError(f"Simulation: model='auto' chooses the thermal model and the adaptive "
                         f"integrator's rtol itself, but {', '.join(f'{k}=' for k in conflicts)} "
                         "was given too; leave it out, or drop model='auto'")
    options = {name: value for name, value in keywords.items()
               if name in defaults and name not in ("self", "system", "duration", "thermal",
                                                    "rtol", "step", "adaptive", "model",
                                                    "tolerance")
               and value is not defaults.get(name) and value != defaults.get(name)}
    assessment = assess(keywords["system"], keywords["duration"],
                        0.01 if tolerance is None else tolerance, **options)
    return (assessment.system_recommended(), assessment.config.thermal,
            assessment.config.rtol, None, None, assessment)


# ``import softflow.assess`` makes the package attribute ``softflow.assess`` this module
# (the import system sets it), where ``sf.assess`` is otherwise the function: the module
# is callable as the function, so ``sf.assess(system, ...)`` works either way.
class _CallableModule(types.ModuleType):
    def __call__(self, *args, **kwargs):
        return assess(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
