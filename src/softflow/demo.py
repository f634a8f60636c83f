"""The FONS paper's example scene (section V), packaged for ``softflow demo``.

A pressure source steps 0.3 bar above atmospheric for 0.5 s, filling a latex
balloon actuator (measured peak-valley PV curve) with water through a
0.6 m x 1 mm tube. The actuator is written as a user component, exactly in
the shape of the paper's listing (examples/paper_example.py is the listing).

The tube carries the water column's inertia (``inertance=True``), which the
paper's listing leaves out: there it changes the actuator's and the tube's
pressures by 2.5 % of the 0.3 bar step (measured at rtol 1e-7 with and
without it; the run's own error at the default rtol 1e-3 is 0.1 %), the
actuator's water by 6.8 % of its swing (at 0.09 s), and the flow just after
the source drops at 0.5 s by more than its own size (the column keeps
moving). Without it softflow warns of exactly that (ModelWarning, check
``'tube_inertia'``: "would add 870 Pa ..., 0.029 of the pressures it works
between").
"""
from __future__ import annotations

from importlib import resources

import softflow as sf


def balloon_csv():
    """Path of the packaged measured latex balloon PV curve."""
    return resources.files("softflow") / "data" / "latex_balloon_60mm_pv.csv"


class PaperActuator(sf.Component):
    """The paper's user-written actuator: p = PV(mass / rho), dm/dt = mf.

    Parameters: label : str; fluid : Fluid; pvcurve : PVCurve;
    initial_mass : float [kg] (1 g, as in the paper's listing).
    """

    def __init__(self, label, fluid, pvcurve, initial_mass=1e-3):
        super().__init__(label)
        p0 = sf.pressure_atmospheric
        p_ = sf.Variable("pressure", "across", label="p", initial_value=p0)
        mf_ = sf.Variable("massflow", "through", label="mf")
        m_ = sf.Variable("mass", "local", label="mass", initial_value=initial_mass)
        self.set_terminals(sf.Terminal("a", [p_, mf_]))
        self.set_states(m_)
        rho = fluid.rho

        def evaluate(t, p, mass):
            return [p - pvcurve.fdf_volume(volume=mass / rho)[0]]

        def update_state(dt, mass, mf):
            return {"mass": mass + mf * dt}

        self.evaluate = self.auto(evaluate)
        self.update_state = self.auto_state(update_state)


def paper_system(fluid=None, p0=None, pvcurve=None, inertance=True):
    """Build the paper's source -> tube -> actuator system; ``inertance=False``
    leaves the water column's inertia out, as the paper's listing does (see
    the module docstring: 2.5 % of the pressures, and a ModelWarning)."""
    fluid = sf.water if fluid is None else fluid
    p0 = sf.pressure_atmospheric if p0 is None else p0
    pvcurve = sf.PVCurve(str(balloon_csv())) if pvcurve is None else pvcurve
    system = sf.System()
    system += sf.PressureSource("source", pressure=lambda t: p0 + (0.3e5 if t < 0.5 else 0.0))
    system += sf.CircularTube(label="tube", fluid=fluid, length=0.60, diameter=1e-3,
                              inertance=inertance)
    system += PaperActuator("actu", fluid=fluid, pvcurve=pvcurve)
    system.connect("tube", "source")
    system.connect("tube", "actu")
    return system


def plot(result, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    p0 = sf.pressure_atmospheric
    t = result.times
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(6, 5))
    ax1.plot(t, (result.get("source", "pressure") - p0) * 1e-5, label="source")
    ax1.plot(t, (result.get("actu", "pressure") - p0) * 1e-5, label="actuator")
    ax1.set_ylabel("gauge pressure [bar]")
    ax1.legend()
    ax2.plot(t, result.get("actu", "mass") / sf.water.rho * 1e6)
    ax2.set_ylabel("actuator volume [mL]")
    ax2.set_xlabel("time [s]")
    fig.suptitle("FONS paper example (softflow)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
