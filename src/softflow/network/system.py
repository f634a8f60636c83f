"""System: a set of components and the nodes that join their terminals."""
from __future__ import annotations

from operator import attrgetter
from typing import TYPE_CHECKING, Any, Iterable, Iterator, Union

from .component import Component
from .variable import Terminal

if TYPE_CHECKING:
    from typing_extensions import Self

    #: What :meth:`System.connect` takes: a component label, a ``(label, terminal)``
    #: pair, a Component or a Terminal.
    TerminalSpec = Union[str, tuple[str, str], Component, Terminal]


_terminals_of = attrgetter("terminals")


class NetworkError(ValueError):
    """The network is ill-formed: bad labels, bad connections, wrong equation counts."""


class Node:
    """A junction of terminals: one unknown per across quantity, one
    conservation equation per through quantity."""

    def __init__(self, index: int, terminals: Iterable[Terminal]) -> None:
        self.index = index
        self.terminals = list(terminals)

    @property
    def name(self) -> str:
        return "node(" + ", ".join(t.name for t in self.terminals) + ")"

    def quantities(self, role: str) -> list[str]:
        seen: list[str] = []
        for t in self.terminals:
            for v in t.variables:
                if v.role == role and v.quantity not in seen:
                    seen.append(v.quantity)
        return seen

    def __repr__(self) -> str:
        return f"<Node {self.index}: {[t.name for t in self.terminals]}>"


class System:
    """A fluidic network: components plus connections.

    Add components with ``system += component`` or ``system.add(...)`` and join
    terminals with :meth:`connect`.
    """

    def __init__(self, label: str = "system") -> None:
        self.label = label
        self.components: list[Component] = []
        self._by_label: dict[str, Component] = {}
        # union-find over terminals, each keyed by (component label, terminal
        # index): plain values, so a pickled or deep-copied System keeps its
        # connections (object ids would not survive either)
        self._parent: dict[tuple, tuple] = {}
        self._connected: set[tuple] = set()

    # -- building -----------------------------------------------------------------
    def add(self, *components: Component | list[Component] | tuple[Component, ...]) -> Self:
        """Add one or more components; their labels must be unique."""
        for c in components:
            if isinstance(c, (list, tuple)):
                self.add(*c)
                continue
            if not isinstance(c, Component):
                raise NetworkError(f"System.add expects Component objects, got {c!r}")
            if c.label in self._by_label:
                raise NetworkError(f"System: duplicate component label {c.label!r}")
            if not c.terminals:
                raise NetworkError(f"{c.describe()} has no terminals; call set_terminals "
                                   "in its __init__")
            self.components.append(c)
            self._by_label[c.label] = c
            for k in range(len(c.terminals)):
                self._parent[(c.label, k)] = (c.label, k)
        return self

    def __iadd__(self, component: Component | list[Component] | tuple[Component, ...]) -> Self:
        self.add(component)
        return self

    def get(self, label: str) -> Component:
        """The component with this label."""
        try:
            return self._by_label[label]
        except KeyError:
            raise KeyError(self._unknown_label(label)) from None

    def _unknown_label(self, label: object) -> str:
        import difflib
        close = difflib.get_close_matches(str(label), list(self._by_label), n=3)
        hint = f"; did you mean {close}?" if close else ""
        return f"System has no component {label!r}{hint}"

    def _key(self, t: Terminal) -> tuple[str, int] | None:
        """(component label, terminal index) of a terminal of this system, or None."""
        comp = t.component
        if comp is None or self._by_label.get(comp.label) is not comp:
            return None
        for k, other in enumerate(comp.terminals):
            if other is t:
                return (comp.label, k)
        return None

    def _find(self, tid: tuple) -> tuple:
        root = tid
        while self._parent[root] != root:
            root = self._parent[root]
        while self._parent[tid] != root:
            self._parent[tid], tid = root, self._parent[tid]
        return root

    def _resolve(self, spec: Any, taken: list) -> Any:
        """Turn a connect() argument into its terminal's key."""
        key: tuple[str, int] | None
        if type(spec) is str:
            # the common case first (a str is none of the types tested below)
            comp = self._by_label.get(spec)
            if comp is not None:
                connected = self._connected
                for k in range(len(comp.terminals)):
                    key = (spec, k)
                    if key not in connected and key not in taken:
                        return key
        if isinstance(spec, Terminal):
            key = self._key(spec)
            if key is None:
                raise NetworkError(f"connect: terminal {spec.name!r} belongs to no component "
                                   "of this system")
            return key
        if isinstance(spec, Component):
            spec = spec.label
        if isinstance(spec, tuple) and len(spec) == 2:
            label, term = spec
            if label not in self._by_label:
                raise NetworkError("connect: " + self._unknown_label(label))
            comp = self._by_label[label]
            try:
                return self._key(comp.get_terminal(term))
            except KeyError as err:
                raise NetworkError(f"connect: {err.args[0]}") from None
        if isinstance(spec, str):
            if spec not in self._by_label:
                raise NetworkError("connect: " + self._unknown_label(spec))
            comp = self._by_label[spec]
            for k in range(len(comp.terminals)):
                if (spec, k) not in self._connected and (spec, k) not in taken:
                    return (spec, k)
            if len(comp.terminals) == 1:
                # a one-terminal component (a tank, a source) joins its only
                # terminal's node again: connect('tube1', 'tank') then
                # connect('tank', 'tube2') chains through the tank, as in FONS
                return (spec, 0)
            raise NetworkError(
                f"connect: {comp.describe()} has no unconnected terminal left; name the "
                f"terminal explicitly, e.g. connect(({spec!r}, {comp.terminals[0].label!r}), ...)")
        raise NetworkError(
            "connect: expected a component label, a (label, terminal) tuple, a Component "
            f"or a Terminal, got {spec!r}")

    def connect(self, *specs: TerminalSpec) -> Self:
        """Join terminals into one node.

        Each argument is a component label (its first unconnected terminal is
        used, as in the FONS paper; a component with one terminal reuses it once
        it is connected, so ``connect('tube1', 'tank')`` then
        ``connect('tank', 'tube2')`` joins both tubes at the tank), a
        ``(label, terminal_label)`` tuple, a Component or a Terminal. Connecting
        a terminal that is already part of a node merges the nodes. A component
        with several terminals, all connected, must be given with the terminal
        named.
        """
        if len(specs) < 2:
            raise NetworkError("connect: give at least two terminals to join")
        taken: list = []
        resolve = self._resolve
        for s in specs:
            key = resolve(s, taken)
            if key in taken:
                t = self._by_label[key[0]].terminals[key[1]]
                raise NetworkError(f"connect: terminal {t.name!r} is given twice; a component "
                                   "cannot be connected to itself through one terminal")
            taken.append(key)
        return self._join(taken)

    def _join(self, keys: list) -> Self:
        """Join the terminals ``keys`` ((component label, terminal index) of this
        system's terminals, checked by the caller) into one node."""
        find, parent = self._find, self._parent
        root = find(keys[0])
        for tid in keys[1:]:
            r = find(tid)
            if r != root:
                parent[r] = root
        self._connected.update(keys)
        return self

    # -- topology -----------------------------------------------------------------
    def nodes(self) -> list[Node]:
        """Current nodes, in the order of the components' terminals."""
        node_of, count = self.terminal_nodes()
        buckets: list[list[Terminal]] = [[] for _ in range(count)]
        for t, k in zip([t for c in self.components for t in c.terminals], node_of):
            buckets[k].append(t)
        return [Node(i, ts) for i, ts in enumerate(buckets)]

    def terminal_nodes(self, terminal_count: int | None = None) -> tuple[list[int], int]:
        """(the node index of every terminal, in the order of the components'
        terminals; the number of nodes), nodes numbered as :meth:`nodes`
        returns them: by first appearance in that order. ``terminal_count``:
        the number of the components' terminals, where the caller has counted
        them."""
        parent, find = self._parent, self._find
        comps = self.components
        if terminal_count is None:
            terminal_count = sum(map(len, map(_terminals_of, comps)))
        if len(parent) == terminal_count:
            # the union-find's keys are the terminals in that order (added with
            # their components, never removed): no key tuples to build
            roots = [p if parent[p] == p else find(key) for key, p in parent.items()]
        else:   # a component's terminals changed after it was added
            roots = [find((c.label, k)) for c in comps for k in range(len(c.terminals))]
        index = {r: k for k, r in enumerate(dict.fromkeys(roots))}
        return list(map(index.__getitem__, roots)), len(index)

    def is_connected(self, terminal: Terminal) -> bool:
        """Whether ``terminal`` (of a component of this system) is part of a node."""
        return self._key(terminal) in self._connected

    def unconnected_terminals(self, terminal_count: int | None = None) -> list[Terminal]:
        """Terminals of no node (``terminal_count``: as for :meth:`terminal_nodes`)."""
        connected = self._connected
        comps = self.components
        if terminal_count is None:
            terminal_count = sum(map(len, map(_terminals_of, comps)))
        # every key connected (connect only records keys of the union-find, one
        # per terminal added): nothing to list, without a key per terminal
        if len(connected) == len(self._parent) == terminal_count:
            return []
        return [t for c in comps for k, t in enumerate(c.terminals)
                if (c.label, k) not in connected]

    def __contains__(self, label: object) -> bool:
        return label in self._by_label

    def __iter__(self) -> Iterator[Component]:
        return iter(self.components)

    def __len__(self) -> int:
        return len(self.components)

    def __repr__(self) -> str:
        return f"<System {self.label!r}: {len(self.components)} components>"
