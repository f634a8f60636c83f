"""softflow.fons scripts on the compiled core: fons's components that keep
their softflow class's law (its constructor and result reading their own)
are evaluated by that law's compiled code, and a fonsim-style user
component (labelled ``auto`` functions, a Jacobian optionally returned
next to the values) is compiled as softflow's are; the numbers are the
per-group Python path's."""
import numpy as np
import pytest

import softflow as sf
import softflow.fons as fons
from softflow.demo import balloon_csv
from softflow.solve import netcore, settings

P0 = fons.pressure_atmospheric


class Actuator(fons.Component):
    """The paper's actuator in fonsim's form; ``jacobian``: its evaluate
    returns fonsim's optional Jacobian next to the values."""

    def __init__(self, label, fluid, pvcurve, jacobian=False):
        super().__init__(label)
        p_ = fons.Variable("pressure", "across", label="p", initial_value=P0)
        mf_ = fons.Variable("massflow", "through", label="mf")
        m_ = fons.Variable("mass", "local", label="mass", initial_value=1e-3)
        self.set_terminals(fons.Terminal("a", [p_, mf_]))
        self.set_states(m_)
        if jacobian:
            def evaluate(t, p, mass):
                return [p - pvcurve.fdf_volume(volume=mass / fluid.rho)[0]], [{"p": 1.0}]
        else:
            def evaluate(t, p, mass):
                return [p - pvcurve.fdf_volume(volume=mass / fluid.rho)[0]]
        self.evaluate = self.auto(evaluate)

        def update_state(dt, mass, mf):
            return {"mass": mass + mf * dt}
        self.update_state = self.auto_state(update_state)


def listing(jacobian=False):
    system = fons.System()
    system += fons.PressureSource("source", pressure=lambda t: P0 + (.3e5 if t < .5 else 0))
    system += fons.CircularTube(label="tube", fluid=fons.water, length=0.60, diameter=1e-3)
    system += Actuator("actu", fluid=fons.water,
                       pvcurve=fons.pvcurve.PVCurve(str(balloon_csv())), jacobian=jacobian)
    system.connect("tube", "source")
    system.connect("tube", "actu")
    return system


def chain():
    system = fons.System()
    system += fons.PressureSource("src", pressure=2e5)
    system += fons.CircularTube("tube", fluid=fons.air)
    system += fons.Container("tank", fluid=fons.air, volume=20e-6)
    system += fons.CheckValve("valve", pressure_threshold=1e3, fluid=fons.air)
    system += fons.Sink("out")
    system.connect("src", "tube")
    system.connect("tube", "tank")
    system.connect("tank", "valve")
    system.connect("valve", "out")
    return system


def _run(build, **kw):
    sim = fons.Simulation(build(), duration=1.0 if build is not chain else 0.05, **kw)
    sim.run()
    return sim


@pytest.mark.parametrize("build", [listing, chain])
def test_fons_library_components_run_on_their_compiled_laws(monkeypatch, build):
    """fons's PressureSource, CircularTube, Container, CheckValve and Sink
    are evaluated by softflow's compiled laws (the compiled network serves
    the scene); fixed steps give the per-group path's numbers to 1e-10."""
    compiled = _run(build, step=1e-3)
    net = getattr(compiled.asm.residual, "network", None)
    assert net is not None and not net.callbacks
    monkeypatch.setattr(netcore, "_law_class", lambda cls: cls)    # fons's classes: Python
    python = _run(build, step=1e-3)
    assert getattr(python.asm.residual, "network", None) is None
    scale = np.abs(python.asm.x0).max() + 1.0
    np.testing.assert_allclose(compiled.result.X, python.result.X, rtol=1e-10,
                               atol=1e-10 * scale)


def test_a_class_that_changes_its_law_keeps_its_own(monkeypatch):
    """A subclass that redefines a name of its library class (fons's
    FlowRestrictor, fonsim's own residual) or defines a hook the assembly
    reads (begin_step, switching, ...) is not evaluated by the library
    class's compiled law, also where it is given one after a first build;
    one that adds names of its own is."""
    assert netcore._law_class(fons.FlowRestrictor) is fons.FlowRestrictor
    assert netcore._law_class(fons.CircularTube) is sf.CircularTube

    class Labelled(sf.CircularTube):
        def describe_more(self):
            return "a tube"

    class OwnLaw(sf.CircularTube):
        @classmethod
        def residual(cls, P, V, S, t, jac):
            return super().residual(P, V, S, t, jac)
    class Hooked(sf.CircularTube):          # a hook CircularTube does not have
        @classmethod
        def wants_begin_step(cls, P):
            return True
    assert netcore._law_class(Labelled) is sf.CircularTube
    assert netcore._law_class(OwnLaw) is OwnLaw
    assert netcore._law_class(Hooked) is Hooked
    Labelled.residual = OwnLaw.residual             # changed since: seen at the next build
    assert netcore._law_class(Labelled) is Labelled


@pytest.mark.parametrize("jacobian", [False, True])
def test_a_fonsim_style_user_component_is_compiled(monkeypatch, jacobian):
    """fonsim's labelled evaluate is compiled (its wrapper that drops a
    returned Jacobian aside); one that returns a Jacobian (a list of dicts,
    which numba does not compile) is called back through the wrapper: the
    numbers are the call-back's, bit for bit, at fixed steps."""
    a = _run(lambda: listing(jacobian), step=1e-3)
    net = a.asm.residual.network
    assert bool(net.callbacks) == jacobian and len(net.kernels) == (not jacobian)
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    b = _run(lambda: listing(jacobian), step=1e-3)
    assert b.asm.residual.network.callbacks
    np.testing.assert_array_equal(a.result.X, b.result.X)


class ArrayTank(fons.Component):
    """A tank in fonsim's array form: methods that fill fonsim's arrays and
    read the component's attributes, a closure's float and the module's
    number (fons.pressure_atmospheric)."""

    def __init__(self, label, volume, order):
        super().__init__(label)
        self.set_terminals(fons.Terminal("a", fons.terminal_fluidic,
                                         {"pressure": "p", "massflow": "mf"}))
        self.rho, self.volume, self.order = fons.air.rho, volume, order
        self.set_states(fons.Variable("mass", "local", label="m",
                                      initial_value=volume * self.rho))
        if order:
            self.set_arguments(self.terminals[0]("pressure"), self.terminals[0]("massflow"))
        self.nb_equations = 1

    def evaluate(self, values, jacobian_state, jacobian_arguments, state, arguments,
                 elapsed_time):
        p = arguments[0] if self.order else arguments[1]
        values[0] = state[0] * fons.pressure_atmospheric - p * self.volume * self.rho
        jacobian_state[0, 0] = fons.pressure_atmospheric

    def update_state(self, state_new, jacobian, state, arguments, dt):
        mf = arguments[1] if self.order else arguments[0]
        state_new[0] = state[0] + dt * mf


@pytest.mark.parametrize("order", [False, True])
def test_a_fonsim_array_form_component_is_compiled(monkeypatch, order):
    """fonsim's array form (evaluate / update_state filling arrays, with or
    without set_arguments) is compiled with an adaptor that makes fonsim's
    arrays; its runs are the call-back's bit for bit."""
    def build():
        s = fons.System()
        s.add(fons.PressureSource("src", pressure=2e5))
        s.add(fons.CircularTube("tube", fluid=fons.air))
        s.add(ArrayTank("tank", 20e-6, order))
        s.connect("src", "tube")
        s.connect("tube", "tank")
        return s

    def run():
        sim = fons.Simulation(build(), duration=0.1, step=1e-3)
        sim.run()
        return sim
    a = run()
    net = a.asm.residual.network
    assert not net.callbacks and len(net.kernels) == 1
    monkeypatch.setattr(settings, "COMPILED_USER_CODE", False)
    b = run()
    assert b.asm.residual.network.callbacks
    np.testing.assert_array_equal(a.result.X, b.result.X)
    np.testing.assert_array_equal(a.result.S, b.result.S)
