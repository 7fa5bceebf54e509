"""The model (paper §3): the true scene graph, its forward kinematics, and what a user would do with it."""

from __future__ import annotations

import json
import math

import numpy as np

from .cameras import project
from .clicks import longest_visible_run
from .parameters import (
    BASE_WIDTH,
    CLICK_SIGMA_PX,
    IMAGE_MARGIN_PX,
    ROOM,
    SEED,
    SEGMENT_MIN_PX,
    TABLE_CENTRE,
    WALL_THICK,
)
from .raycast import visible

# The format is "The model" in scenes/FORMAT.md. A primitive's local frame has its origin at the
# centre of its bottom face, local +z up. A joint gives parent_from_node (4 × 4), written out here
# as this file reads the format (tests/test_example_scene.py writes it out again and holds every
# handle to the corners of the quads scene.py lays out):
#
#   marker    T(marker) · Rz(yaw) · T(−handle)          the handle sits on the marker, turned about +Z
#   rests_on  F · T(s, t, 0) · Rz(yaw)                  F: the parent face's frame (origin, x, y, normal);
#                                                       the world's floor z = 0 without a parent
#   fixed     T(translation) · Rz(rz) · Ry(ry) · Rx(rx)  XYZ Euler angles about the parent's axes
#   hinge     T(p) · Rot(axis, angle) · T(−p) · fixed   p = axis_point; fixed = the pose at angle 0;
#                                                       a positive angle turns counter-clockwise
#                                                       about axis (right-hand rule)

# The door swings into the room about the downward axis (so that opening is a positive angle): 0°
# is shut against the stop in the frame, and at about 153° its free edge would meet the east wall.
DOOR_HINGE_AXIS = (0.0, 0.0, -1.0)
DOOR_LIMITS_DEG = (0.0, 150.0)
# The walls' nodes (true_walls). No photo shows a wall's thickness, its outer faces or (the ajar
# panel hides them) the doorway's corners, so the user places the walls from what was measured in
# the room: its size (5 × 4 m, 2.6 m high), the walls' thickness at the doorway, the doorway's width,
# height and distance from the west wall. In the project they are "solve": false (FORMAT.md) at those
# values; they rest on the floor, so they follow the floor as solved. They take no pins.
WALL_NODES = ("wall_west", "wall_north", "wall_east", "wall_south", "wall_south.west", "wall_south.east",
              "wall_south.lintel")
PIN_PROBE_M = 0.02  # a corner is clicked only where ≥ 2 of its edges are seen this far from it
PIN_MIN_SEP_PX = 8.0  # … and no other seen corner of that primitive lies this near it (scale 1)
ROUGH_SIZE_REL = (0.10, 0.25)  # a dropped primitive's sizes (and position, × its extent) are this far off
ROUGH_YAW_DEG = (5.0, 10.0)
ROUGH_HINGE_DEG = (8.0, 12.0)
# Model edges on which the user draws a red edge observation (each in the photo that shows the
# longest visible run of it).
EDGE_OBSERVATION_CANDIDATES = [
    ("floor", "e1"), ("floor", "e2"), ("cabinet", "e9"), ("cabinet", "e10"), ("cabinet", "e5"),
    ("box", "e8"), ("box", "e9"), ("box", "e10"), ("box", "e11"), ("table.top", "e4"), ("table.top", "e7"),
    ("door", "e9"), ("door", "e4"),
]

_RING = ((-1, -1), (1, -1), (1, 1), (-1, 1))  # v0…v3: counter-clockwise from (−x, −y), seen from +z
QUAD_EDGES = {f"e{k}": (f"v{k}", f"v{(k + 1) % 4}") for k in range(4)}
BOX_EDGES = {**QUAD_EDGES,
             **{f"e{k + 4}": (f"v{k + 4}", f"v{(k + 1) % 4 + 4}") for k in range(4)},
             **{f"e{k + 8}": (f"v{k}", f"v{k + 4}") for k in range(4)}}


def rounded(x, nd=3):
    """x flattened, as floats rounded to nd decimals (what the project file holds)."""
    return [round(float(v), nd) for v in np.ravel(x)]


def primitive_handles(prim: dict) -> dict[str, np.ndarray]:
    """Handle name → position in the primitive's local frame (quad and box, FORMAT.md)."""
    p = prim["params"]
    w, d = p["width"], p["depth"]
    out = {f"v{k}": np.array([sx * w / 2, sy * d / 2, 0.0]) for k, (sx, sy) in enumerate(_RING)}
    if prim["type"] == "box":
        out.update({f"v{k + 4}": np.array([sx * w / 2, sy * d / 2, p["height"]]) for k, (sx, sy) in enumerate(_RING)})
    elif prim["type"] != "quad":
        raise ValueError(f"primitive type {prim['type']!r}: this generator knows quad and box")
    return out


def primitive_edges(prim: dict) -> dict[str, tuple[str, str]]:
    return BOX_EDGES if prim["type"] == "box" else QUAD_EDGES


def _T(t) -> np.ndarray:
    M = np.eye(4)
    M[:3, 3] = t
    return M


def _R4(R: np.ndarray) -> np.ndarray:
    M = np.eye(4)
    M[:3, :3] = R
    return M


def _axis_rotation(axis, angle_deg: float) -> np.ndarray:
    """Rodrigues: counter-clockwise by angle_deg about the unit vector along axis (right-hand rule)."""
    k = np.asarray(axis, dtype=np.float64)
    k = k / np.linalg.norm(k)
    a = math.radians(angle_deg)
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * Kx + (1 - math.cos(a)) * (Kx @ Kx)


def _euler_xyz(rotation_deg) -> np.ndarray:
    """XYZ Euler angles about the parent's (fixed) axes: Rz(rz) · Ry(ry) · Rx(rx)."""
    rx, ry, rz = rotation_deg
    return _axis_rotation((0, 0, 1), rz) @ _axis_rotation((0, 1, 0), ry) @ _axis_rotation((1, 0, 0), rx)


def face_frame(prim: dict | None, face: str) -> np.ndarray:
    """primitive_from_face: the face's origin (its centre) and axes (x, y, outward normal)."""
    if prim is None:
        raise ValueError(f"face {face!r} of a group: a group has no faces")
    if face == "top":
        return _T([0.0, 0.0, prim["params"].get("height", 0.0) if prim["type"] == "box" else 0.0])
    if face == "bottom" and prim["type"] == "box":
        return _R4(_axis_rotation((1, 0, 0), 180.0))  # x, −y, −z: right-handed, normal down
    raise ValueError(f"{prim['type']} has no face {face!r}")


def joint_transform(joint: dict, prim: dict | None, parent_prim: dict | None, has_parent: bool,
                    markers: dict[str, np.ndarray]) -> np.ndarray:
    """parent_from_node (4 × 4) of one joint (the table at the top of this section)."""
    kind = joint["type"]
    if kind == "marker":
        h = primitive_handles(prim)[joint["handle"]]
        return _T(markers[joint["marker"]]) @ _R4(_axis_rotation((0, 0, 1), joint["yaw_deg"])) @ _T(-h)
    if kind == "rests_on":
        F = face_frame(parent_prim, joint["face"]) if has_parent else np.eye(4)
        s, t = joint["position"]
        return F @ _T([s, t, 0.0]) @ _R4(_axis_rotation((0, 0, 1), joint["yaw_deg"]))
    pose = _T(joint["translation"]) @ _R4(_euler_xyz(joint["rotation_deg"]))
    if kind in ("fixed", "free"):
        return pose
    if kind == "hinge":
        p = np.asarray(joint["axis_point"], dtype=np.float64)
        return _T(p) @ _R4(_axis_rotation(joint["axis"], joint["angle_deg"])) @ _T(-p) @ pose
    raise ValueError(f"joint type {kind!r}: this generator knows marker, rests_on, fixed, free and hinge")


def model_world_transforms(nodes: list[dict], markers: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Node name → world_from_node, composing joints down the graph (parents listed first)."""
    world: dict[str, np.ndarray] = {}
    prims = {n["name"]: n.get("primitive") for n in nodes}
    for n in nodes:
        parent = n.get("parent")
        if parent is not None and parent not in world:
            raise ValueError(f"node {n['name']!r}: parent {parent!r} must be listed before it")
        T = joint_transform(n["joint"], n.get("primitive"), prims.get(parent), parent is not None, markers)
        world[n["name"]] = T if parent is None else world[parent] @ T
    return world


def model_handles_world(nodes: list[dict], markers: dict[str, np.ndarray]) -> dict[str, dict[str, np.ndarray]]:
    """Primitive node name → handle name → world position (3,)."""
    world = model_world_transforms(nodes, markers)
    out = {}
    for n in nodes:
        if n.get("primitive") is not None:
            T = world[n["name"]]
            out[n["name"]] = {h: T[:3, :3] @ x + T[:3, 3] for h, x in primitive_handles(n["primitive"]).items()}
    return out


def scene_markers(scene: dict) -> dict[str, np.ndarray]:
    return {n: p for n, (p, _) in scene["markers"].items()}


def _c(x) -> list[float] | float:
    """Values rounded to 1e-12 m (or degree): 0.4 rather than 0.3999999999999999 in the files."""
    if np.ndim(x):
        return [_c(v) for v in np.ravel(x)]
    return round(float(x), 12) + 0.0  # + 0.0: no −0.0


def true_model(scene: dict) -> list[dict]:
    """The room's true scene graph (FORMAT.md nodes), read off the objects build_scene rendered.

    Values are rounded to 1e-12 (see _c); the tests hold every handle to its rendered corner within 1e-9.
    """
    X, Y, _ = ROOM
    floor_c = np.array([X / 2, Y / 2, 0.0])  # the floor's top-face frame: its centre, axes +x, +y
    obj = {o["name"]: o for o in scene["objects"]}

    def box(name):
        w, d, h = obj[name]["size"]
        return {"type": "box", "params": {"width": _c(w), "depth": _c(d), "height": _c(h)}}

    def bottom(name):
        return np.array(obj[name]["centre"]) - [0.0, 0.0, obj[name]["size"][2] / 2]

    def on_floor(name):
        b = bottom(name) - floor_c
        assert abs(b[2]) < 1e-12, f"{name} does not stand on the floor"
        return {"type": "rests_on", "face": "top", "position": _c(b[:2]), "yaw_deg": _c(obj[name]["yaw_deg"])}

    table_c = np.array([TABLE_CENTRE[0], TABLE_CENTRE[1], 0.0])
    nodes = [
        {"name": "floor", "primitive": {"type": "quad", "params": {"width": X, "depth": Y}},
         "joint": {"type": "marker", "marker": "O", "handle": "v0", "yaw_deg": 0.0}},
        {"name": "cabinet", "parent": "floor", "primitive": box("cabinet"), "joint": on_floor("cabinet")},
        {"name": "box", "parent": "floor", "primitive": box("box"), "joint": on_floor("box")},
        {"name": "table", "parent": "floor",
         "joint": {"type": "rests_on", "face": "top", "position": _c((table_c - floor_c)[:2]), "yaw_deg": 0.0}},
    ]
    for part in ("table.top", "table.leg1", "table.leg2", "table.leg3", "table.leg4"):
        assert obj[part]["yaw_deg"] == 0.0
        nodes.append({"name": part, "parent": "table", "primitive": box(part),
                      "joint": {"type": "fixed", "translation": _c(bottom(part) - table_c),
                                "rotation_deg": [0.0, 0.0, 0.0]}})
    # The door as rendered is open by ajar_deg; its pose at angle 0 turns it back about the hinge.
    door = obj["door"]
    hinge = np.array(door["hinge"])
    shut = _axis_rotation(DOOR_HINGE_AXIS, -door["ajar_deg"])
    nodes.append({"name": "door", "parent": "floor", "primitive": box("door"),
                  "joint": {"type": "hinge", "axis_point": _c(hinge - floor_c), "axis": list(DOOR_HINGE_AXIS),
                            "translation": _c(hinge + shut @ (bottom("door") - hinge) - floor_c),
                            "rotation_deg": [0.0, 0.0, _c(door["yaw_deg"] + door["ajar_deg"])],
                            "angle_deg": _c(door["ajar_deg"]), "limits_deg": list(DOOR_LIMITS_DEG)}})
    nodes += true_walls(scene)
    return nodes


def true_walls(scene: dict) -> list[dict]:
    """The walls' nodes (WALL_NODES), read off the wall quads build_scene rendered: a box WALL_THICK
    thick behind each, its front face (local −y) the quad itself, toward the room, its local +x left
    to right as seen from the room. The west, north and east walls rest on the floor; the south wall is a group
    resting on the floor (its origin at the floor-level centre line of the whole wall, turned as its
    pieces are) whose pieces beside and above the doorway are fixed in it."""
    X, Y, _ = ROOM
    floor_c = np.array([X / 2, Y / 2, 0.0])
    quads = {q["name"]: q for q in scene["quads"]}

    def wall(name):
        """(primitive, bottom centre, yaw in degrees) of the box behind the quad ``name``."""
        q = quads[name]
        e1, e2, n = q["edge1"], q["edge2"], q["normal"]
        assert abs(e1[2]) < 1e-12 and abs(e2[0]) + abs(e2[1]) < 1e-12 and e2[2] > 0, f"{name} is not upright"
        prim = {"type": "box", "params": {"width": _c(np.linalg.norm(e1)), "depth": WALL_THICK, "height": _c(e2[2])}}
        centre = q["corner"] + e1 / 2 - n * (WALL_THICK / 2)
        yaw = math.degrees(math.atan2(n[0] + 0.0, -n[1] + 0.0))  # turns local −y onto n (+ 0.0: no −0.0)
        return prim, centre, yaw

    nodes = []
    for name in ("wall_west", "wall_north", "wall_east"):
        prim, centre, yaw = wall(name)
        nodes.append({"name": name, "parent": "floor", "primitive": prim,
                      "joint": {"type": "rests_on", "face": "top", "position": _c((centre - floor_c)[:2]),
                                "yaw_deg": _c(yaw)}})
    south, south_yaw = np.array([X / 2, -WALL_THICK / 2, 0.0]), 180.0
    nodes.append({"name": "wall_south", "parent": "floor",
                  "joint": {"type": "rests_on", "face": "top", "position": _c((south - floor_c)[:2]),
                            "yaw_deg": south_yaw}})
    for part in ("west", "east", "lintel"):
        prim, centre, yaw = wall(f"wall_south.{part}")
        assert yaw == south_yaw
        nodes.append({"name": f"wall_south.{part}", "parent": "wall_south", "primitive": prim,
                      "joint": {"type": "fixed", "translation": _c(_axis_rotation((0, 0, 1), -yaw) @ (centre - south)),
                                "rotation_deg": [0.0, 0.0, 0.0]}})
    assert [n["name"] for n in nodes] == list(WALL_NODES)
    return nodes


def rough_model(nodes: list[dict], rng: np.random.Generator) -> list[dict]:
    """The starting values a user has after dropping each primitive onto the photos.

    Sizes are off by 10–25 %, rests_on positions by 10–25 % of the object's extent, yaws by 5–10°
    and the hinge angle by 8–12°, each in a random sense. Fixed joints and a hinge's axis and shut
    pose are kept: they have no degree of freedom, so a wrong value there could never be solved
    away (the user states them as the object's known make-up). Every node draws the same numbers
    whatever its kind, so the streams stay stable. The walls (WALL_NODES) are placed at their
    measured values and marked "solve": false.
    """
    out = json.loads(json.dumps(nodes))
    extent = {n["name"]: max(n["primitive"]["params"]["width"], n["primitive"]["params"]["depth"])
              for n in nodes if n.get("primitive")}
    extent["table"] = extent["table.top"]
    for n in out:
        rel = rng.uniform(*ROUGH_SIZE_REL, 3) * rng.choice([-1.0, 1.0], 3)
        shift, phi = rng.uniform(*ROUGH_SIZE_REL), rng.uniform(0.0, 2 * math.pi)
        dyaw = rng.uniform(*ROUGH_YAW_DEG) * rng.choice([-1.0, 1.0])
        dhinge = rng.uniform(*ROUGH_HINGE_DEG) * rng.choice([-1.0, 1.0])
        if n["name"] in WALL_NODES:
            n["solve"] = False
            continue
        prim, j = n.get("primitive"), n["joint"]
        if prim is not None:
            for k, key in enumerate(prim["params"]):
                prim["params"][key] = round(prim["params"][key] * (1 + rel[k]), 3)
        if j["type"] == "rests_on":
            s, t = j["position"]
            r = shift * extent[n["name"]]
            j["position"] = [round(s + r * math.cos(phi), 3), round(t + r * math.sin(phi), 3)]
        if j["type"] in ("rests_on", "marker"):
            j["yaw_deg"] = round(j["yaw_deg"] + dyaw, 1)
        if j["type"] == "hinge":
            lo, hi = j["limits_deg"]
            j["angle_deg"] = round(min(max(j["angle_deg"] + dhinge, lo), hi), 1)
    # The legs' heights show in no photo (the top hides their upper ends and every camera stands
    # above the table), so the user states what is known: each leg reaches the top, so it holds
    # its height at the top's offset above the floor (a known dimension, not a guess).
    top_z = next(n for n in nodes if n["name"] == "table.top")["joint"]["translation"][2]
    for n in out:
        if n["name"].startswith("table.leg"):
            n["primitive"]["params"]["height"] = top_z
            n["hold"] = ["height"]
    return out


def pinnable(scene: dict, cam: dict, prim: dict, handles: dict[str, np.ndarray]) -> dict[str, bool]:
    """Which handles a careful user would drag onto this photo: the corner is visible (at least
    IMAGE_MARGIN_PX inside the image, nothing more than VISIBILITY_EPS_M nearer on its ray), so
    are points PIN_PROBE_M along at least two of its edges (else the corner cannot be made out),
    and no other such corner of the primitive projects within PIN_MIN_SEP_PX of it (the two ends
    of a thin edge seen end-on cannot be told apart: the door's free edge from p3)."""
    names = list(handles)
    probes, owner = [], []
    for a, b in primitive_edges(prim).values():
        d = handles[b] - handles[a]
        step = min(PIN_PROBE_M, 0.25 * float(np.linalg.norm(d))) * d / np.linalg.norm(d)
        probes += [handles[a] + step, handles[b] - step]
        owner += [a, b]
    pts = np.array([handles[h] for h in names] + probes)
    vis = visible(scene, cam, pts, IMAGE_MARGIN_PX * cam["width"] / BASE_WIDTH)
    seen = dict(zip(names, vis[:len(names)], strict=True))
    n_edges = {h: 0 for h in names}
    for h, ok in zip(owner, vis[len(names):], strict=True):
        n_edges[h] += int(ok)
    ok = {h: bool(seen[h] and n_edges[h] >= 2) for h in names}
    uv, _ = project(cam, pts[:len(names)])
    sep = PIN_MIN_SEP_PX * cam["width"] / BASE_WIDTH
    crowded = {h for i, h in enumerate(names) for j, o in enumerate(names)
               if i != j and ok[h] and ok[o] and np.linalg.norm(uv[i] - uv[j]) < sep}
    return {h: ok[h] and h not in crowded for h in names}


def choose_pins(scene: dict, cams: list[dict], nodes: list[dict]) -> list[dict]:
    """Every handle a careful user would pin, photo k's clicks from the stream default_rng([SEED, 1, k])
    (N(0, 0.7 px · scale) per coordinate, drawn for every handle so that the streams stay stable).
    The walls, placed from measurements, take none (they come last, so no stream moves)."""
    handles = model_handles_world(nodes, scene_markers(scene))
    pins = []
    for k, cam in enumerate(cams):
        rng = np.random.default_rng([SEED, 1, k])
        sigma = CLICK_SIGMA_PX * cam["width"] / BASE_WIDTH
        for n in nodes:
            if n.get("primitive") is None or n["name"] in WALL_NODES:
                continue
            hw = handles[n["name"]]
            uv, _ = project(cam, np.array(list(hw.values())))
            uv = uv + rng.normal(0.0, sigma, uv.shape)
            ok = pinnable(scene, cam, n["primitive"], hw)
            pins += [{"photo": cam["id"], "node": n["name"], "handle": h, "uv": rounded(uv[i]), "fixed": True}
                     for i, h in enumerate(hw) if ok[h]]
    return pins


def _segment_distance(p, a, b) -> float:
    """Distance of image point p from the segment a–b."""
    d = b - a
    s = min(max(float((p - a) @ d / (d @ d)), 0.0), 1.0)
    return float(np.linalg.norm(p - (a + s * d)))


def choose_edge_observations(scene: dict, cams: list[dict], nodes: list[dict]) -> list[dict]:
    """For each EDGE_OBSERVATION_CANDIDATES edge, two clicks (at 10 % and 90 % of its longest visible
    run) in the photo where that run is longest, if it is at least SEGMENT_MIN_PX long and no other
    visible edge of the primitive passes within PIN_MIN_SEP_PX of its middle (a thin edge face seen
    obliquely shows two lines a user could not tell apart); noise from the stream
    default_rng([SEED, 2]), drawn for every candidate."""
    handles = model_handles_world(nodes, scene_markers(scene))
    prims = {n["name"]: n.get("primitive") for n in nodes}
    rng = np.random.default_rng([SEED, 2])
    out = []
    for node, edge in EDGE_OBSERVATION_CANDIDATES:
        edges = primitive_edges(prims[node])
        noise = rng.normal(0.0, CLICK_SIGMA_PX, (2, 2))
        best = None
        for cam in cams:
            scale = cam["width"] / BASE_WIDTH
            runs = {e: longest_visible_run(scene, cam, handles[node][a], handles[node][b], IMAGE_MARGIN_PX * scale)
                    for e, (a, b) in edges.items()}
            if runs[edge] is None:
                continue
            X = np.array([runs[edge][0] + f * (runs[edge][1] - runs[edge][0]) for f in (0.1, 0.5, 0.9)])
            uv, _ = project(cam, X)
            length = float(np.linalg.norm(uv[2] - uv[0]) / 0.8)
            near = [e for e, r in runs.items() if e != edge and r is not None
                    and _segment_distance(uv[1], *project(cam, np.array(r))[0]) < PIN_MIN_SEP_PX * scale]
            if length >= SEGMENT_MIN_PX * scale and not near and (best is None or length > best[0]):
                best = (length, cam, uv[[0, 2]] + noise * scale)
        if best is not None:
            out.append({"photo": best[1]["id"], "node": node, "edge": edge, "points": [rounded(x) for x in best[2]]})
    return out


def model_json(scene: dict, cams: list[dict]) -> dict:
    """The project's model: the user's rough nodes, pins and edge observations (FORMAT.md)."""
    truth = true_model(scene)
    return {"nodes": rough_model(truth, np.random.default_rng([SEED, 3])),
            "pins": choose_pins(scene, cams, truth),
            "edge_observations": choose_edge_observations(scene, cams, truth)}


def check_model_coverage(model: dict, truth_nodes: list[dict]) -> None:
    """Every primitive but the legs is pinned in ≥ 2 photos with ≥ 3 distinct handles, spanning
    both signs of local x and y, and a box has a top handle too. At least two legs have ≥ 3 handles
    spanning x and y: their tops hide under the table top, and most photos frame them out, but a
    leg's bottom corners lie on the floor, so one photo places them. The walls, placed from
    measurements ("solve": false), take no pins at all."""
    prims = {n["name"]: n["primitive"] for n in truth_nodes if n.get("primitive") and n["name"] not in WALL_NODES}
    if any(p["node"] in WALL_NODES for p in model["pins"]):
        raise AssertionError("a wall is pinned; the walls are placed from measurements")
    if any(n.get("solve", True) for n in model["nodes"] if n["name"] in WALL_NODES):
        raise AssertionError('every wall node must be "solve": false')
    legs_ok = 0
    for name, prim in prims.items():
        pins = [p for p in model["pins"] if p["node"] == name]
        local = primitive_handles(prim)
        hs = {p["handle"] for p in pins}
        problems = []
        if len({p["photo"] for p in pins}) < (1 if name.startswith("table.leg") else 2) or len(hs) < 3:
            problems.append(f"{len(hs)} handles in {len({p['photo'] for p in pins})} photos")
        for k, axis in ((0, "x"), (1, "y")):
            if len({np.sign(local[h][k]) for h in hs}) < 2:
                problems.append(f"no span along local {axis}")
        if prim["type"] == "box" and not any(local[h][2] > 0 for h in hs) and not name.startswith("table.leg"):
            problems.append("no top handle")
        if name.startswith("table.leg"):
            legs_ok += not problems
        elif problems:
            raise AssertionError(f"model node {name}: " + "; ".join(problems))
    if legs_ok < 2:
        raise AssertionError(f"only {legs_ok} table legs are pinned well enough, expected >= 2")


