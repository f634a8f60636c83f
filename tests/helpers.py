"""Helpers shared by tests: mass balances under every time integrator."""
import numpy as np


def assert_balance(res, stored_change, label, name="massflow", terminal=None, *, scale,
                   sign=1.0, rel=1e-9):
    """stored_change == sign * (time integral of ``label.name`` as the run formed
    it, :meth:`Result.integral`) to ``rel`` of ``scale``: exact but for round-off
    under backward Euler and under every BDF order."""
    supplied = sign * res.integral(label, name, terminal)
    gap = np.abs(stored_change - supplied).max()
    assert gap < rel * scale, (gap / scale, rel)
