"""Run-time parameters: ``Simulation.run(params={"tube.diameter": ...})``.

A parameter is an argument of a library component's constructor, named
``label.argument``. The component is rebuilt from the arguments it was made
with, the new ones replacing theirs, so every value is checked (units,
range) exactly as the constructor checks it; the compiled model then
evaluates the rebuilt component in place of the old one
(:meth:`softflow.solve.assembly.Assembly.replace`). The System is not
touched. What would change the network's structure (the label, the fluid,
the thermal model, a tube's inertance, a curve shared with other actuators)
is refused with a message saying to build a new Simulation.
"""
from __future__ import annotations

import functools
import inspect

from ..network.system import NetworkError

#: Constructor arguments that define the structure, not numbers of the model.
STRUCTURAL = frozenset({"label", "fluid", "thermal", "inertance", "compressible"})


@functools.lru_cache(maxsize=None)
def _class_signature(cls):
    return inspect.signature(cls.__init__)


def _signature(comp):
    return _class_signature(type(comp))


@functools.lru_cache(maxsize=None)
def _keyword_names(cls):
    """The names of the constructor's positional-or-keyword arguments after
    self, in order, where every argument can be passed by name (else None)."""
    params = list(_class_signature(cls).parameters.values())[1:]
    if any(p.kind in (p.POSITIONAL_ONLY, p.VAR_POSITIONAL) for p in params):
        return None
    return tuple(p.name for p in params if p.kind == p.POSITIONAL_OR_KEYWORD)


@functools.lru_cache(maxsize=None)
def _class_parameters(cls):
    params = _class_signature(cls).parameters
    return tuple(n for n in list(params)[1:]
                 if n not in STRUCTURAL and not n.startswith("_")
                 and params[n].kind not in (inspect.Parameter.VAR_POSITIONAL,
                                            inspect.Parameter.VAR_KEYWORD))


def parameter_names(comp):
    """The run-time parameters of a component (its constructor's arguments
    that do not define structure)."""
    return list(_class_parameters(type(comp)))


def given_value(comp, name):
    """The constructor argument ``name`` of a library component as it was given
    (its default where it was not); None where the component keeps no definition.
    (A component may store another thing under the name: a hysteretic actuator's
    initial_branch 'inflation' is kept as the number 1.0.)"""
    definition = comp.__dict__.get("_definition")
    if definition is None:
        return None
    args, kwargs = definition
    try:
        bound = _signature(comp).bind(comp, *args, **kwargs)
    except TypeError:
        return None
    bound.apply_defaults()
    return bound.arguments.get(name)


def is_choice(comp, name):
    """The constructor argument ``name`` is a name or a flag, not a number: given
    as a str or bool, or declared so (``initial_branch: str | None``: a hysteretic
    actuator keeps its default choice as the number 1.0 or 0.0)."""
    if isinstance(given_value(comp, name), (str, bool)):
        return True
    param = _signature(comp).parameters.get(name)
    note = getattr(param, "annotation", None)
    if not isinstance(note, str) or not note.strip():
        return False
    kinds = {k.strip() for k in note.split("|")}
    return kinds <= {"str", "bool", "None"} and kinds != {"None"}


def split(params, labels):
    """``{"label.name": value}`` as ``{label: {name: value}}``; clear errors for
    keys that are not ``label.name`` or name no component."""
    if not isinstance(params, dict):
        raise TypeError(f"params must be a dict {{'label.parameter': value}}, got {params!r}")
    out = {}
    for key, value in params.items():
        if not isinstance(key, str) or "." not in key:
            raise KeyError(f"params: key {key!r} is not 'label.parameter' (e.g. "
                           f"'tube.diameter')")
        label, name = key.rsplit(".", 1)
        if label not in labels:
            have = ", ".join(repr(x) for x in sorted(labels)[:20])
            raise KeyError(f"params[{key!r}]: no component {label!r}; the components are {have}")
        out.setdefault(label, {})[name] = value
    return out


def rebuild(comp, changes, label=None):
    """A new component like ``comp`` with the constructor arguments ``changes``
    (and, where given, another ``label``: a batch's copy of a scene)."""
    definition = comp.__dict__.get("_definition")
    if not getattr(comp, "vectorized", False) or definition is None:
        raise NetworkError(f"{comp.describe()}: a user component's parameters are fixed when "
                           "the Simulation is built; build a new Simulation")
    valid = parameter_names(comp)
    for name in changes:
        if name in STRUCTURAL:
            raise NetworkError(f"params['{comp.label}.{name}']: {name} defines the network's "
                               "structure; build a new Simulation to change it")
        if name not in valid:
            raise KeyError(f"params['{comp.label}.{name}']: {comp.describe()} has no parameter "
                           f"{name!r}; its parameters are {', '.join(valid)}")
    args, kwargs = definition
    names = _keyword_names(type(comp))
    if names is not None and len(args) <= len(names):
        # the constructor's arguments by name (Signature.bind costs ~50 us a
        # call; a sweep rebuilds a component per variant)
        merged = dict(zip(names, args))
        merged.update(kwargs)
        merged.update(changes)
        if label is not None:
            merged["label"] = label
        call_args, call_kwargs = (), merged
    else:
        bound = _signature(comp).bind(comp, *args, **kwargs)
        bound.arguments.update(changes)
        if label is not None:
            bound.arguments["label"] = label
        call_args, call_kwargs = bound.args[1:], bound.kwargs
    try:
        return type(comp)(*call_args, **call_kwargs)
    except (ValueError, TypeError) as err:
        keys = ", ".join(f"'{comp.label}.{n}'" for n in changes)
        raise type(err)(f"params[{keys}]: {err}") from None
