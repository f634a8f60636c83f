# %% [markdown]
# # Pressure drop in a circular tube: laminar and turbulent
#
# A mass-flow source pushes water through a 1 m tube into a constant-pressure
# sink. At steady state the tube's pressure drop is compared with
#
# * laminar flow: Hagen–Poiseuille, Δp = 128 μ L Q / (π D⁴);
# * turbulent flow: Darcy–Weisbach, Δp = f (L/D) ρ v²/2, with the friction
#   factor f from the `fluids` package: Haaland (the tube's default, as in the
#   FONS paper) and Colebrook (`friction='Colebrook'`, solved exactly in
#   softflow, compared with `fluids.friction.Colebrook`).
#
# Stated tolerance: 0.5 % (measured: round-off level, since both sides use the
# same formulas; the test guards the tube's residual, units and solver).

# %%
import math

import fluids.friction
import numpy as np

import softflow as sf

p0 = sf.pressure_atmospheric
L, D, eps = 1.0, 2e-3, 1.5e-6
fl = sf.water
rho, mu = fl.density(p0), fl.viscosity(p0)
A = math.pi * D ** 2 / 4


def simulated_dp(mdot, friction):
    s = sf.System()
    s += sf.MassFlowSource("pump", massflow=mdot)
    s += sf.CircularTube("tube", fl, length=L, diameter=D, roughness=eps, friction=friction)
    s += sf.PressureSource("sink", pressure=p0)
    s.connect("tube", "pump")
    s.connect("tube", "sink")
    res = sf.Simulation(s, duration=0.01, step=0.005).run()
    return res.get("tube", "pressure", "a")[-1] - res.get("tube", "pressure", "b")[-1]


rows = []
for friction, reference in (("Haaland", fluids.friction.Haaland),
                            ("Colebrook", fluids.friction.Colebrook)):
    for Re in (100, 500, 1500, 1e4, 3e4, 1e5):
        mdot = Re * mu * A / D
        v = mdot / (rho * A)
        if Re < 2300:
            ref = 128 * mu * L * (mdot / rho) / (math.pi * D ** 4)
        else:
            ref = reference(Re, eps / D) * L / D * rho * v ** 2 / 2
        dp = simulated_dp(mdot, friction)
        rows.append((Re, dp, ref, dp / ref - 1))
        print(f"{friction:9s} Re = {Re:8.0f}: softflow {dp:12.2f} Pa, reference {ref:12.2f} Pa, "
              f"rel. difference {dp / ref - 1:+.2e}")

# %%
worst = max(abs(r[3]) for r in rows)
print(f"largest relative difference {worst:.2e} (tolerance 5e-3)")
assert worst < 5e-3
