"""LibraryComponent: components that evaluate all instances of a class at once.

A library class declares its interface in class attributes and states its
equations in rate form, as classmethods that work on NumPy arrays holding
every instance of the class in the network:

``rates(P, V, S, jac)``
    the time derivatives of its continuous states (dm/dt = mdot, ...), with
    their analytic derivatives in the interface variables V;
``residual(P, V, S, t, jac)``
    its algebraic equations, with S the states at the time of V, and their
    analytic derivatives in V and in the continuous states;
``switch(P, V, S)``
    the next value of each discrete state (a mode) after a converged step.

``switching(P, V, S)`` (optional, with discrete states)
    each discrete state's switching function, (n, n_discrete): negative while
    its mode holds at (V, S), crossing zero where :meth:`switch` changes it.
    The adaptive stepper places the end of a step that switches a mode at the
    crossing (a secant between the step's ends) instead of bisecting.
``switching_jacobian(P, V, S)``, ``switching_param_jacobian(P, V, S, name)`` (optional)
    its derivatives in V (n, m, nv) and S (n, m, ns), and in a parameter (n, m),
    for the sensitivities' jump at a located switch (else finite differences).
``regime(P, V)`` (optional)
    which piece of a piecewise law each instance is on at V, a NumPy array
    of (n,) integers (a check valve: shut, the bottom of its opening band in
    pieces, its steep middle, open). Newton's chord iterations reuse a
    Jacobian only while every instance stays on the piece it was evaluated
    on: a slope from one piece (an opening valve's steep one) read on
    another makes the chord's updates small far from the root, and the
    update-based convergence test is then fooled
    (:meth:`softflow.solve.newton.Newton.solve`).
``kinks(P, V)`` (optional)
    which side of each point where the law's second derivative jumps each
    instance is on at V, a NumPy array of (n,) integers (a check valve:
    shut, inside its opening band, open). A step across one lowers the
    BDF's order to 1: the method's history from before the kink
    extrapolates a smooth trajectory past it (a tank whose valve has just
    shut goes on rising at order 2).
``param_jacobian(P, V, S, t, name)`` (optional)
    dF/dtheta of ``residual`` and dr/dtheta of ``rates`` for the numeric
    parameter ``name`` of every instance, or None where the class states none
    (then sensitivities take finite differences of a rebuilt twin). Only the
    class that defines it uses it: subclasses with another law (the thermal
    variants) do not inherit it (:func:`softflow.solve.discretize.param_step_derivative`).

A component never sees the time step: :mod:`softflow.solve.discretize` turns
rates and residuals into the equations of one step of whichever stepper runs
(backward Euler, BDF 1-5). The assembly stacks the instances' parameters
once per Simulation into a :class:`Params` namespace.
"""
from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING, Any, Hashable, Sequence

import numpy as np

from ..constants import atomic_size, pressure_atmospheric
from ..network.component import Component
from ..network.variable import SharedVariable, Terminal, Variable
from ..units import to_si

if TYPE_CHECKING:
    from .._typing import Array
    from ..fluids.base import Fluid

#: Standard fluid port: absolute pressure (across) and mass flow into the component (through).
FLUID_PORT = (("pressure", "across", "p"), ("massflow", "through", "mf"))


class Params:
    """Stacked parameters of a group of instances (attributes are arrays of length n)."""

    def __init__(self, components):
        self.components = list(components)
        self.n = len(self.components)
        first = self.components[0]
        self.fluid = getattr(first, "fluid", None)
        names = type(first).param_names
        if not names:
            return
        # every parameter in one array, a row each (one conversion instead of one
        # per name: ~1 us a name on a small group); per name where they differ
        # in shape, as before
        try:
            table = np.array([[getattr(c, name) for c in self.components] for name in names],
                             dtype=float)
        except ValueError:
            table = None
        if table is None or table.ndim != 2:
            for name in names:
                setattr(self, name, np.array([getattr(c, name) for c in self.components],
                                             dtype=float))
            return
        for name, row in zip(names, table):
            setattr(self, name, row)


class LibraryComponent(Component):
    """Base of vectorized library components.

    Subclasses set:

    ``terminal_spec``
        ``((terminal_label, ((quantity, role, label), ...)), ...)``
    ``state_spec``
        ``((label, quantity), ...)``
    ``param_names``
        numeric SI attributes stacked into :class:`Params`
    ``jac_pattern``
        ``((equation, variable), ...)`` structural nonzeros of the step
        equations' Jacobian dF/dV; variables are numbered in interface order
        (terminal variables, then locals)
    ``residual_pattern``
        the entries of ``jac_pattern`` that :meth:`residual` itself fills in V
        (default: all of them)
    ``state_jac_pattern``
        ``((equation, state), ...)`` nonzeros of dF/dX of :meth:`residual` in the
        continuous states X (numbered among the continuous states, in
        ``state_spec`` order; discrete states are not counted)
    ``rate_pattern``
        ``((state, variable), ...)`` nonzeros of dr/dV of :meth:`rates` (states
        numbered as in ``state_jac_pattern``)
    ``discrete_states``
        labels of states that are modes (e.g. a valve's open/closed memory):
        :meth:`residual` reads them at the start of the step and :meth:`switch`
        decides them from the converged solution, so a mode never changes
        inside a Newton solve

    Every entry of dF/dX · dr/dV must have its place in ``jac_pattern``
    (checked when a network is compiled).
    """

    vectorized = True
    #: whether the component may impose a flow at its node whatever the
    #: node's pressure (the flow sources): the solver's culprit finder looks
    #: for nodes that no pressure balances only in networks with such a
    #: component (user components, which do not say, count as such)
    imposes_flow = False
    #: thermal model resolved by the Simulation (None: isothermal, the paper's model);
    #: see :mod:`softflow.solve.thermal`
    _thermal = None
    terminal_spec: tuple = ()
    state_spec: tuple = ()
    param_names: tuple = ()
    jac_pattern: tuple = ()
    residual_pattern: tuple | None = None     # None: jac_pattern (set in __init_subclass__)
    state_jac_pattern: tuple = ()
    rate_pattern: tuple = ()
    discrete_states: tuple = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        init = cls.__dict__.get("__init__")
        if init is not None:
            cls.__init__ = _recording(init)
        if "residual_pattern" not in cls.__dict__ and (
                "jac_pattern" in cls.__dict__ or cls.residual_pattern is None):
            cls.residual_pattern = cls.jac_pattern

    def __init__(self, label: str, fluid: Fluid | None = None) -> None:
        super().__init__(label)
        self.fluid = fluid
        cls = type(self)
        templates = _INTERFACE.get(cls)
        if templates is None:
            templates = _interface_templates(cls)
        if templates is _CUSTOM:
            # a subclass that redefines set_terminals/set_states gets them called
            self.set_terminals(*_spec_terminals(cls))
            self.set_states(*[Variable(q, "local", label=lab) for lab, q in self.state_spec])
            return
        # the interface, checked once per class (see _interface_templates): its
        # variables are shared, read-only (SharedVariable; a volume takes its own
        # copy of the one it sets, Terminal.own_variable): fewer objects to
        # build and for the cyclic collector to walk in a large network
        terminal_templates, state_templates = templates
        terms = []
        for tlabel, vars_ in terminal_templates:
            t = _of_checked(tlabel, vars_)
            t.component = self
            terms.append(t)
        self.terminals = terms
        self.states = state_templates

    # -- helpers for subclasses ------------------------------------------------------
    def _si(self, value, unit, name, *, positive=False, nonnegative=False, size=False):
        """``value`` in SI (``unit``), checked finite (and > 0 with ``positive``,
        >= 0 with ``nonnegative``; ``size``: a length of a flow passage, at
        least an atom's size), or a ValueError naming this component and
        ``name``."""
        tp = type(value)
        if tp is float or tp is int:
            v = float(value)    # a plain SI number: what to_si would return
        else:
            v = to_si(value, unit, name=name, owner=self.describe())
            if np.ndim(v) != 0:
                raise ValueError(f"{self.describe()}: {name} must be a scalar, got an array")
        if not _isfinite(v):
            raise ValueError(f"{self.describe()}: {name} must be finite, got {v}")
        if positive and not v > 0:
            raise ValueError(f"{self.describe()}: {name} must be > 0 [{unit}], got {v}")
        if nonnegative and v < 0:
            raise ValueError(f"{self.describe()}: {name} must be >= 0 [{unit}], got {v}")
        if size and v < atomic_size:
            # (no flow law describes a passage below a molecule's size; a
            # 1 pm long tube failed at t = 0 after ~250 residual evaluations,
            # its flow out of reach of Newton's steps)
            raise ValueError(
                f"{self.describe()}: {name} = {v:g} m is below an atom's size "
                f"({atomic_size:g} m), where no flow law holds; check its units (a plain "
                "number is metres)" + ("; a restriction of no length is an Orifice"
                                       if name == "length" else ""))
        return v

    def _check_fluid_state(self, pressure, name):
        """A fluid-range error for an initial state, naming this component and parameter."""
        try:
            self.fluid.density(pressure)
        except _fluid_base().FluidError as err:
            raise _fluid_base().FluidError(f"{self.describe()}: {name} = {pressure:.6g} Pa: {err}") from None

    def _check_fluid(self, fluid):
        if not isinstance(fluid, _fluid_base().Fluid):
            raise TypeError(f"{self.describe()}: fluid must be a softflow Fluid (e.g. sf.air, "
                            f"sf.water), got {fluid!r}")
        return fluid

    # -- grouping and kernels ----------------------------------------------------------
    def group_key(self) -> Hashable:
        """Instances with equal keys are evaluated together in one kernel call."""
        return (type(self), id(self.fluid))

    def initial_states(self) -> list[float]:
        """State values at t = 0, in ``state_spec`` order."""
        return [0.0] * len(self.state_spec)

    def kernel_class(self) -> type[LibraryComponent]:
        """The class whose kernels evaluate this instance: its own in isothermal
        scenes, its thermal variant (:mod:`softflow.components.thermal`) in thermal ones."""
        if self._thermal is None:
            return type(self)
        from .thermal import thermal_class
        return thermal_class(type(self), held=self._thermal == "isothermal")

    def initial_state_values(self) -> list[float]:
        """Initial states of the compiled model (thermal variants add internal energy)."""
        if self._thermal is None:
            return self.initial_states()
        return self.kernel_class().thermal_initial_states(self)

    @classmethod
    def make_params(cls, components: Sequence[LibraryComponent]) -> Params:
        return Params(components)

    @classmethod
    def rates(cls, P: Params, V: Array, S: Array, jac: bool) -> tuple[Array, Any]:
        """Rates of the continuous states, r (n, n_continuous) in ``state_spec``
        order, and, if ``jac``, dr/dV as a sequence of ``len(rate_pattern)``
        columns (arrays of length n, or floats for entries equal in every
        instance); else None.

        Rates depend on the interface variables V and on the discrete states
        in S (the modes), never on the continuous states themselves."""
        return np.empty((P.n, 0)), ()

    @classmethod
    def residual(cls, P: Params, V: Array, S: Array, t: float,
                 jac: bool) -> tuple[Array, Array | None]:
        """Residuals F (n, n_eq) at time t and, if ``jac``, their Jacobian
        (n, len(residual_pattern) + len(state_jac_pattern)): dF/dV in
        ``residual_pattern`` order, then dF/dX in ``state_jac_pattern`` order.

        S (n, n_states) holds the continuous states at the time of V and the
        discrete states (modes) as they were at the start of the step."""
        raise NotImplementedError

    @classmethod
    def switch(cls, P: Params, V: Array, S: Array) -> Array:
        """The discrete states (n, n_discrete) after a step that converged to V,
        with S the states at its end (modes still the old ones)."""
        raise NotImplementedError(f"{cls.__name__} declares discrete states but no switch")

    @classmethod
    def kernel(cls, P: Params, V: Array, S: Array, t: float, dt: float,
               jac: bool) -> tuple[Array, Array | None]:
        """The step equations F(V, S + dt·r(V), t) and their Jacobian dF/dV in
        ``jac_pattern`` order, for states S at the start of the step (or a
        BDF predictor) and step dt (or its c): see :mod:`softflow.solve.discretize`."""
        from ..solve.discretize import step_kernel
        return step_kernel(cls, P, V, S, t, dt, jac)

    @classmethod
    def update(cls, P: Params, V: Array, S: Array, dt: float) -> Array:
        """States at the end of the step whose equations :meth:`kernel` states."""
        from ..solve.discretize import step_update
        return step_update(cls, P, V, S, dt)

    @classmethod
    def affine(cls, P: Params) -> Affine | None:
        """None, or an :class:`Affine` description of this group's residual
        (without Jacobian) as an affine map of V, which small systems evaluate
        for all such groups with one matrix product. Only a class whose
        :meth:`residual` the description matches may return one (a subclass with
        its own residual must not inherit it)."""
        return None


def _fluid_base():
    """softflow.fluids.base, imported on first use (it loads the fluid stack)."""
    global _FLUID_BASE
    if _FLUID_BASE is None:
        from ..fluids import base
        _FLUID_BASE = base
    return _FLUID_BASE


_FLUID_BASE = None
_isfinite = math.isfinite
_of_checked = Terminal._of_checked

#: per library class: (((terminal label, (Variable, ...)), ...), (state Variable, ...)),
#: the interface its constructor copies, or _CUSTOM
_INTERFACE: dict = {}
_CUSTOM = object()


def _spec_terminals(cls):
    """New Terminals of a library class's ``terminal_spec`` (pressures start at
    1 atm, the other variables at 0)."""
    return [Terminal(tlabel, [Variable(q, role, label=lab,
                                       initial_value=pressure_atmospheric if q == "pressure"
                                       else 0.0) for q, role, lab in vars_])
            for tlabel, vars_ in cls.terminal_spec]


def _interface_templates(cls):
    """The interface of a library class, built and checked once, the way
    ``Terminal(...)``, ``set_terminals`` and ``set_states`` build and check it
    for each instance; ``_CUSTOM`` where the class redefines those methods."""
    if (cls.set_terminals is not Component.set_terminals
            or cls.set_states is not Component.set_states):
        _INTERFACE[cls] = _CUSTOM
        return _CUSTOM
    probe = Component.__new__(cls)
    Component.__init__(probe, "interface")
    try:
        Component.set_terminals(probe, *_spec_terminals(cls))
        Component.set_states(probe, *[Variable(q, "local", label=lab)
                                      for lab, q in cls.state_spec])
    except (TypeError, ValueError):
        # an ill-declared class: each instance builds (and fails) as it always did
        _INTERFACE[cls] = _CUSTOM
        return _CUSTOM
    templates = (tuple((t.label, tuple(SharedVariable.of(v) for v in t.variables))
                       for t in probe.terminals),
                 tuple(SharedVariable.of(v) for v in probe.states))
    _INTERFACE[cls] = templates
    return templates


def _recording(init):
    """``init`` that first keeps the arguments it was called with (the
    outermost constructor's, once) as ``_definition``: run-time parameters
    rebuild a component from them (:mod:`softflow.solve.params`)."""
    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        # getattr, not self.__dict__: reading __dict__ would make every
        # instance build its attribute dict (time, and one more object to collect)
        if getattr(self, "_definition", None) is None:
            self._definition = (args, kwargs)
        init(self, *args, **kwargs)
    return __init__


class Affine:
    """F[i, e] = sum_k coef[i, e, k] V[i, k] - offset(t) while valid(V) holds.

    coef : (n, n_eq, n_vars) constant array
    offset : callable t -> float or 1-D array of n·n_eq values (row order), or None
    valid : callable V -> bool, or None for always; where it is False the
        kernel evaluates the group instead
    """

    def __init__(self, coef, offset=None, valid=None):
        self.coef, self.offset, self.valid = np.asarray(coef, dtype=float), offset, valid
