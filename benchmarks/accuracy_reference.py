"""Reference solutions and third-party solvers for the air-chain work-precision benchmark.

Scene (``air_chain``): PressureSource -> (CircularTube -> Container) x N, ideal-gas
air (``sf.air``), isothermal, laminar tubes (``friction='laminar'``,
``compressible='mean_density'``: the equations below; the default pipe-flow law
adds the exit's dynamic pressure), tubes 0.2 m x 2 mm, containers 5 mL at 1 atm; the
source holds 1 atm + 0.2 bar from t = 0, for 0.2 s. Error measure: the largest
|p - p_ref| over the containers and the solver's own output times, divided by the
step STEP_PA = 0.2e5 Pa. (Only output times count: a solver with few, long steps is
not charged for its error between them.)

The same equations as softflow's kernels, as an explicit ODE in the container masses
m_i (the network's only states):

    p_i  = m_i R T / V                       Container: density(p) V = m, rho = p/(R T)
    q_i  = rho(pm) (p_{i-1} - p_i) / (64 c)  CircularTube, laminar: dp = 64 c / rho(pm) q,
         = K (p_{i-1}^2 - p_i^2)             c = mu L / (2 A D^2), pm = (p_{i-1} + p_i)/2,
                                             K = 1 / (128 R T c), p_{-1} = source pressure
    dm_i/dt = q_i - q_{i+1}                  (q_N = 0: the last container is a dead end)

mu is ``sf.air.viscosity`` at 1 atm (a constant at the 'ideal' level), R T is
``sf.air.R * sf.air.temperature``. The Jacobian is tridiagonal and analytic.
``python benchmarks/accuracy_reference.py --verify`` shows softflow's fixed-step
backward Euler converging to this ODE's solution at first order (no error floor).

The reference is scipy Radau at rtol 1e-13 (atol 1e-20 kg, the masses being ~6e-6 kg),
cached in benchmarks/.cache/ as its step points (t, m); between them it is the quintic
Hermite interpolant of m, m' = f(m), m'' = J(m) f(m) (local error O(h^6), like the
steps themselves, and independent of scipy's private dense-output classes).

Solvers compared (all with analytic banded/sparse Jacobians), each ``run_*`` returning
(cpu seconds [time.process_time, median of repeats for short runs], error, steps):

- ``run_scipy('BDF' | 'Radau', N, rtol)``: solve_ivp on the mass ODE (Jacobian dense
  below 32 containers, sparse CSC, i.e. SuperLU, above);
- ``run_cvode(N, rtol)``: SUNDIALS CVODE (BDF) via scikit-sundae, band solver;
- ``run_ida(N, rtol)``: SUNDIALS IDA on the DAE in softflow-like unknowns: masses
  differential, container pressures and tube flows algebraic (3N unknowns, index 1),
  band solver.

atol choice: atol = rtol x DM (masses, DM = V x 0.2 bar / (R T), the mass one container
gains over the step), rtol x 0.2 bar (IDA's pressures) and rtol x the initial flow
(IDA's flows). An absolute error of atol in a mass is rtol x STEP_PA in its pressure,
i.e. rtol in the benchmark's error unit; the masses never fall below m0 ~ 5 DM, so the
relative part rtol |m| dominates the weights anyway.

    python benchmarks/accuracy_reference.py            # tables, N = 8 and 200 (~15 s)
    python benchmarks/accuracy_reference.py --rtols 1e-2 1e-4 1e-6 1e-8 1e-10 --N 200
    python benchmarks/accuracy_reference.py --verify   # softflow fixed-step vs the reference
"""
from __future__ import annotations

import argparse
import functools
import statistics
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sps
from scipy.integrate import solve_ivp

import softflow as sf
from scenes import chain

P_ATM = sf.pressure_atmospheric
STEP_PA = 0.2e5                      # Pa: the source step, and the error's unit
DURATION = 0.2                       # s
LENGTH, DIAMETER, VOLUME = 0.2, 2e-3, 5e-6   # as benchmarks/scenes.chain
REF_RTOL, REF_ATOL = 1e-13, 1e-20    # reference tolerances (atol in kg)
CACHE = Path(__file__).resolve().parent / ".cache"
RTOLS = tuple(10.0 ** -k for k in range(2, 9))
SOLVERS = ("scipy BDF", "scipy Radau", "IDA", "CVODE")
TARGETS = (1e-2, 1e-4, 1e-6)


def air_chain(N, friction="laminar", fluid=None):
    """The softflow System: ``scenes.chain`` (PressureSource -> (CircularTube ->
    Container) x N) with this module's parameters and the tubes' friction law."""
    return chain(N, fluid=fluid, p_source=P_ATM + STEP_PA, length=LENGTH, diameter=DIAMETER,
                 volume=VOLUME, friction=friction, compressible="mean_density")


class ChainODE:
    """The air chain's equations (module doc) as an ODE in the masses, and as a DAE."""

    def __init__(self, N):
        self.N = N
        self.RT = sf.air.R * sf.air.temperature
        mu = float(sf.air.viscosity(P_ATM))
        area = np.pi * DIAMETER ** 2 / 4.0
        self.c_mu = mu * LENGTH / (2.0 * area * DIAMETER ** 2)   # as set_tube_coefficients
        self.K = 1.0 / (128.0 * self.RT * self.c_mu)
        self.k = self.RT / VOLUME                                # p = k m
        self.p_src = P_ATM + STEP_PA
        self.m0 = np.full(N, P_ATM / self.k)
        self.dm_step = STEP_PA / self.k                          # DM of the module doc
        self.q0 = self.K * (self.p_src ** 2 - P_ATM ** 2)        # the initial flow
        # everything the solution depends on, to validate the disk cache
        self.key = np.array([N, self.RT, mu, LENGTH, DIAMETER, VOLUME, P_ATM, STEP_PA])

    def flows(self, p):
        """Tube flows q_i into container i, for pressures p of shape (N, ...)."""
        up = np.concatenate((np.broadcast_to(self.p_src, (1,) + p.shape[1:]), p[:-1]))
        return self.K * (up - p) * (up + p)

    def rhs(self, t, m):
        """dm/dt (m of shape (N,) or (N, n))."""
        q = self.flows(self.k * m)
        dm = q.copy()
        dm[:-1] -= q[1:]
        return dm

    def jac_diagonals(self, m):
        """(sub, main, super) diagonals of d(dm/dt)/dm (m of shape (N,) or (N, n))."""
        p = self.k * m
        off = 2.0 * self.K * self.k * p
        main = -2.0 * off
        main[-1] = -off[-1]                   # the last container has no outflow
        return off[:-1], main, off[1:]        # sub: d/dm_{i-1}, super: d/dm_{i+1}

    def jac(self, t, m):
        """Jacobian for solve_ivp: dense below 32 containers, sparse CSC above."""
        lo, d, up = self.jac_diagonals(m)
        J = sps.diags([lo, d, up], [-1, 0, 1], format="csc")
        return J.toarray() if self.N < 32 else J

    def second_derivative(self, m):
        """m'' = J(m) f(m), for m of shape (N, n)."""
        f = self.rhs(0.0, m)
        lo, d, up = self.jac_diagonals(m)
        out = d * f
        out[1:] += lo * f[:-1]
        out[:-1] += up * f[1:]
        return out


class Reference:
    """p_ref(t): container pressures, shape (N, len(t)), from the reference's step
    points by quintic Hermite interpolation (module doc)."""

    def __init__(self, ode, t, m):
        self.ode, self.t = ode, t
        self.m = m                                           # (N, n)
        self.dm = ode.rhs(0.0, m)
        self.ddm = ode.second_derivative(m)

    def __call__(self, times):
        times = np.atleast_1d(np.asarray(times, dtype=float))
        if times.min() < self.t[0] - 1e-12 or times.max() > self.t[-1] + 1e-12:
            raise ValueError(f"reference covers [{self.t[0]}, {self.t[-1]}] s only")
        j = np.clip(np.searchsorted(self.t, times, side="right") - 1, 0, len(self.t) - 2)
        h = self.t[j + 1] - self.t[j]
        s = (times - self.t[j]) / h
        s2, s3 = s * s, s * s * s
        s4, s5 = s3 * s, s3 * s2
        m0, m1 = self.m[:, j], self.m[:, j + 1]
        d0, d1 = self.dm[:, j] * h, self.dm[:, j + 1] * h
        e0, e1 = self.ddm[:, j] * h * h, self.ddm[:, j + 1] * h * h
        m = ((1 - 10 * s3 + 15 * s4 - 6 * s5) * m0 + (10 * s3 - 15 * s4 + 6 * s5) * m1
             + (s - 6 * s3 + 8 * s4 - 3 * s5) * d0 + (-4 * s3 + 7 * s4 - 3 * s5) * d1
             + 0.5 * (s2 - 3 * s3 + 3 * s4 - s5) * e0 + 0.5 * (s3 - 2 * s4 + s5) * e1)
        return self.ode.k * m


@functools.lru_cache(maxsize=None)
def _reference(N, duration):
    ode = ChainODE(N)
    path = CACHE / f"air_chain_N{N}_T{duration:g}.npz"
    if path.exists():
        data = np.load(path)
        if np.array_equal(data["key"], ode.key) and float(data["rtol"]) == REF_RTOL:
            return Reference(ode, data["t"], data["m"])
    sol = solve_ivp(ode.rhs, (0.0, duration), ode.m0, method="Radau", rtol=REF_RTOL,
                    atol=REF_ATOL, jac=ode.jac)
    if not sol.success:
        raise RuntimeError(f"reference N={N}: {sol.message}")
    CACHE.mkdir(exist_ok=True)
    np.savez(path, t=sol.t, m=sol.y, key=ode.key, rtol=REF_RTOL)
    return Reference(ode, sol.t, sol.y)


def reference(N, duration=DURATION, t_eval=None):
    """The reference solution of the N-container chain: a callable p_ref(t) -> (N, len(t))
    [Pa], or its values at ``t_eval`` when given. Computed once, then read from
    benchmarks/.cache/."""
    ref = _reference(int(N), float(duration))
    return ref if t_eval is None else ref(t_eval)


def error_of(times, p_containers, duration=DURATION):
    """max over containers and ``times`` of |p - p_ref(t)| / STEP_PA, for container
    pressures ``p_containers`` of shape (N, len(times)) [Pa]."""
    p = np.asarray(p_containers, dtype=float)
    times = np.asarray(times, dtype=float)
    if p.ndim != 2 or p.shape[1] != len(times):
        raise ValueError(f"p_containers must be (N, len(times)), got {p.shape}")
    return float(np.abs(p - reference(p.shape[0], duration)(times)).max() / STEP_PA)


def container_pressures(result, N):
    """Container pressures (N, len(result.times)) [Pa] from a softflow Result of
    ``air_chain(N)``; then ``error_of(result.times, container_pressures(result, N))``."""
    return np.array([result.get(f"cont{i}", "pressure") for i in range(N)])


def _timed(solve, budget=0.25, max_runs=25):
    """Median CPU time of ``solve()`` and the last run's result: at least 3 runs, more
    (up to ``max_runs``) until ``budget`` seconds of CPU are spent; one run if the
    first takes longer than ``budget``."""
    cpus = []
    while True:
        t0 = time.process_time()
        out = solve()
        cpus.append(time.process_time() - t0)
        if cpus[0] > budget or len(cpus) >= max_runs or (len(cpus) >= 3
                                                          and sum(cpus) >= budget):
            return statistics.median(cpus), out


def run_scipy(method, N, rtol, duration=DURATION):
    """scipy solve_ivp ('BDF' or 'Radau') on the mass ODE with the analytic Jacobian:
    (cpu [s], error, steps)."""
    ode = ChainODE(N)

    def solve():
        sol = solve_ivp(ode.rhs, (0.0, duration), ode.m0, method=method, rtol=rtol,
                        atol=rtol * ode.dm_step, jac=ode.jac)
        if not sol.success:
            raise RuntimeError(f"scipy {method} N={N} rtol={rtol}: {sol.message}")
        return sol

    cpu, sol = _timed(solve)
    return cpu, error_of(sol.t, ode.k * sol.y, duration), len(sol.t) - 1


def run_cvode(N, rtol, duration=DURATION):
    """SUNDIALS CVODE (BDF, band linear solver, analytic Jacobian) on the mass ODE:
    (cpu [s], error, steps). Output at every internal step."""
    from sksundae.cvode import CVODE
    ode = ChainODE(N)
    i = np.arange(N)

    def rhsfn(t, y, yp):
        yp[:] = ode.rhs(t, y)

    def jacfn(t, y, yp, JJ):     # JJ is (N, N); the same entries are written every call
        lo, d, up = ode.jac_diagonals(np.asarray(y))
        JJ[i, i] = d
        JJ[i[1:], i[:-1]] = lo
        JJ[i[:-1], i[1:]] = up

    def solve():
        solver = CVODE(rhsfn, method="BDF", rtol=rtol, atol=rtol * ode.dm_step,
                       linsolver="band", lband=1, uband=1, jacfn=jacfn,
                       max_num_steps=10 ** 6)
        sol = solver.solve(np.array([0.0, duration]), ode.m0)
        if not sol.success:
            raise RuntimeError(f"CVODE N={N} rtol={rtol}: {sol.message}")
        return sol

    cpu, sol = _timed(solve)
    return cpu, error_of(sol.t, ode.k * sol.y.T, duration), len(sol.t) - 1


def run_ida(N, rtol, duration=DURATION):
    """SUNDIALS IDA (band linear solver, analytic Jacobian) on the DAE with unknowns
    y = [q_0, m_0, p_0, q_1, m_1, p_1, ...] (tube flow, container mass, node pressure):

        (p_{i-1} - p_i) - 64 c R T / pm q_i = 0      tube, softflow's form
        m_i' - (q_i - q_{i+1})                = 0      mass balance (differential)
        p_i V / (R T) - m_i                   = 0      container

    (bandwidths 1 below, 2 above). The algebraic unknowns take part in IDA's error
    test (scikit-sundae exposes no suppressalg). Returns (cpu [s], error, steps);
    the error uses the algebraic pressures p_i."""
    from sksundae.ida import IDA
    ode = ChainODE(N)
    n = 3 * N
    iq, im, ip = np.arange(0, n, 3), np.arange(1, n, 3), np.arange(2, n, 3)
    a = 64.0 * ode.c_mu * ode.RT
    cap = 1.0 / ode.k                     # V / (R T)

    def resfn(t, y, yp, res):
        q, m, p = y[iq], y[im], y[ip]
        up = np.concatenate(([ode.p_src], p[:-1]))
        res[iq] = (up - p) - a * q / (0.5 * (up + p))
        out = q.copy()
        out[:-1] -= q[1:]
        res[im] = yp[im] - out
        res[ip] = cap * p - m

    def jacfn(t, y, yp, res, cj, JJ):   # the same entries are written every call
        q, p = y[iq], y[ip]
        up = np.concatenate(([ode.p_src], p[:-1]))
        pm = 0.5 * (up + p)
        half = 0.5 * a * q / (pm * pm)
        JJ[iq, iq] = -a / pm
        JJ[iq, ip] = -1.0 + half
        JJ[iq[1:], ip[:-1]] = 1.0 + half[1:]
        JJ[im, im] = cj
        JJ[im, iq] = -1.0
        JJ[im[:-1], iq[1:]] = 1.0
        JJ[ip, ip] = cap
        JJ[ip, im] = -1.0

    y0 = np.zeros(n)
    y0[im], y0[ip], y0[0] = ode.m0, P_ATM, ode.q0      # consistent: only tube 0 flows
    yp0 = np.zeros(n)
    yp0[1] = ode.q0
    atol = np.empty(n)
    atol[iq], atol[im], atol[ip] = rtol * ode.q0, rtol * ode.dm_step, rtol * STEP_PA

    def solve():
        solver = IDA(resfn, rtol=rtol, atol=atol, algebraic_idx=np.concatenate((iq, ip)),
                     linsolver="band", lband=1, uband=2, jacfn=jacfn, max_num_steps=10 ** 6)
        sol = solver.solve(np.array([0.0, duration]), y0, yp0)
        if not sol.success:
            raise RuntimeError(f"IDA N={N} rtol={rtol}: {sol.message}")
        return sol

    cpu, sol = _timed(solve)
    return cpu, error_of(sol.t, sol.y[:, ip].T, duration), len(sol.t) - 1


RUNNERS = {"scipy BDF": functools.partial(run_scipy, "BDF"),
           "scipy Radau": functools.partial(run_scipy, "Radau"),
           "IDA": run_ida, "CVODE": run_cvode}


def cpu_to_reach(points, target):
    """CPU time [s] at which a solver's rtol sweep first reaches error <= target.

    ``points``: (rtol, cpu, error), loosest rtol first. At the first point with
    error <= target, log(cpu) is interpolated linearly in log(error) between it and
    the point before (its own CPU time if it is the first point or the error went
    up); None if no point reaches the target."""
    prev = None
    for _, cpu, err in points:
        if err <= target:
            if prev is None or err <= 0 or prev[1] <= err:
                return cpu
            w = np.log(prev[1] / target) / np.log(prev[1] / err)
            return float(np.exp((1 - w) * np.log(prev[0]) + w * np.log(cpu)))
        prev = (cpu, err)
    return None


def verify_softflow(N=8, steps=(1e-3, 1e-4, 1e-5), duration=DURATION):
    """softflow's fixed-step backward Euler against the reference: the error (the
    largest over all times, and at t = duration) should fall ~10x per 10x in step."""
    ref = reference(N, duration)
    print(f"softflow fixed step vs reference, N = {N} (error in units of {STEP_PA:g} Pa)\n")
    print("| step [s] | max error | ratio | error at t_end | ratio | CPU [s] |")
    print("|---|---|---|---|---|---|")
    last = None
    for h in steps:
        t0 = time.process_time()
        res = sf.Simulation(air_chain(N), duration=duration, step=h).run()
        cpu = time.process_time() - t0
        err = np.abs(container_pressures(res, N) - ref(res.times)) / STEP_PA
        e_max, e_end = err.max(), err[:, -1].max()
        r1, r2 = ("-", "-") if last is None else (f"{last[0] / e_max:.2f}",
                                                  f"{last[1] / e_end:.2f}")
        print(f"| {h:g} | {e_max:.3e} | {r1} | {e_end:.3e} | {r2} | {cpu:.2f} |")
        last = (e_max, e_end)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--verify", action="store_true",
                        help="compare softflow's fixed-step run with the reference instead")
    parser.add_argument("--N", type=int, nargs="+", default=[8, 200])
    parser.add_argument("--rtols", type=float, nargs="+", default=list(RTOLS))
    args = parser.parse_args()
    rtols = sorted(args.rtols, reverse=True)
    if args.verify:
        for N in args.N:
            verify_softflow(N, steps=(1e-3, 1e-4, 1e-5) if N <= 20 else (1e-4, 1e-5))
            print()
        return
    for N in args.N:
        reference(N)                          # computed (and cached) outside the timings
        rows = {name: [(rtol, *RUNNERS[name](N, rtol)) for rtol in rtols] for name in SOLVERS}
        print(f"\n### N = {N}: error (units of 0.2 bar) / CPU ms / steps\n")
        print("| rtol | " + " | ".join(SOLVERS) + " |")
        print("|---" * (len(SOLVERS) + 1) + "|")
        for k, rtol in enumerate(rtols):
            cells = [f"{e:.1e} / {1e3 * c:.1f} / {n}" for _, c, e, n in
                     (rows[name][k] for name in SOLVERS)]
            print(f"| {rtol:.0e} | " + " | ".join(cells) + " |")
        print(f"\nN = {N}: CPU ms to first reach error <= target (log-log interpolation "
              "between rtol points)\n")
        print("| solver | " + " | ".join(f"{t:.0e}" for t in TARGETS) + " |")
        print("|---" * (len(TARGETS) + 1) + "|")
        for name in SOLVERS:
            pts = [(r, c, e) for r, c, e, _ in rows[name]]
            cells = []
            for target in TARGETS:
                cpu = cpu_to_reach(pts, target)
                bound = "<= " if pts[0][2] <= target else ""   # met at the loosest rtol
                cells.append("not reached" if cpu is None else f"{bound}{1e3 * cpu:.1f}")
            print(f"| {name} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
