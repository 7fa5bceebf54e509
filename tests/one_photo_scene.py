"""One generated photo of a room (vebuild.synthetic: its own projection, P = K [R | −RC]): the
camera, the clicks a careful user makes, a box resting on the floor, and the one-photo project
written from them (tests/test_single_photo.py and the tests built on it)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.camera import rotation_from_ypr
from vebuild.project import load_project, save_project
from vebuild.synthetic import CLICK_NOISE_PX, add_segments, projection_matrix, random_camera, write_project

W, H = 1600, 1200
DOOR_M = 2.0  # a door's height, the known length
BOX_M = 0.9  # the height measured


@dataclass
class OnePhoto:
    """A generated photo of a room: the camera, the clicks a careful user makes, and the truth in the
    frame calibration puts it in (origin at the floor point O)."""

    cam: Any
    origin: np.ndarray  # the origin's floor point in the generator's frame
    points: dict[str, np.ndarray]  # named world points (generator's frame)
    clicks: dict[str, np.ndarray] = field(default_factory=dict)

    def truth(self, name: str) -> np.ndarray:
        return self.points[name] - self.origin

    @property
    def C(self) -> np.ndarray:
        return self.cam.C - self.origin


def pixels(cam: Any, X: np.ndarray) -> np.ndarray:
    h = projection_matrix(cam.K, cam.R, cam.C) @ np.r_[X, 1.0]
    assert h[2] > 0.5, "a point behind the camera"
    return h[:2] / h[2]


def one_photo(rng: np.random.Generator, noise_px: float = CLICK_NOISE_PX, level: bool = False) -> OnePhoto:
    """A camera 1.2–1.9 m above the floor looking 12–35° down (or level, a 2vp view) at a room's
    corner region, with a door's foot and top, a box's foot and top, and three floor markers ahead."""
    for _ in range(200):
        cam = random_camera(rng, "2vp" if level else "3vp", W, H)
        yaw = rng.uniform(0, 2 * np.pi)
        pitch = -np.radians(rng.uniform(1.0, 2.5) if level else rng.uniform(12, 35))
        cam.R = rotation_from_ypr(yaw, pitch, np.radians(rng.normal(0, 2)))
        fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        side = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
        base = cam.C * [1, 1, 0]

        def ahead(d: float, s: float, base: np.ndarray = base, fwd: np.ndarray = fwd,
                  side: np.ndarray = side) -> np.ndarray:
            return base + d * fwd + s * side

        pts = {"O": ahead(rng.uniform(2.5, 4.0), rng.uniform(-0.8, 0.8))}
        door = ahead(rng.uniform(3.0, 5.0), rng.uniform(-1.2, 1.2))
        box = ahead(rng.uniform(2.5, 4.5), rng.uniform(-1.2, 1.2))
        pts.update({"door_foot": door, "door_top": door + [0, 0, DOOR_M], "box_foot": box,
                    "box_top": box + [0, 0, BOX_M]})
        for k in range(1, 4):
            pts[f"F{k}"] = ahead(rng.uniform(2.0, 5.0), rng.uniform(-1.5, 1.5))
        try:
            uv = {n: pixels(cam, X) for n, X in pts.items()}
        except AssertionError:
            continue
        if not all(5 < u < W - 5 and 5 < v < H - 5 for u, v in uv.values()):
            continue
        add_segments(cam, rng, noise_px)
        ph = OnePhoto(cam, pts["O"], pts)
        ph.clicks = {n: p + rng.normal(0.0, noise_px, 2) for n, p in uv.items()}
        return ph
    raise RuntimeError("no camera sees the whole scene")


def box_on_the_floor(ph: OnePhoto, rng: np.random.Generator) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """A 0.6 × 0.4 × BOX_M box resting on the floor at the photo's box foot, yawed 20°, and its
    corners pinned in the photo (the farthest floor corner hidden), with click noise."""
    from vebuild.model.scene import model_from_dict

    foot = ph.truth("box_foot")
    node = {"name": "box", "primitive": {"type": "box", "params": {"width": 0.6, "depth": 0.4, "height": BOX_M}},
            "joint": {"type": "rests_on", "face": "top", "position": [float(foot[0]), float(foot[1])],
                      "yaw_deg": 20.0}}
    m = model_from_dict([node], {"O": np.zeros(3)})
    prim = m.node("box").primitive
    T = m.world_transforms()["box"]
    world = prim.handles() @ T[:3, :3].T + T[:3, 3]
    hidden = int(np.argmax(np.linalg.norm(world[:4] - ph.C, axis=1)))
    pins = [{"photo": "p", "node": "box", "handle": h, "fixed": True,
             "uv": [float(v) for v in pixels(ph.cam, X + ph.origin) + rng.normal(0, CLICK_NOISE_PX, 2)]}
            for k, (h, X) in enumerate(zip(prim.handle_names(), world, strict=True)) if k != hidden]
    return node, pins


def write_one_photo(folder: Path, ph: OnePhoto, *, known_length: bool = True, camera_height: float | None = None,
                    floor_distance: bool = False, origin: bool = True) -> Path:
    """A one-photo project of ``ph``: O (the origin) and F1–F3 on the floor marked; the door's height
    as a known length (foot first); optionally the camera's height and a tape between F1 and F2.
    ``origin=False``: no marker at all."""
    path = write_project(folder, [ph.cam], {n: ph.points[n] for n in ("O", "F1")})
    project = load_project(path)
    d = project.data
    names = ["O", "F1", "F2", "F3"] if origin else []
    d["photos"][0]["marker_observations"] = {n: [float(v) for v in ph.clicks[n]] for n in names}
    d["markers"] = [{"name": n, "on_floor": True} for n in names]
    if origin:
        d["origin_marker"] = "O"
    else:
        d.pop("origin_marker", None)
    d["reference_distances"] = []
    if floor_distance:
        dist = float(np.linalg.norm(ph.points["F1"] - ph.points["F2"]))
        d["reference_distances"].append({"a": "F1", "b": "F2", "distance": round(dist, 4), "sigma": 0.002,
                                         "role": "scale"})
    if known_length:
        d["known_lengths"] = [{"photo": ph.cam.id, "axis": "z", "floor_end": 0, "length": DOOR_M, "sigma": 0.002,
                               "ends": [[float(v) for v in ph.clicks["door_foot"]],
                                        [float(v) for v in ph.clicks["door_top"]]]}]
    if camera_height is not None:
        d["photos"][0]["camera_height"] = {"value": camera_height, "sigma": 0.01}
    save_project(project)
    return path
