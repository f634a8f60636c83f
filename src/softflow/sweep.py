"""Design studies: one Simulation run over many parameter variants.

``sf.sweep(sim, params)`` runs a compiled :class:`~softflow.Simulation` once per
variant with run-time parameters (``sim.run(params=variant)``, see
:mod:`softflow.solve.params`: nothing is recompiled, the System is not
touched), samples the chosen outputs on one time grid and returns a
:class:`SweepResult` (``.to_xarray()``, ``.to_dataframe()``).

``params`` is a grid, ``{"tube.diameter": [...], "tank.volume": [...]}`` (the
Cartesian product of the lists; the last key varies fastest), or an explicit
list of variants ``[{"tube.diameter": ...}, ...]``. A grid's list may be a
dict ``{coordinate: value}`` to label values that are not numbers (curves,
waveforms): ``{"act.curve": {15e3: curve_15, 22e3: curve_22}}``.

Engines
-------
``"serial"``
    A loop of ``sim.run(params=v, raise_on_failure=False)`` in this process, on
    ``sim`` itself (afterwards ``sim.result``, and the paper's
    ``system.get(label).get(name)``, hold the last variant's run; the
    parameters are back to the compiled values).
``"processes"``
    :class:`concurrent.futures.ProcessPoolExecutor` with ``workers`` processes
    (default: the CPU count). The Simulation is pickled once (it pickles as its
    definition) and each worker unpickles, so recompiles, it once through the
    pool's initializer; variants go to the workers in chunks.
``"dask"``
    A :class:`dask.distributed.Client` (``client=``; a real cluster needs only
    ``Client("tcp://scheduler:8786")``), or by default a ``LocalCluster`` of
    ``workers`` single-threaded worker processes started for the sweep and
    closed after it. The pickled Simulation is scattered to every worker once;
    chunks of variants are tasks that Dask's scheduler places. Each worker
    thread unpickles the Simulation once per sweep. Needs the ``dask`` extra:
    ``pip install 'softflow[dask]'``.
``"batched"``
    The variants solved together as one vectorized network by
    :mod:`softflow.solve.batched` (``_run_batched(sim, variants, progress=)``:
    one Result-like object per variant, in order, each with ``times``,
    ``status``, ``message``, ``warnings`` and ``get(label, name)``). Each
    variant meets the tolerance on its own: within the tolerance of, not
    bitwise equal to, its serial run. Where the compiled step loop serves
    the scene (adaptive, library components, no per-step heat-transfer
    correlation: :mod:`softflow.solve.variants`), each
    variant is its own run in that loop, taking exactly the steps its own
    run takes, the variants over two threads (``stats['clocks'] == 'own'``,
    ``stats['engine'] == 'compiled loop'``; sources given as Python functions
    are called back); other scenes (user components, fixed steps,
    ``refine=``, walls whose h A a correlation sets at each step) share one
    step sequence
    (``'shared'``, ``stats['shared_because']`` says why).
    Batched beats processes on many variants of a small scene; on variants
    that are themselves large networks, or widely different ones on shared
    steps, processes (or Dask) may be faster. Its bar is the batched run's,
    in simulated time (on own clocks, the slowest variant's). It checks the variants itself
    (``prepare(sim, variants)``, the same errors) and builds its batches from
    the components that check rebuilt.

The serial, process and Dask engines give the same numbers: each variant is
the same run of the same compiled model (bitwise the same at fixed steps and
with the adaptive BDF).
A variant whose run fails is recorded with its status ``'failed'`` and the
solver's message, NaN past the time it reached, and the sweep goes on.
Every variant is checked before any is run (keys, units, ranges, structure),
with the errors of ``Simulation.run(params=...)`` naming the variant.
"""
from __future__ import annotations

import concurrent.futures
import itertools
import math
import os
import pickle
import re
import sys
import threading
import time
import types
import uuid
import warnings
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Callable, List, Tuple, TypeGuard, Union

import numpy as np

if TYPE_CHECKING:
    import pandas
    import xarray

    from ._typing import Array, ArrayLike
    from .solve.result import Result
    from .solve.simulation import Simulation

    #: (status, message, values (n_outputs, n_times), warnings) of one run
    Outcome = Tuple[str, str, Array, List[str]]

ENGINES = ("serial", "processes", "dask", "batched")
#: An output of a sweep: 'label.variable', or (label, variable)
OutputSpec = Union[str, Tuple[str, str]]

#: points of the default time grid of adaptive runs
DEFAULT_POINTS = 201


# ----------------------------------------------------------------------------------------
# the result
class SweepResult:
    """Outputs of a sweep on one time grid, one row per variant.

    Attributes
    ----------
    variants : list of dict
        The variants in run order, ``{'label.parameter': value}`` as given.
    grid : dict or None
        For a grid sweep, ``{'label.parameter': coordinate values}`` (SI numbers,
        or labels for values that are not numbers), in the grid's order; None for
        an explicit list of variants.
    outputs : list of str
        ``'label.variable'`` names of the sampled outputs.
    units : dict
        ``{output or parameter coordinate: SI unit}`` (``'1'``: dimensionless).
    times : ndarray [s]
        The common time grid.
    data : ndarray, shape (n_variants, n_outputs, n_times)
        The sampled values (NaN where a failed run did not reach).
    status : list of str
        ``'success'`` or ``'failed'`` per variant.
    messages : list of str
        Why a variant failed, or ``''``.
    warnings : list of list of str
        The model-validity warnings of each variant's run (``Result.warnings``).
    coordinate_names : dict
        ``{'label.parameter': name}`` of each parameter's coordinate in
        :meth:`to_xarray` and column in :meth:`to_dataframe`: the key itself, or
        ``'<key> (parameter)'`` where the key is also the name of a result column
        of the scene (``'tank.volume'``, ``'source.pressure'``).
    engine : str
    wall_time : float [s]
        Wall time of the sweep (checks, runs and sampling).
    """

    def __init__(self, variants: list[dict[str, Any]], grid: dict[str, Any] | None,
                 outputs: list[str], units: dict[str, str], times: Array, data: Array,
                 status: list[str], messages: list[str], warnings_: list[list[str]],
                 engine: str, wall_time: float, coords: dict[str, tuple[Any, str | None]],
                 names: dict[str, str]) -> None:
        self.variants = variants
        self.grid = grid
        self.outputs = outputs
        self.units = units
        self.times = times
        self.data = data
        self.status = status
        self.messages = messages
        self.warnings = warnings_
        self.engine = engine
        self.wall_time = wall_time
        self._coords = coords      # {key: (values per variant, unit or None)}
        self.coordinate_names = names

    def __len__(self) -> int:
        return len(self.variants)

    def __repr__(self) -> str:
        failed = sum(s != "success" for s in self.status)
        shape = ("x".join(str(len(v)) for v in self.grid.values()) + " grid"
                 if self.grid is not None else "list")
        return (f"<SweepResult {len(self)} variants ({shape}, engine {self.engine!r}), "
                f"{failed} failed, {len(self.outputs)} outputs x {len(self.times)} times>")

    @property
    def failed(self) -> list[int]:
        """Indices of the variants whose run failed."""
        return [i for i, s in enumerate(self.status) if s != "success"]

    def __getitem__(self, output: str) -> np.ndarray:
        """``sweep_result['tank.pressure']``: that output's values, shape
        (n_variants, n_times), SI units."""
        try:
            k = self.outputs.index(output)
        except ValueError:
            raise KeyError(f"SweepResult: no output {output!r}; the outputs are "
                           f"{_listing(self.outputs)}") from None
        return self.data[:, k, :]

    # -- exports --------------------------------------------------------------------------
    def to_xarray(self) -> xarray.Dataset:
        """An xarray Dataset: for a grid, one dimension per swept parameter (its
        coordinate in SI units, ``units`` in its attributes) and ``time``; for an
        explicit list of variants, dimensions ``variant`` and ``time``, each
        parameter a coordinate along ``variant`` (NaN, or ``''``, where a
        variant does not set it). One data variable per output, named
        ``'label.variable'``, with attributes ``units``, ``component`` and
        ``variable``; ``status`` and ``message`` are coordinates over the
        variants (needs xarray: the xarray extra)."""
        try:
            import xarray as xr
        except ImportError:
            raise ImportError("SweepResult.to_xarray needs xarray, an optional dependency: "
                              "pip install 'softflow[xarray]' (or pip install xarray)") from None
        coords: dict[str, tuple[Any, ...]]
        if self.grid is not None:
            dims = [self.coordinate_names[key] for key in self.grid]
            shape = tuple(len(v) for v in self.grid.values())
            coords = {name: (name, np.asarray(values), self._unit_attrs(key))
                      for name, (key, values) in zip(dims, self.grid.items())}
        else:
            dims = ["variant"]
            shape = (len(self.variants),)
            coords = {"variant": ("variant", np.arange(len(self.variants)))}
            for key, (values, _) in self._coords.items():
                coords[self.coordinate_names[key]] = ("variant", np.asarray(values),
                                                      self._unit_attrs(key))
        coords["time"] = ("time", self.times, {"units": "s"})
        coords["status"] = (dims, np.array(self.status, dtype=object).reshape(shape))
        coords["message"] = (dims, np.array(self.messages, dtype=object).reshape(shape))
        data = {}
        for k, output in enumerate(self.outputs):
            label, _, name = output.rpartition(".")
            data[output] = (dims + ["time"],
                            self.data[:, k, :].reshape(shape + (len(self.times),)),
                            {"units": self.units[output], "component": label,
                             "variable": name})
        attrs = {"engine": self.engine, "variants": len(self.variants),
                 "failed": len(self.failed)}
        return xr.Dataset(data, coords=coords, attrs=attrs)

    def to_dataframe(self) -> pandas.DataFrame:
        """A pandas DataFrame in tidy (long) form: one row per variant and time,
        columns ``variant``, one per swept parameter (SI numbers, or labels),
        ``status``, ``message``, ``time`` and one per output; SI units in
        ``df.attrs['units']``. ``df.melt(id_vars=[...])`` makes it longer still
        (needs pandas: the pandas extra)."""
        try:
            import pandas as pd
        except ImportError:
            raise ImportError("SweepResult.to_dataframe needs pandas, an optional dependency: "
                              "pip install 'softflow[pandas]' (or pip install pandas)"
                              ) from None
        n, nt = len(self.variants), len(self.times)
        columns: dict[str, Any] = {"variant": np.repeat(np.arange(n), nt)}
        for key, (values, _) in self._coords.items():
            columns[self.coordinate_names[key]] = np.repeat(np.asarray(values), nt)
        columns["status"] = np.repeat(np.array(self.status, dtype=object), nt)
        columns["message"] = np.repeat(np.array(self.messages, dtype=object), nt)
        columns["time"] = np.tile(self.times, n)
        for k, output in enumerate(self.outputs):
            columns[output] = self.data[:, k, :].reshape(-1)
        df = pd.DataFrame(columns)
        df.attrs["units"] = {"time": "s", **{self.coordinate_names[key]: unit for key, (_, unit)
                                              in self._coords.items() if unit},
                             **{o: self.units[o] for o in self.outputs}}
        df.attrs["engine"] = self.engine
        return df

    def _unit_attrs(self, key: str) -> dict[str, str]:
        unit = self._coords[key][1]
        return {"parameter": key, **({"units": unit} if unit else {})}


# ----------------------------------------------------------------------------------------
# sweep
def sweep(sim: Simulation, params: Mapping[str, Any] | Sequence[Mapping[str, Any]],
          outputs: OutputSpec | Sequence[OutputSpec] | None = None, engine: str = "serial",
          times: ArrayLike | None = None, progress: bool | None = None, client: Any = None,
          workers: int | None = None) -> SweepResult:
    """Run ``sim`` once per parameter variant and collect the outputs.

    Parameters
    ----------
    sim : Simulation
        Compiled once; each variant is ``sim.run(params=variant)``.
    params : dict of lists, or list of dicts
        A grid ``{'label.parameter': [values]}`` (Cartesian product; a dict
        ``{coordinate: value}`` in place of a list labels the values), or the
        variants themselves ``[{'label.parameter': value, ...}, ...]``. Keys
        and values as in ``Simulation.run(params=...)``: Quantities or SI.
    outputs : sequence of str, optional
        ``'label.variable'`` columns of the runs' Results (``Result.columns()``),
        or ``(label, variable)`` pairs; default all.
    engine : {'serial', 'processes', 'dask', 'batched'}
        See :mod:`softflow.sweep`.
    times : array_like [s] or Quantity, optional
        Common time grid, within [0, duration], increasing. Default: the
        Simulation's own ``times=`` where it was built with them, else the
        fixed step grid (k·step, and the duration) for fixed-step
        Simulations, else 201 points over the duration. Each run's values at
        these times come from its integrator's own interpolant
        (:meth:`softflow.Result.at`: the adaptive BDF's polynomial of the
        step that covers each time, backward Euler's straight line between
        its steps), as accurate as the steps themselves, for every engine (a
        batch in the compiled loop, ``stats['engine'] == 'compiled loop'``,
        keeps each variant's polynomials, and a batch on shared steps its
        own).
    progress : bool, optional
        A tqdm bar over the variants: None shows it where standard error is a
        terminal, True always, False never.
    client : dask.distributed.Client, optional
        The Dask engine's client (default: a LocalCluster started for the sweep).
    workers : int, optional
        Worker processes of the 'processes' engine and of the default
        LocalCluster (default: the CPU count).

    Returns
    -------
    SweepResult
    """
    from .solve.simulation import Simulation
    t_start = time.perf_counter()
    if not isinstance(sim, Simulation):
        raise TypeError(f"sweep: sim must be a softflow Simulation, got {type(sim).__name__}")
    if engine not in ENGINES:
        raise ValueError(f"sweep: unknown engine {engine!r}; the engines are "
                         f"{', '.join(map(repr, ENGINES))}")
    if progress is not None and not isinstance(progress, bool):
        raise TypeError(f"sweep: progress must be True, False or None, got {progress!r}")
    if client is not None and engine != "dask":
        raise ValueError(f"sweep: client= is for engine='dask', not {engine!r}")
    if workers is not None:
        if engine not in ("processes", "dask"):
            raise ValueError(f"sweep: workers= is for engine='processes' or 'dask', "
                             f"not {engine!r}")
        if client is not None:
            raise ValueError("sweep: workers= sizes the LocalCluster that engine='dask' "
                             "starts; with client= the cluster's workers are used")
        if (isinstance(workers, bool) or not isinstance(workers, (int, np.integer))
                or workers < 1):
            raise ValueError(f"sweep: workers must be an integer >= 1, got {workers!r}")
    if engine == "dask":
        _import_distributed()
    batched, prepare = _batched_runner() if engine == "batched" else (None, None)

    variants, grid_values = _variants(params)
    columns, units = _columns(sim)
    outputs = _outputs(outputs, columns)
    times = _times(sim, times)
    # the batched engine checks as the others do, keeping the components it
    # rebuilds for its batches (built once, not twice)
    prepared = _check_variants(sim, variants, prepare)
    coords, grid = _coordinates(sim, variants, grid_values)
    names = {key: f"{key} (parameter)" if key in units else key for key in coords}
    units = {o: units[o] for o in outputs}
    for key, (_, unit) in coords.items():
        if unit:
            units[names[key]] = unit

    n = len(variants)
    bar = _bar(n, progress, engine) if engine != "batched" else None
    try:
        if engine == "serial":
            outcomes = _serial(sim, variants, outputs, times, bar)
        elif engine == "processes":
            outcomes = _processes(sim, variants, outputs, times, bar,
                                  workers or os.cpu_count() or 1)
        elif engine == "dask":
            outcomes = _dask(sim, variants, outputs, times, bar, client,
                             workers or os.cpu_count() or 1)
        else:
            from .solve.simulation import _collector_paused
            from .solve.validity import ModelWarning
            # the batch (a System of every variant's copy, compiled, and its
            # results) is ~30 objects a variant that live until the outputs are
            # read and are garbage then: with the collector paused they are
            # freed by the next young collection, where otherwise they were
            # promoted on the way and set off full collections of the whole
            # heap (~50-150 ms each, every sweep or two of 1 000 variants)
            with warnings.catch_warnings(), _collector_paused():
                warnings.simplefilter("ignore", ModelWarning)
                # one run of all the variants: its own bar, in simulated time
                assert batched is not None
                results = (batched(sim, variants, progress=progress) if prepared is None
                           else batched(sim, variants, progress=progress, prepared=prepared))
                if len(results) != n:
                    raise RuntimeError(f"sweep: the batched engine returned {len(results)} "
                                       f"results for {n} variants")
                outcomes = [_outcome(r, outputs, times, v)
                            for r, v in zip(results, _sample(results, outputs, times))]
                del results
    finally:
        if bar is not None:
            bar.close()

    data = np.stack([o[2] for o in outcomes]) if n else np.empty((0, len(outputs), len(times)))
    status = [o[0] for o in outcomes]
    messages = [o[1] for o in outcomes]
    warned = [o[3] for o in outcomes]
    if any(warned):
        from .solve.validity import ModelWarning
        k = sum(bool(w) for w in warned)
        first = next(w for w in warned if w)[0]
        warnings.warn(f"sweep: {k} of {n} variants raised model-validity warnings (see "
                      f"SweepResult.warnings), e.g.: {first}", ModelWarning, stacklevel=2)
    return SweepResult(variants, grid, outputs, units, times, data, status, messages,
                       warned, engine, time.perf_counter() - t_start, coords, names)


# ----------------------------------------------------------------------------------------
# input
def _listing(names: Iterable[str], most: int = 30) -> str:
    names = list(names)
    return ", ".join(map(repr, names[:most])) + (", ..." if len(names) > most else "")


def _variants(params: Any) -> tuple[list[dict[str, Any]],
                                   dict[str, tuple[list[Any], list[Any] | None]] | None]:
    """(variants, grid) from a grid dict or a list of dicts; grid is
    {key: (values, coordinate labels or None)} or None."""
    if isinstance(params, Mapping):
        if not params:
            raise ValueError("sweep: params is an empty grid; give {'label.parameter': "
                             "[values, ...]}")
        grid = {}
        for key, values in params.items():
            if not isinstance(key, str):
                raise KeyError(f"sweep: params key {key!r} is not 'label.parameter' "
                               "(e.g. 'tube.diameter')")
            labels = None
            if isinstance(values, Mapping):
                labels = list(values.keys())
                values = list(values.values())
            elif isinstance(values, (str, bytes)) or not _is_sequence(values):
                raise TypeError(f"sweep: params[{key!r}] must be a list of values (a grid "
                                f"axis), got {values!r}; for a single value use [value]")
            else:
                values = list(values)
            if not values:
                raise ValueError(f"sweep: params[{key!r}] is empty: the grid has no "
                                 "variants")
            grid[key] = (values, labels)
        keys = list(grid)
        variants = [dict(zip(keys, combo))
                    for combo in itertools.product(*(grid[k][0] for k in keys))]
        return variants, grid
    if isinstance(params, (str, bytes)) or not _is_sequence(params):
        raise TypeError("sweep: params must be a grid {'label.parameter': [values]} or a "
                        f"list of variants [{{'label.parameter': value}}, ...], got "
                        f"{type(params).__name__}")
    variants = list(params)
    if not variants:
        raise ValueError("sweep: params is an empty list of variants")
    for i, v in enumerate(variants):
        if not isinstance(v, Mapping):
            raise TypeError(f"sweep: variant {i} must be a dict {{'label.parameter': "
                            f"value}}, got {v!r}")
    return [dict(v) for v in variants], None


def _is_sequence(values: Any) -> bool:
    if isinstance(values, Sequence) or isinstance(values, np.ndarray):
        return True
    # a pint Quantity holding an array
    return hasattr(values, "magnitude") and np.ndim(values.magnitude) == 1


def _describe_variant(i: int, n: int, variant: Mapping[str, Any]) -> str:
    shown = ", ".join(f"{k}={_short(v)}" for k, v in variant.items())
    return f"variant {i} of {n} ({shown})"


def _short(value: Any) -> str:
    if hasattr(value, "magnitude") and hasattr(value, "units"):
        return f"{value:~P}"
    text = repr(value) if isinstance(value, str) else str(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _check_variants(sim: Simulation, variants: list[dict[str, Any]],
                    check: Callable[..., Any] | None = None) -> Any:
    """Put each variant's parameters in force once, as a run would (keys, units,
    ranges and structure checked by :mod:`softflow.solve.params` and
    ``Assembly.replace``: ~0.2 ms a variant), then the compiled values back;
    or ``check(sim, variants)`` (the batched engine's, which keeps the
    components it rebuilds) and its return value. Errors name the variant."""
    n = len(variants)
    try:
        if check is not None:
            return check(sim, variants)
        sim.check_params(*variants)
        return None
    except Exception as err:
        i = getattr(err, "variant_index", 0)
        raise _renamed(err, f"sweep: {_describe_variant(i, n, variants[i])}: "
                            f"{_message(err)}") from err


def _message(err: BaseException) -> str:
    return err.args[0] if isinstance(err, KeyError) and err.args else str(err)


def _renamed(err: BaseException, message: str) -> BaseException:
    """An exception of ``err``'s type with ``message`` (ValueError where the type
    takes other arguments)."""
    try:
        new = type(err)(message)
    except Exception:
        new = ValueError(message)
    return new


def _columns(sim: Simulation) -> tuple[list[str], dict[str, str]]:
    """The Result columns of ``sim``'s runs and their units, without running."""
    probe = sim.probe()
    units = probe.units()
    units.pop("time")
    return probe.columns(), units


def _is_label_pair(o: object) -> TypeGuard[tuple[str, str]]:
    return isinstance(o, tuple) and len(o) == 2 and all(isinstance(x, str) for x in o)


def _outputs(outputs: OutputSpec | Sequence[OutputSpec] | None,
             columns: Sequence[str]) -> list[str]:
    if outputs is None:
        return list(columns)
    given: Sequence[OutputSpec] = (
        [outputs] if isinstance(outputs, str) or _is_label_pair(outputs)
        else outputs)  # type: ignore[assignment]
    # ('tank', 'pressure'), as sf.assess and Result.get take it, is 'tank.pressure'
    names = [".".join(o) if _is_label_pair(o) else str(o) for o in given]
    if not names:
        raise ValueError("sweep: outputs is empty; give 'label.variable' names, or None "
                         "for all")
    for o in names:
        if o not in columns:
            raise KeyError(f"sweep: unknown output {o!r}; the outputs are {_listing(columns)}")
    if len(set(names)) != len(names):
        raise ValueError(f"sweep: outputs repeat a name: {names}")
    return names


def _times(sim: Simulation, times: ArrayLike | None) -> Array:
    from .units import to_si
    T = sim.duration
    if times is None and getattr(sim, "times_requested", None) is not None:
        return np.asarray(sim.times_requested, dtype=float)
    if times is None:
        if not sim.adaptive:
            # the fixed-step integrator's grid t_k = k * step, ending on the duration
            n = max(1, int(math.ceil(T / sim.step - 1e-9)))
            grid = np.minimum(np.arange(n + 1) * sim.step, T)  # type: ignore[operator]  # step: fixed
            grid[-1] = T
            return grid
        return np.linspace(0.0, T, DEFAULT_POINTS)
    grid = np.atleast_1d(to_si(times, "s", name="times", owner="sweep"))
    if grid.ndim != 1 or not len(grid):
        raise ValueError(f"sweep: times must be a non-empty 1-D array of times, got shape "
                         f"{grid.shape}")
    if not np.all(np.isfinite(grid)) or grid[0] < 0 or grid[-1] > T * (1 + 1e-12):
        raise ValueError(f"sweep: times must lie within [0, {T:.6g}] s (the duration), got "
                         f"{grid.min():.6g}..{grid.max():.6g} s")
    if np.any(np.diff(grid) <= 0):
        raise ValueError("sweep: times must be increasing")
    return grid.astype(float)


def _is_number(value: Any) -> bool:
    if isinstance(value, bool):
        return False
    if hasattr(value, "magnitude") and hasattr(value, "units"):
        return np.ndim(value.magnitude) == 0 and isinstance(
            value.magnitude, (int, float, np.integer, np.floating))
    return isinstance(value, (int, float, np.integer, np.floating))


def _si_unit(sim: Simulation, key: str) -> str | None:
    """The SI unit the constructor expects for parameter ``key``, or None: asked
    of the constructor itself with a value of a dimension no parameter has."""
    from .solve.params import rebuild, split
    from .units import Q_
    try:
        (label, changes), = split({key: None}, sim.asm.where).items()
        comp = sim._compiled[label]
        rebuild(comp, {name: Q_(1.0, "mol") for name in changes})
    except Exception as err:      # the UnitError names the unit: '... [m], got 1 mol'
        found = re.search(r"expects [^\[]*\[([^\]]+)\]", str(err))
        return found.group(1) if found else None
    return None


def _to_si(value: Any, unit: str | None) -> float:
    if hasattr(value, "magnitude") and hasattr(value, "units"):
        return float(value.to(unit).magnitude) if unit else float(
            value.to_base_units().magnitude)
    return float(value)


def _labels(values: Sequence[Any]) -> list[str]:
    """Coordinate labels for values that are not numbers: their text, made unique."""
    text = [_short(v) for v in values]
    if len(set(text)) == len(text):
        return text
    return [f"{t} #{i}" for i, t in enumerate(text)]


def _coordinates(sim: Simulation, variants: list[dict[str, Any]],
                 grid: dict[str, tuple[list[Any], list[Any] | None]] | None
                 ) -> tuple[dict[str, tuple[Any, str | None]], dict[str, Any] | None]:
    """{key: (value per variant, SI unit or None)} and, for a grid, {key: axis}."""
    labels: Any         # a grid axis' coordinate labels; below, an iterator of text labels
    if grid is not None:
        coords, axes = {}, {}
        shape = tuple(len(values) for values, _ in grid.values())
        index = np.unravel_index(np.arange(len(variants)), shape)
        for j, (key, (values, labels)) in enumerate(grid.items()):
            unit = None
            if labels is not None:           # {coordinate: value}: the user's coordinates
                axis = np.asarray(labels)
            elif all(_is_number(x) for x in values):
                unit = _si_unit(sim, key)
                axis = np.array([_to_si(x, unit) for x in values])
            else:
                axis = np.array(_labels(values), dtype=object)
            axes[key] = axis
            coords[key] = (axis[index[j]], unit)
        return coords, axes
    coords = {}
    for key in dict.fromkeys(k for v in variants for k in v):
        given = [v[key] for v in variants if key in v]
        if all(_is_number(x) for x in given):
            unit = _si_unit(sim, key)
            coords[key] = (np.array([_to_si(v[key], unit) if key in v else np.nan
                                     for v in variants]), unit)
        else:
            labels = iter(_labels(given))
            coords[key] = (np.array([next(labels) if key in v else "" for v in variants],
                                    dtype=object), None)
    return coords, None


def _bar(n: int, progress: bool | None, engine: str) -> Any:
    if progress is None:
        isatty = getattr(sys.stderr, "isatty", None)
        progress = bool(isatty and isatty())
    if not progress:
        return None
    from tqdm import tqdm
    return tqdm(total=n, unit="variant", desc=f"sweep ({engine})")


# ----------------------------------------------------------------------------------------
# running one variant (in this process or a worker)
def _outcome(result: Result, outputs: list[str], times: Array,
             values: Array | None = None) -> Outcome:
    """(status, message, values (n_outputs, n_times), warnings) of one run;
    ``values``: its outputs already sampled (the batched engine samples all
    its variants at once), else sampled here, the same way
    (:func:`softflow.solve.batched.sample`)."""
    if values is None:
        values = _sample([result], outputs, times)[0]
    return (result.status, result.message, values,
            [str(w) for w in getattr(result, "warnings", [])])


def _sample(results: Sequence[Any], outputs: list[str], times: Array) -> list[Array]:
    """Each result's ``outputs`` at ``times`` (:func:`softflow.solve.batched.sample`:
    NaN past the end of a run that stopped early), read from the run's own
    interpolant where it has one (:meth:`Result.at`; a batch that shares its
    steps interpolated once for all its variants, each variant of the
    compiled loop its own), else linearly between its points."""
    from .solve.batched import VariantResult, sample
    from .solve.result import Result
    batches: dict[int, Any] = {}
    dense: list[Any] = []
    named = {o.rpartition(".")[0] for o in outputs}
    for r in results:
        if type(r) is VariantResult:
            held = r._result
            # a batch sharing its steps, or its variants each on the compiled
            # loop (each its own interpolant, softflow.solve.variants: the
            # components the outputs name read alone, each variant's)
            if getattr(held, "_dense", None) is not None:
                if id(held) not in batches:
                    labels = None
                    if held.stats.get("engine") == "compiled loop":
                        prefixes = {v._prefix for v in results if type(v) is VariantResult
                                    and v._result is held}
                        labels = [p + n for p in prefixes for n in named
                                  if p + n in held._where]
                    batches[id(held)] = held._at_times(times, labels)
                at = batches[id(held)]
                twin = object.__new__(VariantResult)
                twin.__dict__.update(r.__dict__)
                twin._result, twin.times, twin._n = at, at.times, None
                r = twin
        elif isinstance(r, Result) and getattr(r, "_dense", None) is not None:
            r = r._at_times(times)
        dense.append(r)
    return sample(dense, outputs, times)


def _run_variant(sim: Simulation, variant: dict[str, Any], outputs: list[str],
                 times: Array) -> Outcome:
    from .solve.validity import ModelWarning
    try:
        with warnings.catch_warnings():
            # each run's validity records are kept (SweepResult.warnings) and the
            # sweep warns once, in the caller's process
            warnings.simplefilter("ignore", ModelWarning)
            result = sim.run(params=variant, raise_on_failure=False, progress=False)
        return _outcome(result, outputs, times)
    except Exception as err:     # anything but a solver failure: recorded, not raised
        return ("failed", f"{type(err).__name__}: {err}",
                np.full((len(outputs), len(times)), np.nan), [])


def _run_chunk(sim: Simulation, chunk: list[tuple[int, dict[str, Any]]], outputs: list[str],
               times: Array) -> list[tuple[int, Outcome]]:
    return [(i, _run_variant(sim, variant, outputs, times)) for i, variant in chunk]


def _chunks(variants: list[dict[str, Any]], workers: int
            ) -> list[list[tuple[int, dict[str, Any]]]]:
    size = max(1, min(64, math.ceil(len(variants) / (4 * workers))))
    indexed = list(enumerate(variants))
    return [indexed[k:k + size] for k in range(0, len(indexed), size)]


def _serial(sim: Simulation, variants: list[dict[str, Any]], outputs: list[str],
            times: Array, bar: Any) -> list[Outcome]:
    out = []
    try:
        for variant in variants:
            out.append(_run_variant(sim, variant, outputs, times))
            if bar is not None:
                bar.update(1)
    finally:
        sim._set_parameters(None)
    return out


def _lost(chunk: list[tuple[int, dict[str, Any]]], err: BaseException, outputs: list[str],
          times: Array) -> list[tuple[int, Outcome]]:
    """Outcomes of a chunk whose worker failed (not the run: the process)."""
    message = f"worker failed: {type(err).__name__}: {err}"
    return [(i, ("failed", message, np.full((len(outputs), len(times)), np.nan), []))
            for i, _ in chunk]


# -- processes ------------------------------------------------------------------------------
_WORKER_SIM: Any = None         # the Simulation, once _init_worker has run


def _init_worker(blob: bytes) -> None:
    global _WORKER_SIM
    _WORKER_SIM = pickle.loads(blob)


def _worker_chunk(chunk: list[tuple[int, dict[str, Any]]], outputs: list[str],
                  times: Array) -> list[tuple[int, Outcome]]:
    return _run_chunk(_WORKER_SIM, chunk, outputs, times)


def _pickled(sim: Simulation, engine: str) -> bytes:
    """The Simulation as it travels to workers (its definition, recompiled there)."""
    try:
        return pickle.dumps(sim.without_result())
    except Exception as err:
        raise TypeError(f"sweep: engine={engine!r} sends the Simulation to its workers by "
                        f"pickle, and this one does not pickle ({type(err).__name__}: {err}); "
                        "define user components and functions at module level, or use "
                        "engine='serial'") from err


def _processes(sim: Simulation, variants: list[dict[str, Any]], outputs: list[str],
               times: Array, bar: Any, workers: int) -> list[Outcome]:
    blob = _pickled(sim, "processes")
    chunks = _chunks(variants, workers)
    out: list[Any] = [None] * len(variants)
    with concurrent.futures.ProcessPoolExecutor(
            max_workers=min(workers, len(chunks)), initializer=_init_worker,
            initargs=(blob,)) as pool:
        futures = {pool.submit(_worker_chunk, chunk, outputs, times): chunk
                   for chunk in chunks}
        _gather(concurrent.futures.as_completed(futures), lambda f: futures[f], out,
                outputs, times, bar)
    return out


def _gather(completed: Any, chunk_of: Any, out: list[Any], outputs: list[str],
            times: Array, bar: Any) -> None:
    """Put the outcomes of finished chunks (futures of either engine, as they
    complete) in their places; a chunk whose worker failed is recorded as lost."""
    for future in completed:
        chunk = chunk_of(future)
        try:
            done = future.result()
        except Exception as err:
            done = _lost(chunk, err, outputs, times)
        for i, outcome in done:
            out[i] = outcome
        if bar is not None:
            bar.update(len(chunk))


# -- dask ---------------------------------------------------------------------------------
def _import_distributed() -> Any:
    try:
        import distributed
    except ImportError as err:
        raise ImportError("sweep: engine='dask' needs dask.distributed, an optional "
                          "dependency: pip install 'softflow[dask]' (or pip install "
                          f"'dask[distributed]'); import failed: {err}") from None
    return distributed


# per worker thread: (sweep token, Simulation), so that threads never share a model
_LOCAL = threading.local()


def _dask_chunk(chunk: list[tuple[int, dict[str, Any]]], blob: Any, token: str,
                outputs: list[str], times: Array) -> list[tuple[int, Outcome]]:
    held = getattr(_LOCAL, "sim", None)
    if held is None or held[0] != token:
        _LOCAL.sim = held = (token, pickle.loads(blob))
    return _run_chunk(held[1], chunk, outputs, times)


def _dask(sim: Simulation, variants: list[dict[str, Any]], outputs: list[str], times: Array,
          bar: Any, client: Any, workers: int) -> list[Outcome]:
    distributed = _import_distributed()
    own = client is None
    cluster: Any = None
    if own:
        import logging
        with warnings.catch_warnings():
            # its HTTP server moves to a free port where 8787 is taken, saying so
            warnings.filterwarnings("ignore", message="Port .* is already in use")
            cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1,
                                               processes=True, dashboard_address=None,
                                               silence_logs=logging.ERROR)
        client = distributed.Client(cluster)
    try:
        n_workers = max(1, len(client.scheduler_info().get("workers", {})))
        chunks = _chunks(variants, n_workers)
        blob = client.scatter(_pickled(sim, "dask"), broadcast=True)
        token = uuid.uuid4().hex
        futures = client.map(_dask_chunk, chunks, blob=blob, token=token, outputs=outputs,
                             times=times, pure=False)
        which = {f.key: chunk for f, chunk in zip(futures, chunks)}
        out: list[Any] = [None] * len(variants)
        _gather(distributed.as_completed(futures), lambda f: which[f.key], out, outputs,
                times, bar)
        return out
    finally:
        if own:
            client.close()
            cluster.close()


# -- batched ------------------------------------------------------------------------------
def _batched_runner() -> tuple[Callable[..., Any], Callable[..., Any] | None]:
    """The batched engine's ``_run_batched`` and, where it has one, its ``prepare``
    (which checks the variants and keeps what its runs reuse)."""
    import importlib
    import importlib.util
    if importlib.util.find_spec("softflow.solve.batched") is None:
        raise NotImplementedError("sweep: engine='batched' needs softflow.solve.batched "
                                  "(_run_batched), which this softflow does not have yet; "
                                  "use engine='processes' or 'dask'")
    module = importlib.import_module("softflow.solve.batched")
    runner = getattr(module, "_run_batched", None)
    if runner is None:
        raise NotImplementedError("sweep: engine='batched': softflow.solve.batched has no "
                                  "_run_batched(sim, variants)")
    return runner, getattr(module, "prepare", None)


# ----------------------------------------------------------------------------------------
# ``import softflow.sweep`` makes the package attribute ``softflow.sweep`` this module
# (the import system sets it), where ``sf.sweep`` is otherwise the function: the module
# is callable as the function, so ``sf.sweep(sim, params)`` works either way.
class _CallableModule(types.ModuleType):
    def __call__(self, *args: Any, **kwargs: Any) -> SweepResult:
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
