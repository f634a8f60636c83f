"""Simulation: compile a System once, integrate it in time, return a Result."""
from __future__ import annotations

import copy
import gc
import importlib
import math
import operator
import threading
from typing import TYPE_CHECKING, Any, Iterable, Mapping

import numpy as np

from ..assess import resolve_auto
from ..constants import pressure_atmospheric
from ..fluids.base import FluidError
from ..network.component import remember_result
from ..units import quantity_unit, to_si
from .assembly import Assembly
from .bdf import BDF, MAX_ORDER
from .culprit import Finder
from .integrator import ImplicitEuler, StepFailure, StoppedAtStart, breakpoints_within
from .progress import Progress
from .linalg import make_linear_solver
from .newton import Newton, Stats
from .params import rebuild
from .params import split as split_params
from .dense import DenseOutput, check_times
from .result import Result
from .input_checks import initial_volumes, negligible_tubes
from .validity import (PV_CURVE_SLACK, ComponentError, beyond, can_refuse,
                       check_result, checks_version, issue)
from . import settings
from .settings import ROUND_OFF, MAX_REFINE
from .thermal import check_model, configure_like, configure_thermal

#: Simulation._integrator's record when not given: the run's own
_RUN_RECORD = object()

if TYPE_CHECKING:
    from .._typing import Array, Scalar
    from ..network.system import System
    from .sensitivity import Sensitivities

#: Default bound on the steps of one run (``max_steps=``): a fixed step or a step_max
#: that asks for more is refused at construction, and a run stops past it.
MAX_STEPS = 10_000_000


#: Newton's relative tolerance at fixed steps (``newton_rtol=`` not given).
NEWTON_RTOL = 1e-6
#: Adaptive runs: Newton's relative tolerance as a fraction of rtol (IDA stops
#: its Newton iteration at a third of the error test's tolerance; a twentieth
#: here, on the max norm). Measured on the nine paper scenes against a fixed
#: 1e-6: 15-22 % fewer Newton iterations at the default rtol (2026-12-03).
NEWTON_FRACTION = 1.0 / 20.0

#: Default absolute tolerances of the adaptive error test, per quantity [SI].
DEFAULT_ATOL = {"pressure": 1.0, "massflow": 1e-9, "mass": 1e-12, "volume": 1e-12,
                "volumeflow": 1e-12, "temperature": 1e-3, "energy": 1e-7, "energyflow": 1e-4}


class SimulationError(RuntimeError):
    """A run failed. ``result`` holds everything computed up to the failure;
    ``time``, ``component`` and ``equation`` say where."""

    def __init__(self, message: str, result: Result | None = None, time: float | None = None,
                 component: str | None = None, equation: str | None = None) -> None:
        super().__init__(message)
        self.result, self.time, self.component, self.equation = result, time, component, equation


METHODS = ("bdf", "euler")


def _step_range(step, step_min, step_max):
    """(step_min, step_max) from a ``step=(min, max)`` pair (fonsim's spelling
    of an adaptive step range); None keeps a bound's default."""
    if len(step) != 2:
        raise ValueError(f"Simulation: step as a sequence must be a pair (step_min, step_max), "
                         f"got {len(step)} values: {step!r}")
    if step_min is not None or step_max is not None:
        raise ValueError("Simulation: give the step range either as step=(min, max) or as "
                         "step_min=/step_max=, not both")
    return step[0], step[1]


class Simulation:
    """Time integration of a System: adaptive variable-order BDF by default,
    backward (implicit) Euler at a fixed step when ``step`` is given.

    Parameters
    ----------
    system : System
    duration : float [s] or Quantity
    step : float [s] or Quantity, or a tuple (step_min, step_max), optional
        Constant step: backward Euler on a fixed grid (the FONS paper's
        scheme). At most ``duration`` (``step == duration`` takes one step; a
        step longer by more than round-off, :data:`ROUND_OFF` relative, is
        refused with a ValueError naming both); a step that does not divide
        the duration ends with a shorter last step. Without it the step is
        adaptive (and ``step`` is the first step when ``adaptive=True`` is
        given). A pair ``(min, max)``, as fonsim writes it, asks for adaptive
        steps within those bounds (either may be None for the default); it
        replaces ``step_min`` and ``step_max``.
    adaptive : bool, optional
        Force adaptive (True) or fixed (False) stepping.
    method : {'bdf', 'euler'}, default 'bdf'
        Adaptive integrator (:mod:`softflow.solve.bdf`): 'bdf' varies order
        (1 to ``max_order``) and step; 'euler' is its order 1, adaptive
        backward Euler. Fixed steps are always backward Euler.
    max_order : int, default 5
        Highest BDF order (1-5) of ``method='bdf'``.
    step_min, step_max : float [s], optional
        Bounds of the adaptive step; defaults duration·1e-9 and duration
        (the error test alone sets the step, so a smooth scene at loose rtol
        takes few; the result records the steps and the points ``refine``
        adds inside them, or the ``times`` asked for; a step_max is not
        needed for output between the steps).
    rtol : float, default 1e-3
        Relative tolerance of the adaptive error test: the local error of each
        state and node pressure (and temperature) per step, in the weighted
        RMS norm with weights ``atol + rtol·|state|`` (pressures: rtol times
        the largest gauge pressure of the network); flows follow from those
        through their components' equations and are not tested themselves
        (:mod:`softflow.solve.bdf`).
    atol : dict, optional
        Absolute tolerances per quantity name, SI. Those not given are
        DEFAULT_ATOL (set for rtol = 1e-3) times rtol/1e-3, so that the error
        follows rtol down to tight tolerances.
    newton_rtol : float, optional
        Relative tolerance of the Newton iteration, with respect to the typical
        magnitude of each quantity in the network (absolute floors atol·1e-3).
        Default: 1e-6 with fixed steps; rtol/20 in adaptive runs, a twentieth
        of the error test's tolerance, where pressures count by their gauge
        magnitude as in the error test, and the tolerances are at least 1e-6
        of the largest magnitude of the run so far, or a fifth of rtol/20 of
        it where that is smaller (a settled network's vanishing flows are not
        asked for more than round-off resolves); a first Newton update is
        accepted on the contraction of earlier solves only up to rtol of the
        scale. Given in an adaptive run, it is used where smaller than
        rtol/20.
    linear_solver : {'auto', 'dense', 'sparse', 'condensed'}
        'auto' uses dense LU up to 128 unknowns; above, 'condensed' (the
        components' own unknowns eliminated, SuperLU on the node system; see
        :mod:`softflow.solve.condense`) where any component can be condensed,
        else 'sparse' (SuperLU on the whole Jacobian).
    breakpoints : sequence of float [s] or Quantity
        Extra times the integrator must land on (input discontinuities);
        components' waveforms declare theirs themselves. Each must lie in
        [0, duration] (to within :data:`ROUND_OFF` of the duration): a negative
        time, one after the end or nan is refused with a ValueError that names
        them. 0 and ``duration`` themselves are accepted and change nothing
        (every run starts and ends there anyway).
    refine : int or 'auto', default 'auto'
        Points the result records per adaptive step: ``refine - 1`` more,
        evenly inside each step, from the BDF's own interpolating polynomial
        (its difference table; as MATLAB's ``Refine`` and scipy's dense
        output). BDF's steps are long where the solution is smooth, and a
        result read linearly between them carries the linear interpolation's
        error on top of the method's (the RC circuit at the default rtol: 20
        steps, 0.058 % at the points, 0.30 % read linearly; 0.059 % with
        ``refine=4``). ``'auto'`` chooses per step as many (1 to
        :data:`softflow.solve.dense.AUTO_REFINE_MAX`) as keep the straight
        lines between the points within the run's tolerance of the step's
        polynomial (atol + rtol times each state's, and each unknown's
        quantity's, largest magnitude in the run;
        :func:`softflow.solve.dense.refine_counts`): the same RC circuit 30
        points, 0.11 % read linearly; at rtol 1e-6, 46 steps and 573 points,
        4.0e-6 read linearly (the steps alone: 1.0e-3). Steps of order 1 get
        none (their polynomial is a line). 1 records the steps alone.
        Discrete states keep their values at each step's start inside it.
        An integer above 1 is refused with fixed steps (backward Euler's own
        interpolant is the straight line between its steps) and with
        sensitivities (computed at the steps; 'auto' records the steps alone
        there); a batched sweep with one runs its variants on one shared step
        sequence ('auto' keeps their own clocks, which record the steps
        alone, each variant with its own interpolant). Values at any time,
        from the same polynomials: ``times=``, :meth:`Result.at`,
        :meth:`Result.interpolate`.
    times : array_like [s] or Quantity, optional
        Times at which the result is recorded, instead of the steps: 1-D,
        finite, sorted (non-decreasing), within [0, duration] (errors name the
        parameter and the offending value). The result holds exactly these
        times (as ``scipy.integrate.solve_ivp``'s ``t_eval``), each value
        from the integrator's own interpolant over the step that covers it
        (:mod:`softflow.solve.dense`: BDF's polynomial of the step's order;
        backward Euler's straight line between its steps), as accurate as the
        steps themselves; a time on a step's end is that step's point (at a
        breakpoint, the inputs' left limit). The steps are unchanged by it,
        and the model's validity checks still judge every step
        (``result.warnings`` are the same). A run that fails holds the
        requested times it reached. Not with sensitivities (computed at the
        steps); ``refine`` does not apply. :meth:`Result.at` and
        :meth:`Result.interpolate` read the run at any other time.
    t_eval : array_like [s] or Quantity, optional
        Another name for ``times`` (scipy's); give one or the other.
    allow_unconnected : bool, default False
        Treat unconnected terminals as closed ends instead of raising.
    thermal : {'isothermal', 'adiabatic', 'heat_transfer'}, default 'isothermal'
        Thermal model of the scene (volumes may override it with their own
        ``thermal=``): 'isothermal' is the FONS paper's model, with no
        temperature unknowns; the others add a temperature and an energy flow at
        every fluid terminal and the energy equation in every volume (gases
        only). See :mod:`softflow.solve.thermal` and
        :mod:`softflow.components.thermal`.
    record : sequence of str, optional
        Labels of the components whose variables are kept at every step;
        default all. For networks of 1e5 components, keeping everything costs
        about as much as solving (memory bandwidth). The interpolant between
        the steps (:meth:`Result.at`) keeps the same columns: k rows of its
        difference table a step, at order k.
    beyond_limits : {'error', 'warn'}, default 'error'
        What a run does where a model passes its own maximum (a gas tube
        choking, :mod:`softflow.solve.model_checks`): 'error' stops it there
        (SimulationError; the result up to that point has status 'failed';
        a model past its maximum at t = 0 stops the run right after its
        consistent start, without computing the rest), 'warn' returns the
        whole run with a ModelWarning. Validity findings
        short of that are always warnings (``result.warnings``).
    max_steps : int, default 10**7
        Most steps a run may take, accepted and rejected (as ``result.stats``
        counts them, ``steps + rejected_steps``; the solves of the consistent
        start, of the adaptive method's restarts at t = 0 and at breakpoints
        and of continuation are not steps). A fixed ``step``
        (or a ``step_max``) that needs more over ``duration`` is refused at
        construction with the estimate; pass a larger ``max_steps`` to confirm.
    model : {None, 'auto'}, default None
        'auto' lets softflow choose the thermal model, the fluid level, the
        friction and tube laws and rtol: :func:`softflow.assess` runs the scene
        in its cheapest configuration and one level up where its validity
        checks say so, and the Simulation compiles the recommended System (a
        new one; ``system`` is not changed). The Assessment is
        ``sim.assessment``. ``thermal``, ``rtol`` and ``step`` given with it
        conflict and raise.
    tolerance : float [-], default 0.01 with model='auto'
        Accepted error of each output (the volumes' pressures) as a fraction
        of its range, for model='auto'.
    """

    #: whether the compile checks that the network's equations are not
    #: structurally singular (Assembly.check_nonsingular); the batched
    #: engine's network of copies of a scene compiled and checked already
    #: skips it (softflow.solve.batched: each copy is a run(params=) of that
    #: scene, which does not check again)
    _check_regular = True

    #: the rtol the validity checks judge a run's limits at (None: the run's
    #: own; sf.assess sets its rtol0 on the runs it makes at 10 rtol0)
    _checks_rtol: float | None = None

    def __init__(self, system: System, duration: Scalar = 1.0, step: Scalar | None = None, *,
                 adaptive: bool | None = None, method: str = "bdf", max_order: int = MAX_ORDER,
                 step_min: Scalar | None = None, step_max: Scalar | None = None,
                 rtol: float = 1e-3, atol: Mapping[str, float] | None = None,
                 newton_rtol: float | None = None, linear_solver: str = "auto",
                 breakpoints: Iterable[Scalar] = (), allow_unconnected: bool = False,
                 record: str | Iterable[str] | None = None, thermal: str = "isothermal",
                 max_steps: int = MAX_STEPS, beyond_limits: str = "error",
                 model: str | None = None, tolerance: float | None = None,
                 refine: int | str = "auto", times: Any = None, t_eval: Any = None) -> None:
        if model is not None or tolerance is not None:    # let softflow choose: softflow.assess
            system, thermal, rtol, model, tolerance, self.assessment = resolve_auto(
                {k: v for k, v in locals().items() if k not in ("times", "t_eval")})
        # what the Simulation is made of, for pickling: its compiled model holds
        # generated code, which is rebuilt from these on load
        self._definition = {k: v for k, v in locals().items() if k not in ("self", "__class__")}
        owner = "Simulation"
        self.system = system
        self.duration = to_si(duration, "s", name="duration", owner=owner)
        if not (self.duration > 0 and math.isfinite(self.duration)):
            raise ValueError(f"Simulation: duration must be > 0 s and finite, "
                             f"got {self.duration}")
        if isinstance(step, (tuple, list)):
            step_min, step_max = _step_range(step, step_min, step_max)
            step = None
        self.step = None if step is None else to_si(step, "s", name="step", owner=owner)
        if self.step is not None and not (self.step > 0 and math.isfinite(self.step)):
            raise ValueError(f"Simulation: step must be > 0 s and finite, got {self.step}")
        self.adaptive = (self.step is None) if adaptive is None else bool(adaptive)
        if not self.adaptive and self.step is None:
            raise ValueError("Simulation: adaptive=False needs a step")
        if not self.adaptive and self.step > self.duration * (1.0 + ROUND_OFF):
            step_s, duration_s = f"{self.step:.6g}", f"{self.duration:.6g}"
            if step_s == duration_s:         # just above: show the digits that differ
                step_s, duration_s = repr(self.step), repr(self.duration)
            raise ValueError(f"Simulation: step={step_s} s is longer than "
                             f"duration={duration_s} s; expected a fixed step of at "
                             "most the duration (step=duration takes one step), or no step "
                             "for adaptive steps")
        self.step_min = (self.duration * 1e-9 if step_min is None
                         else to_si(step_min, "s", name="step_min", owner=owner))
        if method not in METHODS:
            raise ValueError(f"Simulation: unknown method {method!r}; expected one of "
                             f"{', '.join(repr(m) for m in METHODS)}")
        self.method = method
        if (isinstance(max_order, bool) or not isinstance(max_order, (int, np.integer))
                or not 1 <= max_order <= MAX_ORDER):
            raise ValueError(f"Simulation: max_order must be an integer from 1 to {MAX_ORDER}, "
                             f"got {max_order!r}")
        if method == "euler" and max_order not in (1, MAX_ORDER):
            raise ValueError(f"Simulation: method='euler' is BDF of order 1; max_order="
                             f"{max_order} asks for more (use method='bdf', max_order="
                             f"{max_order})")
        self.max_order = 1 if method == "euler" else int(max_order)
        self.step_max = (self.duration if step_max is None
                         else to_si(step_max, "s", name="step_max", owner=owner))
        if not 0 < self.step_min <= self.step_max:
            raise ValueError(f"Simulation: need 0 < step_min <= step_max, got {self.step_min}, "
                             f"{self.step_max}")
        if beyond_limits not in ("error", "warn"):
            raise ValueError(f"Simulation: beyond_limits must be 'error' or 'warn', got "
                             f"{beyond_limits!r}")
        self.beyond_limits = beyond_limits
        self.max_steps = _check_max_steps(max_steps, self.duration, self.step, self.step_max,
                                          self.adaptive)
        self.rtol = to_si(rtol, "", name="rtol", owner=owner)
        self.newton_rtol = (None if newton_rtol is None
                            else to_si(newton_rtol, "", name="newton_rtol", owner=owner))
        for name, v in (("rtol", self.rtol), ("newton_rtol", self.newton_rtol)):
            if v is None:
                continue
            if not (v > 0 and math.isfinite(v)):
                raise ValueError(f"Simulation: {name} must be a finite number > 0, got {v}")
        self.atol = default_atol(self.rtol)
        # every variable's quantity, looked up only where an atol names one
        known = _quantities(system) if atol else ()
        for q, v in (atol or {}).items():
            if q not in known:
                raise KeyError(f"Simulation: atol names unknown quantity {q!r}; the quantities "
                               f"are {', '.join(map(repr, sorted(known)))}")
            unit = quantity_unit(q)
            self.atol[q] = to_si(v, unit, name=f"atol[{q!r}]", owner=owner) if unit else float(v)
            if not (self.atol[q] > 0 and math.isfinite(self.atol[q])):
                raise ValueError(f"Simulation: atol[{q!r}] must be a finite number > 0, "
                                 f"got {self.atol[q]}")
        self.breakpoints = _check_breakpoints(breakpoints, self.duration, owner)
        #: refine='auto': the points per step chosen per step (then ``refine`` is 1)
        self.refine_auto = isinstance(refine, str) and refine == "auto"
        if self.refine_auto:
            refine = 1
        elif (isinstance(refine, bool) or not isinstance(refine, (int, np.integer))
                or not 1 <= refine <= MAX_REFINE):
            raise ValueError(f"Simulation: refine must be an integer from 1 to {MAX_REFINE} "
                             f"(points recorded per step) or 'auto', got {refine!r}")
        if refine > 1 and not self.adaptive:
            raise ValueError(f"Simulation: refine={refine} records points inside the adaptive "
                             "BDF's steps from its interpolating polynomial; fixed steps "
                             "(step=) record every step already: pass a smaller step instead")
        #: the points per adaptive step that ``refine=`` fixes (1 under 'auto')
        self.refine = int(refine)
        if times is not None and t_eval is not None:
            raise TypeError("Simulation: times= and t_eval= name the same thing (the times "
                            "the result is recorded at); give one of them, not both")
        name = "t_eval" if t_eval is not None else "times"
        given = t_eval if t_eval is not None else times
        #: the times the result is recorded at (``times=`` / ``t_eval=``), or None
        self.times_requested = (None if given is None else check_times(
            given, self.duration, owner=owner, name=name, round_off=ROUND_OFF))
        self._times_name = name
        # a pure compile: the System is only read. A thermal scene adds variables
        # and per-scene data to its components, so it is compiled from a copy
        # (fluids and curves are shared, being values); an isothermal one
        # needs nothing of the kind and is compiled from the System itself
        with _collector_paused():
            model = (system if check_model(thermal) == "isothermal"  # type: ignore[assignment]
                     else copy.deepcopy(system))
            self._model = model
            self.thermal = configure_thermal(model, thermal)
            self.asm = Assembly(model, allow_unconnected=allow_unconnected)
            # the compiled components, and the run-time parameters now in force
            self._compiled: dict[str, Any] = {}
            for g in self.asm.groups:
                self._compiled.update(zip([c.label for c in g.comps], g.comps))
            self._applied: dict[str, Any] = {}
            if self._check_regular:
                self.asm.check_nonsingular(self.step if self.step is not None
                                           else self.step_max)
                self.asm.check_nonsingular(0.0)  # the consistent-initial-value solve at t = 0
        self.linear_solver_kind = linear_solver
        self.record = None if record is None else self._record_indices(record)
        self.result: Result | None = None
        # the consistent point at t = 0 of the last run and what it was solved for
        # (see _start_key), tried first by the next run (Integrator.initial)
        self._start: tuple | None = None

    def __getstate__(self) -> dict[str, Any]:
        return {"definition": self._definition, "result": self.result}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(**state["definition"])  # type: ignore[misc]
        self.result = state["result"]

    def _record_indices(self, labels):
        if isinstance(labels, str):
            labels = [labels]
        xs, ss = [], []
        for label in labels:
            if label not in self.asm.where:
                have = sorted(self.asm.where)
                raise KeyError(f"Simulation: record names unknown component {label!r}; the "
                               f"components are {', '.join(map(repr, have[:20]))}"
                               + (", ..." if len(have) > 20 else ""))
            g, i = self.asm.where[label]
            xs.extend(g.col[i].tolist())
            ss.extend(range(g.s0 + i * g.ns, g.s0 + (i + 1) * g.ns))
        return (np.unique(np.array(xs, dtype=np.int64)), np.array(ss, dtype=np.int64),
                list(labels))

    def _can_refuse(self):
        """validity.can_refuse of the network, found once per set of registered
        checks (run-time parameters replace components by ones of their class)."""
        version = checks_version()
        known = getattr(self, "_refusable", None)
        if known is None or known[0] != version:
            known = self._refusable = (version, can_refuse(self.asm))
        return known[1]

    def _start_key(self, newton):
        """What the consistent point at t = 0 is solved for: the components in force
        (as objects: run-time parameters replace them), the initial unknowns and
        states, Newton's tolerances and linear solver; and what the check at the
        start reads of it (the registered checks, the recorded components). A run
        whose key is the last run's may start from that run's point, which Newton
        still confirms (Integrator.initial): user code may read what no key can
        see."""
        asm = self.asm
        return ((asm.x0.tobytes(), asm.S0.tobytes(), newton.rtol, newton.atol.tobytes(),
                 tuple(newton._links), newton._T_range, newton.lin.kind,
                 # what the check at the start (_fatal_at_start) reads besides
                 checks_version(), None if self.record is None else tuple(self.record[2])),
                tuple(c for g in asm.groups for c in g.comps))

    def _newton_rtol(self) -> float:
        """The Newton iteration's relative tolerance for a run: fixed steps
        ``newton_rtol`` (default :data:`NEWTON_RTOL`); adaptive runs rtol / 20
        (:data:`NEWTON_FRACTION`), or ``newton_rtol`` where given smaller."""
        given = self.newton_rtol
        if not self.adaptive:
            return NEWTON_RTOL if given is None else given
        rtol = self.rtol * NEWTON_FRACTION
        return rtol if given is None else min(given, rtol)

    def _atol_vector(self, quantities, factor=1.0):
        return np.array([self.atol.get(q, 1e-9) * factor for q in quantities], dtype=float)

    @property
    def times(self) -> Array:
        """Times of the last run [s] (the paper's ``sim.times``)."""
        if self.result is None:
            raise RuntimeError("Simulation.times: call run() first")
        return self.result.times

    @property
    def stats(self) -> dict[str, Any]:
        return self.result.stats if self.result is not None else {}

    def check_params(self, *params):
        """Check sets of run-time parameters (each as ``run(params=...)`` would take
        it: keys, units, ranges, structure) without running; the compiled values
        stay in force. Raises the error a run would, with ``variant_index`` set to
        the position of the set that failed."""
        try:
            for i, p in enumerate(params):
                try:
                    self._set_parameters(p)
                except Exception as err:
                    err.variant_index = i
                    raise
        finally:
            self._set_parameters(None)

    def probe(self):
        """A one-point Result at the initial values, recorded as the runs are:
        its columns, units and variable index (``get`` names, outputs) without
        running."""
        asm, record = self.asm, self.record
        x0 = asm.x0 if record is None else asm.x0[record[0]]
        s0 = asm.S0 if record is None else asm.S0[record[1]]
        return Result(asm, np.zeros(1), x0[None, :], s0[None, :], recorded=record)

    def without_result(self):
        """A shallow copy that pickles without the last run's Result (what a
        Simulation sent to workers needs: its definition)."""
        import copy as _copy
        twin = _copy.copy(self)
        twin.result = None
        return twin

    def _set_parameters(self, params):
        """Put the run-time parameters ``params`` in force (the compiled values
        for every other component; see :mod:`softflow.solve.params`)."""
        wanted = split_params(params or {}, self.asm.where)
        new = {label: configure_like(rebuild(self._compiled[label], changes),
                                     self._compiled[label], self.thermal)
               for label, changes in wanted.items()}
        for label in self._applied:
            new.setdefault(label, self._compiled[label])
        if not new:
            return
        try:
            self.asm.replace(new)
        except Exception:
            self.asm.replace({label: self._compiled[label] for label in new})
            self._applied = {}
            raise
        self._applied = wanted

    def run(self, *, raise_on_failure: bool = True, progress: bool | None = None,
            params: Mapping[str, Any] | None = None,
            sensitivities: Iterable[str] | None = None) -> Result:
        """Integrate from 0 to ``duration``.

        Returns the Result. If the solver fails, raises SimulationError (whose
        ``result`` holds the steps computed so far), or with
        ``raise_on_failure=False`` returns that partial Result with
        ``status == 'failed'`` and a ``message``.

        ``params``: run-time parameters for this run, ``{"label.argument":
        value}`` with the argument named as in the component's constructor
        (``{"tube.diameter": sf.Q_(1.5, "mm"), "act.curve": other_curve}``;
        Quantities or SI), checked as the constructor checks them. Other runs
        use the values the Simulation was built with; nothing is recompiled,
        and the System is not changed. Library components (thermal scenes
        included).
        ``progress``: a bar in
        simulated time for a run longer than ~2 s of wall time, shown where
        standard error is a terminal (None), always (True) or never (False);
        solver events go to the logger 'softflow' (:mod:`softflow.solve.progress`).

        Before it integrates, the run judges its inputs (with the run-time
        parameters in force) and warns at once (ModelWarning): an actuator
        whose initial volume lies outside its PV curve's data (check
        ``'initial_volume_range'``), a circular tube whose flow is negligible
        over the duration (``'tube_negligible_flow'``,
        :func:`softflow.solve.input_checks.negligible_tubes`). These records come first in
        ``result.warnings``, before the findings on the solution.

        ``sensitivities``: parameters (``"label.argument"``, numeric, as in
        ``params``) to differentiate the run with respect to, alongside it
        (:mod:`softflow.solve.sensitivity`); read them with
        :meth:`Result.sensitivity`.
        """
        self._set_parameters(params)
        asm = self.asm
        network = getattr(asm.residual, "network", None)
        if network is not None:
            # user components compiled for values since changed
            # (softflow.solve.usercompile): their kernels for the values now
            network.check_user_values()
        # what the inputs alone show (an actuator starting beyond its curve's data,
        # a tube too thin to matter): warned now, before the run's time, and kept
        # in result.warnings with the findings on the solution
        found = self._input_records()
        issue(found)
        integ, newton, lin, stats, culprit = self._integrator(bool(sensitivities))
        sens: Sensitivities | None = None
        integ.progress = Progress(self.duration, progress, asm.s_names)  # type: ignore[assignment]
        if sensitivities:
            if self.times_requested is not None:
                raise ValueError(f"Simulation.run: sensitivities are computed at the steps; "
                                 f"this Simulation records its result at {self._times_name}="
                                 "...: build it without them for sensitivities (and read "
                                 "other times with result.at)")
            if self.refine > 1:
                raise ValueError(f"Simulation.run: sensitivities are computed at the steps; "
                                 f"this Simulation records refine={self.refine} points a "
                                 "step: build it with refine=1 for sensitivities")
            from .sensitivity import Sensitivities
            names = [sensitivities] if isinstance(sensitivities, str) else list(sensitivities)
            sens = Sensitivities(asm, newton, names,
                                 {label: g.comps[i] for label, (g, i) in asm.where.items()},
                                 thermal=self.thermal)
            integ.sens = sens  # type: ignore[assignment]
        start_key = self._start_key(newton)
        if self._start is not None and _same_start(self._start[0], start_key):
            integ.start = self._start[1]
        if self.beyond_limits == "error" and self._can_refuse():
            integ.stop_at_start = lambda: self._fatal_at_start(integ.rec)  # type: ignore[assignment]
        error = None
        try:
            with np.errstate(all="ignore"), integ.progress, _huge_pages_off():
                integ.run()
        except StoppedAtStart:
            pass      # the checks below refuse the run from t = 0, with their message
        except StepFailure as fail:
            error = self._describe_failure(fail, newton, culprit.explain(fail),
                                           integ.rec.t[-1] if integ.rec.t else None)
        except Exception as err:  # user code or inputs failing mid-run: keep what we have
            t = integ.rec.t[-1] if integ.rec.t else 0.0
            if isinstance(err, ComponentError):    # user code: its component, method, time
                error = SimulationError(str(err), time=t if err.time is None else err.time,
                                        component=err.component)
                error.method = err.method  # type: ignore[attr-defined]
            elif isinstance(err, FluidError) and getattr(err, "component", None):
                # a state update met a fluid's range: softflow's own error, named
                error = SimulationError(f"after t = {t:.6g} s: {err}", time=t,
                                        component=getattr(err, "component", None))
            else:
                error = SimulationError(f"after t = {t:.6g} s: {type(err).__name__}: {err}",
                                        time=t)
            if isinstance(err, FluidError) and getattr(err, "component", None):
                error.__cause__ = None      # the message says it all, named
            else:
                error.__cause__ = err.__cause__ if isinstance(err, ComponentError) else err
        self._start = None if integ.consistent is None else (start_key, integ.consistent)
        with _huge_pages_off():
            t, X, S = integ.rec.arrays()
            integrals = integ.rec.integrals()
            dense = None
            if not len(t):     # failed at t = 0: the initial values as a 1-point result
                xs, ss = ((slice(None), slice(None)) if self.record is None
                          else self.record[:2])
                t, X, S = np.zeros(1), asm.x0[xs][None, :], asm.S0[ss][None, :]
                integrals = None if integrals is None else np.zeros_like(X)
                dense = DenseOutput.linear_between(t, X, S, None)
            else:
                # the points inside the steps (refine) and the interpolant
                # between them (softflow.solve.dense)
                t, X, S, integrals, dense = integ.finish(t, X, S, integrals)
        info = stats.as_dict()
        info["forced_steps"] = integ.forced_steps
        info["linear_solver"] = lin.kind
        info["method"] = self.method if self.adaptive else "euler"
        info["rtol"] = self.rtol
        # accepted steps per order (index 0 unused); fixed steps are all order 1
        info["order_steps"] = (list(integ.order_counts) if self.adaptive  # type: ignore[union-attr]
                               else [0, stats.steps])
        info["unknowns"] = asm.n
        result = Result(asm, t, X, S, status="success" if error is None else "failed",
                        message="" if error is None else str(error), stats=info,
                        recorded=self.record, integrals=integrals, dense=dense)
        if sens is not None:
            xs, ss = ((slice(None), slice(None)) if self.record is None else self.record[:2])
            result._set_sensitivities(sens, xs, ss, len(t))
        records = _with_inputs(found, check_result(asm, result, rtol=self._checks_rtol))
        result.validity, result.warnings = records, beyond(records)
        fatal = [w for w in result.warnings if w.details.get("fatal")]
        if fatal and error is None and self.beyond_limits == "error":
            # past a model's own maximum (a choked tube): no result from there on
            first = min(fatal, key=lambda w: w.details["first_time"])
            cut = max(1, int(np.searchsorted(t, first.details["first_time"])))
            error = SimulationError(f"stopped at t = {first.details['first_time']:.6g} s: "
                                    f"{first.message}", time=first.details["first_time"],
                                    component=first.component)
            result = Result(asm, t[:cut], X[:cut], S[:cut], status="failed",
                            message=str(error), stats=info, recorded=self.record,
                            integrals=None if integrals is None else integrals[:cut],
                            dense=None if dense is None else dense.until(t[cut - 1]))
            result.validity, result.warnings = records, beyond(records)
            if sens is not None:
                result._set_sensitivities(sens, xs, ss, cut)
        if self.times_requested is not None:
            # the result at the times asked for, from the interpolant; the
            # checks above judged every step
            result = result._at_times(self.times_requested)
            result._dense = result._dense.compact()     # the steps' own points alone
        warned = {id(r) for r in found}          # at the start
        issue([w for w in result.warnings if id(w) not in warned])
        self.result = result
        remember_result(self.system.components, result)
        if error is not None:
            error.result = result
            if raise_on_failure:
                raise error
        return result

    def _integrator(self, sensitivities: bool = False,
                    record: Any = _RUN_RECORD) -> tuple[Any, Any, Any, Any, Any]:
        """The stepper of a run with the parameters in force, not yet run:
        (integ, newton, lin, stats, culprit), the stepper (BDF or backward
        Euler) with its Newton, linear solver, counters and culprit finder
        as :meth:`run` makes them (the batched engine's variants on the
        compiled loop, :mod:`softflow.solve.variants`, make one to read
        their settings from). ``sensitivities``: whether the run computes
        any. ``record``: the run's (Simulation(record=)) unless given, None
        for every unknown and state."""
        asm = self.asm
        record = self.record if record is _RUN_RECORD else record
        for g in asm.groups:
            # sources' values kept from the last run's times: a Python signal
            # may read state that changed since (its values are asked anew)
            forget = getattr(g.params, "forget", None)
            if forget is not None:
                forget()
        components = [g.comps[i] for g, i in asm.where.values()]
        stats = Stats()
        lin = make_linear_solver(asm, self.linear_solver_kind)
        newton = Newton(asm, lin, stats, rtol=self._newton_rtol(),
                        atol=self._atol_vector(asm.x_quantity, 1e-3))
        gas = None if self.thermal == "isothermal" else next(
            (c.fluid for c in components
             if getattr(c, "fluid", None) is not None and c.fluid.compressible), None)
        if gas is not None:
            T = gas.temperature
            newton.set_magnitude_link("energyflow", "massflow",
                                      float(gas.cp(pressure_atmospheric, T)) * T)
            ranges = [getattr(c.fluid, "T_range", (0.0, math.inf)) for c in components
                      if getattr(c, "fluid", None) is not None and c.fluid.compressible]
            newton.set_temperature_range(max(r[0] for r in ranges), min(r[1] for r in ranges))
        breaks = list(self.breakpoints)
        for c in components:
            breaks.extend(float(b) for b in breakpoints_within(c, self.duration))
        integ: BDF | ImplicitEuler
        if self.adaptive:
            integ = BDF(asm, newton, stats, duration=self.duration, rtol=self.rtol,
                        atol_states=self._atol_vector(asm.s_quantity),
                        atol_unknowns=self._atol_vector(asm.x_quantity), step_min=self.step_min,
                        step_max=self.step_max, max_order=self.max_order,
                        first_step=self.step, breakpoints=breaks, record=record,
                        refine=None if self.refine_auto and not sensitivities else self.refine)
        else:
            integ = ImplicitEuler(asm, newton, stats, duration=self.duration, step=self.step,
                                  step_min=self.step_min, breakpoints=breaks, record=record)
        integ.max_steps = self.max_steps
        culprit = Finder(asm, newton, integ)
        integ.culprit = culprit  # type: ignore[assignment]
        newton.before_continuation = culprit.before_continuation  # type: ignore[assignment]
        newton.before_full = culprit.before_full  # type: ignore[assignment]
        return integ, newton, lin, stats, culprit

    def _input_records(self):
        """ValidityRecords of the inputs in force, found before the run: actuators
        whose initial volume is outside their curve's data
        (:func:`softflow.components.actuators.initial_volume_records`) and tubes
        whose flow is negligible (:func:`~softflow.solve.input_checks.negligible_tubes`). Found again only
        where run-time parameters replaced components."""
        asm = self.asm
        rtol = self._checks_rtol if self._checks_rtol is not None else self.rtol
        # the components in force where parameters replaced them (held, so compared
        # as objects)
        key = (rtol, tuple(asm.where[label][0].comps[asm.where[label][1]]
                           for label in sorted(self._applied)))
        known = getattr(self, "_inputs_found", None)
        if (known is not None and known[0][0] == key[0] and len(known[0][1]) == len(key[1])
                and all(map(operator.is_, known[0][1], key[1]))):
            return list(known[1])
        out = initial_volumes(asm)
        out.extend(negligible_tubes(asm, self.duration, rtol))
        self._inputs_found = (key, tuple(out))
        return out

    def _fatal_at_start(self, rec):
        """Whether the checks that can refuse a run (a choked tube) refuse it at the
        consistent point at t = 0: then the run stops there instead of computing
        to the end and being cut back to t = 0 (the check is that of the whole
        run, on its first point)."""
        t, X, S = rec.arrays()
        point = Result(self.asm, t, X, S, recorded=self.record)
        return any(r.details.get("fatal") and r.status == "beyond"
                   for r in check_result(self.asm, point, fatal_only=True))

    def _describe_failure(self, fail, newton, found=None, t_last=None):
        """The SimulationError of a failed step; ``found``: its culprit
        (:class:`softflow.solve.culprit.Finding`), named first where there is
        one; ``t_last``: the last point computed, where the result ends (said
        where it is not the failed step's start: the step ends at fail.t)."""
        out = fail.outcome
        comp = eq = None
        where = ""
        if out.row is not None:
            comp, eq = self.asm.component_of_row(out.row)
            where = f"; worst equation: {self.asm.describe_row(out.row)}"
        if comp is None:       # a fluid's range left by one component's state
            comp = getattr(newton.fluid_error, "component", None)
        edge = _temperature_edge(out, newton)
        if edge:
            where += edge
        unknowns = None
        if comp is None and getattr(out, "unknown", None) is not None:
            unknowns = [out.unknown]           # a node's unknown (its pressure)
        elif comp is None and out.row is not None and out.row < self.asm.n_node_rows:
            # a node's conservation equation: the flows that meet there
            unknowns = self.asm.through_cols[self.asm.through_rows == out.row].tolist()
        if unknowns:
            labels = [c.label for g in self.asm.groups for i, c in enumerate(g.comps)
                      if np.isin(g.col[i], unknowns).any()]
            if labels:
                comp = labels[0]
                where += f"; components at that node: {', '.join(map(repr, labels))}"
        step = f"step {fail.dt:.3g} s"
        if t_last is not None and fail.t > 0.0:
            # the result ends at the last point computed, the failed step's start
            step = (f"the step of {fail.dt:.3g} s from t = {t_last:.6g} s, where the result "
                    "ends")
        msg = f"solver failed at t = {fail.t:.6g} s ({step}): {out.reason}{where}"
        if found is not None:
            msg = (f"solver failed at t = {fail.t:.6g} s ({step}): "
                   f"{found.message} (the step's solve: {out.reason}{where})")
            comp, eq = found.component, None
        return SimulationError(msg, time=fail.t, component=comp, equation=eq)


def _same_start(a, b):
    """Whether two :meth:`Simulation._start_key` s are the same: equal values,
    the very same component objects."""
    return (a[0] == b[0] and len(a[1]) == len(b[1])
            and all(map(operator.is_, a[1], b[1])))


def _temperature_edge(out, newton):
    """'; ...' naming the node temperatures of the failed iterate that sit at the
    edge of the fluids' temperature range (Newton keeps its iterates inside:
    the solution may lie beyond it), or ''."""
    rng, i, x = newton._T_range, newton._T_idx, getattr(out, "x", None)
    if rng is None or x is None or not i.size:
        return ""
    T = x[i]
    lo, hi = rng
    at = np.flatnonzero((np.abs(T - lo) <= 1e-9 * lo) | (np.abs(T - hi) <= 1e-9 * hi))
    if not at.size:
        return ""
    names = ", ".join(newton.asm.x_names[int(i[k])] for k in at[:3])
    return (f"; {names} at the edge of the temperature range the scene's fluids cover "
            f"({lo:.6g} ... {hi:.6g} K): the solution may lie beyond it (the 'eos' "
            "level covers a wider range)")


def _madvise_switch():
    """NumPy's switch of ``madvise(MADV_HUGEPAGE)`` on its large arrays
    (``_set_madvise_hugepage``: ``numpy._core`` from NumPy 2, ``numpy.core``
    before; documented with ``NUMPY_MADVISE_HUGEPAGE``), or None where this
    NumPy has none."""
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        switch = getattr(module, "_set_madvise_hugepage", None)
        if switch is not None:
            return switch
    return None


_MADVISE = _madvise_switch()


class _huge_pages_off:
    """NumPy's transparent huge pages off while a run integrates and builds
    its result, unless :data:`settings.HUGE_PAGES <softflow.solve.settings.HUGE_PAGES>`
    allows them: the switch is process-wide, so it is restored as it was
    when the last of the runs that hold it (threads) leaves, also on errors.
    Only where the memory comes from changes, never a number."""

    __slots__ = ("held",)
    _lock = threading.Lock()
    _holders = 0
    _saved = True

    def __enter__(self):
        self.held = _MADVISE is not None and not settings.HUGE_PAGES
        if self.held:
            cls = _huge_pages_off
            with cls._lock:
                if cls._holders == 0:
                    cls._saved = _MADVISE(False)
                cls._holders += 1
        return None

    def __exit__(self, *exc):
        if self.held:
            cls = _huge_pages_off
            with cls._lock:
                cls._holders -= 1
                if cls._holders == 0:
                    _MADVISE(cls._saved)
        return False


class _collector_paused:
    """Python's cyclic garbage collector off while a network compiles: compiling
    allocates ~10 objects per component and frees none of them, so the
    collector's passes over the growing heap find nothing to free (they were
    ~40 % of compiling a 20 000-component chain). Restored as it was, also on
    errors; the objects are collected later as usual. (A class: a generator's
    context manager costs ~2 us more a Simulation.)"""

    __slots__ = ("enabled",)

    def __enter__(self):
        self.enabled = gc.isenabled()
        gc.disable()
        return None

    def __exit__(self, *exc):
        if self.enabled:
            gc.enable()
        return False


def default_atol(rtol):
    """{quantity: absolute tolerance} a Simulation at ``rtol`` takes where atol=
    names none: DEFAULT_ATOL, set for rtol = 1e-3, times rtol/1e-3 (tolerance
    proportionality: rtol = 1e-8 with 1 Pa floors would stop at 1 Pa)."""
    return {q: v * rtol / 1e-3 for q, v in DEFAULT_ATOL.items()}


def _quantities(system):
    """Quantity names an atol may set: the defaults and every variable's and state's."""
    out = set(DEFAULT_ATOL)
    for c in system.components:
        out.update(v.quantity for _, v in c.interface_variables())
        out.update(sv.quantity for sv in c.states)
    return out


def _with_inputs(found, records):
    """The records of the inputs (``found``) first, then those of the solution,
    without a PV-curve record that only repeats an initial volume's: reached on
    the same side, within validity.PV_CURVE_SLACK of the data's range of the
    initial volume (the run went no further out than where it started), and
    without those on the flow of a tube whose flow is negligible: the result
    is that of a closed tube, and its flow, below what the solver resolves,
    says nothing (a 1 nm x 1 nm tube from 100 bar into a tank was said to
    choke as isothermal pipe flow at a flow of the wrong sign, -5.5e-13
    kg/s, the solver's noise)."""
    if not found:
        return records
    start = {r.component: r for r in found if r.check == "initial_volume_range"}
    closed = {r.component for r in found if r.check == "tube_negligible_flow"}

    def repeats(r):
        if r.component in closed:
            return True
        s = start.get(r.component)
        if (s is None or r.check != "pv_curve_range"
                or r.details.get("side") != s.details["side"]):
            return False
        lo, hi = s.details["data_range"]
        return abs(r.measured - s.measured) <= PV_CURVE_SLACK * (hi - lo)
    return list(found) + [r for r in records if not repeats(r)]


def _check_breakpoints(breakpoints, duration, owner):
    """``breakpoints`` as a tuple of floats [s], each checked to lie in [0, duration]
    (within :data:`ROUND_OFF` of it, relative to the duration)."""
    try:
        items = None if isinstance(breakpoints, str) else list(breakpoints)
    except TypeError:              # a number, or a Quantity that is one
        items = None
    if items is None:
        raise TypeError(f"{owner}: breakpoints must be a sequence of times [s], got "
                        f"{breakpoints!r} (one breakpoint: breakpoints=[t])")
    out = tuple(to_si(b, "s", name="breakpoints", owner=owner) for b in items)
    tol = ROUND_OFF * duration
    bad = [b for b in out if not -tol <= b <= duration + tol]      # nan too
    if bad:
        shown = ", ".join(f"{b:.6g}" for b in bad[:5]) + (", ..." if len(bad) > 5 else "")
        raise ValueError(f"{owner}: breakpoints must lie within the run, [0, duration] = "
                         f"[0, {duration:.6g}] s; got {shown} s")
    return out


def _check_max_steps(max_steps, duration, step, step_max, adaptive):
    """``max_steps`` checked, and compared with the steps the run asks for at least."""
    if (isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer))
            or max_steps < 1):
        raise ValueError(f"Simulation: max_steps must be an integer >= 1, got {max_steps!r}")
    fixed = step is not None and not adaptive
    least = duration / (step if fixed else step_max)
    if least > max_steps:
        what = f"step={step:.3g} s" if fixed else f"step_max={step_max:.3g} s"
        raise ValueError(f"Simulation: {what} over duration={duration:.6g} s asks for "
                         f"{least:.3g} steps, more than max_steps={max_steps:.3g}; give a "
                         f"larger step, or max_steps={math.ceil(least * 1.01)} to confirm")
    return int(max_steps)
