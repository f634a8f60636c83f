"""fonsim's wave generators (``fons.wave``) over softflow's waveforms.

``Custom(wave_array, time_notation='absolute', kind='previous')`` is a wave
through given points with fonsim's kinds ('previous', 'zero', 'next',
'nearest', 'linear', 'slinear', 'quadratic', 'cubic': scipy's ``interp1d``
names, the same values), and it declares the times at which it or its slope
jumps, so the adaptive integrator lands on them. As in fonsim,
``Custom(...) * 1e5 + fons.pressure_atmospheric`` changes the wave in place
and returns it (``copy()`` makes a separate one).

The periodic shapes ``sine``, ``square``, ``sawtooth``, ``triangle`` and
``unity`` take an angle [rad]; ``time_to_angle(time, frequency, phase)`` gives
it. A source driven by them is a plain callable (no declared jumps: the
adaptive step finds them by rejection); softflow's own ``waveforms.Sine`` and
``waveforms.Square`` declare theirs.
"""
from __future__ import annotations

from . import custom, wave
from .custom import Custom
from .wave import sawtooth, sine, square, time_to_angle, triangle, unity

__all__ = ["Custom", "custom", "wave", "sawtooth", "sine", "square", "time_to_angle",
           "triangle", "unity"]


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"wave.{name}", __name__)
