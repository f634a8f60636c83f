"""Step equations of rate-form library components.

This is the one place where a library component's equations meet the time
discretization. A component states (:class:`softflow.components.base.LibraryComponent`)

    X' = r(V, S)           ``rates``: the rates of its continuous states X
    0  = F(V, X, t)        ``residual``: algebraic residuals, X at the time of V

and, for a discrete state (a valve's or a hysteretic actuator's mode), a
``switch`` that decides the next mode from a converged step. It never sees
the step. Every stepper hands a step as

    X_{n+1} = psi + c · r(V_{n+1})

(backward Euler: psi = X_n, c = h; BDF of order k: psi from the difference
table and c = h / g_k, see :mod:`softflow.solve.bdf`), so the step equations
are F(V, psi + c·r(V), t) = 0 with the Jacobian

    dF/dV + dF/dX · c · dr/dV

made here from the component's analytic pieces. The assembly calls the
result as ``kernel(V, S, t, dt, jac)`` and ``update(V, S, dt)`` with S = psi
and dt = c (floats). Rates may depend on the interface variables V and on the
discrete modes, not on the continuous states themselves (each state is then
an explicit function of the step's unknowns, and a linear multistep method
keeps every linear invariant, such as a closed network's total mass, to
round-off).
"""
from __future__ import annotations

import functools

import numpy as np


class StepPlan:
    """How a class's residual and rate Jacobian columns combine into the
    columns of its step Jacobian (``jac_pattern``)."""

    def __init__(self, cls):
        self.cls = cls
        ns = len(cls.state_spec)
        disc = {i for i, (label, _) in enumerate(cls.state_spec) if label in cls.discrete_states}
        self.cont = np.array([i for i in range(ns) if i not in disc], dtype=np.int64)
        self.disc = np.array(sorted(disc), dtype=np.int64)
        self.all_cont = self.cont.size == ns
        # residual columns: residual_pattern (V) then state_jac_pattern (continuous X)
        col_of = {entry: j for j, entry in enumerate(cls.jac_pattern)}
        missing = [e for e in cls.residual_pattern if e not in col_of]
        if missing:
            raise TypeError(f"{cls.__name__}: residual_pattern entries {missing} are not in "
                            "jac_pattern")
        self.res_cols = np.array([col_of[e] for e in cls.residual_pattern], dtype=np.int64)
        # the residual's V columns are the step Jacobian's first ones, in order
        self.res_prefix = bool(np.all(self.res_cols == np.arange(len(self.res_cols))))
        n_res = len(cls.residual_pattern)
        # products dF/dX[e, s] · dr/dV[s, v] -> step column of (e, v)
        products = []
        for ks, (e, s) in enumerate(cls.state_jac_pattern):
            for kr, (s2, v) in enumerate(cls.rate_pattern):
                if s2 != s:
                    continue
                if (e, v) not in col_of:
                    raise TypeError(f"{cls.__name__}: jac_pattern lacks ({e}, {v}), which "
                                    f"dF/dX ({e}, state {s}) · dr/dV ({s}, {v}) fills")
                products.append((col_of[(e, v)], n_res + ks, kr))
        # the first contribution to a column that no residual entry fills assigns
        filled = set(self.res_cols.tolist())
        self.products = []
        for col, kj, kr in products:
            self.products.append((col, kj, kr, col in filled))
            filled.add(col)
        self.n_jac = len(cls.jac_pattern)


@functools.lru_cache(maxsize=None)
def step_plan(cls):
    return StepPlan(cls)


def step_functions(cls, P):
    """``kernel(V, S, t, dt, jac)`` and ``update(V, S, dt)`` of the group P of
    class ``cls``: the step equations of its rates and residuals."""
    plan = step_plan(cls)
    residual, rates, switch = cls.residual, cls.rates, cls.switch
    if plan.cont.size == 0:
        def kernel(V, S, t, dt, jac):
            return residual(P, V, S, t, jac)

        if plan.disc.size:
            disc = plan.disc

            def update(V, S, dt):
                X = S.copy()
                X[:, disc] = switch(P, V, S)
                return X
        else:
            def update(V, S, dt):
                return S
        return kernel, update

    cont, all_cont, products = plan.cont, plan.all_cont, plan.products
    res_cols, n_jac = plan.res_cols, plan.n_jac
    n_res = len(res_cols)
    # the usual layouts (every class of the library): the residual's columns
    # are the first of the step Jacobian's, so it is filled in place, or after
    # one slice copy (a few us a call on small scenes against fancy indexing)
    in_place = plan.res_prefix and n_res == n_jac
    prefix = plan.res_prefix

    def end_states(V, S, dt, jac):
        R, dR = rates(P, V, S, jac)
        if all_cont:
            return S + dt * R, dR
        X = S.copy()
        X[:, cont] += dt * R
        return X, dR

    def kernel(V, S, t, dt, jac):
        X, dR = end_states(V, S, dt, jac)
        F, Jr = residual(P, V, X, t, jac)
        if not jac:
            return F, None
        if in_place:
            J = Jr[:, :n_jac]
        elif prefix:
            J = np.empty((P.n, n_jac))
            J[:, :n_res] = Jr[:, :n_res]
        else:
            J = np.empty((P.n, n_jac))
            J[:, res_cols] = Jr[:, :n_res]
        for col, kj, kr, add in products:
            term = (dt * dR[kr]) * Jr[:, kj]
            if add:
                J[:, col] += term
            else:
                J[:, col] = term
        return F, J

    def update(V, S, dt):
        X, _ = end_states(V, S, dt, False)
        if plan.disc.size:
            X[:, plan.disc] = switch(P, V, X)
        return X

    return kernel, update


def step_kernel(cls, P, V, S, t, dt, jac):
    """One call of the step equations (for tests and one-off evaluations; the
    assembly binds :func:`step_functions` once per group)."""
    return step_functions(cls, P)[0](V, S, t, dt, jac)


def step_update(cls, P, V, S, dt):
    """States at the end of one step (see :func:`step_kernel`)."""
    return step_functions(cls, P)[1](V, S, dt)


# -- derivatives for the sensitivity equations (softflow.solve.sensitivity) -------------
def linearizable(cls):
    """True where a class's step equations are those of its rates and residual
    (the rule; not a class that writes its own ``kernel``, such as a thermal
    deforming volume): :func:`step_linearization` then states their
    derivatives analytically."""
    from ..components.base import LibraryComponent
    return cls.kernel.__func__ is LibraryComponent.kernel.__func__


def step_point(cls, P, V, S, t, dt, jac=True):
    """One step's equations and, with ``jac``, every derivative the sensitivity
    equations need, from one call of ``rates`` and one of ``residual`` at the
    point (V, S = psi, dt = c). ``dt`` is a float or one value per row (n,):
    the rows may be steps of different sizes (rows of several steps stacked,
    :mod:`softflow.solve.sensitivity`). Returns

    F (n, n_eq)
        the step equations F(V, S + dt·r(V), t);
    J (n, len(jac_pattern))
        their Jacobian in V, as the step kernel's (None without ``jac``);
    X (n, n_states)
        the states at the end of the step, S + dt·r(V) (modes unchanged);
    FX (n, n_eq, n_continuous)
        dF/dX of ``residual`` at X (= d step equations / d psi);
    RV (n, n_continuous, n_vars)
        dr/dV of ``rates`` (the states' update moves by dt·RV per unit V).
    """
    plan = step_plan(cls)
    cont, ncont = plan.cont, plan.cont.size
    dtc = dt if np.ndim(dt) == 0 else np.asarray(dt, dtype=float)[:, None]
    if ncont:
        R, dR = cls.rates(P, V, S, jac)
        if plan.all_cont:
            X = S + dtc * R
        else:
            X = S.copy()
            X[:, cont] += dtc * R
    else:
        X, dR = S, ()
    F, Jr = cls.residual(P, V, X, t, jac)
    if not jac:
        return F, None, X, None, None
    n_res = len(plan.res_cols)
    FX = np.zeros((P.n, F.shape[1], ncont))
    for k, (e, s) in enumerate(cls.state_jac_pattern):
        FX[:, e, s] = Jr[:, n_res + k]
    RV = np.zeros((P.n, ncont, V.shape[1]))
    for k, (s, v) in enumerate(cls.rate_pattern):
        RV[:, s, v] = dR[k]
    # dF/dV + dF/dX · dt · dr/dV, placed as the step kernel places it
    # (step_functions; there on its hot path, with dt a float)
    J = np.empty((P.n, plan.n_jac))
    J[:, plan.res_cols] = Jr[:, :n_res]
    dtv = dt if np.ndim(dt) == 0 else np.asarray(dt, dtype=float)
    for col, kj, kr, add in plan.products:
        term = (dtv * dR[kr]) * Jr[:, kj]
        if add:
            J[:, col] += term
        else:
            J[:, col] = term
    return F, J, X, FX, RV


def step_linearization(cls, P, V, S, t, dt):
    """The derivatives of one step's equations that the sensitivity equations
    need besides the step Jacobian, at the point (V, S = psi, dt = c): (X, FX,
    RV) of :func:`step_point`."""
    _, _, X, FX, RV = step_point(cls, P, V, S, t, dt)
    return X, FX, RV


def param_step_derivative(cls, P, V, X, FX, t, dt, name):
    """d(step equations)/d theta and d(end states)/d theta of the group P for
    its parameter ``name``, from the class's own ``param_jacobian``, or None
    where the class (not a parent: a thermal variant or a subclass with another
    law must not inherit it) states none for ``name``:

        dG/dtheta = dF/dtheta + dF/dX · dt · dr/dtheta,   dX/dtheta = dt · dr/dtheta

    (X, FX from :func:`step_point`; ``dt`` a float or one value per row).
    Returns ((n, n_eq), (n, n_continuous))."""
    if "param_jacobian" not in cls.__dict__:
        return None
    out = cls.param_jacobian(P, V, X, t, name)
    if out is None:
        return None
    dF, dr = out
    dtc = dt if np.ndim(dt) == 0 else np.asarray(dt, dtype=float)[:, None]
    dX = dtc * np.asarray(dr, dtype=float).reshape(P.n, FX.shape[2])
    dF = np.asarray(dF, dtype=float).reshape(P.n, FX.shape[1])
    if dX.size:
        dF = dF + np.einsum("nes,ns->ne", FX, dX)
    return dF, dX
