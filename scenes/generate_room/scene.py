"""The scene: every surface as a textured quad, the objects, the markers."""

from __future__ import annotations

import math

import numpy as np

from .parameters import (
    AMBIENT,
    BOX_CENTRE,
    BOX_SIZE,
    BOX_YAW_DEG,
    CABINET_DEPTH,
    CABINET_H,
    CABINET_Y,
    DIFFUSE,
    DOOR_AJAR_DEG,
    DOOR_H,
    DOOR_X0,
    DOOR_X1,
    LIGHT_DIR,
    ROOM,
    TABLE_CENTRE,
    TABLE_LEG,
    TABLE_LEG_INSET,
    TABLE_SIZE,
    TABLE_TOP_THICK,
    TABLE_TOP_Z,
)


def quad(name, obj, corner, e1, e2, texture, frame=None):
    """A rectangle corner + a·e1 + b·e2 (a, b ∈ [0, 1]) whose outward normal is e1 × e2.

    frame (origin, u, v, W, H) places the texture; by default it is the quad's own (corner,
    e1/|e1|, e2/|e2|, |e1|, |e2|). Pieces of one wall share the wall's frame, so the wallpaper
    runs on across them.
    """
    corner, e1, e2 = (np.asarray(v, dtype=np.float64) for v in (corner, e1, e2))
    if abs(float(e1 @ e2)) > 1e-9 * (e1 @ e1 + e2 @ e2):
        raise ValueError(f"quad {name}: edges must be perpendicular")
    if frame is None:
        frame = (corner, e1 / np.linalg.norm(e1), e2 / np.linalg.norm(e2),
                 float(np.linalg.norm(e1)), float(np.linalg.norm(e2)))
    n = np.cross(e1, e2)
    n /= np.linalg.norm(n)
    shade = AMBIENT + DIFFUSE * max(0.0, float(n @ LIGHT_DIR))
    return {"name": name, "object": obj, "corner": corner, "edge1": e1, "edge2": e2,
            "texture": texture, "normal": n, "shade": shade,
            "tex_origin": np.asarray(frame[0], dtype=np.float64), "tex_u": frame[1], "tex_v": frame[2],
            "tex_size": (frame[3], frame[4])}


def _box_axes(yaw_deg):
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return np.array([c, s, 0.0]), np.array([-s, c, 0.0]), np.array([0.0, 0.0, 1.0])


def box_quads(name, obj, centre, size, yaw_deg, textures, skip=()):
    """The faces of a box (centre, full size along its local axes, turned yaw_deg about +Z).

    textures maps face (+x, −x, +y, −y, +z, −z) to a texture name; edge1 × edge2 points outward
    and, on vertical faces, edge2 points up.
    """
    ux, uy, uz = _box_axes(yaw_deg)
    c = np.asarray(centre, dtype=np.float64)
    hx, hy, hz = (0.5 * v for v in size)
    faces = {
        "+x": (c + hx * ux - hy * uy - hz * uz, 2 * hy * uy, 2 * hz * uz),
        "-x": (c - hx * ux + hy * uy - hz * uz, -2 * hy * uy, 2 * hz * uz),
        "+y": (c + hy * uy + hx * ux - hz * uz, -2 * hx * ux, 2 * hz * uz),
        "-y": (c - hy * uy - hx * ux - hz * uz, 2 * hx * ux, 2 * hz * uz),
        "+z": (c + hz * uz - hx * ux - hy * uy, 2 * hx * ux, 2 * hy * uy),
        "-z": (c - hz * uz - hx * ux + hy * uy, 2 * hx * ux, -2 * hy * uy),
    }
    return [quad(f"{name}.{f}", obj, *faces[f], textures.get(f, textures["*"]))
            for f in faces if f not in skip]


def _box_vertical_edges(name, centre, size, yaw_deg):
    """The four vertical edges of a box, bottom → top (the +Z sense)."""
    ux, uy, _ = _box_axes(yaw_deg)
    c = np.asarray(centre, dtype=np.float64)
    hx, hy, hz = (0.5 * v for v in size)
    out = []
    for sx, sy, tag in ((1, 1, "pp"), (1, -1, "pm"), (-1, 1, "mp"), (-1, -1, "mm")):
        p = c + sx * hx * ux + sy * hy * uy
        out.append((f"{name}.vert_{tag}", p + [0, 0, -hz], p + [0, 0, hz]))
    return out


def _aligned_box_edges(name, lo, hi):
    """The 12 edges of an axis-aligned box [lo, hi], grouped by world axis, low → high end."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    out = {"x": [], "y": [], "z": []}
    for k, axis in enumerate("xyz"):
        o1, o2 = [m for m in range(3) if m != k]
        for a in (lo[o1], hi[o1]):
            for b in (lo[o2], hi[o2]):
                p, q = np.empty(3), np.empty(3)
                p[o1] = q[o1] = a
                p[o2] = q[o2] = b
                p[k], q[k] = lo[k], hi[k]
                tag = f"{'xyz'[o1]}{'lo' if a == lo[o1] else 'hi'}_{'xyz'[o2]}{'lo' if b == lo[o2] else 'hi'}"
                out[axis].append((f"{name}.{axis}_{tag}", p, q))
    return out


def build_scene() -> dict:
    """The room, its furniture, markers and the straight 3D edges a user could mark.

    Returns a dict: quads (list), objects (parametric boxes), markers (name → (position,
    description)), edges (axis → list of (name, start, end), end − start along +axis), light.
    """
    X, Y, Z = ROOM
    quads: list[dict] = []
    # --- the room shell; normals point into the room -------------------------------------------
    quads.append(quad("floor", "room", (0, 0, 0), (X, 0, 0), (0, Y, 0), "floor_tiles"))
    quads.append(quad("ceiling", "room", (0, 0, Z), (0, Y, 0), (X, 0, 0), "ceiling_panels"))
    quads.append(quad("wall_west", "room", (0, 0, 0), (0, Y, 0), (0, 0, Z), "wallpaper_sage"))
    quads.append(quad("wall_north", "room", (0, Y, 0), (X, 0, 0), (0, 0, Z), "wallpaper_blue"))
    quads.append(quad("wall_east", "room", (X, Y, 0), (0, -Y, 0), (0, 0, Z), "wallpaper_rose"))
    # The south wall (y = 0) has the door opening: three pieces sharing one texture frame.
    south = (np.array([X, 0, 0.0]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]), X, Z)
    quads.append(quad("wall_south.west", "room", (DOOR_X0, 0, 0), (-DOOR_X0, 0, 0), (0, 0, Z),
                       "wallpaper_cream", south))
    quads.append(quad("wall_south.east", "room", (X, 0, 0), (DOOR_X1 - X, 0, 0), (0, 0, Z),
                       "wallpaper_cream", south))
    quads.append(quad("wall_south.lintel", "room", (DOOR_X1, 0, DOOR_H), (DOOR_X0 - DOOR_X1, 0, 0),
                       (0, 0, Z - DOOR_H), "wallpaper_cream", south))
    # --- a closed dark recess behind the opening, so every ray hits something ------------------
    cx0, cx1, cy0, cz1 = DOOR_X0 - 0.1, DOOR_X1 + 0.1, -0.8, DOOR_H + 0.1
    quads += [
        quad("corridor.floor", "corridor", (cx0, cy0, 0), (cx1 - cx0, 0, 0), (0, -cy0, 0), "corridor"),
        quad("corridor.ceiling", "corridor", (cx0, cy0, cz1), (0, -cy0, 0), (cx1 - cx0, 0, 0), "corridor"),
        quad("corridor.back", "corridor", (cx1, cy0, 0), (cx0 - cx1, 0, 0), (0, 0, cz1), "corridor"),
        quad("corridor.west", "corridor", (cx0, cy0, 0), (0, -cy0, 0), (0, 0, cz1), "corridor"),
        quad("corridor.east", "corridor", (cx1, 0, 0), (0, cy0, 0), (0, 0, cz1), "corridor"),
    ]
    objects = [{"name": "room", "centre": [X / 2, Y / 2, Z / 2], "size": [X, Y, Z], "yaw_deg": 0.0}]

    # --- table: a top slab on four legs -------------------------------------------------------
    tx, ty = TABLE_CENTRE
    tw, td = TABLE_SIZE
    top_c = (tx, ty, TABLE_TOP_Z - TABLE_TOP_THICK / 2)
    top_s = (tw, td, TABLE_TOP_THICK)
    quads += box_quads("table.top", "table", top_c, top_s, 0.0, {"+z": "oak_top", "*": "oak_edge"})
    objects.append({"name": "table.top", "parent": "table", "centre": list(top_c), "size": list(top_s),
                    "yaw_deg": 0.0})
    leg_h = TABLE_TOP_Z - TABLE_TOP_THICK
    legs = []
    for k, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1)), start=1):
        lc = (tx + sx * (tw / 2 - TABLE_LEG_INSET - TABLE_LEG / 2),
              ty + sy * (td / 2 - TABLE_LEG_INSET - TABLE_LEG / 2), leg_h / 2)
        ls = (TABLE_LEG, TABLE_LEG, leg_h)
        legs.append((f"table.leg{k}", lc, ls))
        quads += box_quads(f"table.leg{k}", "table", lc, ls, 0.0, {"*": "walnut_leg"}, skip=("+z", "-z"))
        objects.append({"name": f"table.leg{k}", "parent": "table", "centre": list(lc), "size": list(ls),
                        "yaw_deg": 0.0})

    # --- cabinet against the west wall, front facing +x ---------------------------------------
    cab_c = (CABINET_DEPTH / 2, sum(CABINET_Y) / 2, CABINET_H / 2)
    cab_s = (CABINET_DEPTH, CABINET_Y[1] - CABINET_Y[0], CABINET_H)
    quads += box_quads("cabinet", "cabinet", cab_c, cab_s, 0.0, {"+x": "cabinet_front", "*": "cabinet_paint"},
                        skip=("-x", "-z"))
    objects.append({"name": "cabinet", "centre": list(cab_c), "size": list(cab_s), "yaw_deg": 0.0})

    # --- door panel, hinged on the east jamb and swung into the room ---------------------------
    door_w, door_t, door_h = DOOR_X1 - DOOR_X0 - 0.01, 0.04, DOOR_H - 0.015
    door_yaw = 180.0 - DOOR_AJAR_DEG  # local +x points from the hinge toward the free edge
    door_ux, door_uy, _ = _box_axes(door_yaw)  # −door_uy points into the room
    hinge = np.array([DOOR_X1, 0.0, 0.0])
    door_c = hinge + door_ux * (door_w / 2 + 0.005) - door_uy * (door_t / 2) + [0, 0, 0.01 + door_h / 2]
    door_s = (door_w, door_t, door_h)
    quads += box_quads("door", "door", door_c, door_s, door_yaw,
                        {"+y": "door_face_back", "-y": "door_face", "*": "door_edge"}, skip=("-z",))
    objects.append({"name": "door", "centre": door_c.tolist(), "size": list(door_s), "yaw_deg": door_yaw,
                    "hinge": hinge.tolist(), "ajar_deg": DOOR_AJAR_DEG})

    # --- cardboard box on the floor, turned about z -------------------------------------------
    box_c = (BOX_CENTRE[0], BOX_CENTRE[1], BOX_SIZE[2] / 2)
    quads += box_quads("box", "box", box_c, BOX_SIZE, BOX_YAW_DEG, {"+z": "cardboard_top", "*": "cardboard_side"},
                        skip=("-z",))
    objects.append({"name": "box", "centre": list(box_c), "size": list(BOX_SIZE), "yaw_deg": BOX_YAW_DEG})

    names = [q["name"] for q in quads]
    assert len(set(names)) == len(names), "quad names must be unique"

    # --- markers --------------------------------------------------------------------------------
    tl = (tx - tw / 2, ty - td / 2)
    th = (tx + tw / 2, ty + td / 2)
    bx, by, _ = _box_axes(BOX_YAW_DEG)
    bc = np.array([BOX_CENTRE[0], BOX_CENTRE[1], BOX_SIZE[2]])
    markers = {
        "O": ((0, 0, 0), "floor corner, south-west (the origin)"),
        "X5": ((X, 0, 0), "floor corner, south-east"),
        "Y4": ((0, Y, 0), "floor corner, north-west"),
        "T1": ((tl[0], tl[1], TABLE_TOP_Z), "table top corner, south-west"),
        "T2": ((th[0], tl[1], TABLE_TOP_Z), "table top corner, south-east"),
        "T3": ((th[0], th[1], TABLE_TOP_Z), "table top corner, north-east"),
        "T4": ((tl[0], th[1], TABLE_TOP_Z), "table top corner, north-west"),
        "C1": ((CABINET_DEPTH, CABINET_Y[0], CABINET_H), "cabinet top front corner, south"),
        "C2": ((CABINET_DEPTH, CABINET_Y[1], CABINET_H), "cabinet top front corner, north"),
        "B1": (tuple(bc + BOX_SIZE[0] / 2 * bx - BOX_SIZE[1] / 2 * by), "box top corner, toward +x"),
        "B2": (tuple(bc - BOX_SIZE[0] / 2 * bx - BOX_SIZE[1] / 2 * by), "box top corner, toward -y"),
        # the opening's own corners hide behind the ajar panel from most viewpoints
        "D1": (tuple(door_c + door_s[0] / 2 * door_ux - door_s[1] / 2 * door_uy + [0, 0, door_s[2] / 2]),
               "door panel, top corner of the free edge, room side"),
    }
    markers = {k: (np.array(p, dtype=np.float64), d) for k, (p, d) in markers.items()}

    # --- straight 3D edges along the world axes, start → end in the positive sense -------------
    e = {"x": [], "y": [], "z": []}
    for z, zn in ((0.0, "floor"), (Z, "ceiling")):
        e["x"] += [(f"{zn}_south", (0, 0, z), (X, 0, z)), (f"{zn}_north", (0, Y, z), (X, Y, z))]
        e["y"] += [(f"{zn}_west", (0, 0, z), (0, Y, z)), (f"{zn}_east", (X, 0, z), (X, Y, z))]
    for x, y in ((0, 0), (X, 0), (0, Y), (X, Y)):
        e["z"].append((f"corner_{int(x)}_{int(y)}", (x, y, 0), (x, y, Z)))
    for k in range(1, int(round(Y / 0.5))):
        e["x"].append((f"tile_joint_y{0.5 * k:.1f}", (0, 0.5 * k, 0), (X, 0.5 * k, 0)))
    for k in range(1, int(round(X / 0.5))):
        e["y"].append((f"tile_joint_x{0.5 * k:.1f}", (0.5 * k, 0, 0), (0.5 * k, Y, 0)))
    # Wallpaper stripe borders (where the wide band starts, s mod 0.24 = 0) are straight vertical
    # lines a user can click too; a few per wall, away from corners and the door.
    walls = {"wall_west": ((0, 0), (0, 1), (0.72, 1.92, 3.12)),
             "wall_north": ((0, Y), (1, 0), (0.96, 2.40, 3.84)),
             "wall_east": ((X, Y), (0, -1), (0.72, 1.92, 3.12)),
             "wall_south": ((X, 0), (-1, 0), (2.40, 3.84, 4.56))}
    for wall, (o, u, ss) in walls.items():
        for s_ in ss:
            x, y = o[0] + s_ * u[0], o[1] + s_ * u[1]
            e["z"].append((f"{wall}.stripe_{s_:.2f}", (x, y, 0.10), (x, y, Z)))
    e["x"].append(("door_lintel", (DOOR_X0, 0, DOOR_H), (DOOR_X1, 0, DOOR_H)))
    e["z"] += [("door_jamb_west", (DOOR_X0, 0, 0), (DOOR_X0, 0, DOOR_H)),
               ("door_jamb_east", (DOOR_X1, 0, 0), (DOOR_X1, 0, DOOR_H))]
    top_edges = _aligned_box_edges("table.top", (tl[0], tl[1], TABLE_TOP_Z - TABLE_TOP_THICK),
                                   (th[0], th[1], TABLE_TOP_Z))
    e["x"] += top_edges["x"]
    e["y"] += top_edges["y"]
    for name, lc, ls in legs:
        e["z"] += _box_vertical_edges(name, lc, ls, 0.0)
    cab_edges = _aligned_box_edges("cabinet", (0, CABINET_Y[0], 0), (CABINET_DEPTH, CABINET_Y[1], CABINET_H))
    for axis in "xyz":
        e[axis] += cab_edges[axis]
    e["z"] += _box_vertical_edges("door", door_c, door_s, door_yaw)
    e["z"] += _box_vertical_edges("box", box_c, BOX_SIZE, BOX_YAW_DEG)
    edges = {a: [(n, np.asarray(p, dtype=np.float64), np.asarray(q, dtype=np.float64)) for n, p, q in v]
             for a, v in e.items()}
    for a, v in edges.items():
        k = "xyz".index(a)
        for n, p, q in v:
            d = q - p
            assert d[k] > 0 and np.allclose(np.delete(d, k), 0), f"edge {n} is not along +{a}"

    return {"room": ROOM, "quads": quads, "objects": objects, "markers": markers, "edges": edges,
            "light": {"direction": LIGHT_DIR.tolist(), "ambient": AMBIENT, "diffuse": DIFFUSE}}


