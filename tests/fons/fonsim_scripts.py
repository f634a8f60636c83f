"""fonsim-0.6-style scripts, written from fonsim's documentation (its
tutorials "A first network", "A more complex network", custom components,
waves and exporting results, and its API reference), one function each.

Each takes the module the script imports as ``fons`` (``fonsim`` itself, or
``softflow.fons``) and the fluids to use, runs the script as written for
fonsim, and returns its key numbers. The bodies use fonsim's API only: that
they run under ``softflow.fons`` is what the tests check; that the numbers
agree with fonsim's is what the side-by-side tests check.
"""
import contextlib
import io
from pathlib import Path

import numpy as np

DATA = Path(__file__).resolve().parents[2] / "examples" / "latex_balloon_60mm_pv.csv"
TIMES = (0.05, 0.1, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.5)


def at(t, series, times):
    times = [x for x in times if x <= t[-1] + 1e-12]
    return np.interp(times, t, series)


def _run(sim):
    # fonsim prints its progress on stdout
    with contextlib.redirect_stdout(io.StringIO()):
        sim.run()


def first_network(fons, air, step=(None, None)):
    """Tutorial 'A first network': a 2 bar source fills a 50 mL container
    through a 60 cm, 2 mm tube; plots as in the tutorial."""
    import matplotlib.pyplot as plt
    system = fons.System()
    mycomponent = fons.PressureSource("source_00", pressure=2e5)
    system.add(mycomponent)
    system.add(fons.Container("container_00", fluid=air, volume=50e-6))
    system.add(fons.CircularTube("tube_00", fluid=air, length=0.60, diameter=2e-3))
    system.connect("tube_00", "source_00")
    system.connect("tube_00", "container_00")
    sim = fons.Simulation(system, duration=0.2, step=step)
    _run(sim)
    fig, axs = plt.subplots(3, sharex=True)
    fons.plot(axs[0], sim, "pressure", "bar", ("source_00", "container_00"))
    fons.plot(axs[1], sim, "massflow", "g/s", (("tube_00", "a"),))
    fons.plot_state(axs[2], sim, "mass", "g", ("container_00",))
    plt.close(fig)
    t = np.asarray(sim.times)
    return {
        "container gauge pressure [Pa]": at(t, system.get("container_00").get("pressure")
                                            - fons.pressure_atmospheric, (0.01, 0.02, 0.05, 0.1, 0.2)),
        "tube massflow [kg/s]": at(t, system.get("tube_00").get("massflow", "a"),
                                   (0.01, 0.05, 0.1)),
        "container mass gain [kg]": at(t, system.get("container_00").get_state("mass")
                                       - system.get("container_00").get_state("mass")[0],
                                       (0.05, 0.2)),
    }


def more_complex_network(fons, air, step=(None, None)):
    """Tutorial 'A more complex network': a stepped wave (0.9, 0.1, 0.5 bar
    gauge) feeds one tube that splits into two tubes and two containers."""
    waves = [(0, 0.900), (0.5, 0.100), (1.0, 0.500)]
    wave_function = fons.wave.Custom(waves) * 1e5 + fons.pressure_atmospheric
    system = fons.System("my_system")
    system += fons.PressureSource("source_00", pressure=wave_function)
    system += fons.CircularTube("tube_00", fluid=air, length=0.25, diameter=2e-3)
    system += fons.CircularTube("tube_01", fluid=air, length=0.50, diameter=2e-3)
    system += fons.CircularTube("tube_02", fluid=air, length=1.00, diameter=2e-3)
    system += fons.Container("container_00", fluid=air, volume=20e-6)
    system += fons.Container("container_01", fluid=air, volume=50e-6)
    system.connect("source_00", "tube_00")
    system.connect(("tube_00", "b"), ("tube_01", "a"))
    system.connect(("tube_00", "b"), ("tube_02", "a"))
    system.connect("tube_01", "container_00")
    system.connect("tube_02", "container_01")
    sim = fons.Simulation(system, duration=1.5, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    p0 = fons.pressure_atmospheric
    return {f"{c} gauge pressure [Pa]": at(t, system.get(c).get("pressure") - p0, TIMES)
            for c in ("container_00", "container_01")}


def two_balloons(fons, water, step=(None, None)):
    """The introductory example: a pressure step inflates two balloon
    actuators (the measured 60 mm latex balloon) through a short and a long
    tube, chained through the first actuator's second terminal."""
    curve = fons.data.PVCurve(str(DATA), pressure_reference="relative")
    system = fons.System()
    system += fons.PressureSource("source", pressure=fons.pressure_atmospheric + 0.35e5)
    system += fons.CircularTube("tube_0", fluid=water, length=0.3, diameter=2e-3)
    system += fons.FreeActuator("actu_0", fluid=water, curve=curve)
    system += fons.CircularTube("tube_1", fluid=water, length=1.5, diameter=1e-3)
    system += fons.FreeActuator("actu_1", fluid=water, curve=curve)
    system.connect("source", "tube_0", "actu_0")
    system.connect(("actu_0", "b"), "tube_1", "actu_1")
    sim = fons.Simulation(system, duration=3.0, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    out = {}
    for label in ("actu_0", "actu_1"):
        actu = system.get(label)
        volume = actu.get_state("mass") / water.rho
        out[f"{label} volume [m^3]"] = at(t, volume, (0.1, 0.25, 0.5, 1.0, 2.0, 3.0))
        out[f"{label} gauge pressure [Pa]"] = at(
            t, actu.get("pressure", "a") - fons.pressure_atmospheric, (0.25, 1.0, 3.0))
    return out


def custom_container(fons, air, step=1e-3):
    """Tutorial 'Custom components': a container written with Component,
    Terminal, Variable, auto and auto_state (and an analytic Jacobian returned
    next to the residual), beside the library Container."""
    class MyContainer(fons.Component):
        def __init__(self, label, fluid, volume):
            super().__init__(label)
            self.set_terminals(fons.Terminal("a", fons.terminal_fluidic,
                                             {"pressure": "p", "massflow": "mf"}))
            m0 = volume * fluid.rho_stp
            self.set_states(fons.Variable("mass", "local", label="m", initial_value=m0,
                                          range=(0, np.inf)))

            @self.auto
            def evaluate(p, m):
                values, jacobian = np.zeros(1), [{}]
                values[0] = p - m / volume / fluid.rho_stp * fons.pressure_atmospheric
                jacobian[0]["p"] = 1.0
                jacobian[0]["m"] = -fons.pressure_atmospheric / volume / fluid.rho_stp
                return values, jacobian
            self.evaluate = evaluate

            @self.auto_state
            def update_state(dt, m, mf):
                return {"m": m + dt * mf}, {"m/mf": dt}
            self.update_state = update_state

    system = fons.System()
    system += fons.PressureSource("source", pressure=fons.wave.Custom(
        [[0.0, 0.1, 0.3], [1.5e5, 2.0e5, 1.0e5]], kind="previous"))
    for i, cls in enumerate((MyContainer, fons.Container)):
        system += fons.CircularTube(f"tube_{i}", fluid=air, length=0.5, diameter=1.5e-3)
        system += cls(f"tank_{i}", fluid=air, volume=30e-6)
        system.connect("source", f"tube_{i}")
        system.connect(f"tube_{i}", f"tank_{i}")
    sim = fons.Simulation(system, duration=0.5, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    return {f"tank_{i} pressure [Pa]": at(t, system.get(f"tank_{i}").get("pressure"),
                                          (0.05, 0.1, 0.2, 0.3, 0.4, 0.5)) for i in (0, 1)}


def accumulator(fons, water, step=1e-3):
    """MassflowSource into a LinearAccumulator(k=...) (water): the pressure
    rises by k·mdot/rho per second."""
    system = fons.System()
    system += fons.MassflowSource("pump", fluid=water, massflow=lambda t: 1e-3 if t < 0.5 else 0)
    system += fons.LinearAccumulator("acc", fluid=water, k=1e9)
    system.connect("pump", "acc")
    sim = fons.Simulation(system, duration=1.0, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    acc = system.get("acc")
    return {"acc gauge pressure [Pa]": at(t, acc.get("pressure") - fons.pressure_atmospheric,
                                          (0.25, 0.5, 1.0)),
            "acc mass gain [kg]": at(t, acc.get_state("mass") - acc.get_state("mass")[0],
                                     (0.25, 1.0))}


def volumeflow_into_container(fons, air, step=1e-3):
    """VolumeflowSource (1 mL/s of air at the container's density) into a
    10 mL Container for 5 s."""
    system = fons.System()
    system += fons.VolumeflowSource("pump", fluid=air, volumeflow=1e-6)
    system += fons.Container("tank", fluid=air, volume=10e-6)
    system.connect("pump", "tank")
    sim = fons.Simulation(system, duration=5.0, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    return {"tank gauge pressure [Pa]": at(t, system.get("tank").get("pressure")
                                           - fons.pressure_atmospheric, (1.0, 2.5, 5.0))}


def restrictor_to_sink(fons, fluid, pressure=1.5e5, step=1e-3):
    """PressureSource -> FlowRestrictor(k=0.6) -> Sink: steady mass flow."""
    system = fons.System()
    system += fons.PressureSource("source", pressure=pressure)
    system += fons.FlowRestrictor("restrictor", fluid=fluid, diameter=1e-3, k=0.6)
    sink = fons.Sink("sink")
    system += sink
    # by object: fonsim 0.6's Sink stores itself as its label, so its label fails there
    system.connect("source", "restrictor", sink)
    sim = fons.Simulation(system, duration=0.01, step=step)
    _run(sim)
    return {"massflow [kg/s]": system.get("restrictor").get("massflow", "a")[-1:]}


def restrictor_fill(fons, air, step=1e-4):
    """PressureSource (1.2 bar) -> FlowRestrictor -> 50 mL Container (air)."""
    system = fons.System()
    system += fons.PressureSource("source", pressure=1.2e5)
    system += fons.FlowRestrictor("restrictor", fluid=air, diameter=0.5e-3, k=0.6)
    system += fons.Container("tank", fluid=air, volume=50e-6)
    system.connect("source", "restrictor", "tank")
    sim = fons.Simulation(system, duration=0.3, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    return {"tank pressure [Pa]": at(t, system.get("tank").get("pressure"),
                                     (0.02, 0.05, 0.1, 0.2, 0.3))}


def check_valve(fons, air, threshold=0.0, step=1e-3):
    """A 2 bar pulse through a tube and a CheckValve(pressure_threshold=...)
    into a Container: the valve keeps the pressure after the pulse."""
    system = fons.System()
    system += fons.PressureSource("source", pressure=fons.wave.Custom(
        [(0, 2e5), (0.5, fons.pressure_atmospheric)]))
    system += fons.CircularTube("tube", fluid=air, length=0.6, diameter=2e-3)
    system += fons.CheckValve("valve", pressure_threshold=threshold)
    system += fons.Container("tank", fluid=air, volume=50e-6)
    system.connect("source", "tube", "valve", "tank")
    sim = fons.Simulation(system, duration=1.0, step=step)
    _run(sim)
    t = np.asarray(sim.times)
    return {"tank pressure [Pa]": at(t, system.get("tank").get("pressure"),
                                     (0.05, 0.1, 0.25, 0.45, 0.75, 1.0))}
