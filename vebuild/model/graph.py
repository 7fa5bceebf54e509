"""The scene graph as held in memory: its nodes, each a primitive (or a group) on its parent by a
joint, the :class:`Model` that holds them in parent-before-child order with its parameter vector
and world transforms, and the :class:`Relation` s between nodes (checked and solved by
:mod:`.relations`). The project file's form is read by :func:`vebuild.model.scene.model_from_dict`.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .entered import Entered
from .joints import Joint, ModelError
from .primitives import Primitive
from .room_checks import RoomError

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Relation:
    """One relation of ``$.model.relations``: ``a``, ``b`` the two faces or edges (``flush``,
    ``aligned``), ``offset`` metres along b's normal (``flush``), ``params`` (``equal``)."""

    type: str
    a: str | None
    b: str | None
    offset: float = 0.0
    params: tuple[str, ...] = ()
    name: str | None = None

    def to_dict(self) -> dict[str, Any]:
        d: dict[str, Any] = {"type": self.type}
        if self.type == "equal":
            d["params"] = list(self.params)
        else:
            d["a"], d["b"] = self.a, self.b
            if self.type == "flush":
                d["offset"] = self.offset
        if self.name is not None:
            d["name"] = self.name
        return d

    def label(self) -> str:
        """How messages name it: its ``name``, else its type and what it relates."""
        if self.name is not None:
            return self.name
        if self.type == "equal":
            return f"equal {', '.join(self.params)}"
        return f"{self.type} {self.a} – {self.b}"

    def nodes(self) -> tuple[str, ...]:
        """The nodes it relates, each once."""
        refs = self.params if self.type == "equal" else (self.a or "", self.b or "")
        sep = "." if self.type == "equal" else ":"
        return tuple(dict.fromkeys(r.rsplit(sep, 1)[0] for r in refs))


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
    check_cycles(nodes)
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


def check_cycles(nodes: list[Node]) -> None:
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
