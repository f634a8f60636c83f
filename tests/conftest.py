"""Shared test set-up: the tests folder on sys.path for the helpers in
``tests/helpers.py``."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import pytest


@pytest.fixture
def python_steps(monkeypatch):
    """Every step of the run taken by the BDF in Python, none by the compiled
    loop (softflow.solve.steploop): for tests that count or replace the
    Python Newton's solves, which the compiled loop's steps do not call."""
    from softflow.solve import settings
    monkeypatch.setattr(settings, "COMPILED_STEPS", False)
