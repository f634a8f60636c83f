"""fonsim's ``fons.data.writeout``: a run's results as a JSON file."""
from __future__ import annotations

import datetime
import json
import socket
from pathlib import Path


def writeout_simulation(filename, simulation):
    """Write a run's results to a JSON file (the format follows the extension;
    JSON only), laid out as fonsim's: ``components`` map each component's
    terminal variables ('over' for across, 'through') and states to keys of
    ``data``, which holds the time series (SI: Pa, kg/s, kg, s).

    Parameters
    ----------
    filename : str or Path
        Ends in ``.json``.
    simulation : Simulation
        A Simulation that has run.
    """
    path = Path(filename)
    if path.suffix.lower() != ".json":
        raise ValueError(f"fons.data.writeout_simulation: {str(filename)!r}: only JSON files "
                         f"are written (name it *.json); for CSV use "
                         f"simulation.result.to_csv(path)")
    result = getattr(simulation, "result", None)
    if result is None:
        raise RuntimeError("fons.data.writeout_simulation: the simulation has not run; call "
                           "simulation.run() first")
    from ... import __version__
    data = {"time": result.times.tolist()}
    components = {}
    for comp in simulation.system.components:
        terms = {}
        for t in comp.terminals:
            entry = {"over": {}, "through": {}}
            for var in t.variables:
                key = f"{comp.label}/{t.label}/{var.label}"
                data[key] = result.get(comp.label, var.quantity, terminal=t.label).tolist()
                entry["over" if var.role == "across" else "through"][var.label] = key
            terms[t.label] = entry
        states = {}
        for s in comp.states:
            key = f"{comp.label}/{s.label}"
            data[key] = result.get(comp.label, s.label).tolist()
            states[s.label] = key
        components[comp.label] = {"terminals": terms, "states": states, "time": "time"}
    doc = {
        "scheme": "softflow.fons simulation writeout 1",
        "general": {"date": datetime.datetime.now().isoformat(timespec="seconds"),
                    "hostname": socket.gethostname(), "version": f"softflow {__version__}"},
        "simulation": {"system": {"label": simulation.system.label,
                                  "nb components": len(simulation.system.components)},
                       "solver": {"name": f"softflow {result.stats.get('method', '')}"},
                       "time": "time"},
        "components": components,
        "data": data,
    }
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh)


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"data.writeout.{name}", __name__)
