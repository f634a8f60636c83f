"""Validity checks of softflow's physical models, run on every solution.

Registered with :func:`softflow.solve.validity.register`; each looks at the
recorded solution of one compiled group (a few array reductions) and returns
:class:`~softflow.solve.validity.ValidityRecord` s. A record whose
``details['fatal']`` is True is a result from past a model's own maximum:
the run stops there (:class:`softflow.solve.simulation.SimulationError`,
status 'failed', the result cut before it) instead of returning it.

Each check grades its figure by ``fraction``, the figure relative to its limit
in the check's direction (the ratio figure / limit, or limit / figure for a
time scale that must not be too short): past 1 a warning (status 'beyond'),
from :data:`~softflow.solve.validity.NEAR_FRACTION` (0.5) a near miss
(status 'near', kept in ``result.validity``, not warned). The fraction of each
check is named below.

Checks
------
``tube_reynolds``
    A tube with ``friction='laminar'`` whose Reynolds number passed its
    ``Re_laminar`` (2 300): Hagen–Poiseuille under-predicts the pressure drop
    of transitional and turbulent flow; the message gives by how much, the
    default blended law's friction factor over the laminar one at the peak
    Reynolds number (``details['friction_ratio']``, :func:`laminar_shortfall`).
    Fraction: Re / Re_laminar (below it the laminar law and the default blend
    are the same law).
``tube_mach`` / ``tube_choked``
    Gas tubes with ``compressible='mean_density'`` (the default isothermal
    pipe-flow law models acceleration and choking, and has no such check):
    the Mach number at the tube's low-pressure end, v/c with
    ``v = |mdot| / (rho(p_low) A)``. The mean-density law neglects the gas's
    acceleration, which matters from about Mach 0.3 (``tube_mach``), and past
    the isothermal choking Mach 1/sqrt(gamma) (0.845 for air) it keeps giving
    more flow for more pressure difference, a wrong answer: that is fatal
    (``tube_choked``). Both suggest the default law. Fraction: Mach / 0.3.
``tube_isothermal_flow``
    A gas tube of an isothermal scene that choked with the default pipe-flow
    law, which is isothermal there: adiabatic (Fanno) pipe flow, the better
    model of a tube too short and fast to exchange heat with its wall (and the
    law of a thermal scene), passes a different choked flow at the tube's
    f L/D (more, for air: 12 % at f L/D = 0.1, 8 % at 1, 2.5 % at 10, 0.5 % at
    100). Fraction: the relative difference of the two choked flows over
    ``max(10 rtol, 1e-2)``.
``orifice_choked``
    An orifice given by K (an incompressible law) with a gas, at a
    pressure ratio below the critical ratio (2/(gamma+1))^(gamma/(gamma-1))
    (0.528 for air): the real flow is choked there; the nozzle law (``Cd``
    with a gas) and the ISO 6358 model (``C``, ``b``) describe it, and are
    not checked. Fraction: the relative pressure drop 1 - p_low/p_high
    against the critical one, 1 - 0.528.
``gas_compressibility``
    A gas at the ``ideal`` level whose compressibility factor Z (from CoolProp
    at the pressures and temperatures the run visited) differs from 1 by more
    than ``max(10 rtol, 1e-3)``: the ideal-gas density is off by that much.
    Fraction: ``|Z - 1|`` / that limit. CoolProp is asked only where a virial
    bound and then the gas's property table (built from the installed CoolProp)
    cannot rule a near miss out (``settings.Z_TABLE_MARGIN``).
``tube_inertia``
    A liquid tube without inertance whose column's inertial pressure, l/A
    times the fastest change of its mass flow (steps where the flow jumped by
    more than half its peak, a pump switched on, left out: that is an impulse),
    is more than ``max(10 rtol, 1e-2)`` of the pressures it works between (its
    ends' gauge pressures): the inertia changes the result by about that
    fraction (a water RC circuit: 5 % estimated, 3.9 % measured with
    ``inertance=True``); use ``inertance=True``. Fraction: the inertial
    pressure's share / ``max(10 rtol, 1e-2)``.
``thermal_time_scale``
    An isothermal gas volume that filled or emptied much faster than its wall
    can exchange heat: the time scale ``m / |mdot|`` against the thermal time
    constant m cv / (h A) of the volume's own wall where it was given one
    (``hA``, or a coefficient and an area), else with h from free convection
    (a sphere of the volume's size, 10 K difference: an estimate). Faster than a tenth of it,
    the gas is closer to adiabatic than to isothermal. The message gives the
    isothermal model's error as :func:`isothermal_error` estimates it
    (``details['estimated_error']``; a 1 L tank blown down from 10 bar in ~1 s:
    0.4 estimated, 23 % of the pressure measured against free-convection walls).
    Fraction: a tenth of the thermal time constant / the fill time.
``cavitation``
    A liquid whose absolute pressure fell below its vapour pressure at its
    temperature, at any node where a component of that liquid meets (a
    check of the whole network, one record per liquid: its lowest pressure,
    the node, the time): there the liquid would boil, which softflow does not
    model (a liquid is one phase, its pressure free to fall as if it could
    hold any tension). The vapour pressure comes from the liquid's table
    metadata (:mod:`softflow.fluids.vapour`: water from CoolProp's
    saturation pressure, water-glycol by Raoult's law), at any fluid level,
    without CoolProp; a liquid without one is not checked. Fraction: the
    vapour pressure / the lowest pressure.
``fluid_range``
    A tabulated fluid (the table level, ``out_of_range='raise'``) whose
    pressure at a node where one of its components meets left the table's
    range while the run went on: nothing evaluated the fluid there (a tube's
    law works at its mean pressure; a source sets the node and takes no
    property), so nothing refused it. One record per fluid, the farthest
    node. Fraction: the range's end over the pressure (or the reverse above
    it); recorded past 1 + rtol only (a node held at the table's end by a
    source sits there to the solve's tolerance).
``adiabatic_time_scale``
    The reverse: an adiabatic gas volume of a thermal scene (no wall heat)
    whose temperature stayed away from its wall's, by more than
    ``max(10 rtol, 1e-2)`` of it, for longer than its wall's thermal time
    constant (free convection estimate, as above) would allow: the time
    integral of the difference over its largest value against that constant.
    A real wall would have taken back most of the difference (a fast fill
    held for seconds); give the volume its wall and run
    ``thermal='heat_transfer'``. Fraction: that time / the thermal time
    constant.

Measured against the examples (issue 40)
----------------------------------------
Every ModelWarning the demo, the examples and the validation notebooks raised
was compared with a run that models what the check says is left out (at rtol
1e-7 both; pressures relative to the run's largest gauge pressure, volumes to
their swing, flows to their peak). Each effect was larger than the run's
tolerance, and none of the thresholds here was raised; the examples model the
effects instead (see their docstrings and :mod:`softflow.paper_scenes`):

* the demo's tube, ``tube_inertia`` 0.029: the pressures 2.5 %, the volume 6.8 %;
* Fig. 3's R2, ``tube_inertia``: monotonic 0.16 (the pressures 0.5 %, the flows
  55 %), peak-valley 0.61 (41 %, the volumes 71 %); Fig. 4's tube 0.23 (4.7 %,
  1.2 %); Fig. 5's water and glycol 0.063 and 0.013 (7.7 % and 1.1 %);
* the RC notebook's 0.5 mm tube at tau = 0.1 s, ``tube_inertia`` 0.078: 5.8 %;
  the balloon's snap through 0.1 m x 5 mm, 1.6: 30 %, the volumes 62 %;
* Fig. 5 with air, ``thermal_time_scale`` 1.1-15: the pressures 57 %, the
  volumes 73 %; a 1 L blowdown from 10 bar, 1.34: 23 % in the choked phase;
* 10 bar air at rtol 1e-5, ``gas_compressibility`` 3.5: the tank's mass
  0.38 %, its pressure 0.54 %.

The inertia figure is an upper estimate where the flow's fastest change is a
start-up transient shorter than the column's time constant (Fig. 3 monotonic:
0.16 for 0.5 % of the pressures, Fig. 4: 0.23 for 4.7 %); it is within 1.3x of
the measured effect in the RC-like scenes (demo, RC, Fig. 5). In the
transients it over-estimates, the flows still move by more than the tolerance
(55 % in Fig. 3 just after the pump stops), so the warning stands.
"""
from __future__ import annotations

import math
import operator
import os
import sys

import numpy as np

from ..components.tubes import _friction_term
from ..constants import pressure_atmospheric
from ..correlations.fanno import adiabatic_choked_massflow
from ..correlations.gas_pipe import isothermal_choked_massflow
from ..fluids.base import FluidError
from ..fluids.ideal import IdealGas
from .settings import (
    ADIABATIC_PERSISTENCE,
    MACH_INCOMPRESSIBLE,
    SMALL_NETWORK,
    THERMAL_DT,
    THERMAL_FRACTION,
    Z_GRID,
    Z_TABLE_MARGIN,
)
from .validity import NEAR_FRACTION, ValidityRecord, grade, group_times, group_values

#: Below this Mach number no tube is near either limit (the mean-density law's
#: or choking), whatever its law.
NEAR_MACH = NEAR_FRACTION * MACH_INCOMPRESSIBLE


def _record(comp, check, measured, limit, unit, fraction, suggestion, message, **details):
    """A record graded by ``fraction`` (see the module doc): a near miss's
    message says how near, and that nothing needs changing yet."""
    status = grade(fraction)
    if status == "near":
        message += " A near miss (status 'near'), not a warning."
        suggestion = f"if the scene is pushed further: {suggestion}"
    return ValidityRecord(component=comp.label, check=check, measured=float(measured),
                          limit=float(limit), unit=unit, suggestion=suggestion,
                          message=f"{comp.describe()}: {message} Suggestion: {suggestion}",
                          details=details, status=status or "beyond",
                          fraction=float(fraction))


def _past(fraction, limit_text):
    """'past <limit>' or '<fraction> of <limit>' for a message."""
    return f"past {limit_text}" if fraction > 1.0 else f"at {fraction:.0%} of {limit_text}"


def _rtol(result):
    return float(result.stats.get("rtol", 1e-3))


def _limit(result, floor):
    """A check's limit that follows the run's tolerance: max(10 rtol, floor)."""
    return max(10.0 * _rtol(result), floor)


# -- tubes ---------------------------------------------------------------------------
def tube_reynolds(g, result):
    comp0 = g.comps[0]
    if getattr(comp0, "friction", None) != "laminar":
        return []
    keep, mf = group_values(g, result, "massflow_a")
    if not keep:
        return []
    comps = [g.comps[i] for i in keep]
    # every tube at once (a chain of 200 took 2.5 ms one by one); the viscosity
    # once per fluid
    mus: dict[int, float] = {}
    for c in comps:
        if id(c.fluid) not in mus:
            mus[id(c.fluid)] = float(c.fluid.viscosity(pressure_atmospheric))
    mu = np.array([mus[id(c.fluid)] for c in comps])
    diameter = np.array([c.diameter for c in comps])
    re_lam = np.array([c.Re_laminar for c in comps], dtype=float)
    re_all = np.abs(mf) * (4.0 / (math.pi * diameter * mu))     # |mf| D / (mu A)
    peak_at = np.argmax(re_all, axis=0)
    fractions = re_all[peak_at, np.arange(len(keep))] / re_lam
    tt = group_times(g, result, keep)
    out = []
    listed = np.flatnonzero(fractions >= NEAR_FRACTION)
    # by how much: the default blend's friction factor there over the laminar
    # one, every listed tube in one call
    ratios = _laminar_shortfalls([comps[j] for j in listed],
                                 [float(re_all[peak_at[j], j]) for j in listed])
    for j, ratio in zip(listed, ratios):
        c, k = comps[j], int(peak_at[j])
        re = re_all[:, j]
        fraction = float(fractions[j])         # graded 'near' or 'beyond' by the filter
        out.append(_record(
            c, "tube_reynolds", re[k], c.Re_laminar, "", fraction,
            "use a turbulent correlation (friction='Haaland', the default, blends "
            "laminar and turbulent flow)",
            f"Reynolds number reached {re[k]:.4g} at t = {tt[k, j]:.6g} s, "
            f"{_past(fraction, f'Re_laminar = {c.Re_laminar:g}')} of its "
            "friction='laminar' law" + (
                f", which then under-predicts the pressure drop: the default blended law "
                f"(Haaland) gives {ratio:.3g} times the laminar friction there."
                if fraction > 1 else "."),
            time=float(tt[k, j]), friction_ratio=ratio))
    return out


def laminar_shortfall(tube, re):
    """The default blended friction law's f·Re (Haaland above Re_turbulent) over
    the laminar 64 at Reynolds number ``re``, for ``tube``'s roughness: by how
    much a friction='laminar' tube's pressure drop is short there."""
    from ..correlations.friction import fRe_blended
    eD = float(tube.roughness) / float(tube.diameter)
    f_re = fRe_blended(np.array([re]), np.array([eD]), 2300.0, 4000.0, derivative=False)[0]
    return float(np.ravel(f_re)[0]) / 64.0


def _laminar_shortfalls(tubes, res):
    """:func:`laminar_shortfall` of each of ``tubes`` at its Reynolds number in
    ``res``, in one call of the compiled friction law (elementwise: the same
    numbers as one call each)."""
    if not tubes:
        return []
    from ..correlations.friction import fRe_blended
    eD = np.array([float(t.roughness) / float(t.diameter) for t in tubes])
    f_re = fRe_blended(np.array(res, dtype=float), eD, 2300.0, 4000.0, derivative=False)[0]
    return [float(v) / 64.0 for v in np.ravel(f_re)]


def two_port_values(g, result):
    """(indices in the group, mf_a, p_a, p_b) of the recorded members of a
    group of two-ports (times x members each); the values None where none of
    them is recorded."""
    keep, mf = group_values(g, result, "massflow_a")
    if not keep:
        return keep, None, None, None
    _, pa = group_values(g, result, "pressure_a")
    _, pb = group_values(g, result, "pressure_b")
    return keep, mf, pa, pb


def tube_mach(g, result):
    comp0 = g.comps[0]
    fluid = comp0.fluid
    # the isothermal pipe-flow law (the default) models acceleration and choking
    if (fluid is None or not fluid.compressible
            or getattr(comp0, "compressible", None) != "mean_density"):
        return []
    keep, mf, pa, pb = two_port_values(g, result)
    if not keep:
        return []
    area = np.array([math.pi * g.comps[i].diameter ** 2 / 4 for i in keep])
    p_low = np.minimum(pa, pb)
    try:
        rho, c = fluid.density(p_low), fluid.speed_of_sound(p_low)
    except FluidError:
        # a tube end below a table's range (the tube's own law takes the mean
        # pressure, inside it): the ideal gas, exact enough at low pressure
        ideal = fluid.with_level("ideal")
        rho, c = ideal.density(p_low), ideal.speed_of_sound(p_low)
    with np.errstate(all="ignore"):
        mach = np.abs(mf) / (rho * area) / c
        mach = np.where(np.isfinite(mach), mach, 0.0)
    peak = mach.max(axis=0)
    gamma = float(fluid.gamma(pressure_atmospheric))
    choke = 1.0 / math.sqrt(gamma)
    tt = group_times(g, result, keep)
    out = []
    use = ("use the default CircularTube(..., compressible='pipe_flow'), which adds the "
           "gas's acceleration and chokes")
    for j in np.flatnonzero(peak >= NEAR_MACH):
        c = g.comps[keep[j]]
        k = int(np.argmax(mach[:, j]))
        t = float(tt[k, j])
        ratio = float(p_low[k, j] / max(pa[k, j], pb[k, j]))
        if peak[j] >= choke:
            first = int(np.argmax(mach[:, j] >= choke))
            out.append(_record(
                c, "tube_choked", peak[j], choke, "", max(peak[j] / choke, 1.0 + 1e-12),
                use,
                f"gas flow chokes: Mach {peak[j]:.3g} at its low-pressure end at t = {t:.6g} s "
                f"(pressure ratio p_low/p_high = {ratio:.3g}), past the isothermal choking "
                f"limit Mach 1/sqrt(gamma) = {choke:.3g}, where more pressure difference "
                "gives no more flow; the compressible='mean_density' law has left its range "
                "(it keeps giving more).",
                fatal=True, first_time=float(tt[first, j]), pressure_ratio=ratio,
                time=t))
        else:
            fraction = peak[j] / MACH_INCOMPRESSIBLE
            out.append(_record(
                c, "tube_mach", peak[j], MACH_INCOMPRESSIBLE, "", fraction, use,
                f"Mach {peak[j]:.3g} at its low-pressure end at t = {t:.6g} s (pressure ratio "
                f"{ratio:.3g}), {_past(fraction, f'Mach {MACH_INCOMPRESSIBLE}')}"
                + (": " if fraction > 1 else ", past which ") + "the gas's acceleration, "
                "which the mean-density law neglects, is no longer small.", time=t))
    return out


def tube_isothermal_flow(g, result):
    comp0 = g.comps[0]
    fluid = comp0.fluid
    # an isothermal scene's gas tube with the pipe-flow law (a thermal scene's is
    # adiabatic already); an ideal gas, whose adiabatic law is known
    if (fluid is None or not fluid.compressible or getattr(comp0, "_thermal", None) is not None
            or getattr(comp0, "compressible", None) != "pipe_flow"
            or not isinstance(fluid, IdealGas)):
        return []
    keep, mf, pa, pb = two_port_values(g, result)
    if not keep:
        return []
    comps = [g.comps[i] for i in keep]
    area = np.array([math.pi * c.diameter ** 2 / 4 for c in comps])
    RT = fluid.R * fluid.temperature
    G = np.abs(mf) / area
    # choked: the downstream pressure below the exit's G c (isothermal Mach 1)
    choked = np.minimum(pa, pb) < G * math.sqrt(RT)
    limit = _limit(result, 1e-2)
    tt = group_times(g, result, keep)
    gamma = float(fluid.gamma0)
    out = []
    for j in np.flatnonzero(choked.any(axis=0)):
        c = comps[j]
        k = int(np.argmax(np.where(choked[:, j], G[:, j], -1.0)))
        # f L/D at that flow, from the tube's own friction term: G^2 f L/D = 2 Phi
        P = type(c).make_params([c])
        V = np.array([[pa[k, j], mf[k, j], pb[k, j]]])
        Phi = _friction_term(P, V[:, 0], V[:, 1], V[:, 2], False)[0]
        fLD = float(2.0 * abs(Phi[0]) / (G[k, j] ** 2))
        ratio = (adiabatic_choked_massflow(1.0, fluid.temperature, 1.0, fluid.R, gamma, fLD)
                 / isothermal_choked_massflow(1.0, 1.0, RT, fLD))
        fraction = abs(ratio - 1.0) / limit
        if not grade(fraction):
            continue
        out.append(_record(
            c, "tube_isothermal_flow", abs(ratio - 1.0), limit, "", fraction,
            "run the scene with thermal='adiabatic', where a gas tube is adiabatic "
            "(Fanno) pipe flow",
            f"choked as isothermal pipe flow (at t = {tt[k, j]:.6g} s, f L/D = {fLD:.3g}), "
            f"where adiabatic (Fanno) pipe flow, the model of a tube too short and fast to "
            f"exchange heat with its wall, would choke at a flow {abs(ratio - 1.0):.2%} "
            f"{'larger' if ratio > 1.0 else 'smaller'}, "
            + (f"more than {limit:.3g} (max(10 rtol, 1 %))." if fraction > 1 else
               f"against a limit of {limit:.3g} (max(10 rtol, 1 %))."),
            flow_ratio=float(ratio), fLD=fLD, time=float(tt[k, j])))
    return out


def orifice_choked(g, result):
    comp0 = g.comps[0]
    fluid = comp0.fluid
    if fluid is None or not fluid.compressible or getattr(comp0, "model", None) != "K":
        return []      # the nozzle (Cd) and ISO 6358 laws model the choking
    keep, pa = group_values(g, result, "pressure_a")
    if not keep:
        return []
    _, pb = group_values(g, result, "pressure_b")
    gamma = float(fluid.gamma(pressure_atmospheric))
    critical = (2.0 / (gamma + 1.0)) ** (gamma / (gamma - 1.0))
    tt = group_times(g, result, keep)
    out = []
    for j, i in enumerate(keep):
        c = g.comps[i]
        ratio = np.minimum(pa[:, j], pb[:, j]) / np.maximum(pa[:, j], pb[:, j])
        k = int(np.argmin(ratio))
        fraction = (1.0 - float(ratio[k])) / (1.0 - critical)
        if grade(fraction):
            out.append(_record(
                c, "orifice_choked", ratio[k], critical, "", fraction,
                "give the orifice by its discharge coefficient (Orifice(..., diameter=..., "
                "Cd=...): the isentropic nozzle law) or its ISO 6358 sonic conductance and "
                "critical ratio (Orifice(..., C=..., b=...)); both choke",
                f"pressure ratio p_low/p_high reached {ratio[k]:.3g} at t = "
                f"{tt[k, j]:.6g} s, " + (
                    f"below the critical ratio {critical:.3g}: the real flow is choked "
                    "there, and the incompressible K law over-predicts it."
                    if fraction > 1 else f"a pressure drop {fraction:.0%} of the critical "
                    f"one (ratio {critical:.3g}), where the gas's expansion starts to matter."),
                time=float(tt[k, j])))
    return out


# -- gases ---------------------------------------------------------------------------
#: Critical temperature [K], critical pressure [Pa] and acentric factor of the
#: built-in gases (NIST Chemistry WebBook; Lemmon et al. 2000 for air as a
#: pseudo-pure fluid), for :func:`compressibility_bound`.
_CRITICAL = {"air": (132.53, 3.786e6, 0.0335), "nitrogen": (126.19, 3.3958e6, 0.0372)}
_R = 8.314462618                # J/(mol K)


#: where between the two temperatures compressibility_bound looks (np.linspace's
#: fixed cost is ~20x that of this product on 7 numbers)
_BOUND_STEPS = np.arange(7) / 6.0


def compressibility_bound(name, t_low, t_high, p):
    """An upper bound on ``|Z - 1|`` of built-in gas ``name`` at pressures ``p``
    [Pa] (a float or an array: the bound has its shape) and any temperature
    from ``t_low`` to ``t_high`` [K], or None for another gas or near
    condensation (below 1.2 Tc): ask CoolProp.

    Z - 1 = B p / (R T) + C p^2 / (R T)^2 + ..., bounded by
    ``(2 |B| + 2e-6) p / (R T) + 2e-9 p^2 / (R T)^2`` (B in m^3/mol, C in
    m^6/mol^2), the largest over the temperatures (the two given and five
    between). B from the Pitzer correlation with Abbott's equations (Smith,
    Van Ness and Abbott, *Introduction to Chemical Engineering Thermodynamics*,
    7th ed., eqs. 3.61-3.66): B pc / (R Tc) = B0 + omega B1, B0 = 0.083 -
    0.422 / Tr^1.6, B1 = 0.139 - 0.172 / Tr^4.2 (air at 293 K: B = -9e-6
    m^3/mol from it, -8e-6 measured). Against CoolProp (tested) the bound is
    at least 1.4x ``|Z - 1|`` from 1.2 Tc to 800 K wherever it is below 0.1."""
    crit = _CRITICAL.get(name)
    if crit is None:
        return None
    Tc, pc, omega = crit
    # one temperature (an isothermal scene): plain floats, and p's own shape; the
    # arithmetic below is the same on floats and arrays (on a few numbers each
    # NumPy operation costs ~1 us, a float one ~0.05 us)
    one = t_high == t_low
    T = float(t_low) if one else t_low + (t_high - t_low) * _BOUND_STEPS
    tr = T / Tc
    if not (tr if one else tr.min()) >= 1.2:
        return None
    B = _R * Tc / pc * (0.083 - 0.422 / tr ** 1.6 + omega * (0.139 - 0.172 / tr ** 4.2))
    if not isinstance(p, float):
        p = np.asarray(p, dtype=float)
        if not one:
            p = p[..., None]
    rt = _R * T
    bound = (2 * abs(B) + 2e-6) * p / rt + 2e-9 * (p / rt) ** 2
    return bound if one else np.max(bound, axis=-1)


def _largest_on_ranges(grid, rows, lo, hi):
    """Per range [lo_j, hi_j], the value of largest magnitude of the piecewise
    linear functions ``rows`` (each sampled on ``grid``, ascending) over it: at
    its two ends and at the grid points strictly between them, every row
    (the first such value where magnitudes tie). One array operation for all
    the ranges (a loop over them cost ~8 us a range)."""
    inside = (grid > lo[:, None]) & (grid < hi[:, None])
    z = np.concatenate([part for row in rows for part in (
        np.interp(lo, grid, row)[:, None], np.interp(hi, grid, row)[:, None],
        np.where(inside, row, 0.0))], axis=1)
    return z[np.arange(lo.size), np.argmax(np.abs(z), axis=1)]


#: {(fluid spec, temperature, tables directory): its table level or None}: the
#: tables _table_clears reads (a TableFluid costs ~0.17 ms to make)
_Z_TABLES = {}


def _z_table(fluid):
    """The table level of gas ``fluid`` at its own temperature, or None where
    there is none to trust in CoolProp's place: no catalog entry, no table, a
    table built with another CoolProp version than the installed one (whose
    warning a check must not raise)."""
    from ..fluids.tables import TABLES_ENV
    spec = getattr(fluid, "spec", None)
    if spec is None:
        return None
    # (the directory by the variable that moves it: resolving the default path
    # costs ~0.1 ms)
    key = (spec, float(fluid.temperature), os.environ.get(TABLES_ENV))
    try:
        return _Z_TABLES[key]
    except KeyError:
        pass
    except TypeError:        # an unhashable spec
        return None
    table = None
    try:
        import json

        from ..fluids.tables import coolprop_version, table_files, tables_directory
        _, json_path = table_files(spec.table_stem, tables_directory())
        built = json.loads(json_path.read_text()).get("coolprop_version")
        if built is not None and built == coolprop_version():
            table = fluid.with_level("table")
            if table.liquid:
                table = None
    except Exception:        # no table, unreadable, a temperature outside it
        table = None
    _Z_TABLES[key] = table
    return table


def _table_clears(fluid, grid, T, near):
    """Whether the gas's property table shows |Z - 1| short of ``near`` (a near
    miss) by more than :data:`Z_TABLE_MARGIN` at every pressure of ``grid`` and
    temperature of ``T``: then CoolProp's Z there, and every value
    gas_compressibility interpolates between them, is short of it too, and the
    check has no record to give. False where the table cannot tell (none, a
    state outside it)."""
    table = _z_table(fluid)
    if table is None:
        return False
    try:
        dz = np.array([table.compressibility(grid, tt) for tt in T], dtype=float) - 1.0
    except Exception:        # a state outside the table
        return False
    largest = float(np.abs(dz).max()) if dz.size else math.nan
    return math.isfinite(largest) and largest + Z_TABLE_MARGIN < near


def gas_compressibility(g, result):
    """One record per gas volume of group ``g`` whose ideal-gas density is off
    by ``|Z - 1|`` near or past the limit over its own pressures (volumes at
    different pressures differ: the high-pressure part of a network may need a
    finer fluid level where the rest does not)."""
    comp0 = g.comps[0]
    fluid = comp0.fluid
    if fluid is None or not fluid.compressible or fluid.level != "ideal":
        return []
    keep, p = group_values(g, result, "pressure")
    if not keep or not p.size:
        return []
    T = [float(fluid.temperature)]
    try:
        _, temps = group_values(g, result, "temperature", default=(None, None))
        if temps is not None and temps.size:
            T = [float(np.nanmin(temps)), float(np.nanmax(temps))]
    except KeyError:
        pass
    limit = _limit(result, 1e-3)
    # the bound grows with |p|: where it stays short of a near miss at the largest
    # |p| of all the volumes, no volume is asked below (one bound instead of one
    # per volume, and no NaN-aware reductions)
    top = float(np.abs(p).max())
    if top == top:
        screen = compressibility_bound(fluid.name, min(T), max(T), top)
        if screen is not None and not screen >= NEAR_FRACTION * limit:
            return []
    with np.errstate(all="ignore"):
        p_min, p_max = np.nanmin(p, axis=0), np.nanmax(p, axis=0)
    # CoolProp is asked only where Z - 1 may reach a near miss, by a virial bound
    # for the built-in gases (a plain run of air at low pressure then does not
    # import CoolProp); another gas came from CoolProp already and is asked
    # whatever its pressure
    bound = compressibility_bound(fluid.name, min(T), max(T), p_max)
    asked = (np.arange(p_max.size) if bound is None else
             np.flatnonzero(bound >= NEAR_FRACTION * limit))
    if not asked.size:
        return []
    # Z - 1 on a grid of pressures over every volume asked (a few CoolProp calls
    # however many volumes), read per volume over its own pressure range
    lo, hi = float(np.nanmin(p_min[asked])), float(np.nanmax(p_max[asked]))
    grid = np.unique(np.geomspace(lo, hi, Z_GRID) if hi > lo else np.array([hi]))
    if _table_clears(fluid, grid, T, NEAR_FRACTION * limit):
        return []
    try:
        from ..fluids.base import Fluid
        real = Fluid(fluid.name, level="eos", temperature=T[0])
    except Exception:        # a fluid CoolProp does not know
        return []
    try:
        dz_grid = np.array([[float(real.compressibility(pp, tt)) - 1.0 for pp in grid]
                            for tt in T])
    except Exception:        # a state outside CoolProp's range
        return []
    dz_j = _largest_on_ranges(grid, dz_grid, p_min[asked], p_max[asked])
    out = []
    for j, dz in zip(asked.tolist(), dz_j.tolist()):
        fraction = abs(dz) / limit
        if not grade(fraction):
            continue
        pressures = (float(p_min[j]), float(p_max[j]))
        out.append(_record(
            g.comps[keep[j]], "gas_compressibility", dz, limit, "", fraction,
            f"use the fluid's 'table' or 'eos' level (sf.{fluid.name}.with_level('table'))",
            f"the ideal-gas density of {fluid.name} is off by Z - 1 = {dz:+.3g} at the "
            f"pressures it reached (up to {pressures[1] / 1e5:.4g} bar) and "
            f"{', '.join(dict.fromkeys(f'{x:.4g}' for x in T))} K, "
            + (f"more than {limit:.3g} (10 x rtol)." if fraction > 1
               else f"{fraction:.0%} of the limit {limit:.3g} (10 x rtol)."),
            pressure=pressures[1]))
    return out


# -- liquids --------------------------------------------------------------------------
def _liquid_nodes(asm, keep=None):
    """{id(fluid): (fluid, node pressure unknowns, [(group, their positions in its
    members' interface)])} of the network's liquids: the node pressures where a
    component of each liquid meets (x[:n_across] of quantity 'pressure').
    ``keep``: a test of the fluid instead (any fluid it passes, gas or liquid).
    Found once per network and test (its structure is fixed; run-time
    parameters replace members of a group by members with the same fluid:
    found again where a group's fluid is another object)."""
    fluids = [getattr(g.comps[0], "fluid", None) for g in asm.groups]
    known = asm.__dict__.setdefault("_liquid_nodes", {})
    hit = known.get(keep)
    if hit is not None and len(hit[0]) == len(fluids) and all(map(operator.is_, hit[0], fluids)):
        return hit[1]
    n_across = asm.n_across
    # a small network on Python lists (~5 us against ~25 us of NumPy calls)
    small = asm.n <= SMALL_NETWORK
    found: dict = {}
    for g in asm.groups:
        fluid = getattr(g.comps[0], "fluid", None)
        if fluid is None or (not keep(fluid) if keep is not None
                             else getattr(fluid, "compressible", True)):
            continue
        col = g.col.reshape(len(g.comps), -1)
        rows = col.tolist() if small else None
        first = rows[0] if small else col[0].tolist()
        pos = [k for k, i in enumerate(first)
               if i < n_across and asm.x_quantity[i] == "pressure"]
        if not pos:
            continue
        entry = found.setdefault(id(fluid), (fluid, [], []))
        if small:       # col[:, pos].ravel(), member by member
            entry[1].extend([row[k] for row in rows for k in pos])
        else:
            entry[1].append(col[:, pos].ravel())
        entry[2].append((g, pos))
    out = {key: (fluid, np.array(sorted(set(cols)), dtype=np.int64) if small
                 else np.unique(np.concatenate(cols)), owners)
           for key, (fluid, cols, owners) in found.items()}
    known[keep] = (fluids, out)
    return out




#: {(spec, temperature, tables directory variable, whether CoolProp is loaded):
#: vapour pressure} of the liquids the cavitation check met (see _vapour_pressure)
_VAPOUR: dict = {}
#: (softflow.fluids.tables.TABLES_ENV, softflow.fluids.vapour.vapour_pressure),
#: imported on first use
_VAPOUR_FN = None


def _vapour_pressure(fluid):
    """:func:`softflow.fluids.vapour.vapour_pressure` of a liquid ``fluid``,
    remembered by what it is a function of: the fluid's spec (a frozen value)
    and temperature, the tables directory it reads (``$SOFTFLOW_FLUID_TABLES``)
    and whether CoolProp is loaded (asked for a liquid without a record).
    Looked up afresh for a fluid without a hashable spec."""
    global _VAPOUR_FN
    if _VAPOUR_FN is None:
        from ..fluids.tables import TABLES_ENV
        from ..fluids.vapour import vapour_pressure
        _VAPOUR_FN = (TABLES_ENV, vapour_pressure)
    TABLES_ENV, vapour_pressure = _VAPOUR_FN
    spec = getattr(fluid, "spec", None)
    try:
        key = (spec, float(fluid.temperature), os.environ.get(TABLES_ENV),
               "CoolProp" in sys.modules, bool(getattr(fluid, "compressible", False)))
        hash(key)
    except (TypeError, ValueError):
        return vapour_pressure(fluid)       # (which says what is wrong)
    if spec is None or type(spec).__hash__ is object.__hash__:
        return vapour_pressure(fluid)    # (a spec compared by identity: no value)
    got = _VAPOUR.get(key, _VAPOUR)
    if got is _VAPOUR:
        if len(_VAPOUR) >= 256:
            _VAPOUR.clear()
        got = _VAPOUR[key] = vapour_pressure(fluid)
    return got


def _node_pressures(result, nodes):
    """(the recorded ones of ``nodes``, their columns in ``result.X``); none
    recorded: an empty array of nodes. The checks reduce X's columns whole and
    pick theirs from the reductions, without gathering the nodes' columns into
    a new array (a 2 000-component water network's 995 nodes of 4 020 columns
    over 5 036 points: 0.126 s gathered, ~0.01 s reduced)."""
    cols = result._xcol[nodes]
    recorded = cols >= 0
    return nodes[recorded], cols[recorded]


def _component_at_node(asm, result, owners, node):
    """(a component of ``owners`` (a network check's (group, terminal
    position) pairs) meeting at ``node``, a recorded one where there is one;
    its recorded times; the node's name)."""
    at = [(g, int(i)) for g, pos in owners for i in
          np.flatnonzero((g.col.reshape(len(g.comps), -1)[:, pos] == node).any(axis=1))]
    comp_g, i = next(((g, i) for g, i in at if g.comps[i].label in result._where), at[0])
    return (comp_g.comps[i], group_times(comp_g, result, [i])[:, 0],
            str(asm.x_names[node]).removesuffix(" pressure"))


def cavitation(asm, result):
    """(A network check, :func:`softflow.solve.validity.register_network`.) The
    lowest pressure of each liquid against its vapour pressure (module doc)."""
    out = []
    for fluid, nodes, owners in _liquid_nodes(asm).values():
        nodes, cols = _node_pressures(result, nodes)
        if not nodes.size:
            continue
        X = result.X
        low = np.fmin.reduce(X, axis=0)[cols]  # per node, NaN left out
        low[np.isnan(low)] = np.inf            # (a node without a number at all)
        j = int(np.argmin(low))
        p_min = float(low[j])
        p_vap = _vapour_pressure(fluid)
        if p_vap is None or not p_min > 0:
            continue
        fraction = p_vap / p_min
        if not grade(fraction):
            continue
        k = int(np.nanargmin(X[:, cols[j]]))
        comp, times, where = _component_at_node(asm, result, owners, int(nodes[j]))
        t = float(times[k])
        T = float(fluid.temperature)
        liquid = f"{fluid.name} at {T:.5g} K ({T - 273.15:.4g} degC)"
        if fraction > 1:
            message = (f"the pressure of its liquid, {liquid}, fell to {p_min:.4g} Pa "
                       f"(absolute) at {where} at t = {t:.6g} s, below the liquid's vapour "
                       f"pressure {p_vap:.4g} Pa: there the liquid would boil (cavitate), "
                       "which softflow does not model (the liquid stays one phase, its "
                       "pressure free to fall as if it held any tension): the flows and "
                       "pressures near there are not physical.")
        else:
            message = (f"the pressure of its liquid, {liquid}, fell to {p_min:.4g} Pa "
                       f"(absolute) at {where} at t = {t:.6g} s, within a factor "
                       f"{1 / fraction:.3g} of the liquid's vapour pressure {p_vap:.4g} Pa, "
                       "below which it would boil (cavitate), which softflow does not model.")
        out.append(_record(
            comp, "cavitation", p_min, p_vap, "Pa", fraction,
            "keep the liquid above its vapour pressure where it is drawn: a higher "
            "pressure on the suction side (source, tank), a shorter or wider suction "
            "line, or a slower pump",
            message, time=t, node=where, temperature=T, vapour_pressure=p_vap))
    return out


def _raising_table(fluid):
    """Whether ``fluid`` is tabulated over a pressure range it refuses to
    leave (a table level at out_of_range='raise')."""
    rng = getattr(fluid, "p_range", None)
    return (rng is not None and getattr(fluid, "out_of_range", "raise") == "raise"
            and getattr(fluid, "level", None) == "table")


def fluid_range(asm, result):
    """(A network check.) A node where a component of a tabulated fluid meets
    whose pressure left the table's range while the run went on: no component
    evaluated the fluid at that pressure (a tube's law works at its mean
    pressure, a source sets the node and takes no property), so nothing
    refused it, but the state there is outside what the table covers (a
    pressure source ramped below a glycol table's 0.5 bar; the air table's
    0.1 bar). One record per fluid: the farthest node, its pressure and time.
    Fraction: how far outside, the range's end over the pressure (below it) or
    the pressure over the end (above it); only past 1."""
    out = []
    for fluid, nodes, owners in _liquid_nodes(asm, keep=_raising_table).values():
        nodes, cols = _node_pressures(result, nodes)
        if not nodes.size:
            continue
        lo, hi = (float(v) for v in fluid.p_range)
        X = result.X
        with np.errstate(all="ignore"):
            low = np.fmin.reduce(X, axis=0)[cols]
            high = np.fmax.reduce(X, axis=0)[cols]
            far = np.fmax(np.where(low > 0.0, lo / low, np.inf), high / hi)
        far[np.isnan(far)] = 0.0
        j = int(np.argmax(far))
        fraction = float(far[j])
        # a node held at the table's very end (a source at its last pressure)
        # sits there to the solve's tolerance: no record within the run's rtol
        if not fraction > 1.0 + _rtol(result):
            continue
        below = lo / low[j] >= high[j] / hi if low[j] > 0.0 else True
        P = X[:, cols[j]]
        k = int(np.nanargmin(P) if below else np.nanargmax(P))
        p = float(P[k])
        comp, times, where = _component_at_node(asm, result, owners, int(nodes[j]))
        t = float(times[k])
        outside = (P < lo) if below else (P > hi)
        t_first = float(times[int(np.argmax(outside))])
        edge = lo if below else hi
        out.append(_record(
            comp, "fluid_range", p, edge, "Pa", fraction,
            "keep the pressures within the table (the sources that set them), or use a "
            f"level that covers them: {fluid.name!r} at level='eos', or the table with "
            "out_of_range='eos'",
            f"the pressure of its fluid, {fluid.name!r} at the table level, reached "
            f"{p:.4g} Pa (absolute) at {where} at t = {t:.6g} s, outside the table's range "
            f"{lo:.6g} ... {hi:.6g} Pa (outside from t = {t_first:.6g} s on): no component "
            "evaluated the fluid there (a tube's law "
            "works at its mean pressure, a source takes no property), so the run went on, "
            "but the state at that node is outside what the table covers.",
            time=t, first_time=t_first, node=where, p_range=(lo, hi)))
    return out


# -- thermal -------------------------------------------------------------------------
def fill_and_thermal_times(g, result):
    """For the isothermal gas volumes of group ``g`` (but those the user holds
    at their wall temperature, ``thermal='isothermal'``): (indices in the group,
    fill time scale ``m / |mdot|`` at the peak flow [s], thermal time constant
    m cv / (h A) there [s], the time index of the peak), or None."""
    comp0 = g.comps[0]
    fluid = comp0.fluid
    if fluid is None or not fluid.compressible or getattr(comp0, "_thermal", None) is not None:
        return None
    keep, mass = group_values(g, result, "mass")
    # a volume given thermal='isothermal' is held at its wall temperature by the
    # user's own choice (a thermostatted vessel): nothing to estimate there
    own = [j for j, i in enumerate(keep) if getattr(g.comps[i], "thermal", None) != "isothermal"]
    if not own:
        return None
    _, mf = group_values(g, result, "massflow")
    _, p = group_values(g, result, "pressure")
    if len(own) < len(keep):
        keep, mass, mf, p = [keep[j] for j in own], mass[:, own], mf[:, own], p[:, own]
    flow = np.abs(mf)
    k = np.argmax(flow, axis=0)
    cols = np.arange(len(keep))
    peak, m, pk = flow[k, cols], mass[k, cols], p[k, cols]
    moving = peak > 0
    if not moving.any():
        return None
    T = float(fluid.temperature)
    with np.errstate(all="ignore"):
        t_fill = np.where(moving, m / peak, np.inf)
        hA = _sphere_hA(fluid, pk, T + THERMAL_DT, T, m / fluid.density(pk))
        if hA is None:
            return None
        for j, i in enumerate(keep):      # a wall the user gave is the scene's own
            hA[j] = _wall_hA(g.comps[i], fluid, pk[j], T, m[j], hA[j])
        t_thermal = m * fluid.cv(pk) / hA
    return keep, t_fill, t_thermal, k


def isothermal_error(result):
    """{label: estimated error of the isothermal model} for the gas volumes of
    an isothermal run: (gamma - 1) t_thermal / t_fill, the relative
    temperature rise of gas filled at the peak rate whose wall removes heat
    with the time constant t_thermal (capped at gamma - 1, the adiabatic
    limit). An order-of-magnitude estimate (the near-choking scene of
    benchmarks/assess_scenes.py: 0.3 estimated, 13 % measured)."""
    from ..components.thermal import VOLUME_CLASSES
    out = {}
    for g in {id(g): g for g, _ in result._where.values()}.values():
        if not isinstance(g.comps[0], VOLUME_CLASSES):
            continue
        times = fill_and_thermal_times(g, result)
        if times is None:
            continue
        keep, t_fill, t_thermal, _ = times
        gamma1 = float(g.comps[0].fluid.gamma(pressure_atmospheric)) - 1.0
        with np.errstate(all="ignore"):
            err = np.minimum(gamma1 * t_thermal / t_fill, gamma1)
        for j, i in enumerate(keep):
            out[g.comps[i].label] = float(err[j])
    return out


def thermal_time_scale(g, result):
    times = fill_and_thermal_times(g, result)
    if times is None:
        return []
    keep, t_fill, t_thermal, k = times
    with np.errstate(all="ignore"):
        fraction = THERMAL_FRACTION * t_thermal / t_fill
        # the isothermal model's error, as isothermal_error estimates it
        gamma1 = float(g.comps[0].fluid.gamma(pressure_atmospheric)) - 1.0
        error = np.minimum(gamma1 * t_thermal / t_fill, gamma1)
    tt = group_times(g, result, keep)
    out = []
    for j in np.flatnonzero(fraction >= NEAR_FRACTION):
        c = g.comps[keep[j]]
        out.append(_record(
            c, "thermal_time_scale", t_fill[j], THERMAL_FRACTION * t_thermal[j], "s",
            fraction[j],
            "run the scene with thermal='adiabatic' (or 'heat_transfer' with the "
            "volume's area and a heat-transfer coefficient)",
            f"its gas filled or emptied on a time scale m/|mdot| = {t_fill[j]:.3g} s at "
            f"t = {tt[k[j], j]:.6g} s, against a thermal time constant "
            f"~{t_thermal[j]:.3g} s of its wall ("
            + ("its own h A" if has_wall(c) else "free convection estimate") + "), "
            + ("much faster than the wall exchanges heat: the gas is closer to adiabatic "
               "than to the isothermal model, and its pressure swings are larger than "
               f"computed, by up to ~{error[j]:.0%} ((gamma - 1) t_thermal / t_fill, at most "
               "gamma - 1: an order-of-magnitude estimate; an isothermal 1 L blowdown "
               "in ~1 s measured 23 % against free-convection walls)."
               if fraction[j] > 1 else
               f"{fraction[j]:.0%} of the way to the limit (a tenth of that constant)."),
            thermal_time_constant=float(t_thermal[j]), time=float(tt[k[j], j]),
            estimated_error=float(error[j])))
    return out


#: np.trapezoid from NumPy 2.0, np.trapz before it (numpy>=1.23 is supported)
_trapezoid = getattr(np, "trapezoid", None) or getattr(np, "trapz")


def adiabatic_time_scale(g, result):
    """Adiabatic gas volumes of a thermal scene whose temperature stayed away
    from the wall's for longer than the wall's thermal time constant (see the
    module docstring)."""
    comp0 = g.comps[0]
    fluid = comp0.fluid
    if fluid is None or not fluid.compressible:
        return []
    if len(result.times) < 2 or not any(getattr(c, "_thermal", None) == "adiabatic"
                                        for c in g.comps):
        return []          # isothermal, held or with a wall: nothing neglected here
    keep, T = group_values(g, result, "temperature")
    own = [j for j, i in enumerate(keep) if getattr(g.comps[i], "_thermal", None) == "adiabatic"]
    if not own:
        return []
    _, m = group_values(g, result, "mass")
    _, p = group_values(g, result, "pressure")
    keep = [keep[j] for j in own]
    T, m, p = T[:, own], m[:, own], p[:, own]
    t = group_times(g, result, keep)
    Tw = np.array([g.comps[i]._T_wall for i in keep])
    dev = np.abs(T - Tw)
    k = np.argmax(dev, axis=0)
    cols = np.arange(len(keep))
    peak = dev[k, cols]
    limit = _limit(result, 1e-2)
    significant = peak > limit * Tw
    if not significant.any():
        return []
    pk, Tk, mk = p[k, cols], T[k, cols], m[k, cols]
    with np.errstate(all="ignore"):
        persistence = _trapezoid(dev, t, axis=0) / peak
        hA = _sphere_hA(fluid, pk, Tk, Tw, mk / fluid.density(pk, Tk))
        if hA is None:
            return []
        t_thermal = mk * fluid.cv(pk, Tk) / hA
        fraction = persistence / (ADIABATIC_PERSISTENCE * t_thermal)
    out = []
    for j in np.flatnonzero(significant):
        if not grade(fraction[j]):
            continue
        c = g.comps[keep[j]]
        out.append(_record(
            c, "adiabatic_time_scale", persistence[j], ADIABATIC_PERSISTENCE * t_thermal[j],
            "s", fraction[j],
            "give the volume its wall (hA, or heat_transfer_coefficient and area) and run "
            "thermal='heat_transfer', or run it isothermal",
            f"its gas stayed up to {peak[j]:.3g} K from its wall temperature "
            f"({Tw[j]:.5g} K) for ~{persistence[j]:.3g} s (the time integral of the "
            f"difference over its largest value), against a thermal time constant "
            f"~{t_thermal[j]:.3g} s of its wall (free convection estimate): "
            + ("a real wall would have taken back most of that difference, which the "
               "adiabatic model keeps: its temperature, and its mass or pressure, are off."
               if fraction[j] > 1 else f"{fraction[j]:.0%} of the way to that limit."),
            thermal_time_constant=float(t_thermal[j]), time=float(t[k[j], j])))
    return out


def has_wall(comp):
    """Whether a volume was given a wall (hA, or a coefficient and an area)."""
    return (getattr(comp, "hA", None) is not None
            or getattr(comp, "h_correlation", None) is not None)


#: the FreeConvection('sphere') of _sphere_hA, made on first use
_SPHERE = None


def _sphere_hA(fluid, p, T, T_wall, volume):
    """h A [W/K] by free convection of gas at (p, T) in a sphere of ``volume``
    against its wall at ``T_wall`` (the thermal checks' estimate of a volume's
    wall), or None for a fluid without conductivity."""
    global _SPHERE
    sphere = _SPHERE
    if sphere is None:
        from ..correlations.heat_transfer import FreeConvection
        sphere = _SPHERE = FreeConvection("sphere")     # a value: made once
    length = sphere.characteristic_length(volume)
    try:
        h = sphere.coefficient(fluid, p, T, T_wall, length)
    except Exception:      # a fluid without conductivity: no estimate
        return None
    return h * np.pi * length ** 2


def _wall_hA(comp, fluid, p, T, m, estimate):
    """h A of a volume's wall [W/K]: its own hA, or its correlation's h at the
    state (a THERMAL_DT difference) times its area, else ``estimate``."""
    if not has_wall(comp):
        return estimate
    if comp.hA is not None:
        return comp.hA
    corr = comp.h_correlation
    length = corr.characteristic_length(m / fluid.density(p))
    return float(corr.coefficient(fluid, p, T + THERMAL_DT, T, length)) * comp.area


def tube_inertia(g, result):
    comp0 = g.comps[0]
    fluid = comp0.fluid
    if fluid is None or fluid.compressible or getattr(comp0, "state_spec", ()):
        return []          # gases: compressibility dominates; inertial tubes model it
    if len(result.times) < 3:
        return []
    keep, mf, pa, pb = two_port_values(g, result)
    if not keep:
        return []
    t = group_times(g, result, keep)
    limit = _limit(result, 1e-2)
    jump = np.abs(np.diff(mf, axis=0))
    with np.errstate(all="ignore"):
        rate = jump / np.diff(t, axis=0)
    # the pressures the tube works against: its ends' gauge pressures and its drop
    scale = np.maximum(np.max(np.abs(pa - pressure_atmospheric), axis=0),
                       np.max(np.abs(pb - pressure_atmospheric), axis=0))
    scale = np.maximum(scale, np.max(np.abs(pa - pb), axis=0))
    out = []
    for j, i in enumerate(keep):
        c = g.comps[i]
        peak = float(np.max(np.abs(mf[:, j])))
        # a flow imposed as a step (a pump switched on) jumps within one step
        # whatever the step: the inertia there is an impulse, not a lag; what
        # counts are the flow's resolved changes
        resolved = jump[:, j] <= 0.5 * peak
        if not (peak > 0 and scale[j] > 0 and resolved.any()):
            continue
        k = int(np.nanargmax(np.where(resolved, rate[:, j], -1.0)))
        inertial = c.length / (math.pi * c.diameter ** 2 / 4) * float(rate[k, j])
        ratio = inertial / float(scale[j])
        if grade(ratio / limit):
            out.append(_record(
                c, "tube_inertia", ratio, limit, "", ratio / limit,
                "build the tube with CircularTube(..., inertance=True)",
                f"its liquid column's inertia, which the tube leaves out, would add "
                f"{inertial:.3g} Pa (l/A times the flow's fastest change, at t = "
                f"{t[k + 1, j]:.6g} s), {ratio:.3g} of the pressures it works between "
                f"({scale[j]:.3g} Pa), " + (f"more than {limit:.3g} (10 x rtol)."
                                            if ratio > limit else
                                            f"against a limit of {limit:.3g} (10 x rtol)."),
                inertial_pressure=inertial, time=float(t[k + 1, j])))
    return out


#: tube_mach's choked record refuses the run (``details['fatal']``): Simulation.run
#: asks it alone at t = 0 to stop a run refused from its start at once
tube_mach.can_refuse = True  # type: ignore[attr-defined]


def register_all(register, register_network):
    from ..components.actuators import Actuator, HystereticActuator
    from ..components.chambers import Container, LinearAccumulator
    from ..components.tubes import CircularTube
    from ..components.valves import Orifice
    register(CircularTube, tube_reynolds)
    register(CircularTube, tube_mach)
    register(CircularTube, tube_isothermal_flow)
    register(CircularTube, tube_inertia)
    register(Orifice, orifice_choked)
    for cls in (Container, LinearAccumulator, Actuator, HystereticActuator):
        register(cls, gas_compressibility)
        register(cls, thermal_time_scale)
        register(cls, adiabatic_time_scale)
    register_network(cavitation)
    register_network(fluid_range)
