"""The table level: interpolation (exactness, C1 continuity across cell borders),
the shipped tables' recorded error bounds (hypothesis), out-of-range handling, and
the file checks (corrupt, other CoolProp version, other format, missing)."""
import json
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import softflow as sf
from softflow.fluids import FluidTableError
from softflow.fluids.catalog import BUILTIN
from softflow.fluids.hermite import Bicubic, UniformAxis
from softflow.fluids.tables import ANY_COOLPROP_ENV, TABLES_ENV, load_table, tables_directory
from softflow.fluids.tables.__main__ import main as tables_cli

NAMES = list(BUILTIN)


def _table(name):
    return load_table(BUILTIN[name])


# -- interpolation ----------------------------------------------------------------------
def test_bicubic_reproduces_a_bicubic_polynomial_with_its_gradient():
    x, y = UniformAxis(-1.0, 2.0, 7), UniformAxis(0.0, 5.0, 9)
    f = lambda a, b: (1 + a - 2 * a**2 + 0.5 * a**3) * (3 - b + 0.2 * b**3)    # noqa: E731
    fa = lambda a, b: (1 - 4 * a + 1.5 * a**2) * (3 - b + 0.2 * b**3)          # noqa: E731
    fb = lambda a, b: (1 + a - 2 * a**2 + 0.5 * a**3) * (-1 + 0.6 * b**2)      # noqa: E731
    interp = Bicubic(x, y, f(x.nodes[:, None], y.nodes[None, :]))
    rng = np.random.default_rng(3)
    a, b = rng.uniform(-1, 2, 500), rng.uniform(0, 5, 500)
    v, va, vb = interp(a, b, grad=True)
    assert np.allclose(v, f(a, b), rtol=0, atol=1e-11)
    assert np.allclose(va, fa(a, b), rtol=0, atol=1e-10)
    assert np.allclose(vb, fb(a, b), rtol=0, atol=1e-10)


@pytest.mark.parametrize("shape", [(), (1,), (3,), (2, 2), (5,), (40,)])
def test_scalar_and_array_queries_give_the_same_numbers(shape):
    """A query of any shape gives, point by point, the numbers of one-point
    queries (Python floats, NumPy floats, 0-d arrays: NumPy floats back), at
    cell borders, past the axis ends (the end cells extended) and for the
    1-D slice too; arrays come back in the query's shape."""
    x, y = UniformAxis(-1.0, 2.0, 7), UniformAxis(0.0, 5.0, 9)
    rng = np.random.default_rng(11)
    interp = Bicubic(x, y, rng.normal(size=(7, 9)))
    line = interp.slice_at_y(1.7)
    a = rng.uniform(-1.5, 2.5, shape)
    b = rng.uniform(-0.5, 5.5, shape)
    if a.size:
        a.flat[0], b.flat[0] = x.nodes[3], y.nodes[4]          # on a border
    parts = [interp(a, b), *interp(a, b, grad=True), line(a), *line(a, grad=True)]
    assert all(type(v) is (np.float64 if shape == () else np.ndarray) and np.shape(v) == shape
               for v in parts)
    for k in np.ndindex(shape):
        for xq, yq in ((float(a[k]), float(b[k])), (a[k], b[k]), (np.array(a[k]), b[k])):
            one = [interp(xq, yq), *interp(xq, yq, grad=True), line(xq), *line(xq, grad=True)]
            assert all(type(v) is np.float64 for v in one)
            assert [v[k] for v in parts] == one


def test_queries_broadcast_and_are_computed_in_float64():
    """Queries of two shapes broadcast; integer and float32 ones are
    evaluated as float64 (the float32 values converted first)."""
    x, y = UniformAxis(0.0, 1.0, 6), UniformAxis(0.0, 2.0, 7)
    interp = Bicubic(x, y, np.random.default_rng(2).normal(size=(6, 7)))
    got = interp(0.3, np.array([0.1, 0.9, 1.7]), grad=True)
    want = interp(np.full(3, 0.3), np.array([0.1, 0.9, 1.7]), grad=True)
    assert all(np.array_equal(g, w) for g, w in zip(got, want))
    got = interp(np.array([[0.3], [0.6]]), np.array([0.1, 0.9]))
    assert got.shape == (2, 2) and got[1, 0] == interp(0.6, 0.1)
    f32 = np.float32([0.3, 0.7]), np.float32([0.4, 1.1])
    got = interp(*f32, grad=True)
    want = interp(*(v.astype(np.float64) for v in f32), grad=True)
    assert all(g.dtype == np.float64 and np.array_equal(g, w) for g, w in zip(got, want))
    assert interp(np.array([0, 1]), np.array([1, 2])).dtype == np.float64
    assert np.array_equal(interp([0, 1], [1, 2]), interp(np.array([0.0, 1.0]),
                                                         np.array([1.0, 2.0])))


def test_a_state_past_the_table_says_its_edge_and_value_without_other_warnings():
    """An array of pressures against the fluid's one temperature (broadcast):
    the FluidError names the edge crossed and the value past it, and nothing
    else is said on the way (numba, handed broadcast_arrays' views, warned
    that they would not stay writeable)."""
    import warnings
    water = sf.water.with_level("table")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(sf.FluidError, match="pressure 3e\\+07 Pa is outside") as err:
            water.density(np.array([1e5, 3e7]))
        assert (err.value.quantity, err.value.limit, err.value.value) == (
            "pressure", water.p_range[1], 3e7)
        assert water.density(np.array([1e5, 2e5]), 300.0).shape == (2,)


def test_nan_points_give_nan_in_every_part():
    """NaN gives NaN in every part (one query of many: the others keep their
    numbers)."""
    x, y = UniformAxis(0.0, 1.0, 5), UniformAxis(0.0, 1.0, 5)
    interp = Bicubic(x, y, np.arange(25.0).reshape(5, 5))
    line = interp.slice_at_y(0.5)
    xq = np.array([0.5, np.nan, 0.2])
    f, fx, fy = interp(xq, np.array([0.5, 0.5, np.nan]), grad=True)
    assert np.isnan(f[1:]).all() and np.isnan(fx[1:]).all() and np.isnan(fy[1:]).all()
    assert (f[0], fx[0], fy[0]) == interp(0.5, 0.5, grad=True)
    g, gx = line(xq, grad=True)
    assert np.isnan(g[1]) and np.isnan(gx[1]) and g[2] == line(0.2)
    assert all(np.isnan(v) for v in interp(np.nan, 0.5, grad=True))


@pytest.mark.parametrize("name", NAMES)
def test_value_and_first_derivatives_continuous_across_cell_borders(name):
    table = _table(name)
    px, Tx = table.p_axis, table.T_axis
    rng = np.random.default_rng(7)
    for key in table.values:
        interp = table.interpolant(key)
        # across p borders (interior nodes), at random T; then across T borders
        for axis, nodes, other in ((0, px.nodes[1:-1], Tx), (1, Tx.nodes[1:-1], px)):
            o = rng.uniform(other.lo, other.hi, nodes.size)
            step = (px if axis == 0 else Tx).step
            eps = 1e-9 * step
            sides = []
            for shift in (-eps, eps):
                q = nodes + shift
                sides.append(np.array(interp(q, o, grad=True) if axis == 0
                                      else interp(o, q, grad=True)))
            left, right = sides
            # per row (f, f_p, f_T); floors for derivatives that vanish (MEG density in p)
            fmax = np.abs(left[0]).max()
            floor = np.array([0.0, 1e-6 * fmax / px.step, 1e-6 * fmax / Tx.step])
            scale = np.maximum(np.abs(left).max(axis=1), floor)[:, None]
            # jumps far below what a kink would give (a C0-only interpolant jumps by
            # about |f''| * step in the derivative, ~1e-2 of the scale here)
            assert np.all(np.abs(left - right) <= 1e-7 * scale), (key, axis)


@pytest.mark.parametrize("name", NAMES)
def test_isothermal_slice_equals_the_2d_interpolant(name):
    fluid = sf.Fluid(name, level="table", temperature=301.37)
    p = np.linspace(*fluid.p_range, 997)
    T = np.full_like(p, 301.37)
    for prop in ("density", "density_dp", "viscosity"):
        assert np.allclose(getattr(fluid, prop)(p), getattr(fluid, prop)(p, T), rtol=1e-13,
                           atol=0)


def test_density_derivative_is_continuous_through_the_fluid():
    air = sf.air.with_level("table")
    border = air.table.p_axis.nodes[40]
    lo, hi = air.density_dp(border - 1e-3), air.density_dp(border + 1e-3)
    assert hi == pytest.approx(lo, rel=1e-9)


# -- recorded error bound, at random states ---------------------------------------------
_EOS = {n: sf.Fluid(n, level="eos") for n in NAMES}
_TABLE = {n: sf.Fluid(n, level="table") for n in NAMES}
_PROPS = {"Z": "compressibility", "density": "density", "viscosity": "viscosity",
          "cp": "cp", "cv": "cv", "enthalpy": "enthalpy", "internal_energy": "internal_energy",
          "speed_of_sound": "speed_of_sound"}


@pytest.mark.parametrize("name", NAMES)
@settings(max_examples=200, deadline=None, database=None)   # no .hypothesis/ in the repo
@given(s=st.floats(0, 1), r=st.floats(0, 1))
def test_table_stays_within_its_recorded_error_bound(name, s, r):
    table, eos = _TABLE[name], _EOS[name]
    p = table.p_range[0] + s * (table.p_range[1] - table.p_range[0])
    T = table.T_range[0] + r * (table.T_range[1] - table.T_range[0])
    meta = table.table.meta["properties"]
    for key, entry in meta.items():
        prop = _PROPS[key]
        got, want = getattr(table, prop)(p, T), getattr(eos, prop)(p, T)
        if entry["error_measure"] == "relative":
            err = abs(got / want - 1)
        else:
            err = abs(got - want) / np.ptp(table.table.values[key])
        assert err <= entry["error_bound"], (key, p, T, err, entry["error_bound"])


def test_shipped_tables_meet_the_goals():
    total = sum(f.stat().st_size for f in tables_directory().iterdir())
    assert total < 20e6
    for name in NAMES:
        meta = _table(name).meta
        assert meta["properties"]["density"]["max_error"] < 1e-3 * 0.01   # goal 0.1 %
        assert meta["coolprop_version"] and len(meta["sha256"]) == 64
        assert meta["error_check"]["points"] > 10000


# -- out of range -----------------------------------------------------------------------
def test_out_of_range_raises_by_default_and_names_the_quantity():
    air = sf.air.with_level("table")
    with pytest.raises(sf.FluidError, match=r"pressure 3e\+07 Pa is outside the table range "
                                             r"10000 \.\.\. 2e\+07 Pa"):
        air.density(np.array([1e5, 3e7]))
    with pytest.raises(sf.FluidError, match=r"temperature 500 K is outside the table range "
                                             r"233\.15 \.\.\. 423\.15 K"):
        air.viscosity(1e5, 500.0)
    with pytest.raises(sf.FluidError, match="pressure 1000 Pa is outside"):
        air.density(1e3)      # the isothermal (T=None) path checks too


def test_out_of_range_errors_name_the_edge_they_crossed():
    # (the solver's searches stop at that edge in one trial: FluidError.limit)
    air = sf.air.with_level("table")
    cases = [(lambda: air.density(np.array([1e5, 3e7])), "pressure", 2e7),
             (lambda: air.density(1e3), "pressure", 1e4),
             (lambda: air.viscosity(1e5, 500.0), "temperature", 423.15),
             (lambda: air.viscosity(1e5, 200.0), "temperature", 233.15)]
    for call, quantity, limit in cases:
        with pytest.raises(sf.FluidError) as info:
            call()
        assert info.value.quantity == quantity
        assert info.value.limit == pytest.approx(limit)
    with pytest.raises(sf.FluidError) as info:
        sf.Fluid("no such fluid")
    assert info.value.quantity is None and info.value.limit is None


@pytest.mark.parametrize("name", ["air", "nitrogen"])
def test_gas_tables_reach_vacuum_actuator_pressures(name):
    """The gas tables start at 10 kPa abs (vacuum actuators run to about -0.9 bar
    gauge): at 20 kPa and 300 K table air and nitrogen match CoolProp within the
    recorded bounds, on the 2-D and the isothermal path; 9 kPa is outside."""
    eos = sf.Fluid(name, level="eos")
    table = sf.Fluid(name, level="table", temperature=300.0)
    assert table.p_range[0] == 10e3
    meta = table.table.meta["properties"]
    p, T = 20e3, 300.0
    for key in ("density", "viscosity", "cp", "enthalpy"):
        want = getattr(eos, key)(p, T)
        for got in (getattr(table, key)(p, T), getattr(table, key)(p)):
            if meta[key]["error_measure"] == "relative":
                err = abs(got / want - 1)
            else:
                err = abs(got - want) / np.ptp(table.table.values[key])
            assert err <= meta[key]["error_bound"], (key, err, meta[key]["error_bound"])
    with pytest.raises(sf.FluidError, match=r"pressure 9000 Pa is outside the table range "
                                             r"10000 \.\.\. 2e\+07 Pa"):
        table.density(9e3)
    with pytest.raises(sf.FluidError, match=r"pressure 9000 Pa is outside"):
        table.viscosity(np.array([20e3, 9e3]), np.array([T, T]))


def test_out_of_range_eos_falls_back_to_coolprop_and_never_extrapolates():
    air = sf.air.with_level("table", out_of_range="eos")
    eos = sf.air.with_level("eos")
    p = np.array([1e3, 1e5, 25e6])
    T = np.array([300.0, 300.0, 500.0])
    assert np.allclose(air.density(p, T), eos.density(p, T), rtol=1e-7)
    assert np.allclose(air.density(p), eos.density(p), rtol=1e-7)
    assert air.at(temperature=320.0).out_of_range == "eos"


def test_fluid_temperature_outside_the_table_is_refused():
    with pytest.raises(sf.FluidError, match=r"temperature 223\.15 K is outside the table "
                                             r"range 233\.15 \.\.\. 423\.15 K"):
        sf.Fluid("air", level="table", temperature=sf.Q_(-50, "degC"))


# -- files ------------------------------------------------------------------------------
@pytest.fixture
def table_copy(tmp_path):
    src = tables_directory()
    for suffix in ("npz", "json"):
        shutil.copy(src / f"water.{suffix}", tmp_path / f"water.{suffix}")
    return tmp_path


def test_tables_directory_from_argument_or_environment(table_copy, monkeypatch):
    assert sf.Fluid("water", level="table", tables_dir=table_copy).table.path.parent == table_copy
    monkeypatch.setenv(TABLES_ENV, str(table_copy))
    assert tables_directory() == table_copy
    with pytest.raises(FluidTableError, match=r"no table 'air' in .*tables there: water.*"
                                               r"python -m softflow.fluids.tables build air"):
        sf.air.with_level("table")


def test_corrupt_table_is_detected(table_copy):
    data = bytearray((table_copy / "water.npz").read_bytes())
    data[len(data) // 2] ^= 0xFF
    (table_copy / "water.npz").write_bytes(bytes(data))
    with pytest.raises(FluidTableError, match="corrupt or modified table"):
        sf.Fluid("water", level="table", tables_dir=table_copy)


def test_unreadable_metadata_is_detected(table_copy):
    (table_copy / "water.json").write_text('{"format": 1, "fluid": ')
    with pytest.raises(FluidTableError, match="unreadable table metadata"):
        sf.Fluid("water", level="table", tables_dir=table_copy)


def _edit_meta(directory, **changes):
    path = directory / "water.json"
    meta = json.loads(path.read_text())
    meta.update(changes)
    path.write_text(json.dumps(meta))


def test_table_from_another_coolprop_version_is_refused(table_copy, monkeypatch):
    _edit_meta(table_copy, coolprop_version="6.4.1")
    with pytest.raises(FluidTableError, match=r"built with CoolProp 6\.4\.1, but CoolProp "
                                               r".* is installed; rebuild"):
        sf.Fluid("water", level="table", tables_dir=table_copy)
    monkeypatch.setenv(ANY_COOLPROP_ENV, "1")
    with pytest.warns(UserWarning, match="built with CoolProp 6.4.1"):
        sf.Fluid("water", level="table", tables_dir=table_copy)


def test_table_of_another_format_or_fluid_is_refused(table_copy):
    _edit_meta(table_copy, format=99)
    with pytest.raises(FluidTableError, match="table format 99"):
        sf.Fluid("water", level="table", tables_dir=table_copy)
    _edit_meta(table_copy, format=1, coolprop_id="HEOS::Ethanol")
    with pytest.raises(FluidTableError, match="table is for 'HEOS::Ethanol'"):
        sf.Fluid("water", level="table", tables_dir=table_copy)


def test_build_and_check_a_table_from_the_command_line(tmp_path, capsys):
    args = ["build", "Argon", "--dir", str(tmp_path), "--pressure", "1 bar", "10 bar",
            "--temperature", "0 degC", "60 degC", "--pressure-nodes", "6",
            "--temperature-step", "20"]
    assert tables_cli(args) == 0
    assert tables_cli(["check", "--dir", str(tmp_path)]) == 0
    assert "ok   argon: HEOS::Argon" in capsys.readouterr().out
    argon = sf.Fluid("Argon", level="table", tables_dir=tmp_path, temperature=300.0)
    meta = argon.table.meta
    assert meta["pressure_range"] == [1e5, 1e6]
    assert meta["temperature_range"] == pytest.approx([273.15, 333.15])
    want = sf.Fluid("Argon", level="eos").density(5e5, 300.0)
    err = abs(argon.density(5e5, 300.0) / want - 1)
    assert err <= meta["properties"]["density"]["error_bound"]


def test_build_refuses_a_range_across_a_phase_boundary(tmp_path, capsys):
    args = ["build", "CO2", "--dir", str(tmp_path), "--pressure", "1 bar", "80 bar",
            "--temperature", "0 degC", "30 degC", "--pressure-nodes", "5",
            "--temperature-step", "10"]
    assert tables_cli(args) == 2
    assert "crosses into the liquid phase" in capsys.readouterr().err


def test_table_from_another_coolprop_patch_release_is_used_with_a_warning(table_copy):
    import CoolProp
    major, minor = CoolProp.__version__.split(".")[:2]
    _edit_meta(table_copy, coolprop_version=f"{major}.{minor}.999")
    with pytest.warns(UserWarning, match=rf"built with CoolProp {major}\.{minor}\.999"):
        water = sf.Fluid("water", level="table", tables_dir=table_copy)
    assert water.density(2e5) > 990


@pytest.mark.parametrize("name", ["air", "water"])
@pytest.mark.parametrize("n", [1, 3, 12])
@pytest.mark.parametrize("out_of_range", ["raise", "eos"])
def test_thermal_parts_from_one_lookup_equal_the_public_methods(name, n, out_of_range):
    """The thermal kernels' (value, d/dp, d/dT) of enthalpy, internal energy and
    density come from one interpolation at the table level: bitwise the numbers
    of the three public methods each (and the per-property path with the
    CoolProp fallback, or at the fluid's own temperature)."""
    fluid = getattr(sf, name).with_level("table", out_of_range=out_of_range)
    rng = np.random.default_rng(n)
    (p_lo, p_hi), (T_lo, T_hi) = fluid.p_range, fluid.T_range
    p = rng.uniform(max(p_lo, 1e5), min(p_hi, 5e6), n)
    T = rng.uniform(T_lo + 5, min(T_hi, 360.0) - 5, n)
    for prop in ("enthalpy", "internal_energy", "density"):
        parts = getattr(fluid, f"_{prop}_parts")
        want = [getattr(fluid, prop)(p, T), getattr(fluid, f"{prop}_dp")(p, T),
                getattr(fluid, f"{prop}_dT")(p, T)]
        for got, w in zip(parts(p, T, True), want):
            assert np.array_equal(got, w), prop
        value, none_p, none_T = parts(p, T, False)
        assert np.array_equal(value, want[0]) and none_p is None and none_T is None
    if out_of_range == "raise":
        with pytest.raises(sf.FluidError, match="outside the table range"):
            fluid._enthalpy_parts(np.full(n, 2 * p_hi), T, True)


def test_range_check_names_the_bad_state_for_one_pressure_and_several_temperatures():
    from softflow.fluids.eos import check_state_range
    with pytest.raises(sf.FluidError, match=r"^F: temperature 5000 K is outside the table "
                                             r"range 200 \.\.\. 400 K"):
        check_state_range("F", np.array([1e5]), np.array([300.0, 5000.0]), (200.0, 400.0),
                          (1e3, 1e7), "table")
    air = sf.air.with_level("table")
    with pytest.raises(sf.FluidError, match=r"^<.*air.*>: pressure 3e\+07 Pa is outside"):
        air.density(np.array([3e7]), np.array([300.0]))    # the fluid's repr, made for the message
