"""FreeConvection.coefficient broadcasts its inputs without np.broadcast_arrays:
every mix of shapes gives, element by element, what scalar inputs give."""
import numpy as np
import pytest

import softflow as sf

RNG = np.random.default_rng(7)
CASES = {
    "scalars": (1.2e5, 300.0, 293.15, 0.01),
    "one-tank": (np.array([1.16e5]), 294.15, 293.15, np.array([0.0124])),
    "p-T-arrays": (RNG.uniform(1e5, 5e5, 5), RNG.uniform(250, 400, 5), 293.15, 0.02),
    "all-arrays": (RNG.uniform(1e5, 5e5, 4), RNG.uniform(250, 400, 4),
                   RNG.uniform(250, 400, 4), RNG.uniform(0.01, 0.1, 4)),
    "outer": (RNG.uniform(1e5, 5e5, (3, 1)), RNG.uniform(250, 400, (1, 4)), 293.15, 0.05),
    "length-only": (2e5, 310.0, 293.15, np.array([0.01, 0.02, 0.03])),
}


@pytest.mark.parametrize("fluid", [sf.air, sf.air.with_level("table")], ids=["ideal", "table"])
@pytest.mark.parametrize("shape, length", [("sphere", None), ("vertical_plate", 0.1)])
@pytest.mark.parametrize("case", sorted(CASES))
def test_coefficient_broadcasts_as_scalar_inputs_give(fluid, shape, length, case):
    corr = sf.FreeConvection(shape, length=length)
    args = CASES[case]
    h = corr.coefficient(fluid, *args)
    want_shape = np.broadcast_shapes(*(np.shape(a) for a in args))
    if want_shape == ():
        assert type(h) is float
    assert np.shape(h) == want_shape
    full = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in args))
    want = np.array([corr.coefficient(fluid, *(float(a[i]) for a in full))
                     for i in np.ndindex(want_shape)]).reshape(want_shape)
    np.testing.assert_array_equal(h, want)


def test_coefficient_rejects_shapes_that_do_not_broadcast():
    with pytest.raises(ValueError):
        sf.FreeConvection("sphere").coefficient(sf.air, np.full(3, 2e5), np.full(2, 300.0),
                                                293.15, 0.01)


def test_the_correlation_gets_numpy_scalars():
    """As before the shapes were handled without np.broadcast_arrays: NumPy
    scalars, whose division by zero gives inf (a Python float's would raise)."""
    seen = []

    def nusselt(Pr, Gr):
        seen.append((type(Pr), type(Gr)))
        return 2.0 + Gr / (Pr - Pr)

    corr = sf.FreeConvection("sphere", nusselt=nusselt)
    with np.errstate(all="ignore"):
        h = corr.coefficient(sf.air, np.array([2e5, 3e5]), 310.0, 293.15, 0.01)
    assert np.isinf(h).all()
    assert seen == [(np.float64, np.float64)] * 2
