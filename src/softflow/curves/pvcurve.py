"""Pressure–volume curves of inflatable actuators."""
from __future__ import annotations

import bisect
import functools
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from .._laws import law_module
from ..constants import pressure_atmospheric
from ..fluids.base import FluidError
from ..units import to_si
from .csvdata import DataFileError, read_table

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from .._typing import Array, ArrayLike, PVPoint

#: Fewest samples a smoothing spline accepts (scipy's make_smoothing_spline).
MIN_POINTS_SMOOTHING = 5

#: What a PVCurve does beyond its first and last sample (``extrapolate=``).
EXTRAPOLATE = ("linear", "clamp", "error")

#: How a PVCurve runs between its samples (``interpolation=``): monotone cubics
#: (the default) or straight lines.
INTERPOLATION = ("pchip", "linear")


class CurveRangeError(FluidError):
    """A volume beyond the data of a PV curve built with ``extrapolate='error'``.
    Like a state outside a fluid's range, the solver treats it as a failed
    trial point (the step is cut) and names it if the run cannot go on."""


class PVCurve:
    """A measured or analytic pressure–volume characteristic p(V).

    Default interpolation is monotone piecewise-cubic Hermite (PCHIP):
    C1-continuous, so Newton sees a continuous dp/dV, and free of overshoot
    between samples, so a peak–valley curve keeps its measured peak and valley.
    ``interpolation='linear'`` draws straight lines between the samples
    instead (fonsim's curves; dp/dV jumps at every sample). For noisy
    measurements, ``smoothing`` replaces it by a cubic smoothing spline (C2)
    and ``filter_window`` low-passes the pressures first.

    Outside the sampled volumes the curve does what ``extrapolate`` says: by
    default (``'linear'``) it continues in a straight line with its end
    slopes, as it always has; ``'clamp'`` holds the end pressures; ``'error'``
    refuses (a run fails there, naming the actuator). Whatever the policy, a
    run whose actuator goes past the data (by more than 1 % of the data's
    volume range) says so in ``result.warnings`` and with a
    :class:`softflow.ModelWarning`: how far and when.

    Synthetic curves of the shapes in the paper's Figs. 3-5 come from
    :meth:`monotonic`, :meth:`plateau` and :meth:`peak_valley`; a hysteretic
    pair from :meth:`softflow.curves.HysteresisLoop.snapping`.

    Parameters
    ----------
    source : str or Path, optional
        CSV file with a names row and a units row (e.g. ``s, ml, mbar``), as in
        ``PVCurve('actuator.csv')``.
    volume : array_like [m^3] or Quantity, optional
        Volumes, strictly increasing (instead of ``source``).
    pressure : array_like [Pa] or Quantity, optional
        Pressures at those volumes (instead of ``source``).
    gauge : bool, optional
        The given pressures are gauge (relative to 1 atm). Default: True for a
        CSV file (measured PV data usually are gauge), False for arrays
        (softflow's convention is absolute pressure).
    volume_column, pressure_column : str
        Column names in the CSV file (case-insensitive).
    volume_unit, pressure_unit : str, optional
        Units of the columns if the file has no units row.
    smoothing : float [-] or 'auto', optional
        Fit a cubic smoothing spline (scipy ``make_smoothing_spline``) instead of
        interpolating: it minimises sum (p_i - s(V_i))^2 + lam * integral s''^2
        on normalised data (volume mapped to [0, 1], pressure divided by its
        range), so ``lam`` is dimensionless: 0 interpolates (natural spline),
        1e-6 smooths lightly, 1e-3 strongly; ``'auto'`` (or True) chooses lam by
        generalised cross-validation. Needs at least 5 samples. The spline is C2
        but may overshoot between samples and flattens sharp peaks.
    filter_window : int, optional
        Low-pass the pressures with a Savitzky–Golay filter over this many
        samples (odd, >= filter_order + 2) before interpolating: a local
        polynomial fit that removes noise while keeping peaks better than a
        moving average. It treats the samples as evenly spaced in volume (as a
        syringe-pump measurement is); for unevenly spaced data use ``smoothing``.
    filter_order : int, default 2
        Polynomial order of the Savitzky–Golay filter.
    extrapolate : {'linear', 'clamp', 'error'}, default 'linear'
        Beyond the first and last volume: continue with the end slopes
        (``'linear'``; the default, kept so that existing scenes run as before,
        never silently: see above), hold the end pressures (``'clamp'``, dp/dV
        = 0 there), or raise :class:`CurveRangeError` (``'error'``).
    interpolation : {'pchip', 'linear'}, default 'pchip'
        Between the samples: monotone cubics (``'pchip'``), or straight lines
        (``'linear'``: on each interval the chord's slope, so dp/dV jumps at
        every sample; fonsim's curves, which ``softflow.fons`` selects). Its
        end slopes (for ``extrapolate='linear'``) are the first and last
        chords. Not with ``smoothing`` (a spline replaces the interpolation);
        ``filter_window`` filters the pressures first, as with PCHIP. The
        solver is not told of the slope's jumps: the adaptive error test
        finds them, as it finds PCHIP's jumps in curvature (telling it, which
        drops BDF to order 1 at each, took more steps: the balloon inflated
        past its peak at rtol 1e-6, water 493 -> 779, air 2 902 -> 3 483).

    Attributes
    ----------
    volume : ndarray [m^3]
    pressure : ndarray [Pa]
        Absolute pressure of the curve at ``volume`` (after filtering/smoothing).
    measured_pressure : ndarray [Pa]
        Absolute pressure as given.
    slope : ndarray [Pa/m^3]
        dp/dV at ``volume`` (``interpolation='linear'``: the slope of the
        chord that starts there; at the last sample, of the last chord).
    interpolation : str
        ``'pchip'`` or ``'linear'``.
    """

    def __init__(self, source: str | Path | None = None, volume: ArrayLike | None = None,
                 pressure: ArrayLike | None = None, *, gauge: bool | None = None,
                 volume_column: str = "Volume", pressure_column: str = "Pressure",
                 volume_unit: str | None = None, pressure_unit: str | None = None,
                 smoothing: float | str | None = None, filter_window: int | None = None,
                 filter_order: int = 2, extrapolate: str = "linear",
                 interpolation: str = "pchip") -> None:
        if not (isinstance(extrapolate, str) and extrapolate in EXTRAPOLATE):
            raise ValueError(f"PVCurve: extrapolate must be one of "
                             f"{', '.join(map(repr, EXTRAPOLATE))}, got {extrapolate!r}")
        if not (isinstance(interpolation, str) and interpolation in INTERPOLATION):
            raise ValueError(f"PVCurve: interpolation must be one of "
                             f"{', '.join(map(repr, INTERPOLATION))} (monotone cubics or "
                             f"straight lines between the samples), got {interpolation!r}")
        smoothed = smoothing is not None and smoothing is not False
        if interpolation == "linear" and smoothed:
            raise ValueError(f"PVCurve: interpolation='linear' and smoothing={smoothing!r} "
                             f"exclude each other (a smoothing spline replaces the "
                             f"interpolation); give one of them (filter_window= low-passes "
                             f"the pressures before a linear interpolation)")
        self.extrapolate = extrapolate
        self.interpolation = interpolation
        self.gauge = (source is not None) if gauge is None else bool(gauge)
        if source is not None:
            if volume is not None or pressure is not None:
                raise ValueError("PVCurve: give either a CSV file or volume and pressure arrays")
            table = read_table(source)
            v = table.column(volume_column, "m**3", default_unit=volume_unit)
            p = table.column(pressure_column, "Pa", default_unit=pressure_unit)
            self.origin = str(Path(source))
            lines = table.lines
        else:
            if volume is None or pressure is None:
                raise ValueError("PVCurve: give a CSV file, or both volume and pressure")
            v = np.atleast_1d(to_si(volume, "m**3", name="volume", owner="PVCurve"))
            p = np.atleast_1d(to_si(pressure, "Pa", name="pressure", owner="PVCurve"))
            self.origin = "arrays"
            lines = None
        v = np.asarray(v, dtype=float)
        p = np.asarray(p, dtype=float)
        where = f"PVCurve ({self.origin})"
        if v.shape != p.shape or v.ndim != 1:
            raise ValueError(f"{where}: volume and pressure must be 1-D arrays of equal length")
        if len(v) < 2:
            raise ValueError(f"{where}: needs at least 2 points, got {len(v)}")
        bad = ~(np.isfinite(v) & np.isfinite(p))
        if bad.any():
            raise ValueError(f"{where}: NaN or inf at point {int(np.argmax(bad))}")
        steps = np.diff(v)
        if (steps <= 0).any():
            i = int(np.argmax(steps <= 0)) + 1
            loc = f"line {lines[i]}" if lines is not None else f"point {i}"
            raise DataFileError(f"{where}: volume must increase strictly (single-valued p(V)); "
                                f"it does not at {loc} ({v[i - 1]:.6g} -> {v[i]:.6g} m^3)")
        if self.gauge:
            p = p + pressure_atmospheric
        self.volume = v
        self.measured_pressure = p
        if filter_window is not None:
            p = _savgol(p, filter_window, filter_order, where)
        if smoothing is not None and smoothing is not False:
            p, slope = _smoothing_spline(v, p, smoothing, where)
        elif interpolation == "linear":
            # each sample's slope is that of the chord starting there (the last
            # one's, of the last chord): the pieces' and the extensions' slopes
            chords = np.diff(p) / np.diff(v)
            slope = np.concatenate([chords, chords[-1:]])
        else:
            from scipy.interpolate import PchipInterpolator   # lazy: import softflow stays fast
            slope = PchipInterpolator(v, p)(v, 1)
        self.pressure = p
        self.slope = slope
        self._build_tables()

    # -- evaluation ------------------------------------------------------------------------
    def _build_tables(self) -> None:
        """Cubic pieces in monomial form around each piece's left end, plus the two
        linear extrapolations: piece k = searchsorted(volume, V, 'right') holds
        p = c0 + x (c1 + x (c2 + x c3)) with x = V - base[k]. Straight pieces
        (``interpolation='linear'``) are the same rows with c2 = c3 = 0 and
        c1 the chord's slope, so the compiled lookup reads both alike."""
        v, p, d = self.volume, self.pressure, self.slope
        h = np.diff(v)
        delta = np.diff(p) / h
        if self.interpolation == "linear":
            c2 = c3 = np.zeros_like(h)
        else:
            c2 = (3 * delta - 2 * d[:-1] - d[1:]) / h
            c3 = (d[:-1] + d[1:] - 2 * delta) / h ** 2
        self._base = np.concatenate([v[:1], v])
        self._c0 = np.concatenate([p[:1], p])
        self._c1 = np.concatenate([d[:1], d])
        self._c2 = np.concatenate([[0.0], c2, [0.0]])
        self._c3 = np.concatenate([[0.0], c3, [0.0]])
        if self.extrapolate == "clamp":      # the end pressures, held: zero slope outside
            self._c1[0] = self._c1[-1] = 0.0
        self._lo, self._hi = float(v[0]), float(v[-1])
        self._refuse = self.extrapolate == "error"
        # what the compiled lookup reads (softflow.laws.volumes): the knots, one
        # row [base, c0, c1, c2, c3] per piece, the extrapolation's code
        self._knots = np.ascontiguousarray(v, dtype=float)
        self._table = np.ascontiguousarray(
            np.column_stack([self._base, self._c0, self._c1, self._c2, self._c3]))
        self._mode = EXTRAPOLATE.index(self.extrapolate)
        # the antiderivative (work) at each piece's base, from the first volume
        full = _antiderivative(0.0, p[:-1], d[:-1], c2, c3, h)
        self._w0 = np.concatenate([[0.0, 0.0], np.cumsum(full)])
        # the work of one volume (an actuator alone in its group) runs on lists
        self._vl = v.tolist()
        self._wl = self._w0.tolist()
        self._tl = list(zip(self._base.tolist(), self._c0.tolist(), self._c1.tolist(),
                            self._c2.tolist(), self._c3.tolist()))

    def __call__(self, volume: float | ArrayLike) -> float | Array:
        """Absolute pressure [Pa] at ``volume`` [m^3]."""
        return self.fdf_volume(volume)[0]

    def fdf_volume(self, volume: float | ArrayLike
                   ) -> tuple[float, float] | tuple[Array, Array]:
        """Absolute pressure [Pa] and its derivative dp/dV [Pa/m^3] at ``volume`` [m^3]
        (a float, an array of any shape or a pint Quantity)."""
        if isinstance(volume, float):
            # one volume (a user component's argument, perhaps a NumPy scalar):
            # the compiled lookup on a float, its result two floats
            return self._scalar(float(volume))
        if type(volume) is np.ndarray and volume.ndim and volume.dtype == np.float64:
            return self._array(volume)
        volume = to_si(volume, "m**3", name="volume", owner="PVCurve.fdf_volume")
        if isinstance(volume, float):
            return self._scalar(volume)
        return self._array(volume)  # type: ignore[arg-type]  # a float64 ndarray

    def work(self, volume: Array) -> Array:
        """The integral of the absolute pressure over volume from the curve's first
        volume to ``volume`` [J] (a float64 array): the work a gas does on the wall
        as it follows the curve, exact for the curve's pieces and its extensions
        (its derivative in volume is the pressure)."""
        x = np.asarray(volume, dtype=float)
        if x.shape == (1,):
            # one volume (an actuator alone in its group): on floats, the
            # arithmetic of the arrays below
            v = float(x[0])
            if self._refuse and not self._lo <= v <= self._hi:
                self._beyond(v)
            piece = bisect.bisect_right(self._vl, v)
            b, c0, c1, c2, c3 = self._tl[piece]
            return np.array([_antiderivative(self._wl[piece], c0, c1, c2, c3, v - b)])
        if self._refuse and x.size and not (self._lo <= np.min(x) and np.max(x) <= self._hi):
            self._beyond(x)
        k = np.searchsorted(self.volume, x, side="right")
        return _antiderivative(self._w0[k], self._c0[k], self._c1[k], self._c2[k], self._c3[k],
                               x - self._base[k])

    def _beyond(self, x: float | Array) -> NoReturn:
        lo, hi = self._lo, self._hi
        bad = x if np.ndim(x) == 0 else (np.min(x) if np.min(x) < lo else np.max(x))
        raise CurveRangeError(
            f"PVCurve ({self.origin}): volume {float(bad):.9g} m^3 is beyond its data "
            f"{lo:.9g} ... {hi:.9g} m^3 (extrapolate='error'; 'linear' or 'clamp' continue "
            "the curve there)")

    def _scalar(self, x: float) -> tuple[float, float]:
        if self._refuse and not self._lo <= x <= self._hi:
            self._beyond(x)
        return _volume_laws().curve_point(self._knots, self._table, x)

    def _array(self, x: Array) -> tuple[Array, Array]:
        # the compiled lookup (softflow.laws.volumes.curve_array), any shape
        p, d = np.empty(x.shape), np.empty(x.shape)
        if _volume_laws().curve_array(self._knots, self._table, self._mode, x.ravel(),
                                      p.reshape(-1), d.reshape(-1)) >= 0:
            self._beyond(x)
        return p, d

    def __repr__(self) -> str:
        policy = "" if self.extrapolate == "linear" else f", extrapolate={self.extrapolate!r}"
        if getattr(self, "interpolation", "pchip") != "pchip":
            policy += f", interpolation={self.interpolation!r}"
        return (f"<PVCurve {self.origin}: {len(self.volume)} points, "
                f"V {self.volume[0]:.3g}..{self.volume[-1]:.3g} m^3{policy}>")

    def plot(self, ax: Axes | None = None, *, volume_unit: str = "mL",
             pressure_unit: str = "mbar", gauge: bool = True, points: bool = True,
             extend: float = 0.0, label: str | None = None) -> Axes:
        """Plot the curve (and, with ``points``, the samples it was built from).

        Parameters
        ----------
        ax : matplotlib Axes, optional
            Where to draw (default: a new figure).
        volume_unit, pressure_unit : str
            Display units (default mL and mbar).
        gauge : bool
            Pressure relative to 1 atm (default), else absolute.
        points : bool
            Mark the given samples (as given, before any filter or smoothing).
        extend : float [-]
            Also draw this fraction of the volume range beyond each end (the
            linear continuation the solver uses there).
        label : str, optional
            Legend entry of the curve.

        Returns
        -------
        matplotlib Axes
        """
        from ..units import Q_, UnitError
        v0, v1 = float(self.volume[0]), float(self.volume[-1])
        if not (isinstance(extend, (int, float)) and extend >= 0):
            raise ValueError(f"PVCurve.plot: extend must be a fraction >= 0, got {extend!r}")
        pad = extend * (v1 - v0)
        v = np.unique(np.concatenate([np.linspace(v0 - pad, v1 + pad, 400), self.volume]))
        offset = pressure_atmospheric if gauge else 0.0

        def shown(values: Any, si: str, unit: str, what: str) -> Any:
            try:
                return Q_(values, si).to(unit).magnitude
            except Exception as err:           # pint: undefined unit or wrong dimension
                raise UnitError(f"PVCurve.plot: {what}_unit {unit!r} is not a {what} "
                                f"unit ({err})") from None

        if ax is None:
            import matplotlib.pyplot as plt
            _, ax = plt.subplots()
        line, = ax.plot(shown(v, "m**3", volume_unit, "volume"),
                        shown(self(v) - offset, "Pa", pressure_unit, "pressure"),
                        label=label or f"PV curve ({self.origin})")
        if points:
            ax.plot(shown(self.volume, "m**3", volume_unit, "volume"),
                    shown(self.measured_pressure - offset, "Pa", pressure_unit, "pressure"),
                    ".", color=line.get_color(), alpha=0.6,
                    label="samples" if label is None else f"{label} (samples)")
        ax.set_xlabel(f"volume [{volume_unit}]")
        ax.set_ylabel(f"{'gauge ' if gauge else ''}pressure [{pressure_unit}]")
        ax.legend()
        return ax

    # -- synthetic curves (the shapes of the paper's Figs. 3-5) -----------------------------
    @classmethod
    def monotonic(cls, start: PVPoint, knee: PVPoint, end: PVPoint, *, gauge: bool = False,
                  extrapolate: str = "linear") -> PVCurve:
        """Stiff rise up to ``knee``, softer rise to ``end``: a soft bending actuator.

        Each point is a (volume [m^3], pressure [Pa]) pair (floats or Quantities);
        volumes and pressures must increase. PCHIP through the points and the
        midpoint of knee and end (which keeps the end slope, and so the
        extension beyond ``end``, rising).
        """
        where = "PVCurve.monotonic"
        pts = _key_points(where, ("start", start), ("knee", knee), ("end", end))
        _require(pts, "start", "<", "knee", where)
        _require(pts, "knee", "<", "end", where)
        (vk, pk), (ve, pe) = pts["knee"], pts["end"]
        pts = {"start": pts["start"], "knee": pts["knee"],
               "mid": (0.5 * (vk + ve), 0.5 * (pk + pe)), "end": pts["end"]}
        return _from_points(pts, gauge, "monotonic", extrapolate)

    @classmethod
    def plateau(cls, start: PVPoint, knee: PVPoint, plateau_end: PVPoint, end: PVPoint, *,
                gauge: bool = False, extrapolate: str = "linear") -> PVCurve:
        """Stiff rise to ``knee``, a (nearly) flat plateau to ``plateau_end``, then
        stiffening to ``end`` (the paper's Fig. 4 actuators).

        Points are (volume [m^3], pressure [Pa]) pairs; pressures must not fall
        (equal knee and plateau_end pressures give a flat plateau).
        """
        where = "PVCurve.plateau"
        pts = _key_points(where, ("start", start), ("knee", knee),
                          ("plateau_end", plateau_end), ("end", end))
        _require(pts, "start", "<", "knee", where)
        _require(pts, "knee", "<=", "plateau_end", where)
        _require(pts, "plateau_end", "<", "end", where)
        return _from_points(pts, gauge, "plateau", extrapolate)

    @classmethod
    def peak_valley(cls, start: PVPoint, peak: PVPoint, valley: PVPoint, end: PVPoint, *,
                    gauge: bool = False, extrapolate: str = "linear") -> PVCurve:
        """Rise to ``peak``, fall to ``valley``, rise again to ``end`` (a latex
        balloon; the paper's Figs. 3 and 5).

        Points are (volume [m^3], pressure [Pa]) pairs. PCHIP puts zero slope at
        the peak and the valley, so they are exactly the curve's local maximum
        and minimum.
        """
        where = "PVCurve.peak_valley"
        pts = _key_points(where, ("start", start), ("peak", peak), ("valley", valley),
                          ("end", end))
        _require(pts, "start", "<", "peak", where)
        _require(pts, "valley", "<", "peak", where)
        _require(pts, "valley", "<", "end", where)
        return _from_points(pts, gauge, "peak-valley", extrapolate)


# -- helpers ------------------------------------------------------------------------------


_volume_laws = functools.partial(law_module, "volumes")


def _antiderivative(w0: Any, c0: Any, c1: Any, c2: Any, c3: Any, x: Any) -> Any:
    """w0 plus the integral from 0 to x of c0 + c1 x + c2 x^2 + c3 x^3 (a piece of
    the curve in monomial form: the work along it); floats or arrays alike."""
    return w0 + x * (c0 + x * (c1 / 2 + x * (c2 / 3 + x * c3 / 4)))


def _savgol(p: Array, window: int, order: int, where: str) -> Array:
    if (isinstance(window, bool) or not isinstance(window, (int, np.integer))
            or window < 3 or window % 2 == 0 or window > len(p)):
        raise ValueError(f"{where}: filter_window must be an odd integer >= 3 and <= the "
                         f"number of points ({len(p)}), got {window!r}")
    if (isinstance(order, bool) or not isinstance(order, (int, np.integer))
            or not 0 <= order <= window - 2):
        raise ValueError(f"{where}: filter_order must be an integer from 0 to filter_window - 2 "
                         f"({window - 2}), got {order!r}")
    from scipy.signal import savgol_filter    # lazy: scipy.signal (and .stats) take ~0.4 s
    return savgol_filter(p, int(window), int(order), mode="interp")


def _smoothing_spline(v: Array, p: Array, smoothing: float | str, where: str
                      ) -> tuple[Array, Array]:
    """(values, slopes) at the samples of a cubic smoothing spline through (v, p).

    Its knots are the samples, so cubic Hermite interpolation of these values
    and slopes is the spline itself."""
    if len(v) < MIN_POINTS_SMOOTHING:
        raise ValueError(f"{where}: smoothing needs at least {MIN_POINTS_SMOOTHING} points, "
                         f"got {len(v)}")
    if smoothing is True or (isinstance(smoothing, str) and smoothing == "auto"):
        lam = None
    else:
        try:
            lam = float(smoothing)
        except (TypeError, ValueError):
            lam = -1.0
        if not (np.isfinite(lam) and lam >= 0) or isinstance(smoothing, str):
            raise ValueError(f"{where}: smoothing must be a number >= 0 (dimensionless) or "
                             f"'auto', got {smoothing!r}")
    span_v = v[-1] - v[0]
    mean_p = p.mean()
    span_p = np.ptp(p) or 1.0
    x = (v - v[0]) / span_v
    from scipy.interpolate import make_smoothing_spline
    spl = make_smoothing_spline(x, (p - mean_p) / span_p, lam=lam)
    return spl(x) * span_p + mean_p, spl(x, 1) * (span_p / span_v)


def _key_points(where: str, *named: tuple[str, Any]) -> dict[str, tuple[float, float]]:
    out = {}
    for name, pt in named:
        try:
            vol, pres = pt
        except (TypeError, ValueError):
            raise ValueError(f"{where}: {name} must be a (volume, pressure) pair, "
                             f"got {pt!r}") from None
        vol = to_si(vol, "m**3", name=f"{name} volume", owner=where)
        pres = to_si(pres, "Pa", name=f"{name} pressure", owner=where)
        if not (np.ndim(vol) == 0 and np.ndim(pres) == 0 and np.isfinite(vol)
                and np.isfinite(pres)):
            raise ValueError(f"{where}: {name} must be a pair of finite numbers, got {pt!r}")
        out[name] = (float(vol), float(pres))
    names = list(out)
    for a, b in zip(names, names[1:]):
        if not out[a][0] < out[b][0]:
            raise ValueError(f"{where}: the volume of {b} ({out[b][0]:.6g} m^3) must be larger "
                             f"than that of {a} ({out[a][0]:.6g} m^3)")
    return out


def _require(pts: dict[str, tuple[float, float]], a: str, op: str, b: str, where: str) -> None:
    pa, pb = pts[a][1], pts[b][1]
    if not (pa < pb if op == "<" else pa <= pb):
        raise ValueError(f"{where}: the pressure at {a} ({pa:.6g} Pa) must be {op} the "
                         f"pressure at {b} ({pb:.6g} Pa)")


def _from_points(pts: dict[str, tuple[float, float]], gauge: bool, kind: str,
                 extrapolate: str = "linear") -> PVCurve:
    vols, pres = zip(*pts.values())
    curve = PVCurve(volume=np.array(vols), pressure=np.array(pres), gauge=gauge,
                    extrapolate=extrapolate)
    curve.origin = f"{kind} through {len(vols)} points"
    return curve
