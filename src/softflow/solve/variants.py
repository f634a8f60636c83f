"""Batched variants on the compiled loop: each variant of a scene its own
run of the BDF on its own clock, in the compiled step loop
(:func:`softflow.laws.stepper.variants`), one variant after another, the
variants split over two threads where the machine has the cores (the
compiled loop holds no lock), each thread working in arrays of its own.

The batched sweep (:mod:`softflow.solve.batched`) builds the K variants as
one network of K copies and compiles it once; that network's compiled
arrays give each variant's own (its network floats, source values and
sources' descriptions, initial values and watched volumes' floors: the
copies' rows, found through :class:`Layout`), and a run of the scene
itself (one :class:`~softflow.solve.bdf.BDF` made and not run) gives the
loop's settings, the same for every variant. Each variant's consistent
start is solved in the same call (:func:`softflow.laws.stepper.start_solve`,
then confirmed on fresh factors at its solution) and its steps are the
compiled loop's (:func:`softflow.laws.stepper.stretch`), exactly the steps
a run of the variant alone takes where the loop takes them all: the same
method, tolerances and controller, on the same equations.

A variant whose run the loop hands back (a failed solve the BDF's Newton
or the culprit finder would look into, a step forced at the smallest
step, a mode switch at the smallest steps, an emptied volume, the step
budget) or whose
start does not converge is reported failed, and the batched engine runs it
alone (its Result then says why, where it fails).

What this covers (:func:`reason_not` and :class:`_Template`): adaptive
runs without ``refine`` of scenes whose network the compiled loop serves
(the compiled residual, user components compiled
(:mod:`softflow.solve.usercompile`) but none called back, sources of any
kind (a Python function called back), no heat-transfer correlation's
per-step h A; its
dense, banded or sparse LU, each start on a dense LU: up to
:data:`~softflow.solve.settings.DENSE_MAX` unknowns a variant); check
valves, flow sources and thermal scenes included (their starts solved
without the Python solve's culprit finder and flows-first stage: a
variant whose start does not converge here runs alone). The variants may
differ in any run-time parameter whose network floats keep their sizes
(a tube's diameter, a source's waveform, an actuator's curve of as many
samples); the batch network may then split a group of the scene by
variant (:func:`_gather_index`). Other scenes share one step sequence
(:mod:`softflow.solve.batched`).

Cost (1 000 variants of the source-tube-tank scene, ``benchmarks/bench_sweep.py``):
~65 us of CPU a variant in the loop (start and ~15 steps), ~36 ms of wall
time on this project's two cores; the sweep around it (checking the
variants, building and compiling the batch network, its validity checks,
the results) ~100 ms more.

Results: the batch's Result (each variant's points padded to the longest,
in the batch's layout), with the batch's interpolant: each variant's
own dense output (:class:`_VariantsDense`), which sweeps read at their
times.
"""
from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor, wait

import numpy as np

from .._laws import law_module
from .batched import PREFIX, _variant_of
from . import settings
from .settings import DENSE_MAX
from .usercall import raise_pending



class Unsupported(Exception):
    """The batch cannot run on the compiled loop (see :func:`reason_not`)."""


class Layout:
    """Where each variant's unknowns, states and rows are in the batch's vectors:
    ``xperm`` orders the unknowns variant by variant (``x[xperm].reshape(K, nx)``
    is variant-major, each row in the same order as every other), likewise
    ``sperm`` the states and ``rperm`` the residual rows; ``inst`` maps each
    group to its instances' variants."""

    def __init__(self, asm, K):
        self.K = K
        n, ns = asm.n, len(asm.S0)
        x_var = np.full(n, -1, dtype=np.int64)
        s_var = np.full(ns, -1, dtype=np.int64)
        r_var = np.full(n, -1, dtype=np.int64)
        self.inst = {}
        for g in asm.groups:
            v = np.array([_variant_of(c.label) for c in g.comps], dtype=object)
            if any(e is None for e in v):
                raise Unsupported("a component outside the variants' copies")
            v = v.astype(np.int64)
            self.inst[id(g)] = v
            col = g.col.reshape(g.n, -1)
            x_var[col] = v[:, None]
            if g.ns:
                s_var[g.s0:g.s1] = np.repeat(v, g.ns)
            r_var[g.r0:g.r1] = np.repeat(v, (g.r1 - g.r0) // g.n)
        nr = asm.n_node_rows
        if nr:
            r_var[asm.through_rows] = x_var[asm.through_cols]
        if (x_var < 0).any() or (r_var < 0).any() or (ns and (s_var < 0).any()):
            raise Unsupported("unknowns or equations of no variant")
        for name, var, size in (("unknowns", x_var, n), ("states", s_var, ns),
                                ("equations", r_var, n)):
            if size % K or (np.bincount(var, minlength=K) != size // K).any():
                raise Unsupported(f"the variants differ in their number of {name}")
        self.xperm = np.argsort(x_var, kind="stable")
        self.sperm = np.argsort(s_var, kind="stable")
        self.rperm = np.argsort(r_var, kind="stable")
        self.nx, self.ns = n // K, ns // K
        # each unknown's (state's, equation's) variant and place among its own
        nx = self.nx
        self.x_var, self.s_var = x_var, s_var
        self.x_local = _places(self.xperm, nx)
        self.s_local = _places(self.sperm, self.ns)
        r_local = _places(self.rperm, nx)
        # each Jacobian entry's place in its variant's dense block (K, nx, nx)
        rows, cols = asm.pattern_rows, asm.pattern_cols
        if (r_var[rows] != x_var[cols]).any():
            raise Unsupported("an equation of one variant on another's unknown")
        self.block_pos = (r_var[rows] * nx + r_local[rows]) * nx + self.x_local[cols]
        xq = np.asarray(asm.x_quantity, dtype=object)[self.xperm].reshape(K, self.nx)
        sq = np.asarray(asm.s_quantity, dtype=object)[self.sperm].reshape(K, self.ns)
        if (xq != xq[0]).any() or (sq != sq[0]).any():
            raise Unsupported("the variants' unknowns are ordered differently")
        self.x_quantity, self.s_quantity = list(xq[0]), list(sq[0])

    def to_v(self, x):
        """Batch vector of unknowns -> (K, nx)."""
        return x[self.xperm].reshape(self.K, self.nx)

    def s_to_v(self, S):
        return S[self.sperm].reshape(self.K, self.ns)

    def from_v(self, Xv, out):
        out[self.xperm] = Xv.ravel()
        return out

    def s_from_v(self, Sv, out):
        out[self.sperm] = Sv.ravel()
        return out


def _places(perm, n_local):
    """Each index's position within its variant's, given the variant-major
    order ``perm`` of a vector whose variants hold ``n_local`` entries each."""
    out = np.empty(perm.size, dtype=np.int64)
    out[perm] = np.arange(perm.size) % max(n_local, 1)
    return out


def reason_not(sim):
    """Why the scene of the Simulation ``sim`` cannot run its variants on the
    compiled loop here, or None (the module's "What this covers"; the loop's
    own conditions are asked of a stepper made for it, :class:`_Template`)."""
    from . import settings
    if not settings.COMPILED_VARIANTS:
        return "settings.COMPILED_VARIANTS is off"
    if not sim.adaptive:
        return "fixed steps (step=) share one grid"
    if sim.refine > 1:
        return "refine= records points inside each step on the one-network BDF only"
    asm = sim.asm
    net = getattr(asm.residual, "network", None)
    if net is None:
        return "a component the compiled network does not cover"
    if net.callbacks:
        return ("a user component that numba does not compile (called back in Python on "
                "the network's own arrays)")
    if asm.has_begin_step:
        from .steploop import per_step_coefficients
        return f"{per_step_coefficients(asm)}, called back on the network's own floats"
    return None


class _Template:
    """What every variant's run shares, read off a stepper of the scene made
    and not run (:meth:`Simulation._integrator
    <softflow.solve.simulation.Simulation._integrator>`)."""

    def __init__(self, sim):
        from .integrator import VolumeWatch
        from .progress import Progress
        from .steploop import _source_rows, compiled_steps, not_served_because, start_setup
        st = self.st = law_module("stepper")
        integ, newton, lin, stats, culprit = sim._integrator(record=None)
        asm = self.asm = sim.asm
        start = start_setup(integ, hooks_aside=True)
        if start is None:
            raise Unsupported(not_served_because(integ)
                              or "the compiled loop does not serve the scene")
        x0, S0 = asm.x0.copy(), asm.S0.copy()
        integ.rec.add(0.0, x0, S0)
        integ._setup(x0, S0)
        integ._watch = VolumeWatch.of(asm, S0, getattr(integ, "atol", None))
        integ.progress = Progress(sim.duration, False)
        steps = compiled_steps(integ)
        if steps is None:
            raise Unsupported(not_served_because(integ)
                              or "the compiled loop does not serve the scene")
        if asm.n > DENSE_MAX:
            raise Unsupported(f"variants of more than {DENSE_MAX} unknowns (each start's "
                              "dense LU)")
        steps.state_in()
        ist, fst = steps.ist.copy(), steps.fst.copy()
        # the culprit finder's rows (the regions of nodes without volume that a
        # flow source feeds: none here, found once from the initial values),
        # which a run's loop asks for at its first failed solve
        ist[st.REJECT_NEWTON] = int(_source_rows(culprit, steps.lin[12], (x0, S0, 0.0)))
        if not ist[st.REJECT_NEWTON]:
            raise Unsupported("the culprit finder's rows were not found")
        ist[st.BUDGET_LEFT] = sim.max_steps if sim.max_steps is not None else 1 << 62
        ist[st.STALE] = 1
        self.steps, self.integ = steps, integ
        self.width = integ._D.shape[1]
        self.qmax = (np.zeros(steps.floor.size) if integ._qmax_run is None
                     else np.array(integ._qmax_run, dtype=float))
        _, _, self.start_lin, self.start_tol, sist, sfst, _ = start
        self.first = (ist, fst, sist, sfst, steps.floor.copy(), self.qmax)
        self.atol_s = np.broadcast_to(np.asarray(integ.atol, dtype=float), S0.shape)
        self.net = steps.net
        self.n, self.ns = asm.n, S0.size


def _gather_index(tn, bn, K, lay):
    """Each variant's indices into the batch network's ``fpar`` and ``u``
    (K, size of the scene's), found through its components' labels: each
    group of the scene is, in each variant, all in one group of the batch
    (the batch may split a group of the scene by variant, as where the
    variants' actuators have curves of their own), whose class, option and
    float sizes are the scene's group's, and whose unknowns and states are,
    in the variant's order (``lay``), the scene's group's. Unsupported where
    that does not hold (a variant's curve of another size)."""
    tg, bg = tn.groups, bn.groups
    net = law_module("network")
    same = [net.CLS, net.NV, net.NEQ, net.NJ, net.OPTION]
    where = {}          # the batch's labels: (group, instance)
    for b, g in enumerate(bn.asm.groups):
        for i, c in enumerate(g.comps):
            where[c.label] = (b, i)
    f_parts, u_parts = [], []
    for gi, t_asm_g in enumerate(tn.asm.groups):
        n_shared, n_per, has_u = (int(v) for v in tn.float_sizes[gi])
        n_t = int(tg[gi, net.N])
        try:
            found = np.array([[where[PREFIX.format(j) + c.label] for c in t_asm_g.comps]
                              for j in range(K)], dtype=np.int64).reshape(K, n_t, 2)
        except KeyError as err:
            raise Unsupported(f"the batch has no copy {err} of the scene's component") from None
        b = found[:, 0, 0]                              # each variant's group in the batch
        inst = found[:, :, 1]
        if (found[:, :, 0] != b[:, None]).any():
            raise Unsupported("a variant's components of one group of the scene are in "
                              "several of the batch's")
        # a compiled user component (softflow.solve.usercompile): the same
        # kernel (U0); its key (OPTION) is its own network's layout, which the
        # variants' runs read through the scene's (their places are checked below)
        cols = same if tg[gi, net.CLS] != net.USER else [net.CLS, net.NV, net.NEQ, net.NJ,
                                                          net.U0]
        if ((bg[b][:, cols] != tg[gi, cols]).any()
                or (bn.float_sizes[b] != tn.float_sizes[gi]).any()):
            raise Unsupported("a variant's network group differs from the scene's")
        if tg[gi, net.CLS] == net.USER and not _same_runtime(tn, gi, bn, b):
            raise Unsupported("a variant's user component reads other run-time values than "
                              "the scene's")
        _same_places(t_asm_g, [bn.asm.groups[v] for v in b], inst, lay)
        f0 = bg[b, net.F0][:, None]
        f_parts.append(f0 + np.arange(n_shared))
        if n_per:
            per = f0[:, :, None] + n_shared + inst[:, :, None] * n_per + np.arange(n_per)
            f_parts.append(per.reshape(K, -1))
        if has_u:
            u_parts.append(bg[b, net.U0][:, None] + inst)
    f_idx = np.concatenate(f_parts, axis=1) if f_parts else np.zeros((K, 0), np.int64)
    u_idx = np.concatenate(u_parts, axis=1) if u_parts else np.zeros((K, 0), np.int64)
    if f_idx.shape[1] != tn.fpar.size or u_idx.shape[1] != tn.u.size:
        raise Unsupported("the variants' network floats differ from the scene's")
    return f_idx, u_idx


def _same_runtime(tn, gi, bn, b):
    """Whether the compiled user component of the scene's group ``gi`` and
    its copies in the batch's groups ``b`` hold the same run-time values
    (:func:`softflow.solve.usercompile.layout`: the variants' runs read the
    scene's layout)."""
    mine = {row: lay for row, _, _, lay, _ in tn.watched}
    theirs = {row: lay for row, _, _, lay, _ in bn.watched}
    if gi not in mine or any(int(v) not in theirs for v in b):
        return False
    return all(theirs[int(v)].digest == mine[gi].digest for v in b)


def _same_places(tg, groups, inst, lay):
    """Unsupported unless each variant's copies of the scene's group ``tg``
    (instances ``inst[j]`` of its batch group ``groups[j]``) have their
    unknowns and states where the scene's group has them, in the variant's
    own order (:class:`Layout`)."""
    by_group: dict = {}
    for j, g in enumerate(groups):
        by_group.setdefault(id(g), (g, []))[1].append(j)
    for g, js in by_group.values():
        js = np.asarray(js, dtype=np.int64)
        col = np.asarray(g.col)[inst[js]]                          # (variants, n, nv)
        if ((lay.x_var[col] != js[:, None, None]).any()
                or (lay.x_local[col] != np.asarray(tg.col)[None]).any()):
            raise Unsupported("a variant's unknowns are ordered unlike the scene's")
        if g.ns:
            states = g.s0 + inst[js][:, :, None] * g.ns + np.arange(g.ns)
            want = tg.s0 + np.arange(tg.n)[:, None] * tg.ns + np.arange(tg.ns)
            if (lay.s_local[states] != want[None]).any():
                raise Unsupported("a variant's states are ordered unlike the scene's")


def _sources_of(described, u_idx, K):
    """Each variant's sources' description (base, slot, codes, factors,
    starts, floats; padded rows) and its number of signals, from the batch
    network's ``described`` and each variant's indices into its values."""
    base, slot, codes, factors, starts, floats = described
    BASE = np.ascontiguousarray(base[u_idx])
    SLOT = np.ascontiguousarray(slot[u_idx])
    if not codes.size:
        return (BASE, SLOT, np.zeros((K, 0), np.int64), np.zeros((K, 0)),
                np.zeros((K, 0), np.int64), np.zeros((K, 0)), np.zeros(K, np.int64))
    # each signal's floats: from its start to the next signal's (laid end to end)
    order = np.argsort(starts, kind="stable")
    ends = np.empty(starts.size, dtype=np.int64)
    ends[order] = np.append(starts[order][1:], floats.size)
    mine = [np.unique(row[row > 0]) - 1 for row in SLOT]
    m = np.array([s.size for s in mine], dtype=np.int64)
    width = max(int(m.max()), 1)
    nfl = max([int((ends[s] - starts[s]).sum()) for s in mine] + [1])
    CODES, FACTORS = np.zeros((K, width), np.int64), np.zeros((K, width))
    STARTS, FLOATS = np.zeros((K, width), np.int64), np.zeros((K, nfl))
    for j, sig in enumerate(mine):
        local = np.zeros(codes.size + 1, dtype=np.int64)
        local[sig + 1] = np.arange(1, sig.size + 1)
        SLOT[j] = local[SLOT[j]]
        CODES[j, :sig.size], FACTORS[j, :sig.size] = codes[sig], factors[sig]
        at = 0
        for i, k in enumerate(sig):
            seg = floats[starts[k]:ends[k]]
            STARTS[j, i] = at
            FLOATS[j, at:at + seg.size] = seg
            at += seg.size
    return BASE, SLOT, CODES, FACTORS, STARTS, FLOATS, m


def _copied(value):
    """A copy of an array, or of a tuple of them (nested)."""
    if isinstance(value, tuple):
        return tuple(_copied(v) for v in value)
    return value.copy() if isinstance(value, np.ndarray) else value


class _Worker:
    """One thread's work arrays and records."""

    def __init__(self, tpl, n_variants):
        st, steps = tpl.st, tpl.steps
        n, ns = tpl.n, tpl.ns
        raw = tpl.net[0].copy()
        self.net = (raw,) + tuple(tpl.net[1:])
        self.lin = (raw,) + _copied(steps.lin[1:])
        # (its info, lin[13], copied with the template's banded or sparse LUs'
        # addresses: the copies have the template's types, which each call checks)
        self.start_lin = (raw,) + _copied(tpl.start_lin[1:])
        rec = _copied(steps.buffers)
        self.rec = rec + (steps.x_index, steps.s_index)
        self.dense = _copied(steps.dbuf) + (steps.d_cols,)
        self.events = steps.events.copy()
        nq = steps.buffers[3].shape[1]
        self.scratch = st.stretch_scratch(n, ns, tpl.width, nq, steps.lin[11].size)
        self.start_scratch = st.fixed_scratch(n, ns)
        self.work = (np.zeros(n), np.zeros(ns), np.zeros((tpl.integ._D.shape[0], tpl.width)),
                     np.zeros(nq), np.zeros(st.IST_SIZE, np.int64), np.zeros(st.FST_SIZE),
                     np.zeros(st.IST_SIZE, np.int64), np.zeros(st.FST_SIZE),
                     np.zeros(steps.floor.size), np.zeros(tpl.qmax.size),
                     np.zeros(st.STATS_SIZE, np.int64), np.zeros(st.STATS_SIZE, np.int64),
                     np.zeros(tpl.net[7].size))
        self.rows = max(settings.VARIANT_ROWS * n_variants, 16)
        self.d_rows = 2 * self.rows             # (orders 1-5, mostly 1-2)
        self.d_width = steps.dbuf[4].shape[1]
        self.out = (np.empty(self.rows), np.empty((self.rows, n)), np.empty((self.rows, ns)),
                    np.empty((self.rows, nq)), np.empty(self.rows),
                    np.empty(self.rows, np.int64), np.empty(self.rows, np.int64),
                    np.empty((self.d_rows, self.d_width)))
        self.pos = np.zeros(2, np.int64)
        self.done = 0           # variants run (the progress bar reads it)
        self.totals = np.zeros(st.STATS_SIZE, np.int64)

    def run(self, tpl, picks, given, w_index, meta):
        """The variants ``picks`` (:func:`softflow.laws.stepper.variants`),
        given more rows where they need them. The thread works on copies of
        its variants' rows and of the arrays every thread reads (numba counts
        references to an array atomically at each call that passes it or
        view taken of it: threads passing the same arrays would contend for
        one cache line). 1 000 source-tube-tank variants, dealt in turn to
        two threads this way: the loop ~1.8x one thread's speed (~1.3x with
        the variants in two halves and the arrays shared: the halves' runs
        took 5-14 and 14-30 steps)."""
        st = tpl.st
        shared = _copied((tpl.first, tpl.steps.tol, tpl.start_tol, w_index, tpl.steps.G,
                          tpl.steps.ERRC))
        first, tol, start_tol, w_index, G, ERRC = shared
        mine = tuple(np.ascontiguousarray(a[picks]) for a in given)
        meta_mine = tuple(np.zeros(picks.size, dtype=np.int64) for _ in meta)
        j, K = 0, picks.size
        while j < K:
            # (a few dozen variants a call: the progress bar's count moves)
            end = min(j + settings.VARIANT_CHUNK, K)
            j = st.variants(j, end, mine, first, self.net, self.lin, self.start_lin, tol,
                            start_tol, self.rec, self.dense, self.events, w_index, G, ERRC,
                            self.scratch, self.start_scratch, self.work, self.out, self.pos,
                            meta_mine, self.totals)
            self.done = j
            if j < end:        # out of rows: twice as many, and on from variant j
                used, d_used = int(self.pos[0]), int(self.pos[1])
                self.rows *= 2
                self.d_rows *= 2
                self.out = (tuple(_grown(a, self.rows, used) for a in self.out[:7])
                            + (_grown(self.out[7], self.d_rows, d_used),))
        for whole, part in zip(meta, meta_mine):
            whole[picks] = part
        return self


def _grown(a, rows, used):
    """``a`` with ``rows`` rows, its first ``used`` kept."""
    b = np.empty((rows,) + a.shape[1:], dtype=a.dtype)
    b[:used] = a[:used]
    return b


def run(sim, batch_sim, K, progress=None):
    """Run the compiled batch ``batch_sim`` of K variants of the scene of
    ``sim``, each on its own clock in the compiled loop (module docstring).

    Returns (result, counts, times, steps, failed): the batch's Result (each
    variant's points padded to the longest, its validity checked on each
    variant's own times), the number of points of each variant, their times
    (M, K), accepted and rejected steps per variant, and {variant: reason}
    of the variants whose run failed here (the caller runs those alone).
    Raises :class:`Unsupported` where the batch cannot run so.
    ``progress``: a bar as ``Simulation.run(progress=)`` shows it, whose
    time is the duration times the share of the variants run."""
    from .integrator import VolumeWatch
    from .newton import Stats
    from .progress import CHECK_INTERVAL, Progress
    from .result import Result
    from .steploop import _solve_counts_out
    why = reason_not(sim) or reason_not(batch_sim)
    if why is not None:
        raise Unsupported(why)
    tpl = _Template(sim)
    st = tpl.st
    basm = batch_sim.asm
    bnet = basm.residual.network
    lay = Layout(basm, K)
    if lay.nx != tpl.n or lay.ns != tpl.ns:
        raise Unsupported("the variants' sizes differ from the scene's")
    f_idx, u_idx = _gather_index(tpl.asm.residual.network, bnet, K, lay)
    described = bnet.source_arrays()
    if described is None:
        raise Unsupported("a source's signal the compiled loop does not evaluate")
    X0 = np.ascontiguousarray(lay.to_v(basm.x0), dtype=float)
    S0 = np.ascontiguousarray(lay.s_to_v(basm.S0), dtype=float)
    FPAR = np.ascontiguousarray(bnet.fpar[f_idx])
    U = np.ascontiguousarray(bnet.u[u_idx])
    sources = _sources_of(described, u_idx, K)
    # the watched volumes: each variant's floors from its own initial states
    w_index = tpl.steps.watch[0]
    if w_index.size:
        batch_atol = lay.s_from_v(np.tile(tpl.atol_s, (K, 1)), np.empty(basm.S0.size))
        bw = VolumeWatch.of(basm, basm.S0, batch_atol)
        floors = np.full((K, lay.ns), np.nan)
        floors[lay.s_var[bw.index], lay.s_local[bw.index]] = bw.floor
        WFLOOR = np.ascontiguousarray(floors[:, w_index])
        if bw.index.size != K * w_index.size or np.isnan(WFLOOR).any():
            raise Unsupported("the variants' volumes are watched unlike the scene's")
    else:
        WFLOOR = np.zeros((K, 0))
    breaks, n_breaks = _breakpoints(batch_sim, K)
    given = (X0, S0, FPAR, U) + sources + (WFLOOR, breaks, n_breaks)
    meta = (np.zeros(K, np.int64), np.zeros(K, np.int64), np.zeros(K, np.int64),
            np.zeros(K, np.int64), np.zeros(K, np.int64))
    threads = 2 if K >= settings.VARIANT_THREADS_MIN and (os.cpu_count() or 1) >= 2 else 1
    # every threads-th variant to each thread (a sweep's neighbours are alike:
    # the halves of 1 000 sorted tube diameters took 5-14 and 14-30 steps)
    owner = np.arange(K) % threads
    picks = [np.flatnonzero(owner == i) for i in range(threads)]
    workers = [_Worker(tpl, picks[i].size) for i in range(threads)]
    with np.errstate(all="ignore"), Progress(batch_sim.duration, progress) as bar, \
            ThreadPoolExecutor(threads) as pool:
        running = [pool.submit(workers[i].run, tpl, picks[i], given, w_index, meta)
                   for i in range(threads)]
        pending = running
        while pending:
            pending = wait(running, timeout=CHECK_INTERVAL)[1]
            # the bar: the share of the variants run, as a share of the duration
            bar.reached(batch_sim.duration * sum(w.done for w in workers) / K)
        for r in running:
            r.result()          # (an error in a thread raised here)
    raise_pending()             # an interrupt a Python signal's call-back met
    first, count, code, steps, rejected = meta
    exits = st.EXITS
    failed = {}
    for j in np.flatnonzero(code != st.DONE):
        c = int(code[j])
        failed[int(j)] = ("its consistent start did not converge here" if c == st.START_FAILED
                          else f"the compiled loop handed its run back ({exits[c]})")
    # each variant's points, padded with its last, in the batch's layout (a
    # variant that runs alone: its initial values, at 0 and a hair after)
    ok = count > 0
    counts = np.where(ok, count, 1)
    M = int(counts.max())
    jrow = np.arange(M)[:, None]
    rows = np.where(ok, first, 0)[None, :] + np.minimum(jrow, counts[None, :] - 1)
    T = batch_sim.duration
    times = np.zeros((M, K))
    Xv = np.broadcast_to(X0, (M, K, tpl.n)).copy()
    Sv = np.broadcast_to(S0, (M, K, tpl.ns)).copy()
    Qv = np.zeros((M, K, workers[0].out[3].shape[1]))
    for i, w in enumerate(workers):
        mine = (owner == i) & ok
        r = rows[:, mine]
        times[:, mine] = w.out[0][r]
        Xv[:, mine] = w.out[1][r]
        Sv[:, mine] = w.out[2][r]
        Qv[:, mine] = w.out[3][r]
    pad = jrow >= counts[None, :]
    times = np.where(pad, times + (jrow - counts[None, :] + 1) * 1e-12 * T, times)
    X, S, Q = _in_batch(Xv, Sv, Qv, lay, basm.n, basm.S0.size, batch_sim.record)
    dense = _VariantsDense(workers, owner, first, np.where(ok, count, 0), lay, basm,
                           batch_sim.record, T)
    stats = Stats()
    totals = sum(w.totals for w in workers)
    stats.steps, stats.rejected_steps = int(steps.sum()), int(rejected.sum())
    stats.error_test_failures = int(totals[st.ERROR_FAILS])
    stats.newton_failures = int(totals[st.NEWTON_FAILS])
    _solve_counts_out(st, totals, stats)
    info = stats.as_dict()
    info.update(method=batch_sim.method, rtol=batch_sim.rtol, unknowns=basm.n,
                clocks="own", engine="compiled loop", forced_steps=0, linear_solver="dense",
                order_steps=[0] + [int(totals[7 + k]) for k in range(1, sim.max_order + 1)])
    result = Result(basm, times[:, 0], X, S, stats=info, recorded=batch_sim.record,
                    integrals=Q, dense=dense)
    checked(result, batch_sim, lay.inst, times, failed)
    return result, np.where(ok, count, 0), times, (steps, rejected), failed


def checked(result, batch_sim, inst, times, failed):
    """The validity checks of a batch ``result`` whose variants keep their
    own ``times`` (M, K) (each group's instances' variants in ``inst``), into
    ``result.validity`` and ``result.warnings``; where the Simulation stops
    past a model's own limits (``beyond_limits='error'``), each variant
    found past one added to ``failed`` (the caller runs it alone, where its
    result says so)."""
    from .validity import beyond, check_result
    result.instance_times = lambda g, keep: times[:, inst[id(g)][np.asarray(keep, dtype=np.int64)]]
    records = check_result(batch_sim.asm, result)
    result.validity, result.warnings = records, beyond(records)
    if batch_sim.beyond_limits == "error":
        for w in result.warnings:
            if w.details.get("fatal"):
                v = _variant_of(str(w.component))
                if v is not None:
                    failed.setdefault(v, w.message)


def _in_batch(Xv, Sv, Qv, lay, n, ns, record):
    """Rows of every variant's unknowns, states and quadratures, variant-major
    ((rows, K, nx), (rows, K, ns), (rows, K, nx)), as the batch's X, S, Q
    (n unknowns, ns states; the columns Simulation(record=) keeps, where
    ``record``)."""
    rows = Xv.shape[0]
    X, S, Q = np.empty((rows, n)), np.empty((rows, ns)), np.empty((rows, n))
    X[:, lay.xperm] = Xv.reshape(rows, -1)
    S[:, lay.sperm] = Sv.reshape(rows, -1)
    Q[:, lay.xperm] = Qv.reshape(rows, -1)
    if record is not None:
        xs, ss = record[:2]
        X, S, Q = X[:, xs], S[:, ss], Q[:, xs]
    return X, S, Q


class _VariantsDense:
    """The batch's interpolant: each variant's own dense output (its steps'
    polynomials), read at common times into the batch's layout (a variant
    run alone elsewhere: NaN). Each thread's records are one
    :class:`softflow.solve.dense.DenseOutput` whose entries are its
    variants' one after another; each variant's times are placed among its
    own entries, and all are evaluated in one call (the numbers of a
    DenseOutput of each variant alone: its entries' own arithmetic).
    Where every time asked is the start or the end, the points are read as
    they are. What :meth:`Result.at <softflow.solve.result.Result.at>` and
    the sweeps (:func:`softflow.sweep._sample`) read a batch's variants
    from."""

    def __init__(self, workers, owner, first, count, lay, basm, record, T):
        self._workers, self._owner, self._first, self._count = workers, owner, first, count
        self._lay, self._record = lay, record
        self._n, self._ns = basm.n, basm.S0.size
        self._discrete = basm.s_discrete if basm.has_discrete else None
        self._outputs: dict = {}
        self.end = T

    @property
    def nbytes(self):
        """Memory of the variants' records and differences [bytes]."""
        return sum(a.nbytes for w in self._workers for a in w.out)

    def _of(self, i):
        """The DenseOutput of thread i's records (made on first use)."""
        got = self._outputs.get(i)
        if got is None:
            from .dense import DenseOutput
            w = self._workers[i]
            out, rows, d_rows = w.out, int(w.pos[0]), int(w.pos[1])
            got = DenseOutput(out[0][:rows], out[4][:rows], out[5][:rows],
                              np.arange(rows), out[7][:d_rows], out[1][:rows],
                              out[2][:rows], out[3][:rows], self._discrete)
            got.off = out[6][:rows]          # (each entry's first row, as written)
            self._outputs[i] = got
        return got

    def values(self, tau, cols=None, chunk=None):
        """(X, S, Q) of the batch at the times ``tau`` (``cols`` as
        :meth:`DenseOutput.values <softflow.solve.dense.DenseOutput.values>`)."""
        tau = np.asarray(tau, dtype=float)
        lay, K, P = self._lay, self._lay.K, tau.size
        Xv = np.full((P, K, lay.nx), np.nan)
        Sv = np.full((P, K, lay.ns), np.nan)
        Qv = np.full((P, K, lay.nx), np.nan)
        live = np.flatnonzero(self._count > 0)
        first, count = self._first, self._count
        ends = bool(np.isin(tau, (0.0, self.end)).all())
        local = None            # the variants' own columns to evaluate (None: all)
        if cols is not None:
            cS, cX, cQ = (np.asarray(c, dtype=np.int64) for c in cols)
            xb = cX if self._record is None else np.asarray(self._record[0])[cX]
            sb = cS if self._record is None else np.asarray(self._record[1])[cS]
            qb = cQ if self._record is None else np.asarray(self._record[0])[cQ]
            local = (np.unique(lay.s_local[sb]), np.unique(lay.x_local[xb]),
                     np.unique(lay.x_local[qb]))
        for i, w in enumerate(self._workers):
            js = live[self._owner[live] == i]
            if not js.size:
                continue
            out = w.out
            if ends:
                # the start and the end, every variant's first and last points:
                # gathered for all at once (a sweep of end values)
                r = np.where(tau[:, None] == 0.0, first[js], first[js] + count[js] - 1)
                Xv[:, js], Sv[:, js], Qv[:, js] = out[1][r], out[2][r], out[3][r]
                continue
            # each variant's times among its own entries (DenseOutput.entries:
            # the first entry ending at or after each), for all at once: one
            # search on the thread's times each lifted by its variant's rank
            # (rows of a thread are its variants' one after another), then
            # made exact on the times themselves (the lift's round-off may
            # move a time near an entry's end past it)
            f, n = first[js], count[js]
            t_all = out[0][:int(w.pos[0])]
            last = f + n - 1
            tq = np.minimum(np.maximum(tau[None, :], 0.0), t_all[last][:, None])
            span = 2.0 * (float(np.max(t_all)) + 1.0)
            rank = np.repeat(np.arange(js.size), n)
            if rank.size != t_all.size:
                raise RuntimeError("a thread's records are not its variants' one after another")
            at = np.searchsorted(rank * span + t_all, (np.arange(js.size)[:, None] * span
                                                       + tq).ravel(), side="left")
            at = np.clip(at.reshape(js.size, P), f[:, None], last[:, None])
            while True:
                up = (t_all[at] < tq) & (at < last[:, None])
                if not up.any():
                    break
                at += up
            while True:
                down = (at > f[:, None]) & (t_all[np.maximum(at - 1, 0)] >= tq)
                if not down.any():
                    break
                at -= down
            X, S, Q = self._of(i).on(at.ravel(), tq.ravel(), local)
            parts = [(Xv, X), (Sv, S)] + ([] if Q is None else [(Qv, Q)])
            for k, (whole, part) in enumerate(parts):
                part = part.reshape(js.size, P, -1).transpose(1, 0, 2)
                if local is None:
                    whole[:, js] = part
                else:           # (local: states, unknowns, quadratures)
                    whole[:, js[:, None], local[(1, 0, 2)[k]][None, :]] = part
        X, S, Q = _in_batch(Xv, Sv, Qv, lay, self._n, self._ns, self._record)
        if cols is not None:
            cS, cX, cQ = cols
            return X[:, cX], S[:, cS], Q[:, cQ]
        return X, S, Q


def _breakpoints(batch_sim, K):
    """Each variant's breakpoints inside the run (the Simulation's and its own
    components', :func:`softflow.solve.integrator.breaks_inside`), with the
    end where one falls on it (its last step then reads its sources' left
    limit there, as a run alone does): (K, most) padded with inf,
    and each one's number."""
    from ..network.component import Component
    from .integrator import breakpoints_within, breaks_inside
    asm, T = batch_sim.asm, batch_sim.duration
    common = [float(b) for b in batch_sim.breakpoints]
    own = [list(common) for _ in range(K)]
    for g in asm.groups:
        c0 = g.comps[0]
        if (getattr(c0, "breakpoints_until", None) is None
                and type(c0).breakpoints is Component.breakpoints):
            continue                # (a group of a class that states none)
        for comp in g.comps:
            own[_variant_of(comp.label)].extend(float(b) for b in
                                                breakpoints_within(comp, T))
    lists = [breaks_inside(breaks, T) for breaks in own]
    counts = np.array([len(b) for b in lists], dtype=np.int64)
    out = np.full((K, max(int(counts.max()), 1)), np.inf)
    for j, b in enumerate(lists):
        out[j, :len(b)] = b
    return out, counts
