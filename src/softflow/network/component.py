"""The Component base class: the paper's interface for user-written components.

A user component declares terminals and states, then assigns ``evaluate``
(algebraic residuals) and, if it has states, either ``update_state`` (the
paper's way: the states at the end of a step of length dt, which must be
affine in dt, ``mass + mf * dt``) or ``state_rates`` (their time derivatives,
``{'mass': mf}``; softflow's own components work this way). Wrapping them in
:meth:`Component.auto`, :meth:`Component.auto_state` or
:meth:`Component.auto_rates` tells softflow to obtain their derivatives by
finite differences. Library components (see ``softflow.components``) instead
evaluate all instances of a class in one vectorized call with analytic
Jacobians.
"""
from __future__ import annotations

import collections
import inspect
import weakref
from typing import TYPE_CHECKING, Any, Callable, Iterable

from .variable import Terminal, Variable

if TYPE_CHECKING:
    from .._typing import Array, Quantity
    from ..solve.result import Result

#: The last Result a Simulation computed for each component, for the FONS
#: paper's ``system.get(label).get(name)``: kept here, weakly keyed by the
#: component, so that running a Simulation never writes into the System. The
#: values are weak references too: a Result refers to its compiled network and
#: so to the components, and a strong value would keep its own key (every
#: component ever run, its Simulation and its last Result) alive for good
#: (~120 objects and the result arrays per Simulation built and dropped).
_LAST_RESULT: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()

#: The last results are also held here, so that a Simulation built, run and
#: dropped in one line (``sf.Simulation(system, ...).run()``) leaves its result
#: readable through the System; an older one lives as long as its Simulation
#: (``sim.result``) or the Result itself is referenced.
RECENT_RESULTS = 8
_RECENT: "collections.deque" = collections.deque(maxlen=RECENT_RESULTS)


def remember_result(components: Iterable[Component], result: Result) -> None:
    """Make ``result`` the one :meth:`Component.get` reads for ``components``."""
    ref = weakref.ref(result)
    for c in components:
        _LAST_RESULT[c] = ref
    _RECENT.append(result)


class AutoFunction:
    """A user function whose derivatives softflow approximates by finite differences.

    Arguments are matched to the component's variables by name (a variable's
    label, or ``label_terminal`` when the label occurs at several terminals);
    ``t`` is the time and, for ``update_state``, ``dt`` is the step.
    """

    def __init__(self, func: Callable[..., Any], kind: str) -> None:
        if not callable(func):
            raise TypeError(f"auto: expected a function, got {func!r}")
        self.func = func
        self.kind = kind
        params = inspect.signature(func).parameters.values()
        for p in params:
            if p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD):
                raise TypeError(
                    f"{kind} function {func.__name__!r}: *args/**kwargs are not "
                    "supported; name each variable it needs")
        self.argnames = tuple(p.name for p in params)

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.func(*args, **kwargs)

    def __repr__(self) -> str:
        return f"<{self.kind} {self.func.__name__}{self.argnames}>"


class Component:
    """Base class of every network component.

    Parameters
    ----------
    label : str
        Unique name of the component within its System.
    """

    #: True for library classes that evaluate all their instances at once.
    vectorized = False

    def __init__(self, label: str) -> None:
        if not isinstance(label, str) or not label:
            raise ValueError(
                f"{type(self).__name__}: label must be a non-empty string, got {label!r}")
        self.label = label
        self.terminals: list[Terminal] = []
        self.states: list[Variable] = []
        self.locals: list[Variable] = []
        self.evaluate: Callable[..., Any] | None = None
        self.update_state: Callable[..., Any] | None = None
        self.state_rates: Callable[..., Any] | None = None

    # -- declaring the interface -------------------------------------------------
    def set_terminals(self, *terminals: Terminal | list[Terminal] | tuple[Terminal, ...]) -> None:
        """Declare the component's terminals (Terminal objects), in order."""
        if len(terminals) == 1 and isinstance(terminals[0], (list, tuple)):
            terminals = tuple(terminals[0])
        terms: tuple[Terminal, ...] = terminals  # type: ignore[assignment]  # checked below
        for t in terms:
            if not isinstance(t, Terminal):
                raise TypeError(f"{self.describe()}: set_terminals expects Terminal objects, got {t!r}")
        labels = [t.label for t in terms]
        if len(set(labels)) != len(labels):
            raise ValueError(f"{self.describe()}: duplicate terminal labels {labels}")
        for t in terms:
            t.component = self
        self.terminals = list(terms)

    def set_states(self, *variables: Variable | list[Variable] | tuple[Variable, ...]) -> None:
        """Declare state variables, integrated in time by ``update_state``."""
        self.states = [self._check_local(v, "set_states") for v in _flatten(variables)]

    def set_locals(self, *variables: Variable | list[Variable] | tuple[Variable, ...]) -> None:
        """Declare algebraic local unknowns (each adds one equation to ``evaluate``)."""
        self.locals = [self._check_local(v, "set_locals") for v in _flatten(variables)]

    def _check_local(self, v: Variable, where: str) -> Variable:
        if not isinstance(v, Variable):
            raise TypeError(f"{self.describe()}: {where} expects Variable objects, got {v!r}")
        if v.role != "local":
            raise ValueError(f"{self.describe()}: {where} got variable {v.label!r} with role "
                             f"{v.role!r}; it must be 'local'")
        return v.copy()

    def auto(self, func: Callable[..., Any]) -> AutoFunction:
        """Wrap an ``evaluate(t, <variables>...)`` function; derivatives by finite differences."""
        return AutoFunction(func, "evaluate")

    def auto_state(self, func: Callable[..., Any]) -> AutoFunction:
        """Wrap an ``update_state(dt, <variables>...)`` function returning
        ``{state_label: new_value}``; derivatives by finite differences."""
        return AutoFunction(func, "update_state")

    def auto_rates(self, func: Callable[..., Any]) -> AutoFunction:
        """Wrap a ``state_rates(<variables>...)`` function returning
        ``{state_label: d(state)/dt}`` (e.g. ``{'mass': mf}``), the rate form of
        ``update_state``: every stepper then discretizes it itself. Derivatives
        by finite differences. Rates may use the component's variables, not
        its states (nor the time)."""
        return AutoFunction(func, "state_rates")

    # -- introspection --------------------------------------------------------------
    def describe(self) -> str:
        return f"{type(self).__name__} {self.label!r}"

    def get_terminal(self, label: str) -> Terminal:
        for t in self.terminals:
            if t.label == label:
                return t
        raise KeyError(f"{self.describe()} has no terminal {label!r}; "
                       f"its terminals are {[t.label for t in self.terminals]}")

    def interface_variables(self) -> list[tuple[str | None, Variable]]:
        """(terminal_label or None, Variable) for every algebraic variable, in order:
        terminal variables first, then locals. This is the order of V in kernels."""
        out: list[tuple[str | None, Variable]] = [
            (t.label, v) for t in self.terminals for v in t.variables]
        out += [(None, v) for v in self.locals]
        return out

    def variable_names(self) -> tuple[list[str], list[str]]:
        """Names by which evaluate/update_state arguments address each variable.

        Returns (names of interface variables, names of states)."""
        iface = self.interface_variables()
        counts: dict[str, int] = {}
        for _, v in iface:
            counts[v.label] = counts.get(v.label, 0) + 1
        names = [v.label if counts[v.label] == 1 else f"{v.label}_{term}"
                 for term, v in iface]
        return names, [s.label for s in self.states]

    @property
    def n_equations(self) -> int:
        """Equations the component must provide: one per through variable and local."""
        return sum(len(t.through) for t in self.terminals) + len(self.locals)

    def breakpoints(self) -> Iterable[float]:
        """Times at which this component's inputs are discontinuous (for the integrator)."""
        return ()

    def outputs(self) -> dict[str, Callable[..., Array]]:
        """Derived result quantities: {name: function(get) -> array}; see Result.get."""
        return {}

    # -- results ------------------------------------------------------------------------
    def get(self, name: str, terminal: str | None = None, *,
            as_quantity: bool = False) -> Array | Quantity:
        """Values of a variable over the last simulation run, as a NumPy array.

        ``name`` is a variable label, a quantity name (``'pressure'``) or a state;
        give ``terminal`` when the name occurs at several terminals. The last
        run is the last ``Simulation.run()`` of a System holding this component
        (softflow keeps that link itself; the component is not changed by a
        run, and a pickled or copied component has no results). The link does
        not keep that Result alive: it lasts while the Simulation
        (``sim.result``) or the Result is referenced, or for the next
        :data:`RECENT_RESULTS` runs otherwise.
        """
        ref = _LAST_RESULT.get(self)
        if ref is None:
            raise RuntimeError(f"{self.describe()}: no results yet; run a Simulation first")
        result = ref()
        if result is None:
            raise RuntimeError(
                f"{self.describe()}: its last result is no longer held (the Simulation "
                f"that ran it and its Result were dropped, and {RECENT_RESULTS} runs or "
                "more came after it); keep the Simulation (sim.result) or the Result that "
                "run() returns")
        return result.get(self.label, name, terminal=terminal, as_quantity=as_quantity)

    def __repr__(self) -> str:
        return f"<{self.describe()}>"


def _flatten(items: Iterable[Any]) -> list[Any]:
    out: list[Any] = []
    for it in items:
        if isinstance(it, (list, tuple)):
            out.extend(it)
        else:
            out.append(it)
    return out
