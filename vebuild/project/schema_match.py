"""Whether a project document matches the JSON schema of format version 1, and jsonschema's
errors where it does not (:mod:`.validation` words them). jsonschema-rs, the schema compiled,
answers the question; jsonschema is imported and asked only for the errors. An edit's check
(``valid_before``) runs the schema over the list items the edit brought alone."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import jsonschema


@cache
def schema() -> dict[str, Any]:
    """The JSON Schema of format version 1."""
    text = resources.files("vebuild.schema").joinpath("project-v1.schema.json").read_text("utf-8")
    return json.loads(text)


@cache
def reference_validator() -> jsonschema.Draft202012Validator:
    import jsonschema  # imported where a document does not match: most commands never need it

    return jsonschema.Draft202012Validator(schema())


@cache
def fast_validator() -> Any:
    """The same schema, compiled by jsonschema-rs: it only says whether a document matches, some
    30 times faster than jsonschema (a house of 10,000 pins: 0.3 s, not 8 s, at every load)."""
    import jsonschema_rs

    return jsonschema_rs.Draft202012Validator(schema())


def _errors(doc: Any) -> list[jsonschema.ValidationError]:
    """jsonschema's errors for ``doc`` (none where it matches): where jsonschema-rs finds the
    document matching, jsonschema is not asked; where it does not (or cannot read a value),
    jsonschema finds the errors, in the words the messages are made from."""
    try:
        if fast_validator().is_valid(doc):
            return []
    except (ValueError, TypeError, OverflowError):  # a value it cannot convert: jsonschema decides
        pass
    return list(reference_validator().iter_errors(doc))


#: The lists whose items the schema checks one by one, each against the same schema and valid or
#: not whatever its neighbours are (``"items"`` alone): an edit's validation checks only the items
#: that were not in the list before it. A house's ten thousand pins made the schema check of every
#: edit several seconds; a list whose schema says more (a length, unique items) is checked whole.
ITEM_LISTS = (("photos",), ("model", "nodes"), ("model", "pins"), ("model", "edge_observations"))
#: A list of the same length as before whose items differ from the old ones at this many places at
#: most was changed in place (a pin moved, a node's size typed): those items are checked; more, and
#: each is looked for among the old items by its text (its repr).
IN_PLACE_ITEMS = 8


def schema_errors(data: Any, valid_before: Any = None,
                  cut: tuple[Any, dict[tuple[str, ...], list[int]]] | None = None) -> list[jsonschema.ValidationError]:
    """jsonschema's errors for ``data`` (none where it matches). ``valid_before``, a document that
    matched (the one before an edit), spares the check the items of :data:`ITEM_LISTS` found in
    its same list (``cut``: :func:`new_items` of the two, where already worked out); the errors'
    paths are the document's own."""
    if valid_before is None:
        return _errors(data)
    checked, where = new_items(data, valid_before) if cut is None else cut
    errors = _errors(checked)
    for e in errors:  # the paths of the list that was checked, back to the document's indices
        path = list(e.path)
        for prefix, index in where.items():
            n = len(prefix)
            if tuple(path[:n]) == prefix and len(path) > n and isinstance(path[n], int):
                path[n] = index[path[n]]
        e.relative_path.clear()  # the deque its absolute path is read from
        e.relative_path.extend(path)
    return errors


@cache
def plain_item_lists() -> tuple[tuple[str, ...], ...]:
    """Those of :data:`ITEM_LISTS` whose schema is a list with ``items`` and nothing more."""
    root = schema()

    def at(sch: dict[str, Any], key: str) -> dict[str, Any]:
        sch = sch["properties"][key]
        while "$ref" in sch:
            sch = root["$defs"][sch["$ref"].removeprefix("#/$defs/")]
        return sch

    plain = []
    for path in ITEM_LISTS:
        sch = root
        for key in path:
            sch = at(sch, key)
        if set(sch) <= {"type", "items", "description"} and sch.get("type") == "array":
            plain.append(path)
    return tuple(plain)


def new_items(data: Any, before: Any) -> tuple[Any, dict[tuple[str, ...], list[int]]]:
    """``data`` with the lists of :data:`ITEM_LISTS` cut to the items not in ``before``'s same
    list (dicts along the way copied: the document itself is not changed), and for each list cut,
    the indices in ``data`` of the items kept."""
    out = dict(data)
    where: dict[tuple[str, ...], list[int]] = {}
    for path in plain_item_lists():
        new, old = _get(data, path), _get(before, path)
        if not isinstance(new, list) or not isinstance(old, list):
            continue
        keep = [i for i, item in enumerate(new) if i >= len(old) or item != old[i]]
        if len(new) != len(old) or len(keep) > IN_PLACE_ITEMS:
            # Items moved (one removed or added before them, or one taken out and put back at the
            # end: a pin dragged again) are found by their repr: equal text is equal JSON (an equal
            # item written with its keys in another order is only checked again).
            seen = set(map(repr, old))
            keep = [i for i in keep if repr(new[i]) not in seen]
        node = out
        for key in path[:-1]:
            node[key] = dict(node[key])
            node = node[key]
        node[path[-1]] = [new[i] for i in keep]
        where[path] = keep
    return out, where


def _get(doc: Any, path: tuple[str, ...]) -> Any:
    for key in path:
        if not isinstance(doc, dict):
            return None
        doc = doc.get(key)
    return doc
