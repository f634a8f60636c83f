"""Assembly, Newton, implicit Euler and results."""
from .result import Result
from .simulation import Simulation, SimulationError

__all__ = ["Simulation", "SimulationError", "Result"]
