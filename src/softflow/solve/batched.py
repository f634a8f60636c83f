"""Batched variants: K variants of one scene solved as one network.

``sweep(..., engine='batched')`` (:mod:`softflow.sweep`) builds one System
holding a relabelled copy of the scene per variant (``v<k>/<label>``), each
with that variant's run-time parameters, and compiles it once. The copies
share no node, so the network is K independent sub-networks. In the
compiled step loop each variant then runs on its own, on its copy's arrays
taken out of the batch network's; elsewhere the batch runs as one network:
the kernels evaluate each component class for all variants in one
vectorized call, and Newton solves the block-diagonal system (one sparse
factorization).

Each variant meets the tolerance on its own, and, where the scene allows,
keeps its own clock (``result.stats['clocks'] == 'own'``): its own time,
step, order and error test, so a stiff variant takes small steps without
making the others take them, and each valve snaps on its own clock: each
variant's own run of the BDF in the compiled step loop
(:mod:`softflow.solve.variants`, ``stats['engine'] == 'compiled loop'``:
exactly the steps the variant's own run takes, the variants over two
threads), wherever that loop serves the scene, whatever the number of
variants (sources given as Python functions included, called back). Other
scenes (user components, fixed steps, ``refine=``, walls whose h A a
correlation sets at each step) share one step sequence
(``stats['clocks'] == 'shared'``, with ``stats['shared_because']``):
the error test takes the largest of the sub-networks' own error norms, each
unknown scaled by its quantity's magnitude in its own sub-network
(:class:`softflow.solve.bdf.BDF`), so where one variant needs small steps
(a snap, a fast transient) the others take them too, which costs time but
not accuracy. Batching pays for many variants of a small scene (where a
serial loop's per-run overhead dominates); it pays less where each variant
is already a large network, and on shared steps less again when the
variants differ widely in stiffness.

A variant whose failure is traced to its own components is taken out and run
on its own (its Result says why it failed); the batch then runs again
without it, in two halves where that variant ran through on its own (the
failure was the joint solve's: :func:`_run_batch`).

Every variant is checked before any runs (:func:`prepare`), as
``Simulation.run(params=...)`` checks it: its changed components are
rebuilt by their constructors (units, ranges) and judged as
:meth:`Assembly.replace` judges them (class, groups); the batch is built
from those same components, so each is constructed once. Thermal scenes,
whose components the compile configures in place, are checked by
``Simulation.check_params`` and rebuilt for the batch.

Where the time goes on shared steps (1 000 source-tube-tank variants,
batches of 250, ~0.6 s in all): the four batch runs ~0.45 s, the checks,
building and compiling the batches ~0.1 s. The shared step sequences take
more steps than their variants would alone (340 against 4-57 per variant run
serially, 173 for the 250 widest tubes whose own runs take 40-57), at
~1.3 ms a step. In the compiled loop each variant's run costs ~65 us of
CPU, and the checks,
building and compiling the batch, the validity checks and the results are
most of the sweep (module :mod:`softflow.solve.variants`).
"""
from __future__ import annotations

import copy
import functools
import warnings

import numpy as np

from ..network.system import NetworkError, System
from ..network.variable import SharedVariable
from .params import rebuild
from .params import split as split_params
from .validity import ModelWarning, beyond

#: Label prefix of variant k's copy of a component.
PREFIX = "v{}/"


class VariantResult:
    """One variant's part of a batched run, read like a :class:`Result`
    (``get``, ``times``, ``status``, ``message``, ``stats``, ``integral``)."""

    def __init__(self, result, prefix, validity=None, times=None, stats=None):
        self._result, self._prefix = result, prefix
        # on own clocks (softflow.solve.variants) a variant's points are the
        # first len(times) rows of the batch's
        self._n = None if times is None else len(times)
        self.times = result.times if times is None else times
        self.status, self.message = result.status, result.message
        self.stats = dict(result.stats, batched=True, **(stats or {}))
        if validity is None:        # this variant's records, found among all of the batch's
            validity = [w for w in getattr(result, "validity", [])
                        if str(w.component).startswith(prefix)]
        self.validity = [_relabel(w, prefix) for w in validity]
        self.warnings = beyond(self.validity)

    @property
    def success(self):
        return self.status == "success"

    def get(self, label, name, terminal=None, *, as_quantity=False):
        out = self._result.get(self._prefix + label, name, terminal=terminal,
                               as_quantity=as_quantity)
        return out if self._n is None else out[:self._n]

    def integral(self, label, name, terminal=None, as_quantity=False):
        out = self._result.integral(self._prefix + label, name, terminal=terminal,
                                    as_quantity=as_quantity)
        return out if self._n is None else out[:self._n]

    def __repr__(self):
        return f"<VariantResult {self._prefix!r}: {len(self.times)} points, {self.status}>"


def sample(results, outputs, times):
    """Each result's ``outputs`` (``'label.variable'``) at ``times``, as every
    sweep engine reads them: ``np.interp`` between the result's own points,
    NaN past the end of a run that stopped early; a list of arrays
    (n_outputs, n_times). The variants of one batch have their outputs'
    columns found once for all of them (:meth:`Result._columns`) and read in
    one gather per variant, where ``get`` per output and variant resolved
    each label anew (1 000 variants, 10 outputs: 55 -> 43 ms). Other results
    (a serial run, variants of a batch run alone) and derived outputs are
    read with ``get``."""
    values = [np.full((len(outputs), len(times)), np.nan) for _ in results]
    split = [column.rpartition(".") for column in outputs]
    groups = {}
    for k, r in enumerate(results):
        groups.setdefault(id(r._result) if type(r) is VariantResult else -1 - k, []).append(k)
    for ks in groups.values():
        first = results[ks[0]]
        found = ([first._result._columns([results[k]._prefix + label for k in ks], name)
                  for label, _, name in split] if type(first) is VariantResult
                 else [None] * len(split))
        xs = [m for m, f in enumerate(found) if f is not None and f[0] == "x"]
        ss = [m for m, f in enumerate(found) if f is not None and f[0] == "s"]
        rest = [m for m, f in enumerate(found) if f is None]
        x_cols = np.array([found[m][1] for m in xs], dtype=np.int64).reshape(len(xs), len(ks))
        s_cols = np.array([found[m][1] for m in ss], dtype=np.int64).reshape(len(ss), len(ks))
        if xs or ss:
            _sample_batch(results, ks, values, xs, x_cols, ss, s_cols, times)
        for j, k in enumerate(ks):
            r = results[k]
            t = r.times
            n = len(t)
            if not n or not rest:
                continue
            cols = [(m, r.get(split[m][0], split[m][2])) for m in rest]
            if r.status == "success":
                at, reached = times, slice(None)
            else:
                reached = times <= t[-1] * (1 + 1e-12)
                at = times[reached]
            out = values[k]
            for m, y in cols:
                out[m, reached] = np.interp(at, t, y)
    return values


def _sample_batch(results, ks, values, xs, x_cols, ss, s_cols, times):
    """:func:`sample` of the variants ``ks`` of one batch's result, for the
    outputs ``xs`` and ``ss`` (their columns in the batch's X and S, one per
    variant), into ``values``: each variant's places among its points found
    once for all its outputs, and each output interpolated for all the
    variants in a few array operations, by ``np.interp``'s own formula (the
    same numbers, bitwise: tested; a sweep of 1 000 variants read at common
    times, one output: 10 -> 3 ms). A variant's points are the first of the
    batch's rows."""
    first = results[ks[0]]._result
    K, P = len(ks), times.size
    lo = np.zeros((K, P), dtype=np.int64)
    left = np.zeros((K, P), dtype=bool)        # at or before the first point
    right = np.zeros((K, P), dtype=bool)       # at or past the last
    last = np.zeros(K, dtype=np.int64)
    reached = np.ones((K, P), dtype=bool)
    shared = None           # the places on times every variant shares (one array)
    for j, k in enumerate(ks):
        r = results[k]
        t = r.times
        n = len(t)
        if not n:
            reached[j] = False
            continue
        last[j] = n - 1
        if shared is None or shared[0] is not t:
            at = np.searchsorted(t, times, side="right") - 1
            shared = (t, at < 0, times >= t[-1], np.clip(at, 0, max(n - 2, 0)))
        left[j], right[j], lo[j] = shared[1:]
        if r.status != "success":
            reached[j] = times <= t[-1] * (1 + 1e-12)
    var = np.arange(K)[:, None]
    tt = np.empty((len(first.times), K))
    for j, k in enumerate(ks):
        t = results[k].times
        tt[:len(t), j] = t
    x0, x1 = tt[lo, var], tt[np.minimum(lo + 1, last[:, None]), var]
    single = (last == 0)[:, None]
    for ms, data, cols in ((xs, first.X, x_cols), (ss, first.S, s_cols)):
        for i, m in enumerate(ms):
            Y = data[:, cols[i]]
            y0, y1 = Y[lo, var], Y[np.minimum(lo + 1, last[:, None]), var]
            with np.errstate(all="ignore"):
                slope = (y1 - y0) / (x1 - x0)
                y = slope * (times[None, :] - x0) + y0
                again = np.isnan(y)
                if again.any():
                    y2 = slope * (times[None, :] - x1) + y1
                    y = np.where(again, np.where(np.isnan(y2) & (y0 == y1), y0, y2), y)
            y = np.where(left | single, Y[0, :][:, None], y)
            y = np.where(right, Y[last, np.arange(K)][:, None], y)
            y = np.where(reached, y, np.nan)
            for j, k in enumerate(ks):
                values[k][m] = y[j]


def _relabel(record, prefix):
    """``record`` (a ValidityRecord of the batch) as the variant's own: its
    component and the label its message quotes without the batch prefix
    (``'v17/tube'`` -> ``'tube'``). A copy of the frozen record made without
    dataclasses.replace (~1 us against ~8 us; a record or two per variant)."""
    twin = object.__new__(type(record))
    twin.__dict__.update(record.__dict__)
    object.__setattr__(twin, "component", record.component[len(prefix):])
    object.__setattr__(twin, "message", record.message.replace("'" + prefix, "'"))
    return twin


def _copy(comp, label, changes=None):
    """``comp`` under another label: rebuilt with ``changes`` (checked as its
    constructor checks them), or else a shallow copy sharing its fluid,
    curve and numbers, with its own terminals and variables (a library
    class's read-only SharedVariables are shared, as its instances share
    them)."""
    if changes:
        return rebuild(comp, changes, label=label)
    twin = _shallow(comp)
    twin.label = label
    twin.terminals = []
    for t in comp.terminals:
        nt = _shallow(t)
        nt.variables = _own(t.variables)
        nt.component = twin
        twin.terminals.append(nt)
    twin.states = _own(comp.states)
    twin.locals = _own(comp.locals)
    return twin


def _own(variables):
    """A twin's list of ``variables``: copies of plain Variables (a user may
    change them), the read-only shared ones as they are. Each copy is ~5
    objects the garbage collector then tracks (a batch of 1 000 three-
    component variants: 9 000 Variables)."""
    return [v if type(v) is SharedVariable else v.copy() for v in variables]


def _plain(cls):
    """Whether copy.copy of a ``cls`` instance is a new instance with the same
    __dict__ (no reduce protocol, __copy__, __setstate__ or __slots__ of its
    own); known per class."""
    known = _PLAIN.get(cls)
    if known is None:
        known = _PLAIN[cls] = not (
            cls.__reduce_ex__ is not object.__reduce_ex__
            or cls.__reduce__ is not object.__reduce__
            or getattr(cls, "__getstate__", None) is not object.__getstate__
            or hasattr(cls, "__setstate__") or hasattr(cls, "__copy__")
            or hasattr(cls, "__slots__"))
    return known


_PLAIN: dict = {}


def _shallow(obj):
    """copy.copy of a plain object (its attributes shared), without copy's
    reduce protocol: ~1 us against ~6 us, some 10 copies per component of a
    batch."""
    cls = type(obj)
    if not _plain(cls) or not hasattr(obj, "__dict__"):
        return copy.copy(obj)      # a class that copies its own way
    twin = object.__new__(cls)
    twin.__dict__.update(obj.__dict__)
    return twin


def build_batch(system, variants, labels, built=None):
    """A System with one relabelled copy of ``system`` per variant (a dict of
    run-time parameters), joined as the original is. ``built``: for each
    variant, its components already rebuilt with its parameters
    (:func:`prepare`; ``{label: component}``), used in place of rebuilding."""
    from .simulation import _collector_paused
    with _collector_paused():      # ~10 new objects per component, none freed
        return _build(system, variants, labels, built)


def _build(system, variants, labels, built):
    batch = System(f"{system.label} x {len(variants)}")
    # each node of the scene as its terminals' (label, index): a variant's
    # copies are joined by those keys, relabelled (System._join: the scene's
    # own connections, nothing to look up or check again)
    nodes = [[(t.component.label, next(k for k, o in enumerate(t.component.terminals)
                                       if o is t)) for t in nd.terminals]
             for nd in system.nodes() if len(nd.terminals) > 1]
    for k, params in enumerate(variants):
        prefix = PREFIX.format(k)
        if built is None:
            changes = split_params(params, labels)
            for c in system.components:
                batch.add(_copy(c, prefix + c.label, changes.get(c.label)))
        else:
            own = built[k]
            for c in system.components:
                mine = own.get(c.label)
                if mine is not None:
                    # rebuilt for this variant alone (prepare): relabelled in
                    # place, not copied again
                    mine.label = prefix + c.label
                    batch.add(mine)
                else:
                    batch.add(_copy(c, prefix + c.label))
        for nd in nodes:
            batch._join([(prefix + label, k) for label, k in nd])
    return batch


# -- checking the variants ---------------------------------------------------------------
def _si_template(comp):
    """``comp`` rebuilt from SI numbers in place of its scalar Quantity arguments
    (constructors then skip pint: ~60 us a Quantity), or ``comp`` itself where
    that does not give the same numbers (a constructor that reads a
    Quantity's dimension, not only its magnitude)."""
    import pint
    args, kwargs = comp.__dict__.get("_definition") or ((), {})

    def si(v):
        if isinstance(v, pint.Quantity) and np.ndim(v.magnitude) == 0:
            return float(v.to_base_units().magnitude)
        return v
    new_args, new_kwargs = tuple(si(a) for a in args), {k: si(v) for k, v in kwargs.items()}
    if all(a is b for a, b in zip(args, new_args)) and all(
            new_kwargs[k] is v for k, v in kwargs.items()):
        return comp
    template = copy.copy(comp)
    template._definition = (new_args, new_kwargs)
    try:
        probe = rebuild(template, {})
    except Exception:
        return comp
    mine, theirs = vars(probe), vars(comp)
    for key, value in theirs.items():
        if isinstance(value, float) and not (
                isinstance(mine.get(key), float)
                and abs(mine[key] - value) <= 1e-12 * abs(value)):
            return comp
    return template


class Prepared:
    """Every variant checked before any runs, as ``Simulation.run(params=...)``
    checks it (keys, units and ranges by the constructors, structure as
    :meth:`Assembly.replace` judges it), with the components that check
    rebuilt kept for the batch: ``built[k]`` is ``{label: component}`` of
    variant k's changed components (keys: the labels in the scene; each
    component joins its variant's batch as it is, relabelled there)."""

    def __init__(self, sim, variants):
        from .simulation import _collector_paused
        with _collector_paused():      # new components, none freed
            self._check(sim, variants)

    def _check(self, sim, variants):
        self.variants = [dict(v) for v in variants]
        self.built = None
        if sim.thermal != "isothermal":
            # a thermal scene configures each rebuilt component in place: the
            # checks of a run, and the batch rebuilds its own
            sim.check_params(*self.variants)
            return
        asm = sim.asm
        compiled = sim._compiled
        templates = {}
        built = []
        for i, params in enumerate(self.variants):
            try:
                wanted = split_params(params, asm.where)
                own = {}
                for label, changes in wanted.items():
                    template = templates.get(label)
                    if template is None:
                        template = templates[label] = _si_template(compiled[label])
                    own[label] = _rebuilt(template, changes, compiled[label])
                _check_groups(asm, compiled, own)
            except Exception as err:
                err.variant_index = i
                raise
            built.append(own)
        self.built = built


def _rebuilt(template, changes, old):
    """``template`` (``old``, or its SI twin) rebuilt with ``changes``; refused as
    :meth:`Assembly.replace` refuses a change of class."""
    comp = rebuild(template, changes)
    if type(comp) is not type(old) or comp.kernel_class() is not old.kernel_class():
        raise NetworkError(f"{old.describe()}: becoming a {type(comp).__name__} changes "
                           "the network's structure; build a new Simulation")
    return comp


def _check_groups(asm, compiled, own):
    """What :meth:`Assembly.replace` refuses: new values that split a group of
    the compiled model (e.g. another curve for one of two actuators)."""
    groups = {}
    for label in own:
        g, _ = asm.where[label]
        groups[id(g)] = g
    for g in groups.values():
        if len(g.comps) < 2:
            continue
        comps = [own.get(c.label, compiled[c.label]) for c in g.comps]
        if len({c.group_key() for c in comps}) > 1:
            labels = ", ".join(repr(c.label) for c in comps)
            raise NetworkError(
                f"{labels} are evaluated together (same class, fluid, curve or flow "
                "regime bounds); new values that split them (e.g. another curve for one "
                "of them) change the network's structure: give them all the same, or "
                "build a new Simulation")


def prepare(sim, variants):
    """Check every variant (errors carry ``variant_index``) and keep what the
    batches reuse (:class:`Prepared`)."""
    return Prepared(sim, variants)


# -- running ------------------------------------------------------------------------------
#: Variants per batch: the variants are ordered by their parameter values and
#: cut into batches of this size, so that each batch's shared step sequence
#: serves variants of similar time scales (1 000 source-tube-tank variants,
#: 0.5-2 mm tubes: ~540/s as one batch, ~720-820/s in batches of 250).
BATCH_SIZE = 250
#: Variants per batch where each keeps its own clock (softflow.solve.variants):
#: no shared steps to keep alike, and one batch network built and compiled
#: for them all
OWN_CLOCKS_BATCH_SIZE = 1000


def _order_key(params):
    """Sort key of a variant: its numeric parameter values, by key."""
    out = []
    for key in sorted(params):
        v = params[key]
        try:
            out.append(float(getattr(v, "magnitude", v)))
        except (TypeError, ValueError):
            out.append(0.0)
    return tuple(out)


def _run_batched(sim, variants, progress=None, batch_size=BATCH_SIZE, prepared=None,
                 own_clocks=True):
    """Results (one per variant, in order) of ``sim`` under each variant's
    run-time parameters, solved in batches of ``batch_size`` similar variants
    (module doc). ``prepared``: the variants already checked by
    :func:`prepare` (else they are checked here, all before any runs).
    ``own_clocks``: each variant on its own clock where the compiled loop
    (:mod:`softflow.solve.variants`) serves the scene (True), or never
    (False: one shared step sequence per batch)."""
    from . import variants as compiled
    from .simulation import _huge_pages_off
    network = getattr(sim.asm.residual, "network", None)
    if network is not None:
        network.check_user_values()     # user components' values changed since built
    if prepared is None:
        prepared = prepare(sim, variants)
    variants = prepared.variants
    built = prepared.built
    if own_clocks and compiled.reason_not(sim) is None:
        batch_size = max(batch_size, OWN_CLOCKS_BATCH_SIZE)
    order = sorted(range(len(variants)), key=lambda k: _order_key(variants[k]))
    results = [None] * len(variants)
    found: list = []       # (variant, validity record) of every batch run
    for start in range(0, len(order), batch_size):
        chunk = order[start:start + batch_size]
        own = None if built is None else [built[k] for k in chunk]
        mine: list = []
        with _huge_pages_off():     # (a batch's records: settings.HUGE_PAGES)
            done = _run_batch(sim, [variants[k] for k in chunk], progress, own,
                              own_clocks=own_clocks, found=mine)
        for k, res in zip(chunk, done):
            results[k] = res
        found += [(chunk[j], w) for j, w in mine]
    _summarize(found, len(variants))
    return results


def _on_own_clocks(sim, batch_sim, todo, progress=None):
    """(the batch run with a clock per variant, None), or (None, why not)
    where it keeps the shared step sequence: each variant's run in the
    compiled loop (:mod:`softflow.solve.variants`) where that serves the
    scene."""
    from . import variants
    try:
        return variants.run(sim, batch_sim, len(todo), progress), None
    except variants.Unsupported as err:
        return None, str(err)


def _run_batch(sim, variants, progress, built=None, own_clocks=True, found=None):
    """Results of one batch (in order), the batch run as one network: each
    variant on its own clock where the compiled loop
    (:mod:`softflow.solve.variants`) serves the scene and ``own_clocks``,
    else on one shared step sequence.

    Where the batch fails on a variant's component, that variant runs on its
    own: if it fails there too, the failure is its own (its Result says why)
    and the others run again as one batch; if it succeeds, the failure was
    the joint solve's (one damping and one continuation for all the
    sub-networks: 38 check-valve variants whose consistent start at t = 0
    failed together, each starting alone), and the others run again in two
    halves. A failure not traced to one variant runs each on its own.

    The validity records of the batch runs, as (variant index, record), go to
    ``found`` where given (:func:`_run_batched` issues them once for the
    sweep, :func:`_summarize`), else are issued here."""
    from .simulation import Simulation, SimulationError
    results: list = [None] * len(variants)
    labels = {c.label for c in sim.system.components}
    opts = {k: v for k, v in sim._definition.items() if k != "system"}
    groups = [list(range(len(variants)))]
    summary = found is None
    found = [] if found is None else found
    while groups:
        todo = groups.pop()
        batch = build_batch(sim.system, [variants[k] for k in todo], labels,
                            None if built is None else [built[k] for k in todo])
        kw = dict(opts)
        if kw.get("record") is not None:
            rec = [kw["record"]] if isinstance(kw["record"], str) else list(kw["record"])
            kw["record"] = [PREFIX.format(j) + r for j in range(len(todo)) for r in rec]
        try:
            with warnings.catch_warnings():      # issued once per check (_summarize)
                warnings.simplefilter("ignore", ModelWarning)
                batch_sim = _copies_simulation()(batch, **kw)
                own, why = (_on_own_clocks(sim, batch_sim, todo, progress) if own_clocks
                            else (None, "own_clocks=False"))
                if own is not None:
                    res, counts, times, (steps, rejected), failed = own
                else:
                    res, failed = batch_sim.run(progress=progress), {}
        except SimulationError as err:
            culprit = _variant_of(err.component)
            if culprit is None or culprit >= len(todo):
                # not traced to one variant: each runs on its own
                for k in todo:
                    results[k] = sim.run(params=variants[k], raise_on_failure=False)
                continue
            k = todo.pop(culprit)
            results[k] = alone = sim.run(params=variants[k], raise_on_failure=False)
            if alone.status == "success" and len(todo) > 1:
                half = len(todo) // 2       # the joint solve's failure: in halves
                groups += [todo[half:], todo[:half]]
            elif todo:
                groups.append(todo)
            continue
        mine: dict = {}
        for w in getattr(res, "validity", []):
            mine.setdefault(_variant_of(w.component), []).append(w)
        for j, k in enumerate(todo):
            if j in failed:    # on its own clock it failed: run alone, its result says why
                results[k] = sim.run(params=variants[k], raise_on_failure=False)
            elif own is not None:
                n = int(counts[j])
                results[k] = VariantResult(
                    res, PREFIX.format(j), mine.get(j, []), times=times[:n, j],
                    stats={"steps": int(steps[j]), "rejected_steps": int(rejected[j])})
            else:
                results[k] = VariantResult(res, PREFIX.format(j), mine.get(j, []),
                                           stats={"clocks": "shared", "shared_because": why})
        for w in res.warnings:
            j = _variant_of(w.component)
            if j is not None and j < len(todo) and j not in failed:
                found.append((todo[j], w))
    if summary:
        _summarize(found, len(variants))
    return results


@functools.lru_cache(maxsize=None)
def _copies_simulation():
    """The Simulation class of a batch of copies of a scene compiled and
    checked already: the copies' structural regularity is not checked again
    (a run(params=) of the scene does not check it either; ~7 ms of 1 000
    variants' batch)."""
    from .simulation import Simulation

    class CopiesSimulation(Simulation):
        _check_regular = False
    return CopiesSimulation


def _summarize(found, n_variants):
    """One ModelWarning per check of a batched sweep: its first finding and
    how many of the ``n_variants`` variants share it (each variant's own are
    in its result's warnings); ``found``: (variant index, batch record), from
    every batch run (a split batch's halves and the batches of a sweep
    counted together)."""
    by_check: dict = {}
    for k, r in found:
        by_check.setdefault(r.check, []).append((k, r))
    for check, items in by_check.items():
        variants = {k for k, _ in items}
        more = (f" (and the same check in {len(variants) - 1} more of the {n_variants} "
                "variants; see each variant's result.warnings)" if len(variants) > 1 else "")
        r = items[0][1]
        first = _relabel(r, r.component.split("/", 1)[0] + "/")
        warnings.warn(first.message + more, ModelWarning, stacklevel=3)


def _variant_of(label):
    """The batch index of a copied component's label, or None."""
    if not isinstance(label, str) or not label.startswith("v") or "/" not in label:
        return None
    head = label[1:label.index("/")]
    return int(head) if head.isdigit() else None

