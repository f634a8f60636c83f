"""Library classes share their interface variables among instances
(SharedVariable, read-only); a volume holds its own copy of the pressure
variable whose initial value it sets."""
import copy
import pickle

import pytest

import softflow as sf
from helpers import source_tube_tank
from softflow.network.variable import SharedVariable, Variable


def test_instances_share_read_only_variables_and_volumes_own_their_pressure():
    a = sf.Container("a", sf.air, 1e-5, initial_pressure=2e5)
    b = sf.Container("b", sf.air, 1e-5)
    pa, mfa = a.terminals[0].variables
    pb, mfb = b.terminals[0].variables
    assert mfa is mfb and isinstance(mfa, SharedVariable)
    assert type(pa) is Variable and pa is not pb
    assert (pa.initial_value, pb.initial_value) == (2e5, sf.pressure_atmospheric)
    t1, t2 = sf.CircularTube("t1", sf.air, 0.1, 1e-3), sf.CircularTube("t2", sf.air, 0.2, 1e-3)
    assert t1.terminals[1].variables[0] is t2.terminals[1].variables[0]
    with pytest.raises(AttributeError, match="'mf' is shared by every component of its "
                                             "class.*own_variable"):
        t1.terminals[0].variables[1].initial_value = 1.0
    own = t1.terminals[0].own_variable(1)
    own.initial_value = 1e-6
    assert t1.terminals[0].variables[1] is own and t2.terminals[0].variables[1].initial_value == 0.0


def test_copies_and_pickles_keep_the_values():
    t = sf.CircularTube("t", sf.air, 0.1, 1e-3)
    v = t.terminals[0].variables[0]
    assert copy.copy(v) is v and copy.deepcopy(v) is v
    back = pickle.loads(pickle.dumps(t)).terminals[0].variables[0]
    assert isinstance(back, SharedVariable)
    assert (back.quantity, back.role, back.label, back.initial_value) == \
        (v.quantity, v.role, v.label, v.initial_value)
    assert type(v.copy()) is Variable


def test_a_thermal_compile_leaves_the_shared_interface_alone():
    s = source_tube_tank()
    other = sf.CircularTube("other", sf.air, 0.5, 1e-3)
    before = [len(t.variables) for t in other.terminals]
    sf.Simulation(s, duration=0.01, thermal="adiabatic").run()
    assert [len(t.variables) for t in other.terminals] == before == [2, 2]
    assert [len(t.variables) for t in s.get("tube").terminals] == [2, 2]
    fresh = sf.CircularTube("fresh", sf.air, 0.5, 1e-3)
    assert [v.label for v in fresh.terminals[0].variables] == ["p", "mf"]
