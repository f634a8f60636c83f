"""Assembly: the network compiled once into index maps and a sparsity pattern.

Unknowns x: one per node and across quantity (e.g. the node's pressure), one
per terminal through variable (the mass flow into the component there) and one
per algebraic local. States S are kept apart and eliminated per component
(backward Euler), so they never become unknowns of the linear solve.

Rows: one conservation equation per node and through quantity, then each group
of components' equations, contiguous per group.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial
from itertools import repeat
from operator import attrgetter, itemgetter

import numpy as np
from scipy.linalg.lapack import dgetrf as _getrf
from scipy.sparse import csc_matrix
from scipy.sparse.csgraph import connected_components, maximum_bipartite_matching
from scipy.sparse.linalg import splu

from ..constants import pressure_atmospheric
from ..fluids.base import FluidError
from ..network.system import NetworkError
from .compiled import function
from .discretize import step_functions
from .netcore import compiled_residual
from .settings import (
    DENSE_CHECK_MAX,
    NODE_DOT_MAX,
    REGULARITY_ANSWERS,
    SMALL_BLOCKS_MAX,
    SMALL_NUMBERING_MAX,
    UNROLL_MAX_GROUPS,
)
from .userkernel import UserKernel
from .validity import ComponentError, user_code_error


def _equilibrated(A):
    """A (CSC) with its rows, then its columns scaled to a largest magnitude of
    one, or None if a row or column is all zero. The arithmetic and the zeros
    dropped are those of ``diags(1/r) @ A @ diags(1/c)`` in SciPy, done on the
    arrays directly: the sparse-matrix products cost ~0.5 ms per check on a
    6-unknown scene, several times its whole compile otherwise."""
    A = csc_matrix(A)
    A.sum_duplicates()
    n_rows, n_cols = A.shape
    rows = A.indices
    cols = np.repeat(np.arange(n_cols), np.diff(A.indptr))
    r = np.zeros(n_rows)
    np.maximum.at(r, rows, np.abs(A.data))
    if (r == 0).any():
        return None
    data = (1.0 / r)[rows] * A.data
    c = np.zeros(n_cols)
    np.maximum.at(c, cols, np.abs(data))
    if (c == 0).any():
        return None
    data = data * (1.0 / c)[cols]
    keep = data != 0          # sparse products do not store the zeros they produce
    indptr = np.concatenate([[0], np.cumsum(np.bincount(cols[keep], minlength=n_cols))])
    return csc_matrix((data[keep], rows[keep], indptr), shape=A.shape)


def _is_regular(A):
    """Numerical regularity after row and column equilibration (rows of the
    Jacobian differ by many orders of magnitude: kg vs Pa)."""
    if A.shape[0] <= DENSE_CHECK_MAX:
        return _is_regular_dense(A.toarray())
    A = _equilibrated(A)
    if A is None:
        return False
    try:
        with np.errstate(all="ignore"):
            lu = splu(A, permc_spec="COLAMD")
    except RuntimeError:
        return False
    d = np.abs(lu.U.diagonal())
    return bool(d.size == 0 or d.min() > 1e-12)


def _structurally_regular(n, indices, indptr):
    """Whether the n x n pattern (CSC: row ``indices`` per column, ``indptr``)
    matches every row to a column of its own (a perfect matching: the pattern
    is structurally regular). Augmenting paths in Python: for a small network
    (~10 us) where SciPy's matching costs ~80 us with its sparse matrices."""
    cols_of_row = [[] for _ in range(n)]
    rows = indices.tolist()
    ptr = indptr.tolist()
    for c in range(n):
        for r in rows[ptr[c]:ptr[c + 1]]:
            cols_of_row[r].append(c)
    row_of = [-1] * n        # the row each column is matched to
    col_of = [-1] * n        # the column each row is matched to
    for r0 in range(n):
        for c in cols_of_row[r0]:          # a free column at once
            if row_of[c] < 0:
                row_of[c], col_of[r0] = r0, c
                break
        else:
            # an alternating path from r0 to a free column, searched depth first
            came = {}                      # column -> the row it was reached from
            stack = [r0]
            found = -1
            while stack and found < 0:
                r = stack.pop()
                for c in cols_of_row[r]:
                    if c in came:
                        continue
                    came[c] = r
                    if row_of[c] < 0:
                        found = c
                        break
                    stack.append(row_of[c])
            if found < 0:
                return False
            c = found
            while True:                    # flip the path's matches
                r = came[c]
                before = col_of[r]
                row_of[c], col_of[r] = r, c
                if r == r0:
                    break
                c = before
    return True


def _is_regular_dense(J):
    """:func:`_is_regular` for a small dense J: the same equilibration (rows,
    then columns, to a largest magnitude of one) and pivot test."""
    if not J.size:
        return True
    if J.shape == (1, 1):
        # scaled, a number is +-1 (regular) where it is finite and not 0
        a = float(J[0, 0])
        return a != 0.0 and math.isfinite(a)
    r = np.abs(J).max(axis=1)
    if not r.all():
        return False
    J = J / r[:, None]
    c = np.abs(J).max(axis=0)
    if not c.all():
        return False
    J = J / c
    # LAPACK's getrf, as scipy.linalg.lu_factor calls it, without its
    # wrappers and the warning it raises on an exact zero pivot (a 4 x 4
    # block: ~26 us, against ~47 us through lu_factor)
    lu, _, info = _getrf(J, overwrite_a=1)
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of getrf")
    # min |pivot| > 1e-12, pivot by pivot on Python floats (a NaN pivot fails
    # both ways: NumPy's min propagates it, and NaN > 1e-12 is False)
    return all(abs(u) > 1e-12 for u in lu.diagonal().tolist())


class _Answers:
    """A test's answers by the exact bytes of its arrays: the regularity tests of
    a network's compile (:meth:`Assembly._check_structure`,
    :meth:`Assembly.check_nonsingular`) are pure functions of the pattern and
    the Jacobian at the initial values, which a scene compiled again (a
    benchmark, a notebook run twice, sf.assess's runs) gives bit for bit. At
    most ``size`` answers, the oldest forgotten first; ``calls`` counts the
    tests made (for the tests)."""

    def __init__(self, test, size=REGULARITY_ANSWERS):
        self.test, self.size, self.known, self.calls = test, size, {}, 0

    def __call__(self, key, *args):
        known = self.known
        got = known.get(key)
        if got is None:
            self.calls += 1
            got = bool(self.test(*args))
            if len(known) >= self.size:
                try:        # (another thread may have forgotten it already)
                    del known[next(iter(known))]
                except (KeyError, RuntimeError, StopIteration):
                    pass
            known[key] = got
        return got


def _array_key(*arrays):
    """The exact key of arrays: each one's dtype, shape and bytes."""
    return tuple((a.dtype.str, a.shape, a.tobytes()) for a in arrays)


#: answers of _structurally_regular, by (n, indices, indptr)
_STRUCTURAL = _Answers(_structurally_regular)
#: answers of _is_regular_dense, by the dense Jacobian
_DENSE_REGULAR = _Answers(_is_regular_dense)


#: Parameters named (where a component has them) when its scale is extreme.
_SCALE_PARAMETERS = ("length", "diameter", "volume", "initial_volume", "compliance",
                     "capacitance", "K", "Cd", "C", "conductance", "closed_conductance")


def _check_fluids_at_nodes(asm, comps):
    """Components joined at one node must carry the same fluid (name and solute
    fraction; level and temperature may differ): a different one is an interface
    the network does not model, and its mass balance would mix two fluids."""
    fluids = set(map(id, map(getattr, comps, repeat("fluid"), repeat(None))))
    fluids.discard(id(None))
    if len(fluids) <= 1:
        return      # one fluid object everywhere (the common case): nothing can differ
    for nd in asm.nodes:
        seen = {}
        for t in nd.terminals:
            comp = t.component if hasattr(t, "component") else None
            fluid = getattr(comp, "fluid", None)
            if fluid is None:
                continue
            name = getattr(fluid, "name", repr(fluid))
            key = (name, getattr(getattr(fluid, "spec", None), "fraction", None),
                   bool(getattr(fluid, "compressible", True)))
            seen.setdefault(key, []).append(comp)
        if len(seen) > 1:
            parts = "; ".join(
                f"{', '.join(c.describe() for c in comps)}: {_fluid_name(comps[0].fluid)}"
                for comps in seen.values())
            raise NetworkError(
                f"different fluids meet at {nd.name}: {parts}. A node joins components of "
                "one fluid; give them the same fluid (a deliberate interface between two "
                "fluids needs a component that models it)")


def _fluid_name(fluid):
    frac = getattr(getattr(fluid, "spec", None), "fraction", None)
    return f"{fluid.name!r}" + (f" (fraction {frac:g})" if frac is not None else "")


class Group:
    """Components evaluated by one kernel call, and where they live in x, F, S and J."""

    def __init__(self, comps, kernel, update, pattern, neq, ns, has_states):
        self.comps = comps
        self.n = len(comps)
        self.kernel = kernel
        self.update = update
        self.pattern = pattern
        self.neq = neq
        self.ns = ns
        self.has_states = has_states
        self.begin = None  # begin_step(V, S) hook, or None
        self.switching = None  # switching(V, S): the discrete states' switching functions
        self.fold = None   # fold(V, S, k, rising): the pressure instance k snaps to at a fold
        self.regime = None  # regime(V): the piece of a piecewise law each instance is on
        self.kinks = None  # kinks(V): the side of the law's kinks each instance is on
        self.row = None    # a single user component's kernel (1-D calls), or None
        self.cls = self.params = None   # a library group's class and Params
        # its residual as an affine map of V (components.base.Affine), or None;
        # a library group's is made from cls and params on first use (affine)
        self._affine = None
        self.col = None  # (n, nv) global unknown index of each interface variable
        self.r0 = self.r1 = self.s0 = self.s1 = self.j0 = self.j1 = 0

    @property
    def affine(self):
        """The group's residual as an affine map of V (:class:`components.base.Affine`),
        or None: a library group's ``cls.affine(params)``, made on first use (only
        the per-group residual of a small network reads it, where the compiled
        one does not serve)."""
        got = self._affine
        if got is _UNMADE:
            got = self._affine = self.cls.affine(self.params)
        return got

    @affine.setter
    def affine(self, value):
        self._affine = value


#: Group._affine not yet made
_UNMADE = object()


def _group_failure(g, err, t):
    """The ComponentError for an exception from inside a library group's kernel
    (a user's input function or curve, typically): the component, or every
    component of the group where it is one of several."""
    if g.n == 1:
        c = g.comps[0]
        return user_code_error(err, c.describe(), c.label, "its equations", t)
    labels = [c.label for c in g.comps]
    return user_code_error(err, f"one of {_group_name(g)}", ", ".join(labels),
                           "its equations", t)


def _group_name(g):
    labels = [c.label for c in g.comps]
    shown = ", ".join(repr(lab) for lab in labels[:4]) + (", ..." if len(labels) > 4 else "")
    return f"{type(g.comps[0]).__name__} {shown}"


def _fluid_failure(g, err):
    """The FluidError ``err`` of group ``g``'s kernel, saying which components asked
    for the bad state (``component``: the label, where the group has one;
    ``components``: the labels of the group)."""
    out = FluidError(f"in {_group_name(g)}: {err}")
    out.quantity, out.limit, out.value = err.quantity, err.limit, err.value
    out.component = g.comps[0].label if len(g.comps) == 1 else None
    out.components = frozenset(c.label for c in g.comps)
    return out


#: What _library_group makes of a class's Params: Assembly.replace takes all of
#: them from a group made anew (one left behind would keep the old numbers).
_FROM_PARAMS = ("kernel", "update", "_affine", "begin", "switching", "fold", "regime",
                "kinks", "cls", "params")


def _library_group(cls, comps):
    P = cls.make_params(comps)
    if cls.kernel.__func__ is (_LIBRARY_KERNEL or _library_kernel()):
        kernel, update = step_functions(cls, P)     # rates and residuals (the rule)
    else:
        # a LibraryComponent subclass of a user's that writes its step equations
        # itself (kernel/update with the step, read by BDF as psi and c)
        kernel, update = partial(cls.kernel, P), partial(cls.update, P)
    g = Group(comps, kernel=kernel, update=update,
              pattern=cls.jac_pattern, neq=comps[0].n_equations, ns=len(cls.state_spec),
              has_states=bool(cls.state_spec))
    g.cls, g.params = cls, P      # the compiled network residual reads them (netcore)
    g._affine = _UNMADE           # cls.affine(P), on first use (Group.affine)
    sw = getattr(cls, "switching", None)
    if sw is not None and cls.discrete_states:
        g.switching = partial(sw, P)
    fold = getattr(cls, "fold_pressure", None)
    if fold is not None:
        g.fold = partial(fold, P)
    regime = getattr(cls, "regime", None)
    if regime is not None:
        g.regime = partial(regime, P)
    kinks = getattr(cls, "kinks", None)
    if kinks is not None:
        g.kinks = partial(kinks, P)
    # per-step coefficients (e.g. heat-transfer correlations), frozen over each step
    wants = getattr(cls, "wants_begin_step", None)
    if wants is not None and wants(P):
        g.begin = lambda V, S: cls.begin_step(P, V, S)
    return g


_LIBRARY_KERNEL = None


def _library_kernel():
    """``LibraryComponent.kernel``'s function (the rule of softflow.solve.discretize),
    imported once (the components import this package)."""
    global _LIBRARY_KERNEL
    if _LIBRARY_KERNEL is None:
        from ..components.base import LibraryComponent
        _LIBRARY_KERNEL = LibraryComponent.kernel.__func__
    return _LIBRARY_KERNEL


def _user_group(comp):
    uk = UserKernel(comp)
    g = Group([comp], kernel=uk.kernel, update=uk.update, pattern=uk.pattern,
              neq=uk.neq, ns=uk.ns, has_states=uk.ns > 0)
    g.row = uk    # one instance: the assembly may call its 1-D *_row methods
    return g


def _initial_states(c):
    """A component's states at t = 0, as floats in its state order."""
    vals = (c.initial_state_values() if c.vectorized
            else [sv.initial_value if sv.initial_value is not None else 0.0 for sv in c.states])
    return [float(v) for v in vals]


class _Names(Sequence):
    """Names of the unknowns or rows, for messages: spelled out on first use
    (tens of thousands of f-strings were a fifth of compiling a large network).
    A read-only sequence of str; pickles and copies as a list."""

    def __init__(self, make):
        self._make = make
        self._list = None

    def _names(self):
        if self._list is None:
            self._list = self._make()
            self._make = None
        return self._list

    def __getitem__(self, i):
        return self._names()[i]

    def __len__(self):
        return len(self._names())

    def __iter__(self):
        return iter(self._names())

    def index(self, value, *args):
        return self._names().index(value, *args)

    def __eq__(self, other):
        return list(self._names()) == (list(other) if isinstance(other, (Sequence,)) else other)

    def __reduce__(self):
        return (list, (self._names(),))

    def __repr__(self):
        return repr(self._names())


def _node_pairs(spec):
    """(node index, quantity) of each node unknown or row, in order, from
    ``spec``: the list itself, or (number of nodes, quantities of every node)."""
    if isinstance(spec, tuple):
        count, qs = spec
        return [(k, q) for k in range(count) for q in qs]
    return spec


def _unknown_names(asm, across_named, groups):
    """Names of the unknowns in x order: node across unknowns, then each group's
    interface variables that are not across ones (as compiled, g.iface)."""
    nodes = asm.nodes
    names = [f"{nodes[k].name} {q}" for k, q in _node_pairs(across_named)]
    for g in groups:
        for c, (iface, _) in zip(g.comps, g.iface):
            for term, v in iface:
                if v.role != "across":
                    where = f"{c.label}.{term}" if term else c.label
                    names.append(f"{where} {v.label}")
    return names


def _row_names(asm, node_through, groups):
    """Names of the rows: node conservation rows, then each group's equations."""
    nodes = asm.nodes
    names = [f"conservation of {q} at {nodes[k].name}" for k, q in _node_pairs(node_through)]
    for g in groups:
        for c in g.comps:
            for e in range(g.neq):
                names.append(f"equation {e} of {c.describe()}")
    return names


def _state_names(groups):
    return [f"{c.label} {sv.label}" for g in groups if g.ns for c in g.comps for sv in c.states]


class _Interfaces(Sequence):
    """A group's interfaces as compiled, per component: (its interface variables,
    its states), read from the compiled components on first use (a list per
    component was a tenth of compiling a large network). Pickles as a list."""

    def __init__(self, comps):
        self._comps = comps
        self._made = {}

    def __getitem__(self, i):
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self._comps)))]
        if i < 0:
            i += len(self._comps)
        out = self._made.get(i)
        if out is None:
            c = self._comps[i]
            out = self._made[i] = (c.interface_variables(), list(c.states))
        return out

    def __len__(self):
        return len(self._comps)

    def __reduce__(self):
        return (list, (list(self),))


class _Layout:
    """The interface every member of a library group shares: one slot per
    interface variable, (terminal label or None, terminal index or None,
    index in the terminal or among the locals, quantity, role); the
    (across, through) quantities of each terminal; and per terminal the
    members' variable lists, or None where every member holds the first
    one's (a class's shared interface)."""

    __slots__ = ("slots", "terminal_sigs", "lists", "first")

    def __init__(self, slots, terminal_sigs, lists, first):
        self.slots = slots
        self.terminal_sigs = terminal_sigs
        self.lists = lists
        self.first = first

    def values(self, comps):
        """(slot, initial value of that variable in each component: a list, or
        one value for all) per slot."""
        out = []
        for k, (term, ti, vi, _, _) in enumerate(self.slots):
            if ti is None:
                out.append((k, [c.locals[vi].initial_value for c in comps]))
            elif self.lists[ti] is None:
                out.append((k, self.first.terminals[ti].variables[vi].initial_value))
            else:
                out.append((k, [vs[vi].initial_value for vs in self.lists[ti]]))
        return out


def _group_layout(comps):
    """The shared :class:`_Layout` of a library group, or None where its members
    differ in their terminals' or locals' quantities and roles (numbered one
    by one then, as before)."""
    if len(comps) == 1:
        return _own_layout(comps[0])
    return _shared_layout(comps)


def _shared_layout(comps):
    """:func:`_group_layout` compared member by member (any group; a group of
    one takes :func:`_own_layout`, the same answer without comparing)."""
    first = comps[0]
    nt, nl = len(first.terminals), len(first.locals)
    term_lists = list(map(_terminals_of, comps))
    if set(map(len, term_lists)) != {nt} or set(map(len, map(_locals_of, comps))) != {nl}:
        return None
    slots, sigs, lists = [], set(), []
    for ti, t in enumerate(first.terminals):
        tv = t.variables
        kinds = [(v.quantity, v.role) for v in tv]
        terms = list(map(itemgetter(ti), term_lists))
        if set(map(_label_of, terms)) != {t.label}:
            return None
        vls = list(map(_variables_of, terms))
        others = [vs for vs in vls if vs is not tv]
        if others:
            # members with variables of their own (a volume's pressure): the
            # same quantities and roles, position by position
            if {len(vs) for vs in others} != {len(tv)}:
                return None
            for vi, kind in enumerate(kinds):
                if {(vs[vi].quantity, vs[vi].role) for vs in others} != {kind}:
                    return None
        lists.append(vls if others else None)
        for vi, v in enumerate(tv):
            slots.append((t.label, ti, vi, v.quantity, v.role))
        sigs.add((tuple(dict.fromkeys(q for q, r in kinds if r == "across")),
                  tuple(dict.fromkeys(q for q, r in kinds if r == "through"))))
    if nl:
        kinds = [(v.quantity, v.role) for v in first.locals]
        for ls in [c.locals for c in comps]:
            if [(v.quantity, v.role) for v in ls] != kinds:
                return None
        for vi, v in enumerate(first.locals):
            slots.append((None, None, vi, v.quantity, v.role))
    return _Layout(slots, sigs, lists, first)


def _own_layout(comp):
    """:func:`_group_layout` of a group of one component (nothing to compare: its
    own interface, slot by slot)."""
    slots, sigs = [], set()
    for ti, t in enumerate(comp.terminals):
        tv = t.variables
        label = t.label
        for vi, v in enumerate(tv):
            slots.append((label, ti, vi, v.quantity, v.role))
        sigs.add((tuple(dict.fromkeys(v.quantity for v in tv if v.role == "across")),
                  tuple(dict.fromkeys(v.quantity for v in tv if v.role == "through"))))
    for vi, v in enumerate(comp.locals):
        slots.append((None, None, vi, v.quantity, v.role))
    return _Layout(slots, sigs, [None] * len(comp.terminals), comp)


_terminals_of = attrgetter("terminals")
_locals_of = attrgetter("locals")
_label_of = attrgetter("label")
_variables_of = attrgetter("variables")


def _number_small(g, slots, at, t_start, node_of, across_of, row_of, quantities,
                  through_rows, through_cols):
    """A library group's unknowns numbered as Assembly.__init__ numbers them with
    NumPy (``g.col``; its node rows and columns appended to ``through_rows``
    and ``through_cols``; its own unknowns' quantities to ``quantities``), on
    Python lists: a small network's groups of one or a few members cost ~5 us
    each this way against ~15 us in NumPy calls. The lists: each component's
    first terminal, each terminal's node, and per quantity each node's across
    unknown and conservation row."""
    own = [k for k, slot in enumerate(slots) if slot[4] != "across"]
    n_own = len(own)
    base = len(quantities)
    if own:
        quantities += [slots[k][3] for k in own] * g.n
    across = [(k, across_of[q], ti) for k, (_, ti, _, q, role) in enumerate(slots)
              if role == "across"]
    through = [(k, row_of[q], ti) for k, (_, ti, _, q, role) in enumerate(slots)
               if role == "through"]
    cols, trows, tcols = [], [], []
    row = [0] * len(slots)
    for i, pos in enumerate(at):
        first = t_start[pos]
        at_own = base + i * n_own
        for j, k in enumerate(own):
            row[k] = at_own + j
        for k, nodes, ti in across:
            row[k] = nodes[node_of[first + ti]]
        for k, rows, ti in through:     # component by component, in interface order
            trows.append(rows[node_of[first + ti]])
            tcols.append(row[k])
        cols.append(row[:])
    g.col = np.array(cols, dtype=np.int64).reshape(g.n, len(slots))
    if through:
        through_rows.append(np.array(trows, dtype=np.int64))
        through_cols.append(np.array(tcols, dtype=np.int64))


def _terminal_sig(t):
    return (tuple(dict.fromkeys(v.quantity for v in t.variables if v.role == "across")),
            tuple(dict.fromkeys(v.quantity for v in t.variables if v.role == "through")))


class Assembly:
    """Compiled network: evaluates residuals F(x) and Jacobian values for given
    states, time and step, with no knowledge of components beyond their kernels."""

    def __init__(self, system, *, allow_unconnected=False):
        comps = list(system.components)
        if not comps:
            raise NetworkError("System is empty: add components before simulating")
        tcount = list(map(len, map(_terminals_of, comps)))
        n_terminals = sum(tcount)
        unconnected = system.unconnected_terminals(n_terminals)
        if unconnected and not allow_unconnected:
            names = ", ".join(t.name for t in unconnected)
            raise NetworkError(
                f"unconnected terminal(s): {names}. Connect them, or pass "
                "allow_unconnected=True to treat them as closed ends (zero flow)")
        node_of, n_nodes = system.terminal_nodes(n_terminals)
        # the nodes' terminals, as Node objects on first use (self.nodes)
        self._node_comps, self._node_of, self._nodes = comps, node_of, None
        self.n_nodes = int(n_nodes)     # (nodes: the Node objects, made on first use)
        _check_fluids_at_nodes(self, comps)

        # groups, in first-appearance order (with each member's position in comps)
        groups, keyed = [], {}
        for pos, c in enumerate(comps):
            if c.vectorized:
                key = c.group_key()
                if c._thermal is not None:   # thermal variants group apart
                    key = (c.kernel_class(), key)
                if key not in keyed:
                    keyed[key] = ([], [])
                    groups.append(("lib", key))
                members, at = keyed[key]
                members.append(c)
                at.append(pos)
            else:
                groups.append(("user", (c, pos)))
        self.groups = []
        group_pos = []
        for kind, item in groups:
            if kind == "lib":
                members, at = keyed[item]
                self.groups.append(_library_group(members[0].kernel_class(), members))
                group_pos.append(at)
            else:
                self.groups.append(_user_group(item[0]))
                group_pos.append([item[1]])
        #: component label -> (its Group, its index in the group)
        self.where = {}
        for g in self.groups:
            self.where.update(zip(map(_label_of, g.comps), zip(repeat(g), range(g.n))))
        # each group's interface as compiled (a later thermal or isothermal compile
        # of the same components changes their variables, not this Assembly's
        # results); per component on first use (_Interfaces)
        layouts = []
        for g in self.groups:
            g.iface = _Interfaces(list(g.comps))
            layouts.append(_group_layout(g.comps) if g.row is None else None)
        self._layouts = layouts

        # unknowns and rows are numbered here; their names (for messages) are
        # spelled out on first use (_Names), from the lists of what they name
        across_of, row_of, across_named, node_through = self._node_numbering(layouts, n_nodes)
        #: per quantity, an array over the nodes of the node's across unknown
        #: (``node_across['pressure'][k]``) and of its conservation row
        #: (``node_rows['massflow'][k]``), -1 where the node has none
        self.node_across, self.node_rows = across_of, row_of
        if isinstance(across_named, tuple):      # (nodes, the quantities of each)
            quantities = list(across_named[1]) * across_named[0]
            self.n_node_rows = len(node_through[1]) * node_through[0]
            #: the quantity each node row conserves (massflow, energyflow)
            self.node_row_quantities = list(node_through[1]) * node_through[0]
        else:
            quantities = [q for _, q in across_named]
            self.n_node_rows = len(node_through)
            self.node_row_quantities = [q for _, q in node_through]
        #: node across unknowns (pressures, temperatures) are x[:n_across]
        self.n_across = len(quantities)

        # unknown indices per component interface variable: across ones at the
        # node of their terminal, the others numbered in turn, component by
        # component (one lookup per terminal; NumPy per library group)
        small = n_terminals <= SMALL_NUMBERING_MAX
        node_arr = None
        if small:       # the same numbers on Python ints (see _number_small)
            starts, first = [], 0
            for count in tcount:
                starts.append(first)
                first += count
            lists = (starts, list(node_of),
                     {q: a.tolist() for q, a in across_of.items()},
                     {q: a.tolist() for q, a in row_of.items()})
        else:
            tcount = np.array(tcount, dtype=np.int64)
            t_start = np.cumsum(tcount) - tcount
            node_arr = np.asarray(node_of, dtype=np.int64)
        through_rows, through_cols = [], []
        for g, layout, at in zip(self.groups, layouts, group_pos):
            if layout is None:
                if node_arr is None:
                    tcount = np.array(tcount, dtype=np.int64)
                    t_start = np.cumsum(tcount) - tcount
                    node_arr = np.asarray(node_of, dtype=np.int64)
                self._number_one_by_one(g, node_arr, t_start, at, across_of, row_of,
                                        quantities, through_rows, through_cols)
                continue
            if small:
                _number_small(g, layout.slots, at, *lists, quantities, through_rows,
                              through_cols)
                continue
            slots = layout.slots
            col = np.empty((g.n, len(slots)), dtype=np.int64)
            starts = t_start[at]
            own = [k for k, (_, _, _, q, role) in enumerate(slots) if role != "across"]
            base = len(quantities)
            if own:
                col[:, own] = base + np.arange(g.n * len(own)).reshape(g.n, len(own))
                quantities += [slots[k][3] for k in own] * g.n
            thr = []
            for k, (_, ti, _, q, role) in enumerate(slots):
                if role == "across":
                    col[:, k] = across_of[q][node_arr[starts + ti]]
                elif role == "through":
                    thr.append((k, row_of[q][node_arr[starts + ti]]))
            if thr:     # component by component, in interface order
                through_rows.append(np.stack([r for _, r in thr], axis=1).ravel())
                through_cols.append(col[:, [k for k, _ in thr]].ravel())
            g.col = col
        self.n = len(quantities)
        self.x_names = _Names(partial(_unknown_names, self, across_named, self.groups))
        self.x_quantity = quantities
        # the unknowns grouped by quantity (Newton's tolerances and the integrators'
        # error weights scale each by its quantity's largest magnitude)
        self.q_names = sorted(set(quantities))
        q_index = {q: k for k, q in enumerate(self.q_names)}
        q_id = [q_index[q] for q in quantities]
        self.q_id = np.array(q_id, dtype=np.int64)
        if small:      # the unknowns by quantity, stably, and where each quantity starts
            self.q_order = np.array(sorted(range(len(q_id)), key=q_id.__getitem__),
                                    dtype=np.intp)
            count = [0] * len(self.q_names)
            for k in q_id:
                count[k] += 1
            first, at = [], 0
            for c in count:
                first.append(at)
                at += c
            self.q_starts = np.array(first, dtype=np.intp)
        else:
            self.q_order = np.argsort(self.q_id, kind="stable")
            self.q_starts = np.searchsorted(self.q_id[self.q_order],
                                            np.arange(len(self.q_names)))
        self.through_rows = (np.concatenate(through_rows).astype(np.int64) if through_rows
                             else np.zeros(0, dtype=np.int64))
        self.through_cols = (np.concatenate(through_cols).astype(np.int64) if through_cols
                             else np.zeros(0, dtype=np.int64))
        through_rows = self.through_rows
        self.x0 = self._initial_unknowns(compiled=True)

        # rows, states and Jacobian slots per group
        r = self.n_node_rows
        s = 0
        j = len(through_rows)
        s_quantity, S0, s_discrete = [], [], []
        self.row_names = _Names(partial(_row_names, self, node_through, self.groups))
        for g in self.groups:
            g.r0, g.r1 = r, r + g.n * g.neq
            r = g.r1
            g.s0, g.s1 = s, s + g.n * g.ns
            s = g.s1
            g.j0, g.j1 = j, j + g.n * len(g.pattern)
            j = g.j1
            if not g.ns:
                continue
            S0 += [v for c in g.comps for v in _initial_states(c)]
            first = g.comps[0]
            st, modes = first.states, getattr(first, "discrete_states", ())
            if all(c.states is st and getattr(c, "discrete_states", ()) is modes
                   for c in g.comps):       # one interface shared by the group's members
                s_quantity += [sv.quantity for sv in st] * g.n
                s_discrete += [sv.label in set(modes) for sv in st] * g.n
                continue
            for c in g.comps:
                modes = set(getattr(c, "discrete_states", ()))
                for sv in c.states:
                    s_quantity.append(sv.quantity)
                    s_discrete.append(sv.label in modes)
        self.n_rows = r
        self.S0 = np.array(S0, dtype=float)
        self.s_names = _Names(partial(_state_names, self.groups))
        self.s_quantity = s_quantity
        # discrete states (modes of switching components) change between steps only;
        # the step controller leaves them out of its error estimate
        self.s_discrete = np.array(s_discrete, dtype=bool)
        self.s_continuous = np.array([k for k, d in enumerate(s_discrete) if not d],
                                     dtype=np.intp)
        self.has_discrete = any(s_discrete)
        if self.n_rows != self.n:
            odd = [nd.name for nd in self.nodes
                   if len(nd.quantities("across")) != len(nd.quantities("through"))]
            raise NetworkError(
                f"the network has {self.n} unknowns but {self.n_rows} equations; every node "
                "needs as many through quantities (conservation laws) as across quantities; "
                f"these do not: {', '.join(odd[:5])}")

        # sparsity pattern: constant node entries, then each group's local patterns
        if small:
            rows, cols = self._pattern_small()
        else:
            rows = [self.through_rows]
            cols = [self.through_cols]
            for g in self.groups:
                if not g.pattern:
                    continue
                pe = np.array([e for e, _ in g.pattern], dtype=np.int64)
                pv = np.array([v for _, v in g.pattern], dtype=np.int64)
                inst = np.arange(g.n)[:, None]
                rows.append((g.r0 + inst * g.neq + pe[None, :]).ravel())
                cols.append(g.col[:, pv].ravel())
            rows = np.concatenate(rows)
            cols = np.concatenate(cols)
        self.raw = np.zeros(len(rows))
        self.raw[: len(through_rows)] = 1.0
        if small:
            self._csc_small(rows, cols)
        else:
            key = cols * self.n + rows
            ukey, inv = np.unique(key, return_inverse=True)
            self.nnz = len(ukey)
            self.indices = (ukey % self.n).astype(np.int32)
            ucols = ukey // self.n
            self.indptr = np.concatenate(
                [[0], np.cumsum(np.bincount(ucols, minlength=self.n))]).astype(np.int32)
            self.duplicates = self.nnz != len(key)
            self._inv = inv
            if not self.duplicates:
                order = np.empty_like(inv)
                order[inv] = np.arange(len(inv))
                self._order = order
        self.pattern_rows = rows
        self.pattern_cols = cols
        self._compile_plans()
        #: what linear solvers derive from the pattern, kept for later runs
        self.solver_cache = {}
        self._check_structure()

    def _pattern_small(self):
        """(rows, cols) of every raw Jacobian entry, the node entries first, then
        each group's local pattern instance by instance: the arrays
        Assembly.__init__ makes with NumPy per group, on Python lists (a
        small network)."""
        rows, cols = self.through_rows.tolist(), self.through_cols.tolist()
        for g in self.groups:
            if not g.pattern:
                continue
            pe = [e for e, _ in g.pattern]
            pv = [v for _, v in g.pattern]
            neq, r0 = g.neq, g.r0
            for i, at in enumerate(g.col.tolist()):
                base = r0 + i * neq
                rows += [base + e for e in pe]
                cols += [at[v] for v in pv]
        return np.array(rows, dtype=np.int64), np.array(cols, dtype=np.int64)

    def _csc_small(self, rows, cols):
        """The CSC pattern (indices, indptr, nnz, duplicates, _inv, _order) of the
        raw entries at (rows, cols), as Assembly.__init__ finds it with
        np.unique, on Python ints (a small network: ~3 us against ~20 us)."""
        n = self.n
        key = [c * n + r for r, c in zip(rows.tolist(), cols.tolist())]
        ukey = sorted(set(key))
        at = {k: i for i, k in enumerate(ukey)}
        inv = [at[k] for k in key]
        self.nnz = len(ukey)
        self.indices = np.array([k % n for k in ukey], dtype=np.int32)
        count = [0] * (n + 1)
        for k in ukey:
            count[k // n + 1] += 1
        for c in range(n):
            count[c + 1] += count[c]
        self.indptr = np.array(count, dtype=np.int32)
        self.duplicates = self.nnz != len(key)
        self._inv = np.array(inv, dtype=np.intp)
        if not self.duplicates:
            order = [0] * len(inv)
            for i, k in enumerate(inv):
                order[k] = i
            self._order = np.array(order, dtype=np.intp)

    @property
    def nodes(self):
        """The network's nodes (:class:`softflow.network.system.Node`), as
        ``System.nodes()`` returned them at compile; made on first use."""
        if self._nodes is None:
            from ..network.system import Node
            buckets = [[] for _ in range(max(self._node_of, default=-1) + 1)]
            terminals = [t for c in self._node_comps for t in c.terminals]
            for t, k in zip(terminals, self._node_of):
                buckets[k].append(t)
            self._nodes = [Node(i, ts) for i, ts in enumerate(buckets)]
        return self._nodes

    def _node_numbering(self, layouts, n_nodes):
        """Where each node's across unknowns and conservation rows are: per
        quantity an array over nodes of the unknown (row) index, -1 where the
        node has no such quantity; and what they are, for names."""
        sigs = set()
        for g, layout in zip(self.groups, layouts):
            if layout is not None:
                sigs.update(layout.terminal_sigs)
            else:
                sigs.update(_terminal_sig(t) for c in g.comps for t in c.terminals)
        if len(sigs) == 1:
            # every terminal carries the same quantities (the usual network): so
            # does every node, numbered node by node
            (acr, thr), = sigs
            at = np.arange(n_nodes, dtype=np.int64)
            across_of = {q: at * len(acr) + k for k, q in enumerate(acr)}
            row_of = {q: at * len(thr) + k for k, q in enumerate(thr)}
            return across_of, row_of, (n_nodes, acr), (n_nodes, thr)
        across, rows = {}, {}
        across_named, node_through = [], []
        for nd in self.nodes:
            for q in nd.quantities("across"):
                across.setdefault(q, {})[nd.index] = len(across_named)
                across_named.append((nd.index, q))
            for q in nd.quantities("through"):
                rows.setdefault(q, {})[nd.index] = len(node_through)
                node_through.append((nd.index, q))

        def table(found):
            out = {}
            for q, where in found.items():
                arr = np.full(n_nodes, -1, dtype=np.int64)
                arr[list(where)] = list(where.values())
                out[q] = arr
            return out
        return table(across), table(rows), across_named, node_through

    def _number_one_by_one(self, g, node_arr, t_start, at, across_of, row_of, quantities,
                           through_rows, through_cols):
        """Unknown indices of a group numbered component by component (user
        components; library groups whose members differ)."""
        cols = []
        for c, pos in zip(g.comps, at):
            tindex = {t.label: k for k, t in enumerate(c.terminals)}
            row, trows, tcols = [], [], []
            for term, v in c.interface_variables():
                role = v.role
                if role == "across":
                    idx = int(across_of[v.quantity][node_arr[t_start[pos] + tindex[term]]])
                else:
                    idx = len(quantities)
                    quantities.append(v.quantity)
                    if role == "through":
                        nd = node_arr[t_start[pos] + tindex[term]]
                        trows.append(int(row_of[v.quantity][nd]))
                        tcols.append(idx)
                row.append(idx)
            cols.append(row)
            through_rows.append(np.array(trows, dtype=np.int64))
            through_cols.append(np.array(tcols, dtype=np.int64))
        g.col = np.array(cols, dtype=np.int64).reshape(
            g.n, len(g.comps[0].interface_variables()))

    # -- checks ---------------------------------------------------------------------------
    def _check_structure(self):
        if self.n <= SMALL_BLOCKS_MAX and _STRUCTURAL(
                (self.n, *_array_key(self.indices, self.indptr)),
                self.n, self.indices, self.indptr):
            return      # (a network that is not is named below, as it always was)
        pat = csc_matrix((np.ones(self.nnz), self.indices, self.indptr), shape=(self.n, self.n))
        match = maximum_bipartite_matching(pat.tocsr(), perm_type="column")
        unmatched_rows = np.flatnonzero(match < 0)
        if len(unmatched_rows):
            matched = set(match[match >= 0].tolist())
            free = [self.x_names[i] for i in range(self.n) if i not in matched]
            rows = [self.row_names[i] for i in unmatched_rows[:5]]
            raise NetworkError(
                "the network is structurally singular: some unknowns are not determined by "
                f"any equation ({', '.join(free[:5])}) while some equations have nothing to "
                f"determine ({'; '.join(rows)}). Look for floating sub-networks or "
                "components without a pressure or flow reference")

    def check_nonsingular(self, dt):
        """Factor the Jacobian once at the initial values; if it is singular, name
        the components of each independent sub-network whose block is singular
        (e.g. a closed loop of liquid with nothing fixing its pressure). With
        dt = 0 this checks the consistent-initial-value problem at t = 0.

        A Jacobian singular there is tested once more with each dead end at
        the pressure of the node it hangs from
        (:func:`softflow.solve.sourcenodes.dead_end_start`): a gas restriction
        choked in front of a dead end started at 1 atm (a Cd orifice from a
        2.5 bar container) has no slope in the dead end's pressure there,
        which is no structural singularity (the consistent start begins from
        there where the first start fails)."""
        regular, A = self._regular_at(self.x0, dt)
        if regular is not False:
            return      # (not finite: reported with time and equation by the first solve)
        from . import sourcenodes
        start = sourcenodes.dead_end_start(self, self.x0)
        if start is not None and self._regular_at(start, dt)[0] is True:
            return
        sym = (abs(A) + abs(A).T).tocsr()
        n_blocks, label = connected_components(sym, directed=False)
        culprits = []
        for b in range(n_blocks):
            idx = np.flatnonzero(label == b)
            if _is_regular(A[idx][:, idx].tocsc()):
                continue
            comps = []
            for r in idx:
                c, _ = self.component_of_row(int(r))
                if c is not None and c not in comps:
                    comps.append(c)
            culprits.append(comps)
        if culprits and dt == 0.0:
            names = "; ".join(", ".join(c) for c in culprits)
            raise NetworkError(
                f"the initial values at t = 0 are undetermined in the sub-network(s) of: "
                f"{names}. Typically a storage volume (Container, accumulator) is joined "
                "directly to a pressure source or to another volume, so the flow between "
                "them is not fixed by any equation; put a tube or orifice between them")
        if culprits:
            names = "; ".join(", ".join(c) for c in culprits)
            raise NetworkError(
                f"the network equations are singular in the sub-network(s) of: {names}. "
                "Something there is undetermined: "
                + (self._rigid_liquid_hint([c for comps in culprits for c in comps]) or
                   "typically a closed loop of incompressible fluid with no pressure "
                   "reference, or a floating sub-network"))

    def _regular_at(self, x, dt):
        """(whether the Jacobian at x, S0, t = 0 is regular: True, False, or
        None where it is not finite; the Jacobian as a sparse matrix where it
        was made, else None). Small systems are tested on the dense matrix
        (the usual answer, without sparse matrices)."""
        with np.errstate(all="ignore"):
            self.residual(x, self.S0, 0.0, dt, jac=True)
        n = self.n
        if n <= DENSE_CHECK_MAX:
            J = self.dense_jacobian()
            if not np.isfinite(J).all():
                return None, None
            # (the test leaves J as it is: the key is what it tested)
            if _DENSE_REGULAR(_array_key(J), J):
                return True, None
        A = self.jacobian_csc()
        if n > DENSE_CHECK_MAX:       # (small systems were tested above)
            if not np.isfinite(A.data).all():
                return None, A
            if _is_regular(A):
                return True, A
        return False, A

    def _rigid_liquid_hint(self, labels):
        """Where rigid containers of a liquid are among ``labels``, a sentence
        naming them as the likely cause (they admit no flow, so nothing but the
        laws at their node sets their pressure), else None."""
        rigid = []
        for label in labels:
            g, i = self.where[label]
            comp = g.comps[i]
            fluid = getattr(comp, "fluid", None)
            if (type(comp).__name__ == "Container" and fluid is not None
                    and not fluid.compressible):
                rigid.append(comp.describe())
        if not rigid:
            return None
        return (f"{', '.join(rigid)} hold{'s' if len(rigid) == 1 else ''} a liquid in a rigid "
                "volume, which admits no flow, so only the laws at its node set its pressure "
                "(a valve at rest, such as a shut check valve, sets none); give the liquid a "
                "compliance with a LinearAccumulator or an Actuator (or use a gas)")

    def diagnose_scale(self):
        """Which component's scale is extreme relative to the rest, from the Jacobian
        last evaluated (``raw``): after equilibrating rows and columns (each to a
        largest magnitude of one), the component whose equations hold the smallest
        structural entry, if it is below 1e-12 (a coefficient lost to round-off
        against the others: a conductance, volume or compliance many orders of
        magnitude from the network's). Returns (message, row) or (None, None)."""
        J = csc_matrix((self.jacobian_data(), self.indices, self.indptr),
                       shape=(self.n, self.n)).tocoo()
        if not np.isfinite(J.data).all() or not J.nnz:
            return None, None
        a = np.abs(J.data)
        r = np.zeros(self.n)
        np.maximum.at(r, J.row, a)
        a = a / np.where(r > 0, r, 1.0)[J.row]
        c = np.zeros(self.n)
        np.maximum.at(c, J.col, a)
        a = a / np.where(c > 0, c, 1.0)[J.col]
        tiny = (a < 1e-12) & (a > 0) & (J.row >= self.n_node_rows)
        if tiny.any():
            k = np.flatnonzero(tiny)[np.argmin(a[tiny])]
            row, col = int(J.row[k]), int(J.col[k])
            what = (f"in its equation the coefficient of {self.x_names[col]} is {a[k]:.1e} "
                    "of the largest after scaling, below round-off")
        else:
            # no coefficient lost within a row: the rows themselves many orders of
            # magnitude apart (an LU without scaling sees them as singular)
            comp_rows = r[self.n_node_rows:]
            nz = np.flatnonzero(comp_rows > 0)
            if nz.size < 2 or comp_rows[nz].max() < 1e12 * comp_rows[nz].min():
                return None, None
            logs = np.log10(comp_rows[nz])
            median = float(np.median(logs))
            j = int(nz[np.argmax(np.abs(logs - median))])
            row = self.n_node_rows + j
            what = (f"its equation's coefficients are {comp_rows[j]:.1e} against a median "
                    f"{10 ** median:.1e} of the network's equations, "
                    f"{comp_rows[nz].max() / comp_rows[nz].min():.1e} apart in all")
        label, _ = self.component_of_row(row)
        g, i = self.where[label]
        comp = g.comps[i]
        # (a tube's minor losses K = 0, the default, are no scale of it)
        params = [f"{name} = {getattr(comp, name):.3g}" for name in _SCALE_PARAMETERS
                  if isinstance(getattr(comp, name, None), (int, float))
                  and not (name == "K" and getattr(comp, name) == 0)]
        shown = f" ({', '.join(params)})" if params else ""
        msg = (f"the scale of {comp.describe()}{shown} is extreme relative to the rest of "
               f"the network: {what}. Check its dimensions (units), or leave it out if it "
               "is meant to be closed or open")
        return msg, row

    def subnetworks(self):
        """(x_block, s_block, count): which independent sub-network (connected
        part of the network) each unknown and each state belongs to, numbered
        from 0. Made once; a connected network is one block."""
        if getattr(self, "_subnetworks", None) is None:
            if self.n <= SMALL_BLOCKS_MAX:
                count, x_block = self._small_blocks()
            else:
                first, others = [], []
                for g in self.groups:
                    cols = g.col
                    if cols.shape[1] > 1:
                        first.append(np.repeat(cols[:, :1], cols.shape[1] - 1, axis=1).ravel())
                        others.append(cols[:, 1:].ravel())
                a = np.concatenate(first) if first else np.zeros(0, dtype=np.int64)
                b = np.concatenate(others) if others else np.zeros(0, dtype=np.int64)
                graph = csc_matrix((np.ones(a.size), (a, b)), shape=(self.n, self.n))
                count, x_block = connected_components(graph, directed=False)
            s_block = np.empty(len(self.S0), dtype=np.int64)
            for g in self.groups:
                if g.ns:
                    s_block[g.s0:g.s1] = np.repeat(x_block[g.col[:, 0]], g.ns)
            self._subnetworks = (x_block, s_block, int(count))
        return self._subnetworks

    def _small_blocks(self):
        """(count, x_block) of :meth:`subnetworks` by union-find on Python ints
        (a small network: scipy's sparse graph costs ~0.15 ms to build there),
        blocks numbered in order of their lowest unknown, as
        ``connected_components`` numbers them."""
        parent = list(range(self.n))

        def root(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        for g in self.groups:
            if g.col.shape[1] < 2:       # (no columns, or one: nothing to join)
                continue
            for row in g.col.tolist():
                a = root(row[0])
                for j in row[1:]:
                    b = root(j)
                    if a != b:
                        if b < a:
                            a, b = b, a
                        parent[b] = a
        label, x_block = {}, []
        for i in range(self.n):
            x_block.append(label.setdefault(root(i), len(label)))
        return len(label), np.array(x_block, dtype=np.int64)

    def _initial_unknowns(self, compiled=False):
        """Initial values of the unknowns from the components' variables: a node's
        across unknown takes the first initial value given at it, in the order
        of the groups, their components and their interfaces (``compiled``:
        the interfaces just compiled, g.iface, are the components' own)."""
        if self.n <= SMALL_NUMBERING_MAX:
            return self._initial_unknowns_small(compiled)
        x0 = np.zeros(self.n)
        idx, vals = [], []
        for g, layout in zip(self.groups, self._layouts):
            if layout is not None and not compiled:     # other components (replace)
                layout = _group_layout(g.comps)
            if layout is None:
                for i, c in enumerate(g.comps):
                    iface = g.iface[i][0] if compiled else c.interface_variables()
                    for (_, v), k in zip(iface, g.col[i].tolist()):
                        if v.initial_value is not None:
                            idx.append([k])
                            vals.append([v.initial_value])
                continue
            # per slot, every member's value: component by component, slot by slot
            given = np.zeros(g.col.shape, dtype=bool)
            value = np.zeros(g.col.shape)
            for k, vs in layout.values(g.comps):
                if not isinstance(vs, list):      # one value for every member
                    if vs is not None:
                        given[:, k] = True
                        value[:, k] = vs
                    continue
                have = [v is not None for v in vs]
                if all(have):
                    given[:, k] = True
                    value[:, k] = vs
                elif any(have):
                    given[:, k] = have
                    value[have, k] = [v for v in vs if v is not None]
            idx.append(g.col[given])
            vals.append(value[given])
        if idx:
            idx = np.concatenate([np.asarray(i, dtype=np.int64) for i in idx])
            vals = np.concatenate([np.asarray(v, dtype=float) for v in vals])
            # the first value given for each unknown (a node's across unknown
            # may be given at several terminals; the others once)
            first, at = np.unique(idx, return_index=True)
            x0[first] = vals[at]
        return x0

    def stated_unknowns(self):
        """:attr:`x0` with each node's pressure at the first value a component
        states there other than the 1 atm that tubes, valves and flow sources
        only guess (a volume's initial pressure, a pressure source's): where
        the network starts, for the culprit finder's analysis of a start that
        fails. The initial values themselves keep the first value given
        (changing them moves converging starts' paths)."""
        return self._initial_unknowns_small(False, stated=True)

    def _initial_unknowns_small(self, compiled, stated=False):
        """:meth:`_initial_unknowns` of a small network on Python lists: the
        values in the same order (group by group, component by component,
        variable by variable), the first one given for each unknown kept
        (``stated``: :meth:`stated_unknowns`' rule, any size)."""
        first = {}
        if stated:
            guess = pressure_atmospheric

            def keep(k, value):
                # the first value, or the first stated one after 1 atm guesses
                old = first.get(k)
                return old is None or (old == guess and value != guess)
        else:
            def keep(k, value):
                return k not in first
        for g, layout in zip(self.groups, self._layouts):
            if layout is not None and not compiled:     # other components (replace)
                layout = _group_layout(g.comps)
            cols = g.col.tolist()
            if layout is None:
                for i, c in enumerate(g.comps):
                    iface = g.iface[i][0] if compiled else c.interface_variables()
                    for (_, v), k in zip(iface, cols[i]):
                        value = v.initial_value
                        if value is not None and keep(k, value):
                            first[k] = value
                continue
            slots = layout.values(g.comps)
            for i, at in enumerate(cols):
                for k, vs in slots:
                    value = vs[i] if isinstance(vs, list) else vs
                    if value is not None and keep(at[k], value):
                        first[at[k]] = value
        x0 = [0.0] * self.n
        for k, value in first.items():
            x0[k] = float(value)
        return np.array(x0, dtype=float)

    def replace(self, components):
        """Evaluate the given components (``{label: component}``) in place of the
        compiled ones with those labels: same class, same group (shared
        fluid, curve, blend range), new numbers. Kernels, initial values and
        the generated residual are rebuilt; the topology, the sparsity and the
        linear solver's analysis stay. What would change the structure raises
        a NetworkError saying to build a new Simulation."""
        touched = {}
        for label, comp in components.items():
            g, i = self.where[label]
            old = g.comps[i]
            if g.row is not None or not comp.vectorized:
                raise NetworkError(f"{old.describe()}: a user component's parameters are fixed "
                                   "when the Simulation is built; build a new Simulation")
            if type(comp) is not type(old) or comp.kernel_class() is not old.kernel_class():
                raise NetworkError(f"{old.describe()}: becoming a {type(comp).__name__} changes "
                                   "the network's structure; build a new Simulation")
            touched[id(g)] = g
            g.comps[i] = comp
        for g in touched.values():
            keys = {c.group_key() for c in g.comps}
            if len(keys) > 1:
                labels = ", ".join(repr(c.label) for c in g.comps)
                raise NetworkError(
                    f"{labels} are evaluated together (same class, fluid, curve or flow "
                    "regime bounds); new values that split them (e.g. another curve for one "
                    "of them) change the network's structure: give them all the same, or "
                    "build a new Simulation")
            fresh = _library_group(g.comps[0].kernel_class(), g.comps)
            for name in _FROM_PARAMS:
                setattr(g, name, getattr(fresh, name))
        self.x0 = self._initial_unknowns()
        self.S0 = np.array([v for g in self.groups if g.ns for c in g.comps
                            for v in _initial_states(c)], dtype=float)
        self._compile_plans()

    def describe_row(self, row):
        return self.row_names[row]

    def group_of_row(self, row):
        """(group, instance) whose equation ``row`` is, or (None, None)."""
        for g in self.groups:
            if g.r0 <= row < g.r1:
                return g, (row - g.r0) // g.neq
        return None, None

    def component_of_row(self, row):
        g, k = self.group_of_row(row)
        if g is None:
            return None, None
        return g.comps[k].label, (row - g.r0) % g.neq

    # -- evaluation ------------------------------------------------------------------------
    def _compile_plans(self):
        """What residual() and update_states() need of each group, as tuples
        unpacked once per call: on small scenes (the paper's three components)
        the attribute lookups cost ~1 us of a ~10 us residual."""
        self._plan = []
        for g in self.groups:
            # stateless groups get one empty (n, 0) array instead of a slice and a
            # reshape of S at every call
            no_states = np.empty((g.n, 0)) if not g.ns else None
            self._plan.append((g, g.kernel, g.col, g.s0, g.s1, (g.n, g.ns), no_states,
                               g.r0, g.r1, g.j0, g.j1))
        self._update_plan = [(g.update, g.col, g.s0, g.s1, (g.n, g.ns))
                             for g in self.groups if g.has_states]
        # one group holding every state (a single volume, or one class of them):
        # its update is the new state vector, no copy of S to write it into
        n_s = len(self.S0)
        self._one_update = (self._update_plan[0] if len(self._update_plan) == 1
                            and self._update_plan[0][2:4] == (0, n_s) else None)
        self._one_update_row = None
        if self._one_update is not None:
            g = next(g for g in self.groups if g.has_states)
            if g.row is not None:
                self._one_update_row = (g.row.update_row_fn, g.col[0])
        # node rows of small systems by a dense incidence matrix: one dot product
        # (0.3 us) against a weighted bincount (0.5 us) for the paper's scene
        nr = self.n_node_rows
        self._incidence = None
        if 0 < nr and self.n <= NODE_DOT_MAX:
            inc = np.zeros((nr, self.n))
            np.add.at(inc, (self.through_rows, self.through_cols), 1.0)
            self._incidence = inc
        self.__dict__.pop("residual", None)
        self.__dict__.pop("_python_residual", None)
        compiled = compiled_residual(self, self._failure_env())
        if compiled is not None:
            # the per-group path (python_residual) made on first use: the
            # compiled one hands its errors to it, and tests compare the two
            self.residual = compiled
        elif len(self.groups) <= UNROLL_MAX_GROUPS:
            self.residual = self.python_residual
        self._regime_plan = [(g.regime, g.col) for g in self.groups if g.regime is not None]
        self._kink_plan = [(g.kinks, g.col) for g in self.groups if g.kinks is not None]

    @property
    def python_residual(self):
        """:meth:`residual` as the per-group kernels compute it (unrolled
        generated code up to :data:`UNROLL_MAX_GROUPS` groups): the residual
        itself where the compiled network loop does not cover the network,
        else kept beside it (its errors name the law's, tests compare the
        two); made on first use (~60 us of compiling a small network)."""
        got = self.__dict__.get("_python_residual")
        if got is None:
            got = (self._unrolled_residual() if len(self.groups) <= UNROLL_MAX_GROUPS
                   else Assembly.residual.__get__(self, Assembly))
            self.__dict__["_python_residual"] = got
        return got

    @python_residual.setter
    def python_residual(self, fn):
        self.__dict__["_python_residual"] = fn

    @property
    def has_regimes(self):
        """Whether any group states the pieces of a piecewise law (``regime``)."""
        return bool(self._regime_plan)

    @property
    def has_kinks(self):
        """Whether any group states the kinks of its law (``kinks``)."""
        return bool(self._kink_plan)

    def kinks(self, x):
        """The side of its law's kinks each instance of every group that
        states them is on at x (one array), or None without any."""
        return self._pieces(self._kink_plan, x)

    def regimes(self, x):
        """The piece of its piecewise law each instance of every group that
        states one is on at x (one array of the classes' integers), or None
        without any."""
        return self._pieces(self._regime_plan, x)

    @staticmethod
    def _pieces(plan, x):
        if not plan:
            return None
        if len(plan) == 1:
            fn, col = plan[0]
            return fn(x[col])
        return np.concatenate([fn(x[col]).ravel() for fn, col in plan])

    def _bind_group(self, env, i, user_call):
        """Put what generated code calls for group i into ``env`` (k<i>: its
        kernel, or the user component's ``user_call`` row method; c<i>: its
        columns; e<i>: its empty states) and return the source of its states
        argument."""
        g, kernel, col, s0, s1, s_shape, no_states = self._plan[i][:7]
        if g.row is not None:
            env[f"k{i}"], env[f"c{i}"] = getattr(g.row, user_call), col[0]
            return f"S[{s0}:{s1}]"
        env[f"k{i}"], env[f"c{i}"], env[f"e{i}"] = kernel, col, no_states
        return f"e{i}" if no_states is not None else f"S[{s0}:{s1}].reshape({s_shape})"

    def _unrolled_residual(self):
        """:meth:`residual` with the loop over groups unrolled, compiled once from
        source whose only literals are this network's slice bounds and shapes
        (arrays, kernels and names are passed as values): on the paper's three
        groups the loop's unpacking and tests cost ~0.5 us of ~5 us."""
        env = {"empty": np.empty, "array": np.array, "bincount": np.bincount,
               "FluidError": FluidError, "raw": self.raw, "inc": self._incidence,
               "trows": self.through_rows, "tcols": self.through_cols,
               **self._failure_env()}
        nr = self.n_node_rows
        # small systems gather F as one list (a list per part and one array at the
        # end: 0.9 us against 1.2 us for slice assignments on the paper's scene)
        gather = self._incidence is not None
        lines = ["def residual(x, S, t, dt, jac=False):"]
        if gather:
            lines.append("    F = inc.dot(x).tolist()")
        else:
            lines.append(f"    F = empty({self.n})")
            if nr:
                lines.append(f"    F[:{nr}] = bincount(trows, weights=x[tcols], minlength={nr})")
        lines += ["    i = 0", "    try:"]
        for i, (g, kernel, col, s0, s1, s_shape, no_states, r0, r1, j0, j1) in \
                enumerate(self._plan):
            user = g.row is not None   # a user component: 1-D rows in and out
            states = self._bind_group(env, i, "kernel_row")
            flat = "Fg" if user else "Fg.ravel()"
            lines += [f"        i = {i}",
                      f"        Fg, Jg = k{i}(x[c{i}], {states}, t, dt, jac)",
                      f"        F += {flat}.tolist()" if gather else f"        F[{r0}:{r1}] = {flat}"]
            if j1 > j0:
                lines.append(f"        if jac: raw[{j0}:{j1}] = Jg{'' if user else '.ravel()'}")
        lines += ["    except FluidError as err:     # say which components asked for the bad state",
                  "        raise fluid_failure(groups[i], err) from None",
                  "    except PASS:",
                  "        raise",
                  "    except Exception as err:     # user code inside: name the component",
                  "        raise failure(groups[i], err, t)",
                  "    return array(F)" if gather else "    return F"]
        fn = function("\n".join(lines), "residual", env)
        fn.__doc__ = Assembly.residual.__doc__
        if gather:
            fn = self._affine_residual(fn)
        return fn

    def _failure_env(self):
        return {"PASS": (ComponentError, NetworkError), "failure": _group_failure,
                "fluid_failure": _fluid_failure, "groups": self.groups}

    def _affine_residual(self, full):
        """For a small system, the residual without Jacobian with the node rows and
        every group that describes itself as affine in its variables
        (:meth:`LibraryComponent.affine`, e.g. sources, tubes of a liquid in
        laminar flow) evaluated as one product A·x, minus their time-dependent
        offsets; the other groups, and affine ones whose condition fails at x,
        through their kernels. With a Jacobian, ``full`` does it all. On the
        paper's scene this saves two kernel calls (~1.2 us) a step."""
        n, env = self.n, {"full": full, "array": np.array, "FluidError": FluidError,
                          **self._failure_env()}
        A = np.zeros((n, n))
        A[:self.n_node_rows] = self._incidence
        body, numpy_offsets = [], []
        for i, (g, kernel, col, s0, s1, s_shape, no_states, r0, r1, j0, j1) in \
                enumerate(self._plan):
            aff = g.affine
            # a user component: its generated residual itself
            states = self._bind_group(env, i, "residual_row")
            call = (f"k{i}(x[c{i}], {states}, t, dt).tolist()" if g.row is not None
                    else f"k{i}(x[c{i}], {states}, t, dt, False)[0].ravel().tolist()")
            if aff is None:
                body += [f"        i = {i}", f"        F[{r0}:{r1}] = {call}"]
                continue
            rows = r0 + np.arange(g.n)[:, None, None] * g.neq + np.arange(g.neq)[None, :, None]
            np.add.at(A, (np.broadcast_to(rows, aff.coef.shape),
                          np.broadcast_to(col[:, None, :], aff.coef.shape)), aff.coef)
            if aff.offset is not None:
                env[f"o{i}"] = aff.offset
                if r1 - r0 == 1:
                    body += [f"        i = {i}", f"        F[{r0}] -= o{i}(t)"]
                else:
                    numpy_offsets.append(f"    Fa[{r0}:{r1}] -= o{i}(t)")
            if aff.valid is not None:
                env[f"q{i}"] = aff.valid
                body += [f"        i = {i}",
                         f"        if not q{i}(x[c{i}]): F[{r0}:{r1}] = {call}"]
        env["A"] = A
        lines = (["def residual(x, S, t, dt, jac=False):",
                  "    if jac:",
                  "        return full(x, S, t, dt, True)",
                  "    Fa = A.dot(x)"] + numpy_offsets +
                 ["    F = Fa.tolist()", "    i = 0", "    try:"] + (body or ["        pass"]) +
                 ["    except FluidError as err:     # say which components asked for the bad state",
                  "        raise fluid_failure(groups[i], err) from None",
                  "    except PASS:",
                  "        raise",
                  "    except Exception as err:     # user code inside: name the component",
                  "        raise failure(groups[i], err, t)",
                  "    return array(F)"])
        fn = function("\n".join(lines), "residual", env)
        fn.__doc__ = Assembly.residual.__doc__
        return fn

    def residual(self, x, S, t, dt, jac=False):
        """F(x) for states S at the start of the step; with jac, also fills self.raw."""
        F = np.empty(self.n)
        nr = self.n_node_rows
        if self._incidence is not None:
            np.dot(self._incidence, x, out=F[:nr])
        elif nr:
            F[:nr] = np.bincount(self.through_rows, weights=x[self.through_cols], minlength=nr)
        raw = self.raw
        for g, kernel, col, s0, s1, s_shape, no_states, r0, r1, j0, j1 in self._plan:
            try:
                Fg, Jg = kernel(x[col], S[s0:s1].reshape(s_shape) if no_states is None
                                else no_states, t, dt, jac)
            except FluidError as err:     # say which components asked for the bad state
                raise _fluid_failure(g, err) from None
            except (ComponentError, NetworkError):
                raise
            except Exception as err:      # user code inside: name the component
                raise _group_failure(g, err, t)
            F[r0:r1] = Fg.ravel()
            if jac and j1 > j0:
                raw[j0:j1] = Jg.ravel()
        return F

    def quantity_max(self, v):
        """Largest |v_i| over the unknowns i of each quantity (in q_names order)."""
        return np.maximum.reduceat(np.abs(v[self.q_order]), self.q_starts)

    @property
    def has_begin_step(self):
        return any(g.begin is not None for g in self.groups)

    def begin_step(self, x, S):
        """Let groups with per-step coefficients set them from the point (x, S)
        where the next step starts."""
        for g in self.groups:
            if g.begin is not None:
                g.begin(x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns))

    def switching(self, x, S):
        """The switching functions of every group that states them, one array:
        each negative while its mode holds and crossing zero where ``switch``
        changes it (``S``: the modes as they were). None without any."""
        parts = [np.asarray(g.switching(x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns)),
                            dtype=float).ravel()
                 for g in self.groups if g.switching is not None]
        return np.concatenate(parts) if parts else None

    def update_states(self, x, S, dt):
        """States at the end of a step, given the converged unknowns (a fluid-range
        error names the group whose update met it)."""
        try:
            return self._update_states(x, S, dt)
        except FluidError as err:
            for g in self.groups:
                if g.has_states:
                    try:
                        g.update(x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns), dt)
                    except FluidError:
                        named = _fluid_failure(g, err)
                        named.component = g.comps[0].label
                        raise named from None
            raise

    def _update_states(self, x, S, dt):
        if self._one_update_row is not None:      # a single user component's 1-D rows
            update_row, col = self._one_update_row
            new = update_row(x[col], S, dt)
            return S.copy() if new is S else new
        if self._one_update is not None:
            update, col, s0, s1, s_shape = self._one_update
            Sg = S.reshape(s_shape)
            new = update(x[col], Sg, dt)
            # a state-free update hands S itself back: never alias the old states
            if new is Sg or new.base is S or new.base is Sg:
                return S.copy()
            return new.ravel()
        out = S.copy()
        for update, col, s0, s1, s_shape in self._update_plan:
            out[s0:s1] = update(x[col], S[s0:s1].reshape(s_shape), dt).ravel()
        return out

    def jacobian_data(self):
        """Values of the Jacobian in CSC order (after :meth:`residual` with jac=True)."""
        if self.duplicates:
            return np.bincount(self._inv, weights=self.raw, minlength=self.nnz)
        return self.raw[self._order]

    def jacobian_csc(self):
        return csc_matrix((self.jacobian_data(), self.indices, self.indptr), shape=(self.n, self.n))

    def jacobian_csr(self):
        """(indptr, indices, data): the Jacobian of the last ``residual(...,
        jac=True)`` in CSR form (``jacobian_csc().tocsr()``'s arrays, int64),
        its pattern found once (the network's topology is fixed): a gather of
        the values, without SciPy's matrix and conversion at each call (~0.15
        ms a call at 4 000 unknowns: the culprit finder's node analysis asks
        thousands)."""
        got = self.__dict__.get("_csr_pattern")
        if got is None:
            where = csc_matrix((np.arange(self.nnz, dtype=float), self.indices, self.indptr),
                               shape=(self.n, self.n)).tocsr()
            got = self._csr_pattern = (where.indptr.astype(np.int64),
                                       where.indices.astype(np.int64),
                                       where.data.astype(np.int64))
        indptr, indices, perm = got
        return indptr, indices, self.jacobian_data()[perm]

    def dense_index(self):
        """Each raw Jacobian entry's place in the flattened dense (n, n) matrix."""
        flat = self.__dict__.get("_dense_flat")
        if flat is None:
            flat = self._dense_flat = self.pattern_rows * self.n + self.pattern_cols
        return flat

    def dense_jacobian(self):
        """The Jacobian of the last ``residual(..., jac=True)`` as a dense (n, n)
        array (entries of one place summed), for small systems."""
        n = self.n
        return np.bincount(self.dense_index(), weights=self.raw,
                           minlength=n * n).reshape(n, n)
