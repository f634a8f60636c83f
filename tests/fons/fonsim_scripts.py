"""fonsim-0.6-style scripts, written from fonsim's documentation (its
tutorials "A first network", "A more complex network", custom components,
waves and exporting results, and its API reference), one function each.

Each takes the module the script imports as ``fons`` (``fonsim`` itself, or
``softflow.fons``) and, for the tutorials, the fluid to use (the scripts of
fonsim's conventions, below, use the module's own), runs the script as
written for fonsim, and returns its key numbers. The bodies use fonsim's API
only: that they run under ``softflow.fons`` is what the tests check; that the
numbers agree with fonsim's is what the side-by-side tests check.
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


# -- one script per convention of fonsim's model (issue 39) ------------------------------
# Each takes the module imported as ``fons``, the Simulation's step and, for
# softflow.fons, its own options (rtol=...); it uses the module's own fluids and
# constants and returns its outputs at SAMPLES evenly spaced times of the run (none
# at a jump of a source). The tubes stay laminar (Re < 2300) so that a script shows
# its own convention, not the tubes' laminar-turbulent blend
# (``tube_transition``).
SAMPLES = 40


def _samples(sim, duration, series):
    t = np.asarray(sim.times)
    grid = np.linspace(0.0, duration, SAMPLES)
    return {k: np.interp(grid, t, np.asarray(v, dtype=float)) for k, v in series.items()}


def air_tank_with_leak(fons, step=(None, None), **options):
    """fons.air and the atmosphere: a 1.25 bar source fills a 20 mL tank
    through a 1 m, 0.8 mm tube while a thinner tube leaks it to a Sink at
    the default (atmospheric) pressure; absolute pressure, mass and both flows."""
    system = fons.System()
    system += fons.PressureSource("supply", pressure=1.25e5)
    system += fons.CircularTube("feed", fluid=fons.air, length=1.0, diameter=0.8e-3)
    system += fons.Container("tank", fluid=fons.air, volume=20e-6)
    system += fons.CircularTube("leak", fluid=fons.air, length=1.0, diameter=0.5e-3)
    vent = fons.Sink("vent")
    system += vent
    system.connect("supply", "feed", "tank")
    system.connect(("tank", "a"), ("leak", "a"))
    # by object: fonsim 0.6's Sink stores itself as its label, so its label fails there
    system.connect(("leak", "b"), vent)
    sim = fons.Simulation(system, duration=1.0, step=step, **options)
    _run(sim)
    tank = system.get("tank")
    return _samples(sim, 1.0, {
        "tank pressure [Pa]": tank.get("pressure"),
        "tank mass [kg]": tank.get_state("mass"),
        "feed massflow [kg/s]": system.get("feed").get("massflow", "a"),
        "leak massflow [kg/s]": system.get("leak").get("massflow", "a"),
    })


def water_into_accumulator(fons, step=(None, None), **options):
    """fons.water: a 0.4 bar (gauge) step pushes water through a 1 m, 1 mm
    tube into a LinearAccumulator that holds 2 mL at 1 atm; pressure, mass and
    the tube's flow (the water's viscosity sets the time constant)."""
    p_atm = fons.pressure_atmospheric
    system = fons.System()
    system += fons.PressureSource("pump", pressure=p_atm + 0.4e5)
    system += fons.CircularTube("line", fluid=fons.water, length=1.0, diameter=1e-3)
    system += fons.LinearAccumulator("acc", fluid=fons.water, k=2e10, v0=2e-6)
    system.connect("pump", "line", "acc")
    sim = fons.Simulation(system, duration=1.0, step=step, **options)
    _run(sim)
    acc = system.get("acc")
    return _samples(sim, 1.0, {
        "acc pressure [Pa]": acc.get("pressure"),
        "acc mass [kg]": acc.get_state("mass"),
        "line massflow [kg/s]": system.get("line").get("massflow", "a"),
    })


def tube_transition(fons, fluid_name="air", step=(None, None), **options):
    """Steady flows through a tube (1 m, 0.8 mm) into the atmosphere from
    a range of pressures: laminar, then across the laminar-turbulent band
    (Re 2300 to 4000), where fonsim weighs the two laws linearly in Re."""
    fluid = getattr(fons, fluid_name)
    gauges = ((0.02e5, 0.1e5, 0.3e5, 0.45e5, 0.6e5, 0.8e5, 1.0e5) if fluid_name == "air"
              else (0.1e5, 0.5e5, 1.0e5, 1.5e5, 2.0e5, 3.0e5))
    system = fons.System()
    for i, gauge in enumerate(gauges):
        system += fons.PressureSource(f"high_{i}", pressure=fons.pressure_atmospheric + gauge)
        system += fons.CircularTube(f"tube_{i}", fluid=fluid, length=1.0, diameter=0.8e-3)
        system += fons.PressureSource(f"low_{i}", pressure=fons.pressure_atmospheric)
        system.connect(f"high_{i}", f"tube_{i}")
        system.connect((f"tube_{i}", "b"), f"low_{i}")
    sim = fons.Simulation(system, duration=0.01, step=1e-3)
    _run(sim)
    return {"massflow [kg/s]": np.array([system.get(f"tube_{i}").get("massflow", "a")[-1]
                                         for i in range(len(gauges))])}


def constants_and_module_paths(fons):
    """fonsim's module paths and constants, imported the way a fonsim script
    does (``import fonsim.constants.norm as cnorm`` ...), with their values."""
    import importlib
    base = fons.__name__
    norm = importlib.import_module(f"{base}.constants.norm")
    physical = importlib.import_module(f"{base}.constants.physical")
    pvcurve = importlib.import_module(f"{base}.data.pvcurve")
    custom = importlib.import_module(f"{base}.wave.custom")
    plotting = importlib.import_module(f"{base}.visual.plotting")
    assert fons.wave.wave.sine is fons.wave.sine
    assert fons.visual.plotting.plot is fons.plot
    assert fons.cnorm is norm and fons.cphy is physical
    assert pvcurve.PVCurve is fons.data.PVCurve and custom.Custom is fons.wave.Custom
    assert plotting.plot_state is fons.plot_state
    return {
        "atmospheric pressure [Pa]": np.array([norm.pressure_atmospheric,
                                               fons.pressure_atmospheric]),
        "temperature [K]": np.array([norm.temperature, fons.temperature]),
        "gas constant [J/mol/K]": np.array([physical.gas_constant, fons.gas_constant]),
        "air rho_stp, mu": np.array([fons.air.rho_stp, fons.air.mu]),
        "water rho, mu": np.array([fons.water.rho, fons.water.mu]),
    }


def pv_curve_conventions(fons):
    """fons.data.PVCurve read as fonsim reads it: the pressure beyond the
    data (held by default, whatever the derivative option), the interpolated
    initial volume at a pressure, and the autocorrected series."""
    rel = fons.data.PVCurve(str(DATA), pressure_reference="relative")
    held = fons.data.PVCurve(str(DATA), extrapolate=True)
    held_d = fons.data.PVCurve(str(DATA), extrapolate_derivative=True)
    shifted = fons.data.PVCurve(str(DATA), autocorrect=True)
    outside = (0.2e-6, 0.9e-6, 58e-6, 80e-6)
    p_atm = fons.pressure_atmospheric
    return {
        "pressure beyond the data [Pa]": np.array(
            [c.fdf_volume(v)[0] - p_atm for c in (rel, held, held_d) for v in outside]),
        "slope beyond the data, default [Pa/m^3]": np.array([rel.fdf_volume(v)[1]
                                                             for v in outside]),
        "initial volume at pressure [m^3]": np.array([rel.get_initial_volume(p_atm + dp)
                                                      for dp in (0.1e5, 0.2e5, 0.5e5, 0.8e5)]),
        "autocorrected volumes [m^3]": np.asarray(shifted.v, dtype=float),
        "autocorrected gauge pressures [Pa]": np.asarray(shifted.p, dtype=float) - p_atm,
    }


def pv_curve_between_samples(fons):
    """A PV curve between its samples: fonsim interpolates straight lines,
    softflow monotone cubics (PCHIP)."""
    curve = fons.data.PVCurve(str(DATA))
    v = np.asarray(curve.v, dtype=float)
    mid = 0.5 * (v[:-1] + v[1:])
    return {"pressure between samples [Pa]": np.array([curve.fdf_volume(x)[0] for x in mid])
            - fons.pressure_atmospheric}


def actuator_drained_below_its_data(fons, step=(None, None), **options):
    """A water-filled balloon (a PVCurve object: its data start at 1 mL and
    22 mbar) at 3 mL drains through a tube to the atmosphere, past its first
    sample, where the curve holds its first pressure."""
    curve = fons.data.pvcurve.PVCurve(str(DATA), pressure_reference="relative")
    system = fons.System()
    system += fons.FreeActuator("balloon", fluid=fons.water, curve=curve, initial_volume=3e-6)
    system += fons.CircularTube("tube", fluid=fons.water, length=0.5, diameter=0.8e-3)
    system += fons.PressureSource("atmosphere", pressure=fons.pressure_atmospheric)
    system.connect(("balloon", "a"), "tube", "atmosphere")
    sim = fons.Simulation(system, duration=8.0, step=step, **options)
    _run(sim)
    balloon = system.get("balloon")
    return _samples(sim, 8.0, {
        "balloon gauge pressure [Pa]": balloon.get("pressure", "a") - fons.pressure_atmospheric,
        "balloon mass [kg]": balloon.get_state("mass"),
        "tube massflow [kg/s]": system.get("tube").get("massflow", "a"),
    })


def _inflate(fons, fluid, curve, duration, gauge, tube, step, initial_volume=None, **options):
    system = fons.System()
    system += fons.PressureSource("source", pressure=fons.pressure_atmospheric + gauge)
    system += fons.CircularTube("tube", fluid=fluid, length=tube[0], diameter=tube[1])
    kw = {} if curve is None else {"curve": curve}
    if initial_volume is not None:
        kw["initial_volume"] = initial_volume
    system += fons.FreeActuator("actuator", fluid=fluid, **kw)
    system.connect("source", "tube", "actuator")
    sim = fons.Simulation(system, duration=duration, step=step, **options)
    _run(sim)
    act = system.get("actuator")
    return _samples(sim, duration, {
        "actuator gauge pressure [Pa]": act.get("pressure", "a") - fons.pressure_atmospheric,
        "actuator mass [kg]": act.get_state("mass"),
        "tube massflow [kg/s]": system.get("tube").get("massflow", "a"),
    })


def actuator_curve_file_water(fons, step=(None, None), **options):
    """FreeActuator(curve='file.csv') with water, filled from 0.5 bar gauge:
    fonsim shifts the file's curve to start at 0 mL and 1 atm and starts the
    actuator there, empty."""
    return _inflate(fons, fons.water, str(DATA), 3.0, 0.5e5, (1.0, 1e-3), step, **options)


def actuator_curve_file_air(fons, step=(None, None), **options):
    """FreeActuator(curve='file.csv') with air, filled from 0.3 bar gauge."""
    return _inflate(fons, fons.air, str(DATA), 0.4, 0.3e5, (1.0, 0.8e-3), step, **options)


def actuator_default_curve(fons, step=(None, None), **options):
    """FreeActuator without a curve: fonsim's default, the 60 mm latex
    balloon it ships, read as a curve file."""
    return _inflate(fons, fons.water, None, 3.0, 0.5e5, (1.0, 1e-3), step, **options)


def actuator_initial_volume_minimum_air(fons, step=(None, None), **options):
    """FreeActuator(initial_volume='minimum') on a PVCurve object (its data
    start at 1 mL, 22 mbar), air: fonsim gives it the mass 1 mL holds at
    1 atm, so it starts slightly compressed."""
    curve = fons.data.PVCurve(str(DATA))
    return _inflate(fons, fons.air, curve, 0.4, 0.3e5, (1.0, 0.8e-3), step,
                    initial_volume="minimum", **options)


def actuator_initial_volume_auto_water(fons, step=(None, None), **options):
    """FreeActuator(initial_volume='auto') on a curve whose data cross 1 atm
    (the file shifted down by 0.1 bar): fonsim starts where the straight line
    between the two samples around 1 atm reaches it."""
    curve = fons.data.PVCurve(str(DATA), autocorrect=(False, lambda p: p - 0.1e5))
    return _inflate(fons, fons.water, curve, 3.0, 0.4e5, (1.0, 1e-3), step,
                    initial_volume="auto", **options)


def empty_accumulator(fons, fluid_name, step=(None, None), **options):
    """LinearAccumulator with fonsim's default v0 = 0 (empty at p0), filled
    through a tube from 0.25 bar gauge, then emptied to 0.1 bar gauge."""
    fluid = getattr(fons, fluid_name)
    p_atm = fons.pressure_atmospheric
    k = 5e10 if fluid_name == "water" else 2e9
    tube = (0.5, 1e-3) if fluid_name == "water" else (1.0, 0.8e-3)
    system = fons.System()
    system += fons.PressureSource("source", pressure=fons.wave.Custom(
        [(0.0, p_atm + 0.25e5), (0.5, p_atm + 0.1e5)]))
    system += fons.CircularTube("tube", fluid=fluid, length=tube[0], diameter=tube[1])
    system += fons.LinearAccumulator("acc", fluid=fluid, k=k)
    system.connect("source", "tube", "acc")
    sim = fons.Simulation(system, duration=1.0, step=step, **options)
    _run(sim)
    acc = system.get("acc")
    return _samples(sim, 1.0, {
        "acc gauge pressure [Pa]": acc.get("pressure") - p_atm,
        "acc mass [kg]": acc.get_state("mass"),
        "tube massflow [kg/s]": system.get("tube").get("massflow", "a"),
    })


def gas_accumulator_off_atmosphere(fons, step=(None, None), **options):
    """LinearAccumulator(air, p0 = 1.5 bar, v0 = 5 mL): fonsim fills it with
    the mass 5 mL hold at 1 atm, so it starts below p0, and a 1.3 bar source
    tops it up."""
    system = fons.System()
    system += fons.PressureSource("source", pressure=1.3e5)
    system += fons.CircularTube("tube", fluid=fons.air, length=1.0, diameter=0.8e-3)
    system += fons.LinearAccumulator("acc", fluid=fons.air, k=1e10, p0=1.5e5, v0=5e-6)
    system.connect("source", "tube", "acc")
    sim = fons.Simulation(system, duration=0.5, step=step, **options)
    _run(sim)
    acc = system.get("acc")
    return _samples(sim, 0.5, {
        "acc pressure [Pa]": acc.get("pressure"),
        "acc mass [kg]": acc.get_state("mass"),
        "tube massflow [kg/s]": system.get("tube").get("massflow", "a"),
    })


def restrictor_mean_density(fons, step=(None, None), **options):
    """FlowRestrictor with air across a large pressure ratio: a 2.5 bar source
    fills a 20 mL tank through a 0.4 mm restrictor, which a second one (1 mm)
    vents to a Sink; fonsim takes the density at the mean pressure."""
    system = fons.System()
    system += fons.PressureSource("supply", pressure=2.5e5)
    system += fons.FlowRestrictor("inlet", fluid=fons.air, diameter=0.4e-3, k=0.6)
    system += fons.Container("tank", fluid=fons.air, volume=20e-6)
    system += fons.FlowRestrictor("outlet", fluid=fons.air, diameter=0.3e-3, k=0.8)
    vent = fons.Sink("vent")
    system += vent
    system.connect("supply", "inlet", "tank")
    system.connect(("tank", "a"), ("outlet", "a"))
    system.connect(("outlet", "b"), vent)
    sim = fons.Simulation(system, duration=0.5, step=step, **options)
    _run(sim)
    tank = system.get("tank")
    return _samples(sim, 0.5, {
        "tank pressure [Pa]": tank.get("pressure"),
        "tank mass [kg]": tank.get_state("mass"),
        "inlet massflow [kg/s]": system.get("inlet").get("massflow", "a"),
        "outlet massflow [kg/s]": system.get("outlet").get("massflow", "a"),
    })


def check_valve_charging(fons, step=(None, None), **options):
    """An ideal CheckValve (no threshold) between a tube and a 20 mL tank,
    charging from 1.25 bar: fonsim's valve adds no resistance once open, so
    the tank fills as through the tube alone. (Only while the source
    pushes: once it drops, fonsim 0.6's valve lets air back.)"""
    system = fons.System()
    system += fons.PressureSource("source", pressure=1.25e5)
    system += fons.CircularTube("tube", fluid=fons.air, length=1.0, diameter=0.8e-3)
    system += fons.CheckValve("valve")
    system += fons.Container("tank", fluid=fons.air, volume=20e-6)
    system.connect("source", "tube", "valve", "tank")
    sim = fons.Simulation(system, duration=0.4, step=step, **options)
    _run(sim)
    return _samples(sim, 0.4, {
        "tank pressure [Pa]": system.get("tank").get("pressure"),
        "valve inlet pressure [Pa]": system.get("valve").get("pressure", "a"),
        "tube massflow [kg/s]": system.get("tube").get("massflow", "a"),
    })
