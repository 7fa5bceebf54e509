"""A small furnished room for the viewer's tests: walls with a doorway, a door on a hinge, a box
resting on the floor, a cabinet with a drawer on a runner, a table made of a group. Known
geometry, no photos (the viewer draws it untextured)."""

from __future__ import annotations

import json
from pathlib import Path

ROOM_X, ROOM_Y, WALL_H, WALL_T = 6.0, 5.0, 2.5, 0.1
DOOR_LIMITS_DEG = (0.0, 100.0)
DRAWER_LIMITS = (0.0, 0.35)


def _wall(name, cx, cy, w, d, h=WALL_H, z=0.0):
    # Walls are fixed to the floor (its frame's origin is the room's centre on the floor).
    return {"name": name, "parent": "floor", "primitive": {"type": "box", "params": {"width": w, "depth": d,
                                                                                     "height": h}},
            "joint": {"type": "fixed", "translation": [cx - ROOM_X / 2, cy - ROOM_Y / 2, z],
                      "rotation_deg": [0, 0, 0]}}


def nodes() -> list[dict]:
    t = WALL_T
    return [
        {"name": "floor", "primitive": {"type": "quad", "params": {"width": ROOM_X, "depth": ROOM_Y}},
         "joint": {"type": "fixed", "translation": [ROOM_X / 2, ROOM_Y / 2, 0.0], "rotation_deg": [0, 0, 0]}},
        _wall("wall.south", ROOM_X / 2, -t / 2, ROOM_X + 2 * t, t),
        _wall("wall.north", ROOM_X / 2, ROOM_Y + t / 2, ROOM_X + 2 * t, t),
        _wall("wall.west", -t / 2, ROOM_Y / 2, t, ROOM_Y),
        # The east wall has a doorway from y = 2 to y = 3, 2.1 m high.
        _wall("wall.east.1", ROOM_X + t / 2, 1.0, t, 2.0),
        _wall("wall.east.2", ROOM_X + t / 2, 4.0, t, 2.0),
        _wall("wall.east.lintel", ROOM_X + t / 2, 2.5, t, 1.0, h=WALL_H - 2.1, z=2.1),
        {"name": "box", "parent": "floor", "primitive": {"type": "box", "params": {"width": 0.6, "depth": 0.4,
                                                                                   "height": 0.5}},
         "joint": {"type": "rests_on", "face": "top", "position": [-1.0, -0.5], "yaw_deg": 0.0}},
        # The door closes the doorway; its hinge is at (5.98, 2.05), it opens into the room.
        {"name": "door", "parent": "floor", "primitive": {"type": "box", "params": {"width": 0.9, "depth": 0.04,
                                                                                    "height": 2.0}},
         "joint": {"type": "hinge", "axis_point": [5.98 - ROOM_X / 2, 2.05 - ROOM_Y / 2, 0.0], "axis": [0, 0, 1],
                   "translation": [5.98 - ROOM_X / 2, 2.5 - ROOM_Y / 2, 0.0], "rotation_deg": [0, 0, 90],
                   "angle_deg": 10.0, "limits_deg": list(DOOR_LIMITS_DEG)}},
        {"name": "cabinet", "parent": "floor", "primitive": {"type": "box", "params": {"width": 0.6, "depth": 0.5,
                                                                                       "height": 0.9}},
         "joint": {"type": "rests_on", "face": "top", "position": [1.0 - ROOM_X / 2, 4.7 - ROOM_Y / 2],
                   "yaw_deg": 0.0}},
        {"name": "drawer", "parent": "cabinet", "primitive": {"type": "box", "params": {"width": 0.5, "depth": 0.45,
                                                                                        "height": 0.2}},
         "joint": {"type": "slider", "axis": [0, -1, 0], "translation": [0, 0, 0.6], "rotation_deg": [0, 0, 0],
                   "offset": 0.0, "limits": list(DRAWER_LIMITS)}},
        {"name": "table", "parent": "floor", "joint": {"type": "rests_on", "face": "top",
                                                       "position": [0.2, 1.0], "yaw_deg": 0.0}},
        {"name": "table.top", "parent": "table", "primitive": {"type": "box", "params": {"width": 1.2, "depth": 0.8,
                                                                                        "height": 0.04}},
         "joint": {"type": "fixed", "translation": [0, 0, 0.72], "rotation_deg": [0, 0, 0]}},
        {"name": "table.leg", "parent": "table", "primitive": {"type": "box", "params": {"width": 0.05,
                                                                                        "depth": 0.05,
                                                                                        "height": 0.72}},
         "joint": {"type": "fixed", "translation": [0, 0, 0], "rotation_deg": [0, 0, 0]}},
    ]


VIEWS = [
    {"name": "entrance", "position": [5.2, 2.5, 1.6], "look_at": [0.0, 2.5, 0.6], "fov_deg": 75.0,
     "width": 640, "height": 360},
    {"name": "facing the west wall", "position": [1.0, 1.0, 1.6], "direction": [-1.0, 0.0, 0.0],
     "fov_deg": 75.0, "width": 640, "height": 360},
    {"name": "at the box", "position": [3.2, 1.3, 1.6], "look_at": [2.0, 2.0, 0.25], "fov_deg": 75.0,
     "width": 640, "height": 360},
    {"name": "at the door", "position": [3.8, 3.4, 1.6], "look_at": [6.0, 2.4, 1.0], "fov_deg": 75.0,
     "width": 640, "height": 360},
]


def write_project(folder: Path, with_model: bool = True) -> Path:
    data = {"format": "vebuild-project", "version": 1, "name": "viewer test room", "photos": [], "markers": [],
            "reference_distances": [], "views": VIEWS,
            "lighting": {"presets": [{"name": "lamp", "ambient": [0.1, 0.1, 0.1],
                                      "lights": [{"type": "point", "position": [3.0, 2.5, 2.3], "intensity": 3.0}]}]}}
    if with_model:
        data["model"] = {"nodes": nodes()}
    path = folder / "viewer.vebuild.json"
    path.write_text(json.dumps(data, indent=1))
    return path
