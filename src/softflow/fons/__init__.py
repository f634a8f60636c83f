"""fonsim 0.6 scripts on softflow: ``import softflow.fons as fons``.

The names of fonsim 0.6's public API (its tutorials, examples and API
reference) as thin layers over softflow's own components, curves, waveforms
and results: one physics, softflow's. A fonsim name that is not supported
raises :class:`FonsimNameError` (an AttributeError) saying what to use
instead. Differences from fonsim and how to move a script to softflow's own
API: ``docs/coming-from-fonsim.md``.
"""
from __future__ import annotations

from ..constants import gas_constant, pressure_atmospheric, temperature_standard
from . import data, fluid, fluids, wave
from ._unsupported import FonsimNameError, unsupported
from .components import (CheckValve, CircularTube, Container, FlowRestrictor, FreeActuator,
                         LinearAccumulator, MassflowSource, PressureSource, Sink,
                         VolumeflowSource)
from .core import Component, Simulation, System, Terminal, Variable, terminal_fluidic
from .data import pvcurve
from .fluids import air, water
from .visual import plot, plot_state

#: softflow's fluid temperature [K] (fonsim's reference is 288.15 K)
temperature = temperature_standard

__all__ = [
    "Variable", "Terminal", "Component", "System", "Simulation", "terminal_fluidic",
    "PressureSource", "Sink", "MassflowSource", "VolumeflowSource", "CircularTube",
    "Container", "FlowRestrictor", "CheckValve", "LinearAccumulator", "FreeActuator",
    "air", "water", "fluid", "fluids", "wave", "data", "pvcurve", "plot", "plot_state",
    "pressure_atmospheric", "gas_constant", "temperature", "FonsimNameError",
]


def __getattr__(name):
    return unsupported(name, __name__)
