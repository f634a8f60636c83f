"""fonsim's ``fons.data.writeout``: a run's results as a JSON file, laid out
as fonsim 0.6 lays it out."""
from __future__ import annotations

import datetime
import json
import socket
from pathlib import Path

#: fonsim 0.6's name of its JSON layout, which this file follows
SCHEME = "0.1-alpha"


def writeout_simulation(filename, simulation):
    """Write a run's results to a JSON file (the format follows the extension;
    JSON only), laid out as fonsim's: ``data`` holds the time series (SI: s,
    Pa, kg/s, kg) under the keys '0', '1', ... ('0' is the time);
    ``components[label]['terminals'][terminal]['over' | 'through'][key]``
    and ``components[label]['states'][key]`` give each variable's index in
    ``data``, by variable key ('pressure', 'massflow', 'mass');
    ``simulation`` holds the system's ``label``, ``nb_components`` and
    ``nb_nodes`` (fonsim's nodes: a FreeActuator's terminal 'b' counts apart)
    and the index of the time. (fonsim 0.6 writes, under each terminal
    variable's index, a row of the component's arguments at one step instead
    of the variable's time series: here each index holds its series.)

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
    data = [result.times.tolist()]

    def keep(values):
        data.append([float(x) for x in values])
        return len(data) - 1

    system = simulation.system
    components = {}
    for comp in system.components:
        terms = {}
        for term, key, _ in _arguments(comp):
            entry = terms.setdefault(term, {"over": {}, "through": {}})
            role = "over" if _is_across(comp, term, key) else "through"
            entry[role][key] = keep(_values(comp, key, term))
        states = {s.quantity: keep(result.get(comp.label, s.label)) for s in comp.states}
        components[comp.label] = {"terminals": terms, "states": states}
    now = datetime.datetime.now(datetime.timezone.utc).astimezone()
    doc = {
        "scheme": SCHEME,
        "general": {"date": now.strftime("%Y/%m/%d %H:%M:%S %z"),
                    "hostname": socket.gethostname(), "version": f"softflow {__version__}"},
        "simulation": {"system": {"label": system.label,
                                  "nb_components": len(system.components),
                                  "nb_nodes": _nb_nodes(system)},
                       "solver": {},
                       "time": 0},
        "components": components,
        "data": {str(i): series for i, series in enumerate(data)},
    }
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(doc, fh)


def _arguments(comp):
    """(terminal, key, label) of the component's terminal variables, in fonsim's
    order (a softflow component: each terminal's through, then across ones)."""
    if hasattr(comp, "_fonsim_arguments"):
        return comp._fonsim_arguments()
    return [(t.label, v.quantity, v.label) for t in comp.terminals
            for role in ("through", "across") for v in t.variables if v.role == role]


def _is_across(comp, term, key):
    for t in comp.terminals:
        if t.label == term:
            for v in t.variables:
                if v.quantity == key:
                    return v.role == "across"
    return key == "pressure"


def _values(comp, key, term):
    if hasattr(comp, "_values"):
        return comp._values(key, term)
    return comp.get(key, term)


def _nb_nodes(system):
    """fonsim's count of nodes: softflow's, a FreeActuator's terminal 'b' apart
    (its own node where it is not connected)."""
    count = getattr(system, "fonsim_node_count", None)
    return count() if count is not None else len(system.nodes())


def __getattr__(name):
    from .._unsupported import unsupported
    return unsupported(f"data.writeout.{name}", __name__)
