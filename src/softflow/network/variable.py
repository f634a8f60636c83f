"""Variables and terminals, the paper's vocabulary for a component's interface."""
from __future__ import annotations

from typing import TYPE_CHECKING, Iterable

from ..units import quantity_unit, to_si

if TYPE_CHECKING:
    from .._typing import Scalar
    from .component import Component

ROLES = ("across", "through", "local")


class Variable:
    """One scalar quantity of a component.

    Parameters
    ----------
    quantity : str
        Physical quantity, e.g. ``'pressure'``, ``'massflow'``, ``'mass'``.
        Terminals meeting at a node share one unknown per *across* quantity
        and conserve each *through* quantity.
    role : {'across', 'through', 'local'}
        ``across`` (potential, e.g. absolute pressure [Pa]), ``through``
        (flow into the component, e.g. mass flow [kg/s]) or ``local``
        (internal to the component: a state or an algebraic unknown).
    label : str, optional
        Name by which ``evaluate``/``update_state`` arguments and results
        refer to it; defaults to ``quantity``.
    initial_value : float or pint.Quantity, optional
        Starting value (SI) for the solver or, for a state, its value at t = 0.
    """

    __slots__ = ("quantity", "role", "label", "initial_value")

    def __init__(self, quantity: str, role: str, label: str | None = None,
                 initial_value: Scalar | None = None) -> None:
        if not isinstance(quantity, str) or not quantity:
            raise ValueError(f"Variable: quantity must be a non-empty string, got {quantity!r}")
        if role not in ROLES:
            raise ValueError(
                f"Variable {label or quantity!r}: role must be one of {ROLES}, got {role!r}"
            )
        self.quantity = quantity
        self.role = role
        self.label = label if label is not None else quantity
        if type(initial_value) is float:
            pass            # a plain SI float: nothing to convert or check
        elif initial_value is not None:
            unit = quantity_unit(quantity)
            if unit is not None:
                initial_value = to_si(initial_value, unit, name="initial_value",
                                      owner=f"Variable {self.label!r}")
            else:
                initial_value = to_si(initial_value, "", name="initial_value",
                                      owner=f"Variable {self.label!r} ({quantity})")
        self.initial_value: float | None = initial_value  # type: ignore[assignment]

    def copy(self) -> "Variable":
        new = _new_variable(Variable)
        new.quantity = self.quantity
        new.role = self.role
        new.label = self.label
        new.initial_value = self.initial_value
        return new

    def __repr__(self) -> str:
        return (f"Variable({self.quantity!r}, {self.role!r}, label={self.label!r}, "
                f"initial_value={self.initial_value!r})")


_new_variable = object.__new__


class SharedVariable(Variable):
    """A Variable that every instance of a library class shares (its interface,
    checked once per class): read-only. Copies (:meth:`Variable.copy`) are plain
    Variables; copying or deep-copying it gives itself, as for other immutable
    values."""

    __slots__ = ()

    @classmethod
    def of(cls, v: Variable) -> "SharedVariable":
        new = _new_variable(cls)
        for name in Variable.__slots__:
            object.__setattr__(new, name, getattr(v, name))
        return new

    def __setattr__(self, name: str, value: object) -> None:
        raise AttributeError(
            f"Variable {self.label!r} is shared by every component of its class and "
            f"cannot be changed; give the component its own copy first "
            f"(terminal.own_variable(index))")

    def __copy__(self) -> "SharedVariable":
        return self

    def __deepcopy__(self, memo: dict) -> "SharedVariable":
        return self

    def __reduce__(self) -> tuple:
        return (_shared_variable, (self.quantity, self.role, self.label, self.initial_value))


def _shared_variable(quantity: str, role: str, label: str,
                     initial_value: float | None) -> SharedVariable:
    return SharedVariable.of(Variable(quantity, role, label, initial_value))


class Terminal:
    """A connection point of a component: a label and its across/through variables.

    The variables are copied, so one set of Variable templates can serve
    several terminals.
    """

    def __init__(self, label: str, variables: Iterable[Variable]) -> None:
        if not isinstance(label, str) or not label:
            raise ValueError(f"Terminal: label must be a non-empty string, got {label!r}")
        variables = list(variables)
        for v in variables:
            if not isinstance(v, Variable):
                raise TypeError(f"Terminal {label!r}: expected Variable objects, got {v!r}")
            if v.role == "local":
                raise ValueError(
                    f"Terminal {label!r}: variable {v.label!r} has role 'local'; "
                    "terminals hold only 'across' and 'through' variables")
        quantities = [(v.quantity, v.role) for v in variables]
        if len(set(quantities)) != len(quantities):
            raise ValueError(f"Terminal {label!r}: a quantity appears twice")
        self.label = label
        self.variables = [v.copy() for v in variables]
        self.component: Component | None = None  # set by Component.set_terminals

    @classmethod
    def _of_checked(cls, label: str, variables: list[Variable]) -> Terminal:
        """A Terminal of ``variables`` (new Variables, already checked, this
        terminal's own): the constructor's result without its checks and
        copies, for library classes whose interface is checked once per class."""
        t = _new_terminal(cls)
        t.label = label
        t.variables = variables
        t.component = None
        return t

    def own_variable(self, index: int) -> Variable:
        """This terminal's own copy of its variable ``index`` (a library class
        shares one interface among its instances): the variable now in the
        terminal, which may then be changed."""
        v = self.variables[index]
        if isinstance(v, SharedVariable):
            v = v.copy()
            self.variables = [*self.variables[:index], v, *self.variables[index + 1:]]
        return v

    @property
    def across(self) -> list[Variable]:
        return [v for v in self.variables if v.role == "across"]

    @property
    def through(self) -> list[Variable]:
        return [v for v in self.variables if v.role == "through"]

    @property
    def name(self) -> str:
        owner = self.component.label if self.component is not None else "?"
        return f"{owner}.{self.label}"

    def __repr__(self) -> str:
        return f"Terminal({self.name!r}, {[v.label for v in self.variables]})"


_new_terminal = object.__new__
