"""examples/inverse_design.py: the restrictor diameter for a target lag, found
with the sensitivity derivative from 30 % off."""
import runpy
import warnings
from pathlib import Path

import pytest

import softflow as sf

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "inverse_design.py"


@pytest.mark.slow
def test_the_diameter_for_a_target_lag_is_found_from_30_percent_off():
    ns = runpy.run_path(str(EXAMPLE))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sf.ModelWarning)
        sim = sf.Simulation(ns["fig4"]("tube"), duration=ns["duration"](4) / 2, rtol=1e-5)
        res = sim.run(sensitivities=["R2.diameter"])
        half = {lab: 0.5 * (res.get(lab, "volume")[0] + res.get(lab, "volume").max())
                for lab in ("act1", "act2")}       # the levels held fixed
        target, slope = ns["lag"](res, half=half)
        # the lag's derivative against a central difference of whole runs
        h = 2.5e-5
        up = sim.run(params={"R2.diameter": 2.5e-3 + h}, sensitivities=["R2.diameter"])
        down = sim.run(params={"R2.diameter": 2.5e-3 - h}, sensitivities=["R2.diameter"])
        fd = (ns["lag"](up, half=half)[0] - ns["lag"](down, half=half)[0]) / (2 * h)
        assert slope == pytest.approx(fd, rel=0.02)
        found, runs, _ = ns["find_diameter"](target, 0.7 * 2.5e-3, verbose=False)
    assert found == pytest.approx(2.5e-3, rel=1e-3)
    assert runs <= 12
