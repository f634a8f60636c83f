# %% [markdown]
# # Gas flow through a tube at any pressure ratio, choked flow included (air)
#
# softflow's default tube law for a gas (`CircularTube(..., compressible='pipe_flow')`)
# is, in an isothermal scene, isothermal pipe flow between two nodes whose
# pressures are stagnation pressures (the gas at rest in the volumes):
#
# * the gas accelerates from rest into the tube, isothermally:
#   c² ln(p₀/p₁) = u₁²/2, c² = RT;
# * it flows with friction and acceleration (Crane TP-410;
#   `fluids.compressible.isothermal_gas`): p₁² − p₂² = G²c² [fL/D + 2 ln(p₁/p₂)],
#   G = ṁ/A;
# * it chokes where its exit velocity reaches c (Mach 1/√γ): the exit pressure
#   is then G c and a lower downstream pressure passes no more flow
#   (`fluids.compressible.P_isothermal_critical_flow`).
#
# The reference is `gas_reference.py` beside this notebook: the same equations
# written on their own with NumPy, SciPy and `fluids` (Haaland's friction
# factor and the isothermal pipe flow from `fluids`), solved with a bracketing
# root finder to 1e-12; it never imports softflow. Stated tolerances: the mass
# flow of one tube within 0.5 % over pressure ratios 0.05–0.95, fL/D 0.1–100
# and Reynolds numbers 10²–10⁶; five pneumatic scenes, run at softflow's
# default settings, within 2 % of their pressure range over the whole run.

# %%
import sys
import warnings
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

import softflow as sf
from softflow.components.tubes import CircularTube

# the reference beside this notebook (the repository's examples/validation/)
sys.path.insert(0, str(Path(sf.__file__).resolve().parents[2] / "examples" / "validation"))
import gas_reference as ref  # noqa: E402


def softflow_massflow(p0, p_down, length, diameter):
    """The mass flow that zeroes the tube's own residual between two fixed pressures."""
    P = CircularTube.make_params([CircularTube("t", sf.air, length, diameter)])
    S = np.zeros((1, 0))

    def residual(mf):
        return CircularTube.residual(P, np.array([[p0, mf, p_down, -mf]]), S, 0.0, False)[0][0, 1]
    hi = 1.0
    while residual(hi) > 0:
        hi *= 10.0
    return brentq(residual, 0.0, hi, xtol=1e-300, rtol=1e-13)


# %% [markdown]
# ## One tube, choked or not

# %%
rows = []
for diameter in (0.5e-3, 2e-3, 10e-3):
    for l_over_d in (5.0, 50.0, 500.0, 5000.0):
        for p0 in (1.2e5, 2e5, 2e6):
            for ratio in (0.05, 0.1, 0.2, 0.35, 0.5, 0.65, 0.8, 0.95):
                length = l_over_d * diameter
                want, choked = ref.tube_massflow(p0, ratio * p0, length, diameter)
                got = softflow_massflow(p0, ratio * p0, length, diameter)
                G = want / (np.pi * diameter ** 2 / 4)
                Re = G * diameter / ref.MU_AIR
                fld = ref.friction_factor(Re, ref.ROUGHNESS / diameter) * l_over_d
                rows.append((ratio, fld, Re, choked, got / want - 1))
rows = np.array(rows)
err = np.abs(rows[:, 4])
print(f"{len(rows)} tubes: pressure ratio {rows[:, 0].min():g}-{rows[:, 0].max():g}, "
      f"fL/D {rows[:, 1].min():.3g}-{rows[:, 1].max():.3g}, "
      f"Re {rows[:, 2].min():.3g}-{rows[:, 2].max():.3g}, {int(rows[:, 3].sum())} choked")
print(f"largest relative difference of the mass flow: {err.max():.2e} (choked: "
      f"{err[rows[:, 3] == 1].max():.2e}, not choked: {err[rows[:, 3] == 0].max():.2e})")
assert rows[:, 1].min() <= 0.1 and rows[:, 1].max() >= 100
assert rows[:, 2].min() <= 1e2 and rows[:, 2].max() >= 1e6
assert 0 < rows[:, 3].sum() < len(rows)
assert err.max() < 5e-3

# %% [markdown]
# No tube passes more than the isothermal nozzle of its bore (a tube of zero
# length, G = p₀ e^(-1/2)/c), and a choked tube's flow does not depend on the
# downstream pressure:

# %%
nozzle = 2e5 * np.exp(-0.5) / np.sqrt(ref.RT) * np.pi * (2e-3) ** 2 / 4
shortest = softflow_massflow(2e5, 0.05 * 2e5, 1e-4, 2e-3)
flows = [softflow_massflow(2e5, r * 2e5, 0.5, 2e-3) for r in (0.05, 0.2, 0.3)]
print(f"0.1 mm of 2 mm tube: {shortest / nozzle:.4f} of the nozzle's flow; "
      f"0.5 m choked at 0.05, 0.2, 0.3: {[f'{f * 1e3:.6f}' for f in flows]} g/s")
assert shortest <= nozzle and shortest > 0.97 * nozzle
assert max(flows) - min(flows) < 1e-12 * max(flows)

# %% [markdown]
# ## Five pneumatic scenes at the default settings
#
# 1. a 50 mL tank filled from 3 bar gauge through 10 cm of 4 mm tube;
# 2. a 1 L tank at 10 bar abs blowing down to the atmosphere through 1 m of 4 mm tube;
# 3. the same through 30 cm of 2 mm tube;
# 4. two 100 mL tanks at 5 and 1 bar abs joined by 20 cm of 3 mm tube;
# 5. a 6 bar gauge supply into a soft actuator (its PV curve in `gas_reference.py`)
#    through 2 m of 2 mm tube.
#
# The reference integrates each scene to rtol 1e-10. softflow runs each with
# `sf.Simulation(system, duration=...)` and nothing else.
#
# These scenes choke and empty or fill their tanks within a fraction of a
# second: an isothermal model of them is the model under test here, not a
# faithful one, and softflow's checks say so on every run (the last column:
# the checks that warned, kept in `res.warnings`, each a `ModelWarning`
# gathered here instead of printed). `tube_isothermal_flow`: the choked tube
# would pass a few percent more as adiabatic (Fanno) pipe flow, the model of a
# tube too short and fast to exchange heat with its wall; `thermal_time_scale`:
# the tank fills or empties faster than its wall exchanges heat. The next
# section runs the same scenes adiabatic, the model those checks point to.

# %%
import matplotlib.pyplot as plt  # noqa: E402

import gas_scenes  # noqa: E402  (the five scenes built in softflow, beside this notebook)

print(f"{'scene':14s} {'duration':>9s} {'choked':>7s} {'largest difference':>19s} {'steps':>6s}"
      "  model warnings")
fig, axes = plt.subplots(1, 5, figsize=(16, 3))
worst = 0.0
for ax, name in zip(axes, ref.SCENE_FUNCTIONS):
    r = ref.SCENE_FUNCTIONS[name]()
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always", sf.ModelWarning)
        res = sf.Simulation(gas_scenes.scene(name), duration=r.duration).run()
    assert res.success
    assert not [w for w in res.warnings if w.check in ("tube_choked", "tube_mach")]
    diffs = []
    for label, want in r.pressure_at(res.times).items():
        p = res.get(label, "pressure")
        diffs.append(np.max(np.abs(p - want)) / r.pressure_range)
        ax.plot(r.t, r.pressures[label] / 1e5, "k-", lw=3, alpha=0.3)
        ax.plot(res.times, p / 1e5, ".", ms=3)
    ax.set_title(name)
    ax.set_xlabel("t [s]")
    worst = max(worst, max(diffs))
    checks = sorted({w.check for w in res.warnings})
    print(f"{name:14s} {r.duration:8.3g}s {r.choked_fraction:7.1%} {max(diffs):18.2%} "
          f"{res.stats['steps']:6d}  {', '.join(checks) or 'none'}")
    assert set(checks) <= {"tube_isothermal_flow", "thermal_time_scale"}
axes[0].set_ylabel("p [bar abs]")
print(f"largest difference of all five: {worst:.2%} of the pressure range (tolerance 2 %)")
assert worst < 0.02

# %% [markdown]
# ## The same scenes, adiabatic
#
# With `thermal='adiabatic'` the volumes keep their energy and a gas tube is
# adiabatic pipe flow: isentropic entry from the upstream stagnation state,
# Fanno flow (fL/D = F*(M₁) − F*(M₂)), choked at Mach 1, the stagnation
# enthalpy carried through (`softflow.correlations.fanno`). The reference's
# adiabatic scenes solve the same equations on their own (Fanno's closed
# forms, checked against Fanno tables and the isentropic nozzle). Stated
# tolerance: 2 % of the pressure range and of each gas temperature's range.
#
# The adiabatic model is the fast scenes' own, and the checks that warned
# above are silent; two others may speak (last column), about what the
# reference leaves out as well: `adiabatic_time_scale`, a tank that stays far
# from its wall's temperature for longer than the wall's thermal time constant
# (a real wall would take the heat back: the thermal notebook's heat-transfer
# scenes), and `gas_compressibility`, the ideal gas at the blowdown's coldest
# (150 K at 10 bar: Z − 1 = −6 %; the references are ideal-gas closed forms).

# %%
print(f"{'scene':14s} {'duration':>9s} {'choked':>7s} {'pressure':>9s} {'temperature':>12s}"
      "  model warnings")
worst_p = worst_T = 0.0
for name, make in ref.ADIABATIC_SCENE_FUNCTIONS.items():
    r = make()
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always", sf.ModelWarning)
        res = sf.Simulation(gas_scenes.scene(name), duration=r.duration,
                            thermal="adiabatic").run()
    assert res.success
    dp = max(np.max(np.abs(res.get(k, "pressure") - v)) / r.pressure_range
             for k, v in r.pressure_at(res.times).items())
    dT = max(np.max(np.abs(res.get(k, "temperature") - v)) / np.ptp(r.temperatures[k])
             for k, v in r.temperature_at(res.times).items())
    worst_p, worst_T = max(worst_p, dp), max(worst_T, dT)
    checks = sorted({w.check for w in res.warnings})
    print(f"{name:14s} {r.duration:8.3g}s {r.choked_fraction:7.1%} {dp:9.2%} {dT:12.2%}  "
          f"{', '.join(checks) or 'none'}")
    assert set(checks) <= {"adiabatic_time_scale", "gas_compressibility"}
assert worst_p < 0.02 and worst_T < 0.02
