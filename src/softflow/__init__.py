"""softflow: lumped fluidic networks of soft inflatable actuators.

The object model follows the FONS paper (Variable, Terminal, Component,
System, Simulation), so ``import softflow as fons`` runs FONS scripts.
"""
from .components import (CircularTube, Container, LibraryComponent, LinearAccumulator,
                         MassFlowSource, PressureSource, VolumeFlowSource)
from .constants import pressure_atmospheric
from .curves import PVCurve, pvcurve, read_table
from .fluids import ConstantLiquid, Fluid, IdealGas, air, nitrogen, water
from .network import Component, NetworkError, Node, System, Terminal, Variable
from .solve import Result, Simulation, SimulationError
from .units import Q_, UnitError, ureg

__version__ = "0.1.0"

__all__ = [
    "Variable", "Terminal", "Component", "Node", "System", "NetworkError",
    "Simulation", "SimulationError", "Result",
    "LibraryComponent", "PressureSource", "MassFlowSource", "VolumeFlowSource",
    "CircularTube", "Container", "LinearAccumulator",
    "PVCurve", "pvcurve", "read_table",
    "Fluid", "IdealGas", "ConstantLiquid", "air", "nitrogen", "water",
    "pressure_atmospheric", "ureg", "Q_", "UnitError",
]
