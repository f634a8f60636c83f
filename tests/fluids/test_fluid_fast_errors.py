"""Fluid input errors answer without loading CoolProp (2-3 s): names and solution
fractions are checked against CoolProp's own lists kept in the catalog, which must
equal what the installed CoolProp says. Checked by which modules a fresh
interpreter loaded, not by wall time."""
import json
import subprocess
import sys

import pytest

from softflow.fluids import catalog


def _coolprop_loaded_by(code):
    probe = (f"import sys\n{code}\nimport json\n"
             "print(json.dumps('CoolProp' in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.splitlines()[-1])


def test_snapshot_equals_the_installed_coolprop():
    import CoolProp
    import CoolProp.CoolProp as CP
    snap = catalog._snapshot()
    assert catalog._SNAPSHOT_VERSION == CoolProp.__version__ and snap is not None
    assert snap[0] == catalog._coolprop_names_live()
    solutions = CP.get_global_param_string("incompressible_list_solution").split(",")
    pure = CP.get_global_param_string("incompressible_list_pure").split(",")
    assert snap[1] == frozenset(pure) | frozenset(solutions)
    assert snap[2] == {s: (CP.PropsSI("fraction_min", f"INCOMP::{s}"),
                           CP.PropsSI("fraction_max", f"INCOMP::{s}")) for s in solutions}


ERRORS = [
    ("sf.Fluid('Airr', level='eos')", "unknown fluid 'Airr'"),
    ("sf.Fluid('INCOMP::MPGG')", "did you mean 'INCOMP::MPG'"),
    ("sf.ethylene_glycol.at(fraction=0.7)", "fraction 0.7 is outside CoolProp's range for "
                                            "INCOMP::MEG: 0 ... 0.6"),
    ("sf.Fluid('INCOMP::MPG[0.9]')", "fraction 0.9 is outside CoolProp's range for "
                                     "INCOMP::MPG: 0 ... 0.6"),
    ("sf.Fluid('Air', level='table', temperature=500)",
     "temperature 500 K is outside the table range 233.15 ... 423.15 K"),
]


@pytest.mark.parametrize("code, message", ERRORS)
def test_fluid_input_errors_name_what_was_expected(code, message):
    import softflow as sf
    with pytest.raises(sf.FluidError) as info:
        eval(code, {"sf": sf})
    assert message in str(info.value)


def test_fluid_input_errors_do_not_load_coolprop():
    tries = "\n".join(f"try:\n    {code}\nexcept sf.FluidError:\n    pass"
                      for code, _ in ERRORS)
    assert not _coolprop_loaded_by(f"import softflow as sf\n{tries}")


def test_another_coolprop_version_reads_the_live_lists(monkeypatch):
    monkeypatch.setattr(catalog, "_SNAPSHOT_VERSION", "0.0.0")
    catalog._snapshot.cache_clear()
    catalog._coolprop_names.cache_clear()
    try:
        assert catalog._snapshot() is None
        assert catalog._coolprop_names()["co2"] == "CarbonDioxide"
    finally:
        monkeypatch.undo()
        catalog._snapshot.cache_clear()
        catalog._coolprop_names.cache_clear()
