"""Waveforms: values (scalar and array), breakpoints, units and bad input."""
import math

import numpy as np
import pytest

import softflow as sf
from softflow.curves.csvdata import DataFileError
from softflow.curves.waveforms import (Constant, PiecewiseConstant, PiecewiseLinear, Ramp, Sine,
                                       Square, Step, Trapezoid, Waveform, from_csv)
from softflow.units import UnitError

Q_ = sf.Q_

EXAMPLES = {
    "Constant": Constant(Q_(2, "bar")),
    "Step": Step(0.1, Q_(0, "bar"), Q_(0.5, "bar")),
    "Ramp": Ramp(0.2, 0.7, 1.0, 3.0),
    "Trapezoid": Trapezoid(1.0, 5.0, rise=0.1, hold=0.2, fall=0.3, start=0.05, period=1.0),
    "PiecewiseLinear": PiecewiseLinear([0.0, 0.5, 1.0, 2.0], [0.0, 2.0, -1.0, 0.5]),
    "PiecewiseConstant": PiecewiseConstant([0.0, 10.0, 15.0], Q_([1.8, 0, -1.8], "mL/s")),
    "Sine": Sine(2.0, Q_(3, "Hz"), offset=1.0, phase=Q_(30, "deg")),
    "Square": Square(-1.0, 1.0, frequency=2.0, duty=0.25, start=0.1),
}


# ---------------------------------------------------------------------------------------
# common behaviour
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_scalar_and_array_evaluation_agree(name):
    w = EXAMPLES[name]
    t = np.linspace(-1.0, 20.0, 2001)
    arr = w(t)
    assert isinstance(arr, np.ndarray) and arr.shape == t.shape
    scal = [w(float(x)) for x in t]
    assert all(isinstance(v, float) for v in scal)
    np.testing.assert_allclose(arr, scal, rtol=1e-13, atol=1e-13)
    assert w(t.reshape(23, 87)).shape == (23, 87)


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_breakpoints_are_where_value_or_slope_jumps(name):
    """Away from the declared breakpoints the waveform is smooth: its second
    difference is tiny; across each breakpoint the value or slope jumps."""
    w = EXAMPLES[name]
    if name in ("Sine", "Constant"):
        assert w.breakpoints == ()
        assert w.breakpoints_until(100.0) == ()
        return
    T = 20.0
    breaks = np.array(w.breakpoints_until(T))
    assert breaks.size and np.all(np.diff(breaks) > 0)
    grid = np.linspace(0.0, T, 4001)
    scale = np.max(np.abs(w(grid)))
    h = 1e-6
    for b in breaks:
        v = w(np.array([b - 2 * h, b - h, b + h, b + 2 * h]))
        slope_l, slope_r = (v[1] - v[0]) / h, (v[3] - v[2]) / h
        jump = abs(v[2] - v[1]) > 1e-3 * scale or abs(slope_r - slope_l) > 1e-3 * scale
        assert jump, (name, b)
    # smooth between breakpoints
    mids = grid[np.min(np.abs(grid[:, None] - breaks[None, :]), axis=1) > 3e-3]
    d = 1e-3
    second = w(mids + d) - 2 * w(mids) + w(mids - d)
    assert np.max(np.abs(second)) < 1e-9 * scale, name


def test_waveform_units_are_si_base():
    assert EXAMPLES["Step"](1.0) == pytest.approx(0.5e5)
    assert EXAMPLES["Step"].unit.dimensionality == sf.ureg.Unit("Pa").dimensionality
    assert EXAMPLES["PiecewiseConstant"](1.0) == pytest.approx(1.8e-6)
    assert EXAMPLES["Ramp"].unit is None
    w = Step(Q_(100, "ms"), Q_(1, "atm"), Q_(1.3, "bar"))
    assert w.breakpoints == (pytest.approx(0.1),)
    assert w(0.0) == pytest.approx(101325.0) and w(0.1) == pytest.approx(1.3e5)
    assert w.factor_to("Pa", name="pressure", owner="x") == 1.0
    with pytest.raises(UnitError, match=r"pressure expects a volume flow.*Step"):
        w.factor_to("m**3/s", name="pressure", owner="x")


def test_list_of_quantities_is_accepted():
    w = PiecewiseLinear([Q_(0, "s"), Q_(1, "min")], [Q_(1, "bar"), Q_(2000, "mbar")])
    assert w(30.0) == pytest.approx(1.5e5)
    assert w.breakpoints == (0.0, 60.0)


# ---------------------------------------------------------------------------------------
# each waveform's values
# ---------------------------------------------------------------------------------------
def test_step_is_right_continuous():
    w = Step(0.1, 1.0, 2.0)
    assert w(0.1) == 2.0
    assert w(math.nextafter(0.1, 0.0)) == 1.0
    assert w.breakpoints == (0.1,)


def test_ramp_values():
    w = EXAMPLES["Ramp"]
    np.testing.assert_allclose(w(np.array([0.0, 0.2, 0.45, 0.7, 9.0])), [1, 1, 2, 3, 3])
    assert w.breakpoints == (0.2, 0.7)


def test_trapezoid_values_and_periodic_breakpoints():
    w = EXAMPLES["Trapezoid"]  # low 1, high 5, start 0.05, rise .1, hold .2, fall .3, period 1
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.5, 0.7, 0.8])
    np.testing.assert_allclose(w(t), [1, 3, 5, 5, 3, 1, 1])
    np.testing.assert_allclose(w(t + 3.0), w(t))
    assert w.breakpoints == pytest.approx((0.05, 0.15, 0.35, 0.65))
    b = w.breakpoints_until(2.5)
    np.testing.assert_allclose(b, [0.05, 0.15, 0.35, 0.65, 1.05, 1.15, 1.35, 1.65, 2.05, 2.15,
                                   2.35])
    # not periodic: the single pulse
    single = Trapezoid(0.0, 1.0, rise=0.0, hold=1.0, fall=0.5)
    assert single(0.0) == 1.0 and single(1.25) == 0.5 and single(5.0) == 0.0
    assert single.breakpoints == (0.0, 1.0, 1.5)
    assert single.breakpoints_until(1.2) == (0.0, 1.0)


def test_piecewise_linear_matches_interp():
    w = EXAMPLES["PiecewiseLinear"]
    t = np.linspace(-1, 3, 97)
    np.testing.assert_allclose(w(t), np.interp(t, w.times, w.values))
    assert w.breakpoints == (0.0, 0.5, 1.0, 2.0)


def test_piecewise_constant_is_the_paper_pump():
    w = EXAMPLES["PiecewiseConstant"]
    np.testing.assert_allclose(w(np.array([-1.0, 0.0, 9.99, 10.0, 14.0, 15.0, 30.0])),
                               np.array([1.8, 1.8, 1.8, 0, 0, -1.8, -1.8]) * 1e-6)
    assert w.breakpoints == (10.0, 15.0)   # times[0] is no jump: values[0] holds before it
    assert w.breakpoints_until(12.0) == (10.0,)


def test_sine_values():
    w = EXAMPLES["Sine"]
    t = np.linspace(0, 1, 11)
    np.testing.assert_allclose(w(t), 1 + 2 * np.sin(2 * np.pi * 3 * t + np.pi / 6), rtol=1e-14)


def test_square_values_and_breakpoints():
    w = EXAMPLES["Square"]  # low -1, high 1, period 0.5, duty .25, start .1
    np.testing.assert_allclose(w(np.array([0.0, 0.1, 0.2, 0.23, 0.6, 0.73])), [-1, 1, 1, -1, 1, -1])
    assert w.breakpoints == (0.1, 0.225)
    b = w.breakpoints_until(2.0)
    assert len(b) == 8 and b[0] == 0.1 and b[-1] == pytest.approx(1.725)
    np.testing.assert_allclose(np.diff(b[::2]), 0.5)


#: periodic waveforms that jump, on periods that are no binary fractions
#: (before the edges were computed as breakpoints_until computes them, 4 % of
#: these breakpoints had the jump an ulp or more before them, 27 % after)
JUMPING = [Square(0.0, 1.0, f, duty, start) for f in (3.0, 7.0, 1.7, 100 / 3)
           for duty in (0.1, 0.3, 0.5, 0.7) for start in (0.0, 0.01, 0.1)]
JUMPING += [Trapezoid(0.0, 1.0, rise, hold, fall, start, period)
            for period in (1 / 3, 0.7, 1 / 7, 0.13, None)
            for rise, hold, fall in ((0.0, 0.05, 0.0), (0.0, 0.03, 0.01), (0.01, 0.02, 0.0))
            for start in (0.0, 0.01, 1 / 3)]


@pytest.mark.parametrize("w", JUMPING, ids=[f"{type(w).__name__}-{i}" for i, w in enumerate(JUMPING)])
def test_a_jump_falls_exactly_at_its_breakpoint(w):
    # the step that lands on a breakpoint b sees the inputs at the float just
    # before b (their left limit), the next one starts at b: the value must
    # change exactly between those two floats, in scalar and array evaluation
    bps = w.breakpoints_until(3.0)
    assert len(bps) >= (5 if w.period is not None else 1)
    jumps = 0
    for b in bps:
        eps = 1e-9
        left, right = math.nextafter(b, -math.inf), b
        assert w(left) == w(b - eps) or abs(w(left) - w(b - eps)) < 1e-6, (b, "left")
        assert w(right) == w(b + eps) or abs(w(right) - w(b + eps)) < 1e-6, (b, "right")
        pair = w(np.array([left, right]))
        assert pair[0] == w(left) and pair[1] == w(right)
        jumps += abs(w(right) - w(left)) > 0.5
    assert jumps > 0


# ---------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("make, match", [
    (lambda: PiecewiseLinear([0, 1, 1, 2], [0, 1, 2, 3]),
     r"PiecewiseLinear: times must be strictly increasing, but times\[2\] = 1 s"),
    (lambda: PiecewiseConstant([0, 2, 1], [0, 1, 2]), r"PiecewiseConstant.*times\[2\]"),
    (lambda: PiecewiseLinear([0, 1], [0, 1, 2]), r"equally long"),
    (lambda: PiecewiseLinear([0, np.nan], [0, 1]), r"times must be finite"),
    (lambda: PiecewiseLinear([0, 1], [0, np.inf]), r"values must be finite"),
    (lambda: Ramp(1.0, 1.0, 0, 1), r"Ramp: t1 \(1.0 s\) must be after t0"),
    (lambda: Trapezoid(0, 1, rise=0.5, hold=0.5, fall=0.5, period=1.0), r"period"),
    (lambda: Trapezoid(0, 1, rise=-0.1, hold=0.5, fall=0.5), r"rise must be >= 0"),
    (lambda: Sine(1, 0.0), r"frequency must be > 0"),
    (lambda: Square(0, 1, 1.0, duty=1.0), r"duty must be in \(0, 1\)"),
    (lambda: Step(0.1, [1, 2], 3), r"before must be a scalar"),
])
def test_bad_input_names_the_parameter(make, match):
    with pytest.raises(ValueError, match=match):
        make()


@pytest.mark.parametrize("make, match", [
    (lambda: Step(0.1, Q_(1, "bar"), Q_(1, "mL/s")), r"Step: after is in .* but before"),
    (lambda: Step(Q_(1, "m"), 0, 1), r"Step: time expects a time"),
    (lambda: Sine(Q_(1, "bar"), Q_(1, "m")), r"frequency expects"),
    (lambda: Constant("1 bar"), r"string"),
])
def test_unit_errors(make, match):
    with pytest.raises(UnitError, match=match):
        make()


# ---------------------------------------------------------------------------------------
# CSV
# ---------------------------------------------------------------------------------------
def test_from_csv_with_units_row(tmp_path):
    p = tmp_path / "signal.csv"
    p.write_text("Supply pressure,2024-01-01\ntime,pressure\nms,mbar\n0,0\n100,300\n500,300\n")
    w = from_csv(p, "time", "pressure")
    assert isinstance(w, PiecewiseLinear)
    assert w(0.05) == pytest.approx(150e2)
    assert w.breakpoints == pytest.approx((0.0, 0.1, 0.5))
    assert w.unit.dimensionality == sf.ureg.Unit("Pa").dimensionality
    steps = from_csv(p, kind="previous")  # default columns: first and second
    assert isinstance(steps, PiecewiseConstant) and steps(0.05) == 0.0
    with pytest.raises(UnitError, match="mbar"):
        from_csv(p, unit="mL/s")


def test_from_csv_without_units_row_needs_unit(tmp_path):
    p = tmp_path / "flow.csv"
    p.write_text("t,q\n0,1.8\n10,0\n15,-1.8\n")
    with pytest.raises(DataFileError, match="give unit="):
        from_csv(p)
    w = from_csv(p, unit="mL/s", kind="previous")
    assert w(12.0) == 0.0 and w(16.0) == pytest.approx(-1.8e-6)


def test_from_csv_times_not_increasing_names_the_line(tmp_path):
    p = tmp_path / "bad.csv"
    p.write_text("t,p\ns,bar\n0,1\n1,2\n1,3\n")
    with pytest.raises(DataFileError, match=r"line 5: times must be strictly increasing"):
        from_csv(p)


def test_user_waveform_subclass():
    class Half(Waveform):
        _breaks = (1.0,)

        def _scalar(self, t):
            return 0.5 * t

        def _array(self, t):
            return 0.5 * t

    w = Half()
    assert w(3.0) == 1.5 and w.breakpoints_until(0.5) == ()
