"""The scene graph: primitives and groups attached to their parents by joints (paper §3, Figure 6).

A joint is an exact parameterisation of how a node may sit on its parent: a box that rests on the
floor has three degrees of freedom (a position in the floor's plane and a turn about its normal),
a door on its hinge has one. The solver moves only these degrees of freedom and the primitives'
own parameters, so every joint holds exactly, whatever the observations say.

The joints themselves are in :mod:`vebuild.model.joints` (re-exported here). Transforms are 4×4
matrices mapping a node's local frame into its parent's (``parent_from_node``);
a node attached to the world has the world as parent. Lengths in metres, angles in radians here
(degrees in the project file).
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .entered import Entered, HoldError, fill_entered_values, hold_list
from .joints import (  # noqa: F401  (re-exported: the scene graph and its joints, one import)
    DOF_KINDS,
    JOINT_TYPES,
    FlushJoint,
    FreeJoint,
    HingeJoint,
    Joint,
    MarkerJoint,
    ModelError,
    RestsOnJoint,
    SliderJoint,
    error_at,
    joint_from_dict,
    pose_matrix,
    pose_to_dict,
    rotation4,
    rz,
    translation,
)
from .primitives import MIN_SIZE_M, PRIMITIVE_TYPES, Primitive, primitive_from_dict
from .relations import Relation, relations_from_dict
from .room import RoomError
from .room_joints import check_room_joints

Array = NDArray[np.float64]

@dataclass
class Node:
    name: str
    parent: str | None
    primitive: Primitive | None
    joint: Joint
    solve: bool = True
    hold: tuple[str, ...] = ()  # parameter or degree-of-freedom names held exactly at their values
    #: The ``hold`` entries given as objects (entered with a 1σ); those with σ 0 are in ``hold`` too.
    entered: tuple[Entered, ...] = ()

    def entered_sigma(self, name: str) -> float | None:
        """The 1σ (file units) of parameter ``name`` as entered: 0 for one held exactly (a plain
        name or σ 0), None for one not held."""
        for e in self.entered:
            if e.name == name:
                return e.sigma
        return 0.0 if name in self.hold else None

    def entered_record(self, name: str) -> dict[str, Any]:
        """``{"entered": true, "entered_sigma": s}`` for a held or entered parameter (FORMAT.md
        ``model_solution``), else ``{}``."""
        s = self.entered_sigma(name)
        return {} if s is None else {"entered": True, "entered_sigma": s}

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"name": self.name}
        if self.parent is not None:
            d["parent"] = self.parent
        if self.primitive is not None:
            d["primitive"] = self.primitive.to_dict()
        d["joint"] = self.joint.to_dict()
        if not self.solve:
            d["solve"] = False
        if self.hold or self.entered:
            objects = {e.name for e in self.entered}
            d["hold"] = [h for h in self.hold if h not in objects] + [e.to_dict() for e in self.entered]
        return d


class Model:
    """Nodes in parent-before-child order, with world transforms and handle positions.

    The parameter vector the solver sees is, node by node, the joint's degrees of freedom then the
    primitive's parameters, exactly the values the model stores (see ``layout``).
    """

    def __init__(self, nodes: list[Node], relations: Sequence[Relation] = ()):
        self.nodes = _topological(nodes)
        #: Relations between faces, edges and parameters of the nodes (:mod:`.relations`), checked
        #: against the nodes by :func:`model_from_dict`; the solver keeps them.
        self.relations: list[Relation] = list(relations)
        self.index = {n.name: i for i, n in enumerate(self.nodes)}
        self.children: dict[str, list[str]] = {n.name: [] for n in self.nodes}
        for n in self.nodes:
            if n.parent is not None:
                self.children[n.parent].append(n.name)
        # Parameter layout: slices of the vector per node.
        self.slices: dict[str, tuple[slice, slice]] = {}
        k = 0
        for n in self.nodes:
            nq = len(n.joint.dof_names)
            npar = 0 if n.primitive is None else len(n.primitive.PARAMS)
            self.slices[n.name] = (slice(k, k + nq), slice(k + nq, k + nq + npar))
            k += nq + npar
        self.size = k

    def node(self, name: str) -> Node:
        try:
            return self.nodes[self.index[name]]
        except KeyError:
            raise ModelError(f"no node named '{name}' in the model") from None

    def vector(self) -> Array:
        """The current parameter vector."""
        x = np.zeros(self.size)
        for n in self.nodes:
            sq, sp = self.slices[n.name]
            x[sq] = n.joint.values()
            if n.primitive is not None:
                x[sp] = n.primitive.params
        return x

    def set_vector(self, x: Array) -> None:
        """Store x in the joints and primitives; nothing changes when a value cannot be kept (a
        solve that bent a room out of shape is a VebuildError naming the node)."""
        prims = {}
        for n in self.nodes:
            if n.primitive is not None:
                try:
                    prims[n.name] = n.primitive.with_params(x[self.slices[n.name][1]])
                except RoomError as e:  # a solve or a drag bent a room out of shape: say which and how
                    from vebuild.errors import VebuildError

                    raise VebuildError(f"node '{n.name}': the solved values make an impossible room ({e}); check "
                                       "the pins and edges on it, or hold the dimensions a tape measured") from None
        for n in self.nodes:
            n.joint.set_values(x[self.slices[n.name][0]])
            if n.primitive is not None:
                n.primitive = prims[n.name]

    def bounds(self) -> tuple[Array, Array]:
        lo, hi = np.full(self.size, -np.inf), np.full(self.size, np.inf)
        for n in self.nodes:
            sq, sp = self.slices[n.name]
            lo[sq], hi[sq] = n.joint.bounds()
            if n.primitive is not None:
                lo[sp] = n.primitive.minimum_sizes()
        return lo, hi

    def clip(self, x: Array) -> Array:
        """x brought within every joint's limits (by the joint) and above every primitive's least sizes."""
        x = np.array(x, float)
        for n in self.nodes:
            sq, sp = self.slices[n.name]
            x[sq] = n.joint.clip(x[sq])
            if n.primitive is not None:
                x[sp] = np.maximum(x[sp], n.primitive.minimum_sizes())
        return x

    def parameter_names(self) -> list[str]:
        out = []
        for n in self.nodes:
            out += [f"{n.name}.{d}" for d in n.joint.dof_names]
            if n.primitive is not None:
                out += [f"{n.name}.{p}" for p in n.primitive.PARAMS]
        return out

    def parameter_kinds(self) -> list[str]:
        """The kind (DOF_KINDS) of every parameter, in parameter_names order."""
        out: list[str] = []
        for n in self.nodes:
            out += list(n.joint.dof_kinds)
            if n.primitive is not None:
                out += list(n.primitive.param_kinds())
        return out

    def world_transforms(self, x: Array | None = None, only: Collection[str] | None = None,
                         cache: Mapping[str, Array] | None = None) -> dict[str, Array]:
        """world_from_node for every node (or the subset ``only``, taking others from ``cache``)."""
        x = self.vector() if x is None else x
        if only is None:
            todo = self.nodes
            out: dict[str, Array] = {}
        else:
            # Only a subtree changes (one parameter of a drag or a Jacobian column): start from the
            # cached transforms and recompute just those nodes, parents first.
            todo = [self.nodes[self.index[name]] for name in sorted(only, key=self.index.__getitem__)]
            out = dict(cache or {})
        for n in todo:
            T = self.local_transform(n, x)
            out[n.name] = T if n.parent is None else out[n.parent] @ T
        return out

    def local_transform(self, n: Node, x: Array) -> Array:
        """parent_from_node of node ``n`` for model vector x (its joint, given its parent's
        primitive and both nodes' parameters)."""
        sq, sp = self.slices[n.name]
        parent = None if n.parent is None else self.node(n.parent)
        p_params = None
        if parent is not None and parent.primitive is not None:
            p_params = x[self.slices[parent.name][1]]
        node_params = x[sp] if n.primitive is not None else None
        parent_prim = None if parent is None else parent.primitive
        return n.joint.transform(x[sq], parent_prim, p_params, n.primitive, node_params)

    def lazy_world_transforms(self, x: Array) -> WorldTransforms:
        """world_from_node for model vector x, each node's computed (with its ancestors') only when
        asked for: the same values as :meth:`world_transforms`, for a question about a few nodes."""
        return WorldTransforms(self, x)

    def subtree(self, name: str) -> list[str]:
        """The node and all its descendants, parents first."""
        out = [name]
        for c in self.children[name]:
            out += self.subtree(c)
        return out

    def handle_world(self, name: str, handle: str, x: Array | None = None,
                     transforms: Mapping[str, Array] | None = None) -> Array:
        """World position of one handle of a primitive node."""
        x = self.vector() if x is None else x
        T = (transforms or self.world_transforms(x))[name]
        prim = self.node(name).primitive
        if prim is None:
            raise ModelError(f"node '{name}' is a group: it has no handle '{handle}'")
        h = prim.handles(x[self.slices[name][1]])[prim.handle_names().index(handle)]
        return T[:3, :3] @ h + T[:3, 3]

    def to_dict(self) -> list[dict[str, Any]]:
        return [n.to_dict() for n in self.nodes]


def _topological(nodes: list[Node]) -> list[Node]:
    by_name: dict[str, Node] = {}
    for n in nodes:
        if n.name in by_name:
            raise ModelError(f"node '{n.name}': the name is used twice; node names must be unique")
        by_name[n.name] = n
    for n in nodes:
        if n.parent is not None and n.parent not in by_name:
            raise ModelError(f"node '{n.name}': its joint attaches it to parent '{n.parent}', which is not a node")
    _check_cycles(nodes)
    # Parents before children, each node after its chain of ancestors (iterative: a long chain
    # must not exhaust the stack).
    order: list[Node] = []
    placed: set[str] = set()
    for n in nodes:
        chain: list[Node] = []
        m: Node | None = n
        while m is not None and m.name not in placed:
            chain.append(m)
            m = by_name[m.parent] if m.parent is not None else None
        for c in reversed(chain):
            placed.add(c.name)
            order.append(c)
    return order


def _primitive(d: Any, human: str, path: str) -> Primitive:
    """A node's primitive, its sizes checked with the JSON path of the one at fault."""
    if not isinstance(d, Mapping) or not isinstance(d.get("params", {}), Mapping):
        raise error_at(human, path, "expected an object {\"type\": T, \"params\": {...}}")
    params = d.get("params", {})
    kind = d.get("type")
    cls = PRIMITIVE_TYPES.get(kind) if isinstance(kind, str) else None
    for name, value in params.items():
        if cls is None or name not in cls.PARAMS or not isinstance(value, int | float):
            continue
        least = cls.minimum_size(name)  # (a room's PARAMS depend on its structure: it checks its own)
        if value >= least:
            continue
        if least > 0 and value <= 0:
            raise error_at(human, f"{path}.params.{name}", f"{cls.TYPE}: {name} must be > 0, got {value!r}")
        raise error_at(human, f"{path}.params.{name}", f"{cls.TYPE}: {name} must be at least {least:g} m (sizes "
                     f"stay above {MIN_SIZE_M:g} m, the solver's least), got {value!r}")
    try:
        prim = primitive_from_dict(d)
    except RoomError as e:  # a room names its field: params.c2_y, openings[1].wall, corners
        raise error_at(human, f"{path}.{e.at}", str(e)) from None
    except (ValueError, TypeError) as e:
        raise error_at(human, f"{path}.params" if isinstance(d.get("type"), str) else f"{path}.type", str(e)) from None
    for name, value, least in zip(prim.PARAMS, prim.params, prim.minimum_sizes(), strict=True):
        if not value >= least:
            raise error_at(human, f"{path}.params.{name}", f"{prim.TYPE}: {name} must be at least {least:g} m (sizes "
                         f"stay above {MIN_SIZE_M:g} m, the solver's least), got {params.get(name, value)!r}")
    return prim


def model_from_dict(nodes: list[Mapping[str, Any]], markers: Mapping[str, Array] | None = None,
                    relations: Any = None) -> Model:
    """The model from the project file's ``model.nodes`` and ``model.relations`` (None: none);
    ModelError names the node (or the relation) and the field."""
    out = []
    index: dict[str, int] = {}
    for i, d in enumerate(nodes):
        where = f"$.model.nodes[{i}] (node '{d.get('name')}')"
        path = f"$.model.nodes[{i}]"
        prim = None
        if "primitive" in d:
            prim = _primitive(d["primitive"], f"{where}.primitive", f"{path}.primitive")
        joint = joint_from_dict(d.get("joint", {"type": "fixed"}), f"{where}.joint", markers, f"{path}.joint")
        if isinstance(joint, MarkerJoint):
            if d.get("parent") is not None:
                raise error_at(f"{where}.joint", f"{path}.parent",
                             "a marker joint ties a node to the world; this node has a parent")
            if prim is None or joint.handle not in prim.handle_names():
                have = ", ".join(prim.handle_names()) if prim is not None else "none (a group has no handles)"
                raise error_at(f"{where}.joint", f"{path}.joint.handle", f"handle '{joint.handle}' is not a handle of "
                             f"this node's primitive (its handles are: {have})")
        try:
            hold, entered = hold_list(d.get("hold", ()), (prim.PARAMS if prim is not None else ()) + joint.dof_names)
        except HoldError as e:
            raise error_at(f"{where}.hold", f"{path}.hold{e.at}", e.detail) from None
        index.setdefault(d["name"], i)
        out.append(Node(d["name"], d.get("parent"), prim, joint, bool(d.get("solve", True)), hold, entered))
    for i, n in enumerate(out):
        if n.parent is not None and n.parent not in index:
            raise ModelError(f"node '{n.name}': its joint attaches it to parent '{n.parent}', which is not a node",
                             f"$.model.nodes[{i}].parent",
                             f"node '{n.name}' is attached to parent '{n.parent}', which is not a node")
    _check_cycles(out)
    model = Model(out)
    fill_entered_values(model)
    check_room_joints(model, index)
    for n in model.nodes:
        if isinstance(n.joint, RestsOnJoint) and n.parent is not None:
            parent = model.node(n.parent).primitive
            if parent is None or n.joint.face not in parent.faces():
                faces = ", ".join(parent.faces()) if parent is not None else "none (a group)"
                detail = f"rests on face '{n.joint.face}' of '{n.parent}', which has faces: {faces}"
                raise ModelError(f"node '{n.name}': {detail}", f"$.model.nodes[{index[n.name]}].joint.face",
                                 f"node '{n.name}' {detail}")
        if isinstance(n.joint, FlushJoint):
            _check_flush_joint(model, n, f"$.model.nodes[{index[n.name]}]")
    model.relations = relations_from_dict([] if relations is None else relations, model)
    return model


def _check_flush_joint(model: Model, n: Node, path: str) -> None:
    """A flush joint's faces must be flat faces of the parent and of the node."""
    joint = n.joint
    assert isinstance(joint, FlushJoint)
    sides: list[tuple[str, str | None, str, Primitive | None]] = [("own_face", joint.own_face, n.name, n.primitive)]
    if n.parent is not None:
        sides.insert(0, ("face", joint.face, n.parent, model.node(n.parent).primitive))
    elif joint.face is not None:
        detail = (f"node '{n.name}' is flush against face '{joint.face}' of the world, which has none; with no "
                  "parent, leave out \"face\" (the floor z = 0)")
        raise ModelError(f"node '{n.name}': {detail}", f"{path}.joint.face", detail)
    for key, face, owner, prim in sides:
        if face is None:
            detail = f"node '{n.name}' is flush against its parent '{owner}' but names no face; expected \"face\": " \
                     f"one of the parent's flat faces: {', '.join(prim.planes()) if prim else 'none (a group)'}"
            raise ModelError(f"node '{n.name}': {detail}", f"{path}.joint.face", detail)
        if prim is None or face not in prim.planes():
            have = ", ".join(prim.planes()) or "none" if prim is not None else "none (a group)"
            detail = f"node '{n.name}' is flush with face '{face}' of '{owner}', which has flat faces: {have}"
            raise ModelError(f"node '{n.name}': {detail}", f"{path}.joint.{key}", detail)


def _check_cycles(nodes: list[Node]) -> None:
    """A cycle in the parents (the first node on it named by its JSON path); iterative."""
    parent = {n.name: n.parent for n in nodes}
    index = {n.name: i for i, n in reversed(list(enumerate(nodes)))}
    done: set[str] = set()
    for n in nodes:
        path: list[str] = []
        seen: set[str] = set()
        name: str | None = n.name
        while name is not None and name not in done:
            if name in seen:
                cycle = " → ".join(path[path.index(name):] + [name])
                detail = f"the scene graph has a cycle: {cycle}; every node needs a path to the world"
                raise ModelError(detail, f"$.model.nodes[{index[name]}].parent", detail)
            seen.add(name)
            path.append(name)
            name = parent.get(name)
        done.update(path)


class WorldTransforms(Mapping[str, Array]):
    """Every node's world_from_node for one model vector, computed on first use: a node's is its
    parent's times its own joint's, as :meth:`Model.world_transforms` computes it (bit for bit)."""

    def __init__(self, model: Model, x: Array) -> None:
        self._model, self._x = model, x
        self._done: dict[str, Array] = {}

    def __getitem__(self, name: str) -> Array:
        T = self._done.get(name)
        if T is None:
            if name not in self._model.index:
                raise KeyError(name)
            n = self._model.node(name)
            local = self._model.local_transform(n, self._x)
            T = local if n.parent is None else self[n.parent] @ local
            self._done[name] = T
        return T

    def __iter__(self) -> Iterator[str]:
        return (n.name for n in self._model.nodes)

    def __len__(self) -> int:
        return len(self._model.nodes)
