"""fonsim's standard components as softflow's own, under fonsim's names,
signatures and defaults. Each class is the softflow component (same kernel,
same physics) with fonsim's result getters; where fonsim's parameters differ
they are mapped here, once.
"""
from __future__ import annotations

from .. import components as _sf
from ..components.base import LibraryComponent
from ..constants import pressure_atmospheric
from .core import ResultsMixin
from .data import PVCurve

#: An ideal check valve (fonsim's: no resistance once open) as softflow's
#: CheckValve: a passage this wide opening over this band above the threshold.
IDEAL_VALVE_DIAMETER = 20e-3      # [m]
IDEAL_VALVE_OPENING_BAND = 300.0  # [Pa] (100 Pa: the t = 0 Newton solve failed with a threshold)

#: fonsim's LinearAccumulator starts empty by default (v0 = 0); softflow needs a
#: positive fluid volume, so an empty one starts at this pressure above p0 [Pa].
EMPTY_ACCUMULATOR_OFFSET = 1e-3


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

    def __init__(self, label=None, fluid=None, pressure=None):
        label = _label(label, "PressureSource")
        if pressure is None:
            raise TypeError(f"fons.PressureSource {label!r}: give pressure= [Pa, absolute]")
        super().__init__(label, pressure)


class Sink(PressureSource):
    """fonsim's ``Sink(label, pressure=1 atm)``: a pressure source at the
    atmosphere. (fonsim 0.6 stores the Sink object as its own label, so
    connecting it by label fails there; here the label is the label.)"""

    def __init__(self, label=None, pressure=pressure_atmospheric):
        super().__init__(_label(label, "Sink"), pressure=pressure)


class MassflowSource(ResultsMixin, _sf.MassFlowSource):
    """fonsim's ``MassflowSource(label, fluid=None, massflow)`` [kg/s],
    positive when fluid leaves the source; the fluid is not needed."""

    def __init__(self, label=None, fluid=None, massflow=None):
        label = _label(label, "MassflowSource")
        if massflow is None:
            raise TypeError(f"fons.MassflowSource {label!r}: give massflow= [kg/s]")
        super().__init__(label, massflow)


class VolumeflowSource(ResultsMixin, _sf.VolumeFlowSource):
    """fonsim's ``VolumeflowSource(label, fluid, volumeflow)`` [m^3/s],
    positive when fluid leaves the source, at the terminal's density."""

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
    ``sf.CircularTube`` law that models it)."""

    def __init__(self, label=None, fluid=None, length=0.6, diameter=0.002, roughness=1.5e-6):
        label = _label(label, "CircularTube")
        super().__init__(label, _fluid(fluid, "CircularTube", label), length, diameter,
                         roughness, compressible="mean_density")


class Container(ResultsMixin, _sf.Container):
    """fonsim's ``Container(label, fluid, volume)`` [m^3], starting at 1 atm."""

    def __init__(self, label=None, fluid=None, volume=None):
        label = _label(label, "Container")
        if volume is None:
            raise TypeError(f"fons.Container {label!r}: give volume= [m^3]")
        super().__init__(label, _fluid(fluid, "Container", label), volume)


class FlowRestrictor(ResultsMixin, _sf.Orifice):
    """fonsim's ``FlowRestrictor(label, fluid, diameter=0.002, k=0.6)``:
    softflow's Orifice with loss coefficient K = k, dp = k rho v^2 / 2.
    softflow takes rho at the upstream pressure, fonsim at the mean pressure:
    for a gas across a large pressure ratio the flows differ (by sqrt of the
    density ratio)."""

    def __init__(self, label=None, fluid=None, diameter=0.002, k=0.6):
        label = _label(label, "FlowRestrictor")
        super().__init__(label, _fluid(fluid, "FlowRestrictor", label), diameter, K=k)


class CheckValve(ResultsMixin, _sf.CheckValve):
    """fonsim's ideal ``CheckValve(label, pressure_threshold=0)``: flow from
    ``a`` to ``b`` once p_a - p_b reaches the threshold [Pa], none back.

    softflow's CheckValve with cracking pressure = threshold, a
    ``IDEAL_VALVE_DIAMETER`` passage opening over ``IDEAL_VALVE_OPENING_BAND``.
    fonsim's valve takes no fluid: the valve takes that of the components it is
    connected to when the Simulation is built (or ``fluid=`` if given).
    """

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
    with compliance 1/k, reference pressure p0 and fluid volume v0 there,
    starting at rest at p0. (fonsim starts a gas-filled one with the mass
    rho_stp·v0, which is at rest at p0 only when p0 is atmospheric.) With
    v0 = 0 it starts ``EMPTY_ACCUMULATOR_OFFSET`` above p0 with the volume that
    gives (softflow needs some fluid)."""

    def __init__(self, label=None, fluid=None, k=None, p0=pressure_atmospheric, v0=0.0):
        label = _label(label, "LinearAccumulator")
        if k is None or not float(k) > 0:
            raise ValueError(f"fons.LinearAccumulator {label!r}: k must be a stiffness > 0 "
                             f"[Pa/m^3], got {k!r}")
        if v0 < 0:
            raise ValueError(f"fons.LinearAccumulator {label!r}: v0 must be >= 0 m^3, got {v0}")
        k, p0, v0 = float(k), float(p0), float(v0)
        start = p0 if v0 > 0 else p0 + EMPTY_ACCUMULATOR_OFFSET
        # V(p) = v0 + (p - p0)/k, written about the starting pressure
        super().__init__(label, _fluid(fluid, "LinearAccumulator", label),
                         volume=v0 + (start - p0) / k, compliance=1.0 / k,
                         reference_pressure=start, initial_pressure=start)


class FreeActuator(ResultsMixin, _sf.Actuator):
    """fonsim's ``FreeActuator(label, fluid, curve, initial_volume=None)``:
    softflow's Actuator on the PV curve ``curve`` (a CSV file name, read as
    ``fons.data.PVCurve(curve)`` with gauge pressures, a PVCurve, or an object
    with ``fdf_volume``). It starts at ``initial_volume`` [m^3], by default the
    curve's data point closest to 1 atm. fonsim's two terminals 'a' and 'b'
    are one node here ('b' connects to 'a'), as they share the volume's
    pressure. ``get_state('mass')`` is the stored mass, ``get_state('volume')``
    the volume. (fonsim 0.6 starts an actuator whose curve is given as a file
    name empty, below its curve's data; here it starts at the initial volume
    either way, as fonsim does for a PVCurve object.)"""

    _terminal_aliases = {"b": "a"}

    def __init__(self, label=None, fluid=None, curve=None, initial_volume=None):
        label = _label(label, "FreeActuator")
        if curve is None:
            raise TypeError(f"fons.FreeActuator {label!r}: give curve= (a CSV file or a PVCurve)")
        if isinstance(curve, str) or hasattr(curve, "__fspath__"):
            curve = PVCurve(curve)
        if initial_volume is None and hasattr(curve, "get_initial_volume"):
            initial_volume = curve.get_initial_volume(pressure_atmospheric)
        super().__init__(label, _fluid(fluid, "FreeActuator", label), curve,
                         initial_volume=initial_volume)
