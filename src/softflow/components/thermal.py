"""Thermal variants of the library components (adiabatic and heat-transfer gas scenes).

In a thermal scene (``Simulation(..., thermal='adiabatic' | 'heat_transfer')``)
every fluid terminal carries two more variables: the temperature ``T`` [K]
(across: one unknown per node) and the energy flow ``E`` [W] (through,
positive into the component: one energy-conservation row per node). The
isothermal kernels stay untouched; each class gets a variant here, made by
:func:`thermal_class`, that the assembly selects at compile time.

Energy model
------------
* **Flow elements** (tubes, orifices, valves) are adiabatic and store nothing:
  E_a + E_b = 0, and the energy entering at ``a`` is the enthalpy the mass flow
  carries from upstream,

      E_a = mdot_a · h_up + G · (T_a - T_b),
      h_up = w h(p_a, T_a) + (1 - w) h(p_b, T_b),  w = smoothstep(mdot_a, -B, B)

  with the C1 upwind blend over the band B = :data:`UPWIND_BAND` (exactly
  upwind beyond it). Kinetic energy is neglected (stagnation enthalpy = static
  enthalpy: velocities well below the speed of sound in the volumes). The
  conductance G = :data:`ZERO_FLOW_CONDUCTANCE` (a thermal leak of 1e-6 W/K,
  the enthalpy flow of 1 µg/s of air per kelvin) gives a node through which
  nothing flows a temperature (the average of its neighbours'); it moves energy
  between volumes but never creates or destroys any, so energy balances close
  exactly. A gas tube, a Tesla valve and an open snapping valve of an ideal
  gas with the pipe-flow law (the default) are adiabatic (Fanno) pipe flow
  from the upstream node's stagnation state (their ``thermal_drop`` or
  ``thermal_rows``; T_up its temperature). Elsewhere the temperature enters
  the gas flow laws through the ideal-gas density at the upstream temperature:
  orifices' mass flow scales with sqrt(T_ref/T_up), the other tubes' and a
  closed snapping valve's pressure drop with T_up/T_ref (T_ref: the fluid's
  own temperature; viscosity stays at its nominal value). Inertial tubes and check valves keep their nominal-temperature
  flow law (their energy transport is still upwind).
* **Energy reference**: energies are counted from one reference enthalpy per
  scene, h0 = h(1 atm, T) of the first gas found (its own temperature): a
  volume's internal energy is U = m·(u - h0) and energy flows are
  mdot·(h - h0). Since mass is conserved at every node and through every
  element, this is the same energy balance as with absolute enthalpies; it
  keeps the energy rows of the Jacobian of the size of the temperature
  differences instead of the (arbitrary) absolute enthalpy, which the linear
  solver's singularity test needs.
* **Nodes** have no volume: the energy row of a node mixes the enthalpy flows
  of its inflows, so the outflows leave with the mass-weighted mixed enthalpy.
* **Volumes** (Container, LinearAccumulator, Actuator, HystereticActuator)
  are in rate form like every other component. A volume whose gas is free
  (adiabatic, or with wall heat transfer) integrates its mass m and its
  *stored energy* E_s, the gas's internal energy plus the work W it has done
  on the wall since t = 0, and carries its wall heat Q [W] as a local unknown
  ``wall_heat``:

      dm/dt = mdot,     dE_s/dt = E + Q
      0 = wall law:     rho(p, T) Vol = m (Vol = volume, or volume +
                        compliance (p - p_ref)), or p = curve(m / rho(p, T))
      0 = m (u(p, T) - h0) + W(Vol) - E_s
      0 = Q - hA (T_wall - T)

  with u(p, T), h(p, T) from the fluid (constant cv/cp for ideal gases, real
  properties at the ``table`` and ``eos`` levels). W(Vol) is the integral of
  the wall's pressure over volume (dW/dVol = the wall's pressure): exact for
  an accumulator and a PVCurve's cubic pieces, Gauss-Legendre for a curve
  given as a function (:meth:`softflow.curves.PVCurve.work`). For a
  quasi-static wall p·dVol/dt = dW/dt, so the energy equation
  dU/dt = E + Q - p dVol/dt needs no rate of the volume: only first
  derivatives of the fluid's properties enter, and the rates are linear in
  the unknowns, so a closed adiabatic network keeps its total stored energy
  to round-off under every stepper and order. The terminal temperature is the
  gas temperature (a well-mixed volume: what leaves has its state). hA = 0 is
  adiabatic; an hA from a correlation (FreeConvection) is set at the start of
  each step. Results: ``mass``, ``stored_energy``, ``wall_heat`` and the
  derived ``volume``, ``internal_energy`` = m (u - h0) and ``wall_work``.

  A volume with ``thermal='isothermal'`` in a thermal scene is *held* at its
  wall temperature: it integrates its mass only, with residuals the wall law
  and T = T_wall; the heat that holds it there is whatever the energy the flows
  carry requires (:func:`softflow.solve.thermal.energy_balance` closes its
  balance with it).

  A HystereticActuator keeps its discrete state ``branch``: the step uses the
  branch it started on, which switches between steps from the converged
  volume. Its work is counted along the loop (:meth:`HysteresisLoop.work`);
  at a change of branch the discrete state ``work_offset`` moves the count so
  that E_s does not jump (the loop's area is work the wall dissipates).
* **Sources** are reservoirs at their ``temperature``: a PressureSource fixes its
  node's temperature; flow sources deliver h(p, T_source) and take in the
  node's enthalpy when the flow reverses.

Compiled laws
-------------
For an ideal gas whose properties are :class:`~softflow.IdealGas`'s own
(:func:`ideal_gas_constants`) the kernels below evaluate each group in one
compiled pass of :mod:`softflow.laws.thermal` (the upwind energy, the walls
and the rows of volumes, the flow elements' rows around their laws, the flow
sources), the same laws the compiled network residual
(:mod:`softflow.solve.netcore`) calls instance by instance; the NumPy code
stays for the other fluids (table and eos levels) and for laws the compiled
passes do not know (a tube's mean-density law, a curve given as a function).
"""
from __future__ import annotations

import functools

import numpy as np

from .._laws import law_module
from ..constants import pressure_atmospheric
from ..correlations.orifice import ISO_6358_RHO0, ISO_6358_T0
from .actuators import Actuator, HystereticActuator
from .chambers import (MASS_RATE_PATTERN, Container, LinearAccumulator, accumulator_volume,
                       mass_rates)
from .sources import MassFlowSource, PressureSource, VolumeFlowSource
from .tubes import CircularTube, InertialCircularTube
from .valves import CheckValve, Orifice, SnappingValve, TeslaValve

#: Mass-flow band of the smooth upwind blend [kg/s].
UPWIND_BAND = 1e-9
#: Thermal conductance across every flow element and flow source [W/K] (see module doc).
ZERO_FLOW_CONDUCTANCE = 1e-6

#: Variables a thermal terminal adds: (quantity, role, label).
THERMAL_PORT_EXTRA = (("temperature", "across", "T"), ("energyflow", "through", "E"))

#: the compiled laws of thermal scenes of an ideal gas (softflow.laws.thermal)
_thermal_laws = functools.partial(law_module, "thermal")

#: the methods of an ideal gas that the compiled laws write out (softflow.laws.thermal)
_IDEAL_METHODS = ("density", "density_dp", "density_dT", "enthalpy", "internal_energy",
                  "_density_parts", "_internal_energy_parts", "_enthalpy_linear")


def ideal_gas_constants(fluid):
    """(R, cp, cv, c) of an ideal gas whose properties are IdealGas's own
    (rho = p / (R T), h = cp T + c, u = cv T + c): what the compiled laws of
    :mod:`softflow.laws.thermal` take; None for any other fluid (table and eos
    levels, a subclass with a law of its own), which keeps the NumPy kernels."""
    from ..fluids.ideal import IdealGas
    kind = type(fluid)
    if not isinstance(fluid, IdealGas) or any(getattr(kind, name) is not getattr(IdealGas, name)
                                              for name in _IDEAL_METHODS):
        return None
    return (float(fluid.R), float(fluid.cp0), float(fluid.cv0),
            float(fluid.h_ref - fluid.cp0 * fluid.temperature))


def _parts(fl, name, p, T, jac):
    """(value, d/dp, d/dT) of the fluid property ``name`` ('enthalpy',
    'internal_energy', 'density'); derivatives None without jac. Fluids with a
    private ``_<name>_parts`` (the ideal level) answer in one call, with
    constant derivatives as floats: the per-call overhead of the public
    array-in/array-out methods dominates small thermal scenes."""
    fast = getattr(fl, f"_{name}_parts", None)
    if fast is not None:
        return fast(p, T, jac)
    value = getattr(fl, name)(p, T)
    if not jac:
        return value, None, None
    return value, getattr(fl, f"{name}_dp")(p, T), getattr(fl, f"{name}_dT")(p, T)


def _upwind_weight(mf, jac):
    """smoothstep(mf, -UPWIND_BAND, UPWIND_BAND) of correlations.friction, in one
    compiled pass (:func:`softflow.laws.thermal.upwind_weight`); returns (w,
    dw/dmf or None)."""
    mf = np.asarray(mf, dtype=float)
    w, dw = np.empty(mf.shape), np.empty(mf.shape)
    _thermal_laws().upwind_weight_array(mf.ravel(), UPWIND_BAND, w.reshape(-1), dw.reshape(-1))
    return w, (dw if jac else None)


def upwind_energy(fl, mf, pa, Ta, pb, Tb, jac, h0=0.0):
    """Energy flow into ``a`` carried by the mass flow mf (into ``a``), upwind
    enthalpy with the smooth blend, plus the zero-flow conductance; returns
    (E, w, dw, dE, T_up) with dE = (d/dmf, d/dpa, d/dTa, d/dpb, d/dTb) or None
    (entries may be floats where they do not depend on the instance), dw None
    without jac, and T_up = w Ta + (1 - w) Tb the blended upstream temperature."""
    linear = getattr(fl, "_enthalpy_linear", None)
    if linear is not None:
        # h = cp T + c (ideal gas): the blended enthalpy is that of the blended
        # temperature, in one compiled pass (softflow.laws.thermal.upwind_energy)
        cp, c = linear()
        out = np.empty((7, np.size(mf)))
        _thermal_laws().upwind_energy_array(*_flat_floats(mf, Ta, Tb), float(cp),
                                            float(c - h0), UPWIND_BAND, ZERO_FLOW_CONDUCTANCE,
                                            *out)
        E, w, dw, T_up, d_mf, d_Ta, d_Tb = out
        if not jac:
            return E, w, None, None, T_up
        return E, w, dw, (d_mf, 0.0, d_Ta, 0.0, d_Tb), T_up
    w, dw = _upwind_weight(mf, jac)
    dT = Ta - Tb
    T_up = Tb + w * dT
    ha, ha_p, ha_T = _parts(fl, "enthalpy", pa, Ta, jac)
    hb, hb_p, hb_T = _parts(fl, "enthalpy", pb, Tb, jac)
    ha = ha - h0
    hb = hb - h0
    dh = ha - hb
    h = hb + w * dh
    E = mf * h + ZERO_FLOW_CONDUCTANCE * dT
    if not jac:
        return E, w, dw, None, T_up
    mw = mf * w
    mw1 = mf * (1.0 - w)
    d_mf = h + mf * dw * dh
    d_pa = mw * ha_p
    d_Ta = mw * ha_T + ZERO_FLOW_CONDUCTANCE
    d_pb = mw1 * hb_p
    d_Tb = mw1 * hb_T - ZERO_FLOW_CONDUCTANCE
    return E, w, dw, (d_mf, d_pa, d_Ta, d_pb, d_Tb), T_up


def _flat_floats(*arrays):
    """The arrays as 1-D float64 arrays of one size (broadcast where one is a
    float or of another shape), for a compiled pass."""
    out = [np.asarray(a, dtype=float) for a in arrays]
    shape = np.broadcast_shapes(*(a.shape for a in out))
    return [a.reshape(-1) if a.shape == shape else np.broadcast_to(a, shape).reshape(-1)
            for a in out]


def wall_hA(fluid, correlations, area, length, p, T, T_wall):
    """h·A [W/K] of volumes with heat-transfer correlations, at pressures p and gas
    temperatures T (arrays, one entry per volume; instances sharing one
    correlation object are evaluated together)."""
    out = np.empty(len(correlations))
    groups = {}
    for k, corr in enumerate(correlations):
        groups.setdefault(id(corr), (corr, []))[1].append(k)
    for corr, ks in groups.values():
        ks = np.array(ks)
        out[ks] = corr.coefficient(fluid, p[ks], T[ks], T_wall[ks], length[ks]) * area[ks]
    return out


def _put(J, k, columns):
    """J[:, k:k+len(columns)] = columns (arrays or floats; column_stack needs arrays)."""
    for i, col in enumerate(columns):
        J[:, k + i] = col


def _stack(P, components, name):
    return np.array([getattr(c, name) for c in components], dtype=float)


# ---------------------------------------------------------------------------------------
# flow elements: V = [p_a, mf_a, T_a, E_a, p_b, mf_b, T_b, E_b]
# ---------------------------------------------------------------------------------------
_ISO_COLS = np.array([0, 1, 4, 5])      # the isothermal kernel's V inside the thermal V
_ENERGY_PATTERN = ((2, 3), (2, 7), (3, 0), (3, 1), (3, 2), (3, 3), (3, 4), (3, 6))


class ThermalTwoPort:
    """Mixin: a two-port flow element with upwind energy transport (equations 2, 3)
    around its isothermal flow law (equations 0, 1), see the module docstring.

    ``flow_temperature``: how the upstream temperature enters the flow law,
    'sqrt_density' (mass flow ∝ sqrt(rho)), 'inverse_density' (pressure drop
    ∝ 1/rho) or None (nominal temperature)."""

    flow_temperature = None
    direct = False      # see _kernel_pressure_drop

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.T_ref = float(P.fluid.temperature)
        P.h0 = components[0]._h0
        P.ideal = ideal_gas_constants(P.fluid)
        P.thermal_law = None if P.ideal is None else cls._compiled_law(P)
        return P

    @classmethod
    def _compiled_law(cls, P):
        """The group's residual as one compiled pass of :mod:`softflow.laws.thermal`
        (an ideal gas), its name: 'orifice' and 'check' (an orifice, a check
        valve: their compiled laws), 'tube' (a CircularTube of an analytic
        friction correlation on the pipe-flow law: adiabatic pipe flow), 'tesla'
        (a Tesla valve: the same with its friction term), 'snapping' (a snapping
        valve: open, its passage's adiabatic pipe flow); None for the others
        (an inertial tube, a tube's mean-density law), which keep the NumPy code
        below."""
        base = cls.isothermal_class
        if base is Orifice or base is CheckValve:
            return None if not P.compiled else ("orifice" if base is Orifice else "check")
        if getattr(P, "R_gas", None) is None:         # not the pipe-flow law of an ideal gas
            return None
        if base is CircularTube and P.kind is not None:
            return "tube"
        if base is TeslaValve:
            return "tesla"
        if base is SnappingValve and P.compiled:
            return "snapping"
        return None

    @classmethod
    def rates(cls, P, V, S, jac):
        return super().rates(P, V[:, _ISO_COLS], S, jac)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if cls.direct:
            return cls._kernel_pressure_drop(P, V, jac)
        if P.thermal_law is not None:
            return cls._compiled_kernel(P, V, jac, S)
        Fi, Ji = super().residual(P, V[:, _ISO_COLS], S, t, jac)
        pa, mf, Ta, Ea, pb, Tb, Eb = V[:, 0], V[:, 1], V[:, 2], V[:, 3], V[:, 4], V[:, 6], V[:, 7]
        E, w, dw, dE, T_up = upwind_energy(P.fluid, mf, pa, Ta, pb, Tb, jac, P.h0)
        F = np.empty((P.n, 4))
        F[:, :2] = Fi
        np.add(Ea, Eb, out=F[:, 2])
        np.subtract(Ea, E, out=F[:, 3])
        mode = cls.flow_temperature
        own = None
        if mode == "sqrt_density":                # F1 = mf - theta q_iso
            q = mf - Fi[:, 1]
            theta = np.sqrt(P.T_ref / T_up)
            np.subtract(mf, theta * q, out=F[:, 1])
            if jac:
                coef = (0.5 * q) * theta / T_up    # dF1/dT_up = -q dtheta/dT_up
        elif mode is not None:                     # F1 = (pa - pb) - theta dp_iso
            dp = (pa - pb) - Fi[:, 1]
            theta = T_up * (1.0 / P.T_ref)
            F[:, 1] -= (theta - 1.0) * dp          # Fi1 = (pa - pb) - dp
            if jac:
                coef = dp * (-1.0 / P.T_ref)
            # the instances whose law is of the upstream temperature itself (an
            # open snapping valve of an ideal gas: adiabatic pipe flow)
            rows = getattr(cls, "thermal_rows", None)
            own = None if rows is None else rows(P, V[:, _ISO_COLS], S, T_up, jac)
            if own is not None:
                mask, dp_T, d_pa, d_mf, d_pb, d_T = own
                F[:, 1] = np.where(mask, (pa - pb) - dp_T, F[:, 1])
                if jac:
                    coef = np.where(mask, -d_T, coef)
        if not jac:
            return F, None
        # Ji: the flow law's V columns, then its state columns (an inertial tube's),
        # which go last here too, after the energy rows' columns
        nb = Ji.shape[1] - len(cls.state_jac_pattern)
        J = np.empty((P.n, len(cls.residual_pattern) + len(cls.state_jac_pattern)))
        J[:, len(cls.residual_pattern):] = Ji[:, nb:]
        k = nb
        if mode is None:
            J[:, :nb] = Ji[:, :nb]
        else:
            # base pattern (two-port): (0,mf_a) (0,mf_b) (1,pa) (1,mf) (1,pb); the
            # flow-law columns scale with theta, up to the constant +-1 of the
            # pressure difference in the pressure-drop form (column by column:
            # a broadcast in-place product over strided columns is ~10x slower)
            J[:, :2] = Ji[:, :2]
            one_theta = 1.0 - theta
            np.multiply(theta, Ji[:, 2], out=J[:, 2])
            np.multiply(theta, Ji[:, 4], out=J[:, 4])
            dT_up = coef * dw * (Ta - Tb)          # dF1/dmf through T_up
            if mode == "sqrt_density":             # = 1 - theta dq/dmf
                J[:, 3] = theta * Ji[:, 3] + (one_theta + dT_up)
            else:
                J[:, 2] += one_theta
                J[:, 4] -= one_theta
                J[:, 3] = theta * Ji[:, 3] + dT_up
                if own is not None:
                    J[:, 2] = np.where(mask, 1.0 - d_pa, J[:, 2])
                    J[:, 3] = np.where(mask, dT_up - d_mf, J[:, 3])
                    J[:, 4] = np.where(mask, -1.0 - d_pb, J[:, 4])
            cw = coef * w
            J[:, k] = cw
            np.subtract(coef, cw, out=J[:, k + 1])
            k += 2
        _energy_columns(J, k, dE)
        return F, J

    @classmethod
    def _param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta (n, 4), dr/d theta) of the thermal variant from its isothermal
        class's ``param_jacobian`` (None where that states none): the energy rows
        (2, 3) hold no parameter, and the flow law's row 1 is the isothermal one
        scaled by the upstream temperature's factor theta (sqrt(T_ref/T_up) on the
        mass flow, T_up/T_ref on the pressure drop), which no parameter moves;
        the rates (an inertial tube's) are the isothermal ones. The variant's
        ``param_jacobian`` (set by :func:`_two_port_variant`)."""
        base = cls.isothermal_class
        if "param_jacobian" not in base.__dict__:
            return None
        out = base.param_jacobian(P, V[:, _ISO_COLS], S, t, name)
        if out is None:
            return None
        dF_iso, dr = out
        dF = np.zeros((P.n, 4))
        dF[:, :2] = dF_iso
        mode = cls.flow_temperature
        if mode is not None:
            w, _ = _upwind_weight(V[:, 1], False)
            T_up = V[:, 6] + w * (V[:, 2] - V[:, 6])
            # a law of the upstream temperature itself (see _kernel_pressure_drop)
            derivative = (getattr(cls, "thermal_drop_parameter_derivative", None)
                          if cls.direct else None)
            law = None if derivative is None else derivative(P, V[:, _ISO_COLS], T_up, name)
            if law is not None:
                dF[:, 1] = -law
            else:
                dF[:, 1] *= (np.sqrt(P.T_ref / T_up) if mode == "sqrt_density"
                             else T_up / P.T_ref)
                rows = (None if cls.direct or mode == "sqrt_density"
                        else getattr(cls, "thermal_rows_parameter_derivative", None))
                own = None if rows is None else rows(P, V[:, _ISO_COLS], S, T_up, name)
                if own is not None:
                    mask, d = own
                    dF[:, 1] = np.where(mask, -d, dF[:, 1])
        return dF, dr

    @classmethod
    def _kernel_pressure_drop(cls, P, V, jac):
        """The same equations for a flow law given as p_a - p_b = dp(p_a, mf, p_b)
        (``pressure_drop`` of the isothermal class, scaled by theta = T_up/T_ref),
        without building the isothermal residual and Jacobian first: ~30 %
        fewer array operations, which is what small thermal scenes pay for."""
        if P.thermal_law is not None:
            return cls._compiled_kernel(P, V, jac)
        pa, mf, Ta, Ea, pb, Tb, Eb = V[:, 0], V[:, 1], V[:, 2], V[:, 3], V[:, 4], V[:, 6], V[:, 7]
        E, w, dw, dE, T_up = upwind_energy(P.fluid, mf, pa, Ta, pb, Tb, jac, P.h0)
        # a law of the upstream temperature itself (a gas tube's adiabatic pipe
        # flow), else the isothermal law scaled by theta = T_up/T_ref
        thermal_drop = getattr(cls, "thermal_drop", None)
        law = None if thermal_drop is None else thermal_drop(P, pa, mf, pb, T_up, jac)
        if law is None:
            dp, d_pa, d_mf, d_pb = cls.pressure_drop(P, pa, mf, pb, jac)
            theta = T_up * (1.0 / P.T_ref)
            d_T = dp * (1.0 / P.T_ref) if jac else None
        else:
            dp, d_pa, d_mf, d_pb, d_T = law
            theta = 1.0
        F = np.empty((P.n, 4))
        np.add(mf, V[:, 5], out=F[:, 0])
        np.subtract(pa - pb, theta * dp, out=F[:, 1])
        np.add(Ea, Eb, out=F[:, 2])
        np.subtract(Ea, E, out=F[:, 3])
        if not jac:
            return F, None
        # pattern: (0,mf_a) (0,mf_b) (1,pa) (1,mf) (1,pb) (1,Ta) (1,Tb), energy rows
        J = np.empty((P.n, len(cls.jac_pattern)))
        J[:, 0] = 1.0
        J[:, 1] = 1.0
        J[:, 2] = 1.0 - theta * d_pa
        coef = -d_T                                # dF1/dT_up
        J[:, 3] = (-theta * d_mf if isinstance(dw, float)      # plain upwind: dw = 0
                   else coef * dw * (Ta - Tb) - theta * d_mf)
        J[:, 4] = -1.0 - theta * d_pb
        cw = coef * w
        J[:, 5] = cw
        np.subtract(coef, cw, out=J[:, 6])
        _energy_columns(J, 7, dE)
        return F, J

    @classmethod
    def _compiled_kernel(cls, P, V, jac, S=None):
        """:meth:`residual` of an ideal gas's tube, Tesla valve, orifice or check
        valve, snapping valve (``P.thermal_law``; S its modes) in one compiled pass
        (softflow.laws.thermal)."""
        n, law = P.n, P.thermal_law
        F = np.empty((n, 4))
        J = np.empty((n, 13 if law == "check" else 15)) if jac else _NO_ENTRIES
        V = np.ascontiguousarray(V, dtype=float)
        ch = P.ideal[3] - P.h0
        laws = _thermal_laws()
        if law == "orifice":
            laws.orifice_residual(V, P.law, P.law_RT, P.law_rho, P.T, ISO_6358_RHO0, ISO_6358_T0,
                                  P.K, P.area, P.dp_small, P.gamma, P.Cd, P.C, P.b,
                                  P.subsonic_index, P.pr_laminar, P.T_ref, P.ideal[1], ch,
                                  UPWIND_BAND, ZERO_FLOW_CONDUCTANCE, F.reshape(-1),
                                  J.reshape(-1), jac)
        elif law == "check":
            laws.check_valve_residual(V, P.nozzle, P.law_RT, P.law_rho, P.K, P.Cd, P.gamma,
                                      P.area, P.dp_small, P.cracking_pressure, P.opening_band,
                                      P.leakage, P.ideal[1], ch, UPWIND_BAND,
                                      ZERO_FLOW_CONDUCTANCE, F.reshape(-1), J.reshape(-1), jac)
        elif law == "snapping":
            laws.snapping_residual(V, np.ascontiguousarray(S, dtype=float), P.kind, P.Re_lo,
                                   P.Re_hi, P.re_per_mf, P.c_mu, P.eD, P.friction_terms,
                                   P.area, P.kre, P.closed_conductance, P.law_RT, P.law_rho,
                                   P.R_gas, P.gamma, P.T_ref, P.ideal[1], ch, UPWIND_BAND,
                                   ZERO_FLOW_CONDUCTANCE, F.reshape(-1), J.reshape(-1), jac)
        elif law == "tube":
            laws.tube_residual(V, P.kind, P.Re_lo, P.Re_hi, P.re_per_mf, P.c_mu, P.eD,
                               P.kind_terms, P.area, P.kre, P.R_gas, P.gamma, P.ideal[1], ch,
                               UPWIND_BAND, ZERO_FLOW_CONDUCTANCE, F.reshape(-1),
                               J.reshape(-1), jac)
        else:
            laws.tesla_residual(V, P.kind, P.Re_lo, P.Re_hi, P.re_per_mf, P.c_mu, P.eD,
                                P.friction_terms, P.area, P.mf_blend, P.diodicity, P.R_gas,
                                P.gamma, P.ideal[1], ch, UPWIND_BAND, ZERO_FLOW_CONDUCTANCE,
                                F.reshape(-1), J.reshape(-1), jac)
        return F, (J if jac else None)


#: the entries' argument of a compiled pass evaluated without them
_NO_ENTRIES = np.empty((0, 15))


def _energy_columns(J, k, dE):
    """The energy rows' Jacobian columns of a two-port: (2,E_a) (2,E_b) and
    (3,p_a) (3,mf) (3,T_a) (3,E_a) (3,p_b) (3,T_b), from dE of upwind_energy."""
    d_mf, d_pa, d_Ta, d_pb, d_Tb = dE
    J[:, k] = 1.0
    J[:, k + 1] = 1.0
    J[:, k + 2] = -d_pa
    np.negative(d_mf, out=J[:, k + 3])
    np.negative(d_Ta, out=J[:, k + 4])
    J[:, k + 5] = 1.0
    J[:, k + 6] = -d_pb
    np.negative(d_Tb, out=J[:, k + 7])


def _switching_on_iso_columns(base):
    """A switching element's (a snapping valve's) ``switch``, ``switching`` and
    their Jacobians, and a piecewise law's ``regime`` and ``kinks`` (a check
    valve's), for its thermal variant: the isothermal law's, on the
    isothermal columns of V (in the thermal V, column 2 is T_a, not p_b)."""
    out = {}
    from .base import LibraryComponent
    if base.switch.__func__ is not LibraryComponent.switch.__func__:
        out["switch"] = classmethod(lambda cls, P, V, S: base.switch.__func__(
            cls, P, V[:, _ISO_COLS], S))
    if getattr(base, "switching", None) is not None:
        out["switching"] = classmethod(lambda cls, P, V, S: base.switching.__func__(
            cls, P, V[:, _ISO_COLS], S))
    if getattr(base, "switching_jacobian", None) is not None:
        def switching_jacobian(cls, P, V, S):
            GV_iso, GS = base.switching_jacobian.__func__(cls, P, V[:, _ISO_COLS], S)
            GV = np.zeros(GV_iso.shape[:2] + (V.shape[1],))
            GV[:, :, _ISO_COLS] = GV_iso
            return GV, GS
        out["switching_jacobian"] = classmethod(switching_jacobian)
    for name in ("regime", "kinks"):         # a check valve's pieces and kinks
        law = getattr(base, name, None)
        if law is not None:
            out[name] = classmethod(lambda cls, P, V, law=law: law.__func__(
                cls, P, V[:, _ISO_COLS]))
    if getattr(base, "switching_param_jacobian", None) is not None:
        out["switching_param_jacobian"] = classmethod(
            lambda cls, P, V, S, name: base.switching_param_jacobian.__func__(
                cls, P, V[:, _ISO_COLS], S, name))
    return out


def _two_port_variant(base, flow_temperature):
    iso_map = {0: 0, 1: 1, 2: 4, 3: 5}
    pattern = tuple((e, iso_map[v]) for e, v in base.jac_pattern)
    res_pattern = tuple((e, iso_map[v]) for e, v in base.residual_pattern)
    if flow_temperature is not None:
        assert base.jac_pattern == ((0, 1), (0, 3), (1, 0), (1, 1), (1, 2))
        assert base.residual_pattern == base.jac_pattern and not base.state_jac_pattern
        pattern += ((1, 2), (1, 6))
        res_pattern += ((1, 2), (1, 6))
    pattern += _ENERGY_PATTERN
    res_pattern += _ENERGY_PATTERN
    # a CircularTube-like law p_a - p_b = dp, without states: the direct kernel
    direct = (flow_temperature == "inverse_density" and hasattr(base, "pressure_drop")
              and not base.state_spec)
    return type(f"Thermal{base.__name__}", (ThermalTwoPort, base),
                {"flow_temperature": flow_temperature, "jac_pattern": pattern,
                 "residual_pattern": res_pattern,
                 "rate_pattern": tuple((st, iso_map[v]) for st, v in base.rate_pattern),
                 "direct": direct, "isothermal_class": base,
                 # its own (the sensitivities use only a class's own param_jacobian)
                 "param_jacobian": ThermalTwoPort.__dict__["_param_jacobian"],
                 **_switching_on_iso_columns(base),
                 "__doc__": f"{base.__name__} in a thermal scene (see softflow.components.thermal)."})


# ---------------------------------------------------------------------------------------
# sources: V = [p, mf, T, E]
# ---------------------------------------------------------------------------------------
def _source_energy(P, V, jac):
    """Residual E - (energy the flow carries) of a flow source, and its derivatives
    (p, mf, T, E). Outflow (mf < 0) carries h(p, T_source), inflow the node's h."""
    p, mf, T, E = V[:, 0], V[:, 1], V[:, 2], V[:, 3]
    Es, _, _, dE, _ = upwind_energy(P.fluid_thermal, mf, p, T, p, P.T_source, jac, P.h0)
    F = E - Es
    if not jac:
        return F, None
    d_mf, d_pa, d_Ta, d_pb, _ = dE
    return F, (-(d_pa + d_pb), -d_mf, -d_Ta, 1.0)


def _thermal_source_jacobian(P, name, dF0):
    """(dF/d theta (n, 2), dr/d theta (n, 0)) of a thermal source for its
    constant value ``name`` (row 0), None for other parameters."""
    if name != P.components[0].signal.name:
        return None
    dF = np.zeros((P.n, 2))
    dF[:, 0] = dF0
    return dF, np.zeros((P.n, 0))


class _ThermalSource:
    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.T_source = np.array([c._T_source for c in components], dtype=float)
        P.fluid_thermal = components[0]._thermal_fluid
        P.h0 = components[0]._h0
        P.ideal = ideal_gas_constants(P.fluid_thermal)
        return P

    @classmethod
    def _compiled_residual(cls, P, V, q, jac, volume):
        """A flow source's residual of an ideal gas in one compiled pass
        (:func:`softflow.laws.thermal.source_residual`)."""
        n = P.n
        F = np.empty((n, 2))
        J = np.empty((n, 7 if volume else 5)) if jac else _NO_ENTRIES
        R, cp, _, c = P.ideal
        _thermal_laws().source_residual(volume, np.ascontiguousarray(V, dtype=float),
                                        np.ascontiguousarray(np.broadcast_to(q, n), dtype=float),
                                        P.T_source, R, cp, c - P.h0, UPWIND_BAND,
                                        ZERO_FLOW_CONDUCTANCE, F.reshape(-1), J.reshape(-1),
                                        jac)
        return F, (J if jac else None)

    @classmethod
    def thermal_initial_states(cls, comp):
        return []


class ThermalPressureSource(_ThermalSource, PressureSource):
    """PressureSource in a thermal scene: a reservoir that also fixes its node's temperature."""

    jac_pattern = ((0, 0), (1, 2))

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.ones = np.ones((P.n, 2))     # the constant Jacobian (copied by the assembly)
        return P

    @classmethod
    def residual(cls, P, V, S, t, jac):
        F = np.empty((P.n, 2))
        F[:, 0] = V[:, 0] - P.values(t)
        F[:, 1] = V[:, 2] - P.T_source
        return F, (P.ones if jac else None)

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """dF/d pressure = (-1, 0): the temperature row holds no pressure."""
        return _thermal_source_jacobian(P, name, -1.0)


class ThermalMassFlowSource(_ThermalSource, MassFlowSource):
    """MassFlowSource in a thermal scene (delivers gas at its ``temperature``)."""

    jac_pattern = ((0, 1), (1, 0), (1, 1), (1, 2), (1, 3))

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if P.ideal is not None:
            return cls._compiled_residual(P, V, P.values(t), jac, False)
        F = np.empty((P.n, 2))
        F[:, 0] = V[:, 1] + P.values(t)
        F[:, 1], dE = _source_energy(P, V, jac)
        if not jac:
            return F, None
        J = np.empty((P.n, 5))
        J[:, 0] = 1.0
        _put(J, 1, dE)
        return F, J

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """dF/d massflow = (1, 0): the energy row reads the flow, not its setting."""
        return _thermal_source_jacobian(P, name, 1.0)


class ThermalVolumeFlowSource(_ThermalSource, VolumeFlowSource):
    """VolumeFlowSource in a thermal scene: the volume flow is measured at the
    temperature of the gas it moves (the source's when delivering, the node's
    when drawing)."""

    jac_pattern = ((0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2), (1, 3))

    @classmethod
    def residual(cls, P, V, S, t, jac):
        q = P.values(t)
        if P.ideal is not None:
            return cls._compiled_residual(P, V, q, jac, True)
        p, T = V[:, 0], V[:, 2]
        out = q >= 0
        T_q = np.where(out, P.T_source, T)
        fl = P.fluid_thermal
        F = np.empty((P.n, 2))
        F[:, 0] = V[:, 1] + fl.density(p, T_q) * q
        F[:, 1], dE = _source_energy(P, V, jac)
        if not jac:
            return F, None
        J = np.empty((P.n, 7))
        J[:, 0] = fl.density_dp(p, T_q) * q
        J[:, 1] = 1.0
        J[:, 2] = np.where(out, 0.0, fl.density_dT(p, T_q) * q)
        _put(J, 3, dE)
        return F, J

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """dF/d volumeflow = (rho(p, T_q), 0), T_q the source's temperature while it
        delivers, the node's while it draws."""
        q = P.values(t)
        T_q = np.where(q >= 0, P.T_source, V[:, 2])
        return _thermal_source_jacobian(P, name, P.fluid_thermal.density(V[:, 0], T_q))


# ---------------------------------------------------------------------------------------
# volumes (see the module docstring). A free volume (adiabatic or heat transfer):
# V = [p, mf, T, E, wall_heat], continuous states (mass, stored_energy); a volume
# held at its wall temperature: V = [p, mf, T, E], continuous state mass.
# ---------------------------------------------------------------------------------------
#: dm/dt = mf (V column 1), d(stored energy)/dt = E + Q (columns 3 and 4)
_FREE_RATE_PATTERN = ((0, 1), (1, 3), (1, 4))
#: rows: 0 the wall's law (mass), 1 the stored energy, 2 the wall heat
_FREE_RESIDUAL_PATTERN = ((0, 0), (0, 2), (1, 0), (1, 2), (2, 2), (2, 4))
_FREE_STATE_PATTERN = ((0, 0), (1, 0), (1, 1))
_FREE_PATTERN = _FREE_RESIDUAL_PATTERN + ((0, 1), (1, 1), (1, 3), (1, 4))
#: rows: 0 the wall's law (mass), 1 T = T_wall
_HELD_RESIDUAL_PATTERN = ((0, 0), (0, 2), (1, 2))
_HELD_PATTERN = _HELD_RESIDUAL_PATTERN + ((0, 1),)
#: the locals a free volume adds after its terminal variables: (label, quantity)
FREE_LOCALS = (("wall_heat", "heatflow"),)
#: wall kinds of softflow.laws.thermal.wall_law, and a hysteresis loop (loop_wall):
#: written out, so that making the Params does not import numba
_RIGID, _LINEAR, _CURVE, _LOOP = 0, 1, 2, 3
#: the arguments of a compiled pass that its wall or its evaluation does not use
_NO_FLOATS = np.empty(0)
_NO_TABLE = np.empty((0, 5))
_NO_VOLUME_ENTRIES = np.empty((0, 9))


class _ThermalVolume:
    """Shared parameters of thermal volumes: wall temperature, h·A (constant or
    from a correlation, frozen over each step), the scene's energy reference."""

    #: the locals (label, quantity) the volume adds in a thermal scene
    local_spec: tuple = ()

    @classmethod
    def fold_pressure(cls, P, V, S, k, rising):
        """The pressure volume ``k`` snaps to at a fold of its gas's mass
        (:func:`softflow.components.actuators.fold_pressure`), searched at the
        gas's present temperature, or nan (no curve wall, no fold near). For a
        free gas (adiabatic, wall heat) it is the start of the jump, not its
        end: the snap holds the mass and the stored energy (the gas's and the
        wall's work), and Newton, with the states held, then finds the
        temperature and the volume that hold both (softflow.solve.bdf)."""
        curve = getattr(cls, "_fold_curve", None)
        if curve is None:
            return np.nan
        from .actuators import fold_pressure
        T = float(V[k, 2])
        m = float(S[k, 0])

        def density(p):
            return _parts(P.fluid, "density", p, np.full_like(p, T), False)[0]
        vol = m / float(density(np.array([float(V[k, 0])]))[0])
        return fold_pressure(lambda v: curve(P, v, S, k), density, vol, m, rising)

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.hA = np.array([c._hA for c in components], dtype=float)
        P.T_wall = np.array([c._T_wall for c in components], dtype=float)
        # volumes whose h comes from a correlation (FreeConvection): h·A is set at
        # the start of every step by begin_step
        corr = [i for i, c in enumerate(components) if c._h_corr is not None]
        P.corr_idx = np.array(corr, dtype=np.int64)
        if corr:
            cs = [components[i] for i in corr]
            try:
                P.fluid.conductivity(pressure_atmospheric)
            except NotImplementedError as err:
                raise ValueError(f"{cs[0].describe()}: heat_transfer_coefficient="
                                 f"{cs[0]._h_corr!r} needs the fluid's thermal conductivity: "
                                 f"{err}") from None
            P.corr = [c._h_corr for c in cs]
            P.corr_area = np.array([c.area for c in cs])
            P.corr_length = np.array([c._h_corr.characteristic_length(initial_fluid_volume(c))
                                      for c in cs])
        P.any_heat = bool(P.hA.any()) or bool(corr)   # adiabatic volumes skip the wall terms
        P.h0 = components[0]._h0
        # an ideal gas behind a wall the compiled laws know: one compiled pass
        # (softflow.laws.thermal.volume_residual)
        P.ideal = ideal_gas_constants(P.fluid)
        P.wall = None
        # (each wall's _compiled_wall: (wall kind, its constants per instance, a
        # list of arrays or floats, its PVCurves, a loop's floats) for
        # softflow.laws.thermal, or None where it is not one it knows)
        compiled_wall = getattr(cls, "_compiled_wall", None)
        if P.ideal is not None and compiled_wall is not None:
            wall = compiled_wall(P)
            if wall is not None:
                kind, per, curves, extra = wall
                per = (np.ascontiguousarray(np.column_stack(
                    [np.broadcast_to(np.asarray(a, dtype=float), P.n) for a in per]))
                    if per else np.zeros((P.n, 0)))
                tables = tuple((c._knots, c._table, np.ascontiguousarray(c._w0, dtype=float),
                                int(c._mode)) for c in curves)
                P.wall = (kind, per.reshape(-1), per.shape[1], tables, tuple(extra),
                          bool(getattr(P, "scaled", False)))
        return P

    @classmethod
    def _compiled_residual(cls, P, V, S, jac, free):
        """The residual of :meth:`_Free.residual` (``free``) or
        :meth:`_Held.residual` in one compiled pass, or None where a curve
        refuses a volume (the NumPy code then raises the curve's error)."""
        wall, fl, k, tables, extra, scaled = P.wall
        R, _, cv, c = P.ideal
        F = np.empty((P.n, 3 if free else 2))
        J = np.empty((P.n, 9 if free else 4)) if jac else _NO_VOLUME_ENTRIES
        laws = _thermal_laws()
        if wall == _LOOP:
            (ku, tu, wu, mu), (kd, td, wd, md) = tables
            refused = laws.loop_residual(free, V, S, R, cv, c, P.h0, P.hA, P.T_wall, P.any_heat,
                                         ku, tu, wu, mu, kd, td, wd, md, *extra, F, J, jac)
        else:
            knots, table, w0, mode = tables[0] if tables else (_NO_FLOATS, _NO_TABLE,
                                                               _NO_FLOATS, 0)
            refused = laws.volume_residual(wall, free, V, S, R, cv, c, P.h0, P.hA, P.T_wall,
                                           P.any_heat, fl, k, knots, table, w0, mode, scaled,
                                           pressure_atmospheric, F, J, jac)
        if refused >= 0:
            return None
        return F, (J if jac else None)

    @classmethod
    def wants_begin_step(cls, P):
        return P.corr_idx.size > 0

    @classmethod
    def begin_step(cls, P, V, S):
        """Freeze the correlation volumes' h·A at the state where the step starts."""
        i = P.corr_idx
        P.hA[i] = wall_hA(P.fluid, P.corr, P.corr_area, P.corr_length,
                          V[i, 0], V[i, 2], P.T_wall[i])

    @classmethod
    def _initial_mass_energy(cls, comp):
        fl, p0, T0 = comp.fluid, comp.initial_pressure, comp._T_initial
        m0 = float(fl.density(p0, T0)) * initial_fluid_volume(comp)
        # u as the kernels evaluate it (an equilibrium volume starts at rest exactly)
        u0 = _parts(fl, "internal_energy", np.array([p0]), np.array([T0]), False)[0]
        return m0, m0 * (float(u0[0]) - comp._h0)


class _Free(_ThermalVolume):
    """Rate form of a volume whose gas temperature is free (adiabatic, or with wall
    heat transfer): rates dm/dt = mdot, dE_s/dt = E + Q; residuals: the wall's
    law (:meth:`_wall`), E_s = m (u(p, T) - h0) + W, Q = hA (T_wall - T)."""

    local_spec: tuple = FREE_LOCALS
    jac_pattern: tuple = _FREE_PATTERN
    residual_pattern: tuple | None = _FREE_RESIDUAL_PATTERN
    state_jac_pattern: tuple = _FREE_STATE_PATTERN
    rate_pattern: tuple = _FREE_RATE_PATTERN

    @classmethod
    def thermal_initial_states(cls, comp):
        return list(cls._initial_mass_energy(comp))

    @classmethod
    def rates(cls, P, V, S, jac):
        R = np.empty((P.n, 2))
        R[:, 0] = V[:, 1]
        np.add(V[:, 3], V[:, 4], out=R[:, 1])
        return R, ((1.0, 1.0, 1.0) if jac else None)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if P.wall is not None:
            out = cls._compiled_residual(P, V, S, jac, True)
            if out is not None:
                return out
        p, T = V[:, 0], V[:, 2]
        m = S[:, 0]
        F0, d0, dvol, W, p_wall = cls._wall(P, p, T, S, jac)
        u, u_p, u_T = _parts(P.fluid, "internal_energy", p, T, jac)
        u = u - P.h0
        F = np.empty((P.n, 3))
        F[:, 0] = F0
        F[:, 1] = m * u + W - S[:, 1]
        if P.any_heat:
            F[:, 2] = V[:, 4] - P.hA * (P.T_wall - T)
        else:
            F[:, 2] = V[:, 4]
        if not jac:
            return F, None
        J = np.empty((P.n, 9))
        J[:, 0], J[:, 1] = d0[0], d0[1]
        J[:, 2] = m * u_p + p_wall * dvol[0]
        J[:, 3] = m * u_T + p_wall * dvol[1]
        J[:, 4] = P.hA
        J[:, 5] = 1.0
        J[:, 6] = d0[2]
        J[:, 7] = u + p_wall * dvol[2]
        J[:, 8] = -1.0
        return F, J


class _Held(_ThermalVolume):
    """Rate form of a volume held at its wall temperature (``thermal='isothermal'``
    in a thermal scene): dm/dt = mdot; residuals: the wall's law, T = T_wall.
    The energy the flows carry in or out is whatever arrives: the wall takes up
    the difference as heat."""

    jac_pattern: tuple = _HELD_PATTERN
    residual_pattern: tuple | None = _HELD_RESIDUAL_PATTERN
    state_jac_pattern: tuple = ((0, 0),)
    rate_pattern: tuple = MASS_RATE_PATTERN

    @classmethod
    def thermal_initial_states(cls, comp):
        return [cls._initial_mass_energy(comp)[0]]

    @classmethod
    def rates(cls, P, V, S, jac):
        return mass_rates(P, V, jac)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if P.wall is not None:
            out = cls._compiled_residual(P, V, S, jac, False)
            if out is not None:
                return out
        p, T = V[:, 0], V[:, 2]
        F0, d0, _, _, _ = cls._wall(P, p, T, S, jac, work=False)
        F = np.empty((P.n, 2))
        F[:, 0] = F0
        F[:, 1] = T - P.T_wall
        if not jac:
            return F, None
        J = np.empty((P.n, 4))
        J[:, 0], J[:, 1], J[:, 2], J[:, 3] = d0[0], d0[1], 1.0, d0[2]
        return F, J


# The walls: _wall(P, p, T, S, jac, work=True) -> (F0, (dF0/dp, dF0/dT, dF0/dm), (dvol/dp,
# dvol/dT, dvol/dm), W, p_wall): the residual of the wall's law at the stored mass
# m = S[:, 0], the work W the gas has done on the wall since t = 0 and the wall's
# pressure p_wall = dW/dvol (derivatives None without jac; W, p_wall 0 for a rigid
# wall or without work). For an ideal gas, _compiled_wall says how the compiled
# laws (softflow.laws.thermal) evaluate the same wall, where they know it.
class _RigidWall:
    @classmethod
    def _compiled_wall(cls, P):
        return _RIGID, [P.volume], (), ()

    @classmethod
    def _wall(cls, P, p, T, S, jac, work=True):
        rho, rho_p, rho_T = _parts(P.fluid, "density", p, T, jac)
        F0 = rho * P.volume - S[:, 0]
        if not jac:
            return F0, None, None, 0.0, 0.0
        return F0, (rho_p * P.volume, rho_T * P.volume, -1.0), (0.0, 0.0, 0.0), 0.0, 0.0


class _LinearWall:
    """vol = volume + compliance (p - p_ref); the wall's pressure is p itself, so
    W = compliance ((p - p_ref)^2 - (p_0 - p_ref)^2) / 2 + p_ref (vol - vol_0)."""

    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.p_initial = np.array([c.initial_pressure for c in components], dtype=float)
        return P

    @classmethod
    def _compiled_wall(cls, P):
        return _LINEAR, [P.volume, P.compliance, P.reference_pressure, P.p_initial], (), ()

    @classmethod
    def _wall(cls, P, p, T, S, jac, work=True):
        rho, rho_p, rho_T = _parts(P.fluid, "density", p, T, jac)
        C, p_ref = P.compliance, P.reference_pressure
        vol = accumulator_volume(P, p)
        F0 = rho * vol - S[:, 0]
        W = 0.0
        if work:
            g, g0 = p - p_ref, P.p_initial - p_ref
            W = C * (0.5 * (g * g - g0 * g0) + p_ref * (g - g0))
        if not jac:
            return F0, None, None, W, p
        return F0, (rho_p * vol + rho * C, rho_T * vol, -1.0), (C, 0.0, 0.0), W, p


class _CurveWall:
    """vol = m / rho(p, T), p = p_curve(vol); W = the curve's work from the initial
    volume. Subclasses give the curve (:meth:`_curve`) and its work (:meth:`_work`)."""

    @classmethod
    def _wall(cls, P, p, T, S, jac, work=True):
        rho, rho_p, rho_T = _parts(P.fluid, "density", p, T, jac)
        vol = S[:, 0] / rho
        pc, dpc = cls._curve(P, vol, S, jac)
        F0 = p - pc
        W = cls._work(P, vol, S) if work else 0.0
        if not jac:
            return F0, None, None, W, pc
        dvol = (-vol * rho_p / rho, -vol * rho_T / rho, 1.0 / rho)
        return F0, (1.0 - dpc * dvol[0], -dpc * dvol[1], -dpc * dvol[2]), dvol, W, pc


class _PlainCurve(_CurveWall):
    @classmethod
    def make_params(cls, components):
        P = super().make_params(components)
        P.work0 = cls._curve_work(P, np.array([c.initial_volume for c in components]))
        return P

    @classmethod
    def _compiled_wall(cls, P):
        from ..curves.pvcurve import PVCurve
        from .actuators import compiled_curve
        curve = P.components[0].curve
        if (not compiled_curve(curve) or type(curve).work is not PVCurve.work
                or cls._curve.__func__ is not _PlainCurve._curve.__func__
                or cls.curve_pressure is not Actuator.curve_pressure):
            return None
        return _CURVE, [P.pressure_scale, P.work0], (curve,), ()

    @classmethod
    def _curve(cls, P, vol, S, jac):
        return Actuator.curve_pressure(P, vol, jac)

    @classmethod
    def _curve_work(cls, P, vol):
        """The integral of the (scaled) curve pressure over volume, up to a constant."""
        w = P.curve.work(vol)
        if P.scaled:
            base = pressure_atmospheric * vol
            w = base + P.pressure_scale * (w - base)
        return w

    @classmethod
    def _work(cls, P, vol, S):
        return cls._curve_work(P, vol) - P.work0


class _LoopCurve(_CurveWall):
    """A hysteresis loop: the branch the step started on (discrete state ``branch``,
    1 = inflation; the loop hands over to the other branch past its end)."""

    @classmethod
    def _compiled_wall(cls, P):
        from ..curves.hysteresis import HysteresisLoop
        from ..curves.pvcurve import PVCurve
        loop = P.loop
        if (not P.compiled or type(loop).work is not HysteresisLoop.work
                or any(type(c).work is not PVCurve.work for c in (loop.inflation, loop.deflation))
                or cls._curve.__func__ is not _LoopCurve._curve.__func__
                or cls._work.__func__ is not _LoopCurve._work.__func__):
            return None
        return (_LOOP, [], (loop.inflation, loop.deflation),
                (loop.volume_high, loop.volume_low, *loop._work_shifts))

    @classmethod
    def _curve(cls, P, vol, S, jac):
        pc, dpc = P.loop.fdf_volume(vol, S[:, cls._branch] > 0.5)
        return pc, (dpc if jac else None)

    @classmethod
    def _work(cls, P, vol, S):
        # the loop's work along the step's branch, less its value at t = 0 carried
        # over every change of branch (the discrete state work_offset)
        return P.loop.work(vol, S[:, 2] > 0.5) - S[:, 3]

    @staticmethod
    def _gas_volume(P, V, S):
        """The gas volume m / rho(p, T) of the stored mass S[:, 0]."""
        return S[:, 0] / P.fluid.density(V[:, 0], V[:, 2])

    @classmethod
    def switching(cls, P, V, S):
        """The loop's switching function (:meth:`HysteresisLoop.switching`), for
        every discrete state (the work offset changes with the branch)."""
        g = P.loop.switching(cls._gas_volume(P, V, S), S[:, cls._branch] > 0.5)
        return np.repeat(g[:, None], len(cls.discrete_states), axis=1)

    @classmethod
    def switching_jacobian(cls, P, V, S):
        """d(switching)/dV and d/dS of :meth:`switching` (every column alike): the
        branch's sign times the gas volume's derivatives, vol = m / rho(p, T)."""
        p, T = V[:, 0], V[:, 2]
        rho = P.fluid.density(p, T)
        vol = S[:, 0] / rho
        sign = np.where(S[:, cls._branch] > 0.5, 1.0, -1.0)
        m = len(cls.discrete_states)
        GV = np.zeros((P.n, m, V.shape[1]))
        GV[:, :, 0] = (-sign * vol * P.fluid.density_dp(p, T) / rho)[:, None]
        GV[:, :, 2] = (-sign * vol * P.fluid.density_dT(p, T) / rho)[:, None]
        GS = np.zeros((P.n, m, S.shape[1]))
        GS[:, :, 0] = (sign / rho)[:, None]
        return GV, GS

    @classmethod
    def switching_param_jacobian(cls, P, V, S, name):
        """0: the loop's limits are not numeric parameters."""
        return np.zeros((P.n, len(cls.discrete_states)))

    @classmethod
    def switch(cls, P, V, S):
        vol = cls._gas_volume(P, V, S)
        old = S[:, cls._branch] > 0.5
        new = P.loop.next_inflating(vol, old)
        if cls._branch == 1:                  # held: the branch alone
            return new[:, None].astype(float)
        # the stored energy stays: the new branch's work is counted from where the
        # old one ended (the loop's area goes to the wall, out of the gas's energy)
        offset = S[:, 3] + P.loop.work(vol, new) - P.loop.work(vol, old)
        return np.column_stack([new.astype(float), offset])


# -- parameter derivatives of the volumes (the sensitivities' param_jacobian) ----------
# Each wall states d(wall law)/d theta and d(work W)/d theta (:meth:`_wall_param`),
# from the isothermal class's own volume law (volume_jacobian, scale_jacobian) and its
# initial point's derivatives (_initial_point_jacobian: how theta moves p0 and V0).

#: Parameters of a volume's thermal model: they do not move its initial pressure or
#: volume (initial_temperature moves its initial mass and energy through rho(p0, T0)).
_THERMAL_PARAMETERS = ("initial_temperature", "wall_temperature", "hA",
                       "heat_transfer_coefficient", "area")


def _first(x):
    return float(np.asarray(x, dtype=float).ravel()[0])


def _initial_points(P, name):
    """Per instance: (dp0/d theta, dV0/d theta, p0, V0) arrays (n,) from the isothermal
    class's ``_initial_point_jacobian`` (0 for the thermal model's parameters), or
    None where it states none."""
    seen = {}
    for c in P.components:
        if id(c) not in seen:
            d = (0.0, 0.0) if name in _THERMAL_PARAMETERS else c._initial_point_jacobian(name)
            if d is None:
                return None
            seen[id(c)] = (d[0], d[1], c.initial_pressure, initial_fluid_volume(c))
    return np.array([seen[id(c)] for c in P.components], dtype=float).T


def _rigid_wall_param(cls, P, p, T, S, name, d0):
    """rho(p, T)·d(volume)/d theta of the law rho(p, T) vol - m (the isothermal
    class's ``volume_jacobian``); no work."""
    dvol = cls.volume_jacobian(P, p).get(name)
    if dvol is None:
        return 0.0, 0.0
    return _parts(P.fluid, "density", p, T, False)[0] * dvol, 0.0


def _linear_wall_param(cls, P, p, T, S, name, d0):
    """As the rigid wall's, and W = compliance (p^2 - p_0^2)/2: d/d compliance =
    W/compliance, and -compliance p_0 dp_0/d theta."""
    dF0 = _rigid_wall_param(cls, P, p, T, S, name, d0)[0]
    p_i = P.p_initial
    dW = -P.compliance * p_i * d0[0]
    if name == "compliance":
        dW = dW + 0.5 * (p * p - p_i * p_i)
    return dF0, dW


def _plain_curve_param(cls, P, p, T, S, name, d0):
    """p - (p_atm + s (curve(vol) - p_atm)) with vol = m / rho(p, T): the isothermal
    class's ``scale_jacobian``; W = work(vol) - work(v0) of the scaled curve: d/ds =
    the unscaled gauge work between v0 and vol, and -p0 dv0/d theta."""
    dW = -d0[2] * d0[1]
    if name != "pressure_scale":
        return 0.0, dW
    vol = S[:, 0] / _parts(P.fluid, "density", p, T, False)[0]
    v0 = d0[3]
    gauge = (P.curve.work(vol) - pressure_atmospheric * vol) - (
        P.curve.work(v0) - pressure_atmospheric * v0)
    return Actuator.scale_jacobian(P, vol), dW + gauge


def _loop_curve_param(cls, P, p, T, S, name, d0):
    """The loop's law has no numeric parameter; W = work(vol) - work_offset, the
    offset carrying the loop's work at v0 (its changes of branch fall at the
    loop's fixed limits): -p0 dv0/d theta."""
    return 0.0, -d0[2] * d0[1]


for _wall, _param in ((_RigidWall, _rigid_wall_param), (_LinearWall, _linear_wall_param),
                      (_PlainCurve, _plain_curve_param), (_LoopCurve, _loop_curve_param)):
    setattr(_wall, "_wall_param", classmethod(_param))


def _volume_param_jacobian(cls, P, V, S, t, name):
    """(dF/d theta, dr/d theta) of a thermal volume (rates: none): the wall's law and
    work (:meth:`_wall_param`) for the isothermal class's parameters (volume,
    compliance, reference/initial pressure, initial volume, pressure_scale,
    meet_tolerance); wall_temperature, hA and a constant heat_transfer_coefficient
    / area in Q - hA (T_wall - T) (a held volume: T - T_wall); initial_temperature
    0 (it sets the initial states only). None for an area with a heat-transfer
    correlation (h set each step: finite differences) and for other names."""
    free = issubclass(cls, _Free)
    n = P.n
    dF = np.zeros((n, 3 if free else 2))
    dr = np.zeros((n, 2 if free else 1))
    p, T = V[:, 0], V[:, 2]
    if name in _THERMAL_PARAMETERS:
        if name == "initial_temperature" or not free and name != "wall_temperature":
            return dF, dr
        if name == "wall_temperature":
            dF[:, 2 if free else 1] = -P.hA if free else -1.0
            return dF, dr
        if name == "area" and P.corr_idx.size:
            return None
        gap = P.T_wall - T
        if name == "hA":
            dF[:, 2] = -gap
        else:
            area = np.array([c.area if c.area is not None else np.nan for c in P.components])
            dF[:, 2] = -gap * (area if name == "heat_transfer_coefficient" else P.hA / area)
        return dF, dr
    d0 = _initial_points(P, name)
    if d0 is None:
        return None
    dF0, dW = cls._wall_param(P, p, T, S, name, d0)
    dF[:, 0] = dF0
    if free:
        dF[:, 1] = dW
    return dF, dr


def _volume_initial_state_jacobian(cls, comp, name):
    """d(initial states)/d theta of a thermal volume: m0 = rho(p0, T0)·V0 and
    E_s0 = m0 (u(p0, T0) - h0) with p0, V0 moved as the isothermal class's
    ``_initial_point_jacobian`` says and T0 by initial_temperature; discrete
    states 0 (a hysteretic volume's work offset: see :func:`_loop_curve_param`);
    None where the isothermal class states none."""
    dT = 1.0 if name == "initial_temperature" else 0.0
    d = (0.0, 0.0) if name in _THERMAL_PARAMETERS else comp._initial_point_jacobian(name)
    if d is None:
        return None
    p0, T0 = np.array([comp.initial_pressure]), np.array([comp._T_initial])
    V0 = initial_fluid_volume(comp)
    rho, rho_p, rho_T = (_first(a) for a in _parts(comp.fluid, "density", p0, T0, True))
    u, u_p, u_T = (_first(a) for a in _parts(comp.fluid, "internal_energy", p0, T0, True))
    dm = (rho_p * d[0] + rho_T * dT) * V0 + rho * d[1]
    dU = dm * (u - comp._h0) + rho * V0 * (u_p * d[0] + u_T * dT)
    rows = {"mass": dm, "stored_energy": dU}
    return [rows.get(label, 0.0) for label, _ in cls.state_spec]


class ThermalContainer(_Free, _RigidWall, Container):
    """Container in a thermal scene (rigid: no work)."""

    state_spec = (("mass", "mass"), ("stored_energy", "energy"))


class HeldContainer(_Held, _RigidWall, Container):
    """Container held at its wall temperature in a thermal scene."""

    state_spec = (("mass", "mass"),)


class ThermalLinearAccumulator(_Free, _LinearWall, LinearAccumulator):
    """LinearAccumulator in a thermal scene: the gas does work p·dV on the wall."""

    state_spec = (("mass", "mass"), ("stored_energy", "energy"))


class HeldLinearAccumulator(_Held, _LinearWall, LinearAccumulator):
    """LinearAccumulator held at its wall temperature in a thermal scene."""

    state_spec = (("mass", "mass"),)


class ThermalActuator(_Free, _PlainCurve, Actuator):
    """Actuator in a thermal scene: vol = m / rho(p, T), p = curve(vol), work p·dV."""

    state_spec = (("mass", "mass"), ("stored_energy", "energy"))


class HeldActuator(_Held, _PlainCurve, Actuator):
    """Actuator held at its wall temperature in a thermal scene."""

    state_spec = (("mass", "mass"),)


class ThermalHystereticActuator(_Free, _LoopCurve, HystereticActuator):
    """HystereticActuator in a thermal scene: as :class:`ThermalActuator` on the
    branch the step started on (discrete state ``branch``, 1 = inflation); the
    branch switches between steps from the converged volume, as in the
    isothermal kernel. The work the gas does is counted along the loop; at a
    change of branch the discrete state ``work_offset`` moves the new branch's
    count to where the old one ended, so the stored energy never jumps."""

    state_spec = (("mass", "mass"), ("stored_energy", "energy"), ("branch", "dimensionless"),
                  ("work_offset", "energy"))
    discrete_states: tuple = ("branch", "work_offset")
    _branch = 2

    @classmethod
    def thermal_initial_states(cls, comp):
        m0, U0 = cls._initial_mass_energy(comp)
        inflating = np.array([comp.initial_branch > 0.5])
        w0 = float(comp.loop.work(np.array([comp.initial_volume]), inflating)[0])
        return [m0, U0, comp.initial_branch, w0]


class HeldHystereticActuator(_Held, _LoopCurve, HystereticActuator):
    """HystereticActuator held at its wall temperature in a thermal scene."""

    state_spec = (("mass", "mass"), ("branch", "dimensionless"))
    _branch = 1

    @classmethod
    def thermal_initial_states(cls, comp):
        return [cls._initial_mass_energy(comp)[0], comp.initial_branch]


for _cls in (ThermalContainer, HeldContainer, ThermalLinearAccumulator, HeldLinearAccumulator,
             ThermalActuator, HeldActuator, ThermalHystereticActuator,
             HeldHystereticActuator):
    # each class's own (the sensitivities use only a class's own param_jacobian)
    setattr(_cls, "param_jacobian", classmethod(_volume_param_jacobian))
    setattr(_cls, "thermal_initial_state_jacobian",
            classmethod(_volume_initial_state_jacobian))


def initial_fluid_volume(comp):
    """Gas volume of a volume component at t = 0 [m^3]."""
    if isinstance(comp, Container):
        return comp.volume
    if isinstance(comp, LinearAccumulator):
        return comp._fluid_volume(comp.initial_pressure)
    return comp.initial_volume


def volume_outputs(comp):
    """Derived results of a thermal volume ``comp`` (compiled in a thermal scene):
    ``volume`` [m^3], ``internal_energy`` m (u(p, T) - h0) [J] and, for a free
    deformable one, ``wall_work`` [J], the work its gas has done on the wall
    since t = 0 (stored_energy - internal_energy)."""
    fl, h0 = comp.fluid, comp._h0

    def internal_energy(get):
        return get("mass") * (fl.internal_energy(get("pressure"), get("temperature")) - h0)

    if isinstance(comp, Container):
        vol = comp.volume

        def volume(get):
            return np.full(np.shape(get("mass")), vol)
    elif isinstance(comp, LinearAccumulator):
        def volume(get):
            return comp._fluid_volume(get("pressure"))
    else:
        def volume(get):
            return get("mass") / fl.density(get("pressure"), get("temperature"))
    out = {"volume": ("volume", volume), "internal_energy": ("energy", internal_energy)}
    if comp._thermal != "isothermal" and not isinstance(comp, Container):
        out["wall_work"] = ("energy", lambda get: get("stored_energy") - internal_energy(get))
    return out


# ---------------------------------------------------------------------------------------
_FLOW_ELEMENTS = {
    Orifice: "sqrt_density",
    CircularTube: "inverse_density",
    TeslaValve: "inverse_density",
    SnappingValve: "inverse_density",
    InertialCircularTube: None,
    CheckValve: None,
}
THERMAL_CLASSES = {cls: _two_port_variant(cls, ft) for cls, ft in _FLOW_ELEMENTS.items()}
for _cls in THERMAL_CLASSES.values():
    _cls.thermal_initial_states = classmethod(
        lambda cls, comp: list(comp.initial_states()))
THERMAL_CLASSES.update({
    PressureSource: ThermalPressureSource, MassFlowSource: ThermalMassFlowSource,
    VolumeFlowSource: ThermalVolumeFlowSource, Container: ThermalContainer,
    LinearAccumulator: ThermalLinearAccumulator, Actuator: ThermalActuator,
    HystereticActuator: ThermalHystereticActuator,
})
#: Volumes held at their wall temperature (``thermal='isothermal'`` in a thermal scene).
HELD_CLASSES = {
    Container: HeldContainer, LinearAccumulator: HeldLinearAccumulator,
    Actuator: HeldActuator, HystereticActuator: HeldHystereticActuator,
}
#: Classes that store gas (take initial_temperature, wall heat transfer).
VOLUME_CLASSES = (Container, LinearAccumulator, Actuator, HystereticActuator)
SOURCE_CLASSES = (PressureSource, MassFlowSource, VolumeFlowSource)


def thermal_class(cls, held=False):
    """The thermal variant of a library class (KeyError naming it if there is none);
    ``held``: a volume's variant held at its wall temperature."""
    if held and cls in HELD_CLASSES:
        return HELD_CLASSES[cls]
    try:
        return THERMAL_CLASSES[cls]
    except KeyError:
        raise KeyError(f"{cls.__name__} has no thermal model yet; thermal scenes support "
                       f"{', '.join(sorted(c.__name__ for c in THERMAL_CLASSES))}") from None
