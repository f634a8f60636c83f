"""fonsim's physical constants (``fons.constants.physical``, ``fons.cphy``)."""

#: Molar gas constant [J/(mol K)], fonsim's value (CODATA 2014; softflow uses
#: CODATA 2018's exact 8.314462618). fons's gases are defined by their density
#: at the reference state, so neither value changes a fons result.
gas_constant = 8.314459848
