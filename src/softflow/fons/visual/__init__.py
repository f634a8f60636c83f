"""fonsim's ``fons.visual``: its plotting module (``fons.visual.plotting``;
``fons.plot`` and ``fons.plot_state`` are its functions)."""
from __future__ import annotations

from . import plotting

__all__ = ["plotting"]


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"visual.{name}", __name__)
