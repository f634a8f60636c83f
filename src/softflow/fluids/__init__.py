"""Fluids behind one protocol (:class:`softflow.fluids.base.Fluid`), at three levels.

- ``ideal``: ideal gas with constant cp, or constant-property liquid (the paper's model).
- ``table``: C1 interpolation of CoolProp tables in ``fluid_tables/``.
- ``eos``: CoolProp itself (the reference).

``Fluid('Air', level='table', temperature=Q_(20, 'degC'))`` makes one; the built-ins
``air``, ``nitrogen``, ``water``, ``ethylene_glycol`` are at level ``ideal`` (20 degC);
``air.with_level('table')`` and ``air.at(temperature=...)`` give variants.
"""
from .base import PROPERTY_UNITS, Fluid, FluidError
from .catalog import GLYCOL_FRACTION, FluidSpec
from .eos import EosFluid
from .ideal import ConstantLiquid, IdealGas, air, ethylene_glycol, nitrogen, water
from .tables import FluidTableError
from .tabulated import TableFluid

__all__ = ["Fluid", "FluidError", "FluidTableError", "FluidSpec", "IdealGas",
           "ConstantLiquid", "EosFluid", "TableFluid", "air", "nitrogen", "water",
           "ethylene_glycol", "GLYCOL_FRACTION", "PROPERTY_UNITS"]
