"""Scene files: a System (and, optionally, how to run it) in a TOML file.

    from softflow import scene
    scene.save(system, "fill.toml", simulation={"duration": "2 s"})
    system = scene.load("fill.toml")
    sc = scene.read("fill.toml")      # .system, .simulation (keywords), .path; sc.simulate()
    softflow run fill.toml --duration "2 s" --output run.csv

Why TOML: a person reads and edits it (comments, no braces or indentation
rules, no YAML surprises such as ``no`` read as false), every value has one
type, and Python reads it with the standard library (``tomllib``, 3.11; the
``tomli`` backport on 3.10). Writing needs ``tomli-w``, the write half by
tomllib's author: small, pure Python, and it writes exactly the TOML tomllib
reads back.

The format (``format = 1``)::

    format = 1
    connections = [              # each entry: the terminals of one node
        ["source.a", "tube.a"],  # 'label.terminal', or 'label' alone
        ["tube.b", "tank.a"],
    ]

    [simulation]                 # optional: Simulation keywords
    duration = "2 s"

    [fluids.warm_air]            # optional: named fluids (or inline tables)
    name = "air"
    level = "table"
    temperature = "40 degC"

    [components.source]
    type = "PressureSource"
    pressure = { waveform = "Step", time = "0.1 s", before = "1 atm", after = "1.5 bar" }

    [components.tube]
    type = "CircularTube"
    fluid = "air"                # built-in (air, nitrogen, water, ethylene_glycol) or [fluids]
    length = "30 cm"
    diameter = "1 mm"

    [components.tank]
    type = "Actuator"
    fluid = "warm_air"
    curve = { csv = "balloon.csv" }          # path relative to this file
    # or: curve = { volume = [0, 5, 10], volume_unit = "mL",
    #               pressure = [0, 20, 25], pressure_unit = "kPa", gauge = true }

Quantities are strings, ``"30 cm"``, or plain SI numbers; a file loaded and
saved again keeps them as written. A System built in Python is written from
its components' SI values (``"0.3 m"``) and checked by rebuilding every
component from what was written. Python functions (a ``lambda`` waveform, a
callable PV curve) and user-written components cannot be written: save()
names the component and says so.

Errors name the file and the key (``fill.toml: components.tube.diameter
(line 14): ...``).
"""
from __future__ import annotations

import inspect
import math
import re
import sys
import weakref
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .network.system import System
    from .solve.simulation import Simulation

FORMAT = 1
#: the component classes a scene may name
COMPONENT_TYPES = ("PressureSource", "MassFlowSource", "VolumeFlowSource", "CircularTube",
                   "Orifice", "CheckValve", "TeslaValve", "SnappingValve", "Container",
                   "LinearAccumulator", "Actuator", "HystereticActuator")
WAVEFORM_TYPES = ("Constant", "Step", "Ramp", "PiecewiseLinear", "PiecewiseConstant",
                  "Trapezoid", "Sine", "Square", "from_csv")
BUILTIN_FLUIDS = ("air", "nitrogen", "water", "ethylene_glycol")
#: Simulation keywords a [simulation] table may hold, and their units
SIMULATION_KEYS = {"duration": "s", "step": "s", "step_min": "s", "step_max": "s",
                   "rtol": "", "method": None, "max_order": None, "thermal": None,
                   "newton_rtol": "", "linear_solver": None, "allow_unconnected": None,
                   "record": None, "breakpoints": "s", "beyond_limits": None,
                   "max_steps": None}
_SOURCE_SIGNAL = {"PressureSource": ("pressure", "Pa"), "MassFlowSource": ("massflow", "kg/s"),
                  "VolumeFlowSource": ("volumeflow", "m**3/s")}
_CURVE_PARAMS = ("curve", "inflation_curve", "deflation_curve")
_NUMBER = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(.*?)\s*$")

#: the table each component was loaded from (units as written), for save()
_WRITTEN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class SceneError(ValueError):
    """A scene file that cannot be read or a System that cannot be written;
    the message names the file and the key (and line, where known)."""


@dataclass
class Scene:
    """A scene file read: the System, the [simulation] keywords (SI values or
    strings as Simulation takes them) and the file it came from."""
    system: System
    simulation: dict = field(default_factory=dict)
    path: Path | None = None

    def simulate(self, **overrides: Any) -> Simulation:
        """``Simulation(system, **simulation, **overrides)``."""
        from .solve import Simulation
        kw = {**self.simulation, **overrides}
        return Simulation(self.system, **kw)


# -- reading ---------------------------------------------------------------------------------
def _toml_loads(text: str) -> dict:
    if sys.version_info >= (3, 11):
        import tomllib
    else:                                    # pragma: no cover - Python 3.10
        import tomli as tomllib
    return tomllib.loads(text)


class _Reader:
    def __init__(self, text: str, where: str, base: Path) -> None:
        self.text, self.where, self.base = text, where, base
        self.lines = text.splitlines()

    def line_of(self, key: str) -> int | None:
        """Line (1-based) of a dotted key: its table header, then the key in it."""
        parts = key.split(".")
        for n in range(len(parts), 0, -1):
            header = re.compile(r"^\s*\[\s*" + r"\s*\.\s*".join(map(re.escape, parts[:n]))
                                + r"\s*\]\s*(#.*)?$")
            for i, line in enumerate(self.lines):
                if header.match(line):
                    if n == len(parts):
                        return i + 1
                    item = re.compile(r"^\s*" + re.escape(parts[n]) + r"\s*=")
                    for j in range(i + 1, len(self.lines)):
                        if self.lines[j].lstrip().startswith("["):
                            break
                        if item.match(self.lines[j]):
                            return j + 1
                    return i + 1
        item = re.compile(r"^\s*" + re.escape(parts[0]) + r"\s*=")
        for i, line in enumerate(self.lines):
            if item.match(line):
                return i + 1
        return None

    def error(self, key: str, message: str) -> SceneError:
        line = self.line_of(key) if key else None
        at = f" (line {line})" if line else ""
        return SceneError(f"{self.where}: {key}{at}: {message}" if key
                          else f"{self.where}: {message}")


def _quantity(value: Any, unit: str | None, reader: _Reader, key: str) -> Any:
    """A TOML scalar as a Quantity (strings, 'value unit') or an SI float."""
    from .units import Q_, ureg
    if isinstance(value, bool):
        raise reader.error(key, f"expected a number or a quantity such as '1.5 bar', got {value!r}")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str):
        m = _NUMBER.match(value)
        if not m:
            raise reader.error(key, f"expected a quantity such as '1.5 bar', got {value!r}")
        mag, u = float(m.group(1)), m.group(2)
        try:
            q = Q_(mag, u) if u else Q_(mag)
        except Exception as err:
            raise reader.error(key, f"unknown unit {u!r} in {value!r} ({err})") from None
        if unit is not None and q.dimensionality != ureg.Quantity(1, unit).dimensionality:
            raise reader.error(key, f"{value!r} is not {_dimension(unit)} (expected a unit "
                                    f"like {unit!r})")
        return q
    raise reader.error(key, f"expected a number or a quantity string, got {value!r}")


def _dimension(unit: str) -> str:
    from .units import describe_dimension
    return describe_dimension(unit)


def _array(table: dict, name: str, unit: str | None, reader: _Reader, key: str) -> Any:
    """table[name] (a list of numbers) in table[name + '_unit'] (default SI)."""
    from .units import Q_
    values = table.get(name)
    if not isinstance(values, list) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise reader.error(f"{key}.{name}", f"expected a list of numbers, got {values!r}")
    u = table.get(f"{name}_unit")
    if u is None:
        return np.asarray(values, dtype=float)
    q = _quantity(f"1 {u}", unit, reader, f"{key}.{name}_unit")
    return Q_(np.asarray(values, dtype=float), q.units)


def _doc_units(cls: type) -> dict[str, str | None]:
    """Parameter -> SI unit from the class docstring ('name : float [m]'), None
    for non-numeric parameters (str, bool, fluids, curves)."""
    out: dict[str, str | None] = {}
    for line in (inspect.getdoc(cls) or "").splitlines():
        head, sep, desc = line.partition(" : ")
        if not sep or line.startswith(" "):
            continue
        m = re.search(r"\[([^\]]*)\]", desc)
        numeric = desc.startswith(("float", "int")) or (m is not None and not desc.startswith(
            ("{", "str", "bool")))
        unit = None
        if m and numeric:
            unit = m.group(1).strip()
            unit = "" if unit in ("-", "") else unit.replace("^", "**").replace("·", "*")
        for name in head.split(","):
            out[name.strip()] = unit if numeric else None
    return out


def _unit_of(cls: type, name: str) -> str | None:
    unit = _doc_units(cls).get(name)
    if unit is None:
        return None
    from .units import ureg
    try:
        ureg.Quantity(1, unit)
    except Exception:
        return None          # a unit written for people ('SI of the source'): leave to the class
    return unit


def _fluid(value: Any, fluids: dict, reader: _Reader, key: str) -> Any:
    import softflow as sf
    if isinstance(value, str):
        if value in fluids:
            return fluids[value]
        if value in BUILTIN_FLUIDS:
            return getattr(sf, value)
        raise reader.error(key, f"unknown fluid {value!r}; expected one of "
                                f"{', '.join(BUILTIN_FLUIDS + tuple(fluids))} or a table "
                                "{ name = ..., level = ..., temperature = ... }")
    if isinstance(value, dict):
        return _fluid_table(value, reader, key)
    raise reader.error(key, f"expected a fluid name or table, got {value!r}")


def _fluid_table(table: dict, reader: _Reader, key: str) -> Any:
    import softflow as sf
    unknown = set(table) - {"name", "level", "temperature", "fraction", "out_of_range"}
    if unknown:
        raise reader.error(f"{key}.{sorted(unknown)[0]}", "unknown fluid key; expected name, "
                                                          "level, temperature, fraction, out_of_range")
    if "name" not in table:
        raise reader.error(key, "missing field 'name' (e.g. name = \"air\")")
    kw: dict[str, Any] = {"level": table.get("level", "ideal")}
    if "temperature" in table:
        kw["temperature"] = _quantity(table["temperature"], "K", reader, f"{key}.temperature")
    if "fraction" in table:
        kw["fraction"] = _quantity(table["fraction"], "", reader, f"{key}.fraction")
    if "out_of_range" in table:
        kw["out_of_range"] = table["out_of_range"]
    try:
        return sf.Fluid(table["name"], **kw)  # type: ignore[call-arg]  # its metaclass builds it
    except Exception as err:
        raise reader.error(key, f"{type(err).__name__}: {err}") from None


def _curve(value: Any, reader: _Reader, key: str) -> Any:
    import softflow as sf
    if not isinstance(value, dict):
        raise reader.error(key, "expected a curve table: { csv = \"file.csv\" } or "
                                "{ volume = [...], volume_unit = \"mL\", pressure = [...], "
                                "pressure_unit = \"kPa\" }")
    options = {k: v for k, v in value.items() if k not in (
        "csv", "volume", "pressure", "volume_unit", "pressure_unit")}
    try:
        if "csv" in value:
            path = Path(value["csv"])
            path = path if path.is_absolute() else reader.base / path
            if not path.is_file():
                raise reader.error(f"{key}.csv", f"no such file: {path}")
            kw = {k: value[k] for k in ("volume_unit", "pressure_unit") if k in value}
            return sf.PVCurve(path, **kw, **options)
        for name in ("volume", "pressure"):
            if name not in value:
                raise reader.error(key, f"missing field {name!r} (or give csv = \"file.csv\")")
        return sf.PVCurve(volume=_array(value, "volume", "m**3", reader, key),
                          pressure=_array(value, "pressure", "Pa", reader, key), **options)
    except SceneError:
        raise
    except Exception as err:
        raise reader.error(key, f"{type(err).__name__}: {err}") from None


def _waveform(value: dict, unit: str, reader: _Reader, key: str) -> Any:
    from .curves import waveforms
    kind = value.get("waveform")
    if kind not in WAVEFORM_TYPES:
        raise reader.error(f"{key}.waveform", f"unknown waveform {kind!r}; expected one of "
                                              f"{', '.join(WAVEFORM_TYPES)}")
    func = getattr(waveforms, kind)
    params = inspect.signature(func).parameters
    kw: dict[str, Any] = {}
    for name, v in value.items():
        if name == "waveform" or name.endswith("_unit"):
            continue
        if name not in params:
            raise reader.error(f"{key}.{name}", f"{kind} has no parameter {name!r}; it takes "
                                                f"{', '.join(params)}")
        if kind == "from_csv":
            kw[name] = (str(reader.base / v) if name == "path" and not Path(v).is_absolute()
                        else v)
        elif isinstance(v, list):
            kw[name] = _array(value, name, "s" if name == "times" else None, reader, key)
        else:
            u = "s" if name in ("time", "t0", "t1", "rise", "hold", "fall", "start", "period") \
                else "Hz" if name == "frequency" else "" if name == "duty" else None
            kw[name] = _quantity(v, u, reader, f"{key}.{name}")
    try:
        return func(**kw)
    except Exception as err:
        raise reader.error(key, f"{type(err).__name__}: {err}") from None


def _component(label: str, table: dict, fluids: dict, reader: _Reader,
               raw_fluids: dict | None = None) -> Any:
    import softflow as sf
    key = f"components.{label}"
    if not isinstance(table, dict):
        raise reader.error(key, "expected a table [components.LABEL] with type = ...")
    kind = table.get("type")
    if kind is None:
        raise reader.error(key, "missing field 'type' (e.g. type = \"CircularTube\")")
    if kind not in COMPONENT_TYPES:
        raise reader.error(f"{key}.type", f"unknown component type {kind!r}; expected one "
                                          f"of {', '.join(COMPONENT_TYPES)}")
    cls = getattr(sf, kind)
    params = inspect.signature(cls.__init__).parameters
    kw: dict[str, Any] = {}
    unit: str | None
    for name, value in table.items():
        if name == "type":
            continue
        k = f"{key}.{name}"
        if name not in params or name in ("self", "label"):
            raise reader.error(k, f"{kind} has no parameter {name!r}; it takes "
                                  f"{', '.join(p for p in params if p not in ('self', 'label'))}")
        if name == "fluid":
            kw[name] = _fluid(value, fluids, reader, k)
        elif name in _CURVE_PARAMS:
            kw[name] = _curve(value, reader, k)
        elif kind in _SOURCE_SIGNAL and name == _SOURCE_SIGNAL[kind][0]:
            unit = _SOURCE_SIGNAL[kind][1]
            kw[name] = (_waveform(value, unit, reader, k) if isinstance(value, dict)
                        else _quantity(value, None, reader, k))
        else:
            unit = _unit_of(cls, name)
            if unit is not None:
                kw[name] = _quantity(value, unit, reader, k)
            elif isinstance(value, str) and _NUMBER.match(value):
                kw[name] = _quantity(value, None, reader, k)
            else:
                kw[name] = value
    missing = [p.name for p in params.values() if p.name not in ("self", "label")
               and p.default is inspect.Parameter.empty and p.name not in kw
               and p.kind is not p.VAR_KEYWORD]
    if missing:
        raise reader.error(key, f"missing field {missing[0]!r} of {kind} "
                                f"(required: {', '.join(missing)})")
    try:
        comp = cls(label, **kw)
    except Exception as err:
        raise reader.error(key, f"{type(err).__name__}: {err}") from None
    fluid = table.get("fluid")
    raw = (raw_fluids or {}).get(fluid) if isinstance(fluid, str) else None
    _WRITTEN[comp] = (dict(table), reader.base, raw)
    return comp


def _endpoint(spec: Any, system: Any, reader: _Reader, key: str) -> Any:
    if not isinstance(spec, str) or not spec:
        raise reader.error(key, f"expected 'label' or 'label.terminal', got {spec!r}")
    label, _, term = spec.partition(".")
    if label not in system:
        raise reader.error(key, f"dangling connection: no component {label!r} in the scene "
                                f"(components: {', '.join(c.label for c in system)})")
    if not term:
        return label
    comp = system.get(label)
    names = [t.label for t in comp.terminals]
    if term not in names:
        raise reader.error(key, f"dangling connection: {comp.describe()} has no terminal "
                                f"{term!r} (terminals: {', '.join(names)})")
    return (label, term)


def loads(text: str, *, name: str = "<scene>", base: str | Path | None = None) -> Scene:
    """A Scene from TOML text; ``name`` is used in messages, ``base`` resolves
    relative file paths (default: the current directory)."""
    import softflow as sf
    reader = _Reader(text, name, Path(base) if base is not None else Path.cwd())
    try:
        doc = _toml_loads(text)
    except Exception as err:          # tomllib.TOMLDecodeError names line and column
        raise SceneError(f"{name}: not valid TOML: {err}") from None
    unknown = set(doc) - {"format", "connections", "simulation", "fluids", "components"}
    if unknown:
        raise reader.error(sorted(unknown)[0], "unknown top-level key; expected format, "
                                               "connections, simulation, fluids, components")
    fmt = doc.get("format", FORMAT)
    if fmt != FORMAT:
        raise reader.error("format", f"scene format {fmt!r} is not supported (this softflow "
                                     f"reads format {FORMAT})")
    fluids = {n: _fluid_table(t, reader, f"fluids.{n}") if isinstance(t, dict)
              else _fluid(t, {}, reader, f"fluids.{n}")
              for n, t in doc.get("fluids", {}).items()}
    comps = doc.get("components")
    if not comps:
        raise reader.error("", "no [components.LABEL] tables: a scene needs components")
    system = sf.System()
    for label, table in comps.items():
        system += _component(label, table, fluids, reader, doc.get("fluids", {}))
    connections = doc.get("connections", [])
    if not isinstance(connections, list):
        raise reader.error("connections", "expected a list of nodes, e.g. "
                                          "[[\"source.a\", \"tube.a\"], ...]")
    for i, node in enumerate(connections):
        key = f"connections[{i}]"
        if not isinstance(node, list) or len(node) < 2:
            raise reader.error("connections", f"{key}: a node joins at least two terminals, "
                                              f"got {node!r}")
        ends = [_endpoint(s, system, reader, "connections") for s in node]
        try:
            system.connect(*ends)
        except Exception as err:
            raise reader.error("connections", f"{key} {node!r}: {err}") from None
    simulation = _simulation(doc.get("simulation", {}), reader)
    if not simulation.get("allow_unconnected"):
        loose = system.unconnected_terminals()
        if loose:
            raise reader.error("connections", "dangling terminal(s) not connected to anything: "
                                              f"{', '.join(t.name for t in loose)} (connect "
                                              "them, or set allow_unconnected = true in "
                                              "[simulation] to close them)")
    return Scene(system, simulation)


def _simulation(table: dict, reader: _Reader) -> dict:
    out: dict[str, Any] = {}
    for name, value in table.items():
        key = f"simulation.{name}"
        if name not in SIMULATION_KEYS:
            raise reader.error(key, f"unknown Simulation keyword; expected one of "
                                    f"{', '.join(SIMULATION_KEYS)}")
        unit = SIMULATION_KEYS[name]
        if unit is None:
            out[name] = value
        elif isinstance(value, list):
            out[name] = [_quantity(v, unit, reader, key) for v in value]
        else:
            out[name] = _quantity(value, unit, reader, key)
    return out


def read(path: str | Path) -> Scene:
    """The Scene in a TOML file (System, [simulation] keywords, path)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise SceneError(f"{path}: cannot read: {err.strerror or err}") from None
    scene = loads(text, name=str(path), base=path.parent)
    scene.path = path
    return scene


def load(path: str | Path) -> System:
    """The System in a TOML scene file."""
    return read(path).system


# -- writing ---------------------------------------------------------------------------------
def _fmt(value: float | np.floating[Any], unit: str) -> Any:
    """'0.3 m': the shortest text that reads back as the same float."""
    if unit == "":
        return float(value)
    return f"{float(value)!r} {unit.replace('**', '^')}"


def _write_fluid(fluid: Any, owner: str) -> Any:
    import softflow as sf
    for name in BUILTIN_FLUIDS:
        if fluid is getattr(sf, name):
            return name
    spec = getattr(fluid, "spec", None)
    if spec is None:
        raise SceneError(f"{owner}: its fluid {fluid!r} was built by hand (no catalog name); "
                         "a scene file can hold catalog fluids only (sf.Fluid(name, level=...))")
    out: dict[str, Any] = {"name": spec.name, "level": fluid.level,
                           "temperature": _fmt(fluid.temperature, "K")}
    if spec.fraction is not None:
        out["fraction"] = float(spec.fraction)
    options = fluid._level_options() if hasattr(fluid, "_level_options") else {}
    if options.get("out_of_range", "raise") != "raise":
        out["out_of_range"] = options["out_of_range"]
    return out


def _write_curve(curve: Any, owner: str, name: str) -> dict:
    import softflow as sf
    if not isinstance(curve, sf.PVCurve):
        raise SceneError(f"{owner}: {name} is a {type(curve).__name__}, not a PVCurve; a "
                         "Python function cannot be written to a scene file (give the curve "
                         "as sf.PVCurve(volume=..., pressure=...) or a CSV file)")
    out: dict[str, Any] = {"volume": [float(v) for v in curve.volume], "volume_unit": "m**3",
                           "pressure": [float(p) for p in curve.pressure],
                           "pressure_unit": "Pa", "gauge": False}     # absolute
    if curve.extrapolate != "linear":
        out["extrapolate"] = curve.extrapolate
    if getattr(curve, "interpolation", "pchip") != "pchip":
        out["interpolation"] = curve.interpolation
    return out


def _write_waveform(wf: Any, owner: str, name: str, si_unit: str) -> dict:
    """A waveform's table, its values in ``si_unit`` (the input's SI unit)."""
    from .units import ureg
    kind = type(wf).__name__
    if kind not in WAVEFORM_TYPES:
        raise SceneError(f"{owner}: {name} is a {kind} waveform, which a scene file cannot hold")
    unit = "" if wf.unit is None else (
        si_unit if wf.unit.dimensionality == ureg.Unit(si_unit).dimensionality
        else f"{wf.unit:~}")
    out: dict[str, Any] = {"waveform": kind}
    for p in inspect.signature(type(wf).__init__).parameters.values():
        if p.name == "self":
            continue
        v = getattr(wf, p.name, None)
        if v is None:
            if p.default is inspect.Parameter.empty:
                raise SceneError(f"{owner}: {name}: cannot read the {kind}'s {p.name!r}")
            continue
        u = ("s" if p.name in ("time", "t0", "t1", "rise", "hold", "fall", "start", "period",
                               "times")
             else "Hz" if p.name == "frequency" else "" if p.name in ("duty", "phase") else unit)
        if isinstance(v, np.ndarray):
            out[p.name] = [float(x) for x in v]
            if u:
                out[f"{p.name}_unit"] = u
        else:
            out[p.name] = _fmt(v, u)
    return out


def _write_signal(comp: Any, name: str) -> Any:
    from .curves.waveforms import Waveform
    sig = comp.signal
    owner = comp.describe()
    if sig.func is None:
        return _fmt(sig.const, sig.unit)
    if isinstance(sig.func, Waveform):
        return _write_waveform(sig.func, owner, name, sig.unit)
    raise SceneError(f"{owner}: {name} is a Python function "
                     f"({getattr(sig.func, '__name__', type(sig.func).__name__)}); a scene file "
                     "cannot hold code: give it as a waveform (sf.waveforms.Step, "
                     "PiecewiseLinear, ...) to save this scene")


def _from_attributes(comp: Any) -> dict:
    """The table of a Python-built library component, from its SI attributes."""
    kind = _type_name(comp)
    import softflow as sf
    cls = getattr(sf, kind)
    owner = comp.describe()
    table: dict[str, Any] = {"type": kind}
    model = getattr(comp, "model", None)
    for p in inspect.signature(cls.__init__).parameters.values():
        name = p.name
        if name in ("self", "label"):
            continue
        if name == "fluid":
            if comp.fluid is not None:
                table["fluid"] = _write_fluid(comp.fluid, owner)
            continue
        if kind in _SOURCE_SIGNAL and name == _SOURCE_SIGNAL[kind][0]:
            table[name] = _write_signal(comp, name)
            continue
        if name in _CURVE_PARAMS:
            curve = (getattr(comp, name, None) if name == "curve"
                     else getattr(comp.loop, name.split("_")[0], None))
            table[name] = _write_curve(curve, owner, name)
            continue
        if kind == "Actuator" and name == "initial_pressure":
            continue                       # initial_volume says it
        if kind == "HystereticActuator" and name == "initial_branch":
            table[name] = "inflation" if comp.initial_branch == 1.0 else "deflation"
            continue
        if kind == "HystereticActuator" and name == "meet_tolerance":
            table[name] = _fmt(comp.loop.meet_tolerance, "Pa")
            continue
        if kind == "Orifice" and name == "m" and model == "ISO 6358":
            if not _same(comp.subsonic_index, p.default):
                table[name] = comp.subsonic_index
            continue
        if kind == "Orifice" and name == "K" and math.isfinite(comp.Cd):
            continue                       # worked out from Cd
        if not hasattr(comp, name):
            if p.default is inspect.Parameter.empty:
                raise SceneError(f"{owner}: cannot read its parameter {name!r} back to write it")
            continue
        value = getattr(comp, name)
        if value is None or (p.default is not inspect.Parameter.empty
                             and _same(value, p.default)):
            continue
        if isinstance(value, (float, np.floating)) and math.isnan(value):
            continue                       # not used in the component's configuration
        if isinstance(value, (bool, str, np.bool_)):
            table[name] = bool(value) if isinstance(value, np.bool_) else value
        elif isinstance(value, (int, float, np.floating)):
            unit = _unit_of(cls, name)
            if unit is None:
                raise SceneError(f"{owner}: {name} = {value!r} has no unit in {kind}'s docstring")
            table[name] = _fmt(value, unit)
        elif callable(value):
            raise SceneError(f"{owner}: {name} is a Python function, which a scene file "
                             "cannot hold")
        else:
            raise SceneError(f"{owner}: cannot write {name} = {value!r} to a scene file")
    return table


def _same(a: Any, b: Any) -> bool:
    try:
        return bool(a == b) or (isinstance(a, float) and isinstance(b, float)
                                and math.isclose(a, b, rel_tol=1e-12))
    except Exception:
        return False


def _type_name(comp: Any) -> str:
    import softflow as sf
    for kind in COMPONENT_TYPES:
        cls = getattr(sf, kind)
        if type(comp) is cls or (isinstance(comp, cls) and type(comp).__module__.startswith(
                "softflow.components")):
            return kind
    raise SceneError(f"{comp.describe()}: a {type(comp).__name__} is not a library component "
                     f"(a user-written component's Python code cannot be written to a scene "
                     f"file); scenes hold {', '.join(COMPONENT_TYPES)}")


def _check_rebuilt(comp: Any, table: dict) -> None:
    """Rebuild ``comp`` from ``table`` and compare its SI parameters and inputs."""
    reader = _Reader("", "<written>", Path.cwd())
    try:
        twin = _component(comp.label, table, {}, reader)
    except SceneError as err:
        raise SceneError(f"{comp.describe()}: what would be written does not rebuild it: "
                         f"{err}") from None
    names = list(getattr(type(comp), "param_names", ())) + ["initial_volume", "initial_pressure"]
    for name in names:
        a, b = getattr(comp, name, None), getattr(twin, name, None)
        if isinstance(a, (int, float)) and not isinstance(a, bool) and not (
                isinstance(b, (int, float)) and (math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-300)
                                                 or (math.isnan(a) and math.isnan(b)))):
            raise SceneError(f"{comp.describe()}: its {name} ({a!r}) cannot be written "
                             f"faithfully to a scene file (it would read back as {b!r})")
    if hasattr(comp, "signal"):
        for t in (0.0, 1e-3, 0.5, 1.0, 2.0, 10.0):
            if not math.isclose(comp.signal(t), twin.signal(t), rel_tol=1e-9, abs_tol=1e-12):
                raise SceneError(f"{comp.describe()}: its input cannot be written faithfully "
                                 f"(at t = {t} s: {comp.signal(t)} vs {twin.signal(t)})")


def _table_of(comp: Any, base: Path) -> dict:
    written = _WRITTEN.get(comp)
    if written is not None:
        table, origin, _ = written
        return {k: _moved(v, origin, base) if k in _CURVE_PARAMS or (
            isinstance(v, dict) and v.get("waveform") == "from_csv") else v
            for k, v in table.items()}
    table = _from_attributes(comp)
    _check_rebuilt(comp, table)
    return table


def _moved(table: Any, origin: Path, base: Path) -> Any:
    """A curve or from_csv table whose file path, relative to ``origin``, is made
    relative to ``base`` (where the new file goes), or absolute."""
    if not isinstance(table, dict):
        return table
    key = "csv" if "csv" in table else "path" if "path" in table else None
    if key is None or Path(table[key]).is_absolute():
        return table
    import os
    target = (origin / table[key]).resolve()
    try:
        rel = os.path.relpath(target, base.resolve())
    except ValueError:           # another drive (Windows)
        rel = str(target)
    return {**table, key: Path(rel).as_posix()}


def to_dict(system: System, simulation: dict | None = None, *,
            base: str | Path | None = None) -> dict:
    """The scene of ``system`` as the dict its TOML file holds; file paths of
    curves are written relative to ``base`` (the new file's folder; default
    the current directory)."""
    base = Path(base) if base is not None else Path.cwd()
    comps: dict[str, Any] = {}
    fluids: dict[str, Any] = {}
    for comp in system.components:
        table = _table_of(comp, base)
        if isinstance(table.get("fluid"), dict):      # one [fluids] entry per distinct fluid
            spec = table["fluid"]
            name = next((n for n, f in fluids.items() if f == spec), None)
            if name is None:
                name = f"{spec['name']}_{spec['level']}" if spec["name"] not in fluids else \
                    f"{spec['name']}_{len(fluids)}"
                while name in fluids or name in BUILTIN_FLUIDS:
                    name += "_"
                fluids[name] = spec
            table["fluid"] = name
        comps[comp.label] = table
    nodes = [[f"{t.component.label}.{t.label}"  # type: ignore[union-attr]  # connected
              for t in node.terminals]
             for node in system.nodes() if len(node.terminals) > 1]
    doc: dict[str, Any] = {"format": FORMAT, "connections": nodes}
    if simulation:
        doc["simulation"] = {k: (_fmt(_si(v, SIMULATION_KEYS.get(k)),
                                      SIMULATION_KEYS[k])  # type: ignore[arg-type]  # not None
                                 if SIMULATION_KEYS.get(k) and not isinstance(v, (str, list))
                                 else v) for k, v in simulation.items()}
        unknown = set(simulation) - set(SIMULATION_KEYS)
        if unknown:
            raise SceneError(f"save: unknown Simulation keyword {sorted(unknown)[0]!r}; "
                             f"expected one of {', '.join(SIMULATION_KEYS)}")
    for name, spec in _loaded_fluids(system).items():
        fluids.setdefault(name, spec)
    if fluids:
        doc["fluids"] = fluids
    doc["components"] = comps
    return doc


def _loaded_fluids(system: Any) -> dict:
    """[fluids] entries that components loaded from a file refer to by name."""
    out = {}
    for comp in system.components:
        written = _WRITTEN.get(comp)
        fluid = written[0].get("fluid") if written else None
        if isinstance(fluid, str) and fluid not in BUILTIN_FLUIDS:
            out[fluid] = written[2] if written[2] is not None else _write_fluid(  # type: ignore[index]
                comp.fluid, comp.describe())
    return out


def _si(value: Any, unit: str | None) -> float:
    from .units import to_si
    return to_si(value, unit, name="simulation", owner="save") if unit else value


def dumps(system: System, simulation: dict | None = None, *,
          base: str | Path | None = None) -> str:
    """The TOML text of ``system`` (and the Simulation keywords ``simulation``)."""
    import tomli_w
    doc = to_dict(system, simulation, base=base)
    head = f"# softflow scene (format {FORMAT}); softflow run FILE --duration '1 s'\n"
    text = tomli_w.dumps(doc)
    # one node per line reads better than tomli-w's one terminal per line
    text = re.sub(r"connections = \[\n(.*?)\n\]\n",
                  lambda m: "connections = [\n" + ",\n".join(
                      "    " + line.strip().rstrip(",") for line in _nodes_lines(doc))
                  + ",\n]\n" if doc["connections"] else "connections = []\n",
                  text, count=1, flags=re.S)
    return head + text


def _nodes_lines(doc: dict) -> list[str]:
    return ["[" + ", ".join(f'"{t}"' for t in node) + "]" for node in doc["connections"]]


def save(system: System, path: str | Path, *, simulation: dict | None = None) -> Path:
    """Write ``system`` (and the Simulation keywords ``simulation``, e.g.
    ``{"duration": "2 s"}``) to a TOML scene file; returns the path.

    Components read from a scene file are written as they were written there
    (units included); others from their SI values, each checked by rebuilding
    it from what is written. Raises SceneError naming the component for what a
    file cannot hold: Python functions (a lambda input, a callable PV curve),
    user-written components, hand-built fluids.
    """
    path = Path(path)
    text = dumps(system, simulation, base=path.parent)
    path.write_text(text, encoding="utf-8")
    return path
