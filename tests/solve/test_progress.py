"""Progress of a run: the tqdm bar (simulated time, shown only after a delay,
only where asked or interactive) and the solver's events on the 'softflow'
logger."""
import logging

import pytest
import tqdm

import softflow as sf
from softflow import paper_scenes
from softflow.solve import progress as progress_module
from softflow.solve.progress import Progress

from helpers import rc_circuit


class RecordingBar(tqdm.tqdm):
    made = []

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.updates = []
        self.closed_by_run = False
        RecordingBar.made.append(self)

    def update(self, n=1):
        self.updates.append(n)
        return super().update(n)

    def close(self):
        self.closed_by_run = True
        super().close()


@pytest.fixture
def bars(monkeypatch):
    """Bars open at once (no 2 s delay) and are recorded."""
    RecordingBar.made = []
    monkeypatch.setattr(progress_module, "DELAY", 0.0)
    monkeypatch.setattr(progress_module, "CHECK_INTERVAL", 0.0)
    monkeypatch.setattr(tqdm, "tqdm", RecordingBar)
    return RecordingBar.made


@pytest.mark.parametrize("step", [None, 1e-3], ids=["bdf", "fixed"])
def test_progress_true_shows_a_bar_in_simulated_time_up_to_the_duration(bars, step):
    res = sf.Simulation(rc_circuit(), duration=0.3, step=step).run(progress=True)
    assert res.success
    assert len(bars) == 1
    bar = bars[0]
    assert bar.total == pytest.approx(0.3)
    assert bar.n == pytest.approx(0.3)                    # simulated seconds, to the end
    assert len(bar.updates) >= 3 and all(u >= 0 for u in bar.updates)
    assert bar.closed_by_run


def test_progress_false_and_non_interactive_default_show_no_bar(bars):
    sf.Simulation(rc_circuit(), duration=0.3).run(progress=False)
    sf.Simulation(rc_circuit(), duration=0.3).run()    # pytest's stderr is not a terminal
    assert bars == []


def test_a_quick_run_shows_no_bar_even_when_asked(monkeypatch):
    RecordingBar.made = []
    monkeypatch.setattr(tqdm, "tqdm", RecordingBar)
    monkeypatch.setattr(progress_module, "CHECK_INTERVAL", 0.0)   # DELAY stays 2 s
    monkeypatch.setattr(progress_module.time, "perf_counter", lambda: 0.0)  # no time passes
    sf.Simulation(rc_circuit(), duration=0.3).run(progress=True)
    assert RecordingBar.made == []


def test_the_bar_closes_when_the_run_fails(bars):
    system = sf.System()
    system += sf.PressureSource("bad", pressure=lambda t: 1.1e5 if t < 0.1 else float("nan"))
    system += sf.CircularTube("tube", sf.water, length=1.0, diameter=0.5e-3)
    system += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-12)
    system.connect("tube", "bad")
    system.connect("tube", "acc")
    res = sf.Simulation(system, duration=0.3, step=1e-3).run(progress=True,
                                                            raise_on_failure=False)
    assert not res.success
    assert len(bars) == 1 and bars[0].closed_by_run and bars[0].n < 0.3


def test_progress_must_be_a_bool_or_none():
    with pytest.raises(TypeError, match="progress must be True, False or None"):
        sf.Simulation(rc_circuit(), duration=0.1).run(progress="yes")


def test_step_reads_the_clock_only_every_stride_steps(monkeypatch):
    reads = []
    monkeypatch.setattr(progress_module.time, "perf_counter", lambda: reads.append(1) or 0.0)
    p = Progress(1.0, True)
    with p:
        for i in range(1000):
            p.step(i / 1000)
    # enter, exit and one look per 16 steps at most (the stride grows when no time passes)
    assert p.steps == 1000
    assert len(reads) <= 2 + 1000 // 16


def test_solver_events_are_logged_naming_the_switched_component(caplog):
    caplog.set_level(logging.DEBUG, logger="softflow")
    system = paper_scenes.fig4("snapping")
    res, _ = paper_scenes.run(system, 4)
    messages = [r.getMessage() for r in caplog.records if r.name == "softflow"]
    switches = [m for m in messages if m.startswith("switch at t =")]
    assert switches and all("R2 " in m for m in switches), switches[:3]
    assert any(m.startswith("BDF restart at t = 0 s") for m in messages)
    rejected = [m for m in messages if m.startswith("step rejected")]
    assert len(rejected) == res.stats["rejected_steps"] > 0
    summary = [m for m in messages if m.startswith("run finished")]
    assert summary == [f"run finished after {res.stats['steps']} steps "
                       f"({res.stats['rejected_steps']} rejected) in "
                       + summary[0].split(" in ")[1]]


def test_fixed_step_switches_are_logged_too(caplog):
    caplog.set_level(logging.DEBUG, logger="softflow")
    res, _ = paper_scenes.run(paper_scenes.fig4("snapping"), 4, step=0.01)
    assert res.success
    assert any(r.getMessage().startswith("switch at t =") and "R2 " in r.getMessage()
               for r in caplog.records)


def test_nothing_is_logged_below_info_by_default(caplog):
    caplog.set_level(logging.INFO, logger="softflow")
    sf.Simulation(rc_circuit(), duration=0.1).run()
    assert [r.levelno for r in caplog.records if r.name == "softflow"] == [logging.INFO]


def test_a_bar_that_opens_late_counts_its_elapsed_time_from_the_runs_start(monkeypatch):
    """The bar opens after DELAY s of the run; its elapsed field counts from
    the run's start (it read 00:00 when it appeared). A fake clock: the run
    starts at 100 s, the bar opens at its first look at 103 s."""
    clock = iter([100.0, 103.0, 103.0, 103.0, 103.0, 103.0])
    monkeypatch.setattr(progress_module.time, "perf_counter", lambda: next(clock))
    monkeypatch.setattr(tqdm, "tqdm", RecordingBar)
    RecordingBar.made = []
    with Progress(1.0, enabled=True) as p:
        p._next = 1
        p.step(0.5)
        bar = RecordingBar.made[0]
        assert bar._time() - bar.start_t >= 3.0       # the 3 s before the bar
