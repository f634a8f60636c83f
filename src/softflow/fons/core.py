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
from ..network.component import _LAST_RESULT, AutoFunction
from ..solve import Simulation as _Simulation
from .constants.norm import pressure_atmospheric

_ROLES = {"across": "across", "through": "through", "local": "local", "free": "local"}


class _FonsimNames(_Variable):
    """A softflow Variable under fonsim's attribute names: ``key`` (its
    quantity) and ``orientation`` (its role)."""

    __slots__ = ()

    @property
    def key(self):
        return self.quantity

    @property
    def orientation(self):
        return self.role


class Variable(_FonsimNames):
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

    @property
    def variables_across(self):
        """fonsim's ``{key: Variable}`` of the terminal's across variables."""
        return {v.quantity: _fonsim_view(v, self) for v in self.variables
                if v.role == "across"}

    @property
    def variables_through(self):
        """fonsim's ``{key: Variable}`` of the terminal's through variables."""
        return {v.quantity: _fonsim_view(v, self) for v in self.variables
                if v.role == "through"}

    @property
    def isconnected(self):
        """Whether the terminal is connected in the System its component is in
        (an attribute, as fonsim's)."""
        system = getattr(self.component, "_fons_system", None)
        return system is not None and system.is_connected(self)


#: fonsim's standard fluid port: absolute pressure (across, starting at fonsim's
#: 1 atm, >= 0) and mass flow (through)
terminal_fluidic = [Variable("pressure", "across", initial_value=pressure_atmospheric,
                             range=(0, math.inf)),
                    Variable("massflow", "through", initial_value=0.0)]


class ResultsMixin:
    """fonsim's view of a softflow component: its result getters (``get``,
    ``get_all``, ``get_state``, by fonsim's variable keys or labels), its
    ``arguments`` in fonsim's order with their ``argument_history`` and
    ``state_history``, and terminals with fonsim's ``variables_across`` /
    ``variables_through``.

    A library class lists its variables as fonsim has them in
    ``fonsim_arguments`` ((terminal, key, fonsim's label) in fonsim's order)
    and its states' fonsim labels in ``fonsim_states`` ({label: state}).
    """

    #: (terminal label, variable key, fonsim's label) of each argument, in fonsim's
    #: order; None: every terminal's through variables, then its across ones
    fonsim_arguments = None
    #: fonsim's label of each state -> softflow's state label
    fonsim_states = {}

    # the terminals, as fons Terminals (fonsim's dict views); a library class's
    # own terminals are softflow's, turned into fons ones as they are set
    @property
    def terminals(self):
        return self.__dict__["_fons_terminals"]

    @terminals.setter
    def terminals(self, terms):
        for t in terms:
            if type(t) is _Terminal:
                t.__class__ = Terminal
        self.__dict__["_fons_terminals"] = terms

    # -- fonsim's names ---------------------------------------------------------------
    def _fonsim_arguments(self):
        """[(terminal label, key, label)] of the arguments, in fonsim's order."""
        order = getattr(self, "_fons_argument_order", None)
        if order is not None:
            return list(order)
        if self.fonsim_arguments is not None:
            return list(self.fonsim_arguments)
        return [(t.label, v.quantity, v.label) for t in self.terminals
                for role in ("through", "across") for v in t.variables if v.role == role]

    def _fonsim_label(self, name):
        """(key, terminal) of the argument fonsim labels ``name``, or None."""
        if self.fonsim_arguments is None:
            return None
        return next(((key, term) for term, key, label in self.fonsim_arguments
                     if label == name and label != "None"), None)

    @property
    def arguments(self):
        """The component's terminal variables in fonsim's order (its
        ``arguments``: a custom component's ``set_arguments`` order, else every
        terminal's through variables, then its across ones), as Variables with
        fonsim's keys and labels; each has ``terminal``, its terminal's label."""
        out = []
        for term, key, label in self._fonsim_arguments():
            v = _ArgumentView(key, _role_of(self, term, key), label=label)
            v.terminal = term
            out.append(v)
        return out

    @property
    def nb_arguments(self):
        return len(self._fonsim_arguments())

    @property
    def argument_history(self):
        """(steps, arguments) array: each argument (:attr:`arguments`) over the
        last run, the initial point first."""
        cols = [self._values(key, term) for term, key, _ in self._fonsim_arguments()]
        return np.column_stack(cols) if cols else np.empty((len(self._run_times()), 0))

    @property
    def state_history(self):
        """(steps, states) array: each state over the last run."""
        cols = [_Component.get(self, st.label) for st in self.states]
        return np.column_stack(cols) if cols else np.empty((len(self._run_times()), 0))

    def _run_times(self):
        return _last_result(self).times

    def _values(self, key, terminal):
        """A terminal variable over the last run (a hook: FreeActuator's 'b')."""
        return _Component.get(self, key, terminal)

    # -- getters ----------------------------------------------------------------------
    def get(self, variable_key, terminal_label=None, *, as_quantity=False):
        """Values of a variable over the last run, by fonsim's key ('pressure',
        'massflow'), fonsim's label of it ('p0', 'mf1': the variable at its
        terminal) or softflow's label. Without ``terminal_label``, a variable
        found at several terminals is taken at the first (as fonsim)."""
        found = self._fonsim_label(variable_key)
        if found is not None and terminal_label in (None, found[1]):
            variable_key, terminal_label = found
        elif terminal_label is None:
            if variable_key in self.fonsim_states:
                state = self.fonsim_states[variable_key]
                raise KeyError(
                    f"{self.describe()}: {variable_key!r} is fonsim's label of its state "
                    f"{state!r}: use get_state({variable_key!r}) (fonsim 0.6's get() matches "
                    f"{variable_key!r} by its first letters to a terminal variable instead; "
                    f"softflow.fons matches names exactly)")
            holders = [t.label for t in self.terminals
                       if any(variable_key in (v.label, v.quantity) for v in t.variables)]
            if len(holders) > 1:
                terminal_label = holders[0]
        if not as_quantity and terminal_label is not None and any(
                variable_key == v.quantity for t in self.terminals for v in t.variables):
            return self._values(variable_key, terminal_label)
        return _Component.get(self, variable_key, terminal_label, as_quantity=as_quantity)

    def get_all(self, variable_key, terminal_label=None):
        """(values, Terminal) of a terminal variable over the last run."""
        if terminal_label is None:
            found = self._fonsim_label(variable_key)
            if found is not None:
                variable_key, terminal_label = found
        values = self.get(variable_key, terminal_label)
        if terminal_label is not None:
            return values, self._terminal_of(terminal_label)
        term = next((t for t in self.terminals
                     if any(variable_key in (v.label, v.quantity) for v in t.variables)), None)
        return values, term

    def _terminal_of(self, label):
        return self.get_terminal(label)

    def get_state(self, label):
        """Values of a state (by fonsim's or softflow's label, or its key) or of
        a derived output such as an actuator's 'volume' over the last run."""
        label = self.fonsim_states.get(label, label)
        names = {s.label for s in self.states} | {s.quantity for s in self.states}
        if label not in names and label not in self.outputs():
            raise KeyError(f"{self.describe()} has no state {label!r}; its states are "
                           f"{[s.label for s in self.states]}, its outputs "
                           f"{list(self.outputs())}")
        return _Component.get(self, label)


class _ArgumentView(_FonsimNames):
    """A Variable as fonsim lists it among a component's ``arguments``: its
    key, orientation and label, and the label of its ``terminal``."""

    __slots__ = ("terminal",)


def _fonsim_view(v, terminal):
    """``v`` with fonsim's attributes (``key``, ``orientation``): itself where it
    has them (a fons Variable), else a copy (a library component's own)."""
    if hasattr(v, "key"):
        return v
    view = _ArgumentView(v.quantity, v.role, label=v.label, initial_value=v.initial_value)
    view.terminal = terminal.label
    return view


def _last_result(comp):
    """The Result of the last run of a System holding ``comp``."""
    ref = _LAST_RESULT.get(comp)
    result = None if ref is None else ref()
    if result is None:
        raise RuntimeError(f"{comp.describe()}: no results; run a Simulation first (and keep "
                           f"it)")
    return result


def _role_of(comp, term, key):
    for t in comp.terminals:
        if t.label == term:
            for v in t.variables:
                if v.quantity == key:
                    return v.role
    return "across" if key == "pressure" else "through"


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
    # the user's own function, which softflow.solve.usercompile compiles
    # where it returns the values alone (a tuple with a Jacobian does not
    # pass the kernel's checks there: the call then runs this wrapper)
    call._softflow_values_of = func  # type: ignore[attr-defined]
    return call


class Component(ResultsMixin, _Component):
    """fonsim's Component: declare terminals and states, then give the
    equations in either of fonsim's two forms.

    - Labelled: ``self.evaluate = self.auto(f)`` and ``self.update_state =
      self.auto_state(g)`` (or as decorators), with arguments named after the
      variables' labels; ``t``/``dt`` are the time and the step. A Jacobian
      returned next to the values (fonsim's optional second return value) is
      dropped: softflow differentiates ``auto`` functions itself.
    - Array form: methods ``evaluate(self, values, jacobian_state,
      jacobian_arguments, state, arguments, elapsed_time)`` and
      ``update_state(self, state_new, jacobian, state, arguments, dt)`` that
      fill ``values`` (``self.nb_equations`` residuals) and ``state_new`` in
      place from ``arguments``, the terminal variables in the order of
      :attr:`arguments` (:meth:`set_arguments`, else each terminal's through
      variables, then its across ones). The Jacobians they fill are not read:
      softflow takes finite differences of the values.
    """

    def __init__(self, label=None):
        array_form = {name: getattr(self, name) for name in ("evaluate", "update_state")
                      if callable(getattr(type(self), name, None))}
        super().__init__(label)
        self.ranges = {}
        self._fons_argument_order = None
        if "evaluate" in array_form:
            self.evaluate = _ArrayEvaluate(self, array_form["evaluate"])
        if "update_state" in array_form:
            self.update_state = _ArrayUpdate(self, array_form["update_state"])

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
        """Order the component's ``arguments`` (what an array-form ``evaluate``
        and ``update_state`` receive, and the columns of ``argument_history``):
        terminal variables (``terminal('pressure')``) or their labels."""
        if len(arguments) == 1 and isinstance(arguments[0], (list, tuple)):
            arguments = tuple(arguments[0])
        order = []
        for a in arguments:
            found = None
            for t in self.terminals:
                for v in t.variables:
                    if v is a or (isinstance(a, str) and a == v.label):
                        found = (t.label, v.quantity, v.label)
            if found is None:
                labels = [v.label for t in self.terminals for v in t.variables]
                raise ValueError(f"{self.describe()}: set_arguments got {a!r}, which is none "
                                 f"of its terminals' variables (labels {labels}); set the "
                                 f"terminals first and give their variables "
                                 f"(terminal('pressure')) or labels")
            order.append(found)
        self._fons_argument_order = order

    @property
    def nb_equations(self):
        """The equations the component gives: fonsim's count, which an
        array-form component sets; by default one per through variable and
        local variable (softflow's count)."""
        return self.__dict__.get("_fons_nb_equations", self.n_equations)

    @nb_equations.setter
    def nb_equations(self, n):
        self.__dict__["_fons_nb_equations"] = int(n)

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


class _ArrayForm(AutoFunction):
    """An array-form ``evaluate``/``update_state`` of a fons Component as the
    labelled function softflow calls: its arguments are the time (or step),
    the component's variables and its states, by name; it gathers the
    variables into fonsim's ``arguments`` array and calls the method."""

    #: softflow.solve.usercompile compiles ``method`` with an adaptor that
    #: makes these arrays as :attr:`func` does
    array_form = True

    def __init__(self, comp, method, kind):
        self.comp, self.method, self.kind = comp, method, kind

    @property
    def argnames(self):
        names, snames = self.comp.variable_names()
        return ("t" if self.kind == "evaluate" else "dt", *names, *snames)

    def _layout(self):
        """(positions of the arguments among the variables, number of variables,
        number of states, number of arguments)."""
        comp = self.comp
        iface = comp.interface_variables()
        index = {(term, v.quantity): k for k, (term, v) in enumerate(iface)}
        order = comp._fonsim_arguments()
        try:
            picks = np.array([index[(term, key)] for term, key, _ in order], dtype=int)
        except KeyError as err:
            raise ValueError(f"{comp.describe()}: its argument {err.args[0]} is not one of "
                             f"its variables") from None
        return picks, len(iface), len(comp.states), len(order)

    def __call__(self, *args):
        return self.func(*args)

    @property
    def func(self):
        picks, nv, ns, na = self._layout()
        comp, method = self.comp, self.method
        if self.kind == "evaluate":
            neq = comp.nb_equations

            def evaluate(t, *values):
                v = np.asarray(values[:nv], dtype=float)
                out = np.zeros(neq)
                method(out, np.zeros((neq, ns)), np.zeros((neq, na)),
                       np.asarray(values[nv:], dtype=float), v[picks], t)
                return out
            return evaluate

        def update_state(dt, *values):
            v = np.asarray(values[:nv], dtype=float)
            new = np.zeros(ns)
            method(new, np.zeros((ns, na)), np.asarray(values[nv:], dtype=float), v[picks],
                   dt)
            return new
        return update_state

    def __repr__(self):
        return f"<fonsim array-form {self.kind} of {self.comp.describe()}>"


class _ArrayEvaluate(_ArrayForm):
    def __init__(self, comp, method):
        super().__init__(comp, method, "evaluate")


class _ArrayUpdate(_ArrayForm):
    def __init__(self, comp, method):
        super().__init__(comp, method, "update_state")


class _Nodes(list):
    """fonsim's ``System.nodes`` (a list attribute) that is also softflow's
    ``System.nodes()`` (a method): both spellings give the nodes."""

    def __call__(self):
        return list(self)


class System(_System):
    """fonsim's System: ``connect(a, b, c)`` joins a-b and then b-c (a chain, as
    fonsim does; softflow's own ``System.connect`` joins all into one node,
    which here is ``connect_common``). ``nodes`` is a list, as in fonsim (and
    callable, as softflow's method)."""

    def __init__(self, label=None):
        super().__init__("system" if label is None else label)
        # fonsim's nodes, where a FreeActuator's terminal 'b' is its own (softflow
        # joins it to 'a'): a union-find over (label, terminal label)
        self._fons_parent = {}
        self._fons_connected = set()

    @property
    def nodes(self):
        return _Nodes(_System.nodes(self))

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

    # -- fonsim's nodes (FreeActuator's terminal 'b' apart) ----------------------------
    def _fonsim_key(self, spec):
        """(label, terminal label) of ``spec`` as fonsim resolves it: a
        FreeActuator named without a terminal takes 'a', then 'b'."""
        if isinstance(spec, _Component):
            spec = spec.label
        if isinstance(spec, tuple) and len(spec) == 2:
            label = spec[0] if isinstance(spec[0], str) else getattr(spec[0], "label", None)
            return (label, spec[1])
        if isinstance(spec, _Terminal) and spec.component is not None:
            return (spec.component.label, spec.label)
        comp = self._by_label.get(spec) if isinstance(spec, str) else None
        if comp is not None and getattr(comp, "_terminal_aliases", None):
            for term in ("a", "b"):
                if (comp.label, term) not in self._fons_connected:
                    return (comp.label, term)
            return (comp.label, "a")
        return None

    def _fons_find(self, key):
        parent = self._fons_parent
        parent.setdefault(key, key)
        while parent[key] != key:
            parent[key] = parent[parent[key]]
            key = parent[key]
        return key

    def _fons_join(self, a, b):
        keys, taken = [], []
        for spec in (a, b):
            key = self._fonsim_key(spec)
            if key is None:          # as softflow resolves it (first unconnected, ...)
                try:
                    found = self._resolve(spec, taken)
                except (NetworkError, KeyError, TypeError):
                    return           # (softflow's connect says what is wrong)
                taken.append(found)
                key = (found[0], self._by_label[found[0]].terminals[found[1]].label)
            keys.append(key)
        ka, kb = keys
        ra, rb = self._fons_find(ka), self._fons_find(kb)
        if ra != rb:
            self._fons_parent[rb] = ra
        self._fons_connected.update((ka, kb))

    def fonsim_node_of(self, label, terminal):
        """The (label, terminal label) of every terminal in fonsim's node of
        ``(label, terminal)`` (a FreeActuator's 'a' and 'b' apart), itself
        included."""
        root = self._fons_find((label, terminal))
        return [k for k in list(self._fons_parent) if self._fons_find(k) == root]

    def fonsim_node_count(self):
        """The number of fonsim's nodes: every terminal's node (an unconnected
        terminal its own), a FreeActuator's terminal 'b' apart from its 'a'."""
        keys = [(c.label, t.label) for c in self.components for t in c.terminals]
        keys += [(c.label, "b") for c in self.components
                 if getattr(c, "_terminal_aliases", None)]
        return len({self._fons_find(k) if k in self._fons_parent else k for k in keys})

    def connect(self, *args):
        """Connect ``args`` in sequence: args[0]-args[1], args[1]-args[2], ...

        Each is a component label, a Component, a Terminal or a
        ``(label, terminal_label)`` pair; a label alone takes the component's
        first unconnected terminal (a one-terminal component's only one)."""
        if len(args) < 2:
            raise NetworkError("connect: give at least two components to connect")
        for a, b in zip(args, args[1:]):
            # (fonsim's key first: it looks at what was connected before)
            self._fons_join(a, b)
            super().connect(a, b)
        return self

    def connect_common(self, *args):
        """Join all ``args`` in one node."""
        for a in args[1:]:
            self._fons_join(args[0], a)
        return super().connect(*args)

    def connect_two_components(self, component_a, component_b):
        return self.connect(component_a, component_b)

    def connect_two_terminals(self, terminal_a, terminal_b):
        return self.connect(terminal_a, terminal_b)

    def get_component_and_terminal(self, arg):
        """(Component, Terminal) that ``arg`` designates (see :meth:`connect`)."""
        label, k = self._resolve(arg, [])
        comp = self.get(label)
        return comp, comp.terminals[k]


_DISCRETIZATIONS = ("backward",)
_OTHER_DISCRETIZATIONS = {
    "forward": "forward Euler (explicit)",
    "tustin": "the trapezoidal rule (Tustin)",
}

#: fonsim's default step range, as fractions of the duration: (duration·1e-4,
#: duration·1e-2); a range given with one end only takes the other as fonsim
#: does: min = min(duration·1e-4, max·1e-2), max = max(duration·1e-2, 10·min)
STEP_MIN_FRACTION, STEP_MAX_FRACTION = 1e-4, 1e-2
#: softflow's rtol for fonsim's ``relative_solving_tolerance`` in an adaptive run:
#: fonsim's default 0.01 is softflow's default rtol, 1e-3
RTOL_PER_SOLVING_TOLERANCE = 0.1
#: ``step=None``: fonsim's fixed step, this fraction of the duration
FIXED_STEP_FRACTION = 1e-3


def fonsim_steps(duration, step=(None, None), step_min=None, step_max=None):
    """fonsim's step for ``Simulation(duration, step, step_min, step_max)``:
    ``('fixed', dt)`` or ``('adaptive', (min, max))`` [s].

    A number is a fixed step; None fonsim's fixed step, duration·1e-3; a pair
    ``(min, max)`` (the default ``(None, None)``) adaptive steps within it,
    a missing end as fonsim fills it (:data:`STEP_MIN_FRACTION`). ``step_min``
    or ``step_max`` given replace the pair (fonsim's deprecated spelling)."""
    duration = float(duration)
    if step_min is not None or step_max is not None:
        step = (step_min, step_max)
    if step is None:
        return "fixed", duration * FIXED_STEP_FRACTION
    if not isinstance(step, (tuple, list)):
        return "fixed", step
    if len(step) != 2:
        raise ValueError(f"fons.Simulation: step must be a number (fixed), None or a pair "
                         f"(min, max), got {step!r}")
    lo, hi = step
    lo = None if lo is None else float(lo)
    hi = None if hi is None else float(hi)
    if lo is None and hi is None:
        lo, hi = duration * STEP_MIN_FRACTION, duration * STEP_MAX_FRACTION
    elif lo is None:
        lo = min(duration * STEP_MIN_FRACTION, hi * 1e-2)
    elif hi is None:
        hi = max(duration * STEP_MAX_FRACTION, 10.0 * lo)
    return "adaptive", (lo, min(hi, duration))


class Simulation(_Simulation):
    """fonsim's ``Simulation(system, duration=10, step=(None, None), ...)`` on
    softflow's integrator.

    Steps as fonsim's (:func:`fonsim_steps`): ``step`` a number, backward
    Euler at that fixed step (fonsim's scheme); None, fixed at duration·1e-3;
    a pair ``(min, max)`` or the default, adaptive within those bounds
    (by default fonsim's (duration·1e-4, duration·1e-2)), softflow's BDF with
    its error control (rtol 1e-3) where fonsim adapts the step to its Newton
    iteration's convergence. ``discretization`` must be 'backward' (fonsim's
    default; 'forward' and 'tustin' are refused, naming what to use).
    ``relative_solving_tolerance`` is fonsim's Newton tolerance, which in
    fonsim steers the adaptive step (at a fixed step fonsim's Newton converges
    past it): an adaptive run here takes ``rtol`` = relative_solving_tolerance
    / 10 (fonsim's default 0.01: softflow's default rtol 1e-3) unless
    ``rtol=`` is given; softflow's Newton converges to its own tolerance.
    ``minimum_solving_tolerance`` (fonsim's absolute floor),
    ``go_backwards_allowed`` and ``verbose`` are accepted as they are;
    ``max_steps`` stops a fixed-step run after that many steps. softflow's
    own options (``rtol``, ``method``, ...) may be given as keywords.

    After :meth:`run` (which returns None, as fonsim's; the Result is
    ``sim.result``): ``times``, ``state`` (steps x states) and ``phi`` (steps
    x arguments: every component's :attr:`~ResultsMixin.arguments`, in
    component order), as fonsim's.
    """

    def __init__(self, system_to_simulate, duration=10, step=(None, None), step_min=None,
                 step_max=None, discretization="backward", relative_solving_tolerance=0.01,
                 minimum_solving_tolerance=1e-10, go_backwards_allowed=True, max_steps=0,
                 verbose=0, **options):
        if discretization not in _DISCRETIZATIONS:
            what = _OTHER_DISCRETIZATIONS.get(discretization)
            said = f"fonsim's {what}" if what else "not one of fonsim's"
            raise ValueError(f"fons.Simulation: discretization={discretization!r} ({said}) is "
                             f"not supported: softflow integrates implicitly, with backward "
                             f"Euler at a fixed step (step=dt) or adaptive BDF (step=(min, "
                             f"max)); give discretization='backward' (fonsim's default)")
        for name, value in (("relative_solving_tolerance", relative_solving_tolerance),
                            ("minimum_solving_tolerance", minimum_solving_tolerance)):
            if not (isinstance(value, (int, float)) and value > 0):
                raise ValueError(f"fons.Simulation: {name} must be a number > 0, got {value!r}")
        if "adaptive" in options:
            raise TypeError("fons.Simulation: adaptive= is not taken; give the step as fonsim "
                            "does (step=dt fixed, step=(min, max) adaptive)")
        kind, value = fonsim_steps(duration, step, step_min, step_max)
        if kind == "fixed":
            step, lo, hi = value, None, None
        else:
            step, (lo, hi) = None, value
            lo = min(lo, hi)
        if kind == "adaptive" and "rtol" not in options:
            # fonsim's tolerance steers its step adaptation: here the error test's
            # (0.01, fonsim's default: softflow's rtol 1e-3)
            options["rtol"] = float(relative_solving_tolerance) * RTOL_PER_SOLVING_TOLERANCE
        if max_steps and kind == "fixed":
            duration = min(float(duration), max_steps * float(step))
        elif max_steps:
            warnings.warn("fons.Simulation: max_steps applies to fixed steps only; the "
                          "adaptive run goes to the end of duration", stacklevel=2)
        _bind_pending_fluids(system_to_simulate)
        super().__init__(system_to_simulate, duration=duration, step=step, step_min=lo,
                         step_max=hi, **options)
        self.discretization = discretization
        self.relative_solving_tolerance = float(relative_solving_tolerance)
        self.minimum_solving_tolerance = float(minimum_solving_tolerance)
        self.go_backwards_allowed = go_backwards_allowed
        self.verbose = verbose

    def run(self, *, raise_on_failure=True, **options):
        """Run the simulation; the results are in the components (``get``),
        ``sim.times``, ``sim.state``, ``sim.phi`` and ``sim.result``. Returns
        None, as fonsim's."""
        result = super().run(raise_on_failure=raise_on_failure, **options)
        _check_ranges(self.system, result)
        return None

    # -- fonsim's arrays ------------------------------------------------------------
    def _ran(self):
        if self.result is None:
            raise RuntimeError("fons.Simulation: it has not run; call sim.run() first")
        return self.result

    @property
    def state(self):
        """(steps, states) array: every component's states over the run, in
        component order (fonsim's ``sim.state``)."""
        self._ran()
        cols = [c.state_history for c in self.system.components if c.states]
        return np.hstack(cols) if cols else np.empty((len(self.times), 0))

    @property
    def phi(self):
        """(steps, arguments) array: every component's arguments over the run, in
        component order, each component's in its ``arguments`` order (fonsim's
        ``sim.phi``)."""
        self._ran()
        cols = [c.argument_history for c in self.system.components
                if hasattr(c, "argument_history")]
        return np.hstack(cols) if cols else np.empty((len(self.times), 0))

    def print_equations(self):
        """Print the network's equations, as fonsim's: at each node, its
        terminals' across variables equal and their through variables summing to
        zero, then each component's equations."""
        k = 0
        for node in self.system.nodes():
            terms = node.terminals
            if len(terms) < 2:
                continue
            for quantity in node.quantities("across"):
                held = [t for t in terms if any(v.quantity == quantity for v in t.across)]
                for a, b in zip(held, held[1:]):
                    print(f"eq {k}: {quantity}[{a.name}] - {quantity}[{b.name}] = 0")
                    k += 1
            for quantity in node.quantities("through"):
                held = [t.name for t in terms if any(v.quantity == quantity for v in t.through)]
                print(f"eq {k}: " + " + ".join(f"{quantity}[{n}]" for n in held) + " = 0")
                k += 1
        for comp in self.system.components:
            for i in range(comp.n_equations):
                print(f"eq {k}: {comp.label} equation {i} = 0")
                k += 1


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
