"""The nine simulations of the FONS paper's Figs. 3-5, as scene builders.

Every scene has the paper's architecture: a volume-flow source that pumps
1.8 mL/s in, pauses, and pumps the same volume out, then two actuators with a
flow restrictor in front of each:

    pump --R1--> actuator 1 --R2--> actuator 2

(Fig. 5 adds a rigid 100 mL accumulator on actuator 1's node, through a short
wide connector). The paper gives the
shapes of the characteristics, not their numbers; the curves below are
synthetic ones of those shapes, sized for the 1.8 mL/s pump:

* Fig. 3: restrictors negligible; actuator 2 monotonic; actuator 1 monotonic,
  peak-valley or hysteretic.
* Fig. 4: plateau curves, actuator 1's plateau lower; R2 is a tight 2.5 mm ID
  tube, a Tesla valve (the tube's resistance from 1 to 2, higher back) or a
  snapping valve (bursts on inflation, a tight restrictor on deflation).
* Fig. 5: peak-valley curves, actuator 1's peak slightly above actuator 2's
  and its valley much lower; tight tubes; filled with air, water or ethylene
  glycol (one argument differs).

``run(system, fig)`` integrates a scene and returns its Result and wall time;
``figure(fig)`` builds the three scenes of a figure and ``run_figure(fig)`` runs
them and saves the paper's panels C and D (``plot_panels``);
``enclosed_area`` measures the asymmetry of the (V_act1, V_act2) path.

``physics='paper'`` (the default) builds the scenes as the paper models them;
softflow's model checks then warn (ModelWarning) of what that leaves out, each
measured here against a run that models it (pressures relative to the run's
largest gauge pressure, volumes to their swing, at rtol 1e-7 both):

* the water column's inertia in R2 (check ``'tube_inertia'``): Fig. 3
  monotonic 0.5 % of the pressures (0.8 % of the volumes; the flows just
  after the pump stops by half), peak-valley 41 % (71 %), hysteretic 34 %
  (34 %), Fig. 4 tube 4.7 % (1.2 %), Fig. 5 water 7.7 % (8.8 %), glycol 1.1 %
  (0.6 %): the snaps ring through the short wide tube;
* the air's heat exchange with its walls in Fig. 5 (``'thermal_time_scale'``:
  the snaps fill and empty the actuators in ms, against wall time constants
  of 0.4-1.7 s): 57 % of the pressures, 73 % of the volumes, against walls by
  free convection (``thermal='heat_transfer'``);
* Fig. 5's liquids fill the actuators to 19.5 and 27.6 mL, past the 12 mL
  their synthetic curves are drawn to (``'pv_curve_range'``).

``physics='full'`` models them: R2 with ``inertance=True`` (a liquid's),
Fig. 5's curves drawn to 30 mL (the same rise per mL after the valley), and
its gas volumes given walls that exchange heat by free convection
(``sf.FreeConvection('sphere')``), run with ``thermal='heat_transfer'``
(:func:`simulation_options`). The figures keep the paper's behaviour (Fig. 3's
enclosed areas -0.28 and -0.21 against -0.26 and -0.22, Fig. 4's tube 0.049
against 0.048) and run without a ModelWarning; ``examples/paper_fig*.py`` use it.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .components import (Actuator, CircularTube, Container, HystereticActuator,
                         SnappingValve, TeslaValve, VolumeFlowSource)
from .constants import pressure_atmospheric
from .correlations.heat_transfer import FreeConvection
from .curves import HysteresisLoop, PVCurve
from .curves.waveforms import PiecewiseConstant
from .fluids import water
from .network import System

ML = 1e-6          # m^3 per mL
KPA = 1e3          # Pa per kPa

#: pump in at 1.8 mL/s for t_in, pause for T_PAUSE, pump out for t_in; Figs. 3-4
#: pump 14.4 mL (8 s), Fig. 5 45 mL (25 s): with air, the 100 mL accumulator
#: must be compressed by about a fifth before the actuators reach their peaks
FLOW = 1.8 * ML
T_PAUSE = 2.0
T_IN = {3: 8.0, 4: 8.0, 5: 25.0}


def duration(fig):
    return 2 * T_IN[fig] + T_PAUSE


def pump_waveform(t_in):
    """1.8 mL/s in for t_in [s], pause, 1.8 mL/s out for t_in (positive: leaving
    the source)."""
    return PiecewiseConstant([0.0, t_in, t_in + T_PAUSE, 2 * t_in + T_PAUSE],
                             [FLOW, 0.0, -FLOW, 0.0])


def _pv(v_kpa_pairs):
    """Points in (mL, kPa gauge) -> SI (m^3, Pa gauge)."""
    return [(v * ML, p * KPA) for v, p in v_kpa_pairs]


# -- characteristics ---------------------------------------------------------------------
def curve_monotonic(knee_kpa=20.0):
    """A soft bending actuator: stiff to the knee, then soft."""
    start, knee, end = _pv([(1.0, 0.0), (3.0, knee_kpa), (14.0, knee_kpa + 15.0)])
    return PVCurve.monotonic(start, knee, end, gauge=True)


def curve_peak_valley(peak_kpa=28.0, valley_kpa=16.0, volumes=(1.0, 3.5, 7.0, 14.0),
                      end_kpa=None):
    """A balloon-like actuator: rise to a peak, fall to a valley, rise again
    (``volumes``: start, peak, valley and end volumes in mL; ``end_kpa``: the
    end's pressure, default 12 kPa above the peak)."""
    vs, vp, vv, ve = volumes
    start, peak, valley, end = _pv([(vs, 0.0), (vp, peak_kpa), (vv, valley_kpa),
                                    (ve, peak_kpa + 12.0 if end_kpa is None else end_kpa)])
    return PVCurve.peak_valley(start, peak, valley, end, gauge=True)


def loop_hysteretic():
    """Separate inflation and deflation curves joined by snaps."""
    start, peak, valley, end = _pv([(1.0, 0.0), (6.0, 26.0), (4.0, 12.0), (14.0, 40.0)])
    return HysteresisLoop.snapping(start, peak, valley, end, snap_volume=0.3 * ML, gauge=True)


def curve_plateau(level_kpa):
    """Stiff rise to a plateau at ``level_kpa`` (gauge), stiffening after it."""
    start, knee, plateau_end, end = _pv([(1.0, 0.0), (2.0, level_kpa), (7.0, level_kpa + 1.0),
                                         (10.0, level_kpa + 25.0)])
    return PVCurve.plateau(start, knee, plateau_end, end, gauge=True)


# -- restrictors -------------------------------------------------------------------------
#: the two ways to build the scenes (module docstring)
PHYSICS = ("paper", "full")


def _full(physics):
    if physics not in PHYSICS:
        raise ValueError(f"physics must be one of {PHYSICS}, got {physics!r}")
    return physics == "full"


def negligible_tube(label, fluid, inertance=False):
    """A short wide tube (5 cm x 4 mm); ``inertance``: with its liquid column's
    inertia (a gas's tube has none to add)."""
    return CircularTube(label, fluid, length=0.05, diameter=4e-3,
                        inertance=inertance and not fluid.compressible)


def tight_tube(label, fluid, length=1.0, inertance=False):
    """The paper's tight tube: 2.5 mm inner diameter (``inertance`` as above)."""
    return CircularTube(label, fluid, length=length, diameter=2.5e-3,
                        inertance=inertance and not fluid.compressible)


def laminar_conductance(fluid, length, diameter):
    """Hagen-Poiseuille volume-flow conductance pi D^4 / (128 mu L) [m^3/(s Pa)]."""
    return math.pi * diameter ** 4 / (128 * fluid.viscosity(pressure_atmospheric) * length)


# -- scenes ------------------------------------------------------------------------------
def _chain(fig, fluid, act1, act2, r1, r2, accumulator=False):
    """pump --r1--> act1 --r2--> act2; ``accumulator``: True (a rigid 100 mL
    Container) or a volume of one's own, on act1's node."""
    s = System()
    s += VolumeFlowSource("pump", volumeflow=pump_waveform(T_IN[fig]), fluid=fluid)
    s += r1
    s += act1
    s += r2
    s += act2
    s.connect(("pump", "a"), (r1.label, "a"))
    s.connect((r1.label, "b"), (act1.label, "a"))
    s.connect((act1.label, "a"), (r2.label, "a"))
    s.connect((r2.label, "b"), (act2.label, "a"))
    if accumulator:
        # on actuator 1's node, through a short wide connector (two volumes on one
        # node would leave the split of the flow between them undetermined at t = 0)
        s += negligible_tube("R_acc", fluid)
        s += (accumulator if accumulator is not True
              else Container("accumulator", fluid, volume=100 * ML))
        s.connect(("R_acc", "a"), (act1.label, "a"))
        s.connect(("R_acc", "b"), ("accumulator", "a"))
    return s


FIG3_CASES = ("monotonic", "peak-valley", "hysteretic")
FIG4_CASES = ("tube", "tesla", "snapping")
FIG5_FLUIDS = ("air", "water", "ethylene glycol")


def fig3(case, fluid=water, physics="paper"):
    """Fig. 3: actuator 1 'monotonic', 'peak-valley' or 'hysteretic'; negligible
    restrictors (``physics='full'``: R2 with its liquid's inertia)."""
    full = _full(physics)
    if case == "monotonic":
        act1 = Actuator("act1", fluid, curve_monotonic(knee_kpa=16.0))
    elif case == "peak-valley":
        act1 = Actuator("act1", fluid, curve_peak_valley())
    elif case == "hysteretic":
        inflation, deflation = loop_hysteretic()
        act1 = HystereticActuator("act1", fluid, inflation, deflation)
    else:
        raise ValueError(f"fig3: case must be one of {FIG3_CASES}, got {case!r}")
    act2 = Actuator("act2", fluid, curve_monotonic(knee_kpa=20.0))
    return _chain(3, fluid, act1, act2, negligible_tube("R1", fluid),
                  negligible_tube("R2", fluid, inertance=full))


def fig4(case, fluid=water, physics="paper"):
    """Fig. 4: plateau actuators (1 lower than 2) joined by a tight tube, a Tesla
    valve or a snapping valve (``physics='full'``: the tube with its liquid's
    inertia)."""
    full = _full(physics)
    length, diameter = 1.0, 2.5e-3
    if case == "tube":
        r2 = tight_tube("R2", fluid, length, inertance=full)
    elif case == "tesla":
        r2 = TeslaValve("R2", fluid, length=length, diameter=diameter, diodicity=4.0)
    elif case == "snapping":
        # closed: 5x tighter than the tube; open: a short wide passage
        r2 = SnappingValve("R2", fluid, opening_pressure=5 * KPA, closing_pressure=1 * KPA,
                           closed_conductance=laminar_conductance(fluid, length, diameter) / 5,
                           length=0.05, diameter=4e-3)
    else:
        raise ValueError(f"fig4: case must be one of {FIG4_CASES}, got {case!r}")
    act1 = Actuator("act1", fluid, curve_plateau(15.0))
    act2 = Actuator("act2", fluid, curve_plateau(22.0))
    return _chain(4, fluid, act1, act2, negligible_tube("R1", fluid), r2)


def fig5(fluid, physics="paper"):
    """Fig. 5: peak-valley actuators (1's peak slightly higher, its valley much
    lower), tight tubes and a 100 mL accumulator; ``fluid`` is the one line that
    differs between the three simulations. ``physics='full'``: R2 with a
    liquid's inertia, the curves drawn to 30 mL (the same rise per mL after
    the valley as to 12 mL) and a gas's volumes with walls that exchange heat
    by free convection (run it with :func:`simulation_options`)."""
    full = _full(physics)
    vols = (1.0, 2.5, 5.0, 12.0)

    def curve(peak, valley):
        if not full:
            return curve_peak_valley(peak, valley, vols)
        end = 30.0
        rise = (peak + 12.0 - valley) / (vols[3] - vols[2])       # kPa per mL after the valley
        return curve_peak_valley(peak, valley, vols[:3] + (end,),
                                 end_kpa=valley + rise * (end - vols[2]))

    walls = {}
    if full and fluid.compressible:
        walls = dict(heat_transfer_coefficient=FreeConvection("sphere"),
                     area=_sphere_area(vols[2] * ML))
    act1 = Actuator("act1", fluid, curve(21.0, 5.0), **walls)
    act2 = Actuator("act2", fluid, curve(19.0, 14.0), **walls)
    if walls:
        walls["area"] = _sphere_area(100 * ML)
    return _chain(5, fluid, act1, act2, tight_tube("R1", fluid),
                  tight_tube("R2", fluid, inertance=full),
                  accumulator=Container("accumulator", fluid, volume=100 * ML, **walls))


def _sphere_area(volume):
    """Surface [m^2] of a sphere of ``volume`` [m^3]: a volume's wall, for its heat transfer."""
    return math.pi ** (1 / 3) * (6 * volume) ** (2 / 3)


def simulation_options(system):
    """Simulation options a scene needs: ``thermal='heat_transfer'`` where a
    volume has a wall that exchanges heat (Fig. 5's gas with ``physics='full'``)."""
    walls = any(getattr(c, "h_correlation", None) is not None or getattr(c, "hA", None)
                for c in system)
    return {"thermal": "heat_transfer"} if walls else {}


# -- running and measuring ---------------------------------------------------------------
def run(system, fig, **options):
    """Simulate a scene of Fig. ``fig`` over its pump cycle; returns (Result,
    wall time [s])."""
    from .solve import Simulation
    # (the air scene of Fig. 5 drives the accumulator's tube to Mach 0.89 during
    # act1's snap, t = 16.6 s: the default isothermal pipe-flow law models it)
    kw = dict(duration=duration(fig))
    kw.update(options)
    t0 = time.perf_counter()
    sim = Simulation(system, **kw)
    res = sim.run()
    return res, time.perf_counter() - t0


def figure(fig, physics="paper"):
    """[(case label, System)] of the three simulations of Fig. ``fig`` (3, 4 or 5),
    built with ``physics`` ('paper' or 'full', module docstring)."""
    from .fluids import air, ethylene_glycol
    if fig == 3:
        return [(c, fig3(c, physics=physics)) for c in FIG3_CASES]
    if fig == 4:
        return [(c, fig4(c, physics=physics)) for c in FIG4_CASES]
    if fig == 5:
        return [(name, fig5(f, physics=physics))
                for name, f in zip(FIG5_FLUIDS, (air, water, ethylene_glycol))]
    raise ValueError(f"figure: the paper's scenes are Figs. 3, 4 and 5, got {fig!r}")


def run_figure(fig, prefix=None, physics="paper"):
    """Run the three simulations of Fig. ``fig``, print their wall times, steps and
    enclosed areas, and save panels C and D as ``<prefix>_C.png`` and
    ``<prefix>_D.png`` (default prefix ``fig<N>``). Returns the Results.
    ``physics``: 'paper' or 'full' (module docstring)."""
    results, labels = [], []
    for label, system in figure(fig, physics):
        res, wall = run(system, fig, **simulation_options(system))
        v1, v2 = volumes(res)
        print(f"Fig. {fig} {label:16s}: {wall * 1e3:6.1f} ms, {res.stats['steps']:4d} steps, "
              f"enclosed area {enclosed_area(v1, v2) / ML ** 2:+8.2f} mL^2")
        results.append(res)
        labels.append(label)
    paths = plot_panels(results, labels, f"Fig. {fig}", prefix or f"fig{fig}")
    print("saved", *paths)
    return results


def volumes(res):
    """(V_act1, V_act2) [m^3] arrays of a scene's result."""
    return res.get("act1", "volume"), res.get("act2", "volume")


def enclosed_area(v1, v2):
    """Signed area enclosed by the closed path (v1, v2) [m^6] (shoelace formula;
    the path is closed from its last point back to its first)."""
    x = np.append(v1, v1[0])
    y = np.append(v2, v2[0])
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def plot_panels(results, labels, title, prefix):
    """The paper's panel C (V_act1 and V_act2 against time) and panel D (the
    V_act1-V_act2 path) for several results, saved as ``<prefix>_C.png`` and
    ``<prefix>_D.png``; returns the two paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figc, axc = plt.subplots(figsize=(5.5, 4))
    figd, axd = plt.subplots(figsize=(4.5, 4))
    for res, label, color in zip(results, labels, ("C0", "C1", "C2")):
        v1, v2 = volumes(res)
        axc.plot(res.times, v1 / ML, color=color, label=f"{label}: act 1")
        axc.plot(res.times, v2 / ML, color=color, ls="--", label=f"{label}: act 2")
        axd.plot(v1 / ML, v2 / ML, color=color, label=label)
    axc.set(xlabel="time [s]", ylabel="volume [mL]", title=f"{title} C")
    axd.set(xlabel="V_act1 [mL]", ylabel="V_act2 [mL]", title=f"{title} D")
    axc.legend(fontsize=7)
    axd.legend(fontsize=7)
    paths = []
    for fig, panel in ((figc, "C"), (figd, "D")):
        fig.tight_layout()
        path = f"{prefix}_{panel}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
