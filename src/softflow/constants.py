"""Physical constants (SI)."""

#: Standard atmosphere [Pa] (ISO 2533), the reference for gauge pressures.
pressure_atmospheric = 101325.0

#: Molar gas constant [J/(mol K)] (CODATA 2018, exact).
gas_constant = 8.314462618

#: 20 degC in kelvin, the default fluid temperature.
temperature_standard = 293.15
