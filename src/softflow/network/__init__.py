"""Variables, terminals, components, nodes and systems."""
from .component import AutoFunction, Component
from .system import NetworkError, Node, System
from .variable import Terminal, Variable

__all__ = ["Variable", "Terminal", "Component", "AutoFunction", "Node", "System", "NetworkError"]
