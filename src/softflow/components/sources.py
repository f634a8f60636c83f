"""Pressure and flow sources. Flow sources count positive when fluid leaves
the source (as in the FONS paper); the through variable at the terminal,
positive into the component, is then minus that flow."""
from __future__ import annotations

import numpy as np

from .base import FLUID_PORT, LibraryComponent, Params
from ..units import to_si


class _Signal:
    """A constant or a function of time, returning SI floats."""

    def __init__(self, value, unit, name, owner):
        self.name, self.unit, self.owner = name, unit, owner
        if callable(value):
            self.func = value
            self.breaks = tuple(to_si(b, "s", name=f"{name}.breakpoints", owner=owner)
                                for b in getattr(value, "breakpoints", ()))
            self(0.0)  # validate units and output once, at construction
        else:
            c = to_si(value, unit, name=name, owner=owner)
            self.func = None
            self.const = c
            self.breaks = ()

    def __call__(self, t):
        if self.func is None:
            return self.const
        v = self.func(t)
        if not isinstance(v, float):
            v = to_si(v, self.unit, name=f"{self.name}(t={t:g})", owner=self.owner)
            if not isinstance(v, float):
                raise ValueError(f"{self.owner}: {self.name}(t) must return a scalar, "
                                 f"got an array of shape {np.shape(v)} at t = {t:g} s")
        return v


class _SourceParams(Params):
    def __init__(self, components):
        super().__init__(components)
        self.signals = [c.signal for c in self.components]
        self._t = None
        self._values = None

    def values(self, t):
        """Signal values at t, computed once per distinct t."""
        if t != self._t:
            self._values = np.array([s(t) for s in self.signals], dtype=float)
            self._t = t
        return self._values


class _Source(LibraryComponent):
    terminal_spec = (("a", FLUID_PORT),)

    def breakpoints(self):
        return self.signal.breaks

    @classmethod
    def make_params(cls, components):
        return _SourceParams(components)


class PressureSource(_Source):
    """Imposes an absolute pressure at its terminal ``a``.

    Parameters
    ----------
    label : str
    pressure : float [Pa] or callable t -> float [Pa]
        Absolute pressure, constant or a function of time (a waveform).
    """

    jac_pattern = ((0, 0),)

    def __init__(self, label, pressure):
        super().__init__(label)
        self.signal = _Signal(pressure, "Pa", "pressure", self.describe())

    @classmethod
    def kernel(cls, P, V, S, t, dt, jac):
        F = (V[:, 0] - P.values(t))[:, None]
        J = np.ones((P.n, 1)) if jac else None
        return F, J


class MassFlowSource(_Source):
    """Imposes a mass flow leaving the source through terminal ``a``.

    Parameters
    ----------
    label : str
    massflow : float [kg/s] or callable t -> float [kg/s]
        Positive when fluid leaves the source.
    """

    jac_pattern = ((0, 1),)

    def __init__(self, label, massflow):
        super().__init__(label)
        self.signal = _Signal(massflow, "kg/s", "massflow", self.describe())

    @classmethod
    def kernel(cls, P, V, S, t, dt, jac):
        F = (V[:, 1] + P.values(t))[:, None]
        J = np.ones((P.n, 1)) if jac else None
        return F, J


class VolumeFlowSource(_Source):
    """Imposes a volume flow leaving the source through terminal ``a``;
    the mass flow is density(p) times it, at the terminal's pressure.

    Parameters
    ----------
    label : str
    volumeflow : float [m^3/s] or callable t -> float [m^3/s]
        Positive when fluid leaves the source.
    fluid : Fluid
    """

    jac_pattern = ((0, 0), (0, 1))

    def __init__(self, label, volumeflow, fluid):
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        self.signal = _Signal(volumeflow, "m**3/s", "volumeflow", self.describe())

    @classmethod
    def kernel(cls, P, V, S, t, dt, jac):
        q = P.values(t)
        p = V[:, 0]
        F = (V[:, 1] + P.fluid.density(p) * q)[:, None]
        if not jac:
            return F, None
        J = np.empty((P.n, 2))
        J[:, 0] = P.fluid.density_dp(p) * q
        J[:, 1] = 1.0
        return F, J
