"""The assembly numbers unknowns per library group with NumPy (one node lookup
per terminal): the numbering, initial values, node rows and names must be
those of the plain component-by-component numbering, written out here as the
reference, on isothermal, thermal, user-component and mixed networks."""
import copy

import numpy as np
import pytest

import softflow as sf
from softflow.demo import paper_system
from softflow.solve.assembly import Assembly
from softflow.solve.thermal import configure_thermal

from helpers import rc_circuit, tank_and_actuator

P0 = sf.pressure_atmospheric


def reference_numbering(system):
    """(node across unknowns as (node index, quantity), x quantities, columns of
    every component by label, through rows and columns, x0), component by
    component and variable by variable."""
    nodes = system.nodes()
    node_of = {id(t): nd for nd in nodes for t in nd.terminals}
    quantities, across, across_named, node_rows = [], {}, [], {}
    n_rows = 0
    for nd in nodes:
        for q in nd.quantities("across"):
            across[(nd.index, q)] = len(quantities)
            across_named.append((nd.index, q))
            quantities.append(q)
        for q in nd.quantities("through"):
            node_rows[(nd.index, q)] = n_rows
            n_rows += 1
    return nodes, node_of, quantities, across, across_named, node_rows


def reference(asm, system):
    nodes, node_of, quantities, across, across_named, node_rows = reference_numbering(system)
    cols, trows, tcols = {}, [], []
    for g in asm.groups:
        for c in g.comps:
            terminal_of = {t.label: t for t in c.terminals}
            row = []
            for term, v in c.interface_variables():
                if v.role == "across":
                    idx = across[(node_of[id(terminal_of[term])].index, v.quantity)]
                else:
                    idx = len(quantities)
                    quantities.append(v.quantity)
                    if v.role == "through":
                        nd = node_of[id(terminal_of[term])]
                        trows.append(node_rows[(nd.index, v.quantity)])
                        tcols.append(idx)
                row.append(idx)
            cols[c.label] = row
    x0 = np.zeros(len(quantities))
    seen = set()
    for g in asm.groups:
        for c in g.comps:
            for (_, v), idx in zip(c.interface_variables(), cols[c.label]):
                if v.initial_value is None or (v.role == "across" and idx in seen):
                    continue
                x0[idx] = v.initial_value
                seen.add(idx)
    names = [f"{nodes[k].name} {q}" for k, q in across_named]
    return cols, quantities, trows, tcols, x0, names, len(node_rows)


def _chain(n, own_pressure=False):
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    prev = "src"
    for i in range(n):
        s += sf.CircularTube(f"t{i}", sf.air, 0.1, 1e-3)
        kw = {"initial_pressure": P0 + 1e3 * i} if own_pressure else {}
        s += sf.Container(f"c{i}", sf.air, 1e-6, **kw)
        s.connect(prev, f"t{i}")
        s.connect(f"t{i}", f"c{i}")
        prev = f"c{i}"
    return s


def _open_end():
    s = _chain(3, own_pressure=True)
    s += sf.CircularTube("dangling", sf.air, 0.2, 1e-3)
    s.connect("c2", "dangling")
    return s


def _thermal(system):
    model = copy.deepcopy(system)
    configure_thermal(model, "adiabatic")
    return model


@pytest.mark.parametrize("make", [
    lambda: _chain(1), lambda: _chain(7), lambda: _chain(5, own_pressure=True),
    rc_circuit, tank_and_actuator, paper_system, _open_end,
    lambda: _thermal(_chain(4, own_pressure=True)), lambda: _thermal(tank_and_actuator()),
], ids=["chain1", "chain7", "chain_own_p", "rc", "tank_actuator", "paper_user_component",
        "open_end", "thermal_chain", "thermal_tank_actuator"])
def test_numbering_equals_the_component_by_component_one(make):
    system = make()
    asm = Assembly(system, allow_unconnected=True)
    cols, quantities, trows, tcols, x0, names, n_node_rows = reference(asm, system)
    for g in asm.groups:
        for i, c in enumerate(g.comps):
            assert g.col[i].tolist() == cols[c.label], c.label
    assert asm.x_quantity == quantities and asm.n == len(quantities)
    assert asm.through_rows.tolist() == trows and asm.through_cols.tolist() == tcols
    assert asm.n_node_rows == n_node_rows
    assert np.array_equal(asm.x0, x0)
    assert list(asm.x_names[:asm.n_across]) == names
    assert [[t.name for t in nd.terminals] for nd in asm.nodes] == \
           [[t.name for t in nd.terminals] for nd in system.nodes()]
    # the interfaces as compiled, per component
    for g in asm.groups:
        for i, c in enumerate(g.comps):
            iface, states = g.iface[i]
            assert [(t, v.label) for t, v in iface] == \
                   [(t, v.label) for t, v in c.interface_variables()]
            assert [s.label for s in states] == [s.label for s in c.states]


def test_initial_values_follow_replaced_components():
    """Run-time parameters rebuild components; the initial values are read
    from the new ones, as a compile of the changed System reads them."""
    s = sf.System()
    s += sf.PressureSource("src", pressure=1.2e5)
    s += sf.Container("c", sf.air, 1e-6)
    s += sf.CircularTube("t", sf.air, 0.1, 1e-3)
    s.connect("src", "t")
    s.connect("t", "c")
    sim = sf.Simulation(s, duration=1e-3, step=1e-3)
    base = sim.asm.x0.copy()
    sim.run(params={"c.initial_pressure": P0 + 5e3})
    rebuilt = sf.System()
    rebuilt += sf.PressureSource("src", pressure=1.2e5)
    rebuilt += sf.Container("c", sf.air, 1e-6, initial_pressure=P0 + 5e3)
    rebuilt += sf.CircularTube("t", sf.air, 0.1, 1e-3)
    rebuilt.connect("src", "t")
    rebuilt.connect("t", "c")
    assert np.array_equal(sim.asm.x0, Assembly(rebuilt).x0)
    assert not np.array_equal(sim.asm.x0, base)
    sim.run()
    assert np.array_equal(sim.asm.x0, base)


def test_system_nodes_and_unconnected_terminals():
    s = _chain(3)
    node_of, count = s.terminal_nodes()
    assert count == len(s.nodes()) == 4
    assert node_of == [0, 0, 1, 1, 1, 2, 2, 2, 3, 3]
    assert s.unconnected_terminals() == []
    s += sf.CircularTube("loose", sf.air, 0.1, 1e-3)
    assert [t.name for t in s.unconnected_terminals()] == ["loose.a", "loose.b"]
    with pytest.raises(sf.NetworkError, match="unconnected terminal"):
        sf.Simulation(s, duration=1e-3)
