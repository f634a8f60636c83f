"""Sensitivities worked out a chunk of steps at a time (deferred evaluation).

The part of :class:`softflow.solve.sensitivity.Sensitivities` that evaluates
buffered steps together: see that module's docstring ("How it is
evaluated"). The integrators' calls arrive there; what lands here is the
buffer, the stacked evaluation of the rate-form groups over the steps, the
solves (stacked dense, or a sparse LU per step) and the sequential replay of
the states' sensitivities along the integrator's log.
"""
from __future__ import annotations

import copy
import warnings

import numpy as np
from scipy.sparse import csc_matrix
from scipy.sparse.linalg import splu

from .bdf import _PRED_PSI
from .discretize import param_step_derivative, step_point

#: Steps buffered before they are worked out together.
CHUNK = 256
#: The log's mark of the point t = 0 (step orders are >= 0).
INITIAL = -1


class SensitivityWarning(RuntimeWarning):
    """Sensitivities that could not be computed from some step on (NaN there)."""


class DeferredSteps:
    """Mixin of :class:`softflow.solve.sensitivity.Sensitivities`: the deferred
    evaluation (state set up by :meth:`_setup_deferred`)."""

    def _push(self, x, psi, t, c, k):
        # a full buffer is worked out when the next step comes (or at the end),
        # so that the operations logged after its last step (a switch's jump,
        # a restart) are replayed with it
        if self._n_buf == CHUNK:
            self._flush()
        j = self._n_buf
        self._bx[j], self._bpsi[j] = x, psi
        self._bt[j], self._bc[j] = t, c
        self._n_buf = j + 1
        self._log.append(k)

    def _setup_deferred(self):
        asm, n, n_s = self.asm, self.asm.n, len(self.asm.S0)
        self._n_buf, self._log = 0, []
        self._bx, self._bpsi = np.empty((CHUNK, n)), np.empty((CHUNK, n_s))
        self._bt, self._bc = np.empty(CHUNK), np.empty(CHUNK)
        self._tiles = {}
        # per group: (group, class, Params, time-free); where the entries of its
        # FX (n, neq, ncont) and RV (n, ncont, nv) go in d(step equations)/d psi
        # and in the states' d(update)/dx, all groups' in turn
        self._dgroups = []
        fx_rows, fx_cols, rv_rows, rv_cols = [], [], [], []
        for key, (g, cls, P, cont) in self._params_of.items():
            self._dgroups.append((g, cls, P, _time_free(g.comps)))
            ncont = cont.size
            if not ncont:
                continue
            inst = np.arange(g.n)[:, None, None]
            shape = (g.n, g.neq, ncont)
            fx_rows.append(np.broadcast_to(
                g.r0 + inst * g.neq + np.arange(g.neq)[None, :, None], shape).ravel())
            fx_cols.append(np.broadcast_to(g.s0 + inst * g.ns + cont[None, None, :],
                                           shape).ravel())
            shape = (g.n, ncont, g.col.shape[1])
            rv_rows.append(np.broadcast_to(g.s0 + inst * g.ns + cont[None, :, None],
                                           shape).ravel())
            rv_cols.append(np.broadcast_to(g.col[:, None, :], shape).ravel())
        empty = np.zeros(0, dtype=np.int64)
        self._fx_rows, self._fx_cols, self._rv_rows, self._rv_cols = (
            np.concatenate(a) if a else empty for a in (fx_rows, fx_cols, rv_rows, rv_cols))
        self._keep = np.ones(n_s)            # the update keeps psi's continuous states
        if asm.has_discrete:
            self._keep[asm.s_discrete] = 0.0
        # per parameter: (group entry, instance, rows of its equations, columns of
        # its continuous states)
        self._dparams = []
        for p, (g, i, _, _, eps, comp, twin) in enumerate(self.parameters):
            entry = next(e for e in self._dgroups if e[0] is g)
            cont = self._params_of[id(g)][3]
            self._dparams.append((entry, i, slice(g.r0 + i * g.neq, g.r0 + (i + 1) * g.neq),
                                  g.s0 + i * g.ns + cont))
        self._one = {}       # Params of one component (a parameter's own, its twin's)

    def _tiled(self, key, cls, P, comps, m):
        """P for m stacked copies of comps (one row per instance and step)."""
        got = self._tiles.get((key, m))
        if got is None:
            got = self._tiles[(key, m)] = _tile_params(cls, P, comps, m)
        return got

    def _over_steps(self, fn, key, cls, P, comps, free, rows, T):
        """fn(Params, *row arrays, t) for the stacked rows of the buffered steps:
        one call on Params tiled over the steps where the group does not read
        the time (the steps padded with copies of the last to a power of two,
        so that a run tiles its Params for few sizes), else one call per step."""
        m = len(T)
        per = rows[0].shape[0] // m
        if free:
            size = min(1 << (m - 1).bit_length(), max(CHUNK, m))
            if size > m:
                # (whole steps: row k of the stack is instance k mod per)
                rows = [np.concatenate([r, np.tile(r[-per:], (size - m,) + (1,) * (r.ndim - 1))])
                        for r in rows]
            out = fn(self._tiled(key, cls, P, comps, size), *rows, T[0])
            if out is None or size == m:
                return out
            return tuple(None if o is None else o[:m * per] for o in out)
        outs = [fn(P, *(r[j * per:(j + 1) * per] for r in rows), T[j]) for j in range(m)]
        if outs[0] is None:
            return None
        return tuple(None if parts[0] is None else np.concatenate(parts)
                     for parts in zip(*outs))

    def _stacked(self, X, PSI, T, cv):
        """Every derivative at the points (rows of X, PSI, T, cv) at once (one
        rates+residual call per group on the points stacked): the step
        Jacobians' entries RAW (m, as ``asm.raw``), dF/dpsi's FXW (m, at
        _fx_rows, _fx_cols), dr/dV's RVW (m, at _rv_rows, _rv_cols), dF/dtheta
        GT (m, n, n_p) and the states' c·dr/dtheta DS (m, n_s, n_p)."""
        asm, n, n_s, n_p = self.asm, self.asm.n, len(self.asm.S0), self.n_p
        m = len(T)
        RAW = np.empty((m, asm.raw.size))
        RAW[:] = asm.raw                  # the node rows' entries (constant)
        fxw, rvw, at = [], [], {}
        for key, (g, cls, P, free) in enumerate(self._dgroups):
            V = X[:, g.col].reshape(m * g.n, -1)
            Sg = PSI[:, g.s0:g.s1].reshape(m * g.n, g.ns)
            cc = np.repeat(cv, g.n) if g.n > 1 else cv
            F, J, Xe, FX, RV = self._over_steps(
                lambda Q, V_, S_, c_, t_: step_point(cls, Q, V_, S_, t_, c_),
                key, cls, P, g.comps, free, (V, Sg, cc), T)
            RAW[:, g.j0:g.j1] = J.reshape(m, -1)
            if FX.size:
                fxw.append(FX.reshape(m, -1))
                rvw.append(RV.reshape(m, -1))
            at[id(g)] = (V, Sg, F, Xe, FX)
        GT = np.zeros((m, n, n_p))
        DS = np.zeros((m, n_s, n_p))
        for p, ((g, cls, P, free), i, rows, cols) in enumerate(self._dparams):
            dG, dX = self._parameter_rows(p, g, cls, P, i, free, at[id(g)], T, cv)
            GT[:, rows, p] = dG
            if dX.size:
                DS[:, cols, p] = dX
        FXW = np.concatenate(fxw, axis=1) if fxw else np.zeros((m, 0))
        RVW = np.concatenate(rvw, axis=1) if rvw else np.zeros((m, 0))
        return RAW, FXW, RVW, GT, DS

    def _pieces(self, X, PSI, T, cv):
        """Dense networks: s_x = -(A s_psi + B) and the states' s_S = s_psi Mt + dt
        (rows of (n_p, n_s)) at the points, from :meth:`_stacked` and one
        batched solve with the step Jacobians."""
        n, n_s = self.asm.n, len(self.asm.S0)
        m = len(T)
        RAW, FXW, RVW, GT, DS = self._stacked(X, PSI, T, cv)
        J = np.bincount((np.arange(m)[:, None] * (n * n) + self._flat).ravel(),
                        weights=RAW.ravel(), minlength=m * n * n).reshape(m, n, n)
        GPSI = np.zeros((m, n, n_s + self.n_p))   # [d(step eqs)/d psi | d/d theta]
        GPSI[:, self._fx_rows, self._fx_cols] = FXW
        GPSI[:, :, n_s:] = GT
        Z, self._singular_step = _solve_stacked(J, GPSI)
        A, B = Z[:, :, :n_s], Z[:, :, n_s:]
        # s_S = keep·s_psi + c RV s_x + dS with s_x = -(A s_psi + B):
        # s_S = M s_psi + d, M = keep - c RV A, d = dS - c RV B
        if RVW.size:
            RVg = np.bincount((np.arange(m)[:, None] * (n_s * n)
                               + self._rv_rows * n + self._rv_cols).ravel(),
                              weights=RVW.ravel(), minlength=m * n_s * n).reshape(m, n_s, n)
            cRV = cv[:, None, None] * RVg
            M = -(cRV @ A)
            d = DS - cRV @ B
        else:
            M, d = np.zeros((m, n_s, n_s)), DS
        M[:, np.arange(n_s), np.arange(n_s)] += self._keep
        return A, B, M.transpose(0, 2, 1), d.transpose(0, 2, 1)

    def _flush(self):
        """The buffered steps: their pieces at once (:meth:`_pieces`), then the
        states' sensitivities along the log (the sequential part: a log-depth
        scan of the affine maps for backward Euler, the BDF table's operations
        in turn), then the unknowns' at once. Sparse networks:
        :meth:`_flush_sparse`."""
        if not self._dense:
            return self._flush_sparse()
        m = self._n_buf
        A, B, Mt, dt = self._pieces(self._bx[:m], self._bpsi[:m], self._bt[:m], self._bc[:m])
        if self._log[0] == INITIAL:       # the point t = 0: its s_S are the initial states'
            Mt[0], dt[0] = np.eye(Mt.shape[1]), 0.0
        if not self._bdf:                 # backward Euler: s_psi is the last s_S
            SS = _affine_scan(self._sS, Mt, dt)
            PSIP = np.concatenate([self._sS[None], SS[:-1]])
            self._sS = SS[-1]
        else:
            PSIP, SS = self._replay(lambda j, psi_p, op: psi_p @ Mt[j] + dt[j],
                                    lambda j, psi_p: -(psi_p @ A[j].T + B[j].T))
        s_x = -(PSIP @ A.transpose(0, 2, 1) + B.transpose(0, 2, 1))
        self._check_finite(s_x, SS, m)
        self._record(s_x, SS)
        self._n_buf, self._log = 0, []

    def _flush_sparse(self):
        """Sparse networks: the pieces at once (:meth:`_stacked`), then step by
        step J s_x = -(dF/dpsi s_psi + dF/dtheta) with the step's exact J
        (a sparse LU of its own, Newton's factors untouched) and the states'
        update, along the log."""
        asm, n, n_s, n_p = self.asm, self.asm.n, len(self.asm.S0), self.n_p
        m = self._n_buf
        cv = self._bc[:m]
        RAW, FXW, RVW, GT, DS = self._stacked(self._bx[:m], self._bpsi[:m], self._bt[:m], cv)
        if asm.duplicates:
            DATA = np.bincount((np.arange(m)[:, None] * asm.nnz + asm._inv).ravel(),
                               weights=RAW.ravel(), minlength=m * asm.nnz).reshape(m, asm.nnz)
        else:
            DATA = np.ascontiguousarray(RAW[:, asm._order])
        fx_at = (np.arange(n_p)[:, None] * n + self._fx_rows).ravel()
        rv_at = (np.arange(n_p)[:, None] * n_s + self._rv_rows).ravel()
        fx_cols, rv_cols, keep = self._fx_cols, self._rv_cols, self._keep
        GTt, DSt = GT.transpose(0, 2, 1), DS.transpose(0, 2, 1)
        SX = np.full((m, n_p, n), np.nan)
        self._singular_step = None      # the step whose factorization fails, if one does
        J = csc_matrix((DATA[0], asm.indices, asm.indptr), shape=(n, n))   # its pattern

        def advance(j, psi_p, op):
            rhs = np.bincount(fx_at, weights=(FXW[j] * psi_p[:, fx_cols]).ravel(),
                              minlength=n_p * n).reshape(n_p, n) + GTt[j]
            J.data = DATA[j]
            try:
                lu = splu(J, permc_spec="COLAMD", relax=1)
            except RuntimeError:          # exactly singular: NaN from here on
                if self._singular_step is None:
                    self._singular_step = j
                return np.full_like(psi_p, np.nan)
            s_x = -lu.solve(np.ascontiguousarray(rhs.T)).T
            SX[j] = s_x
            if op == INITIAL:
                return psi_p
            return keep * psi_p + cv[j] * np.bincount(
                rv_at, weights=(RVW[j] * s_x[:, rv_cols]).ravel(),
                minlength=n_p * n_s).reshape(n_p, n_s) + DSt[j]
        _, SS = self._replay(advance, lambda j, psi_p: SX[j])
        self._check_finite(SX, SS, m)
        self._record(SX, SS)
        self._n_buf, self._log = 0, []

    def _check_finite(self, SX, SS, m):
        """Warn once (:class:`SensitivityWarning`) at the first buffered step whose
        sensitivities are not finite, naming its time and why; they stay NaN from
        there on (each step's s_psi is formed from the last ones)."""
        if getattr(self, "_failed_at", None) is not None:
            return
        bad = ~(np.isfinite(SX).all(axis=(1, 2)) & np.isfinite(SS).all(axis=(1, 2)))
        if not bad.any():
            return
        j = int(np.argmax(bad))
        self._failed_at = t = float(self._bt[j])
        names = [self.names[p] for p in range(self.n_p)
                 if not (np.isfinite(SX[j, p]).all() and np.isfinite(SS[j, p]).all())]
        # singular where that step's factorization failed (known from the solve:
        # a rank test of the unscaled J, whose rows mix Pa and kg/s, is no test)
        why = ("the step Jacobian is singular there" if j == self._singular_step
               else "a derivative of the step equations is not finite there")
        warnings.warn(f"sensitivities to {', '.join(names)} are NaN from t = {t:.6g} s on: "
                      f"{why}, so the sensitivity equations J s = -(dF/dpsi s_psi + "
                      "dF/dtheta) have no unique solution at that step", SensitivityWarning,
                      stacklevel=2)

    def _replay(self, advance, unknowns):
        """(s_psi, s_S) of the buffered steps along the log: each step's s_psi
        from the last s_S (backward Euler) or the BDF table, its s_S from
        ``advance(j, s_psi, order)``, the table's operations in turn; a
        switch's jump from the last step's s_x, ``unknowns(j, s_psi)``."""
        m, (n_p, n_s) = self._n_buf, self._sS.shape
        PSIP = np.empty((m, n_p, n_s))
        SS = np.empty((m, n_p, n_s))
        sS, table, j = self._sS, self._table, 0
        for op in self._log:
            if type(op) is int:
                if op > 0:
                    # BDF._difference_update as one product: rows 0..k gain the
                    # rows below them up to k and the new difference, row k + 1
                    # is it, row k + 2 it less the old row k + 1
                    pred, psi_p = _PRED_PSI[op] @ table[:op + 1]
                    psi_p = psi_p.reshape(n_p, n_s)
                    sS = advance(j, psi_p, op)
                    table[:op + 3] = _UPDATE[op] @ table[:op + 3] + (sS.ravel() - pred)
                else:
                    psi_p = sS
                    sS = advance(j, psi_p, op)
                PSIP[j], SS[j] = psi_p, sS
                j += 1
            elif op[0] == "jump":
                sS = SS[j - 1] = _jumped(unknowns(j - 1, PSIP[j - 1]), sS, op)
            else:
                self._sS = sS
                self._apply(op)
                table = self._table
        self._sS = sS
        return PSIP, SS

    def _parameter_rows(self, p, g, cls, P, i, free, at, T, cv):
        """(dG/dtheta (m, neq), dX/dtheta (m, n_continuous)) of parameter p over the
        points: its class's ``param_jacobian`` where it states one, else a finite
        difference of its twin's step equations and update."""
        V, Sg, F, Xe, FX = at
        m = len(T)
        comp, twin = self.parameters[p][5:7]

        def rows(a):
            return a if g.n == 1 else a.reshape(m, g.n, *a.shape[1:])[:, i]
        Vi, Si, Xi, FXi = rows(V), rows(Sg), rows(Xe), rows(FX)
        if self._exact[p] is not False:
            name = self.names[p].rsplit(".", 1)[1]
            Pi = P if g.n == 1 else self._one_params(("param", p), cls, comp)
            out = self._over_steps(
                lambda Q, V_, X_, FX_, c_, t_: param_step_derivative(cls, Q, V_, X_, FX_,
                                                                     t_, c_, name),
                ("param", p), cls, Pi, [comp], free, (Vi, Xi, FXi, cv), T)
            self._exact[p] = out is not None
            if out is not None:
                return out
        eps = self.parameters[p][4]
        tcls = twin.kernel_class()
        Ft, _, Xt, _, _ = self._over_steps(
            lambda Q, V_, S_, c_, t_: step_point(tcls, Q, V_, S_, t_, c_, jac=False),
            ("twin", p), tcls, self._one_params(("twin", p), tcls, twin), [twin], free,
            (Vi, Si, cv), T)
        cont = self._params_of[id(g)][3]
        return (Ft - rows(F)) / eps, (Xt[:, cont] - Xi[:, cont]) / eps

    def _one_params(self, key, cls, comp):
        got = self._one.get(key)
        if got is None:
            got = self._one[key] = cls.make_params([comp])
        return got


def _update_matrix(k):
    """L with D_new[:k+3] = L @ D[:k+3] + d (every row) for
    :meth:`softflow.solve.bdf.BDF._difference_update` at order k."""
    L = np.zeros((k + 3, k + 3))
    for i in range(k + 1):
        L[i, i:k + 1] = 1.0
    L[k + 2, k + 1] = -1.0
    L.setflags(write=False)
    return L


_UPDATE = [None] + [_update_matrix(k) for k in range(1, len(_PRED_PSI))]


def _affine_scan(s0, Mt, dt):
    """s_j = s_{j-1} Mt_j + dt_j for j = 0..m-1 from s_{-1} = s0, every j at once:
    the maps composed in log2(m) rounds of stacked products (Hillis-Steele)."""
    Mt, dt = Mt.copy(), dt.copy()
    m, off = len(Mt), 1
    while off < m:
        # map j after map j - off: s Mt_{j-off} Mt_j + dt_{j-off} Mt_j + dt_j
        dt[off:] = dt[:-off] @ Mt[off:] + dt[off:]
        Mt[off:] = Mt[:-off] @ Mt[off:]
        off *= 2
    return s0 @ Mt + dt


def _jumped(s_x, s_S, jump):
    """s_S after a located switch: s_S - (rate change) dt*/dtheta, with
    dt*/dtheta = -(dg/dx s_x + dg/dS s_S + dg/dtheta) / (dg/dt) per parameter."""
    _, gx, gS, gth, gdot, change = jump
    dtau = -(s_x @ gx + s_S @ gS + gth) / gdot
    return s_S - dtau[:, None] * change[None, :]


def _time_free(comps):
    """True where a group's equations do not read the time: softflow's own
    classes read it only through a source's signal (a constant here)."""
    for c in comps:
        if not type(c).__module__.startswith("softflow.components"):
            return False
        signal = getattr(c, "signal", None)
        if signal is not None and getattr(signal, "func", None) is not None:
            return False
    return True


def _tile_params(cls, P, comps, m):
    """``cls.make_params(comps * m)``, made by tiling P where a trial with two
    copies shows that is what it is (every per-instance array repeated, every
    other attribute the same object or an equal plain value), else by
    make_params itself."""
    if m == 1:
        return P
    P2 = cls.make_params(list(comps) * 2)
    a, b = vars(P), vars(P2)
    if a.keys() != b.keys():
        return cls.make_params(list(comps) * m)
    tiled = []
    for key, v in a.items():
        w = b[key]
        if key == "n" or key == "components":
            continue
        if type(v) is np.ndarray:
            # bitwise (stricter than ==; a mismatch only costs make_params)
            if (type(w) is np.ndarray and v.ndim and w.dtype == v.dtype
                    and w.shape == (2 * v.shape[0],) + v.shape[1:]
                    and w.tobytes() == v.tobytes() * 2):
                tiled.append(key)
            elif not (type(w) is np.ndarray and w.dtype == v.dtype and w.shape == v.shape
                      and w.tobytes() == v.tobytes()):
                return cls.make_params(list(comps) * m)
        elif not (w is v or (type(v) in _PLAIN and type(w) is type(v) and w == v)
                  or (type(v) in (list, tuple) and not v and w == v)):
            return cls.make_params(list(comps) * m)
    Q = copy.copy(P)
    for key in tiled:
        v = a[key]
        setattr(Q, key, v.repeat(m, axis=0) if v.shape[0] == 1
                else np.tile(v, (m,) + (1,) * (v.ndim - 1)))
    Q.n = P.n * m
    Q.components = list(P.components) * m
    return Q


_PLAIN = (int, float, bool, str, type(None), np.float64, np.int64, np.bool_)


def _solve_stacked(J, R):
    """(Z, None) with J[j] Z[j] = R[j] for every step j; a singular J[j] leaves
    NaN from its step on: (Z, j)."""
    try:
        return np.linalg.solve(J, R), None
    except np.linalg.LinAlgError:
        Z = np.full(R.shape, np.nan)
        for j in range(len(J)):
            try:
                Z[j] = np.linalg.solve(J[j], R[j])
            except np.linalg.LinAlgError:
                return Z, j
        return Z, None
