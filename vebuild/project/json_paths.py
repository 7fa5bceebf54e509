"""JSON paths into the project file (``$.photos[2].vanishing_segments.x[0]``), written, read back,
and said in words from the document they point into (``photo 'door', field "width"``), so that an
error names the place both ways (:class:`~vebuild.errors.ProjectError`)."""

from __future__ import annotations

import json
import re
from typing import Any


def json_path(parts: Any) -> str:
    """A JSON path such as ``$.photos[2].vanishing_segments.x[0]`` from path components."""
    return "$" + "".join(f"[{p}]" if isinstance(p, int) else json_key(p) for p in parts)


# The nouns for the project file's lists, where "the key's name less its s" would read wrongly.
_NOUNS = {"hypotheses": "hypothesis", "analyses": "analysis", "presets": "lighting preset",
          "pages": "texture page", "faces": "texture face", "audit": "audit entry",
          "reference_distances": "reference distance", "known_lengths": "known length",
          "evidence_markers": "evidence marker", "edge_observations": "edge observation"}
_PATH_PART = re.compile(r'\.([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]|\[("(?:[^"\\]|\\.)*")\]')


def parse_json_path(where: str) -> list[str | int] | None:
    """The components of a JSON path written by :func:`json_path`; None if ``where`` is not one."""
    if not where.startswith("$"):
        return None
    parts: list[str | int] = []
    pos = 1
    while pos < len(where):
        m = _PATH_PART.match(where, pos)
        if m is None:
            return None
        key, index, quoted = m.groups()
        parts.append(key if key is not None else int(index) if index is not None else json.loads(quoted))
        pos = m.end()
    return parts


def _ordinal(n: int) -> str:
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def field_words(where: str, data: Any) -> str:
    """A JSON path said in words, from the document it points into.

    ``$.photos[2].width`` in a project whose third photo has the id 'door' reads
    ``photo 'door', field "width"``; ``$.model.nodes[0].joint.face`` reads
    ``node 'table', field "joint.face"``. '' where the path is the whole file or a top-level key,
    which already reads as a field's name, or is not a JSON path.
    """
    parts = parse_json_path(where)
    if not parts or len(parts) == 1:
        return ""
    words: list[str] = []
    field: list[str] = []
    node: Any = data
    for k, part in enumerate(parts):
        child = _child(node, part)
        owner = parts[k - 1] if k else None
        if isinstance(part, int) and isinstance(owner, str) and (child is None or isinstance(child, dict)):
            # An entry of one of the file's lists of things: a photo, a node, a relation.
            noun = _NOUNS.get(owner, owner.removesuffix("s").replace("_", " "))
            name = _item_name(child)
            words.append(f"{noun} '{name}'" if name is not None else f"the {_ordinal(part + 1)} {noun}")
            field = []
        elif isinstance(part, int):
            if field:
                words.append(f'field "{".".join(field)}"')
            words.append(f"its {_ordinal(part + 1)} item")
            field = []
        else:
            field.append(part)
        node = child
    if field:
        words.append(f'field "{".".join(field)}"')
    return ", ".join(words)


def _child(node: Any, part: str | int) -> Any:
    if isinstance(part, int):
        return node[part] if isinstance(node, list) and 0 <= part < len(node) else None
    return node.get(part) if isinstance(node, dict) else None


def _item_name(item: Any) -> str | None:
    if isinstance(item, dict):
        for key in ("id", "name", "label"):
            if isinstance(item.get(key), str) and item[key]:
                return str(item[key])
    return None


def json_key(name: str) -> str:
    """A key as a JSON path writes it: ``.name``, or ``["a b"]`` where it is not an identifier."""
    if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
        return f".{name}"
    return f"[{json.dumps(name, ensure_ascii=False)}]"


def listing(names: Any, limit: int = 10) -> str:
    """Names quoted for an error message: ``'a', 'b' and 3 more`` (``none`` where there are none)."""
    names = list(names)
    if not names:
        return "none"
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")
