"""Physical constants (SI)."""

#: Standard atmosphere [Pa] (ISO 2533), the reference for gauge pressures.
pressure_atmospheric = 101325.0

#: Molar gas constant [J/(mol K)] (CODATA 2018, exact).
gas_constant = 8.314462618

#: 20 degC in kelvin, the default fluid temperature.
temperature_standard = 293.15

#: An atom's size [m] (~0.1 nm): a tube's length or diameter below it is refused,
#: no flow law holding there.
atomic_size = 1e-10
