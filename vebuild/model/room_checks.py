"""The room primitive's checks (vebuild/model/room.py): its structure as written (corners,
rectilinear, openings) and its geometry once built (a floor polygon that does not cross itself and
runs counter-clockwise, walls of at least MIN_SIZE_M, a thickness the walls can take, openings
inside their walls and apart). Each refusal is a RoomError naming the field at fault.

Layer 1 (DESIGN.md): numpy only.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from .primitives import MIN_SIZE_M

Array = NDArray[np.float64]

OPENING_KINDS = ("door", "window")
#: An opening's name: a letter, then letters, digits or underscores (it prefixes its params,
#: handles and edges: ``door_width``, ``door_sb``, ``door_start``).
_OPENING_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
#: Opening names that would read as the room's own names (its params, handles, edges, faces).
_RESERVED = re.compile(r"^((c|f|t|fo|to|wall|outer|wtop|floor|top|corner|ofloor|otop|ocorner)\d*|ceiling|height"
                       r"|thickness|room)$")
#: Two walls closer than this (metres, relative above 1 m) where they should not meet make the
#: polygon self-intersecting.
_TOUCH_M = 1e-9


@dataclass(frozen=True)
class Opening:
    """A doorway or window in wall ``wall`` (0…N−1); its position and size are the room's params
    ``{name}_offset``, ``{name}_width``, ``{name}_height``, ``{name}_sill``."""

    name: str
    wall: int
    kind: str

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "wall": self.wall, "kind": self.kind}


class RoomError(ValueError):
    """A room as written cannot be built; ``at`` is the field at fault relative to the primitive's
    object (``params.c2_y``, ``openings[1].wall``, ``corners``), for the project file's JSON path."""

    def __init__(self, message: str, at: str = "params") -> None:
        super().__init__(message)
        self.at = at


class RoomShape(Protocol):
    """What the checks here and the mesh (:mod:`.room_mesh`) read of a room: its structure, its
    params and its geometry. :class:`vebuild.model.room.Room` is one."""

    @property
    def PARAMS(self) -> tuple[str, ...]: ...  # noqa: N802 (the primitives' name for it)
    @property
    def n_corners(self) -> int: ...
    @property
    def ceiling(self) -> bool: ...
    @property
    def openings(self) -> tuple[Opening, ...]: ...
    @property
    def walls_present(self) -> tuple[bool, ...]: ...
    def param(self, name: str) -> float: ...
    def corners(self, params: Any = None) -> Array: ...
    def walls(self, params: Any = None) -> dict[str, Array]: ...


def _segments_cross(a: Array, b: Array, c: Array, d: Array) -> bool:
    """Whether closed segments ab and cd share a point (within _TOUCH_M)."""
    def orient(p: Array, q: Array, r: Array) -> float:
        return float((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]))

    def on(p: Array, q: Array, r: Array) -> bool:  # r on segment pq, given collinear
        return bool(min(p[0], q[0]) - _TOUCH_M <= r[0] <= max(p[0], q[0]) + _TOUCH_M
                    and min(p[1], q[1]) - _TOUCH_M <= r[1] <= max(p[1], q[1]) + _TOUCH_M)

    scale = max(1.0, float(np.abs(np.r_[a, b, c, d]).max()))
    eps = _TOUCH_M * scale
    o1, o2, o3, o4 = orient(a, b, c), orient(a, b, d), orient(c, d, a), orient(c, d, b)
    if (min(o1, -o2) > eps or min(-o1, o2) > eps) and (min(o3, -o4) > eps or min(-o3, o4) > eps):
        return True
    return any(abs(o) <= eps and on(p, q, r) for o, p, q, r in ((o1, a, b, c), (o2, a, b, d), (o3, c, d, a),
                                                                 (o4, c, d, b)))


def _self_intersection(c: Array) -> tuple[int, int] | None:
    """The first pair of walls (i, j) of polygon c that meet where they should not, else None."""
    n = len(c)
    for i in range(n):
        for j in range(i + 1, n):
            a, b, p, q = c[i], c[(i + 1) % n], c[j], c[(j + 1) % n]
            if j == i + 1 or (i == 0 and j == n - 1):
                # Neighbours share a corner; they must not fold back onto each other.
                shared, u, v = (b, a, q) if j == i + 1 else (a, b, p)
                du, dv = u - shared, v - shared
                cross = du[0] * dv[1] - du[1] * dv[0]
                if abs(cross) <= _TOUCH_M * max(1.0, float(np.abs(c).max())) ** 2 and du @ dv > 0:
                    return i, j
                continue
            if _segments_cross(a, b, p, q):
                return i, j
    return None


def check_room(room: RoomShape) -> None:
    """RoomError (its field named) where the room as built cannot stand: walls too short, a
    self-intersecting or clockwise floor, walls too thick, openings outside their walls or overlapping."""
    n = room.n_corners
    c = room.corners()
    corner_at = "params"
    area = 0.5 * float(np.sum(c[:, 0] * np.roll(c[:, 1], -1) - np.roll(c[:, 0], -1) * c[:, 1]))
    w = room.walls()
    for i, length in enumerate(w["length"]):
        if length < MIN_SIZE_M:
            raise RoomError(f"room: wall {i} (corner {i} to corner {(i + 1) % n}) is {length:g} m long; walls are "
                            f"at least {MIN_SIZE_M:g} m", corner_at)
    if (pair := _self_intersection(c)) is not None:
        raise RoomError(f"room: the floor polygon intersects itself (walls {pair[0]} and {pair[1]} cross or "
                        "touch); corners must run round the room once", corner_at)
    if area <= 0:
        raise RoomError("room: the corners run clockwise seen from above; they must run counter-clockwise "
                        "(corner 1 on +x, the room on the left of each wall: make the first y coordinate positive)",
                        corner_at)
    span = w["outer_u"][:, 1] - w["outer_u"][:, 0]
    if np.any(span < MIN_SIZE_M):
        i = int(np.argmin(span))
        raise RoomError(f"room: thickness {room.param('thickness'):g} m is too large for its walls: the outer "
                        f"face of wall {i} would be {span[i]:g} m long", "params.thickness")
    if (pair := _self_intersection(w["outer"])) is not None:
        raise RoomError(f"room: thickness {room.param('thickness'):g} m is too large for its walls: the outer "
                        f"faces of walls {pair[0]} and {pair[1]} cross", "params.thickness")
    h = room.param("height")
    spans: dict[int, list[tuple[float, float, str]]] = {}
    for o in room.openings:
        off, width, oh, sill = (room.param(f"{o.name}_{s}") for s in ("offset", "width", "height", "sill"))
        lo = max(0.0, float(w["outer_u"][o.wall, 0]))
        hi = min(float(w["length"][o.wall]), float(w["outer_u"][o.wall, 1]))
        if width > hi - lo:
            raise RoomError(f"room: opening '{o.name}' is {width:g} m wide; wall {o.wall} has room for "
                            f"{hi - lo:g} m between its corners", f"params.{o.name}_width")
        if off < lo - 1e-12 or off + width > hi + 1e-12:
            raise RoomError(f"room: opening '{o.name}' ({off:g} to {off + width:g} m along wall {o.wall}) lies "
                            f"outside the wall, which runs {lo:g} to {hi:g} m (both faces)",
                            f"params.{o.name}_offset")
        if sill + oh > h + 1e-12:
            raise RoomError(f"room: opening '{o.name}' reaches {sill + oh:g} m (sill {sill:g} + height {oh:g}); "
                            f"the walls are {h:g} m high", f"params.{o.name}_height")
        spans.setdefault(o.wall, []).append((off, off + width, o.name))
    for wall, items in spans.items():
        items.sort()
        total = sum(b - a for a, b, _ in items)
        if total > float(w["length"][wall]):
            raise RoomError(f"room: wall {wall} is {float(w['length'][wall]):g} m long, shorter than its "
                            f"openings together ({total:g} m)", f"params.{items[0][2]}_width")
        for (_, b0, n0), (a1, _, n1) in zip(items, items[1:], strict=False):
            if a1 < b0:
                raise RoomError(f"room: openings '{n0}' and '{n1}' overlap on wall {wall} ('{n0}' ends at "
                                f"{b0:g} m, '{n1}' starts at {a1:g} m)", f"params.{n1}_offset")


def wall_presence(walls: Any, corners: int, openings: Iterable[Opening]) -> tuple[bool, ...]:
    """Which walls the room has (``walls``: N true or false, wall i from corner i; None: all of
    them); RoomError names ``walls`` where it is not that list, or where an opening is in a wall
    that is not there."""
    if walls is None:
        return (True,) * corners
    if isinstance(walls, str | bytes | Mapping) or not isinstance(walls, Iterable):
        raise RoomError(f"room: walls must be a list of {corners} true or false (one per wall, wall i from corner i), "
                        f"got {walls!r}", "walls")
    out = tuple(walls)
    if len(out) != corners or not all(isinstance(w, bool) for w in out):
        raise RoomError(f"room: walls must be a list of {corners} true or false (one per wall, wall i from corner i), "
                        f"got {list(out)!r}", "walls")
    if not any(out):
        raise RoomError("room: walls are all false: a room has at least one wall (a floor alone is a quad)", "walls")
    for k, o in enumerate(openings):
        if not out[o.wall]:
            raise RoomError(f"room: opening '{o.name}' is in wall {o.wall}, which the room does not have "
                            f"(walls[{o.wall}] is false)", f"openings[{k}].wall")
    return out


def structure(corners: Any, rectilinear: Any, ceiling: Any,
               openings: Iterable[Any]) -> tuple[int, bool, tuple[Opening, ...]]:
    """The room's structure checked: RoomError names ``corners``, ``rectilinear``, ``openings[i].…``."""
    if isinstance(corners, bool) or not isinstance(corners, int):
        raise RoomError(f"room: corners must be a whole number (how many corners the floor has), got {corners!r}",
                        "corners")
    if not isinstance(rectilinear, bool):
        raise RoomError(f"room: rectilinear must be true or false, got {rectilinear!r}", "rectilinear")
    if not isinstance(ceiling, bool):
        raise RoomError(f"room: ceiling must be true or false, got {ceiling!r}", "ceiling")
    if rectilinear and (corners < 4 or corners % 2):
        raise RoomError(f"room: a rectilinear room has an even number of corners, at least 4 (its walls alternate "
                        f"along x and y); got {corners}. Use \"rectilinear\": false for another polygon", "corners")
    if corners < 3:
        raise RoomError(f"room: a room has at least 3 corners, got {corners}", "corners")
    if corners > 1000:
        raise RoomError(f"room: at most 1000 corners, got {corners}", "corners")
    if isinstance(openings, str | bytes | Mapping) or not isinstance(openings, Iterable):
        raise RoomError(f"room: openings must be a list of {{name, wall, kind}}, got {type(openings).__name__}",
                        "openings")
    out: list[Opening] = []
    for k, o in enumerate(openings):
        at = f"openings[{k}]"
        name: Any
        wall: Any
        kind: Any
        if isinstance(o, Opening):
            name, wall, kind = o.name, o.wall, o.kind
        elif isinstance(o, Mapping):
            if extra := [x for x in o if x not in ("name", "wall", "kind")]:
                raise RoomError(f"room: opening {k} has an unknown field {extra[0]!r}; expected name, wall, kind",
                                f"{at}.{extra[0]}")
            name, wall, kind = o.get("name"), o.get("wall"), o.get("kind", "door")
        else:
            raise RoomError(f"room: opening {k} must be an object {{name, wall, kind}}, got {o!r}", at)
        if not isinstance(name, str) or not _OPENING_NAME.match(name):
            raise RoomError(f"room: opening {k}'s name {name!r} must start with a letter and hold only letters, "
                            "digits and _", f"{at}.name")
        if _RESERVED.match(name):
            raise RoomError(f"room: opening name {name!r} reads as one of the room's own names (corner params, "
                            "handles, edges, faces); choose another", f"{at}.name")
        if any(name == q.name for q in out):
            raise RoomError(f"room: opening name {name!r} is used twice; each opening needs its own", f"{at}.name")
        if isinstance(wall, bool) or not isinstance(wall, int) or not 0 <= wall < corners:
            raise RoomError(f"room: opening '{name}' is in wall {wall!r}; expected a wall 0…{corners - 1} (wall i runs "
                            "from corner i to corner i + 1)", f"{at}.wall")
        if kind not in OPENING_KINDS:
            raise RoomError(f"room: opening '{name}' has kind {kind!r}; expected one of {', '.join(OPENING_KINDS)}",
                            f"{at}.kind")
        out.append(Opening(name, wall, kind))
    return corners, rectilinear, tuple(out)
