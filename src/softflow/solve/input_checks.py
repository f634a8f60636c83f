"""Checks of a network's inputs before it runs (issue 41): a tube whose flow
is negligible over the run (:func:`negligible_tubes`), found from the compiled
network and the components' initial states. Their records come first in
``result.warnings`` (:meth:`softflow.solve.simulation.Simulation.run`)."""
from __future__ import annotations

import math

import numpy as np

from ..constants import pressure_atmospheric
from ..fluids.base import FluidError
from .settings import NEGLIGIBLE_TUBE
from .validity import ValidityRecord


#: the component classes and functions these checks use, imported on their
#: first call (the components import this package; an import statement in a
#: function costs ~1 us a call)
_NAMES = None


def _names():
    """The classes and functions of the checks here, imported once."""
    global _NAMES
    if _NAMES is None:
        from types import SimpleNamespace

        from ..components.actuators import (Actuator, HystereticActuator,
                                            initial_volume_records)
        from ..components.chambers import LinearAccumulator
        from ..components.sources import MassFlowSource, PressureSource, VolumeFlowSource
        from ..components.tubes import CircularTube, laminar_conductance
        _NAMES = SimpleNamespace(
            Actuator=Actuator, HystereticActuator=HystereticActuator,
            initial_volume_records=initial_volume_records, LinearAccumulator=LinearAccumulator,
            MassFlowSource=MassFlowSource, PressureSource=PressureSource,
            VolumeFlowSource=VolumeFlowSource, CircularTube=CircularTube,
            laminar_conductance=laminar_conductance)
    return _NAMES


def initial_volumes(asm):
    """ValidityRecords (check ``'initial_volume_range'``) of the actuators of the
    compiled network ``asm`` whose initial volume lies outside their PV curve's
    data (:func:`softflow.components.actuators.initial_volume_records`, group
    by group)."""
    names = _NAMES if _NAMES is not None else _names()
    actuators = (names.Actuator, names.HystereticActuator)
    out = []
    for g in asm.groups:
        if isinstance(g.comps[0], actuators):
            out.extend(names.initial_volume_records(g.comps))
    return out


def negligible_tubes(asm, duration, rtol):
    """ValidityRecords (check ``'tube_negligible_flow'``) of the circular tubes of
    the compiled network ``asm`` whose flow is negligible over ``duration`` [s]
    (:data:`NEGLIGIBLE_TUBE`).

    A tube's time constant with a volume is tau = C / G: G its laminar
    (Hagen–Poiseuille) mass conductance at the higher of its ends' initial
    pressures, at least atmospheric (an upper bound of its flow per pascal,
    :func:`softflow.components.tubes.laminar_conductance`; a gas source that
    rises later raises it by its pressure ratio, which the margin of
    :data:`NEGLIGIBLE_TUBE` covers), C = dm/dp the volume's capacitance at its
    initial state: its fluid's compressibility plus its wall's compliance (a
    LinearAccumulator's, an actuator's PV curve's). Over the run the tube can
    change the volume's pressure by about duration / tau of the difference
    across it, at most. The volumes are those the tube reaches through other
    components from its ends, up to a volume or a source; the smallest
    capacitance among them is taken. A tube that reaches none (only sources:
    its flow is then the answer itself), or a volume whose capacitance is
    unknown (a user component, an actuator on a falling part of its curve),
    is not judged. Before a run, so that a scene whose tube does nothing says
    so before its result is read; a 1 nm x 1 km tube runs as fast as any
    (25 steps at the default rtol)."""
    names = _NAMES if _NAMES is not None else _names()
    CircularTube, laminar_conductance = names.CircularTube, names.laminar_conductance
    tubes = [g for g in asm.groups if isinstance(g.comps[0], CircularTube)]
    if not tubes:
        return []
    caps, unknown = _capacitances(asm)
    if not caps:
        return []
    c_min = min(caps.values())
    limit = NEGLIGIBLE_TUBE * rtol        # the largest duration / tau reported
    links = None
    out = []
    for g in tubes:
        comps = g.comps
        n = len(comps)
        col = g.col.reshape(n, -1)
        kp = [k for k, c in enumerate(col[0].tolist()) if asm.x_quantity[c] == "pressure"]
        if not kp:
            continue
        p = np.maximum(asm.x0[col[:, kp]].max(axis=1), pressure_atmospheric)
        length = np.fromiter((c.length for c in comps), dtype=float, count=n)
        diameter = np.fromiter((c.diameter for c in comps), dtype=float, count=n)
        try:
            with np.errstate(all="ignore"):
                G = laminar_conductance(comps[0].fluid, length, diameter, p)
        except FluidError:
            continue
        # the smallest capacitance anywhere bounds every tube's figure: only the
        # tubes that pass this look for the volumes they reach
        for k in np.flatnonzero(duration * G < limit * c_min).tolist():
            if links is None:
                links = _links(asm)
            comp = comps[k]
            reached = _volumes_reached(links, comp.label, caps, unknown)
            if not reached:
                continue
            label, C = min(reached, key=lambda lc: lc[1])
            tau = C / G[k]
            if not duration / tau < limit:
                continue
            g_, i_ = asm.where[label]
            volume = g_.comps[i_].describe()
            suggestion = ("check its length and diameter (units), or leave it out if it is "
                          "meant to be closed")
            message = (f"{comp.describe()}: its flow is negligible. With length = "
                       f"{length[k]:.3g} m and diameter = {diameter[k]:.3g} m its laminar "
                       f"(Hagen–Poiseuille) conductance is {G[k]:.3g} kg/s per Pa, so its "
                       f"time constant with {volume} (capacitance {C:.3g} kg/Pa), the "
                       f"smallest volume it reaches, is {tau:.3g} s, {tau / duration:.3g} "
                       f"times the duration ({duration:.6g} s): over the run it can equalize "
                       f"at most {duration / tau:.3g} of the pressure difference across it, "
                       f"less than {NEGLIGIBLE_TUBE:g} x rtol ({rtol:g}); the result is that "
                       f"of a closed tube. Suggestion: {suggestion}")
            out.append(ValidityRecord(
                component=comp.label, check="tube_negligible_flow", measured=tau,
                limit=duration / limit, unit="s", suggestion=suggestion, message=message,
                details={"first_time": 0.0, "conductance": float(G[k]), "volume": label,
                         "capacitance": C, "fraction_equalized": duration / tau},
                fraction=tau * limit / duration))
    return out


def _capacitances(asm):
    """({label: capacitance [kg/Pa]} of the network's volumes, {labels of volumes
    whose capacitance is unknown}). A volume is a component with a mass state;
    its capacitance dm/dp at its initial state is V dρ/dp, the fluid's
    compressibility, plus ρ dV/dp of a compliant wall (a LinearAccumulator's
    compliance, an actuator's PV curve); unknown for a user's volume, an
    actuator on a falling part of its curve, and where it is not > 0 (an
    incompressible liquid in a rigid container)."""
    names = _NAMES if _NAMES is not None else _names()
    Actuator, HystereticActuator = names.Actuator, names.HystereticActuator
    LinearAccumulator = names.LinearAccumulator
    caps, unknown = {}, set()
    S0, x0, quantity = asm.S0, asm.x0, asm.s_quantity
    for g in asm.groups:
        if not g.ns:
            continue
        comps = g.comps
        n = len(comps)
        kinds = quantity[g.s0:g.s0 + g.ns]
        if "mass" not in kinds:
            continue
        first = comps[0]
        fluid = getattr(first, "fluid", None)
        col = g.col.reshape(n, -1)
        kp = [k for k, c in enumerate(col[0].tolist()) if asm.x_quantity[c] == "pressure"]
        if fluid is None or not kp or g.row is not None:     # a user's volume
            unknown.update(c.label for c in comps)
            continue
        # (each member's mass state, a view: g.ns states a member)
        m = S0[g.s0 + kinds.index("mass"):g.s1:g.ns]
        p = x0[col[:, kp[0]]]
        try:
            with np.errstate(all="ignore"):
                rho = np.asarray(fluid.density(p), dtype=float)
                C = m * np.asarray(fluid.density_dp(p), dtype=float) / rho
                # dV/dp of the wall
                if isinstance(first, LinearAccumulator):
                    wall = np.fromiter((c.compliance for c in comps), dtype=float, count=n)
                elif isinstance(first, (Actuator, HystereticActuator)):
                    v0 = np.fromiter((c.initial_volume for c in comps), dtype=float, count=n)
                    if isinstance(first, Actuator):
                        scale = np.fromiter((c.pressure_scale for c in comps), dtype=float,
                                            count=n)
                        slope = scale * np.asarray(first._curve_fn.fdf(v0)[1], dtype=float)
                    else:
                        slope = np.array([float(c.loop.fdf_volume(
                            np.array([c.initial_volume]), c.initial_branch > 0.5)[1][0])
                            for c in comps])
                    # (on a falling part of its curve the actuator's capacitance is
                    # negative, below any bound: no claim)
                    wall = np.where(slope > 0, 1.0 / slope, np.nan)
                else:
                    wall = np.zeros(n)
                C = C + rho * wall
        except (FluidError, ValueError, ArithmeticError):
            unknown.update(c.label for c in comps)
            continue
        for c, v in zip(comps, C.tolist()):
            if v > 0 and math.isfinite(v):
                caps[c.label] = v
            else:
                unknown.add(c.label)
    return caps, unknown


def _links(asm):
    """({label: [node, ...]}, {node: [label, ...]}, {labels of sources}) of the
    compiled network."""
    names = _NAMES if _NAMES is not None else _names()
    MassFlowSource, PressureSource, VolumeFlowSource = (
        names.MassFlowSource, names.PressureSource, names.VolumeFlowSource)
    nodes_of, at = {}, {}
    terminals = [t for c in asm._node_comps for t in c.terminals]
    for t, k in zip(terminals, asm._node_of):
        label = t.component.label
        nodes_of.setdefault(label, []).append(int(k))
        at.setdefault(int(k), []).append(label)
    sources = {c.label for c in asm._node_comps
               if isinstance(c, (PressureSource, MassFlowSource, VolumeFlowSource))}
    return nodes_of, at, sources


def _volumes_reached(links, label, caps, unknown):
    """[(label, capacitance)] of the volumes that component ``label`` reaches from
    its terminals through components that are neither volumes nor sources;
    None where it reaches a volume of unknown capacitance."""
    nodes_of, at, sources = links
    seen = {label}
    todo = list(nodes_of.get(label, ()))
    visited = set(todo)
    found = []
    while todo:
        for other in at.get(todo.pop(), ()):
            if other in seen:
                continue
            seen.add(other)
            if other in unknown:
                return None
            if other in caps:
                found.append((other, caps[other]))
            elif other not in sources:
                for k in nodes_of.get(other, ()):
                    if k not in visited:
                        visited.add(k)
                        todo.append(k)
    return found
