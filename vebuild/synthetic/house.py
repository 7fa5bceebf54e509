"""Seeded generated houses with known answers: rooms in a grid joined by doorways, furnished with
hundreds of primitives, a stairwell, photographed from inside and marked as a careful user would.

The house is a grid of ``rows`` × ``cols`` rectangular rooms (FORMAT.md's room primitive, four
corners, a ceiling except over the stairwell), each joined to one neighbour by a doorway through
their party wall (the ``through`` joint: a spanning tree, room (0, 0) on the origin marker O at its
floor corner f0, the first row chained east, each room of the next rows north of the one below).
Each room holds furniture made of primitives in a scene graph: a table (four legs, a top resting on
a leg, books and a ball on the top) with chairs around it (four legs, a seat, a back), cabinets and
a shelf against the walls, a sofa, a lamp (base, pole, shade), a plant (pot, foliage), crates (some
stacked), wedges and stools. The stairwell (the last room) has a flight of steps instead of the
table.

Photos (cameras from :func:`vebuild.synthetic.realistic_camera`, pinhole, wide lenses: f 0.55–0.85
× the width; tilted down 14–32° so that all three axes recede) stand inside a room, aimed at its
doorways (so that the rooms' cameras share the doorway markers) or at its furniture. What a photo
claims to see is tested here, independently of vebuild's renderer: a point is seen when it is in
front, inside the image, no occluder (each primitive's bounding box, shrunk by 1 mm) of its room
cuts the sight line, and a point beyond the room's walls (the doorway markers) is seen through the
doorway's hole. The marks: vanishing segments along the longest seen stretches of real edges
along the world axes (the walls' corners and floor lines, the doorways' jambs and heads, the
furniture's edges), marker sightings, and a fixed pin on every seen handle of the room's own
primitives, each click the truth plus noise_px (1σ). A photo is kept only where vebuild
calibrate's start could place it after those before it (room_photos.placeable).

The true world positions of the handles come from vebuild's own kinematics (as
:func:`vebuild.synthetic.model_scene`); the photos themselves are rendered above this layer
(vebuild.bench.house_scene). The rooms, doorways, furniture and markers are drawn in
:mod:`vebuild.synthetic.house_layout`, whose :func:`~vebuild.synthetic.house_layout.house_scene`
draws a whole house and has it photographed and marked here.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.model.joints import ModelError
from vebuild.model.scene import model_from_dict
from vebuild.project import new_photo_entry, new_project, save_project

from . import (
    CLICK_NOISE_PX,
    SyntheticPhoto,
    longest_run,
    project_points,
    projection_matrix,
    realistic_camera,
    rotation,
)
from .room_photos import placeable

Array = NDArray[np.float64]

HEIGHT_M = 2.6
THICKNESS_M = 0.1
DOOR_WIDTH_M, DOOR_HEIGHT_M = 0.9, 2.05
#: 1σ of the walls' thickness taped at a doorway's reveal, metres (as the generated rooms').
THICKNESS_TAPE_SIGMA_M = 0.003
#: A seen point lies this far inside the image (px) and this far in front (m).
IMAGE_MARGIN_PX, MIN_DEPTH_M = 5.0, 0.3
OCCLUDER_SHRINK_M = 1e-3
EDGE_SAMPLES = 21
#: A vanishing segment spans at least this share of the image's longer side; a photo needs
#: MIN_SEGMENTS of them per axis.
MIN_SEGMENT_REL, MIN_SEGMENTS, MAX_SEGMENTS = 0.10, 4, 6
#: Focal lengths of the photos (share of the width): wide lenses, as rooms are photographed.
FOCAL_REL = (0.55, 0.85)
#: A photo's heading is this far off the walls' directions (degrees, modulo 90°).
OBLIQUE_DEG = (20.0, 70.0)
#: The first guess's error: sizes (relative), positions (metres), turns (degrees), each uniform, either sign.
GUESS_SIZE_REL, GUESS_POSITION_M, GUESS_YAW_DEG = 0.03, 0.03, 2.0


@dataclass
class Room:
    """A room of the house: its node name, grid cell, inner size, world position of its inner floor
    corner 0, and its openings (name → (wall, offset))."""

    name: str
    cell: tuple[int, int]
    size: tuple[float, float]
    origin: Array
    openings: dict[str, tuple[int, float]] = field(default_factory=dict)
    ceiling: bool = True

    def contains(self, xy: Array, margin: float = 0.0) -> bool:
        lo, hi = self.origin[:2] + margin, self.origin[:2] + np.array(self.size) - margin
        return bool(np.all(xy >= lo) and np.all(xy <= hi))


@dataclass
class Door:
    """A doorway from room ``a`` (opening ``a_opening``) to room ``b`` (``b_opening``): its world
    sill centre (mid-wall), the party wall's normal axis (0: x, 1: y)."""

    a: str
    a_opening: str
    b: str
    b_opening: str
    centre: Array
    axis: int


@dataclass
class House:
    """A generated house: the true nodes (FORMAT.md), the first guess, the rooms and doorways, which
    room each node stands in, the markers (and the rooms whose photos may see each), the photos
    (their room in ``photo_room``) and the pins."""

    nodes: list[dict[str, Any]]
    rooms: dict[str, Room]
    doors: list[Door]
    node_room: dict[str, str]
    markers: dict[str, Array] = field(default_factory=dict)
    marker_rooms: dict[str, set[str]] = field(default_factory=dict)
    photos: list[SyntheticPhoto] = field(default_factory=list)
    photo_room: dict[str, str] = field(default_factory=dict)
    pins: list[dict[str, Any]] = field(default_factory=list)
    guess: list[dict[str, Any]] = field(default_factory=list)
    _geometry: dict[Any, Any] = field(default_factory=dict, repr=False)

    @property
    def primitives(self) -> int:
        return sum(1 for n in self.nodes if "primitive" in n)

    def model(self) -> Any:
        if "model" not in self._geometry:
            nodes: list[Mapping[str, Any]] = list(self.nodes)
            self._geometry["model"] = model_from_dict(nodes, {"O": np.zeros(3)})
        return self._geometry["model"]

    def room_points(self, room: str) -> dict[tuple[str, str], Array]:
        """Every pinnable handle (node, handle) of the room's own primitives, and of the room
        itself its inner corners and its openings' inner-face corners."""
        key = ("points", room)
        if key not in self._geometry:
            m = self.model()
            T = m.world_transforms()
            out = {}
            for n in m.nodes:
                if n.primitive is None or self.node_room.get(n.name) != room:
                    continue
                names = n.primitive.handle_names()
                hs = n.primitive.handles() @ T[n.name][:3, :3].T + T[n.name][:3, 3]
                for h, X in zip(names, hs, strict=True):
                    if n.name == room and (h.startswith(("fo", "to")) or "_o" in h):
                        continue
                    out[(n.name, h)] = X
            self._geometry[key] = out
        return self._geometry[key]

    def occluders(self, room: str) -> tuple[Array, Array, Array]:
        """The room's primitives' bounding boxes: (rotations (n, 3, 3), centres... as world_from_box
        rotation, origin, lo, hi) packed as (R (n,3,3), t (n,3), lohi (n,2,3))."""
        key = ("occ", room)
        if key not in self._geometry:
            m = self.model()
            T = m.world_transforms()
            Rs, ts, lh = [], [], []
            for n in m.nodes:
                if n.primitive is None or n.name == room or self.node_room.get(n.name) != room:
                    continue
                hs = n.primitive.handles()
                lo, hi = hs.min(axis=0), hs.max(axis=0)
                if n.primitive.TYPE in ("cylinder", "frustum"):
                    r = max(abs(lo[0]), abs(hi[0]), abs(lo[1]), abs(hi[1]))
                    lo, hi = np.r_[-r, -r, lo[2]], np.r_[r, r, hi[2]]
                Rs.append(T[n.name][:3, :3])
                ts.append(T[n.name][:3, 3])
                lh.append([lo + OCCLUDER_SHRINK_M, hi - OCCLUDER_SHRINK_M])
            self._geometry[key] = (np.array(Rs).reshape(-1, 3, 3), np.array(ts).reshape(-1, 3),
                                   np.array(lh).reshape(-1, 2, 3))
        return self._geometry[key]

    def hidden(self, room: str, C: Array, X: Array) -> NDArray[np.bool_]:
        """Whether an occluder of the room cuts the sight line from C to each X (n, 3), or a point
        beyond the room's inner walls is not seen through a doorway's hole."""
        R, t, lh = self.occluders(room)
        out = np.zeros(len(X), bool)
        if len(R):
            a = np.einsum("kij,ki->kj", R, C[None, :] - t)  # (k, 3): C in each box's frame
            b = np.einsum("kij,kni->knj", R, X[None, :, :] - t[:, None, :])  # (k, n, 3)
            d = b - a[:, None, :]
            lo, hi = lh[:, None, 0, :], lh[:, None, 1, :]
            with np.errstate(divide="ignore", invalid="ignore"):
                t1, t2 = (lo - a[:, None, :]) / d, (hi - a[:, None, :]) / d
            inside = (a[:, None, :] >= lo) & (a[:, None, :] <= hi)
            tmin = np.where(d == 0, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
            tmax = np.where(d == 0, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
            enter = np.max(np.maximum(tmin, 0.0), axis=2)
            leave = np.min(np.minimum(tmax, 1.0), axis=2)
            out |= np.any(enter < leave, axis=0)
        rm = self.rooms[room]
        lo, hi = rm.origin[:2], rm.origin[:2] + np.array(rm.size)
        beyond = np.any((X[:, :2] < lo - 1e-9) | (X[:, :2] > hi + 1e-9), axis=1)
        for k in np.flatnonzero(beyond):
            out[k] |= not self._through_door(room, C, X[k])
        return out

    def _through_door(self, room: str, C: Array, X: Array) -> bool:
        """Whether the sight line from C (in the room) to X (beyond its walls) leaves the room
        through one of its doorways' holes."""
        rm = self.rooms[room]
        lo, hi = rm.origin[:2], rm.origin[:2] + np.array(rm.size)
        for door in self.doors:
            if room not in (door.a, door.b):
                continue
            ax = door.axis
            plane = lo[ax] if X[ax] < lo[ax] else hi[ax] if X[ax] > hi[ax] else None
            if plane is None or abs(door.centre[ax] - plane) > 2 * THICKNESS_M + 1e-6:
                continue
            s = (plane - C[ax]) / (X[ax] - C[ax])
            P = C + s * (X - C)
            other = 1 - ax
            if abs(P[other] - door.centre[other]) < DOOR_WIDTH_M / 2 and 0.0 < P[2] < DOOR_HEIGHT_M:
                return True
        return False

    def visible(self, photo: SyntheticPhoto, X: Array) -> tuple[NDArray[np.bool_], Array]:
        """(seen, pixels) of world points X (n, 3) in a photo taken in its room."""
        uv, z = project_points(projection_matrix(photo.K, photo.R, photo.C), X)
        ok = (z > MIN_DEPTH_M) & (uv[:, 0] >= IMAGE_MARGIN_PX) & (uv[:, 0] <= photo.width - IMAGE_MARGIN_PX)
        ok &= (uv[:, 1] >= IMAGE_MARGIN_PX) & (uv[:, 1] <= photo.height - IMAGE_MARGIN_PX)
        if ok.any():
            ok[ok] &= ~self.hidden(self.photo_room[photo.id], photo.C, X[ok])
        return ok, uv

    def axis_edges(self, room: str) -> dict[str, list[tuple[Array, Array]]]:
        """Straight edges along the world axes in the room (start → end along +axis): the room's
        inner corners, floor and ceiling lines, its doorways' jambs and heads, and every edge of its
        primitives that lies along an axis."""
        key = ("edges", room)
        if key in self._geometry:
            return self._geometry[key]
        out: dict[str, list[tuple[Array, Array]]] = {"x": [], "y": [], "z": []}
        m = self.model()
        T = m.world_transforms()
        for n in m.nodes:
            if n.primitive is None or self.node_room.get(n.name) != room:
                continue
            if n.name == room:
                pts = self.room_points(room)
                pairs = [(f"f{i}", f"f{(i + 1) % 4}") for i in range(4)] + [(f"f{i}", f"t{i}") for i in range(4)]
                pairs += [(f"t{i}", f"t{(i + 1) % 4}") for i in range(4)]
                for o in self.rooms[room].openings:
                    pairs += [(f"{o}_sb", f"{o}_st"), (f"{o}_eb", f"{o}_et"), (f"{o}_st", f"{o}_et")]
                segs = [(pts[(room, a)], pts[(room, b)]) for a, b in pairs]
            elif n.primitive.TYPE in ("box", "wedge"):
                hs = n.primitive.handles() @ T[n.name][:3, :3].T + T[n.name][:3, 3]
                ring = [(0, 1), (1, 2), (2, 3), (3, 0)]
                idx = [*ring, *((a + 4, b + 4) for a, b in ring), *((k, k + 4) for k in range(4))]
                if n.primitive.TYPE == "wedge":
                    idx = [*ring, (3, 4), (2, 5), (4, 5)]
                segs = [(hs[a], hs[b]) for a, b in idx]
            else:
                continue
            for p, q in segs:
                d = q - p
                k = int(np.argmax(np.abs(d)))
                if np.linalg.norm(np.delete(d, k)) > 1e-6 * max(1.0, abs(d[k])):
                    continue
                out["xyz"[k]].append((p, q) if d[k] > 0 else (q, p))
        self._geometry[key] = out
        return out


def _seen_stretch(house: House, photo: SyntheticPhoto,
                  edges: list[tuple[Array, Array]]) -> list[tuple[Array, Array, float]]:
    """For each edge, its longest seen stretch (ends in the world) and its length on the photo (px)."""
    if not edges:
        return []
    t = np.linspace(0.0, 1.0, EDGE_SAMPLES)[:, None]
    X = np.concatenate([p + t * (q - p) for p, q in edges])
    seen, uv = house.visible(photo, X)
    out = []
    for k in range(len(edges)):
        s = seen[k * EDGE_SAMPLES:(k + 1) * EDGE_SAMPLES]
        best = longest_run(s)
        if best[1] - best[0] < 3:
            continue
        i, j = k * EDGE_SAMPLES + best[0], k * EDGE_SAMPLES + best[1] - 1
        out.append((X[i], X[j], float(np.linalg.norm(uv[j] - uv[i]))))
    return out


def _segments(house: House, photo: SyntheticPhoto, rng: np.random.Generator, noise_px: float) -> bool:
    """Mark the photo's vanishing segments on its longest seen edges per axis (False: too few)."""
    room = house.photo_room[photo.id]
    min_px = MIN_SEGMENT_REL * max(photo.width, photo.height)
    P = projection_matrix(photo.K, photo.R, photo.C)
    chosen = {}
    for axis, edges in house.axis_edges(room).items():
        stretches = sorted((s for s in _seen_stretch(house, photo, edges) if s[2] >= min_px), key=lambda s: -s[2])
        if len(stretches) < MIN_SEGMENTS:
            return False
        chosen[axis] = stretches[:MAX_SEGMENTS]
    for axis, stretches in chosen.items():
        segs = []
        for a, b, _ in stretches:
            ends = np.array([a + 0.05 * (b - a), a + 0.95 * (b - a)])  # a user clicks inside the ends
            uv, _ = project_points(P, ends)
            segs.append((uv + rng.normal(0.0, noise_px, uv.shape)).reshape(-1))
        photo.segments[axis] = np.array(segs)
    return True


def _coverage(house: House, photo: SyntheticPhoto) -> dict[str, Any]:
    """What a photo shows of its room: the markers and pinnable points it sees, its ties (as
    room_photos: markers and node:handle names) and the unit sight line to each."""
    room = house.photo_room[photo.id]
    pts = house.room_points(room)
    keys = [k for k in pts if k != ("room0", "f0")]
    mk = [m for m, rooms in house.marker_rooms.items() if room in rooms]
    X = np.array([*(pts[k] for k in keys), *(house.markers[m] for m in mk)])
    seen, uv = house.visible(photo, X)
    points = {k: uv[i] for i, k in enumerate(keys) if seen[i]}
    markers = {m: uv[len(keys) + i] for i, m in enumerate(mk) if seen[len(keys) + i]}
    # The ties: the markers only. A house is calibrated before it is modelled: vebuild calibrate
    # also ties photos by pinned handles, but the joint placement is dense in its unknowns, and
    # thousands of pinned handles make it impractical (docs/house.md).
    where = {m: house.markers[m] for m in markers}
    rays = {t: (X_ - photo.C) / np.linalg.norm(X_ - photo.C) for t, X_ in where.items()}
    return {"points": points, "markers": markers, "ties": set(where), "rays": rays}


def _camera(rng: np.random.Generator, house: House, room: str, target: Array, pid: str, width: int,
            height: int) -> SyntheticPhoto | None:
    """A tilted camera standing in the room (clear of walls and furniture) aimed at ``target``."""
    rm = house.rooms[room]
    xy = rm.origin[:2] + rng.uniform(0.5, np.array(rm.size) - 0.5)
    R, t, lh = house.occluders(room)
    for k in range(len(R)):
        local = R[k].T @ (np.r_[xy, 0.0] - t[k])
        if np.all(local[:2] >= lh[k, 0, :2] - 0.3) and np.all(local[:2] <= lh[k, 1, :2] + 0.3):
            return None
    cam = realistic_camera(rng, "3vp", width, height, pid, distortion=False)
    f = width * rng.uniform(*FOCAL_REL)
    cam.K[0, 0] = cam.K[1, 1] = f
    cam.exif_focal_px = None
    cam.C = np.r_[xy, rng.uniform(1.4, 1.8)]
    d = target - cam.C
    yaw = float(np.arctan2(d[1], d[0]))
    if not OBLIQUE_DEG[0] <= np.degrees(yaw) % 90.0 <= OBLIQUE_DEG[1]:
        return None
    pitch = float(np.clip(np.arctan2(d[2], np.hypot(d[0], d[1])), np.radians(-32.0), np.radians(-14.0)))
    cam.R = rotation(yaw, pitch, float(np.radians(rng.normal(0.0, 2.0))))
    return cam


def _targets(house: House, room: str) -> list[Array | None]:
    """Where the room's photos must aim, in order (None: at its furniture): the first room's first
    photos at the origin's corner, then the doorway to its parent twice, three at its furniture,
    the doorways to its children three times each."""
    out: list[Array | None] = []
    if room == "room0":  # until two photos have placed a tie, each must see the origin
        out += [np.array([0.8, 0.8, 0.5]), np.array([1.2, 0.6, 0.6]), np.array([0.6, 1.2, 0.6])]
    doors = [d for d in house.doors if room in (d.a, d.b)]
    for door in (d for d in doors if d.b == room):  # the doorway to its parent, the tree's link
        out += [door.centre + np.array([0.0, 0.0, 0.9])] * 2
    out += [None] * 3  # then three at its furniture, before the doorways to its children
    for door in (d for d in doors if d.a == room):
        out += [door.centre + np.array([0.0, 0.0, 0.9])] * 3
    return out


def _free_target(rng: np.random.Generator, house: House, room: str) -> Array:
    """A point a photo may aim at: one of the room's primitives, 0.4 m above its origin."""
    parts = [k for k, r in house.node_room.items() if r == room and k != room]
    T = house.model().world_transforms()
    return T[parts[int(rng.integers(len(parts)))]][:3, 3] + np.array([0.0, 0.0, 0.4])


def _photo(rng: np.random.Generator, house: House, room: str, target: Array, pid: str, width: int, height: int,
           covs: list[dict[str, Any]], noise_px: float, tries: int) -> SyntheticPhoto | None:
    """A photo aimed at ``target`` that calibration can place after those of ``covs`` (None after
    ``tries`` cameras); taken: its marks are made and it joins the house."""
    for _ in range(tries):
        cam = _camera(rng, house, room, target, pid, width, height)
        if cam is None:
            continue
        house.photo_room[pid] = room
        cov = _coverage(house, cam)
        if not covs and "O" not in cov["markers"]:
            continue
        if covs and not placeable([*covs, cov], list(range(len(covs))), len(covs)):
            continue
        if not _segments(house, cam, rng, noise_px):
            continue
        covs.append(cov)
        cam.markers = {m: uv + rng.normal(0.0, noise_px, 2) for m, uv in cov["markers"].items()}
        house.pins += [{"photo": pid, "node": n, "handle": h, "uv": [float(v) for v in uv + rng.normal(0, noise_px, 2)],
                        "fixed": True} for (n, h), uv in cov["points"].items()]
        house.photos.append(cam)
        return cam
    house.photo_room.pop(pid, None)
    return None


def photograph(rng: np.random.Generator, house: House, per_room: int, width: int, height: int,
               noise_px: float = CLICK_NOISE_PX, tries: int = 2000) -> None:
    """Take ``per_room`` photos in every room (rooms in the order the tree joins them): each a
    camera vebuild calibrate's start can place after those before it, with at least MIN_SEGMENTS
    segments per axis; then mark its segments, markers and pins (noise_px 1σ). RuntimeError where a
    room's photo cannot be found."""
    covs: list[dict[str, Any]] = []
    for room in house.rooms:
        must = _targets(house, room)
        k = -1
        while (k := k + 1) < per_room or (must and k < per_room + 6):  # deferred doorways may add a few
            pid = f"{room.replace('room', 'r')}p{k + 1}"
            target = must.pop(0) if must else None
            cam = None
            for attempt in range(4):  # a doorway not yet placeable waits while others of the room link it
                aim = target if attempt == 0 and target is not None else _free_target(rng, house, room)
                cam = _photo(rng, house, room, aim, pid, width, height, covs, noise_px, tries)
                if cam is not None:
                    break
            if cam is None:
                raise RuntimeError(f"no photo {pid} found in {room} that calibration could place")
            if aim is not target and target is not None:
                must.append(target)
        if must:
            raise RuntimeError(f"{room}: {len(must)} doorway photos could not be placed in {per_room} photos")
    counts = {m: sum(m in p.markers for p in house.photos) for m in house.markers}
    for p in house.photos:
        p.markers = {m: uv for m, uv in p.markers.items() if counts[m] >= 2}
    house.markers = {m: X for m, X in house.markers.items() if counts[m] >= 2}


def _off(rng: np.random.Generator, v: float, rel: float) -> float:
    return float(v * (1.0 + rng.uniform(-rel, rel)))


#: A primitive is solved where this many of its handles are pinned in two photos or more, among
#: them a top and a bottom one (where it has both); the others are held (``solve: false``).
MIN_PINNED_HANDLES = {"sphere": 2}
DEFAULT_MIN_PINNED_HANDLES = 4


def _well_pinned(house: House) -> dict[str, bool]:
    """Whether each primitive's pins determine it (MIN_PINNED_HANDLES)."""
    photos: dict[tuple[str, str], set[str]] = {}
    for p in house.pins:
        photos.setdefault((p["node"], p["handle"]), set()).add(p["photo"])
    out = {}
    for n in house.nodes:
        kind = n["primitive"]["type"]
        hs = {h for (node, h), ph in photos.items() if node == n["name"] and len(ph) >= 2}
        enough = len(hs) >= MIN_PINNED_HANDLES.get(kind, DEFAULT_MIN_PINNED_HANDLES)
        if kind == "box":
            enough &= bool(hs & {"v0", "v1", "v2", "v3"}) and bool(hs & {"v4", "v5", "v6", "v7"})
        elif kind in ("cylinder", "frustum"):
            enough &= bool(hs & {"b0", "b1", "b2", "b3", "bc"}) and bool(hs & {"t0", "t1", "t2", "t3", "tc"})
        out[n["name"]] = enough
    return out


def guessed_nodes(rng: np.random.Generator, house: House) -> list[dict[str, Any]]:
    """A user's model after modelling, before the final solve: sizes GUESS_SIZE_REL off, positions
    GUESS_POSITION_M, turns GUESS_YAW_DEG; the walls' thickness entered from a tape (its σ), the
    doorways' sills held at 0; a primitive its pins do not determine (_well_pinned) held at its
    true place and size (``solve: false``, as a user measures it)."""
    shown = _well_pinned(house)
    for _ in range(50):
        nodes = copy.deepcopy(house.nodes)
        for n in nodes:
            prim = n["primitive"]
            if prim["type"] != "room" and not shown.get(n["name"], False):
                n["solve"] = False  # too few pins to determine it: the user measured it (held at the truth)
                continue
            if prim["type"] == "room":
                tape = float(prim["params"]["thickness"] + rng.normal(0.0, THICKNESS_TAPE_SIGMA_M))
                for k, v in prim["params"].items():
                    if k == "thickness":
                        prim["params"][k] = tape
                    elif not k.endswith("_sill"):
                        prim["params"][k] = _off(rng, v, GUESS_SIZE_REL / 2)
                n["hold"] = [*(f"{o['name']}_sill" for o in prim.get("openings", [])),
                             {"name": "thickness", "sigma": THICKNESS_TAPE_SIGMA_M, "value": tape}]
                continue
            prim["params"] = {k: _off(rng, v, GUESS_SIZE_REL) for k, v in prim["params"].items()}
            j = n["joint"]
            j["position"] = [float(v + rng.uniform(-GUESS_POSITION_M, GUESS_POSITION_M)) for v in j["position"]]
            j["yaw_deg"] = float(j["yaw_deg"] + rng.uniform(-GUESS_YAW_DEG, GUESS_YAW_DEG))
        try:
            model_from_dict(list[Mapping[str, Any]](nodes), {"O": np.zeros(3)})
        except (ModelError, ValueError):
            continue
        return nodes
    raise RuntimeError("no valid first guess of the house in 50 draws")


def scale_references(house: House) -> list[dict[str, Any]]:
    """A taped scale from O to the best-seen marker of the first room far from it, and a check
    distance between two markers of the last room."""
    seen = {m: sum(m in p.markers for p in house.photos) for m in house.markers}

    def pick(room: str, far_from: Array) -> str:
        cands = [m for m, rs in house.marker_rooms.items() if rs == {room} and m in house.markers and m != "O"]
        return max(cands, key=lambda m: (min(seen[m], 4), float(np.linalg.norm(house.markers[m] - far_from))))

    first, last = next(iter(house.rooms)), list(house.rooms)[-1]
    a = pick(first, np.zeros(3))
    c = pick(last, house.rooms[last].origin)
    d = pick(last, house.markers[c])
    dist = lambda p, q: round(float(np.linalg.norm(house.markers[p] - house.markers[q])), 4)  # noqa: E731
    return [{"a": "O", "b": a, "distance": dist("O", a), "sigma": 0.002, "role": "scale"},
            {"a": c, "b": d, "distance": dist(c, d), "sigma": 0.002, "role": "check"}]


def write_house_project(folder: Path, house: House, photo_files: dict[str, Path], guess: bool = True) -> Path:
    """The house's project file in ``folder`` (its photos already there): segments, markers, the
    taped distances, the model (the first guess, or the truth) and the pins. Returns its path."""
    data = new_project("generated house")
    data["settings"]["click_sigma_px"] = CLICK_NOISE_PX
    for p in house.photos:
        entry = new_photo_entry(folder, photo_files[p.id], p.id)
        entry["vanishing_segments"] = {a: [[float(x) for x in s] for s in seg] for a, seg in p.segments.items()}
        entry["marker_observations"] = {n: [float(uv[0]), float(uv[1])] for n, uv in p.markers.items()}
        data["photos"].append(entry)
    data["markers"] = [{"name": n} for n in sorted(house.markers)]
    data["origin_marker"] = "O"
    data["reference_distances"] = scale_references(house)
    data["model"] = {"nodes": house.guess if guess else house.nodes, "pins": house.pins, "edge_observations": []}
    path = Path(folder) / "house.vebuild.json"
    save_project(path, data)
    return path
