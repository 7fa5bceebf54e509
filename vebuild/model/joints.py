"""Joints (paper §3, Figure 6): how a node may sit on its parent, an exact parameterisation.

A box that rests on the floor has three degrees of freedom (a position in the floor's plane and a
turn about its normal), a door on its hinge has one. Transforms are 4×4 matrices mapping a node's
local frame into its parent's; lengths in metres, angles in radians here (degrees in the project
file, read by :func:`joint_from_dict`). The scene graph that holds them is
:mod:`vebuild.model.scene`, which re-exports these names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import exp_so3

from .primitives import Primitive
from .room import Room

Array = NDArray[np.float64]

JOINT_TYPES = ("fixed", "free", "rests_on", "flush", "hinge", "slider", "marker", "opening", "through")
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


def error_at(human: str, path: str | None, detail: str) -> ModelError:
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


def euler_xyz_matrix(rotation_deg: Any) -> Array:
    """The rotation by XYZ Euler angles (degrees, about the parent's axes): the very bits of scipy's
    ``Rotation.from_euler("xyz", rotation_deg, degrees=True).as_matrix()`` (its quaternions, composed
    and turned into a matrix in the same order, tests/test_cli_start.py), without importing scipy's
    spatial package (a quarter of a second), so that decoding a model stays light (docs/start-up.md)."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    for axis, angle in enumerate(np.deg2rad(np.asarray(rotation_deg, float)).reshape(3)):
        e = np.zeros(4)
        e[3], e[axis] = math.cos(angle / 2), math.sin(angle / 2)
        if axis == 0:
            q = e
            continue
        p = e  # extrinsic: the next elementary rotation composed on the left
        cross = [p[1] * q[2] - p[2] * q[1], p[2] * q[0] - p[0] * q[2], p[0] * q[1] - p[1] * q[0]]
        q = np.array([p[3] * q[0] + q[3] * p[0] + cross[0], p[3] * q[1] + q[3] * p[1] + cross[1],
                      p[3] * q[2] + q[3] * p[2] + cross[2], p[3] * q[3] - p[0] * q[0] - p[1] * q[1] - p[2] * q[2]])
    x, y, z, w = q
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])


def pose_matrix(t: Any, rotation_deg: Any) -> Array:
    """Translation then XYZ Euler rotation (degrees, about the parent's axes) as a 4×4 matrix."""
    T = rotation4(euler_xyz_matrix(rotation_deg))
    T[:3, 3] = np.asarray(t, float)
    return T


def pose_to_dict(T: Array) -> dict[str, list[float]]:
    from scipy.spatial.transform import Rotation

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


def _frame4(frame: tuple[Array, Array, Array, Array]) -> Array:
    """A face frame (origin, x, y, normal) as the 4×4 matrix from face coordinates."""
    F = np.eye(4)
    F[:3, 0], F[:3, 1], F[:3, 2], F[:3, 3] = frame[1], frame[2], frame[3], frame[0]
    return F


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
        F = np.eye(4) if parent is None else _frame4(parent.face_frame(self.face, parent_params))
        return F @ translation(np.array([q[0], q[1], 0.0])) @ rz(q[2])

    def to_dict(self):
        d: dict[str, Any] = {"type": "rests_on", "position": [self.s, self.t], "yaw_deg": float(np.degrees(self.yaw))}
        if self.face is not None:
            d["face"] = self.face
        return d


#: A face whose y axis has a z component above this is upright (a side face's y is +z exactly; a
#: wedge's slope, at most 45° from the vertical for a ramp no steeper than its depth, is not).
UPRIGHT_AXIS = 0.9


@dataclass
class FlushJoint(Joint):
    """The node's face ``own_face`` lies against the parent's face ``face``, ``offset`` metres out
    along its normal, the two facing each other: a cabinet's back against a wall, a wall on the
    floor. Degrees of freedom as ``rests_on`` (which this is, with ``own_face`` bottom and offset 0):
    the own face's centre at (s, t) in the parent face's frame, turned ``yaw`` about its normal.

    The own face is carried by a resting frame at its centre, z into the node (−normal), that
    goes onto the parent face's frame at (s, t, offset) turned by ``yaw``. Two faces that face each
    other cannot keep both in-plane axes: one of them turns half round. A face whose y axis is
    upright (a side face: y is +z) keeps y, so at yaw 0 a cabinet's back against a wall stands
    upright (its up along the wall face's y, up); any other face keeps x, so a bottom face's
    resting frame is the node's own frame and the transform is rests_on's, bit for bit. Faces are
    any flat face (``Primitive.planes``), the parent's and the node's; with no parent, the face is
    the floor z = 0, as for ``rests_on``.
    """

    face: str | None = None
    own_face: str = "bottom"
    offset: float = 0.0
    s: float = 0.0
    t: float = 0.0
    yaw: float = 0.0
    dof_names: tuple[str, ...] = ("s", "t", "yaw")
    dof_kinds: tuple[str, ...] = ("position", "position", "angle")

    def values(self):
        return np.array([self.s, self.t, self.yaw])

    def set_values(self, q):
        self.s, self.t, self.yaw = (float(v) for v in q)

    def rest_frame(self, node: Primitive | None, node_params: Array | None = None) -> Array:
        """node_from_rest (4×4): the own face's resting frame in the node's frame (identity for a
        bottom face: rests_on)."""
        if node is None or self.own_face == "bottom" and "bottom" in node.faces():
            return np.eye(4)
        o, x, y, n = node.plane_frame(self.own_face, node_params)
        keep_y = abs(y[2]) > UPRIGHT_AXIS  # (−x, y) or (x, −y), then −n (into the node), at the centre
        rest = np.eye(4)
        rest[:3, 0], rest[:3, 1], rest[:3, 2], rest[:3, 3] = (-x, y, -n, o) if keep_y else (x, -y, -n, o)
        return rest

    def transform(self, q, parent, parent_params, node, node_params):
        F = np.eye(4) if parent is None else _frame4(parent.plane_frame(self.face, parent_params))
        T = F @ translation(np.array([q[0], q[1], self.offset])) @ rz(q[2])
        if node is None or self.own_face == "bottom" and "bottom" in node.faces():
            return T  # the node's frame is its bottom face's resting frame (rests_on)
        rest = self.rest_frame(node, node_params)
        inv = np.eye(4)
        inv[:3, :3] = rest[:3, :3].T
        inv[:3, 3] = -rest[:3, :3].T @ rest[:3, 3]
        return T @ inv

    def values_for(self, parent_from_node: Array, parent: Primitive | None, node: Primitive | None) -> Array:
        """(s, t, yaw) that put the node as near ``parent_from_node`` as the joint allows: its own
        face's centre over the point it is over now, turned as it is now about the face's normal
        (what a modelling screen gives a node it makes flush where it stands)."""
        F = np.eye(4) if parent is None or self.face is None else _frame4(parent.plane_frame(self.face))
        M = np.linalg.inv(F) @ np.asarray(parent_from_node, float) @ self.rest_frame(node)
        return np.array([M[0, 3], M[1, 3], float(np.arctan2(M[1, 0], M[0, 0]))])

    def to_dict(self):
        d: dict[str, Any] = {"type": "flush"}
        if self.face is not None:
            d["face"] = self.face
        d.update({"own_face": self.own_face, "offset": self.offset, "position": [self.s, self.t],
                  "yaw_deg": float(np.degrees(self.yaw))})
        return d


def _axis_rotation(axis: Array, angle: float) -> Array:
    return rotation4(exp_so3(axis / np.linalg.norm(axis) * angle))


#: Beyond this |axis·x̂| the axis is too near x for x̂'s perpendicular part to give a steady unit
#: vector u: ŷ's is taken instead (FORMAT.md, ``solve_axis``).
AXIS_NEAR_X = 0.9


def axis_basis(axis: Array) -> tuple[Array, Array, Array]:
    """(â, u, v): the unit axis and two unit vectors perpendicular to it, u the normalised part of
    x̂ perpendicular to the axis (of ŷ where |â·x̂| > AXIS_NEAR_X), v = â × u. A solved axis is
    moved along u and v: the two directions in which an axis can be wrong."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    e = np.array([1.0, 0.0, 0.0]) if abs(a[0]) <= AXIS_NEAR_X else np.array([0.0, 1.0, 0.0])
    u = e - (e @ a) * a
    u /= np.linalg.norm(u)
    return a, u, np.cross(a, u)


@dataclass
class HingeJoint(Joint):
    """A turn by ``angle`` about the line through ``axis_point`` along ``axis`` (the parent's
    frame), from the pose at angle 0 (``base``: the door shut).

    With ``solve_axis`` the axis point is solved too, by its coordinates ``axis_u``, ``axis_v``
    along the two directions perpendicular to the axis (:func:`axis_basis`; its position along
    the axis changes nothing). The pose at angle 0 stays fixed, so the photos find the axis from
    the door seen turned: the turn that carries the shut door to where the photos see it has one
    axis. The solved values are written back into ``axis_point``.
    """

    axis_point: Array = field(default_factory=lambda: np.zeros(3))
    axis: Array = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    angle: float = 0.0
    limits: tuple[float, float] = (-np.pi, np.pi)
    #: (opening, side) of the parent room's jamb the hinge hangs on: axis_point, axis and the pose
    #: at angle 0 are then in that jamb's frame (Room.jamb_frame), which follows the solved room.
    jamb: tuple[str, str] | None = None
    solve_axis: bool = False
    dof_names: tuple[str, ...] = ("angle",)
    dof_kinds: tuple[str, ...] = ("angle",)

    def __post_init__(self) -> None:
        if self.solve_axis:
            self.dof_names, self.dof_kinds = ("angle", "axis_u", "axis_v"), ("angle", "position", "position")

    def values(self):
        if not self.solve_axis:
            return np.array([self.angle])
        _, u, v = axis_basis(self.axis)
        return np.array([self.angle, self.axis_point @ u, self.axis_point @ v])

    def point(self, q: Array) -> Array:
        """The axis point for degrees of freedom q (its part along the axis kept as it is)."""
        if not self.solve_axis:
            return np.asarray(self.axis_point, float)
        a, u, v = axis_basis(self.axis)
        return (self.axis_point @ a) * a + q[1] * u + q[2] * v

    def set_values(self, q):
        if self.solve_axis:
            self.axis_point = self.point(q)
        self.angle = float(q[0])

    def bounds(self):
        n = len(self.dof_names) - 1
        return np.r_[self.limits[0], np.full(n, -np.inf)], np.r_[self.limits[1], np.full(n, np.inf)]

    def turned(self, q: Array) -> Array:
        """axis_frame_from_node: the turn about the axis from the shut pose, in the frame the axis
        is given in (the parent's)."""
        p = self.point(q)
        return translation(p) @ _axis_rotation(self.axis, q[0]) @ translation(-p) @ self.base

    def transform(self, q, parent, parent_params, node, node_params):
        T = self.turned(q)
        if self.jamb is None:
            return T
        return jamb_frame_of(parent, parent_params, *self.jamb) @ T

    def to_dict(self):
        d = {"type": "hinge", "axis_point": [float(v) for v in self.axis_point],
             "axis": [float(v) for v in self.axis], **pose_to_dict(self.base),
             "angle_deg": float(np.degrees(self.angle)), "limits_deg": [float(np.degrees(v)) for v in self.limits]}
        if self.jamb is not None:
            d["jamb"] = {"opening": self.jamb[0], "side": self.jamb[1]}
        if self.solve_axis:
            d["solve_axis"] = True
        return d


@dataclass
class SliderJoint(Joint):
    """A slide by ``offset`` along ``axis`` (the parent's frame) from the pose at offset 0 (``base``).

    With ``solve_axis`` the axis's direction is solved too: two small turns ``axis_a``, ``axis_b``
    (radians) about the directions u, v perpendicular to it (:func:`axis_basis`), folded into
    ``axis`` after each solve (as the free joint folds its rotation), so that the file keeps only
    the axis and a solve always starts from zero turns, far from any singularity.
    """

    axis: Array = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    offset: float = 0.0
    limits: tuple[float, float] = (-np.inf, np.inf)
    solve_axis: bool = False
    dof_names: tuple[str, ...] = ("offset",)
    dof_kinds: tuple[str, ...] = ("position",)

    def __post_init__(self) -> None:
        if self.solve_axis:
            self.dof_names, self.dof_kinds = ("offset", "axis_a", "axis_b"), ("position", "angle", "angle")

    def values(self):
        return np.r_[self.offset, np.zeros(len(self.dof_names) - 1)]

    def direction(self, q: Array) -> Array:
        """The unit axis for degrees of freedom q: the axis turned by q[1] about u, q[2] about v."""
        a, u, v = axis_basis(self.axis)
        if not self.solve_axis:
            return a
        return exp_so3(q[1] * u + q[2] * v) @ a

    def set_values(self, q):
        if self.solve_axis:
            self.axis = self.direction(q)
        self.offset = float(q[0])

    def bounds(self):
        n = len(self.dof_names) - 1
        return np.r_[self.limits[0], np.full(n, -np.inf)], np.r_[self.limits[1], np.full(n, np.inf)]

    def slid(self, q: Array) -> Array:
        """axis_frame_from_node: the slide along the axis, in the frame the axis is given in."""
        return translation(self.direction(q) * q[0]) @ self.base

    def transform(self, q, parent, parent_params, node, node_params):
        return self.slid(q)

    def to_dict(self):
        d = {"type": "slider", "axis": [float(v) for v in self.axis], **pose_to_dict(self.base), "offset": self.offset}
        if all(np.isfinite(self.limits)):  # no limits: none written (JSON has no infinity)
            d["limits"] = [float(v) for v in self.limits]
        if self.solve_axis:
            d["solve_axis"] = True
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


def room_of(parent: Primitive | None, what: str) -> Room:
    """``parent`` as a room; ModelError, saying what needs one, where it is something else."""
    if not isinstance(parent, Room):
        kind = "the world" if parent is None else f"a {parent.TYPE}"
        raise ModelError(f"{what} needs a room as its parent, not {kind}")
    return parent


def jamb_frame_of(parent: Primitive | None, parent_params: Array | None, opening: str, side: str) -> Array:
    """room_from_jamb of the parent room at its current params."""
    return room_of(parent, "a hinge on a jamb").jamb_frame(opening, side, parent_params)
