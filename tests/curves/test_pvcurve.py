"""PVCurve: measured pressure–volume characteristics, interpolated C1-smoothly."""
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

import softflow as sf
from softflow.curves import DataFileError

P0 = sf.pressure_atmospheric
EXAMPLE_CSV = Path(__file__).resolve().parents[2] / "examples" / "latex_balloon_60mm_pv.csv"


@pytest.fixture(scope="module")
def balloon():
    return sf.PVCurve(EXAMPLE_CSV)


def write(tmp_path, text, name="pv.csv"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def interior_points(curve, per_interval=5, seed=0):
    rng = np.random.default_rng(seed)
    v = curve.volume
    s = rng.uniform(0.02, 0.98, (len(v) - 1, per_interval))
    return (v[:-1, None] + s * np.diff(v)[:, None]).ravel()


# ---------------------------------------------------------------------------------------
# reading the example file
# ---------------------------------------------------------------------------------------
def test_example_file_values(balloon):
    assert len(balloon.volume) == len(balloon.pressure) == 56
    assert balloon.volume[0] == pytest.approx(1e-6, rel=1e-12)
    assert balloon.volume[-1] == pytest.approx(55.66e-6, rel=1e-12)
    assert balloon.pressure[0] == pytest.approx(P0 + 2200.0, rel=1e-12)
    assert balloon.pressure[-1] == pytest.approx(P0 + 106000.0, rel=1e-12)
    assert (np.diff(balloon.volume) > 0).all()


def test_paper_spelling_and_str_path():
    curve = sf.pvcurve.PVCurve(str(EXAMPLE_CSV))
    assert sf.pvcurve.PVCurve is sf.PVCurve
    p, dp = curve.fdf_volume(volume=10e-6)        # keyword, as in the paper's example
    assert P0 + 69000 < p < P0 + 74000
    assert "56 points" in repr(curve)


def test_gauge_false_keeps_pressures_absolute():
    curve = sf.PVCurve(EXAMPLE_CSV, gauge=False)
    assert curve.pressure[0] == pytest.approx(2200.0, rel=1e-12)
    ref = sf.PVCurve(EXAMPLE_CSV)
    np.testing.assert_allclose(ref.pressure - curve.pressure, P0, rtol=1e-12)
    x = interior_points(curve)
    np.testing.assert_allclose(ref(x) - curve(x), P0, rtol=1e-9)
    np.testing.assert_allclose(ref.fdf_volume(x)[1], curve.fdf_volume(x)[1], rtol=1e-9)


# ---------------------------------------------------------------------------------------
# interpolation
# ---------------------------------------------------------------------------------------
def test_reproduces_samples_at_nodes(balloon):
    v, p = balloon.volume, balloon.pressure
    np.testing.assert_allclose(balloon(v), p, rtol=1e-14, atol=0)
    for vi, pi in zip(v, p):
        assert balloon(float(vi)) == pytest.approx(pi, rel=1e-14)


def test_matches_scipy_pchip(balloon):
    ref = PchipInterpolator(balloon.volume, balloon.pressure)
    x = interior_points(balloon)
    val, dval = balloon.fdf_volume(x)
    np.testing.assert_allclose(val, ref(x), rtol=1e-10)
    np.testing.assert_allclose(dval, ref(x, 1), rtol=1e-8,
                               atol=1e-10 * np.abs(balloon.slope).max())


def test_is_C1_across_nodes(balloon):
    v = balloon.volume[1:-1]
    smax = np.abs(balloon.slope).max()
    d = 1e-9 * v
    pl, sl = balloon.fdf_volume(v - d)
    pr, sr = balloon.fdf_volume(v + d)
    # value: continuous (the jump is no more than the slope times the gap)
    assert (np.abs(pr - pl) <= 2 * d * smax * 1.01).all()
    # slope: continuous (a kink would show as a jump of order smax)
    np.testing.assert_allclose(sr, sl, rtol=0, atol=1e-5 * smax)
    # and the slope at the node is PCHIP's
    np.testing.assert_allclose(balloon.fdf_volume(v)[1], balloon.slope[1:-1], rtol=1e-12,
                               atol=1e-12 * smax)


def test_is_C1_at_the_ends_of_the_data(balloon):
    smax = np.abs(balloon.slope).max()
    for vi in (balloon.volume[0], balloon.volume[-1]):
        d = 1e-9 * vi
        (pl, pr), (sl, sr) = balloon.fdf_volume(np.array([vi - d, vi + d]))
        assert abs(pr - pl) <= 2 * d * smax * 1.01
        assert abs(sr - sl) <= 1e-5 * smax


def test_derivative_matches_finite_differences(balloon):
    x = np.concatenate([interior_points(balloon, 3, seed=1),
                        [0.2e-6, 0.9e-6, 60e-6, 80e-6]])          # and outside
    h = 1e-4 * np.diff(balloon.volume).min()
    _, dval = balloon.fdf_volume(x)
    fd = (balloon(x + h) - balloon(x - h)) / (2 * h)
    smax = np.abs(balloon.slope).max()
    np.testing.assert_allclose(dval, fd, rtol=1e-5, atol=1e-7 * smax)


def test_scalar_and_array_paths_agree(balloon):
    x = np.concatenate([interior_points(balloon, 2, seed=2), balloon.volume,
                        [-1e-6, 0.0, 0.5e-6, 56e-6, 1e-4]])
    va, da = balloon.fdf_volume(x)
    assert va.shape == da.shape == x.shape
    for i, xi in enumerate(x):
        vs, ds = balloon.fdf_volume(float(xi))
        assert isinstance(vs, float) and isinstance(ds, float)
        assert vs == pytest.approx(va[i], rel=1e-13)
        assert ds == pytest.approx(da[i], rel=1e-12, abs=1e-12 * abs(da).max())
        v0, d0 = balloon.fdf_volume(np.float64(xi))
        assert float(v0) == vs and float(d0) == ds
    # 0-d arrays and ints take the scalar path; 2-D arrays keep their shape
    assert balloon.fdf_volume(np.array(20e-6))[0] == balloon.fdf_volume(20e-6)[0]
    assert balloon(0) == balloon(0.0)
    grid = x[:12].reshape(3, 4)
    np.testing.assert_array_equal(balloon(grid), balloon(grid.ravel()).reshape(3, 4))


def test_linear_extrapolation(balloon):
    v, p, s = balloon.volume, balloon.pressure, balloon.slope
    below = v[0] - np.array([1e-8, 3e-7, 1e-6])
    above = v[-1] + np.array([1e-8, 2e-6, 1e-5])
    val, dval = balloon.fdf_volume(below)
    np.testing.assert_allclose(val, p[0] + s[0] * (below - v[0]), rtol=1e-13)
    np.testing.assert_array_equal(dval, s[0])
    val, dval = balloon.fdf_volume(above)
    np.testing.assert_allclose(val, p[-1] + s[-1] * (above - v[-1]), rtol=1e-13)
    np.testing.assert_array_equal(dval, s[-1])
    assert s[0] > 0 and s[-1] > 0                 # the balloon stiffens at both ends
    assert balloon(float(above[-1])) == pytest.approx(p[-1] + s[-1] * 1e-5, rel=1e-13)


def test_no_overshoot_keeps_peak_and_valley(balloon):
    """PCHIP stays within the samples of each interval: the measured peak and
    valley of the peak–valley curve are kept."""
    x = np.union1d(np.linspace(balloon.volume[0], balloon.volume[-1], 20001), balloon.volume)
    y = balloon(x)
    i = np.clip(np.searchsorted(balloon.volume, x, side="right") - 1, 0, 54)
    lo = np.minimum(balloon.pressure[i], balloon.pressure[i + 1])
    hi = np.maximum(balloon.pressure[i], balloon.pressure[i + 1])
    tol = 1e-9 * P0
    assert ((y >= lo - tol) & (y <= hi + tol)).all()
    first = x < 20e-6
    assert y[first].max() == pytest.approx(P0 + 87000.0, rel=1e-12)   # peak 870 mbar
    valley = (x > 10e-6) & (x < 30e-6)
    assert y[valley].min() == pytest.approx(P0 + 58000.0, rel=1e-12)  # valley 580 mbar


# ---------------------------------------------------------------------------------------
# construction from arrays
# ---------------------------------------------------------------------------------------
def test_from_quantity_arrays():
    curve = sf.PVCurve(volume=sf.Q_([1, 2, 3], "ml"), pressure=sf.Q_([0, 100, 150], "mbar"),
                       gauge=True)
    np.testing.assert_allclose(curve.volume, [1e-6, 2e-6, 3e-6], rtol=1e-12)
    np.testing.assert_allclose(curve.pressure, P0 + np.array([0.0, 1e4, 1.5e4]), rtol=1e-12)
    assert curve(2e-6) == pytest.approx(P0 + 1e4, rel=1e-14)
    assert curve.origin == "arrays"


def test_from_plain_si_arrays_absolute():
    curve = sf.PVCurve(volume=[1e-6, 2e-6, 4e-6], pressure=[1.1e5, 1.3e5, 1.4e5], gauge=False)
    np.testing.assert_array_equal(curve.pressure, [1.1e5, 1.3e5, 1.4e5])
    p, dp = curve.fdf_volume(3e-6)
    assert 1.3e5 < p < 1.4e5 and dp > 0


def test_two_point_curve_is_linear():
    curve = sf.PVCurve(volume=[1e-6, 3e-6], pressure=[0.0, 2e4], gauge=True)
    x = np.linspace(0, 4e-6, 9)
    np.testing.assert_allclose(curve(x), P0 + 1e10 * (x - 1e-6), rtol=1e-12)


def test_csv_without_units_row_needs_explicit_units(tmp_path):
    path = write(tmp_path, "V,P\n1,10\n2,20\n3,25\n")
    with pytest.raises(DataFileError, match="no unit"):
        sf.PVCurve(path, volume_column="V", pressure_column="P")
    curve = sf.PVCurve(path, volume_column="V", pressure_column="P", volume_unit="ml",
                       pressure_unit="kPa")
    np.testing.assert_allclose(curve.volume, [1e-6, 2e-6, 3e-6], rtol=1e-12)
    np.testing.assert_allclose(curve.pressure, P0 + np.array([1e4, 2e4, 2.5e4]), rtol=1e-12)


# ---------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------
def test_csv_unknown_unit(tmp_path):
    path = write(tmp_path, "Balloon,x,y\nTime,Volume,Pressure\ns,ml,mbarr\n1,1,22\n2,2,25\n")
    with pytest.raises(DataFileError, match=r"line 3.*'mbarr'"):
        sf.PVCurve(path)


def test_csv_wrong_dimension_unit(tmp_path):
    path = write(tmp_path, "Time,Volume,Pressure\ns,ml,mm\n1,1,22\n2,2,25\n")
    with pytest.raises(sf.UnitError, match="'Pressure'"):
        sf.PVCurve(path)


def test_csv_non_numeric_cell(tmp_path):
    path = write(tmp_path, "Balloon,x,y\nTime,Volume,Pressure\ns,ml,mbar\n"
                           "1,1,22\n2,2,25\n3,3.o,30\n")
    with pytest.raises(DataFileError, match=r"line 6.*'3\.o'"):
        sf.PVCurve(path)


def test_csv_non_monotonic_volume_names_the_line(tmp_path):
    path = write(tmp_path, "Balloon,x,y\nTime,Volume,Pressure\ns,ml,mbar\n"
                           "1,1,22\n2,2,25\n3,1.5,30\n4,4,40\n")
    with pytest.raises(DataFileError) as info:
        sf.PVCurve(path)
    msg = str(info.value)
    assert "line 6" in msg
    assert "pv.csv" in msg
    assert "increase" in msg


@pytest.mark.parametrize("volume, pressure, error, text", [
    ([1e-6], [1e4], ValueError, "at least 2 points, got 1"),
    ([], [], ValueError, "at least 2 points, got 0"),
    ([1e-6, np.nan, 3e-6], [0, 1e4, 2e4], ValueError, "NaN or inf at point 1"),
    ([1e-6, 2e-6, 3e-6], [0, np.inf, 2e4], ValueError, "NaN or inf at point 1"),
    ([1e-6, 2e-6, 3e-6], [0, 1e4], ValueError, "equal length"),
    ([[1e-6, 2e-6]], [[0, 1e4]], ValueError, "1-D"),
    ([1e-6, 3e-6, 2e-6, 4e-6], [0, 1, 2, 3], DataFileError, "at point 2"),
    ([1e-6, 1e-6, 2e-6], [0, 1, 2], DataFileError, "increase strictly"),
    (sf.Q_([1, 2], "ml"), sf.Q_([1, 2], "ml"), sf.UnitError,
     "PVCurve: pressure expects a pressure"),
    (sf.Q_([1, 2], "bar"), sf.Q_([1, 2], "bar"), sf.UnitError,
     "PVCurve: volume expects a volume"),
])
def test_bad_arrays(volume, pressure, error, text):
    with pytest.raises(error, match=text):
        sf.PVCurve(volume=volume, pressure=pressure)


def test_source_and_arrays_are_exclusive():
    with pytest.raises(ValueError, match="either"):
        sf.PVCurve(EXAMPLE_CSV, volume=[1e-6, 2e-6], pressure=[0, 1])
    with pytest.raises(ValueError, match="both"):
        sf.PVCurve(volume=[1e-6, 2e-6])
    with pytest.raises(ValueError):
        sf.PVCurve()


def test_arrays_are_absolute_unless_gauge_is_named():
    curve = sf.PVCurve(volume=[1e-6, 3e-6], pressure=[1.2e5, 1.3e5])
    np.testing.assert_array_equal(curve.pressure, [1.2e5, 1.3e5])


def test_fdf_volume_accepts_quantities():
    curve = sf.PVCurve(volume=[1e-6, 3e-6], pressure=[1.2e5, 1.3e5])
    p, dp = curve.fdf_volume(sf.Q_(2, "mL"))
    assert p == pytest.approx(1.25e5)
    assert curve(sf.Q_([1, 3], "mL")) == pytest.approx([1.2e5, 1.3e5])
    with pytest.raises(sf.UnitError, match="volume"):
        curve(sf.Q_(2, "bar"))


@pytest.mark.parametrize("content, error, match", [
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n2,2,25\n3,2,30\n",
                 DataFileError, "line 5", id="repeated_volume_is_rejected"),
    # the offending row '3,1.5,30' is line 6 of the file
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n\n2,2,25\n3,1.5,30\n",
                 DataFileError, "line 6", id="non_monotonic_volume_after_blank_line_names_the_right_line"),
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n",
                 ValueError, "at least 2 points, got 1", id="too_short"),
    pytest.param("Time,Volume,Pressure\ns,ml,mbar\n1,1,22\n2,2,nan\n3,3,30\n",
                 ValueError, "NaN", id="nan"),
    pytest.param("Time,Vol,Pressure\ns,ml,mbar\n1,1,22\n2,2,25\n",
                 DataFileError, "no column named 'Volume'", id="missing_column"),
])
def test_bad_csv_curve_is_rejected(tmp_path, content, error, match):
    path = write(tmp_path, content)
    with pytest.raises(error, match=match):
        sf.PVCurve(path)
