"""Property tables for the 'table' level: where they lie, and loading them with checks.

A table is two files in the tables directory: ``STEM.npz`` (the grid axes and each
property's values on the grid, from CoolProp) and ``STEM.json`` (metadata: fluid,
CoolProp version, pressure and temperature range, grid, the interpolation error
measured against CoolProp on off-grid points, and the SHA-256 of the npz file).
Loading refuses a file whose hash does not match (corrupt or edited), a table of
another format, or one built with another CoolProp version (set the environment
variable ``SOFTFLOW_FLUID_TABLES_ANY_COOLPROP=1`` to accept that with a warning).

Rebuild with ``python -m softflow.fluids.tables build`` (see ``--help``).
"""
from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path

import numpy as np

from ..base import FluidError
from ..hermite import Bicubic, UniformAxis

#: Environment variable naming the tables directory (overrides the default).
TABLES_ENV = "SOFTFLOW_FLUID_TABLES"
#: Set to 1 to accept tables built with another CoolProp version (with a warning).
ANY_COOLPROP_ENV = "SOFTFLOW_FLUID_TABLES_ANY_COOLPROP"
#: Version of the file layout; loading refuses other versions.
FORMAT = 1


class FluidTableError(FluidError):
    """A table file is missing, corrupt, of another format or from another CoolProp."""


def default_directory() -> Path:
    """``softflow/fluids/fluid_tables/``: the tables shipped inside the package (package
    data), so a wheel or a non-editable install has them as an editable one does."""
    return Path(__file__).resolve().parent.parent / "fluid_tables"


def tables_directory(explicit=None) -> Path:
    """The directory the table level reads: ``explicit``, else ``$SOFTFLOW_FLUID_TABLES``,
    else the package's own ``fluid_tables/`` (:func:`default_directory`)."""
    if explicit is not None:
        return Path(explicit)
    env = os.environ.get(TABLES_ENV)
    return Path(env) if env else default_directory()


def coolprop_version() -> str:
    """The installed CoolProp's version, read from its package metadata (importing
    CoolProp costs seconds: a table-level scene, or its error, need not)."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("CoolProp")
    except PackageNotFoundError:
        import CoolProp
        return CoolProp.__version__


def sha256_of(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


class PropertyTable:
    """Property values of one fluid on a uniform (p, T) grid, with their interpolants.

    Attributes
    ----------
    meta : dict
        The JSON metadata.
    p_axis, T_axis : UniformAxis
        Pressure [Pa] and temperature [K] axes.
    """

    def __init__(self, meta: dict, values: dict, path: Path):
        self.meta, self.path = meta, path
        grid = meta["grid"]
        self.p_axis = UniformAxis(*meta["pressure_range"], grid["pressure_nodes"])
        self.T_axis = UniformAxis(*meta["temperature_range"], grid["temperature_nodes"])
        self.values = values
        self._interpolants: dict = {}
        self._slices: dict = {}

    @property
    def p_range(self):
        return self.p_axis.lo, self.p_axis.hi

    @property
    def T_range(self):
        return self.T_axis.lo, self.T_axis.hi

    @property
    def properties(self):
        return tuple(self.values)

    def interpolant(self, key: str) -> Bicubic:
        """The C1 interpolant of a tabulated property (built on first use)."""
        found = self._interpolants.get(key)
        if found is None:
            found = self._interpolants[key] = Bicubic(self.p_axis, self.T_axis,
                                                      self.values[key])
        return found

    def slice(self, key: str, temperature: float):
        """The interpolant at one temperature: a piecewise cubic in p (isothermal scenes)."""
        found = self._slices.get((key, temperature))
        if found is None:
            found = self._slices[(key, temperature)] = \
                self.interpolant(key).slice_at_y(temperature)
        return found

    def error_bound(self, key: str) -> float:
        """Recorded bound on the interpolation error of ``key`` (see the metadata)."""
        return self.meta["properties"][key]["error_bound"]


_CACHE: dict = {}


def table_files(stem: str, directory) -> tuple[Path, Path]:
    d = Path(directory)
    return d / f"{stem}.npz", d / f"{stem}.json"


def load_table(spec, tables_dir=None) -> PropertyTable:
    """The checked table of a fluid spec (cached while the files are unchanged)."""
    directory = tables_directory(tables_dir)
    npz_path, json_path = table_files(spec.table_stem, directory)
    if not json_path.exists() or not npz_path.exists():
        have = sorted(p.stem for p in directory.glob("*.json")) if directory.is_dir() else []
        frac = "" if spec.fraction is None else f" --fraction {spec.fraction:g}"
        raise FluidTableError(
            f"fluid {spec.name!r}: no table {spec.table_stem!r} in {directory} (tables "
            f"there: {', '.join(have) or 'none'}); build it with `python -m "
            f"softflow.fluids.tables build {spec.name}{frac}`, point {TABLES_ENV} or "
            f"tables_dir= at a directory that has it, or use level='eos'")
    stat = npz_path.stat(), json_path.stat()
    key = (str(npz_path.resolve()), tuple((s.st_mtime_ns, s.st_size) for s in stat))
    table = _CACHE.get(key)
    if table is None:
        table = _CACHE[key] = read_table(npz_path, json_path)
    expected = spec.coolprop_id
    if table.meta.get("coolprop_id") != expected:
        raise FluidTableError(f"{json_path}: table is for {table.meta.get('coolprop_id')!r}, "
                              f"not {expected!r}")
    return table


def read_table(npz_path: Path, json_path: Path) -> PropertyTable:
    """Read and check one table (hash, format, CoolProp version, array shapes)."""
    rebuild = "rebuild it with `python -m softflow.fluids.tables build`"
    try:
        meta = json.loads(Path(json_path).read_text())
    except (OSError, ValueError) as err:
        raise FluidTableError(f"{json_path}: unreadable table metadata ({err}); {rebuild}") \
            from None
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        got = meta.get("format") if isinstance(meta, dict) else None
        raise FluidTableError(f"{json_path}: table format {got!r}, this softflow reads "
                              f"format {FORMAT}; {rebuild}")
    digest = sha256_of(npz_path)
    if digest != meta.get("sha256"):
        raise FluidTableError(f"{npz_path}: corrupt or modified table (SHA-256 {digest[:12]}... "
                              f"does not match {str(meta.get('sha256'))[:12]}... recorded in "
                              f"{json_path.name}); {rebuild}")
    built, installed = meta.get("coolprop_version"), coolprop_version()
    if built != installed:
        msg = (f"{json_path}: table was built with CoolProp {built}, but CoolProp "
               f"{installed} is installed; {rebuild}")
        # a patch release (8.0.0 -> 8.0.1) keeps the table usable, with a warning;
        # another minor or major version is refused unless the user says otherwise
        same_minor = str(built).split(".")[:2] == str(installed).split(".")[:2]
        if not same_minor and os.environ.get(ANY_COOLPROP_ENV) != "1":
            raise FluidTableError(msg + f" (or set {ANY_COOLPROP_ENV}=1 to use it anyway)")
        warnings.warn(msg, stacklevel=3)
    try:
        with np.load(npz_path) as data:
            values = {k: np.array(data[k], dtype=float) for k in meta["properties"]
                      if k in data.files}
    except (OSError, ValueError, KeyError) as err:
        raise FluidTableError(f"{npz_path}: unreadable table ({err}); {rebuild}") from None
    shape = (meta["grid"]["pressure_nodes"], meta["grid"]["temperature_nodes"])
    derived = {k for k, v in meta["properties"].items() if v.get("derived")}
    for k in meta["properties"]:
        if k in derived:
            continue
        if k not in values or values[k].shape != shape or not np.all(np.isfinite(values[k])):
            raise FluidTableError(f"{npz_path}: property {k!r} missing, not of shape {shape} "
                                  f"or not finite; {rebuild}")
    return PropertyTable(meta, values, Path(npz_path))
