# %% [markdown]
# # LC oscillation: tube inertance against an accumulator (water)
#
# With `inertance=True` a tube carries the fluid's inertia, I = ρL/A, besides
# its laminar resistance R = 128 μ L/(π D⁴). Between a constant-pressure
# reservoir and a linear accumulator of compliance C it forms a series RLC
# circuit. Starting from rest with the accumulator Δ above the reservoir,
#
#     p(t) − p0 = Δ e^(−αt) (cos ω_d t + (α/ω_d) sin ω_d t),
#     α = R/(2I),  ω_d = √(1/(IC) − α²),
#
# so the undamped frequency is 1/(2π√(IC)). Stated tolerances: frequency and
# damping rate within 0.5 %, the whole trajectory within 0.5 % of Δ
# (backward Euler adds a numerical damping rate of about ω²h/2, 0.2 % of α here).

# %%
import math

import numpy as np

import softflow as sf

p0 = sf.pressure_atmospheric
fl = sf.water
rho, mu = fl.density(p0), fl.viscosity(p0)
L, D = 1.0, 2.83e-3                       # m
A = math.pi * D ** 2 / 4
I = rho * L / A                           # Pa s^2 / m^3
R = 128 * mu * L / (math.pi * D ** 4)     # Pa s / m^3
f0 = 2.0                                  # Hz, undamped
C = 1 / ((2 * math.pi * f0) ** 2 * I)     # m^3 / Pa
delta = 1e3                               # Pa

s = sf.System()
s += sf.PressureSource("res", pressure=p0)
s += sf.CircularTube("tube", fl, length=L, diameter=D, friction="laminar", inertance=True)
s += sf.LinearAccumulator("acc", fl, volume=1e-4, compliance=C, initial_pressure=p0 + delta)
s.connect("res", "tube")
s.connect("tube", "acc")
h = 5e-5
res = sf.Simulation(s, duration=2.0, step=h).run()
t, p = res.times, res.get("acc", "pressure") - p0

# %%
alpha = R / (2 * I)
wd = math.sqrt(1 / (I * C) - alpha ** 2)
exact = delta * np.exp(-alpha * t) * (np.cos(wd * t) + alpha / wd * np.sin(wd * t))
traj_err = np.max(np.abs(p - exact)) / delta

# frequency from upward zero crossings (interpolated), damping from the peaks
up = np.flatnonzero((p[:-1] < 0) & (p[1:] >= 0))
tc = t[up] - p[up] * (t[up + 1] - t[up]) / (p[up + 1] - p[up])
f_sim = (len(tc) - 1) / (tc[-1] - tc[0])
peaks = [k for k in range(1, len(p) - 1) if p[k] > p[k - 1] and p[k] >= p[k + 1] and p[k] > 0]
alpha_sim = -np.polyfit(t[peaks], np.log(p[peaks]), 1)[0]
Re = np.abs(res.get("tube", "massflow", "a")).max() * D / (mu * A)

print(f"undamped 1/(2 pi sqrt(IC)) = {f0:.4f} Hz, damped {wd / (2 * math.pi):.4f} Hz, "
      f"simulated {f_sim:.4f} Hz ({f_sim / (wd / (2 * math.pi)) - 1:+.2e})")
print(f"damping rate R/(2I) = {alpha:.4f} 1/s, simulated {alpha_sim:.4f} 1/s "
      f"({alpha_sim / alpha - 1:+.2e})")
print(f"trajectory: max |p - exact| / delta = {traj_err:.2e}; largest Re {Re:.0f}")
assert Re < 2000
assert abs(f_sim / (wd / (2 * math.pi)) - 1) < 5e-3
assert abs(alpha_sim / alpha - 1) < 5e-3
assert traj_err < 5e-3

# %%
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(6, 3.5))
ax.plot(t, p, label="softflow")
ax.plot(t, exact, "--", label="exact RLC")
ax.set_xlabel("time [s]")
ax.set_ylabel("accumulator gauge pressure [Pa]")
ax.legend()
plt.show()
