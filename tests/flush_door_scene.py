"""A door leaf flush against the back wall of a room (tests/test_solve_truth.py): a floor tied to
the origin marker, the back wall resting on it, a 44 mm door resting on the floor with its back
flush against the wall's front; three photos calibrated exactly (covariance 0) pin the floor and
the wall, and one of them pins the door's eight corners. The door's start is placed as the test
asks (behind the wall, turned round), the rest at the truth."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from vebuild.model.scene import model_from_dict
from vebuild.project import Project, load_project
from vebuild.project.records import camera_record
from vebuild.synthetic import CLICK_NOISE_PX, SyntheticPhoto, rotation, write_project

#: The floor's size (m, held); its corner v0 is the origin marker, so its centre is here:
FLOOR = {"width": 6.0, "depth": 5.0}
CENTRE = np.array([3.0, 2.5, 0.0])
WALL = {"width": 6.0, "depth": 0.12, "height": 2.5}
DOOR = {"width": 0.9, "depth": 0.044, "height": 2.0}
#: The wall's and the door's positions on the floor (the floor's frame, its centre at 0).
WALL_T = FLOOR["depth"] / 2 - WALL["depth"] / 2
DOOR_T = WALL_T - WALL["depth"] / 2 - DOOR["depth"] / 2
DOOR_S = 0.8
K = np.array([[1200.0, 0.0, 800.0], [0.0, 1200.0, 600.0], [0.0, 0.0, 1.0]])
#: Where each photo stands and what it looks at (the floor's frame); p1 sees the door whole.
VIEWS = {"p1": ([0.8, -0.5, 1.2], [0.8, 2.4, 1.0]), "p2": ([-2.0, -2.0, 1.7], [0.0, 2.4, 1.2]),
         "p3": ([2.2, -1.8, 1.5], [0.0, 2.4, 1.2])}
FLUSH = {"type": "flush", "a": "door:back", "b": "wall:front"}


def photo(cid: str) -> SyntheticPhoto:
    C, target = (np.asarray(v, float) + CENTRE for v in VIEWS[cid])
    d = target - C
    R = rotation(np.arctan2(d[1], d[0]), np.arctan2(d[2], np.hypot(d[0], d[1])), 0.0)
    return SyntheticPhoto(cid, "3vp", 1600, 1200, K, R, C)


def nodes(door_t: float = DOOR_T, door_yaw_deg: float = 0.0) -> list[dict[str, Any]]:
    """The model's nodes, the door at ``door_t`` (m, front to back on the floor) turned by
    ``door_yaw_deg``; everything else at the truth."""
    return [{"name": "floor", "primitive": {"type": "quad", "params": dict(FLOOR)}, "hold": ["width", "depth"],
             "joint": {"type": "marker", "marker": "O", "handle": "v0", "yaw_deg": 0.0}},
            {"name": "wall", "parent": "floor", "primitive": {"type": "box", "params": dict(WALL)},
             "joint": {"type": "rests_on", "face": "top", "position": [0.0, WALL_T], "yaw_deg": 0.0}},
            {"name": "door", "parent": "floor", "primitive": {"type": "box", "params": dict(DOOR)},
             "joint": {"type": "rests_on", "face": "top", "position": [DOOR_S, door_t], "yaw_deg": door_yaw_deg}}]


def pins(rng: np.random.Generator, door_corners: tuple[str, ...] = tuple(f"v{i}" for i in range(8))
         ) -> list[dict[str, Any]]:
    """Every floor and wall corner each photo sees, and ``door_corners`` in p1 only, at the true
    pixel plus the click noise."""
    truth = model_from_dict(nodes(), {"O": np.zeros(3)})
    T = truth.world_transforms()
    out = []
    for cid in VIEWS:
        p = photo(cid)
        for name in ("floor", "wall", "door"):
            prim = truth.node(name).primitive
            for h, X in zip(prim.handle_names(), prim.handles() @ T[name][:3, :3].T + T[name][:3, 3], strict=True):
                if name == "door" and (cid != "p1" or h not in door_corners):
                    continue
                xc = p.R @ (X - p.C)
                uv = (p.K @ xc)[:2] / xc[2]
                if xc[2] > 0.3 and 0 <= uv[0] <= p.width and 0 <= uv[1] <= p.height:
                    out.append({"photo": cid, "node": name, "handle": h, "fixed": True,
                                "uv": [float(v) for v in uv + rng.normal(0.0, CLICK_NOISE_PX, 2)]})
    return out


def door_project(folder: Path, seed: int, door_t: float = DOOR_T, door_yaw_deg: float = 0.0,
                 related: bool = True, door_corners: tuple[str, ...] = tuple(f"v{i}" for i in range(8))) -> Project:
    """The project (not solved): the door started at ``door_t``, turned by ``door_yaw_deg``, its
    back flush with the wall's front where ``related``, ``door_corners`` pinned in p1."""
    photos = [photo(cid) for cid in VIEWS]
    path = folder / "synthetic.vebuild.json"
    if not path.exists():
        write_project(folder, photos, {"O": np.zeros(3), "M1": np.array([1.0, 0.0, 0.0])})
    project = load_project(path)
    data = project.data
    data["reference_distances"], data["markers"] = [], [{"name": "O"}]
    data["model"] = {"nodes": nodes(door_t, door_yaw_deg),
                     "pins": pins(np.random.default_rng(seed), door_corners),
                     "relations": [dict(FLUSH)] if related else []}
    data["calibration"] = {
        "cameras": {p.id: {"mode": "3vp", **camera_record(p.K, p.R, p.C, np.zeros((9, 9)))} for p in photos},
        "lengths": "metres", "origin_marker": "O",
        "markers": {"O": {"position": [0.0, 0.0, 0.0], "sigma": [0.0, 0.0, 0.0]}}}
    return project
