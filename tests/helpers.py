"""Helpers shared by tests: a reference circuit, mass balances under every
time integrator."""
import math

import numpy as np

import softflow as sf


def rc_circuit(p1=sf.pressure_atmospheric + 1e4, tau=0.1, D=0.5e-3, L=1.0):
    """Laminar water tube charging a linear accumulator (the fluidic RC circuit):
    p = p1 + (P0 - p1) exp(-t / tau), with R = 128 mu L / (pi D^4), C = tau / R."""
    R = 128 * sf.water.mu * L / (math.pi * D ** 4)
    s = sf.System()
    s += sf.PressureSource("src", pressure=p1)
    s += sf.CircularTube("tube", sf.water, length=L, diameter=D)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=tau / R)
    s.connect("tube", "src")
    s.connect("tube", "acc")
    return s


def assert_balance(res, stored_change, label, name="massflow", terminal=None, *, scale,
                   sign=1.0, rel=1e-9):
    """stored_change == sign * (time integral of ``label.name`` as the run formed
    it, :meth:`Result.integral`) to ``rel`` of ``scale``: exact but for round-off
    under backward Euler and under every BDF order."""
    supplied = sign * res.integral(label, name, terminal)
    gap = np.abs(stored_change - supplied).max()
    assert gap < rel * scale, (gap / scale, rel)
