"""Result.report(): the run's summary as text (issue 40): status, the solver's
counters, and the model warnings grouped by component and check, each with
its size; the near misses counted apart."""
import warnings

import pytest

import softflow as sf

P0 = sf.pressure_atmospheric


def _run(system, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        return sf.Simulation(system, **kw).run(raise_on_failure=False)


def _laminar_tube_into_accumulator(dp=2e5, inertance=False):
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + dp)
    s += sf.CircularTube("tube", sf.water, 0.3, 2e-3, friction="laminar", inertance=inertance)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-11)
    s.connect("src", "tube")
    s.connect("tube", "acc")
    return s


def test_a_clean_run_reports_its_status_counters_and_no_warnings():
    from softflow.demo import paper_system
    res = _run(paper_system(), duration=1.0)
    text = res.report()
    lines = text.splitlines()
    assert lines[0] == f"Run: success, t = 0 .. 1 s ({len(res.times)} points)"
    assert lines[1].startswith(f"Solver: {res.stats['steps']} steps "
                               f"({res.stats['rejected_steps']} rejected), "
                               f"{res.stats['newton_iterations']} Newton iterations")
    assert lines[1].endswith("rtol 0.001")
    assert "Warnings: none" in lines
    assert "Near misses" not in text


def test_warnings_are_grouped_by_component_and_check_with_their_size():
    res = _run(_laminar_tube_into_accumulator(), duration=0.5)
    checks = sorted(w.check for w in res.warnings)
    assert checks == ["tube_inertia", "tube_reynolds"]
    text = res.report()
    lines = text.splitlines()
    assert "Warnings: 2 (1 component)" in lines
    k = lines.index("  tube:")
    by_check = {line.split(":")[0].strip(): line for line in lines[k + 1:]
                if line.startswith("    ") and not line.startswith("      ")}
    assert set(by_check) == set(checks)
    for w in res.warnings:
        line = by_check[w.check]
        assert f"{w.measured:.3g}" in line and f"{w.limit:.3g}" in line
        assert f"fraction {w.fraction:.3g}; 1 at the limit" in line
    # the finding in words, without the component's name repeated, wrapped
    assert "CircularTube 'tube'" not in text
    assert "times the laminar friction there" in text
    assert max(len(line) for line in lines) <= 88


def test_one_record_per_component_and_cause():
    """Each check makes at most one record per component, and each is warned once."""
    s = _laminar_tube_into_accumulator()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = sf.Simulation(s, duration=0.5).run()
    keys = [(w.component, w.check) for w in res.warnings]
    assert len(keys) == len(set(keys)) == 2
    assert len([w for w in caught if issubclass(w.category, sf.ModelWarning)]) == 2


def test_a_failed_run_reports_why_it_stopped():
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 1e4)
    s += sf.CircularTube("tube", sf.water, 0.3, 1e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-11)
    s.connect("src", "tube")
    s.connect("tube", "acc")
    res = _run(s, duration=1.0, max_steps=3)
    assert res.status == "failed"
    text = res.report()
    assert text.startswith("Run: failed")
    assert "Message: " in text and res.message.split()[0] in text


def test_near_misses_are_counted_apart_from_the_warnings():
    """A laminar tube at Re ~1 500 is a near miss (status 'near'), not a warning."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 6e3)
    s += sf.CircularTube("tube", sf.water, 1.0, 2e-3, friction="laminar")
    s += sf.PressureSource("out", pressure=P0)
    s.connect("src", "tube")
    s.connect("tube", "out")
    res = _run(s, duration=0.01)
    near = [r for r in res.validity if r.status == "near"]
    assert [r.check for r in near] == ["tube_reynolds"] and not res.warnings
    text = res.report()
    assert "Warnings: none" in text
    assert "Near misses (not warned): 1" in text
    assert f"tube: tube_reynolds at {near[0].fraction:.0%} of its limit" in text


@pytest.mark.parametrize("dp, ratio", [(5e4, (1.5, 20.0))])
def test_the_laminar_tube_warning_says_by_how_much_the_drop_is_short(dp, ratio):
    """tube_reynolds gives the default law's friction over the laminar one at the
    peak Reynolds number (Haaland, from softflow.correlations.friction)."""
    from fluids.friction import friction_factor
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + dp)
    s += sf.CircularTube("tube", sf.water, 1.0, 2e-3, friction="laminar")
    s += sf.PressureSource("out", pressure=P0)
    s.connect("src", "tube")
    s.connect("tube", "out")
    res = _run(s, duration=0.01)
    w = next(w for w in res.warnings if w.check == "tube_reynolds")
    re = w.measured
    # an independent value: Haaland from the fluids package over 64/Re
    want = friction_factor(Re=re, eD=1.5e-6 / 2e-3, Method="Haaland") * re / 64
    assert w.details["friction_ratio"] == pytest.approx(want, rel=1e-3)
    assert ratio[0] < w.details["friction_ratio"] < ratio[1]
    assert f"{w.details['friction_ratio']:.3g} times the laminar friction" in w.message
