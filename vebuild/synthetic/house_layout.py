"""The generated house's rooms, doorways, furniture and markers (vebuild.synthetic.house marks
them): FORMAT.md nodes in a scene graph, every primitive placed in its room's own frame; and
:func:`house_scene`, the whole house: drawn here, then photographed and marked there.

Rooms (r, c) of a grid, room ``room{r * cols + c}``: inner widths 4.4–5.6 m per column, depths
4.2–5.2 m per row, HEIGHT_M high, walls THICKNESS_M (a party wall is two walls back to back). The
doorways of the spanning tree: room (r, c) to (r, c + 1) on the first row (openings ``east`` on
wall 1 and ``west`` on wall 3), room (r, c) to (r + 1, c) (``north`` on wall 2, ``south`` on wall 0).
Four markers at each doorway (two taped crosses on its threshold, two under its head, mid-wall),
seen from both rooms; twelve on each room's walls, four taped on its floor; O at room0's corner f0.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from . import CLICK_NOISE_PX
from .house import DOOR_HEIGHT_M, DOOR_WIDTH_M, HEIGHT_M, THICKNESS_M, Door, House, Room, guessed_nodes, photograph

#: Floor clear in front of a doorway (along the wall, into the room), metres.
DOOR_CLEAR_M = (1.3, 0.8)
#: Steps of the stairwell's flight: count, rise, going, width (metres).
STEPS, RISE_M, GOING_M, STAIR_WIDTH_M = 12, 0.18, 0.27, 0.95


class _Floor:
    """Footprints taken on a room's floor (room frame), each with its height."""

    def __init__(self, size: tuple[float, float]) -> None:
        self.size = np.array(size)
        self.rects: list[tuple[float, float, float, float, float]] = []

    def free(self, x0: float, y0: float, x1: float, y1: float, gap: float = 0.12, margin: float = 0.05) -> bool:
        if x0 < margin or y0 < margin or x1 > self.size[0] - margin or y1 > self.size[1] - margin:
            return False
        return all(x1 + gap <= a or x0 - gap >= c or y1 + gap <= b or y0 - gap >= d for a, b, c, d, _ in self.rects)

    def take(self, x0: float, y0: float, x1: float, y1: float, h: float) -> None:
        self.rects.append((x0, y0, x1, y1, h))


def _node(name: str, parent: str, kind: str, params: dict[str, float], pos: Any, yaw: float = 0.0,
          face: str = "floor") -> dict[str, Any]:
    prim = {"type": kind, "params": {k: float(v) for k, v in params.items()}}
    return {"name": name, "parent": parent, "primitive": prim,
            "joint": {"type": "rests_on", "face": face, "position": [float(pos[0]), float(pos[1])],
                      "yaw_deg": float(yaw)}}


def _box(w: float, d: float, h: float) -> dict[str, float]:
    return {"width": w, "depth": d, "height": h}


def _rot(yaw_deg: float) -> np.ndarray:
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    return np.array([[c, -s], [s, c]])


class _Furnisher:
    """Places one room's furniture (nodes in the room's frame) on its floor."""

    def __init__(self, rng: np.random.Generator, room: Room, nodes: list[dict[str, Any]], node_room: dict[str, str]):
        self.rng, self.room, self.nodes, self.node_room = rng, room, nodes, node_room
        self.floor = _Floor(room.size)
        self.k = 0
        W, D = room.size
        along, into = DOOR_CLEAR_M
        for wall, offset in room.openings.values():
            c = offset + DOOR_WIDTH_M / 2
            rect = {0: (c - along / 2, 0, c + along / 2, into), 1: (W - into, c - along / 2, W, c + along / 2),
                    2: (W - c - along / 2, D - into, W - c + along / 2, D),
                    3: (0, D - c - along / 2, into, D - c + along / 2)}
            self.floor.take(*rect[wall], 0.0)
        if room.name == "room0":
            self.floor.take(0.0, 0.0, 0.9, 0.9, 0.0)  # the origin marker's corner stays clear

    def add(self, kind: str, params: dict[str, float], pos: Any, yaw: float = 0.0, parent: str | None = None,
            face: str = "floor", label: str = "") -> str:
        self.k += 1
        name = f"{self.room.name}_{label or kind}{self.k}"
        self.nodes.append(_node(name, parent or self.room.name, kind, params, pos, yaw, face))
        self.node_room[name] = self.room.name
        return name

    def spot(self, w: float, d: float, h: float, yaw: float, against: bool = False,
             tries: int = 1000) -> tuple[np.ndarray, float] | None:
        """A free footprint w × d (rotated by yaw, a multiple of 90°) for a thing h high: anywhere, or
        with its back (+y) against a wall (its yaw then set by the wall). Its centre and yaw."""
        W, D = self.room.size
        for _ in range(tries):
            if against:
                wall = int(self.rng.integers(4))
                yaw = (180.0, -90.0, 0.0, 90.0)[wall]
                fw, fd = (w, d) if wall in (0, 2) else (d, w)
                along = self.rng.uniform(0.1 + (fw if wall in (0, 2) else fd) / 2,
                                         (W if wall in (0, 2) else D) - 0.1 - (fw if wall in (0, 2) else fd) / 2)
                c = {0: (along, fd / 2 + 0.005), 1: (W - fw / 2 - 0.005, along), 2: (along, D - fd / 2 - 0.005),
                     3: (fw / 2 + 0.005, along)}[wall]
                gap = 0.0
            else:
                fw, fd = (w, d) if round(yaw / 90.0) % 2 == 0 else (d, w)
                c = (self.rng.uniform(fw / 2 + 0.4, W - fw / 2 - 0.4), self.rng.uniform(fd / 2 + 0.4, D - fd / 2 - 0.4))
                gap = 0.3
            rect = (c[0] - fw / 2, c[1] - fd / 2, c[0] + fw / 2, c[1] + fd / 2)
            if self.floor.free(*rect, gap=gap, margin=0.0 if against else 0.05):
                self.floor.take(*rect, h)
                return np.array(c), yaw
        return None

    def legs_and_top(self, centre: np.ndarray, yaw: float, w: float, d: float, h: float, leg: float, top_h: float,
                     label: str) -> str:
        """Four legs on the floor at the corners (inset) and a top resting on the first leg."""
        R = _rot(yaw)
        corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
        legs = []
        for sx, sy in corners:
            p = centre + R @ np.array([sx * (w / 2 - leg / 2 - 0.03), sy * (d / 2 - leg / 2 - 0.03)])
            legs.append((self.add("box", _box(leg, leg, h - top_h), p, yaw, label=f"{label}leg"), p))
        first, p0 = legs[0]
        rel = R.T @ (centre - p0)
        return self.add("box", _box(w, d, top_h), rel, 0.0, parent=first, face="top", label=f"{label}top")

    def table_group(self) -> None:
        w, d = float(self.rng.uniform(1.1, 1.6)), float(self.rng.uniform(0.75, 0.95))
        yaw = float(self.rng.choice([0.0, 90.0]))
        spot = self.spot(w + 1.1, d + 1.1, 0.9, yaw)
        if spot is None:
            return
        c, yaw = spot
        top = self.legs_and_top(c, yaw, w, d, 0.74, 0.06, 0.04, "table")
        for _ in range(3):
            bw, bd = self.rng.uniform(0.15, 0.25), self.rng.uniform(0.1, 0.2)
            self.add("box", _box(bw, bd, self.rng.uniform(0.03, 0.06)),
                     self.rng.uniform([-w / 2 + 0.2, -d / 2 + 0.15], [w / 2 - 0.2, d / 2 - 0.15]),
                     self.rng.uniform(-40, 40), parent=top, face="top", label="book")
        r = float(self.rng.uniform(0.08, 0.12))
        self.add("sphere", {"radius": r}, self.rng.uniform([-w / 2 + 0.2, -d / 2 + 0.2], [w / 2 - 0.2, d / 2 - 0.2]),
                 0.0, parent=top, face="top", label="ball")
        R = _rot(yaw)
        seats = [(x, -1) for x in (-w / 4, w / 4)] + [(x, 1) for x in (-w / 4, w / 4)] + [(-1, 0), (1, 0)]
        for sx, sy in seats:
            if sy == 0:  # at the ends, facing the table along its x
                p, cy = np.array([sx * (w / 2 + 0.3), 0.0]), yaw + (90.0 if sx > 0 else -90.0)
            else:
                p, cy = np.array([sx, sy * (d / 2 + 0.3)]), yaw + (0.0 if sy < 0 else 180.0)
            self.chair(c + R @ p, cy + float(self.rng.uniform(-6.0, 6.0)))

    def chair(self, centre: np.ndarray, yaw: float) -> None:
        """A chair facing +y in its frame turned yaw: four legs, a seat on the first, a back on the seat
        (at its far side: a chair south of a table, yaw 0, faces north)."""
        s = 0.42
        seat = self.legs_and_top(centre, yaw, s, s, 0.46, 0.035, 0.03, "chair")
        self.add("box", _box(s, 0.03, 0.42), [0.0, -(s / 2 - 0.015)], 0.0, parent=seat, face="top", label="chairback")

    def desk(self) -> None:
        """A desk against a wall (legs and a top) and a chair in front of it."""
        w, d = float(self.rng.uniform(1.0, 1.4)), 0.6
        spot = self.spot(w, d + 0.75, 0.8, 0.0, against=True)
        if spot is None:
            return
        c, yaw = spot
        R = _rot(yaw)
        self.legs_and_top(c + R @ np.array([0.0, 0.375]), yaw, w, d, 0.74, 0.05, 0.03, "desk")
        self.chair(c + R @ np.array([0.0, -0.33]), yaw + float(self.rng.uniform(-8.0, 8.0)))

    def against_wall(self, label: str, w: float, d: float, h: float) -> None:
        spot = self.spot(w, d, h, 0.0, against=True)
        if spot is not None:
            self.add("box", _box(w, d, h), spot[0], spot[1], label=label)

    def sofa(self) -> None:
        w, d = float(self.rng.uniform(1.6, 2.0)), 0.85
        spot = self.spot(w, d, 0.85, 0.0, against=True)
        if spot is None:
            return
        base = self.add("box", _box(w, d, 0.42), spot[0], spot[1], label="sofa")
        self.add("box", _box(w, 0.2, 0.42), [0.0, (d - 0.2) / 2], 0.0, parent=base, face="top", label="sofaback")
        for sx in (-1, 1):
            self.add("box", _box(0.18, d - 0.2, 0.22), [sx * (w / 2 - 0.09), -0.1], 0.0, parent=base, face="top",
                     label="sofaarm")

    def lamp(self) -> None:
        spot = self.spot(0.45, 0.45, 1.7, 0.0)
        if spot is None:
            return
        base = self.add("cylinder", {"radius": 0.16, "height": 0.04}, spot[0], 0.0, label="lampbase")
        pole = self.add("cylinder", {"radius": 0.02, "height": 1.3}, [0.0, 0.0], 0.0, parent=base, face="top",
                        label="lamppole")
        self.add("frustum", {"radius_bottom": 0.2, "radius_top": 0.12, "height": 0.25}, [0.0, 0.0], 0.0, parent=pole,
                 face="top", label="lampshade")

    def plant(self) -> None:
        spot = self.spot(0.55, 0.55, 0.85, 0.0)
        if spot is None:
            return
        pot = self.add("frustum", {"radius_bottom": 0.12, "radius_top": 0.17, "height": 0.35}, spot[0], 0.0,
                       label="pot")
        self.add("sphere", {"radius": 0.25}, [0.0, 0.0], 0.0, parent=pot, face="top", label="foliage")

    def crate(self, stack: bool) -> None:
        w, d, h = (float(v) for v in self.rng.uniform([0.3, 0.3, 0.25], [0.6, 0.6, 0.5]))
        yaw = float(self.rng.choice([0.0, 90.0]))
        spot = self.spot(w, d, 2 * h, yaw)
        if spot is None:
            return
        first = self.add("box", _box(w, d, h), spot[0], spot[1], label="crate")
        if stack:
            self.add("box", _box(w * 0.8, d * 0.8, h * 0.8), self.rng.uniform(-0.03, 0.03, 2), 0.0, parent=first,
                     face="top", label="crate")

    def free_standing(self, kind: str, params: dict[str, float], size: float, h: float, label: str) -> None:
        yaw = float(self.rng.choice([0.0, 90.0]))
        spot = self.spot(size, size, h, yaw)
        if spot is not None:
            self.add(kind, params, spot[0], spot[1] + float(self.rng.uniform(-20, 20)), label=label)

    def stairs(self) -> bool:
        """A straight flight against the north wall (wall 2), rising toward +x: STEPS boxes."""
        W, D = self.room.size
        run = STEPS * GOING_M
        x0 = float(self.rng.uniform(0.3, W - 0.3 - run))
        rect = (x0, D - STAIR_WIDTH_M - 0.005, x0 + run, D)
        if not self.floor.free(*rect, gap=0.1, margin=0.0):
            return False
        self.floor.take(*rect, STEPS * RISE_M)
        for k in range(STEPS):
            self.add("box", _box(GOING_M, STAIR_WIDTH_M, RISE_M * (k + 1)),
                     [x0 + (k + 0.5) * GOING_M, D - STAIR_WIDTH_M / 2 - 0.005], 0.0, label="step")
        return True

    def furnish(self, furniture: str, stairwell: bool) -> None:
        rng = self.rng
        if stairwell:
            self.stairs()
        else:
            self.table_group()
        if furniture == "few":
            self.against_wall("cabinet", float(rng.uniform(0.8, 1.2)), float(rng.uniform(0.4, 0.6)),
                              float(rng.uniform(0.8, 2.0)))
            self.crate(False)
            return
        for _ in range(2):
            self.against_wall("cabinet", float(rng.uniform(0.8, 1.2)), float(rng.uniform(0.4, 0.6)),
                              float(rng.uniform(0.8, 2.0)))
        self.against_wall("shelf", 1.0, 0.35, 1.9)
        self.desk()
        self.sofa()
        self.lamp()
        self.plant()
        for k in range(4):
            self.crate(stack=k % 2 == 0)
        for _ in range(2):
            self.free_standing("wedge", _box(0.3, 0.45, 0.2), 0.5, 0.2, "wedge")
            self.free_standing("cylinder", {"radius": 0.17, "height": 0.45}, 0.4, 0.45, "stool")


def _room_node(room: Room, params_openings: list[tuple[str, int, float]]) -> dict[str, Any]:
    W, D = room.size
    params = {"c1_x": W, "c2_y": D, "height": HEIGHT_M, "thickness": THICKNESS_M}
    for name, _, offset in params_openings:
        params.update({f"{name}_offset": offset, f"{name}_width": DOOR_WIDTH_M, f"{name}_height": DOOR_HEIGHT_M,
                       f"{name}_sill": 0.0})
    prim = {"type": "room", "corners": 4, "rectilinear": True, "ceiling": room.ceiling,
            "params": {k: float(v) for k, v in params.items()},
            "openings": [{"name": n, "wall": w, "kind": "door"} for n, w, _ in params_openings]}
    return {"name": room.name, "primitive": prim}


def furnished_house(rng: np.random.Generator, rows: int, cols: int, furniture: str = "full",
                    stairwell: bool = True) -> House:
    """The house's rooms, doorways, furniture and markers (module docstring); no photos yet."""
    if furniture not in ("full", "few"):
        raise ValueError(f"furniture is 'full' or 'few', not {furniture!r}")
    widths = rng.uniform(4.4, 5.6, cols)
    depths = rng.uniform(4.2, 5.2, rows)
    t2 = 2 * THICKNESS_M
    rooms: dict[str, Room] = {}
    for r in range(rows):
        for c in range(cols):
            origin = np.array([sum(widths[:c]) + c * t2, sum(depths[:r]) + r * t2, 0.0])
            name = f"room{r * cols + c}"
            rooms[name] = Room(name, (r, c), (float(widths[c]), float(depths[r])), origin)
    last = f"room{rows * cols - 1}"
    if stairwell:
        rooms[last].ceiling = False  # open above the flight
    doors: list[Door] = []
    joints: dict[str, dict[str, Any]] = {"room0": {"type": "marker", "marker": "O", "handle": "f0", "yaw_deg": 0.0}}
    parents: dict[str, str] = {}
    for r in range(rows):
        for c in range(cols):
            child = rooms[f"room{r * cols + c}"]
            if r == 0 and c == 0:
                continue
            if r == 0:
                parent = rooms[f"room{c - 1}"]
                W, D = parent.size
                y = float(rng.uniform(1.0, D - 1.0))
                a = y - DOOR_WIDTH_M / 2
                parent.openings["east"] = (1, a)
                child.openings["west"] = (3, D - a - DOOR_WIDTH_M)
                doors.append(Door(parent.name, "east", child.name, "west",
                                  parent.origin + np.array([W + THICKNESS_M, y, 0]), 0))
                joints[child.name] = {"type": "through", "opening": "east", "own_opening": "west"}
            else:
                parent = rooms[f"room{(r - 1) * cols + c}"]
                W, D = parent.size
                x = float(rng.uniform(1.0, W - 1.0))
                parent.openings["north"] = (2, W - x - DOOR_WIDTH_M / 2)
                child.openings["south"] = (0, x - DOOR_WIDTH_M / 2)
                doors.append(Door(parent.name, "north", child.name, "south",
                                  parent.origin + np.array([x, D + THICKNESS_M, 0]), 1))
                joints[child.name] = {"type": "through", "opening": "north", "own_opening": "south"}
            parents[child.name] = parent.name
    nodes: list[dict[str, Any]] = []
    node_room: dict[str, str] = {}
    for room in rooms.values():
        node = _room_node(room, [(n, w, o) for n, (w, o) in room.openings.items()])
        node["joint"] = joints[room.name]
        if room.name in parents:
            node["parent"] = parents[room.name]
        nodes.append(node)
        node_room[room.name] = room.name
    furnishers = {}
    for room in rooms.values():
        f = _Furnisher(rng, room, nodes, node_room)
        f.furnish(furniture, stairwell and room.name == last)
        furnishers[room.name] = f
    house = House(nodes, rooms, doors, node_room)
    _markers(rng, house, furnishers)
    return house


def _markers(rng: np.random.Generator, house: House, furnishers: dict[str, _Furnisher], n_wall: int = 12,
             n_floor: int = 4) -> None:
    """O, four markers per doorway, n_wall on each room's walls (clear of its doorways and of what
    stands against them), n_floor taped on its floor."""
    house.markers["O"] = np.zeros(3)
    house.marker_rooms["O"] = {"room0"}
    for k, d in enumerate(house.doors):
        along = np.eye(3)[1 - d.axis]
        head = d.centre + np.array([0.0, 0.0, DOOR_HEIGHT_M])
        for tag, X in (("a", d.centre - along * DOOR_WIDTH_M / 4), ("b", d.centre + along * DOOR_WIDTH_M / 4),
                       ("c", head - along * DOOR_WIDTH_M / 4), ("d", head + along * DOOR_WIDTH_M / 4)):
            house.markers[f"D{k + 1}{tag}"] = X
            house.marker_rooms[f"D{k + 1}{tag}"] = {d.a, d.b}
    for i, (name, room) in enumerate(house.rooms.items()):
        floor = furnishers[name].floor
        W, D = room.size
        k = 0
        for _ in range(500):
            if k >= n_wall:
                break
            wall = int(rng.integers(4))
            s = float(rng.uniform(0.3, (W if wall in (0, 2) else D) - 0.3))
            z = float(rng.uniform(0.3, 2.2))
            xy = {0: (s, 0.0), 1: (W, s), 2: (W - s, D), 3: (0.0, D - s)}[wall]
            if any(w == wall and o - 0.15 < s < o + DOOR_WIDTH_M + 0.15 for w, o in room.openings.values()):
                continue
            if any(a - 0.15 < xy[0] < c + 0.15 and b - 0.15 < xy[1] < d + 0.15 and z < h + 0.15
                   for a, b, c, d, h in floor.rects if h > 0):
                continue
            k += 1
            house.markers[f"M{i}_{k}"] = np.r_[room.origin[:2] + np.array(xy), z]
            house.marker_rooms[f"M{i}_{k}"] = {name}
        for _ in range(500):
            if k >= n_wall + n_floor:
                break
            spot = rng.uniform(0.5, np.array(room.size) - 0.5)
            if not floor.free(spot[0] - 0.1, spot[1] - 0.1, spot[0] + 0.1, spot[1] + 0.1, gap=0.1):
                continue
            k += 1
            house.markers[f"M{i}_{k}"] = np.r_[room.origin[:2] + spot, 0.0]
            house.marker_rooms[f"M{i}_{k}"] = {name}


#: Houses drawn (from the same stream) before giving up: a drawn house whose photos calibration
#: could not place one after another is drawn again.
HOUSE_ATTEMPTS = 5


def house_scene(rng: np.random.Generator, rows: int = 2, cols: int = 4, per_room: int = 13, width: int = 6000,
                height: int = 4000, furniture: str = "full", stairwell: bool = True,
                noise_px: float = CLICK_NOISE_PX) -> House:
    """A generated house (vebuild.synthetic.house's docstring): the rooms, their furniture and
    markers drawn here, photographed and marked there, and a first guess. RuntimeError where the
    draw cannot be photographed."""
    for _ in range(HOUSE_ATTEMPTS):
        house = furnished_house(rng, rows, cols, furniture, stairwell)
        try:
            photograph(rng, house, per_room, width, height, noise_px)
        except RuntimeError:
            continue
        house.guess = guessed_nodes(rng, house)
        return house
    raise RuntimeError(f"no house drawn in {HOUSE_ATTEMPTS} tries could be photographed so that calibration "
                       "places every photo")
