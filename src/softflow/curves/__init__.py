"""PV curves and data files with units."""
from . import pvcurve
from .csvdata import DataFileError, read_table
from .pvcurve import PVCurve

__all__ = ["pvcurve", "PVCurve", "read_table", "DataFileError"]
