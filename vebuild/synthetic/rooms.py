"""Seeded generated rooms with known answers: an L-shaped room shell with a doorway and a window,
a door leaf on a hinge at the doorway's jamb, a cabinet flush against a wall and a row of equal
units flush against another, photographed from inside so that no photo sees any corner of the floor.

The geometry here is the room's own (corners, walls, openings, boxes as plain numpy), written out
apart from vebuild's room primitive and joints, so that a convention slip in those is caught by
comparing the two (tests/test_room_scenes.py): the true world points, the visibility tests and the
clicks all come from this module. The cameras, lenses, vanishing segments, click noise and the
project writer are vebuild.synthetic's. The photos are chosen in :mod:`vebuild.synthetic.room_photos`;
the project-file side (the true and the guessed model as FORMAT.md nodes and relations, the pins and
edge observations) and the whole generated room (:func:`vebuild.synthetic.room_model.room_scene`:
geometry, photos, model and marks) are :mod:`vebuild.synthetic.room_model`.

Room frame (as FORMAT.md's room primitive): the floor at z = 0, inner floor corner 0 at the origin,
corner 1 on +x, corners counter-clockwise seen from above; wall i runs from corner i to corner i + 1
with the room on its left; its thickness lies outside (to the right). The world frame is the room
frame moved so that the foot of the doorway's jamb away from the hinge (handle ``door_sb`` or
``door_eb``: the leaf, open, would hide the other) is the origin marker O: a marker at a floor
corner would be a floor corner seen by a photo, which these rooms exclude.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from . import SyntheticPhoto, distort, longest_run, project_points, projection_matrix

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: How far inside the image (px) a point must project to count as seen: a user does not click in
#: the last few pixels, and synthetic.add_segments keeps the same margin.
IMAGE_MARGIN_PX = 5.0
#: Nearest a seen point may be in front of the camera, metres (as synthetic.observe_markers).
MIN_DEPTH_M = 0.3
#: Boxes are shrunk by this much (metres) for the occlusion test, so that a box's own corner is not
#: hidden by the face it lies on (its sight line touches the box at its end).
OCCLUDER_SHRINK_M = 1e-3
#: Points along an edge tested for visibility, to find the stretch of it a photo shows.
EDGE_SAMPLES = 41
#: The least length (px, on the photo) of an edge's seen stretch for a user to mark it.
MIN_STRETCH_PX = 150.0
#: 1σ of a wall's thickness taped at the doorway's reveal, metres: a tape read to the millimetre
#: across a reveal whose edges are not sharp.
THICKNESS_TAPE_SIGMA_M = 0.003
#: 1σ of a door leaf's thickness taped at its free edge, metres.
LEAF_TAPE_SIGMA_M = 0.001


@dataclass
class Opening:
    """A hole in wall ``wall``: from ``offset`` metres along the wall's inner face (from corner
    ``wall``) for ``width``, from ``sill`` above the floor for ``height``."""

    name: str
    wall: int
    kind: str
    offset: float
    width: float
    height: float
    sill: float


@dataclass
class Box:
    """A box standing upright: bottom centre ``centre`` (world), turned ``yaw`` (radians) about +z;
    ``size`` = (width along its x, depth along its y, height)."""

    name: str
    size: Array
    centre: Array
    yaw: float

    def corners(self) -> Array:
        """v0…v7 as FORMAT.md's box: v0…v3 the bottom ring counter-clockwise from (−x, −y), then the top."""
        w, d, h = self.size
        ring = np.array([[-w / 2, -d / 2], [w / 2, -d / 2], [w / 2, d / 2], [-w / 2, d / 2]])
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        xy = ring @ np.array([[c, s], [-s, c]]) + self.centre[:2]
        z0 = self.centre[2]
        return np.vstack([np.c_[xy, np.full(4, z0)], np.c_[xy, np.full(4, z0 + h)]])

    def frame(self) -> Array:
        """world_from_box (4×4)."""
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        T = np.eye(4)
        T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        T[:3, 3] = self.centre
        return T

    def hides(self, C: Array, X: Array) -> Mask:
        """Whether the box (shrunk by OCCLUDER_SHRINK_M) cuts the sight lines from C to each X (n, 3)."""
        T = self.frame()
        a = (C - T[:3, 3]) @ T[:3, :3]
        b = (X - T[:3, 3]) @ T[:3, :3]
        half = self.size[:2] / 2 - OCCLUDER_SHRINK_M
        lo = np.array([-half[0], -half[1], OCCLUDER_SHRINK_M])
        hi = np.array([half[0], half[1], self.size[2] - OCCLUDER_SHRINK_M])
        d = b - a
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (lo - a) / d
            t2 = (hi - a) / d
        tmin = np.where(d == 0, np.where((a >= lo) & (a <= hi), -np.inf, np.inf), np.minimum(t1, t2))
        tmax = np.where(d == 0, np.where((a >= lo) & (a <= hi), np.inf, -np.inf), np.maximum(t1, t2))
        enter = np.max(np.maximum(tmin, 0.0), axis=1)
        leave = np.min(np.minimum(tmax, 1.0), axis=1)
        return enter < leave


@dataclass
class Hinge:
    """The door leaf's hinge at the doorway's jamb ``side`` ("start" or "end"): the axis point and the
    leaf's shut pose in the jamb frame (origin at the jamb's foot on the wall's inner face, x along
    the wall from corner i to i + 1, y into the room, z up), its axis ±z, open ``angle`` (radians)."""

    side: str
    axis_point: Array
    axis: Array
    shut_centre: Array
    angle: float


@dataclass
class RoomScene:
    """A generated room, its furniture, its photos and what a user marks in them.

    ``corners`` (N, 2) in the room frame; ``origin`` the room frame's origin in the world (the room
    is not turned: its walls lie along the world's x and y); the boxes in the world frame.
    """

    corners: Array
    height: float
    thickness: float
    openings: list[Opening]
    origin: Array
    cabinet: Box
    cabinet_wall: int
    row: list[Box]
    row_wall: int
    leaf: Box
    hinge: Hinge
    #: What the user tapes at the scene: the walls' thickness at the doorway's reveal, the leaf's
    #: thickness (the true values plus the tape's error, drawn with the room: one measurement,
    #: whatever the first guess).
    tapes: dict[str, float] = field(default_factory=dict)
    photos: list[SyntheticPhoto] = field(default_factory=list)
    markers: dict[str, Array] = field(default_factory=dict)
    #: Derived geometry, keyed by what it derives from (the scene is plain data: a changed field
    #: gives a new key).
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    # ---- the room's own geometry (world frame) ------------------------------------------------
    def wall(self, i: int) -> tuple[Array, Array, Array, float]:
        """Wall i: its start corner (world, z = 0), unit direction, outward unit normal, length."""
        key = ("wall", i, self.corners.tobytes(), self.origin.tobytes())
        if key not in self._cache:
            self._cache[key] = self._wall(i)
        return self._cache[key]

    def _wall(self, i: int) -> tuple[Array, Array, Array, float]:
        n = len(self.corners)
        a, b = self.corners[i], self.corners[(i + 1) % n]
        d = (b - a) / np.linalg.norm(b - a)
        return np.r_[a + self.origin[:2], 0.0], np.r_[d, 0.0], np.r_[d[1], -d[0], 0.0], float(np.linalg.norm(b - a))

    def outer_corners(self) -> Array:
        """The walls' outer faces' corners (N, 2, world): each wall's inner line moved out by the
        thickness, neighbours meeting (mitred)."""
        n = len(self.corners)
        out = []
        for i in range(n):
            _, _, n_prev, _ = self.wall((i - 1) % n)
            _, _, n_here, _ = self.wall(i)
            A = np.array([n_prev[:2], n_here[:2]])
            out.append(self.corners[i] + self.origin[:2] + np.linalg.solve(A, [self.thickness, self.thickness]))
        return np.array(out)

    def opening(self, name: str) -> Opening:
        return next(o for o in self.openings if o.name == name)

    def handles(self) -> dict[str, Array]:
        """Every room handle (FORMAT.md's names) in the world."""
        key = ("handles", self.corners.tobytes(), self.origin.tobytes(), self.height, self.thickness,
               tuple((o.wall, o.offset, o.width, o.height, o.sill) for o in self.openings))
        if key not in self._cache:
            self._cache[key] = self._handles()
        return self._cache[key]

    def _handles(self) -> dict[str, Array]:
        n = len(self.corners)
        out: dict[str, Array] = {}
        fl = self.corners + self.origin[:2]
        for i in range(n):
            out[f"f{i}"] = np.r_[fl[i], 0.0]
            out[f"t{i}"] = np.r_[fl[i], self.height]
        for i, p in enumerate(self.outer_corners()):
            out[f"fo{i}"] = np.r_[p, 0.0]
            out[f"to{i}"] = np.r_[p, self.height]
        for o in self.openings:
            a, d, nrm, _ = self.wall(o.wall)
            z0, z1 = np.array([0, 0, o.sill]), np.array([0, 0, o.sill + o.height])
            s, e = a + o.offset * d, a + (o.offset + o.width) * d
            for pre, shift in (("", 0.0), ("o", self.thickness)):
                out[f"{o.name}_{pre}sb"] = s + shift * nrm + z0
                out[f"{o.name}_{pre}st"] = s + shift * nrm + z1
                out[f"{o.name}_{pre}eb"] = e + shift * nrm + z0
                out[f"{o.name}_{pre}et"] = e + shift * nrm + z1
        return out

    def edges(self) -> dict[str, tuple[str, str]]:
        """The room's inner edges a photo can show: floor{i}, top{i}, corner{i} (FORMAT.md's names)."""
        n = len(self.corners)
        out = {}
        for i in range(n):
            out[f"floor{i}"] = (f"f{i}", f"f{(i + 1) % n}")
            out[f"top{i}"] = (f"t{i}", f"t{(i + 1) % n}")
            out[f"corner{i}"] = (f"f{i}", f"t{i}")
        return out

    def jamb_frame(self, name: str, side: str) -> Array:
        """world_from_jamb (4×4): origin at the jamb's foot on the inner face, x along the wall,
        y into the room, z up."""
        o = self.opening(name)
        a, d, nrm, _ = self.wall(o.wall)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2] = d, -nrm, [0.0, 0.0, 1.0]
        T[:3, 3] = a + (o.offset if side == "start" else o.offset + o.width) * d + np.array([0, 0, o.sill])
        return T

    @property
    def origin_handle(self) -> str:
        """The room handle at the origin marker O: the foot of the doorway's jamb away from the hinge."""
        return "door_eb" if self.hinge.side == "start" else "door_sb"

    def boxes(self) -> list[Box]:
        return [self.cabinet, *self.row, self.leaf]

    def seen_points(self) -> dict[tuple[str, str], Array]:
        """Every point a user could pin: (node, handle) → world. The room's floor corners are
        included (to be checked unseen), its outer corners are not (seen only through an opening)."""
        pts = {("room", h): X for h, X in self.handles().items() if not (h.startswith("fo") or h.startswith("to")
                                                                             or "_o" in h)}
        for b in self.boxes():
            pts.update({(b.name, f"v{k}"): X for k, X in enumerate(b.corners())})
        return pts

    # ---- visibility ---------------------------------------------------------------------------
    def inside(self, xy: Array) -> bool:
        """Whether a world point (x, y) lies inside the floor polygon (ray casting)."""
        p = self.corners + self.origin[:2]
        x, y = xy
        c = False
        for i in range(len(p)):
            (x1, y1), (x2, y2) = p[i], p[(i + 1) % len(p)]
            if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
                c = not c
        return c

    def wall_distance(self, xy: Array) -> float:
        """Distance (m) from a world point (x, y) to the nearest wall's inner face."""
        best = np.inf
        for i in range(len(self.corners)):
            a, d, _, L = self.wall(i)
            t = np.clip((xy - a[:2]) @ d[:2], 0.0, L)
            best = min(best, float(np.linalg.norm(xy - a[:2] - t * d[:2])))
        return best

    def visible(self, photo: SyntheticPhoto, X: Array) -> tuple[Mask, Array]:
        """(seen mask, pixels on the distorted photo) of world points X (n, 3): in front, inside the
        image, and no wall or box cutting the sight line."""
        P = projection_matrix(photo.K, photo.R, photo.C)
        uv, z = project_points(P, X)
        uv = distort(photo, uv)
        ok = (z > MIN_DEPTH_M) & (uv[:, 0] >= IMAGE_MARGIN_PX) & (uv[:, 0] <= photo.width - IMAGE_MARGIN_PX)
        ok &= (uv[:, 1] >= IMAGE_MARGIN_PX) & (uv[:, 1] <= photo.height - IMAGE_MARGIN_PX)
        ok &= ~self._walls_hide(photo.C, X)
        for b in self.boxes():
            ok &= ~b.hides(photo.C, X)
        return ok, uv

    def _walls_hide(self, C: Array, X: Array) -> Mask:
        """Whether a wall cuts the sight line from C (inside the room) to X: the line crosses a
        wall's inner face strictly before X (a point on a wall is not hidden by its own wall) and
        not through an opening's hole. A point beyond the inner face in a hole (the leaf's edge in
        the doorway) is seen through it: the hole is a convex prism through the wall. A sight line
        that leaves the room through an opening cannot come back in (one doorway on wall N − 1,
        the plane x = 0 with the whole room on its +x side, one window elsewhere, and a line
        crosses a plane once)."""
        hidden = np.zeros(len(X), bool)
        D = X[:, :2] - C[:2]
        eps = 1e-6
        for i in range(len(self.corners)):
            a, d, _, L = self.wall(i)
            w = d[:2] * L
            den = D[:, 0] * w[1] - D[:, 1] * w[0]
            r = a[:2] - C[:2]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (r[0] * w[1] - r[1] * w[0]) / den
                s = (r[0] * D[:, 1] - r[1] * D[:, 0]) / den
            cut = (np.abs(den) > 1e-12) & (t > eps) & (t < 1 - 1e-4) & (s >= 0.0) & (s <= 1.0)
            z = C[2] + t * (X[:, 2] - C[2])
            for o in self.openings:
                if o.wall == i:
                    cut &= ~((s * L > o.offset) & (s * L < o.offset + o.width) & (z > o.sill) & (z < o.sill + o.height))
            hidden |= cut
        return hidden

    def seen_floor_corners(self, photo: SyntheticPhoto) -> list[str]:
        """The room's floor corners the photo shows (none, in a scene this module generates)."""
        h = self.handles()
        names = [f"f{i}" for i in range(len(self.corners))]
        seen, _ = self.visible(photo, np.array([h[n] for n in names]))
        return [n for n, s in zip(names, seen, strict=True) if s]

    def edge_stretch(self, photo: SyntheticPhoto, edge: str) -> tuple[Array, Array] | None:
        """The longest stretch of a room edge the photo shows, as its two ends in the world, or
        None where none is MIN_STRETCH_PX long."""
        return self.edge_stretches(photo)[edge]

    def edge_stretches(self, photo: SyntheticPhoto) -> dict[str, tuple[Array, Array] | None]:
        """edge_stretch of every room edge (one visibility test for all)."""
        h = self.handles()
        edges = self.edges()
        t = np.linspace(0.0, 1.0, EDGE_SAMPLES)[:, None]
        X = np.concatenate([h[a] + t * (h[b] - h[a]) for a, b in edges.values()])
        seen_all, uv_all = self.visible(photo, X)
        out: dict[str, tuple[Array, Array] | None] = {}
        for k, e in enumerate(edges):
            rows = slice(k * EDGE_SAMPLES, (k + 1) * EDGE_SAMPLES)
            seen, uv, pts = seen_all[rows], uv_all[rows], X[rows]
            best = longest_run(seen)
            i, j = best[0], best[1] - 1
            ok = best[1] - best[0] >= 3 and np.linalg.norm(uv[j] - uv[i]) >= MIN_STRETCH_PX
            out[e] = (pts[i], pts[j]) if ok else None
        return out


def _l_room(rng: np.random.Generator) -> tuple[Array, float, float]:
    """Six corners of an L-shaped room (5–7 m × 4–6 m, the notch at the far corner), its height and
    wall thickness."""
    W, D = rng.uniform(5.0, 7.0), rng.uniform(4.0, 6.0)
    c3x, c2y = W * rng.uniform(0.45, 0.65), D * rng.uniform(0.4, 0.6)
    corners = np.array([[0.0, 0.0], [W, 0.0], [W, c2y], [c3x, c2y], [c3x, D], [0.0, D]])
    return corners, float(rng.uniform(2.4, 2.8)), float(rng.uniform(0.08, 0.2))


def room_geometry(rng: np.random.Generator) -> RoomScene:
    """The room, its openings and furniture, drawn from ``rng`` (no photos yet)."""
    corners, height, thickness = _l_room(rng)
    n = len(corners)
    lengths = [float(np.linalg.norm(corners[(i + 1) % n] - corners[i])) for i in range(n)]
    dw = float(rng.uniform(0.8, 0.95))
    # The doorway in wall N − 1 (x = 0), the room's full width in front of it (the L's notch is
    # across the room from it).
    dwall = n - 1
    door = Opening("door", dwall, "door", float(rng.uniform(1.2, lengths[dwall] - dw - 1.2)), dw,
                   float(rng.uniform(2.0, 2.1)), 0.0)
    win_wall = int(rng.choice([i for i in (1, 3, 4) if lengths[i] >= 2.2]))
    ww = float(rng.uniform(0.9, min(1.4, lengths[win_wall] - 1.0)))
    sill = float(rng.uniform(0.8, 1.0))
    win = Opening("win", win_wall, "window", float(rng.uniform(0.5, lengths[win_wall] - ww - 0.5)), ww,
                  float(rng.uniform(0.9, min(1.3, height - 0.2 - sill))), sill)
    # The world's origin is the foot of the doorway's jamb away from the hinge.
    side = str(rng.choice(["start", "end"]))
    a = corners[dwall]
    d = (corners[0] - a) / lengths[dwall]
    origin = -np.r_[a + (door.offset + (door.width if side == "start" else 0.0)) * d, 0.0]
    sign = 1.0 if side == "start" else -1.0
    leaf_size = np.array([dw - 0.01, rng.uniform(0.035, 0.045), door.height - 0.01])
    hinge = Hinge(side, np.array([sign * rng.uniform(0.005, 0.02), rng.uniform(0.01, 0.03), 0.0]),
                  np.array([0.0, 0.0, sign]), np.array([sign * (0.005 + leaf_size[0] / 2), -leaf_size[1] / 2, 0.0]),
                  float(np.radians(rng.uniform(20.0, 70.0))))
    dummy = Box("x", np.ones(3), np.zeros(3), 0.0)
    scene = RoomScene(corners, height, thickness, [door, win], origin, dummy, 0, [], 0, dummy, hinge)
    scene.leaf = _leaf(scene, leaf_size)
    scene.tapes = {"thickness": float(thickness + rng.normal(0.0, THICKNESS_TAPE_SIGMA_M)),
                   "leaf_depth": float(leaf_size[1] + rng.normal(0.0, LEAF_TAPE_SIGMA_M))}
    # The cabinet stands with its back flush against a wall with no opening; a row of two or three
    # equal units with their backs flush against another.
    free = [i for i in range(n) if i not in (dwall, win_wall)]
    cab_wall = int(rng.choice([i for i in free if lengths[i] >= 1.6]))
    size = np.array([rng.uniform(0.8, 1.2), rng.uniform(0.4, 0.6), rng.uniform(1.6, 2.0)])
    scene.cabinet = _against(scene, "cabinet", cab_wall, size, rng.uniform(0.3 + size[0] / 2,
                                                                          lengths[cab_wall] - 0.3 - size[0] / 2))
    scene.cabinet_wall = cab_wall
    unit = np.array([rng.uniform(0.5, 0.7), rng.uniform(0.35, 0.5), rng.uniform(1.2, 1.8)])
    k = int(rng.integers(2, 4))
    walls = [i for i in free if i != cab_wall and lengths[i] >= k * unit[0] + 0.6] or \
            [i for i in free if i != cab_wall and lengths[i] >= 2 * unit[0] + 0.6]
    if not walls:
        raise RuntimeError("no wall is free for the row of units")
    row_wall = int(rng.choice(walls))
    k = min(k, int((lengths[row_wall] - 0.6) // unit[0]))
    start = rng.uniform(0.3, lengths[row_wall] - 0.3 - k * unit[0])
    scene.row = [_against(scene, f"unit{j + 1}", row_wall, unit.copy(), start + (j + 0.5) * unit[0])
                 for j in range(k)]
    scene.row_wall = row_wall
    return scene


def _against(scene: RoomScene, name: str, wall: int, size: Array, along: float) -> Box:
    """A box with its back (+y face) flush against wall ``wall``'s inner face, its centre ``along``
    metres from the wall's start corner."""
    a, d, nrm, _ = scene.wall(wall)
    x_axis = np.cross(nrm, [0.0, 0.0, 1.0])  # the box's +y along the wall's outward normal
    return Box(name, size, a + along * d - nrm * size[1] / 2, float(np.arctan2(x_axis[1], x_axis[0])))


def _leaf(scene: RoomScene, size: Array) -> Box:
    """The door leaf where its hinge puts it: the shut pose turned about the axis by the angle."""
    hg = scene.hinge
    turn = hg.angle * hg.axis[2]  # about +z
    c, s = np.cos(turn), np.sin(turn)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    q = hg.axis_point + Rz @ (hg.shut_centre - hg.axis_point)
    J = scene.jamb_frame("door", hg.side)
    centre = J[:3, :3] @ q + J[:3, 3]
    x = J[:3, :3] @ Rz[:, 0]
    return Box("door", size, centre, float(np.arctan2(x[1], x[0])))
