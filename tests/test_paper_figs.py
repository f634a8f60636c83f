"""The nine simulations of the FONS paper's Figs. 3-5 show the behaviour the
paper describes, measured in numbers (softflow.paper_scenes builds them)."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import softflow as sf
from softflow import paper_scenes as ps
from helpers import crossing_time

ML = ps.ML
PUMP = ps.FLOW / ML           # mL/s
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _run(builder, case, fig):
    # (the time each takes is measured by benchmarks/bench_paper_scenes.py: no
    # wall-clock assertion in tests)
    res, _ = ps.run(builder(case), fig)
    assert res.success, res.message
    return res


@pytest.fixture(scope="module")
def fig3():
    return {c: _run(ps.fig3, c, 3) for c in ps.FIG3_CASES}


@pytest.fixture(scope="module")
def fig4():
    return {c: _run(ps.fig4, c, 4) for c in ps.FIG4_CASES}


@pytest.fixture(scope="module")
def fig5():
    fluids = {"air": sf.air, "water": sf.water, "ethylene glycol": sf.ethylene_glycol}
    return {name: _run(ps.fig5, f, 5) for name, f in fluids.items()}


def normalized_area(res):
    """Enclosed area of the (V1, V2) path over the area of its bounding box."""
    v1, v2 = ps.volumes(res)
    return ps.enclosed_area(v1, v2) / (np.ptp(v1) * np.ptp(v2))


def rates(res):
    """dV1/dt and dV2/dt [mL/s] per step."""
    t = res.times
    v1, v2 = ps.volumes(res)
    return np.diff(v1) / np.diff(t) / ML, np.diff(v2) / np.diff(t) / ML


def first_crossing(res, which, level_ml, rising, after=0.0):
    t = res.times
    v = ps.volumes(res)[which] / ML
    ok = t[1:] > after
    hit = ((v[:-1] < level_ml) & (v[1:] >= level_ml)) if rising else \
        ((v[:-1] > level_ml) & (v[1:] <= level_ml))
    k = np.flatnonzero(hit & ok)
    return t[k[0] + 1]


# -- common to all nine ------------------------------------------------------------------
def test_every_scene_returns_to_its_start(fig3, fig4, fig5):
    for res in [*fig3.values(), *fig4.values(), fig5["water"], fig5["ethylene glycol"]]:
        v1, v2 = ps.volumes(res)
        # the pump takes out what it put in: an incompressible fill ends where it began
        assert (v1[-1] + v2[-1]) == pytest.approx(v1[0] + v2[0], abs=0.05 * ML)


# -- Fig. 3 ------------------------------------------------------------------------------
def test_fig3_two_monotonic_actuators_give_a_symmetric_path(fig3):
    assert abs(normalized_area(fig3["monotonic"])) < 0.005


@pytest.mark.parametrize("case", ["peak-valley", "hysteretic"])
def test_fig3_peak_valley_and_hysteretic_actuators_enclose_an_area(fig3, case):
    assert abs(normalized_area(fig3[case])) > 0.15


def test_fig3_peak_valley_snap_moves_volume_from_actuator_2_to_1(fig3):
    r1, r2 = rates(fig3["peak-valley"])
    k = np.argmax(r1)
    assert r1[k] > 5 * PUMP       # a snap, far faster than the pump
    assert r2[k] < -0.8 * r1[k] + PUMP


# -- Fig. 4 ------------------------------------------------------------------------------
def _half_times(res, t_in):
    """When V2 passes half its range on inflation and on deflation (linear
    between the points either side: the adaptive steps are ~0.1 s long)."""
    t = res.times
    v2 = ps.volumes(res)[1]
    half = 0.5 * (v2.max() + v2[0])
    up = crossing_time(t, v2, half, np.flatnonzero(v2 >= half)[0])
    down = crossing_time(t, v2, half, np.flatnonzero((v2 <= half) & (t > t_in))[0])
    return up, down


def test_fig4_tight_tube_makes_a_lag(fig4, fig3):
    assert normalized_area(fig4["tube"]) > 0.03
    assert normalized_area(fig4["tube"]) > 20 * abs(normalized_area(fig3["monotonic"]))


def test_fig4_tesla_valve_lags_like_the_tube_on_inflation_and_more_on_deflation(fig4):
    t_in = ps.T_IN[4]
    up_tube, down_tube = _half_times(fig4["tube"], t_in)
    up_tesla, down_tesla = _half_times(fig4["tesla"], t_in)
    assert up_tesla == pytest.approx(up_tube, abs=0.05)
    assert down_tesla > down_tube + 0.3
    assert normalized_area(fig4["tesla"]) > 2 * normalized_area(fig4["tube"])
    # identical inflation: actuator 2's volume follows the tube case until the pause
    tube, tesla = fig4["tube"], fig4["tesla"]
    t = np.linspace(0, t_in, 200)
    v_tube = np.interp(t, tube.times, ps.volumes(tube)[1])
    v_tesla = np.interp(t, tesla.times, ps.volumes(tesla)[1])
    assert np.max(np.abs(v_tube - v_tesla)) < 0.02 * np.ptp(v_tube)


def test_fig4_snapping_valve_bursts_on_inflation_and_restricts_on_deflation(fig4):
    res = fig4["snapping"]
    t = res.times
    is_open = res.get("R2", "open")
    openings = t[1:][np.diff(is_open) > 0]
    t_in = ps.T_IN[4]
    assert len(openings) >= 4 and np.all(openings < t_in)     # bursts, inflation only
    mf = np.abs(res.get("R2", "massflow", "a"))
    assert mf[is_open[:-1].astype(bool).nonzero()[0] + 1].max() > 5 * mf[t > t_in + 2].max()
    _, down_tube = _half_times(fig4["tube"], t_in)
    _, down_snap = _half_times(res, t_in)
    assert down_snap > down_tube + 0.5                          # tighter than the tube


# -- Fig. 5 ------------------------------------------------------------------------------
def test_fig5_air_lets_the_actuators_snap_independently(fig5):
    r1, r2 = rates(fig5["air"])
    k = np.argmax(np.abs(r1))
    assert abs(r1[k]) > 20 * PUMP                # a fast snap of actuator 1 ...
    assert abs(r2[k]) < 0.1 * abs(r1[k])         # ... that actuator 2 hardly feels


def test_fig5_water_couples_the_volumes_during_a_snap(fig5):
    r1, r2 = rates(fig5["water"])
    k = np.argmax(np.abs(r1))
    assert abs(r1[k]) > 2 * PUMP
    assert np.sign(r2[k]) == -np.sign(r1[k])     # opposite directions
    assert r1[k] + r2[k] == pytest.approx(PUMP, abs=0.02)    # only the pump adds volume


def test_fig5_glycol_damps_the_snaps_and_changes_the_sequence_on_inflation_only(fig5):
    water, glycol = fig5["water"], fig5["ethylene glycol"]
    fastest = lambda res: max(np.abs(r).max() for r in rates(res))   # noqa: E731
    assert fastest(glycol) < 0.5 * fastest(water)
    t_in = ps.T_IN[5]
    level = 4.0   # mL, between the peak and the valley volumes
    for res, first_up in ((water, 1), (glycol, 0)):
        t1 = first_crossing(res, 0, level, rising=True)
        t2 = first_crossing(res, 1, level, rising=True)
        assert (t1 < t2) == (first_up == 0)
    for res in (water, glycol):                  # deflation: actuator 2 first, both fluids
        t1 = first_crossing(res, 0, level, rising=False, after=t_in)
        t2 = first_crossing(res, 1, level, rising=False, after=t_in)
        assert t2 < t1


# -- the example scripts -----------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("fig", [3, 4, 5])
def test_example_script_saves_panels_c_and_d(fig, tmp_path):
    out = subprocess.run([sys.executable, str(EXAMPLES / f"paper_fig{fig}.py")], cwd=tmp_path,
                         capture_output=True, text=True, env={"MPLBACKEND": "Agg",
                                                              "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    for panel in "CD":
        assert (tmp_path / f"fig{fig}_{panel}.png").stat().st_size > 10_000


def test_cli_figures_writes_the_panels(tmp_path, monkeypatch, capsys):
    from softflow.cli import main
    monkeypatch.setenv("MPLBACKEND", "Agg")
    assert main(["figures", "--fig", "3", "--output-dir", str(tmp_path / "out")]) == 0
    for panel in "CD":
        assert (tmp_path / "out" / f"fig3_{panel}.png").stat().st_size > 10_000
    assert "Fig. 3 hysteretic" in capsys.readouterr().out
