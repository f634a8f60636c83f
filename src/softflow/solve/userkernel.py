"""The per-instance path for user-written components (the paper's ``Actuator``).

States are eliminated locally: update_state gives the end-of-step states as a
function of the component's own variables, and the residual's Jacobian picks
up dF/dS · dS/dV by the chain rule. Derivatives come from forward differences.
"""
from __future__ import annotations

import numpy as np

from ..fluids.base import FluidError
from ..network.component import AutoFunction
from ..network.system import NetworkError
from .compiled import expression, function
from .validity import ComponentError, user_code_error

#: Exceptions that pass from user code unchanged: a fluid asked for a state outside
#: its range (the solver cuts the step, as for library components), and softflow's
#: own errors that already name the component.
_PASS = (FluidError, NetworkError)

#: Typical magnitude per quantity, used to size finite-difference steps at zero.
_TYPICAL = {"pressure": 1e5, "massflow": 1e-4, "mass": 1e-4, "volume": 1e-5,
            "volumeflow": 1e-6, "temperature": 300.0}
_REL = 1.5e-8


def _compiled_states(names):
    """``out -> np.array([float(out[name]) for name in names])`` for the dict an
    update_state returns, compiled once: 0.25 us a call against 0.55 us for
    the comprehension (one state, measured). The names are passed as values,
    never written into the source."""
    keys = {f"k{i}": n for i, n in enumerate(names)}
    picks = ", ".join(f"f(o[k{i}])" for i in range(len(names)))
    return expression(f"lambda o: a([{picks}])", {"a": np.array, "f": float, **keys})


def _compiled_call(func, plan):
    """``(t, v, s) -> func(...)`` with the arguments picked from the time (or
    step), the variables v and the states s in the order of ``plan``, compiled
    once from source: 0.3 us a call against 0.7 us for gathering a list by
    the plan at every call (three arguments, measured). The source holds only
    the names t, v, s, f and integer indices from our own binding."""
    picks = ["t" if kind == "t" else f"{kind}[{int(k)}]" for kind, k in plan]
    return expression(f"lambda t, v, s: f({', '.join(picks)})", {"f": func})


def _update_from_rates(comp, rates, names, snames):
    """An ``update_state`` (dt, states..., variables...) -> {state: state + dt·rate}
    made from a component's ``state_rates``: the one place where a user's
    rates meet the step, affine in dt by construction."""
    if not isinstance(rates, AutoFunction):
        rates = AutoFunction(rates, "state_rates")
    bad = [a for a in rates.argnames if a not in names]
    if bad:
        kind = "a state" if any(a in snames for a in bad) else "no variable"
        raise NetworkError(
            f"{comp.describe()}: state_rates argument(s) {bad} name {kind}; rates may use "
            f"the component's variables {names} (not its states, nor t)")
    func, n_s, owner, label = rates.func, len(snames), comp.describe(), comp.label

    def update(dt, *args):
        states, values = args[:n_s], args[n_s:]
        try:
            r = func(*values)
        except _PASS:
            raise
        except Exception as err:    # the caller adds the time (UserKernel._fail)
            raise user_code_error(err, owner, label, "state_rates", None)
        try:
            return {s: x + dt * float(r[s]) for s, x in zip(snames, states)}
        except (KeyError, TypeError, IndexError, ValueError):
            raise NetworkError(f"{owner}: state_rates must return {{state: rate}} with a "
                               f"number for every state {snames}, got {r!r}") from None

    up = AutoFunction.__new__(AutoFunction)    # its arguments are bound by name below
    up.func, up.kind, up.argnames = update, "update_state", ("dt", *snames, *rates.argnames)
    return up


class UserKernel:
    """Evaluates one user component; exposes the same kernel/update interface as
    library groups, with n = 1 and a dense local Jacobian pattern."""

    def __init__(self, comp):
        self.comp = comp
        names, snames = comp.variable_names()
        iface = comp.interface_variables()
        self.nv = len(names)
        self.ns = len(snames)
        self.neq = comp.n_equations
        self.vscale = np.array([_TYPICAL.get(v.quantity, 1.0) for _, v in iface])
        self.sscale = np.array([_TYPICAL.get(s.quantity, 1.0) for s in comp.states])
        self.snames = snames
        ev = comp.evaluate
        if ev is None:
            raise NetworkError(f"{comp.describe()}: no evaluate function; assign "
                               "self.evaluate = self.auto(function) in __init__")
        if not isinstance(ev, AutoFunction):
            ev = AutoFunction(ev, "evaluate")
        self.ev = ev
        self.ev_args = self._bind(ev, names, snames, special=("t",))
        self._ev_call = _compiled_call(ev.func, self.ev_args)
        self._ev_shape = (self.neq,)
        up = comp.update_state
        rates = getattr(comp, "state_rates", None)
        if rates is not None:
            if up is not None:
                raise NetworkError(f"{comp.describe()}: has both update_state and state_rates; "
                                   "give one of them")
            if not self.ns:
                raise NetworkError(f"{comp.describe()}: has state_rates but no states "
                                   "(declare them with set_states)")
            up = _update_from_rates(comp, rates, names, snames)
        if self.ns:
            if up is None:
                raise NetworkError(f"{comp.describe()}: has states {snames} but no update_state; "
                                   "assign self.update_state = self.auto_state(function)")
            if not isinstance(up, AutoFunction):
                up = AutoFunction(up, "update_state")
            self.up = up
            self.up_args = self._bind(up, names, snames, special=("dt",))
            self._up_call = _compiled_call(up.func, self.up_args)
            self._up_states = _compiled_states(snames)
        else:
            self.up = None
        self.pattern = tuple((e, k) for e in range(self.neq) for k in range(self.nv))
        self.ev_v = [k for kind, k in self.ev_args if kind == "v"]
        self.ev_s = [k for kind, k in self.ev_args if kind == "s"]
        self.up_v = ([k for kind, k in self.up_args if kind == "v"] if self.up else [])
        self._compile_rows()

    def _bind(self, fn, names, snames, special):
        out = []
        for a in fn.argnames:
            if a in special:
                out.append(("t", 0))
            elif a in names:
                out.append(("v", names.index(a)))
            elif a in snames:
                out.append(("s", snames.index(a)))
            else:
                avail = list(special) + names + snames
                raise NetworkError(f"{self.comp.describe()}: {fn.kind} argument {a!r} matches no "
                                   f"variable; available names are {avail}")
        return out

    # -- calls into user code ---------------------------------------------------------
    def _fail(self, err, method, t):
        """The ComponentError for an exception ``err`` from the user's ``method``
        (one from ``state_rates``, raised without the time, gets it here)."""
        if isinstance(err, ComponentError):
            method, err = err.method, err.__cause__
        return user_code_error(err, self.comp.describe(), self.comp.label, method, t)

    def _call_ev(self, t, v, s):
        try:
            out = self._ev_call(t, v, s)
        except _PASS:
            raise
        except Exception as err:
            raise self._fail(err, "evaluate", t)
        return self._residual_of(out)

    def _residual_of(self, out):
        """evaluate's answer as a 1-D float array of length neq, or a clear error."""
        try:
            out = np.asarray(out, dtype=float)
        except (TypeError, ValueError):
            raise NetworkError(f"{self.comp.describe()}: evaluate must return a list of numbers, "
                               f"got {out!r}") from None
        if out.shape != self._ev_shape:
            out = out.reshape(-1)
            if out.size != self.neq:
                raise NetworkError(
                    f"{self.comp.describe()}: evaluate returned {out.size} residual(s) but the "
                    f"component has {self.neq} unknown(s) to determine (one per through variable "
                    f"and local variable)")
        return out

    def _call_up(self, dt, v, s, t=None):
        try:
            out = self._up_call(dt, v, s)
        except _PASS:
            raise
        except Exception as err:
            raise self._fail(err, "update_state", t)
        if type(out) is dict and len(out) == self.ns:
            try:   # the usual answer, every state once: no diagnostics needed
                return self._up_states(out)
            except KeyError:
                pass
        return self._states_of(out)

    def _states_of(self, out):
        """update_state's answer as a 1-D float array of the states, or a clear error."""
        if isinstance(out, dict):
            missing = [n for n in self.snames if n not in out]
            extra = [n for n in out if n not in self.snames]
            if missing or extra:
                raise NetworkError(f"{self.comp.describe()}: update_state must return every state "
                                   f"{self.snames}; missing {missing}, unknown {extra}")
            return np.array([float(out[n]) for n in self.snames])
        # a copy: the user's function may keep the array it returns and change it later
        arr = np.array(out, dtype=float).reshape(-1)
        if arr.size != self.ns:
            raise NetworkError(f"{self.comp.describe()}: update_state returned {arr.size} values "
                               f"for {self.ns} state(s)")
        return arr

    def _compile_rows(self):
        """The residual (no Jacobian) and the state update of this component as
        two generated functions, each calling the user's functions directly with
        their arguments picked, and checking the usual answers inline (the calls
        of :meth:`_call_up` and :meth:`_call_ev`, same results): on the paper's
        actuator ~0.4 us of ~2 us a step. Anything unusual goes to the
        diagnostics of :meth:`_states_of` and :meth:`_residual_of`."""
        env = {"ev": self.ev.func, "asarray": np.asarray, "array": np.array, "f": float,
               "residual_of": self._residual_of, "states_of": self._states_of,
               "shape": self._ev_shape, "ns": self.ns, "PASS": _PASS, "fail": self._fail}
        ev_picks = ", ".join("t" if kind == "t" else f"{kind}[{int(k)}]"
                             for kind, k in self.ev_args)
        lines = ["def row(v, s, t, dt):"]
        if self.up is not None:
            env["up"] = self.up.func
            env.update({f"k{i}": n for i, n in enumerate(self.snames)})
            up_picks = ", ".join("dt" if kind == "t" else f"{kind}[{int(k)}]"
                                 for kind, k in self.up_args)
            states = ", ".join(f"f(o[k{i}])" for i in range(self.ns))
            # (a try block costs nothing until it catches, Python >= 3.11)
            update = ["    try:",
                      "        o = up(" + up_picks + ")",
                      "    except PASS:",
                      "        raise",
                      "    except Exception as err:",
                      "        raise fail(err, 'update_state', T)",
                      "    if type(o) is dict and len(o) == ns:",
                      "        try:",
                      f"            s = array([{states}])",
                      "        except KeyError:",
                      "            s = states_of(o)",
                      "    else:",
                      "        s = states_of(o)"]
            lines += [u.replace("T)", "t)") for u in update]
            upd = (["def update(v, s, dt):"] + [u.replace("T)", "None)") for u in update]
                   + ["    return s"])
        lines += ["    try:",
                  "        r = ev(" + ev_picks + ")",
                  "    except PASS:",
                  "        raise",
                  "    except Exception as err:",
                  "        raise fail(err, 'evaluate', t)",
                  "    try:",
                  "        F = asarray(r, dtype=float)",
                  "    except (TypeError, ValueError):",
                  "        return residual_of(r)",
                  "    return F if F.shape == shape else residual_of(F)"]
        self._row = function("\n".join(lines), "row", env)
        self._update = (function("\n".join(upd), "update", dict(env))
                        if self.up is not None else None)
        #: (v, s_old, t, dt) -> residual row, and (v, s, dt) -> end-of-step states
        #: (None without states): what the assembly calls directly
        self.residual_row = self._row
        self.update_row_fn = self._update

    # -- kernel interface ---------------------------------------------------------------
    # Groups of library components take (n, nv) variables and (n, ns) states; a user
    # component is one instance, and the assembly calls its *_row methods with the
    # 1-D rows directly (no reshaping of S, no row picking: ~0.4 us a step).
    def update(self, V, S, dt):
        return self.update_row(V[0], S[0], dt)[None, :]

    def update_row(self, v, s, dt):
        """End-of-step states (1-D) from the variables v and start-of-step states s;
        s itself when the component has none."""
        if self._update is None:
            return s
        return self._update(v, s, dt)

    def kernel(self, V, S, t, dt, jac):
        F, J = self.kernel_row(V[0], S[0], t, dt, jac)
        return F[None, :], (None if J is None else J[None, :])

    def kernel_row(self, v, s_old, t, dt, jac):
        """Residual (1-D) and, with jac, the dense local Jacobian (flattened row-major,
        the order of ``pattern``) at the variables v and start-of-step states s_old."""
        if not jac:
            return self._row(v, s_old, t, dt), None
        s = self._call_up(dt, v, s_old, t) if self.up is not None else s_old
        F = self._call_ev(t, v, s)
        v = v.copy()     # perturbed in place below
        J = np.zeros((self.neq, self.nv))
        for k in self.ev_v:
            h = _REL * max(abs(v[k]), self.vscale[k])
            vk = v[k]
            v[k] = vk + h
            J[:, k] = (self._call_ev(t, v, s) - F) / h
            v[k] = vk
        if self.up is not None and self.ev_s:
            dFds = np.zeros((self.neq, self.ns))
            for k in self.ev_s:
                h = _REL * max(abs(s[k]), self.sscale[k])
                sp = s.copy()
                sp[k] += h
                dFds[:, k] = (self._call_ev(t, v, sp) - F) / h
            dSdv = np.zeros((self.ns, self.nv))
            for k in self.up_v:
                h = _REL * max(abs(v[k]), self.vscale[k])
                vk = v[k]
                v[k] = vk + h
                dSdv[:, k] = (self._call_up(dt, v, s_old, t) - s) / h
                v[k] = vk
            J += dFds @ dSdv
        return F, J.ravel()
