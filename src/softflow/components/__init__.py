"""The component library (vectorized, analytic Jacobians)."""
from .actuators import Actuator, HystereticActuator
from .base import LibraryComponent
from .chambers import Container, LinearAccumulator
from .sources import MassFlowSource, PressureSource, VolumeFlowSource
from .tubes import CircularTube, InertialCircularTube
from .valves import CheckValve, Orifice, SnappingValve, TeslaValve

__all__ = ["LibraryComponent", "PressureSource", "MassFlowSource", "VolumeFlowSource",
           "CircularTube", "InertialCircularTube", "Container", "LinearAccumulator",
           "Orifice", "CheckValve", "TeslaValve", "SnappingValve",
           "Actuator", "HystereticActuator"]
