"""fonsim 0.6 names that softflow.fons does not provide, and what to use instead."""
from __future__ import annotations

_COMPONENTS = "fons.CircularTube, fons.Container, fons.FreeActuator, ..."
_INTERNAL = ("fonsim's internal module {name!r} has no counterpart in softflow.fons; use the "
             "public names (" + _COMPONENTS + ") or softflow's own API (import softflow as sf)")
_PHYSICS = ("{name!r} is one of fonsim's per-component equation functions; softflow writes "
            "each law once inside its components: use the component (" + _COMPONENTS + ")")

#: name -> advice
ADVICE = {
    "CircularTube_autodiff": "use fons.CircularTube (softflow's tubes have analytic Jacobians)",
    "Container_autodiff": "use fons.Container (analytic Jacobian)",
    "Dummy": ("fonsim's placeholder component has no softflow counterpart; leave the "
              "terminal unconnected with Simulation(system, allow_unconnected=True) or "
              "write a fons.Component"),
    "Bingham": ("softflow has Newtonian fluids only: use fons.fluid.IdealIncompressible "
                "(or softflow.Fluid('...', level='eos'))"),
    "setnumpythreads": "softflow does not change NumPy's thread settings; set OMP_NUM_THREADS",
    "notice_beta": "softflow prints no notice on import",
    "colors": "use matplotlib's colours directly",
    "indexmatch": "softflow matches result names exactly (Component.get lists the names)",
    "conversion": "use pint through softflow: sf.Q_(1, 'bar').to('Pa')",
}
for _n in ("core", "solver", "node", "component", "system", "simulation", "variable",
           "terminal", "terminals", "containers", "containers_autodiff", "restrictors",
           "sources", "valves", "actuators", "dummy", "circulartube_autodiff", "dataseries",
           "interpolate", "curve", "writeout", "custom", "math"):
    ADVICE.setdefault(_n, _INTERNAL.format(name=_n))
for _n in ("accumulator_compressible", "accumulator_incompressible",
           "circulartube_compressible", "circulartube_incompressible",
           "container_compressible", "container_incompressible",
           "flowrestrictor_compressible", "flowrestrictor_incompressible",
           "freeactuator_compressible", "freeactuator_incompressible",
           "volumeflowsource_compressible", "volumeflowsource_incompressible", "fd"):
    ADVICE.setdefault(_n, _PHYSICS.format(name=_n))


class FonsimNameError(AttributeError):
    """A fonsim 0.6 name that softflow.fons does not support; the message says
    what to use instead."""


def unsupported(name, module):
    """Raise FonsimNameError for ``name`` looked up in ``module`` (a module __getattr__)."""
    if name.startswith("__"):   # dunder lookups (copy, pickle, IPython) stay plain
        raise AttributeError(f"module {module!r} has no attribute {name!r}")
    short = name.rsplit(".", 1)[-1]
    advice = ADVICE.get(short)
    if advice is None:
        raise FonsimNameError(f"softflow.fons has no {name!r}: it is not part of fonsim 0.6's "
                              f"public API that softflow.fons covers (see "
                              f"docs/coming-from-fonsim.md); softflow's own API: "
                              f"import softflow as sf")
    raise FonsimNameError(f"softflow.fons does not support fonsim's {name!r}: {advice}")
