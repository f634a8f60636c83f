# %% [markdown]
# # Let softflow choose the model: `sf.assess` on three contrasting scenes
#
# `sf.assess(system, duration, tolerance, outputs)` runs the cheapest
# configuration (isothermal, ideal fluids, the components' own friction laws,
# no inertance, rtol = tolerance), reads the validity records of that run
# (judged as for a run at rtol0 = tolerance/10), goes one level up on each
# axis whose check is near its limit (half of it or more) or past it, keeps a
# level where it changes the outputs by more than half the tolerance (axes
# far past their limit are adopted in one run), measures the time tolerance
# on the models chosen (rtol0 against 10 rtol0), and recommends a
# configuration, per component where parts of the network differ. Here,
# three scenes that need different models:
#
# 1. a slow syringe-like fill of an air actuator: isothermal is adequate;
# 2. a fast fill of a 1 L tank through a valve: the gas heats up, adiabatic is needed;
# 3. a 1 L bottle filled from 12 to 18 MPa: the ideal gas is off by percents, the
#    tabulated real gas is needed.
#
# Each recommendation is then checked against a fine reference (the finest
# models, rtol 1e-7), independently of assess: the stated tolerance is 1 % of
# each output's range.

# %%
import numpy as np

import softflow as sf
from softflow.assess import variant_system

P = sf.pressure_atmospheric
TOL = 0.01


def syringe():
    s = sf.System()
    pump = sf.waveforms.PiecewiseConstant(sf.Q_([0, 10], "s"), sf.Q_([0.5, 0], "mL/s"))
    s += sf.VolumeFlowSource("pump", volumeflow=pump, fluid=sf.air)
    s += sf.CircularTube("tube", sf.air, length=0.3, diameter=1e-3)
    curve = sf.PVCurve.monotonic((5e-6, P), (8e-6, P + 0.2e5), (20e-6, P + 0.4e5))
    s += sf.Actuator("act", sf.air, curve, initial_pressure=P, hA=0.5)
    s.connect("pump", "tube")
    s.connect("tube", "act")
    return s


def fast_fill():
    s = sf.System()
    s += sf.PressureSource("supply", pressure=sf.Q_(4, "bar"))
    s += sf.Orifice("valve", sf.air, C=2e-8, b=0.3)
    s += sf.Container("tank", sf.air, volume=1e-3)
    s.connect("supply", "valve")
    s.connect("valve", "tank")
    return s


def bottle():
    s = sf.System()
    s += sf.PressureSource("supply", pressure=18e6)
    s += sf.CircularTube("tube", sf.air, length=2.0, diameter=1e-3)
    s += sf.Container("bottle", sf.air, volume=1e-3, initial_pressure=12e6, hA=0.5)
    s.connect("supply", "tube")
    s.connect("tube", "bottle")
    return s


scenes = {
    "slow syringe fill": (syringe, 12.0, [("act", "volume"), ("act", "pressure")],
                          "heat_transfer"),
    "fast 1 L fill": (fast_fill, 1.0, [("tank", "pressure")], "adiabatic"),
    "12 -> 18 MPa bottle": (bottle, 20.0, [("bottle", "mass"), ("bottle", "pressure")],
                            "heat_transfer"),
}
assessments = {}
for name, (build, duration, outputs, _) in scenes.items():
    a = sf.assess(build(), duration, tolerance=TOL, outputs=outputs)
    assessments[name] = a
    print(f"{name}: recommended {a.recommended}")

# %%
# what each axis did, measured on the scene (effect on the outputs, cost)
for name, a in assessments.items():
    print(f"--- {name}")
    print(a.table.to_string(index=False))

# %% [markdown]
# The validity records of each base run decide which axes are run one level
# up: 'beyond' records are warnings (a plain run warns them as
# `sf.ModelWarning`), 'near' ones are figures at half their limit or more
# (here the bottle's fill time against its wall's thermal time constant), not
# warned but measured. The base runs use the cheapest models on purpose, so
# their records are the point here: `sf.assess` reads them instead of warning
# them, and lists them below. The runs it recommends (and the references
# further down) warn of nothing.

# %%
from softflow.solve.validity import table

for name, a in assessments.items():
    print(f"--- {name}")
    print(table(a.validity)[["component", "check", "status", "fraction"]].to_string(index=False)
          if a.validity else "no record")

# %% [markdown]
# ## Against a fine reference
#
# The reference runs the finest models (the wall's heat transfer where the scene
# has one, else adiabatic; the `table` level; rtol 1e-7). The recommended run
# must be within 1 % of each output's range at its own time points.

# %%
for name, (build, duration, outputs, thermal) in scenes.items():
    a = assessments[name]
    res = a.simulation().run()
    ref = sf.Simulation(variant_system(build(), "table", None), duration, thermal=thermal,
                        rtol=1e-7).run()
    for label, var in outputs:
        mine = res.get(label, var)
        fine = np.interp(res.times, ref.times, ref.get(label, var))
        err = np.max(np.abs(mine - fine)) / np.ptp(ref.get(label, var))
        print(f"{name}: {label}.{var} within {err:.2%} of the reference")
        assert err < TOL, (name, label, var, err)

rec = {name: a.recommended for name, a in assessments.items()}
assert rec["slow syringe fill"]["thermal"] in ("isothermal", "heat_transfer")
assert rec["fast 1 L fill"]["thermal"] == "adiabatic"
assert rec["12 -> 18 MPa bottle"]["fluid_level"] in ("table", "eos")
