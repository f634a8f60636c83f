"""fonsim's standard components as softflow's own, under fonsim's names,
signatures and defaults. Each class is the softflow component (same kernel,
same physics) with fonsim's result getters; where fonsim's parameters differ
they are mapped here, once.
"""
from __future__ import annotations

import os
from importlib import resources

import numpy as np
from scipy.optimize import brentq

from .. import components as _sf
from ..components.base import LibraryComponent
from ..network import Component as _Component
from ..components.valves import (_NO_JACOBIAN, ISO_6358_RHO0, ISO_6358_T0,
                                 _given_density, _valve_laws)
from ..units import to_si
from .constants.norm import pressure_atmospheric
from .core import ResultsMixin
from .data.pvcurve import PVCurve
from .data.pvcurve import initial_volume as initial_volume_at

#: An ideal check valve (fonsim's: no resistance once open) as softflow's
#: CheckValve: a passage this wide opening over this band above the threshold.
IDEAL_VALVE_DIAMETER = 20e-3      # [m]
IDEAL_VALVE_OPENING_BAND = 300.0  # [Pa] (100 Pa: the t = 0 Newton solve failed with a threshold)

#: fonsim's LinearAccumulator starts empty by default (v0 = 0); softflow's needs a
#: positive fluid volume, so an empty one starts at this pressure above p0 [Pa]
#: (with k = 1e9 Pa/m^3: 1e-12 m^3 of fluid).
EMPTY_ACCUMULATOR_OFFSET = 1e-3

#: fonsim's FreeActuator starts empty on a curve given as a file (shifted to
#: start at 0 m^3); softflow's Actuator needs a positive volume, so an empty one
#: starts at this fraction of its curve's volume range (1e-9: 6e-14 m^3 on the
#: 60 mm balloon's curve, a pressure 2e-3 Pa above the curve's first).
EMPTY_ACTUATOR_FRACTION = 1e-9

#: The PV curve fonsim's FreeActuator takes when given none: the 60 mm latex
#: balloon measured for the FONS paper (fonsim ships the same file).
DEFAULT_CURVE = "latex_balloon_60mm_pv.csv"


def _label(label, cls):
    if not isinstance(label, str) or not label:
        raise ValueError(f"fons.{cls}: give a label (a non-empty string), got {label!r}")
    return label


def _fluid(fluid, cls, label):
    if fluid is None:
        raise TypeError(f"fons.{cls} {label!r}: give fluid= (fons.air, fons.water, or "
                        f"fons.fluid.IdealCompressible/IdealIncompressible(...))")
    return fluid


class PressureSource(ResultsMixin, _sf.PressureSource):
    """fonsim's ``PressureSource(label, fluid=None, pressure)``: absolute
    pressure [Pa], a number or a function of time (e.g. a ``fons.wave.Custom``);
    the fluid is not needed."""

    fonsim_arguments = (("a", "pressure", "None"), ("a", "massflow", "None"))

    def __init__(self, label=None, fluid=None, pressure=None):
        label = _label(label, "PressureSource")
        if pressure is None:
            raise TypeError(f"fons.PressureSource {label!r}: give pressure= [Pa, absolute]")
        super().__init__(label, pressure)


class Sink(PressureSource):
    """fonsim's ``Sink(label, pressure=1 atm)``: a pressure source at
    fonsim's atmosphere (101 300 Pa). (fonsim 0.6 stores the Sink object as
    its own label, so connecting it by label fails there; here the label is
    the label.)"""

    def __init__(self, label=None, pressure=pressure_atmospheric):
        super().__init__(_label(label, "Sink"), pressure=pressure)


class MassflowSource(ResultsMixin, _sf.MassFlowSource):
    """fonsim's ``MassflowSource(label, fluid=None, massflow)`` [kg/s],
    positive when fluid leaves the source; the fluid is not needed."""

    fonsim_arguments = (("a", "massflow", "None"), ("a", "pressure", "None"))

    def __init__(self, label=None, fluid=None, massflow=None):
        label = _label(label, "MassflowSource")
        if massflow is None:
            raise TypeError(f"fons.MassflowSource {label!r}: give massflow= [kg/s]")
        super().__init__(label, massflow)


class VolumeflowSource(ResultsMixin, _sf.VolumeFlowSource):
    """fonsim's ``VolumeflowSource(label, fluid, volumeflow)`` [m^3/s],
    positive when fluid leaves the source, at the terminal's density."""

    fonsim_arguments = (("a", "pressure", "None"), ("a", "massflow", "None"))

    def __init__(self, label=None, fluid=None, volumeflow=None):
        label = _label(label, "VolumeflowSource")
        if volumeflow is None:
            raise TypeError(f"fons.VolumeflowSource {label!r}: give volumeflow= [m^3/s]")
        super().__init__(label, volumeflow, _fluid(fluid, "VolumeflowSource", label))


class CircularTube(ResultsMixin, _sf.CircularTube):
    """fonsim's ``CircularTube(label, fluid, length=0.6, diameter=0.002,
    roughness=1.5e-6)`` [m]: softflow's tube (Darcy–Weisbach, Haaland) with
    fonsim's gas law, the density at the mean pressure and no acceleration
    (``compressible='mean_density'``: it does not choke; past Mach 0.3 softflow
    warns, past the choke it refuses the run, naming the default
    ``sf.CircularTube`` law that models it) and fonsim's laminar-turbulent
    transition, the two laws weighed linearly in Re between 2 300 and 4 000
    (``transition='linear'``)."""

    fonsim_arguments = (("a", "massflow", "mf0"), ("a", "pressure", "p0"),
                        ("b", "massflow", "mf1"), ("b", "pressure", "p1"))

    def __init__(self, label=None, fluid=None, length=0.6, diameter=0.002, roughness=1.5e-6):
        label = _label(label, "CircularTube")
        super().__init__(label, _fluid(fluid, "CircularTube", label), length, diameter,
                         roughness, compressible="mean_density", transition="linear")


class Container(ResultsMixin, _sf.Container):
    """fonsim's ``Container(label, fluid, volume)`` [m^3], starting at fonsim's
    1 atm (101 300 Pa)."""

    fonsim_arguments = (("a", "massflow", "mf"), ("a", "pressure", "p"))
    fonsim_states = {"m": "mass"}

    def __init__(self, label=None, fluid=None, volume=None):
        label = _label(label, "Container")
        if volume is None:
            raise TypeError(f"fons.Container {label!r}: give volume= [m^3]")
        super().__init__(label, _fluid(fluid, "Container", label), volume,
                         initial_pressure=pressure_atmospheric)


class FlowRestrictor(ResultsMixin, _sf.Orifice):
    """fonsim's ``FlowRestrictor(label, fluid, diameter=0.002, k=0.6)``:
    softflow's Orifice with loss coefficient K = k, dp = k rho v^2 / 2, with
    fonsim's density: at the mean pressure (p_a + p_b)/2, where softflow's
    Orifice takes the upstream one (for a gas across a large pressure ratio
    the flows differ by the square root of their ratio: 9 % from 1.5 bar
    into the atmosphere).

    The same compiled orifice law (:func:`softflow.laws.valves.orifice_residual`)
    is given the density at the mean pressure instead of making the upstream
    one (``DENSITY_POINT``); its Jacobian takes the density's slope in both
    pressures. A liquid's density is the same at every pressure: there it is
    softflow's Orifice unchanged."""

    fonsim_arguments = (("a", "pressure", "None"), ("a", "massflow", "None"),
                        ("b", "pressure", "None"), ("b", "massflow", "None"))

    #: where the loss law takes its density (softflow's Orifice: 'upstream')
    DENSITY_POINT = "mean"

    def __init__(self, label=None, fluid=None, diameter=0.002, k=0.6):
        label = _label(label, "FlowRestrictor")
        super().__init__(label, _fluid(fluid, "FlowRestrictor", label), diameter, K=k)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if not P.fluid.compressible:
            return _sf.Orifice.residual.__func__(cls, P, V, S, t, jac)
        pa, pb = V[:, 0], V[:, 2]
        # rho at (p_a + p_b)/2 and its slope per p_a (= per p_b): half of d rho/dp
        rho_m, drho_m = _given_density(P, (pa, pb), mean=True)
        F = np.empty((P.n, 2))
        J = np.empty((P.n, 5)) if jac else _NO_JACOBIAN
        # the law's given density is read as an upstream one: its slope enters
        # the upstream pressure's column only ...
        _valve_laws().orifice_residual(
            P.law, V, P.law_RT, P.law_rho, P.K, P.area, P.dp_small, P.gamma, P.Cd, P.T, P.C,
            P.b, P.subsonic_index, P.pr_laminar, ISO_6358_RHO0, ISO_6358_T0, True, rho_m,
            drho_m, F, J, jac)
        if not jac:
            return F, None
        # ... and the mean density moves with the downstream pressure as much:
        # d mdot/d p_down += (d mdot/d rho) drho_m, with d mdot/d rho = mdot/(2 rho)
        # for the loss law (regularized or not); row 1 is mf_a - mdot
        q = V[:, 1] - F[:, 1]
        extra = q / (2.0 * rho_m) * drho_m
        down = np.where(pa >= pb, 4, 2)      # J's (1, p_b) or (1, p_a) entry
        J[np.arange(P.n), down] -= extra
        return F, J


class CheckValve(ResultsMixin, _sf.CheckValve):
    """fonsim's ideal ``CheckValve(label, pressure_threshold=0)``: flow from
    ``a`` to ``b`` once p_a - p_b reaches the threshold [Pa], none back.

    softflow's CheckValve with cracking pressure = threshold, a
    ``IDEAL_VALVE_DIAMETER`` passage opening over ``IDEAL_VALVE_OPENING_BAND``.
    fonsim's valve takes no fluid: the valve takes that of the components it is
    connected to when the Simulation is built (or ``fluid=`` if given).
    """

    fonsim_arguments = (("a", "massflow", "mf0"), ("a", "pressure", "p0"),
                        ("b", "massflow", "mf1"), ("b", "pressure", "p1"))

    def __init__(self, label=None, pressure_threshold=0, *, fluid=None):
        label = _label(label, "CheckValve")
        self._threshold = pressure_threshold
        self._fluid_pending = True
        # terminals now (so it can be connected); the valve itself once its fluid is known
        LibraryComponent.__init__(self, label)
        if fluid is not None:
            self._bind_fluid(fluid)

    def _bind_fluid(self, fluid):
        terminals = self.terminals
        # (an ideal valve's wide passage: the orifice equation, with which its
        # agreement with fonsim was measured, rather than a gas's nozzle law)
        _sf.CheckValve.__init__(self, self.label, fluid, IDEAL_VALVE_DIAMETER,
                                cracking_pressure=self._threshold,
                                opening_band=IDEAL_VALVE_OPENING_BAND,
                                gas_law="incompressible")
        self.set_terminals(*terminals)   # keep the terminals the System has connected
        self._fluid_pending = False


class LinearAccumulator(ResultsMixin, _sf.LinearAccumulator):
    """fonsim's ``LinearAccumulator(label, fluid, k, p0=1 atm, v0=0)``:
    p = k (V - v0) + p0 [Pa, Pa/m^3, m^3], i.e. softflow's LinearAccumulator
    with compliance 1/k and fluid volume v0 at p0.

    It starts, as fonsim's, with the mass v0 · density at 1 atm (fonsim's
    101 300 Pa), at the pressure where that mass fills V(p): at p0 for a
    liquid, and for a gas when p0 is 1 atm; by default (v0 = 0) empty at p0.
    softflow needs some fluid in it: an empty one starts
    ``EMPTY_ACCUMULATOR_OFFSET`` (1 mPa) above p0 with the volume that gives.
    """

    fonsim_arguments = (("a", "massflow", "mf"), ("a", "pressure", "p"))
    fonsim_states = {"m": "mass"}

    def __init__(self, label=None, fluid=None, k=None, p0=pressure_atmospheric, v0=0.0):
        label = _label(label, "LinearAccumulator")
        fluid = _fluid(fluid, "LinearAccumulator", label)
        if k is None or not float(k) > 0:
            raise ValueError(f"fons.LinearAccumulator {label!r}: k must be a stiffness > 0 "
                             f"[Pa/m^3], got {k!r}")
        if v0 < 0:
            raise ValueError(f"fons.LinearAccumulator {label!r}: v0 must be >= 0 m^3, got {v0}")
        k, p0, v0 = float(k), float(p0), float(v0)
        if v0 > 0:
            mass = v0 * float(fluid.density(pressure_atmospheric))
            start = _accumulator_start(fluid, k, p0, v0, mass)
            super().__init__(label, fluid, volume=v0, compliance=1.0 / k,
                             reference_pressure=p0, initial_pressure=start)
        else:
            # V(p) = (p - p0)/k, written about the starting pressure
            start = p0 + EMPTY_ACCUMULATOR_OFFSET
            super().__init__(label, fluid, volume=(start - p0) / k, compliance=1.0 / k,
                             reference_pressure=start, initial_pressure=start)
        self.k, self.p0, self.v0 = k, p0, v0


def _accumulator_start(fluid, k, p0, v0, mass):
    """The pressure at which ``mass`` fills the accumulator's V(p) = v0 + (p - p0)/k."""
    if not fluid.compressible:
        return p0

    def excess(p):          # increasing in p: V(p) rises, mass/rho(p) falls
        return v0 + (p - p0) / k - mass / float(fluid.density(p))
    lo, hi = sorted((p0, pressure_atmospheric))
    if excess(lo) * excess(hi) > 0:    # (cannot happen for an ideal gas)
        lo, hi = 1e-3 * lo, 1e3 * hi
    return brentq(excess, lo, hi, xtol=1e-9, rtol=1e-14) if lo < hi else lo


class FreeActuator(ResultsMixin, _sf.Actuator):
    """fonsim's ``FreeActuator(label, fluid, curve=None, initial_volume=None)``:
    softflow's Actuator on the PV curve ``curve``.

    ``curve`` is a CSV file name, read as fonsim reads it:
    ``fons.data.PVCurve(curve, autocorrect=True)`` (shifted to start at 0 m^3
    and 1 atm, the end pressures held beyond the data); ``None`` (fonsim's
    default): the 60 mm latex balloon's measured curve, which fonsim ships
    and softflow too (``softflow/data/latex_balloon_60mm_pv.csv``), read the
    same way; or a curve object (a fons or softflow PVCurve, or any object
    with ``fdf_volume``), taken as it is.

    ``initial_volume`` [m^3]: None or 'auto' (where the curve first reaches
    1 atm, :meth:`fons.data.PVCurve.get_initial_volume`), 'minimum' (the
    curve's smallest volume) or a number. As in fonsim, the actuator starts
    with the mass that volume holds at 1 atm (fonsim's 101 300 Pa), at the
    point of the curve where that mass is: at the volume itself for a
    liquid, slightly below it for a gas above 1 atm. An empty one (volume 0,
    a curve given as a file) starts ``EMPTY_ACTUATOR_FRACTION`` of its curve's
    volume range above 0 (softflow needs some fluid).

    fonsim's two terminals 'a' and 'b' are one node here ('b' connects to
    'a'), as they share the volume's pressure; the flow through each is
    fonsim's all the same: ``get('massflow', 'b')`` (``'mf1'``) is minus the
    flows of the other terminals of fonsim's node of 'b', ``get('massflow',
    'a')`` the rest. ``get_state('mass')`` is the stored mass,
    ``get_state('volume')`` the volume.
    """

    fonsim_arguments = (("a", "massflow", "mf0"), ("a", "pressure", "p0"),
                        ("b", "massflow", "mf1"), ("b", "pressure", "p1"))
    fonsim_states = {"mass": "mass"}

    _terminal_aliases = {"b": "a"}

    def __init__(self, label=None, fluid=None, curve=None, initial_volume=None):
        label = _label(label, "FreeActuator")
        fluid = _fluid(fluid, "FreeActuator", label)
        owner = f"fons.FreeActuator {label!r}"
        if curve is None:
            curve = _fonsim_file_curve(resources.files("softflow") / "data" / DEFAULT_CURVE)
        elif isinstance(curve, bytes):
            raise TypeError(f"{owner}: softflow reads PV curves from files only; write the "
                            f"bytes to a CSV file and give its path as curve=")
        elif isinstance(curve, (str, os.PathLike)):
            curve = _fonsim_file_curve(curve)
        elif not hasattr(curve, "fdf_volume"):
            raise TypeError(f"{owner}: curve must be a CSV file name, a PVCurve or an object "
                            f"with fdf_volume(volume) -> (pressure, dp/dV), got {curve!r}")
        v0 = _actuator_volume(curve, initial_volume, owner)
        start = _actuator_start(curve, fluid, v0, owner)
        if not start > 0:
            data = _data_volumes(curve)
            span = (data[-1] - data[0]) if data is not None else 1e-6
            start = EMPTY_ACTUATOR_FRACTION * span
        super().__init__(label, fluid, curve, initial_volume=start)

    @property
    def pvcurve(self):
        """The PV curve (fonsim's attribute name)."""
        return self.curve

    # fonsim's terminals 'a' and 'b': one pressure; the flow through each
    def _values(self, key, terminal):
        if terminal not in ("a", "b"):
            return super()._values(key, terminal)
        if key != "massflow":
            return super()._values(key, "a")
        through_b = _flow_through_b(self, set())
        if terminal == "b":
            return through_b
        return super()._values("massflow", "a") - through_b

    def _terminal_of(self, label):
        return self.get_terminal("a" if label == "b" else label)


def _flow_through_b(actuator, seen):
    """The mass flow [kg/s] into a FreeActuator through fonsim's terminal 'b'
    over the last run: minus the flows into the other terminals of fonsim's
    node of 'b' (softflow joins 'b' to 'a': the actuator's own flow is the
    sum of both)."""
    system = getattr(actuator, "_fons_system", None)
    times = _Component.get(actuator, "massflow", "a")
    if system is None or actuator.label in seen:
        return np.zeros_like(times) if system is None else np.full_like(times, np.nan)
    seen = seen | {actuator.label}
    total = np.zeros_like(times)
    for label, term in system.fonsim_node_of(actuator.label, "b"):
        if (label, term) == (actuator.label, "b"):
            continue
        other = system.get(label)
        if isinstance(other, FreeActuator):
            through_b = _flow_through_b(other, seen)
            flow = through_b if term == "b" else \
                _Component.get(other, "massflow", "a") - through_b
        else:
            flow = _Component.get(other, "massflow", term)
        total = total + flow
    return -total


def _fonsim_file_curve(path):
    """A PV curve file as fonsim's FreeActuator reads one: autocorrected, the
    end pressures held beyond the data (fonsim: extrapolate=False,
    extrapolate_derivative=True)."""
    return PVCurve(path, autocorrect=True, extrapolate=False, extrapolate_derivative=True)


def _data_volumes(curve):
    v = getattr(curve, "volume", None)
    if v is None:
        v = getattr(curve, "v", None)
    return None if v is None else np.asarray(v, dtype=float)


def _actuator_volume(curve, initial_volume, owner):
    """fonsim's starting volume [m^3] for ``initial_volume``."""
    if initial_volume is None or (isinstance(initial_volume, str) and initial_volume == "auto"):
        if hasattr(curve, "get_initial_volume"):
            return float(curve.get_initial_volume(pressure_atmospheric))
        v = _data_volumes(curve)
        if v is not None and hasattr(curve, "pressure"):   # a softflow PVCurve
            return initial_volume_at(v, curve.pressure, pressure_atmospheric)
        raise ValueError(f"{owner}: the curve {curve!r} has no get_initial_volume(p0) nor "
                         f"data; give initial_volume= [m^3]")
    if isinstance(initial_volume, str):
        if initial_volume == "minimum":
            v = _data_volumes(curve)
            if v is None:
                raise ValueError(f"{owner}: initial_volume='minimum' needs a curve with data "
                                 f"(v or volume); give initial_volume= [m^3]")
            return float(np.min(v))
        raise ValueError(f"{owner}: initial_volume must be None, 'auto', 'minimum' or a "
                         f"volume [m^3], got {initial_volume!r}")
    v0 = to_si(initial_volume, "m**3", name="initial_volume", owner=owner)
    if not v0 >= 0:
        raise ValueError(f"{owner}: initial_volume must be >= 0 m^3, got {initial_volume!r}")
    return v0


def _actuator_start(curve, fluid, v0, owner):
    """The volume [m^3] at which the mass ``v0`` holds at 1 atm (fonsim's
    initial mass) sits on the curve: V with V · density(curve(V)) = that mass."""
    if not fluid.compressible or v0 == 0:
        return v0
    mass = v0 * float(fluid.density(pressure_atmospheric))

    def excess(v):
        return v * float(fluid.density(float(curve.fdf_volume(float(v))[0]))) - mass

    here = excess(v0)
    if here == 0:
        return v0
    if here > 0:             # above 1 atm at v0: the gas is compressed, V < v0
        lo, hi = 0.0, v0
    else:
        lo, hi = v0, 2 * v0
        for _ in range(60):
            if excess(hi) > 0:
                break
            lo, hi = hi, 2 * hi
        else:
            raise ValueError(f"{owner}: no volume on the curve holds the starting mass "
                             f"{mass:.6g} kg")
    return brentq(excess, lo, hi, xtol=1e-15 * v0, rtol=1e-13)
