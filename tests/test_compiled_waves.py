"""The waveforms' one law (softflow.laws.waves, which the classes of
softflow.curves.waveforms evaluate through, scalar and array) against each
class's definition written here in NumPy, at thousands of times (every
breakpoint and its neighbouring floats, period multiples, far beyond tables,
negative times), and the sources' values of softflow.solve.wavecodes against
the source groups' own ``values(t)``. Runs compiled and, with
NUMBA_DISABLE_JIT=1, as plain Python."""
import math
import types

import numpy as np
import pytest

import softflow as sf
from softflow.components.sources import _SourceParams
from softflow.components.thermal import ThermalMassFlowSource, ThermalPressureSource
from softflow.curves.waveforms import (Constant, PiecewiseConstant, PiecewiseLinear, Ramp,
                                       Sine, Square, Step, Trapezoid, Waveform)
from softflow.laws import waves
from softflow.solve import wavecodes
from softflow.units import ureg

Q_ = sf.Q_

WAVES = {
    "constant": lambda: Constant(3.25),
    "constant-negative-zero": lambda: Constant(-0.0),
    "constant-bar": lambda: Constant(Q_(1.3, "bar")),
    "step": lambda: Step(0.1, 1e5, 2e5),
    "step-at-zero": lambda: Step(0.0, Q_(1, "atm"), Q_(1.5, "bar")),
    "step-negative-time": lambda: Step(-1.5, -2.0, 7.0),
    "step-inexact-time": lambda: Step(1 / 3, 0.3, 0.7),
    "ramp": lambda: Ramp(0.0, 1.0, 0.0, 1.0),
    "ramp-down-kpa": lambda: Ramp(0.1, 0.3, Q_(200, "kPa"), Q_(100, "kPa")),
    "ramp-negative": lambda: Ramp(-2.0, 3.3, 7.0, -7.0),
    "ramp-short": lambda: Ramp(1e-9, 1.1e-9, 0.1, 0.3),
    "linear-one-point": lambda: PiecewiseLinear([1.0], [5.0]),
    "linear-two-points": lambda: PiecewiseLinear([0.0, 0.7], [1e5, 3e5]),
    "linear-table": lambda: PiecewiseLinear([-1.0, 0.0, 0.1, 0.3, 1 / 3, 2.5, 10.0],
                                            [0.3, -1.1, 2.0, 2.0, 7.5, 1e-3, -4.0]),
    "linear-ml-s": lambda: PiecewiseLinear(Q_([0, 10, 15], "s"), Q_([1.8, 0, -1.8], "mL/s")),
    "linear-random": lambda: _random_table(PiecewiseLinear, 7),
    "held-one-point": lambda: PiecewiseConstant([1.0], [5.0]),
    "held-fons-paper": lambda: PiecewiseConstant(Q_([0, 10, 15], "s"),
                                                 Q_([1.8, 0, -1.8], "mL/s")),
    "held-table": lambda: PiecewiseConstant([-1.0, 0.0, 0.1, 0.3, 1 / 3, 2.5, 10.0],
                                            [0.3, -1.1, 2.0, 2.0, 7.5, 1e-3, -4.0]),
    "held-random": lambda: _random_table(PiecewiseConstant, 8),
    "trapezoid": lambda: Trapezoid(1e5, 2e5, 0.1, 0.2, 0.3),
    "trapezoid-periodic": lambda: Trapezoid(1e5, 2e5, 0.1, 0.2, 0.3, start=0.05, period=1.0),
    "trapezoid-tight-period": lambda: Trapezoid(-1.0, 3.0, 0.1, 0.2, 0.4, start=0.3,
                                                period=0.7000000000000001),
    "trapezoid-jumps": lambda: Trapezoid(0.0, 1.0, 0.0, 0.3, 0.0, start=-0.2, period=0.9),
    "trapezoid-no-hold": lambda: Trapezoid(Q_(0.2, "bar"), Q_(1, "bar"), 0.3, 0.0, 0.1,
                                           period=0.4 + 1 / 3),
    "trapezoid-negative-start": lambda: Trapezoid(2.0, -1.0, 0.25, 0.5, 0.125, start=-3.7),
    "sine": lambda: Sine(1.0, 1.0),
    "sine-offset-phase": lambda: Sine(Q_(5, "g/s"), 3.7, offset=Q_(1, "kg/min"),
                                      phase=Q_(30, "degree")),
    "sine-fast": lambda: Sine(2e4, 1e3, offset=1e5, phase=-1.2),
    "sine-slow": lambda: Sine(0.5, 1e-3, offset=-0.25, phase=math.pi),
    "square": lambda: Square(0.0, 1.0, 1.0),
    "square-duty-start": lambda: Square(Q_(1, "atm"), Q_(2, "bar"), 3.0, duty=0.3, start=0.2),
    "square-negative-start": lambda: Square(-1.0, 1.0, 7.0, duty=0.9, start=-0.45),
    "square-fast": lambda: Square(1e5, 3e5, 1e3, duty=0.1, start=1 / 3),
}


def _random_table(cls, n):
    rng = np.random.default_rng(n)
    times = np.cumsum(rng.uniform(1e-3, 2.0, n)) - 1.0
    return cls(times, rng.normal(size=n) * 1e5)


def _near(times):
    """The times and the two floats either side of each."""
    t = np.asarray(times, dtype=float)
    down = np.nextafter(t, -np.inf)
    up = np.nextafter(t, np.inf)
    return [t, down, up, np.nextafter(down, -np.inf), np.nextafter(up, np.inf)]


def _times(w):
    """Thousands of times for the waveform w: a grid, random times, far times,
    its breakpoints (periodic repetitions included) and period multiples, each
    with its neighbouring floats."""
    rng = np.random.default_rng(1)
    special = [0.0, -0.0, 5e-324, -5e-324, 1e-300, -1e-300, 1e6, 1e9 + 0.1, 1e12, 1e15,
               -1e15, 123456.789]
    marks = list(w.breakpoints) + list(w.breakpoints_until(30.0))
    marks += list(getattr(w, "times", ()))
    for name in ("time", "t0", "t1", "start"):
        if hasattr(w, name):
            marks.append(getattr(w, name))
    if w.period is not None:
        start = getattr(w, "start", 0.0)
        offsets = [b - start for b in w.breakpoints] + [0.0, w.period]
        for k in list(range(-3, 200)) + [997, 10 ** 4, 10 ** 6, 10 ** 9]:
            marks += [start + k * w.period + x for x in offsets]
    parts = [np.linspace(-3.0, 40.0, 2001), rng.uniform(-100.0, 1e4, 1000),
             rng.uniform(-1.0, 1.0, 500), np.asarray(special)] + _near(marks)
    return np.concatenate([np.ravel(p) for p in parts])


def _compiled(w):
    """(code, floats, start) of w alone, as describe() stores them."""
    code, floats = wavecodes._floats(w)
    return code, np.array(floats, dtype=float), 0


def _reference(w, t):
    """The waveform's definition (its class docstring), written here in NumPy
    on its public attributes, independently of softflow.laws.waves: the
    values the one law must give, away from the edges (where the law's own
    floats decide the side: tests/curves/test_waveforms.py's
    test_a_jump_falls_exactly_at_its_breakpoint)."""
    if isinstance(w, Constant):
        return np.full(t.shape, w.value)
    if isinstance(w, Step):
        return np.where(t >= w.time, w.after, w.before)
    if isinstance(w, Ramp):
        return np.interp(t, [w.t0, w.t1], [w.v0, w.v1])
    if isinstance(w, PiecewiseLinear):
        return np.interp(t, w.times, w.values)
    if isinstance(w, PiecewiseConstant):
        return w.values[np.maximum(np.searchsorted(w.times, t, side="right") - 1, 0)]
    if isinstance(w, Sine):
        return w.offset + w.amplitude * np.sin(2 * np.pi * w.frequency * t + w.phase)
    start = w.start
    tau = t - start if w.period is None else np.mod(t - start, w.period)
    if isinstance(w, Square):
        return np.where((t >= start) & (tau < w.duty * w.period), w.high, w.low)
    assert isinstance(w, Trapezoid)
    span = w.high - w.low
    with np.errstate(divide="ignore", invalid="ignore"):
        rising = w.low + span * tau / w.rise
        falling = w.high - span * (tau - w.rise - w.hold) / w.fall
    return np.select([t < start, tau < w.rise, tau < w.rise + w.hold,
                      tau < w.rise + w.hold + w.fall],
                     [w.low, rising, w.high, falling], default=w.low)


def _steepest(w):
    """The largest |slope| of the waveform [its unit / s] (0: piecewise constant)."""
    if isinstance(w, Sine):
        return 2 * np.pi * w.frequency * abs(w.amplitude)
    if isinstance(w, Ramp):
        return abs(w._slope)
    if isinstance(w, PiecewiseLinear) and len(w.times) > 1:
        return float(np.max(np.abs(np.diff(w.values) / np.diff(w.times))))
    if isinstance(w, Trapezoid):
        spans = [d for d in (w.rise, w.fall) if d > 0.0]
        return abs(w.high - w.low) / min(spans) if spans else 0.0
    return 0.0


def _bits(x):
    return np.asarray(x, dtype=np.float64).view(np.int64)


@pytest.mark.parametrize("name", list(WAVES))
def test_the_one_law_gives_each_waveforms_definition(name):
    # softflow.laws.waves is the waveforms' one law: a waveform's scalar and
    # array values, and the compiled loop's, are its wave_value's; checked
    # here against each class's definition at thousands of times (a few
    # ulps of the arithmetic apart, the sine's phase by its period's
    # multiple: 1e-16 of the argument), away from the edges
    w = WAVES[name]()
    code, floats, at = _compiled(w)
    times = _times(w)
    assert times.size > 3000
    got = np.array([waves.wave_value(code, floats, at, float(t)) for t in times])
    assert np.array_equal(_bits([w(float(t)) for t in times]), _bits(got))
    assert np.array_equal(_bits(w(times)), _bits(got))
    want = _reference(w, times)
    scale = np.abs(times) + (w.period or 0.0)
    away = np.ones(times.shape, dtype=bool)
    if w.period is None and w.breakpoints:
        edges = np.array(w.breakpoints)
        near = np.min(np.abs(times[:, None] - edges[None, :]), axis=1)
        away = near > 1e-9 * (np.abs(times) + 1.0)
    elif w.period is not None:
        # the period's remainder of a time far out carries its rounding:
        # within 1e-9 of a period's edge the side is the law's
        frac = np.mod(times - w.start, w.period) / w.period
        offsets = np.array([(b - w.start) / w.period for b in w.breakpoints] + [0.0, 1.0])
        away &= np.min(np.abs(frac[:, None] - offsets[None, :]), axis=1) > 1e-9 * (
            1.0 + np.abs(times) / w.period)
    away &= np.abs(times) < 1e12
    assert away.sum() > 1000, name
    # a time's rounding (a few ulps of t, or of its period's remainder) times
    # the waveform's steepest slope, and the arithmetic's own
    tol = 1e-15 * scale * _steepest(w) + 1e-12 * (np.abs(want) + np.max(np.abs(want[away])))
    bad = np.flatnonzero(away & ~(np.abs(got - want) <= tol))
    assert bad.size == 0, [(times[i], got[i], want[i]) for i in bad[:5]]


def test_every_waveform_class_is_covered_and_only_exactly():
    covered = {Constant, Step, Ramp, PiecewiseLinear, PiecewiseConstant, Trapezoid, Sine,
               Square}
    made = {type(make()) for make in WAVES.values()}
    assert made == covered

    class MyStep(Step):
        pass

    assert wavecodes._floats(MyStep(0.1, 1.0, 2.0)) is None
    codes = [waves.CONSTANT, waves.STEP, waves.RAMP, waves.LINEAR, waves.HELD,
             waves.TRAPEZOID, waves.SINE, waves.SQUARE]
    assert sorted(codes) == list(range(8))
    for make in WAVES.values():
        w = make()
        code, floats = wavecodes._floats(w)
        n = len(getattr(w, "times", ()))
        assert len(floats) == waves.size(code, n)


def test_an_unknown_code_gives_nan():
    assert math.isnan(waves.wave_value(99, np.zeros(4), 0, 0.5))


def test_waveforms_stored_side_by_side_read_their_own_floats():
    ws = [WAVES[name]() for name in ("linear-table", "square-duty-start", "held-random",
                                     "trapezoid-periodic", "ramp-negative")]
    floats, starts, codes = [], [], []
    for w in ws:
        code, fl = wavecodes._floats(w)
        codes.append(code)
        starts.append(len(floats))
        floats += fl
    floats = np.array(floats)
    for t in np.linspace(-2.0, 12.0, 701):
        for w, code, at in zip(ws, codes, starts):
            assert _bits(waves.wave_value(code, floats, at, float(t))) == _bits(w(float(t)))


# ---------------------------------------------------------------------------------------
# sources
# ---------------------------------------------------------------------------------------
def _in_kpa(w):
    """w with its unit declared kPa (the waveform classes keep SI base units, so
    only such a declaration gives a source a factor other than 1)."""
    w.unit = ureg.Unit("kPa")
    return w


def _groups():
    shared = Square(Q_(1, "atm"), Q_(2, "bar"), 3.0, duty=0.3, start=0.2)
    flow = PiecewiseLinear(Q_([0, 1, 1.5, 4], "s"), Q_([0, 2, 2, -1], "L/min"))
    return {
        "one-step-kpa": (sf.PressureSource, [
            sf.PressureSource("a", Step(0.1, Q_(100, "kPa"), Q_(250, "kPa")))]),
        "one-step-gauge": (sf.PressureSource, [
            sf.PressureSource("a", Step(0.1, 0.0, Q_(0.5, "bar")), gauge=True)]),
        "shared-gauge-and-not": (sf.PressureSource, [
            sf.PressureSource("a", shared), sf.PressureSource("b", shared, gauge=True)]),
        "mixed": (sf.PressureSource, [
            sf.PressureSource("a", Step(0.1, Q_(1, "atm"), Q_(1.5, "bar"))),
            sf.PressureSource("b", Q_(2, "bar")),
            sf.PressureSource("c", shared),
            sf.PressureSource("d", Trapezoid(Q_(1, "bar"), Q_(3, "bar"), 0.1, 0.2, 0.05,
                                             start=0.3, period=0.5), gauge=True),
            sf.PressureSource("e", shared),
            sf.PressureSource("f", Q_(0.3, "bar"), gauge=True),
            sf.PressureSource("g", PiecewiseConstant([0.0, 1.0, 2.0], Q_([1, 2, 3], "bar")))]),
        "factor-kpa": (sf.PressureSource, [
            sf.PressureSource("a", _in_kpa(Ramp(0.1, 0.7, 100.0, 300.0 / 7))),
            sf.PressureSource("b", _in_kpa(Sine(20.0, 2.0, offset=1e2 / 3))),
            sf.PressureSource("c", Q_(1, "bar"))]),
        "one-factor-kpa": (sf.PressureSource, [
            sf.PressureSource("a", _in_kpa(Square(100.0, 100.0 / 3, 3.0)))]),
        "massflow-g-s": (sf.MassFlowSource, [
            sf.MassFlowSource("m", Sine(Q_(5, "g/s"), 1.0, offset=Q_(1, "kg/min"))),
            sf.MassFlowSource("n", Q_(3, "g/s"))]),
        "volumeflow-l-min": (sf.VolumeFlowSource, [
            sf.VolumeFlowSource("q", flow, fluid=sf.water),
            sf.VolumeFlowSource("r", Ramp(0, 1, Q_(0, "mL/s"), Q_(2, "L/min")), fluid=sf.water),
            sf.VolumeFlowSource("s", flow, fluid=sf.water)]),
        "constants-only": (sf.MassFlowSource, [
            sf.MassFlowSource("m", 1e-3), sf.MassFlowSource("n", Q_(-2, "g/s"))]),
        "thermal": (_SourceParams, [
            ThermalPressureSource("p", Trapezoid(1e5, 2e5, 0.1, 0.2, 0.3, period=1.0)),
            ThermalPressureSource("q", 1.5e5)]),
        "thermal-flow": (_SourceParams, [
            ThermalMassFlowSource("m", PiecewiseConstant([0.0, 0.5], Q_([1, -1], "g/s")))]),
    }


def _params(cls, sources):
    return cls(sources) if cls is _SourceParams else cls.make_params(sources)


def _source_times(sources):
    marks = []
    for s in sources:
        marks += list(s.breakpoints_until(5.0))
    parts = [np.linspace(-1.0, 6.0, 1401), [0.0, 1e6, 1e9 + 0.25]] + _near(marks)
    return np.concatenate([np.ravel(p) for p in parts])


@pytest.mark.parametrize("name", list(_groups()))
def test_source_values_are_the_groups_values_to_the_bit(name):
    cls, sources = _groups()[name]
    P = _params(cls, sources)
    described = wavecodes.describe(P)
    assert described is not None
    base, slot, codes, factors, starts, floats = described
    assert base.dtype == factors.dtype == floats.dtype == np.float64
    assert slot.dtype == codes.dtype == starts.dtype == np.int64
    assert len(codes) == len(P._varying)
    reference = _params(cls, sources)
    for t in _source_times(sources):
        got = wavecodes.values(described, float(t))
        want = reference.values(float(t))
        assert np.array_equal(_bits(got), _bits(want)), (t, got, want)


def test_a_unit_factor_is_found_and_applied():
    cls, sources = _groups()["factor-kpa"]
    _, _, _, factors, _, _ = wavecodes.describe(_params(cls, sources))
    kpa = sources[0].signal.func.__closure__ is not None
    assert kpa and factors.tolist() == [ureg.Quantity(1.0, "kPa").to("Pa").magnitude] * 2
    assert factors[0] == pytest.approx(1e3)
    _, _, _, factors, _, _ = wavecodes.describe(_params(*_groups()["mixed"]))
    assert factors.tolist() == [1.0] * 4


def test_source_values_fill_out_in_place():
    cls, sources = _groups()["mixed"]
    base, slot, codes, factors, starts, floats = wavecodes.describe(_params(cls, sources))
    out = np.full(base.size, np.nan)
    waves.source_values(0.25, base, slot, codes, factors, starts, floats, out)
    assert np.array_equal(out, _params(cls, sources).values(0.25))


def _called_back(P, monkeypatch, times=(0.0, 0.05, 0.1, 0.25, 0.9)):
    """A group with a signal the laws do not state: described with the
    PYTHON code (compiled, softflow.solve.usercompile, or called back), its
    compiled values the group's own at each
    of ``times``; with settings.COMPILED_USER off, left to Python (None)."""
    from softflow.solve import settings
    described = wavecodes.describe(P)
    assert described is not None and waves.PYTHON in described[2]
    base, slot, codes, factors, starts, floats = described
    for t in times:
        out = np.full(base.size, np.nan)
        waves.source_values(t, base, slot, codes, factors, starts, floats, out)
        P.forget()
        assert np.array_equal(out, P.values(t)), t
    monkeypatch.setattr(settings, "COMPILED_USER", False)
    assert wavecodes.describe(P) is None
    monkeypatch.setattr(settings, "COMPILED_USER", True)


def test_a_python_function_is_called_back(monkeypatch):
    P = sf.PressureSource.make_params([
        sf.PressureSource("a", Step(0.1, 1e5, 2e5)),
        sf.PressureSource("b", lambda t: Q_(1 + t, "bar"))])
    _called_back(P, monkeypatch)
    P = sf.MassFlowSource.make_params([sf.MassFlowSource("m", lambda t: 1e-3 * t)])
    _called_back(P, monkeypatch)


@pytest.mark.parametrize("compiled", [True, False])
def test_a_python_function_that_raises_gives_nan_and_keeps_the_error(compiled, monkeypatch):
    """The compiled values are NaN where the function raised, compiled
    (softflow.solve.usercompile) or called back; a call-back keeps the
    error for the Python path (softflow.solve.usercall.RAISED), which raises
    it naming the source (tests/solve/test_usercall.py,
    tests/solve/test_usercompile.py)."""
    from softflow.solve import settings, usercall
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", compiled)

    def signal(t):
        if t > 0.5:
            raise ValueError("no pressure past 0.5 s")
        return 1e5
    P = sf.PressureSource.make_params([sf.PressureSource("a", signal)])
    base, slot, codes, factors, starts, floats = wavecodes.describe(P)
    out = np.zeros(1)
    waves.source_values(0.2, base, slot, codes, factors, starts, floats, out)
    assert out[0] == 1e5
    usercall.RAISED.clear()
    waves.source_values(0.7, base, slot, codes, factors, starts, floats, out)
    assert np.isnan(out[0])
    if compiled:
        assert not usercall.RAISED
    else:
        assert "no pressure past 0.5 s" in str(usercall.RAISED[-1])


def test_a_waveform_subclass_is_called_back(monkeypatch):
    class Doubled(Step):
        def _scalar(self, t):
            return 2.0 * super()._scalar(t)

    class Plain(Sine):
        pass

    class Mine(Waveform):
        def _scalar(self, t):
            return 1e5 + t

        def _array(self, t):
            return 1e5 + t

    for w in (Doubled(0.1, 1e5, 2e5), Plain(1e4, 1.0, offset=1e5), Mine(),
              _in_kpa(Plain(10.0, 1.0, offset=100.0))):
        P = sf.PressureSource.make_params([sf.PressureSource("a", w),
                                           sf.PressureSource("b", 1e5)])
        _called_back(P, monkeypatch)


def test_a_fons_wave_is_called_back(monkeypatch):
    from softflow.fons.wave import Custom

    w = Custom([[0.0, 1e5], [1.0, 2e5]])
    P = sf.PressureSource.make_params([sf.PressureSource("a", w)])
    _called_back(P, monkeypatch)


def test_parameters_computing_values_otherwise_are_left_to_python():
    class Own(_SourceParams):
        def values(self, t):
            return super().values(t) * 2.0

    assert wavecodes.describe(Own([sf.PressureSource("a", Step(0.1, 1e5, 2e5))])) is None


def test_a_signal_keeping_its_waveform_and_factor_is_read_from_them():
    w = Step(0.1, 1.0, 2.0)
    signal = types.SimpleNamespace(func=lambda t: 1e3 * w(t), fast=True, waveform=w,
                                   factor=1e3)
    assert wavecodes.waveform_of(signal) == (w, 1e3)
    # a function that merely closes over a waveform is not taken for a _Signal's
    signal = types.SimpleNamespace(func=lambda t: 2.0 * w(t), fast=True, unit="Pa",
                                   name="pressure", owner="test")
    assert wavecodes.waveform_of(signal) is None
    value, factor = w, 2.0
    signal.func = lambda t: factor * value(t)
    assert wavecodes.waveform_of(signal) is None     # 2.0 is not w's factor to Pa
    assert wavecodes.waveform_of(types.SimpleNamespace(func=None, fast=False)) is None


def test_joined_groups_give_each_groups_values_end_to_end():
    groups = _groups()
    names = ["mixed", "constants-only", "factor-kpa", "volumeflow-l-min", "one-step-kpa"]
    parts = [wavecodes.describe(_params(*groups[name])) for name in names]
    joined = wavecodes.join(parts)
    assert joined[1].dtype == np.int64 and joined[0].dtype == np.float64
    marks = [s.breakpoints_until(5.0) for name in names for s in groups[name][1]]
    for t in np.concatenate(_near([b for m in marks for b in m]) + [np.linspace(-1, 6, 141)]):
        want = np.concatenate([_params(*groups[name]).values(float(t)) for name in names])
        assert np.array_equal(_bits(wavecodes.values(joined, float(t))), _bits(want)), t
    empty = wavecodes.join([])
    assert all(a.size == 0 for a in empty)
    assert wavecodes.values(empty, 1.0).size == 0
