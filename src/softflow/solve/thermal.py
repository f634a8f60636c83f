"""The thermal model of a scene: isothermal, adiabatic or with heat transfer.

``Simulation(system, ..., thermal=...)`` calls :func:`configure_thermal` before
compiling. In an isothermal scene (the default, the FONS paper's model) every
library component keeps its plain pressure/mass-flow terminals and kernels: no
temperature unknowns at all. In a thermal scene each fluid terminal gets a
temperature (across) and an energy flow (through) variable and each component
is evaluated by its thermal variant (:mod:`softflow.components.thermal`, where
the equations are documented).

Models
------
``'isothermal'``
    Temperatures are the fluids' own; no energy equation.
``'adiabatic'``
    Volumes exchange no heat with their walls (hA = 0).
``'heat_transfer'``
    Volumes exchange Q = hA·(T_wall - T) with their walls; every volume needs
    ``heat_transfer_coefficient`` and ``area`` (or ``hA``). The coefficient may
    be a :class:`~softflow.FreeConvection` correlation, evaluated from the gas
    state at the start of each step (:mod:`softflow.correlations.heat_transfer`).

A volume's own ``thermal=`` overrides the scene's model in a thermal scene:
``'adiabatic'``, ``'heat_transfer'``, or ``'isothermal'`` (held at its wall
temperature, the heat flow being whatever keeps it there).

What is modelled: gases (ideal, table or eos level), enthalpy transport
upwind, mixing at nodes, compression work in deformable volumes, wall heat
transfer with a constant hA or by free convection. Not modelled: liquids'
energy equation (a thermal scene rejects liquids), kinetic energy of the flow, friction heating beyond
what isenthalpic throttling implies, heat conduction along tubes, temperature
dependence of viscosity.
"""
from __future__ import annotations

import difflib

import numpy as np

from ..correlations.heat_transfer import FreeConvection
from ..network.system import NetworkError
from ..network.variable import Variable

MODELS = ("isothermal", "adiabatic", "heat_transfer")
#: Per-component overrides accepted in a thermal scene.
COMPONENT_MODELS = MODELS


def check_model(name, owner="Simulation", allowed=MODELS):
    """The normalized model name; a ValueError suggesting close matches otherwise."""
    if not isinstance(name, str):
        raise ValueError(f"{owner}: thermal must be one of {allowed}, got {name!r}")
    key = name.strip().lower().replace("-", "_").replace(" ", "_")
    if key in allowed:
        return key
    close = difflib.get_close_matches(key, allowed, n=2, cutoff=0.5)
    hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
    raise ValueError(f"{owner}: unknown thermal model {name!r}{hint} "
                     f"(known: {', '.join(allowed)})")


def configure_thermal(system, model):
    """Put every component of ``system`` into the scene's thermal model (see module doc).

    Returns the normalized model name."""
    from ..components.thermal import SOURCE_CLASSES, THERMAL_CLASSES, VOLUME_CLASSES
    model = check_model(model)
    comps = list(system.components)
    if model == "isothermal":
        for c in comps:
            if not c.vectorized:
                continue
            override = getattr(c, "thermal", None)
            if override not in (None, "isothermal"):
                raise ValueError(
                    f"{c.describe()}: thermal={override!r}, but the Simulation is isothermal "
                    "(no temperature unknowns). Choose the model for the scene, e.g. "
                    f"Simulation(..., thermal={override!r}); components may then override it")
            if c._thermal is not None:
                _leave(c)
        return model

    fluid_at = _node_fluids(system)
    gases = [getattr(c, "fluid", None) for c in comps]
    gases = [f for f in gases if f is not None and f.compressible]
    # one energy reference per scene (see softflow.components.thermal)
    from ..constants import pressure_atmospheric
    h0 = float(gases[0].enthalpy(pressure_atmospheric, gases[0].temperature)) if gases else 0.0
    for c in comps:
        if not c.vectorized:
            names = {v.quantity for t in c.terminals for v in t.variables}
            if not {"temperature", "energyflow"} <= names:
                raise NetworkError(
                    f"{c.describe()}: a user component in a thermal scene must carry "
                    "'temperature' (across) and 'energyflow' (through) at its terminals, or "
                    "the energy its flow carries would be lost; run the scene isothermal")
            continue
        cls = type(c)
        if cls not in THERMAL_CLASSES:
            raise NetworkError(f"{c.describe()}: {cls.__name__} has no thermal model yet; "
                               f"thermal scenes support "
                               f"{', '.join(sorted(k.__name__ for k in THERMAL_CLASSES))}")
        fluid = getattr(c, "fluid", None)
        if fluid is None:
            fluid = fluid_at.get(id(c))
        if fluid is None:
            raise NetworkError(f"{c.describe()}: no gas found at its terminal to give it "
                               "thermal properties; connect it to a tube, orifice or volume")
        _configure_one(c, model, fluid, h0)
    return model


def _configure_one(c, model, fluid, h0):
    """Put one library component into the scene's thermal model, with the gas
    ``fluid`` found for it and the scene's energy reference ``h0``."""
    from ..components.thermal import SOURCE_CLASSES, VOLUME_CLASSES
    _check_gas(c, fluid, model)
    if isinstance(c, VOLUME_CLASSES):
        _setup_volume(c, model)
        T0 = c._T_initial
    elif isinstance(c, SOURCE_CLASSES):
        c._thermal_fluid = fluid
        T_src = getattr(c, "temperature", None)
        c._T_source = float(fluid.temperature) if T_src is None else T_src
        _check_range(c, fluid, c._T_source, "temperature")
        T0 = c._T_source
        c._thermal = "source"
    else:
        T0 = float(fluid.temperature)
        c._thermal = "flow"
    c._h0 = h0
    _enter(c, T0)


def configure_like(new, old, model):
    """Put ``new`` (a component rebuilt from ``old`` with other numbers) into the
    thermal model ``old`` was compiled in; nothing in an isothermal scene."""
    if model == "isothermal" or getattr(old, "_thermal", None) is None:
        return new
    fluid = getattr(new, "fluid", None) or getattr(old, "_thermal_fluid", None) or old.fluid
    _configure_one(new, model, fluid, old._h0)
    return new


def _node_fluids(system):
    """id(component) -> a fluid found among the components sharing a node with it."""
    out = {}
    for nd in system.nodes():
        fluids = [getattr(t.component, "fluid", None) for t in nd.terminals]
        fluids = [f for f in fluids if f is not None]
        if fluids:
            for t in nd.terminals:
                out.setdefault(id(t.component), fluids[0])
    return out


def _check_gas(c, fluid, model):
    if not fluid.compressible:
        raise ValueError(
            f"{c.describe()}: fluid {fluid.name!r} is a liquid, but the scene asks for "
            f"thermal={model!r}, which models gases: enthalpy transport, mixing, compression "
            "work and wall heat transfer of a compressible gas. The energy equation of "
            "liquids is not modelled; run liquid scenes with thermal='isothermal'")


def _check_range(c, fluid, T, name):
    lo, hi = getattr(fluid, "T_range", (0.0, np.inf))
    if not (T > 0 and lo <= T <= hi):
        raise ValueError(f"{c.describe()}: {name} {T:g} K is outside the valid temperature "
                         f"range of {fluid!r} ({lo:g} ... {hi:g} K)")


def _setup_volume(c, model):
    mode = c.thermal if getattr(c, "thermal", None) is not None else model
    if has_wall_heat(c) and mode == "adiabatic":
        if getattr(c, "thermal", None) == "adiabatic":
            raise ValueError(f"{c.describe()}: thermal='adiabatic' contradicts the wall heat "
                             "transfer given (hA, or heat_transfer_coefficient and area); "
                             "drop one of them")
        mode = "heat_transfer"   # a volume given its wall heat transfer uses it
    fluid = c.fluid
    c._T_initial = float(fluid.temperature) if c.initial_temperature is None \
        else c.initial_temperature
    c._T_wall = float(fluid.temperature) if c.wall_temperature is None else c.wall_temperature
    _check_range(c, fluid, c._T_initial, "initial_temperature")
    _check_range(c, fluid, c._T_wall, "wall_temperature")
    if mode == "heat_transfer":
        if not has_wall_heat(c):
            raise ValueError(
                f"{c.describe()}: heat transfer needs a wall heat transfer coefficient and "
                "area: give heat_transfer_coefficient [W/(m^2 K)] and area [m^2], or hA "
                "[W/K]; or thermal='adiabatic' for this volume")
        c._hA = c.hA if c.hA is not None else 0.0   # a correlation sets it every step
        c._h_corr = c.h_correlation
    else:
        c._hA = 0.0
        c._h_corr = None
    c._thermal = mode


def _enter(c, T0):
    for t in c.terminals:
        # a new list (the first two may be the class's shared variables);
        # idempotent: a second thermal compile replaces the extras
        t.variables = [*t.variables[:2],
                       Variable("temperature", "across", label="T", initial_value=T0),
                       Variable("energyflow", "through", label="E", initial_value=0.0)]
    cls = c.kernel_class() if c._thermal is not None else None
    c.states = [Variable(q, "local", label=lab) for lab, q in cls.state_spec]
    c.locals = [Variable(q, "local", label=lab, initial_value=0.0)
                for lab, q in getattr(cls, "local_spec", ())]


def _leave(c):
    for t in c.terminals:
        t.variables = t.variables[:2]
    c._thermal = None
    c.states = [Variable(q, "local", label=lab) for lab, q in type(c).state_spec]
    c.locals = []


#: Docstring entries of the thermal parameters every volume takes (appended to
#: the volumes' class docstrings, which end with an indented empty line).
THERMAL_VOLUME_DOC = """thermal : {None, 'adiabatic', 'heat_transfer', 'isothermal'}, optional
        This volume's thermal model in a thermal scene (default: the scene's,
        ``Simulation(thermal=...)``); see :mod:`softflow.solve.thermal`.
    initial_temperature : float [K], optional
        Gas temperature at t = 0 in a thermal scene (default: the fluid's).
    wall_temperature : float [K], optional
        Wall temperature for heat transfer (default: the fluid's temperature).
    heat_transfer_coefficient : float [W/(m^2 K)] or FreeConvection, optional
        Convective coefficient h of Q = h·A·(T_wall - T), with ``area``; a
        :class:`~softflow.FreeConvection` correlation computes h from the gas
        state, frozen over each step.
    area : float [m^2], optional
        Wall area A exchanging heat.
    hA : float [W/K], optional
        The product h·A directly (instead of the two above).
"""


def has_wall_heat(comp):
    """Whether a volume was given wall heat transfer (hA, or h and area)."""
    return comp.hA is not None or getattr(comp, "h_correlation", None) is not None


def thermal_volume_fields(comp, initial_temperature, wall_temperature,
                          heat_transfer_coefficient, area, hA, thermal):
    """Check and store a volume's thermal parameters (constructor helper)."""
    comp.thermal = None if thermal is None else check_model(thermal, comp.describe(),
                                                            COMPONENT_MODELS)
    comp.initial_temperature = (None if initial_temperature is None else
                                comp._si(initial_temperature, "K", "initial_temperature",
                                         positive=True))
    comp.wall_temperature = (None if wall_temperature is None else
                             comp._si(wall_temperature, "K", "wall_temperature", positive=True))
    if hA is not None and (heat_transfer_coefficient is not None or area is not None):
        raise ValueError(f"{comp.describe()}: give hA [W/K], or heat_transfer_coefficient "
                         "[W/(m^2 K)] with area [m^2], not both")
    comp.h_correlation = None
    if hA is not None:
        comp.hA = comp._si(hA, "W/K", "hA", nonnegative=True)
    elif heat_transfer_coefficient is not None or area is not None:
        if heat_transfer_coefficient is None or area is None:
            missing = "area [m^2]" if area is None else "heat_transfer_coefficient [W/(m^2 K)]"
            raise ValueError(f"{comp.describe()}: heat transfer needs both "
                             f"heat_transfer_coefficient and area; {missing} is missing")
        comp.area = comp._si(area, "m**2", "area", positive=True)
        if isinstance(heat_transfer_coefficient, FreeConvection):
            comp.h_correlation = heat_transfer_coefficient
            comp.hA = None
        else:
            comp.hA = comp._si(heat_transfer_coefficient, "W/(m**2*K)",
                               "heat_transfer_coefficient", nonnegative=True) * comp.area
    else:
        comp.hA = None
    if comp.thermal == "heat_transfer" and not has_wall_heat(comp):
        raise ValueError(f"{comp.describe()}: thermal='heat_transfer' needs "
                         "heat_transfer_coefficient [W/(m^2 K)] and area [m^2], or hA [W/K]")
    T = comp.initial_temperature
    if T is not None:
        _check_range(comp, comp.fluid, T, "initial_temperature")


def energy_balance(result, system):
    """Energy audit of a thermal run [J], from the recorded results.

    Returns a dict: ``stored`` (change of the volumes' internal energy),
    ``inflow`` (energy delivered by all sources), ``wall_heat`` (heat from the
    walls), ``work`` (p·dV work the gas did on deformable walls), ``error`` =
    stored - inflow - wall_heat + work and ``relative_error`` (error over the
    largest of the terms and |U_0|), and ``independent`` (True where no volume
    is held at its wall temperature).

    Energy flows and wall heat are integrated by the run's own quadrature
    (:meth:`Result.integral` of the sources' ``energyflow`` and the volumes'
    ``wall_heat``), exact under every stepper and order; the internal energy's
    change is that of the integrated ``stored_energy`` less the work done on
    the wall (``wall_work``: the stored energy less m (u(p, T) - h0)). So
    ``error`` checks, to round-off, that the energy the sources delivered is the
    energy the volumes store and exchanged with their walls, whatever the
    stepper and order. A volume held at its wall temperature
    (``thermal='isothermal'``) takes as heat whatever keeps it there: its heat
    closes its own balance (and its work is the trapezoidal sum of p·dV), so it
    carries no independent check (``independent`` is False)."""
    from ..components.chambers import Container
    from ..components.thermal import SOURCE_CLASSES, VOLUME_CLASSES
    independent = True
    stored = inflow = heat = work = 0.0
    scale = 0.0
    for c in system.components:
        # the run's own copy of the component: a thermal Simulation compiles a
        # copy of the System and sets its per-scene data (wall, hA) there
        c = result._component(c.label)
        if isinstance(c, SOURCE_CLASSES):
            inflow += -float(result.integral(c.label, "energyflow")[-1])
        elif isinstance(c, VOLUME_CLASSES):
            w = 0.0
            if c._thermal == "isothermal":
                independent = False
                U = result.get(c.label, "internal_energy")
                if not isinstance(c, Container):
                    vol, p = result.get(c.label, "volume"), result.get(c.label, "pressure")
                    w = float(np.sum((p[1:] + p[:-1]) / 2 * np.diff(vol)))
                E = float(result.integral(c.label, "energyflow")[-1])
                heat += (U[-1] - U[0]) - E + w
                dU = U[-1] - U[0]
            else:
                # the integrated stored energy less the wall's work: the change of
                # the internal energy, to round-off in the states (the energy row
                # ties m (u - h0) to them only to Newton's tolerance)
                U = result.get(c.label, "stored_energy")
                if not isinstance(c, Container):
                    ww = result.get(c.label, "wall_work")
                    w = float(ww[-1] - ww[0])
                heat += float(result.integral(c.label, "wall_heat")[-1])
                dU = U[-1] - U[0] - w
            stored += dU
            work += w
            scale = max(scale, abs(U[0]), abs(U[-1]))
    error = stored - inflow - heat + work
    scale = max(scale, abs(inflow), abs(heat), abs(work), abs(stored), 1e-300)
    return {"stored": stored, "inflow": inflow, "wall_heat": heat, "work": work,
            "error": error, "relative_error": abs(error) / scale,
            "independent": independent}
