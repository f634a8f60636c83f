"""Fluids behind one protocol (see :class:`softflow.fluids.base.Fluid`)."""
from .base import Fluid
from .ideal import ConstantLiquid, IdealGas, air, nitrogen, water

__all__ = ["Fluid", "IdealGas", "ConstantLiquid", "air", "nitrogen", "water"]
