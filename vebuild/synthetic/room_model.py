"""A generated room (vebuild.synthetic.rooms) as a project file's model: the truth and a user's
first guess as FORMAT.md nodes and relations, and the user's marks on the model (pins on the handles
each photo shows, edge observations on the stretches of the room's edges whose ends it does not).

The nodes: the room (a rectilinear six-corner room with its doorway and window) tied to the origin
marker by the foot of the doorway's jamb away from the hinge; the door leaf on a hinge at its jamb, its axis solved
(``solve_axis``); the cabinet and the row's units resting on the room's floor, each with a ``flush``
relation putting its back against its wall, and ``equal`` relations making the units one size.

:func:`room_scene` draws a whole room: its geometry (vebuild.synthetic.rooms), its photos
(vebuild.synthetic.room_photos), the true model, the first guess and the marks.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.model.joints import ModelError
from vebuild.model.scene import model_from_dict
from vebuild.project import load_project, save_project

from . import CLICK_NOISE_PX, write_project
from .room_photos import photograph
from .rooms import LEAF_TAPE_SIGMA_M, THICKNESS_TAPE_SIGMA_M, Box, RoomScene, room_geometry

Array = NDArray[np.float64]

#: How far a user's first guess of a turn is off (degrees, either sign, uniform): a room or a
#: cabinet is set square to the vanishing lines' axes by eye.
GUESS_YAW_DEG = (2.0, 5.0)
#: The hinge's stops: a leaf opening into the room turns from shut (0) to 120°.
HINGE_LIMITS_DEG = (0.0, 120.0)
#: Where on an edge's seen stretch a user clicks its two points (shares of the stretch from each end).
EDGE_CLICK_AT = (0.1, 0.9)


def _local(scene: RoomScene, b: Box) -> tuple[list[float], float]:
    """A box's rests_on position on the room's floor (the room's own x, y: the floor's frame is the
    room's origin, FORMAT.md) and its yaw in degrees."""
    return [float(v) for v in (b.centre[:2] - scene.origin[:2])], float(np.degrees(b.yaw))


def room_params(scene: RoomScene) -> dict[str, float]:
    """The room primitive's params (FORMAT.md's order) from the scene's own geometry."""
    c = scene.corners
    p = {"c1_x": c[1, 0], "c2_y": c[2, 1], "c3_x": c[3, 0], "c4_y": c[4, 1], "height": scene.height,
         "thickness": scene.thickness}
    for o in scene.openings:
        p.update({f"{o.name}_offset": o.offset, f"{o.name}_width": o.width, f"{o.name}_height": o.height,
                  f"{o.name}_sill": o.sill})
    return {k: float(v) for k, v in p.items()}


def _box(b: Box) -> dict[str, Any]:
    return {"type": "box", "params": {"width": float(b.size[0]), "depth": float(b.size[1]),
                                      "height": float(b.size[2])}}


def true_nodes(scene: RoomScene) -> list[dict[str, Any]]:
    """The true model as FORMAT.md nodes (no holds: the truth)."""
    hg = scene.hinge
    nodes: list[dict[str, Any]] = [
        {"name": "room", "primitive": {"type": "room", "corners": len(scene.corners), "rectilinear": True,
                                       "ceiling": False, "params": room_params(scene),
                                       "openings": [{"name": o.name, "wall": o.wall, "kind": o.kind}
                                                    for o in scene.openings]},
         "joint": {"type": "marker", "marker": "O", "handle": scene.origin_handle,
                   "yaw_deg": 0.0}},
        {"name": "door", "parent": "room", "primitive": _box(scene.leaf),
         "joint": {"type": "hinge", "jamb": {"opening": "door", "side": hg.side},
                   "axis_point": [float(v) for v in hg.axis_point], "axis": [float(v) for v in hg.axis],
                   "translation": [float(v) for v in hg.shut_centre], "rotation_deg": [0.0, 0.0, 0.0],
                   "angle_deg": float(np.degrees(hg.angle)), "limits_deg": list(HINGE_LIMITS_DEG),
                   "solve_axis": True}}]
    for b in [scene.cabinet, *scene.row]:
        pos, yaw = _local(scene, b)
        nodes.append({"name": b.name, "parent": "room", "primitive": _box(b),
                      "joint": {"type": "rests_on", "face": "floor", "position": pos, "yaw_deg": yaw}})
    return nodes


def relations(scene: RoomScene) -> list[dict[str, Any]]:
    """The cabinet's and the units' backs flush against their walls; the units of one size."""
    out: list[dict[str, Any]] = [{"type": "flush", "a": "cabinet:back", "b": f"room:wall{scene.cabinet_wall}"}]
    out += [{"type": "flush", "a": f"{b.name}:back", "b": f"room:wall{scene.row_wall}"} for b in scene.row]
    out += [{"type": "equal", "params": [f"{b.name}.{p}" for b in scene.row]} for p in ("width", "depth", "height")]
    return out


def _off(rng: np.random.Generator, v: float, rel: tuple[float, float]) -> float:
    """v off by rel (uniform in the range, either sign)."""
    return float(v * (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(*rel)))


#: First guesses drawn until one is a valid room (its openings inside its walls, under its height):
#: a user's first model is one vebuild accepts.
GUESS_ATTEMPTS = 200


def guessed_nodes(rng: np.random.Generator, scene: RoomScene, guess_rel: tuple[float, float]) -> list[dict[str, Any]]:
    """:func:`guessed_node_draw` until the room it guesses is valid (GUESS_ATTEMPTS)."""
    for _ in range(GUESS_ATTEMPTS):
        nodes = guessed_node_draw(rng, scene, guess_rel)
        try:
            model_from_dict(list(nodes), {"O": np.zeros(3)}, relations(scene))
        except (ModelError, ValueError):
            continue
        return nodes
    raise RuntimeError(f"no valid first guess in {GUESS_ATTEMPTS} draws")


def guessed_node_draw(rng: np.random.Generator, scene: RoomScene, guess_rel: tuple[float, float]
                      ) -> list[dict[str, Any]]:
    """A user's first model: every size and position guess_rel off (relative, either sign), turns
    GUESS_YAW_DEG off, the hinge's axis at the jamb's corner ([0, 0, 0]); the doorway's sill held at
    0 (a doorway has none), the walls' and the leaf's thicknesses entered from a tape (their faces'
    far sides no photo shows). The leaf's shut pose (the hinge's pose at angle 0) is the user's
    statement of where the leaf sits when shut, in the doorway with its face on the wall's inner
    face: it is kept (solve_axis finds the axis from the leaf seen open, given the shut pose)."""
    nodes = true_nodes(scene)
    room = nodes[0]
    params = room["primitive"]["params"]
    tape = scene.tapes["thickness"]
    for k in params:
        if k == "thickness":
            params[k] = tape
        elif k != "door_sill":
            params[k] = _off(rng, params[k], guess_rel)
    room["joint"]["yaw_deg"] = float(rng.choice([-1.0, 1.0]) * rng.uniform(*GUESS_YAW_DEG))
    room["hold"] = ["door_sill", {"name": "thickness", "sigma": THICKNESS_TAPE_SIGMA_M, "value": tape}]
    door = nodes[1]
    leaf = door["primitive"]["params"]
    leaf_tape = scene.tapes["leaf_depth"]
    leaf.update(width=_off(rng, leaf["width"], guess_rel), height=_off(rng, leaf["height"], guess_rel),
                depth=leaf_tape)
    door["hold"] = [{"name": "depth", "sigma": LEAF_TAPE_SIGMA_M, "value": leaf_tape}]
    door["joint"]["angle_deg"] = _off(rng, door["joint"]["angle_deg"], guess_rel)
    door["joint"]["axis_point"] = [0.0, 0.0, 0.0]
    for node in nodes[2:]:
        node["primitive"]["params"] = {k: _off(rng, v, guess_rel) for k, v in node["primitive"]["params"].items()}
        node["joint"]["position"] = [_off(rng, v, guess_rel) for v in node["joint"]["position"]]
        node["joint"]["yaw_deg"] += float(rng.choice([-1.0, 1.0]) * rng.uniform(*GUESS_YAW_DEG))
    return nodes


def marks(rng: np.random.Generator, scene: RoomScene, noise_px: float = CLICK_NOISE_PX) -> tuple[list, list]:
    """(pins, edge observations) a careful user makes: every handle a photo shows is pinned (on the
    distorted photo, noise_px 1σ), except the origin marker's (marked as a marker); each room edge
    whose seen stretch is long enough (MIN_STRETCH_PX) and whose ends the photo does not both show
    gets two clicks on that stretch (EDGE_CLICK_AT)."""
    pts = scene.seen_points()
    keys = [k for k in pts if k != ("room", scene.origin_handle)]
    pins, edges = [], []
    for photo in scene.photos:
        seen, uv = scene.visible(photo, np.array([pts[k] for k in keys]))
        shown = set()
        for (node, handle), s, p in zip(keys, seen, uv, strict=True):
            if s:
                shown.add((node, handle))
                pins.append({"photo": photo.id, "node": node, "handle": handle,
                             "uv": [float(v) for v in p + rng.normal(0.0, noise_px, 2)], "fixed": True})
        for e, stretch in scene.edge_stretches(photo).items():
            ha, hb = scene.edges()[e]
            if stretch is None or (("room", ha) in shown and ("room", hb) in shown):
                continue
            a, b = stretch
            X = np.array([a + t * (b - a) for t in EDGE_CLICK_AT])
            _, uv = scene.visible(photo, X)
            edges.append({"photo": photo.id, "node": "room", "edge": e,
                          "points": [[float(v) for v in q + rng.normal(0.0, noise_px, 2)] for q in uv]})
    return pins, edges


def write_room_project(folder: Path, scene: RoomScene, nodes: list[dict[str, Any]], pins: list, edges: list) -> Path:
    """The generated room's project (vebuild.synthetic.write_project: photos, markers, the taped
    scale) with the model ``nodes``, the scene's relations and the marks. Returns its path."""
    path = write_project(folder, scene.photos, scene.markers)
    project = load_project(path)
    project.data["model"] = {"nodes": nodes, "relations": relations(scene), "pins": pins, "edge_observations": edges}
    save_project(path, project.data)
    return path


#: Rooms drawn before giving up: a drawn room whose photos cannot show everything without a floor
#: corner (room_photos.photograph) is drawn again from the same stream.
ROOM_ATTEMPTS = 8


@dataclass
class GeneratedRoom:
    """A generated room (:func:`room_scene`): the scene, the true model (FORMAT.md nodes and
    relations), the user's first guess, and the marks on the model (pins, edge observations)."""

    scene: RoomScene
    truth: dict
    guess: list
    pins: list
    edges: list

    def write(self, folder, guess: bool = True):
        """The project file (the guessed model, or with ``guess`` false the true one); its path."""
        return write_room_project(folder, self.scene, self.guess if guess else self.truth["nodes"], self.pins,
                                  self.edges)

    def with_fresh_noise(self, rng: np.random.Generator, noise_px: float) -> GeneratedRoom:
        """The same room, photos and first guess with every click drawn again: noise_px (1σ) added
        to each vanishing-segment point, marker sighting, pin and edge click, and both tapes drawn
        again from the true thicknesses. Only meaningful on a room drawn with exact clicks
        (room_scene's ``noise_px=0``): the noise is added to the clicks as they are. Repeated
        draws on one room measure its intervals' coverage over the noise alone."""
        g = copy.deepcopy(self)
        for cam in g.scene.photos:
            cam.markers = {m: uv + rng.normal(0.0, noise_px, 2) for m, uv in cam.markers.items()}
            for axis, segs in cam.segments.items():
                cam.segments[axis] = (segs + rng.normal(0.0, noise_px, segs.shape) if isinstance(segs, np.ndarray)
                                      else [s + rng.normal(0.0, noise_px, s.shape) for s in segs])
        for pin in g.pins:
            pin["uv"] = [float(v) for v in np.asarray(pin["uv"]) + rng.normal(0.0, noise_px, 2)]
        for e in g.edges:
            e["points"] = [[float(v) for v in np.asarray(q) + rng.normal(0.0, noise_px, 2)] for q in e["points"]]
        tapes = {"thickness": g.scene.thickness + rng.normal(0.0, THICKNESS_TAPE_SIGMA_M),
                 "leaf_depth": float(g.scene.leaf.size[1]) + rng.normal(0.0, LEAF_TAPE_SIGMA_M)}
        g.scene.tapes = {k: float(v) for k, v in tapes.items()}
        for node in g.guess:
            key, param = {"room": ("thickness", "thickness"), "door": ("leaf_depth", "depth")}.get(node["name"],
                                                                                                (None, None))
            if key is None:
                continue
            node["primitive"]["params"][param] = g.scene.tapes[key]
            for h in node["hold"]:
                if isinstance(h, dict) and h["name"] == param:
                    h["value"] = g.scene.tapes[key]
        return g


def room_scene(rng: np.random.Generator, guess_rel: tuple[float, float] = (0.10, 0.25),
               noise_px: float | None = None) -> GeneratedRoom:
    """A generated L-shaped room (room_geometry), photographed from inside with no photo seeing a
    floor corner, marked as a careful user would (clicks with noise_px 1σ, vebuild.synthetic's
    CLICK_NOISE_PX unless given), with a first guess guess_rel off. The stream of ``rng`` does not
    depend on noise_px: ``noise_px=0`` gives the same room, photos and guess with exact clicks."""
    noise = CLICK_NOISE_PX if noise_px is None else noise_px
    for _ in range(ROOM_ATTEMPTS):
        scene = room_geometry(rng)
        try:
            photograph(rng, scene, noise_px=noise)
        except RuntimeError:
            continue
        pins, edges = marks(rng, scene, noise)
        return GeneratedRoom(scene, {"nodes": true_nodes(scene), "relations": relations(scene)},
                             guessed_nodes(rng, scene, guess_rel), pins, edges)
    raise RuntimeError(f"no room drawn in {ROOM_ATTEMPTS} tries could be photographed without a floor corner")
