"""Pressure and flow sources. Flow sources count positive when fluid leaves
the source (as in the FONS paper); the through variable at the terminal,
positive into the component, is then minus that flow.

Every source value may be a constant (number in SI or pint Quantity), a
waveform from ``softflow.curves.waveforms`` (which carries its unit and its
breakpoints), or any callable t [s] -> value (float in SI or Quantity).
Pressures are absolute, as in the paper; ``PressureSource(..., gauge=True)``
takes them relative to the atmosphere instead.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..constants import pressure_atmospheric
from ..curves.waveforms import Waveform
from ..units import to_si
from .base import FLUID_PORT, Affine, LibraryComponent, Params

if TYPE_CHECKING:
    from .._typing import Input, Scalar
    from ..fluids.base import Fluid


class _Signal:
    """A constant, a waveform or a function of time, returning SI floats.

    Waveforms (``softflow.curves.waveforms``) carry their unit and are checked
    and scaled once here; other callables are converted on every call (pint
    Quantities allowed) and may declare ``breakpoints`` (a tuple of times [s])
    or ``breakpoints_until(T)``.
    """

    def __init__(self, value, unit, name, owner):
        self.name, self.unit, self.owner = name, unit, owner
        self.const = None
        self.func = None
        self.fast = False     # func returns SI floats: no per-call conversion
        # the waveform and its factor to SI, where the value is one (the
        # compiled step loop evaluates it: softflow.solve.wavecodes)
        self.waveform, self.factor = None, None
        if isinstance(value, Waveform):
            factor = value.factor_to(unit, name=name, owner=owner)
            self.waveform, self.factor = value, factor
            self.func = value if factor == 1.0 else (lambda t: factor * value(t))
            self.fast = True
            self._until = value.breakpoints_until
            self.breaks = tuple(value.breakpoints)
        elif callable(value):
            self.func = value
            self.breaks = tuple(to_si(b, "s", name=f"{name}.breakpoints", owner=owner)
                                for b in getattr(value, "breakpoints", ()))
            self._until = getattr(value, "breakpoints_until", None)
        else:
            self.const = to_si(value, unit, name=name, owner=owner)
            if np.ndim(self.const) != 0:
                raise ValueError(f"{owner}: {name} must be a scalar, a waveform or a "
                                 f"function of time, got an array")
            self.breaks = ()
            self._until = None
        self.initial = self(0.0)  # validates units and output once, at construction

    def breakpoints_until(self, until):
        if self._until is not None:
            return tuple(float(b) for b in self._until(until))
        return tuple(b for b in self.breaks if b <= until)

    def __call__(self, t):
        if self.func is None:
            return self.const
        v = self.func(t)
        if self.fast or isinstance(v, float):
            return v
        v = to_si(v, self.unit, name=f"{self.name}(t={t:g})", owner=self.owner)
        if not isinstance(v, float):
            raise ValueError(f"{self.owner}: {self.name}(t) must return a scalar, "
                             f"got an array of shape {np.shape(v)} at t = {t:g} s")
        return v


class _SourceParams(Params):
    """Signal values of a group of sources: constants once, each distinct
    time-varying signal object once per distinct t."""

    def __init__(self, components):
        super().__init__(components)
        signals = [c.signal for c in self.components]
        offsets = np.array([getattr(c, "offset", 0.0) for c in self.components])
        self._base = offsets + [0.0 if s.func is not None else s.const for s in signals]
        # slot 0 holds 0 for constants; each distinct time-varying function gets a slot
        # (as a list first: NumPy's scalar writes cost more on a group of one or few)
        slots = {}
        self._varying = []
        slot = [0] * self.n
        for i, s in enumerate(signals):
            if s.func is not None:
                if id(s.func) not in slots:
                    self._varying.append(s)
                    slots[id(s.func)] = len(self._varying)
                slot[i] = slots[id(s.func)]
        self._slot = np.array(slot, dtype=np.int64)
        # the common case (one source, or many driven by one waveform): no gather
        self._one_signal = len(self._varying) == 1 and all(k == 1 for k in slot)
        self._t = None
        self._values = self._base
        # all sources of the group at one value (one source, or one signal and one
        # offset): flat_values() and column() hand out that value as a float
        # (not for a subclass with its own values())
        base = self._base.tolist()
        self._uniform = (not self._varying or self._one_signal) and all(
            b == base[0] for b in base) and type(self).values is _SourceParams.values
        self._base0 = float(self._base[0])
        self._tc = None
        self._value = self._base0

    def forget(self):
        """Drop the values kept for the last time asked (a new run asks anew:
        a Python signal may read state that changed between runs)."""
        self._t = self._tc = None

    def flat_values(self, t):
        """The values at t as a float when they are all equal (once per distinct
        t), else 1-D (n,)."""
        if not self._uniform:
            return self.values(t)
        if self._varying and t != self._tc:
            self._value = self._base0 + self._varying[0](t)
            self._tc = t
        return self._value

    def column(self, t):
        """The values at t for an (n, 1) residual: a float when they are all
        equal, else an (n, 1) column (a source kernel in one subtraction, no
        reshaping: 0.4 us of its 0.8 us, measured)."""
        if self._uniform:
            return self.flat_values(t)
        return self.values(t)[:, None]

    def values(self, t):
        """Signal values at t, computed once per distinct t."""
        if self._varying and t != self._t:
            if self._one_signal:
                self._values = self._base + self._varying[0](t)
            else:
                vals = np.array([0.0] + [s(t) for s in self._varying])
                self._values = self._base + vals[self._slot]
            self._t = t
        return self._values


def _value_jacobian(P, name, dF):
    """(dF/d theta, dr/d theta) of a source for its value ``name`` (constant
    values only: a waveform is no number), or None for other parameters."""
    if name != P.components[0].signal.name:
        return None
    return np.broadcast_to(dF, (P.n,))[:, None].copy(), np.zeros((P.n, 0))


class _Source(LibraryComponent):
    terminal_spec = (("a", FLUID_PORT),)
    temperature = None

    def _set_temperature(self, temperature):
        """Gas temperature [K] of the source in thermal scenes (None: the fluid's)."""
        if temperature is not None:
            self.temperature = self._si(temperature, "K", "temperature", positive=True)

    def group_key(self):
        # in a thermal scene the gas found at the terminal enters the kernel
        return (type(self), id(self.fluid), id(getattr(self, "_thermal_fluid", None)))

    def breakpoints(self):
        return self.signal.breaks

    def breakpoints_until(self, until):
        """Breakpoints in [0, until] [s], periodic waveforms' repetitions included."""
        return self.signal.breakpoints_until(until)

    @classmethod
    def make_params(cls, components):
        return _SourceParams(components)


class PressureSource(_Source):
    """Imposes a pressure at its terminal ``a``.

    Parameters
    ----------
    label : str
    pressure : float [Pa], Quantity, waveform or callable t -> float [Pa]
        Absolute pressure (or gauge pressure with ``gauge=True``), constant or
        a function of time, e.g. ``Step(0.5, sf.Q_(1, 'atm'), sf.Q_(1.3, 'bar'))``.
    gauge : bool, default False
        If True, ``pressure`` is relative to the atmosphere
        (``sf.pressure_atmospheric`` = 101325 Pa is added to it).
    temperature : float [K], optional
        Temperature of the gas the source delivers in a thermal scene (default:
        the temperature of the gas at its terminal); ignored when isothermal.
    """

    jac_pattern: tuple = ((0, 0),)

    def __init__(self, label: str, pressure: Input, *, gauge: bool = False,
                 temperature: Scalar | None = None) -> None:
        super().__init__(label)
        self._set_temperature(temperature)
        if not isinstance(gauge, bool):
            raise TypeError(f"{self.describe()}: gauge must be True or False, got {gauge!r}")
        self.gauge = gauge
        self.offset = pressure_atmospheric if gauge else 0.0
        self.signal = _Signal(pressure, "Pa", "pressure", self.describe())
        p0 = self.signal.initial + self.offset
        if not p0 > 0:
            hint = "" if gauge else " (pressures are absolute; for gauge pressure pass gauge=True)"
            raise ValueError(f"{self.describe()}: pressure must be > 0 Pa absolute, got "
                             f"{p0:g} Pa at t = 0{hint}")

    @classmethod
    def residual(cls, P, V, S, t, jac):
        F = V[:, :1] - P.column(t)
        J = np.ones((P.n, 1)) if jac else None
        return F, J

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """dF/d pressure = -1 (F = p - pressure)."""
        return _value_jacobian(P, name, -1.0)

    @classmethod
    def affine(cls, P):
        # F = p - value(t), V = [p, mf]; only for this kernel, not for subclasses'
        if cls.residual.__func__ is not PressureSource.residual.__func__:
            return None
        return Affine(np.broadcast_to([[[1.0, 0.0]]], (P.n, 1, 2)), offset=P.flat_values)


class MassFlowSource(_Source):
    """Imposes a mass flow leaving the source through terminal ``a``.

    Parameters
    ----------
    label : str
    massflow : float [kg/s], Quantity, waveform or callable t -> float [kg/s]
        Positive when fluid leaves the source.
    temperature : float [K], optional
        Temperature of the gas the source delivers in a thermal scene (default:
        the temperature of the gas at its terminal); ignored when isothermal.
    """

    imposes_flow = True

    jac_pattern: tuple = ((0, 1),)

    def __init__(self, label: str, massflow: Input, *,
                 temperature: Scalar | None = None) -> None:
        super().__init__(label)
        self._set_temperature(temperature)
        self.signal = _Signal(massflow, "kg/s", "massflow", self.describe())

    @classmethod
    def residual(cls, P, V, S, t, jac):
        F = V[:, 1:2] + P.column(t)
        J = np.ones((P.n, 1)) if jac else None
        return F, J

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """dF/d massflow = 1 (F = mf + massflow)."""
        return _value_jacobian(P, name, 1.0)

    @classmethod
    def affine(cls, P):
        # F = mf + value(t), V = [p, mf]; only for this kernel, not for subclasses'
        if cls.residual.__func__ is not MassFlowSource.residual.__func__:
            return None
        return Affine(np.broadcast_to([[[0.0, 1.0]]], (P.n, 1, 2)),
                      offset=lambda t: -P.flat_values(t))


class VolumeFlowSource(_Source):
    """Imposes a volume flow leaving the source through terminal ``a``;
    the mass flow is density(p) times it, at the terminal's pressure.

    The FONS paper's Figs. 3-5 pump (1.8 mL/s in for 10 s, a 5 s pause, then
    1.8 mL/s out) is one line::

        from softflow.curves.waveforms import PiecewiseConstant
        pump = sf.VolumeFlowSource("pump", fluid=sf.water, volumeflow=PiecewiseConstant(
            sf.Q_([0, 10, 15], "s"), sf.Q_([1.8, 0, -1.8], "mL/s")))

    Parameters
    ----------
    label : str
    volumeflow : float [m^3/s], Quantity, waveform or callable t -> float [m^3/s]
        Positive when fluid leaves the source.
    fluid : Fluid
    temperature : float [K], optional
        Temperature of the gas the source delivers in a thermal scene (default:
        the temperature of the gas at its terminal); ignored when isothermal.
    """

    imposes_flow = True

    jac_pattern: tuple = ((0, 0), (0, 1))

    def __init__(self, label: str, volumeflow: Input, fluid: Fluid, *,
                 temperature: Scalar | None = None) -> None:
        super().__init__(label)
        self._set_temperature(temperature)
        self.fluid = self._check_fluid(fluid)
        self.signal = _Signal(volumeflow, "m**3/s", "volumeflow", self.describe())

    @classmethod
    def residual(cls, P, V, S, t, jac):
        q = P.values(t)
        p = V[:, 0]
        F = (V[:, 1] + P.fluid.density(p) * q)[:, None]
        if not jac:
            return F, None
        J = np.empty((P.n, 2))
        J[:, 0] = P.fluid.density_dp(p) * q
        J[:, 1] = 1.0
        return F, J

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """dF/d volumeflow = rho(p) (F = mf + rho(p)·volumeflow)."""
        return _value_jacobian(P, name, P.fluid.density(V[:, 0]))
