"""Result.plot, Result.plot_path and PVCurve.plot: what is drawn, in which units, and
the errors for what does not exist."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import softflow as sf  # noqa: E402

P0 = sf.pressure_atmospheric


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def curve():
    return sf.PVCurve(volume=sf.Q_([1, 2, 4, 6], "mL"), pressure=sf.Q_([10, 40, 30, 60], "mbar"),
                      gauge=True)


@pytest.fixture(scope="module")
def result(curve):
    """src -> tube1 -> act1 -> tube2 -> act2 (the paper's chain, air)."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 0.05e5)
    s += sf.CircularTube("tube1", sf.air, length=0.2, diameter=1e-3)
    s += sf.Actuator("act1", sf.air, curve=curve, initial_volume=sf.Q_(1, "mL"))
    s += sf.CircularTube("tube2", sf.air, length=0.5, diameter=0.5e-3)
    s += sf.Actuator("act2", sf.air, curve=curve, initial_volume=sf.Q_(1, "mL"))
    s.connect(("src", "a"), ("tube1", "a"))
    s.connect(("tube1", "b"), ("act1", "a"))
    s.connect(("act1", "a"), ("tube2", "a"))
    s.connect(("tube2", "b"), ("act2", "a"))
    return sf.Simulation(s, duration=0.1, step=2e-3).run()


def _lines(ax):
    return {line.get_label(): line for line in ax.get_lines()}


def test_plot_one_quantity_returns_one_axes_in_si(result):
    ax = result.plot("act1.volume", ("act2", "volume"))
    assert isinstance(ax, matplotlib.axes.Axes)
    assert ax.get_ylabel() == "volume [m³]" and ax.get_xlabel() == "time [s]"
    lines = _lines(ax)
    assert set(lines) == {"act1.volume", "act2.volume"}
    np.testing.assert_array_equal(lines["act2.volume"].get_xdata(), result.times)
    np.testing.assert_array_equal(lines["act2.volume"].get_ydata(), result.get("act2", "volume"))


def test_plot_units_gauge_and_several_quantities(result):
    axes = result.plot(components=["act1", "act2"], names=["pressure", "volume"],
                       units={"pressure": "mbar", "volume": "mL"}, gauge=True, time_unit="ms")
    assert isinstance(axes, list) and len(axes) == 2
    pressure_ax, volume_ax = axes
    assert pressure_ax.get_ylabel() == "gauge pressure [mbar]"
    assert volume_ax.get_ylabel() == "volume [mL]"
    assert volume_ax.get_xlabel() == "time [ms]"
    p = _lines(pressure_ax)["act1.pressure"]
    np.testing.assert_allclose(p.get_ydata(), (result.get("act1", "pressure") - P0) / 100)
    np.testing.assert_allclose(p.get_xdata(), result.times * 1e3)
    v = _lines(volume_ax)["act2.volume"]
    np.testing.assert_allclose(v.get_ydata(), result.get("act2", "volume") * 1e6)


def test_plot_per_terminal_and_into_given_axes(result):
    fig, ax = plt.subplots()
    out = result.plot(("tube1", "massflow", "b"), "tube2.massflow_a", units="g/s", ax=ax)
    assert out is ax
    lines = _lines(ax)
    np.testing.assert_allclose(lines["tube1.massflow_b"].get_ydata(),
                               result.get("tube1", "massflow", "b") * 1e3)
    assert ax.get_ylabel() == "massflow [g/s]"


def test_plot_path_is_panel_d(result):
    ax = result.plot_path(("act1", "volume"), ("act2", "volume"), units="mL", label="air")
    assert ax.get_xlabel() == "act1.volume [mL]"
    assert ax.get_ylabel() == "act2.volume [mL]"
    path, start = ax.get_lines()
    np.testing.assert_allclose(path.get_xdata(), result.get("act1", "volume") * 1e6)
    np.testing.assert_allclose(path.get_ydata(), result.get("act2", "volume") * 1e6)
    assert start.get_xdata()[0] == pytest.approx(1.0)       # the start is marked
    assert ax.get_legend().get_texts()[0].get_text() == "air"
    ax = result.plot_path("act1.volume", "act1.pressure", units={"pressure": "kPa"},
                          gauge=True)
    assert ax.get_xlabel() == "act1.volume [m³]"
    assert ax.get_ylabel() == "act1.pressure (gauge) [kPa]"
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(),
                               (result.get("act1", "pressure") - P0) / 1e3)


def test_plotting_what_does_not_exist_lists_what_does(result):
    with pytest.raises(KeyError, match=r"'act1' has no variable 'volumes'.*'volume'"):
        result.plot("act1.volumes")
    with pytest.raises(KeyError, match=r"no component 'act3'.*'act1', 'act2'"):
        result.plot_path(("act1", "volume"), ("act3", "volume"))
    with pytest.raises(ValueError, match=r"'volume' is not 'component.variable'.*act1.volume"):
        result.plot("volume")
    with pytest.raises(ValueError, match="components= and names= together"):
        result.plot(components=["act1"])
    with pytest.raises(sf.UnitError, match=r"act1.volume is a volume \[m\*\*3\].*'bar'"):
        result.plot("act1.volume", units="bar")
    with pytest.raises(sf.UnitError, match="time_unit 'mL'"):
        result.plot("act1.volume", time_unit="mL")
    with pytest.raises(ValueError, match="2 quantities to plot.*ax= gives 1"):
        result.plot("act1.volume", "act1.pressure", ax=plt.subplots()[1])
    with pytest.raises(TypeError, match=r"\(component, variable\[, terminal\]\)"):
        result.plot(42)


def test_plot_without_variables_draws_the_nodes_that_hold_something(result):
    """result.plot() draws the pressures of the one-port components (source,
    actuators) and the actuators' volumes, which change: two stacked axes."""
    axes = result.plot()
    assert len(axes) == 2
    assert set(_lines(axes[0])) == {"src.pressure", "act1.pressure", "act2.pressure"}
    assert set(_lines(axes[1])) == {"act1.volume", "act2.volume"}
    np.testing.assert_allclose(_lines(axes[1])["act2.volume"].get_ydata(),
                               result["act2.volume"])


def test_pvcurve_plot(curve):
    ax = curve.plot()
    assert ax.get_xlabel() == "volume [mL]" and ax.get_ylabel() == "gauge pressure [mbar]"
    line, samples = ax.get_lines()
    np.testing.assert_allclose(samples.get_xdata(), [1, 2, 4, 6])
    np.testing.assert_allclose(samples.get_ydata(), [10, 40, 30, 60])
    # the curve passes through its samples and spans exactly their range
    x, y = line.get_xdata(), line.get_ydata()
    assert x[0] == pytest.approx(1) and x[-1] == pytest.approx(6)
    np.testing.assert_allclose(np.interp([2, 4], x, y), [40, 30], rtol=1e-9)
    ax = curve.plot(volume_unit="L", pressure_unit="kPa", gauge=False, points=False,
                    extend=0.1)
    (line,) = ax.get_lines()
    assert ax.get_ylabel() == "pressure [kPa]"
    assert line.get_xdata()[0] == pytest.approx(0.001 - 0.1 * 0.005)     # 0.5 mL
    assert line.get_ydata().max() > (P0 + 6000) / 1000        # the linear continuation
    with pytest.raises(sf.UnitError, match="volume_unit 'bar'"):
        curve.plot(volume_unit="bar")
    with pytest.raises(ValueError, match="extend"):
        curve.plot(extend=-1)


def test_hysteresis_loop_plot():
    loop = sf.HysteresisLoop.snapping((1e-6, 0.0), (6e-6, 2.6e3), (4e-6, 1.2e3), (14e-6, 4e3),
                                      snap_volume=0.3e-6, gauge=True)
    ax = loop.plot(points=False)
    assert [line.get_label() for line in ax.get_lines()] == ["inflation", "deflation"]
