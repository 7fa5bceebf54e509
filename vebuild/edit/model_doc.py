"""What the modelling screen reads and rewrites in a model document (``$.model``): the solved
nodes merged back into it, the relations dropped with a removed node, the face a new primitive
rests on and each parameter's kind (a size, or a room corner's position)."""

from __future__ import annotations

import copy
from typing import Any

from vebuild.model.primitives import primitive_from_dict


def drop_relations_of(doc: dict[str, Any], gone: set[str]) -> list[str]:
    """Take out of the model document the relations that name a removed node (an ``equal`` keeps
    its other members while two remain); returns what was dropped, for the message."""
    kept, dropped = [], []
    for r in doc.get("relations", []):
        if r.get("type") == "equal":
            params = [p for p in r.get("params", []) if p.rpartition(".")[0] not in gone]
            if len(params) >= 2:
                kept.append({**r, "params": params})
                continue
        elif not any(str(r.get(k, "")).rpartition(":")[0] in gone for k in ("a", "b")):
            kept.append(r)
            continue
        dropped.append(f"{r['type']} " + (", ".join(r.get("params", [])) if r.get("type") == "equal"
                                         else f"{r.get('a')} – {r.get('b')}"))
    if kept:
        doc["relations"] = kept
    else:
        doc.pop("relations", None)
    return dropped


def resting_face(prim: Any) -> str | None:
    """The face a new primitive rests on: a parent's top, or a room's floor (its one restable face)."""
    if prim is None:
        return None
    faces = list(prim.faces())
    return "top" if "top" in faces else ("floor" if "floor" in faces else None)


def param_kinds(prim_doc: dict[str, Any]) -> dict[str, str]:
    """Each parameter's kind ("size" ≥ 0, or "position": a room's corner coordinates, any sign)."""
    try:
        prim = primitive_from_dict(prim_doc)
    except ValueError:
        return {}
    kinds = getattr(prim, "param_kinds", None)
    if not callable(kinds):
        return {}
    got = kinds()
    return dict(got) if isinstance(got, dict) else dict(zip(prim.PARAMS, got, strict=True))


def merge_nodes(docs: list[dict[str, Any]], solved: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The nodes' documents with joints and sizes from the solved model (other keys kept)."""
    by = {d["name"]: d for d in solved}
    out = []
    for d in docs:
        s = by.get(d["name"], {})
        d = copy.deepcopy(d)
        if "joint" in s:
            d["joint"] = s["joint"]
        if "primitive" in s:
            d["primitive"] = s["primitive"]
        out.append(d)
    return out
