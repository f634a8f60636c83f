"""Forward sensitivities of a run with respect to run-time parameters.

``Simulation.run(sensitivities=["tube.diameter", ...])`` differentiates the
computed solution with respect to each named parameter (a numeric argument
of a library component's constructor, named as in ``run(params=...)``),
alongside the run, by the staggered direct method: after every accepted
step, with the step's equations

    F(x, psi + c r(x; theta), t; theta) = 0       (states S = psi + c r)

differentiated along the parameter, the unknowns' sensitivity s_x solves

    J s_x = -(dF/dpsi s_psi + dF/dtheta)

with J the step Jacobian at the converged point. Step by step, the stepper's
own LU factors, already made, solve all parameters' right-hand sides at once
(one multi-column solve); where Newton reuses factors from an earlier step, a
few corrections with products of the exact J at the converged point (one
Jacobian evaluation per step, shared by all parameters) converge the
stale-factor solve, and fresh factors are made where they do not. (Deferred,
below, the steps are instead solved together with their exact J.) The states'
sensitivity follows from the step's update, s_S = s_psi + c (dr/dx s_x +
dr/dtheta). s_psi is formed from the states' sensitivities exactly as psi is
from the states (the same difference table for BDF, the last step's for
backward Euler), so the sensitivities are those of the discrete solution the
stepper computed.

Every derivative is analytic where the component states it. dF/dpsi (= dF/dX
at the step's end states) and dr/dx come from the rate-form contract's own
Jacobians (:func:`softflow.solve.discretize.step_point`). The
parameter derivatives come from an optional classmethod of a library class,
``param_jacobian(P, V, S, t, name)`` -> (dF/dtheta (n, n_eq) of its
``residual``, dr/dtheta (n, n_continuous) of its ``rates``) for parameter
``name`` of every instance of the group, or None for a parameter it does not
cover; the step's dF/dtheta + dF/dX · c · dr/dtheta is composed once, in
:func:`softflow.solve.discretize.param_step_derivative`. Every numeric
parameter of the library's isothermal classes is covered (the friction
blend's bounds Re_laminar / Re_turbulent, an ISO 6358 orifice's b,
pr_laminar and m, an orifice's or check valve's Cd and Re_laminar included).
Only the class that defines ``param_jacobian`` uses it: a subclass with
another law falls back. The thermal variants state their own: the flow
elements and sources the isothermal law's, the flow row scaled by the
upstream temperature's factor; the volumes (free or held) their wall's law
and work from the isothermal class's volume law and initial point, and the
wall heat's parameters. A source's temperature and volumes whose h·A a
heat-transfer correlation sets each step (``begin_step``; held over the step
in the sensitivity equations too, so these are approximate, and their
``area`` is refused) are not covered. The fallback, for those, user
components and classes that write their own step, is a finite
difference (relative step 1e-6) of a twin component rebuilt with the
parameter moved (given what the run's ``begin_step`` set), and directional
differences of the group's step kernel and update along the sensitivity
vectors. Initial states: a component's ``initial_state_jacobian(name)``
where it states one (a Container's mass rho(p0)·volume; in a thermal scene
its thermal class's ``thermal_initial_state_jacobian(comp, name)``: mass and
stored energy), else the twin's difference.

Which arguments are numbers: a component's attribute of the argument's name,
else the number it was given (an argument kept under another name or folded
into another, :data:`USED_AS`), else the number it chose where the argument was
left out (:data:`CHOSEN`). A name, a flag, a curve or a correlation is refused,
and so are an argument the configuration does not use, and a number the
component works out from another argument (moving it alone contradicts that
one), each naming the key and the reason.

How it is evaluated. Nothing of the sensitivity equations feeds back into
the run, so on networks whose groups are all in rate form the accepted steps
(x, psi, t, c) are only buffered, and every CHUNK steps worked out together
(:mod:`softflow.solve.sensitivity_deferred`):
one ``rates`` and one ``residual`` call per group on the steps stacked (its
Params tiled over them; a group that reads the time, a source with a signal,
one call per step) gives every step's Jacobian entries, d(step
equations)/d(psi, theta) and the update's dr/dx. Dense networks (up to
DEFER_MAX unknowns) then take one batched solve J A = dF/dpsi, J B =
dF/dtheta and the states' maps s_S = M s_psi + d, and the one sequential part
is cheap: backward Euler's s_S_n = M_n s_S_{n-1} + d_n as a log-depth scan of
the affine maps, BDF's along its difference table, whose operations
(restart, rescale, order drop) the integrator logs in order and which are
replayed here. Sparse networks solve step by step along the same log, each
step with a sparse LU of its own J. Each step's J is the exact Jacobian at
its converged point, as the step-by-step method's corrections converge to;
the run itself is untouched (Newton's factors and so its steps are the plain
run's). Other networks (user components, classes that write their own step,
per-step coefficients) go step by step as above. Where a buffered step's
Jacobian is singular (or a derivative not finite), the sensitivities are NaN
from that step on and a :class:`SensitivityWarning` names the parameters,
the time and the reason.

At t = 0 the initial states' sensitivity is that of the component's initial
states (e.g. a Container's mass to its volume), and the unknowns' follows from
the consistent-initial-value equations.

Discrete switches (a valve snapping, a hysteretic branch change). The
solution is piecewise smooth; its derivative depends on how the switch time
t* is found:

* Adaptive BDF: the stepper locates the switch where the class's switching
  function g (negative while the mode holds) crosses zero, so t* is a
  function of the parameters, and at the switch the states' sensitivities
  jump (:meth:`Sensitivities.switch`):

      s_S(t*+) = s_S(t*-) - (dS/dt(t*+) - dS/dt(t*-)) dt*/dtheta,
      dt*/dtheta = -(dg/dx s_x + dg/dS s_S + dg/dtheta) / (dg/dt)

  at the end of the step that switched (the left-hand values: the step's
  s_x, s_S; dS/dt(t*-) = (S - psi)/c, exact for the step; dS/dt(t*+) the
  restart's rate in the new mode; dg/dt = dg/dx x' + dg/dS S' with x' from
  the unknowns' difference table at the step's order). The unknowns'
  sensitivities after it follow from the next step's equations in the new
  mode. The gradients of g are the class's ``switching_jacobian(P, V, S)``
  and ``switching_param_jacobian(P, V, S, name)`` (the library's: a snapping
  valve's +-1 on its pressures and opening/closing pressure, a hysteretic
  loop's volume against its branch limits), forward differences of
  ``switching`` where the class that states ``switching`` does not state
  them. The stepper ends a switching step just past the earliest crossing,
  but accepts one over which several cross (within its last SWITCH_PAST, or
  a step that moves by less than the tolerance): each crossing then jumps in
  turn, in the order of its crossing time, by its own dt*/dtheta and the
  rate change of its own mode, the rates with the modes changed one after
  another worked out from the equations at the step's end. A run that ends on
  the step that switched (no restart follows) gets its jump at that last
  point all the same (:meth:`Sensitivities.finish`), its rates after the
  switch and the unknowns' rate before it from the equations there.
  Measured against central differences of whole runs at rtol 1e-8 (tests):
  <= 1.3e-4 after a snapping valve's switches, where the held switch time
  was off by order one; a hysteretic loop's branches meet at its limits, so
  the rates, and the jump, are continuous there. Without a switching
  function (user classes) the switch time is held where it fell.
* Fixed steps (``step=``): a switch is not located; it falls at the end of
  the step on which the switching condition first holds, and a small change
  of a parameter leaves it on that step. The grid-quantized switch time is
  then held, and the held-switch sensitivity is the exact derivative of that
  discrete scheme (a parameter that acts only on the switch, such as a
  valve's opening pressure, has sensitivity 0); the derivative of the
  continuous solution's switch time is not in it.
"""
from __future__ import annotations

import warnings
from functools import partial

import numpy as np
import pint
from scipy.sparse.linalg import splu

from ..network.system import NetworkError
from .bdf import _PRED_PSI, BDF
from .linalg import SingularJacobian
from .discretize import linearizable, param_step_derivative, step_plan, step_point
from .linalg import DENSE_MAX
from .sensitivity_deferred import INITIAL, DeferredSteps, SensitivityWarning, _jumped  # noqa: F401
from .params import STRUCTURAL, given_value, is_choice, parameter_names, rebuild
from .thermal import configure_like

#: Relative step of the finite differences (parameters without an analytic
#: derivative, groups whose step equations are not stated in rate form).
REL_STEP = 1e-6
#: Stale-factor corrections of the sensitivity solve before fresh factors are made.
MAX_CORRECTIONS = 4
#: The corrections stop when the last one is below this fraction of the solution
#: (per unknown, in Newton's tolerance units).
CORRECTION_RTOL = 1e-8
#: Work out the sensitivities of rate-form networks in chunks of steps (see
#: the module docstring), with stacked dense solves up to DEFER_MAX unknowns and
#: a sparse LU per step above; False: always step by step. Measured on air
#: chains (2 parameters, cost over the plain run, loaded 2-core machine):
#: deferred 1.1-1.3x against step by step 3.5-3.9x at 34 unknowns, 1.2-1.3x
#: against 6-95x at 82; at 102-122 the stacked solves' n^3 and OpenBLAS's
#: threads take over (2-9x, against 5-43x step by step); sparse, 1.5-1.6x
#: against 3.8-4.1x at 162, 1.9-2.0x against 3.5-3.6x at 802.
DEFER = True
DEFER_MAX = DENSE_MAX
#: Take parameter derivatives from the classes' ``param_jacobian`` where they
#: give one (False: finite differences everywhere; for tests and benchmarks).
ANALYTIC = True


def _owner(cls, name):
    """The class of cls's MRO that defines ``name`` (None: none)."""
    return next((k for k in cls.__mro__ if name in k.__dict__), None)


def _switching_gradient(cls, P, V, S):
    """d(switching)/dV (n, m, nv) and d/dS (n, m, ns): the class's
    ``switching_jacobian`` where the class that states ``switching`` states it
    too, else forward differences of ``switching`` (user classes)."""
    if ANALYTIC and _owner(cls, "switching_jacobian") is _owner(cls, "switching"):
        GV, GS = cls.switching_jacobian(P, V, S)
        return np.asarray(GV, dtype=float), np.asarray(GS, dtype=float)
    g0 = np.asarray(cls.switching(P, V, S), dtype=float).reshape(len(V), -1)
    out = []
    for A in (V, S):
        G = np.zeros(g0.shape + (A.shape[1],))
        for k in range(A.shape[1]):
            h = REL_STEP * np.maximum(np.abs(A[:, k]), 1e-3)
            B = A.copy()
            B[:, k] += h
            args = (B, S) if A is V else (V, B)
            G[:, :, k] = (np.asarray(cls.switching(P, *args), float).reshape(g0.shape)
                          - g0) / h[:, None]
        out.append(G)
    return out[0], out[1]


def _switching_param(cls, P, V, S, i, j, name, twin, eps):
    """d(switching function j of instance i)/d theta: the class's
    ``switching_param_jacobian`` (same rule as :func:`_switching_gradient`), else
    a difference of the perturbed twin's."""
    if ANALYTIC and _owner(cls, "switching_param_jacobian") is _owner(cls, "switching"):
        out = cls.switching_param_jacobian(P, V, S, name)
        if out is not None:
            return float(np.asarray(out, dtype=float).reshape(len(V), -1)[i, j])
    tcls = twin.kernel_class()
    moved = np.asarray(tcls.switching(tcls.make_params([twin]), V[i:i + 1], S[i:i + 1]), float)
    here = np.asarray(cls.switching(P, V, S), dtype=float).reshape(len(V), -1)[i, j]
    return float((moved.ravel()[j] - here) / eps)


def _begin_params(g):
    """The Params a library group's ``begin`` (per-step coefficients) sets."""
    for cell in getattr(g.begin, "__closure__", None) or ():
        if hasattr(cell.cell_contents, "components") and hasattr(cell.cell_contents, "n"):
            return cell.cell_contents
    return None


def _is_number(value):
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def _named_choice(comp, name):
    """The argument is a name or a flag (a hysteretic actuator's initial_branch
    'inflation', a valve's initially_open), whatever number the component keeps
    for it (:func:`softflow.solve.params.is_choice`)."""
    return is_choice(comp, name)


def _differentiable(comp, name):
    """A parameter sensitivities can be taken to: a finite number, not a choice."""
    value = _numeric_value(comp, name)
    return _is_number(value) and np.isfinite(value) and not _named_choice(comp, name)


#: Arguments left out (None) whose number the component chooses: where to read it
#: (a thermal scene's temperatures, a hysteresis loop's meet tolerance).
CHOSEN = {"initial_temperature": "_T_initial", "wall_temperature": "_T_wall",
          "temperature": "_T_source", "meet_tolerance": "loop.meet_tolerance"}


#: Arguments kept under another attribute, or folded into one: where that attribute
#: is NaN, the component's configuration does not use the argument (an ISO 6358
#: orifice's Re_laminar, a K or Cd orifice's m; an orifice keeps its Cd as Cd,
#: NaN where it was given K or C).
USED_AS = {"Orifice": {"m": "subsonic_index", "Re_laminar": "dp_small"}}


def _numeric_value(comp, name):
    """The SI number behind a component's parameter: its attribute, a source's
    constant value (None for a waveform or a function of time), else the number
    it was given (an argument kept under another name or not at all: an
    orifice's m or Cd, a wall's heat_transfer_coefficient; a Quantity in SI), else
    the number the component chose where it was left out (:data:`CHOSEN`)."""
    alias = USED_AS.get(type(comp).__name__, {}).get(name)
    if alias is not None and not np.isfinite(getattr(comp, alias, 0.0)):
        return float("nan")
    value = getattr(comp, name, None)
    signal = getattr(comp, "signal", None)
    if value is None and signal is not None and signal.name == name:
        value = signal.const
    if value is not None:
        return value
    given = given_value(comp, name)
    if _is_number(given):
        return float(given)
    if isinstance(given, pint.Quantity) and np.ndim(given.magnitude) == 0:
        return float(given.to_base_units().magnitude)
    if given is None and name in CHOSEN:
        value = comp
        for part in CHOSEN[name].split("."):
            value = getattr(value, part, None)
        return value
    return given if given is not None else value


def _warn_held_coefficients(components):
    """A SensitivityWarning where a volume takes its heat-transfer coefficient
    from a correlation: h A is set at each step's start and held, and its
    dependence on the state is not carried, so every sensitivity of the run
    is approximate (a 100 mL tank filled through a 1 mm tube, FreeConvection
    wall, fixed 1 ms steps, against central differences of whole runs:
    d/d tube.diameter 1.3 % off in pressure, 8 % in temperature; the
    volume's own parameters 6-18 %)."""
    held = [c.label for c in components.values() if getattr(c, "_h_corr", None) is not None]
    if held:
        warnings.warn(
            f"sensitivities are approximate in this run: {', '.join(repr(h) for h in held)} "
            "take their heat-transfer coefficient from a correlation, whose dependence on the "
            "state is held at each step's start (measured 1-18 % off); give "
            "them a constant hA, or a constant heat_transfer_coefficient and area, for exact "
            "sensitivities", SensitivityWarning, stacklevel=3)


class Sensitivities(DeferredSteps):
    """The sensitivity equations of a compiled network for a list of parameters.

    The integrators hand over each accepted step, :meth:`step` (with the BDF
    order whose difference table forms the step's s_psi, or 0 for backward
    Euler: the last step's states), and the BDF its table's operations
    (:meth:`restart`, :meth:`rescale`, :meth:`reset_order`)."""

    def __init__(self, asm, newton, names, components, thermal="isothermal"):
        self.asm, self.newton = asm, newton
        self.names = list(names)
        _warn_held_coefficients(components)
        # per parameter: (group, index in group, perturbed kernel, perturbed update
        # (made when first needed), step, the compiled component, its perturbed twin)
        self.parameters = []
        for key in self.names:
            if not isinstance(key, str) or "." not in key:
                raise KeyError(f"sensitivities: {key!r} is not 'label.parameter' "
                               "(e.g. 'tube.diameter')")
            label, name = key.rsplit(".", 1)
            if label not in asm.where:
                have = ", ".join(repr(x) for x in sorted(asm.where)[:20])
                raise KeyError(f"sensitivities: no component {label!r}; the components are "
                               f"{have}")
            g, i = asm.where[label]
            comp = components[label]
            valid = parameter_names(comp) if getattr(comp, "vectorized", False) else []
            if name in STRUCTURAL:
                raise NetworkError(f"sensitivities[{key!r}]: {name} defines the network's "
                                   "structure, not a number of the model; sensitivities are "
                                   f"taken with respect to {', '.join(valid)}")
            if name not in valid:
                raise KeyError(f"sensitivities[{key!r}]: {comp.describe()} has no parameter "
                               f"{name!r}; its parameters are {', '.join(valid) or 'none'}")
            value = _numeric_value(comp, name)
            if not _is_number(value) or _named_choice(comp, name):
                shown = given_value(comp, name) if _named_choice(comp, name) else value
                shown = "not given: the component chooses" if shown is None else repr(shown)
                numeric = [k for k in valid if k not in STRUCTURAL and _differentiable(comp, k)]
                raise NetworkError(
                    f"sensitivities[{key!r}]: {comp.describe()}'s {name!r} is not a number "
                    f"({shown}), so it is not differentiable; sensitivities are taken with "
                    f"respect to numeric parameters: {comp.label!r}'s are "
                    f"{', '.join(numeric) or 'none'}")
            if not np.isfinite(value):
                raise NetworkError(
                    f"sensitivities[{key!r}]: {comp.describe()} does not use {name!r} "
                    f"(it is {value!r} in this configuration)")
            if name == "area" and getattr(comp, "_h_corr", None) is not None:
                raise NetworkError(
                    f"sensitivities[{key!r}]: {comp.describe()}'s h·A comes from a heat-"
                    "transfer correlation, worked out at the start of each step and held "
                    "over it; its derivative is not carried, so 'area' is not "
                    "differentiable here (give a constant heat_transfer_coefficient, or hA)")
            eps = REL_STEP * (abs(value) if value != 0 else 1.0)
            try:
                moved = rebuild(comp, {name: value + eps})
            except (ValueError, TypeError) as err:
                # a number the component works out from another argument (an
                # orifice's K from its Cd): moving it alone contradicts that one
                raise NetworkError(
                    f"sensitivities[{key!r}]: {comp.describe()}'s {name!r} ({value!r}) cannot "
                    f"be moved alone, so it is not differentiable here: {err}") from None
            twin = configure_like(moved, comp, thermal)
            self.parameters.append((g, i, None, None, eps, comp, twin))
        self.n_p = len(self.parameters)
        self._setup_groups()
        n_s = len(asm.S0)
        self._sS = np.zeros((self.n_p, n_s))     # the states' at the last accepted step
        self._table = None                         # BDF: their difference table
        self._bdf = False                          # a BDF run (the table is in use)
        self._blocks_x, self._blocks_s = [], []   # (steps, n_p, n), (steps, n_p, n_s)
        self.deferred = self._deferrable()
        if self.deferred:
            self._setup_deferred()

    def _setup_groups(self):
        """How each group's part of the equations is differentiated: analytically
        (rate form, see :func:`softflow.solve.discretize.step_point`) or
        by directional finite differences of its step kernel and update (user
        components, classes that write their own step, per-step coefficients)."""
        self._params_of = {}      # id(group) -> (group, class, Params, continuous states)
        self._analytic, self._fd = [], []
        for g in self.asm.groups:
            cls = g.comps[0].kernel_class() if getattr(g.comps[0], "vectorized", False) \
                else None
            if cls is not None and g.row is None and g.begin is None and linearizable(cls):
                self._params_of[id(g)] = (g, cls, cls.make_params(g.comps), step_plan(cls).cont)
                if g.ns:
                    self._analytic.append(g)
            elif g.ns:
                self._fd.append(g)
        # per parameter: an analytic derivative (None: not yet known, then True/False)
        self._exact = [None if ANALYTIC and id(g) in self._params_of else False
                       for g, *_ in self.parameters]
        self._dense = self.asm.n <= DENSE_MAX
        if self._dense:
            self._flat = self.asm.dense_index()

    # -- the integrators' side ----------------------------------------------------------
    def initial(self, x0, S0, t0=0.0):
        """Sensitivities at the consistent initial point: the initial states' from
        the components' own, the unknowns' from the t = 0 equations (c = 0)."""
        s_S0 = np.zeros((self.n_p, len(S0)))
        for p, (g, i, _, _, eps, comp, twin) in enumerate(self.parameters):
            if g.ns:
                s_S0[p, g.s0 + i * g.ns:g.s0 + (i + 1) * g.ns] = self._initial_states(
                    comp, twin, eps, self.names[p].rsplit(".", 1)[1])
        self._sS = s_S0
        self._ends, self._t_last, self._switched_last = (None, (x0, S0, t0, None)), t0, False
        if self.deferred:     # worked out with the first steps (s_x0 None till then)
            self._push(x0, S0, t0, 0.0, INITIAL)
            return None, s_S0
        s_x0 = self._unknowns(x0, S0, s_S0, t0, 0.0, np.zeros((self.n_p, len(x0))),
                              fresh=True)[0]
        self._record(s_x0[None], s_S0[None])
        return s_x0, s_S0

    def step(self, x, psi, t, c, k=0):
        """One accepted step, converged to x from psi at time t with coefficient c:
        its states' s_psi are the last step's states' (k = 0, backward Euler) or
        formed from the BDF difference table at order k."""
        self._ends = (self._ends[1], (x, psi, t, c))
        self._t_last, self._switched_last = t, False
        if self.deferred:
            self._push(x, psi, t, c, k)
            return
        if k:
            pred, psi_p = _PRED_PSI[k] @ self._table[:k + 1]
            s_psi = psi_p.reshape(self.n_p, -1)
        else:
            s_psi = self._sS
        start = self._last_x if self._blocks_x else np.zeros((self.n_p, self.asm.n))
        s_x, s_S = self._step_now(x, psi, s_psi, t, c, start)
        if k:
            BDF._difference_update(self._table, s_S.ravel() - pred, k)
        self._sS = s_S
        self._record(s_x[None], s_S[None])

    def restart(self, kmax):
        """BDF restart at order 1: the table holds the current states' alone."""
        self._bdf = True
        self._op(("restart", kmax))

    def rescale(self, k, M):
        """BDF step change: rows 1..k of the table times M (as the states')."""
        self._op(("rescale", k, M))

    def reset_order(self, k_new):
        """BDF order drop: the differences above k_new go."""
        self._op(("reset", k_new))

    def switch(self, x0, S0, x, S, psi, c, xdot, rate_after):
        """A located discrete switch (BDF): the step from (x0, S0) ended at (x, S)
        (new modes) from psi with coefficient c, the unknowns' rate there xdot, the
        states' rate in the new mode rate_after. The switch time t* moved by the
        parameters, dt*/dtheta = -(dg/dx s_x + dg/dS s_S + dg/dtheta) / (dg/dt)
        for the switching function g that crossed zero, makes the states'
        sensitivity jump by -(rate after - rate before) dt*/dtheta."""
        self._switched_last = True
        for jump in self._switch_jumps(x0, S0, x, S, psi, c, xdot, rate_after):
            if self.deferred:
                self._log.append(jump)
            else:
                self._sS = _jumped(self._last_x, self._sS, jump)
                self._blocks_s[-1][-1] = self._sS

    def _switch_jumps(self, x0, S0, x, S, psi, c, xdot, rate_after):
        """[("jump", dg/dx (n,), dg/dS (n_s,), dg/dtheta (n_p,), dg/dt, rate change
        (n_s,)), ...]: one per switching function that crossed zero in the step
        and whose mode changed, in the order of their (secant) crossing times.
        The integrator places a step's end just past the earliest crossing, but
        accepts a step over which several cross (within its last SWITCH_PAST, or a
        step that moved by less than the tolerance): each then jumps in turn,
        crossing j by -(f_j - f_(j-1)) dt_j*/dtheta, f_j the states' rate with
        the first j modes changed (all from the equations at the step's end,
        :meth:`_rates_in_modes`; one crossing alone takes the step's rate
        before and the integrator's after, as before), dt_j*/dtheta from the
        left-hand s_x and the s_S the earlier jumps left. Empty where none crossed (the switch is held where it fell)."""
        asm = self.asm
        disc = asm.s_discrete
        old = S.copy()
        old[disc] = S0[disc]
        found = []
        for g in asm.groups:
            if g.switching is None:
                continue
            g0 = np.asarray(g.switching(x0[g.col], S0[g.s0:g.s1].reshape(g.n, g.ns)), float)
            g1 = np.asarray(g.switching(x[g.col], old[g.s0:g.s1].reshape(g.n, g.ns)), float)
            g0, g1 = g0.reshape(g.n, -1), g1.reshape(g.n, -1)
            cross = (g0 < 0.0) & (g1 >= 0.0)
            if not cross.any():
                continue
            local = step_plan(g.comps[0].kernel_class()).disc
            for i, j in zip(*np.nonzero(cross)):
                at = g.s0 + int(i) * g.ns + int(local[j])
                if S[at] != S0[at]:           # its mode did change
                    found.append((g0[i, j] / (g0[i, j] - g1[i, j]), len(found), g,
                                  int(i), int(j), at))
        found.sort(key=lambda f: f[:2])
        rate_before = (S - psi) / c
        rate_before[disc] = 0.0
        if len(found) == 1:
            rate = rate_before
        else:
            # several: every rate from the equations alike (the step's and the
            # restart probe's differ from these by Newton's tolerance, which the
            # differences between them would hand to the other crossings' states)
            rate = self._rates_in_modes(x, old, self._t_last)
        jumps, modes = [], old.copy()
        for k, (_, _, g, i, j, at) in enumerate(found):
            modes[at] = S[at]
            if k + 1 < len(found):
                after = self._rates_in_modes(x, modes, self._t_last)
            elif len(found) > 1:
                modes[disc] = S[disc]
                after = self._rates_in_modes(x, modes, self._t_last)
            else:
                after = np.asarray(rate_after, dtype=float).copy()
                after[disc] = 0.0
            jump = self._crossing_jump(g, i, j, x, old, xdot, rate_before, after - rate)
            rate = after
            if jump is not None:
                jumps.append(jump)
            else:
                warnings.warn(f"sensitivities: {g.comps[i].describe()} switched at t = "
                              f"{self._t_last:.6g} s where its switching function only "
                              "grazes zero (its rate there is not positive): the switch "
                              "time is not differentiable there, and the sensitivities "
                              "hold it", SensitivityWarning, stacklevel=2)
        return jumps

    def _crossing_jump(self, g, i, j, x, old, xdot, rate_before, change):
        """The jump of switching function j of instance i of group g (see
        :meth:`_switch_jumps`); None where it grazes (dg/dt <= 0: t* is not
        differentiable there)."""
        asm = self.asm
        disc = asm.s_discrete
        V, Sg = x[g.col], old[g.s0:g.s1].reshape(g.n, g.ns)
        cls = g.comps[0].kernel_class()
        P = g.switching.args[0]
        GV, GS = _switching_gradient(cls, P, V, Sg)
        gx = np.zeros(asm.n)
        np.add.at(gx, g.col[i], GV[i, j])
        gS = np.zeros(len(old))
        gS[g.s0 + i * g.ns:g.s0 + (i + 1) * g.ns] = GS[i, j]
        gS[disc] = 0.0
        change = change.copy()
        change[disc] = 0.0
        gdot = float(gx @ xdot + gS @ rate_before)
        gth = np.zeros(self.n_p)
        for p, (gp, ip, _, _, eps, comp, twin) in enumerate(self.parameters):
            if gp is g and ip == i:
                gth[p] = _switching_param(cls, P, V, Sg, i, j, self.names[p].rsplit(".", 1)[1],
                                          twin, eps)
        if not (np.isfinite(gdot) and gdot > 0.0):
            return None
        return ("jump", gx, gS, gth, gdot, change)

    # -- the algebraic equations at a point (c = 0), for the switches' rates -----------
    def _algebraic_jacobian(self, x, S, t):
        """F(x; S) of the equations at c = 0 (the states held) and their Jacobian
        (dense or CSC), evaluated here: Newton's factors are not touched."""
        F = self.asm.residual(x, S, t, 0.0, jac=True)
        return F, self._jacobian()

    @staticmethod
    def _lin_solve(J, b):
        if isinstance(J, np.ndarray):
            return np.linalg.solve(J, b)
        return splu(J.tocsc(), permc_spec="COLAMD").solve(np.ascontiguousarray(b))

    def _rates_in_modes(self, x, S, t):
        """The states' rates (discrete: 0) at the states S with the modes in S: the
        unknowns from the equations at c = 0 (Newton from x, held to 1e-10 of
        Newton's tolerances), the rates from the update, affine in its step
        (X = S + dt r; the adaptive stepper requires it)."""
        asm = self.asm
        x = x.copy()
        for _ in range(20):
            F, J = self._algebraic_jacobian(x, S, t)
            dx = self._lin_solve(J, F)
            x -= dx
            if np.max(np.abs(dx) / self.newton.tol) <= 1e-10:
                break
        r = np.asarray(asm.update_states(x, S, 1.0), dtype=float) - S
        if asm.has_discrete:
            r[asm.s_discrete] = 0.0
        return r

    def _unknowns_rate(self, x, S, rate, t):
        """dx/dt along the states' rate at (x, S) (the equations at c = 0:
        J x' = -(dF/dS S' + dF/dt), the bracket a central difference along
        (S', 1) of relative size 1e-6 of the state's scale)."""
        F0, J = self._algebraic_jacobian(x, S, t)
        scale = np.max(np.abs(S[rate != 0]), initial=0.0) / max(np.max(np.abs(rate)), 1e-300)
        h = 1e-6 * (scale if 0.0 < scale < np.inf else 1.0)
        up = self.asm.residual(x, S + h * rate, t + h, 0.0)
        down = self.asm.residual(x, S - h * rate, t - h, 0.0)
        return -self._lin_solve(J, (up - down) / (2.0 * h))

    def _end_switch(self):
        """A run that ends on the step that switched (no restart follows, so the
        integrator hands over no :meth:`switch`): the jump at that last point,
        with the rates after it and the unknowns' rate before it worked out here
        (:meth:`_rates_in_modes`, :meth:`_unknowns_rate`)."""
        asm = self.asm
        if not (self._bdf and asm.has_discrete) or getattr(self, "_switched_last", True):
            return
        prev, last = self._ends
        if prev is None or last is None or last[3] is None:
            return
        x, psi, t, c = last
        S = np.asarray(asm.update_states(x, psi, c), dtype=float)
        disc = asm.s_discrete
        if np.array_equal(S[disc], psi[disc]):
            return
        x0, S0, _, c0 = prev
        if c0 is not None:                     # the step before's end states
            S0 = np.asarray(asm.update_states(x0, S0, c0), dtype=float)
        old = S.copy()
        old[disc] = psi[disc]
        rate_before = (S - psi) / c
        rate_before[disc] = 0.0
        xdot = self._unknowns_rate(x, old, rate_before, t)
        rate_after = self._rates_in_modes(x, S, t)
        self._t_last = t
        self.switch(x0, S0, x, S, psi, c, xdot, rate_after)

    def _op(self, op):
        if self.deferred:
            self._log.append(op)
        else:
            self._apply(op)

    def _apply(self, op):
        kind = op[0]
        if kind == "restart":
            if self._table is None:
                self._table = np.zeros((op[1] + 3, self._sS.size))
            self._table[:] = 0.0
            self._table[0] = self._sS.ravel()
        elif kind == "rescale":
            k = op[1]
            self._table[1:k + 1] = op[2] @ self._table[1:k + 1]
        else:
            self._table[op[1] + 1:] = 0.0

    # -- results ------------------------------------------------------------------------
    def _record(self, s_x, s_S):
        self._blocks_x.append(s_x)
        self._blocks_s.append(s_S)
        self._last_x = s_x[-1]

    def finish(self):
        """The jump of a switch on the run's last step (:meth:`_end_switch`), then
        the steps still waiting (deferred mode)."""
        if not getattr(self, "_finished", False):
            self._finished = True
            self._end_switch()
        if self.deferred and self._n_buf:
            self._flush()

    def arrays(self, x_index, s_index):
        """{parameter: (s_x over time (T x recorded unknowns), s_S (T x recorded states))}."""
        self.finish()
        n_x, n_s = self.asm.n, len(self.asm.S0)
        X = (np.concatenate(self._blocks_x) if self._blocks_x
             else np.zeros((0, self.n_p, n_x)))
        S = (np.concatenate(self._blocks_s) if self._blocks_s
             else np.zeros((0, self.n_p, n_s)))
        return {name: (X[:, p][:, x_index], S[:, p][:, s_index])
                for p, name in enumerate(self.names)}

    # -- one step at a time (large or non-rate-form networks) ---------------------------
    def _jacobian(self):
        """The step Jacobian of the last ``residual(..., jac=True)``, for products."""
        asm = self.asm
        if self._dense:
            return asm.dense_jacobian()
        return asm.jacobian_csc()

    def _linearize(self, x, psi, t, c):
        """Per rate-form group: (V, psi, X, FX, RV) at the converged point."""
        lin = {}
        for key, (g, cls, P, _) in self._params_of.items():
            V = x[g.col]
            Sg = psi[g.s0:g.s1].reshape(g.n, g.ns)
            _, _, X, FX, RV = step_point(cls, P, V, Sg, t, c)
            lin[key] = (V, Sg, X, FX, RV)
        return lin

    def _parameter_terms(self, p, lin, x, psi, t, c):
        """(dG/dtheta of the rows of parameter p's component (neq,), and dX/dtheta
        of its states (ns,)): analytic where its class states it, else a finite
        difference of the perturbed twin's step kernel and update."""
        g, i, kernel_p, update_p, eps, comp, twin = self.parameters[p]
        if kernel_p is None:
            from .assembly import _library_group
            comps = list(g.comps)
            comps[i] = twin
            fresh = _library_group(twin.kernel_class(), comps)
            kernel_p, update_p = fresh.kernel, fresh.update
            self.parameters[p] = (g, i, kernel_p, update_p, eps, comp, twin)
            if fresh.begin is not None:
                self.__dict__.setdefault("_twin_params", {})[p] = _begin_params(fresh)
        if self._exact[p] is not False:
            _, cls, P, cont = self._params_of[id(g)]
            V, Sg, X, FX, _ = lin[id(g)]
            name = self.names[p].rsplit(".", 1)[1]
            out = param_step_derivative(cls, P, V, X, FX, t, c, name)
            self._exact[p] = out is not None
            if out is not None:
                dS = np.zeros(g.ns)
                dS[cont] = out[1][i]
                return out[0][i], dS
        V = x[g.col]
        Sg = psi[g.s0:g.s1].reshape(g.n, g.ns)
        if g.begin is not None:
            self._freeze_like(g, p)
        F0, _ = g.kernel(V, Sg, t, c, False)
        Fp, _ = kernel_p(V, Sg, t, c, False)
        dG = (Fp[i] - F0[i]) / eps
        if not g.ns:
            return dG, np.zeros(0)
        return dG, (np.asarray(update_p(V, Sg, c))[i] - np.asarray(g.update(V, Sg, c))[i]) / eps

    def _freeze_like(self, g, p):
        """Give parameter p's perturbed twin group what the run's group set at the
        start of the step (``begin_step``: a heat-transfer correlation's h·A,
        frozen over the step), so that the difference is the parameter's alone:
        every entry of the run's Params that begin_step moved from its made value."""
        P_run = _begin_params(g)
        P_twin = self.__dict__.get("_twin_params", {}).get(p)
        if P_run is None or P_twin is None:
            return
        made = self.__dict__.setdefault("_made", {})
        if id(g) not in made:
            made[id(g)] = g.comps[0].kernel_class().make_params(g.comps)
        for key, base in vars(made[id(g)]).items():
            run, twin = getattr(P_run, key, None), getattr(P_twin, key, None)
            if (type(base) is np.ndarray and base.dtype.kind == "f" and type(run) is np.ndarray
                    and type(twin) is np.ndarray and run.shape == base.shape == twin.shape):
                moved = run != base
                twin[moved] = run[moved]

    def _eps(self):
        return np.array([prm[4] for prm in self.parameters])

    def _unknowns(self, x, psi, s_psi, t, c, start, fresh=False):
        """s_x (n_p x n) at the converged point (x, psi, t, c), with the
        linearization and parameter terms the states' update reuses."""
        asm, n_p = self.asm, self.n_p
        asm.residual(x, psi, t, c, jac=True)
        self.newton._jac_x = x     # where _solve may factor this Jacobian (its pieces)
        lin = self._linearize(x, psi, t, c)
        rhs = np.zeros((asm.n, n_p))
        for g in self._analytic:
            _, _, _, FX, _ = lin[id(g)]
            cont = self._params_of[id(g)][3]
            sp = s_psi[:, g.s0:g.s1].reshape(n_p, g.n, g.ns)[:, :, cont]
            rhs[g.r0:g.r1] -= np.einsum("ies,pis->iep", FX, sp).reshape(g.r1 - g.r0, n_p)
        if self._fd:
            eps = self._eps()
            for g in self._fd:
                V = x[g.col]
                Sg = psi[g.s0:g.s1].reshape(g.n, g.ns)
                F0, _ = g.kernel(V, Sg, t, c, False)
                for p in range(n_p):
                    moved = Sg + eps[p] * s_psi[p, g.s0:g.s1].reshape(g.n, g.ns)
                    Fp, _ = g.kernel(V, moved, t, c, False)
                    rhs[g.r0:g.r1, p] -= (Fp - F0).ravel() / eps[p]
        terms = []
        for p in range(n_p):
            g, i = self.parameters[p][:2]
            dG, dS = self._parameter_terms(p, lin, x, psi, t, c)
            r0 = g.r0 + i * g.neq
            rhs[r0:r0 + g.neq, p] -= dG
            terms.append(dS)
        s_x = self._solve(rhs, start, c, fresh)
        return s_x.T, lin, terms

    def _solve(self, rhs, start, c, fresh):
        """J s = rhs (n x n_p, every parameter at once) on the stepper's factors:
        made at this point (or of the same matrix: a linear network at a fixed
        step) they solve it at once; older ones (Newton reuses factors over
        steps) are corrected with products of the exact J until the correction is
        below CORRECTION_RTOL of s, or replaced by fresh factors (which the next
        steps' Newton solves then use) where MAX_CORRECTIONS do not get there."""
        newton = self.newton
        lin = newton.lin
        if not (fresh or getattr(newton, "stale", False) or newton.lu_dt is None):
            J = self._jacobian()
            if self._dense and np.array_equal(J, getattr(lin, "_J", None)):
                return lin.solve(rhs)
            scale = 1.0 / newton.tol[:, None]
            s = start.T.copy()
            for _ in range(MAX_CORRECTIONS):
                ds = lin.solve(rhs - J @ s)
                s += ds
                if np.max(np.abs(ds) * scale) <= CORRECTION_RTOL * np.max(np.abs(s) * scale):
                    return s
        try:
            newton._factor(c)     # the Jacobian of the residual(jac=True) at this point
        except SingularJacobian:
            # NaN from here on, said once; the run goes on to meet (and name) the
            # singular point itself, as a run without sensitivities does
            if getattr(self, "_failed_at", None) is None:
                self._failed_at = self._t_last
                warnings.warn(f"sensitivities to {', '.join(self.names)} are NaN from "
                              f"t = {self._t_last:.6g} s on: the step Jacobian is singular "
                              "there", SensitivityWarning, stacklevel=2)
            return np.full(np.shape(rhs), np.nan)
        return lin.solve(rhs)

    def _step_now(self, x, psi, s_psi, t, c, start):
        """(s_x, s_S) (n_p x n, n_p x n_s) after a step converged to x from psi."""
        asm, n_p = self.asm, self.n_p
        s_x, lin, terms = self._unknowns(x, psi, s_psi, t, c, start)
        s_S = np.zeros((n_p, len(asm.S0)))
        for g in self._analytic:
            cont = self._params_of[id(g)][3]
            _, _, _, _, RV = lin[id(g)]
            sp = s_psi[:, g.s0:g.s1].reshape(n_p, g.n, g.ns)
            out = np.zeros_like(sp)
            # s_X = s_psi + c (dr/dV s_V): the update X = psi + c r(V)
            out[:, :, cont] = sp[:, :, cont] + c * np.einsum("isv,piv->pis", RV, s_x[:, g.col])
            s_S[:, g.s0:g.s1] = out.reshape(n_p, -1)
        if self._fd:
            eps = self._eps()
            for g in self._fd:
                V = x[g.col]
                Sg = psi[g.s0:g.s1].reshape(g.n, g.ns)
                base = np.asarray(g.update(V, Sg, c), dtype=float)
                for p in range(n_p):
                    moved = g.update(V + eps[p] * s_x[p][g.col],
                                     Sg + eps[p] * s_psi[p, g.s0:g.s1].reshape(g.n, g.ns), c)
                    s_S[p, g.s0:g.s1] = ((np.asarray(moved) - base) / eps[p]).ravel()
        for p, dS in enumerate(terms):
            g, i = self.parameters[p][:2]
            if g.ns:
                s_S[p, g.s0 + i * g.ns:g.s0 + (i + 1) * g.ns] += dS
        if asm.has_discrete:
            s_S[:, asm.s_discrete] = 0.0
        return s_x, s_S

    @staticmethod
    def _initial_states(comp, twin, eps, name):
        """d(initial states)/d theta: the component's own, where it states them
        (isothermal scenes), else a finite difference of its twin's."""
        if comp._thermal is None:
            exact = getattr(comp, "initial_state_jacobian", None)
        else:     # the thermal variant's (initial mass and stored energy)
            exact = getattr(comp.kernel_class(), "thermal_initial_state_jacobian", None)
            exact = None if exact is None else partial(exact, comp)
        if exact is not None and ANALYTIC:
            out = exact(name)
            if out is not None:
                return np.asarray(out, dtype=float)
        a = np.array(comp.initial_state_values(), dtype=float)
        b = np.array(twin.initial_state_values(), dtype=float)
        return (b - a) / eps

    # -- deferred: steps worked out CHUNK at a time --------------------------------------
    def _deferrable(self):
        """Every group in rate form (no user component, no own step, no per-step
        coefficients); dense systems of at most DEFER_MAX unknowns, sparse ones
        (a sparse LU per step, :meth:`_flush_sparse`)."""
        return (DEFER and (self.asm.n <= DEFER_MAX or not self._dense) and not self._fd
                and len(self._params_of) == len(self.asm.groups))
