"""fonsim 0.6 scripts on softflow: ``import softflow.fons as fons``.

The names of fonsim 0.6's public API (its tutorials, examples and API
reference) as thin layers over softflow's own components, curves, waveforms
and results: one physics, softflow's. A fonsim name that is not supported
raises :class:`FonsimNameError` (an AttributeError) saying what to use
instead. Differences from fonsim and how to move a script to softflow's own
API: ``docs/coming-from-fonsim.md``.
"""
from __future__ import annotations

from . import constants, data, fluid, fluids, visual, wave
from ._unsupported import FonsimNameError, unsupported
from .components import (CheckValve, CircularTube, Container, FlowRestrictor, FreeActuator,
                         LinearAccumulator, MassflowSource, PressureSource, Sink,
                         VolumeflowSource)
from .core import Component, Simulation, System, Terminal, Variable, terminal_fluidic
from .data import pvcurve
from .fluids import air, water
from .visual.plotting import plot, plot_state

#: fonsim's constants modules, under fonsim's names
cnorm = constants.norm
cphy = constants.physical
#: fonsim's atmospheric pressure [Pa] (101 300 Pa; softflow's: 101 325 Pa)
pressure_atmospheric = cnorm.pressure_atmospheric
#: fonsim's reference temperature [K] (288.15 K; softflow's fluids: 293.15 K)
temperature = cnorm.temperature
#: fonsim's molar gas constant [J/(mol K)]
gas_constant = cphy.gas_constant

__all__ = [
    "Variable", "Terminal", "Component", "System", "Simulation", "terminal_fluidic",
    "PressureSource", "Sink", "MassflowSource", "VolumeflowSource", "CircularTube",
    "Container", "FlowRestrictor", "CheckValve", "LinearAccumulator", "FreeActuator",
    "air", "water", "fluid", "fluids", "wave", "data", "pvcurve", "visual", "plot",
    "plot_state", "constants", "cnorm", "cphy", "pressure_atmospheric", "gas_constant",
    "temperature", "FonsimNameError",
]


def __getattr__(name):
    return unsupported(name, __name__)
