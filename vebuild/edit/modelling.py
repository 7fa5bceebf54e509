"""Modelling in the photos (paper §3, §3.1, Figure 7): adding primitives, their sizes, joints and
groups, dragging their vertices with the solver following live, and fixing vertices where they are
seen; each change one undoable edit."""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild import camera as cam_math
from vebuild.errors import ProjectError
from vebuild.model.drag import DragSession, drag_nodes
from vebuild.model.primitives import PRIMITIVE_TYPES, primitive_from_dict, primitive_kinds
from vebuild.model.residuals import EdgeObservation, Pin
from vebuild.model.scene import Model, ModelError
from vebuild.project import decode

from .drag_words import stuck_words
from .history import EditError
from .marks import Marks
from .model_doc import drop_relations_of, merge_nodes, param_kinds, resting_face

Array = NDArray[np.float64]

#: During a drag, the grabbed vertex must end within this many pixels of the mouse, and the fixed
#: vertices within this many pixels of where they were, or the constraints "cannot follow": the
#: primitive stays where it was. Four click σ (1 px each): the least-squares compromise among
#: consistent clicks stays well inside it, a joint or fixed vertex that blocks the move does not.
FOLLOW_TOL_PX = 4.0
#: Default sizes (metres) of each kind of new primitive, and the handle a first one puts on the
#: origin marker: facts of the primitive classes.
DEFAULT_PARAMS: dict[str, dict[str, float]] = {kind: params for kind, (_, params) in primitive_kinds().items()}
ANCHOR_HANDLE = {name: cls.ANCHOR_HANDLE for name, cls in PRIMITIVE_TYPES.items()}


@dataclass
class DragFeedback:
    """After one mouse move of a drag: whether the model followed, and if not, why."""

    ok: bool
    reason: str | None
    handle_px: tuple[float, float]
    ms: float


class _Drag:
    def __init__(self, session: DragSession, model: Model, start_revision: int):
        self.session = session
        self.model = model
        self.start_revision = start_revision  # the session's revision when the drag began
        self.x_good = model.vector()  # the model vector last shown
        self.xp_good = session.x.copy()  # the drag problem's vector that gives it
        self.uv_good = session.pin.uv.copy()
        self.baseline_fixed = 0.0
        self.moved = False
        self.revision = 0  # counts the moves the model followed
        self.T = session.problem.transforms(self.x_good)
        self.T_key = 0


def fresh_name(name: str | None, kind: str, taken: Collection[str]) -> str:
    """``name`` stripped, or where none is given the first of kind1, kind2, … not in ``taken``."""
    if name is not None and name.strip():
        return name.strip()
    k = 1
    while f"{kind}{k}" in taken:
        k += 1
    return f"{kind}{k}"


class Modelling(Marks):
    """Primitives, joints, drags and fixed vertices (mixed into the session)."""

    # -- the model (paper §3) -----------------------------------------------------------------------

    def _markers_placed(self) -> dict[str, Array]:
        """Where the calibration placed the markers (none before calibration)."""
        return decode.markers(self.data, "calibration")

    @property
    def model(self) -> Model | None:
        """The model as the document holds it; None without nodes, or (saying why) when it is not
        a valid model."""
        if "model" not in self._cache:
            self._cache["model"] = None
            if (self.data.get("model") or {}).get("nodes"):
                try:
                    self._cache["model"] = self._decoded_model()
                except EditError as e:
                    self.say(str(e))
        return self._cache["model"]

    def _decoded_model(self) -> Model:
        """``$.model.nodes`` decoded, marker joints tied to the calibrated markers; a model that is
        not valid is an EditError naming the node and the field, as the screen shows it."""
        try:
            return decode.model_nodes(self._nodes(), self._markers_placed(), self._model_doc().get("relations"))
        except ModelError as e:
            raise EditError(str(e)) from None

    def _model_doc(self) -> dict[str, Any]:
        return self.data.setdefault("model", {"nodes": [], "pins": [], "edge_observations": []})

    def _nodes(self) -> list[dict[str, Any]]:
        return self._model_doc().setdefault("nodes", [])

    def _node_doc(self, name: str) -> dict[str, Any]:
        for n in self._nodes():
            if n["name"] == name:
                return n
        raise EditError(f"the model has no node called '{name}'")

    def _pins(self) -> list[dict[str, Any]]:
        return self._model_doc().setdefault("pins", [])

    def _edge_docs(self) -> list[dict[str, Any]]:
        return self._model_doc().setdefault("edge_observations", [])

    def _rebuild_check(self) -> None:
        """The model as edited must still be a model (EditError, the edit undone). The last step
        of an edit: the model decoded here is the edited document's, kept as :attr:`model` once the
        edit is done (:meth:`~vebuild.edit.history.History._edit`) rather than decoded again."""
        self._nodes()  # $.model.nodes there for the decoder to read
        self._cache["rebuilt-model"] = self._decoded_model()

    def add_primitive(self, kind: str, *, name: str | None = None, parent: str | None = None,
                      at: tuple[str, Sequence[float]] | None = None,
                      params: dict[str, float] | None = None, marker: str | None = None) -> str:
        """Add a primitive, attached to ``parent`` (resting on its top), to a calibrated ``marker``
        (its first handle on the marker; the first primitive goes on the origin marker, paper §3.1),
        or else resting on the floor; ``at`` = (photo, (u, v)) puts it where that pixel's ray meets
        the surface it rests on."""
        if kind not in DEFAULT_PARAMS:
            raise EditError(f"a primitive is one of {', '.join(DEFAULT_PARAMS)}, not {kind!r}")
        ptype = "frustum" if kind == "cone" else kind
        existing = {n["name"] for n in self._nodes()}
        name = fresh_name(name, kind, existing)
        if name in existing:
            raise EditError(f"the model already has a node called '{name}'")
        if parent is not None and parent not in existing:
            raise EditError(f"the model has no node called '{parent}' to attach '{name}' to")
        values = dict(DEFAULT_PARAMS[kind]) | (params or {})
        joint: dict[str, Any]
        origin = self.data.get("origin_marker") or (self.data.get("calibration") or {}).get("origin_marker")
        if marker is not None and parent is not None:
            raise EditError(f"'{name}' can hang on a parent or on a marker, not both")
        if parent is None and (marker is not None or not existing):
            if not self.cameras:
                raise EditError("calibrate first: the first primitive is placed on the origin marker, which the "
                                "calibration locates")
            anchor = marker if marker is not None else origin
            if anchor not in self._markers_placed():
                raise EditError(f"marker '{anchor}' has no calibrated position yet: mark it in two photos and "
                                "calibrate" if marker is not None else
                                "the first primitive sits on the origin marker; mark the origin and calibrate")
            joint = {"type": "marker", "marker": anchor, "handle": ANCHOR_HANDLE[ptype], "yaw_deg": 0.0}
        else:
            joint = {"type": "rests_on", "position": [0.0, 0.0], "yaw_deg": 0.0}
            if parent is not None:
                prim = self.model.node(parent).primitive if self.model else None
                face = resting_face(prim)
                if prim is None or face is None:
                    faces = ", ".join(prim.faces()) if prim else "none (a group)"
                    raise EditError(f"'{parent}' has no top face for '{name}' to rest on (its faces: {faces}); "
                                    "attach it to another node")
                joint["face"] = face
            if at is not None:
                joint["position"] = self._surface_point(parent, at, values, ptype)
        try:  # as the primitive writes itself (a room adds its corners, ceiling and openings)
            prim_doc = primitive_from_dict({"type": ptype, "params": values}).to_dict()
        except ValueError as e:
            raise EditError(f"a new {kind}: {e}") from None
        node = {"name": name, "primitive": prim_doc, "joint": joint}
        if parent is not None:
            node["parent"] = parent
        with self._edit(f"add {kind} {name}"):
            self._nodes().append(node)
            self._model_doc().setdefault("pins", [])
            self._model_doc().setdefault("edge_observations", [])
            self._rebuild_check()
        self.say(f"added {kind} '{name}'" + (f" on '{parent}'" if parent else "") +
                 ": drag its corners onto the photo")
        return name

    def _surface_point(self, parent: str | None, at: tuple[str, Sequence[float]], values: dict[str, float],
                       ptype: str) -> list[float]:
        """(s, t) on the parent's top face (or the floor) under the pixel ``at``."""
        photo, uv = at
        cam = self._camera(photo)
        C = np.asarray(cam.C, float)
        d = cam_math.pixel_rays_world(cam.K, cam.R, np.asarray(uv, float), cam.lens)
        o, x, y, n = np.zeros(3), np.eye(3)[0], np.eye(3)[1], np.eye(3)[2]
        if parent is not None:
            model = self.model
            prim = model.node(parent).primitive if model is not None else None
            assert model is not None and prim is not None  # add_primitive checked the parent's top face
            T = model.world_transforms()[parent]
            fo, fx, fy, fn = prim.face_frame(resting_face(prim) or "top")
            o, x, y, n = T[:3, :3] @ fo + T[:3, 3], T[:3, :3] @ fx, T[:3, :3] @ fy, T[:3, :3] @ fn
        denom = float(d @ n)
        lam = float((o - C) @ n) / denom if abs(denom) > 1e-9 else -1.0
        if lam <= 0:
            raise EditError("that pixel does not look at the surface the new primitive rests on; click on it")
        P = C + lam * d
        return [float((P - o) @ x), float((P - o) @ y)]

    def remove_node(self, name: str) -> None:
        """Remove a node with its children, their observations and any hypothesis joints of them."""
        model = self.model
        if model is None or name not in model.index:
            raise EditError(f"the model has no node called '{name}'")
        gone = set(model.subtree(name))
        with self._edit(f"remove {name}"):
            doc = self._model_doc()
            doc["nodes"] = [n for n in doc["nodes"] if n["name"] not in gone]
            doc["pins"] = [p for p in doc.get("pins", []) if p["node"] not in gone]
            doc["edge_observations"] = [e for e in doc.get("edge_observations", []) if e["node"] not in gone]
            self.data["reference_distances"] = [d for d in self.data["reference_distances"]
                                                if not any(e.split(":", 1)[0] in gone for e in (d["a"], d["b"])
                                                           if ":" in e)]
            for h in self.data.get("hypotheses", []):
                h["joints"] = {k: v for k, v in h["joints"].items() if k not in gone}
            dropped = drop_relations_of(doc, gone)
            if not doc["nodes"]:
                del self.data["model"]
            self.data.pop("model_solution", None)
        if dropped:
            self.say(f"removed with it: {'; '.join(dropped)}")

    def set_params(self, node: str, params: dict[str, float]) -> None:
        with self._edit(f"sizes of {node}"):
            doc = self._node_doc(node)
            if "primitive" not in doc:
                raise EditError(f"'{node}' is a group: it has no sizes")
            kinds = param_kinds(doc["primitive"])
            for k, v in params.items():
                if k not in doc["primitive"]["params"]:
                    raise EditError(f"'{node}' has no size '{k}' (it has {', '.join(doc['primitive']['params'])})")
                if not math.isfinite(v):
                    raise EditError(f"{node}.{k} must be a number of metres, not {v!r}")
                if kinds.get(k, "size") == "size" and not v >= 0:
                    raise EditError(f"{node}.{k} must be a length ≥ 0 m, not {v!r}")
                doc["primitive"]["params"][k] = float(v)
                for e in doc.get("hold", []):  # a size typed for an entered value is its new entry
                    if isinstance(e, dict) and e.get("name") == k:
                        e["value"] = float(v)
            self._rebuild_check()

    def set_joint(self, node: str, joint: dict[str, Any]) -> None:
        """Replace the node's joint (the project file's form, degrees)."""
        with self._edit(f"joint of {node}"):
            self._node_doc(node)["joint"] = copy.deepcopy(joint)
            self._rebuild_check()

    def set_limits(self, node: str, lo: float, hi: float) -> None:
        """Limits of a hinge (degrees) or slider (metres)."""
        doc = self._node_doc(node)
        kind = doc.get("joint", {}).get("type")
        if kind not in ("hinge", "slider"):
            raise EditError(f"'{node}' moves on a {kind} joint, which has no limits (a hinge or a slider has)")
        if not lo <= hi:
            raise EditError(f"limits must run from low to high, not [{lo}, {hi}]")
        with self._edit(f"limits of {node}"):
            j = self._node_doc(node)["joint"]
            if kind == "hinge":
                j["limits_deg"] = [float(lo), float(hi)]
                j["angle_deg"] = float(np.clip(j.get("angle_deg", 0.0), lo, hi))
            else:
                j["limits"] = [float(lo), float(hi)]
                j["offset"] = float(np.clip(j.get("offset", 0.0), lo, hi))
            self._rebuild_check()

    def set_solve(self, node: str, solve: bool) -> None:
        with self._edit(f"{'solve' if solve else 'hold'} {node}"):
            doc = self._node_doc(node)
            if solve:
                doc.pop("solve", None)
            else:
                doc["solve"] = False

    def group(self, nodes: Sequence[str], name: str) -> str:
        """Make the nodes the parts of one object: a group node under their common parent, resting
        where the first of them rests, and each part fixed to it where it is now (paper §3)."""
        model = self.model
        if model is None or len(nodes) < 1:
            raise EditError("select the primitives to group first")
        name = name.strip()
        if not name or name in model.index:
            raise EditError(f"a group needs a new name; '{name}' is taken" if name else "a group needs a name")
        for n in nodes:
            if n not in model.index:
                raise EditError(f"the model has no node called '{n}'")
        parents = {model.node(n).parent for n in nodes}
        if len(parents) != 1:
            raise EditError("only nodes attached to the same parent can be grouped: "
                            + ", ".join(f"{n} on {model.node(n).parent or 'the world'}" for n in nodes))
        parent = parents.pop()
        first = model.node(nodes[0])
        if first.joint.type == "marker":
            raise EditError(f"'{nodes[0]}' is tied to a marker; group the objects standing on it instead")
        T = model.world_transforms()
        group_joint = first.joint.to_dict()
        T_group = T[nodes[0]]
        with self._edit(f"group {name}"):
            docs = self._nodes()
            at = min(i for i, d in enumerate(docs) if d["name"] in nodes)
            g: dict[str, Any] = {"name": name, "joint": group_joint}
            if parent is not None:
                g["parent"] = parent
            docs.insert(at, g)
            from vebuild.model.scene import pose_to_dict

            for n in nodes:
                rel = np.linalg.inv(T_group) @ T[n]
                d = self._node_doc(n)
                d["parent"] = name
                d["joint"] = {"type": "fixed", **pose_to_dict(rel)}
            self._rebuild_check()
        self.say(f"grouped {', '.join(nodes)} as '{name}': they move together")
        return name

    # -- handles, drags, pins (paper §3.1, Figure 7) ------------------------------------------------

    def _model_now(self) -> tuple[Model | None, Array | None]:
        """The model and its vector as shown: during a drag, the drag's live state."""
        if self._drag is not None:
            return self._drag.model, self._drag.x_good
        m = self.model
        if m is None:
            return None, None
        if "vector" not in self._cache:  # as the transforms: kept until the next change (asked per node)
            v = m.vector()
            v.setflags(write=False)  # shared by every caller until the next change
            self._cache["vector"] = v
        return m, self._cache["vector"]

    def handles(self, photo: str,
                nodes: Sequence[str] | None = None) -> list[tuple[str, str, tuple[float, float], bool]]:
        """Every primitive's handles (or those of ``nodes``) projected into the photo: (node,
        handle, (u, v), fixed)."""
        cam = self.cameras.get(photo)
        model, x = self._model_now()
        if cam is None or model is None or x is None:
            return []
        T = self._transforms()
        fixed = {(p["node"], p["handle"]) for p in self._pins() if p["photo"] == photo and p.get("fixed", True)}
        out = []
        for node in model.nodes if nodes is None else [model.node(n) for n in nodes]:
            if node.primitive is None:
                continue
            hs = node.primitive.handles(x[model.slices[node.name][1]])
            W = hs @ T[node.name][:3, :3].T + T[node.name][:3, 3]
            front = cam_math.world_to_camera(cam.R, cam.C, W)[:, 2] > 0
            uv = cam_math.project(cam.K, cam.R, cam.C, W, cam.lens)
            for h, ok, p in zip(node.primitive.handle_names(), front, uv, strict=True):
                if ok:
                    out.append((node.name, h, (float(p[0]), float(p[1])), (node.name, h) in fixed))
        return out

    def _transforms(self) -> dict[str, Array]:
        """World transforms of every node as shown; during a drag only the moving subtree is
        recomputed (the rest cannot move)."""
        d = self._drag
        if d is None:
            if "transforms" not in self._cache:
                model = self.model
                assert model is not None  # asked for only to draw or hit-test the model's handles
                self._cache["transforms"] = model.world_transforms()
            return self._cache["transforms"]
        if d.T_key != d.revision:
            d.T = d.session.problem.transforms(d.x_good)
            d.T_key = d.revision
        return d.T

    def handle_at(self, photo: str, uv: Sequence[float], radius_px: float,
                  prefer: str | None = None) -> tuple[str, str] | None:
        """The handle nearest uv within radius_px (those of node ``prefer`` first)."""
        near = [(math.dist(p, uv) - (radius_px if n == prefer else 0.0), n, h)
                for n, h, p, _ in self.handles(photo) if math.dist(p, uv) <= radius_px]
        return min(near)[1:] if near else None

    @property
    def dragging(self) -> bool:
        return self._drag is not None

    def _observations(self, model: Model) -> tuple[list[Pin], list[EdgeObservation]]:
        """The fixed vertices and the user's edges in the calibrated photos, decoded (and checked)
        against ``model``."""
        try:
            pins, edges = decode.pins_of(self.project, model), decode.edge_observations_of(self.project, model)
        except ProjectError as e:
            raise EditError(f"{e.where}: {e.detail}") from None
        except ModelError as e:  # an observation of a node the model lacks
            raise EditError(str(e)) from None
        return [p for p in pins if p.photo in self.cameras], [e for e in edges if e.photo in self.cameras]

    def begin_drag(self, photo: str, node: str, handle: str) -> None:
        """Grab a handle in a photo (paper Figure 7): until one of its vertices is fixed the node moves
        as a whole along its joint; then its sizes change too."""
        if self._drag is not None:
            self.cancel_drag()
        self._camera(photo)
        model = self.model
        if model is None or node not in model.index:
            raise EditError(f"the model has no node called '{node}'")
        free = drag_nodes(model, node)
        movable = [n for n in free if model.node(n).solve]
        if not movable:
            raise EditError(f"'{node}' cannot be dragged: it is held as it is; tick 'solve' in its properties (the "
                            "Model tab) to let the solver move it")
        pins, edges = self._observations(model)
        try:
            ds = DragSession(model, self.cameras, pins, edges, photo, node, handle,
                             click_sigma_px=self.settings["click_sigma_px"], edges_into=())
        except (KeyError, ValueError) as e:
            raise EditError(f"cannot drag {node}:{handle}: {e}") from None
        if ds.x.size == 0:
            raise EditError(f"'{node}' cannot move: its joint ({model.node(free[-1]).joint.type}) has no freedom "
                            "and its sizes are held")
        self._drag = _Drag(ds, model, self.revision)
        self._drag.baseline_fixed = self._fixed_error(ds)

    def _fixed_error(self, ds: DragSession) -> float:
        """The largest distance of the drag's other fixed vertices from their pins, now."""
        p = ds.problem
        r = p.residuals(ds.x) * p.sigma
        return max((float(np.linalg.norm(r[p.rows_pin[i]])) for i, q in enumerate(p.pins) if q is not ds.pin),
                   default=0.0)

    def drag_to(self, uv: Sequence[float]) -> DragFeedback:
        """The mouse is at uv: solve; if the constraints cannot follow, stay and say why."""
        d = self._drag
        if d is None:
            raise EditError("no drag in progress")
        t0 = time.perf_counter()
        ds = d.session
        x_prev = ds.x.copy()
        target = np.asarray(uv, float)
        try:
            res = ds.move(target)
            reach = float(np.linalg.norm(res.handle_px - target))
            ok = bool(np.all(np.isfinite(res.x))) and reach <= FOLLOW_TOL_PX and \
                res.fixed_error_px <= d.baseline_fixed + FOLLOW_TOL_PX
        except (np.linalg.LinAlgError, FloatingPointError, ValueError):
            ok, reach, res = False, float("inf"), None
        shape = _shape_problem(d, res.x) if ok and res is not None else None
        if shape is not None:
            ok = False
        if ok:
            d.x_good, d.xp_good, d.uv_good, d.moved = res.x.copy(), ds.x.copy(), target.copy(), True
            d.revision += 1
            self.revision += 1
            return DragFeedback(True, None, (float(res.handle_px[0]), float(res.handle_px[1])),
                                1e3 * (time.perf_counter() - t0))
        ds.x = x_prev
        ds.problem.set_pin_pixel(ds._pin_index, d.uv_good)
        reason = shape or self._why_stuck(d, res.fixed_error_px - d.baseline_fixed if res is not None else None)
        cam = self.cameras[ds.photo]
        # the transforms as last shown (those of x_good): the whole house's would be recomputed
        hp = cam_math.project(cam.K, cam.R, cam.C, d.model.handle_world(ds.node, ds.handle, d.x_good,
                                                                        self._transforms()), cam.lens)
        return DragFeedback(False, reason, (float(hp[0]), float(hp[1])), 1e3 * (time.perf_counter() - t0))

    def _why_stuck(self, d: _Drag, fixed_shift: float | None) -> str:
        ds = d.session
        model = d.model
        root = model.node(ds.free[-1])
        what = f"{ds.node}:{ds.handle}"
        j = root.joint
        how = {"rests_on": f"it rests on {('the ' + repr(root.parent) + ' top') if root.parent else 'the floor'} "
                           "(it slides and turns on it only)",
               "hinge": "it turns on its hinge only" + (" and is at its limit" if _at_limit(j) else ""),
               "slider": "it slides along its runner only" + (" and is at its limit" if _at_limit(j) else ""),
               "marker": f"it is tied to marker '{getattr(j, 'marker', '?')}' (it turns about it only)",
               "fixed": "it is fixed to its parent", "free": "it moves freely"}.get(j.type, f"its {j.type} joint")
        moved = set(ds.moved)
        pins = [p for p in ds.other_pins if p.fixed and p.node in moved and p.photo in self.cameras]
        fixed = sorted({f"{p.node}:{p.handle}" for p in pins if (p.node, p.handle) != (ds.node, ds.handle)})
        itself = sorted({p.photo for p in pins if (p.node, p.handle) == (ds.node, ds.handle)})
        held = f"; its fixed vertices {', '.join(fixed[:4])} hold it" if fixed else ""
        if itself:  # the dragged vertex fixed where another photo sees it: the photo names it, not the list
            held += f"; {what} itself is fixed in photo {', '.join(itself)}"
        shift = (f" (they would move {fixed_shift:.1f} px)"
                 if fixed and fixed_shift and fixed_shift > FOLLOW_TOL_PX else "")
        # The first line in words, offering the one change that lets it go there; the second the detail.
        on_marker = j.type == "marker" and root.name == ds.node and getattr(j, "handle", None) == ds.handle
        return (stuck_words(j, len(fixed), on_marker, _at_limit(j))
                + f"\n{what} cannot go there: {how}{held}{shift}; it stays where it was. Unfix a vertex (F), "
                "or change the joint")

    def end_drag(self) -> None:
        """Keep the dragged result; the grabbed vertex becomes fixed in that photo."""
        d = self._drag
        if d is None:
            return
        ds = d.session
        if not d.moved:
            self._drag = None
            self.revision += 1
            return
        ds.x = d.xp_good
        try:
            pin = ds.release()
        except ValueError as e:  # a shape the primitive refuses: nothing is kept
            self._drag = None
            self.revision += 1
            raise EditError(f"the drag of {ds.node}:{ds.handle} is not kept: {e}") from None
        pin.uv = d.uv_good
        self._drag = None
        with self._edit(f"drag {pin.node}:{pin.handle} in {pin.photo}"):
            self._model_doc()["nodes"] = merge_nodes(self._nodes(), d.model.to_dict())
            key = (pin.photo, pin.node, pin.handle)
            pins = [p for p in self._pins() if (p["photo"], p["node"], p["handle"]) != key]
            pins.append({"photo": pin.photo, "node": pin.node, "handle": pin.handle,
                         "uv": [float(pin.uv[0]), float(pin.uv[1])], "fixed": True})
            self._model_doc()["pins"] = pins
            self._rebuild_check()

    def cancel_drag(self) -> None:
        if self._drag is not None:
            self._drag.session.cancel()
            self._drag = None
            self.revision += 1

    def fix(self, photo: str, node: str, handle: str, uv: Sequence[float] | None = None) -> None:
        """Fix a vertex where it is seen in the photo (or at uv)."""
        if uv is None:
            found = [p for n, h, p, _ in self.handles(photo) if (n, h) == (node, handle)]
            if not found:
                raise EditError(f"{node}:{handle} is not in view in photo '{photo}'")
            uv = found[0]
        with self._edit(f"fix {node}:{handle} in {photo}"):
            pins = [p for p in self._pins() if (p["photo"], p["node"], p["handle"]) != (photo, node, handle)]
            pins.append({"photo": photo, "node": node, "handle": handle, "uv": [float(uv[0]), float(uv[1])],
                         "fixed": True})
            self._model_doc()["pins"] = pins

    def unfix(self, photo: str, node: str, handle: str) -> None:
        pins = self._pins()
        if not any((p["photo"], p["node"], p["handle"]) == (photo, node, handle) for p in pins):
            raise EditError(f"{node}:{handle} is not fixed in photo '{photo}'")
        with self._edit(f"unfix {node}:{handle} in {photo}"):
            key = (photo, node, handle)
            self._model_doc()["pins"] = [p for p in pins if (p["photo"], p["node"], p["handle"]) != key]


def _shape_problem(d: _Drag, x: Array) -> str | None:
    """Why the moved primitives cannot take the shape of model vector ``x`` (a room whose corners
    would cross or turn clockwise), or None: the model stays as it was, as when the joints cannot
    follow."""
    model = d.model
    for name in d.session.moved:
        prim = model.node(name).primitive
        if prim is None or getattr(prim, "LINEAR", True):
            continue  # a linear primitive takes any sizes the solver's bounds allow
        try:
            prim.with_params(x[model.slices[name][1]])
        except ValueError as e:
            return (f"{d.session.node}:{d.session.handle} cannot go there: {name} would not be a valid "
                    f"{prim.TYPE} ({e}); it stays where it was")
    return None


def _at_limit(j: Any) -> bool:
    lims = getattr(j, "limits", None)
    if lims is None:
        return False
    v = j.values()[0]
    return bool(min(abs(v - lims[0]), abs(v - lims[1])) < 1e-6)
