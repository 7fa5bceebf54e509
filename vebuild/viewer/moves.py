"""What the walk-through says about an object and its moves, in the world frame (pure numpy).

A joint's own degrees of freedom are in its parent's frame (a ``rests_on`` joint's ``s, t`` are
along the floor face's axes, from the floor's centre), which tells a viewer nothing. Here an
object is described by where it is in the room, the world frame of DESIGN.md (metres, x and y
along the floor, z up): the centre of its bounding box, the heading of its own x axis (degrees
from world +x toward +y), and, where it has been moved, how far its centre moved and by how much
it turned, against the measured model. A hinge's opening and a slider's travel, which are
already an angle and a length, are said as such, with their limits.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.model.scene import HingeJoint, Model, SliderJoint

Array = NDArray[np.float64]

#: A move smaller than this (metres) or a turn smaller than TURN_SAID_DEG is not reported as one.
MOVE_SAID_M = 0.0005
TURN_SAID_DEG = 0.05
#: Within this angle (degrees) of the vertical a turn's axis is said to be the vertical.
VERTICAL_AXIS_DEG = 1.0


def _signed(v: float, unit: str, digits: int) -> str:
    """A signed figure with a true minus sign: ``+0.300 m``, ``−0.290 m``."""
    s = f"{abs(v):.{digits}f}"
    return ("−" if v < 0 and float(s) != 0 else "+") + s + unit


def _subtree_world_vertices(model: Model, node: str, transforms: dict[str, Array]) -> Array:
    pts = []
    for name in model.subtree(node):
        n = model.node(name)
        if n.primitive is not None:
            V = n.primitive.mesh(None, 8).vertices
            T = transforms[name]
            pts.append(V @ T[:3, :3].T + T[:3, 3])
    if not pts:
        return transforms[node][:3, 3][None, :]
    return np.concatenate(pts)


def centre_and_heading(model: Model, node: str) -> tuple[Array, float]:
    """The world centre (bounding box of the node and what it carries, metres) and the heading of
    the node's x axis in the floor plane (degrees from +x toward +y, in (−180, 180])."""
    T = model.world_transforms()
    V = _subtree_world_vertices(model, node, T)
    centre = 0.5 * (V.min(axis=0) + V.max(axis=0))
    x = T[node][:3, 0]
    return centre, math.degrees(math.atan2(float(x[1]), float(x[0])))


def _turn(model: Model, measured: Model, node: str) -> tuple[float, Array]:
    """The turn (degrees, and its unit axis in the world) from the measured pose to the current."""
    from scipy.spatial.transform import Rotation

    R = model.world_transforms()[node][:3, :3] @ measured.world_transforms()[node][:3, :3].T
    rv = Rotation.from_matrix(R).as_rotvec()
    angle = float(np.linalg.norm(rv))
    return math.degrees(angle), (rv / angle if angle > 0 else np.array([0.0, 0.0, 1.0]))


def joint_words(model: Model, node: str) -> str:
    """A node's joint in words with world-frame figures: where a hinge's axis stands and how far
    open it is, the world direction a slider runs along and how far out it is."""
    n = model.node(node)
    j = n.joint
    P = np.eye(4) if n.parent is None else model.world_transforms()[n.parent]
    if isinstance(j, HingeJoint):
        lo, hi = (math.degrees(v) for v in j.limits)
        a = P[:3, :3] @ (j.axis / np.linalg.norm(j.axis))
        c = P[:3, :3] @ j.point(j.values()) + P[:3, 3]
        where = (f"the vertical at x {c[0]:.2f} m, y {c[1]:.2f} m" if abs(a[2]) > math.cos(math.radians(
            VERTICAL_AXIS_DEG)) else f"the axis ({a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f}) through "
                                       f"({c[0]:.2f}, {c[1]:.2f}, {c[2]:.2f}) m")
        return f"hinge ({lo:.0f}° to {hi:.0f}°): open {math.degrees(j.angle):.1f}° about {where}"
    if isinstance(j, SliderJoint):
        a = P[:3, :3] @ j.direction(j.values())
        lim = (f" ({j.limits[0]:.2f} m to {j.limits[1]:.2f} m)" if all(np.isfinite(j.limits)) else "")
        return f"slider{lim}: out {j.offset:.3f} m along ({a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f})"
    return j.type


def move_words(model: Model, measured: Model, node: str) -> str:
    """How far ``node`` is from where it was measured: its centre's move (metres, world axes) and
    its turn (degrees); "where measured" if it has not moved."""
    c, _ = centre_and_heading(model, node)
    c0, _ = centre_and_heading(measured, node)
    d = c - c0
    deg, axis = _turn(model, measured, node)
    parts = []
    if np.linalg.norm(d) >= MOVE_SAID_M:
        parts.append(f"moved {np.linalg.norm(d):.3f} m (x {_signed(d[0], '', 3)}, y {_signed(d[1], '', 3)}, "
                     f"z {_signed(d[2], '', 3)} m)")
    if deg >= TURN_SAID_DEG:
        if abs(axis[2]) > math.cos(math.radians(VERTICAL_AXIS_DEG)):  # + counter-clockwise seen from above
            parts.append(f"turned {_signed(math.copysign(deg, axis[2]), '°', 1)} about the vertical")
        else:
            parts.append(f"turned {deg:.1f}° about ({axis[0]:.2f}, {axis[1]:.2f}, {axis[2]:.2f})")
    return ", ".join(parts) + " from where measured" if parts else "where measured"


def describe(mover: Any, node: str) -> str:
    """The panel's line for a selected node: its group and joint, where it is in the room, and
    how far it has been moved (the node a drag on it moves, if that is an ancestor)."""
    from vebuild.model.arrange import CannotMove

    model = mover.model
    n = model.node(node)
    group = n.parent or "the world"
    c, heading = centre_and_heading(model, node)
    text = (f"{node} in {group}; joint {joint_words(model, node)}; centre x {c[0]:.2f}, y {c[1]:.2f}, "
            f"z {c[2]:.2f} m, facing {heading:.1f}°")
    try:
        moves = mover.movable(node)
    except CannotMove:
        return text + " (cannot move)"
    how = "" if moves == node else f" (moves '{moves}')"
    return text + how + "; " + (moves + " " if moves != node else "") + move_words(model, mover.measured, moves)


def moved_line(mover: Any, node: str) -> str:
    """The message after a drag or a turn: what moved and by how much, in the room's frame."""
    j = mover.model.node(node).joint
    state = ""
    if isinstance(j, HingeJoint):
        state = f"; now open {math.degrees(j.angle):.1f}°"
    elif isinstance(j, SliderJoint):
        state = f"; now out {j.offset:.3f} m"
    return f"{node}: {move_words(mover.model, mover.measured, node)}{state}"
