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


# ---------------------------------------------------------------------------------------
# smoothing and filtering noisy measurements
# ---------------------------------------------------------------------------------------
NOISE = 1000.0       # Pa, about 1 % of the balloon's 104 kPa pressure range


@pytest.fixture(scope="module")
def noisy_balloon(balloon):
    """The measured balloon curve as a logger would record it: 500 volumes
    (0.11 mL apart) with Gaussian pressure noise of 1 kPa."""
    v = np.linspace(balloon.volume[0], balloon.volume[-1], 500)
    rng = np.random.default_rng(2024)
    return v, balloon(v), balloon(v) + rng.normal(0.0, NOISE, v.size)


def _sign_changes_of_slope(curve, n=5001):
    x = np.linspace(curve.volume[0], curve.volume[-1], n)
    d = curve.fdf_volume(x)[1]
    d = d[np.abs(d) > 1e-9 * np.abs(d).max()]       # not the round-off at a flat node
    return int(np.count_nonzero(np.diff(np.sign(d))))


@pytest.mark.parametrize("kwargs, rms_max, err_max, extrema_max", [
    # smoothing spline (GCV): noise / 4, within 1.5 % of the range (the largest error is
    # at the steep first rise, which smoothing rounds off), only the real extrema
    (dict(smoothing="auto"), 0.35 * NOISE, 1500.0, 4),
    (dict(smoothing=1e-6), 0.35 * NOISE, 1500.0, 20),
    # Savitzky-Golay over 21 samples: noise / 3 in value, but the slope stays rough
    (dict(filter_window=21), 0.45 * NOISE, 1500.0, 150),
    (dict(filter_window=21, smoothing="auto"), 0.35 * NOISE, 1500.0, 4),
], ids=["smoothing-auto", "smoothing-1e-6", "savgol-21", "savgol+smoothing"])
def test_smoothing_and_filter_reduce_noise(balloon, noisy_balloon, kwargs, rms_max, err_max,
                                           extrema_max):
    v, p_clean, p_noisy = noisy_balloon
    raw = sf.PVCurve(volume=v, pressure=p_noisy)
    curve = sf.PVCurve(volume=v, pressure=p_noisy, **kwargs)
    rms = lambda c: float(np.sqrt(np.mean((c(v) - p_clean) ** 2)))  # noqa: E731
    assert rms(raw) > 0.9 * NOISE
    assert rms(curve) < rms_max
    x = np.linspace(v[0], v[-1], 5001)
    assert np.abs(curve(x) - balloon(x)).max() < err_max
    # noise through PCHIP makes hundreds of spurious peaks (each a possible snap)
    assert _sign_changes_of_slope(raw) > 200
    assert _sign_changes_of_slope(curve) <= extrema_max
    np.testing.assert_array_equal(curve.measured_pressure, p_noisy)


def test_smoothing_spline_is_scipys_and_C2(balloon):
    """The stored values and slopes at the samples reproduce scipy's smoothing
    spline exactly (its knots are the samples), so the curve is C2."""
    from scipy.interpolate import make_smoothing_spline
    v, p = balloon.volume, balloon.pressure
    curve = sf.PVCurve(volume=v, pressure=p, smoothing=1e-6)
    span_v, span_p, mean_p = v[-1] - v[0], np.ptp(p), p.mean()
    spl = make_smoothing_spline((v - v[0]) / span_v, (p - mean_p) / span_p, lam=1e-6)
    x = interior_points(balloon, 4, seed=3)
    s = (x - v[0]) / span_v
    val, dval = curve.fdf_volume(x)
    np.testing.assert_allclose(val, spl(s) * span_p + mean_p, rtol=1e-12)
    np.testing.assert_allclose(dval, spl(s, 1) * span_p / span_v, rtol=0,
                               atol=1e-10 * np.abs(curve.slope).max())
    # second derivative continuous across the interior samples
    h = 1e-4 * np.diff(v).min()
    d2 = lambda y: (curve.fdf_volume(y + h)[1] - curve.fdf_volume(y - h)[1]) / (2 * h)  # noqa
    inner = v[1:-1]
    np.testing.assert_allclose(d2(inner - 10 * h), d2(inner + 10 * h), rtol=0,
                               atol=1e-3 * np.abs(d2(inner)).max())


def test_smoothing_zero_interpolates_and_gauge_is_kept(tmp_path):
    curve = sf.PVCurve(EXAMPLE_CSV, smoothing=0.0)
    np.testing.assert_allclose(curve(curve.volume), curve.measured_pressure, rtol=1e-12)
    assert curve.measured_pressure[0] == pytest.approx(P0 + 2200.0)
    assert sf.PVCurve(EXAMPLE_CSV, smoothing=True).pressure.shape == (56,)


def test_savgol_keeps_a_quadratic():
    """A Savitzky-Golay filter of order 2 leaves a quadratic untouched."""
    v = np.linspace(1e-6, 2e-5, 40)
    p = 1e5 + 1e13 * (v - 1e-6) ** 2 + 1e9 * v
    curve = sf.PVCurve(volume=v, pressure=p, filter_window=9)
    np.testing.assert_allclose(curve.pressure, p, rtol=1e-12)


@pytest.mark.parametrize("kwargs, text", [
    (dict(smoothing="auto", volume=[1, 2, 3, 4], pressure=[1, 2, 3, 4]),
     "smoothing needs at least 5 points, got 4"),
    (dict(smoothing=-1.0), "smoothing must be a number >= 0"),
    (dict(smoothing="lots"), "smoothing must be a number >= 0"),
    (dict(smoothing=np.nan), "smoothing must be a number >= 0"),
    (dict(filter_window=4), "filter_window must be an odd integer >= 3"),
    (dict(filter_window=1), "filter_window must be an odd integer >= 3"),
    (dict(filter_window=7.0), "filter_window must be an odd integer >= 3"),
    (dict(filter_window=9, volume=[1, 2, 3, 4, 5], pressure=[1, 2, 3, 4, 5]),
     r"<= the number of points \(5\), got 9"),
    (dict(filter_window=5, filter_order=4), "filter_order must be an integer from 0"),
    (dict(filter_window=5, filter_order=-1), "filter_order must be an integer from 0"),
])
def test_bad_smoothing_and_filter(kwargs, text):
    kwargs = dict(kwargs)
    v = np.array(kwargs.pop("volume", np.arange(1, 11))) * 1e-6
    p = np.array(kwargs.pop("pressure", np.arange(1, 11)), dtype=float) * 1e4 + P0
    with pytest.raises(ValueError, match=text):
        sf.PVCurve(volume=v, pressure=p, **kwargs)


# ---------------------------------------------------------------------------------------
# fdf_volume paths
# ---------------------------------------------------------------------------------------
def test_fdf_volume_array_kinds(balloon):
    x = np.linspace(0.5e-6, 60e-6, 17)
    ref = balloon.fdf_volume(x)
    for kind in (x.astype(np.float32), x.tolist(), sf.Q_(x * 1e6, "mL")):
        got = balloon.fdf_volume(kind)
        np.testing.assert_allclose(got[0], ref[0], rtol=1e-6)
        np.testing.assert_allclose(got[1], ref[1], rtol=1e-5, atol=1e-6 * np.abs(ref[1]).max())
    ints = balloon.fdf_volume(np.array([0, 1]))
    np.testing.assert_allclose(ints[0], balloon.fdf_volume(np.array([0.0, 1.0]))[0])
    # a non-contiguous view works too
    np.testing.assert_array_equal(balloon(x[::2]), ref[0][::2])


# ---------------------------------------------------------------------------------------
# synthetic curves
# ---------------------------------------------------------------------------------------
ML = 1e-6


def test_peak_valley_keeps_peak_and_valley():
    c = sf.PVCurve.peak_valley(start=(sf.Q_(1, "mL"), sf.Q_(0, "mbar")),
                               peak=(sf.Q_(5, "mL"), sf.Q_(900, "mbar")),
                               valley=(sf.Q_(15, "mL"), sf.Q_(500, "mbar")),
                               end=(sf.Q_(30, "mL"), sf.Q_(1200, "mbar")), gauge=True)
    x = np.union1d(np.linspace(1 * ML, 30 * ML, 30001), c.volume)
    p = c(x) - P0
    assert p[x < 10 * ML].max() == pytest.approx(9e4, rel=1e-12)
    assert p[(x > 5 * ML) & (x < 25 * ML)].min() == pytest.approx(5e4, rel=1e-12)
    np.testing.assert_allclose(c.fdf_volume(np.array([5 * ML, 15 * ML]))[1], 0.0,
                               atol=1e-12 * np.abs(c.slope).max())
    assert c(1 * ML) == pytest.approx(P0) and c(30 * ML) == pytest.approx(P0 + 1.2e5)
    assert "peak-valley" in repr(c)
    assert _sign_changes_of_slope(c) == 2         # exactly one peak and one valley


def test_plateau_and_monotonic_rise():
    plateau = sf.PVCurve.plateau((1 * ML, P0), (3 * ML, P0 + 3e4), (12 * ML, P0 + 3.3e4),
                                 (16 * ML, P0 + 8e4))
    x = np.linspace(1 * ML, 16 * ML, 3001)
    p, dp = plateau.fdf_volume(x)
    assert (dp >= 0).all()
    on_plateau = (x > 4 * ML) & (x < 11 * ML)
    assert np.ptp(p[on_plateau]) < 3.3e3 and dp[on_plateau].max() < 0.1 * dp.max()
    flat = sf.PVCurve.plateau((1 * ML, P0), (3 * ML, P0 + 3e4), (12 * ML, P0 + 3e4),
                              (16 * ML, P0 + 8e4))
    assert flat(7 * ML) == pytest.approx(P0 + 3e4)
    mono = sf.PVCurve.monotonic((1 * ML, 0.0), (4 * ML, 4e4), (20 * ML, 7e4), gauge=True)
    p, dp = mono.fdf_volume(np.linspace(1 * ML, 20 * ML, 1001))
    assert (dp > 0).all() and dp[0] > 3 * dp[-1]


@pytest.mark.parametrize("maker, args, text", [
    ("peak_valley", [(1, 0), (5, 9), (3, 5), (30, 12)], "volume of valley"),
    ("peak_valley", [(1, 0), (5, 9), (15, 10), (30, 12)],
     r"pressure at valley .* must be < the pressure at peak"),
    ("peak_valley", [(1, 10), (5, 9), (15, 5), (30, 12)],
     r"pressure at start .* must be < the pressure at peak"),
    ("peak_valley", [(1, 0), (5, 9), (15, 5), (30, 4)], r"pressure at valley .* < .* end"),
    ("plateau", [(1, 0), (3, 3), (12, 2), (16, 8)], r"plateau_end"),
    ("monotonic", [(1, 0), (4, 4), (20, 3)], r"pressure at knee"),
    ("monotonic", [(1, 0), (4, 4)], "missing"),
    ("monotonic", [(1, 0), (4, 4), (20,)], "end must be a .volume, pressure. pair"),
    ("monotonic", [(1, 0), (4, np.nan), (20, 5)], "knee must be a pair of finite numbers"),
])
def test_synthetic_curve_bad_input(maker, args, text):
    scaled = [tuple(a * s for a, s in zip(pt, (ML, 1e4))) for pt in args]
    with pytest.raises((ValueError, TypeError), match=text):
        getattr(sf.PVCurve, maker)(*scaled)


def test_synthetic_curve_units_are_checked():
    with pytest.raises(sf.UnitError, match="PVCurve.peak_valley: peak pressure expects a "
                                           "pressure"):
        sf.PVCurve.peak_valley((1 * ML, 0), (sf.Q_(5, "mL"), sf.Q_(1, "mL")), (15 * ML, 5e4),
                               (30 * ML, 1e5))


# ---------------------------------------------------------------------------------------
# hysteresis loops
# ---------------------------------------------------------------------------------------
from softflow.curves.hysteresis import HysteresisLoop  # noqa: E402


def _loop(**kw):
    return HysteresisLoop.snapping(start=(1 * ML, 0.0), peak=(6 * ML, 8e4),
                                   valley=(4 * ML, 3e4), end=(20 * ML, 1.2e5),
                                   snap_volume=0.5 * ML, gauge=True, **kw)


def test_snapping_loop_branches_meet_exactly():
    loop = _loop()
    inf, dfl = loop
    assert loop.volume_low == pytest.approx(3.5 * ML)
    assert loop.volume_high == pytest.approx(6.5 * ML)
    for v in (loop.volume_low, loop.volume_high):
        assert inf(v) == pytest.approx(dfl(v), rel=1e-14)
    # peak and valley kept; inflation above deflation inside the loop
    x = np.linspace(loop.volume_low + 0.05 * ML, loop.volume_high - 0.05 * ML, 301)
    assert (inf(x) > dfl(x)).all()
    assert inf(np.union1d(np.linspace(1 * ML, 6.5 * ML, 5001), inf.volume)).max() == \
        pytest.approx(P0 + 8e4, rel=1e-12)
    assert dfl(np.union1d(np.linspace(3.5 * ML, 20 * ML, 5001), dfl.volume)).min() == \
        pytest.approx(P0 + 3e4, rel=1e-12)


def test_loop_switching_rule():
    loop = _loop()
    v = np.array([2.0, 5.0, 6.49, 0.0, 9.0, 5.0, 3.51, 0.0, 2.0]) * ML
    v[3], v[7] = loop.volume_high, loop.volume_low          # exactly at the ends
    inflating = np.array([1, 1, 1, 1, 1, 0, 0, 0, 0], dtype=bool)
    nxt = loop.next_inflating(v, inflating)
    np.testing.assert_array_equal(nxt, [1, 1, 1, 0, 0, 0, 0, 1, 1])
    # each branch is continuous in volume: past its end it is the other curve
    for flag in (True, False):
        x = np.linspace(0.5 * ML, 25 * ML, 20001)
        p = loop.fdf_volume(x, np.full(x.shape, flag))[0]
        assert np.abs(np.diff(p)).max() < 2e3


def test_hysteresis_loop_bad_input():
    inf, dfl = _loop()
    with pytest.raises(ValueError, match=r"HysteresisLoop: hysteresis branches do not meet at "
                                         r"V = 6\.5e-06 m\^3"):
        HysteresisLoop(inf, sf.PVCurve(volume=dfl.volume,
                                       pressure=dfl.pressure + np.array([0, 5e3, 5e3, 5e3])))
    with pytest.raises(TypeError, match="inflation_curve must be a PVCurve"):
        HysteresisLoop(lambda v: P0, dfl)
    with pytest.raises(ValueError, match="meet_tolerance must be a pressure >= 0"):
        HysteresisLoop(inf, dfl, meet_tolerance=-1.0)
    with pytest.raises(ValueError, match="snap_volume must be > 0"):
        HysteresisLoop.snapping(
            (1 * ML, 0), (6 * ML, 8e4), (4 * ML, 3e4), (20 * ML, 1.2e5), snap_volume=0.0)
    with pytest.raises(ValueError, match="volumes must satisfy"):
        HysteresisLoop.snapping((1 * ML, 0), (6 * ML, 8e4), (4 * ML, 3e4), (20 * ML, 1.2e5),
                                snap_volume=3 * ML)
    with pytest.raises(ValueError, match="pressures must satisfy"):
        HysteresisLoop.snapping((1 * ML, 0), (6 * ML, 8e4), (4 * ML, 9e4), (20 * ML, 1.2e5),
                                snap_volume=0.5 * ML)


@pytest.mark.parametrize("extrapolate", ["linear", "clamp"])
def test_work_is_the_integral_of_the_pressure(extrapolate):
    """PVCurve.work: the exact integral of the curve (pieces and extensions) from
    its first volume; its derivative is the pressure."""
    from scipy.integrate import quad
    v = np.linspace(1e-6, 5e-6, 9)
    c = sf.PVCurve(volume=v, pressure=1e5 + 2e4 * np.sin(v * 1e6), extrapolate=extrapolate)
    vols = np.array([0.5e-6, 1e-6, 2.3e-6, 4.99e-6, 5e-6, 6e-6])
    want = [quad(lambda x: float(c(x)), 1e-6, V, epsabs=0, epsrel=1e-13, limit=200,
                 points=list(v))[0] for V in vols]
    np.testing.assert_allclose(c.work(vols), want, rtol=1e-12, atol=1e-18)
    h = 1e-12
    np.testing.assert_allclose((c.work(vols + h) - c.work(vols - h)) / (2 * h), c(vols),
                               rtol=1e-6)
    # one volume at a time (the list path of an actuator alone in its group):
    # bitwise the numbers of the array path
    for V, w in zip(vols, c.work(vols)):
        one = c.work(np.array([V]))
        assert one.shape == (1,) and one[0] == w


def test_work_of_one_volume_beyond_the_data_is_refused():
    from softflow.curves.pvcurve import CurveRangeError
    c = sf.PVCurve(volume=[1e-6, 2e-6, 3e-6], pressure=[1e5, 1.2e5, 1.3e5], extrapolate="error")
    for bad in ([0.5e-6], [3.5e-6], [0.5e-6, 2e-6]):
        with pytest.raises(CurveRangeError, match="beyond its data"):
            c.work(np.array(bad))


def test_hysteresis_work_is_continuous_through_the_handover():
    from softflow.paper_scenes import loop_hysteretic
    loop = loop_hysteretic()
    for inflating, edge in ((True, loop.volume_high), (False, loop.volume_low)):
        v = edge * (1 + np.array([-1e-9, 1e-9]))
        w = loop.work(v, inflating)
        p, _ = loop.fdf_volume(v, inflating)
        # the jump across the edge is the pressure times the gap, not the loop's area
        assert abs(w[1] - w[0]) <= 2 * p.max() * (v[1] - v[0])


def test_a_callable_curve_integrates_by_gauss_legendre():
    import softflow as sf
    act = sf.Actuator("a", sf.air, lambda v: 1e5 + 1e10 * v + 3e14 * v * v, initial_volume=1e-6)
    fn = act._curve_fn
    v = np.array([0.5e-6, 2e-6, 4e-6])
    exact = 1e5 * (v - 1e-6) + 0.5e10 * (v**2 - 1e-12) + 1e14 * (v**3 - 1e-18)
    np.testing.assert_allclose(fn.work(v), exact, rtol=1e-13)


# ---------------------------------------------------------------------------------------
# interpolation='linear': straight lines between the samples (fonsim's curves)
# ---------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def balloon_linear():
    return sf.PVCurve(EXAMPLE_CSV, interpolation="linear")


def test_linear_interpolation_is_numpy_interp_with_chord_slopes(balloon_linear):
    c = balloon_linear
    assert c.interpolation == "linear" and sf.PVCurve(EXAMPLE_CSV).interpolation == "pchip"
    x = interior_points(c)
    p, dp = c.fdf_volume(x)
    np.testing.assert_allclose(p, np.interp(x, c.volume, c.pressure), rtol=1e-14)
    chords = np.diff(c.pressure) / np.diff(c.volume)
    k = np.searchsorted(c.volume, x) - 1
    np.testing.assert_allclose(dp, chords[k], rtol=1e-12)
    # the scalar path (the compiled lookup on a float) gives the same
    for v in x[::7]:
        assert c.fdf_volume(float(v)) == pytest.approx(tuple(a[0] for a in
                                                             c.fdf_volume(np.array([v]))),
                                                       rel=1e-14)
    # the samples themselves; a sample takes the slope of the chord that starts there
    np.testing.assert_allclose(c(c.volume), c.pressure, rtol=1e-14)
    np.testing.assert_allclose(c.slope, np.append(chords, chords[-1]), rtol=1e-14)
    np.testing.assert_allclose(c.fdf_volume(c.volume[1:-1])[1], chords[1:], rtol=1e-12)
    assert "interpolation='linear'" in repr(c)


@pytest.mark.parametrize("extrapolate", ["linear", "clamp"])
def test_linear_interpolation_beyond_the_data(extrapolate):
    c = sf.PVCurve(EXAMPLE_CSV, interpolation="linear", extrapolate=extrapolate)
    v, p = c.volume, c.pressure
    first, last = (p[1] - p[0]) / (v[1] - v[0]), (p[-1] - p[-2]) / (v[-1] - v[-2])
    below, above = v[0] - 0.5e-6, v[-1] + 2e-6
    if extrapolate == "linear":    # the end chords continued
        assert c.fdf_volume(below) == (pytest.approx(p[0] - 0.5e-6 * first), pytest.approx(first))
        assert c.fdf_volume(above) == (pytest.approx(p[-1] + 2e-6 * last), pytest.approx(last))
    else:
        assert c.fdf_volume(below) == (pytest.approx(p[0]), 0.0)
        assert c.fdf_volume(above) == (pytest.approx(p[-1]), 0.0)


def test_linear_interpolation_work_is_the_trapezoid_rule(balloon_linear):
    c = balloon_linear
    v = c.volume
    w = c.work(v)
    np.testing.assert_allclose(w[1:], np.cumsum(np.diff(v) * 0.5 * (c.pressure[1:]
                                                                    + c.pressure[:-1])),
                               rtol=1e-12)
    x = np.linspace(v[0], v[-1], 1001)
    dw = np.gradient(c.work(x), x)
    np.testing.assert_allclose(dw[1:-1], c(x)[1:-1], rtol=2e-3)


def test_linear_interpolation_with_a_filter_and_the_synthetic_shape():
    v = np.linspace(1e-6, 10e-6, 21)
    p = P0 + 1e4 * (v / 1e-6) ** 2 / 100
    c = sf.PVCurve(volume=v, pressure=p, interpolation="linear", filter_window=5)
    np.testing.assert_allclose(c(v), c.pressure, rtol=1e-14)   # through the filtered ones
    two = sf.PVCurve(volume=[1e-6, 2e-6], pressure=[1.1e5, 1.3e5], interpolation="linear")
    assert two(1.5e-6) == pytest.approx(1.2e5) and two.fdf_volume(1.2e-6)[1] == \
        pytest.approx(2e10)


@pytest.mark.parametrize("kwargs, text", [
    (dict(interpolation="cubic"), "PVCurve: interpolation must be one of 'pchip', 'linear' "
                                  "(monotone cubics or straight lines between the samples), "
                                  "got 'cubic'"),
    (dict(interpolation=None), "interpolation must be one of 'pchip', 'linear'"),
    (dict(interpolation="linear", smoothing=1e-6),
     "interpolation='linear' and smoothing=1e-06 exclude each other"),
])
def test_interpolation_bad_input(kwargs, text):
    with pytest.raises(ValueError, match=text.replace("(", r"\(").replace(")", r"\)")):
        sf.PVCurve(EXAMPLE_CSV, **kwargs)


def test_linear_curve_actuator_runs_through_its_kinks():
    # the balloon inflated past its peak and back by air: the straight pieces'
    # slopes jump at every sample (the solver is not told of these kinks: its
    # error test finds them); the run agrees with itself at a tight tolerance
    def run(rtol):
        s = sf.System()
        s += sf.PressureSource("src", pressure=lambda t: P0 + 1e5 * min(t / 2.0, 1.0)
                               * (1.0 if t < 3.0 else 0.0))
        s += sf.CircularTube("tube", sf.air, length=0.5, diameter=1e-3)
        s += sf.Actuator("act", sf.air, sf.PVCurve(EXAMPLE_CSV, interpolation="linear"))
        s.connect("src", "tube")
        s.connect("tube", "act")
        return sf.Simulation(s, duration=5.0, rtol=rtol, breakpoints=[3.0]).run()
    loose, tight = run(1e-3), run(1e-6)
    v_loose, v_tight = loose.get("act", "volume"), tight.get("act", "volume")
    assert v_tight.max() > 40e-6            # through the peak (6 mL) to 41 mL
    assert v_loose.max() == pytest.approx(v_tight.max(), rel=2e-3)
    assert v_loose[-1] == pytest.approx(v_tight[-1], rel=5e-3)
    # on the curve (the points inside steps are the BDF's interpolant: within 3e-6)
    p = tight.get("act", "pressure")
    np.testing.assert_allclose(p, sf.PVCurve(EXAMPLE_CSV, interpolation="linear")(v_tight),
                               rtol=1e-5)


def test_linear_curve_in_a_scene_file_stays_linear(tmp_path):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.3e5)
    s += sf.CircularTube("tube", sf.water, length=0.5, diameter=1e-3)
    s += sf.Actuator("act", sf.water, sf.PVCurve(EXAMPLE_CSV, interpolation="linear"))
    s.connect("src", "tube")
    s.connect("tube", "act")
    path = sf.scene.save(s, tmp_path / "scene.toml")
    back = sf.scene.load(path).get("act").curve
    assert back.interpolation == "linear"
    x = interior_points(back)
    np.testing.assert_allclose(back(x), s.get("act").curve(x), rtol=1e-12)
