"""The scene graph: primitives and groups attached to their parents by joints (paper §3, Figure 6).

A joint is an exact parameterisation of how a node may sit on its parent: a box that rests on the
floor has three degrees of freedom (a position in the floor's plane and a turn about its normal),
a door on its hinge has one. The solver moves only these degrees of freedom and the primitives'
own parameters, so every joint holds exactly, whatever the observations say.

Transforms are 4×4 matrices mapping a node's local frame into its parent's (``parent_from_node``);
a node attached to the world has the world as parent. Lengths in metres, angles in radians here
(degrees in the project file).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from ..camera import exp_so3
from .entered import Entered, HoldError, fill_entered_values, hold_list
from .primitives import MIN_SIZE_M, PRIMITIVE_TYPES, Primitive, primitive_from_dict

Array = NDArray[np.float64]

JOINT_TYPES = ("fixed", "free", "rests_on", "hinge", "slider", "marker")
#: What a degree of freedom measures: a position (metres), an angle (radians; degrees in files)
#: or, for a primitive's parameters, a size (metres). The solver's pull toward the value before a
#: solve and the file's units follow the kind.
DOF_KINDS = ("position", "angle", "size")


class ModelError(ValueError):
    """The model as written is not a valid scene graph; the message names the node and the field.

    ``where`` is the JSON path of the field at fault (None where unknown: a model built in code),
    ``detail`` the message without the location, for errors that name the path separately.
    """

    def __init__(self, message: str, where: str | None = None, detail: str | None = None) -> None:
        super().__init__(message)
        self.where = where
        self.detail = detail or message


def _error(human: str, path: str | None, detail: str) -> ModelError:
    """A ModelError located by ``human`` in its text ("$.model.nodes[2] (node 'x').joint") and by
    ``path`` (the JSON path) for the project file's error."""
    return ModelError(f"{human}: {detail}", path, detail)


def translation(t: Array) -> Array:
    T = np.eye(4)
    T[:3, 3] = t
    return T


def rotation4(R: Array) -> Array:
    T = np.eye(4)
    T[:3, :3] = R
    return T


def rz(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    return rotation4(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))


def pose_matrix(t: Any, rotation_deg: Any) -> Array:
    """Translation then XYZ Euler rotation (degrees, about the parent's axes) as a 4×4 matrix."""
    T = rotation4(Rotation.from_euler("xyz", np.asarray(rotation_deg, float), degrees=True).as_matrix())
    T[:3, 3] = np.asarray(t, float)
    return T


def pose_to_dict(T: Array) -> dict[str, list[float]]:
    return {"translation": [float(x) for x in T[:3, 3]],
            "rotation_deg": [float(x) for x in Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)]}


@dataclass
class Joint:
    """How a node sits on its parent. Subclasses define the degrees of freedom ``q``."""

    type: str = "fixed"
    base: Array = field(default_factory=lambda: np.eye(4))  # the pose at q = 0 (fixed, free, hinge, slider)

    dof_names: tuple[str, ...] = ()
    #: The kind (DOF_KINDS) of each degree of freedom, in dof_names order.
    dof_kinds: tuple[str, ...] = ()

    def values(self) -> Array:
        return np.zeros(0)

    def set_values(self, q: Array) -> None:
        """Store solved values (free joints fold their small rotation into the base here)."""

    def bounds(self) -> tuple[Array, Array]:
        n = len(self.dof_names)
        return np.full(n, -np.inf), np.full(n, np.inf)

    def clip(self, q: Array) -> Array:
        """The degrees of freedom ``q`` brought within the joint's limits (a hinge's stops, a
        slider's travel); the solver and the viewer's moves keep a joint in range through this."""
        lo, hi = self.bounds()
        return np.clip(np.asarray(q, float), lo, hi)

    def transform(self, q: Array, parent: Primitive | None, parent_params: Array | None,
                  node: Primitive | None, node_params: Array | None) -> Array:
        """parent_from_node for dof values q (and the current primitive parameters)."""
        return self.base

    def to_dict(self) -> dict[str, Any]:
        return {"type": "fixed", **pose_to_dict(self.base)}


@dataclass
class FreeJoint(Joint):
    dof_names: tuple[str, ...] = ("tx", "ty", "tz", "wx", "wy", "wz")
    dof_kinds: tuple[str, ...] = ("position",) * 3 + ("angle",) * 3

    def values(self) -> Array:
        return np.r_[self.base[:3, 3], 0.0, 0.0, 0.0]

    def set_values(self, q: Array) -> None:
        # Local re-parameterisation (paper §3.1): the rotation is kept as a matrix and each solve
        # works on a small rotation about the current one, so it never meets a singularity.
        R = exp_so3(q[3:6]) @ self.base[:3, :3]
        self.base = rotation4(R)
        self.base[:3, 3] = q[:3]

    def transform(self, q, parent, parent_params, node, node_params):
        T = rotation4(exp_so3(q[3:6]) @ self.base[:3, :3])
        T[:3, 3] = q[:3]
        return T

    def to_dict(self):
        return {"type": "free", **pose_to_dict(self.base)}


@dataclass
class RestsOnJoint(Joint):
    """The node's bottom face lies on the parent's face ``face`` (the floor z = 0 for the world)."""

    face: str | None = None
    s: float = 0.0
    t: float = 0.0
    yaw: float = 0.0
    dof_names: tuple[str, ...] = ("s", "t", "yaw")
    dof_kinds: tuple[str, ...] = ("position", "position", "angle")

    def values(self):
        return np.array([self.s, self.t, self.yaw])

    def set_values(self, q):
        self.s, self.t, self.yaw = (float(v) for v in q)

    def transform(self, q, parent, parent_params, node, node_params):
        F = np.eye(4)
        if parent is not None:
            o, x, y, n = parent.face_frame(self.face, parent_params)
            F[:3, 0], F[:3, 1], F[:3, 2], F[:3, 3] = x, y, n, o
        return F @ translation(np.array([q[0], q[1], 0.0])) @ rz(q[2])

    def to_dict(self):
        d: dict[str, Any] = {"type": "rests_on", "position": [self.s, self.t], "yaw_deg": float(np.degrees(self.yaw))}
        if self.face is not None:
            d["face"] = self.face
        return d


def _axis_rotation(axis: Array, angle: float) -> Array:
    return rotation4(exp_so3(axis / np.linalg.norm(axis) * angle))


@dataclass
class HingeJoint(Joint):
    axis_point: Array = field(default_factory=lambda: np.zeros(3))
    axis: Array = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    angle: float = 0.0
    limits: tuple[float, float] = (-np.pi, np.pi)
    dof_names: tuple[str, ...] = ("angle",)
    dof_kinds: tuple[str, ...] = ("angle",)

    def values(self):
        return np.array([self.angle])

    def set_values(self, q):
        self.angle = float(q[0])

    def bounds(self):
        return np.array([self.limits[0]]), np.array([self.limits[1]])

    def transform(self, q, parent, parent_params, node, node_params):
        turn = _axis_rotation(self.axis, q[0])
        return translation(self.axis_point) @ turn @ translation(-self.axis_point) @ self.base

    def to_dict(self):
        return {"type": "hinge", "axis_point": [float(v) for v in self.axis_point],
                "axis": [float(v) for v in self.axis], **pose_to_dict(self.base),
                "angle_deg": float(np.degrees(self.angle)), "limits_deg": [float(np.degrees(v)) for v in self.limits]}


@dataclass
class SliderJoint(Joint):
    axis: Array = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    offset: float = 0.0
    limits: tuple[float, float] = (-np.inf, np.inf)
    dof_names: tuple[str, ...] = ("offset",)
    dof_kinds: tuple[str, ...] = ("position",)

    def values(self):
        return np.array([self.offset])

    def set_values(self, q):
        self.offset = float(q[0])

    def bounds(self):
        return np.array([self.limits[0]]), np.array([self.limits[1]])

    def transform(self, q, parent, parent_params, node, node_params):
        return translation(self.axis / np.linalg.norm(self.axis) * q[0]) @ self.base

    def to_dict(self):
        d = {"type": "slider", "axis": [float(v) for v in self.axis], **pose_to_dict(self.base), "offset": self.offset}
        if all(np.isfinite(self.limits)):  # no limits: none written (JSON has no infinity)
            d["limits"] = [float(v) for v in self.limits]
        return d


@dataclass
class MarkerJoint(Joint):
    """The node's ``handle`` sits exactly on a calibrated marker; the node turns about +Z (§3.1)."""

    marker: str = ""
    handle: str = ""
    position: Array = field(default_factory=lambda: np.zeros(3))  # the marker's world position
    yaw: float = 0.0
    dof_names: tuple[str, ...] = ("yaw",)
    dof_kinds: tuple[str, ...] = ("angle",)

    def values(self):
        return np.array([self.yaw])

    def set_values(self, q):
        self.yaw = float(q[0])

    def transform(self, q, parent, parent_params, node, node_params):
        h = node.handles(node_params)[node.handle_names().index(self.handle)]
        return translation(self.position) @ rz(q[0]) @ translation(-h)

    def to_dict(self):
        return {"type": "marker", "marker": self.marker, "handle": self.handle, "yaw_deg": float(np.degrees(self.yaw))}


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

    def __init__(self, nodes: list[Node]):
        self.nodes = _topological(nodes)
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
        for n in self.nodes:
            sq, sp = self.slices[n.name]
            n.joint.set_values(x[sq])
            if n.primitive is not None:
                n.primitive = n.primitive.with_params(x[sp])

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
                out += ["size"] * len(n.primitive.PARAMS)
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
            sq, sp = self.slices[n.name]
            parent = None if n.parent is None else self.node(n.parent)
            p_params = None
            if parent is not None and parent.primitive is not None:
                p_params = x[self.slices[parent.name][1]]
            node_params = x[sp] if n.primitive is not None else None
            parent_prim = None if parent is None else parent.primitive
            T = n.joint.transform(x[sq], parent_prim, p_params, n.primitive, node_params)
            out[n.name] = T if parent is None else out[parent.name] @ T
        return out

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


def joint_from_dict(d: Mapping[str, Any], where: str, markers: Mapping[str, Array] | None = None,
                    path: str | None = None) -> Joint:
    """A joint from its project-file form (degrees); ModelError names ``where`` (and has the JSON
    path ``path``) on bad input."""
    kind = d.get("type")
    base = pose_matrix(d.get("translation", [0, 0, 0]), d.get("rotation_deg", [0, 0, 0]))

    def at(key: str) -> str | None:
        return None if path is None else f"{path}.{key}"

    def axis_of(default: list[float]) -> Array:
        axis = np.asarray(d.get("axis", default), float)
        if not np.hypot.reduce(np.abs(axis)) >= 1e-6:
            raise _error(where, at("axis"), f"the {kind} joint's axis {list(axis)} has no direction; expected a "
                         "non-zero vector [x, y, z], at least 1e-6 long")
        return axis

    def limits_of(key: str, default: list[float], unit: str) -> tuple[float, float]:
        lo, hi = (float(v) for v in d.get(key, default))
        if lo > hi:
            raise _error(where, at(key), f"the {kind} joint's limits [{lo:g}{unit}, {hi:g}{unit}] are reversed; "
                         "expected [lo, hi] with lo no greater than hi")
        return lo, hi

    if kind == "fixed":
        return Joint(base=base)
    if kind == "free":
        return FreeJoint(type="free", base=base)
    if kind == "rests_on":
        s, t = d.get("position", [0.0, 0.0])
        return RestsOnJoint(type="rests_on", face=d.get("face"), s=float(s), t=float(t),
                            yaw=float(np.radians(d.get("yaw_deg", 0.0))))
    if kind == "hinge":
        axis = axis_of([0, 0, 1])
        lo, hi = np.radians(limits_of("limits_deg", [-180.0, 180.0], "°"))
        angle = float(np.radians(d.get("angle_deg", 0.0)))
        if not lo <= angle <= hi:
            raise _error(where, at("angle_deg"), f"hinge angle {np.degrees(angle):.1f}° lies outside its limits "
                         f"[{np.degrees(lo):.1f}°, {np.degrees(hi):.1f}°]")
        return HingeJoint(type="hinge", base=base, axis_point=np.asarray(d.get("axis_point", [0, 0, 0]), float),
                          axis=axis, angle=angle, limits=(float(lo), float(hi)))
    if kind == "slider":
        axis = axis_of([1, 0, 0])
        lo, hi = limits_of("limits", [-np.inf, np.inf], " m")
        off = float(d.get("offset", 0.0))
        if not lo <= off <= hi:
            raise _error(where, at("offset"), f"slider offset {off} lies outside its limits [{lo}, {hi}]")
        return SliderJoint(type="slider", base=base, axis=axis, offset=off, limits=(float(lo), float(hi)))
    if kind == "marker":
        name = d.get("marker", "")
        if markers is None or name not in markers:
            raise _error(where, at("marker"), f"the joint ties the node to marker '{name}', which has no calibrated "
                         "position; run vebuild calibrate first, or name a marker the calibration placed")
        return MarkerJoint(type="marker", marker=name, handle=d.get("handle", ""),
                           position=np.asarray(markers[name], float), yaw=float(np.radians(d.get("yaw_deg", 0.0))))
    raise _error(where, at("type"), f"joint type '{kind}' is not one of {', '.join(JOINT_TYPES)}")


def _primitive(d: Any, human: str, path: str) -> Primitive:
    """A node's primitive, its sizes checked with the JSON path of the one at fault."""
    if not isinstance(d, Mapping) or not isinstance(d.get("params", {}), Mapping):
        raise _error(human, path, "expected an object {\"type\": T, \"params\": {...}}")
    params = d.get("params", {})
    kind = d.get("type")
    cls = PRIMITIVE_TYPES.get(kind) if isinstance(kind, str) else None
    for name, value in params.items():
        if cls is None or name not in cls.PARAMS or not isinstance(value, int | float):
            continue
        least = cls.minimum_size(name)
        if value >= least:
            continue
        if least > 0 and value <= 0:
            raise _error(human, f"{path}.params.{name}", f"{cls.TYPE}: {name} must be > 0, got {value!r}")
        raise _error(human, f"{path}.params.{name}", f"{cls.TYPE}: {name} must be at least {least:g} m (sizes "
                     f"stay above {MIN_SIZE_M:g} m, the solver's least), got {value!r}")
    try:
        prim = primitive_from_dict(d)
    except (ValueError, TypeError) as e:
        raise _error(human, f"{path}.params" if isinstance(d.get("type"), str) else f"{path}.type", str(e)) from None
    for name, value, least in zip(prim.PARAMS, prim.params, prim.minimum_sizes(), strict=True):
        if not value >= least:
            raise _error(human, f"{path}.params.{name}", f"{prim.TYPE}: {name} must be at least {least:g} m (sizes "
                         f"stay above {MIN_SIZE_M:g} m, the solver's least), got {params.get(name, value)!r}")
    return prim


def model_from_dict(nodes: list[Mapping[str, Any]], markers: Mapping[str, Array] | None = None) -> Model:
    """The model from the project file's ``model.nodes``; ModelError names the node and the field."""
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
                raise _error(f"{where}.joint", f"{path}.parent",
                             "a marker joint ties a node to the world; this node has a parent")
            if prim is None or joint.handle not in prim.handle_names():
                have = ", ".join(prim.handle_names()) if prim is not None else "none (a group has no handles)"
                raise _error(f"{where}.joint", f"{path}.joint.handle", f"handle '{joint.handle}' is not a handle of "
                             f"this node's primitive (its handles are: {have})")
        try:
            hold, entered = hold_list(d.get("hold", ()), (prim.PARAMS if prim is not None else ()) + joint.dof_names)
        except HoldError as e:
            raise _error(f"{where}.hold", f"{path}.hold{e.at}", e.detail) from None
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
    for n in model.nodes:
        if isinstance(n.joint, RestsOnJoint) and n.parent is not None:
            parent = model.node(n.parent).primitive
            if parent is None or n.joint.face not in parent.faces():
                faces = ", ".join(parent.faces()) if parent is not None else "none (a group)"
                detail = f"rests on face '{n.joint.face}' of '{n.parent}', which has faces: {faces}"
                raise ModelError(f"node '{n.name}': {detail}", f"$.model.nodes[{index[n.name]}].joint.face",
                                 f"node '{n.name}' {detail}")
    return model


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

