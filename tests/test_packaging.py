"""What a wheel carries: the fluid tables and the PEP 561 marker as package data, the
licence, one version. (Building and installing a wheel is .ci/run's wheel_smoke.)"""
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
