"""Type aliases of the public API's annotations.

Imported only under ``typing.TYPE_CHECKING`` (with ``from __future__ import
annotations`` the hints stay strings), so they cost nothing at run time.
"""
from __future__ import annotations

from typing import Any, Callable, Union

import numpy as np
import numpy.typing as npt
from pint import Quantity

from .correlations.heat_transfer import FreeConvection
from .curves.pvcurve import PVCurve
from .curves.waveforms import Waveform

#: A float array, as the kernels and results hold values (SI units).
Array = npt.NDArray[np.float64]
#: A bool array (a mask, e.g. which actuators are on a branch).
BoolArray = npt.NDArray[np.bool_]
#: Plain numbers or arrays in SI units (no Quantity), as the fluid properties take them.
SIArrayLike = npt.ArrayLike
#: A parameter: a pint Quantity or a plain number taken to be in SI units.
Scalar = Union[float, Quantity]
#: Values that may be arrays: array-likes in SI units, or a Quantity holding them.
ArrayLike = Union[npt.ArrayLike, Quantity]
#: A point of a synthetic PV curve: (volume [m^3], pressure [Pa]), floats or Quantities.
PVPoint = tuple[Scalar, Scalar]
#: A source's value: constant (Quantity or SI), a waveform, or a function of time [s].
Input = Union[float, Quantity, Waveform, Callable[[float], Any]]
#: A PV curve: a PVCurve (or an object with its ``fdf_volume``), or a function V -> p.
Curve = Union[PVCurve, Callable[[Any], Any]]
#: A wall's heat-transfer coefficient: a number [W/(m^2 K)] or a correlation.
HeatTransfer = Union[float, Quantity, FreeConvection]

__all__ = ["Array", "ArrayLike", "BoolArray", "Curve", "HeatTransfer", "Input", "PVPoint",
           "Quantity", "SIArrayLike", "Scalar"]
