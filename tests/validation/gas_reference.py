"""Independent reference for pneumatic scenes whose tube chokes (isothermal air).

Written with NumPy, SciPy and ``fluids`` only: it does not import softflow, so it
can validate softflow's choked tube law. Run it as a script for a table of the
five scenes and the reference's own checks::

    python tests/validation/gas_reference.py

Model
-----
Air is an ideal gas at a constant temperature: R = 287.04749097718457 J/(kg K),
T = 293.15 K, constant viscosity mu = 1.8205675178515367e-05 Pa s (gamma =
1.399177960909333 only converts the choking velocity to a Mach number). A
rigid volume V at pressure p holds m = p V / (R T) (isothermal); the
atmosphere is 101325 Pa.

A tube of length L, diameter D, roughness eps = 1.5e-6 m and area A carries
the mass flux G = mdot / A between two node pressures, read as stagnation
pressures; the gas flows from the higher, p0, to the lower, p_down.
With c = sqrt(R T) (the isothermal sound speed):

* entry, isothermal acceleration from rest to the tube's inlet pressure p1:
  ln(p0 / p1) = M1^2 / 2 with M1 = G c / p1 (solved in closed form,
  p1 = p0 exp(W0(-g^2) / 2), g = G c / p0, W0 the principal Lambert W
  branch: the subsonic root);
* pipe, isothermal flow with friction and acceleration (Crane TP-410, eq. 1-6;
  the equation ``fluids.compressible.isothermal_gas`` solves, which
  :func:`self_check` compares with):
  p1^2 - p2^2 = G^2 c^2 [f L / D + 2 ln(p1 / p2)];
* exit: p2 = max(p_down, G c). The flow chokes when the exit velocity reaches
  c = sqrt(R T) (isothermal Mach 1/sqrt(gamma) = 0.845); beyond that it no
  longer depends on p_down. At the choke, f L / D equals the isothermal Fanno
  parameter (1 - M1^2) / M1^2 + ln(M1^2) of the inlet Mach number
  (Shapiro, *The Dynamics and Thermodynamics of Compressible Fluid Flow*, 1953,
  ch. 6; White, *Fluid Mechanics*, sec. 9.7).
* Darcy friction f from Re = G D / mu: f Re = 64 for Re <= 2300; Haaland
  f = [-1.8 log10((eps/D/3.7)^1.11 + 6.9/Re)]^-2 for Re >= 4000 (Haaland, J.
  Fluids Eng. 105 (1983) 89; ``fluids.friction.Haaland``); between them
  f Re = 64 + w(s) (f_H(Re) Re - 64), s = (Re - 2300)/1700, w = 3 s^2 - 2 s^3.

For given (p0, p_down) the mass flux is found by ``scipy.optimize.brentq`` to a
relative 1e-12: first the choked flux G* (exit velocity c), then, where
p_down > G* c, the unchoked flux in (0, G*) with p2 = p_down.

Scenes (pressures over time by ``scipy.integrate.solve_ivp``, DOP853, rtol
1e-10, dense output): see :data:`SCENES` and the functions :func:`fill`,
:func:`blowdown_4mm`, :func:`blowdown_2mm`, :func:`two_tanks` and
:func:`actuator`. Each returns a :class:`SceneResult`. The durations are the
times each scene takes to come within 1 % of its equilibrium (of its initial
distance from it), rounded up to two significant digits; ``choked_fraction``
is the share of the duration during which p_down < G* c. ``python
gas_reference.py`` gives (the choke's end does not depend on the duration):

=============  ========  =================  =============  ==========  =========  =======
scene          duration  final [Pa]         choked         choke ends  peak mdot  peak Re
=============  ========  =================  =============  ==========  =========  =======
fill           0.024 s   399268             30.0 %         7.20 ms     9.24 g/s   161548
blowdown_4mm   2.1 s     106275             45.6 %         0.958 s     14.9 g/s   260608
blowdown_2mm   7.2 s     109703             52.2 %         3.76 s      4.12 g/s   144139
two_tanks      0.065 s   301975, 298025     31.8 %         20.7 ms     5.61 g/s   130710
actuator       0.34 s    695917             1.9 %          6.4 ms      1.43 g/s   49887
=============  ========  =================  =============  ==========  =========  =======
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import PchipInterpolator
from scipy.optimize import brentq
from scipy.special import lambertw

# -- air ---------------------------------------------------------------------------------
R_AIR = 287.04749097718457          # J/(kg K)
T_AIR = 293.15                      # K
MU_AIR = 1.8205675178515367e-05     # Pa s
GAMMA_AIR = 1.399177960909333
P_ATM = 101325.0                    # Pa
ROUGHNESS = 1.5e-6                  # m
RT = R_AIR * T_AIR
C_ISO = math.sqrt(RT)               # m/s, the isothermal choking velocity
MACH_CHOKE = 1.0 / math.sqrt(GAMMA_AIR)

RE_LAMINAR, RE_TURBULENT = 2300.0, 4000.0

#: relative tolerance of every root find of the mass flux
RTOL_ROOT = 1e-12
#: the ODE integrations
RTOL_ODE = 1e-10

_LN10 = math.log(10.0)
_ENTRY_LIMIT = math.exp(-0.5)       # largest g = G c / p0 the entry can pass (M1 = 1)


# -- friction -----------------------------------------------------------------------------
def friction_haaland(Re: float, eD: float) -> float:
    """Haaland's Darcy friction factor (the same as ``fluids.friction.Haaland``)."""
    y = -1.8 * math.log((eD / 3.7) ** 1.11 + 6.9 / Re) / _LN10
    return 1.0 / (y * y)


def friction_times_Re(Re: float, eD: float) -> float:
    """f Re: 64 (laminar) up to Re 2300, Haaland from 4000, a C1 smoothstep between."""
    if Re <= RE_LAMINAR:
        return 64.0
    turbulent = friction_haaland(Re, eD) * Re
    if Re >= RE_TURBULENT:
        return turbulent
    s = (Re - RE_LAMINAR) / (RE_TURBULENT - RE_LAMINAR)
    return 64.0 + s * s * (3.0 - 2.0 * s) * (turbulent - 64.0)


def friction_factor(Re: float, eD: float) -> float:
    """Darcy f of the blended law (f Re / Re)."""
    return friction_times_Re(Re, eD) / Re


# -- the tube law ---------------------------------------------------------------------------
def entry_pressure(p0: float, G: float) -> float:
    """Inlet pressure p1 after isothermal acceleration from rest at p0 to the mass
    flux G: ln(p0/p1) = M1^2/2, M1 = G c / p1, the subsonic root (Lambert W0)."""
    g = G * C_ISO / p0
    if g >= _ENTRY_LIMIT:                      # M1 = 1, the entry's own limit (W0(-1/e) = -1)
        return p0 * _ENTRY_LIMIT
    x = math.exp(0.5 * lambertw(-g * g, 0).real)
    # a Newton step on -ln x - g^2/(2 x^2) = 0 polishes W0 near its branch point
    d = g * g - x * x
    if d < -1e-6 * x * x:
        x -= (-math.log(x) - 0.5 * g * g / (x * x)) * x ** 3 / d
    return p0 * x


def pipe_residual(G: float, p1: float, p2: float, L: float, D: float,
                  eps: float = ROUGHNESS) -> float:
    """p1^2 - p2^2 - G^2 c^2 [f L/D + 2 ln(p1/p2)] [Pa^2], with G^2 f L/D written
    as G (f Re) mu L / D^2 (finite at G = 0)."""
    Re = G * D / MU_AIR
    return (p1 * p1 - p2 * p2
            - RT * (G * friction_times_Re(Re, eps / D) * MU_AIR * L / (D * D)
                    + 2.0 * G * G * math.log(p1 / p2)))


def choked_massflux(p0: float, L: float, D: float, eps: float = ROUGHNESS) -> float:
    """G* [kg/(m^2 s)]: the mass flux whose exit velocity is c (p2 = G c) from the
    stagnation pressure p0, entry included."""
    g_max = _ENTRY_LIMIT * p0 / C_ISO

    def res(G: float) -> float:
        return pipe_residual(G, entry_pressure(p0, G), G * C_ISO, L, D, eps)

    # res(0) = p0^2 > 0; at g_max (M1 = 1, p1 = G c) only the friction term is left: < 0
    return brentq(res, 1e-12 * g_max, g_max, xtol=1e-18 * g_max, rtol=RTOL_ROOT, maxiter=500)


def tube_massflux(p0: float, p_down: float, L: float, D: float, eps: float = ROUGHNESS
                  ) -> tuple[float, bool]:
    """(G, choked) from the node pressure p0 to p_down; G < 0 where p_down > p0."""
    if p0 == p_down:
        return 0.0, False
    if p0 < p_down:
        G, choked = tube_massflux(p_down, p0, L, D, eps)
        return -G, choked
    G_star = choked_massflux(p0, L, D, eps)
    if p_down <= G_star * C_ISO:
        return G_star, True

    def res(G: float) -> float:
        return pipe_residual(G, entry_pressure(p0, G), p_down, L, D, eps)

    # res(0) = p0^2 - p_down^2 > 0; res(G*) < 0 since the choked exit G* c < p_down
    G = brentq(res, 0.0, G_star, xtol=1e-18 * G_star, rtol=RTOL_ROOT, maxiter=500)
    return G, False


def tube_massflow(p0: float, p_down: float, L: float, D: float, eps: float = ROUGHNESS
                  ) -> tuple[float, bool]:
    """(mdot [kg/s], choked) through a tube of length L and diameter D [m] from
    the stagnation pressure p0 to p_down [Pa]; negative where p_down > p0."""
    G, choked = tube_massflux(p0, p_down, L, D, eps)
    return G * math.pi * D * D / 4.0, choked


def tube_state(p0: float, p_down: float, L: float, D: float, eps: float = ROUGHNESS) -> dict:
    """Everything along the tube at (p0 > p_down): G, p1, p2, M1, Re, f, choked."""
    G, choked = tube_massflux(p0, p_down, L, D, eps)
    p1 = entry_pressure(p0, G)
    p2 = max(p_down, G * C_ISO)
    Re = G * D / MU_AIR
    return dict(G=G, mdot=G * math.pi * D * D / 4, p1=p1, p2=p2, M1=G * C_ISO / p1,
                M2=G * C_ISO / p2, Re=Re, f=friction_factor(Re, eps / D), choked=choked)


def pipe_massflow(p1: float, p2: float, L: float, D: float, eps: float = ROUGHNESS) -> float:
    """The pipe part alone (no entry): mdot [kg/s] from the inlet pressure p1 to
    the exit pressure p2 < p1 of an unchoked pipe (p2 > G c)."""
    def res(G: float) -> float:
        return pipe_residual(G, p1, p2, L, D, eps)

    hi = p2 / C_ISO                      # exit velocity c: the pipe's own choke
    if res(hi) > 0:
        raise ValueError(f"the pipe chokes before p2 = {p2:.6g} Pa")
    G = brentq(res, 0.0, hi, xtol=1e-18 * hi, rtol=RTOL_ROOT, maxiter=500)
    return G * math.pi * D * D / 4


def fanno_parameter(M: float) -> float:
    """Isothermal Fanno parameter f L*/D = (1 - M^2)/M^2 + ln(M^2), M = v / sqrt(R T)."""
    return (1.0 - M * M) / (M * M) + math.log(M * M)


def choked_massflux_by_mach(p0: float, L: float, D: float, eps: float = ROUGHNESS) -> float:
    """G* a second way, for the checks: in the inlet Mach number M1, where
    p1 = p0 exp(-M1^2/2) and G = M1 p1 / c are explicit, solve
    fanno(M1) = f(Re(G)) L / D."""
    def G_of(M: float) -> float:
        return M * p0 * math.exp(-0.5 * M * M) / C_ISO

    def res(M: float) -> float:
        G = G_of(M)
        return fanno_parameter(M) - friction_factor(G * D / MU_AIR, eps / D) * L / D

    return G_of(brentq(res, 1e-9, 1.0, xtol=1e-16, rtol=RTOL_ROOT, maxiter=500))


# -- scenes -------------------------------------------------------------------------------------
@dataclass
class Tube:
    length: float     # m
    diameter: float   # m
    roughness: float = ROUGHNESS

    @property
    def area(self) -> float:
        return math.pi * self.diameter ** 2 / 4

    def massflow(self, p0: float, p_down: float) -> tuple[float, bool]:
        return tube_massflow(p0, p_down, self.length, self.diameter, self.roughness)

    def choke_margin(self, p_up: float, p_down: float) -> float:
        """p_low - G*(p_high) c [Pa]: negative while the tube chokes."""
        hi, lo = max(p_up, p_down), min(p_up, p_down)
        if hi == lo:
            return hi
        return lo - choked_massflux(hi, self.length, self.diameter, self.roughness) * C_ISO


#: An actuator's PV curve: volumes [mL] and gauge pressures [bar]. A fibre-
#: reinforced chamber that stiffens as it inflates (compliance from 4 mL/bar
#: down to 1.5 mL/bar), with data past the 6 bar gauge supply so that its
#: equilibrium lies inside them. softflow side: sf.PVCurve(volume=Q_(.., 'mL'),
#: pressure=Q_(.., 'bar'), gauge=True), PCHIP of the absolute pressure on volume.
ACTUATOR_VOLUME_ML = (20.0, 24.0, 28.0, 32.0, 35.0, 37.5, 39.5, 41.0)
ACTUATOR_GAUGE_BAR = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0)

#: The five scenes (SI). ``duration``: within 1 % of equilibrium (see
#: :func:`time_to_one_percent`), rounded up to two significant digits.
SCENES: dict[str, dict] = {
    "fill": dict(supply=401325.0, volume=50e-6, initial=P_ATM,
                 tube=Tube(0.10, 4e-3), duration=None),
    "blowdown_4mm": dict(volume=1e-3, initial=1e6, ambient=P_ATM,
                         tube=Tube(1.0, 4e-3), duration=None),
    "blowdown_2mm": dict(volume=1e-3, initial=1e6, ambient=P_ATM,
                         tube=Tube(0.30, 2e-3), duration=None),
    "two_tanks": dict(volume_a=100e-6, volume_b=100e-6, initial_a=5e5, initial_b=1e5,
                      tube=Tube(0.20, 3e-3), duration=None),
    "actuator": dict(supply=701325.0, tube=Tube(2.0, 2e-3), initial=P_ATM,
                     volume_ml=ACTUATOR_VOLUME_ML, gauge_bar=ACTUATOR_GAUGE_BAR,
                     duration=None),
}


@dataclass
class SceneResult:
    """A scene's reference solution.

    ``t``: output times [s] (``n`` points over the duration); ``pressures``:
    {label: absolute pressure [Pa] at t}; ``pressure_at(times)`` the same at any
    times (the ODE's dense output, to rtol 1e-10); ``choked_fraction``: share
    of the duration with the tube choked; ``choke_events``: the times the
    tube's choke state changed."""
    name: str
    duration: float
    t: np.ndarray
    pressures: dict[str, np.ndarray]
    pressure_at: Callable[[np.ndarray], dict[str, np.ndarray]]
    choked_fraction: float
    choke_events: list[float]
    choked_at_start: bool
    equilibrium: dict[str, float]
    initial: dict[str, float]
    massflow: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    reynolds: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    ode_stats: dict = field(default_factory=dict)

    @property
    def pressure_range(self) -> float:
        """Largest span of any of the scene's pressures over the run [Pa]."""
        return max(float(np.ptp(p)) for p in self.pressures.values())

    def distance_to_equilibrium(self) -> float:
        """|p(end) - p_eq| / |p(0) - p_eq|, the largest over the pressures."""
        return max(abs(self.pressures[k][-1] - self.equilibrium[k])
                   / abs(self.initial[k] - self.equilibrium[k]) for k in self.pressures)


def _integrate(rhs, y0, t_end, events, atol, ode):
    ode = {"method": "DOP853", "rtol": RTOL_ODE, **(ode or {})}
    atol = atol * ode.pop("atol_scale", 1.0)
    sol = solve_ivp(rhs, (0.0, t_end), y0, atol=atol, dense_output=True, events=events, **ode)
    if sol.status != 0:
        raise RuntimeError(f"solve_ivp: {sol.message}")
    return sol


def _finish(name, duration, sol, pressures_of, massflow_of, tube, choke_fn, equilibrium,
            initial, n):
    """The SceneResult of a scene integrated to its duration; the choke events from
    solve_ivp's event location (a root of choke_fn on the dense output)."""
    t = np.linspace(0.0, duration, n)
    pressure_at = lambda times: pressures_of(np.atleast_1d(np.asarray(times, float)), sol)
    pressures = pressure_at(t)
    events = sorted(float(x) for x in sol.t_events[0] if 0.0 < x < duration)
    choked0 = choke_fn(0.0, sol.sol(0.0)) < 0
    # the state alternates at each event: add up the choked intervals
    bounds = [0.0] + events + [duration]
    choked_time, state = 0.0, choked0
    for a, b in zip(bounds[:-1], bounds[1:]):
        if state:
            choked_time += b - a
        state = not state
    mdot = np.array([massflow_of(sol.sol(x)) for x in t])
    Re = np.abs(mdot) / tube.area * tube.diameter / MU_AIR
    return SceneResult(name, duration, t, pressures, pressure_at, choked_time / duration,
                       events, bool(choked0), equilibrium, initial, mdot, Re,
                       dict(nfev=int(sol.nfev), steps=len(sol.t) - 1))


def _event(fn):
    fn.terminal = False
    fn.direction = 0
    return fn


def fill(duration: float | None = None, n: int = 2001, ode: dict | None = None) -> SceneResult:
    """A 50 mL rigid tank at 101325 Pa filled from a constant 401325 Pa (3 bar
    gauge) through 10 cm of 4 mm tube. Pressures: {'tank'}."""
    sc = SCENES["fill"]
    tube, V, ps = sc["tube"], sc["volume"], sc["supply"]
    duration = duration or sc["duration"] or time_to_one_percent("fill")

    def rhs(t, y):
        return [RT / V * tube.massflow(ps, y[0])[0]]

    choke = _event(lambda t, y: tube.choke_margin(ps, y[0]))
    sol = _integrate(rhs, [sc["initial"]], duration, [choke], 1e-6, ode)
    return _finish("fill", duration, sol, lambda t, s: {"tank": s.sol(t)[0]},
                   lambda y: tube.massflow(ps, y[0])[0], tube, choke,
                   {"tank": ps}, {"tank": sc["initial"]}, n)


def _blowdown(name, duration, n, ode):
    sc = SCENES[name]
    tube, V, pa = sc["tube"], sc["volume"], sc["ambient"]
    duration = duration or sc["duration"] or time_to_one_percent(name)

    def rhs(t, y):
        return [-RT / V * tube.massflow(y[0], pa)[0]]

    choke = _event(lambda t, y: tube.choke_margin(y[0], pa))
    sol = _integrate(rhs, [sc["initial"]], duration, [choke], 1e-6, ode)
    return _finish(name, duration, sol, lambda t, s: {"tank": s.sol(t)[0]},
                   lambda y: tube.massflow(y[0], pa)[0], tube, choke,
                   {"tank": pa}, {"tank": sc["initial"]}, n)


def blowdown_4mm(duration: float | None = None, n: int = 2001, ode: dict | None = None
                 ) -> SceneResult:
    """A 1 L tank at 1e6 Pa blowing down to 101325 Pa through 1 m of 4 mm tube.
    Pressures: {'tank'}."""
    return _blowdown("blowdown_4mm", duration, n, ode)


def blowdown_2mm(duration: float | None = None, n: int = 2001, ode: dict | None = None
                 ) -> SceneResult:
    """A 1 L tank at 1e6 Pa blowing down to 101325 Pa through 30 cm of 2 mm tube.
    Pressures: {'tank'}."""
    return _blowdown("blowdown_2mm", duration, n, ode)


def two_tanks(duration: float | None = None, n: int = 2001, ode: dict | None = None
              ) -> SceneResult:
    """Two 100 mL tanks at 5e5 and 1e5 Pa joined by 20 cm of 3 mm tube.
    Pressures: {'tank_a', 'tank_b'} (a starts high)."""
    sc = SCENES["two_tanks"]
    tube, Va, Vb = sc["tube"], sc["volume_a"], sc["volume_b"]
    duration = duration or sc["duration"] or time_to_one_percent("two_tanks")

    def rhs(t, y):
        m = tube.massflow(y[0], y[1])[0]           # a -> b
        return [-RT / Va * m, RT / Vb * m]

    choke = _event(lambda t, y: tube.choke_margin(y[0], y[1]))
    y0 = [sc["initial_a"], sc["initial_b"]]
    sol = _integrate(rhs, y0, duration, [choke], 1e-6, ode)
    p_eq = (sc["initial_a"] * Va + sc["initial_b"] * Vb) / (Va + Vb)
    return _finish("two_tanks", duration, sol,
                   lambda t, s: dict(zip(("tank_a", "tank_b"), s.sol(t))),
                   lambda y: tube.massflow(y[0], y[1])[0], tube, choke,
                   {"tank_a": p_eq, "tank_b": p_eq},
                   {"tank_a": sc["initial_a"], "tank_b": sc["initial_b"]}, n)


def actuator_curve() -> PchipInterpolator:
    """The actuator's PV curve: absolute pressure [Pa] of volume [m^3], PCHIP
    (as softflow's PVCurve: monotone cubic through (V, p), linear beyond)."""
    sc = SCENES["actuator"]
    v = np.asarray(sc["volume_ml"]) * 1e-6
    p = np.asarray(sc["gauge_bar"]) * 1e5 + P_ATM
    return PchipInterpolator(v, p)


def actuator(duration: float | None = None, n: int = 2001, ode: dict | None = None
             ) -> SceneResult:
    """A 701325 Pa (6 bar gauge) supply into a soft actuator through 2 m of 2 mm
    tube, from 0 gauge. The actuator holds m = p V / (R T) with p = curve(V)
    (:func:`actuator_curve`); its state here is V:
    dV/dt = R T mdot / (p(V) + V p'(V)). Pressures: {'actuator'}; the volume
    [m^3] is in ``result.volume_at(t)``."""
    sc = SCENES["actuator"]
    tube, ps = sc["tube"], sc["supply"]
    curve = actuator_curve()
    slope = curve.derivative()
    duration = duration or sc["duration"] or time_to_one_percent("actuator")
    v0 = sc["volume_ml"][0] * 1e-6            # 0 gauge: the first point

    def rhs(t, y):
        v = y[0]
        p = float(curve(v))
        return [RT * tube.massflow(ps, p)[0] / (p + v * float(slope(v)))]

    choke = _event(lambda t, y: tube.choke_margin(ps, float(curve(y[0]))))
    sol = _integrate(rhs, [v0], duration, [choke], 1e-18, ode)
    res = _finish("actuator", duration, sol, lambda t, s: {"actuator": curve(s.sol(t)[0])},
                  lambda y: tube.massflow(ps, float(curve(y[0])))[0], tube, choke,
                  {"actuator": ps}, {"actuator": float(curve(v0))}, n)
    res.volume_at = lambda times: sol.sol(np.atleast_1d(np.asarray(times, float)))[0]
    return res


SCENE_FUNCTIONS = {"fill": fill, "blowdown_4mm": blowdown_4mm, "blowdown_2mm": blowdown_2mm,
                   "two_tanks": two_tanks, "actuator": actuator}


def time_to_one_percent(name: str, rounded: bool = True, t_max: float = 1000.0) -> float:
    """The time [s] at which the scene ``name`` comes within 1 % of its equilibrium
    (every pressure within 1 % of its initial distance from it), rounded up to
    two significant digits unless ``rounded`` is False."""
    probe = SCENE_FUNCTIONS[name](duration=1e-9, n=2)      # its equilibrium and start
    label = max(probe.initial, key=lambda k: abs(probe.initial[k] - probe.equilibrium[k]))
    p_eq, p_init = probe.equilibrium[label], probe.initial[label]
    target = 0.01 * abs(p_init - p_eq)
    t_hit = _first_time_within(name, label, p_eq, target, t_max)
    if not rounded:
        return t_hit
    exponent = math.floor(math.log10(t_hit)) - 1
    return math.ceil(t_hit / 10 ** exponent) * 10 ** exponent


def _first_time_within(name, label, p_eq, target, t_max):
    # runs of the scene 4x longer each time until one ends within the band, then the
    # crossing of |p - p_eq| = target on its dense output (the distance falls
    # monotonically in all five scenes)
    t_end = 1e-3
    while t_end <= t_max:
        res = SCENE_FUNCTIONS[name](duration=t_end, n=2)
        if abs(res.pressures[label][-1] - p_eq) <= target:
            return brentq(lambda x: abs(res.pressure_at(x)[label][0] - p_eq) - target,
                          0.0, t_end, xtol=1e-12 * t_end)
        t_end *= 4
    raise RuntimeError(f"{name}: not within 1 % of equilibrium by {t_max} s")


# the durations [s], each time_to_one_percent(name) (computed by `python gas_reference.py`,
# which checks them again)
DURATIONS = {"fill": 0.024, "blowdown_4mm": 2.1, "blowdown_2mm": 7.2, "two_tanks": 0.065,
             "actuator": 0.34}
for _name, _d in DURATIONS.items():
    SCENES[_name]["duration"] = _d


# -- the reference's own checks -------------------------------------------------------------
def self_check(verbose: bool = True) -> list[tuple[str, float, float]]:
    """Limiting cases and cross-checks; returns (what, relative error, tolerance)
    rows and raises AssertionError on the first failure."""
    from fluids.compressible import P_isothermal_critical_flow, isothermal_gas
    from fluids.friction import Haaland

    rows = []

    def check(what, err, tol):
        rows.append((what, err, tol))
        if verbose:
            print(f"  {'ok ' if err <= tol else 'BAD'} {what}: {err:.3g} (tol {tol:g})")
        assert err <= tol, f"{what}: {err:.3g} > {tol:g}"

    # friction
    for Re in (4000.0, 2e4, 3e5):
        for eD in (1.5e-6 / 2e-3, 1.5e-6 / 4e-3, 0.0):
            check(f"Haaland vs fluids Re={Re:g} eD={eD:.3g}",
                  abs(friction_haaland(Re, eD) / Haaland(Re, eD) - 1), 1e-13)
    check("blend continuous at 2300", abs(friction_times_Re(2300.0 * (1 + 1e-12), 3e-4) - 64), 1e-6)
    check("blend continuous at 4000",
          abs(friction_times_Re(4000.0 * (1 - 1e-12), 3e-4) / friction_times_Re(4000.0, 3e-4) - 1),
          1e-9)

    # the entry: ln(p0/p1) = M1^2/2 by brentq instead of Lambert W
    for p0, G in ((1e6, 500.0), (4e5, 700.0), (1e5, 200.0)):
        p1 = entry_pressure(p0, G)
        p1b = brentq(lambda x: math.log(p0 / x) - 0.5 * (G * C_ISO / x) ** 2, G * C_ISO, p0,
                     xtol=1e-9, rtol=1e-15)
        check(f"entry p1 (Lambert W vs brentq) p0={p0:g} G={G:g}", abs(p1 / p1b - 1), 1e-12)

    # the pipe part alone against fluids.isothermal_gas (given the same f)
    for (p1, p2, L, D) in ((1e6, 5e5, 1.0, 4e-3), (4e5, 3e5, 0.1, 4e-3), (2e5, 1.2e5, 2.0, 2e-3),
                           (1.05e5, 1.01e5, 1.0, 1e-3)):
        m = pipe_massflow(p1, p2, L, D)
        f = friction_factor(m / (math.pi * D * D / 4) * D / MU_AIR, ROUGHNESS / D)
        m_fl = isothermal_gas(rho=p1 / RT, fd=f, P1=p1, P2=p2, L=L, D=D)
        check(f"pipe vs fluids.isothermal_gas p1={p1:g} p2={p2:g} L={L:g} D={D:g}",
              abs(m / m_fl - 1), 1e-10)

    # the pipe's own choke against fluids.P_isothermal_critical_flow: with the exit at G c,
    # the pipe equation from p1 gives the critical exit pressure fluids finds for that f
    for (p1, L, D) in ((1e6, 1.0, 4e-3), (5e5, 0.2, 3e-3), (7e5, 2.0, 2e-3)):
        def res(G):
            return pipe_residual(G, p1, G * C_ISO, L, D)
        G = brentq(res, 1e-9 * p1 / C_ISO, p1 / C_ISO * (1 - 1e-15), xtol=1e-12, rtol=1e-14)
        f = friction_factor(G * D / MU_AIR, ROUGHNESS / D)
        check(f"pipe choke vs fluids.P_isothermal_critical_flow p1={p1:g} L={L:g}",
              abs(G * C_ISO / P_isothermal_critical_flow(p1, f, D, L) - 1), 1e-9)

    # the whole law, unchoked: from its own inlet pressure p1 it is fluids.isothermal_gas
    for (p0, pd, L, D) in ((1e6, 8e5, 1.0, 4e-3), (3e5, 2.5e5, 0.3, 2e-3), (2e5, 1.9e5, 0.1, 4e-3)):
        st = tube_state(p0, pd, L, D)
        assert not st["choked"]
        m_fl = isothermal_gas(rho=st["p1"] / RT, fd=st["f"], P1=st["p1"], P2=pd, L=L, D=D)
        check(f"tube p0={p0:g} p_down={pd:g} L={L:g} D={D:g}: from p1 vs fluids.isothermal_gas",
              abs(st["mdot"] / m_fl - 1), 1e-10)

    # long tubes: the entry's share vanishes, the law -> fluids.isothermal_gas from p0, the
    # difference the entry's first-order effect p0^2 M1^2 / (2 (p0^2 - p_down^2))
    p0, pd, D = 2e5, 1.5e5, 4e-3
    for L in (50.0, 500.0, 5000.0):
        st = tube_state(p0, pd, L, D)
        m_fl = isothermal_gas(rho=p0 / RT, fd=st["f"], P1=p0, P2=pd, L=L, D=D)
        entry = p0 ** 2 * st["M1"] ** 2 / (2 * (p0 ** 2 - pd ** 2))
        err = abs(st["mdot"] / m_fl - 1)
        check(f"long tube L={L:g} m (2->1.5 bar, 4 mm) vs fluids.isothermal_gas from p0, "
              f"within the entry estimate {entry:.2g} (+-20 %)", abs(err / entry - 1), 0.2)
    check("long tube L=5000 m vs fluids.isothermal_gas from p0", err, 1e-5)

    # choked flow: fL/D equals the isothermal Fanno parameter at the inlet Mach
    for (p0, L, D) in ((401325.0, 0.1, 4e-3), (1e6, 1.0, 4e-3), (1e6, 0.3, 2e-3),
                       (5e5, 0.2, 3e-3), (701325.0, 2.0, 2e-3), (1.2e5, 0.5, 1e-3)):
        st = tube_state(p0, 1.0, L, D)
        assert st["choked"]
        check(f"choked p0={p0:g} L={L:g} D={D:g}: fanno(M1) vs f L/D",
              abs(fanno_parameter(st["M1"]) / (st["f"] * L / D) - 1), 1e-9)
        check(f"choked p0={p0:g} L={L:g} D={D:g}: exit velocity = c",
              abs(st["M2"] - 1), 1e-12)
        check(f"choked p0={p0:g} L={L:g} D={D:g}: G* by inlet Mach",
              abs(st["G"] / choked_massflux_by_mach(p0, L, D) - 1), 1e-10)

    # continuity at the choke: just above p_down = G* c the unchoked flux tends to G*
    p0, L, D = 1e6, 1.0, 4e-3
    G_star = choked_massflux(p0, L, D)
    G_near, ch = tube_massflux(p0, G_star * C_ISO * (1 + 1e-6), L, D)
    # (G* - G ~ (p_down - G* c)^2 there: the exit's dF/dp2 vanishes at p2 = G c)
    check("continuity at the choke", abs(G_near / G_star - 1) if not ch else 1.0, 1e-9)
    # and flow rises with p0 - p_down, stays at G* below the choke
    assert tube_massflux(p0, 0.5 * G_star * C_ISO, L, D) == (G_star, True)
    Gs = [tube_massflux(p0, pd, L, D)[0] for pd in np.linspace(p0, 1.01 * G_star * C_ISO, 60)]
    check("mass flux rises as p_down falls", 0.0 if np.all(np.diff(Gs) > 0) else 1.0, 0.0)
    return rows


def scene_checks(results: dict[str, SceneResult] | None = None, verbose: bool = True
                 ) -> list[tuple[str, float, float]]:
    """Checks of the scene integrations: the fill's choked phase in closed form, the
    two tanks' mass, each scene's duration (within 1 % of equilibrium, not much
    more) and its pressures against a second integrator (LSODA, rtol 1e-8)."""
    results = results or {name: fn() for name, fn in SCENE_FUNCTIONS.items()}
    rows = []

    def check(what, err, tol):
        rows.append((what, err, tol))
        if verbose:
            print(f"  {'ok ' if err <= tol else 'BAD'} {what}: {err:.3g} (tol {tol:g})")
        assert err <= tol, f"{what}: {err:.3g} > {tol:g}"

    # fill: a constant choked flow G* A from the constant supply, so the tank's pressure
    # rises linearly until it reaches G* c
    sc, r = SCENES["fill"], results["fill"]
    tube, V, ps, pi = sc["tube"], sc["volume"], sc["supply"], sc["initial"]
    G_star = choked_massflux(ps, tube.length, tube.diameter)
    rate = RT / V * G_star * tube.area
    t_c = (G_star * C_ISO - pi) / rate
    check("fill: the choke ends at (G* c - p_i) V / (R T G* A)",
          abs(r.choke_events[0] / t_c - 1), 1e-8)
    check("fill: linear rise while choked",
          abs(r.pressure_at(0.5 * t_c)["tank"][0] / (pi + rate * 0.5 * t_c) - 1), 1e-9)
    # two tanks: equal volumes, so p_a + p_b holds the mass
    r = results["two_tanks"]
    total = r.pressures["tank_a"] + r.pressures["tank_b"]
    check("two_tanks: mass conserved", float(np.max(np.abs(total / total[0] - 1))), 1e-9)
    for name, r in results.items():
        check(f"{name}: ends within 1 % of equilibrium", r.distance_to_equilibrium(), 0.01)
        check(f"{name}: the duration is the 1 % time",
              abs(r.duration / time_to_one_percent(name) - 1), 1e-12)
        alt = SCENE_FUNCTIONS[name](n=201, ode={"method": "LSODA", "rtol": 1e-8,
                                                "atol_scale": 100.0})
        ours = r.pressure_at(alt.t)
        err = max(float(np.max(np.abs(alt.pressures[k] - ours[k]))) for k in ours)
        check(f"{name}: DOP853 rtol 1e-10 vs LSODA rtol 1e-8 (of the range)",
              err / r.pressure_range, 1e-6)
        check(f"{name}: choke events, DOP853 vs LSODA",
              abs(alt.choke_events[0] / r.choke_events[0] - 1), 1e-6)
    return rows


def report(results: dict[str, SceneResult] | None = None) -> dict[str, SceneResult]:
    """Run the five scenes and print a table of them."""
    results = results or {name: fn() for name, fn in SCENE_FUNCTIONS.items()}
    print(f"{'scene':<13} {'duration':>9} {'t_1%':>10} {'final pressures [Pa]':<27} "
          f"{'to eq.':>7} {'choked':>7} {'choke ends':>11} {'peak mdot':>11} {'peak Re':>8}")
    for name, r in results.items():
        finals = ", ".join(f"{p[-1]:.6g}" for p in r.pressures.values())
        t1 = time_to_one_percent(name, rounded=False)
        print(f"{name:<13} {r.duration:>8.4g}s {t1:>9.4g}s {finals:<27} "
              f"{r.distance_to_equilibrium():>7.2%} {r.choked_fraction:>7.1%} "
              f"{(r.choke_events[0] if r.choke_events else float('nan')):>10.4g}s "
              f"{np.max(np.abs(r.massflow)) * 1e3:>8.4g}g/s {np.max(r.reynolds):>8.0f}")
    return results


if __name__ == "__main__":
    import time
    t0 = time.perf_counter()
    print("self-checks:")
    self_check()
    print(f"({time.perf_counter() - t0:.2f} s)\n")
    t0 = time.perf_counter()
    results = report()
    print(f"({time.perf_counter() - t0:.2f} s)\n\nscene checks:")
    scene_checks(results)
