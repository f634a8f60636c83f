"""A network's step equations in one compiled pass: the loop over its groups.

The assembly (:mod:`softflow.solve.assembly`) describes each group of
components by integers and floats; this loop evaluates the node rows (the
sum of the through variables at each node) and then each group by its class
id, calling the same compiled laws the groups call one at a time
(:mod:`.tube`, :mod:`.volumes`, :mod:`.valves`; in thermal scenes of an
ideal gas :mod:`.thermal`; a user's component through its callback into
Python, :mod:`softflow.solve.usercall`), with the step's states X = psi + c·r(V)
formed as :mod:`softflow.solve.discretize` forms them. It replaces a Python
call and its NumPy glue per group and per evaluation; what it covers is listed
in :data:`softflow.solve.netcore` (the rest of the library, user components
and real fluids keep the per-group path).

Layout. ``groups`` holds one row per group (:data:`GROUP_FIELDS`): its class
id, its size n, its number of interface variables nv, the offset of its
columns in ``cols`` (n·nv global indices of its variables, instance by
instance), the offsets of its states in S, of its rows in F and of its
Jacobian entries in ``raw`` (n·neq rows and n·nj entries, instance by
instance, each in the class's ``jac_pattern`` order), the offset of its
floats in ``fpar`` (group constants first, then a fixed number per
instance), an integer option (a friction correlation's id, a fluid's kind)
and the offset of its time-dependent values in ``u`` (source values, set
before each call by the caller). Settings come in as arguments, never as
globals (numba freezes globals into its cache).

End-of-step states. Given a non-empty ``Sout`` (S's size and layout), every
class with states also writes its states at the end of the step there, as
:func:`softflow.solve.discretize.step_functions`' ``update`` (the assembly's
``update_states``) makes them: the continuous ones X = psi + c·r(V), the
very values its rows are evaluated at, the discrete ones as the class's
``switch`` sets them from X (a snapping valve's mode from p_a - p_b
(:func:`snapping_switch`), a hysteretic actuator's branch from its volume
(:func:`.volumes.on_inflation`) and, in a thermal scene of a free gas, its
work offset (:func:`loop_offset`)). Classes without states write nothing.

Switching functions, kinks and pieces. :func:`switching`, :func:`kinks` and
:func:`regimes` are the assembly's ``switching(x, S)``, ``kinks(x)`` and
``regimes(x)`` (:mod:`softflow.solve.assembly`) on the same arrays: the
values of every group whose class states them, in group order, instance by
instance, with the classes' own arithmetic (a snapping valve's
``switching``, isothermal and thermal; a hysteretic actuator's loop's,
isothermal and thermal, free (one value per discrete state: two) or held;
a check valve's ``kinks`` and ``regime``, isothermal and thermal). Each
writes into the array it is given and returns how many it wrote
(:func:`sizes`: how many each writes for a network).
"""
from __future__ import annotations

import math

import numpy as np

from . import call_user, jit
from .fanno import gas_constants
from .tube import isothermal_drop, tube_drop
from .orifice import _maximum
from .valves import (check_valve_flow, friction_term, mean_density, orifice_flow,
                     orifice_upstream, restrictor_row, tesla_drop)
from .valves import density as valve_density
from .volumes import (compliant_mass, curve_law, curve_point_flat, density, on_inflation,
                      refused, rigid_mass, scaled_curve)
from .thermal import (adiabatic_tesla_rows, adiabatic_tube_rows, check_valve_rows,
                      energy_entries, free_rows, held_rows, ideal_density, loop_offset,
                      loop_wall, orifice_rows, snapping_rows, source_energy, upwind_energy,
                      volume_flow_law, wall_law)

#: class ids
PRESSURE_SOURCE, MASS_FLOW_SOURCE, VOLUME_FLOW_SOURCE = 1, 2, 3
TUBE, RIGID_GAS, RIGID_LIQUID, ACCUMULATOR = 4, 5, 6, 7
ORIFICE, CHECK_VALVE, TESLA_VALVE, SNAPPING_VALVE, INERTIAL_TUBE = 8, 9, 10, 11, 12
ACTUATOR, HYSTERETIC_ACTUATOR = 13, 14
#: thermal scenes of an ideal gas (softflow.components.thermal, laws in .thermal)
THERMAL_PRESSURE_SOURCE, THERMAL_MASS_FLOW_SOURCE, THERMAL_VOLUME_FLOW_SOURCE = 15, 16, 17
THERMAL_TUBE, THERMAL_TESLA_VALVE, FREE_VOLUME, HELD_VOLUME = 18, 19, 20, 21
THERMAL_ORIFICE, THERMAL_CHECK_VALVE, THERMAL_SNAPPING_VALVE = 22, 23, 24
THERMAL_INERTIAL_TUBE = 25
#: a user's component (one instance), called back in Python (softflow.solve.usercall):
#: its row's OPTION holds its key, U0 the callback's address
USER = 26

#: the columns of a row of ``groups``
GROUP_FIELDS = ("cls", "n", "nv", "col", "s0", "r0", "neq", "j0", "nj", "f0", "option", "u0")
CLS, N, NV, COL, S0, R0, NEQ, J0, NJ, F0, OPTION, U0 = range(12)

#: floats per instance (after the group's own) of the classes that take them
TUBE_FLOATS = 6            # re_per_mf, c, eD, a, area, kre; group: Re_lo, Re_hi, c2
TUBE_GROUP_FLOATS = 3
ORIFICE_FLOATS = 9         # K, area, dp_small, gamma, Cd, C, b, m, pr_laminar
ORIFICE_GROUP_FLOATS = 5   # R T (0: a liquid), rho (a liquid's), T, ISO 6358's rho0, T0
CHECK_VALVE_FLOATS = 8     # K, Cd, gamma, area, dp_small, cracking, band, leakage
#: R T, rho, then the cut of its regimes (:func:`regimes`): the band's top and bottom edge
#: REGIME_EDGE and the bottom's number of pieces LOW_PIECES (softflow.components.valves)
CHECK_VALVE_GROUP_FLOATS = 4
TESLA_FLOATS = 7           # re_per_mf, c_mu, eD, a, area, mf_blend, diodicity
#: a snapping valve's: re_per_mf, c_mu, eD, a, area, closed conductance, opening and
#: closing pressures (its switch's)
SNAPPING_FLOATS = 8
VALVE_GROUP_FLOATS = 5     # Re_lo, Re_hi, c2 (p/rho of an ideal gas, else 0), R T, rho
INERTIAL_FLOATS = 7        # the tube's six, then A/L (1 / (L/A))
#: thermal flow elements: group floats lo, hi, R, gamma, cp, c - h0, band, G
THERMAL_FLOW_GROUP_FLOATS = 8
THERMAL_TUBE_FLOATS = 6    # re_per_mf, c_mu, eD, a, area, kre
THERMAL_TESLA_FLOATS = 7   # re_per_mf, c_mu, eD, a, area, mf_blend, diodicity
#: a thermal snapping valve's: group floats those of a flow element, then R T, rho, T_ref
THERMAL_SNAPPING_GROUP_FLOATS = 11
#: re_per_mf, c_mu, eD, a, area, kre, closed conductance, opening and closing pressures
THERMAL_SNAPPING_FLOATS = 9
#: thermal volumes: group floats R, cv, c, h0, any heat, curve mode, scaled, p_atm (then a
#: curve wall's curve and its work at its knots; a loop's V_hi, V_lo, work shifts, the
#: deflation curve's mode, then both curves so); per instance hA, T_wall, the wall's own
VOLUME_GROUP_FLOATS = 8
#: a thermal orifice's group floats: the orifice's five, then T_ref, cp, c - h0, band, G
THERMAL_ORIFICE_GROUP_FLOATS = 10
#: a thermal check valve's: R T, rho, then cp, c - h0, band, G, then REGIME_EDGE, LOW_PIECES
THERMAL_CHECK_VALVE_GROUP_FLOATS = 8


@jit
def residual(x, S, t, dt, jac, F, raw, n_node_rows, trows, tcols, groups, cols, fpar, u,
             Sout):
    """F(x) of the network's step equations (states S = psi, step coefficient
    dt = c) into F, and with ``jac`` the Jacobian's entries into ``raw``;
    where ``Sout`` is not empty (S's size), the states at the end of the step
    into it (see the module). Returns -1, or the index of a group that met a
    state its law refuses (an actuator's volume beyond a curve that does not
    extrapolate): the caller evaluates that network on the per-group path,
    which raises the error (F, raw and Sout are then incomplete)."""
    for k in range(n_node_rows):
        F[k] = 0.0
    for k in range(trows.size):
        F[trows[k]] += x[tcols[k]]
    for g in range(groups.shape[0]):
        cls = groups[g, CLS]
        if cls == TUBE:
            _tube(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == PRESSURE_SOURCE or cls == MASS_FLOW_SOURCE:
            _source(x, F, raw, jac, groups[g], cols, u, cls == PRESSURE_SOURCE)
        elif cls == VOLUME_FLOW_SOURCE:
            _volume_flow_source(x, F, raw, jac, groups[g], cols, fpar, u)
        elif cls == RIGID_GAS or cls == ACCUMULATOR:
            _volume(x, S, dt, F, raw, jac, groups[g], cols, fpar, cls == ACCUMULATOR, Sout)
        elif cls == RIGID_LIQUID:
            _rigid_liquid(x, S, dt, F, raw, jac, groups[g], cols, Sout)
        elif cls == ORIFICE:
            _orifice(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == CHECK_VALVE:
            _check_valve(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == TESLA_VALVE:
            _tesla_valve(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == SNAPPING_VALVE:
            _snapping_valve(x, S, F, raw, jac, groups[g], cols, fpar, Sout)
        elif cls == INERTIAL_TUBE:
            _inertial_tube(x, S, dt, F, raw, jac, groups[g], cols, fpar, Sout)
        elif cls == ACTUATOR:
            if not _actuator(x, S, dt, F, raw, jac, groups[g], cols, fpar, Sout):
                return g
        elif cls == HYSTERETIC_ACTUATOR:
            _hysteretic(x, S, dt, F, raw, jac, groups[g], cols, fpar, Sout)
        elif cls == THERMAL_TUBE:
            _thermal_tube(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == FREE_VOLUME or cls == HELD_VOLUME:
            if not _thermal_volume(x, S, dt, F, raw, jac, groups[g], cols, fpar,
                                   cls == FREE_VOLUME, Sout):
                return g
        elif cls == THERMAL_PRESSURE_SOURCE:
            _thermal_pressure_source(x, F, raw, jac, groups[g], cols, fpar, u)
        elif cls == THERMAL_MASS_FLOW_SOURCE or cls == THERMAL_VOLUME_FLOW_SOURCE:
            _thermal_flow_source(x, F, raw, jac, groups[g], cols, fpar, u,
                                 cls == THERMAL_VOLUME_FLOW_SOURCE)
        elif cls == THERMAL_TESLA_VALVE:
            _thermal_tesla(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == THERMAL_ORIFICE:
            _thermal_orifice(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == THERMAL_CHECK_VALVE:
            _thermal_check_valve(x, F, raw, jac, groups[g], cols, fpar)
        elif cls == THERMAL_SNAPPING_VALVE:
            _thermal_snapping_valve(x, S, F, raw, jac, groups[g], cols, fpar, Sout)
        elif cls == THERMAL_INERTIAL_TUBE:
            _thermal_inertial_tube(x, S, dt, F, raw, jac, groups[g], cols, fpar, Sout)
        elif cls == USER:
            if call_user(groups[g, U0], groups[g, OPTION], t, dt, jac, x, S, F, raw,
                         Sout) != 0:
                return g
    return -1


@jit
def _wall_law(F, raw, jac, gr, i, p, rho, rho_p, vol, pc, dpc, dt):
    """Row and entries of a volume on a PV curve, F = p - p_curve(m / rho(p))
    at the step's mass (:func:`.volumes.curve_law`): (dF/dp, dF/dmdot = c dF/dm)."""
    f, d_p, d_m = curve_law(p, rho, rho_p, vol, pc, dpc)
    F[gr[R0] + i] = f
    if jac:
        raw[gr[J0] + 2 * i] = d_p
        raw[gr[J0] + 2 * i + 1] = (dt * 1.0) * d_m


@jit
def _curve(fpar, at):
    """A PV curve stored at fpar[at:]: (knots, table, the offset past it), as
    [n knots, n rows, knots..., table rows of 5...]."""
    nk, nr = int(fpar[at]), int(fpar[at + 1])
    k0 = at + 2
    t0 = k0 + nk
    return fpar[k0:t0], fpar[t0:t0 + 5 * nr].reshape((nr, 5)), t0 + 5 * nr


@jit
def _flat_curve(fpar, at):
    """:func:`_curve`'s knots and table, the table's rows flat
    (:func:`.volumes.curve_point_flat`), and the offset past it."""
    nk, nr = int(fpar[at]), int(fpar[at + 1])
    k0 = at + 2
    t0 = k0 + nk
    return fpar[k0:t0], fpar[t0:t0 + 5 * nr], t0 + 5 * nr


@jit
def _actuator(x, S, dt, F, raw, jac, gr, cols, fpar, Sout):
    """A group of actuators on one compiled PV curve
    (:func:`.volumes.actuator_residual`), state: the mass; floats: the fluid's
    constant, p_atm, whether scaled, the curve's extrapolation code, the
    curve, then each one's pressure scale. False where a volume is beyond a
    curve that refuses it."""
    n, c0, s0, f0, kind = gr[N], gr[COL], gr[S0], gr[F0], gr[OPTION]
    c, p_atm, scaled, mode = fpar[f0], fpar[f0 + 1], fpar[f0 + 2] > 0.5, int(fpar[f0 + 3])
    knots, table, end = _flat_curve(fpar, f0 + 4)
    for i in range(n):
        p, mf = x[cols[c0 + 2 * i]], x[cols[c0 + 2 * i + 1]]
        rho, rho_p = density(kind, c, p)
        m = S[s0 + i] + dt * mf
        if Sout.size > 0:
            Sout[s0 + i] = m
        vol = m / rho
        if refused(mode, knots, vol):
            return False
        pc, dpc = curve_point_flat(knots, table, vol)
        if scaled:
            pc, dpc = scaled_curve(pc, dpc, fpar[end + i], p_atm)
        _wall_law(F, raw, jac, gr, i, p, rho, rho_p, vol, pc, dpc, dt)
    return True


@jit
def _hysteretic(x, S, dt, F, raw, jac, gr, cols, fpar, Sout):
    """A group of hysteretic actuators on one loop
    (:func:`.volumes.hysteretic_residual`), states (mass, branch) per
    instance; floats: the fluid's constant, V_hi, V_lo, then the inflation
    and deflation curves. The branch after the step is the curve the step
    read (:meth:`softflow.curves.HysteresisLoop.next_inflating`)."""
    n, c0, s0, f0, kind = gr[N], gr[COL], gr[S0], gr[F0], gr[OPTION]
    c, v_hi, v_lo = fpar[f0], fpar[f0 + 1], fpar[f0 + 2]
    knots_up, table_up, end = _flat_curve(fpar, f0 + 3)
    knots_down, table_down, _ = _flat_curve(fpar, end)
    for i in range(n):
        p, mf = x[cols[c0 + 2 * i]], x[cols[c0 + 2 * i + 1]]
        rho, rho_p = density(kind, c, p)
        m = S[s0 + 2 * i] + dt * mf
        vol = m / rho
        up = on_inflation(vol, S[s0 + 2 * i + 1] > 0.5, v_hi, v_lo)
        if Sout.size > 0:
            Sout[s0 + 2 * i] = m
            Sout[s0 + 2 * i + 1] = 1.0 if up else 0.0
        if up:
            pc, dpc = curve_point_flat(knots_up, table_up, vol)
        else:
            pc, dpc = curve_point_flat(knots_down, table_down, vol)
        _wall_law(F, raw, jac, gr, i, p, rho, rho_p, vol, pc, dpc, dt)


@jit
def _tube_drop(kind, lo, hi, c2, pa, mf, pb, fpar, f):
    """A tube's required p_a - p_b and its partials (dp, d_pa, d_mf, d_pb) from
    its six floats at fpar[f:], by the law ``c2`` names (:mod:`.tube`:
    isothermal pipe flow or the mean-density law of an ideal gas, a liquid's
    Darcy law)."""
    return tube_drop(kind, lo, hi, pa, mf, pb, fpar[f], fpar[f + 1], fpar[f + 2],
                     fpar[f + 3], fpar[f + 4], c2, fpar[f + 5])


@jit
def _inertial_tube(x, S, dt, F, raw, jac, gr, cols, fpar, Sout):
    """A group of tubes with inertance: the flow a state q with rate
    dq/dt = A/L ((p_a - p_b) - dp(mf)) (dp the tube's law), the rows
    (mf_a + mf_b, mf_a - q) at q = psi + c·rate, entries in the tube's pattern
    (the rate's partials times -c, as discretize combines them)."""
    n, c0, s0, f0, kind = gr[N], gr[COL], gr[S0], gr[F0], gr[OPTION]
    lo, hi, c2 = fpar[f0], fpar[f0 + 1], fpar[f0 + 2]
    for i in range(n):
        k = c0 + 4 * i
        pa, mfa, pb = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]]
        f = f0 + TUBE_GROUP_FLOATS + INERTIAL_FLOATS * i
        dp, d_pa, d_mf, d_pb = _tube_drop(kind, lo, hi, c2, pa, mfa, pb, fpar, f)
        a_l = fpar[f + 6]
        q = S[s0 + i] + dt * (a_l * ((pa - pb) - dp))
        if Sout.size > 0:
            Sout[s0 + i] = q
        # rows (mass balance, mf_a - q); entries (1, 1, dq/dp_a, 1 - dq/dmf, dq/dp_b)·
        _two_port(x, F, raw, jac, gr, cols, i, mfa - q, (dt * (a_l * (1.0 - d_pa))) * -1.0,
                  1.0 + (dt * (-a_l * d_mf)) * -1.0, (dt * (-a_l * (1.0 + d_pb))) * -1.0)


@jit
def _tesla_valve(x, F, raw, jac, gr, cols, fpar):
    """A group of Tesla valves (:func:`.valves.tesla_residual`)."""
    n, c0, f0, kind = gr[N], gr[COL], gr[F0], gr[OPTION]
    lo, hi, c2, rho = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 4]
    for i in range(n):
        k = c0 + 4 * i
        pa, mf, pb = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]]
        f = f0 + VALVE_GROUP_FLOATS + TESLA_FLOATS * i
        dp, d_pa, d_mf, d_pb = tesla_drop(kind, lo, hi, pa, mf, pb, fpar[f], fpar[f + 1],
                                          fpar[f + 2], fpar[f + 3], fpar[f + 4], fpar[f + 5],
                                          fpar[f + 6], c2, rho, 0.0)
        _two_port(x, F, raw, jac, gr, cols, i, (pa - pb) - dp, 1.0 - d_pa, -d_mf, -1.0 - d_pb)


@jit
def _snapping_valve(x, S, F, raw, jac, gr, cols, fpar, Sout):
    """A group of snapping valves (:func:`.valves.snapping_residual`), the
    mode of each (> 0.5 open) its state at the step's start, the mode after
    the step :func:`snapping_switch`'s."""
    n, c0, s0, f0, kind = gr[N], gr[COL], gr[S0], gr[F0], gr[OPTION]
    lo, hi, c2, RT, rho = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3], fpar[f0 + 4]
    for i in range(n):
        k = c0 + 4 * i
        pa, mf, pb = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]]
        f = f0 + VALVE_GROUP_FLOATS + SNAPPING_FLOATS * i
        re_per_mf, c_mu, eD, a = fpar[f], fpar[f + 1], fpar[f + 2], fpar[f + 3]
        if Sout.size > 0:
            Sout[s0 + i] = snapping_switch(pa - pb, fpar[f + 6], fpar[f + 7], S[s0 + i])
        is_open = S[s0 + i] > 0.5
        if is_open and c2 > 0.0:
            dp, d_pa, d_mf, d_pb = isothermal_drop(kind, lo, hi, pa, mf, pb, re_per_mf, c_mu,
                                                   eD, a, fpar[f + 4], c2, 0.0)
            f1, j_pa, j_mf, j_pb = (pa - pb) - dp, 1.0 - d_pa, -d_mf, -1.0 - d_pb
        else:
            r, dr = mean_density(pa, pb, RT, rho)
            if is_open:
                X, dX = friction_term(kind, lo, hi, mf, re_per_mf, c_mu, eD, a)
            else:
                dX = 1.0 / fpar[f + 5]
                X = dX * mf
            f1, j_pa, j_mf, j_pb = restrictor_row(pa, pb, X, dX, r, dr)
        _two_port(x, F, raw, jac, gr, cols, i, f1, j_pa, j_mf, j_pb)


@jit
def snapping_switch(dp, opening, closing, mode):
    """A snapping valve's mode after a step that ended at p_a - p_b = dp,
    having started it in ``mode`` (1 open, 0 shut): open above the opening
    pressure, shut below the closing one, else as it was
    (:meth:`softflow.components.valves.SnappingValve.switch`)."""
    return 1.0 if dp > opening else (0.0 if dp < closing else mode)


@jit
def _two_port(x, F, raw, jac, gr, cols, i, f1, j_pa, j_mf, j_pb):
    """Instance i of a two-port group: rows (mf_a + mf_b, f1) and, with jac,
    the entries (1, 1, j_pa, j_mf, j_pb) of the two-port pattern
    (:func:`.tube.two_port_row`)."""
    c, r, j = gr[COL] + 4 * i, gr[R0] + 2 * i, gr[J0] + 5 * i
    F[r] = x[cols[c + 1]] + x[cols[c + 3]]
    F[r + 1] = f1
    if jac:
        raw[j] = 1.0
        raw[j + 1] = 1.0
        raw[j + 2] = j_pa
        raw[j + 3] = j_mf
        raw[j + 4] = j_pb


@jit
def _orifice(x, F, raw, jac, gr, cols, fpar):
    """A group of orifices (:func:`.valves.orifice_residual`), law ``option``
    (loss coefficient, nozzle, ISO 6358), densities made here (an ideal gas
    or a liquid)."""
    n, c0, f0, model = gr[N], gr[COL], gr[F0], gr[OPTION]
    RT, rho, T, rho0, T0 = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3], fpar[f0 + 4]
    for i in range(n):
        k = c0 + 4 * i
        pa, mf, pb = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]]
        f = f0 + ORIFICE_GROUP_FLOATS + ORIFICE_FLOATS * i
        if model == 2:                          # ISO 6358 takes no density
            r, dr = 0.0, 0.0
        else:
            r, dr = valve_density(orifice_upstream(model, pa, pb), RT, rho)
        q, q_pa, q_pb = orifice_flow(model, pa, pb, r, dr, fpar[f], fpar[f + 1], fpar[f + 2],
                                     fpar[f + 3], fpar[f + 4], T, fpar[f + 5], fpar[f + 6],
                                     fpar[f + 7], fpar[f + 8], rho0, T0)
        _two_port(x, F, raw, jac, gr, cols, i, mf - q, -q_pa, 1.0, -q_pb)


@jit
def _check_valve(x, F, raw, jac, gr, cols, fpar):
    """A group of check valves (:func:`.valves.check_valve_residual`), the
    open passage a nozzle where ``option`` is 1."""
    n, c0, f0 = gr[N], gr[COL], gr[F0]
    nozzle = gr[OPTION] == 1
    RT, rho = fpar[f0], fpar[f0 + 1]
    for i in range(n):
        k = c0 + 4 * i
        pa, mf, pb = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]]
        f = f0 + CHECK_VALVE_GROUP_FLOATS + CHECK_VALVE_FLOATS * i
        ro, dro = valve_density(_maximum(pa, pb) if nozzle else pa, RT, rho)
        rm, drm = mean_density(pa, pb, RT, rho)
        cracking = fpar[f + 5]
        q, q_pa, q_pb = check_valve_flow(pa, pb, nozzle, ro, dro, rm, drm, fpar[f], fpar[f + 1],
                                         fpar[f + 2], fpar[f + 3], fpar[f + 4], cracking,
                                         cracking + fpar[f + 6], fpar[f + 7])
        _two_port(x, F, raw, jac, gr, cols, i, mf - q, -q_pa, 1.0, -q_pb)


@jit
def _source(x, F, raw, jac, gr, cols, u, pressure):
    """F = p - value (a pressure source) or mf + value (a flow source), dF = 1."""
    n, c0, r0, j0, u0 = gr[N], gr[COL], gr[R0], gr[J0], gr[U0]
    for i in range(n):
        if pressure:
            F[r0 + i] = x[cols[c0 + 2 * i]] - u[u0 + i]
        else:
            F[r0 + i] = x[cols[c0 + 2 * i + 1]] + u[u0 + i]
        if jac:
            raw[j0 + i] = 1.0


@jit
def _volume_flow_source(x, F, raw, jac, gr, cols, fpar, u):
    """F = mf + rho(p) q, the density by the fluid kind ``option`` (constant
    ``fpar[f0]``); entries (dF/dp, dF/dmf)."""
    n, c0, r0, j0, u0 = gr[N], gr[COL], gr[R0], gr[J0], gr[U0]
    kind, c = gr[OPTION], fpar[gr[F0]]
    for i in range(n):
        p = x[cols[c0 + 2 * i]]
        q = u[u0 + i]
        rho, rho_p = density(kind, c, p)
        F[r0 + i] = x[cols[c0 + 2 * i + 1]] + rho * q
        if jac:
            raw[j0 + 2 * i] = rho_p * q
            raw[j0 + 2 * i + 1] = 1.0


@jit
def _tube(x, F, raw, jac, gr, cols, fpar):
    """A group of tubes (:func:`.tube.residual`: the law ``c2`` names, of
    :mod:`.tube`), correlation id ``option``."""
    n, c0, r0, j0, f0 = gr[N], gr[COL], gr[R0], gr[J0], gr[F0]
    kind = gr[OPTION]
    lo, hi, c2 = fpar[f0], fpar[f0 + 1], fpar[f0 + 2]
    for i in range(n):
        k = c0 + 4 * i
        pa, mfa, pb, mfb = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]], x[cols[k + 3]]
        f = f0 + TUBE_GROUP_FLOATS + TUBE_FLOATS * i
        dp, d_pa, d_mf, d_pb = _tube_drop(kind, lo, hi, c2, pa, mfa, pb, fpar, f)
        F[r0 + 2 * i] = mfa + mfb
        F[r0 + 2 * i + 1] = (pa - pb) - dp
        if jac:
            j = j0 + 5 * i
            raw[j] = 1.0
            raw[j + 1] = 1.0
            raw[j + 2] = 1.0 - d_pa
            raw[j + 3] = -d_mf
            raw[j + 4] = -1.0 - d_pb


@jit
def _volume(x, S, dt, F, raw, jac, gr, cols, fpar, compliant, Sout):
    """Rigid volumes of a compressible fluid (F = rho(p) volume - m) or linear
    accumulators (F = rho(p)(volume + compliance (p - p_ref)) - m), at the
    step's mass m = psi + c·mdot; entries (dF/dp, dF/dmdot = -c). Floats: the
    fluid's constant, then volume (and compliance, p_ref) per instance."""
    n, c0, s0, r0, j0, f0 = gr[N], gr[COL], gr[S0], gr[R0], gr[J0], gr[F0]
    kind, c = gr[OPTION], fpar[f0]
    per = 3 if compliant else 1
    for i in range(n):
        p, mf = x[cols[c0 + 2 * i]], x[cols[c0 + 2 * i + 1]]
        rho, rho_p = density(kind, c, p)
        f = f0 + 1 + per * i
        if compliant:
            m, m_p = compliant_mass(rho, rho_p, p, fpar[f], fpar[f + 1], fpar[f + 2])
        else:
            m, m_p = rigid_mass(rho, rho_p, fpar[f])
        X = S[s0 + i] + dt * mf
        if Sout.size > 0:
            Sout[s0 + i] = X
        F[r0 + i] = m - X
        if jac:
            raw[j0 + 2 * i] = m_p
            raw[j0 + 2 * i + 1] = -dt


@jit
def _rigid_liquid(x, S, dt, F, raw, jac, gr, cols, Sout):
    """A rigid chamber of liquid admits no flow: F = mdot; entries (0, 1);
    its mass at the step's end psi + c·mdot all the same (the rate every
    volume has)."""
    n, c0, s0, r0, j0 = gr[N], gr[COL], gr[S0], gr[R0], gr[J0]
    for i in range(n):
        if Sout.size > 0:
            Sout[s0 + i] = S[s0 + i] + dt * x[cols[c0 + 2 * i + 1]]
        F[r0 + i] = x[cols[c0 + 2 * i + 1]]
        if jac:
            raw[j0 + 2 * i] = 0.0
            raw[j0 + 2 * i + 1] = 1.0


# -- thermal scenes of an ideal gas (softflow.components.thermal; laws: .thermal) --------
@jit
def _thermal_tube(x, F, raw, jac, gr, cols, fpar):
    """A group of gas tubes in a thermal scene, V = [p_a, mf_a, T_a, E_a, p_b,
    mf_b, T_b, E_b] (:func:`.thermal.adiabatic_tube_rows`)."""
    n, c0, r0, j0, f0, kind = gr[N], gr[COL], gr[R0], gr[J0], gr[F0], gr[OPTION]
    lo, hi, R, gamma = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3]
    cp, ch, band, G = fpar[f0 + 4], fpar[f0 + 5], fpar[f0 + 6], fpar[f0 + 7]
    gas = gas_constants(gamma)
    for i in range(n):
        k = c0 + 8 * i
        f = f0 + THERMAL_FLOW_GROUP_FLOATS + THERMAL_TUBE_FLOATS * i
        adiabatic_tube_rows(F, r0 + 4 * i, raw, j0 + 15 * i, jac, x[cols[k]], x[cols[k + 1]],
                            x[cols[k + 2]], x[cols[k + 3]], x[cols[k + 4]], x[cols[k + 5]],
                            x[cols[k + 6]], x[cols[k + 7]], kind, lo, hi, fpar[f], fpar[f + 1],
                            fpar[f + 2], fpar[f + 3], fpar[f + 4], fpar[f + 5], R, gas, cp, ch,
                            band, G)


@jit
def _thermal_tesla(x, F, raw, jac, gr, cols, fpar):
    """A group of Tesla valves in a thermal scene
    (:func:`.thermal.adiabatic_tesla_rows`)."""
    n, c0, r0, j0, f0, kind = gr[N], gr[COL], gr[R0], gr[J0], gr[F0], gr[OPTION]
    lo, hi, R, gamma = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3]
    cp, ch, band, G = fpar[f0 + 4], fpar[f0 + 5], fpar[f0 + 6], fpar[f0 + 7]
    gas = gas_constants(gamma)
    for i in range(n):
        k = c0 + 8 * i
        f = f0 + THERMAL_FLOW_GROUP_FLOATS + THERMAL_TESLA_FLOATS * i
        adiabatic_tesla_rows(F, r0 + 4 * i, raw, j0 + 15 * i, jac, x[cols[k]], x[cols[k + 1]],
                             x[cols[k + 2]], x[cols[k + 3]], x[cols[k + 4]], x[cols[k + 5]],
                             x[cols[k + 6]], x[cols[k + 7]], kind, lo, hi, fpar[f],
                             fpar[f + 1], fpar[f + 2], fpar[f + 3], fpar[f + 4], fpar[f + 5],
                             fpar[f + 6], R, gas, cp, ch, band, G)


@jit
def _thermal_volume(x, S, dt, F, raw, jac, gr, cols, fpar, free, Sout):
    """A group of volumes of an ideal gas in a thermal scene, wall kind
    ``option`` (:func:`.thermal.wall_law`, or 3: a hysteresis loop,
    :func:`.thermal.loop_wall`): free (V = [p, mf, T, E, Q], states [m, E_s]
    at m = psi + c mf, E_s = psi + c (E + Q), a loop's branch and work offset
    after them; rows wall, energy, wall heat) or held at its wall temperature
    (V = [p, mf, T, E], state m, a loop's branch after it; rows wall,
    T - T_wall), the entries in the class's step pattern (the rates' columns
    times c, as discretize combines them); after the step a loop's branch is
    the one its volume is on, its work offset :func:`.thermal.loop_offset`'s
    (:meth:`softflow.components.thermal._LoopCurve.switch`). False where a
    curve refuses a volume."""
    n, c0, s0, r0, j0, f0, wall = gr[N], gr[COL], gr[S0], gr[R0], gr[J0], gr[F0], gr[OPTION]
    R, cv, c, h0 = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3]
    any_heat, mode = fpar[f0 + 4] > 0.5, int(fpar[f0 + 5])
    scaled, p_atm = fpar[f0 + 6] > 0.5, fpar[f0 + 7]
    at = f0 + VOLUME_GROUP_FLOATS
    # the curves: a PV curve wall's, or a loop's two (after V_hi, V_lo, the work's
    # shifts and the deflation curve's mode), each with its work at its knots
    v_hi = v_lo = shift_up = shift_down = 0.0
    mode_down = 0
    if wall == 3:
        v_hi, v_lo, shift_up, shift_down = fpar[at], fpar[at + 1], fpar[at + 2], fpar[at + 3]
        mode_down = int(fpar[at + 4])
        at += 5
    if wall >= 2:
        knots, table, end = _curve(fpar, at)
        w0 = fpar[end:end + table.shape[0]]
        at = end + table.shape[0]
    else:
        knots, table = fpar[at:at], fpar[at:at].reshape((0, 5))
        w0 = knots
    knots_down, table_down, w0_down = knots, table, w0
    if wall == 3:
        knots_down, table_down, end = _curve(fpar, at)
        w0_down = fpar[end:end + table_down.shape[0]]
        at = end + table_down.shape[0]
    per = 2 + (1 if wall == 0 else (4 if wall == 1 else (2 if wall == 2 else 0)))
    nv = 5 if free else 4
    ns = (4 if free else 2) if wall == 3 else (2 if free else 1)
    for i in range(n):
        k = c0 + nv * i
        p, mf, T = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]]
        f = at + per * i
        hA, T_wall = fpar[f], fpar[f + 1]
        s = s0 + ns * i
        m = S[s] + dt * mf
        inflating, offset = False, 0.0
        if wall == 3:
            inflating = S[s + (2 if free else 1)] > 0.5
            offset = S[s + 3] if free else 0.0
            fw, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, ok = loop_wall(
                p, T, m, R, inflating, offset, knots, table, w0, mode, knots_down, table_down,
                w0_down, mode_down, v_hi, v_lo, shift_up, shift_down, free)
        else:
            fw, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, ok = wall_law(
                wall, p, T, m, R, fpar, f + 2, knots, table, w0, mode, scaled, p_atm, free)
        if not ok:
            return False
        out = Sout.size > 0
        if out:
            Sout[s] = m
            if wall == 3:
                # the switch's volume: the mass over the gas's density (p / (R T))
                vol = m / ideal_density(p, T, R)[0]
                up = on_inflation(vol, inflating, v_hi, v_lo)
                Sout[s + (2 if free else 1)] = 1.0 if up else 0.0
                if free:
                    Sout[s + 3] = loop_offset(offset, vol, up, inflating, knots, table, w0,
                                              knots_down, table_down, w0_down, v_hi, v_lo,
                                              shift_up, shift_down)
        if free:
            E, Q = x[cols[k + 3]], x[cols[k + 4]]
            Es = S[s + 1] + dt * (E + Q)
            if out:
                Sout[s + 1] = Es
            r = r0 + 3 * i
            (F[r], F[r + 1], F[r + 2], d0, d1, d2, d3, d4, d5, d6, d7,
             d8) = free_rows(fw, d_p, d_T, d_m, v_p, v_T, v_m, W, p_wall, T, Q, m, Es, cv, c,
                             h0, hA, T_wall, any_heat)
            if jac:
                j = j0 + 10 * i
                raw[j], raw[j + 1], raw[j + 2], raw[j + 3] = d0, d1, d2, d3
                raw[j + 4], raw[j + 5] = d4, d5
                step = dt * 1.0
                raw[j + 6] = step * d6
                raw[j + 7] = step * d7
                raw[j + 8] = step * d8
                raw[j + 9] = step * d8
        else:
            r = r0 + 2 * i
            F[r], F[r + 1], d0, d1, d2, d3 = held_rows(fw, d_p, d_T, d_m, T, T_wall)
            if jac:
                j = j0 + 4 * i
                raw[j], raw[j + 1], raw[j + 2] = d0, d1, d2
                raw[j + 3] = (dt * 1.0) * d3
    return True


@jit
def _thermal_pressure_source(x, F, raw, jac, gr, cols, fpar, u):
    """Rows p - value and T - T_source (per instance at fpar[f0:]); entries 1, 1."""
    n, c0, r0, j0, f0, u0 = gr[N], gr[COL], gr[R0], gr[J0], gr[F0], gr[U0]
    for i in range(n):
        F[r0 + 2 * i] = x[cols[c0 + 4 * i]] - u[u0 + i]
        F[r0 + 2 * i + 1] = x[cols[c0 + 4 * i + 2]] - fpar[f0 + i]
        if jac:
            raw[j0 + 2 * i] = 1.0
            raw[j0 + 2 * i + 1] = 1.0


@jit
def _thermal_flow_source(x, F, raw, jac, gr, cols, fpar, u, volume):
    """Mass (mf + value) or volume (mf + rho(p, T_q) value) flow sources of an
    ideal gas, and their energy rows (:func:`.thermal.source_energy`); group
    floats R, cp, c - h0, band, G, then each one's temperature."""
    n, c0, r0, j0, f0, u0 = gr[N], gr[COL], gr[R0], gr[J0], gr[F0], gr[U0]
    R, cp, ch, band, G = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3], fpar[f0 + 4]
    nj = 7 if volume else 5
    for i in range(n):
        k = c0 + 4 * i
        p, mf, T, E = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]], x[cols[k + 3]]
        T_s, q = fpar[f0 + 5 + i], u[u0 + i]
        fe, e_p, e_mf, e_T, e_E = source_energy(E, mf, T, T_s, cp, ch, band, G)
        r, j = r0 + 2 * i, j0 + nj * i
        F[r + 1] = fe
        if volume:
            rq, rq_p, rq_T = volume_flow_law(p, T, q, T_s, R)
            F[r] = mf + rq
            if jac:
                raw[j], raw[j + 1], raw[j + 2] = rq_p, 1.0, rq_T
                j += 3
        else:
            F[r] = mf + q
            if jac:
                raw[j] = 1.0
                j += 1
        if jac:
            raw[j], raw[j + 1], raw[j + 2], raw[j + 3] = e_p, e_mf, e_T, e_E


@jit
def _thermal_orifice(x, F, raw, jac, gr, cols, fpar):
    """A group of orifices in a thermal scene (:func:`.thermal.orifice_rows`),
    law ``option``."""
    n, c0, r0, j0, f0, model = gr[N], gr[COL], gr[R0], gr[J0], gr[F0], gr[OPTION]
    RT, rho, T, rho0, T0 = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3], fpar[f0 + 4]
    T_ref, cp, ch, band, G = (fpar[f0 + 5], fpar[f0 + 6], fpar[f0 + 7], fpar[f0 + 8],
                              fpar[f0 + 9])
    for i in range(n):
        k = c0 + 8 * i
        f = f0 + THERMAL_ORIFICE_GROUP_FLOATS + ORIFICE_FLOATS * i
        orifice_rows(F, r0 + 4 * i, raw, j0 + 15 * i, jac, x[cols[k]], x[cols[k + 1]],
                     x[cols[k + 2]], x[cols[k + 3]], x[cols[k + 4]], x[cols[k + 5]],
                     x[cols[k + 6]], x[cols[k + 7]], model, RT, rho, T, rho0, T0, fpar[f],
                     fpar[f + 1], fpar[f + 2], fpar[f + 3], fpar[f + 4], fpar[f + 5],
                     fpar[f + 6], fpar[f + 7], fpar[f + 8], T_ref, cp, ch, band, G)


@jit
def _thermal_check_valve(x, F, raw, jac, gr, cols, fpar):
    """A group of check valves in a thermal scene
    (:func:`.thermal.check_valve_rows`), a nozzle where ``option`` is 1."""
    n, c0, r0, j0, f0 = gr[N], gr[COL], gr[R0], gr[J0], gr[F0]
    nozzle = gr[OPTION] == 1
    RT, rho, cp, ch, band, G = (fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3],
                                fpar[f0 + 4], fpar[f0 + 5])
    for i in range(n):
        k = c0 + 8 * i
        f = f0 + THERMAL_CHECK_VALVE_GROUP_FLOATS + CHECK_VALVE_FLOATS * i
        check_valve_rows(F, r0 + 4 * i, raw, j0 + 13 * i, jac, x[cols[k]], x[cols[k + 1]],
                         x[cols[k + 2]], x[cols[k + 3]], x[cols[k + 4]], x[cols[k + 5]],
                         x[cols[k + 6]], x[cols[k + 7]], nozzle, RT, rho, fpar[f],
                         fpar[f + 1], fpar[f + 2], fpar[f + 3], fpar[f + 4], fpar[f + 5],
                         fpar[f + 6], fpar[f + 7], cp, ch, band, G)


@jit
def _thermal_snapping_valve(x, S, F, raw, jac, gr, cols, fpar, Sout):
    """A group of snapping valves in a thermal scene of an ideal gas
    (:func:`.thermal.snapping_rows`), the mode of each (> 0.5 open) its state
    at the step's start, after it :func:`snapping_switch`'s."""
    n, c0, s0, r0, j0, f0, kind = gr[N], gr[COL], gr[S0], gr[R0], gr[J0], gr[F0], gr[OPTION]
    lo, hi, R, gamma = fpar[f0], fpar[f0 + 1], fpar[f0 + 2], fpar[f0 + 3]
    cp, ch, band, G = fpar[f0 + 4], fpar[f0 + 5], fpar[f0 + 6], fpar[f0 + 7]
    RT, rho, T_ref = fpar[f0 + 8], fpar[f0 + 9], fpar[f0 + 10]
    gas = gas_constants(gamma)
    for i in range(n):
        k = c0 + 8 * i
        f = f0 + THERMAL_SNAPPING_GROUP_FLOATS + THERMAL_SNAPPING_FLOATS * i
        if Sout.size > 0:
            Sout[s0 + i] = snapping_switch(x[cols[k]] - x[cols[k + 4]], fpar[f + 7],
                                           fpar[f + 8], S[s0 + i])
        snapping_rows(F, r0 + 4 * i, raw, j0 + 15 * i, jac, S[s0 + i] > 0.5, x[cols[k]],
                      x[cols[k + 1]], x[cols[k + 2]], x[cols[k + 3]], x[cols[k + 4]],
                      x[cols[k + 5]], x[cols[k + 6]], x[cols[k + 7]], kind, lo, hi, fpar[f],
                      fpar[f + 1], fpar[f + 2], fpar[f + 3], fpar[f + 4], fpar[f + 5],
                      fpar[f + 6], RT, rho, R, gas, T_ref, cp, ch, band, G)


@jit
def _thermal_inertial_tube(x, S, dt, F, raw, jac, gr, cols, fpar, Sout):
    """A group of gas tubes with inertance in a thermal scene: the flow law
    of :func:`_inertial_tube` at the nominal temperature, and the upwind
    energy rows (:func:`.thermal.upwind_energy`); entries (0,mf_a) (0,mf_b)
    (1,p_a) (1,mf) (1,p_b), the energy rows', as the step combines them.
    Group floats Re_lo, Re_hi, c2, cp, c - h0, band, G."""
    n, c0, s0, r0, j0, f0, kind = gr[N], gr[COL], gr[S0], gr[R0], gr[J0], gr[F0], gr[OPTION]
    lo, hi, c2 = fpar[f0], fpar[f0 + 1], fpar[f0 + 2]
    cp, ch, band, G = fpar[f0 + 3], fpar[f0 + 4], fpar[f0 + 5], fpar[f0 + 6]
    for i in range(n):
        k = c0 + 8 * i
        pa, mfa, Ta, Ea = x[cols[k]], x[cols[k + 1]], x[cols[k + 2]], x[cols[k + 3]]
        pb, mfb, Tb, Eb = x[cols[k + 4]], x[cols[k + 5]], x[cols[k + 6]], x[cols[k + 7]]
        f = f0 + 7 + INERTIAL_FLOATS * i
        dp, d_pa, d_mf, d_pb = _tube_drop(kind, lo, hi, c2, pa, mfa, pb, fpar, f)
        a_l = fpar[f + 6]
        q = S[s0 + i] + dt * (a_l * ((pa - pb) - dp))
        if Sout.size > 0:
            Sout[s0 + i] = q
        E, _, _, _, e_mf, e_Ta, e_Tb = upwind_energy(mfa, Ta, Tb, cp, ch, band, G)
        r = r0 + 4 * i
        F[r] = mfa + mfb
        F[r + 1] = mfa - q
        F[r + 2] = Ea + Eb
        F[r + 3] = Ea - E
        if jac:
            j = j0 + 13 * i
            raw[j] = 1.0
            raw[j + 1] = 1.0
            raw[j + 2] = (dt * (a_l * (1.0 - d_pa))) * -1.0
            raw[j + 3] = 1.0 + (dt * (-a_l * d_mf)) * -1.0
            raw[j + 4] = (dt * (-a_l * (1.0 + d_pb))) * -1.0
            energy_entries(raw, j + 5, e_mf, e_Ta, e_Tb)


# -- switching functions, kinks and pieces (the assembly's switching, kinks, regimes) ----
@jit
def _loop_switching(vol, inflating, v_hi, v_lo):
    """A hysteresis loop's switching function at the volume vol: vol - V_hi
    while inflating, V_lo - vol while deflating
    (:meth:`softflow.curves.HysteresisLoop.switching`)."""
    return vol - v_hi if inflating else v_lo - vol


@jit
def _snapping_floats(gr):
    """(columns per instance, p_b's column, the first instance's floats,
    floats per instance, the opening pressure's place among them) of a
    snapping valve's group, isothermal or thermal (the closing pressure's
    place is the next)."""
    if gr[CLS] == THERMAL_SNAPPING_VALVE:
        return 8, 4, gr[F0] + THERMAL_SNAPPING_GROUP_FLOATS, THERMAL_SNAPPING_FLOATS, 7
    return 4, 2, gr[F0] + VALVE_GROUP_FLOATS, SNAPPING_FLOATS, 6


@jit
def _check_floats(gr):
    """(columns per instance, p_b's column, the first instance's floats, the
    group's REGIME_EDGE's place) of a check valve's group, isothermal or
    thermal (LOW_PIECES's place is the next)."""
    if gr[CLS] == THERMAL_CHECK_VALVE:
        return (8, 4, gr[F0] + THERMAL_CHECK_VALVE_GROUP_FLOATS,
                gr[F0] + THERMAL_CHECK_VALVE_GROUP_FLOATS - 2)
    return 4, 2, gr[F0] + CHECK_VALVE_GROUP_FLOATS, gr[F0] + CHECK_VALVE_GROUP_FLOATS - 2


@jit
def _switching_per_instance(gr):
    """How many switching functions each instance of the group ``gr`` has (its
    discrete states): 1 for a snapping valve, a hysteretic actuator and a
    thermal one held at its wall temperature, 2 for a free one (its branch
    and work offset), else 0."""
    cls = gr[CLS]
    if cls == SNAPPING_VALVE or cls == THERMAL_SNAPPING_VALVE or cls == HYSTERETIC_ACTUATOR:
        return 1
    if (cls == FREE_VOLUME or cls == HELD_VOLUME) and gr[OPTION] == 3:
        return 2 if cls == FREE_VOLUME else 1
    return 0


@jit
def sizes(groups):
    """(switching functions, kinks, pieces): how many values
    :func:`switching`, :func:`kinks` and :func:`regimes` write for the
    network ``groups`` (0 where none states them)."""
    n_sw = n_kinks = 0
    for g in range(groups.shape[0]):
        gr = groups[g]
        n_sw += gr[N] * _switching_per_instance(gr)
        if gr[CLS] == CHECK_VALVE or gr[CLS] == THERMAL_CHECK_VALVE:
            n_kinks += gr[N]
    return n_sw, n_kinks, n_kinks


@jit
def switching(x, S, groups, cols, fpar, g_out):
    """The switching functions of every group that states them, in group
    order, instance by instance, into g_out (float): the assembly's
    ``switching(x, S)`` (S: the states, their modes as they were), each
    negative while its mode holds. A snapping valve (isothermal or thermal):
    closing pressure - dp while open, dp - opening pressure while shut
    (:meth:`softflow.components.valves.SnappingValve.switching`); a
    hysteretic actuator: its loop's at the volume m / rho of the mass S
    holds (rho at the pressure, and in a thermal scene the temperature, of
    x), once per discrete state (a free gas's branch and work offset: twice).
    Returns how many it wrote (:func:`sizes`)."""
    k = 0
    for g in range(groups.shape[0]):
        gr = groups[g]
        cls, n, c0, s0, f0 = gr[CLS], gr[N], gr[COL], gr[S0], gr[F0]
        if cls == SNAPPING_VALVE or cls == THERMAL_SNAPPING_VALVE:
            nv, b, f, per, at = _snapping_floats(gr)
            for i in range(n):
                dp = x[cols[c0 + nv * i]] - x[cols[c0 + nv * i + b]]
                fi = f + per * i + at
                g_out[k] = fpar[fi + 1] - dp if S[s0 + i] > 0.5 else dp - fpar[fi]
                k += 1
        elif cls == HYSTERETIC_ACTUATOR:
            kind, c, v_hi, v_lo = gr[OPTION], fpar[f0], fpar[f0 + 1], fpar[f0 + 2]
            for i in range(n):
                rho = density(kind, c, x[cols[c0 + 2 * i]])[0]
                g_out[k] = _loop_switching(S[s0 + 2 * i] / rho, S[s0 + 2 * i + 1] > 0.5,
                                           v_hi, v_lo)
                k += 1
        elif (cls == FREE_VOLUME or cls == HELD_VOLUME) and gr[OPTION] == 3:
            free = cls == FREE_VOLUME
            R = fpar[f0]
            at = f0 + VOLUME_GROUP_FLOATS
            v_hi, v_lo = fpar[at], fpar[at + 1]
            nv, ns, branch = (5, 4, 2) if free else (4, 2, 1)
            for i in range(n):
                p, T = x[cols[c0 + nv * i]], x[cols[c0 + nv * i + 2]]
                s = s0 + ns * i
                value = _loop_switching(S[s] / ideal_density(p, T, R)[0], S[s + branch] > 0.5,
                                        v_hi, v_lo)
                g_out[k] = value
                k += 1
                if free:
                    g_out[k] = value
                    k += 1
    return k


@jit
def kinks(x, groups, cols, fpar, out):
    """The side of its law's kinks each check valve (isothermal or thermal)
    is on at x, in group order, into out (any numeric dtype: the integers
    0, 1, 2): the assembly's ``kinks(x)``, 0 shut (dp at or below the
    cracking pressure), 1 inside the opening band, 2 open
    (:meth:`softflow.components.valves.CheckValve.kinks`). Returns how many
    it wrote."""
    k = 0
    for g in range(groups.shape[0]):
        gr = groups[g]
        if gr[CLS] != CHECK_VALVE and gr[CLS] != THERMAL_CHECK_VALVE:
            continue
        nv, b, f, _ = _check_floats(gr)
        c0 = gr[COL]
        for i in range(gr[N]):
            dp = x[cols[c0 + nv * i]] - x[cols[c0 + nv * i + b]]
            fi = f + CHECK_VALVE_FLOATS * i
            cracking = fpar[fi + 5]
            out[k] = (1 if dp > cracking else 0) + (1 if dp >= cracking + fpar[fi + 6] else 0)
            k += 1
    return k


@jit
def check_piece(s, edge, low):
    """The piece of a check valve's law at its band position s
    (:func:`softflow.components.valves._piece`, ``CheckValve.regime``):
    -low - 1 shut (s <= 0), -low ... -1 the band's bottom ``edge`` cut into
    pieces a factor 4 apart in s, 0 the middle, 1 its top ``edge`` and past
    it (nan: 0)."""
    if s <= 0.0:
        return -low - 1.0
    if s < edge:
        return max(np.floor(math.log2(s / edge) * 0.5), -low)
    return 1.0 if s > 1.0 - edge else 0.0


@jit
def regimes(x, groups, cols, fpar, out):
    """The piece of its law each check valve (isothermal or thermal) is on
    at x, in group order, into out (any numeric dtype: the integers -LOW_PIECES
    - 1 ... 1 of :func:`check_piece`): the assembly's ``regimes(x)``
    (:meth:`softflow.components.valves.CheckValve.regime`, s = (dp -
    cracking pressure) / opening band). Returns how many it wrote."""
    k = 0
    for g in range(groups.shape[0]):
        gr = groups[g]
        if gr[CLS] != CHECK_VALVE and gr[CLS] != THERMAL_CHECK_VALVE:
            continue
        nv, b, f, e = _check_floats(gr)
        edge, low = fpar[e], fpar[e + 1]
        c0 = gr[COL]
        for i in range(gr[N]):
            fi = f + CHECK_VALVE_FLOATS * i
            s = (x[cols[c0 + nv * i]] - x[cols[c0 + nv * i + b]] - fpar[fi + 5]) / fpar[fi + 6]
            out[k] = check_piece(s, edge, low)
            k += 1
    return k
