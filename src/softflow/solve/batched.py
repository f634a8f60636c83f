"""Batched variants: K variants of one scene solved as one network.

``sweep(..., engine='batched')`` (:mod:`softflow.sweep`) builds one System
holding a relabelled copy of the scene per variant (``v<k>/<label>``), each
with that variant's run-time parameters, and runs it once. The copies share
no node, so the network is K independent sub-networks: the kernels evaluate
each component class for all variants in one vectorized call, and Newton
solves the block-diagonal system with one sparse factorization.

Each variant meets the tolerance on its own: the adaptive error test takes
the largest of the sub-networks' own error norms, each unknown scaled by its
quantity's magnitude in its own sub-network (:class:`softflow.solve.bdf.BDF`).
The variants do share the step sequence: where one variant needs small
steps (a snap, a fast transient) the others take them too, which costs time
but not accuracy. Batching therefore pays for many similar variants of a
small scene (where per-run overhead dominates a serial loop) and pays less,
or loses, when variants differ widely in stiffness or when each variant is
already a large network.

A variant whose failure is traced to its own components is taken out and run
on its own (its Result says why it failed); the batch then runs again
without it.
"""
from __future__ import annotations

import copy
import warnings
from dataclasses import replace

from ..network.system import System
from .params import rebuild
from .params import split as split_params
from .validity import ModelWarning, beyond

#: Label prefix of variant k's copy of a component.
PREFIX = "v{}/"


class VariantResult:
    """One variant's part of a batched run, read like a :class:`Result`
    (``get``, ``times``, ``status``, ``message``, ``stats``, ``integral``)."""

    def __init__(self, result, prefix):
        self._result, self._prefix = result, prefix
        self.times = result.times
        self.status, self.message = result.status, result.message
        self.stats = dict(result.stats, batched=True)
        n = len(prefix)
        self.validity = [replace(w, component=w.component[n:])
                         for w in getattr(result, "validity", [])
                         if str(w.component).startswith(prefix)]
        self.warnings = beyond(self.validity)

    @property
    def success(self):
        return self.status == "success"

    def get(self, label, name, terminal=None, *, as_quantity=False):
        return self._result.get(self._prefix + label, name, terminal=terminal,
                                as_quantity=as_quantity)

    def integral(self, label, name, terminal=None, as_quantity=False):
        return self._result.integral(self._prefix + label, name, terminal=terminal,
                                     as_quantity=as_quantity)

    def __repr__(self):
        return f"<VariantResult {self._prefix!r}: {len(self.times)} points, {self.status}>"


def _copy(comp, label, changes):
    """``comp`` under another label: rebuilt with ``changes`` (checked as its
    constructor checks them), or else a shallow copy sharing its fluid,
    curve and numbers, with its own terminals and variables."""
    if changes:
        return rebuild(comp, changes, label=label)
    twin = copy.copy(comp)
    twin.label = label
    twin.terminals = []
    for t in comp.terminals:
        nt = copy.copy(t)
        nt.variables = [copy.copy(v) for v in t.variables]
        nt.component = twin
        twin.terminals.append(nt)
    twin.states = [copy.copy(v) for v in comp.states]
    twin.locals = [copy.copy(v) for v in comp.locals]
    return twin


def build_batch(system, variants, labels):
    """A System with one relabelled copy of ``system`` per variant (a dict of
    run-time parameters), joined as the original is."""
    batch = System(f"{system.label} x {len(variants)}")
    nodes = [nd for nd in system.nodes() if len(nd.terminals) > 1]
    for k, params in enumerate(variants):
        prefix = PREFIX.format(k)
        changes = split_params(params, labels)
        for c in system.components:
            batch.add(_copy(c, prefix + c.label, changes.get(c.label, {})))
        for nd in nodes:
            batch.connect(*[(prefix + t.component.label, t.label) for t in nd.terminals])
    return batch


#: Variants per batch: the variants are ordered by their parameter values and
#: cut into batches of this size, so that each batch's shared step sequence
#: serves variants of similar time scales (1 000 source-tube-tank variants,
#: 0.5-2 mm tubes: ~540/s as one batch, ~720-820/s in batches of 250).
BATCH_SIZE = 250


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


def _run_batched(sim, variants, progress=None, batch_size=BATCH_SIZE):
    """Results (one per variant, in order) of ``sim`` under each variant's
    run-time parameters, solved in batches of ``batch_size`` similar variants
    (module doc)."""
    variants = [dict(v) for v in variants]
    order = sorted(range(len(variants)), key=lambda k: _order_key(variants[k]))
    results = [None] * len(variants)
    for start in range(0, len(order), batch_size):
        chunk = order[start:start + batch_size]
        for k, res in zip(chunk, _run_batch(sim, [variants[k] for k in chunk], progress)):
            results[k] = res
    return results


def _run_batch(sim, variants, progress):
    """Results of one batch (in order), the batch run as one network."""
    from .simulation import Simulation, SimulationError
    results = [None] * len(variants)
    todo = list(range(len(variants)))
    labels = {c.label for c in sim.system.components}
    opts = {k: v for k, v in sim._definition.items() if k != "system"}
    while todo:
        batch = build_batch(sim.system, [variants[k] for k in todo], labels)
        kw = dict(opts)
        if kw.get("record") is not None:
            rec = [kw["record"]] if isinstance(kw["record"], str) else list(kw["record"])
            kw["record"] = [PREFIX.format(j) + r for j in range(len(todo)) for r in rec]
        try:
            with warnings.catch_warnings():      # issued below, one per check
                warnings.simplefilter("ignore", ModelWarning)
                res = Simulation(batch, **kw).run(progress=progress)
        except SimulationError as err:
            culprit = _variant_of(err.component)
            if culprit is None or culprit >= len(todo):
                # not traced to one variant: each runs on its own
                for k in todo:
                    results[k] = sim.run(params=variants[k], raise_on_failure=False)
                return results
            k = todo.pop(culprit)
            results[k] = sim.run(params=variants[k], raise_on_failure=False)
            continue
        for j, k in enumerate(todo):
            results[k] = VariantResult(res, PREFIX.format(j))
        _summarize(res.warnings, len(todo))
        break
    return results


def _summarize(records, n_variants):
    """One ModelWarning per check of a batched run: its first finding and how
    many variants share it (each variant's own are in its result's warnings)."""
    by_check = {}
    for r in records:
        by_check.setdefault(r.check, []).append(r)
    for check, found in by_check.items():
        variants = {r.component.split("/", 1)[0] for r in found}
        more = (f" (and the same check in {len(variants) - 1} more of the {n_variants} "
                "variants; see each variant's result.warnings)" if len(variants) > 1 else "")
        warnings.warn(found[0].message + more, ModelWarning, stacklevel=3)


def _variant_of(label):
    """The batch index of a copied component's label, or None."""
    if not isinstance(label, str) or not label.startswith("v") or "/" not in label:
        return None
    head = label[1:label.index("/")]
    return int(head) if head.isdigit() else None
