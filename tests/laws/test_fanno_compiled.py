"""The compiled adiabatic (Fanno) law (softflow.laws.fanno): the array functions
of softflow.correlations.fanno as loops over the scalar law, the scalar law's
partials against central differences, the entry's Mach number solving its
equation to round-off and held at 1 past the limit, and the pure-Python mode
(NUMBA_DISABLE_JIT=1) giving the same numbers. The law itself (against an
independent solution, its smoothness, its root) is tested in
tests/components/test_fanno_law.py."""
import math

import numpy as np
import pytest

from helpers import compiled_and_python

from softflow.correlations import fanno as arrays
from softflow.laws import fanno as fl

R_AIR = 287.05
GAMMAS = (1.4, 1.3, 5.0 / 3.0)


def _a_max(g):
    return (0.5 * (g + 1.0)) ** (-(g + 1.0) / (g - 1.0))


def _states(g, n=600, seed=0):
    """Random (pa, mf, pb, T0, area, phi): both directions, choked or not, up to
    1.4x the entry's limit, a fifth with p_a ~ p_b, a few at zero flow."""
    rng = np.random.default_rng(seed + int(1000 * g))
    pa = 10.0 ** rng.uniform(4.0, 6.3, n)
    pb = np.where(rng.uniform(size=n) < 0.2, pa * (1.0 + rng.uniform(-0.01, 0.01, n)),
                  10.0 ** rng.uniform(4.0, 6.3, n))
    T0 = rng.uniform(150.0, 900.0, n)
    area = np.pi * rng.uniform(5e-4, 1e-2, n) ** 2 / 4
    s = rng.uniform(-1.0, 1.0, n)
    p0 = np.where(s >= 0, pa, pb)
    mf = np.sign(s) * np.abs(s) ** 1.5 * 1.4 * p0 * np.sqrt(g * _a_max(g) / (R_AIR * T0)) * area
    mf[:5] = 0.0
    phi = rng.uniform(0.0, 1e3, n) * mf / area * 10.0 ** rng.uniform(0, 4, n)
    return pa, mf, pb, T0, area, phi


@pytest.mark.parametrize("g", GAMMAS)
def test_array_law_is_the_scalar_law_elementwise(g):
    pa, mf, pb, T0, area, phi = _states(g)
    out = arrays.adiabatic_pipe(pa, mf, pb, T0, area, R_AIR, g, phi)
    for i in range(pa.size):
        want = fl.adiabatic_pipe(pa[i], mf[i], pb[i], T0[i], area[i], R_AIR, g, phi[i])
        assert tuple(float(v[i]) for v in out[:6]) + (bool(out[6][i]),) == want
    choked = out[6]
    G = np.abs(mf) / area
    past = G * G * R_AIR * T0 / (g * np.where(mf >= 0, pa, pb) ** 2) > _a_max(g)
    assert choked.any() and not choked.all() and past.any() and (mf < 0).any()
    # without jac the same residual and flags, no partials
    noj = arrays.adiabatic_pipe(pa, mf, pb, T0, area, R_AIR, g, phi, jac=False)
    np.testing.assert_array_equal(noj[0], out[0])
    np.testing.assert_array_equal(noj[6], choked)
    assert noj[1:6] == (None,) * 5
    # floats give floats; arrays broadcast to their common shape
    one = arrays.adiabatic_pipe(2e5, 1e-3, 1e5, 300.0, 1e-5, R_AIR, g, 1e3)
    assert all(type(v) is float for v in one[:6])
    assert one[:6] == fl.adiabatic_pipe(2e5, 1e-3, 1e5, 300.0, 1e-5, R_AIR, g, 1e3)[:6]
    grid = arrays.adiabatic_pipe(pa[:6, None], mf[None, :4], 1e5, 300.0, 1e-5, R_AIR, g, 0.0)
    assert all(v.shape == (6, 4) for v in grid)
    assert grid[0][2, 3] == fl.adiabatic_pipe(pa[2], mf[3], 1e5, 300.0, 1e-5, R_AIR, g, 0.0)[0]
    a = np.linspace(0.0, 1.5 * _a_max(g), 201).reshape(3, 67)
    z = arrays.adiabatic_entry_z(a, g)
    assert z.shape == a.shape
    assert [fl.adiabatic_entry_z(float(x), g) for x in a.ravel()] == list(z.ravel())
    assert type(arrays.adiabatic_entry_z(0.1, g)) is float


@pytest.mark.parametrize("g", GAMMAS + (1.05,))
def test_scalar_partials_match_central_differences(g):
    """dR/dpa, dR/dmf, dR/dpb, dR/dT0 and dR/dphi of the scalar law against
    central differences (relative step 1e-6), away (1e-3 relative) from the
    choke's kink, the entry's limit and zero flow: within 1e-8 of |difference|
    + the residual's scale over the variable's (measured: 1e-9)."""
    pa, mf, pb, T0, area, phi = _states(g, n=1500, seed=1)
    K = 0.5 * (g + 1.0)
    fwd = mf >= 0
    p0, pd = np.where(fwd, pa, pb), np.where(fwd, pb, pa)
    W = (mf / area) ** 2 * R_AIR * T0 / g
    keep = ((np.abs(pd * pd * K - W) > 1e-3 * W)
            & (np.abs(W / p0 ** 2 / _a_max(g) - 1.0) > 1e-3)
            & (np.abs(mf) > 1e-5 * area * p0 / 300.0))
    past = W / p0 ** 2 > _a_max(g)
    choked = np.zeros(pa.size, dtype=bool)
    for i in np.flatnonzero(keep):
        pa_, mf_, pb_, T0_, area_, phi_ = (float(v[i]) for v in (pa, mf, pb, T0, area, phi))
        args = [pa_, mf_, pb_, T0_, phi_]

        def R_of(x, area_=area_):
            return fl.adiabatic_pipe(x[0], x[1], x[2], x[3], area_, R_AIR, g, x[4])[0]

        out = fl.adiabatic_pipe(pa_, mf_, pb_, T0_, area_, R_AIR, g, phi_)
        choked[i] = out[6]
        for j in range(5):
            h = 1e-6 * abs(args[j])
            up, down = list(args), list(args)
            up[j] += h
            down[j] -= h
            fd = (R_of(up) - R_of(down)) / (2.0 * h)
            scale = (pa_ + pb_ + abs(out[0])) / abs(args[j])
            assert abs(out[1 + j] - fd) <= 1e-8 * (abs(fd) + scale), (j, i)
    # both directions, choked and not, past the entry's limit
    for flags in (choked, fwd, past):
        assert flags[keep].any() and not flags[keep].all()


@pytest.mark.parametrize("g", GAMMAS + (1.0001, 1.05, 2.0, 3.0))
def test_entry_z_solves_its_equation_to_round_off_and_is_held_at_one_past_the_limit(g):
    """ln z1 - n ln(1 + k z1) = ln a, well conditioned in ln a even at the limit
    (where z1 itself is not), holds to a few ulps of |ln a| from a = 1e-299 a* to
    a* (1 - 1e-15); z1 is 1 from a* on, 0 < z1 < 1 below it, increasing."""
    k, n = 0.5 * (g - 1.0), (g + 1.0) / (g - 1.0)
    a_max = fl.gas_constants(g)[6]       # the law's a* (K^-n may differ from it by an ulp)
    t = np.concatenate([10.0 ** -np.linspace(299.0, 1.0, 400), np.linspace(0.1, 0.99, 200),
                        1.0 - np.logspace(-2, -15, 200)])
    a = t * a_max
    z = np.array([fl.adiabatic_entry_z(float(x), g) for x in a])
    assert np.all((z > 0.0) & (z <= 1.0)) and np.all(np.diff(z) >= 0.0)
    residual = np.log(z) - n * np.log1p(k * z) - np.log(a)
    assert np.all(np.abs(residual) <= 8e-16 * (np.abs(np.log(a)) + n)), \
        float(np.max(np.abs(residual) / (np.abs(np.log(a)) + n)))
    for x in (a_max, a_max * (1.0 + 1e-15), 1.5 * a_max, 10.0, 1e300):
        assert fl.adiabatic_entry_z(x, g) == 1.0
    assert fl.adiabatic_entry_z(0.0, g) < 1e-299
    assert math.isnan(fl.adiabatic_entry_z(math.nan, g))


def test_gamma_not_above_one_is_nan_compiled_and_refused_by_the_arrays():
    assert all(math.isnan(v) for v in fl.gas_constants(1.0))
    out = fl.adiabatic_pipe(3e5, 1e-3, 1e5, 300.0, 1e-5, R_AIR, 0.9, 0.0)
    assert all(math.isnan(v) for v in out[:5])     # dR/dphi = -2 R T0/(pa + pb) has no gamma
    assert math.isnan(fl.adiabatic_entry_z(0.1, 1.0))
    for g in (1.0, 0.5, math.nan):
        with pytest.raises(ValueError, match="gamma"):
            arrays.adiabatic_pipe(3e5, 1e-3, 1e5, 300.0, 1e-5, R_AIR, g, 0.0)
        with pytest.raises(ValueError, match="gamma"):
            arrays.adiabatic_entry_z(0.1, g)


@pytest.mark.slow
def test_pure_python_mode_gives_the_compiled_numbers():
    expression = (
        "[fanno.adiabatic_entry_z(0.2, 1.4), fanno.adiabatic_entry_z(0.5787, 1.4), "
        "fanno.adiabatic_pipe(3e5, 2e-3, 1e5, 300.0, 3e-6, 287.05, 1.4, 1e3)[:6], "
        "fanno.adiabatic_pipe(1e5, -2e-3, 3e5, 300.0, 3e-6, 287.05, 1.3, -1e3)[:6], "
        "fanno.adiabatic_pipe(3e5, 0.2, 1e5, 300.0, 3e-6, 287.05, 5 / 3, 1e3)[:6]]")
    compiled, python, _ = compiled_and_python(expression)
    np.testing.assert_allclose(python, compiled, rtol=1e-15)
