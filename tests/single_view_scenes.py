"""Generated one-photo scenes for the single-view measurements of a wall, a raised surface and a
marked plane (tests/test_single_view_kinds.py): a hand-held camera 1.2–1.9 m above the floor,
looking 12–35° down, with a 2 m door (the known length), a wall, a table with something standing
on it, and a plane marked by three points (a ramp, a table top or a wall), each measurement's
clicks with the clicks' noise, and the truth of each."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.actions.calibrate import calibrate_project
from vebuild.camera import rotation_from_ypr
from vebuild.project import Project, load_project, save_project
from vebuild.synthetic import CLICK_NOISE_PX, add_segments, projection_matrix, random_camera, write_project

W, H = 1600, 1200
DOOR_M = 2.0  # the known length: a door's height
DOOR_SIGMA_M = 0.002  # its tape's 1σ
UP = np.array([0.0, 0.0, 1.0])


@dataclass
class Scene:
    """A generated photo: its camera, the world points (the generator's frame), the clicks of each
    kind's measurement (in :data:`SINGLE_VIEW_CLICKS` order) and the truth each should give."""

    cam: Any
    points: dict[str, np.ndarray]
    marks: dict[str, np.ndarray] = field(default_factory=dict)  # the calibration's clicks: markers, door
    clicks: dict[str, list[np.ndarray]] = field(default_factory=dict)
    names: dict[str, list[str]] = field(default_factory=dict)  # the points each kind's clicks show, in order
    truth: dict[str, float] = field(default_factory=dict)
    plane: str = ""  # what the plane-length's plane is: a ramp, a table top or a wall


def pixel(cam: Any, X: np.ndarray) -> np.ndarray:
    """The pixel of world point ``X`` in ``cam`` (a pinhole); ValueError behind the camera."""
    h = projection_matrix(cam.K, cam.R, cam.C) @ np.r_[X, 1.0]
    if not h[2] > 0.5:
        raise ValueError("a point behind the camera")
    return np.asarray(h[:2] / h[2], float)


def scene(rng: np.random.Generator, noise_px: float = CLICK_NOISE_PX) -> Scene:
    """One generated scene whose every point lies on the photo (at least 5 px inside)."""
    for _ in range(500):
        cam = random_camera(rng, "3vp", W, H)
        yaw = rng.uniform(0, 2 * np.pi)
        cam.R = rotation_from_ypr(yaw, -np.radians(rng.uniform(12, 35)), np.radians(rng.normal(0, 2)))
        fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        side = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        base = cam.C * [1, 1, 0]

        def ahead(d: float, s: float, z: float = 0.0, base: np.ndarray = base, fwd: np.ndarray = fwd,
                  side: np.ndarray = side) -> np.ndarray:
            return base + d * fwd + s * side + z * UP

        pts: dict[str, np.ndarray] = {"O": ahead(rng.uniform(2.5, 4.0), rng.uniform(-0.8, 0.8)),
                                      "F1": ahead(rng.uniform(2.0, 5.0), rng.uniform(-1.5, 1.5))}
        door = ahead(rng.uniform(3.0, 5.0), rng.uniform(-1.2, 1.2))
        pts.update(door_foot=door, door_top=door + DOOR_M * UP)
        truth: dict[str, float] = {}
        ids: dict[str, list[str]] = {}

        # A wall 4–6 m ahead, turned up to 40° from facing the camera; a length between two points on it.
        turn = np.radians(rng.uniform(-40, 40))
        along = np.cos(turn) * side + np.sin(turn) * fwd
        wc = ahead(rng.uniform(4.0, 6.0), rng.uniform(-0.5, 0.5))
        pts.update(wall_a=wc - rng.uniform(0.8, 1.6) * along, wall_b=wc + rng.uniform(0.8, 1.6) * along,
                   wall_p=wc + rng.uniform(-1.4, 1.4) * along + rng.uniform(0.2, 2.2) * UP,
                   wall_q=wc + rng.uniform(-1.4, 1.4) * along + rng.uniform(0.2, 2.2) * UP)
        ids["wall-length"] = ["wall_a", "wall_b", "wall_p", "wall_q"]
        truth["wall-length"] = float(np.linalg.norm(pts["wall_p"] - pts["wall_q"]))

        # A table top 0.5–1.0 m high, 2.5–4 m ahead; a point of its edge over the floor; something
        # 0.15–0.6 m tall standing on it.
        h0 = rng.uniform(0.5, 1.0)
        tc = ahead(rng.uniform(2.5, 4.0), rng.uniform(-1.0, 1.0), h0)
        edge = tc + rng.uniform(-0.4, 0.4) * side - 0.3 * fwd
        stand = tc + rng.uniform(-0.3, 0.3) * side + rng.uniform(-0.2, 0.2) * fwd
        tall = rng.uniform(0.15, 0.6)
        pts.update(edge_foot=edge - h0 * UP, edge=edge, stand_foot=stand, stand_top=stand + tall * UP)
        ids["raised-height"] = ["edge_foot", "edge", "stand_foot", "stand_top"]
        truth["raised-height"] = tall

        # A plane marked by three points, each over its floor point (itself, on the floor).
        kind = str(rng.choice(["ramp", "table", "wall"]))
        d, s = rng.uniform(2.5, 4.0), rng.uniform(-0.8, 0.8)
        if kind == "ramp":  # two lower corners on the floor, an upper corner 0.2–0.8 m up, 1–2 m on
            X = [ahead(d, s - 0.6), ahead(d, s + 0.6), ahead(d + rng.uniform(1.0, 2.0), s + rng.uniform(-0.6, 0.6),
                                                            rng.uniform(0.2, 0.8))]
        elif kind == "table":  # three corners of a top 0.5–1.0 m high, each over its leg's foot
            z = rng.uniform(0.5, 1.0)
            X = [ahead(d, s - 0.5, z), ahead(d, s + 0.5, z), ahead(d + 0.8, s + rng.uniform(-0.5, 0.5), z)]
        else:  # a wall facing the camera: two points at its foot, a third 1.8–2.2 m up it
            X = [ahead(d + 1.5, s - 1.0), ahead(d + 1.5, s + 1.0),
                 ahead(d + 1.5, s + rng.uniform(-0.8, 0.8), rng.uniform(1.8, 2.2))]
        for k, x in enumerate(X):
            pts[f"plane_{k}_foot"], pts[f"plane_{k}"] = x * [1, 1, 0], x
        u, v = X[1] - X[0], X[2] - X[0]
        ends = [X[0] + a * u + b * v for a, b in rng.uniform(0.0, 0.6, (2, 2))]
        pts.update(plane_p=ends[0], plane_q=ends[1])
        ids["plane-length"] = [*(f"plane_{k}{e}" for k in range(3) for e in ("_foot", "")), "plane_p", "plane_q"]
        truth["plane-length"] = float(np.linalg.norm(ends[0] - ends[1]))
        try:
            uv = {n: pixel(cam, X) for n, X in pts.items()}
        except ValueError:
            continue
        if not all(5 < u < W - 5 and 5 < v < H - 5 for u, v in uv.values()):
            continue
        add_segments(cam, rng, noise_px)
        sc = Scene(cam, pts, names=ids, truth=truth, plane=kind)
        sc.marks = {n: uv[n] + rng.normal(0.0, noise_px, 2) for n in ("O", "F1", "door_foot", "door_top")}
        for k, names in ids.items():  # each click its own, a point clicked twice (its foot) with two errors
            sc.clicks[k] = [uv[n] + rng.normal(0.0, noise_px, 2) for n in names]
        return sc
    raise RuntimeError("no camera sees the whole scene")


def calibrated(folder: Path, sc: Scene) -> Project:
    """The one-photo project of ``sc`` written to ``folder`` and calibrated as `vebuild calibrate`
    does: two floor markers (O the origin) and the door's height the known length."""
    path = write_project(folder, [sc.cam], {n: sc.points[n] for n in ("O", "F1")})
    project = load_project(path)
    d = project.data
    d["photos"][0]["marker_observations"] = {n: [float(v) for v in sc.marks[n]] for n in ("O", "F1")}
    d["markers"] = [{"name": n, "on_floor": True} for n in ("O", "F1")]
    d["origin_marker"] = "O"
    d["reference_distances"] = []
    d["known_lengths"] = [{"photo": sc.cam.id, "axis": "z", "floor_end": 0, "length": DOOR_M, "sigma": DOOR_SIGMA_M,
                           "ends": [[float(v) for v in sc.marks["door_foot"]],
                                    [float(v) for v in sc.marks["door_top"]]]}]
    calibrate_project(project)
    save_project(project)
    return project
