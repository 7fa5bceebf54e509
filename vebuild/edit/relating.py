"""Relations between the faces, edges and sizes of different nodes in the modelling screen (FORMAT.md
``$.model.relations``): picking a face (or an edge) in a photo, making two of them flush or
aligned, sharing one size among several primitives (equal), removing a relation, and how far the
model as shown is from each relation (its residual, after the last solve or during a drag).

Each change is one undoable edit of the document; the model decoded from it carries the
relations, so drags in the screen keep them (the solver's hard constraint rows).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild import camera as cam_math
from vebuild.model.joints import FlushJoint
from vebuild.model.relations import is_edge, world_edge, world_plane
from vebuild.model.scene import Model

from .history import EditError
from .modelling import Modelling

Array = NDArray[np.float64]

#: Relation kinds made between two picked faces or edges (``equal`` relates sizes, not faces).
PAIR_RELATIONS = ("flush", "aligned")
#: A new relation "holds already" when the model as shown is within these of it: a tenth of a
#: millimetre and a hundredth of a degree, far below what a photo shows (a pixel is millimetres).
HOLDS_M = 1e-4
HOLDS_DEG = 0.01
#: A ray meeting a triangle this close to its edge still hits it (barycentric units): the faces of
#: a box meet at its edges, and a click exactly on an edge picks the nearer face, not none.
HIT_EPS = 1e-9


@dataclass(frozen=True)
class Pick:
    """A face or an edge of a node picked in a photo: ``what`` is "face" or "edge", ``name`` its
    plane name (a mesh face's name, FORMAT.md) or edge name; ``point`` where the click's ray met it."""

    node: str
    name: str
    what: str
    point: tuple[float, float, float]

    @property
    def ref(self) -> str:
        """As a relation names it: ``node:name``."""
        return f"{self.node}:{self.name}"


@dataclass(frozen=True)
class RelationState:
    """One relation as the scene-graph panel lists it: its label and its residual now (metres for a
    position, degrees for a turn; None where the model cannot say, e.g. before it decodes)."""

    index: int
    label: str
    distance_m: float | None
    angle_deg: float | None
    spread: float | None  # equal: the largest difference among the shared values (their unit)


class Relating(Modelling):
    """Relations (mixed into the session)."""

    def _relation_docs(self) -> list[dict[str, Any]]:
        return list((self.data.get("model") or {}).get("relations", []))

    # -- picking ----------------------------------------------------------------------------------

    def _world_meshes(self) -> list[tuple[str, Array, NDArray[np.intp], NDArray[np.intp], list[str]]]:
        """Every primitive's mesh in the world as shown: (node, triangle corners (t, 3, 3), the
        triangles' logical faces (1-based), their indices, the face names), cached per revision."""
        key = ("world-meshes", self.revision)
        if key not in self._cache:
            model, x = self._model_now()
            out = []
            if model is not None and x is not None:
                T = self._transforms()
                for node in model.nodes:
                    if node.primitive is None:
                        continue
                    prim = node.primitive.with_params(x[model.slices[node.name][1]])
                    mesh = prim.mesh(segments=24)
                    V = mesh.vertices @ T[node.name][:3, :3].T + T[node.name][:3, 3]
                    out.append((node.name, V[mesh.faces], mesh.face_ids, np.arange(len(mesh.faces)),
                                list(mesh.face_names)))
            self._cache[key] = out
        return self._cache[key]

    def face_at(self, photo: str, uv: Sequence[float]) -> Pick | None:
        """The face of the model nearest the camera along the ray through pixel ``uv`` (the mesh's
        logical face, whose name is its plane's), or None where the ray meets no primitive."""
        cam = self._camera(photo)
        C = np.asarray(cam.C, float)
        d = cam_math.pixel_rays_world(cam.K, cam.R, np.asarray(uv, float), cam.lens)
        best: tuple[float, str, str] | None = None
        for node, tri, face_ids, _, names in self._world_meshes():
            t = _ray_triangles(C, d, tri)
            if t.size == 0 or not np.any(np.isfinite(t)):
                continue
            i = int(np.nanargmin(t))
            if best is None or t[i] < best[0]:
                best = (float(t[i]), node, names[int(face_ids[i]) - 1])
        if best is None:
            return None
        P = C + best[0] * d
        return Pick(best[1], best[2], "face", (float(P[0]), float(P[1]), float(P[2])))

    def pick_outline(self, photo: str, pick: Pick) -> list[list[tuple[float, float]]]:
        """What shows a pick in a photo: a face's triangles (each three pixels) or an edge's two
        ends, projected; empty where it is behind the camera or the photo has no camera."""
        cam = self.cameras.get(photo)
        if cam is None:
            return []
        if pick.what == "edge":
            model, x = self._model_now()
            if model is None or x is None:
                return []
            P = np.array(world_edge(model, pick.ref, self._transforms(), x))
        else:
            found = [(tri, ids, names) for node, tri, ids, _, names in self._world_meshes() if node == pick.node]
            if not found or pick.name not in found[0][2]:
                return []
            tri, ids, names = found[0]
            P = tri[ids == names.index(pick.name) + 1].reshape(-1, 3)
        if np.any(cam_math.world_to_camera(cam.R, cam.C, P)[:, 2] <= 0):
            return []
        uv = cam_math.project(cam.K, cam.R, cam.C, P, cam.lens)
        k = 2 if pick.what == "edge" else 3
        return [[(float(q[0]), float(q[1])) for q in uv[i:i + k]] for i in range(0, len(uv), k)]

    def plane_names(self, node: str) -> list[str]:
        """The flat faces of a node a relation can name (its planes; a face hidden in every photo,
        such as a cabinet's back on a wall, is chosen from these by name)."""
        model = self.model
        prim = model.node(node).primitive if model is not None and node in model.index else None
        if prim is None:
            return []
        planes = getattr(prim, "planes", None)
        if callable(planes):
            return list(planes())
        return [f for f in prim.mesh(segments=8).face_names if f != "side"]

    def edge_pick(self, node: str, edge: str) -> Pick:
        """An edge of a node as a pick (the Relate tool's Shift+click on a projected edge)."""
        model = self.model
        prim = model.node(node).primitive if model is not None and node in model.index else None
        if prim is None or edge not in [e[0] for e in prim.edges()]:
            raise EditError(f"'{node}' has no edge '{edge}'")
        return Pick(node, edge, "edge", (math.nan, math.nan, math.nan))

    # -- relations --------------------------------------------------------------------------------

    def add_relation(self, kind: str, a: Pick | str, b: Pick | str, offset: float = 0.0,
                     name: str | None = None) -> int:
        """Relate two faces (flush, with ``offset`` metres along b's outward normal; or aligned) or two
        edges (aligned) of different nodes; returns the relation's index in ``$.model.relations``."""
        if kind not in PAIR_RELATIONS:
            raise EditError(f"two faces are related flush or aligned, not {kind!r}")
        ra = a.ref if isinstance(a, Pick) else str(a)
        rb = b.ref if isinstance(b, Pick) else str(b)
        if ra.rsplit(":", 1)[0] == rb.rsplit(":", 1)[0]:
            raise EditError(f"{ra} and {rb} are faces of one node: relate faces of two different nodes")
        if not (isinstance(offset, (int, float)) and math.isfinite(offset)):
            raise EditError(f"a flush offset is a number of metres, not {offset!r}")
        if kind == "aligned" and offset:
            raise EditError("an aligned relation has no offset (flush has one): make it flush, or offset 0")
        if kind == "flush" and any(isinstance(p, Pick) and p.what == "edge" for p in (a, b)):
            raise EditError("flush relates two faces; two edges are aligned (A)")
        rel: dict[str, Any] = {"type": kind, "a": ra, "b": rb}
        if kind == "flush" and offset:
            rel["offset"] = float(offset)
        if name:
            rel["name"] = name.strip()
        with self._edit(f"{kind} {ra} – {rb}"):
            self._model_doc().setdefault("relations", []).append(rel)
            self._rebuild_check()
        index = len(self._relation_docs()) - 1
        how = f"flush against {rb}" + (f" {1000 * offset:+.0f} mm off it" if offset else "") \
            if kind == "flush" else f"aligned with {rb}"
        state = self.relation_states()[index]
        if state.distance_m is not None and state.angle_deg is not None and \
                state.distance_m <= HOLDS_M and state.angle_deg <= HOLDS_DEG:
            self.say(f"{ra} is {how} (relation {index}), as the model stands already: drags keep it")
        else:
            off = "" if state.distance_m is None or state.angle_deg is None else \
                f"; the model is {1000 * state.distance_m:.0f} mm and {state.angle_deg:.1f}° from it now"
            self.say(f"{ra} is {how} (relation {index}){off}: Solve brings the model onto it, and drags keep it")
        return index

    def add_equal(self, params: Sequence[str], name: str | None = None) -> int:
        """One value shared by these parameters (``node.param``, of one kind): six identical chairs."""
        params = [str(p) for p in params]
        if len(params) < 2 or len(set(params)) != len(params):
            raise EditError("equal needs two or more different parameters (select the other nodes with "
                            "Ctrl+click in the tree)")
        model = self.model
        if model is None:
            raise EditError("the model has no nodes")
        for p in params:
            node, _, param = p.rpartition(".")
            prim = model.node(node).primitive if node in model.index else None
            if prim is None or param not in prim.PARAMS:
                have = ", ".join(prim.PARAMS) if prim is not None else "none"
                raise EditError(f"{p}: '{node}' has no size '{param}' (its sizes: {have})")
        rel: dict[str, Any] = {"type": "equal", "params": params}
        if name:
            rel["name"] = name.strip()
        with self._edit(f"equal {', '.join(params)}"):
            self._model_doc().setdefault("relations", []).append(rel)
            self._rebuild_check()
        index = len(self._relation_docs()) - 1
        self.say(f"{', '.join(params)} share one value now (relation {index})")
        return index

    def make_flush_joint(self, a: Pick | str, b: Pick | str, offset: float = 0.0) -> None:
        """Make face a's node flush against face b of its parent by its joint (the exact form of a
        flush relation where the scene graph allows it: the node keeps only its slide and turn on
        that face), placed where it is now as nearly as the joint allows."""
        ra = a.ref if isinstance(a, Pick) else str(a)
        rb = b.ref if isinstance(b, Pick) else str(b)
        node, _, own = ra.rpartition(":")
        parent, _, face = rb.rpartition(":")
        model = self.model
        if model is None or node not in model.index or parent not in model.index:
            raise EditError(f"the model has no node '{node if model is None or node not in model.index else parent}'")
        if model.node(node).parent != parent:
            raise EditError(f"'{node}' hangs on '{model.node(node).parent or 'the world'}', not on '{parent}': a "
                            "flush joint ties a node to a face of its parent; make a flush relation (F) instead")
        if not (isinstance(offset, (int, float)) and math.isfinite(offset)):
            raise EditError(f"a flush offset is a number of metres, not {offset!r}")
        joint = flush_joint_here(model, node, own, face, float(offset))
        with self._edit(f"flush joint {ra} – {rb}"):
            self._node_doc(node)["joint"] = joint
            doc = self._model_doc()
            same = [r for r in doc.get("relations", []) if r.get("type") == "flush"
                    and {r.get("a"), r.get("b")} == {ra, rb} and float(r.get("offset", 0.0)) == float(offset)]
            if same:  # the joint makes it now
                doc["relations"] = [r for r in doc["relations"] if r not in same]
                if not doc["relations"]:
                    del doc["relations"]
            self._rebuild_check()
        self.say(f"'{node}' is flush against {rb} by its joint (its {own} face on it"
                 + (f", {1000 * offset:+.0f} mm off" if offset else "") + "): it slides and turns on that face only")

    def remove_relation(self, index: int) -> None:
        rels = self._relation_docs()
        if not 0 <= index < len(rels):
            raise EditError(f"there is no relation {index} (the model has {len(rels)})")
        label = relation_label(index, rels[index])
        with self._edit(f"remove {label}"):
            doc = self._model_doc()
            doc["relations"].pop(index)
            if not doc["relations"]:
                del doc["relations"]
            self._rebuild_check()
        self.say(f"removed {label}")

    def relation_states(self) -> list[RelationState]:
        """Each relation with its residual in the model as shown (after the last solve, or live
        during a drag), for the scene-graph panel."""
        key = ("relation-states", self.revision)
        if key not in self._cache:
            model, x = self._model_now()
            out = []
            for i, r in enumerate(self._relation_docs()):
                dist = ang = spread = None
                if model is not None and x is not None:
                    try:
                        dist, ang, spread = relation_residual(model, x, r)
                    except (KeyError, ValueError, AttributeError, IndexError):
                        pass
                out.append(RelationState(i, relation_label(i, r), dist, ang, spread))
            self._cache[key] = out
        return self._cache[key]


def flush_joint_here(model: Model, node: str, own: str, face: str, offset: float = 0.0) -> dict[str, Any]:
    """A flush joint (file form) of ``node``'s face ``own`` on its parent's face ``face`` that keeps
    the node where it is as nearly as the joint allows: its own face's centre over the point it is
    over now, turned as it is now about the face's normal."""
    n = model.node(node)
    prim = n.primitive
    parent = model.node(n.parent).primitive if n.parent is not None else None
    for what, p, name in ((node, prim, own), (n.parent, parent, face)):
        planes = list(p.planes()) if p is not None else []
        if name not in planes:
            raise EditError(f"'{what}' has no flat face '{name}' (its faces: {', '.join(planes) or 'none'})")
    assert prim is not None and parent is not None and n.parent is not None
    T = model.world_transforms()
    rel = np.linalg.inv(T[n.parent]) @ T[node]
    s, t, yaw = FlushJoint(type="flush", face=face, own_face=own, offset=float(offset)).values_for(rel, parent, prim)
    return {"type": "flush", "face": face, "own_face": own, "offset": float(offset),
            "position": [float(s), float(t)], "yaw_deg": math.degrees(float(yaw))}


def relation_label(index: int, rel: dict[str, Any]) -> str:
    """How messages and the panel name a relation (its ``name``, or FORMAT.md's default label)."""
    if rel.get("name"):
        return str(rel["name"])
    if rel.get("type") == "equal":
        return f"relations[{index}] (equal {', '.join(rel.get('params', []))})"
    return f"relations[{index}] ({rel.get('type')} {rel.get('a')} – {rel.get('b')})"


def _ray_triangles(C: Array, d: Array, tri: Array) -> Array:
    """Distances along the ray C + t d (t > 0) to each triangle (t, 3, 3) it meets, inf where it
    misses (Möller–Trumbore, both sides of a triangle)."""
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-15
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = C - v0
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= -HIT_EPS) & (v >= -HIT_EPS) & (u + v <= 1 + HIT_EPS) & (t > 0)
    return np.where(hit, t, np.inf)


def relation_residual(model: Model, x: Array, rel: dict[str, Any]
                      ) -> tuple[float | None, float | None, float | None]:
    """How far the model at ``x`` is from one relation: (distance m, angle °, spread) — flush: the
    distance of a's centre from b's plane moved by the offset and the angle between a's normal and
    −b's; aligned faces: the same with b's normal; aligned edges: the largest distance of a's ends
    from b's line and the angle between them; equal: the largest difference of the shared values."""
    kind = rel["type"]
    if kind == "equal":
        names = model.parameter_names()
        vals = [float(x[names.index(p)]) for p in rel["params"]]
        return None, None, float(max(vals) - min(vals))
    T = model.world_transforms(x)
    if kind == "aligned" and is_edge(model, rel["a"]):
        a0, a1 = world_edge(model, rel["a"], T, x)
        b0, b1 = world_edge(model, rel["b"], T, x)
        db = (b1 - b0) / np.linalg.norm(b1 - b0)
        da = (a1 - a0) / np.linalg.norm(a1 - a0)
        dist = max(float(np.linalg.norm(np.cross(p - b0, db))) for p in (a0, a1))
        ang = math.degrees(math.acos(min(1.0, abs(float(da @ db)))))
        return dist, ang, None
    oa, _, _, na = world_plane(model, rel["a"], T, x)
    ob, _, _, nb = world_plane(model, rel["b"], T, x)
    offset = float(rel.get("offset", 0.0)) if kind == "flush" else 0.0
    dist = abs(float((oa - ob) @ nb) - offset)
    want = -nb if kind == "flush" else nb
    ang = math.degrees(math.acos(float(np.clip(na @ want, -1.0, 1.0))))
    return dist, ang, None
