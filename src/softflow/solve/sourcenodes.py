"""The consistent start at t = 0 at nodes without volume that carry a flow source.

Every unknown pressure starts at its initial value (1 atm where none is
given). A flow source (a VolumeFlowSource, a MassFlowSource: in general a
component at one node whose flows the node's state alone sets) at a node
without volume fixes the flow that the node's other components must pass,
and the pressure at which they pass it can lie far from 1 atm: 23 bar to push
7.9 mL/s of air through a 0.3 mm tube and a leaking check valve. From 1 atm
Newton's first step overshoots to a negative pressure (a volume flow
source's slope rho'(p) Q exceeds the slope of tubes at rest), where an ideal
gas's density p/RT stays finite, and Newton settles on a root below zero.

Where the consistent start from the initial values fails, or puts such a
node above :data:`PRESSURE_CAP`, :func:`balanced_start` solves each such
node's mass balance alone for its pressure: the other nodes' pressures held
at their start values, the flows (and the other unknowns) of the node's
components solved for at each trial pressure, a bracketing search from the
start pressure up or down, then a safeguarded Newton iteration in the
bracket. The start is solved again from there
(:meth:`softflow.solve.integrator.Integrator._solve_initial`). Where no
pressure up to the cap balances the node (the components there pass less
than the source pushes in: closed, at rest, dead ends, past their choked
capacity), or none down to :data:`PRESSURE_FLOOR` (a source that draws more
than they can supply), the run is refused with a message that names the
source and the node.

Nothing here knows component classes: the nodes, their sources and whether
a volume sets a node's pressure are read off the Jacobian at the start
(dt = 0), and the balances are the network's residual rows.

* A *flow source* at node k: a component whose across unknowns are all node
  k's and whose block of the Jacobian (its equations, its own unknowns: the
  flows at its terminals and its locals) is square and regular: its flows
  follow from the node's state. A volume at dt = 0 (its equations set the
  pressure from its mass, whatever flows in) and a pressure source have a
  singular block.
* A node *without volume*: with the node's pressure held, its components'
  equations, its other balances (energy) and those of the dead ends behind
  them (nodes whose every flow belongs to those components) determine their
  unknowns and the node's other across unknowns: that block of the Jacobian
  is square and regular. A volume or a pressure source at the node makes it
  singular (the pressure is theirs to set, not the balance's).

The same balance later in a run (:mod:`softflow.solve.culprit`, where a
step's solve fails): :func:`unbalanced` asks each such node at a state and a
time whether any pressure between the floor and the cap balances it
(:func:`_reach`: the limit the balance points to first, two trial pressures
for a diagnosis); :func:`rebalanced` solves each for its balancing pressure,
a start for the step's solve again. There the nodes take in the nodes without
volume beyond them (``local_nodes(..., region=True)``): a junction between
the source's node and a thin tube, whose pressure falls with the node's, is
solved for with it instead of held.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import repeat

import numpy as np

from ..fluids.base import FluidError
from .assembly import DENSE_CHECK_MAX, _is_regular_dense
from .newton import Outcome
from .settings import (
    EDGE_BACKOFF,
    INNER_ITERATIONS,
    INNER_SHIFTED,
    INNER_RTOL,
    MARCH,
    MARCH_TRIALS,
    PRESSURE_CAP,
    PRESSURE_FLOOR,
    REGION_NODES,
    SEARCH_ITERATIONS,
    SEARCH_RTOL,
)
from .validity import ComponentError


@dataclass
class Local:
    """A node without volume that carries a flow source: its pressure
    unknown ``p``, its mass balance ``row``, the equations ``rows`` that
    determine the unknowns ``cols`` for the pressure held, the flow
    sources (components) and the first equation of each."""

    node: int
    p: int
    row: int
    rows: np.ndarray
    cols: np.ndarray
    sources: list
    source_rows: list
    #: the pressures of the dead ends behind the node: each trial starts
    #: them at the node's (at rest, what leads to a dead end passes nothing
    #: at equal pressures; a choked orifice's flow does not depend on its
    #: outlet's pressure, and Newton's step from 1 atm would not find it)
    ends: np.ndarray
    #: the flow sources at the node, then the components at the edge of its
    #: region, each with the columns of its flows into it from inside (its
    #: through unknowns in the region's mass balances)
    members: list = None
    #: the nodes whose balances ``rows`` hold (the node, its dead ends, and
    #: with ``region`` the nodes without volume beyond)
    inside: list = None
    #: whether a component inside has a continuous state (an inertial tube's
    #: flow): fixed at dt = 0, it changes within any step
    dynamic: bool = False
    #: the node of each of ``sources`` (the node's own, then those at the
    #: region's other nodes)
    source_nodes: list = None

    @property
    def rows_set(self):
        """``rows`` as a set (asked whether a failure's equation is here)."""
        got = self.__dict__.get("_rows_set")
        if got is None:
            got = self.__dict__["_rows_set"] = frozenset(self.rows.tolist())
        return got

    @property
    def cols_set(self):
        """``cols`` as a set."""
        got = self.__dict__.get("_cols_set")
        if got is None:
            got = self.__dict__["_cols_set"] = frozenset(self.cols.tolist())
        return got


def _regular(A):
    """A square block numerically regular after row and column equilibration."""
    return A.shape[0] == A.shape[1] and np.isfinite(A).all() and _is_regular_dense(A)


class _Jacobian:
    """The Jacobian of the network's last ``residual(..., jac=True)``, read
    block by block: a dense copy up to :data:`DENSE_CHECK_MAX` unknowns,
    else its CSR arrays, gathered row by row (the values of
    ``jacobian_csc().tocsr()[rows][:, cols].toarray()``, without SciPy's
    sparse indexing: ~50 us a block, the most of this module's cost on a
    small network; the CSR arrays from :meth:`Assembly.jacobian_csr`)."""

    def __init__(self, asm):
        n = self.n = asm.n
        if n <= DENSE_CHECK_MAX:
            self.dense = asm.dense_jacobian()
            return
        self.dense = None
        self.indptr, self.indices, self.data = asm.jacobian_csr()
        self.pos = np.full(n, -1, dtype=np.int64)

    def block(self, rows, cols):
        """The dense block J[rows, cols] (rows and columns in the order given)."""
        rows = np.asarray(rows, dtype=np.int64)
        cols = np.asarray(cols, dtype=np.int64)
        if self.dense is not None:
            # np.ix_'s block, without its per-call checks (a third of a small block's cost)
            return self.dense[rows[:, None], cols]
        if np.unique(cols).size != cols.size:        # a column asked twice
            from scipy.sparse import csr_matrix
            csr = csr_matrix((self.data, self.indices, self.indptr), shape=(self.n, self.n))
            return csr[rows][:, cols].toarray()
        pos = self.pos
        pos[cols] = np.arange(cols.size)
        try:
            start, stop = self.indptr[rows], self.indptr[rows + 1]
            counts = stop - start
            total = int(counts.sum())
            k = (np.repeat(start - (np.cumsum(counts) - counts), counts)
                 + np.arange(total, dtype=np.int64))
            at = pos[self.indices[k]]
            keep = at >= 0
            out = np.zeros((rows.size, cols.size))
            out[np.repeat(np.arange(rows.size), counts)[keep], at[keep]] = self.data[k[keep]]
            return out
        finally:
            pos[cols] = -1


def _block(J, rows, cols):
    return J.block(rows, cols)


class _Topology:
    """What :func:`local_nodes` reads of the network's structure, made once
    per Assembly (its topology is fixed; :meth:`Assembly.replace` changes
    numbers only) as Python lists and dicts: the node of each across
    unknown, each component instance's equations, own unknowns (the flows at
    its terminals, its locals) and across unknowns, the instances whose
    across unknowns are all one node's, the owner of each own unknown, and
    per node its rows, across unknowns and components (on first use)."""

    def __init__(self, asm):
        na = self.na = asm.n_across
        n = asm.n
        # the node of each across unknown
        node_of_col = np.full(na, -1, dtype=np.int64)
        for arr in asm.node_across.values():
            have = arr >= 0
            node_of_col[arr[have]] = np.flatnonzero(have)
        self.node_of_col = node_of_col.tolist()
        # each component instance: its group and index there, its columns;
        # the owner of each own unknown; the instances whose across unknowns
        # are all one node's (a Python loop: a few entries per instance, made
        # once, where NumPy's calls per group cost more on small networks)
        owner = [-1] * n
        self.inst = inst = []         # (group, index in the group)
        self.cols = cols = []         # (the group's columns as lists, index)
        self.single = single = []     # (instance, node): across unknowns all one node's
        node_of = self.node_of_col
        for g in asm.groups:
            listed = np.asarray(g.col, dtype=np.int64).tolist()
            if not listed or not listed[0]:
                continue
            base = len(inst)
            inst.extend(zip(repeat(g), range(g.n)))
            cols.extend(zip(repeat(listed), range(g.n)))
            for k, row in enumerate(listed, base):
                at, one = None, True
                for c in row:
                    if c >= na:
                        owner[c] = k
                    elif at is None:
                        at = node_of[c]
                    elif node_of[c] != at:
                        one = False
                if one and at is not None and at >= 0:
                    single.append((k, at))
        self.owner = owner
        order = np.argsort(asm.through_rows, kind="stable")
        t_rows, t_cols = asm.through_rows[order], asm.through_cols[order]
        self.t_rows = t_rows
        self.t_cols = t_cols.tolist()
        self.t_owner = [owner[c] for c in self.t_cols]
        # each node's rows and across unknowns (all quantities), owners: on first use
        self._across = list(asm.node_across.values())
        self._rows = list(asm.node_rows.values())
        self._owners, self._own, self._acr = {}, {}, {}
        # the mass balance row of each own flow unknown (its terminal's node)
        m_of = asm.node_rows.get("massflow")
        m_rows = ({} if m_of is None else
                  {r: j for j, r in enumerate(m_of.tolist()) if r >= 0})
        self.node_of_flow = {c: m_rows[r] for r, c in zip(t_rows.tolist(), self.t_cols)
                             if r in m_rows}

    def rows_of(self, k):
        """The equations of instance k."""
        g, i = self.inst[k]
        return list(range(g.r0 + i * g.neq, g.r0 + (i + 1) * g.neq))

    def own_of(self, k):
        """The own unknowns of instance k (the flows at its terminals, its locals)."""
        got = self._own.get(k)
        if got is None:
            listed, i = self.cols[k]
            na = self.na
            got = self._own[k] = [c for c in listed[i] if c >= na]
        return got

    def across_of(self, k):
        """The across unknowns of instance k."""
        got = self._acr.get(k)
        if got is None:
            listed, i = self.cols[k]
            na = self.na
            got = self._acr[k] = [c for c in listed[i] if c < na]
        return got

    def node_rows(self, node):
        return [int(arr[node]) for arr in self._rows if arr[node] >= 0]

    def node_across(self, node):
        return [int(arr[node]) for arr in self._across if arr[node] >= 0]

    def owners_at(self, node):
        """The instances whose flows enter node's balances."""
        got = self._owners.get(node)
        if got is None:
            out = set()
            t_rows, t_owner = self.t_rows, self.t_owner
            for r in self.node_rows(node):
                a, b = np.searchsorted(t_rows, [r, r + 1]).tolist()
                out.update(t_owner[a:b])
            out.discard(-1)
            got = self._owners[node] = frozenset(out)
        return got


def _topology(asm):
    """The :class:`_Topology` of ``asm``, made on first use."""
    got = asm.__dict__.get("_source_topology")
    if got is None:
        got = asm.__dict__["_source_topology"] = _Topology(asm)
    return got


def local_nodes(asm, x, S, t=0.0, region=False, junctions=False):
    """The nodes without volume that carry a flow source (module docstring),
    read off the Jacobian at (x, S) at time t (0: the start) and dt = 0, as
    :class:`Local` s; [] where the network has no pressures or no mass
    balances at its nodes, or where the residual cannot be evaluated at x.
    With ``region``, each node's balance takes in the nodes without volume
    beyond it (junctions, up to the volumes and pressure sources that hold
    their pressures: their flows are what limits the node's), else their
    pressures are held as the other nodes'."""
    p_of = asm.node_across.get("pressure")
    m_of = asm.node_rows.get("massflow")
    if p_of is None or m_of is None:
        return []
    try:
        F = asm.residual(x, S, t, 0.0, jac=True)
    except (FluidError, ComponentError):
        return []
    if not np.isfinite(F).all():
        return []
    J = _Jacobian(asm)
    F = np.array(F, dtype=float)
    top = _topology(asm)
    inst, node_of_col = top.inst, top.node_of_col
    rows_of, own_of, across_of = top.rows_of, top.own_of, top.across_of
    node_rows, node_across, owners_at = top.node_rows, top.node_across, top.owners_at

    # the flow sources, by node
    sources = {}
    for k, node in top.single:
        own = own_of(k)
        if own and _regular(_block(J, rows_of(k), own)):
            sources.setdefault(node, []).append(k)
    if junctions:
        # the nodes without a flow source instead (each alone): junctions
        # whose pressure only their components' flows set
        sources = {j: [] for j in range(len(p_of)) if j not in sources}
    if not sources:
        return []
    t_rows, t_cols, owner = top.t_rows, top.t_cols, top.owner

    def volumeless(j):
        # node j has neither a volume nor a pressure source: with its pressure
        # held, its components and its other balances determine their unknowns
        comps_j = owners_at(j)
        r = [i for i in node_rows(j) if i != m_of[j]]
        c = [i for i in node_across(j) if i != p_of[j]]
        for k in comps_j:
            r += rows_of(k)
            c += own_of(k)
        return len(r) == len(c) and _regular(_block(J, r, c))

    node_of_flow = top.node_of_flow
    found = []
    state_rows = None         # the rows that read a continuous state (_state_rows)
    for node, srcs in sources.items():
        p, row = int(p_of[node]), int(m_of[node])
        if p < 0 or row < 0:
            continue
        comps = owners_at(node)
        rows = [r for r in node_rows(node) if r != row]
        cols = [c for c in node_across(node) if c != p]
        # dead ends behind the node's components: their balances are these
        # components' alone
        behind = {node_of_col[c] for k in comps for c in across_of(k)} - {node}
        ends, inside = [], {node}
        for j in sorted(behind):
            if j >= 0 and owners_at(j) <= comps:
                rows += node_rows(j)
                cols += node_across(j)
                inside.add(j)
                if p_of[j] >= 0:
                    ends.append(int(p_of[j]))
        base_rows, base_cols = list(rows), list(cols)
        for k in sorted(comps):
            rows += rows_of(k)
            cols += own_of(k)
        rows, cols = np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)
        if rows.size != cols.size or not _regular(_block(J, rows, cols)):
            continue          # a volume or a pressure source sets the pressure there
        if region:
            # the nodes without volume beyond, up to the volumes and pressure
            # sources that hold theirs (REGION_NODES at most)
            grown, g_comps, g_inside = _grow(node, comps, inside, owners_at, across_of,
                                             node_of_col, volumeless)
            if g_inside != inside:
                r2, c2 = list(base_rows), list(base_cols)
                for j in sorted(g_inside - inside):
                    r2 += node_rows(j)
                    c2 += node_across(j)
                for k in sorted(g_comps):
                    r2 += rows_of(k)
                    c2 += own_of(k)
                r2, c2 = np.array(r2, dtype=np.int64), np.array(c2, dtype=np.int64)
                if grown and r2.size == c2.size and _regular(_block(J, r2, c2)):
                    rows, cols, comps, inside = r2, c2, g_comps, g_inside
        # the sources' flows at the node, then the flows into the region's
        # other components from inside it (those at its edge: each one's
        # flows at its terminals inside, summed)
        a, b = np.searchsorted(t_rows, [row, row + 1]).tolist()
        members = [(k, [c]) for c in t_cols[a:b] for k in [owner[c]] if k in srcs]
        # then the flow sources at the region's other nodes: they feed (or
        # draw from) the same balance (a pump into a junction that a shut
        # valve parts from another pump's node: the two together are what
        # the one outlet does not pass)
        srcs = list(srcs)
        at_node = [node] * len(srcs)
        for j in sorted(inside - {node}):
            for k in sources.get(j, ()):
                if k in comps and k not in srcs:
                    srcs.append(k)
                    at_node.append(j)
                    members.append((k, [c for c in own_of(k)
                                        if node_of_flow.get(c, -1) in inside]))
        for k in sorted(comps - set(srcs)):
            at = {node_of_col[c] for c in across_of(k)}
            if at <= inside:
                continue          # wholly inside: passes nothing out of it
            members.append((k, [c for c in own_of(k) if node_of_flow.get(c, -1) in inside]))
        # an inertial tube inside: its equation ties its flow to its state,
        # which moves within any step (a rigid chamber of liquid, whose mass
        # state its equation, mdot = 0, does not read, is no such component)
        moving = [k for k in comps - set(srcs) if inst[k][0].ns and not asm.s_discrete[
            inst[k][0].s0 + inst[k][1] * inst[k][0].ns:
            inst[k][0].s0 + (inst[k][1] + 1) * inst[k][0].ns].all()]
        if moving and state_rows is None:
            state_rows = _state_rows(asm, x, S, t, F)
        dynamic = any(state_rows[rows_of(k)].any() for k in moving)
        found.append(Local(node, p, row, rows, cols,
                           [inst[k][0].comps[inst[k][1]] for k in srcs],
                           [rows_of(k)[0] for k in srcs], np.array(ends, dtype=np.int64),
                           [(inst[k][0].comps[inst[k][1]], c) for k, c in members],
                           sorted(inside), dynamic, at_node))
    return found


def _state_rows(asm, x, S, t, F):
    """Which rows of the residual F at (x, S, t, dt = 0) read a continuous
    state: those that change where every continuous state moves by a part
    in 1e6 (one residual evaluation; all rows where it fails)."""
    S = np.asarray(S, dtype=float)
    moved = S.copy()
    cont = ~np.asarray(asm.s_discrete, dtype=bool)
    moved[cont] += 1e-6 * np.abs(S[cont]) + 1e-9
    try:
        F2 = asm.residual(x, moved, t, 0.0)
    except (FluidError, ComponentError):
        return np.ones(F.size, dtype=bool)
    return np.asarray(F2, dtype=float) != F


def _grow(node, comps, inside, owners_at, across_of, node_of_col, volumeless):
    """The nodes without volume reachable from ``node`` through components
    (a breadth-first search that stops at nodes with a volume or a pressure
    source): (whether any was added, the components at them, the nodes)."""
    comps, inside = set(comps), set(inside)
    queue, added = sorted(comps), False
    while queue and len(inside) < REGION_NODES:
        k = queue.pop(0)
        for j in sorted({int(node_of_col[c]) for c in across_of(k)} - inside):
            if j < 0 or not volumeless(j):
                continue
            inside.add(j)
            added = True
            new = owners_at(j) - comps
            comps |= new
            queue.extend(sorted(new))
    return added, comps, inside


class _Balance:
    """The mass balance of one :class:`Local` node as a function of its
    pressure: g(p) = the sum of the flows into its components (its
    conservation row's residual), the other unknowns of ``local.cols``
    solved for at each p, the rest of x held."""

    def __init__(self, asm, local, x, S, atol, stats, t=0.0):
        self.asm, self.local, self.S, self.stats, self.t = asm, local, S, stats, t
        self.x = x.copy()
        # the node's other balances (energy) and across unknowns (its
        # temperature) held: where its mass does not balance (every trial
        # pressure but the root), its energy balance has no physical
        # solution (a source delivering gas at the node's own temperature:
        # (mdot_in - mdot_out) h(T) = 0), and the search would go where it
        # takes the temperature (a pump into a check valve near cracking,
        # adiabatic: 498 K, past air's table, at 111 kPa, and the start was
        # refused where it balances at 111.8 kPa)
        node = local.node
        held_rows = {int(a[node]) for a in asm.node_rows.values() if a[node] >= 0} - {local.row}
        held_cols = {int(a[node]) for a in asm.node_across.values() if a[node] >= 0} - {local.p}
        rows, cols = local.rows, local.cols
        if held_rows and held_cols and len(held_rows) == len(held_cols):
            rows = rows[~np.isin(rows, list(held_rows))]
            cols = cols[~np.isin(cols, list(held_cols))]
        self.rows, self.cols = rows, cols
        self.atol = np.broadcast_to(np.asarray(atol, dtype=float), (asm.n,))[cols]
        # absolute pressures and temperatures among the unknowns: each update
        # of theirs is clipped to [-50 %, +100 %] of their value (as Newton
        # clips node temperatures)
        q = np.asarray(asm.x_quantity, dtype=object)[cols]
        self.positive = np.flatnonzero((q == "pressure") | (q == "temperature"))
        #: the region's other node pressures among them: each trial starts
        #: them shifted by the node's change of pressure from the last
        #: solved point (its differences, which set a liquid's flows, kept:
        #: from 1 atm to a table's edge at 20 MPa a trial then takes 2-3
        #: iterations, not 8-11), and from where they were where that fails
        self.shifted = cols[q == "pressure"]

    #: the last FluidError met at a trial pressure (a fluid's range left), or None
    range_error = None

    def _eval(self, x):
        self.stats.residual_evaluations += 1
        self.stats.jacobian_evaluations += 1
        try:
            F = self.asm.residual(x, self.S, self.t, 0.0, jac=True)
        except FluidError as err:
            self.range_error = err
            return None, None
        except ComponentError:
            return None, None
        if not np.isfinite(F).all():
            return None, None
        return F, _Jacobian(self.asm)

    #: g at the last pressure solved for (:meth:`__call__`)
    g = None

    def __call__(self, p):
        """(g(p), dg/dp), with self.x the point solved for at p (and self.g
        its g); None where the solve fails (a fluid's range left, a singular
        block, no convergence)."""
        loc = self.local
        self.range_error = None
        x = self.x.copy()
        shift = p - x[loc.p]
        if shift != 0.0 and self.shifted.size:
            # the region's other pressures shifted along first, then from
            # where they were where that fails: a node behind a check valve
            # in the region, shifted along, takes the valve to a side the
            # inner solve does not come back from (a pump reversing into a
            # shut valve's leak, balanced at 2 MPa: found only from there)
            moved = x.copy()
            moved[self.shifted] += shift
            got = self._solve(moved, p, INNER_SHIFTED)
            if got is not None:
                return got
            self.range_error = None
        return self._solve(x, p)

    def _solve(self, x, p, iterations=INNER_ITERATIONS):
        """:meth:`__call__`'s solve from the unknowns x (a copy, changed), in
        at most ``iterations`` Newton iterations."""
        loc = self.local
        x[loc.p] = p
        x[loc.ends] = p
        rows, cols, atol, pos = self.rows, self.cols, self.atol, self.positive
        for _ in range(iterations):
            F, J = self._eval(x)
            if F is None:
                return None
            A = _block(J, rows, cols)
            try:
                du = -np.linalg.solve(A, F[rows])
            except np.linalg.LinAlgError:
                return None
            if not np.isfinite(du).all():
                return None
            if (np.abs(du) <= atol + INNER_RTOL * np.abs(x[cols])).all():
                # the balance and its slope along the solution at p:
                # dg/dp = J[row, p] - J[row, cols] A^-1 J[rows, p]
                j_row = _block(J, [loc.row], np.append(cols, loc.p))[0]
                dp = np.linalg.solve(A, _block(J, rows, [loc.p])[:, 0])
                x[cols] += du
                self.x = x
                self.g = float(F[loc.row] + j_row[:-1] @ du)
                return self.g, float(j_row[-1] - j_row[:-1] @ dp)
            if pos.size:
                v = x[cols[pos]]
                du[pos] = np.minimum(np.maximum(du[pos], -0.5 * v), v)
            x[cols] += du
        return None


def _search(bal, p0):
    """The pressure that balances ``bal`` (:class:`_Balance`) nearest p0 in
    the direction its balance points (up where the components take less
    than the source gives, down where they take more): ('root', p) with
    bal.x solved there; ('above', p) or ('below', p) where none lies up to
    PRESSURE_CAP or down to PRESSURE_FLOOR, or to the edge of a fluid's
    range (p: the last pressure solved for; with the edge, bal.range_error
    says what lies past it); None where a trial pressure cannot be solved
    for otherwise."""
    at = bal(p0)
    if at is None:
        return None
    g0, slope = at
    if g0 == 0.0:
        return "root", p0
    up = g0 < 0.0
    p_prev, g_prev = p0, g0
    factor, edge = MARCH, None
    for _ in range(MARCH_TRIALS):
        if up and p_prev >= PRESSURE_CAP:
            return "above", p_prev
        if not up and p_prev <= PRESSURE_FLOOR:
            return "below", p_prev
        p = min(p_prev * factor, PRESSURE_CAP) if up else max(p_prev / factor, PRESSURE_FLOOR)
        at = bal(p)
        if at is None and edge is None and _edge_between(bal.range_error, p_prev, p):
            # past a fluid's pressure range: its edge tried next (one trial
            # where narrowing the march towards it took ~10)
            edge = bal.range_error
            p = edge.limit
            at = bal(p)
            if at is not None and not ((at[0] >= 0.0) if up else (at[0] <= 0.0)):
                bal.range_error = edge
                return ("above" if up else "below"), p
        if at is None:
            if bal.range_error is None:
                return None
            # past a fluid's range: closer to its edge, down to 0.1 % of it
            edge = bal.range_error
            factor = math.sqrt(factor)
            if factor < 1.001:
                bal.range_error = edge
                return ("above" if up else "below"), p_prev
            continue
        g, slope = at
        if (g >= 0.0) if up else (g <= 0.0):
            break
        p_prev, g_prev = p, g
        factor = min(factor * factor, MARCH)
    else:
        return None
    # a bracket [a, b] with g(a) < 0 <= g(b) or the reverse: safeguarded Newton
    a, b = (p_prev, p) if p_prev < p else (p, p_prev)
    ga = g_prev if a == p_prev else g
    if g == 0.0:
        return "root", p
    for _ in range(SEARCH_ITERATIONS):
        step = -g / slope if slope != 0.0 and math.isfinite(slope) else math.nan
        q = p + step
        if not a < q < b:
            # bisection, geometric while the bracket spans more than a factor 4
            q = math.sqrt(a * b) if b > 4.0 * a else 0.5 * (a + b)
        at = bal(q)
        if at is None:
            return None
        gq, slope = at
        if gq == 0.0 or abs(q - p) <= SEARCH_RTOL * q:
            return "root", q
        if (gq < 0.0) == (ga < 0.0):
            a, ga = q, gq
        else:
            b = q
        p, g = q, gq
        if b - a <= SEARCH_RTOL * b:
            return "root", q
    return "root", p


def balanced_start(asm, x, S, atol, stats, locals_=None):
    """A start for the consistent point at t = 0 with each node without
    volume that carries a flow source at the pressure that balances its
    flows (module docstring), the other nodes' pressures as in x; and a
    failed Outcome that refuses the run where a node has no such pressure
    between PRESSURE_FLOOR and PRESSURE_CAP (else None). The start is None
    where there is no such node, or none could be solved for.

    ``atol``: the absolute tolerances of the unknowns (Newton's), for the
    solves at each trial pressure; ``stats``: their residual evaluations are
    counted there."""
    if locals_ is None:
        locals_ = local_nodes(asm, x, S)
    x = x.copy()
    moved = False
    for loc in locals_:
        bal = _Balance(asm, loc, x, S, atol, stats)
        found = _search(bal, float(x[loc.p]))
        if found is None:
            continue
        kind, p = found
        if kind == "root":
            x, moved = bal.x, True
            continue
        flows = [float(bal.x[c].sum()) for _, c in loc.members]
        why, first = refusal(asm, loc, kind, p, bal.range_error, flows)
        return None, Outcome(False, x, 0, why, loc.source_rows[first], unknown=loc.p)
    return (x if moved else None), None


def refusal(asm, loc, kind, p, edge, flows=None):
    """The reason a run is refused where node ``loc`` has no balancing
    pressure up to (``kind`` 'above') or down to ('below') ``p``, and the
    index (into ``loc.sources``) of the first source it names; ``edge``: the
    FluidError past p, where a fluid's range ends there; ``flows``: as
    :func:`source_names`'."""
    names, several, picked = source_names(loc, flows, kind == "below")
    node = asm.nodes[loc.source_nodes[picked[0]]].name
    where = "" if edge is None else f", where the fluid's range ends ({edge})"
    # (the wording avoids 'choked': a failure that says so reads as a stop on
    # a gas law's limit, which this is not)
    why = ("(closed, at rest, dead ends, or a gas's flow at its sonic limit); give the "
           "node a volume (a Container), or ")
    if kind == "above":
        verb = "push" if several else "pushes"
        return (f"no consistent start at t = 0: {names} {verb} more into {node}, a node "
                f"without volume, than the components there pass at any pressure up to "
                f"{p:.4g} Pa{where} {why}outlets that pass the flow"), picked[0]
    verb = "draw" if several else "draws"
    return (f"no consistent start at t = 0: {names} {verb} more from {node}, a node "
            f"without volume, than the components there supply at any pressure down to "
            f"{p:.4g} Pa{where} {why}inlets that supply the flow"), picked[0]


def source_names(loc, flows=None, draw=False):
    """The flow sources of :class:`Local` ``loc`` that a refusal names, as
    (text: "A", "A and B", "A, B and C"; whether they are several, the
    verb's number; their indices into ``loc.sources``). With ``flows`` (each
    of ``loc.members``' flow into it from the node: a source that pushes
    into the node has a negative one), those that push (``draw``: draw)
    only: a source the other way is among what passes the flow (a pump
    drawing from a junction where another pushes more), one that passes
    none is no cause (a rigid chamber of liquid, whose flow, zero, its
    node's state sets: a flow source to the balance); all where none
    does."""
    picked = list(range(len(loc.sources)))
    if flows is not None:
        way = [i for i in picked if (flows[i] > 0.0 if draw else flows[i] < 0.0)]
        picked = way or picked
    names = [loc.sources[i].describe() for i in picked]
    text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return text, len(names) > 1, picked


def above_cap(asm, x):
    """Whether a node's absolute pressure in x exceeds PRESSURE_CAP."""
    cols = asm.__dict__.get("_node_pressures")
    if cols is None:
        p_of = asm.node_across.get("pressure")
        cols = asm._node_pressures = (np.zeros(0, dtype=np.int64) if p_of is None
                                      else p_of[p_of >= 0])
    return bool(cols.size) and float(x[cols].max()) > PRESSURE_CAP


def dead_end_start(asm, x):
    """A start for the consistent point at t = 0 with each dead end at the
    pressure of the node it hangs from: x with the pressure of every node
    whose components are all two-ports (each joins it to one other node)
    and that leads nowhere but to such nodes (a dead end; a chain or tree of
    them) set to the pressure of the node the dead ends hang from; None
    where there is none, or all are at it already.

    At rest nothing flows into a dead end, so its pressure is its
    neighbour's (a two-port passes nothing at equal pressures). Started at
    another pressure (1 atm where none is given), a gas restriction in front
    of it may be choked there (a Cd orifice or a check valve from a 2.5 bar
    container to a dead end at 1 atm: the pressure ratio 0.41 is below the
    critical 0.528), and a choked flow does not depend on its outlet's
    pressure: the dead end's column of the Jacobian is zero (or a leak's
    1e-14 of the others), and Newton stops on a singular Jacobian there.
    Read off the topology alone (the components at each node and the nodes
    of their across unknowns), for
    :meth:`softflow.solve.integrator.Integrator._solve_initial`, where the
    start from the initial values failed."""
    p_of = asm.node_across.get("pressure")
    if p_of is None:
        return None
    top = _topology(asm)
    node_of, across_of, owners_at = top.node_of_col, top.across_of, top.owners_at
    p_list = p_of.tolist()
    # the nodes whose components are all two-ports: their distinct other nodes
    nbrs = {}
    for j, pj in enumerate(p_list):
        if pj < 0:
            continue
        comps = owners_at(j)
        if not comps:
            continue
        others = set()
        for k in comps:
            at = {node_of[c] for c in across_of(k)}
            if len(at) != 2 or j not in at:
                break
            (o,) = at - {j}
            if o < 0 or p_list[o] < 0:
                break
            others.add(o)
        else:
            nbrs[j] = others
    # dead ends: pruned as leaves, each hanging from its one other neighbour
    left = {j: set(o) for j, o in nbrs.items()}
    queue = sorted(j for j, o in left.items() if len(o) == 1)
    parent, order = {}, []
    while queue:
        j = queue.pop(0)
        if j in parent or len(left[j]) != 1:
            continue              # (a tree of dead ends with nothing it hangs from)
        (r,) = left[j]
        parent[j] = r
        order.append(j)
        if r in left:
            left[r].discard(j)
            if len(left[r]) == 1 and r not in parent:
                queue.append(r)
    if not order:
        return None
    out = x.copy()
    for j in reversed(order):     # each node's parent before it
        out[p_list[j]] = out[p_list[parent[j]]]
    return None if np.array_equal(out, x) else out


# -- the same balance at a step that cannot be taken ------------------------------------
@dataclass
class Unbalanced:
    """A node without volume whose flow source no pressure balances at a
    state (:func:`unbalanced`): ``kind`` 'above' (the source pushes more than
    the node's components pass at any pressure up to ``p``) or 'below' (it
    draws more than they supply at any pressure down to ``p``); ``flows``: the
    flow of each of :attr:`Local.members` into the node [kg/s] at ``p`` (where
    solved there, else at the state's pressure); ``edge``: the FluidError past
    p where a fluid's range ends there, else None; ``g``: the balance there
    (negative: the source pushes more than they pass; positive: it draws
    more than they supply), ``at``: the unknowns solved for there (a start
    for the balance asked again at p, :func:`balance_at`)."""

    local: Local
    kind: str
    p: float
    flows: list
    edge: object = None
    g: float = math.nan
    at: object = None


def _edge_between(err, a, b):
    """Whether the FluidError ``err`` (or None) names a fluid's pressure edge
    strictly between pressures a and b."""
    limit = getattr(err, "limit", None)
    return (limit is not None and getattr(err, "quantity", None) == "pressure"
            and min(a, b) < limit < max(a, b))


def _reach(bal, p0):
    """:func:`_search`'s answer without the root where there is one: ('root',
    None) where a pressure between p0 and the limit the balance points to
    (PRESSURE_CAP or PRESSURE_FLOOR) balances; ('above' | 'below', p) where
    none does; None where p0 cannot be solved for. Tries the limit first (a
    diagnosis needs only the sign there: two trial pressures where the march
    takes ~17), and marches (:func:`_search`) only where the limit lies past
    a fluid's range; None where the limit cannot be solved for otherwise
    (the marching would cost ~100 residual evaluations for a diagnosis that,
    in successful runs, finds nothing)."""
    at = bal(p0)
    if at is None:
        return None
    g0 = at[0]
    if g0 == 0.0:
        return "root", None
    up = g0 < 0.0
    at = bal(PRESSURE_CAP if up else PRESSURE_FLOOR)
    if at is not None:
        g = at[0]
        if (g >= 0.0) if up else (g <= 0.0):
            return "root", None
        return ("above" if up else "below"), (PRESSURE_CAP if up else PRESSURE_FLOOR)
    if bal.range_error is None:
        return None       # not solved there: no answer (a diagnosis only)
    edge = bal.range_error
    if _edge_between(edge, p0, PRESSURE_CAP if up else PRESSURE_FLOOR):
        # past a fluid's pressure range: the sign at its edge, or just inside
        # it where another node of the region lies past it at the edge
        # (settings.EDGE_BACKOFF; those that would leave that node past it
        # again, by how far it lay from the trial pressure, skipped: a pump
        # into two water nodes 1.2 MPa apart below a table's 20 MPa, 57 -> 45
        # residual evaluations for its refusal at t = 0)
        ahead = 0.0
        for back in (0.0,) + EDGE_BACKOFF:
            p = edge.limit * (1.0 - back if up else 1.0 + back)
            if not (p > p0 if up else p < p0):
                break
            if ahead > 0.0 and ((p + ahead >= edge.limit) if up
                                else (p - ahead <= edge.limit)):
                continue
            at = bal(p)
            if at is not None:
                if (at[0] >= 0.0) if up else (at[0] <= 0.0):
                    return "root", None
                bal.range_error = edge
                return ("above" if up else "below"), p
            past = bal.range_error
            if (past is not None and past.limit == edge.limit
                    and past.quantity == edge.quantity and past.value is not None):
                ahead = max(ahead, (past.value - p) if up else (p - past.value))
    # past a fluid's range: marching to its edge, each trial from the last
    found = _search(bal, p0)
    return None if found is None else (("root", None) if found[0] == "root" else found)


def balance_at(asm, loc, x, S, t, p, atol, stats, start=None):
    """The mass balance of node ``loc`` (:class:`_Balance`: the flows into
    it, the other unknowns of its region solved for) at pressure ``p`` and
    the state (x, S) at time t; None where p cannot be solved for.
    ``start``: unknowns whose region's values the solve starts from (an
    :class:`Unbalanced`'s ``at``, solved at p for another state: 2-3
    iterations where from x's a jump to 1 GPa took ~24)."""
    bal = _Balance(asm, loc, x, S, atol, stats, t)
    if start is not None:
        bal.x[bal.cols] = start[bal.cols]
        bal.x[loc.p] = start[loc.p]          # (the shift to p from there)
    at = bal(p)
    return None if at is None else at[0]


def unbalanced(asm, x, S, t, atol, stats, locals_=None, first=False):
    """The nodes without volume that carry a flow source and that no pressure
    between PRESSURE_FLOOR and PRESSURE_CAP balances at the state (x, S) at
    time t, as :class:`Unbalanced` s (the other nodes' pressures held, as a
    step short enough holds a volume's; the node's components' flows and
    discrete modes as the state has them: a valve closed stays closed). For a
    step that cannot be taken (:mod:`softflow.solve.culprit`): what the
    consistent start refuses at t = 0 (:func:`balanced_start`), met later,
    when a valve closes or a source's signal changes. ``atol``, ``stats``: as
    :func:`balanced_start`'s; ``first``: the first found only (the rest not
    asked)."""
    if locals_ is None:
        locals_ = local_nodes(asm, x, S, t, region=True)
    found = []
    for loc in locals_:
        bal = _Balance(asm, loc, x, S, atol, stats, t)
        reached = _reach(bal, float(x[loc.p]))
        if reached is None or reached[0] == "root":
            continue
        kind, p = reached
        flows = [float(bal.x[c].sum()) for _, c in loc.members]
        found.append(Unbalanced(loc, kind, p, flows, bal.range_error, bal.g, bal.x.copy()))
        if first:
            break
    return found


def rebalanced(asm, x, S, t, atol, stats, locals_):
    """A start for a step's solve that failed: x with each node in
    ``locals_`` (and the unknowns of its region) at the pressure that
    balances it at time t (:func:`_search` from its pressure in x, the other
    nodes' held, its components' unknowns solved there); None where none
    balances. What :func:`balanced_start` does for the consistent start, for
    a step: a pump whose draw steps up behind a check valve at rest, whose
    node's pressure Newton takes along the valve's closed slope (its
    leakage) to a root far below vacuum, where the valve opens 200 Pa below
    the point's pressure."""
    x = x.copy()
    moved = False
    for loc in locals_:
        bal = _Balance(asm, loc, x, S, atol, stats, t)
        p0 = float(x[loc.p])
        found = _search(bal, p0)
        if found is None or found[0] != "root":
            continue
        x, moved = bal.x, True
    return x if moved else None
