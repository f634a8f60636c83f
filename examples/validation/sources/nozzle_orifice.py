# %% [markdown]
# # A gas orifice given by its diameter and discharge coefficient (air)
#
# `Orifice(label, gas, diameter=d, Cd=Cd)` is the isentropic nozzle of a perfect
# gas times Cd, from the upstream stagnation pressure p₀ to the back pressure
# (Anderson, *Modern Compressible Flow*, sec. 5.4; ISO 9300):
#
#     ṁ = Cd A p₀ √(2γ/((γ−1) R T₀)) √(pr^(2/γ) − pr^((γ+1)/γ)),   pr > pr*
#     ṁ = Cd A p₀ √(γ/(R T₀)) (2/(γ+1))^((γ+1)/(2(γ−1))),           pr ≤ pr* (choked)
#
# with pr* = (2/(γ+1))^(γ/(γ−1)), 0.528 for air. The same orifice in ISO 6358
# terms has b = pr* and the sonic conductance C that gives the same choked flow
# (`softflow.correlations.orifice.iso_6358_of_nozzle`). References here: the
# formulas above written out in this notebook, `fluids.flow_meter`'s nozzle
# expansibility factor, and an ODE of an isothermal tank integrated with
# SciPy. Stated tolerances: the orifice's flow within 0.5 % of the nozzle law
# times Cd over pressure ratios 0.05–0.95; a 10 bar blowdown within 1 % of the
# pressure range of the ODE; the ISO 6358 fill of the same orifice choked like
# it (the same flow to 1e-9 while choked).

# %%
import math
import warnings

import numpy as np
from fluids.flow_meter import nozzle_expansibility
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import softflow as sf
from softflow.components.valves import Orifice
from softflow.correlations.orifice import iso_6358_of_nozzle

air = sf.air
R, T, g = air.R, air.temperature, air.gamma0
d, Cd = 2e-3, 0.6
A = math.pi * d * d / 4
pr_star = (2 / (g + 1)) ** (g / (g - 1))


def nozzle(p0, p_down):
    """The nozzle law times Cd, written out (not softflow's); negative backward."""
    if p_down > p0:
        return -nozzle(p_down, p0)
    pr = max(p_down / p0, pr_star)
    return Cd * A * p0 * math.sqrt(2 * g / ((g - 1) * R * T)) * math.sqrt(
        pr ** (2 / g) - pr ** ((g + 1) / g))


def softflow_flow(orifice, p0, p_down):
    P = Orifice.make_params([orifice])
    S = np.zeros((1, 0))

    def residual(mf):
        return Orifice.residual(P, np.array([[p0, mf, p_down, -mf]]), S, 0.0, False)[0][0, 1]
    return brentq(residual, -1.0, 1.0, xtol=1e-300, rtol=1e-14)


# %%
orifice = sf.Orifice("o", air, diameter=d, Cd=Cd)
worst = 0.0
for p0 in (2e5, 1e6):
    for ratio in np.linspace(0.05, 0.95, 19):
        got, want = softflow_flow(orifice, p0, ratio * p0), nozzle(p0, ratio * p0)
        worst = max(worst, abs(got / want - 1))
        # backward, the same flow reversed
        assert softflow_flow(orifice, ratio * p0, p0) == -got
print(f"largest relative difference from the nozzle law, pr 0.05-0.95: {worst:.1e}")
assert worst < 5e-3
# subsonic: the incompressible orifice equation times ISO 5167's nozzle expansibility
p0, p_down = 2e5, 1.6e5
Y = nozzle_expansibility(D=1.0, Do=d, P1=p0, P2=p_down, k=g)    # beta = 0.002: ~0
incompressible = Cd * A * math.sqrt(2 * p0 / (R * T) * (p0 - p_down))
print(f"at pr 0.8: softflow / (Cd A sqrt(2 rho0 dp) Y) - 1 = "
      f"{softflow_flow(orifice, p0, p_down) / (incompressible * Y) - 1:.1e}")
assert abs(softflow_flow(orifice, p0, p_down) / (incompressible * Y) - 1) < 1e-4

# %% [markdown]
# ## A 10 bar blowdown through the orifice, against an ODE

# %%
V, p_start, P0 = 1e-3, 10e5, sf.pressure_atmospheric
s = sf.System()
s += sf.Container("tank", air, volume=V, initial_pressure=p_start)
s += sf.Orifice("valve", air, diameter=d, Cd=Cd)
s += sf.PressureSource("atm", pressure=P0)
s.connect("tank", "valve")
s.connect("valve", "atm")
with warnings.catch_warnings(record=True):
    warnings.simplefilter("always", sf.ModelWarning)
    res = sf.Simulation(s, duration=8.0).run()
assert not [w for w in res.warnings if w.check == "orifice_choked"]

# isothermal ideal gas: V/(R T) dp/dt = -mdot(p, P0)
ode = solve_ivp(lambda t, y: [-nozzle(y[0], P0) * R * T / V], (0.0, 8.0), [p_start],
                method="DOP853", rtol=1e-11, atol=1e-6, dense_output=True)
p, want = res.get("tank", "pressure"), ode.sol(res.times)[0]
err = np.max(np.abs(p - want)) / (p_start - P0)
unchoke = brentq(lambda t: P0 / ode.sol(t)[0] - pr_star, 0.0, 8.0)
print(f"blowdown: largest difference {err:.2e} of the pressure range (tolerance 1 %), "
      f"choked until {unchoke:.2f} s, {res.stats['steps']} steps")
assert err < 0.01

# %% [markdown]
# ## The same orifice as an ISO 6358 component
#
# With C and b from `iso_6358_of_nozzle`, the ISO 6358 law has the nozzle's
# choked flow exactly; subsonic its elliptic curve is an approximation of the
# nozzle's.

# %%
C, b = iso_6358_of_nozzle(d, Cd, g, R)
iso = sf.Orifice("o", air, C=C, b=float(b))
print(f"C = {C:.4e} m^3/(s Pa) = {C * 1e3 * 1e5:.4f} dm^3/(s bar), b = {float(b):.4f}")
for p0 in (3e5, 1e6):
    a, n = softflow_flow(iso, p0, 0.3 * p0), softflow_flow(orifice, p0, 0.3 * p0)
    assert abs(a / n - 1) < 1e-9
sub = max(abs(softflow_flow(iso, 3e5, r * 3e5) - softflow_flow(orifice, 3e5, r * 3e5))
          for r in np.linspace(0.55, 0.95, 9)) / nozzle(3e5, 0.0)
print(f"subsonic: the two laws within {sub:.2%} of the choked flow")
