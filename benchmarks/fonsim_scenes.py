"""Reference scenes run with the ``fonsim`` package, for side-by-side benchmarks.

``fonsim`` (version 0.6, AGPL-3.0) is only *used* here as an installed
third-party library, imported at call time; none of its code is part of
softflow. Install it separately (``pip install fonsim==0.6.0``) to run these
benchmarks.

Two scenes are provided, both returning plain numpy arrays and wall-clock
timings:

* :func:`run_paper_example` -- the example network from section V of the FONS
  paper: a stepped pressure source, a water-filled tube and a user-defined
  actuator component that follows a measured pressure-volume curve.
* :func:`run_chain` -- an air-filled RC ladder: a constant pressure source
  feeding ``N`` (tube -> rigid container) stages in series.

Timings: ``run_seconds`` is ``time.perf_counter()`` around ``Simulation.run()``
only; ``build_run_seconds`` also includes building the components, the
system, the connections and the ``Simulation`` object (which assembles the
dense network matrix). Importing fonsim is excluded from both.

Run as a script for a quick summary::

    python benchmarks/fonsim_scenes.py [N ...]
"""

import contextlib
import io
import sys
import time

from pathlib import Path

import numpy as np

DEFAULT_PV_CSV = str(Path(__file__).resolve().parents[1] / "examples" / "latex_balloon_60mm_pv.csv")


def _import_fonsim():
    """Import fonsim, swallowing the notice it prints to stdout on import."""
    with contextlib.redirect_stdout(io.StringIO()):
        import fonsim
    return fonsim


def _check_step(step):
    """fonsim picks a constant-step Newton solver for a scalar ``step`` and an
    adaptive one for a ``(min, max)`` tuple (``None`` -> its own defaults)."""
    if step is None:
        return (None, None)
    if isinstance(step, tuple):
        return step
    return float(step)


def run_paper_example(csv_path=DEFAULT_PV_CSV, duration=1.0, step=1e-3, *,
                      discretization="backward",
                      relative_solving_tolerance=1e-2, verbose=0):
    """Section V example of the FONS paper, run with fonsim 0.6.

    Network: ``PressureSource -> CircularTube (water, L=0.60 m, d=1 mm) ->
    Actuator``. The source gives absolute pressure ``p0 + 0.3e5`` Pa while
    ``t < 0.5`` s and ``p0`` afterwards, with ``p0 = 1.013e5`` Pa (fonsim's
    standard atmosphere). The actuator is a user-defined component built as in
    the paper's listing: one fluidic terminal (pressure initialised to ``p0``),
    one local state ``mass`` (initial value 1e-3 kg, i.e. about 1.001 mL of
    water), one residual ``p - P(mass / rho_water)`` where ``P`` is the PV
    curve, and the state update ``mass += mf * dt``. Both functions are wrapped
    with ``Component.auto`` / ``auto_state``, so fonsim estimates their
    Jacobians by finite differences (as in the listing).

    Observed behaviour in fonsim 0.6: the finite-difference Jacobians of this
    component come out zero with respect to the mass (the state update's
    sensitivity to ``mf`` is not picked up), so the solver holds the mass
    fixed while it iterates a step. In effect ``p_actu[k] == P(volume[k-1])``:
    the actuator pressure trails the volume by one step (semi-explicit),
    unlike an implicit (backward Euler) update of the actuator.

    CSV handling: no conversion is needed. fonsim's ``PVCurve`` reads the file
    as is: it takes the first all-numeric row as the start of the data, the
    row two above it as column names (matched fuzzily to "volume" and
    "pressure") and the row directly above it as units, which it converts to
    SI ("ml" -> 1e-6 m^3, "mbar" -> 100 Pa). The title line on top is ignored.
    The pressure column is taken as gauge (``pressure_reference="relative"``,
    the default) and ``p0`` is added. The curve is interpolated linearly
    (data held as float32) and clamped to its end values outside the measured
    volume range (no extrapolation, zero slope there).

    :param csv_path: PV curve CSV (title line, names line, units row).
    :param duration: simulated time [s].
    :param step: fixed time step [s]; a ``(min, max)`` tuple or ``None``
                 selects fonsim's adaptive stepping instead.
    :param discretization: 'backward' (fonsim's default), 'forward' or 'tustin'.
    :param relative_solving_tolerance: fonsim's Newton stopping tolerance,
        relative to the range each variable has shown so far (its default
        1e-2, i.e. 1 %; lower it for tighter reference results).
    :param verbose: fonsim verbosity (its default 0). fonsim's stdout is
                    captured either way. Note that in fonsim 0.6 any nonzero
                    value makes the Newton solver print every iteration, and
                    negative values crash its adaptive stepper, so keep 0
                    for timing runs.
    :return: dict with ``times`` [s], ``p_actu`` (absolute, Pa), ``volume``
             (actuator volume, m^3, from the mass state / water density),
             ``p_source`` (Pa), ``massflow`` (into the actuator, kg/s),
             ``run_seconds``, ``build_run_seconds`` and ``steps`` (number of
             time steps taken, i.e. ``len(times) - 1``) and
             ``nonconverged_steps`` (steps where fonsim reported that its
             Newton solver failed to converge).
    """
    fons = _import_fonsim()
    step_arg = _check_step(step)

    t_start = time.perf_counter()
    p0 = fons.pressure_atmospheric
    water = fons.water
    curve = fons.data.pvcurve.PVCurve(str(csv_path))

    class Actuator(fons.Component):
        def __init__(self, label, fluid, pvcurve):
            super().__init__(label)
            p_var = fons.Variable("pressure", "across", label="p",
                                  initial_value=p0)
            mf_var = fons.Variable("massflow", "through", label="mf")
            m_var = fons.Variable("mass", "local", label="mass",
                                  initial_value=1e-3)
            self.set_terminals(fons.Terminal("a", [p_var, mf_var]))
            self.set_states(m_var)

            def residual(t, p, mass):
                return [p - pvcurve.fdf_volume(mass / fluid.rho)[0]]
            self.evaluate = self.auto(residual)

            def advance(dt, mass, mf):
                return {"mass": mass + mf * dt}
            self.update_state = self.auto_state(advance)

    system = fons.System()
    system += fons.PressureSource(
        "source", pressure=lambda t: p0 + (0.3e5 if t < 0.5 else 0.0))
    system += fons.CircularTube(label="tube", fluid=water,
                                length=0.60, diameter=1e-3)
    system += Actuator("actu", fluid=water, pvcurve=curve)
    system.connect("tube", "source")
    system.connect("tube", "actu")

    sim = fons.Simulation(system, duration=duration, step=step_arg,
                          discretization=discretization,
                          relative_solving_tolerance=relative_solving_tolerance,
                          verbose=verbose)
    log = io.StringIO()
    with contextlib.redirect_stdout(log):
        t_run = time.perf_counter()
        sim.run()
        t_end = time.perf_counter()
    failed = log.getvalue().count("failed to converge")

    actu = system.get("actu")
    times = np.array(sim.times, dtype=float)
    return dict(
        times=times,
        p_actu=np.array(actu.get("pressure"), dtype=float),
        volume=np.array(actu.get_state("mass"), dtype=float) / water.rho,
        p_source=np.array(system.get("source").get("pressure"), dtype=float),
        massflow=np.array(actu.get("massflow"), dtype=float),
        run_seconds=t_end - t_run,
        build_run_seconds=t_end - t_start,
        steps=len(times) - 1,
        nonconverged_steps=failed,
    )


def run_chain(N, duration=0.2, step=1e-3, *, discretization="backward",
              relative_solving_tolerance=1e-2, verbose=0):
    """Air-filled ladder ``PressureSource -> (CircularTube -> Container) x N``.

    The source holds absolute pressure ``p0 + 0.2e5`` Pa from ``t = 0``
    (``p0 = 1.013e5`` Pa, fonsim's standard atmosphere). Tube ``i`` (length
    0.2 m, inner diameter 2 mm) joins the node of container ``i-1`` (or the
    source for ``i = 0``) to container ``i`` (rigid, 5e-6 m^3, initially at
    ``p0``, i.e. holding ``5e-6 * 1.23`` kg of air). fonsim's library
    ``CircularTube`` and ``Container`` are used with its ``air`` fluid.

    :param N: number of tube + container stages (>= 1).
    :param duration: simulated time [s].
    :param step: fixed time step [s]; a ``(min, max)`` tuple or ``None``
                 selects fonsim's adaptive stepping instead.
    :param discretization: 'backward' (fonsim's default), 'forward' or 'tustin'.
    :param relative_solving_tolerance: fonsim's Newton stopping tolerance,
        relative to the range each variable has shown so far (its default
        1e-2, i.e. 1 %; lower it for tighter reference results).
    :param verbose: fonsim verbosity (its default 0). fonsim's stdout is
                    captured either way. Note that in fonsim 0.6 any nonzero
                    value makes the Newton solver print every iteration, and
                    negative values crash its adaptive stepper, so keep 0
                    for timing runs.
    :return: dict with ``times`` [s], ``p_first`` and ``p_last`` (absolute
             pressure of the first and last container, Pa), ``p_all``
             (array ``(len(times), N)``), ``run_seconds``,
             ``build_run_seconds``, ``steps`` (``len(times) - 1``) and
             ``nonconverged_steps`` (steps fonsim reported as not converged).
    """
    N = int(N)
    if N < 1:
        raise ValueError("N must be >= 1")
    fons = _import_fonsim()
    step_arg = _check_step(step)

    t_start = time.perf_counter()
    p0 = fons.pressure_atmospheric
    air = fons.air
    system = fons.System()
    system += fons.PressureSource("source", pressure=p0 + 0.2e5)
    for i in range(N):
        system += fons.CircularTube(label=f"tube{i}", fluid=air,
                                    length=0.2, diameter=2e-3)
        system += fons.Container(label=f"cont{i}", fluid=air, volume=5e-6)
    for i in range(N):
        upstream = ("source", "a") if i == 0 else (f"cont{i - 1}", "a")
        system.connect((f"tube{i}", "a"), upstream)
        system.connect((f"tube{i}", "b"), (f"cont{i}", "a"))

    sim = fons.Simulation(system, duration=duration, step=step_arg,
                          discretization=discretization,
                          relative_solving_tolerance=relative_solving_tolerance,
                          verbose=verbose)
    log = io.StringIO()
    with contextlib.redirect_stdout(log):
        t_run = time.perf_counter()
        sim.run()
        t_end = time.perf_counter()
    failed = log.getvalue().count("failed to converge")

    times = np.array(sim.times, dtype=float)
    p_all = np.column_stack([
        np.array(system.get(f"cont{i}").get("pressure"), dtype=float)
        for i in range(N)])
    return dict(
        times=times,
        p_first=p_all[:, 0].copy(),
        p_last=p_all[:, -1].copy(),
        p_all=p_all,
        run_seconds=t_end - t_run,
        build_run_seconds=t_end - t_start,
        steps=len(times) - 1,
        nonconverged_steps=failed,
    )


def _value_at(times, values, t):
    """Value at the first sample with time >= t - 1e-9 (no interpolation)."""
    k = int(np.searchsorted(times, t - 1e-9))
    k = min(k, len(times) - 1)
    return times[k], values[k]


def _main(argv):
    ns = [int(a) for a in argv] or [8]
    r = run_paper_example(DEFAULT_PV_CSV)
    print(f"paper example: steps={r['steps']} run={r['run_seconds']:.3f} s "
          f"build+run={r['build_run_seconds']:.3f} s")
    for t in (0.0, 0.25, 0.5, 0.75, 1.0):
        tk, p = _value_at(r["times"], r["p_actu"], t)
        _, v = _value_at(r["times"], r["volume"], t)
        print(f"  t={tk:.4f} s  p_actu={p:.1f} Pa (gauge {p - 1.013e5:.1f})"
              f"  V={v * 1e6:.4f} mL")
    for n in ns:
        r = run_chain(n)
        print(f"chain N={n}: steps={r['steps']} run={r['run_seconds']:.3f} s "
              f"build+run={r['build_run_seconds']:.3f} s")
        for t in (0.01, 0.05, 0.1, 0.2):
            tk, pf = _value_at(r["times"], r["p_first"], t)
            _, pl = _value_at(r["times"], r["p_last"], t)
            print(f"  t={tk:.4f} s  p_first={pf:.1f} Pa  p_last={pl:.1f} Pa")


if __name__ == "__main__":
    _main(sys.argv[1:])
