"""fonsim's object model (Variable, Terminal, Component, System, Simulation)
as thin layers over softflow's own classes.
"""
from __future__ import annotations

import functools
import math
import warnings

import numpy as np

from ..network import Component as _Component
from ..network import NetworkError
from ..network import System as _System
from ..network import Terminal as _Terminal
from ..network import Variable as _Variable
from ..solve import Simulation as _Simulation
from .constants.norm import pressure_atmospheric

_ROLES = {"across": "across", "through": "through", "local": "local", "free": "local"}


class Variable(_Variable):
    """fonsim's ``Variable(key, orientation, terminal=None, label=None,
    initial_value=0, range=(-inf, inf))``: a softflow Variable whose quantity is
    ``key`` and whose role is ``orientation`` ('free' is 'local').

    ``range`` (min, max) is checked on the results: a run whose solution leaves
    it warns, naming the variable (softflow's Newton does not clip to it; it
    refuses non-positive pressures on its own).
    """

    __slots__ = ("range",)

    def __init__(self, key, orientation, terminal=None, label=None, initial_value=None,
                 range=(-math.inf, math.inf)):
        if orientation not in _ROLES:
            raise ValueError(f"fons.Variable {label or key!r}: orientation must be 'across', "
                             f"'through' or 'local' ('free'), got {orientation!r}")
        role = _ROLES[orientation]
        if initial_value is None and role == "local":
            initial_value = 0.0   # fonsim's default for states
        super().__init__(key, role, label=None if label in (None, "None") else label,
                         initial_value=initial_value)
        try:
            lo, hi = (float(x) for x in range)
        except (TypeError, ValueError):
            raise ValueError(f"fons.Variable {self.label!r}: range must be a pair (min, max), "
                             f"got {range!r}") from None
        if not lo <= hi:
            raise ValueError(f"fons.Variable {self.label!r}: range min {lo} > max {hi}")
        self.range = (lo, hi)

    def copy(self):
        new = Variable.__new__(Variable)
        for name in _Variable.__slots__ + Variable.__slots__:
            setattr(new, name, getattr(self, name))
        return new

    @property
    def key(self):
        return self.quantity

    @property
    def orientation(self):
        return self.role


def _ranges_of(variables, where):
    return {(where, v.label): v.range for v in variables
            if isinstance(v, Variable) and v.range != (-math.inf, math.inf)}


class Terminal(_Terminal):
    """fonsim's ``Terminal(label, variables, variable_labels={})``:
    ``variable_labels`` maps a key to the label of that variable at this
    terminal, e.g. ``Terminal('a', terminal_fluidic, {'pressure': 'p0',
    'massflow': 'mf0'})``."""

    def __init__(self, label, variables, variable_labels=None):
        variables = [v.copy() for v in variables]
        for key, new_label in (variable_labels or {}).items():
            match = [v for v in variables if v.quantity == key]
            if not match:
                raise ValueError(f"fons.Terminal {label!r}: variable_labels names key {key!r}, "
                                 f"but the terminal's variables are "
                                 f"{[v.quantity for v in variables]}")
            for v in match:
                v.label = new_label
        super().__init__(label, variables)

    def get_variables(self, orientation=None):
        """The terminal's variables, or those with role ``orientation``."""
        return [v for v in self.variables
                if orientation is None or v.role == _ROLES.get(orientation, orientation)]

    def get_variable(self, key):
        """The variable of quantity ``key``, or None."""
        return next((v for v in self.variables if v.quantity == key), None)

    __call__ = get_variable


#: fonsim's standard fluid port: absolute pressure (across, starting at fonsim's
#: 1 atm, >= 0) and mass flow (through)
terminal_fluidic = [Variable("pressure", "across", initial_value=pressure_atmospheric,
                             range=(0, math.inf)),
                    Variable("massflow", "through", initial_value=0.0)]


class ResultsMixin:
    """fonsim's result getters on a softflow component: ``get``, ``get_all``
    and ``get_state``."""

    def get(self, variable_key, terminal_label=None, *, as_quantity=False):
        """Values of a variable over the last run. Without ``terminal_label``,
        a variable found at several terminals is taken at the first (as fonsim)."""
        if terminal_label is None:
            holders = [t.label for t in self.terminals
                       if any(variable_key in (v.label, v.quantity) for v in t.variables)]
            if len(holders) > 1:
                terminal_label = holders[0]
        return _Component.get(self, variable_key, terminal_label, as_quantity=as_quantity)

    def get_all(self, variable_key, terminal_label=None):
        """(values, Terminal) of a terminal variable over the last run."""
        values = self.get(variable_key, terminal_label)
        if terminal_label is not None:
            return values, self.get_terminal(terminal_label)
        term = next((t for t in self.terminals
                     if any(variable_key in (v.label, v.quantity) for v in t.variables)), None)
        return values, term

    def get_state(self, label):
        """Values of a state (by label or quantity) or of a derived output such as
        an actuator's 'volume' over the last run."""
        names = {s.label for s in self.states} | {s.quantity for s in self.states}
        if label not in names and label not in self.outputs():
            raise KeyError(f"{self.describe()} has no state {label!r}; its states are "
                           f"{[s.label for s in self.states]}, its outputs "
                           f"{list(self.outputs())}")
        return _Component.get(self, label)


def _values_only(func):
    """``func`` without the analytic Jacobian fonsim lets it return next to its
    values (softflow takes finite differences of ``auto`` functions)."""
    @functools.wraps(func)
    def call(*args):
        out = func(*args)
        if (type(out) is tuple and len(out) == 2 and isinstance(out[1], (list, dict))
                and isinstance(out[0], (np.ndarray, list, dict))):
            return out[0]
        return out
    return call


class Component(ResultsMixin, _Component):
    """fonsim's Component: declare terminals and states, then give
    ``self.evaluate = self.auto(f)`` and ``self.update_state =
    self.auto_state(g)`` (or use them as decorators) with arguments named
    after the variables' labels; ``t``/``dt`` are the time and the step.

    A Jacobian returned next to the values (fonsim's optional second return
    value) is dropped: softflow differentiates ``auto`` functions itself.
    fonsim's array form of ``evaluate``/``update_state`` (indices into
    ``arguments``) is not supported.
    """

    def __init__(self, label=None):
        for name in ("evaluate", "update_state"):
            if callable(getattr(type(self), name, None)):
                raise TypeError(
                    f"{type(self).__name__}: defines {name}(self, ...) in fonsim's array form; "
                    f"softflow.fons takes the labelled form instead: in __init__, "
                    f"self.{name} = self.{'auto' if name == 'evaluate' else 'auto_state'}"
                    f"(function) with the function's arguments named after the variables")
        super().__init__(label)
        self.ranges = {}

    def set_terminals(self, *terminals):
        if len(terminals) == 1 and isinstance(terminals[0], (list, tuple)):
            terminals = tuple(terminals[0])
        super().set_terminals(*terminals)
        for t in self.terminals:
            self.ranges.update(_ranges_of(t.variables, t.label))

    def set_states(self, *variables):
        super().set_states(*variables)
        flat = [v for item in variables for v in (item if isinstance(item, (list, tuple))
                                                  else [item])]
        self.ranges.update(_ranges_of(flat, None))

    def set_arguments(self, *arguments):
        raise NotImplementedError(f"{self.describe()}: set_arguments orders fonsim's argument "
                                  "array, which softflow does not use; name the variables in "
                                  "the auto/auto_state functions instead")

    def auto(self, func):
        af = super().auto(func)
        af.func = _values_only(func)
        return af

    def auto_state(self, func):
        af = super().auto_state(func)
        af.func = _values_only(func)
        return af

    def get_terminal(self, terminallabel=None):
        """The terminal with this label, or without one the first terminal not yet
        connected (None when all are)."""
        if terminallabel is not None:
            return super().get_terminal(terminallabel)
        system = getattr(self, "_fons_system", None)
        for t in self.terminals:
            if system is None or not system.is_connected(t):
                return t
        return None


class System(_System):
    """fonsim's System: ``connect(a, b, c)`` joins a-b and then b-c (a chain, as
    fonsim does; softflow's own ``System.connect`` joins all into one node,
    which here is ``connect_common``)."""

    def __init__(self, label=None):
        super().__init__("system" if label is None else label)

    def add(self, *components):
        super().add(*components)
        for c in self.components:
            c._fons_system = self
        return self

    def _resolve(self, spec, taken):
        # a FreeActuator's terminal 'b' is its terminal 'a' (one volume, one pressure)
        if isinstance(spec, tuple) and len(spec) == 2 and spec[1] == "b":
            comp = self._by_label.get(spec[0] if isinstance(spec[0], str)
                                      else getattr(spec[0], "label", None))
            if getattr(comp, "_terminal_aliases", None):
                spec = (comp.label, comp._terminal_aliases["b"])
        elif isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], _Component):
            spec = (spec[0].label, spec[1])
        return super()._resolve(spec, taken)

    def connect(self, *args):
        """Connect ``args`` in sequence: args[0]-args[1], args[1]-args[2], ...

        Each is a component label, a Component, a Terminal or a
        ``(label, terminal_label)`` pair; a label alone takes the component's
        first unconnected terminal (a one-terminal component's only one)."""
        if len(args) < 2:
            raise NetworkError("connect: give at least two components to connect")
        for a, b in zip(args, args[1:]):
            super().connect(a, b)
        return self

    def connect_common(self, *args):
        """Join all ``args`` in one node."""
        return super().connect(*args)

    def connect_two_components(self, component_a, component_b):
        return super().connect(component_a, component_b)

    def connect_two_terminals(self, terminal_a, terminal_b):
        return super().connect(terminal_a, terminal_b)

    def get_component_and_terminal(self, arg):
        """(Component, Terminal) that ``arg`` designates (see :meth:`connect`)."""
        label, k = self._resolve(arg, [])
        comp = self.get(label)
        return comp, comp.terminals[k]


_DISCRETIZATIONS = ("backward",)


class Simulation(_Simulation):
    """fonsim's ``Simulation(system, duration=10, step=(None, None), ...)`` on
    softflow's integrator.

    ``step`` a number: backward Euler at that fixed step (fonsim's scheme); a
    pair ``(min, max)`` or the default: softflow's adaptive BDF within those
    bounds (softflow's error control, rtol 1e-3, where fonsim adapts the step
    to its Newton convergence). ``discretization`` must be 'backward' (fonsim's
    default). ``relative_solving_tolerance``, ``minimum_solving_tolerance``,
    ``go_backwards_allowed`` and ``verbose`` are fonsim solver settings with no
    counterpart and are accepted as they are; ``max_steps`` stops a
    fixed-step run after that many steps. softflow's own options (``rtol``,
    ``method``, ...) may be given as keywords.
    """

    def __init__(self, system_to_simulate, duration=10, step=(None, None), step_min=None,
                 step_max=None, discretization="backward", relative_solving_tolerance=0.01,
                 minimum_solving_tolerance=1e-10, go_backwards_allowed=True, max_steps=0,
                 verbose=0, **options):
        if discretization not in _DISCRETIZATIONS:
            raise ValueError(f"fons.Simulation: discretization {discretization!r} is not "
                             f"supported; softflow integrates with backward Euler at a fixed "
                             f"step (step=dt) or adaptive BDF (step=(min, max)), both implicit")
        if isinstance(step, (tuple, list)) and tuple(step) == (None, None):
            step = None   # fonsim's default: adaptive, within step_min/step_max if given
        fixed = step is not None and not isinstance(step, (tuple, list))
        if max_steps and fixed:
            duration = min(float(duration), max_steps * float(step))
        elif max_steps:
            warnings.warn("fons.Simulation: max_steps applies to fixed steps only; the "
                          "adaptive run goes to the end of duration", stacklevel=2)
        _bind_pending_fluids(system_to_simulate)
        super().__init__(system_to_simulate, duration=duration, step=step, step_min=step_min,
                         step_max=step_max, **options)
        self.discretization = discretization
        self.verbose = verbose

    def run(self, *, raise_on_failure=True):
        result = super().run(raise_on_failure=raise_on_failure)
        _check_ranges(self.system, result)
        return result


def _bind_pending_fluids(system):
    """Give components made without a fluid (fonsim's CheckValve) the fluid of
    the components they are connected to."""
    pending = [c for c in system.components if getattr(c, "_fluid_pending", False)]
    while pending:
        progress = False
        for node in system.nodes():
            comps = [t.component for t in node.terminals]
            fluid = next((getattr(c, "fluid", None) for c in comps
                          if not getattr(c, "_fluid_pending", False)
                          and getattr(c, "fluid", None) is not None), None)
            for c in comps:
                if fluid is not None and getattr(c, "_fluid_pending", False):
                    c._bind_fluid(fluid)
                    progress = True
        pending = [c for c in pending if c._fluid_pending]
        if pending and not progress:
            raise NetworkError(f"{pending[0].describe()}: no fluid given and none found among "
                               f"the components connected to it; give fluid=fons.air (or "
                               f"another fluid)")


def _check_ranges(system, result):
    for comp in system.components:
        for (term, label), (lo, hi) in getattr(comp, "ranges", {}).items():
            values = result.get(comp.label, label, terminal=term)
            bad = np.flatnonzero((values < lo) | (values > hi))
            if bad.size:
                i = int(bad[0])
                warnings.warn(f"{comp.describe()}: variable {label!r} left its range "
                              f"({lo:g}, {hi:g}) at t = {result.times[i]:.6g} s (value "
                              f"{values[i]:.6g}); softflow does not clip to fonsim ranges",
                              RuntimeWarning, stacklevel=3)
