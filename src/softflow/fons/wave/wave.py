"""fonsim's ``fons.wave.wave``: periodic wave shapes of an angle [rad] and
``time_to_angle``."""
from __future__ import annotations

import math

import numpy as np


def time_to_angle(time, frequency, phase=0.0):
    """Angle [rad] in [0, 2 pi) at ``time`` [s] of a wave of ``frequency`` [Hz]
    started at ``phase`` [rad]."""
    return ((np.asarray(time) * frequency + phase / (2 * math.pi)) % 1.0) * 2 * math.pi


def sine(angle):
    """sin(angle)."""
    return np.sin(angle)


def square(angle):
    """+1 on the first half of each period (its end included), -1 on the second."""
    return np.where(np.asarray(angle) % (2 * math.pi) <= math.pi, 1.0, -1.0)


def sawtooth(angle):
    """Falls linearly from +1 to -1 over each period."""
    return 1.0 - (np.asarray(angle) % (2 * math.pi)) / math.pi


def triangle(angle):
    """0 -> 1 -> 0 -> -1 -> 0 over each period, linear in between."""
    x = (np.asarray(angle) % (2 * math.pi)) / (2 * math.pi)
    return np.where(x < 0.25, 4 * x, np.where(x < 0.75, 2 - 4 * x, 4 * x - 4))


def unity(angle):
    """1 at every angle."""
    return np.ones_like(np.asarray(angle, dtype=float))


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"wave.wave.{name}", __name__)
