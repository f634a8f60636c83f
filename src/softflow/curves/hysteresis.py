"""Hysteretic pressure–volume characteristics: an inflation and a deflation branch.

The FONS paper's hysteretic actuator (Fig. 3, green) has "different PV curves
for inflation and deflation separated by snapping events". softflow models
this as two single-valued branches p(V) that meet at the two ends of the
hysteresis loop, V_lo and V_hi:

* the actuator follows the inflation branch until its volume reaches V_hi,
  the end of the inflation branch, and then the deflation branch;
* it follows the deflation branch until its volume falls to V_lo, the start
  of the deflation branch, and then the inflation branch again.

Beyond the end of its branch (within a step, before the switch is recorded)
an actuator already uses the other curve, so neither branch is ever
extrapolated past the point where it hands over.

A reversal inside the loop retraces the branch the actuator is on: it has not
snapped yet. The snap itself is the steep falling part of a branch (a
negative-stiffness segment); where the network cannot follow it slowly, the
volume jumps there, as on a peak–valley curve. Because the branches meet
where the actuator changes branch, the pressure is continuous at a switch.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterator

import numpy as np

from ..constants import pressure_atmospheric
from ..units import to_si
from .pvcurve import PVCurve, _key_points

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from .._typing import Array, ArrayLike, BoolArray, PVPoint, Scalar

#: Default mismatch allowed where the branches meet, as a fraction of the
#: larger pressure range of the two branches.
MEET_FRACTION = 0.01


class HysteresisLoop:
    """Two PV branches that meet at the ends of a hysteresis loop.

    Parameters
    ----------
    inflation_curve : PVCurve
        p(V) while inflating; its last volume is V_hi, where the actuator
        changes to the deflation branch.
    deflation_curve : PVCurve
        p(V) while deflating; its first volume is V_lo, where the actuator
        changes to the inflation branch.
    meet_tolerance : float [Pa], optional
        Largest pressure difference of the branches at V_lo and V_hi; default
        1 % of the larger pressure range of the two branches.
    owner : str, optional
        Who owns the loop, for error messages (e.g. ``"HystereticActuator 'a1'"``).

    Notes
    -----
    Iterating a loop gives (inflation_curve, deflation_curve), so
    ``HystereticActuator('a', fluid, *loop)`` works.
    """

    def __init__(self, inflation_curve: PVCurve, deflation_curve: PVCurve, *,
                 meet_tolerance: Scalar | None = None, owner: str = "HysteresisLoop") -> None:
        for name, c in (("inflation_curve", inflation_curve),
                        ("deflation_curve", deflation_curve)):
            if not isinstance(c, PVCurve):
                raise TypeError(f"{owner}: {name} must be a PVCurve, got {c!r}")
        self.inflation = inflation_curve
        self.deflation = deflation_curve
        self.volume_high = float(inflation_curve.volume[-1])
        self.volume_low = float(deflation_curve.volume[0])
        if not self.volume_low < self.volume_high:
            raise ValueError(
                f"{owner}: hysteresis branches do not overlap: deflation_curve starts at "
                f"V = {self.volume_low:.6g} m^3, after inflation_curve ends at "
                f"V = {self.volume_high:.6g} m^3")
        if meet_tolerance is None:
            span = max(np.ptp(inflation_curve.pressure), np.ptp(deflation_curve.pressure))
            meet_tolerance = MEET_FRACTION * span
        else:
            meet_tolerance = to_si(meet_tolerance, "Pa", name="meet_tolerance", owner=owner)
            if not (np.ndim(meet_tolerance) == 0 and meet_tolerance >= 0):
                raise ValueError(f"{owner}: meet_tolerance must be a pressure >= 0 [Pa], "
                                 f"got {meet_tolerance!r}")
        self.meet_tolerance = float(meet_tolerance)
        # the branches' work counts where one hands over to the other (work())
        hi, lo = np.array([self.volume_high]), np.array([self.volume_low])
        self._work_shifts = (
            float(inflation_curve.work(hi)[0] - deflation_curve.work(hi)[0]),
            float(deflation_curve.work(lo)[0] - inflation_curve.work(lo)[0]))
        for vol in (self.volume_low, self.volume_high):
            pi = float(inflation_curve(vol))
            pd = float(deflation_curve(vol))
            if abs(pi - pd) > self.meet_tolerance:
                raise ValueError(
                    f"{owner}: hysteresis branches do not meet at V = {vol:.6g} m^3: "
                    f"inflation_curve gives {pi:.6g} Pa, deflation_curve {pd:.6g} Pa "
                    f"(meet_tolerance {self.meet_tolerance:.3g} Pa)")

    def __iter__(self) -> Iterator[PVCurve]:
        return iter((self.inflation, self.deflation))

    def on_inflation_curve(self, volume: float | Array, inflating: bool | ArrayLike) -> BoolArray:
        """Where the inflation curve applies: below V_hi while inflating, at or below
        V_lo while deflating. Past the end of its own branch an actuator is
        already on the other one (they meet there), which is also the branch it
        takes after the step: see :meth:`next_inflating`."""
        return np.where(inflating, volume < self.volume_high, volume <= self.volume_low)

    def fdf_volume(self, volume: float | Array, inflating: bool | ArrayLike
                   ) -> tuple[Array, Array]:
        """Absolute pressure [Pa] and dp/dV [Pa/m^3] at ``volume`` [m^3] (array) of an
        actuator on the inflation branch where ``inflating`` (bool array), on the
        deflation branch elsewhere. Continuous in volume on either branch (to within
        meet_tolerance where the branches hand over)."""
        pi, di = self.inflation.fdf_volume(volume)
        pd, dd = self.deflation.fdf_volume(volume)
        use = self.on_inflation_curve(volume, inflating)
        return np.where(use, pi, pd), np.where(use, di, dd)

    def work(self, volume: Array, inflating: ArrayLike) -> Array:
        """Work [J] done on the wall along the branch an actuator that started the
        step on the inflation branch (``inflating``) or the deflation branch
        follows up to ``volume``: the integral of the pressure :meth:`fdf_volume`
        gives, continuous in volume through the handover to the other branch
        (V_hi while inflating, V_lo while deflating). Counted from each branch's
        own reference, so only differences along one step's branch mean anything
        (a change of branch moves the reference: see
        :class:`softflow.components.thermal.ThermalHystereticActuator`)."""
        vol = np.asarray(volume, dtype=float)
        w_inf, w_dfl = self.inflation.work(vol), self.deflation.work(vol)
        shifts = self._work_shifts
        # inflating: past V_hi on the deflation branch, continued from V_hi;
        # deflating: at or below V_lo on the inflation branch, continued from V_lo
        up = np.where(vol < self.volume_high, w_inf, w_dfl + shifts[0])
        down = np.where(vol > self.volume_low, w_dfl, w_inf + shifts[1])
        return np.where(inflating, up, down)

    def switching(self, volume: Array, inflating: ArrayLike) -> Array:
        """Where the branch changes, as a function that crosses zero there:
        volume - V_hi while inflating, V_lo - volume while deflating (negative
        while the branch holds; :meth:`next_inflating` changes it at >= 0)."""
        vol = np.asarray(volume, dtype=float)
        return np.where(inflating, vol - self.volume_high, self.volume_low - vol)

    def next_inflating(self, volume: float | Array, inflating: bool | ArrayLike) -> BoolArray:
        """Branch after a step that ended at ``volume`` (True: inflation)."""
        return self.on_inflation_curve(volume, inflating)

    def plot(self, ax: Axes | None = None, **kwargs: Any) -> Axes:
        """Plot the inflation and the deflation curve on one Axes (keywords as
        :meth:`PVCurve.plot`); returns the Axes."""
        ax = self.inflation.plot(ax, label="inflation", **kwargs)
        return self.deflation.plot(ax, label="deflation", **kwargs)

    def __repr__(self) -> str:
        return (f"<HysteresisLoop V {self.volume_low:.3g}..{self.volume_high:.3g} m^3>")

    @classmethod
    def snapping(cls, start: PVPoint, peak: PVPoint, valley: PVPoint, end: PVPoint, *,
                 snap_volume: Scalar, gauge: bool = False) -> HysteresisLoop:
        """A synthetic loop with a snap on inflation and a snap back on deflation.

        Inflation rises from ``start`` to ``peak``, then falls within
        ``snap_volume`` to the deflation branch (the snap) and ends there, at
        V_hi = peak volume + snap_volume. Deflation runs from ``end`` down to
        ``valley``, then rises within ``snap_volume`` to the inflation branch
        (the snap back) and ends there, at V_lo = valley volume - snap_volume.
        Below V_lo and above V_hi there is one curve.

        Parameters
        ----------
        start, peak, valley, end : (volume [m^3], pressure [Pa]) pairs
            Floats or Quantities; the volumes must satisfy
            start < valley - snap_volume, valley <= peak + snap_volume,
            valley - snap_volume <= peak and peak + snap_volume < end.
        snap_volume : float [m^3] or Quantity
            Volume over which each snap happens (small: the snap is steep).
        gauge : bool, default False
            The pressures are gauge rather than absolute.
        """
        where = "HysteresisLoop.snapping"
        pts = _key_points(where, ("start", start), ("valley", valley), ("end", end))
        pk = _key_points(where, ("start", start), ("peak", peak), ("end", end))["peak"]
        w = to_si(snap_volume, "m**3", name="snap_volume", owner=where)
        if not (np.ndim(w) == 0 and w > 0):
            raise ValueError(f"{where}: snap_volume must be > 0 [m^3], got {snap_volume!r}")
        p_shift = pressure_atmospheric if gauge else 0.0     # work in absolute pressure
        (vs, ps), (vv, pv), (ve, pe) = pts["start"], pts["valley"], pts["end"]
        vp, pp = pk
        ps, pv, pe, pp = ps + p_shift, pv + p_shift, pe + p_shift, pp + p_shift
        v_lo, v_hi = vv - w, vp + w
        if not (vs < v_lo and v_lo <= vp and vv <= v_hi and v_hi < ve):
            raise ValueError(
                f"{where}: volumes must satisfy start < valley - snap_volume <= peak and "
                f"valley <= peak + snap_volume < end; got start {vs:.6g}, valley {vv:.6g}, "
                f"peak {vp:.6g}, end {ve:.6g}, snap_volume {w:.6g} m^3")
        if not (ps < pp and pv < pe and pv < pp):
            raise ValueError(f"{where}: pressures must satisfy start < peak, valley < end "
                             "and valley < peak")
        # The midpoints make each branch's shape on its own side independent of the
        # other branch: the deflation curve between valley and end does not depend on
        # its first point (the valley is a local minimum, so PCHIP's slope there is 0
        # whatever comes before), the inflation curve between start and peak not on
        # its last. So each branch can take the other's pressure where they meet, exactly.
        vm2, pm2 = 0.5 * (vv + ve), 0.5 * (pv + pe)
        vm1, pm1 = 0.5 * (vs + vp), 0.5 * (ps + pp)

        def deflation(p_lo: float) -> PVCurve:
            return PVCurve(volume=[v_lo, vv, vm2, ve], pressure=[p_lo, pv, pm2, pe])

        p_hi = float(deflation(pp)(v_hi))
        if not p_hi < pp:
            raise ValueError(f"{where}: the deflation branch at peak + snap_volume "
                             f"({p_hi - p_shift:.6g} Pa) must lie below the peak")
        inflation = PVCurve(volume=[vs, vm1, vp, v_hi], pressure=[ps, pm1, pp, p_hi])
        p_lo = float(inflation(v_lo))
        if not p_lo > pv:
            raise ValueError(f"{where}: the inflation branch at valley - snap_volume "
                             f"({p_lo - p_shift:.6g} Pa) must lie above the valley")
        inflation.origin = "snapping loop, inflation"
        defl = deflation(p_lo)
        defl.origin = "snapping loop, deflation"
        return cls(inflation, defl, owner=where)
