"""A seeded L-shaped room to model by clicking (the modelling screen's Room, Opening and Box tools):
two of its six walls are missing (the photos are taken through the gap), a doorway in one wall and a
table (a box) on its floor. Its photos look down into the room from outside the missing walls, so
that one of them sees every floor corner; markers on the floor and walls and vanishing segments let
the photos be calibrated; the photos themselves are plain grey (calibration reads only the marks).

Room frame = world frame: the floor at z = 0, corner 0 at the origin marker O, corner 1 on +x,
corners counter-clockwise seen from above (FORMAT.md, the room primitive): (0, 0), (a, 0), (a, b),
(c, b), (c, d), (0, d). Wall i runs from corner i to corner i + 1; walls 4 and 5 (y = d and x = 0)
are the missing ones. Only tests and benchmarks import this module.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from . import (
    CLICK_NOISE_PX,
    SyntheticPhoto,
    add_segments,
    markers_in_two_photos,
    observe_markers,
    rotation,
    write_project,
)

Array = NDArray[np.float64]

#: The walls the room has (walls 4 and 5 are missing).
WALLS = (True, True, True, True, False, False)
#: The doorway: in this wall, this far from its corner, this wide and high (metres), on the floor.
DOOR_WALL, DOOR_OFFSET_M, DOOR_WIDTH_M, DOOR_HEIGHT_M = 1, 0.7, 0.9, 2.05
#: The photos' size (px) and horizontal field of view (degrees): a phone's main camera.
PHOTO_W, PHOTO_H, FOV_DEG = 1600, 1200, 66.0


@dataclass
class ClickRoom:
    """The truth: corners (6, 2), wall height, the doorway on DOOR_WALL, the table (centre on the
    floor, yaw in degrees, width × depth × height), the photos and markers."""

    corners: Array
    height: float
    table_centre: Array
    table_yaw_deg: float
    table_size: Array
    photos: list[SyntheticPhoto] = field(default_factory=list)
    markers: dict[str, Array] = field(default_factory=dict)

    def params(self) -> dict[str, float]:
        """The room primitive's params of the truth (FORMAT.md), the doorway named ``door``."""
        c = self.corners
        return {"c1_x": float(c[1, 0]), "c2_y": float(c[2, 1]), "c3_x": float(c[3, 0]), "c4_y": float(c[4, 1]),
                "height": self.height, "door_offset": DOOR_OFFSET_M, "door_width": DOOR_WIDTH_M,
                "door_height": DOOR_HEIGHT_M, "door_sill": 0.0}

    def table_corners(self) -> Array:
        """The table's (4, 3) bottom corners then its (4, 3) top corners, counter-clockwise from
        (−w/2, −d/2) in its own frame (as the box primitive's v0…v7)."""
        w, d, h = self.table_size
        a = np.radians(self.table_yaw_deg)
        R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        ring = np.array([[-w / 2, -d / 2], [w / 2, -d / 2], [w / 2, d / 2], [-w / 2, d / 2]]) @ R.T + self.table_centre
        return np.vstack([np.column_stack([ring, np.zeros(4)]), np.column_stack([ring, np.full(4, h)])])

    def door_points(self) -> dict[str, Array]:
        """The doorway's start and end feet (``sb``, ``eb``) and tops (``st``, ``et``) on the wall's
        inner face (world)."""
        c = self.corners
        a, b = c[DOOR_WALL], c[(DOOR_WALL + 1) % 6]
        u = (b - a) / np.linalg.norm(b - a)
        s, e = a + u * DOOR_OFFSET_M, a + u * (DOOR_OFFSET_M + DOOR_WIDTH_M)
        return {"sb": np.r_[s, 0.0], "eb": np.r_[e, 0.0], "st": np.r_[s, DOOR_HEIGHT_M], "et": np.r_[e, DOOR_HEIGHT_M]}

    def write(self, folder: Path) -> Path:
        """The project (grey photos, their marks, the scale distance), uncalibrated; its path."""
        return write_project(folder, self.photos, self.markers)


def _look(C: Array, target: Array) -> Array:
    d = target - C
    return rotation(float(np.arctan2(d[1], d[0])), float(np.arctan2(d[2], np.hypot(d[0], d[1]))), 0.0)


def click_room(rng: np.random.Generator, noise_px: float = CLICK_NOISE_PX) -> ClickRoom:
    """The room drawn from ``rng`` (sizes a few tens of centimetres either way), three photos from
    outside its missing walls, 2.6–3 m up, looking down into it, and the markers each photo marks
    (those seen in two photos or more; marks with ``noise_px`` 1σ)."""
    a, b = rng.uniform(4.6, 5.4), rng.uniform(2.3, 2.7)
    c, d = rng.uniform(2.3, 2.7), rng.uniform(3.8, 4.3)
    corners = np.array([[0, 0], [a, 0], [a, b], [c, b], [c, d], [0, d]], float)
    room = ClickRoom(corners, float(rng.uniform(2.45, 2.75)), np.array([rng.uniform(1.2, 1.6), rng.uniform(1.0, 1.3)]),
                     float(rng.uniform(10.0, 25.0)), np.array([1.2, 0.8, 0.75]))
    markers: dict[str, Array] = {"O": np.zeros(3)}
    for k in range(1, 9):  # on the floor, in the room's lower arm
        markers[f"M{k}"] = np.array([rng.uniform(0.3, a - 0.3), rng.uniform(0.3, b - 0.3), 0.0])
    for k in range(9, 13):  # on wall 1's and wall 0's inner faces
        markers[f"M{k}"] = (np.array([a, rng.uniform(0.2, b - 0.2), rng.uniform(0.3, 2.0)]) if k % 2 else
                            np.array([rng.uniform(0.5, a - 0.5), 0.0, rng.uniform(0.3, 2.0)]))
    f = PHOTO_W / (2 * np.tan(np.radians(FOV_DEG / 2)))
    K = np.array([[f, 0, PHOTO_W / 2], [0, f, PHOTO_H / 2], [0, 0, 1.0]])
    target = np.array([0.5 * a, 0.45 * d, 0.0])
    views = [np.array([-3.6, 0.5 * d + rng.uniform(-0.3, 0.3), rng.uniform(2.6, 3.0)]),
             np.array([-2.8, d + 1.2 + rng.uniform(-0.3, 0.3), rng.uniform(2.6, 3.0)]),
             np.array([-2.6, -0.8 + rng.uniform(-0.3, 0.3), rng.uniform(2.6, 3.0)])]
    for k, C in enumerate(views):
        cam = SyntheticPhoto(f"p{k + 1}", "3vp", PHOTO_W, PHOTO_H, K.copy(), _look(C, target), C)
        cam.exif_focal_px = float(f)
        observe_markers(cam, markers, rng, noise_px)
        add_segments(cam, rng, noise_px)
        room.photos.append(cam)
    room.markers = markers_in_two_photos(room.photos, markers)
    return room
