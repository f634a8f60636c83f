"""Assembly, Newton, the time integrators (fixed-step backward Euler, adaptive
BDF) and results."""
from .result import Result
from .simulation import Simulation, SimulationError

__all__ = ["Simulation", "SimulationError", "Result"]
