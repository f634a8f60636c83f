"""PV curves and data files with units."""
from . import pvcurve
from .csvdata import DataFileError, read_table
from .hysteresis import HysteresisLoop
from .pvcurve import PVCurve

__all__ = ["pvcurve", "PVCurve", "HysteresisLoop", "read_table", "DataFileError"]
