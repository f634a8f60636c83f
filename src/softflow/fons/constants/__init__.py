"""fonsim's constants (``fons.constants``, also ``fons.cnorm`` and ``fons.cphy``):
``norm`` holds the reference state of fonsim's model, ``physical`` the gas
constant. softflow.fons builds its fluids, its default pressures and its gauge
pressures on these, so that a fonsim script gives fonsim's numbers; softflow's
own API uses :mod:`softflow.constants` (101 325 Pa, 293.15 K, CODATA 2018)."""
from . import norm, physical

__all__ = ["norm", "physical"]
