"""Let softflow choose the model: the cheapest configuration adequate for a scene.

``sf.assess(system, duration, tolerance=0.01, outputs=[("act1", "volume")])`` runs
the scene in its cheapest configuration (isothermal, ideal fluids, the
components' own friction and tube laws, ``rtol = tolerance / 10``), reads the
validity checks of that run (:mod:`softflow.solve.model_checks`) and, on each
axis where a check fires or is near its limit, runs the scene one level up and
measures what that changes in the outputs: the largest difference over time,
relative to each output's range. An axis whose effect is a noticeable part of
the tolerance gets the level up; the others stay cheap.

Axes and their levels
---------------------
time tolerance
    ``rtol0 = tolerance / 10`` -> ``rtol0 / 10``, always, on the models chosen
    on the other axes (their time errors differ: a friction law's transition,
    a thermal scene's slow modes): where the two differ by more than
    ``LOOSE_FRACTION`` of the tolerance, the tighter one is recommended.
thermal
    ``'isothermal'`` -> ``'adiabatic'`` (``'heat_transfer'`` where every gas
    volume has a wall: ``hA``, or a coefficient and an area), when a volume
    fills faster than its wall exchanges heat (check ``thermal_time_scale``,
    a free-convection estimate), or when the user gave a volume a wall (its
    heat transfer is then measured instead of estimated).
fluid level
    ``'ideal'`` -> ``'table'`` (-> ``'eos'`` where a state leaves the tables),
    when a gas's compressibility factor is off by more than NEAR_FRACTION of the
    tolerance (check ``gas_compressibility``, its limit tightened to that).
friction
    the tubes given ``friction='laminar'`` whose Reynolds number passed their
    ``Re_laminar`` -> ``'Haaland'`` (check ``tube_reynolds``): an override of
    those tubes only (below ``Re_laminar`` the two laws are the same).
tube law
    gas tubes past Mach 0.3 with the mean-density law ->
    ``compressible='isothermal'`` (check ``tube_mach``), those tubes only.

Variants are built from a copy of the System (components rebuilt from their
recorded constructor arguments); the user's System is never changed.
Costs are CPU times (``time.process_time``) of building and running each
Simulation.
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
#: A check counts as near its limit (and its axis is tried one level up) past
#: this fraction of the tolerance (the gas compressibility check: |Z - 1|).
NEAR_FRACTION = 0.25
#: The neglected effects together may use this much of the tolerance (the time
#: error up to LOOSE_FRACTION more); past it, the largest neglected axis is
#: given its level up too.
BUDGET_FRACTION = 0.5
#: rtol0 is kept where it differs from a run at rtol0 / 10 by at most this
#: fraction of the tolerance (else rtol0 / 10 is recommended).
LOOSE_FRACTION = 0.4

_THERMAL_CHECK = "thermal_time_scale"
_FLUID_CHECK = "gas_compressibility"
_FRICTION_CHECK = "tube_reynolds"
_MACH_CHECK = "tube_mach"


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
    """One run of the assessment: its configuration, its Result (or the
    error that stopped it) and its CPU time [s]."""

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
    ``{label: {argument: value}}`` applied. ``system`` is not changed."""
    from .network import System
    overrides = overrides or {}
    unknown = sorted(set(overrides) - {c.label for c in system.components})
    if unknown:
        raise KeyError(f"overrides name no component of the system: {unknown}")
    work = copy.deepcopy(system)
    fluids = {}

    def level(fluid):
        if (fluid is None or fluid_level is None or fluid.level == fluid_level
                or getattr(fluid, "spec", None) is None):
            return fluid
        if id(fluid) not in fluids:
            fluids[id(fluid)] = fluid.with_level(fluid_level)
        return fluids[id(fluid)]

    out = System(work.label)
    for comp in work.components:
        changes = dict(overrides.get(comp.label, {}))
        fluid = comp.__dict__.get("fluid")
        new_fluid = level(fluid)
        if new_fluid is not fluid and "fluid" in inspect.signature(type(comp).__init__).parameters:
            changes["fluid"] = new_fluid
        out.add(_rebuilt(comp, changes) if changes else comp)
    for node in work.nodes():
        if len(node.terminals) > 1:
            out.connect(*[(t.component.label, t.label) for t in node.terminals])
    return out


def _gas_volumes(system):
    from .components.thermal import VOLUME_CLASSES
    return [c for c in system.components if isinstance(c, VOLUME_CLASSES)
            and getattr(c, "fluid", None) is not None and c.fluid.compressible]


def _has_wall(comp):
    return getattr(comp, "hA", None) is not None or getattr(comp, "h_correlation", None) is not None


def _catalogued_gases(system):
    return [c.fluid for c in system.components
            if getattr(c, "fluid", None) is not None and c.fluid.compressible
            and getattr(c.fluid, "spec", None) is not None]


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
        ``thermal``, ``fluid_level``, ``friction`` ('as given' or 'Haaland' for
        the tubes named in ``overrides``), ``tube_law``, ``rtol``, and
        ``overrides`` ``{label: {argument: value}}`` for the components that
        need a level of their own.
    table : pandas.DataFrame
        One row per axis: axis, level tried, effect (largest output
        difference relative to its range), cost (CPU s of that run, and as a
        multiple of the base run), verdict.
    runs : list of Run
        Every run made (configuration, Result or error, CPU time).
    warnings : list of ValidityRecord
        The base run's validity findings.
    cost : float
        CPU time of the whole assessment [s].
    """

    def __init__(self, system, duration, tolerance, outputs, options, rows, recommended,
                 config, runs, warnings_, cost):
        self.system, self.duration, self.tolerance = system, duration, tolerance
        self.outputs, self.options = outputs, options
        self.rows, self.recommended, self.config = rows, recommended, config
        self.runs, self.warnings, self.cost = runs, warnings_, cost

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
    def __init__(self, system, duration, tolerance, outputs, options):
        self.system, self.duration, self.tolerance = system, duration, tolerance
        self.outputs, self.options = outputs, options
        self.runs = []
        self._systems = {}

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
            sim = Simulation(self._systems[key], self.duration, thermal=config.thermal,
                             rtol=config.rtol, **self.options)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ModelWarning)
                result = sim.run(raise_on_failure=False, progress=False)
            if result.status != "success":
                error = result.message
        except Exception as err:       # a variant that cannot be built: reported, not fatal
            error = f"{type(err).__name__}: {err}"
        done = Run(config, result if error is None else None, error,
                   time.process_time() - t0)
        self.runs.append(done)
        return done


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
    a = _Assessor(system, duration, tolerance, outputs, simulation_options)
    rows = []
    rtol0 = tolerance / 10
    gases = _catalogued_gases(system)
    volumes = _gas_volumes(system)
    walls = bool(volumes) and all(_has_wall(c) for c in volumes)
    thermal_up = "heat_transfer" if walls else "adiabatic"
    laminar = [c.label for c in system.components if getattr(c, "friction", None) == "laminar"]

    base_cfg = Config("isothermal", "ideal", rtol0)
    base = a.run(base_cfg)
    if not base.ok:
        base = _fallback(a, base_cfg, thermal_up, gases, laminar)
    base_cfg = base.config
    for output in outputs:
        try:
            _series(base.result, output)
        except KeyError as err:
            raise KeyError(f"assess: output {output[:2] if output[2] is None else output}: "
                           f"{err.args[0]}") from None
    records = base.result.warnings
    rows.append(("base", base_cfg.describe(), math.nan, base.cpu, 1.0, "run"))

    def cost_row(axis, tried, effect, run, verdict):
        rows.append((axis, tried, effect, run.cpu, run.cpu / base.cpu if base.cpu else math.nan,
                     verdict))

    config = base_cfg
    neglected = {}
    lower = base
    # model axes, each compared at the chosen rtol against the same-rtol base
    fired = {r.check: [] for r in records}
    for r in records:
        fired[r.check].append(r)
    fluid_near = _fluid_near(base.result, records)
    candidates = []            # (axis, tried, config up, reason)
    if base_cfg.thermal == "isothermal":
        if _THERMAL_CHECK in fired or any(_has_wall(c) for c in volumes):
            # the check estimates a wall by free convection; a wall the user gave
            # is the scene's own physics, measured directly
            candidates.append(("thermal", f"isothermal -> {thermal_up}",
                               lower.config.replace(thermal=thermal_up), _THERMAL_CHECK))
        else:
            rows.append(("thermal", "isothermal", math.nan, 0.0, 0.0,
                         "kept: no volume fills faster than a tenth of its thermal time "
                         "constant" if volumes else "kept: no gas volume"))
    if base_cfg.fluid_level == "ideal" and gases:
        if _FLUID_CHECK in fired or fluid_near:
            candidates.append(("fluid level", "ideal -> table",
                               lower.config.replace(fluid_level="table"),
                               "compressibility factor Z - 1 near or past the tolerance"))
        else:
            rows.append(("fluid level", "ideal", math.nan, 0.0, 0.0,
                         f"kept: |Z - 1| below {NEAR_FRACTION:g} x tolerance"))
    for check, axis, arg, value in ((_FRICTION_CHECK, "friction", "friction", "Haaland"),
                                    (_MACH_CHECK, "tube law", "compressible", "isothermal")):
        if check in fired:
            labels = sorted({r.component for r in fired[check]})
            candidates.append((axis, f"{', '.join(labels)}: {arg}={value!r}",
                               lower.config.with_overrides({lab: {arg: value} for lab in labels}),
                               check))
        elif axis == "friction" and laminar:
            rows.append((axis, "laminar", math.nan, 0.0, 0.0,
                         "kept: every laminar tube stays below its Re_laminar"))

    adopted = {}
    for axis, tried, up_cfg, _reason in candidates:
        up = a.run(up_cfg)
        if not up.ok and axis == "fluid level":
            cost_row(axis, tried, math.nan, up, f"failed: {up.error}")
            up_cfg, tried = up_cfg.replace(fluid_level="eos"), "ideal -> eos"
            up = a.run(up_cfg)
        if not up.ok:
            cost_row(axis, tried, math.nan, up, f"failed: {up.error}; kept the lower level")
            continue
        effect = difference(lower.result, up.result, outputs)
        if effect > ADOPT_FRACTION * tolerance:
            adopted[axis] = up_cfg
            cost_row(axis, tried, effect, up, f"adopted: changes the outputs by {effect:.2%}")
        else:
            neglected[axis] = (effect, up_cfg, len(rows))
            cost_row(axis, tried, effect, up, f"kept the lower level: {effect:.2%}")
    # the errors left add up: keep them within the budget (the time error is
    # measured below, on the configuration chosen)
    while neglected and (sum(e for e, _, _ in neglected.values())
                         > BUDGET_FRACTION * tolerance):
        axis = max(neglected, key=lambda k: neglected[k][0])
        effect, up_cfg, row = neglected.pop(axis)
        adopted[axis] = up_cfg
        rows[row] = rows[row][:5] + (f"adopted: {effect:.2%}, and the neglected effects "
                                     f"together pass {BUDGET_FRACTION:g} x tolerance",)
    for axis, up_cfg in adopted.items():
        if axis == "thermal":
            config = config.replace(thermal=up_cfg.thermal)
        elif axis == "fluid level":
            config = config.replace(fluid_level=up_cfg.fluid_level)
        else:
            config = config.with_overrides(up_cfg.overrides_dict())

    # time tolerance, on the models chosen (their time errors differ: a friction
    # law's transition, a thermal scene's slower modes): rtol0 against rtol0 / 10
    chosen = a.run(config)
    if chosen.ok:
        tight = a.run(config.replace(rtol=rtol0 / 10))
        tried = f"rtol {rtol0:.0e} -> {rtol0 / 10:.0e}"
        if tight.ok:
            d = difference(chosen.result, tight.result, outputs)
            if d > LOOSE_FRACTION * tolerance:
                config = tight.config
                verdict = f"adopted: rtol {rtol0:.0e} is {d:.2%} off"
            else:
                verdict = f"kept rtol {rtol0:.0e}: {d:.2%} from rtol {rtol0 / 10:.0e}"
            cost_row("time tolerance", tried, d, tight, verdict)
        else:
            cost_row("time tolerance", tried, math.nan, tight, f"failed: {tight.error}")
    else:
        cost_row("models chosen", config.describe(), math.nan, chosen,
                 f"failed together: {chosen.error}; kept the base configuration")
        config = base_cfg
    recommended = _recommendation(config, laminar)
    cost = time.process_time() - t_start
    return Assessment(system, duration, tolerance, outputs, simulation_options, rows,
                      recommended, config, a.runs, records, cost)


def _recommendation(config, laminar):
    overrides = config.overrides_dict()
    haaland = [lab for lab, args in overrides.items() if args.get("friction") == "Haaland"]
    isothermal = [lab for lab, args in overrides.items()
                  if args.get("compressible") == "isothermal"]
    return {"thermal": config.thermal, "fluid_level": config.fluid_level,
            "friction": ("Haaland" if laminar and sorted(haaland) == sorted(laminar)
                         else "as given, Haaland where overridden" if haaland else "as given"),
            "tube_law": ("as given, isothermal where overridden" if isothermal
                         else "as given"),
            "rtol": config.rtol, "overrides": overrides}


class _StrictRtol:
    """A base run's result seen with rtol times NEAR_FRACTION: the
    compressibility check's limit, max(10 rtol, 1e-3), is then NEAR_FRACTION
    of the tolerance (rtol0 = tolerance / 10), and finds what is near it."""

    def __init__(self, result):
        self._result = result
        self.stats = {**result.stats,
                      "rtol": result.stats.get("rtol", 1e-3) * NEAR_FRACTION}

    def __getattr__(self, name):
        return getattr(self._result, name)


def _fluid_near(result, records):
    """Whether the ideal-gas level is near its limit: the compressibility check
    evaluated with its limit at NEAR_FRACTION of the tolerance."""
    if any(r.check == _FLUID_CHECK for r in records):
        return True
    from .components.thermal import VOLUME_CLASSES
    from .solve.model_checks import gas_compressibility
    groups = {id(g): g for g, _ in result._where.values()}.values()
    view = _StrictRtol(result)
    return any(gas_compressibility(g, view) for g in groups
               if isinstance(g.comps[0], VOLUME_CLASSES))


def _fallback(a, base_cfg, thermal_up, gases, laminar):
    """The base configuration failed: try one level up on each axis, then all
    at once; the first that runs becomes the base. None runs: AssessmentError."""
    tries = [base_cfg.replace(rtol=base_cfg.rtol / 10)]
    tries.append(base_cfg.replace(thermal=thermal_up))
    if gases:
        tries += [base_cfg.replace(fluid_level="table"), base_cfg.replace(fluid_level="eos")]
    if laminar:
        tries.append(base_cfg.with_overrides({lab: {"friction": "Haaland"} for lab in laminar}))
    every = base_cfg.replace(thermal=thermal_up, fluid_level="eos" if gases else "ideal",
                             rtol=base_cfg.rtol / 10)
    if laminar:
        every = every.with_overrides({lab: {"friction": "Haaland"} for lab in laminar})
    tries.append(every)
    for cfg in tries:
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
