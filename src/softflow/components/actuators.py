"""Inflatable actuators: a chamber whose volume follows a pressure–volume curve.

Unknowns of an actuator: the terminal's pressure p and mass flow mf; state:
the stored fluid mass m, with dm/dt = mf. The mass and the density give the
volume, and the curve gives the pressure from it:

    V = m / rho(p),    residual  p - p_curve(V) = 0

(with an incompressible fluid V depends on mf alone). The pressure is
computed from the volume, never the volume from the pressure: p(V) is a
function for every curve, V(p) is not for a peak–valley curve, so this form
stays single-valued and differentiable through the curve's negative-stiffness
part. It is the FONS paper's own user actuator (``p - pvcurve(mass / rho)``),
with an analytic Jacobian. Keeping the volume as an extra unknown was tried
first and dropped: that row is dominated by dp/dV ~ 1e10 Pa/m^3, so Newton's
row-scaled line search hardly saw the pressure error, and it failed to start
a tube-fed actuator 800 Pa away from its source, which this form solves.
"""
from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..constants import pressure_atmospheric
from ..curves.hysteresis import HysteresisLoop
from ..curves.pvcurve import CurveRangeError, PVCurve
from ..fluids.base import FluidError
from ..solve.thermal import THERMAL_VOLUME_DOC, thermal_volume_fields
from ..solve.validity import ValidityRecord, _curves_of
from .base import FLUID_PORT, LibraryComponent, Params
from .chambers import (MASS_RATE_PATTERN, _given, given_densities, initial_mass_jacobian,
                       mass_rates, set_fluid_law, volume_laws)

if TYPE_CHECKING:
    from .._typing import Curve, HeatTransfer, Scalar
    from ..fluids.base import Fluid

#: Relative step of the central differences used for a callable curve without
#: a derivative: h = FD_STEP * max(|V|, initial volume).
FD_STEP = 1e-6

ACTUATOR_PATTERN = ((0, 0), (0, 1))
#: the residual itself depends on p (and on the mass, ACTUATOR_STATE_PATTERN)
ACTUATOR_RESIDUAL_PATTERN = ((0, 0),)
ACTUATOR_STATE_PATTERN = ((0, 0),)


class _CurveFunction:
    """p(V) [Pa] and dp/dV [Pa/m^3] of volume arrays, whatever form the curve came in."""

    def __init__(self, curve, derivative, volume_scale, owner):
        self._args = (curve, derivative, volume_scale, owner)
        if hasattr(curve, "fdf_volume"):
            if derivative is not None:
                raise ValueError(f"{owner}: curve_derivative is only for a callable curve; "
                                 f"{curve!r} gives its own derivative (fdf_volume)")
            self.fdf = curve.fdf_volume
            self.value = lambda v: curve.fdf_volume(v)[0]
            self.user = None
            self.work = getattr(curve, "work", self._quadrature)
            self.v_ref = volume_scale
            return
        if derivative is not None and not callable(derivative):
            raise TypeError(f"{owner}: curve_derivative must be a callable V [m^3] -> dp/dV "
                            f"[Pa/m^3], got {derivative!r}")
        self.user = curve      # a user's function: its failures name the actuator
        self.h_floor = FD_STEP * volume_scale
        self.work = self._quadrature
        self.v_ref = volume_scale
        self.value = _vectorized(curve, volume_scale, owner, "curve")
        if derivative is not None:
            d = _vectorized(derivative, volume_scale, owner, "curve_derivative")
            self.fdf = lambda v: (self.value(v), d(v))
        else:
            self.fdf = self._central_differences

    def __getstate__(self):
        # the bound lambdas do not pickle: keep the definition, rebuild on load
        return self._args

    def __setstate__(self, args):
        self.__init__(*args)

    def _quadrature(self, v):
        """Integral of p(V) from the initial volume to ``v`` [J]: Gauss-Legendre
        with :data:`WORK_NODES` points (exact for polynomial curves of degree up to
        2 WORK_NODES - 1), for curves that do not integrate themselves."""
        x, w = _gauss_legendre()
        half = (np.asarray(v, dtype=float) - self.v_ref) / 2
        nodes = (self.v_ref + half)[:, None] + half[:, None] * x
        return half * (self.value(nodes.ravel()).reshape(nodes.shape) @ w)

    def _central_differences(self, v):
        h = np.maximum(FD_STEP * np.abs(v), self.h_floor)
        return self.value(v), (self.value(v + h) - self.value(v - h)) / (2 * h)


#: Gauss-Legendre points of the work integral of a curve given as a function.
WORK_NODES = 16


@functools.lru_cache(maxsize=1)
def _gauss_legendre():
    return np.polynomial.legendre.leggauss(WORK_NODES)


def _vectorized(func, v0, owner, name):
    """``func`` as array -> array, checked once at the initial volume."""
    try:
        out = np.asarray(func(np.array([v0, v0])), dtype=float)
        array_ok = out.shape == (2,)
    except Exception:                      # a scalar-only function (math.*, if-branches)
        array_ok = False
    try:
        p0 = float(func(float(v0)))
    except Exception as err:
        raise ValueError(f"{owner}: {name}({v0:.6g} m^3) failed: {err}") from err
    if not np.isfinite(p0):
        raise ValueError(f"{owner}: {name}({v0:.6g} m^3) returned {p0}; expected a finite "
                         "number in SI units")
    if array_ok:
        return lambda v: np.asarray(func(v), dtype=float)
    return lambda v: np.array([float(func(float(x))) for x in v])


class Actuator(LibraryComponent):
    """Inflatable actuator with a pressure–volume curve, terminal ``a``.

    The fluid volume V = m / rho(p) of the stored mass m (state) sets the
    absolute pressure p = curve(V). Results: ``pressure``, ``massflow``, the
    state ``mass`` and the output ``volume`` [m^3]. Filled with a gas, where
    the curve falls more steeply than the gas expands, the mass it holds
    folds: the adaptive BDF snaps it there to the far volume that holds the
    same mass (:meth:`fold_pressure`; docs/guide/solver.md).

    Parameters
    ----------
    label : str
    fluid : Fluid
    curve : PVCurve or callable
        The PV curve: a :class:`~softflow.curves.PVCurve` (from CSV or arrays),
        any object with the same ``fdf_volume(V) -> (p, dp/dV)`` method, or a
        callable V [m^3] -> absolute pressure [Pa]. A callable should accept
        NumPy arrays (it is called once per Newton iteration with the volumes of
        all actuators sharing it); one that does not is called per volume.
        Without ``curve_derivative`` its slope comes from central differences
        with step ``1e-6 * max(|V|, initial volume)``.
    initial_volume : float [m^3] or Quantity, optional
        Volume at t = 0. Default: the first volume of a PVCurve; a callable
        curve needs it. A volume outside the PV curve's data (its first to
        last sample) starts the actuator on the curve's extension, not on
        measured data: a curve with ``extrapolate='error'`` refuses it here
        (CurveRangeError, a ValueError, naming the actuator and the data's
        range); with 'linear' or 'clamp' every run warns at its start
        (ModelWarning, in ``result.warnings`` as check
        ``'initial_volume_range'``) with the volume, the data's range and the
        pressure the actuator starts at. (A callable curve has no data range:
        nothing is checked.)
    initial_pressure : float [Pa] or Quantity, optional
        Absolute pressure at t = 0 instead of ``initial_volume`` (PVCurve only):
        the actuator starts at the smallest volume where the curve reaches it,
        i.e. on the first rising branch of a peak–valley curve. A pressure
        beyond the data's, reached on a 'linear' extension, gives a volume
        outside the data: warned as for ``initial_volume``.
    curve_derivative : callable, optional
        dp/dV [Pa/m^3] of a callable curve, V [m^3] -> float or array.
    pressure_scale : float [-], default 1
        Scales the curve's gauge pressure, p = p_atm + pressure_scale · (curve(V)
        - p_atm): a stiffer (> 1) or softer (< 1) actuator of the same shape, a
        number to fit to measurements (``sf.fit``) or to design with.
    """

    terminal_spec = (("a", FLUID_PORT),)
    param_names = ("pressure_scale",)
    state_spec: tuple = (("mass", "mass"),)
    jac_pattern: tuple = ACTUATOR_PATTERN
    residual_pattern: tuple | None = ACTUATOR_RESIDUAL_PATTERN
    state_jac_pattern = ACTUATOR_STATE_PATTERN
    rate_pattern = MASS_RATE_PATTERN

    def __init__(self, label: str, fluid: Fluid, curve: Curve,
                 initial_volume: Scalar | None = None, initial_pressure: Scalar | None = None,
                 *, curve_derivative: Callable[[Any], Any] | None = None,
                 thermal: str | None = None, initial_temperature: Scalar | None = None,
                 wall_temperature: Scalar | None = None,
                 heat_transfer_coefficient: HeatTransfer | None = None,
                 area: Scalar | None = None, hA: Scalar | None = None,
                 pressure_scale: Scalar = 1.0) -> None:
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        self.pressure_scale = self._si(pressure_scale, "", "pressure_scale", positive=True)
        if not (hasattr(curve, "fdf_volume") or callable(curve)):
            raise TypeError(f"{self.describe()}: curve must be a PVCurve or a callable V [m^3] "
                            f"-> absolute pressure [Pa], got {curve!r}")
        self.curve = curve
        self.curve_derivative = curve_derivative
        v0 = self._initial_volume(curve, initial_volume, initial_pressure)
        self._curve_fn = _CurveFunction(curve, curve_derivative, abs(v0) or 1e-9,
                                        self.describe())
        try:
            p0 = float(self._curve_fn.value(np.array([v0]))[0])
        except CurveRangeError as err:      # extrapolate='error': say whose and which
            raise _refused_initial_volume(self, v0) from err
        _set_initial_state(self, v0, self._scaled(p0))
        thermal_volume_fields(self, initial_temperature, wall_temperature,
                              heat_transfer_coefficient, area, hA, thermal)

    # -- set-up ---------------------------------------------------------------------------
    def _scaled(self, p):
        """The curve's absolute pressure p with its gauge part scaled."""
        return pressure_atmospheric + self.pressure_scale * (p - pressure_atmospheric)

    def _initial_volume(self, curve, initial_volume, initial_pressure):
        if initial_volume is not None and initial_pressure is not None:
            raise ValueError(f"{self.describe()}: give initial_volume or initial_pressure, "
                             "not both")
        if initial_volume is not None:
            return self._si(initial_volume, "m**3", "initial_volume", positive=True)
        if not isinstance(curve, PVCurve):
            raise ValueError(f"{self.describe()}: the curve is not a PVCurve, so give "
                             "initial_volume [m^3] (a PVCurve's first volume is the default, "
                             "and only a PVCurve can be inverted for initial_pressure)")
        if initial_pressure is None:
            return float(curve.volume[0])
        p0 = self._si(initial_pressure, "Pa", "initial_pressure", positive=True)
        # the curve's own pressure there (its gauge part is scaled by pressure_scale)
        v0 = volume_at_pressure(curve, pressure_atmospheric
                                + (p0 - pressure_atmospheric) / self.pressure_scale)
        if v0 is None or not v0 > 0:
            raise ValueError(f"{self.describe()}: initial_pressure {p0:.6g} Pa is not reached "
                             f"by the PV curve at a positive volume ({curve!r})")
        return v0

    def group_key(self):
        return (type(self), id(self.fluid), id(self.curve), id(self.curve_derivative))

    def initial_states(self):
        return [float(self.fluid.density(self.initial_pressure)) * self.initial_volume]

    def _initial_point_jacobian(self, name):
        """(dp0/d theta, dv0/d theta) of the initial point on the curve, p0 = p_atm +
        s·(curve(v0) - p_atm): for initial_volume (or initial_pressure, the curve
        inverted) and pressure_scale; None for others."""
        v0, p0, s = self.initial_volume, self.initial_pressure, self.pressure_scale
        pc, dpc = (float(a[0]) for a in self._curve_fn.fdf(np.array([v0])))
        # (moving one of initial_volume / initial_pressure gives it from then on)
        if name == "initial_volume":
            return s * dpc, 1.0
        if name == "initial_pressure":
            return 1.0, 1.0 / (s * dpc)
        if name == "pressure_scale":
            if _given(self, "initial_pressure"):   # v0 moves: curve(v0) = p_atm + (p0 - p_atm)/s
                return 0.0, -(p0 - pressure_atmospheric) / (s * s * dpc)
            return pc - pressure_atmospheric, 0.0
        return None

    def initial_state_jacobian(self, name):
        """d(initial mass)/d theta of m0 = rho(p0)·v0 (:meth:`_initial_point_jacobian`),
        or None."""
        return initial_mass_jacobian(self, name)

    # -- kernels --------------------------------------------------------------------------
    @classmethod
    def make_params(cls, components):
        P = set_fluid_law(Params(components))
        P.curve = components[0]._curve_fn
        P.scaled = bool(np.any(P.pressure_scale != 1.0))
        # a group on a PVCurve evaluates its residual in one compiled pass over
        # the curve's table (laws.volumes.actuator_residual); a callable or
        # another kind of curve object, through its Python function
        curve = components[0].curve
        P.pv = (curve if compiled_curve(curve)
                and cls.residual.__func__ is Actuator.residual.__func__
                and cls.curve_pressure is Actuator.curve_pressure else None)
        return P

    @staticmethod
    def curve_pressure(P, vol, jac, scale=None):
        """(p, dp/dV or None) of the group's curve at ``vol``, gauge part scaled
        (by each instance's pressure_scale, or by ``scale``)."""
        if jac:
            pc, dpc = P.curve.fdf(vol)
        else:
            pc, dpc = P.curve.value(vol), None
        if P.scaled:
            s = P.pressure_scale if scale is None else scale
            pc = pressure_atmospheric + s * (pc - pressure_atmospheric)
            dpc = None if dpc is None else s * dpc
        return pc, dpc

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta) of F = p - (p_atm + s·(curve(V) - p_atm)) for the
        pressure_scale s; initial_volume and initial_pressure set the initial mass
        only (0); None for others (the curve is not a number)."""
        if name in ("initial_volume", "initial_pressure"):
            return np.zeros((P.n, 1)), np.zeros((P.n, 1))
        if name != "pressure_scale":
            return None
        return cls.scale_jacobian(P, _volume(P, V, S)[2])[:, None], np.zeros((P.n, 1))

    @staticmethod
    def scale_jacobian(P, vol):
        """d(p - p_curve)/d pressure_scale at the volume vol: p_atm - curve(vol)."""
        return pressure_atmospheric - P.curve.value(vol)

    @classmethod
    def fold_pressure(cls, P, V, S, k, rising):
        """The absolute pressure [Pa] actuator ``k`` of the group snaps to at a
        fold of its gas's mass (:func:`fold_pressure`), nan where it is at
        none; ``rising``: whether its mass rises."""
        _, _, vol = _volume(P, V, S)
        return fold_pressure(lambda v: cls._fold_curve(P, v, S, k), P.fluid, vol[k], S[k, 0],
                             rising)

    @classmethod
    def _fold_curve(cls, P, vol, S, k):
        """The curve's absolute pressure of actuator ``k`` at the volumes ``vol``
        (an array; the fold search's, here and in thermal scenes)."""
        scale = np.broadcast_to(P.pressure_scale, (P.n,))[k]
        return Actuator.curve_pressure(P, vol, False, scale=scale)[0]

    @classmethod
    def rates(cls, P, V, S, jac):
        return mass_rates(P, V, jac)

    @classmethod
    def residual(cls, P, V, S, t, jac):
        pv = P.pv
        if pv is not None:
            rho, rho_p = given_densities(P, V[:, 0], jac)
            F = np.empty((P.n, 1))
            J = np.empty((P.n, 2)) if jac else _NO_JACOBIAN
            if volume_laws().actuator_residual(
                    P.rho_kind, P.rho_c, V, S, rho, rho_p, pv._knots, pv._table, pv._mode,
                    P.scaled, P.pressure_scale, pressure_atmospheric, F, J, jac) < 0:
                return F, (J if jac else None)
            # a volume the curve refuses (extrapolate='error'): the curve's own
            # error, as the path below raises it
        p, rho, vol = _volume(P, V, S)
        try:
            pc, dpc = cls.curve_pressure(P, vol, jac)
            if not jac:
                return (p - pc)[:, None], None
        except FluidError:
            raise
        except Exception as err:
            if P.curve.user is None:
                raise
            raise _curve_failure(P, vol, err, t)
        return _residual(P, p, rho, vol, pc, dpc)

    def outputs(self):
        if self._thermal is not None:      # gas temperature, internal energy, work
            from .thermal import volume_outputs
            return volume_outputs(self)
        return _volume_output(self.fluid)


def _curve_failure(P, vol, err, t):
    """A ComponentError naming the actuator whose volume made its (user's) curve
    function raise: the volumes of a group are tried one at a time."""
    from ..solve.validity import user_code_error
    culprit, v_bad = 0, float(vol[0])
    for i, v in enumerate(np.asarray(vol, dtype=float).tolist()):
        try:
            P.curve.fdf(np.array([v]))
        except Exception:
            culprit, v_bad = i, v
            break
    c = P.components[culprit]
    return user_code_error(err, c.describe(), c.label, "curve", t, f"V = {v_bad:.6g} m^3")


def _set_initial_state(comp, v0, p0):
    if not (np.isfinite(p0) and p0 > 0):
        raise ValueError(f"{comp.describe()}: the PV curve gives pressure {p0!r} Pa at the "
                         f"initial volume {v0:.6g} m^3; expected an absolute pressure > 0")
    comp.initial_volume = v0
    comp.initial_pressure = p0
    comp.terminals[0].own_variable(0).initial_value = p0
    comp._check_fluid_state(p0, "the initial pressure (from the PV curve)")


#: An initial volume is outside its curve's data when it lies past the first or
#: last sample by more than this fraction of the data's volume range: the
#: round-off of unit conversions (6 mL given in mL against data in m^3), no more.
#: (The check after a run allows validity.PV_CURVE_SLACK, the adaptive steps'
#: overshoot; an initial volume is the user's own number.)
INITIAL_VOLUME_SLACK = 1e-9

_BEYOND_DATA = {"linear": "continued in a straight line with its end slope",
                "clamp": "held at its end pressure"}


def _data_range(comp):
    """(first volume, last volume [m^3], where the data came from, extrapolation
    policy) of the data of ``comp``'s PV curve (both curves of a hysteresis
    loop), or None where the curve has no data (a callable)."""
    curves = _curves_of(comp)
    if not curves:
        return None
    lo = min(float(c.volume[0]) for c in curves)
    hi = max(float(c.volume[-1]) for c in curves)
    policies = sorted({c.extrapolate for c in curves})
    origin = curves[0].origin if len(curves) == 1 else "inflation/deflation curves"
    return lo, hi, origin, "/".join(policies)


def _refused_initial_volume(comp, v0):
    """The error of an initial volume that a curve with extrapolate='error' refuses."""
    lo, hi, origin, _ = _data_range(comp)
    return CurveRangeError(
        f"{comp.describe()}: initial_volume {v0 * 1e6:.6g} mL ({v0:.6g} m^3) is outside "
        f"its PV curve's data, {lo * 1e6:.6g} ... {hi * 1e6:.6g} mL ({origin}), which the "
        "curve refuses (extrapolate='error'); expected an initial volume within the data, "
        "or a curve built with extrapolate='linear' or 'clamp' (a warning then)")


def initial_volume_records(comps):
    """ValidityRecords (check ``'initial_volume_range'``) of the actuators among
    ``comps`` (one compiled group: one curve, or one hysteresis loop) whose
    initial volume lies outside their PV curve's data by more than
    :data:`INITIAL_VOLUME_SLACK` of its range: the run starts them on the
    curve's extension. Each names the actuator, the volume, the data's range
    and the pressure it starts at. Empty for curves without data."""
    found = _data_range(comps[0])
    if found is None:
        return []
    lo, hi, origin, policy = found
    span = hi - lo
    slack = INITIAL_VOLUME_SLACK * span
    # each initial volume as a float, tested one by one (a group holds one or a
    # few: NumPy's calls cost more than the tests)
    v0 = [float(c.initial_volume) for c in comps]
    below, above_hi = lo - slack, hi + slack
    out = []
    for k in [k for k, v in enumerate(v0) if v < below or v > above_hi]:
        comp, v = comps[k], v0[k]
        above = v > hi
        limit = hi if above else lo
        past = abs(v - limit)
        side = "last" if above else "first"
        how = _BEYOND_DATA.get(policy, f"extrapolated ({policy})")
        given = (" (from its initial_pressure)" if isinstance(comp, Actuator)
                 and _given(comp, "initial_pressure") else "")
        suggestion = ("give an initial volume within the data, or measure the PV curve over "
                      "the volumes the actuator starts at")
        message = (f"{comp.describe()}: initial volume {v * 1e6:.6g} mL{given} is outside "
                   f"its PV curve's data, {lo * 1e6:.6g} ... {hi * 1e6:.6g} mL ({origin}): "
                   f"{past * 1e6:.3g} mL ({100 * past / span:.3g} % of the data's range) "
                   f"beyond its {side} sample. It starts there at "
                   f"{comp.initial_pressure / 1e5:.6g} bar (absolute), where the curve is "
                   f"{how}, not measured. "
                   f"Suggestion: {suggestion}")
        out.append(ValidityRecord(component=comp.label, check="initial_volume_range",
                                  measured=v, limit=limit, unit="m^3", suggestion=suggestion,
                                  message=message,
                                  details={"beyond": past, "fraction_of_range": past / span,
                                           "first_time": 0.0, "policy": policy, "side": side,
                                           "data_range": (lo, hi),
                                           "initial_pressure": comp.initial_pressure}))
    return out


def _volume(P, V, S):
    """Pressure, density and volume of the stored mass S[:, 0]."""
    p = V[:, 0]
    rho = P.fluid.density(p)
    return p, rho, S[:, 0] / rho


#: A fold's far state (:func:`fold_pressure`) is searched over volumes from
#: the current one up to FOLD_SPAN times it (mass rising) or down to
#: 1 / FOLD_SPAN of it (falling), at FOLD_POINTS volumes
FOLD_SPAN = 3.0
FOLD_POINTS = 3001
#: ... and only where the fold is at hand: the stored mass leaves the
#: curve's reach within FOLD_NEAR of the current volume
FOLD_NEAR = 0.02


def fold_pressure(pressure_of, fluid, vol, mass, rising):
    """The absolute pressure [Pa] an actuator snaps to at a fold, or nan.

    A gas-filled actuator holds the mass m = rho(p(V)) V: where its PV curve
    p(V) falls more steeply than the gas expands (a snap), m(V) has a local
    maximum (a fold, for a rising mass; a minimum for a falling one) beyond
    which no volume nearby holds a larger (smaller) mass; the actuator then
    jumps, at the mass it holds, to the next volume that does, past the
    snap. ``pressure_of(V)``: the curve's absolute pressure at the volumes V
    (an array); ``fluid``: the gas, or a function of the pressures giving
    its densities (a thermal volume's at its gas's temperature); ``vol``,
    ``mass``: the current volume and mass; ``rising``:
    whether the mass rises. nan where there is no fold within FOLD_NEAR of
    ``vol`` or no volume past it within FOLD_SPAN."""
    step = (FOLD_SPAN if rising else 1.0 / FOLD_SPAN) - 1.0
    grid = vol * (1.0 + step * np.linspace(0.0, 1.0, FOLD_POINTS)[1:])
    density = getattr(fluid, "density", fluid)
    try:
        with np.errstate(all="ignore"):
            d = density(pressure_of(grid)) * grid - mass
    except (FluidError, ValueError):
        return np.nan
    if not rising:
        d = -d
    short = np.flatnonzero(~(d >= 0.0))        # out of the curve's reach (or not finite)
    if not short.size or abs(grid[short[0]] - vol) > FOLD_NEAR * vol:
        return np.nan
    back = np.flatnonzero(d[short[0]:] >= 0.0)
    if not back.size:
        return np.nan
    j = short[0] + back[0]
    f = d[j - 1] / (d[j - 1] - d[j]) if np.isfinite(d[j - 1]) else 1.0
    v = grid[j - 1] + f * (grid[j] - grid[j - 1])
    return float(pressure_of(np.array([v]))[0])


def _residual(P, p, rho, vol, pc, dpc):
    """The wall law p - p_curve(V), V = m / rho(p), of a group whose curve was
    evaluated in Python (pc, dpc at vol), with its derivatives in p and m:
    (F (n, 1), J (n, 2)), by the compiled law (laws.volumes.curve_law_array)."""
    n = P.n
    F, J = np.empty((n, 1)), np.empty((n, 2))
    volume_laws().curve_law_array(*(np.broadcast_to(np.asarray(x, dtype=float), (n,))
                                    for x in (p, rho, P.fluid.density_dp(p), vol, pc, dpc)),
                                  F, J)
    return F, J


def compiled_curve(curve):
    """Whether ``curve`` is a PVCurve that the compiled lookup reads (its table;
    a subclass that evaluates itself otherwise is not)."""
    kind = type(curve)
    return (isinstance(curve, PVCurve) and kind.fdf_volume is PVCurve.fdf_volume
            and kind._array is PVCurve._array and kind._scalar is PVCurve._scalar)


_NO_JACOBIAN = np.empty((0, 2))


def _volume_output(fluid):
    return {"volume": ("volume", lambda get: get("mass") / fluid.density(get("pressure")))}


def volume_at_pressure(curve, pressure):
    """Smallest volume [m^3] at which ``curve`` (a PVCurve) reaches ``pressure`` [Pa],
    its linear extensions included; None where it never does. Between samples
    PCHIP does not overshoot, so the first sample at or above the pressure
    brackets the first crossing."""
    v, p, s = curve.volume, curve.pressure, curve.slope
    if getattr(curve, "extrapolate", "linear") != "linear" and not p[0] <= pressure <= p.max():
        return None            # 'clamp' and 'error' reach only the pressures of the data
    if pressure < p[0]:
        return v[0] + (pressure - p[0]) / s[0] if s[0] > 0 else None
    above = p >= pressure
    i = int(np.argmax(above))
    if not above[i]:
        return v[-1] + (pressure - p[-1]) / s[-1] if s[-1] > 0 else None
    if p[i] == pressure:
        return float(v[i])
    from scipy.optimize import brentq     # lazy: scipy.optimize costs a process ~0.5 s
    return brentq(lambda x: float(curve(x)) - pressure, v[i - 1], v[i],
                  xtol=1e-13 * (v[i] - v[i - 1]), rtol=1e-14)


class HystereticActuator(LibraryComponent):
    """Actuator with separate inflation and deflation PV curves, terminal ``a``.

    Follows the inflation curve until the volume reaches the curve's last
    volume V_hi, then the deflation curve until the volume falls to the
    deflation curve's first volume V_lo, and so on (see
    :mod:`softflow.curves.hysteresis`); the two curves must meet at V_lo and
    V_hi. Snapping is the steep falling part of a curve. The branch is the
    discrete state ``branch`` (1 = inflation, 0 = deflation): each step uses
    the branch it started on, and the branch changes between steps. Residuals
    and results as for :class:`Actuator` (``pressure``, ``mass``, ``branch`` and
    the output ``volume``); filled with a gas it snaps at a fold of the mass
    it holds as :class:`Actuator` does (:meth:`fold_pressure`).

    Parameters
    ----------
    label : str
    fluid : Fluid
    inflation_curve : PVCurve
    deflation_curve : PVCurve
        (``HystereticActuator(label, fluid, *loop)`` takes a
        :class:`~softflow.curves.HysteresisLoop`.)
    initial_volume : float [m^3] or Quantity, optional
        Default: the first volume of the inflation curve. A volume outside the
        loop's data (the lowest first sample to the highest last sample of
        its two curves) is warned at the start of every run, as for
        :class:`Actuator`.
    initial_branch : {'inflation', 'deflation'}, optional
        Default: deflation if initial_volume >= V_hi, else inflation. Past the
        end of the named branch the actuator starts on the other one.
    meet_tolerance : float [Pa], optional
        Allowed pressure mismatch of the curves where they meet; default 1 % of
        their larger pressure range.
    """

    terminal_spec = (("a", FLUID_PORT),)
    state_spec: tuple = (("mass", "mass"), ("branch", "dimensionless"))
    discrete_states = ("branch",)
    jac_pattern: tuple = ACTUATOR_PATTERN
    residual_pattern: tuple | None = ACTUATOR_RESIDUAL_PATTERN
    state_jac_pattern = ACTUATOR_STATE_PATTERN
    rate_pattern = MASS_RATE_PATTERN

    def __init__(self, label: str, fluid: Fluid, inflation_curve: PVCurve,
                 deflation_curve: PVCurve, initial_volume: Scalar | None = None, *,
                 initial_branch: str | None = None, meet_tolerance: Scalar | None = None,
                 thermal: str | None = None, initial_temperature: Scalar | None = None,
                 wall_temperature: Scalar | None = None,
                 heat_transfer_coefficient: HeatTransfer | None = None,
                 area: Scalar | None = None, hA: Scalar | None = None) -> None:
        super().__init__(label)
        self.fluid = self._check_fluid(fluid)
        self.loop = HysteresisLoop(inflation_curve, deflation_curve,
                                   meet_tolerance=meet_tolerance, owner=self.describe())
        refused = [name for name, c in (("inflation_curve", inflation_curve),
                                        ("deflation_curve", deflation_curve))
                   if getattr(c, "extrapolate", "linear") == "error"]
        if refused:
            # the loop evaluates both branches at every volume and picks one, so a
            # branch that refuses volumes beyond its own data would stop every run
            raise ValueError(f"{self.describe()}: {' and '.join(refused)} built with "
                             "extrapolate='error', which a hysteresis loop does not support "
                             "(it evaluates both branches everywhere); use 'linear' or "
                             "'clamp': result.warnings reports volumes beyond the data")
        if initial_volume is None:
            v0 = float(inflation_curve.volume[0])
        else:
            v0 = self._si(initial_volume, "m**3", "initial_volume", positive=True)
        if initial_branch is None:
            inflating = v0 < self.loop.volume_high
        elif initial_branch in ("inflation", "deflation"):
            inflating = initial_branch == "inflation"
        else:
            raise ValueError(f"{self.describe()}: initial_branch must be 'inflation' or "
                             f"'deflation', got {initial_branch!r}")
        inflating = bool(self.loop.on_inflation_curve(np.array([v0]), inflating)[0])
        self.initial_branch = 1.0 if inflating else 0.0
        p0 = float(self.loop.fdf_volume(np.array([v0]), inflating)[0][0])
        _set_initial_state(self, v0, p0)
        thermal_volume_fields(self, initial_temperature, wall_temperature,
                              heat_transfer_coefficient, area, hA, thermal)

    def group_key(self):
        return (type(self), id(self.fluid), id(self.loop.inflation), id(self.loop.deflation))

    def initial_states(self):
        return [float(self.fluid.density(self.initial_pressure)) * self.initial_volume,
                self.initial_branch]

    def _initial_point_jacobian(self, name):
        """(dp0/d theta, dv0/d theta) for initial_volume, p0 on the initial branch
        (which a small change keeps), and meet_tolerance (0); None for others."""
        if name == "meet_tolerance":
            return 0.0, 0.0
        if name != "initial_volume":
            return None
        v0 = self.initial_volume
        return float(self.loop.fdf_volume(np.array([v0]), self.initial_branch > 0.5)[1][0]), 1.0

    def initial_state_jacobian(self, name):
        """d(initial states)/d theta: the mass's (:meth:`_initial_point_jacobian`), the
        branch's 0; None for others."""
        dm = initial_mass_jacobian(self, name)
        return None if dm is None else dm + [0.0]

    @classmethod
    def make_params(cls, components):
        P = set_fluid_law(Params(components))
        P.loop = components[0].loop
        # the loop's branches read by the compiled pass (laws.volumes.hysteretic_residual)
        P.compiled = (compiled_curve(P.loop.inflation) and compiled_curve(P.loop.deflation)
                      and type(P.loop).fdf_volume is HysteresisLoop.fdf_volume
                      and type(P.loop).on_inflation_curve is HysteresisLoop.on_inflation_curve)
        return P

    @classmethod
    def param_jacobian(cls, P, V, S, t, name):
        """(dF/d theta, dr/d theta): initial_volume and meet_tolerance do not enter
        the equations (0); None for others."""
        if name in ("initial_volume", "meet_tolerance"):
            return np.zeros((P.n, 1)), np.zeros((P.n, 1))
        return None

    @classmethod
    def rates(cls, P, V, S, jac):
        return mass_rates(P, V, jac)

    @classmethod
    def switch(cls, P, V, S):
        _, _, vol = _volume(P, V, S)
        return P.loop.next_inflating(vol, S[:, 1] > 0.5)[:, None]

    @classmethod
    def switching(cls, P, V, S):
        _, _, vol = _volume(P, V, S)
        return P.loop.switching(vol, S[:, 1] > 0.5)[:, None]

    @classmethod
    def fold_pressure(cls, P, V, S, k, rising):
        """As :meth:`Actuator.fold_pressure`, along the branch actuator ``k`` is
        on (past its end, the other one: the branches meet there)."""
        _, _, vol = _volume(P, V, S)
        return fold_pressure(lambda v: cls._fold_curve(P, v, S, k), P.fluid, vol[k], S[k, 0],
                             rising)

    #: the column of the branch state (1 = inflation) among the states
    _branch = 1

    @classmethod
    def _fold_curve(cls, P, vol, S, k):
        """The pressure of the branch actuator ``k`` is on, at the volumes ``vol``
        (the fold search's, here and in thermal scenes)."""
        return P.loop.fdf_volume(vol, bool(S[k, cls._branch] > 0.5))[0]

    @classmethod
    def switching_jacobian(cls, P, V, S):
        """d(switching)/dV (n, 1, 1) and d/dS (n, 1, 2): the branch's sign times
        the volume's derivatives, vol = m / rho(p)."""
        p, rho, vol = _volume(P, V, S)
        sign = np.where(S[:, 1] > 0.5, 1.0, -1.0)
        GV = np.zeros((P.n, 1, V.shape[1]))
        GV[:, 0, 0] = -sign * vol * P.fluid.density_dp(p) / rho
        GS = np.zeros((P.n, 1, S.shape[1]))
        GS[:, 0, 0] = sign / rho
        return GV, GS

    @classmethod
    def switching_param_jacobian(cls, P, V, S, name):
        """d(switching)/d theta (n, 1): the loop's limits are not numeric
        parameters (0 for initial_volume and meet_tolerance)."""
        return np.zeros((P.n, 1))

    @classmethod
    def residual(cls, P, V, S, t, jac):
        if P.compiled:
            # the branch's curve and the wall law in one compiled pass
            loop = P.loop
            up, down = loop.inflation, loop.deflation
            rho, rho_p = given_densities(P, V[:, 0], jac)
            F = np.empty((P.n, 1))
            J = np.empty((P.n, 2)) if jac else _NO_JACOBIAN
            volume_laws().hysteretic_residual(
                P.rho_kind, P.rho_c, V, S, 1, rho, rho_p, up._knots, up._table, down._knots,
                down._table, loop.volume_high, loop.volume_low, F, J, jac)
            return F, (J if jac else None)
        p, rho, vol = _volume(P, V, S)
        pc, dpc = P.loop.fdf_volume(vol, S[:, 1] > 0.5)
        if not jac:
            return (p - pc)[:, None], None
        return _residual(P, p, rho, vol, pc, dpc)

    def outputs(self):
        if self._thermal is not None:      # gas temperature, internal energy, work
            from .thermal import volume_outputs
            return volume_outputs(self)
        return _volume_output(self.fluid)


if Actuator.__doc__ and HystereticActuator.__doc__:   # None under python -OO
    Actuator.__doc__ += THERMAL_VOLUME_DOC
    HystereticActuator.__doc__ += THERMAL_VOLUME_DOC
