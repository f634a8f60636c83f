"""Small functions compiled from generated source, with the compiled code
cached by its text: networks rebuilt with the same structure (a design loop)
compile each once. Generated sources hold only names and integer literals of
our own; the values they use are passed in a namespace."""
from __future__ import annotations

from functools import lru_cache


@lru_cache(maxsize=512)
def _code(source, mode):
    return compile(source, "<softflow generated>", mode)


def expression(source, namespace):
    """The value of the expression ``source`` (e.g. a lambda) in ``namespace``."""
    return eval(_code(source, "eval"), namespace)


def function(source, name, namespace):
    """The function ``name`` defined by ``source``, with ``namespace`` as its globals."""
    exec(_code(source, "exec"), namespace)
    return namespace[name]
