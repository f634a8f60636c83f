"""fonsim's ``fons.visual.plotting``: quick plots (``fons.plot``, ``fons.plot_state``)
of a run's results."""
from __future__ import annotations

import pint

from ...units import UnitError, quantity_unit, ureg


def _component_and_terminal(system, item):
    if isinstance(item, (tuple, list)) and len(item) == 2:
        comp, term = item
    else:
        comp, term = item, None
    label = comp if isinstance(comp, str) else getattr(comp, "label", None)
    return system.get(label), term


def _plot(axs, sim, label, unit, components, states):
    result = getattr(sim, "result", None)
    if result is None:
        raise RuntimeError("fons.plot: the simulation has not run; call sim.run() first")
    for item in components:
        comp, term = _component_and_terminal(sim.system, item)
        if states:
            values = comp.get_state(label) if hasattr(comp, "get_state") else comp.get(label)
            quantity = next((s.quantity for s in comp.states if label in (s.label, s.quantity)),
                            label)
        else:
            values = comp.get(label, term)
            quantity = next((v.quantity for t in comp.terminals for v in t.variables
                             if label in (v.label, v.quantity)), label)
        si = quantity_unit(quantity)
        if si is None:
            raise UnitError(f"fons.plot: the unit of {quantity!r} is not known; plot "
                            f"system.get({comp.label!r}).get({label!r}) yourself")
        try:
            factor = ureg.Quantity(1.0, si).to(unit).magnitude
        except (pint.DimensionalityError, pint.UndefinedUnitError) as err:
            raise UnitError(f"fons.plot: cannot show {label!r} of {comp.describe()} in "
                            f"{unit!r}: {err}") from None
        name = comp.label if term is None else f"{comp.label}.{term}"
        axs.plot(result.times, values * factor, label=name)
    axs.set_ylabel(f"{label} [{unit}]")
    axs.legend()


def plot(axs, sim, label, unit, components):
    """Plot a terminal variable of components over time on matplotlib axes.

    Parameters
    ----------
    axs : matplotlib Axes
    sim : Simulation (after run)
    label : str
        Variable, e.g. 'pressure' (absolute) or 'massflow'.
    unit : str
        Unit to show it in, e.g. 'bar', 'g/s'.
    components : iterable
        Component labels or objects, or (component, terminal_label) pairs.
    """
    _plot(axs, sim, label, unit, components, states=False)


def plot_state(axs, sim, label, unit, components):
    """Plot a state (e.g. 'mass') or output (e.g. 'volume') of components over
    time; arguments as :func:`plot`."""
    _plot(axs, sim, label, unit, components, states=True)


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"visual.plotting.{name}", __name__)
