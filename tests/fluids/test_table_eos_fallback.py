"""The table level with ``out_of_range='eos'``: every property method gives the
eos level's values, for scalars and arrays, with all points in the table, all
outside it, or some of each (issue 41: the derivative methods failed whenever
the in-table part of a call was empty).

Tolerances against the eos fluid:
- outside the table: the table fluid hands the states to CoolProp, so the
  values are the eos fluid's own (compared to 1e-12, round-off only);
- inside, values: the table's recorded error bound of the property (relative,
  or absolute over the tabulated span, as the metadata says); gamma = cp/cv
  the sum of the cp and cv bounds; conductivity is CoolProp's at this level;
- inside, derivatives: the interpolant's exact derivative. For a cubic spline
  the value error is O(h^4 f'''') and the slope error O(h^3 f''''), with
  classical constants 5/384 and 1/24: a slope error of about 3.2 x (value
  error) / h. So a derivative of f along an axis of step h is allowed
  DERIVATIVE_FACTOR x (f's recorded bound) x (f's scale) / h. Measured on the
  shipped air and water tables (20 000 random points and the table's edges)
  the largest ratio is 3.26, at the lowest tabulated temperature; 8 leaves a
  margin of 2.5.
"""
import inspect
import math
import warnings

import numpy as np
import pytest

import softflow as sf
from softflow.fluids.base import PROPERTY_UNITS
from softflow.fluids.hermite import Bicubic, UniformAxis
from softflow.fluids.tabulated import TableFluid

NAMES = ["air", "water"]
METHODS = sorted(PROPERTY_UNITS)
DERIVATIVE_FACTOR = 8.0
ROUND_OFF = 1e-12

# states outside each table (air: 10 kPa ... 20 MPa, 233.15 ... 423.15 K;
# water: 50 kPa ... 20 MPa, 274.15 ... 368.15 K), all within CoolProp's range:
# pressures below and above at the fluid's temperature (the T=None form) ...
OUTSIDE_P = {"air": [5e3, 9.9e3, 20.5e6, 30e6], "water": [20e3, 49e3, 25e6, 30e6]}
# ... and (p, T) pairs with the temperature, or both, outside
OUTSIDE_PT = {
    "air": [(1e5, 200.0), (1e5, 500.0), (5e3, 500.0), (30e6, 200.0), (2e6, 233.0),
            (2e6, 423.5), (5e3, 293.15), (30e6, 293.15)],
    "water": [(0.2e6, 273.5), (1e6, 370.0), (10e6, 380.0), (30e6, 273.5), (20e3, 380.0),
              (20e3, 293.15), (30e6, 293.15)],
}


@pytest.fixture(scope="module", params=NAMES)
def fluids(request):
    base = getattr(sf, request.param)
    return (request.param, base.with_level("table", out_of_range="eos"),
            base.with_level("eos"))


def _inside_states(table, n_random=12):
    """(p, T) inside the table: its corners and edges, a few interior states and
    seeded random ones."""
    (p_lo, p_hi), (T_lo, T_hi) = table.p_range, table.T_range
    p = np.array([p_lo, p_lo * 1.5, 1.01325e5, 0.3 * p_hi, p_hi])
    T = np.array([T_lo, 0.6 * T_lo + 0.4 * T_hi, table.temperature, T_hi])
    P, TT = (a.ravel() for a in np.meshgrid(p, T))
    rng = np.random.default_rng(41)
    P = np.concatenate([P, rng.uniform(p_lo, p_hi, n_random)])
    TT = np.concatenate([TT, rng.uniform(T_lo, T_hi, n_random)])
    return P, TT


def _inside_pressures(table):
    p_lo, p_hi = table.p_range
    return np.concatenate([[p_lo, 1.01325e5, 2.5e6, p_hi],
                           np.random.default_rng(7).uniform(p_lo, p_hi, 8)])


def _bound(table, key):
    return table.table.error_bound(key), table.table.meta["properties"][key]["error_measure"]


def _value_scale(table, key, values):
    """The scale a recorded bound multiplies: |value| or the tabulated span."""
    bound, measure = _bound(table, key)
    scale = np.abs(values) if measure == "relative" else np.ptp(table.table.values[key])
    return bound * scale


def _allowed(table, eos, method, p, T):
    """Largest |table - eos| accepted at states inside the table (see the module
    docstring); T None: the fluid's temperature."""
    want = getattr(eos, method)(p, T)
    slack = 4 * np.finfo(float).eps * np.abs(want)
    if method == "conductivity":
        return slack
    if method == "gamma":
        return (_bound(table, "cp")[0] + _bound(table, "cv")[0]) * np.abs(want) + slack
    if method == "compressibility":     # Z tabulated for gases, p / (rho R T) for liquids
        return _value_scale(table, "density" if table.liquid else "Z", want) + slack
    base, _, axis = method.rpartition("_")
    if axis not in ("dp", "dT"):
        return _value_scale(table, method, want) + slack
    step = (table.table.p_axis if axis == "dp" else table.table.T_axis).step
    f = getattr(eos, base)(p, T)
    return DERIVATIVE_FACTOR * _value_scale(table, base, f) / step + slack


def _assert_eos_values(got, want):
    np.testing.assert_allclose(got, want, rtol=ROUND_OFF, atol=0)


def test_the_methods_checked_are_every_property_method_of_a_table_fluid():
    """Every public method called as f(p, T=None) is a property in
    PROPERTY_UNITS, so a method added later is checked here too."""
    found = {name for name, member in inspect.getmembers(TableFluid, inspect.isfunction)
             if not name.startswith("_")
             and list(inspect.signature(member).parameters)[1:] == ["p", "T"]}
    assert found == set(METHODS)


# -- (a) every point inside the table ------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_inside_the_table_within_its_recorded_error(fluids, method):
    name, table, eos = fluids
    p, T = _inside_states(table)
    got, want = getattr(table, method)(p, T), getattr(eos, method)(p, T)
    err, allowed = np.abs(got - want), _allowed(table, eos, method, p, T)
    assert np.all(err <= allowed), (name, method, p[np.argmax(err / allowed)],
                                    T[np.argmax(err / allowed)], np.max(err / allowed))
    # the isothermal form (1-D slice at the fluid's temperature)
    p1 = _inside_pressures(table)
    got, want = getattr(table, method)(p1), getattr(eos, method)(p1)
    assert np.all(np.abs(got - want) <= _allowed(table, eos, method, p1, None)), (name, method)


# -- (b) every point outside the table ----------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_outside_the_table_gives_the_eos_values(fluids, method):
    name, table, eos = fluids
    f, ref = getattr(table, method), getattr(eos, method)
    p_iso = np.array(OUTSIDE_P[name])
    p, T = np.array(OUTSIDE_PT[name]).T
    _assert_eos_values(f(p_iso), ref(p_iso))                        # T=None, 1-D
    _assert_eos_values(f(p, T), ref(p, T))                          # T given, 1-D
    k = p.size // 2 * 2
    p2, T2 = p[:k].reshape(2, -1), T[:k].reshape(2, -1)
    _assert_eos_values(f(p2, T2), ref(p2, T2))                      # T given, 2-D
    for pk in p_iso:                                                # scalars, T=None
        assert f(pk) == pytest.approx(ref(pk), rel=ROUND_OFF, abs=0)
        assert f(np.float64(pk)) == pytest.approx(ref(pk), rel=ROUND_OFF, abs=0)
    for pk, Tk in zip(p, T):                                        # scalars, T given
        assert f(pk, Tk) == pytest.approx(ref(pk, Tk), rel=ROUND_OFF, abs=0)


def test_outside_coolprop_too_raises_as_the_eos_level_does(fluids):
    _, table, eos = fluids
    for p, T in ((-1e3, None), (1e5, 30.0), (np.array([np.nan, 1e5]), None)):
        for method in ("density", "density_dp", "enthalpy_dT", "internal_energy_dp"):
            with pytest.raises(sf.FluidError):
                getattr(eos, method)(p, T)
            with pytest.raises(sf.FluidError):
                getattr(table, method)(p, T)


# -- (c) mixed arrays -------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_mixed_arrays_take_each_state_from_its_own_side(fluids, method):
    """The states outside take the eos values; those inside the same numbers as
    in a call with only in-table states (a state's value does not depend on
    the rest of the call)."""
    name, table, eos = fluids
    f, ref = getattr(table, method), getattr(eos, method)
    p_in, T_in = _inside_states(table, n_random=0)
    p_in, T_in = p_in[:4], T_in[:4]
    p_out, T_out = np.array(OUTSIDE_PT[name][:4]).T
    p = np.stack([np.r_[p_in[:2], p_out[:2]], np.r_[p_out[2:], p_in[2:]]])    # (2, 4)
    T = np.stack([np.r_[T_in[:2], T_out[:2]], np.r_[T_out[2:], T_in[2:]]])
    inside = np.array([[True, True, False, False], [False, False, True, True]])
    got = f(p, T)
    assert got.shape == (2, 4)
    _assert_eos_values(got[~inside], ref(p[~inside], T[~inside]))
    assert np.array_equal(got[inside], f(p[inside], T[inside]))
    # the isothermal form
    p_iso = np.array([table.p_range[0], OUTSIDE_P[name][0], 2e6, OUTSIDE_P[name][-1]])
    inside_iso = np.array([True, False, True, False])
    got = f(p_iso)
    _assert_eos_values(got[~inside_iso], ref(p_iso[~inside_iso]))
    assert np.array_equal(got[inside_iso], f(p_iso[inside_iso]))


# -- (d) scalars give scalars, arrays keep their shapes ---------------------------------
def _queries(table, name):
    """(p, T) pairs of every form, inside and outside the table."""
    p_in, (p_out, T_out) = 2e6, OUTSIDE_PT[name][1]
    T_in = table.temperature
    return [
        (p_in, None), (p_out, None), (OUTSIDE_P[name][0], None), (p_in, T_in), (p_out, T_out),
        (np.float64(p_in), None), (np.array(p_in), None), (np.array(OUTSIDE_P[name][0]), None),
        (np.array(p_out), np.array(T_out)), (np.array(p_in), np.array(T_in)),
        (np.array([p_in]), None), (np.array([OUTSIDE_P[name][0]]), None),
        (np.array([p_out]), np.array([T_out])),
        (np.full((2, 3), p_in), None), (np.full((2, 3), OUTSIDE_P[name][-1]), None),
        (np.full((2, 3), p_out), T_out), (p_in, np.full((3, 2), T_in)),
        (np.array([[p_in], [OUTSIDE_P[name][0]]]), np.array([T_in, T_out, T_in])),
        (np.array([]), None), (np.zeros((0, 3)) + p_in, None), (np.array([]), T_out),
        (np.zeros((2, 0)) + p_out, np.zeros((2, 0)) + T_out),
    ]


@pytest.mark.parametrize("method", METHODS)
def test_scalars_give_floats_and_arrays_keep_their_shape(fluids, method):
    name, table, eos = fluids
    f, ref = getattr(table, method), getattr(eos, method)
    for p, T in _queries(table, name):
        got, want = f(p, T), ref(p, T)
        assert type(got) is type(want), (method, p, T, type(got), type(want))
        assert np.shape(got) == np.shape(want) == np.broadcast_shapes(np.shape(p),
                                                                      np.shape(T)), (p, T)
        if np.ndim(want) == 0:
            assert isinstance(got, float)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("method", METHODS)
def test_empty_queries_at_out_of_range_raise(name, method):
    """No states, no values, and no error (the default out_of_range too)."""
    table = getattr(sf, name).with_level("table")
    for p, T in ((np.array([]), None), (np.zeros((0, 3)), None), (np.array([]), 300.0),
                 (np.zeros((2, 0)), np.zeros((2, 0)))):
        got = getattr(table, method)(p, T)
        assert isinstance(got, np.ndarray) and got.shape == np.broadcast_shapes(
            np.shape(p), np.shape(T))


@pytest.mark.parametrize("shape", [(0,), (0, 3), (2, 0)])
def test_interpolants_of_no_points_give_empty_parts(shape):
    """The root of issue 41: with grad, a query of no points gave () instead of
    (value, d/dx[, d/dy]); every part is an empty float64 array of the
    query's shape."""
    x, y = UniformAxis(0.0, 1.0, 6), UniformAxis(0.0, 2.0, 7)
    interp = Bicubic(x, y, np.random.default_rng(3).normal(size=(6, 7)))
    line = interp.slice_at_y(0.7)
    a = np.zeros(shape)
    parts = [interp(a, a), *interp(a, a, grad=True), line(a), *line(a, grad=True)]
    assert len(parts) == 1 + 3 + 1 + 2
    assert all(isinstance(v, np.ndarray) and v.shape == shape and v.dtype == np.float64
               for v in parts)
    got = interp(a, np.zeros(shape[:-1] + (1,)), grad=True)         # broadcast to no points
    assert len(got) == 3 and all(v.shape == shape for v in got)


# -- in a simulation ----------------------------------------------------------------------
@pytest.mark.parametrize("thermal", [None, "adiabatic"])
@pytest.mark.parametrize("p_tank, p_source", [(5e3, 8e3), (30e6, 25e6)])
def test_a_scene_starting_outside_the_table_runs_and_matches_the_eos_level(
        p_tank, p_source, thermal):
    """A container of air at 5 kPa (below the table) or 30 MPa (above it) filled
    or emptied through a tube: at level 'table' with out_of_range='eos' it runs
    (it stopped at t = 0 with an unrelated SimulationError) and gives the eos
    level's result within the solver's tolerance."""
    def final(fluid):
        s = sf.System()
        s += sf.PressureSource("src", pressure=p_source)
        s += sf.CircularTube("tube", fluid, length=0.3, diameter=1e-3)
        s += sf.Container("tank", fluid, volume=1e-5, initial_pressure=p_tank)
        s.connect("tube", "src")
        s.connect("tube", "tank")
        options = {} if thermal is None else {"thermal": thermal}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sf.ModelWarning)   # "closer to adiabatic"
            res = sf.Simulation(s, duration=0.01, **options).run()
        return res.get("tank", "pressure")[-1], res.get("tank", "mass")[-1]

    p_table, m_table = final(sf.air.with_level("table", out_of_range="eos"))
    p_eos, m_eos = final(sf.air.with_level("eos"))
    assert math.isfinite(p_table) and p_table != pytest.approx(p_tank, rel=1e-3)  # it moved
    assert p_table == pytest.approx(p_eos, rel=1e-6)
    assert m_table == pytest.approx(m_eos, rel=1e-6)
