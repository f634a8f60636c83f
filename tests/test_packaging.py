"""What a wheel carries: the fluid tables and the PEP 561 marker as package data, the
licence, one version; what each install needs: the demo runs on the runtime
dependencies alone, and the `dev` extra holds what the tests import. (Building and
installing a wheel is .ci/run's wheel_smoke.)"""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import softflow as sf
from softflow.fluids.tables import TABLES_ENV, default_directory, tables_directory

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = Path(sf.__file__).resolve().parent


@pytest.fixture(scope="module")
def pyproject():
    tomllib = pytest.importorskip("tomllib")        # Python >= 3.11
    return tomllib.loads((ROOT / "pyproject.toml").read_text())


def _package_data(pyproject):
    patterns = pyproject["tool"]["setuptools"]["package-data"]["softflow"]
    return {p.resolve() for pattern in patterns for p in PACKAGE.glob(pattern)}


def test_fluid_tables_are_package_data(pyproject, monkeypatch):
    monkeypatch.delenv(TABLES_ENV, raising=False)
    tables = default_directory().resolve()
    assert tables == tables_directory().resolve()
    assert PACKAGE in tables.parents, f"{tables} lies outside the package {PACKAGE}"
    files = {f.resolve() for f in tables.iterdir() if f.is_file()}
    assert {f.suffix for f in files} == {".npz", ".json"}
    stems = {f.stem for f in files}
    assert {"air", "nitrogen", "water", "ethylene_glycol-0.6"} <= stems
    missing = sorted(f.name for f in files - _package_data(pyproject))
    assert not missing, f"tables a wheel would leave out (pyproject package-data): {missing}"


def test_pv_data_and_typed_marker_are_package_data(pyproject):
    shipped = _package_data(pyproject)
    assert (PACKAGE / "py.typed").resolve() in shipped
    assert (PACKAGE / "data" / "latex_balloon_60mm_pv.csv").resolve() in shipped


def test_license_is_the_declared_bsd_3_clause(pyproject):
    assert pyproject["project"]["license"] == {"text": "BSD-3-Clause"}
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("BSD 3-Clause License")
    assert "Copyright (c)" in text and "softflow developers" in text
    assert "Neither the name of the copyright holder" in text     # the third clause


def test_version_has_one_source(pyproject):
    assert "version" not in pyproject["project"]
    assert "version" in pyproject["project"]["dynamic"]
    attr = pyproject["tool"]["setuptools"]["dynamic"]["version"]["attr"]
    assert attr == "softflow.__version__"
    assert sf.__version__.count(".") == 2


#: packages of the `dev` extra (and the other extras) that are not runtime
#: dependencies: the first set-up command, `pip install -e . && softflow demo`,
#: does not install them, so the demo must not import them
NOT_RUNTIME = ("pandas", "xarray", "fonsim", "dask", "distributed", "hypothesis", "pytest",
               "xdist", "nbclient", "nbformat", "ipykernel", "IPython", "mypy", "sksundae",
               "sphinx", "myst_nb")

_BLOCKING_DEMO = """
import importlib.machinery
import sys

blocked = set(sys.argv[1].split(","))


class RuntimeOnly:  # finds what the path finder finds, but not what only extras install
    @staticmethod
    def find_spec(name, path=None, target=None):
        if name.partition(".")[0] in blocked:
            return None
        return importlib.machinery.PathFinder.find_spec(name, path, target)

    @staticmethod
    def invalidate_caches():
        importlib.machinery.PathFinder.invalidate_caches()


sys.meta_path[:] = [RuntimeOnly if f is importlib.machinery.PathFinder else f
                    for f in sys.meta_path]
from softflow.cli import main
code = main(["demo", "--output", "demo.png"])
imported = sorted(m for m in blocked if m in sys.modules)
print("imported:", imported)
sys.exit(code)
"""


def test_the_demo_runs_on_the_runtime_dependencies_alone(tmp_path):
    """As if only `pip install -e .` had run: every package that only an extra
    installs is made unimportable, and `softflow demo` still writes its plot."""
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join([str(PACKAGE.parent),
                                           os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-c", _BLOCKING_DEMO, ",".join(NOT_RUNTIME)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "imported: []" in done.stdout
    assert (tmp_path / "demo.png").stat().st_size > 10_000


def _names(requirements):
    return {re.split(r"[\s\[<>=!~;]", r, maxsplit=1)[0].lower().replace("_", "-")
            for r in requirements}


def test_runtime_dependencies_hold_none_of_the_test_stack(pyproject):
    runtime = _names(pyproject["project"]["dependencies"])
    extras = pyproject["project"]["optional-dependencies"]
    dev = _names(extras["dev"])
    assert {"pytest", "pandas", "xarray", "fonsim"} <= dev
    assert not runtime & {"pytest", "pytest-xdist", "pandas", "xarray", "fonsim", "dask",
                          "hypothesis", "mypy", "scikit-sundae"}
    # every comparison-only package a test imports is in dev: fonsim (tests/fons)
    tests = Path(__file__).resolve().parent
    imported = {m for f in tests.rglob("*.py")
                for m in re.findall(r"^\s*(?:import|from)\s+(fonsim|sksundae)\b",
                                    f.read_text(), re.M)}
    imported |= {m for f in tests.rglob("*.py")
                 for m in re.findall(r"importorskip\(\"(fonsim|sksundae)", f.read_text())}
    wanted = {"fonsim": "fonsim", "sksundae": "scikit-sundae"}
    assert {wanted[m] for m in imported} <= dev
