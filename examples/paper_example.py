#!/usr/bin/env python3
# The FONS paper's 44-line example (section V), with only its import line
# changed, and the measured latex balloon curve as the actuator's PV file.
# Run it from this folder:  cd examples && python paper_example.py
import softflow as fons
p0 = fons.pressure_atmospheric

# === Create the components ===
class Actuator(fons.Component):
    def __init__(self, label, fluid, pvcurve):
        super().__init__(label)
        p_ = fons.Variable('pressure', 'across', label='p', initial_value=p0)
        mf_ = fons.Variable('massflow', 'through', label='mf')
        m_ = fons.Variable('mass', 'local', label='mass', initial_value=1e-3)

        self.set_terminals(fons.Terminal('a', [p_, mf_]))
        self.set_states(m_)

        def evaluate(t, p, mass):
            return [p - pvcurve.fdf_volume(volume=mass/fluid.rho) [0]]
        self.evaluate = self.auto(evaluate)

        def update_state(dt, mass, mf):
            return {'mass': mass + mf * dt}
        self.update_state = self.auto_state(update_state)

# === Create the fluidic system ===
system = fons.System()
system += fons.PressureSource('source',
                              pressure=lambda t: p0 + (.3e5 if t<.5 else 0))
system += fons.CircularTube(label='tube', fluid=fons.water,
                            length=0.60, diameter=1e-3)
system += Actuator('actu', fluid=fons.water,
                   pvcurve=fons.pvcurve.PVCurve('latex_balloon_60mm_pv.csv'))

# Connect the components to each other
system.connect('tube', 'source')
system.connect('tube', 'actu')

# == Simulate the system ==
sim = fons.Simulation(system, duration=1.)
sim.run()

# Put results in local variables (e.g. for visualization later)
t = sim.times
p_actu = (system.get('actu').get('pressure') - p0) * 1e-5
