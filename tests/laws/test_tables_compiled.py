"""The table level's compiled interpolants (softflow.laws.tables): one point
evaluated by the scalar functions equals the array path (Bicubic, Cubic)
elementwise, bit for bit; the cell lookup's edge rules; the partials against
central differences; the range checks; a call from other compiled code; and
the pure-Python mode (NUMBA_DISABLE_JIT=1) giving the same numbers."""
import subprocess
import sys

import numba
import numpy as np
import pytest

import softflow as sf
from softflow.fluids.hermite import Bicubic, UniformAxis
from helpers import probe_json
from softflow.laws import tables as tl

# tabulated properties of two shipped tables (a gas's Z, a liquid's density)
# and a synthetic one with rough values, on axes of few cells
CASES = [("air", "Z"), ("air", "viscosity"), ("water", "density"), ("water", "enthalpy")]


def _synthetic():
    x, y = UniformAxis(-1.0, 2.0, 7), UniformAxis(0.0, 5.0, 9)
    return Bicubic(x, y, np.random.default_rng(11).normal(size=(7, 9)))


def _interpolant(case):
    if case == "synthetic":
        return _synthetic()
    name, key = case
    return getattr(sf, name).with_level("table").table.interpolant(key)


def _queries(interp, n=3000, seed=5):
    """Random points across the table and 5 % past its ends, every node, and
    points a hair either side of the interior nodes."""
    X, Y = interp.x, interp.y
    rng = np.random.default_rng(seed)
    xs = [rng.uniform(X.lo - 0.05 * (X.hi - X.lo), X.hi + 0.05 * (X.hi - X.lo), n)]
    ys = [rng.uniform(Y.lo - 0.05 * (Y.hi - Y.lo), Y.hi + 0.05 * (Y.hi - Y.lo), n)]
    gx, gy = np.meshgrid(X.nodes, Y.nodes, indexing="ij")
    xs.append(gx.ravel())
    ys.append(gy.ravel())
    for eps in (-1e-12, 1e-12):
        xs.append(X.nodes[1:-1] * (1 + eps))
        ys.append(rng.uniform(Y.lo, Y.hi, X.n - 2))
        ys.append(Y.nodes[1:-1] * (1 + eps) + eps)
        xs.append(rng.uniform(X.lo, X.hi, Y.n - 2))
    return np.concatenate(xs), np.concatenate(ys)


def _args(interp):
    return interp.cells, interp.x.lo, interp.x.step, interp.y.lo, interp.y.step


@pytest.mark.parametrize("case", CASES + ["synthetic"], ids=str)
def test_point_functions_equal_the_array_path_elementwise(case):
    interp = _interpolant(case)
    x, y = _queries(interp)
    f, fx, fy = interp(x, y, grad=True)
    assert np.array_equal(interp(x, y), f)
    args = _args(interp)
    points = np.array([tl.bicubic_grad(*args, a, b) for a, b in zip(x.tolist(), y.tolist())])
    assert np.array_equal(points, np.stack([f, fx, fy], axis=1))
    assert np.array_equal([tl.bicubic(*args, a, b) for a, b in zip(x.tolist(), y.tolist())], f)
    # scalars through the class: the same numbers, as NumPy floats
    for a, b, want in zip(x[:50], y[:50], points[:50]):
        got = interp(float(a), b, grad=True)
        assert all(type(v) is np.float64 for v in got) and np.array_equal(got, want)
        assert interp(a, np.array(b)) == want[0]
    # the 1-D slice at a temperature between nodes and at a node
    for y0 in (0.37 * interp.y.lo + 0.63 * interp.y.hi, interp.y.nodes[2]):
        line = interp.slice_at_y(y0)
        g, gx = line(x, grad=True)
        assert np.array_equal(line(x), g)
        cx = (line.cells, line.x.lo, line.x.step)
        assert np.array_equal([tl.cubic_grad(*cx, a) for a in x.tolist()],
                              np.stack([g, gx], axis=1))
        assert np.array_equal([tl.cubic(*cx, a) for a in x.tolist()], g)
        # the same function as the 2-D interpolant there (to round-off: the
        # slice's coefficients are summed once in u)
        np.testing.assert_allclose(g, interp(x, np.full_like(x, y0)),
                                   rtol=1e-13, atol=1e-13 * np.abs(f).max())


def test_cell_lookup_edges():
    """Nodes start their cell (t = 0) but the last, which ends the last
    cell; points past the ends take the end cells (t below 0 or above 1);
    NaN takes cell 0 and gives NaN in every part."""
    axis = UniformAxis(1.0, 4.0, 7)                     # step 0.5, cells 0 ... 5
    for k, node in enumerate(axis.nodes):
        i, t = tl.cell(node, axis.lo, axis.step, axis.n)
        assert (i, t) == ((k, 0.0) if k < axis.n - 1 else (axis.n - 2, 1.0))
    assert tl.cell(0.5, 1.0, 0.5, 7) == (0, -1.0)
    assert tl.cell(5.0, 1.0, 0.5, 7) == (5, 3.0)
    i, t = tl.cell(np.nan, 1.0, 0.5, 7)
    assert i == 0 and np.isnan(t)
    i, t = tl.cell(np.inf, 1.0, 0.5, 7)
    assert i == 5 and t == np.inf
    # the array form (UniformAxis.locate) is the scalar function elementwise
    x = np.r_[np.linspace(0.0, 5.0, 301), axis.nodes, np.nan]
    i, t = axis.locate(x)
    want = [tl.cell(v, axis.lo, axis.step, axis.n) for v in x.tolist()]
    assert np.array_equal(i, [w[0] for w in want])
    np.testing.assert_array_equal(t, [w[1] for w in want])
    interp = _synthetic()
    for parts in (interp(np.nan, 1.0, grad=True), interp(0.3, np.array([np.nan]), grad=True),
                  interp.slice_at_y(1.0)(np.array([np.nan, 0.5]), grad=True)):
        assert np.isnan(np.asarray(parts)[..., 0]).all()


@pytest.mark.parametrize("case", CASES + ["synthetic"], ids=str)
def test_partials_match_central_differences(case):
    """Inside the cells (the polynomial is smooth there; the differences' steps
    stay within a cell): d/dx and d/dy of the 2-D interpolant and d/dx of the
    slice against central differences of the values."""
    interp = _interpolant(case)
    X, Y = interp.x, interp.y
    rng = np.random.default_rng(17)
    n = 400
    i, j = rng.integers(0, X.n - 1, n), rng.integers(0, Y.n - 1, n)
    x = X.lo + (i + rng.uniform(0.05, 0.95, n)) * X.step
    y = Y.lo + (j + rng.uniform(0.05, 0.95, n)) * Y.step
    args = _args(interp)
    hx, hy = 1e-5 * X.step, 1e-5 * Y.step
    scale = np.abs(interp(x, y)).max()
    line = interp.slice_at_y(0.5 * (Y.lo + Y.hi))
    cx = (line.cells, line.x.lo, line.x.step)
    for a, b in zip(x.tolist(), y.tolist()):
        _, fx, fy = tl.bicubic_grad(*args, a, b)
        dx = (tl.bicubic(*args, a + hx, b) - tl.bicubic(*args, a - hx, b)) / (2 * hx)
        dy = (tl.bicubic(*args, a, b + hy) - tl.bicubic(*args, a, b - hy)) / (2 * hy)
        assert fx == pytest.approx(dx, rel=1e-6, abs=1e-8 * scale / X.step)
        assert fy == pytest.approx(dy, rel=1e-6, abs=1e-8 * scale / Y.step)
        gx = tl.cubic_grad(*cx, a)[1]
        d = (tl.cubic(*cx, a + hx) - tl.cubic(*cx, a - hx)) / (2 * hx)
        assert gx == pytest.approx(d, rel=1e-6, abs=1e-8 * scale / X.step)


def test_range_checks():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-0.5, 2.5, 200), rng.uniform(-0.5, 2.5, 200)
    for n in (0, 1, 2, 5, 200):
        xs, ys = x[:n], y[:n]
        want = bool(np.all((xs >= 0.0) & (xs <= 2.0)))
        assert tl.inside_span(xs, 0.0, 2.0) is want
        want2 = want and bool(np.all((ys >= 0.0) & (ys <= 2.0)))
        assert tl.inside_box(xs, ys, 0.0, 2.0, 0.0, 2.0) is want2
    ends = np.array([0.0, 2.0])
    assert tl.inside_span(ends, 0.0, 2.0) and tl.inside_box(ends, ends, 0.0, 2.0, 0.0, 2.0)
    assert not tl.inside_span(np.array([1.0, np.nan]), 0.0, 2.0)
    assert not tl.inside_box(ends, np.array([1.0, np.nan]), 0.0, 2.0, 0.0, 2.0)


def test_callable_from_other_compiled_code():
    """A law compiled elsewhere calls the table functions as they are (plain
    arguments: the coefficient arrays and floats)."""
    air = sf.air.with_level("table")
    Z = air.table.interpolant("Z")
    line = air.table.slice("Z", air.temperature)
    R = air.R

    @numba.njit
    def gas_density(cells, x0, dx, y0, dy, line_cells, p, T):
        Zv, Zp, _ = tl.bicubic_grad(cells, x0, dx, y0, dy, p, T)
        Zi = tl.cubic(line_cells, x0, dx, p)
        return p / (Zv * R * T), Zp, Zi

    p, T = 3.3e5, 301.0
    rho, Zp, Zi = gas_density(*_args(Z), line.cells, p, T)
    assert rho == air.density(p, T)
    assert Zp == Z(p, T, grad=True)[1] and Zi == line(p)


def test_reading_a_table_does_not_import_numba():
    """The compiled functions load at the first evaluation, not with the table."""
    probe = ("import sys\nimport softflow as sf\n"
             "fluid = sf.air.with_level('table')\n"
             "before = 'numba' in sys.modules\n"
             "fluid.density(2e5)\n"
             "print(before, 'numba' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True"]


# -- the pure-Python mode and the cache ---------------------------------------------------
_PROBE = """
import json
import numpy as np
import softflow as sf
import softflow.laws as laws
from softflow.laws import tables as tl
air, water = sf.air.with_level('table'), sf.water.with_level('table')
Z = air.table.interpolant('Z')
line = water.table.slice('density', water.temperature)
args = (Z.cells, Z.x.lo, Z.x.step, Z.y.lo, Z.y.step)
pts = [(1.2e5, 250.3), (3.3e5, 301.0), (Z.x.nodes[7], Z.y.nodes[3]), (2.1e7, 430.0),
       (5e3, 200.0)]
out = [tl.bicubic_grad(*args, p, T) for p, T in pts]
out += [tl.bicubic(*args, p, T) for p, T in pts]
out += [tl.cubic_grad(line.cells, line.x.lo, line.x.step, p) for p, _ in pts]
out += [list(tl.cell(p, Z.x.lo, Z.x.step, Z.x.n)) for p, _ in pts]
p = np.array([p for p, _ in pts[:3]])
T = np.array([T for _, T in pts[:3]])
out += [air.density(p, T).tolist(), air.density_dp(p).tolist(),
        water.density(p, 300.0).tolist(), water.enthalpy_dT(p).tolist(),
        [air.density(1.5e5), air.viscosity(2e5, 310.0)]]
hits = sum(len(f.stats.cache_hits) for f in vars(tl).values() if hasattr(f, 'stats'))
print(json.dumps({'values': out, 'jit': not laws.numba.config.DISABLE_JIT, 'hits': hits}))
"""


def _probe(disable_jit):
    return probe_json(_PROBE, NUMBA_DISABLE_JIT=disable_jit)


@pytest.mark.slow
def test_pure_python_mode_gives_the_compiled_numbers_and_the_cache_is_used():
    compiled, python = _probe("0"), _probe("1")
    assert compiled["jit"] and not python["jit"]
    flat = [np.hstack([np.ravel(v) for v in r["values"]]).astype(float)
            for r in (compiled, python)]
    np.testing.assert_array_equal(flat[1], flat[0])
    assert _probe("0")["hits"] > 0           # a second process loads the cache
