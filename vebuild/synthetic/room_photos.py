"""The photos of a generated room (vebuild.synthetic.rooms): random candidate cameras standing in
the room, aimed as a photographer would (at the doorway, the window, the furniture, a wall's upper
stretch), each refused if it sees any corner of the floor; then a set of 4–10 of them chosen that
together show every wall, box and opening twice, and their marks (vanishing segments, markers).
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.calibration.start import MIN_INTERSECTION_ANGLE_DEG

from . import CLICK_NOISE_PX, SyntheticPhoto, add_segments, realistic_camera, rotation
from .rooms import RoomScene

Array = NDArray[np.float64]
#: What one photo shows (coverage): walls, points, markers, ties (sets) and rays (tie → unit sight line).
Coverage = dict[str, Any]


def _markers(rng: np.random.Generator, scene: RoomScene, n_wall: int = 80, n_floor: int = 16) -> dict[str, Array]:
    """The origin O (RoomScene.origin_handle), n_wall marks on the walls' inner faces (posters,
    switches: 0.3–2.2 m up, clear of the openings and of the furniture against them) and n_floor
    taped crosses on the floor (at least 0.5 m from the walls, clear of the furniture)."""
    out = {"O": scene.handles()[scene.origin_handle].copy()}
    k = 1
    for _ in range(4000):
        if k > n_wall:
            break
        i = int(rng.integers(len(scene.corners)))
        a, d, _, L = scene.wall(i)
        s, z = rng.uniform(0.3, L - 0.3), rng.uniform(0.3, min(2.2, scene.height - 0.2))
        if any(o.wall == i and o.offset - 0.1 < s < o.offset + o.width + 0.1 for o in scene.openings):
            continue
        X = a + s * d + np.array([0.0, 0.0, z])
        if any(np.linalg.norm(X[:2] - b.centre[:2]) < np.hypot(*b.size[:2]) / 2 + 0.2 for b in scene.boxes()):
            continue
        out[f"M{k}"] = X
        k += 1
    lo, hi = scene.corners.min(axis=0) + scene.origin[:2], scene.corners.max(axis=0) + scene.origin[:2]
    for _ in range(4000):
        if k > n_wall + n_floor:
            break
        xy = rng.uniform(lo, hi)
        if not scene.inside(xy) or scene.wall_distance(xy) < 0.5:
            continue
        if any(np.linalg.norm(xy - b.centre[:2]) < np.hypot(*b.size[:2]) / 2 + 0.2 for b in scene.boxes()):
            continue
        out[f"M{k}"] = np.r_[xy, 0.0]
        k += 1
    return out


#: How far a photo's heading is off the walls' directions (degrees, modulo 90°): a photo facing a
#: wall squarely has a vanishing point near infinity, and its focal length is undetermined.
OBLIQUE_DEG = (20.0, 70.0)
#: The share of the photos not facing the doorway taken level (2vp: the window's sill and the
#: furniture's fronts in frame; the floor far off, so that most of them see a floor corner and are
#: refused); the others are tilted up.
LEVEL_VIEWS = 0.4


def _view(rng: np.random.Generator, scene: RoomScene) -> tuple[str, Array, Array, float]:
    """A photo a user would take: its kind, where the photographer stands (x, y), what they aim at,
    and the camera's pitch (radians, up > 0). Facing the doorway's foot (the origin) from 1.5–3 m,
    tilted down 15–35° (a level camera so near would not see the floor there); or, level (2vp,
    LEVEL_VIEWS of them) or tilted up 12–30° (3vp: no floor in the frame's lower part beyond a
    metre or two), from anywhere in the room at the window, the cabinet, a unit of the row or a
    wall's upper stretch."""
    h = scene.handles()
    pick = int(rng.integers(6)) - 1
    if pick <= 0:
        at = (h["door_sb"] + h["door_eb"]) / 2 + np.array([0.0, 0.0, rng.uniform(0.2, 1.0)])
        _, d, nrm, _ = scene.wall(scene.openings[0].wall)
        xy = (at - nrm * rng.uniform(1.5, 3.0) + d * rng.uniform(-0.8, 0.8))[:2]
        return "3vp", xy, at, float(-np.radians(rng.uniform(15.0, 35.0)))
    if pick == 1:
        at = (h["win_sb"] + h["win_et"]) / 2
    elif pick == 2:
        at = scene.cabinet.centre + np.array([0, 0, scene.cabinet.size[2] * 0.7])
    elif pick == 3:
        b = scene.row[int(rng.integers(len(scene.row)))]
        at = b.centre + np.array([0, 0, b.size[2] * 0.8])
    else:
        wall = int(rng.integers(len(scene.corners)))
        a, d, _, L = scene.wall(wall)
        at = a + rng.uniform(0.2, 0.8) * L * d + np.array([0.0, 0.0, rng.uniform(1.2, scene.height)])
    lo, hi = scene.corners.min(axis=0) + scene.origin[:2], scene.corners.max(axis=0) + scene.origin[:2]
    if rng.random() < LEVEL_VIEWS:
        return "2vp", rng.uniform(lo, hi), at, float(np.radians(rng.uniform(-1.5, 1.5)))
    return "3vp", rng.uniform(lo, hi), at, float(np.radians(rng.uniform(12.0, 30.0)))


def _candidate(rng: np.random.Generator, scene: RoomScene, pid: str, width: int,
               height: int) -> SyntheticPhoto | None:
    """A camera standing in the room (_view), that sees no floor corner (or None)."""
    kind, xy, target, pitch = _view(rng, scene)
    if not scene.inside(xy) or scene.wall_distance(xy) < 0.5:
        return None
    if any(np.linalg.norm(xy - b.centre[:2]) < np.hypot(*b.size[:2]) / 2 + 0.3 for b in scene.boxes()):
        return None
    cam = realistic_camera(rng, kind, width, height, pid, distortion=bool(rng.random() < 0.5))
    cam.C = np.r_[xy, rng.uniform(1.3, 1.8)]
    dvec = target - cam.C
    yaw = float(np.arctan2(dvec[1], dvec[0]))
    off_axis = np.degrees(yaw) % 90.0
    if not OBLIQUE_DEG[0] <= off_axis <= OBLIQUE_DEG[1]:
        return None  # facing a wall squarely: one vanishing point near infinity, f undetermined
    cam.R = rotation(yaw, pitch, float(np.radians(rng.normal(0.0, 2.0))))
    if scene.seen_floor_corners(cam):
        return None
    return cam


def coverage(scene: RoomScene, cam: SyntheticPhoto, markers: dict[str, Array]) -> Coverage:
    """What one photo shows: the room's walls (a stretch of a line of each), the pinnable points
    ((node, handle)), the markers."""
    pts = scene.seen_points()
    keys = list(pts)
    seen, _ = scene.visible(cam, np.array([pts[k] for k in keys]))
    walls = set()
    n = len(scene.corners)
    for e, stretch in scene.edge_stretches(cam).items():
        if stretch is not None:
            i = int(re.sub(r"\D", "", e))
            walls.add(i)
            if e.startswith("corner"):
                walls.add((i - 1) % n)
    mk = list(markers)
    mseen, _ = scene.visible(cam, np.array([markers[m] for m in mk]))
    points = {k for k, s in zip(keys, seen, strict=True) if s}
    markers_seen = {m for m, s in zip(mk, mseen, strict=True) if s}
    # What ties the photo to others in the calibration: its markers and its pinned handles (a fixed
    # pin in two photos is a shared point named node:handle, vebuild calibrate's _pinned_handles).
    ties = markers_seen | {f"{n}:{h}" for n, h in points if (n, h) != ("room", scene.origin_handle)}
    where = {**{f"{n}:{h}": pts[(n, h)] for n, h in points}, **{m: markers[m] for m in markers_seen}}
    # The unit sight line to each tie, for the calibration's least intersection angle (_placed).
    rays = {t: (where[t] - cam.C) / np.linalg.norm(where[t] - cam.C) for t in ties}
    return {"walls": walls, "points": points, "markers": markers_seen, "ties": ties, "rays": rays}


#: What the photos must show together, for the model to be determined from them: each wall's line
#: in two photos, each box by two corners in two photos (a box with its back flush against a wall
#: keeps four unknowns, a leaf on its hinge four with its depth entered: two corners of the front's
#: top, in two photos, give them), the doorway's top corners and the window's corners in two, every
#: photo MIN_SHARED_MARKERS markers that another photo shows too (to be placed with the others), the
#: origin in two (the calibration places photos together from markers two of them show).
MIN_PHOTOS_PER_THING = 2
MIN_BOX_CORNERS = 2
MIN_MARKERS_PER_PHOTO = 3
MIN_SHARED_MARKERS = 3


def _needs(scene: RoomScene, covs: list[Coverage]) -> int:
    """How far a set of photos falls short of MIN_PHOTOS_PER_THING (0: enough)."""
    return sum(shortfall(scene, covs).values())


def shortfall(scene: RoomScene, covs: list[Coverage]) -> dict[str, int]:
    """What a set of photos (their coverage) shows too seldom: thing → photos missing."""
    short = {}
    for i in range(len(scene.corners)):
        short[f"wall{i}"] = max(0, MIN_PHOTOS_PER_THING - sum(i in c["walls"] for c in covs))
    for b in scene.boxes():
        k = sum(sum((b.name, f"v{j}") in c["points"] for j in range(8)) >= MIN_BOX_CORNERS for c in covs)
        short[b.name] = max(0, MIN_PHOTOS_PER_THING - k)
    for h in ("door_st", "door_et", "win_st", "win_et", "win_sb", "win_eb"):
        short[h] = max(0, MIN_PHOTOS_PER_THING - sum(("room", h) in c["points"] for c in covs))
    short["O"] = max(0, MIN_PHOTOS_PER_THING - sum("O" in c["markers"] for c in covs))
    for k, c in enumerate(covs):
        others = set().union(*(o["ties"] for j, o in enumerate(covs) if j != k))
        short[f"photo{k}"] = max(0, MIN_SHARED_MARKERS - len(c["ties"] & (others | {"O"})))
    short["placement"] = _unlinked(covs)
    return {k: v for k, v in short.items() if v}


#: Greedy choices of photos tried, each from another first photo, before giving up on a scene.
CHOICE_RESTARTS = 40


def _known(covs: list[Coverage], order: list[int]) -> set[str]:
    """The ties the calibration's start has placed once the photos ``order`` are: the origin, and
    each tie two of them see with sight lines at least MIN_INTERSECTION_ANGLE_DEG apart."""
    out = {"O"}
    for t in set().union(*(covs[j]["ties"] for j in order)):
        rays = [covs[j]["rays"][t] for j in order if t in covs[j]["ties"]]
        if len(rays) >= 2 and max(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))) for k, a in enumerate(rays)
                                  for b in rays[k + 1:]) >= MIN_INTERSECTION_ANGLE_DEG:
            out.add(t)
    return out


def placeable(covs: list[Coverage], order: list[int], i: int, known: set[str] | None = None) -> bool:
    """Whether vebuild calibrate's start can place photo i after the photos ``order``: it shares two
    ties with one of them and sees a tie they have placed (_known)."""
    known = _known(covs, order) if known is None else known
    return bool(covs[i]["ties"] & known) and any(len(covs[i]["ties"] & covs[j]["ties"]) >= 2 for j in order)


def _greedy(rng: np.random.Generator, scene: RoomScene, covs: list[Coverage], n_photos: tuple[int, int],
            first: int) -> list[int]:
    """Photos chosen one by one from ``first``, each one the calibration can place after those
    before it (placeable), the one that leaves the least short."""
    chosen = [first]
    while len(chosen) < n_photos[1]:
        now = _needs(scene, [covs[i] for i in chosen])
        if now == 0 and len(chosen) >= n_photos[0]:
            break
        known = _known(covs, chosen)
        gains = [(now - _needs(scene, [covs[i] for i in chosen] + [c]), len(c["points"]), rng.random(), i)
                 for i, c in enumerate(covs) if i not in chosen and placeable(covs, chosen, i, known)]
        if not gains:
            break
        chosen.append(max(gains)[3])
    return chosen


def _choose(rng: np.random.Generator, scene: RoomScene, covs: list[Coverage],
            n_photos: tuple[int, int]) -> list[int] | None:
    """A set of 4–10 photos that leaves nothing short (None where CHOICE_RESTARTS greedy tries fail)."""
    firsts = [i for i in rng.permutation(len(covs)) if "O" in covs[i]["markers"]]
    for first in firsts[:CHOICE_RESTARTS]:
        chosen = _greedy(rng, scene, covs, n_photos, int(first))
        if len(chosen) >= n_photos[0] and _needs(scene, [covs[i] for i in chosen]) == 0:
            return chosen
    return None


def _placed(covs: list[Coverage], chosen: list[int]) -> list[int]:
    """The photos ``chosen`` that vebuild calibrate's start (calibration/start.py) can place, in the
    order it places them: first the one showing the origin with the most markers, then each that
    shares two markers with a placed photo and sees a marker that two placed photos show (a
    handle pinned in two photos counts as a marker: "ties")."""
    with_origin = [i for i in chosen if "O" in covs[i]["markers"]]
    if not with_origin:
        return []
    order = [max(with_origin, key=lambda i: len(covs[i]["ties"]))]
    left = [i for i in chosen if i != order[0]]
    while left:
        known = _known(covs, order)
        nxt = next((i for i in left if placeable(covs, order, i, known)), None)
        if nxt is None:
            break
        order.append(nxt)
        left.remove(nxt)
    return order


def _unlinked(covs: list[Coverage]) -> int:
    """How many of the photos the calibration could not place (_placed)."""
    return len(covs) - len(_placed(covs, list(range(len(covs))))) if covs else 0


def photograph(rng: np.random.Generator, scene: RoomScene, n_photos: tuple[int, int] = (4, 10),
               width: int = 1600, height: int = 1200, n_candidates: int = 100,
               noise_px: float = CLICK_NOISE_PX) -> None:
    """Choose 4–10 photos (greedily, from random candidates that see no floor corner) that together
    show what the model needs (_needs), then mark their vanishing segments and markers (clicked
    with noise_px 1σ); sets ``scene.photos`` and ``scene.markers`` (the markers seen in two photos
    or more). RuntimeError where no such set is found. The stream of ``rng`` does not depend on
    noise_px (a noise of 0 gives the same room and photos with exact clicks)."""
    markers = _markers(rng, scene)
    cands: list[tuple[SyntheticPhoto, Coverage]] = []
    for k in range(40 * n_candidates):
        if len(cands) >= n_candidates:
            break
        cam = _candidate(rng, scene, f"c{k}", width, height)
        if cam is None:
            continue
        cov = coverage(scene, cam, markers)
        if len(cov["ties"]) >= MIN_MARKERS_PER_PHOTO:
            cands.append((cam, cov))
    covs = [c for _, c in cands]
    chosen = _choose(rng, scene, covs, n_photos)
    if chosen is None:
        firsts = [i for i, c in enumerate(covs) if "O" in c["markers"]] or [0]
        best = min((_greedy(rng, scene, covs, n_photos, i) for i in firsts[:5]),
                   key=lambda ch: _needs(scene, [covs[i] for i in ch]))
        if len(best) >= n_photos[0] and _needs(scene, [covs[i] for i in best]) == 0:
            chosen = best  # the first photos in candidate order found a set the random restarts missed
    if chosen is None:
        raise RuntimeError("no set of photos shows every wall, box and opening twice without a floor corner: "
                           f"short of {shortfall(scene, [covs[i] for i in best])}")
    scene.photos = []
    for j, i in enumerate(_placed(covs, chosen)):
        cam = cands[i][0]
        cam.id = f"p{j + 1}"
        add_segments(cam, rng, noise_px, middle_points=3 if cam.k1 != 0.0 else 0)
        _, uv = scene.visible(cam, np.array(list(markers.values())))
        seen = cands[i][1]["markers"]
        cam.markers = {m: p + rng.normal(0.0, noise_px, 2) for m, p in zip(markers, uv, strict=True) if m in seen}
        scene.photos.append(cam)
    # A user marks a marker where it helps: in two photos or more.
    counts = {m: sum(m in p.markers for p in scene.photos) for m in markers}
    for p in scene.photos:
        p.markers = {m: uv for m, uv in p.markers.items() if counts[m] >= 2}
    scene.markers = {m: X for m, X in markers.items() if counts[m] >= 2}
