"""Progress of a run: a tqdm bar in simulated time, and the solver's events
through :mod:`logging`.

The integrators call :meth:`Progress.step` once per accepted step and the
event methods (:meth:`~Progress.rejected`, :meth:`~Progress.restarted`,
:meth:`~Progress.switched`) where those happen; :class:`softflow.Simulation`
opens and closes the reporter around the run (``with progress: integ.run()``).

The bar
    Shown only for a run that has taken more than :data:`DELAY` seconds of wall
    time (a quick run prints nothing), only when standard error is a terminal
    (``progress=None``, the default) or when asked for (``progress=True``, e.g.
    in a notebook); ``progress=False`` turns it off. It counts simulated
    seconds up to the duration. :meth:`Progress.step` costs one attribute
    increment and one comparison per step: the clock is read every
    ``stride`` steps, the stride adapted to ~:data:`CHECK_INTERVAL` s of wall
    time, and tqdm is imported only when the bar opens.

The log
    Logger ``'softflow'``. DEBUG: every rejected step (Newton failure, error
    test, a mode switch being located) with its time and step, every restart
    of the BDF method, every discrete-state switch naming the component and
    state. INFO: one line per finished run (steps, rejections, wall time).
    ``logging.basicConfig(level=logging.DEBUG)`` or
    ``logging.getLogger('softflow').setLevel(logging.DEBUG)`` with a handler
    shows them; without a handler nothing is printed.
"""
from __future__ import annotations

import logging
import sys
import time
from typing import Any, Sequence

logger = logging.getLogger("softflow")
logger.addHandler(logging.NullHandler())

#: wall time [s] after which a run shows its bar
DELAY = 2.0
#: wall time [s] between two looks at the clock (and at most between bar updates)
CHECK_INTERVAL = 0.1


class Progress:
    """Reporter of one run.

    Parameters
    ----------
    duration : float [s]
        Simulated time the run goes to (the bar's total).
    enabled : bool or None, default None
        The bar: None shows it where standard error is a terminal, True always
        (after :data:`DELAY` s), False never. Logging is independent of it.
    state_names : sequence of str, optional
        Name of every state ('act branch'), to name switched discrete states.
    """

    def __init__(self, duration: float, enabled: bool | None = None,
                 state_names: Sequence[str] = ()) -> None:
        if enabled is not None and not isinstance(enabled, bool):
            raise TypeError(f"progress must be True, False or None, got {enabled!r}")
        self.duration = float(duration)
        self.state_names = list(state_names)
        if enabled is None:
            isatty = getattr(sys.stderr, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled = enabled
        self.bar: Any = None
        self.steps = 0
        self.rejections = 0
        self._next = sys.maxsize      # step count at which the clock is read next
        self._stride = 16
        self._debug = False
        self._t0 = self._last = 0.0
        self._t_shown = 0.0

    # -- context: the run ----------------------------------------------------------------
    def __enter__(self) -> Progress:
        self._debug = logger.isEnabledFor(logging.DEBUG)
        self._t0 = self._last = time.perf_counter()
        self._next = self._stride if self.enabled else sys.maxsize
        if self._debug:
            logger.debug("run to t = %.6g s started", self.duration)
        return self

    def __exit__(self, kind: Any, value: Any, tb: Any) -> None:
        wall = time.perf_counter() - self._t0
        if self.bar is not None:
            if kind is None:
                self.bar.update(self.duration - self._t_shown)
            self.bar.close()
            self.bar = None
        self._next = sys.maxsize
        if logger.isEnabledFor(logging.INFO):
            logger.info("run %s after %d steps (%d rejected) in %.3g s wall time",
                        "finished" if kind is None else "stopped", self.steps,
                        self.rejections, wall)

    # -- per accepted step ---------------------------------------------------------------
    def step(self, t: float) -> None:
        """An accepted step reached t [s]."""
        self.steps += 1
        if self.steps >= self._next:
            self._look(t)

    def advance(self, t: float, count: int) -> None:
        """``count`` accepted steps (the compiled loop's) reached t [s]."""
        self.steps += count
        if self.steps >= self._next:
            self._look(t)

    def reached(self, t: float) -> None:
        """The run is at t [s] (a caller that counts no steps: the batched
        variants' share run, :mod:`softflow.solve.variants`)."""
        if self.enabled:
            self._look(t)

    def steps_to_look(self) -> int:
        """Accepted steps before the next look at the clock (the compiled
        loop hands back then, so that the bar moves as it would)."""
        return max(1, self._next - self.steps)

    def _look(self, t: float) -> None:
        now = time.perf_counter()
        spent = now - self._last
        # next look after ~CHECK_INTERVAL s, from the rate of the last stride
        self._stride = max(1, min(100_000, int(self._stride * CHECK_INTERVAL / max(spent, 1e-6))))
        self._next = self.steps + self._stride
        self._last = now
        if self.bar is None:
            if now - self._t0 < DELAY:
                return
            self._open()
        self.bar.update(t - self._t_shown)
        self._t_shown = t

    def _open(self) -> None:
        from tqdm import tqdm
        self.bar = tqdm(total=self.duration, unit="s", desc="softflow",
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g}/{total:.4g} s "
                                   "[{elapsed}<{remaining}]",
                        leave=False, dynamic_ncols=True)
        # the bar opens after DELAY s of the run: its elapsed field counts from
        # the run's start, not from the bar's (it read 00:00 at its first show)
        self.bar.start_t -= time.perf_counter() - self._t0

    # -- events (rare: formatted only when logged) ---------------------------------------
    def rejected(self, t: float, h: float, why: str, detail: Any = None) -> None:
        """A step to t [s] of size h [s] was rejected: why is 'newton' (detail:
        the Newton outcome), 'error' (detail: the error estimate) or 'switch'
        (a discrete state switched within a step longer than the tolerance)."""
        self.rejections += 1
        if self._debug:
            if why == "newton":
                text = f"Newton did not converge ({getattr(detail, 'reason', detail)})"
            elif why == "error":
                text = f"error test failed (estimate {detail:.3g} > 1)"
            elif why == "switch":
                text = "a discrete state switched within it: locating the switch"
            else:
                text = why
            logger.debug("step rejected: t = %.9g s, h = %.3g s: %s", t, h, text)

    def restarted(self, t: float, h: float) -> None:
        """The BDF method restarted at order 1 at t [s] with first step h [s]."""
        if self._debug:
            logger.debug("BDF restart at t = %.9g s, first step %.3g s", t, h)

    def switched(self, t: float, before: Any, after: Any, discrete: Any) -> None:
        """Discrete states (a valve's mode, an actuator's branch) changed at t [s]:
        ``before``/``after`` are the state vectors, ``discrete`` their mask."""
        if self._debug:
            changed = [i for i in range(len(before)) if discrete[i] and before[i] != after[i]]
            names = ", ".join(
                f"{self.state_names[i] if i < len(self.state_names) else f'state {i}'} "
                f"{before[i]:g} -> {after[i]:g}" for i in changed)
            logger.debug("switch at t = %.9g s: %s", t, names)


#: the reporter of integrators run outside a Simulation: no bar, no events
class _Silent(Progress):
    def step(self, t: float) -> None:
        pass

    def advance(self, t: float, count: int) -> None:
        pass

    def steps_to_look(self) -> int:
        return 1 << 62

    def rejected(self, t: float, h: float, why: str, detail: Any = None) -> None:
        pass


SILENT = _Silent(1.0, False)
