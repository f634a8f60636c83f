# %% [markdown]
# # Isothermal blowdown of a tank through a choked orifice (air)
#
# A rigid 1 L tank of air at 10 bar empties to the atmosphere through an ISO
# 6358 orifice (sonic conductance C, critical pressure ratio b). While the
# orifice is choked (p_atm/p ≤ b) its mass flow is ṁ = C ρ₀ p √(T₀/T), with the
# ISO reference density ρ₀ = 1.185 kg/m³ and T₀ = 293.15 K. For an isothermal
# ideal gas, m = pV/(RT), so the tank pressure decays exponentially:
#
#     p(t) = p(0) exp(−t/τ),   τ = V / (R T C ρ₀ √(T₀/T)),
#
# until p = p_atm/b. Stated tolerance: 0.5 % of p over the choked phase, with
# the adaptive step at rtol = 1e-5. Backward Euler is first order: its local
# error control at the default rtol = 1e-3 gives steps of about τ√(2·rtol) and
# a global error of 2.6 % here (a fixed 0.1 ms step: 5e-5). The adiabatic
# blowdown needs the energy equation (the thermal issue) and is not part of
# this notebook.

# %%
import math

import numpy as np

import softflow as sf

p_atm = sf.pressure_atmospheric
air = sf.air
V, p_start = 1e-3, 10e5                  # m^3, Pa
C, b = 1e-8, 0.3                         # m^3/(s Pa), -
rho0, T0 = 1.185, 293.15
T = air.temperature
R = p_atm / (air.density(p_atm) * T)     # specific gas constant of the model

s = sf.System()
s += sf.Container("tank", air, volume=V, initial_pressure=p_start)
s += sf.Orifice("valve", air, C=C, b=b)
s += sf.PressureSource("atm", pressure=p_atm)
s.connect("tank", "valve")
s.connect("valve", "atm")
res = sf.Simulation(s, duration=20.0, rtol=1e-5).run()
t, p = res.times, res.get("tank", "pressure")

# %%
tau = V / (R * T * C * rho0 * math.sqrt(T0 / T))
choked = p > p_atm / b * 1.01
exact = p_start * np.exp(-t / tau)
err = np.max(np.abs(p[choked] / exact[choked] - 1))
print(f"time constant {tau:.3f} s; choked until {t[choked][-1]:.2f} s")
print(f"max relative error over the choked phase {err:.2e} (tolerance 5e-3); "
      f"{res.stats['steps']} steps")
m = res.get("tank", "mass")
vented = -res.integral("valve", "massflow", "a")    # by the run's own quadrature
print(f"mass balance: {np.max(np.abs(m - m[0] - vented)) / m[0]:.1e} relative")
assert err < 5e-3
assert abs(p[-1] - p_atm) < 1.0
assert np.max(np.abs(m - m[0] - vented)) / m[0] < 1e-9

# %%
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(6, 3.5))
ax.semilogy(t, p / 1e5, label="softflow")
ax.semilogy(t[choked], exact[choked] / 1e5, "--", label="closed form (choked)")
ax.axhline(p_atm / b / 1e5, color="gray", lw=0.5)
ax.set_xlabel("time [s]")
ax.set_ylabel("tank pressure [bar]")
ax.legend()
plt.show()
