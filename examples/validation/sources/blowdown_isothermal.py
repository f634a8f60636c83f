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
# until p = p_atm/b.
#
# Air at 10 bar is not an ideal gas to this run's tolerance: its
# compressibility factor is Z = 0.9965 (CoolProp), and the ideal-gas density
# changes the tank's mass by 0.38 % and its pressure by 0.54 % (measured against
# the `table` level at rtol 1e-7); softflow's compressibility check warns of it
# at the `ideal` level. So the run uses air's `table` level, and the reference
# is the same isothermal mass balance with CoolProp's density, V dρ/dt = −ṁ,
# integrated by quadrature in ρ (independent of softflow):
#
#     t(p) = V / (C ρ₀ √(T₀/T)) · ∫ dρ / p   (from p to p(0)),
#
# which for an ideal gas (ρ ∝ p) is the exponential above. Stated tolerance:
# 0.5 % of p over the choked phase, with the adaptive step at rtol = 1e-5.
#
# The tank is *held* at 20 °C, `Container(..., thermal='isothermal')`: the
# reference's assumption, stated in the scene. A real 1 L tank that empties in
# a few seconds cools instead (its wall's free convection takes ~13 s): with
# that wall (`thermal='heat_transfer'`, `sf.FreeConvection`) its pressure falls
# up to 23 % below the isothermal one during the choked phase, which is why
# softflow's thermal check warns of a tank left isothermal by default. The
# cooling blowdown is case 6 of the thermal notebook.

# %%
import math

import numpy as np

import softflow as sf

p_atm = sf.pressure_atmospheric
air = sf.air.with_level("table")
V, p_start = 1e-3, 10e5                  # m^3, Pa
C, b = 1e-8, 0.3                         # m^3/(s Pa), -
rho0, T0 = 1.185, 293.15
T = air.temperature

s = sf.System()
s += sf.Container("tank", air, volume=V, initial_pressure=p_start, thermal="isothermal")
s += sf.Orifice("valve", air, C=C, b=b)
s += sf.PressureSource("atm", pressure=p_atm)
s.connect("tank", "valve")
s.connect("valve", "atm")
res = sf.Simulation(s, duration=20.0, rtol=1e-5).run()
t, p = res.times, res.get("tank", "pressure")

# %%
import CoolProp.CoolProp as CP

k = C * rho0 * math.sqrt(T0 / T)         # choked mass flow per pascal of tank pressure
p_grid = np.geomspace(p_atm / b, p_start, 4001)
rho_grid = np.array([CP.PropsSI("D", "P", pp, "T", T, "Air") for pp in p_grid])
# t(p) = V/k ∫_p^p(0) dρ/p: trapezoids in ρ, from the top of the grid down
steps = 0.5 * (1 / p_grid[1:] + 1 / p_grid[:-1]) * np.diff(rho_grid)
t_grid = V / k * np.concatenate([np.cumsum(steps[::-1])[::-1], [0.0]])
choked = p > p_atm / b * 1.01
exact = np.interp(t, t_grid[::-1], p_grid[::-1])     # the reference p(t)
err = np.max(np.abs(p[choked] / exact[choked] - 1))
R = p_atm / (sf.air.density(p_atm) * T)   # the ideal gas's, for its exponential
tau = V / (R * T * k)
ideal = p_start * np.exp(-t / tau)
print(f"ideal-gas time constant {tau:.3f} s; choked until {t[choked][-1]:.2f} s; the real "
      f"gas's reference departs from the ideal exponential by up to "
      f"{np.max(np.abs(exact[choked] / ideal[choked] - 1)):.2%}")
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
ax.semilogy(t[choked], exact[choked] / 1e5, "--", label="reference (CoolProp, choked)")
ax.semilogy(t[choked], ideal[choked] / 1e5, ":", label="ideal gas exponential")
ax.axhline(p_atm / b / 1e5, color="gray", lw=0.5)
ax.set_xlabel("time [s]")
ax.set_ylabel("tank pressure [bar]")
ax.legend()
plt.show()
