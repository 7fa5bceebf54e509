"""Rooms, openings and boxes made by clicking on a calibrated photo (the modelling screen's Room,
Opening and Box tools; docs/manual.md, "Rooms by clicking").

A click's ray (the photo's camera through the clicked pixel) meets the floor z = 0 (a room's
corners), a room's floor (a box's footprint), a wall's inner face (an opening's corners) or the
vertical through a corner already placed (a height). What the clicks give becomes the primitive's
place and sizes, and each clicked corner is fixed where it was clicked (a pin), so that the solve
refines the shape from the same clicks. Each tool's result is one undoable edit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from vebuild import camera as cam_math
from vebuild.model.primitives import primitive_from_dict
from vebuild.model.room import Room

from .history import EditError
from .rooms import Rooms

Array = NDArray[np.float64]

#: A clicked floor polygon is taken as rectilinear (walls alternating along two square directions,
#: as most rooms are) when each corner's angle is within this many degrees of a right angle: a click
#: 1 px off on a corner 100 px from the next turns its wall by ~0.6°, so 10° leaves a wide margin
#: for clicks and is well short of the 45° of a slanted wall.
RECTILINEAR_TOL_DEG = 10.0
#: A wall's thickness when a room is made by clicking (metres): an interior partition; typed or
#: solved after.
CLICKED_THICKNESS_M = 0.1
#: An opening whose clicked bottom lies lower than this above the floor (metres) is a doorway (its
#: sill on the floor); higher, a window.
DOOR_SILL_MAX_M = 0.15
#: A click snaps to where two marked lines of different axes meet (their segments extended) when
#: that meet lies within this many photo pixels of it, and within LINE_MEET_REACH_PX of both
#: segments' ends: a corner where a wall's foot and a vertical were marked. As snap.SNAP_RADIUS_PX
#: for an image corner, a few click σ.
LINE_MEET_RADIUS_PX = 4.0
LINE_MEET_REACH_PX = 30.0
#: Nearest a click's ray may come to running along the surface it must meet (the sine of the
#: angle between them): a grazing ray's meeting point is too uncertain to place a corner.
GRAZING_SIN = 0.02


def _unit(v: Array) -> Array:
    return v / max(float(np.linalg.norm(v)), 1e-300)


def _signed_area(p: Array) -> float:
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def plan_room(points: Array) -> tuple[Array, float, Array, bool, list[int]]:
    """A room's place and corners from floor points (N, 2) clicked round it, either way round:
    (position of corner 0 in the world's floor, yaw in radians, corners (N, 2) in the room's frame
    as :meth:`Room.from_corners` takes them, whether rectilinear, the click behind each corner).

    Rectilinear (:data:`RECTILINEAR_TOL_DEG`, N even): the walls' common direction is the
    length-weighted mean of the walls' directions modulo 90° (the one nearest wall 0's), and each
    wall's line the mean of its two clicked ends across it. Otherwise the corners are the clicks."""
    p = np.asarray(points, float)
    n = len(p)
    order = list(range(n))
    if _signed_area(p) < 0:  # clicked clockwise: the same corners counter-clockwise from the first
        order = [0, *range(n - 1, 0, -1)]
        p = p[order]
    e = np.roll(p, -1, axis=0) - p
    length = np.hypot(e[:, 0], e[:, 1])
    phi = np.arctan2(e[:, 1], e[:, 0])
    turn = np.degrees(np.angle(np.exp(1j * (np.roll(phi, -1) - phi))))
    rect = n % 2 == 0 and n >= 4 and bool(np.all(np.abs(np.abs(turn) - 90.0) <= RECTILINEAR_TOL_DEG))
    if not rect:
        yaw = float(phi[0])
        c, s = math.cos(yaw), math.sin(yaw)
        q = (p - p[0]) @ np.array([[c, -s], [s, c]])
        q[1, 1] = 0.0
        return p[0].copy(), yaw, q, False, order
    base = 0.25 * math.atan2(float(np.sum(length * np.sin(4 * phi))), float(np.sum(length * np.cos(4 * phi))))
    yaw = base + 0.5 * math.pi * round((phi[0] - base) / (0.5 * math.pi))
    c, s = math.cos(yaw), math.sin(yaw)
    q = (p - p[0]) @ np.array([[c, -s], [s, c]])  # the clicks in axes along the walls
    lines = [0.5 * (q[i, (i + 1) % 2] + q[(i + 1) % n, (i + 1) % 2]) for i in range(n)]  # wall i's line
    # Wall i runs along x (its line a y) for even i, along y (its line an x) for odd i.
    origin = np.array([lines[n - 1], lines[0]])
    corners = np.zeros((n, 2))
    for i in range(n):
        corners[i] = (lines[i - 1 if i % 2 == 0 else i], lines[i if i % 2 == 0 else i - 1])
    corners -= origin
    return p[0] + np.array([[c, -s], [s, c]]) @ origin, yaw, corners, True, order


def line_meet(segments: dict[str, list[Sequence[float]]], uv: Sequence[float],
              radius: float = LINE_MEET_RADIUS_PX) -> tuple[float, float] | None:
    """The meet of two marked lines of different axes (``segments``: axis → [u1, v1, …, u2, v2],
    a polyline's first and last points taken) nearest ``uv`` within ``radius`` pixels, lying
    within LINE_MEET_REACH_PX of both segments' spans; None if there is none."""
    q = np.asarray(uv, float)
    lines = [(axis, np.asarray(s[:2], float), np.asarray(s[-2:], float)) for axis, segs in segments.items()
             for s in segs if len(s) >= 4]
    best: tuple[float, tuple[float, float]] | None = None
    for i, (ax_a, a0, a1) in enumerate(lines):
        for ax_b, b0, b1 in lines[i + 1:]:
            if ax_a == ax_b:
                continue
            da, db = a1 - a0, b1 - b0
            den = da[0] * db[1] - da[1] * db[0]
            if abs(den) < 1e-9 * max(float(da @ da), 1e-12) * 1e3:
                continue  # parallel in the photo
            w = b0 - a0
            t = (w[0] * db[1] - w[1] * db[0]) / den
            s = (w[0] * da[1] - w[1] * da[0]) / den
            la, lb = float(np.linalg.norm(da)), float(np.linalg.norm(db))
            reach_a, reach_b = LINE_MEET_REACH_PX / max(la, 1e-9), LINE_MEET_REACH_PX / max(lb, 1e-9)
            if not (-reach_a <= t <= 1 + reach_a and -reach_b <= s <= 1 + reach_b):
                continue
            p = a0 + t * da
            d = float(np.linalg.norm(p - q))
            if d <= radius and (best is None or d < best[0]):
                best = (d, (float(p[0]), float(p[1])))
    return best[1] if best else None


def along_line(f: Array, u: Array, C: Array, d: Array) -> float | None:
    """How far along the line f + s u (u a unit vector) lies its point nearest the ray C + t d (d a
    unit vector): s; None where the two run within :data:`GRAZING_SIN` of parallel."""
    b = float(d @ u)
    w = f - C
    den = 1.0 - b * b
    if den < GRAZING_SIN ** 2:
        return None
    return (b * float(w @ d) - float(w @ u)) / den


class ClickBuild(Rooms):
    """Rooms, openings and boxes from clicks on a calibrated photo (mixed into the session)."""

    if TYPE_CHECKING:  # the session's snapping (assist.py), mixed in beside this
        def snap_vertex(self, photo: str, uv: Sequence[float], exact: bool = False) -> tuple[tuple[float, float],
                                                                                              Any]: ...

    def snap_corner_click(self, photo: str, uv: Sequence[float], exact: bool = False) -> tuple[float, float]:
        """Where a corner clicked at uv lands: on the meet of two marked lines near it
        (:func:`line_meet`), else on the image corner near it (snap_vertex), else at uv."""
        if exact:
            return float(uv[0]), float(uv[1])
        meet = line_meet(self.photo(photo).get("vanishing_segments") or {}, uv)
        if meet is not None:
            return meet
        return self.snap_vertex(photo, uv)[0]

    # -- rays --------------------------------------------------------------------------------------

    def _ray(self, photo: str, uv: Sequence[float]) -> tuple[Array, Array]:
        if photo not in self.cameras:
            raise EditError(f"photo {photo} is not calibrated: calibrate it first, then click on it")
        cam = self._camera(photo)
        d = cam_math.pixel_rays_world(cam.K, cam.R, np.asarray(uv, float), cam.lens)
        return np.asarray(cam.C, float), np.asarray(d, float)

    def _meet_plane(self, photo: str, uv: Sequence[float], o: Array, n: Array, what: str) -> Array:
        C, d = self._ray(photo, uv)
        denom = float(d @ n)
        lam = float((o - C) @ n) / denom if abs(denom) > GRAZING_SIN else -1.0
        if lam <= 0:
            raise EditError(f"the click at ({uv[0]:.0f}, {uv[1]:.0f}) does not look at {what}: click on it, "
                            "below the horizon")
        return C + lam * d

    def floor_point(self, photo: str, uv: Sequence[float]) -> Array:
        """Where the click's ray meets the floor z = 0 (world)."""
        return self._meet_plane(photo, uv, np.zeros(3), np.array([0.0, 0.0, 1.0]), "the floor")

    def height_above(self, photo: str, uv: Sequence[float], foot: Sequence[float] | Array) -> float:
        """The height above ``foot`` (world) of the point of the vertical through it nearest the
        click's ray: a click on a wall's top above a corner."""
        C, d = self._ray(photo, uv)
        s = along_line(np.asarray(foot, float), np.array([0.0, 0.0, 1.0]), C, d)
        if s is None:
            raise EditError("the click's ray runs along the vertical through the corner: click the top from a photo "
                            "that sees the wall from the side")
        if not s > 0:
            raise EditError(f"the click at ({uv[0]:.0f}, {uv[1]:.0f}) is not above the corner: click the wall's top "
                            "straight above it")
        return float(s)

    # -- rooms -------------------------------------------------------------------------------------

    def room_from_clicks(self, photo: str, uvs: Sequence[Sequence[float]], name: str | None = None,
                         height: float | None = None) -> str:
        """A room whose floor corners are the clicks' meets with the floor (three or more, round the
        room either way), its walls ``height`` high (default: the room's usual height until a top is
        clicked or typed), each corner fixed where it was clicked."""
        if len(uvs) < 3:
            raise EditError(f"a room's floor needs at least 3 corners; {len(uvs)} clicked")
        pts = np.array([self.floor_point(photo, uv)[:2] for uv in uvs])
        origin, yaw, corners, rect, order = plan_room(pts)
        from .modelling import DEFAULT_PARAMS, fresh_name

        h = float(height) if height is not None else DEFAULT_PARAMS["room"]["height"]
        try:
            room = Room.from_corners(corners, h, CLICKED_THICKNESS_M, rectilinear=rect)
        except ValueError as e:
            raise EditError(f"these corners make no room: {e}") from None
        name = fresh_name(name, "room", {n["name"] for n in self._nodes()})
        # The walls' thickness is held at its usual value: photos from inside rarely show it (type
        # the taped value in its field to change it).
        self._add_clicked(name, room.to_dict(), {"type": "rests_on", "position": [float(v) for v in origin],
                                                 "yaw_deg": math.degrees(yaw)},
                          None, photo, [(f"f{i}", uvs[k]) for i, k in enumerate(order)], f"room {name} by clicks",
                          hold=["thickness"])
        self.say(f"room '{name}': {len(uvs)} corners{' at right angles' if rect else ''}, "
                 f"{_size_words(corners)}; now click the top of a wall above a corner, or type the height")
        return name

    def _add_clicked(self, name: str, prim: dict[str, Any], joint: dict[str, Any], parent: str | None, photo: str,
                     pins: list[tuple[str, Sequence[float]]], label: str, hold: Sequence[str] = ()) -> None:
        if name in {n["name"] for n in self._nodes()}:
            raise EditError(f"the model already has something called '{name}': choose another name")
        node: dict[str, Any] = {"name": name, "primitive": prim, "joint": joint}
        if hold:
            node["hold"] = list(hold)
        if parent is not None:
            node["parent"] = parent
        with self._edit(label):
            self._nodes().append(node)
            self._model_doc().setdefault("edge_observations", [])
            self._pins().extend({"photo": photo, "node": name, "handle": h, "uv": [float(uv[0]), float(uv[1])],
                                 "fixed": True} for h, uv in pins)
            self._rebuild_check()

    def _corner_under(self, node: str, photo: str, uv: Sequence[float], handles: Sequence[str]) -> str:
        """Of ``handles`` (floor corners), the one whose vertical, seen in the photo, passes nearest
        the click."""
        model = self.model
        cam = self._camera(photo)
        assert model is not None
        best, got = math.inf, handles[0]
        q = np.asarray(uv, float)
        for h in handles:
            X = model.handle_world(node, h)
            a = cam_math.project(cam.K, cam.R, cam.C, X)
            b = cam_math.project(cam.K, cam.R, cam.C, X + np.array([0.0, 0.0, 1.0]))
            ab = b - a
            t = float(np.clip((q - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 50.0))
            dist = float(np.linalg.norm(a + t * ab - q))
            if dist < best:
                best, got = dist, h
        return got

    def room_height_from_click(self, node: str, photo: str, uv: Sequence[float]) -> float:
        """The room's walls as high as the click on a wall's top above a corner (the corner whose
        vertical passes nearest the click); that top corner fixed where it was clicked."""
        room = self._room(node)
        n = room.n_corners
        corner = self._corner_under(node, photo, uv, [f"f{i}" for i in range(n)])
        model = self.model
        assert model is not None
        h = self.height_above(photo, uv, model.handle_world(node, corner))
        top = "t" + corner[1:]
        self._set_sizes_and_pins(node, {"height": h}, photo, [(top, uv)], f"height of {node} by a click")
        self.say(f"'{node}' is {h:.2f} m high (the top above corner {corner[1:]}); untick the walls the photos do not "
                 "show, then click a doorway's or a window's corners (Opening tool)")
        return h

    def _set_sizes_and_pins(self, node: str, params: dict[str, float], photo: str,
                            pins: list[tuple[str, Sequence[float]]], label: str) -> None:
        with self._edit(label):
            doc = self._node_doc(node)
            doc["primitive"]["params"].update({k: float(v) for k, v in params.items()})
            keys = {(photo, node, h) for h, _ in pins}
            kept = [p for p in self._pins() if (p["photo"], p["node"], p["handle"]) not in keys]
            kept += [{"photo": photo, "node": node, "handle": h, "uv": [float(uv[0]), float(uv[1])], "fixed": True}
                     for h, uv in pins]
            self._model_doc()["pins"] = kept
            self._rebuild_check()

    def set_room_walls(self, node: str, walls: Sequence[bool]) -> None:
        """Which of the room's walls are there (one true or false per wall): an absent wall has no
        faces, so it is neither textured nor hides anything."""
        room = self._room(node)
        if len(walls) != room.n_corners:
            raise EditError(f"'{node}' has {room.n_corners} walls; {len(walls)} given")
        try:
            new = room.with_walls([bool(w) for w in walls])
        except ValueError as e:
            raise EditError(f"'{node}': {e}") from None
        gone = [str(i) for i, w in enumerate(walls) if not w]
        edges = {e[0] for e in new.edges()}
        dropped = [e for e in self._edge_docs() if e["node"] == node and e["edge"] not in edges]
        with self._edit(f"walls of {node}"):
            self._node_doc(node)["primitive"] = new.to_dict()
            # A line marked along a wall that is not there any more goes with it (its top, its outer face).
            self._model_doc()["edge_observations"] = [e for e in self._edge_docs() if e not in dropped]
            self._rebuild_check()
        self.say(f"'{node}' has {sum(map(bool, walls))} of its {room.n_corners} walls"
                 + (f" (no wall {', '.join(gone)})" if gone else "")
                 + (f"; removed with them: {len(dropped)} line{'s' if len(dropped) > 1 else ''} marked along them "
                    f"(in {', '.join(sorted({e['photo'] for e in dropped}))})" if dropped else ""))

    # -- openings ----------------------------------------------------------------------------------

    def _wall_hits(self, node: str, photo: str, uv: Sequence[float]) -> list[tuple[float, int, float, float]]:
        """Each present wall's inner face that the click's ray meets, nearest first:
        (distance, wall, along the wall from its corner, height above the floor)."""
        room = self._room(node)
        model = self.model
        assert model is not None
        T = model.world_transforms()[node]
        C, d = self._ray(photo, uv)
        Rt, t = T[:3, :3], T[:3, 3]
        c_loc, d_loc = Rt.T @ (C - t), Rt.T @ d  # the ray in the room's frame
        w = room.walls()
        h = room.param("height")
        hits = []
        for i in range(room.n_corners):
            if not room.walls_present[i]:
                continue
            nrm = np.r_[w["normal"][i], 0.0]
            o = np.r_[w["start"][i], 0.0]
            denom = float(d_loc @ nrm)
            if abs(denom) < GRAZING_SIN:
                continue
            lam = float((o - c_loc) @ nrm) / denom
            if lam <= 0:
                continue
            X = c_loc + lam * d_loc
            u = float((X[:2] - w["start"][i]) @ w["dir"][i])
            if -0.05 <= u <= float(w["length"][i]) + 0.05 and -0.05 <= X[2] <= h + 0.05:
                hits.append((lam, i, u, float(X[2])))
        return sorted(hits)

    def opening_from_clicks(self, node: str, photo: str, uvs: Sequence[Sequence[float]],
                            name: str | None = None) -> str:
        """A doorway or window from clicks on its corners in the wall: its two bottom corners, then
        its top (3 clicks), or its four corners. The wall is the nearest wall the first click sees;
        the offset and width come from the bottoms along it, the sill from their height (below
        :data:`DOOR_SILL_MAX_M`: a doorway, on the floor) and the height from the top(s)."""
        if len(uvs) not in (3, 4):
            raise EditError(f"an opening takes its two bottom corners and its top (3 clicks) or its four corners; "
                            f"{len(uvs)} clicked")
        room = self._room(node)
        hits = self._wall_hits(node, photo, uvs[0])
        if not hits:
            raise EditError(f"the first click does not fall on a wall of '{node}': click the opening's bottom corners "
                            "on a wall the room has")
        wall = hits[0][1]
        pts = []
        for k, uv in enumerate(uvs):
            on = [hit for hit in self._wall_hits(node, photo, uv) if hit[1] == wall]
            if not on:
                raise EditError(f"click {k + 1} does not fall on wall {wall}, where the first one is: click the "
                                "opening's corners on one wall")
            pts.append(on[0][2:])
        (u0, z0), (u1, z1) = pts[0], pts[1]
        tops = [z for _, z in pts[2:]]
        sill = max(0.0, 0.5 * (z0 + z1))
        kind = "door" if sill < DOOR_SILL_MAX_M else "window"
        if kind == "door":
            sill = 0.0
        top = float(np.mean(tops))
        lo, hi = sorted((u0, u1))
        if top - sill < 0.05 or hi - lo < 0.05:
            raise EditError(f"the clicks make an opening {hi - lo:.2f} m wide and {top - sill:.2f} m high: click its "
                            "bottom corners apart, then its top above them")
        from .modelling import fresh_name

        taken = set(room.opening_names())
        name = fresh_name(name, kind, taken)
        if name in taken:
            raise EditError(f"'{node}' already has an opening called '{name}'")
        try:
            new = room.with_opening(name, wall, kind, lo, hi - lo, top - sill, sill)
        except ValueError as e:
            raise EditError(f"'{node}': a {kind} on wall {wall}: {e}") from None
        start_first = u0 <= u1
        pins = [(f"{name}_{'sb' if start_first else 'eb'}", uvs[0]),
                (f"{name}_{'eb' if start_first else 'sb'}", uvs[1])]
        for uv, (u, _) in zip(uvs[2:], pts[2:], strict=True):
            pins.append((f"{name}_{'st' if abs(u - lo) <= abs(u - hi) else 'et'}", uv))
        with self._edit(f"{kind} {name} in {node} by clicks"):
            doc = self._node_doc(node)
            doc["primitive"] = new.to_dict()
            if kind == "door":  # a doorway's sill is the floor
                doc["hold"] = [*doc.get("hold", []), f"{name}_sill"]
            keys = {(photo, node, h) for h, _ in pins}
            kept = [p for p in self._pins() if (p["photo"], p["node"], p["handle"]) not in keys]
            self._model_doc()["pins"] = kept + [{"photo": photo, "node": node, "handle": h,
                                                 "uv": [float(uv[0]), float(uv[1])], "fixed": True} for h, uv in pins]
            self._rebuild_check()
        what = "doorway" if kind == "door" else "window"
        self.say(f"{what} '{name}' in wall {wall} of '{node}': {hi - lo:.2f} m wide, {top - sill:.2f} m high"
                 + (f", its sill {sill:.2f} m up" if kind == "window" else ""))
        return name

    # -- boxes -------------------------------------------------------------------------------------

    def _support_under(self, photo: str, uv: Sequence[float]) -> tuple[str | None, str | None, Array, Array, Array]:
        """What a click lands on, nearest the camera: a room's floor inside its polygon, or the
        top of a box or a quad inside its rectangle (the node, its face, the face's world origin,
        x and y axes); else the world's floor z = 0 (None, None, …)."""
        model = self.model
        best: tuple[float, str | None, str | None, Array, Array, Array] | None = None
        C = self._ray(photo, uv)[0]
        if model is not None:
            transforms = model.world_transforms()
            for n in model.nodes:
                prim = n.primitive
                params = prim.to_dict()["params"] if prim is not None else {}
                if isinstance(prim, Room):
                    face = "floor"
                elif prim is not None and "top" in prim.faces() and {"width", "depth"} <= set(params):
                    face = "top"
                else:
                    continue
                T = transforms[n.name]
                fo, fx, fy, fn = prim.face_frame(face)
                o, x, y, nrm = T[:3, :3] @ fo + T[:3, 3], T[:3, :3] @ fx, T[:3, :3] @ fy, T[:3, :3] @ fn
                try:
                    P = self._meet_plane(photo, uv, o, nrm, "the floor")
                except EditError:
                    continue
                q = np.array([(P - o) @ x, (P - o) @ y])
                inside = (_inside(q, prim.corners()) if isinstance(prim, Room) else
                          abs(q[0]) <= params["width"] / 2 and abs(q[1]) <= params["depth"] / 2)
                dist = float(np.linalg.norm(P - C))
                if inside and (best is None or dist < best[0]):
                    best = (dist, n.name, face, o, x, y)
        if best is not None:
            return best[1:]
        return None, None, np.zeros(3), np.eye(3)[0], np.eye(3)[1]

    def box_from_clicks(self, photo: str, uvs: Sequence[Sequence[float]], name: str | None = None,
                        height: float | None = None) -> str:
        """A box standing on what the first click lands on (a room's floor, a box's top, else the
        floor), its footprint from three corners clicked round it (the fourth follows) or all four;
        its height ``height`` (default the usual box's) until its top is clicked or typed."""
        if len(uvs) not in (3, 4):
            raise EditError(f"a box's footprint takes 3 of its corners (or all 4); {len(uvs)} clicked")
        parent, face, o, x, y = self._support_under(photo, uvs[0])
        n = np.cross(x, y)
        pts = [self._meet_plane(photo, uv, o, n, "the floor") for uv in uvs]
        q = np.array([[(P - o) @ x, (P - o) @ y] for P in pts])
        ex = q[1] - q[0]
        width = float(np.linalg.norm(ex))
        if width < 0.01:
            raise EditError("the first two corners clicked are the same point: click the footprint's corners in turn "
                            "round it")
        ex /= width
        ey = np.array([-ex[1], ex[0]])
        depths = [float((q[2] - q[1]) @ ey)] + ([float((q[3] - q[0]) @ ey)] if len(q) == 4 else [])
        depth = float(np.mean(depths))
        if abs(depth) < 0.01:
            raise EditError("the third corner clicked lies on the line of the first two: click the footprint's "
                            "corners in turn round it")
        # Box corners v0…v3 run counter-clockwise from (−w/2, −d/2): clicks a, b, c(, d) round it
        # counter-clockwise are v0, v1, v2(, v3); clockwise, b, a, d, c.
        handles = ["v0", "v1", "v2", "v3"]
        if depth < 0:
            ex, ey, depth = -ex, -ey, -depth
            handles = ["v1", "v0", "v3", "v2"]
        start = q[0] if handles[0] == "v0" else q[1]
        centre = start + ex * width / 2 + ey * depth / 2
        from .modelling import DEFAULT_PARAMS, fresh_name

        h = float(height) if height is not None else DEFAULT_PARAMS["box"]["height"]
        prim = primitive_from_dict({"type": "box", "params": {"width": width, "depth": depth, "height": h}}).to_dict()
        joint: dict[str, Any] = {"type": "rests_on", "position": [float(v) for v in centre],
                                 "yaw_deg": math.degrees(math.atan2(ex[1], ex[0]))}
        if parent is not None:
            joint["face"] = face
        name = fresh_name(name, "box", {nd["name"] for nd in self._nodes()})
        self._add_clicked(name, prim, joint, parent, photo, list(zip(handles, uvs, strict=False)),
                          f"box {name} by clicks")
        on = f"the {face} of {parent!r}" if parent else "the floor"
        self.say(f"box '{name}' on {on}: {width:.2f} × {depth:.2f} m; "
                 "now click its top above a corner, or type its height")
        return name

    def box_height_from_click(self, node: str, photo: str, uv: Sequence[float]) -> float:
        """The box as high as the click on its top above a corner; that top corner fixed there."""
        corner = self._corner_under(node, photo, uv, ["v0", "v1", "v2", "v3"])
        model = self.model
        assert model is not None
        T = model.world_transforms()[node]
        foot = model.handle_world(node, corner)
        C, d = self._ray(photo, uv)
        up = T[:3, 2]
        # The vertical of the box's own frame through the corner (its support may be tilted).
        h = along_line(foot, up, C, d)
        if h is None:
            raise EditError("the click's ray runs along the box's corner: click its top from a photo that sees it from "
                            "the side")
        if not h > 0.001:
            raise EditError(f"the click at ({uv[0]:.0f}, {uv[1]:.0f}) is not above the box's corner: click its top")
        self._set_sizes_and_pins(node, {"height": h}, photo, [(f"v{int(corner[1:]) + 4}", uv)],
                                 f"height of {node} by a click")
        self.say(f"'{node}' is {h:.2f} m high")
        return float(h)


def _inside(q: Array, poly: Array) -> bool:
    """Whether point q lies inside polygon poly (N, 2) (even-odd rule)."""
    x, y = float(q[0]), float(q[1])
    inside = False
    n = len(poly)
    for i in range(n):
        (x0, y0), (x1, y1) = poly[i], poly[(i + 1) % n]
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def _size_words(corners: Array) -> str:
    span = corners.max(axis=0) - corners.min(axis=0)
    return f"{span[0]:.2f} × {span[1]:.2f} m across"
