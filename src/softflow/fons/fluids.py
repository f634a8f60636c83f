"""fonsim's fluid library (``fons.fluids``, ``fons.air``, ``fons.water``):
fonsim 0.6's two fluids with fonsim's constants.

- ``air``: an ideal gas of 1.23 kg/m^3 at 101 300 Pa and 288.15 K,
  viscosity 1.82e-5 Pa s (its fallback, as in fonsim: a liquid of the same
  constants, ``air_incompressible``);
- ``water``: 999 kg/m^3, 0.977 mPa s.

softflow's own fluids (``sf.air``: 1.204 kg/m^3 at 101 325 Pa and 20 degC,
18.2 µPa s; ``sf.water``: 998.2 kg/m^3, 1.002 mPa s; CoolProp's values) go
into every fons component in their place: passing ``sf.air`` instead of
``fons.air`` moves a script from fonsim's constants to softflow's.
"""
from __future__ import annotations

from types import SimpleNamespace

from .fluid import IdealCompressible as _Gas
from .fluid import IdealIncompressible as _Liquid

air = _Gas("air", rho=1.23, mu=1.82e-5,
           fallbacks=[_Liquid("air_incompressible", rho=1.23, mu=1.82e-5)])
water = _Liquid("water", rho=999.0, mu=0.977e-3)

#: fonsim groups its fluids by class: ``fons.fluids.IdealCompressible.air``
IdealCompressible = SimpleNamespace(air=air)
IdealIncompressible = SimpleNamespace(water=water)


def __getattr__(name):
    from ._unsupported import unsupported
    return unsupported(f"fluids.{name}", __name__)
