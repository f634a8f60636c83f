"""Forward sensitivities of a run with respect to run-time parameters.

``Simulation.run(sensitivities=["tube.diameter", ...])`` differentiates the
computed solution with respect to each named parameter (a numeric argument
of a library component's constructor, named as in ``run(params=...)``),
alongside the run, by the staggered direct method: after every accepted
step, with the step's equations

    F(x, psi + c r(x; theta), t; theta) = 0       (states S = psi + c r)

differentiated along the parameter, the unknowns' sensitivity s_x solves

    J s_x = -(dF/dpsi s_psi + dF/dtheta)

with J the stepper's own iteration matrix (its LU factors, already made:
a few corrections, each one residual evaluation, converge the stale-factor
solve; fresh factors at the point where they do not), and the states'
sensitivity follows from the step's update, s_S = s_psi + c (dr/dx s_x +
dr/dtheta). s_psi is formed from the states' sensitivities exactly as psi is
from the states (the same difference table for BDF, the last step's for
backward Euler), so the sensitivities are those of the discrete solution the
stepper computed. The products of dF/dpsi, dr/dx and the parameter derivatives
with the sensitivity vectors are directional finite differences (relative
step 1e-6) of the compiled equations, one residual and one update
evaluation each: every library component and user component is covered
without a hand-written parameter Jacobian.

At t = 0 the initial states' sensitivity is that of the component's initial
states (e.g. a Container's mass to its volume), and the unknowns' follows from
the consistent-initial-value equations. At a discrete switch (a valve
snapping, a hysteretic branch change) the derivative is that of the solution
with the switch time held where it fell; a parameter that moves the switch
time has, there, a derivative that this does not include.
"""
from __future__ import annotations

import numpy as np

from ..network.system import NetworkError
from .params import STRUCTURAL, parameter_names, rebuild
from .thermal import configure_like

#: Relative step of the directional finite differences.
REL_STEP = 1e-6
#: Corrections of a stale-factor solve before fresh factors are made.
MAX_CORRECTIONS = 6


class Sensitivities:
    """The sensitivity equations of a compiled network for a list of parameters."""

    def __init__(self, asm, newton, names, components, thermal="isothermal"):
        self.asm, self.newton = asm, newton
        self.names = list(names)
        # per parameter: (group, index in group, perturbed kernel, perturbed update,
        # step, the compiled component, its perturbed twin)
        self.parameters = []
        from .assembly import _library_group
        for key in self.names:
            if not isinstance(key, str) or "." not in key:
                raise KeyError(f"sensitivities: {key!r} is not 'label.parameter' "
                               "(e.g. 'tube.diameter')")
            label, name = key.rsplit(".", 1)
            if label not in asm.where:
                have = ", ".join(repr(x) for x in sorted(asm.where)[:20])
                raise KeyError(f"sensitivities: no component {label!r}; the components are "
                               f"{have}")
            g, i = asm.where[label]
            comp = components[label]
            valid = parameter_names(comp) if getattr(comp, "vectorized", False) else []
            if name in STRUCTURAL:
                raise NetworkError(f"sensitivities[{key!r}]: {name} defines the network's "
                                   "structure, not a number of the model; sensitivities are "
                                   f"taken with respect to {', '.join(valid)}")
            if name not in valid:
                raise KeyError(f"sensitivities[{key!r}]: {comp.describe()} has no parameter "
                               f"{name!r}; its parameters are {', '.join(valid) or 'none'}")
            value = getattr(comp, name, None)
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float)):
                raise NetworkError(
                    f"sensitivities[{key!r}]: {comp.describe()}'s {name!r} is not a number "
                    f"({value!r}); sensitivities are taken with respect to numeric "
                    "parameters (e.g. a diameter, a volume, a pressure)")
            eps = REL_STEP * (abs(value) if value != 0 else 1.0)
            twin = configure_like(rebuild(comp, {name: value + eps}), comp, thermal)
            comps = list(g.comps)
            comps[i] = twin
            fresh = _library_group(twin.kernel_class(), comps)
            self.parameters.append((g, i, fresh.kernel, fresh.update, eps, comp, twin))
        self.n_p = len(self.parameters)
        self.records_x, self.records_s = [], []

    # -- the equations ----------------------------------------------------------------
    def _perturbed_residual(self, p, x, S, t, c, F):
        """F with the rows of parameter p's group from its perturbed kernel."""
        g, i, kernel_p = self.parameters[p][:3]
        Sg = S[g.s0:g.s1].reshape(g.n, g.ns)
        Fg, _ = kernel_p(x[g.col], Sg, t, c, False)
        F = F.copy()
        F[g.r0:g.r1] = Fg.ravel()
        return F

    def _perturbed_update(self, p, x, S, c):
        g, i, _, update_p = self.parameters[p][:4]
        new = self.asm.update_states(x, S, c).copy()
        if g.ns:
            new[g.s0:g.s1] = np.asarray(update_p(x[g.col], S[g.s0:g.s1].reshape(g.n, g.ns),
                                                 c)).ravel()
        return new

    def _solve(self, p, x, psi, s_psi, t, c, s_x, F0, fresh=False):
        """s_x of parameter p at the converged point (x, psi, t, c), where the
        residual is F0."""
        asm, newton = self.asm, self.newton
        eps = self.parameters[p][4]

        def residual_of(s):
            Fp = asm.residual(x + eps * s, psi + eps * s_psi, t, c)
            Fp = self._perturbed_residual(p, x + eps * s, psi + eps * s_psi, t, c, Fp)
            return (Fp - F0) / eps

        fresh = fresh or getattr(newton, "stale", False) or newton.lu_dt is None
        for attempt in range(2):
            if fresh:
                asm.residual(x, psi, t, c, jac=True)
                newton._factor(c)
            # factors made at this point (this step's c, no step since): one
            # correction solves the linear sensitivity equations exactly
            exact = newton.lu_dt == c and newton.age == 0 and not getattr(newton, "stale",
                                                                        False)
            s = s_x.copy()
            for _ in range(MAX_CORRECTIONS):
                ds = newton.lin.solve(-residual_of(s))
                s = s + ds
                if exact or (newton._norm(ds * eps)
                             <= 1e-3 * max(newton._norm(s * eps), 1e-12) + 1e-6):
                    return s
            fresh = True
        return s

    def step(self, x, psi, s_psi, t, c):
        """(s_x, s_S) (n_p x n, n_p x n_s) after a step converged to x from psi."""
        asm = self.asm
        s_x = np.zeros((self.n_p, asm.n))
        s_S = np.zeros((self.n_p, len(asm.S0)))
        S_new = asm.update_states(x, psi, c)
        F0 = asm.residual(x, psi, t, c)       # the same point for every parameter
        last = self.records_x[-1] if self.records_x else None
        for p in range(self.n_p):
            start = last[p] if last is not None else np.zeros(asm.n)
            s_x[p] = self._solve(p, x, psi, s_psi[p], t, c, start, F0)
            eps = self.parameters[p][4]
            moved = self._perturbed_update(p, x + eps * s_x[p], psi + eps * s_psi[p], c)
            s_S[p] = (moved - S_new) / eps
        if asm.has_discrete:
            s_S[:, asm.s_discrete] = 0.0
        self.record(s_x, s_S)
        return s_x, s_S

    def initial(self, x0, S0, t0=0.0):
        """Sensitivities at the consistent initial point: the initial states' from
        the components' own, the unknowns' from the t = 0 equations (c = 0)."""
        s_S0 = np.zeros((self.n_p, len(S0)))
        for p, (g, i, *_rest) in enumerate(self.parameters):
            comp, twin, eps = self.parameters[p][5], self.parameters[p][6], self.parameters[p][4]
            if g.ns:
                a = np.array(comp.initial_state_values(), dtype=float)
                b = np.array(twin.initial_state_values(), dtype=float)
                s_S0[p, g.s0 + i * g.ns:g.s0 + (i + 1) * g.ns] = (b - a) / eps
        s_x0 = np.zeros((self.n_p, len(x0)))
        F0 = self.asm.residual(x0, S0, t0, 0.0)
        for p in range(self.n_p):
            s_x0[p] = self._solve(p, x0, S0, s_S0[p], t0, 0.0, np.zeros(len(x0)), F0,
                                  fresh=p == 0)
        self.record(s_x0, s_S0)
        return s_x0, s_S0

    def record(self, s_x, s_S):
        self.records_x.append(s_x)
        self.records_s.append(s_S)

    def arrays(self, x_index, s_index):
        """{parameter: (s_x over time (T x recorded unknowns), s_S (T x recorded states))}."""
        n_x, n_s = self.asm.n, len(self.asm.S0)
        X = np.array(self.records_x).reshape(-1, self.n_p, n_x)
        S = np.array(self.records_s).reshape(-1, self.n_p, n_s)
        return {name: (X[:, p][:, x_index], S[:, p][:, s_index])
                for p, name in enumerate(self.names)}
