"""fonsim's reference state (``fons.constants.norm``, ``fons.cnorm``).

These are fonsim 0.6's values, not softflow's (:mod:`softflow.constants`:
101 325 Pa, 293.15 K): the atmosphere every fons component starts at, that
gauge pressures (a relative PV curve, ``fons.Sink``) refer to, and at which
``fons.air``'s density is 1.23 kg/m^3.
"""

#: Atmospheric pressure [Pa]: 1.013 bar (softflow: 101 325 Pa).
pressure_atmospheric = 101300.0

#: Temperature of the reference state and of fons's fluids [K]: 15 degC
#: (softflow's fluids: 20 degC).
temperature = 288.15
