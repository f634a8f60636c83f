"""softflow: lumped fluidic networks of soft inflatable actuators.

The object model follows the FONS paper (Variable, Terminal, Component,
System, Simulation), so ``import softflow as fons`` runs FONS scripts.

The public names load on first use (PEP 562): ``import softflow`` itself imports
neither pint, SciPy nor CoolProp, so the command line and scripts start fast, and a
script pays only for what it touches (``sf.System`` loads the network, ``sf.PVCurve``
the curves, ...).
"""
from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

# public name -> module (relative to this package) that defines it
_LAZY = {
    **dict.fromkeys(["Actuator", "CheckValve", "CircularTube", "Container",
                     "HystereticActuator", "LibraryComponent", "LinearAccumulator",
                     "MassFlowSource", "Orifice", "PressureSource", "SnappingValve",
                     "TeslaValve", "VolumeFlowSource"], "components"),
    "pressure_atmospheric": "constants",
    "FreeConvection": "correlations.heat_transfer",
    **dict.fromkeys(["assess", "Assessment", "AssessmentError"], "assess"),
    **dict.fromkeys(["HysteresisLoop", "PVCurve", "pvcurve", "read_table"], "curves"),
    **dict.fromkeys(["ConstantLiquid", "Fluid", "FluidError", "IdealGas", "air",
                     "ethylene_glycol", "nitrogen", "water"], "fluids"),
    **dict.fromkeys(["Component", "NetworkError", "Node", "System", "Terminal",
                     "Variable"], "network"),
    **dict.fromkeys(["Result", "Simulation", "SimulationError"], "solve"),
    **dict.fromkeys(["ModelWarning", "ComponentError"], "solve.validity"),
    **dict.fromkeys(["Q_", "UnitError", "ureg"], "units"),
    **dict.fromkeys(["sweep", "SweepResult"], "sweep"),
    **dict.fromkeys(["fit", "design", "FitResult"], "fitting"),
}
# public names that are modules themselves
_LAZY_MODULES = {"waveforms": "curves.waveforms", "scene": "scene"}

__all__ = [
    "Variable", "Terminal", "Component", "Node", "System", "NetworkError",
    "Simulation", "SimulationError", "Result", "ModelWarning", "ComponentError",
    "LibraryComponent", "PressureSource", "MassFlowSource", "VolumeFlowSource",
    "CircularTube", "Container", "LinearAccumulator",
    "Orifice", "CheckValve", "TeslaValve", "SnappingValve", "Actuator", "HystereticActuator",
    "FreeConvection",
    "PVCurve", "HysteresisLoop", "pvcurve", "read_table", "waveforms",
    "Fluid", "FluidError", "IdealGas", "ConstantLiquid", "air", "nitrogen", "water",
    "ethylene_glycol",
    "pressure_atmospheric", "ureg", "Q_", "UnitError",
    "sweep", "SweepResult", "fit", "design", "FitResult", "assess", "Assessment", "AssessmentError",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY_MODULES:
        value = importlib.import_module(f".{_LAZY_MODULES[name]}", __name__)
    elif name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    else:
        raise AttributeError(f"module 'softflow' has no attribute {name!r}")
    globals()[name] = value          # later look-ups do not come here
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))


if TYPE_CHECKING:       # the same names, eagerly, for type checkers and IDEs
    from .components import (Actuator, CheckValve, CircularTube, Container,
                             HystereticActuator, LibraryComponent, LinearAccumulator,
                             MassFlowSource, Orifice, PressureSource, SnappingValve,
                             TeslaValve, VolumeFlowSource)
    from .assess import Assessment, AssessmentError, assess
    from .constants import pressure_atmospheric
    from .correlations.heat_transfer import FreeConvection
    from .curves import HysteresisLoop, PVCurve, pvcurve, read_table, waveforms
    from .fluids import (ConstantLiquid, Fluid, FluidError, IdealGas, air, ethylene_glycol,
                         nitrogen, water)
    from .network import Component, NetworkError, Node, System, Terminal, Variable
    from .solve import Result, Simulation, SimulationError
    from .solve.validity import ComponentError, ModelWarning
    from . import scene
    from .fitting import FitResult, design, fit
    from .sweep import SweepResult, sweep
    from .units import Q_, UnitError, ureg
