# %% [markdown]
# # The same network with air, water and ethylene glycol
#
# The FONS paper's Fig. 5 network (two peak–valley actuators, tight tubes, a
# 100 mL accumulator, a pump moving 1.8 mL/s in, pausing, and out), built by
# `softflow.paper_scenes.fig5(fluid, physics='full')`: the fluid is the only
# difference. This is the comparison users make when they choose a working
# fluid.
#
# `physics='full'` models what the paper's scene leaves out, each of which
# softflow warns of when it is left out (a `ModelWarning`), measured against
# runs that model it: the liquid's inertia in the tube between the actuators,
# which rings through it at each snap (7.7 % of the pressures with water, 1.1 %
# with glycol); the air's heat exchange with the actuators' and the
# accumulator's walls (the snaps fill and empty them in milliseconds, against
# wall time constants of 0.4–1.7 s: 57 % of the pressures), by free convection
# (`thermal='heat_transfer'`); and actuator curves drawn to the 30 mL that the
# liquids fill them to (the paper's end at 12 mL). Checks:
#
# * mass is conserved in each run: the stored mass changes exactly by what the
#   pump moved (relative 1e-9);
# * the liquids end where they started (volume pumped out = volume pumped in,
#   0.5 % of the pumped volume);
# * the snaps are fastest with air, slower with water, and damped with glycol
#   (the paper's reading of Fig. 5).

# %%
import numpy as np

import softflow as sf
from softflow import paper_scenes as ps

fluids = {"air": sf.air, "water": sf.water, "ethylene glycol": sf.ethylene_glycol}
results = {}
for name, fluid in fluids.items():
    system = ps.fig5(fluid, physics="full")
    res, wall = ps.run(system, 5, **ps.simulation_options(system))
    results[name] = res
    print(f"{name:16s} {wall * 1e3:6.1f} ms, {res.stats['steps']} steps, model warnings: "
          f"{[w.check for w in res.warnings] or 'none'}")

# %%
fastest = {}
for name, res in results.items():
    t = res.times
    stored = sum(res.get(c, "mass") for c in ("act1", "act2", "accumulator"))
    pumped = -res.integral("pump", "massflow")      # by the run's own quadrature
    balance = np.max(np.abs(stored - stored[0] - pumped)) / stored.max()
    v1, v2 = ps.volumes(res)
    fastest[name] = max(np.max(np.abs(np.diff(v)) / np.diff(t)) for v in (v1, v2)) * 1e6
    print(f"{name:16s} mass balance {balance:.1e}; fastest volume change {fastest[name]:9.1f} mL/s")
    assert balance < 1e-9
    if name != "air":
        pumped_volume = ps.FLOW * ps.T_IN[5]
        assert abs((v1[-1] + v2[-1]) - (v1[0] + v2[0])) < 5e-3 * pumped_volume
assert fastest["air"] > fastest["water"] > fastest["ethylene glycol"]

# %%
import matplotlib.pyplot as plt

fig, (axc, axd) = plt.subplots(1, 2, figsize=(11, 4))
for (name, res), color in zip(results.items(), ("C0", "C1", "C2")):
    v1, v2 = ps.volumes(res)
    axc.plot(res.times, v1 * 1e6, color=color, label=f"{name}: act 1")
    axc.plot(res.times, v2 * 1e6, color=color, ls="--", label=f"{name}: act 2")
    axd.plot(v1 * 1e6, v2 * 1e6, color=color, label=name)
axc.set(xlabel="time [s]", ylabel="volume [mL]")
axd.set(xlabel="V_act1 [mL]", ylabel="V_act2 [mL]")
axc.legend(fontsize=7)
axd.legend()
plt.show()
