"""LibraryComponent: components that evaluate all instances of a class at once.

A library class declares its interface in class attributes and implements
``kernel`` (residuals and their analytic Jacobian) and, if it has states,
``update`` (the backward-Euler state update) as classmethods that work on
NumPy arrays holding every instance of the class in the network. The
assembly stacks the instances' parameters once per Simulation into a
:class:`Params` namespace.
"""
from __future__ import annotations

import numpy as np

from ..constants import pressure_atmospheric
from ..network.component import Component
from ..network.variable import Terminal, Variable
from ..units import to_si

#: Standard fluid port: absolute pressure (across) and mass flow into the component (through).
FLUID_PORT = (("pressure", "across", "p"), ("massflow", "through", "mf"))


class Params:
    """Stacked parameters of a group of instances (attributes are arrays of length n)."""

    def __init__(self, components):
        self.components = list(components)
        self.n = len(self.components)
        first = self.components[0]
        self.fluid = getattr(first, "fluid", None)
        for name in type(first).param_names:
            setattr(self, name, np.array([getattr(c, name) for c in self.components], dtype=float))


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
        ``((equation, variable), ...)`` structural nonzeros of dF/dV; variables are
        numbered in interface order (terminal variables, then locals)
    ``discrete_states``
        labels of states that are modes (e.g. a valve's open/closed memory): the
        kernel reads them at the start of the step, ``update`` switches them from
        the converged solution, so a mode never changes inside a Newton solve
    """

    vectorized = True
    #: thermal model resolved by the Simulation (None: isothermal, the paper's model);
    #: see :mod:`softflow.solve.thermal`
    _thermal = None
    terminal_spec: tuple = ()
    state_spec: tuple = ()
    param_names: tuple = ()
    jac_pattern: tuple = ()
    discrete_states: tuple = ()

    def __init__(self, label, fluid=None):
        super().__init__(label)
        self.fluid = fluid
        terms = []
        for tlabel, vars_ in self.terminal_spec:
            vs = [Variable(q, role, label=lab,
                           initial_value=pressure_atmospheric if q == "pressure" else 0.0)
                  for q, role, lab in vars_]
            terms.append(Terminal(tlabel, vs))
        self.set_terminals(*terms)
        self.set_states(*[Variable(q, "local", label=lab) for lab, q in self.state_spec])

    # -- helpers for subclasses ------------------------------------------------------
    def _si(self, value, unit, name, *, positive=False, nonnegative=False):
        v = to_si(value, unit, name=name, owner=self.describe())
        if np.ndim(v) != 0:
            raise ValueError(f"{self.describe()}: {name} must be a scalar, got an array")
        if not np.isfinite(v):
            raise ValueError(f"{self.describe()}: {name} must be finite, got {v}")
        if positive and not v > 0:
            raise ValueError(f"{self.describe()}: {name} must be > 0 [{unit}], got {v}")
        if nonnegative and v < 0:
            raise ValueError(f"{self.describe()}: {name} must be >= 0 [{unit}], got {v}")
        return v

    def _check_fluid_state(self, pressure, name):
        """A fluid-range error for an initial state, naming this component and parameter."""
        from ..fluids.base import FluidError
        try:
            self.fluid.density(pressure)
        except FluidError as err:
            raise FluidError(f"{self.describe()}: {name} = {pressure:.6g} Pa: {err}") from None

    def _check_fluid(self, fluid):
        from ..fluids.base import Fluid
        if not isinstance(fluid, Fluid):
            raise TypeError(f"{self.describe()}: fluid must be a softflow Fluid (e.g. sf.air, "
                            f"sf.water), got {fluid!r}")
        return fluid

    # -- grouping and kernels ----------------------------------------------------------
    def group_key(self):
        """Instances with equal keys are evaluated together in one kernel call."""
        return (type(self), id(self.fluid))

    def initial_states(self):
        """State values at t = 0, in ``state_spec`` order."""
        return [0.0] * len(self.state_spec)

    def kernel_class(self):
        """The class whose kernels evaluate this instance: its own in isothermal
        scenes, its thermal variant (:mod:`softflow.components.thermal`) in thermal ones."""
        if self._thermal is None:
            return type(self)
        from .thermal import thermal_class
        return thermal_class(type(self))

    def initial_state_values(self):
        """Initial states of the compiled model (thermal variants add internal energy)."""
        if self._thermal is None:
            return self.initial_states()
        return self.kernel_class().thermal_initial_states(self)

    @classmethod
    def make_params(cls, components) -> Params:
        return Params(components)

    @classmethod
    def kernel(cls, P, V, S, t, dt, jac):
        """Residuals F (n, n_eq) and, if ``jac``, dF/dV (n, len(jac_pattern)).

        V (n, n_vars) are the interface variables, S (n, n_states) the states at
        the start of the step; states at the end of the step follow from
        :meth:`update` and their dependence on V is part of dF/dV.
        """
        raise NotImplementedError

    @classmethod
    def update(cls, P, V, S, dt):
        """States at the end of a step of length dt (backward Euler)."""
        return S

    @classmethod
    def affine(cls, P):
        """None, or an :class:`Affine` description of this group's residual
        (without Jacobian) as an affine map of V, which small systems evaluate
        for all such groups with one matrix product. Only a class whose
        :meth:`kernel` the description matches may return one (a subclass with
        its own kernel must not inherit it)."""
        return None


class Affine:
    """F[i, e] = sum_k coef[i, e, k] V[i, k] - offset(t) while valid(V) holds.

    coef : (n, n_eq, n_vars) constant array
    offset : callable t -> float or 1-D array of n·n_eq values (row order), or None
    valid : callable V -> bool, or None for always; where it is False the
        kernel evaluates the group instead
    """

    def __init__(self, coef, offset=None, valid=None):
        self.coef, self.offset, self.valid = np.asarray(coef, dtype=float), offset, valid
