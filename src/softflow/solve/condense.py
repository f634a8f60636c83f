"""Static condensation (nodal analysis): a linear solver that eliminates the
components' own unknowns before the sparse LU.

Rows of a component involve only its own unknowns (through flows and locals)
and the across unknowns of its nodes; node rows are sums of through unknowns.
Ordered that way, the Jacobian is

    [ A_ee  A_er ]   e: own unknowns and rows of the condensed components
    [ A_re  A_rr ]   r: node unknowns and rows, and everything not condensed

with A_ee block-diagonal (one k x k block per component, k = its number of
equations = own unknowns) and A_re the constant node incidence. Where every
block is regular (tubes, orifices, flow sources, volumes with dt > 0; not
pressure sources, whose equation does not involve their flow), the Schur
complement

    S = A_rr - A_re B^-1 A_er      (B: the blocks of A_ee)

in the node unknowns is factored instead of the whole Jacobian, and a solve
back-substitutes through the blocks: x_r = S^-1 (b_r - A_re B^-1 b_e), then
x_e = B^-1 b_e - B^-1 A_er x_r, two sparse products with fixed patterns.

The blocks of the library components are triangular up to a permutation
(a flow element: the flow law gives mf_a, the mass balance mf_b, the energy
law E_a, the energy balance E_b), so B^-1 [I | A_er] is a substitution, the
blocks of a factorization in one compiled pass
(:func:`softflow.laws.condense.invert_blocks`); other blocks (user
components) go through LAPACK, batched over a class's instances.

Where a block is singular or nearly so (volumes at dt = 0, the consistent
initial values), its group stays in the node system for that factorization;
where S is singular, the whole Jacobian is factored with :class:`SparseLU`:
same results, same singularity errors as before.
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import csc_matrix, csr_matrix

from .._laws import law_module
from .linalg import SingularJacobian, SparseLU
from .supernodes import ColumnLU

#: A pivot of a triangular block below this fraction of its row's largest
#: block entry, or a generic block whose row- and column-equilibrated inverse
#: has an entry above 1/PIVOT_MIN, counts as (nearly) singular: its group stays
#: in the node system for that factorization.
PIVOT_MIN = 1e-12


def _pattern(rows, cols, shape, order="csr"):
    """Sparse matrix with the (rows, cols) pattern and zero values, and the data
    slot of each entry (duplicates share one): data = bincount(slot, values)."""
    major, minor = (rows, cols) if order == "csr" else (cols, rows)
    n_major, n_minor = shape if order == "csr" else shape[::-1]
    key = major.astype(np.int64) * n_minor + minor
    # a stable sort: the entries come in long sorted runs, which it merges
    # (5-20x faster here than np.unique's quicksort)
    by_key = np.argsort(key, kind="stable")
    skey = key[by_key]
    new = np.empty(len(key), dtype=bool)
    new[:1] = True
    np.not_equal(skey[1:], skey[:-1], out=new[1:])
    ukey = skey[new]
    slot = np.empty(len(key), dtype=np.int64)
    slot[by_key] = np.cumsum(new) - 1
    indptr = np.zeros(n_major + 1, dtype=np.int32)
    np.cumsum(np.bincount(ukey // n_minor, minlength=n_major), out=indptr[1:])
    args = (np.zeros(len(ukey)), (ukey % n_minor).astype(np.int32), indptr)
    M = (csr_matrix if order == "csr" else csc_matrix)(args, shape=shape)
    return M, slot, len(ukey) == len(key)


class _Values:
    """Fills a fixed-pattern matrix's data from a source vector: data = sign * src[idx],
    summed per slot where entries share one."""

    def __init__(self, M, slot, unique, src, sign):
        self.M, self.nnz = M, M.nnz
        if unique:
            order = np.empty_like(slot)
            order[slot] = np.arange(len(slot))
            self.src, self.sign, self.slot = src[order], sign[order], None
        else:
            self.src, self.sign, self.slot = src, sign, slot

    def permuted_columns(self, perm):
        """The same values on a CSC pattern whose column j moved to perm[j]:
        each column's entries keep their order, so no second sort is needed."""
        M = self.M
        n = M.shape[1]
        counts = np.diff(M.indptr)
        old_of_new = np.empty_like(perm)
        old_of_new[perm] = np.arange(n)
        indptr = np.zeros(n + 1, dtype=M.indptr.dtype)
        np.cumsum(counts[old_of_new], out=indptr[1:])
        col = np.repeat(np.arange(n), counts)
        new = indptr[perm[col]] + (np.arange(self.nnz) - M.indptr[col])
        indices = np.empty_like(M.indices)
        indices[new] = M.indices
        out = object.__new__(_Values)
        out.M = csc_matrix((np.zeros(self.nnz), indices, indptr), shape=M.shape)
        out.nnz = self.nnz
        if self.slot is None:
            out.src, out.sign, out.slot = (np.empty_like(self.src), np.empty_like(self.sign),
                                           None)
            out.src[new], out.sign[new] = self.src, self.sign
        else:
            out.src, out.sign, out.slot = self.src, self.sign, new[self.slot]
        return out

    def fill(self, values):
        v = values[self.src]
        v *= self.sign
        if self.slot is not None:
            v = np.bincount(self.slot, weights=v, minlength=self.nnz)
        self.M.data = v


def _substitution_order(cells, k):
    """Pivots (row, column) that solve a block with nonzero ``cells`` by
    substitution (a permuted triangular block), or None."""
    rows = {e: {a for ee, a in cells if ee == e} for e in range(k)}
    known, order = set(), []
    while rows:
        ready = [(e, next(iter(cols - known))) for e, cols in sorted(rows.items())
                 if len(cols - known) == 1]
        if not ready:
            return None
        for e, a in ready:
            if a in known:               # two rows ready for one column: not triangular
                return None
            known.add(a)
            order.append((e, a))
            del rows[e]
    return order


class _Block:
    """One condensed group of components: its block structure and where its
    X = B^-1 [I | A_er] lives (n x k x (k + m) entries from ``xoff``)."""

    def __init__(self, g, own, acr, xoff):
        self.g, self.own, self.acr = g, own, acr
        self.k, self.m = k, m = len(own), len(acr)
        self.xoff = xoff
        self.xsize = g.n * k * (k + m)
        slot = {v: j for j, v in enumerate(own)}
        slot.update({v: k + j for j, v in enumerate(acr)})
        # per equation e: [(pattern index, column in [B | A_er])]
        self.rows = [[(p, slot[v]) for p, (ee, v) in enumerate(g.pattern) if ee == e]
                     for e in range(k)]
        cells = {(e, c) for e in range(k) for _, c in self.rows[e] if c < k}
        self.order = _substitution_order(cells, k)
        # nonzero structure of X: a substitution leaves half of a flow element's
        # B^-1 zero, entries the back-substitution products need not carry
        self.nz = np.ones((k, k + m), dtype=bool)
        if self.order is not None:
            self.nz[:] = False
            for e, a in self.order:
                self.nz[a, e] = True
                for _, c in self.rows[e]:
                    if c >= k:
                        self.nz[a, c] = True
                    elif c != a:
                        self.nz[a] |= self.nz[c]

    def invert_dense(self, J, X):
        """X[:] = B^-1 [I | A_er] from the group's raw Jacobian values J (n, npat)
        by LAPACK, batched over the instances, for a block that is not
        triangular up to a permutation (``order`` None: the triangular ones
        are :func:`softflow.laws.condense.invert_blocks`'); False where a
        block is (nearly) singular."""
        n, k, m = self.g.n, self.k, self.m
        M = np.zeros((n, k, 2 * k + m))
        for e in range(k):
            M[:, e, k + e] = 1.0
            for p, c in self.rows[e]:
                M[:, e, c if c < k else k + c] += J[:, p]
        B = M[:, :, :k]
        try:
            X[:] = np.linalg.solve(B, M[:, :, k:])
        except np.linalg.LinAlgError:
            return False
        # equilibrated by rows (r) then columns (c), B's entries are <= 1 and its
        # inverse c B^-1 r must stay moderate
        r = np.abs(B).max(axis=2)
        if not (r > 0).all():
            return False
        c = (np.abs(B) / r[:, :, None]).max(axis=1)
        growth = np.abs(X[:, :, :k]) * c[:, :, None] * r[:, None, :]
        return bool(np.isfinite(growth).all() and growth.max() * PIVOT_MIN <= 1.0)


def _condensable(g):
    """(own, across) interface positions of a group whose own-unknown block is
    square and structurally regular, else None."""
    iface = g.iface[0][0]
    own = [k for k, (_, v) in enumerate(iface) if v.role != "across"]
    acr = [k for k, (_, v) in enumerate(iface) if v.role == "across"]
    if not own or len(own) != g.neq:
        return None
    pos = {v: j for j, v in enumerate(own)}
    cells = {(e, pos[v]) for e, v in g.pattern if v in pos}
    if len(cells) < g.neq or not _perfect_matching(cells, g.neq):
        return None
    return own, acr


def _perfect_matching(cells, n):
    """Whether the n x n pattern ``cells`` ({(row, col)}) is structurally
    regular: every row matched to its own column (augmenting paths, Kuhn's
    algorithm; a component's block has a few rows, where SciPy's matching on
    a sparse matrix costs ~50x more)."""
    cols_of = [[] for _ in range(n)]
    for r, c in sorted(cells):
        cols_of[r].append(c)
    row_of = {}

    def place(r, seen):
        for c in cols_of[r]:
            if c not in seen:
                seen.add(c)
                if c not in row_of or place(row_of[c], seen):
                    row_of[c] = r
                    return True
        return False
    return all(place(r, set()) for r in range(n))


class CondensationPlan:
    """Index maps of the condensation, built once per Assembly: the blocks
    (at once), the pattern of S and those of the back-substitution matrices
    (at the plan's first factorization, :meth:`_patterns`: a plan whose
    blocks are only tested, as :meth:`CondensedLU.factor` tests the plan
    without exclusions at a consistent start, never builds them; ~1.9 ms
    for an air chain of 200 tubes)."""

    def __init__(self, asm, excluded=frozenset()):
        n = asm.n
        self.blocks = []
        col_elim = np.zeros(n, dtype=bool)
        row_elim = np.zeros(n, dtype=bool)
        xoff = 0
        for gi, g in enumerate(asm.groups):
            parts = _condensable(g) if gi not in excluded else None
            if parts is None:
                continue
            b = _Block(g, *parts, xoff)
            b.index = gi
            xoff += b.xsize
            self.blocks.append(b)
            col_elim[g.col[:, b.own].ravel()] = True
            row_elim[g.r0:g.r1] = True
        if not self.blocks:
            return
        self._substitution_arrays()
        # values: X of all blocks, then the raw Jacobian, then the constant 1
        self.values = np.empty(xoff + len(asm.raw) + 1)
        self.values[-1] = 1.0
        self._pending = (asm, row_elim, col_elim)

    #: (asm, rows, columns eliminated) until :meth:`_patterns` has built the plan's matrices
    _pending = None

    def _patterns(self):
        """S's pattern and fill-reducing order, and the back-substitution
        matrices Q and H (built once, at the plan's first factorization)."""
        asm, row_elim, col_elim = self._pending
        n, xoff = asm.n, len(self.values) - 1 - len(asm.raw)
        red_rows = np.flatnonzero(~row_elim)
        red_cols = np.flatnonzero(~col_elim)
        self.nr = nr = len(red_rows)
        row_pos = np.full(n, -1)
        row_pos[red_rows] = np.arange(nr)
        col_pos = np.full(n, -1)
        col_pos[red_cols] = np.arange(nr)
        node_row_of = np.full(n, -1)        # node row of each through unknown
        node_row_of[asm.through_cols] = asm.through_rows
        raw0, plus = xoff, len(self.values) - 1

        # S = A_rr - A_re W, W = B^-1 A_er: entries (row, col, source, sign)
        pr, pc = asm.pattern_rows, asm.pattern_cols
        keep = np.flatnonzero(~row_elim[pr] & ~col_elim[pc])
        S_parts = [(row_pos[pr[keep]], col_pos[pc[keep]], raw0 + keep, 1.0)]
        # Q = [C; G] with C b = b_r - A_re B^-1 b_e and G b = B^-1 b_e
        Q_parts = [(np.arange(nr), red_rows, np.full(nr, plus), 1.0)]
        # H: x = G b + H x_r (x_e: -W x_r; x_r: identity)
        H_parts = [(red_cols, np.arange(nr), np.full(nr, plus), 1.0)]
        for b in self.blocks:
            g, k, m = b.g, b.k, b.m
            w = k + m
            inst = np.arange(g.n)[:, None, None]
            a = np.arange(k)[None, :, None]
            inv_idx = b.xoff + inst * (k * w) + a * w + np.arange(k)[None, None, :]
            w_idx = b.xoff + inst * (k * w) + a * w + k + np.arange(m)[None, None, :]
            own_cols = g.col[:, b.own]                          # (n, k) global unknowns
            acr_pos = col_pos[g.col[:, b.acr]]                  # (n, m) positions in S
            comp_rows = g.r0 + np.arange(g.n)[:, None] * k + np.arange(k)   # (n, k)
            node_rows = node_row_of[own_cols]                   # (n, k); -1: locals
            # entry (i, a, col) of each product: instance i, own unknown a, and a
            # column of B^-1 (inv) or of W; only where X is structurally nonzero
            nz_inv = np.broadcast_to(b.nz[None, :, :k], (g.n, k, k))
            nz_w = np.broadcast_to(b.nz[None, :, k:], (g.n, k, m))
            through = (node_rows >= 0)[:, :, None]
            rows_t = row_pos[np.maximum(node_rows, 0)][:, :, None]       # node rows
            own3 = own_cols[:, :, None]
            acr3 = acr_pos[:, None, :]
            crow3 = comp_rows[:, None, :]
            sel = nz_w & through
            S_parts.append((np.broadcast_to(rows_t, sel.shape)[sel],
                            np.broadcast_to(acr3, sel.shape)[sel], w_idx[sel], -1.0))
            sel = nz_inv & through
            Q_parts.append((np.broadcast_to(rows_t, sel.shape)[sel],
                            np.broadcast_to(crow3, sel.shape)[sel], inv_idx[sel], -1.0))
            Q_parts.append((nr + np.broadcast_to(own3, nz_inv.shape)[nz_inv],
                            np.broadcast_to(crow3, nz_inv.shape)[nz_inv], inv_idx[nz_inv], 1.0))
            H_parts.append((np.broadcast_to(own3, nz_w.shape)[nz_w],
                            np.broadcast_to(acr3, nz_w.shape)[nz_w], w_idx[nz_w], -1.0))

        def compile_(parts, shape, order="csr"):
            rows = np.concatenate([p[0] for p in parts])
            cols = np.concatenate([p[1] for p in parts])
            src = np.concatenate([p[2] for p in parts])
            sign = np.concatenate([np.full(len(p[2]), p[3]) for p in parts])
            M, slot, unique = _pattern(rows, cols, shape, order)
            return _Values(M, slot, unique, src, sign)

        # a fill-reducing column order of S, found once on its pattern
        S_fill = compile_(S_parts, (nr, nr), "csc")
        perm = ColumnLU.column_order(S_fill.M)
        self.S = S_fill.permuted_columns(perm)
        self.Q = compile_(Q_parts, (nr + n, n))
        H_parts = [(r, perm[c], s, sg) for r, c, s, sg in H_parts]
        self.H = compile_(H_parts, (n, nr))
        # column by column only where nodes have several unknowns (thermal: p, T),
        # which SuperLU groups into supernodes; on one-unknown nodes its own solve
        # is faster (isothermal chain N = 1000: 0.017 vs 0.023 ms)
        several = asm.n_across > asm.n_nodes
        self.lu = ColumnLU(columnwise=None if several else False)
        self._pending = None

    def _substitution_arrays(self):
        """The triangular blocks' structure as the arrays of
        :func:`softflow.laws.condense.invert_blocks` (``_table``: per block;
        ``_order``: per pivot; ``_cells``: per entry of a pivot's equation),
        and the blocks LAPACK inverts (``_dense``: their positions)."""
        table = np.zeros((len(self.blocks), 8), dtype=np.int64)
        order, cells, dense = [], [], []
        for j, b in enumerate(self.blocks):
            if b.order is None:
                dense.append(j)
                continue
            o0 = len(order)
            for e, a in b.order:
                r0 = len(cells)
                cells.extend(b.rows[e])
                order.append((e, a, r0, len(cells)))
            table[j] = (b.g.j0, b.g.n, len(b.g.pattern), b.xoff, b.k, b.m, o0, len(order))
        self._table = table
        self._order = np.array(order, dtype=np.int64).reshape(-1, 4)
        self._cells = np.array(cells, dtype=np.int64).reshape(-1, 2)
        self._dense = dense
        self._triangular = np.array([j for j, b in enumerate(self.blocks) if b.order is not None],
                                    dtype=np.int64)

    def _invert_dense(self, j, raw):
        """Block j's X = B^-1 [I | A_er] into the values by LAPACK; False
        where singular."""
        b = self.blocks[j]
        g = b.g
        J = raw[g.j0:g.j1].reshape(g.n, len(g.pattern))
        X = self.values[b.xoff:b.xoff + b.xsize].reshape(g.n, b.k, b.k + b.m)
        return b.invert_dense(J, X)

    def singular(self, raw):
        """The indices (in asm.groups) of the groups whose blocks are (nearly)
        singular in ``raw``, their inverses X = B^-1 [I | A_er] formed in this
        plan's values (the triangular blocks in one compiled call)."""
        blocks, which = self.blocks, self._triangular
        ok = np.zeros(which.size, dtype=np.bool_)
        law_module("condense").invert_blocks(raw, self.values, self._table, self._order,
                                             self._cells, which, PIVOT_MIN, ok)
        out = {blocks[j].index for j in which[~ok].tolist()}
        out.update(blocks[j].index for j in self._dense if not self._invert_dense(j, raw))
        return frozenset(out)

    def factor(self, raw, inverted=False):
        """Condense and factor. Returns None on success, else the indices (in
        asm.groups) of the groups with (nearly) singular blocks, or an empty set
        where S is singular. ``inverted``: the blocks' inverses of ``raw``
        are in the values already, all regular (:meth:`singular` found none)."""
        values = self.values
        values[len(values) - 1 - len(raw):-1] = raw
        if not inverted:
            singular = self.singular(raw)
            if singular:
                return singular
        if self._pending is not None:
            self._patterns()
        self.S.fill(values)
        if not np.isfinite(self.S.M.data).all():
            return frozenset()
        try:
            self.lu.factor(self.S.M)
        except RuntimeError:
            return frozenset()
        self.Q.fill(values)
        self.H.fill(values)
        return None

    def solve(self, b):
        q = self.Q.M @ b
        nr = self.nr
        x = q[nr:]
        x += self.H.M @ self.lu.solve(q[:nr])
        return x


class CondensedLU:
    """Static condensation of the components' own unknowns, then SuperLU on the
    node system (see module docstring); same interface as :class:`SparseLU`.

    Groups whose blocks are singular in a factorization (volumes at dt = 0)
    are left in the node system for it: a second plan, kept like the first in
    the Assembly's solver cache. Where that fails too (S singular), the whole
    Jacobian is factored by :class:`SparseLU`."""

    kind = "condensed"

    def __init__(self, asm):
        self.asm = asm
        self.n = asm.n
        self.full = SparseLU(asm)
        self._plans = asm.solver_cache.setdefault("condensation", {})
        self.plan = self._plan(frozenset())
        self.mode = None
        self._raw = np.empty(len(asm.raw))

    def _plan(self, excluded):
        plan = self._plans.get(excluded)
        if plan is None:
            plan = self._plans[excluded] = CondensationPlan(self.asm, excluded)
        return plan

    @property
    def worthwhile(self):
        """Whether anything is condensed."""
        return bool(self.plan.blocks)

    def factor(self):
        raw = self.asm.raw
        if not np.isfinite(raw).all():
            raise SingularJacobian("Jacobian contains NaN or inf")
        self._raw[:] = raw
        # every group whose block is singular here (volumes through a dt = 0
        # solve) left out at once: a block's regularity is its own, whatever
        # else the plan condenses, so this is the plan that leaving them out
        # one plan at a time reaches (the plan without exclusions only tested:
        # its S and back-substitution matrices are built where it factors)
        excluded = self.plan.singular(self._raw) if self.plan.blocks else frozenset()
        while True:
            plan = self._plan(excluded)
            if not plan.blocks:
                break
            singular = plan.factor(self._raw, inverted=plan is self.plan)
            if singular is None:
                self.mode, self.active = "condensed", plan
                return
            if not singular:          # S itself: the Jacobian is singular or nearly so
                break
            excluded = excluded | singular
        self.mode = "full"
        self.full.factor()

    @property
    def row_scale(self):
        """1 / max |J_ij| per row of the Jacobian last factored (as SparseLU)."""
        if self.mode == "full":
            return self.full.row_scale
        asm = self.asm
        data = (np.bincount(asm._inv, weights=self._raw, minlength=asm.nnz) if asm.duplicates
                else self._raw[asm._order])
        rs = np.zeros(self.n)
        np.maximum.at(rs, asm.indices, np.abs(data))
        return 1.0 / np.maximum(rs, 1e-300)

    def solve(self, b):
        if self.mode == "full":
            return self.full.solve(b)
        return self.active.solve(b)
