"""fonsim's fluid library (``fons.fluids``, ``fons.air``, ``fons.water``).

The constants are softflow's (CoolProp at 20 degC and 1 atm), not fonsim's:
fonsim's air has rho_stp = 1.23 kg/m^3 and mu = 1.82e-5 Pa s, its water
rho = 999 kg/m^3 and mu = 0.977 mPa s (softflow: 1.204 kg/m^3, 1.82e-5 Pa s;
998.2 kg/m^3, 1.002 mPa s). For fonsim's numbers, build the fluid yourself:
``fons.fluid.IdealCompressible('air', 1.23, 1.82e-5)``.
"""
from __future__ import annotations

from types import SimpleNamespace

from ..fluids import air as _sf_air
from ..fluids import water as _sf_water
from .fluid import IdealCompressible as _Gas
from .fluid import IdealIncompressible as _Liquid

air = _Gas.from_fluid(_sf_air)
water = _Liquid.from_fluid(_sf_water)

#: fonsim groups its fluids by class: ``fons.fluids.IdealCompressible.air``
IdealCompressible = SimpleNamespace(air=air)
IdealIncompressible = SimpleNamespace(water=water)
