"""The adaptive BDF's error norm (softflow.solve.bdf): the states' and unknowns'
weighted entries in one vector, a discrete state's left out."""
import math

import numpy as np

import softflow as sf
from softflow.solve.bdf import BDF, PEAK_FACTOR
from softflow.solve.newton import Stats
from helpers import snapping_valve_scene

P0 = sf.pressure_atmospheric


def _reference_norm(bdf, asm, S_a, S_b, x, dS, dx):
    """The norm as the module docstring states it, written out entry by entry:
    weights atol + rtol max(|S_a|, |S_b|) for the continuous states, atol +
    rtol max_j |x_j - offset_j| over each unknown's quantity (pressures gauge);
    RMS over the continuous states and the unknowns, or the largest weighted
    entry over PEAK_FACTOR where that is larger."""
    e = []
    for i in asm.s_continuous:
        e.append(dS[i] / (bdf.atol[i] + bdf.rtol * max(abs(S_a[i]), abs(S_b[i]))))
    gauge = np.abs(x - np.where(np.array(asm.x_quantity) == "pressure", P0, 0.0))
    q = np.array(asm.x_quantity)
    for j in range(asm.n):
        scale = gauge[q == q[j]].max()
        e.append(dx[j] / (bdf.atol_x[j] + bdf.rtol * scale))
    e = np.array(e)
    return max(math.sqrt(np.mean(e ** 2)), np.abs(e).max() / PEAK_FACTOR)


def test_the_norm_leaves_discrete_states_out_and_is_the_stated_one():
    sim = sf.Simulation(snapping_valve_scene(), duration=0.1)
    asm = sim.asm
    assert asm.has_discrete and 0 < asm.s_continuous.size < asm.S0.size
    bdf = BDF(asm, None, Stats(), duration=0.1, rtol=1e-3, atol_states=1e-12,
              atol_unknowns=1e-9, step_min=1e-9, step_max=1.0)
    rng = np.random.default_rng(7)
    x = asm.x0 + 1e3 * rng.random(asm.n)
    S_a = asm.S0 * (1 + 0.1 * rng.random(asm.S0.size))
    S_b = asm.S0 * (1 + 0.1 * rng.random(asm.S0.size))
    dS, dx = 1e-6 * rng.standard_normal(asm.S0.size), rng.standard_normal(asm.n)
    dS[asm.s_discrete] = 1.0          # a mode that switched: no part of the error
    w = bdf._weights(S_a, S_b, x)
    assert np.isinf(w[:asm.S0.size][asm.s_discrete]).all()
    ref = _reference_norm(bdf, asm, S_a, S_b, x, dS, dx)
    assert abs(bdf._norm(dS, w, dx) / ref - 1) < 1e-14
    assert bdf._enorm(np.concatenate((dS, dx)), w) == bdf._norm(dS, w, dx)
    # one large entry of the unknowns: the peak over PEAK_FACTOR decides
    dx[3] = 1e6
    assert abs(bdf._norm(dS, w, dx) / _reference_norm(bdf, asm, S_a, S_b, x, dS, dx) - 1) < 1e-14
