"""The compiled laws (:mod:`softflow.laws`), each module imported at its first
use: importing numba costs about 0.35 s, which ``import softflow``, reading a
fluid table or building a System do not pay; the first evaluation does."""
from __future__ import annotations

import functools
import importlib
from types import ModuleType


@functools.cache
def law_module(name: str) -> ModuleType:
    """``softflow.laws.<name>``, imported once."""
    return importlib.import_module(f"softflow.laws.{name}")
