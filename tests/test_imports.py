"""``import softflow`` stays light: the heavy libraries load only when a feature needs
them (checked by which modules a fresh interpreter has loaded, not by wall time)."""
import json
import subprocess
import sys

import pytest

import softflow as sf

HEAVY = ("pint", "scipy", "matplotlib", "CoolProp", "pandas", "xarray", "fluids", "ht")


def _loaded_after(code):
    """Top-level packages of HEAVY, and scipy's submodules, loaded by ``code`` in a
    fresh interpreter."""
    probe = (f"import sys\n{code}\nimport json\n"
             "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in "
             f"{HEAVY!r} and m.count('.') <= 1)))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return set(json.loads(out.stdout.splitlines()[-1]))


def test_import_softflow_loads_no_heavy_library():
    loaded = _loaded_after("import softflow")
    assert not loaded, f"import softflow loaded {sorted(loaded)}"


def test_cli_version_loads_no_heavy_library():
    loaded = _loaded_after("import softflow.cli as c\ntry:\n    c.main(['--version'])\n"
                           "except SystemExit:\n    pass")
    assert not loaded, f"softflow --version loaded {sorted(loaded)}"


def test_a_pv_curve_and_a_run_load_no_signal_processing_or_plotting():
    loaded = _loaded_after(
        "import softflow as sf\n"
        "c = sf.PVCurve(volume=[1e-6, 2e-6, 3e-6], pressure=[1.02e5, 1.1e5, 1.3e5])\n"
        "s = sf.System()\n"
        "s += sf.PressureSource('src', pressure=1.2e5)\n"
        "s += sf.CircularTube('tube', sf.air, length=0.1, diameter=1e-3)\n"
        "s += sf.Actuator('act', sf.air, curve=c, initial_volume=1e-6)\n"
        "s.connect('tube', 'src'); s.connect('tube', 'act')\n"
        "sf.Simulation(s, duration=1e-3).run()\n")
    assert "scipy.linalg" in loaded          # the probe sees what a run imports
    for module in ("scipy.signal", "scipy.stats", "matplotlib", "CoolProp", "pandas"):
        assert module not in loaded, f"a plain run imported {module}"


def test_lazy_names_are_the_real_objects():
    from softflow.components import Actuator
    from softflow.curves import waveforms
    assert sf.Actuator is Actuator and sf.waveforms is waveforms
    assert set(sf.__all__) <= set(dir(sf))
    with pytest.raises(AttributeError, match="no attribute 'Simulator'"):
        sf.Simulator


def test_scene_module_loads_on_first_use():
    out = subprocess.run([sys.executable, "-c",
                          "import softflow as sf, sys\n"
                          "assert 'softflow.scene' not in sys.modules\n"
                          "assert sf.scene is sys.modules['softflow.scene'] and callable(sf.scene.save)"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
