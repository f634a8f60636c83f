"""Assembly fast paths for small systems: the unrolled residual, the affine
evaluation of sources and laminar liquid tubes, and the user components' row
calls must give the residual the general path gives (the one evaluated with
the Jacobian, where every group runs its kernel)."""
import numpy as np
import pytest

import softflow as sf
from softflow.components.tubes import CircularTube
from softflow.demo import PaperActuator, balloon_csv
from softflow.solve.assembly import Assembly

P0 = sf.pressure_atmospheric


def _paper():
    s = sf.System()
    s += sf.PressureSource("src", pressure=lambda t: P0 + (3e4 if t < 0.5 else 0.0))
    s += sf.CircularTube("tube", sf.water, length=0.6, diameter=1e-3)
    s += PaperActuator("actu", sf.water, sf.PVCurve(balloon_csv()))
    s.connect("tube", "src")
    s.connect("tube", "actu")
    return s


def _liquid_network():
    """Two pressure sources with different waveforms (one group, two values),
    a mass-flow source, two laminar-only tubes and a Haaland tube, accumulators."""
    s = sf.System()
    s += sf.PressureSource("s1", pressure=lambda t: P0 + 2e4 * t)
    s += sf.PressureSource("s2", pressure=lambda t: P0 + 5e3)
    s += sf.MassFlowSource("q", massflow=lambda t: 1e-4 * (1 + t))
    s += sf.CircularTube("t1", sf.water, length=0.5, diameter=1e-3, friction="laminar")
    s += sf.CircularTube("t2", sf.water, length=0.4, diameter=1e-3, friction="laminar")
    s += sf.CircularTube("t3", sf.water, length=0.3, diameter=4e-3)
    for k in range(3):
        s += sf.LinearAccumulator(f"acc{k}", sf.water, volume=1e-5, compliance=1e-10)
    s.connect("s1", "t1")
    s.connect("t1", "acc0")
    s.connect("s2", "t2")
    s.connect("t2", "acc1")
    s.connect("q", "t3")
    s.connect("t3", "acc2")
    return s


def _both(asm, x, S, t, dt):
    fast = asm.residual(x, S, t, dt, False)
    full = asm.residual(x, S, t, dt, True)
    return fast, full


@pytest.mark.parametrize("build", [_paper, _liquid_network])
def test_fast_residual_equals_the_kernels(build):
    asm = Assembly(build())
    rng = np.random.default_rng(7)
    for trial in range(20):
        x = asm.x0.copy()
        p = np.array([q == "pressure" for q in asm.x_quantity])
        x[p] = P0 + rng.uniform(-2e4, 5e4, p.sum())
        # flows from creeping (laminar) to 0.3 kg/s (turbulent in the 4 mm tube)
        x[~p] = rng.choice([1e-7, 1e-4, 0.3]) * rng.standard_normal((~p).sum())
        S = asm.S0 * (1 + 0.1 * rng.random(asm.S0.shape))
        fast, full = _both(asm, x, S, 0.1 * trial, 1e-3)
        # round-off of each row: the size of the terms it sums (|J| |x|, and |F|)
        terms = abs(asm.jacobian_csc()) @ np.abs(x) + np.abs(full)
        assert np.all(np.abs(fast - full) <= 1e-13 * terms), trial


def test_affine_groups_skip_their_kernels_while_valid(monkeypatch):
    # the per-group residual (the paper's user Actuator is otherwise called
    # back from the compiled network loop)
    monkeypatch.setattr("softflow.solve.settings.COMPILED_USER", False)
    calls = []
    orig = CircularTube.__dict__["residual"].__func__

    def counting(cls, P, V, S, t, jac):
        calls.append(jac)
        return orig(cls, P, V, S, t, jac)

    monkeypatch.setattr(CircularTube, "residual", classmethod(counting))
    asm = Assembly(_paper())
    x = asm.x0.copy()
    asm.residual(x, asm.S0, 0.0, 1e-3)          # no flow: laminar, affine
    assert calls == []
    tube_mf = asm.x_names.index("tube.a mf")
    x[tube_mf] = 0.05                            # Re ~ 65 000: the kernel takes over
    fast, full = _both(asm, x, asm.S0, 0.0, 1e-3)
    assert calls == [False, True]
    np.testing.assert_allclose(fast, full, rtol=1e-13, atol=1e-9)


def test_subclasses_with_their_own_kernel_are_not_affine():
    from softflow.components.tubes import InertialCircularTube
    assert InertialCircularTube.affine(InertialCircularTube.make_params(
        [CircularTube("i", sf.water, 0.5, 1e-3, inertance=True)])) is None
    gas = CircularTube.make_params([CircularTube("g", sf.air, 0.5, 1e-3)])
    assert CircularTube.affine(gas) is None     # a gas: density varies with pressure


def test_simulation_results_do_not_depend_on_the_fast_paths():
    """The paper scene with the generic per-group loop (the residual method
    itself) and with the generated fast paths: same steps, same results to
    round-off."""
    runs = []
    for generic in (False, True):
        sim = sf.Simulation(_paper(), duration=1.0, step=1e-3)
        if generic:
            sim.asm.residual = Assembly.residual.__get__(sim.asm)
        runs.append(sim.run())
    a, b = runs
    assert len(a.times) == len(b.times)
    pa, pb = a.get("actu", "pressure"), b.get("actu", "pressure")
    assert np.max(np.abs(pa - pb)) <= 1e-6 * (pa.max() - P0)


class _SteeperTube(CircularTube):
    """A subclass with its own pressure-drop law (twice the friction)."""

    @classmethod
    def pressure_drop(cls, P, pa, mf, pb, jac):
        dp, d_pa, d_mf, d_pb = super().pressure_drop(P, pa, mf, pb, jac)
        return 2 * dp, d_pa, (None if d_mf is None else 2 * d_mf), d_pb


def test_a_subclass_with_its_own_pressure_drop_is_evaluated_by_it():
    s = sf.System()
    s += sf.PressureSource("src", pressure=P0 + 1e4)
    s += _SteeperTube("tube", sf.water, length=0.5, diameter=1e-3)
    s += sf.LinearAccumulator("acc", sf.water, volume=1e-6, compliance=1e-11)
    s.connect("src", "tube")
    s.connect("tube", "acc")
    asm = Assembly(s)
    x = asm.x0.copy()
    x[asm.x_names.index("tube.a mf")] = 1e-4
    x[asm.x_names.index("tube.b mf")] = -1e-4
    fast, full = _both(asm, x, asm.S0, 0.0, 1e-3)
    np.testing.assert_allclose(fast, full, rtol=1e-13, atol=1e-9)
