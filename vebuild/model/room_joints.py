"""Joints tied to a room's openings (scenes/FORMAT.md, "Joints"): a door leaf hinged at a jamb
(:class:`~vebuild.model.joints.HingeJoint` with ``jamb``), anything set in an opening
(:class:`OpeningJoint`: a window pane) and a room joined to another through a shared opening
(:class:`ThroughJoint`). Each is expressed in a frame of the parent room that follows its solved
parameters, so a door stays in its doorway when the room's corners move.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .graph import Model
from .joints import HingeJoint, Joint, ModelError, error_at, pose_to_dict, room_of, translation
from .primitives import Primitive
from .room import Room

Array = NDArray[np.float64]

JAMB_SIDES = ("start", "end")
_HALF_TURN = np.diag([-1.0, -1.0, 1.0, 1.0])  # a half turn about z: x and y reversed, z kept


def _outer_opening_frame(room: Room, opening: str, params: Array | None) -> Array:
    """The opening's frame moved to the wall's outer face (y still into the room)."""
    p = room.params if params is None else params
    return room.opening_frame(opening, p) @ translation(np.array([0.0, -float(p[room.PARAMS.index("thickness")]),
                                                                  0.0]))


@dataclass
class OpeningJoint(Joint):
    """A fixed pose in the frame of the parent room's opening ``opening`` (Room.opening_frame:
    origin at the sill's centre on the inner face, x along the wall, y into the room, z up)."""

    opening: str = ""

    def transform(self, q, parent, parent_params, node, node_params):
        return room_of(parent, "an opening joint").opening_frame(self.opening, parent_params) @ self.base

    def to_dict(self):
        return {"type": "opening", "opening": self.opening, **pose_to_dict(self.base)}


@dataclass
class ThroughJoint(Joint):
    """This room joined to its parent room through a shared opening: the outer face of this
    room's ``own_opening`` lies on the outer face of the parent's ``opening``, their sill centres
    together, facing each other (the walls back to back). No degree of freedom."""

    opening: str = ""
    own_opening: str = ""

    def transform(self, q, parent, parent_params, node, node_params):
        mine = room_of(node, "a through joint's node")
        theirs = _outer_opening_frame(room_of(parent, "a through joint"), self.opening, parent_params)
        return theirs @ _HALF_TURN @ np.linalg.inv(_outer_opening_frame(mine, self.own_opening, node_params))

    def to_dict(self):
        return {"type": "through", "opening": self.opening, "own_opening": self.own_opening}


def jamb_of(d: Any, where: str, path: str | None) -> tuple[str, str]:
    """A hinge's ``jamb`` ``{"opening": name, "side": "start" | "end"}`` checked."""
    def at(key: str) -> str | None:
        return None if path is None else f"{path}.{key}"

    if not isinstance(d, Mapping):
        raise error_at(where, path, f"a hinge's jamb must be an object {{\"opening\": name, \"side\": \"start\" or "
                       f"\"end\"}}, got {d!r}")
    opening, side = d.get("opening"), d.get("side", "start")
    if not isinstance(opening, str) or not opening:
        raise error_at(where, at("opening"), f"a hinge's jamb names the parent room's opening, got {opening!r}")
    if side not in JAMB_SIDES:
        raise error_at(where, at("side"), f"a jamb's side is 'start' (the opening's offset) or 'end', got {side!r}")
    return opening, str(side)


def room_joint_from_dict(d: Mapping[str, Any], where: str, path: str | None, base: Array) -> Joint:
    """An ``opening`` or ``through`` joint from its project-file form."""
    def text(key: str) -> str:
        v = d.get(key)
        if not isinstance(v, str) or not v:
            raise error_at(where, None if path is None else f"{path}.{key}",
                           f"the {d.get('type')} joint's {key} must name an opening of a room, got {v!r}")
        return v

    if d.get("type") == "opening":
        return OpeningJoint(type="opening", base=base, opening=text("opening"))
    return ThroughJoint(type="through", opening=text("opening"), own_opening=text("own_opening"))


def check_room_joints(model: Model, index: Mapping[str, int]) -> None:
    """Every joint tied to a room names a room and an opening it has: ModelError with the JSON path."""
    for n in model.nodes:
        j = n.joint
        path = f"$.model.nodes[{index.get(n.name, 0)}]"
        parent = None if n.parent is None else model.node(n.parent).primitive
        theirs = "its parent" if n.parent is None else f"parent '{n.parent}'"
        needs: list[tuple[Primitive | None, str, str, str]] = []  # (room, opening, field, whose)
        if isinstance(j, HingeJoint) and j.jamb is not None:
            needs.append((parent, j.jamb[0], "joint.jamb.opening", theirs))
        elif isinstance(j, OpeningJoint):
            needs.append((parent, j.opening, "joint.opening", theirs))
        elif isinstance(j, ThroughJoint):
            needs += [(parent, j.opening, "joint.opening", theirs),
                      (n.primitive, j.own_opening, "joint.own_opening", "this node")]
        for prim, opening, field, whose in needs:
            what = f"node '{n.name}': its {j.type} joint"
            if not isinstance(prim, Room):
                kind = ("the world (no parent)" if n.parent is None else "a group") if prim is None else \
                    f"a {prim.TYPE}"
                where = f"{path}.parent" if whose != "this node" else f"{path}.primitive"
                detail = f"{what} is tied to a room's opening, but {whose} is {kind}, not a room"
                raise ModelError(detail, where, detail)
            if opening not in prim.opening_names():
                have = ", ".join(prim.opening_names()) or "none"
                detail = f"{what} names opening '{opening}', which {whose} lacks (its openings: {have})"
                raise ModelError(f"{detail}", f"{path}.{field}", detail)
