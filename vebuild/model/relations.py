"""Relations between nodes of the scene graph (paper §3): faces flush or aligned, edges aligned,
parameters equal (scenes/FORMAT.md "Relations").

A joint places a node on its parent; a relation ties nodes the tree does not join: a cabinet's
back against a wall that is not its parent, the fronts of cabinets in a row, the widths of six
identical chairs. ``equal`` is exact in the solve (one unknown for the group); ``flush`` and
``aligned`` are hard rows of the least-squares problem (:mod:`.constraints`). This module reads
and checks them against the model, and measures how far one is from holding (metres; radians for
an ``equal`` of angles), for the checks here and the solve's conflict check.

A face or an edge is ``"node:name"`` (split at the last colon: node names may contain dots but
never colons), a flat face of ``Primitive.planes`` or an edge of ``Primitive.edges``; a parameter
is ``"node.param"`` (split at the last dot) as the solution's covariance names it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .graph import Model, Relation
from .joints import FlushJoint, ModelError, RestsOnJoint, error_at

Array = NDArray[np.float64]

RELATION_TYPES = ("flush", "aligned", "equal")
#: The keys each type of relation may have.
_KEYS = {"flush": {"type", "a", "b", "offset", "name"}, "aligned": {"type", "a", "b", "name"},
         "equal": {"type", "params", "name"}}
#: The lever (metres) that turns a face's tilt into a length in a relation's residual: a tilt of
#: ε radians reads as ε metres, as the face's edge would move at a metre from its centre.
LEVER_M = 1.0
#: A relation between nodes the solve does not move, or offsets around a cycle of flush faces,
#: that fail by more than this (metres; radians for angles) do not hold: far above rounding
#: (1e-12 m on a room), far below anything a photo could show (a pixel is millimetres).
HOLDS_TOL = 1e-6


def split_ref(ref: str) -> tuple[str, str]:
    """``"node:face"`` → (node, face), split at the last colon."""
    node, _, name = ref.rpartition(":")
    return node, name


def relations_from_dict(items: Any, model: Model, path: str = "$.model.relations") -> list[Relation]:
    """``$.model.relations`` read and checked against ``model``; a ModelError names the relation
    by its JSON path (``$.model.relations[2].a``) and says what was expected."""
    if not isinstance(items, Sequence) or isinstance(items, str):
        raise ModelError(f"{path}: expected a list of relations, got {type(items).__name__}", path,
                         f"expected a list of relations, got {type(items).__name__}")
    out = [_relation(d, model, f"{path}[{i}]") for i, d in enumerate(items)]
    _check_set(out, model, path)
    return out


def _an(word: str) -> str:
    return f"{'an' if word[:1] in 'aeiou' else 'a'} {word}"


def _fail(rel_path: str, label: str | None, key: str | None, detail: str) -> ModelError:
    human = rel_path if label is None else f"{rel_path} ({label})"
    return error_at(human if key is None else f"{human}.{key}", rel_path if key is None else f"{rel_path}.{key}",
                    detail)


def _relation(d: Any, model: Model, at: str) -> Relation:
    if not isinstance(d, Mapping):
        raise _fail(at, None, None, f"expected an object {{\"type\": flush|aligned|equal, ...}}, got {d!r}")
    kind = d.get("type")
    if kind not in RELATION_TYPES:
        raise _fail(at, None, "type", f"relation type {kind!r} is not one of {', '.join(RELATION_TYPES)}")
    if unknown := sorted(set(d) - _KEYS[kind]):
        raise _fail(at, None, unknown[0], f"a {kind} relation has no key '{unknown[0]}'; its keys: "
                    f"{', '.join(sorted(_KEYS[kind]))}")
    name = d.get("name")
    if name is not None and (not isinstance(name, str) or not name.strip()):
        raise _fail(at, None, "name", f"a relation's name must be a non-empty string, got {name!r}")
    if kind == "equal":
        return _equal(d, model, at, name)
    for key in ("a", "b"):
        if not isinstance(d.get(key), str):
            raise _fail(at, name, key, f"expected \"node:face\" (or \"node:edge\"), got {d.get(key)!r}")
    rel = Relation(kind, d["a"], d["b"], 0.0, (), name)
    label = rel.label()
    off = d.get("offset", 0.0)
    if isinstance(off, bool) or not isinstance(off, int | float) or not np.isfinite(off):
        raise _fail(at, label, "offset", f"expected the distance in metres between the faces, got {off!r}")
    rel = Relation(kind, d["a"], d["b"], float(off), (), name)
    what = [_ref_kind(model, rel, key, at, label) for key in ("a", "b")]
    if kind == "flush" and "edge" in what:
        key = "ab"[what.index("edge")]
        raise _fail(at, label, key, f"'{d[key]}' is an edge; flush relates two faces (an edge can be aligned)")
    if what[0] != what[1]:
        raise _fail(at, label, "b", f"'{rel.a}' is {_an(what[0])} and '{rel.b}' {_an(what[1])}; aligned relates "
                    "two faces or two edges")
    if rel.a == rel.b:
        raise _fail(at, label, "b", f"relates '{rel.a}' with itself; name two different {what[0]}s")
    if split_ref(rel.a or "")[0] == split_ref(rel.b or "")[0]:
        raise _fail(at, label, "b", f"relates two {what[0]}s of node '{split_ref(rel.a or '')[0]}': a primitive's "
                    "own shape already fixes them; relate faces of two different nodes")
    return rel


def _ref_kind(model: Model, rel: Relation, key: str, at: str, label: str) -> str:
    """'face' or 'edge': what ``rel.a`` / ``rel.b`` names; a ModelError if it names nothing."""
    ref = getattr(rel, key)
    node, name = split_ref(ref)
    if ":" not in ref or node not in model.index:
        nodes = ", ".join(n.name for n in model.nodes) or "none"
        what = f"no node '{node}'" if ":" in ref else "no node:name"
        raise _fail(at, label, key, f"'{ref}' names {what}; expected \"node:face\" of one of the model's nodes: "
                    f"{nodes}")
    prim = model.node(node).primitive
    if prim is None:
        raise _fail(at, label, key, f"node '{node}' is a group: it has no faces or edges to relate")
    if name in prim.planes():
        return "face"
    if name in [e[0] for e in prim.edges()]:
        return "edge"
    faces = ", ".join(prim.planes()) or "none"
    edges = ", ".join(e[0] for e in prim.edges()) or "none"
    raise _fail(at, label, key, f"node '{node}' ({prim.TYPE}) has no face or edge '{name}'; its flat faces: "
                f"{faces}; its edges: {edges}")


def _equal(d: Mapping[str, Any], model: Model, at: str, name: str | None) -> Relation:
    params = d.get("params")
    if not isinstance(params, Sequence) or isinstance(params, str) or not all(isinstance(p, str) for p in params):
        raise _fail(at, name, "params", f"expected a list of \"node.param\" names, got {params!r}")
    rel = Relation("equal", None, None, 0.0, tuple(params), name)
    label = rel.label()
    if len(set(params)) < 2:
        raise _fail(at, label, "params", f"equal needs at least two different parameters, got {list(params)}")
    names, kinds = model.parameter_names(), model.parameter_kinds()
    kind_of = dict(zip(names, kinds, strict=True))
    for i, p in enumerate(params):
        if p in params[:i]:
            raise _fail(at, label, f"params[{i}]", f"'{p}' is listed twice")
        if p not in kind_of:
            node = p.rpartition(".")[0]
            have = [n.rpartition(".")[2] for n in names if n.rpartition(".")[0] == node]
            detail = (f"node '{node}' has no parameter '{p.rpartition('.')[2]}'; its parameters: {', '.join(have)}"
                      if have else f"'{p}' names no node of the model (expected \"node.param\"; the nodes: "
                      f"{', '.join(n.name for n in model.nodes)})")
            raise _fail(at, label, f"params[{i}]", detail)
    for i, p in enumerate(params[1:], 1):
        if kind_of[p] != kind_of[params[0]]:
            raise _fail(at, label, f"params[{i}]", f"'{p}' is {_an(kind_of[p])} and '{params[0]}' "
                        f"{_an(kind_of[params[0]])}; equal relates parameters of one kind")
    return rel


# ------------------------------------------------------------------------------------------------
# Checks of the set of relations


def held_exactly(model: Model, param: str) -> bool:
    """Whether the solve keeps ``node.param`` at its value: its node is not solved, or holds it."""
    node, _, name = param.rpartition(".")
    n = model.node(node)
    return not n.solve or name in n.hold


def moves(model: Model, node: str) -> bool:
    """Whether a solve can move ``node``'s faces: it, or a node it hangs from, is solved."""
    name: str | None = node
    while name is not None:
        n = model.node(name)
        if n.solve:
            return True
        name = n.parent
    return False


def _check_set(rels: list[Relation], model: Model, path: str) -> None:
    seen: dict[tuple[Any, ...], int] = {}
    for i, r in enumerate(rels):
        at = f"{path}[{i}]"
        key: tuple[Any, ...] = (r.type, frozenset(r.params)) if r.type == "equal" else (r.type, frozenset((r.a, r.b)))
        if key in seen:
            j = seen[key]
            if r.type == "flush" and rels[j].offset != r.offset:
                raise _fail(at, r.label(), "offset", f"conflicts with {path}[{j}] ({rels[j].label()}): the same "
                            f"faces flush at offsets {rels[j].offset:g} m and {r.offset:g} m")
            raise _fail(at, r.label(), None, f"the same relation as {path}[{j}] ({rels[j].label()}); give it once")
        seen[key] = i
        if r.type == "flush":
            _check_not_a_joint(r, model, at)
        if r.type != "equal" and not any(moves(model, nd) for nd in r.nodes()):
            miss = relation_residual(r, model)
            if miss > HOLDS_TOL:
                raise _fail(at, r.label(), None, f"cannot hold: neither {' nor '.join(repr(n) for n in r.nodes())} "
                            f"is solved, and as they stand the relation misses by {miss:.4g} m; let one of them be "
                            "solved (\"solve\": true) or move it into place")
    _check_equal_groups(rels, model, path)
    _check_flush_cycles(rels, model, path)


def _check_not_a_joint(r: Relation, model: Model, at: str) -> None:
    """A flush relation that a node's own joint (flush or rests_on on that parent face) already makes."""
    for own, other in ((r.a, r.b), (r.b, r.a)):
        node, face = split_ref(own or "")
        parent, pface = split_ref(other or "")
        n = model.node(node)
        j = n.joint
        same = (isinstance(j, RestsOnJoint) and face == "bottom" and j.face == pface and r.offset == 0.0) or \
            (isinstance(j, FlushJoint) and j.own_face == face and j.face == pface and j.offset == r.offset)
        if n.parent == parent and same:
            raise _fail(at, r.label(), None, f"already holds through the {j.type} joint of node '{node}' on "
                        f"'{other}'; remove the relation")


def _check_equal_groups(rels: list[Relation], model: Model, path: str) -> None:
    """Equal relations sharing a parameter are one group; its members held exactly must agree."""
    x = model.vector()
    value = dict(zip(model.parameter_names(), x, strict=True))
    for group, members in equal_groups(rels):
        held = [p for p in sorted(group, key=list(value).index) if held_exactly(model, p)]
        for p in held[1:]:
            if abs(value[p] - value[held[0]]) > HOLDS_TOL:
                i = members[-1]
                raise _fail(f"{path}[{i}]", rels[i].label(), "params", f"conflicting: '{held[0]}' is held at "
                            f"{value[held[0]]:g} and '{p}' at {value[p]:g}, so they cannot be equal; hold one of "
                            "them only, or enter the same value")


def equal_groups(rels: Sequence[Relation]) -> list[tuple[set[str], list[int]]]:
    """The ``equal`` relations merged where they share a parameter: (the parameters, the
    relations' indices), each group once, in the order of their first relation."""
    groups: list[tuple[set[str], list[int]]] = []
    for i, r in enumerate(rels):
        if r.type != "equal":
            continue
        hit = [g for g in groups if g[0] & set(r.params)]
        merged: tuple[set[str], list[int]] = (set(r.params), [])
        for g in hit:
            merged[0].update(g[0])
            merged[1].extend(g[1])
            groups.remove(g)
        merged[1].append(i)
        merged[1].sort()
        groups.append(merged)
    return sorted(groups, key=lambda g: g[1][0])


def _check_flush_cycles(rels: list[Relation], model: Model, path: str) -> None:
    """Faces tied by flush and aligned relations (and flush or rests_on joints): each face's
    distance from the origin along its normal, h, follows from any other's on its chain (flush:
    h_a = −h_b − offset, the normals opposite; aligned: h_a = h_b, the same normal). Around a
    cycle they must add up, in direction and in offset; a cycle that does not is named."""
    # Edges: (face, face, sign, constant, label) with h_a = sign·h_b + constant.
    links: list[tuple[str, str, float, float, str]] = []
    for i, r in enumerate(rels):
        if r.type == "flush":
            links.append((r.a or "", r.b or "", -1.0, -r.offset, f"{path}[{i}] ({r.label()})"))
        elif r.type == "aligned" and r.a in _faces_of(model, r.a):
            links.append((r.a or "", r.b or "", 1.0, 0.0, f"{path}[{i}] ({r.label()})"))
    for n in model.nodes:
        j = n.joint
        if n.parent is None or not isinstance(j, RestsOnJoint | FlushJoint):
            continue
        own, off = ("bottom", 0.0) if isinstance(j, RestsOnJoint) else (j.own_face, j.offset)
        links.append((f"{n.name}:{own}", f"{n.parent}:{j.face}", -1.0, -off,
                      f"the {j.type} joint of node '{n.name}' on '{n.parent}:{j.face}'"))
    if not any(lab.startswith(path) for *_, lab in links):
        return
    # Union by breadth: each face gets h = s·h_root + c and the chain of links that got it there.
    place: dict[str, tuple[float, float, list[str]]] = {}
    adj: dict[str, list[tuple[str, float, float, str]]] = {}  # f → (g, s, k): h_g = s·h_f + k
    for a, b, s, c, lab in links:
        adj.setdefault(a, []).append((b, s, -s * c, lab))  # h_a = s h_b + c  ⇔  h_b = s h_a − s c
        adj.setdefault(b, []).append((a, s, c, lab))
    for root in adj:
        if root in place:
            continue
        place[root] = (1.0, 0.0, [])
        todo = [root]
        while todo:
            f = todo.pop(0)
            sf, cf, chain = place[f]
            for g, sign, k, lab in adj[f]:
                sg, cg = sign * sf, sign * cf + k
                if g not in place:
                    place[g] = (sg, cg, chain + [lab])
                    todo.append(g)
                    continue
                s_old, c_old, chain_old = place[g]
                if s_old != sg or abs(c_old - cg) > HOLDS_TOL:
                    cycle = list(dict.fromkeys([x for x in chain + chain_old if (x in chain) != (x in chain_old)]
                                               + [lab]))
                    why = "turns a face to face both ways" if s_old != sg else \
                        f"puts one face at two places {abs(c_old - cg):.4g} m apart"
                    first = next(x for x in cycle if x.startswith(path))
                    at = first.split("]")[0] + "]"
                    raise ModelError(f"{first}: conflicting: the cycle {'; '.join(cycle)} {why}; its offsets must "
                                     "add up", at, f"conflicting: the cycle {'; '.join(cycle)} {why}")


def _faces_of(model: Model, ref: str | None) -> set[str]:
    node, _ = split_ref(ref or "")
    prim = model.node(node).primitive
    return set() if prim is None else {f"{node}:{f}" for f in prim.planes()}


# ------------------------------------------------------------------------------------------------
# Geometry: how far a relation is from holding


def world_plane(model: Model, ref: str, T: Mapping[str, Array], xm: Array) -> tuple[Array, Array, Array, Array]:
    """The world frame (origin, x, y, normal) of face ``node:face`` for model vector ``xm``."""
    node, face = split_ref(ref)
    prim = model.node(node).primitive
    assert prim is not None
    o, x, y, n = prim.plane_frame(face, xm[model.slices[node][1]])
    R, t = T[node][:3, :3], T[node][:3, 3]
    return R @ o + t, R @ x, R @ y, R @ n


def world_edge(model: Model, ref: str, T: Mapping[str, Array], xm: Array) -> tuple[Array, Array]:
    """The world end points of edge ``node:edge`` for model vector ``xm``."""
    node, edge = split_ref(ref)
    prim = model.node(node).primitive
    assert prim is not None
    ends = {e: (a, b) for e, a, b in prim.edges()}[edge]
    H = prim.handles(xm[model.slices[node][1]])
    names = prim.handle_names()
    R, t = T[node][:3, :3], T[node][:3, 3]
    return R @ H[names.index(ends[0])] + t, R @ H[names.index(ends[1])] + t


def perpendiculars(d: Array) -> tuple[Array, Array]:
    """Two unit vectors u, v perpendicular to unit d (u from x̂, or ŷ when d is near x̂; v = d × u)."""
    e = np.array([1.0, 0.0, 0.0]) if abs(d[0]) <= 0.9 else np.array([0.0, 1.0, 0.0])
    u = e - (e @ d) * d
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def is_edge(model: Model, ref: str) -> bool:
    node, name = split_ref(ref)
    prim = model.node(node).primitive
    return prim is not None and name not in prim.planes()


def rows_of(r: Relation, model: Model, T: Mapping[str, Array], xm: Array) -> Array:
    """The hard rows of a flush or aligned relation (metres), zero where it holds.

    Faces: the distance of a's centre from b's plane (less the offset) and a's two axes' components
    along b's normal times LEVER_M (3 rows). Edges: the two components of each of a's ends across
    b's line (4 rows). These hold for faces turned either way; :func:`relation_residual` also
    measures the direction."""
    assert r.a is not None and r.b is not None
    if is_edge(model, r.a):
        p0, p1 = world_edge(model, r.a, T, xm)
        q0, q1 = world_edge(model, r.b, T, xm)
        d = (q1 - q0) / np.linalg.norm(q1 - q0)
        u, v = perpendiculars(d)
        return np.array([(p0 - q0) @ u, (p0 - q0) @ v, (p1 - q0) @ u, (p1 - q0) @ v])
    oa, xa, ya, _ = world_plane(model, r.a, T, xm)
    ob, _, _, nb = world_plane(model, r.b, T, xm)
    return np.array([(oa - ob) @ nb - r.offset, LEVER_M * (xa @ nb), LEVER_M * (ya @ nb)])


def relation_residual(r: Relation, model: Model, x: Array | None = None,
                      T: Mapping[str, Array] | None = None) -> float:
    """How far relation ``r`` is from holding at model vector ``x`` (default: the model's values):
    metres for faces and edges (a wrong-facing face counts 2·LEVER_M·|n_a ∓ n_b|/2), the spread of
    the values for ``equal`` (metres, or radians for angles)."""
    xm = model.vector() if x is None else x
    if r.type == "equal":
        value = dict(zip(model.parameter_names(), xm, strict=True))
        v = [value[p] for p in r.params]
        return float(max(v) - min(v))
    T = model.world_transforms(xm) if T is None else T
    miss = float(np.linalg.norm(rows_of(r, model, T, xm)))
    assert r.a is not None and r.b is not None
    if not is_edge(model, r.a):
        na, nb = world_plane(model, r.a, T, xm)[3], world_plane(model, r.b, T, xm)[3]
        miss = max(miss, LEVER_M * float(np.linalg.norm(na + nb if r.type == "flush" else na - nb)))
    return miss
