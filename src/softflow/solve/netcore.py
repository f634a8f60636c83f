"""The network residual as one compiled call (issue 38, the compiled core's
second step): where every group of a network is of a class the compiled loop
:func:`softflow.laws.network.residual` covers, the assembly's ``residual``
is that loop, described once per network by integer and float arrays,
instead of one Python kernel call (and its NumPy glue) per group.

Covered in isothermal scenes (the classes themselves, not subclasses):
pressure and mass flow sources; volume flow sources, containers and linear
accumulators of an ideal gas or a constant-density liquid (a rigid container
of any liquid); tubes whose law runs as one compiled pass (an ideal gas on
the pipe-flow law or a liquid of constant properties, with an analytic
friction correlation: ``P.kind``), with or without inertance; orifices (loss
coefficient, nozzle, ISO 6358), check, Tesla and snapping valves of an ideal
gas or a liquid; actuators on a compiled PV curve and hysteretic actuators on
a loop of them.

Covered in thermal scenes (``thermal='adiabatic'`` or ``'heat_transfer'``)
of an ideal gas whose properties are :class:`~softflow.IdealGas`'s own (the
thermal variants of :mod:`softflow.components.thermal`, laws in
:mod:`softflow.laws.thermal`): pressure, mass and volume flow sources; tubes
on the adiabatic pipe-flow law (an analytic correlation), tubes with
inertance, orifices, check, Tesla and snapping valves, with upwind energy;
containers, linear accumulators, actuators on a compiled PV curve and
hysteretic actuators, free (adiabatic or with wall heat) or held at their
wall temperature. A constant h·A is a float of the loop; an h·A that a
heat-transfer correlation sets at the start of each step (``begin_step``)
is copied into the loop's floats before each call.

A user's component (one written with ``evaluate`` / ``update_state`` /
``auto*``, as the paper's ``Actuator``) is called back in Python from the
loop (:mod:`softflow.solve.usercall`; ``settings.COMPILED_USER``), unless it
states switching functions, kinks or pieces. Any other group (library
subclasses with laws of their own, callable curves, real fluids at the table
or eos level, the mean-density gas law in a thermal scene) keeps the whole
network on the per-group path. A state a law refuses (an actuator's volume beyond a curve
given ``extrapolate='error'``) is evaluated again on the per-group path,
which raises the law's own error. The values are the per-group path's to
round-off (tested); time-dependent source values are evaluated by their
sources in Python before each call.

The same call gives the states at the end of a step (the loop's ``Sout``):
:func:`compiled_update` is the assembly's ``update_states`` that way (the
same numbers, bitwise: tested), and the :class:`CompiledNetwork` a compiled
residual carries (``asm.residual.network``) holds the loop's arrays for a
caller that calls :func:`softflow.laws.network.residual` itself (the
compiled step loop). Those arrays also give the assembly's ``switching``,
``kinks`` and ``regimes`` in compiled code (:class:`CompiledNetwork`'s
``switching_loop``, ``kinks_loop``, ``regimes_loop``, and the counts
``n_switching``, ``n_kinks``, ``n_regimes``: the same numbers, bitwise:
tested).
"""
from __future__ import annotations

import numpy as np

from .._laws import law_module
from ..fluids.base import FluidError
from .usercall import raise_pending


#: the names _covered and _covered_thermal compare a group with, imported on
#: their first call (the components import this package; an import statement
#: in the function cost ~1 us per call, ~40 us a compile of the paper's scenes)
_NAMES = None


def _names():
    """The classes and constants of :func:`_covered`, imported once."""
    global _NAMES
    if _NAMES is None:
        from types import SimpleNamespace

        from ..components import thermal
        from ..components.actuators import Actuator, HystereticActuator
        from ..components.chambers import Container, LinearAccumulator, set_fluid_law
        from ..components.sources import MassFlowSource, PressureSource, VolumeFlowSource
        from ..components.tubes import CircularTube, InertialCircularTube
        from ..components.valves import CheckValve, Orifice, SnappingValve, TeslaValve
        from ..constants import pressure_atmospheric
        from ..correlations.orifice import ISO_6358_RHO0, ISO_6358_T0
        _NAMES = SimpleNamespace(
            thermal=thermal, Actuator=Actuator, HystereticActuator=HystereticActuator,
            Container=Container, LinearAccumulator=LinearAccumulator,
            set_fluid_law=set_fluid_law, MassFlowSource=MassFlowSource,
            PressureSource=PressureSource, VolumeFlowSource=VolumeFlowSource,
            CircularTube=CircularTube, InertialCircularTube=InertialCircularTube,
            CheckValve=CheckValve, Orifice=Orifice, SnappingValve=SnappingValve,
            TeslaValve=TeslaValve, pressure_atmospheric=pressure_atmospheric,
            ISO_6358_RHO0=ISO_6358_RHO0, ISO_6358_T0=ISO_6358_T0,
            laws=frozenset({PressureSource, MassFlowSource, VolumeFlowSource, CircularTube,
                            InertialCircularTube, TeslaValve, SnappingValve, Container,
                            Orifice, CheckValve, Actuator, HystereticActuator,
                            LinearAccumulator}))
    return _NAMES


#: what a subclass of a library class may define of that class's own names
#: and still be evaluated by its compiled law: its constructor (how it reads
#: its arguments) and how its results are read (softflow.fons's classes)
_SAME_LAW = frozenset({"__init__", "get", "__doc__", "__module__", "__qualname__",
                       "__annotations__", "__dict__", "__weakref__", "__firstlineno__",
                       "__static_attributes__"})


#: the names the assembly and the step equations look up on a library class
#: (softflow.solve.assembly, softflow.solve.discretize), which a subclass
#: that keeps its class's law must not define, whether that class has them
#: or not (a hook such as begin_step or switching changes the group's law)
_LAW_HOOKS = frozenset({"affine", "begin_step", "discrete_states", "fold_pressure",
                        "jac_pattern", "kernel", "kinks", "make_params", "param_jacobian",
                        "rate_pattern", "rates", "regime", "residual", "residual_pattern",
                        "state_jac_pattern", "state_spec", "switch", "switching", "update",
                        "wants_begin_step"})


def _law_class(cls):
    """The library class whose compiled law evaluates ``cls``'s groups: the
    first of :func:`_covered`'s classes in its order of bases, where no class
    before it defines a name that class has (a law, a constant, a method)
    or a hook of :data:`_LAW_HOOKS`, other than those of :data:`_SAME_LAW`;
    else ``cls`` itself. Asked at each build (a class changed since is seen)."""
    k = _NAMES if _NAMES is not None else _names()
    if cls in k.laws:
        return cls
    for i, lib in enumerate(cls.__mro__):
        if lib in k.laws:
            names = _LAW_HOOKS.union(*(vars(c) for c in lib.__mro__))
            if any((set(vars(c)) & names) - _SAME_LAW for c in cls.__mro__[:i]):
                return cls
            return lib
    return cls


def _covered(g):
    """(class id, option, group floats, per-instance floats (n, k) or None,
    values source or None) of a group the compiled loop evaluates, or None."""
    k = _NAMES if _NAMES is not None else _names()
    Actuator, HystereticActuator = k.Actuator, k.HystereticActuator
    Container, LinearAccumulator = k.Container, k.LinearAccumulator
    set_fluid_law = k.set_fluid_law
    pressure_atmospheric = k.pressure_atmospheric
    MassFlowSource, PressureSource, VolumeFlowSource = (k.MassFlowSource, k.PressureSource,
                                                        k.VolumeFlowSource)
    CircularTube, InertialCircularTube = k.CircularTube, k.InertialCircularTube
    CheckValve, Orifice, SnappingValve, TeslaValve = (k.CheckValve, k.Orifice, k.SnappingValve,
                                                      k.TeslaValve)
    ISO_6358_RHO0, ISO_6358_T0 = k.ISO_6358_RHO0, k.ISO_6358_T0
    net = law_module("network")
    if g.row is not None:
        # a user's component, called back (softflow.solve.usercall); not one
        # with switching functions, kinks or pieces (the compiled loops that
        # give those do not call back)
        from . import settings
        if (not settings.COMPILED_USER or g.switching is not None or g.kinks is not None
                or g.regime is not None or g.begin is not None or g.fold is not None):
            return None
        return net.USER, 0, (), None, None
    cls, P = getattr(g, "cls", None), getattr(g, "params", None)
    if cls is None or P is None:
        return None
    # a subclass that keeps its library class's law (softflow.fons's classes)
    cls = _law_class(cls)
    if cls is PressureSource or cls is MassFlowSource:
        kind = net.PRESSURE_SOURCE if cls is PressureSource else net.MASS_FLOW_SOURCE
        return kind, 0, (), None, P
    if cls is VolumeFlowSource:
        set_fluid_law(P)
        if P.rho_kind == 2:
            return None
        return net.VOLUME_FLOW_SOURCE, P.rho_kind, (P.rho_c,), None, P
    if cls is CircularTube or cls is InertialCircularTube:
        if P.kind is None:
            return None
        per = [P.re_per_mf, P.kind_c, P.eD, P.kind_terms, P.area, P.kre]
        if cls is InertialCircularTube:
            # dq/dt = k (...) with k = 1 / (L/A), as the class's rates make it
            per.append(1.0 / P.length_per_area)
        return ((net.TUBE if cls is CircularTube else net.INERTIAL_TUBE), P.kind,
                (P.Re_lo, P.Re_hi, P.kind_c2), np.column_stack(per), None)
    if cls is TeslaValve or cls is SnappingValve:
        if not P.compiled:
            return None
        valve = (P.Re_lo, P.Re_hi, P.law_c2, P.law_RT, P.law_rho)
        if cls is TeslaValve:
            per = [P.re_per_mf, P.c_mu, P.eD, P.friction_terms, P.area, P.mf_blend,
                   P.diodicity]
            return net.TESLA_VALVE, P.kind, valve, np.column_stack(per), None
        per = [P.re_per_mf, P.c_mu, P.eD, P.friction_terms, P.area, P.closed_conductance,
               P.opening_pressure, P.closing_pressure]
        return net.SNAPPING_VALVE, P.kind, valve, np.column_stack(per), None
    if cls is Container:
        if not P.fluid.compressible:
            return net.RIGID_LIQUID, 0, (), None, None
        if P.rho_kind == 2:
            return None
        return net.RIGID_GAS, P.rho_kind, (P.rho_c,), P.volume[:, None], None
    if cls is Orifice:
        if not P.compiled:
            return None
        per = np.column_stack([P.K, P.area, P.dp_small, P.gamma, P.Cd, P.C, P.b,
                               P.subsonic_index, P.pr_laminar])
        return (net.ORIFICE, P.law, (P.law_RT, P.law_rho, P.T, ISO_6358_RHO0, ISO_6358_T0),
                per, None)
    if cls is CheckValve:
        if not P.compiled:
            return None
        per = np.column_stack([P.K, P.Cd, P.gamma, P.area, P.dp_small, P.cracking_pressure,
                               P.opening_band, P.leakage])
        return (net.CHECK_VALVE, int(bool(P.nozzle)), (P.law_RT, P.law_rho, *_regime_cut()),
                per, None)
    if cls is Actuator:
        if P.pv is None or P.rho_kind == 2:
            return None
        pv = P.pv
        floats = np.concatenate(((P.rho_c, pressure_atmospheric, float(P.scaled),
                                  float(pv._mode)), _curve_floats(pv)))
        return net.ACTUATOR, P.rho_kind, floats, P.pressure_scale[:, None], None
    if cls is HystereticActuator:
        if not P.compiled or P.rho_kind == 2:
            return None
        loop = P.loop
        floats = np.concatenate(((P.rho_c, loop.volume_high, loop.volume_low),
                                 _curve_floats(loop.inflation), _curve_floats(loop.deflation)))
        return net.HYSTERETIC_ACTUATOR, P.rho_kind, floats, None, None
    if cls is LinearAccumulator:
        if P.rho_kind == 2:
            return None
        per = np.column_stack([P.volume, P.compliance, P.reference_pressure])
        return net.ACCUMULATOR, P.rho_kind, (P.rho_c,), per, None
    return _covered_thermal(net, cls, P)


def _covered_thermal(net, cls, P):
    """:func:`_covered` for the thermal variants (softflow.components.thermal)
    of an ideal gas whose laws :mod:`softflow.laws.thermal` compiles."""
    k = _NAMES if _NAMES is not None else _names()
    th, InertialCircularTube = k.thermal, k.InertialCircularTube
    pressure_atmospheric = k.pressure_atmospheric
    ISO_6358_RHO0, ISO_6358_T0 = k.ISO_6358_RHO0, k.ISO_6358_T0
    if cls is th.ThermalPressureSource:
        return net.THERMAL_PRESSURE_SOURCE, 0, (), P.T_source[:, None], P
    if cls is th.ThermalMassFlowSource or cls is th.ThermalVolumeFlowSource:
        gas = th.ideal_gas_constants(P.fluid_thermal)
        if gas is None:
            return None
        kind = (net.THERMAL_MASS_FLOW_SOURCE if cls is th.ThermalMassFlowSource
                else net.THERMAL_VOLUME_FLOW_SOURCE)
        floats = (gas[0], gas[1], gas[3] - P.h0, th.UPWIND_BAND, th.ZERO_FLOW_CONDUCTANCE)
        return kind, 0, floats, P.T_source[:, None], P
    if (cls is th.THERMAL_CLASSES[InertialCircularTube] and P.ideal is not None
            and P.kind is not None and P.kind_c2 > 0.0):
        # its flow law at the nominal temperature, with upwind energy
        per = [P.re_per_mf, P.kind_c, P.eD, P.kind_terms, P.area, P.kre,
               1.0 / P.length_per_area]
        group = (P.Re_lo, P.Re_hi, P.kind_c2, P.ideal[1], P.ideal[3] - P.h0, th.UPWIND_BAND,
                 th.ZERO_FLOW_CONDUCTANCE)
        return net.THERMAL_INERTIAL_TUBE, P.kind, group, np.column_stack(per), None
    law = getattr(P, "thermal_law", None)
    if law is not None and cls.__dict__.get("isothermal_class") is not None:
        energy = (P.ideal[1], P.ideal[3] - P.h0, th.UPWIND_BAND, th.ZERO_FLOW_CONDUCTANCE)
        if law in ("tube", "tesla", "snapping"):
            group = (P.Re_lo, P.Re_hi, P.R_gas, P.gamma, *energy)
        if law == "tube":
            per = [P.re_per_mf, P.c_mu, P.eD, P.kind_terms, P.area, P.kre]
            return net.THERMAL_TUBE, P.kind, group, np.column_stack(per), None
        if law == "tesla":
            per = [P.re_per_mf, P.c_mu, P.eD, P.friction_terms, P.area, P.mf_blend,
                   P.diodicity]
            return net.THERMAL_TESLA_VALVE, P.kind, group, np.column_stack(per), None
        if law == "snapping":
            per = [P.re_per_mf, P.c_mu, P.eD, P.friction_terms, P.area, P.kre,
                   P.closed_conductance, P.opening_pressure, P.closing_pressure]
            group = (*group, P.law_RT, P.law_rho, P.T_ref)
            return net.THERMAL_SNAPPING_VALVE, P.kind, group, np.column_stack(per), None
        if law == "orifice":
            per = np.column_stack([P.K, P.area, P.dp_small, P.gamma, P.Cd, P.C, P.b,
                                   P.subsonic_index, P.pr_laminar])
            group = (P.law_RT, P.law_rho, P.T, ISO_6358_RHO0, ISO_6358_T0, P.T_ref, *energy)
            return net.THERMAL_ORIFICE, P.law, group, per, None
        if law == "check":
            per = np.column_stack([P.K, P.Cd, P.gamma, P.area, P.dp_small, P.cracking_pressure,
                                   P.opening_band, P.leakage])
            return (net.THERMAL_CHECK_VALVE, int(bool(P.nozzle)),
                    (P.law_RT, P.law_rho, *energy, *_regime_cut()), per, None)
        return None
    wall = getattr(P, "wall", None)
    if wall is not None and issubclass(cls, (th._Free, th._Held)):
        kind, fl, k, tables, extra, scaled = wall
        R, _, cv, c = P.ideal
        floats = [R, cv, c, P.h0, float(P.any_heat), float(tables[0][3] if tables else 0),
                  float(scaled), pressure_atmospheric]
        if kind == th._LOOP:         # a loop: V_hi, V_lo, the work's shifts, mode down
            floats += [*extra, float(tables[1][3])]
        for knots, table, w0, _ in tables:
            floats += [float(knots.size), float(table.shape[0]), *knots, *table.ravel(), *w0]
        per = np.column_stack([P.hA, P.T_wall, fl.reshape(P.n, k)])
        free = issubclass(cls, th._Free)
        return net.FREE_VOLUME if free else net.HELD_VOLUME, kind, floats, per, None
    return None


def _regime_cut():
    """A check valve's regimes' cut as the loop reads it (the last of its
    group floats): REGIME_EDGE and LOW_PIECES of
    :meth:`softflow.components.valves.CheckValve.regime`, read when the
    network is described (the compiled code holds no copy)."""
    from ..components import valves
    return float(valves.REGIME_EDGE), float(valves.LOW_PIECES)


def _curve_floats(curve):
    """A compiled PV curve as the loop reads it: [knots, rows, knots...,
    table...] (:func:`softflow.laws.network._curve`), one float array (its
    values one by one as Python floats cost ~10 us an actuator)."""
    knots, table = np.asarray(curve._knots, dtype=float), np.asarray(curve._table, dtype=float)
    return np.concatenate(((float(knots.size), float(table.shape[0])), knots.ravel(),
                           table.ravel()))


#: the loop's ``Sout`` where no states are wanted (held once: the residual's calls
#: allocate nothing for it)
NO_STATES = np.zeros(0)


class CompiledNetwork:
    """One network described for the compiled loop
    :func:`softflow.laws.network.residual`, for callers that call it
    directly (the compiled step loop). Its arguments, in order::

        loop(x, S, t, dt, jac, F, *net.arrays, Sout)
        # net.arrays = (raw, n_node_rows, trows, tcols, groups, cols, fpar, u)

    with F a float array of ``n`` entries (filled), x the unknowns, S = psi,
    dt = c, ``jac`` a bool (the Jacobian's entries into ``raw``, the
    assembly's own array) and ``Sout`` either :data:`NO_STATES` or an array of
    S's size that receives the states at the end of the step (what
    ``asm.update_states(x, S, dt)`` returns). The loop returns -1, or the
    index of a group whose law refused the state (F, raw and Sout are then
    incomplete; the per-group path raises that law's error).

    Attributes: ``loop`` (the compiled function), ``arrays`` (its arguments
    between F and Sout, above), each of them by name (``raw``,
    ``n_node_rows``, ``trows``, ``tcols``, ``groups``, ``cols``, ``fpar``,
    ``u``), ``n`` (unknowns and rows), ``no_states`` (:data:`NO_STATES`),
    ``float_sizes`` (per group: how many of its floats in ``fpar`` all its
    instances share, how many each instance has after them, whether it
    has source values in ``u``, one per instance),
    ``time_dependent`` (whether ``u`` or ``fpar`` change with time or step:
    then :meth:`set_time` must run, in Python, before the loop at a new time,
    unless the caller fills ``u`` itself from :meth:`source_arrays`; a scene
    without it needs no Python call between loop calls). The arrays are the
    ones the assembly's compiled ``residual`` passes (``raw`` the assembly's
    own); a new parameter value (``run(params=...)``) builds a new
    CompiledNetwork (read it again from ``asm.residual.network`` at the
    start of each run).

    The same arrays give the assembly's switching functions, kinks and
    pieces in compiled code (:mod:`softflow.laws.network`)::

        net.switching_loop(x, S, net.groups, net.cols, net.fpar, g_out)  # asm.switching(x, S)
        net.kinks_loop(x, net.groups, net.cols, net.fpar, out)         # asm.kinks(x)
        net.regimes_loop(x, net.groups, net.cols, net.fpar, out)       # asm.regimes(x)

    each writing its values in the assembly's order (g_out float; out of any
    numeric dtype, int64 say: the classes' integers) and returning how many;
    ``n_switching``, ``n_kinks`` and ``n_regimes`` are those counts (0 where
    no group states them: the assembly's answer is then None), for arrays
    allocated once. :meth:`switching`, :meth:`kinks` and :meth:`regimes` are
    the assembly's methods that way (new arrays, or None)."""

    #: the evaluators of the user components the loop calls back
    #: (:mod:`softflow.solve.usercall`), held while the network lives
    callbacks: list = []
    #: the layouts of the user components compiled
    #: (:mod:`softflow.solve.usercompile`: their addresses are the kernels'
    #: keys), held while the network lives
    kernels: list = []
    #: each compiled user component's (row in ``groups``, group, the key of
    #: the values its functions read when compiled, its layout, its kernel's
    #: plan of run-time values): see :meth:`check_user_values`
    watched: list = []
    #: ``refresh()`` copies the h A that heat-transfer correlations set at
    #: each step's start (``asm.begin_step``) into ``fpar``; None where none
    refresh = None

    def check_user_values(self) -> None:
        """Where a compiled user component's functions now read other values
        than they were compiled with (a global or a closure's value changed
        since the Simulation was built, that the compiled kernel holds as a
        constant), its row takes the kernel of the values now (from the
        cache, or compiled), or its call-back, which reads them as they are;
        its run-time values (floats, fluids and curves of its closures:
        :func:`softflow.solve.usercompile.layout`) are read again into its
        layout. Called at the start of each run."""
        if not self.watched:
            return
        from . import usercompile
        net = law_module("network")
        for k, (gi, g, key, lay, plan) in enumerate(self.watched):
            if key == _CALLED_BACK:
                # called back since its values changed: its call-back stays
                # while they still do not compile (no new one at each run)
                if usercompile.kernel(g.row)[0] is None:
                    continue
            elif (usercompile.values_key(g.row, plan) == key
                    and usercompile.refill(lay, g.row, plan)):
                continue
            option, u0, held, now, plan = _user_entry(g, lay)
            self.groups[gi, net.OPTION], self.groups[gi, net.U0] = option, u0
            if now is None:
                self.callbacks.append(held)
            elif held is not lay:
                self.kernels.append(held)
            self.watched[k] = (gi, g, _CALLED_BACK if now is None else now,
                               lay if now is None else held, plan)

    def __init__(self, asm, groups, cols, fpar, u, trows, tcols, varying, sources):
        laws = law_module("network")
        self.loop = laws.residual
        self.asm = asm
        self.n, self.n_node_rows, self.raw = asm.n, asm.n_node_rows, asm.raw
        self.trows, self.tcols = trows, tcols
        self.groups, self.cols, self.fpar, self.u = groups, cols, fpar, u
        self.arrays = (self.raw, self.n_node_rows, trows, tcols, groups, cols, fpar, u)
        self.no_states = NO_STATES
        self.time_dependent = bool(varying)
        self.set_time = _no_time
        self._sources = sources
        self.switching_loop, self.kinks_loop, self.regimes_loop = (
            laws.switching, laws.kinks, laws.regimes)
        self.n_switching, self.n_kinks, self.n_regimes = (
            int(k) for k in laws.sizes(groups))

    def switching(self, x, S):
        """``asm.switching(x, S)`` from the compiled :func:`softflow.laws.network.switching`
        (a new float array), or None where no group states switching functions."""
        if not self.n_switching:
            return None
        out = np.empty(self.n_switching)
        self.switching_loop(x, S, self.groups, self.cols, self.fpar, out)
        return out

    def kinks(self, x):
        """``asm.kinks(x)`` from the compiled :func:`softflow.laws.network.kinks`
        (a new int64 array), or None where no group states kinks."""
        if not self.n_kinks:
            return None
        out = np.empty(self.n_kinks, dtype=np.int64)
        self.kinks_loop(x, self.groups, self.cols, self.fpar, out)
        return out

    def regimes(self, x):
        """``asm.regimes(x)`` from the compiled :func:`softflow.laws.network.regimes`
        (a new int64 array), or None where no group states pieces."""
        if not self.n_regimes:
            return None
        out = np.empty(self.n_regimes, dtype=np.int64)
        self.regimes_loop(x, self.groups, self.cols, self.fpar, out)
        return out

    def source_arrays(self):
        """The sources' values, all of ``u`` in its order, as the arrays
        (base, slot, codes, factors, starts, floats) of the compiled
        :func:`softflow.laws.waves.source_values` (``out=u`` fills u at a
        time t as :meth:`set_time` would; :mod:`softflow.solve.wavecodes`),
        or None where a source's signal is not a waveform those cover."""
        global _WAVECODES
        if _WAVECODES is None:
            from . import wavecodes
            _WAVECODES = wavecodes
        wavecodes = _WAVECODES
        parts = [wavecodes.describe(P) for P in self._sources]
        if any(part is None for part in parts):
            return None
        return wavecodes.join(parts)

    def update_states(self, x, S, dt):
        """The states at the end of a step (the assembly's ``update_states(x, S,
        dt)``: S = psi, dt = c) from one call of the loop: a new array."""
        Sout = np.empty(S.size)
        if self.loop(x, S, 0.0, float(dt), False, np.empty(self.n), *self.arrays, Sout) >= 0:
            return self.asm.update_states(x, S, dt)     # a law refused the state
        return Sout


#: softflow.solve.wavecodes, imported at the first source_arrays
_WAVECODES = None


def _no_time(t):
    """set_time of a network whose loop reads nothing that changes with time."""


def compiled_update(asm):
    """``update_states(x, S, dt)`` of the assembly ``asm`` as one call of the
    compiled loop (:meth:`CompiledNetwork.update_states`: the states the
    per-group ``asm.update_states`` gives), or None where its residual is not
    the compiled one. Bound to the network as it is now: ask again after a
    run with new parameters."""
    network = getattr(asm.residual, "network", None)
    return None if network is None else network.update_states


#: a watched user component's key once its values changed to ones that
#: compiled code cannot read (:meth:`CompiledNetwork.check_user_values`)
_CALLED_BACK = b"called back"


def _user_entry(g, lay=None):
    """(OPTION, U0, what the network holds, the values' key, the kernel's
    plan) of the user group ``g``'s row: its compiled kernel's (the key its
    layout's address, ``lay`` refilled where it has the kernel's size, or a
    new one; the key of the values it was compiled with and the plan of its
    run-time values: :mod:`softflow.solve.usercompile`), or its call-back's
    (its evaluator, key and plan None: :mod:`softflow.solve.usercall`)."""
    from . import usercall, usercompile
    address, key, plan = usercompile.kernel(g.row)
    if address is not None:
        if lay is None or not usercompile.refill(lay, g.row, plan):
            lay = usercompile.layout(g, plan)
        return lay.ctypes.data, address, lay, key, plan
    evaluator = usercall.Evaluator(g)
    return usercall.register(evaluator), usercall.ADDRESS, evaluator, None, None


def compiled_residual(asm, failures):
    """``residual(x, S, t, dt, jac=False)`` of the assembly ``asm`` as one
    compiled call, or None where a group is not covered (see the module).
    ``failures``: the assembly's error wrappers (``PASS``, ``failure``,
    ``fluid_failure``), which name the source whose signal raised. The
    function's attribute ``network`` is the :class:`CompiledNetwork` it
    calls."""
    covered = [_covered(g) for g in asm.groups]
    if not asm.groups or any(c is None for c in covered):
        return None
    net = law_module("network")
    rows, cols, fpar, varying, refresh, sources = [], [], [], [], [], []
    sizes = []      # per group: its shared floats, each instance's floats, whether it has u
    callbacks: list = []     # the user components' evaluators (softflow.solve.usercall)
    kernels: list = []       # the compiled user components' layouts (usercompile)
    watched: list = []       # and their rows, groups and values' keys
    n_u = 0
    u_parts = []
    # each group's row as a list (made one array below), and the running sizes
    # of cols and fpar (where the group's own start)
    n_fields, n_col, n_f = len(net.GROUP_FIELDS), 0, 0
    for g, (cls_id, option, group_floats, per, values) in zip(asm.groups, covered):
        row = [0] * n_fields
        row[net.CLS], row[net.N], row[net.NV] = cls_id, g.n, g.col.shape[1]
        row[net.COL] = n_col
        cols.append(np.ascontiguousarray(g.col, dtype=np.int64).ravel())
        n_col += cols[-1].size
        row[net.S0], row[net.R0], row[net.NEQ] = g.s0, g.r0, g.neq
        row[net.J0], row[net.NJ] = g.j0, len(g.pattern)
        row[net.F0] = n_f
        fpar.append(np.asarray(group_floats, dtype=float))
        n_f += fpar[-1].size
        sizes.append([fpar[-1].size, 0 if per is None else np.shape(per)[1],
                      int(values is not None)])
        if per is not None:
            per = np.ascontiguousarray(per, dtype=float)
            if getattr(g, "begin", None) is not None and cls_id in (net.FREE_VOLUME,
                                                                    net.HELD_VOLUME):
                # h·A set at the start of each step (a heat-transfer correlation):
                # its column of the volumes' floats is refreshed before each call
                at = n_f
                refresh.append((g.params, slice(at, at + per.size, per.shape[1])))
            fpar.append(per.ravel())
            n_f += per.size
        row[net.OPTION] = option
        row[net.U0] = n_u
        if cls_id == net.USER:
            row[net.OPTION], row[net.U0], held, key, plan = _user_entry(g)
            if key is None:
                callbacks.append(held)              # held by the network: see usercall
            else:
                kernels.append(held)                # held by the network
                watched.append((len(rows), g, key, held, plan))
        if values is not None:
            u_parts.append(np.asarray(values.values(0.0), dtype=float).copy())
            sources.append(values)
            if values._varying:
                varying.append((values, n_u, n_u + g.n, g))
            n_u += g.n
        rows.append(row)
    groups = np.array(rows, dtype=np.int64)
    cols = np.concatenate(cols) if cols else np.zeros(0, dtype=np.int64)
    fpar = np.concatenate(fpar) if fpar else np.zeros(0)
    u = np.concatenate(u_parts) if u_parts else np.zeros(0)
    raw, n, nr = asm.raw, asm.n, asm.n_node_rows
    trows = np.ascontiguousarray(asm.through_rows, dtype=np.int64)
    tcols = np.ascontiguousarray(asm.through_cols, dtype=np.int64)
    loop = net.residual
    no_states = NO_STATES

    refreshed = None
    if refresh:
        def refreshed(t=None):
            for P, at in refresh:
                fpar[at] = P.hA
        varying.append((None, refreshed, None, None))
    network = CompiledNetwork(asm, groups, cols, fpar, u, trows, tcols, varying, sources)
    network.callbacks = callbacks
    network.kernels, network.watched = kernels, watched
    network.refresh = refreshed
    network.float_sizes = np.array(sizes, dtype=np.int64).reshape(-1, 3)
    if varying:
        passed, failure = failures["PASS"], failures["failure"]
        fluid_failure = failures["fluid_failure"]

        def set_time(t):
            for P, a, b, g in varying:
                if P is None:           # per-step coefficients: a, the refresh
                    a(t)
                    continue
                try:
                    u[a:b] = P.values(t)
                except FluidError as err:
                    raise fluid_failure(g, err) from None
                except passed:
                    raise
                except Exception as err:      # a user's signal: name the source
                    raise failure(g, err, t)
        network.set_time = set_time

        def residual(x, S, t, dt, jac=False):
            set_time(t)
            F = np.empty(n)
            if loop(x, S, float(t), float(dt), bool(jac), F, raw, nr, trows, tcols, groups,
                    cols, fpar, u, no_states) >= 0:
                raise_pending()
                return asm.python_residual(x, S, t, dt, jac)    # raises the law's error
            return F
    else:
        def residual(x, S, t, dt, jac=False):
            F = np.empty(n)
            if loop(x, S, float(t), float(dt), bool(jac), F, raw, nr, trows, tcols, groups,
                    cols, fpar, u, no_states) >= 0:
                raise_pending()
                return asm.python_residual(x, S, t, dt, jac)    # raises the law's error
            return F
    residual.__doc__ = ("F(x) for states S at the start of the step; with jac, also fills "
                        "the assembly's raw Jacobian entries (one compiled call: "
                        "softflow.solve.netcore).")
    residual.network = network      # type: ignore[attr-defined]
    return residual
