"""What the modelling screen calls a primitive's corners and faces: where they are in the room as
seen from a camera, rather than the names the project file stores (v0…v7, a box's "front" fixed
to its own axes however the user turned it).

A face is named by the world direction of its outward normal (oriented away from the primitive's
centre, so that a room's inward walls are named as a box's are): ``top`` or ``bottom`` where the
normal is mostly up or down, else ``front`` (toward the camera), ``back``, ``left`` or ``right``
(the camera's right, level with the floor). A corner is named by the side of the primitive's
centre it lies on along those three directions: ``front-left-bottom``. The stored name is always
shown beside it (``front-left-bottom · v3``), so that a name in the file can be found on screen;
the file keeps its names.

Plain numpy over world points; no GL."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: A face whose outward normal is within this many degrees of straight up or down is top or bottom.
LEVEL_FACE_DEG = 45.0
#: A corner's offset from the centre along a direction shorter than this share of the primitive's
#: extent along it says neither side (a cylinder's rim point straight in front has no left or right).
CORNER_SIDE_SHARE = 0.1


def view_axes(R: Array | None) -> tuple[Array, Array, Array]:
    """(toward the camera, the camera's right, up), unit world vectors, level with the floor but
    up; without a camera (R None) the world's −y, +x and +z (a plan seen from the front)."""
    up = np.array([0.0, 0.0, 1.0])
    if R is None:
        return np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0]), up
    forward = np.asarray(R, float)[2]  # the camera's viewing direction in the world
    f = forward - (forward @ up) * up
    if np.linalg.norm(f) < 1e-6:  # looking straight down or up: the image's up is "back"
        f = -np.asarray(R, float)[1]
        f = f - (f @ up) * up
    f = f / np.linalg.norm(f)
    return -f, np.cross(f, up), up


def face_direction(normal: Sequence[float], centre_offset: Sequence[float], R: Array | None) -> str:
    """The name of a face's direction: its normal (any sense), turned away from the primitive's
    centre (``centre_offset``: the face's centroid less the primitive's), in the words above."""
    n = np.asarray(normal, float)
    n = n / max(float(np.linalg.norm(n)), 1e-12)
    if n @ np.asarray(centre_offset, float) < 0:
        n = -n
    toward, right, up = view_axes(R)
    if abs(n @ up) >= np.cos(np.radians(LEVEL_FACE_DEG)):
        return "top" if n @ up > 0 else "bottom"
    a, b = n @ toward, n @ right
    if abs(a) >= abs(b):
        return "front" if a > 0 else "back"
    return "right" if b > 0 else "left"


def corner_directions(points: Array, R: Array | None) -> list[str]:
    """Each corner's place about the centre of the corners (n, 3): ``front-left-bottom`` and the
    like (a direction left out where the corner is near the centre along it)."""
    P = np.asarray(points, float).reshape(-1, 3)
    c = 0.5 * (P.min(axis=0) + P.max(axis=0))
    out = []
    axes = view_axes(R)
    words = (("front", "back"), ("right", "left"), ("top", "bottom"))
    proj = (P - c) @ np.stack(axes).T  # (n, 3): along toward, right, up
    extent = np.maximum(proj.max(axis=0) - proj.min(axis=0), 1e-9)
    for row in proj:
        parts = [words[k][0 if row[k] > 0 else 1] for k in range(3) if abs(row[k]) > CORNER_SIDE_SHARE * extent[k]]
        out.append("-".join(parts) if parts else "centre")
    return out


def shown(place: str, stored: str) -> str:
    """What the screen shows for a corner or face: its place, and the name the file stores."""
    return stored if place == stored else f"{place} · {stored}"


def face_places(triangles: Array, face_ids: NDArray[np.intp], names: Sequence[str], R: Array | None) -> dict[str, str]:
    """Each logical face's place name (stored name → place) from its world triangles (t, 3, 3) and
    their 1-based logical face ids; a face whose place another face has too keeps the place with
    its stored name (a cylinder's many sides are ``side``)."""
    tri = np.asarray(triangles, float)
    centre = 0.5 * (tri.reshape(-1, 3).min(axis=0) + tri.reshape(-1, 3).max(axis=0))
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # twice the area, along the normal
    out = {}
    for k, name in enumerate(names):
        sel = np.asarray(face_ids) == k + 1
        if not np.any(sel):
            continue
        n = cross[sel].sum(axis=0)
        offset = tri[sel].reshape(-1, 3).mean(axis=0) - centre
        if np.linalg.norm(n) < 1e-12 or np.linalg.norm(offset) < 1e-9:
            out[name] = name  # a curved side all round: no one direction
            continue
        out[name] = face_direction(n, offset, R)
    return out


def facing(triangles: Array, face_ids: NDArray[np.intp], names: Sequence[str], C: Array) -> set[str]:
    """The logical faces whose outward side (away from the primitive's centre) faces the camera at
    C: those a camera can see unless something stands in front (a room's walls from inside)."""
    tri = np.asarray(triangles, float)
    centre = 0.5 * (tri.reshape(-1, 3).min(axis=0) + tri.reshape(-1, 3).max(axis=0))
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    out = set()
    for k, name in enumerate(names):
        sel = np.asarray(face_ids) == k + 1
        if not np.any(sel):
            continue
        n, mid = cross[sel].sum(axis=0), tri[sel].reshape(-1, 3).mean(axis=0)
        if n @ (mid - centre) < 0:
            n = -n
        if np.linalg.norm(n) < 1e-12 or n @ (np.asarray(C, float) - mid) > 0:
            out.add(name)
    return out
