"""The package's single pint registry and the conversions at its boundary.

Everything public accepts either a pint Quantity or a plain number, which is
then taken to be in SI units. Inside softflow every value is a plain SI float
or NumPy array: pint never appears in a hot loop.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import pint


def _registry() -> pint.UnitRegistry:
    """pint's registry with its parsed unit definitions cached on disk by pint
    itself (``cache_folder=':auto:'``, the user's cache directory): parsing
    them costs each process ~0.12 s of CPU, loading the cache ~0.01 s. Where
    the cache cannot be written or read (no writable home, a cache file
    another process is still writing: pint writes in place), the registry is
    built without it, as before."""
    try:
        return pint.UnitRegistry(cache_folder=":auto:")
    except Exception:       # OSError, a truncated pickle (EOFError, UnpicklingError), ...
        return pint.UnitRegistry()


ureg: pint.UnitRegistry = _registry()
Q_ = ureg.Quantity

#: SI unit of each physical quantity name used by Variables and results.
QUANTITY_UNITS = {
    "pressure": "Pa",
    "massflow": "kg/s",
    "mass": "kg",
    "volume": "m**3",
    "volumeflow": "m**3/s",
    "temperature": "K",
    "length": "m",
    "time": "s",
    "density": "kg/m**3",
    "energy": "J",
    "energyflow": "W",
    "heatflow": "W",
}

_DIMENSION_WORDS = {
    "[length]": "a length",
    "[mass]": "a mass",
    "[time]": "a time",
    "[temperature]": "a temperature",
    "[length] ** 3": "a volume",
    "[mass] / [length] / [time] ** 2": "a pressure",
    "[mass] / [time]": "a mass flow",
    "[length] ** 3 / [time]": "a volume flow",
    "[mass] / [length] ** 3": "a density",
    "[mass] / [length] / [time]": "a dynamic viscosity",
    "[length] ** 2 / [time] ** 2 / [temperature]": "a specific heat",
    "[mass] * [length] ** 2 / [time] ** 2": "an energy",
    "[length] ** 4 * [time] ** 2 / [mass]": "a compliance (volume per pressure)",
    "": "a dimensionless number",
}


class UnitError(ValueError):
    """A value was given with units of the wrong dimension, or an unknown unit."""


def describe_dimension(unit: str) -> str:
    """Human words for the dimension of ``unit``, e.g. 'a length [m]'."""
    dim = str(ureg.Unit(unit).dimensionality)
    words = _DIMENSION_WORDS.get(dim, f"dimension {dim}")
    return f"{words} [{unit}]"


def to_si(value: Any, unit: str, *, name: str, owner: str | None = None) -> Any:  # float | Array
    """Convert ``value`` to the SI ``unit`` and return a float or ndarray.

    Parameters
    ----------
    value : float, array_like or pint.Quantity
        Plain numbers are taken to be in ``unit`` already.
    unit : str
        Target unit, e.g. ``'m'`` or ``'Pa'``.
    name : str
        Parameter name, used in error messages.
    owner : str, optional
        Who owns the parameter, e.g. ``"CircularTube 'tube'"``.
    """
    tp = type(value)
    if tp is float:
        return value            # a plain SI number, the common case: no pint, no NumPy
    if tp is int:
        return float(value)
    where = f"{owner}: " if owner else ""
    if isinstance(value, pint.Quantity):
        target = ureg.Unit(unit)
        if value.dimensionality != target.dimensionality:
            raise UnitError(
                f"{where}{name} expects {describe_dimension(unit)}, got {value:~P}"
            )
        mag = value.to(target).magnitude
    elif isinstance(value, str):
        raise UnitError(
            f"{where}{name} expects {describe_dimension(unit)} as a number or a "
            f"pint Quantity, got the string {value!r} (use sf.Q_({value!r}))"
        )
    else:
        mag = value
    if np.ndim(mag) == 0:
        try:
            return float(mag)
        except (TypeError, ValueError):
            raise UnitError(
                f"{where}{name} expects {describe_dimension(unit)}, got {value!r}"
            ) from None
    return np.asarray(mag, dtype=float)


def to_quantity(values: Any, quantity: str) -> pint.Quantity:
    """Attach the SI unit of a quantity name (see QUANTITY_UNITS) to values."""
    unit = QUANTITY_UNITS.get(quantity)
    if unit is None:
        return Q_(values, "dimensionless")
    return Q_(values, unit)


def quantity_unit(quantity: str) -> str | None:
    """SI unit string for a quantity name, or None if it is not a known one."""
    return QUANTITY_UNITS.get(quantity)
