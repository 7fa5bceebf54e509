"""JSON for the fuzz tests: documents written with values json.dumps cannot write, and every path
into a document (tests/test_fuzz_loader.py, tests/test_fuzz_fspy.py)."""

from __future__ import annotations

import json
from typing import Any


class Raw(str):
    """JSON text put into a document as it is (what json.dumps cannot write: 5000 digits, 1e400)."""


def dumps(value: Any, compact: bool = False) -> str:
    """``value`` as JSON text, each :class:`Raw` written as it is; ``compact``: no spaces after the
    separators (as JavaScript's ``JSON.stringify`` writes, and so fSpy)."""
    item, key = (",", ":") if compact else (", ", ": ")
    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, dict):
        return "{" + item.join(f"{json.dumps(k)}{key}{dumps(v, compact)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + item.join(dumps(v, compact) for v in value) + "]"
    return json.dumps(value)


def paths(value: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every path into ``value`` (keys and list indices), the whole first."""
    out = [prefix]
    if isinstance(value, dict):
        for k, v in value.items():
            out += paths(v, (*prefix, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            out += paths(v, (*prefix, i))
    return out


def at(doc: Any, path: tuple[Any, ...]) -> tuple[Any, Any] | None:
    """The container holding the value at ``path`` in ``doc``, and that value; None where an
    earlier mutation removed it or made a container on the way text or a number (text can be
    indexed, so it is refused here rather than walked into)."""
    parent: Any = None
    target: Any = doc
    try:
        for part in path:
            if not isinstance(target, dict | list):
                return None
            parent, target = target, target[part]
    except (KeyError, IndexError, TypeError):
        return None
    return parent, target
