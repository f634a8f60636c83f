"""Type aliases of the public API's annotations.

Imported only under ``typing.TYPE_CHECKING`` (with ``from __future__ import
annotations`` the hints stay strings), so they cost nothing at run time.
"""
from __future__ import annotations

from typing import Union

import numpy as np
import numpy.typing as npt
from pint import Quantity

#: A float array, as the kernels and results hold values (SI units).
Array = npt.NDArray[np.float64]
#: A parameter: a pint Quantity or a plain number taken to be in SI units.
Scalar = Union[float, Quantity]
#: Values that may be arrays: array-likes in SI units, or a Quantity holding them.
ArrayLike = Union[npt.ArrayLike, Quantity]

__all__ = ["Array", "ArrayLike", "Quantity", "Scalar"]
