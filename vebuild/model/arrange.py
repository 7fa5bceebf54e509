"""Moving objects only as their joints allow (paper §5, Figure 13), with undo, reset and
hypotheses (pure numpy).

A drag grabs a node at a point and follows the mouse ray:

- ``rests_on`` (furniture on the floor) and ``flush`` (a cabinet against a wall): the grabbed
  point slides in the plane of the parent's face; the object turns about that face's normal with
  :meth:`ObjectMover.turn`;
- ``hinge`` (a door): the object turns about its axis to follow the ray's meeting with the plane
  across the axis, within the joint's limits;
- ``slider`` (a drawer): the object slides along its axis to the point nearest the ray, within
  limits;
- ``free``: the object slides horizontally and turns about the vertical.

A node whose own joint has no freedom moves its nearest ancestor that has (a table's leg moves the
table); nodes tied to the origin marker (the floor) or fixed all the way up do not move, and say
why. The moving node takes its children along. A move that would push it into another object (a
wall, other furniture; its own ancestors and descendants excepted) stops where it touches.

The measured model is never changed: the mover works on a copy, and :meth:`ObjectMover.arrangement`
gives the moved joints for saving as a named *hypothesis* (FORMAT.md, ``hypotheses``).
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import VebuildError
from vebuild.model.collide import Footprint, footprints, local_vertices, overlap_depth
from vebuild.model.joint_file import joint_from_dict
from vebuild.model.scene import (
    FlushJoint,
    FreeJoint,
    HingeJoint,
    MarkerJoint,
    Model,
    RestsOnJoint,
    SliderJoint,
)
from vebuild.model.undo import UndoStack

Array = NDArray[np.float64]

#: Overlap of two footprints (metres) tolerated before they count as colliding: objects that touch
#: (a door in its frame, a cabinet against a wall) are not stuck.
TOUCH_TOLERANCE_M = 0.01
#: Halvings when a move collides: the object stops within 2⁻¹² of a sweep step from where it touches.
COLLISION_BISECTIONS = 12
#: A move is checked for collisions every this many metres of its farthest point's travel.
SWEEP_STEP_M = 0.05
MAX_SWEEP_STEPS = 400


class CannotMove(VebuildError):
    """The picked object's joints do not let it move; the message says why."""


@dataclass
class Grab:
    node: str  # the node whose joint moves
    picked: str  # the node the user picked
    point: Array  # grabbed world point
    q0: Array  # joint values at the start
    kind: str
    turned: float = 0.0  # a hinge's turn so far, unwrapped (the mouse may sweep past ±180°)


def _ray_plane(origin: Array, direction: Array, point: Array, normal: Array) -> Array | None:
    denom = float(direction @ normal)
    if abs(denom) < 1e-9:
        return None
    t = float((point - origin) @ normal) / denom
    return None if t <= 0 else origin + t * direction


class ObjectMover:
    """Drags, turns, undo/redo and reset over a working copy of ``model``."""

    def __init__(self, model: Model):
        self.measured = model
        self.model = copy.deepcopy(model)
        self._local = local_vertices(self.model)
        self.history: UndoStack[dict[str, Array]] = UndoStack()
        self.grab: Grab | None = None
        self._before: dict[str, Array] | None = None
        self._allowed: set[tuple[str, str]] = set()
        self._fixed_obstacles: dict[str, list[Footprint]] = {}  # during one move, what stands still

    # -- what may move --------------------------------------------------------------------------

    def movable(self, node: str) -> str:
        """The node a drag on ``node`` moves (itself or its nearest movable ancestor), or CannotMove."""
        n = self.model.node(node)
        chain = [n.name]
        while not self._moves(n) and n.parent is not None:
            n = self.model.node(n.parent)
            chain.append(n.name)
        if not self._moves(n):
            why = {"marker": f"'{n.name}' is tied to the origin marker (it is the world's reference)",
                   "fixed": f"'{n.name}' is fixed to the world"}.get(n.joint.type, f"'{n.name}' has a {n.joint.type} "
                                                                                 "joint")
            via = f" (through {' → '.join(repr(c) for c in chain[:-1])})" if len(chain) > 1 else ""
            raise CannotMove(f"'{node}' cannot move: its joint{via} has no freedom, and {why}")
        return n.name

    @staticmethod
    def _moves(n: Any) -> bool:
        if isinstance(n.joint, HingeJoint | SliderJoint):
            lo, hi = n.joint.bounds()
            return bool(hi[0] > lo[0])
        return isinstance(n.joint, RestsOnJoint | FlushJoint | FreeJoint)

    def joint_type(self, node: str) -> str:
        return self.model.node(node).joint.type

    # -- dragging -------------------------------------------------------------------------------

    def begin(self, picked: str, point: Array) -> str:
        """Grab ``picked`` at world ``point``; returns the node that will move."""
        node = self.movable(picked)
        j = self.model.node(node).joint
        self.grab = Grab(node, picked, np.asarray(point, float), j.values().copy(), j.type)
        self._before = self._snapshot()
        self._fixed_obstacles = {}
        self._allowed = self.overlaps(node)
        return node

    def drag(self, origin: Array, direction: Array) -> bool:
        """Follow the mouse ray; returns whether the object moved."""
        g = self.grab
        if g is None:
            return False
        origin, direction = np.asarray(origin, float), np.asarray(direction, float)
        n = self.model.node(g.node)
        j = n.joint
        P = self._parent_world(g.node)
        q = g.q0.copy()
        if isinstance(j, RestsOnJoint | FlushJoint | FreeJoint):
            if isinstance(j, RestsOnJoint | FlushJoint):
                o, x, y, normal = self._face_world(g.node, j)
            else:
                x, y, normal = P[:3, 0], P[:3, 1], np.array([0.0, 0.0, 1.0])
            hit = _ray_plane(origin, direction, g.point, normal)
            if hit is None:
                return False
            d = hit - g.point
            if isinstance(j, RestsOnJoint | FlushJoint):
                q[0] += d @ x
                q[1] += d @ y
            else:
                q[:2] += (P[:3, :3].T @ d)[:2]
        elif isinstance(j, HingeJoint):
            a = P[:3, :3] @ (j.axis / np.linalg.norm(j.axis))
            c = P[:3, :3] @ j.axis_point + P[:3, 3]
            hit = _ray_plane(origin, direction, g.point, a)
            if hit is None:
                return False
            u, v = g.point - c, hit - c
            u, v = u - (u @ a) * a, v - (v @ a) * a
            if np.linalg.norm(u) < 1e-6 or np.linalg.norm(v) < 1e-6:
                return False
            turn = float(np.arctan2(np.cross(u, v) @ a, u @ v))
            turn = g.turned + (turn - g.turned + np.pi) % (2 * np.pi) - np.pi  # continuous with the last
            g.turned = turn
            q[0] += turn
        elif isinstance(j, SliderJoint):
            a = P[:3, :3] @ (j.axis / np.linalg.norm(j.axis))
            # the point of the axis line through the grab point nearest to the ray
            w = g.point - origin
            b = a @ direction
            den = 1.0 - b * b
            if den < 1e-9:
                return False
            q[0] += (b * (direction @ w) - (a @ w)) / den
        q = j.clip(q)
        return self._set_limited(g.node, q)

    def turn(self, node: str, angle: float) -> bool:
        """Turn a resting or free object about the vertical by ``angle`` radians (no drag needed)."""
        node = self.movable(node)
        j = self.model.node(node).joint
        if not isinstance(j, RestsOnJoint | FlushJoint | FreeJoint):
            raise CannotMove(f"'{node}' turns only on its {j.type} joint; drag it instead")
        before = self._snapshot()
        self._fixed_obstacles = {}
        self._allowed = self.overlaps(node)
        q = j.values().copy()
        if isinstance(j, RestsOnJoint | FlushJoint):  # about the face's normal
            q[2] += angle
        else:
            q[3:6] = [0.0, 0.0, angle]
        moved = self._set_limited(node, q)
        if moved:
            self._push(before)
        return moved

    def end(self) -> None:
        """Release the grabbed object; the move becomes one undo step."""
        if self.grab is not None and self._before is not None and self._changed_since(self._before):
            self._push(self._before)
        self.grab, self._before = None, None

    def cancel(self) -> None:
        """Put the grabbed object back where the drag started."""
        if self._before is not None:
            self._restore(self._before)
        self.grab, self._before = None, None

    # -- undo, reset, hypotheses -----------------------------------------------------------------

    def undo(self) -> bool:
        step = self.history.undo(self._snapshot())
        if step is not None:
            self._restore(step[1])
        return step is not None

    def redo(self) -> bool:
        step = self.history.redo(self._snapshot())
        if step is not None:
            self._restore(step[1])
        return step is not None

    def reset(self, node: str | None = None) -> None:
        """Back to the measured scene: one object (and what it carries), or everything."""
        before = self._snapshot()
        names = [node] if node is not None else [n.name for n in self.model.nodes]
        for name in names:
            self._joint(name).set_values(self.measured.node(name).joint.values().copy())
            if isinstance(self._joint(name), FreeJoint):
                self._joint(name).base = self.measured.node(name).joint.base.copy()
        if self._changed_since(before):
            self._push(before)

    def arrangement(self) -> dict[str, dict[str, Any]]:
        """The joints that differ from the measured scene, as joint records (FORMAT.md)."""
        out = {}
        for n in self.model.nodes:
            m = self.measured.node(n.name).joint
            if not np.allclose(n.joint.values(), m.values(), atol=1e-9) or \
                    not np.allclose(n.joint.base, m.base, atol=1e-12):
                out[n.name] = n.joint.to_dict()
        return out

    def apply(self, joints: Mapping[str, Mapping[str, Any]], where: str = "$.hypotheses") -> None:
        """Set the joints of a hypothesis (one undo step)."""
        before = self._snapshot()
        for name, rec in joints.items():
            node = self.model.node(name)
            new = joint_from_dict(rec, f"{where}.joints.{name}", _markers(self.measured), f"{where}.joints.{name}")
            if new.type != node.joint.type:
                raise VebuildError(f"{where}.joints.{name}: a {new.type} joint, but the node's joint is "
                                   f"{node.joint.type}; a hypothesis moves objects, it does not re-attach them")
            node.joint = new
        self._push(before)

    # -- internals ------------------------------------------------------------------------------

    def _joint(self, name: str) -> Any:
        return self.model.node(name).joint

    def _snapshot(self) -> dict[str, Array]:
        return {n.name: np.r_[n.joint.values(), n.joint.base.ravel()] for n in self.model.nodes}

    def _restore(self, snap: Mapping[str, Array]) -> None:
        for n in self.model.nodes:
            k = len(n.joint.dof_names)
            n.joint.base = snap[n.name][k:].reshape(4, 4).copy()
            if isinstance(n.joint, FreeJoint):
                n.joint.base[:3, 3] = snap[n.name][:3]
            else:
                n.joint.set_values(snap[n.name][:k].copy())

    def _changed_since(self, snap: Mapping[str, Array]) -> bool:
        now = self._snapshot()
        return any(not np.array_equal(now[k], v) for k, v in snap.items())

    def _push(self, before: dict[str, Array]) -> None:
        self.history.push(before)

    def _parent_world(self, node: str) -> Array:
        parent = self.model.node(node).parent
        return np.eye(4) if parent is None else self.model.world_transforms()[parent]

    def _face_world(self, node: str, joint: RestsOnJoint | FlushJoint) -> tuple[Array, Array, Array, Array]:
        """The world frame (origin, x, y, normal) of the face ``node`` rests (or is flush) on by ``joint``."""
        parent = self.model.node(node).parent
        prim = None if parent is None else self.model.node(parent).primitive
        P = self._parent_world(node)
        if prim is None or joint.face is None:  # on the floor (the model's loader names a primitive's face)
            return P[:3, 3], P[:3, 0], P[:3, 1], P[:3, 2]
        o, x, y, normal = prim.plane_frame(joint.face) if isinstance(joint, FlushJoint) else prim.face_frame(joint.face)
        return P[:3, :3] @ o + P[:3, 3], P[:3, :3] @ x, P[:3, :3] @ y, P[:3, :3] @ normal

    def _apply_q(self, node: str, q: Array) -> None:
        # A free joint's rotation values are a small turn about its current base: set_values folds
        # it in, so callers restore the base before applying another q.
        self._joint(node).set_values(q)

    def obstacles(self, node: str) -> list[Footprint]:
        """What ``node``'s subtree may not enter: every other primitive but its ancestors."""
        moving = set(self.model.subtree(node))
        ancestors = set()
        n = self.model.node(node)
        while n.parent is not None:
            ancestors.add(n.parent)
            n = self.model.node(n.parent)
        keep = [name for name in self._local if name not in moving and name not in ancestors]
        return footprints(self.model, nodes=keep, local=self._local)

    def overlaps(self, node: str) -> set[tuple[str, str]]:
        """Pairs (a part of ``node``'s subtree, another object) that overlap where they are now."""
        moving = footprints(self.model, nodes=set(self.model.subtree(node)), local=self._local)
        if node not in self._fixed_obstacles:
            self._fixed_obstacles[node] = self.obstacles(node)
        out = set()
        for a in moving:
            for b in self._fixed_obstacles[node]:
                if a.z_hi > b.z_lo + TOUCH_TOLERANCE_M and a.z_lo < b.z_hi - TOUCH_TOLERANCE_M \
                        and overlap_depth(a.hull, b.hull) > TOUCH_TOLERANCE_M:
                    out.add((a.node, b.node))
        return out

    def collides(self, node: str) -> bool:
        """Whether ``node``'s subtree overlaps another object it did not overlap when the move began
        (a measured scene may have objects touching a little more than the tolerance)."""
        return bool(self.overlaps(node) - self._allowed)

    def _set_limited(self, node: str, q: Array) -> bool:
        """Set ``node``'s joint to ``q``, or as far toward it as it goes without colliding: the move
        is swept in steps of at most :data:`SWEEP_STEP_M` (so nothing jumps through a thin wall),
        and the first colliding step is bisected to where the object touches."""
        j = self._joint(node)
        start = j.values().copy()
        start_base = j.base.copy()
        if np.array_equal(q, start) and not isinstance(j, FreeJoint):
            return False

        def at(t: float) -> bool:
            """Put the joint a share t of the way to q; True if it collides there."""
            j.base = start_base.copy()
            self._apply_q(node, start + t * (q - start))
            return self.collides(node)

        names = set(self.model.subtree(node)) & set(self._local)
        before = self._points(names)
        at(1.0)
        travel = float(np.linalg.norm(self._points(names) - before, axis=1).max()) if len(before) else 0.0
        steps = max(1, min(MAX_SWEEP_STEPS, int(np.ceil(travel / SWEEP_STEP_M))))
        lo = 0.0
        for k in range(1, steps + 1):
            t = k / steps
            if at(t):
                hi = t
                for _ in range(COLLISION_BISECTIONS):
                    mid = 0.5 * (lo + hi)
                    if at(mid):
                        hi = mid
                    else:
                        lo = mid
                at(lo)
                return lo > 0.0
            lo = t
        return True

    def _points(self, names: set[str]) -> Array:
        T = self.model.world_transforms()
        return np.concatenate([self._local[n] @ T[n][:3, :3].T + T[n][:3, 3] for n in sorted(names)]) \
            if names else np.zeros((0, 3))


def _markers(model: Model) -> dict[str, Array]:
    return {n.joint.marker: np.asarray(n.joint.position, np.float64) for n in model.nodes
            if isinstance(n.joint, MarkerJoint)}
