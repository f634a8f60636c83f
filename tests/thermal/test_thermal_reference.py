"""The thermal kernels of an ideal gas, now compiled (softflow.laws.thermal),
against numbers stored from the NumPy kernels they replaced (the commit
before them): each scene's per-group residual and Jacobian entries at seeded
random states to round-off, and whole fixed-step runs (per-group path and
the compiled network residual) to 1e-10 relative. Every thermal class of the
library appears in the scenes (tests/thermal/network_scenes.py).

The stored file was written by this module run as a script with the older
softflow first on the path:

    PYTHONPATH=<old checkout>/src python tests/thermal/test_thermal_reference.py
"""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import softflow as sf

sys.path.insert(0, str(Path(__file__).resolve().parent))
from network_scenes import SCENES  # noqa: E402

DATA = Path(__file__).resolve().parent / "data" / "numpy_kernels_reference.npz"
STATES = 4
STEPS = 40
EVERY = 5


def _states(asm, duration):
    """Seeded random points (x, S, t, dt) around the initial state."""
    rng = np.random.default_rng(11)
    x0, S0 = asm.x0, asm.S0
    for _ in range(STATES):
        x = x0 * (1.0 + 0.05 * rng.standard_normal(asm.n)) + 1e-6 * rng.standard_normal(asm.n)
        S = S0 * (1.0 + 0.05 * rng.standard_normal(S0.size))
        yield x, S, float(rng.uniform(0, duration)), float(10.0 ** rng.uniform(-6, -2))


def _kernels(name, residual="python_residual"):
    """(F, raw) stacked over the states, h·A of correlations set at each state."""
    build, kw, duration = SCENES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        asm = sf.Simulation(build(), duration=duration, **kw).asm
    Fs, raws = [], []
    for x, S, t, dt in _states(asm, duration):
        if asm.has_begin_step:
            asm.begin_step(x, S)
        asm.raw[:] = np.nan
        Fs.append(getattr(asm, residual)(x, S, t, dt, True))
        raws.append(asm.raw.copy())
    return np.array(Fs), np.array(raws)


def _run(name, compiled=True):
    """Pressure, temperature, mass and stored energy of every component that
    has them, every EVERY-th of STEPS fixed steps."""
    build, kw, duration = SCENES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(build(), duration=duration, step=duration / STEPS, **kw)
        if not compiled:
            sim.asm.residual = sim.asm.python_residual
        res = sim.run()
    assert res.success, res.message
    out = []
    for comp in sim.system.components:
        for quantity in ("pressure", "temperature", "mass", "stored_energy"):
            try:
                out.append(res.get(comp.label, quantity)[::EVERY])
            except KeyError:
                pass
    return np.array(out)


@pytest.fixture(scope="module")
def stored():
    return np.load(DATA)


@pytest.mark.parametrize("name", list(SCENES))
def test_the_kernels_are_the_numpy_kernels(name, stored):
    F, raw = _kernels(name)
    np.testing.assert_allclose(F, stored[f"{name}/F"], rtol=1e-14, atol=0.0)
    np.testing.assert_allclose(raw, stored[f"{name}/raw"], rtol=1e-14, atol=0.0)


@pytest.mark.parametrize("name", list(SCENES))
@pytest.mark.parametrize("compiled", [True, False])
def test_fixed_step_runs_are_the_numpy_kernels(name, compiled, stored):
    np.testing.assert_allclose(_run(name, compiled), stored[f"{name}/run"], rtol=1e-10)


if __name__ == "__main__":
    data = {}
    for scene in SCENES:
        data[f"{scene}/F"], data[f"{scene}/raw"] = _kernels(scene)
        data[f"{scene}/run"] = _run(scene, compiled=False)
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, **data)
    print(f"wrote {DATA} ({DATA.stat().st_size} bytes) with {sf.__file__}")
