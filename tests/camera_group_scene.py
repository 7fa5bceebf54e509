"""The generated photos of one camera (vebuild.synthetic.shared), a box pinned where the calibrated
cameras see it, and vebuild run as a command (tests/test_camera_groups.py,
tests/test_report_camera_groups.py)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from vebuild.synthetic import SyntheticPhoto
from vebuild.synthetic.shared import one_camera_set

#: The generated set whose frontal photo p4 cannot fix f alone (its lines leave f undetermined)
#: and whose oblique photos p1–p3 share markers, so that they are placed.
SCENE_SEED = 0


def camera_set() -> tuple[list[SyntheticPhoto], dict[str, np.ndarray]]:
    return one_camera_set(np.random.default_rng(SCENE_SEED))


def run_vebuild(*args: str | Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vebuild", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


#: The box the re-calibration tests solve (a model is needed to solve): its size in metres, standing
#: at the calibrated markers' centroid, pinned where the calibrated cameras see its corners.
BOX = {"width": 0.8, "depth": 0.6, "height": 0.9}


def with_box(path: Path) -> None:
    """Add a box pinned in every placed photo (exactly where its calibrated camera sees each
    corner: the box adds no pull on the cameras of its own) to a calibrated project."""
    from vebuild.camera import project as project_point
    from vebuild.model.scene import model_from_dict
    from vebuild.project import load_project, save_project
    from vebuild.project.decode import cameras

    project = load_project(path)
    data = project.data
    centre = np.mean([m["position"] for m in data["calibration"]["markers"].values()], axis=0)
    node = {"name": "box", "primitive": {"type": "box", "params": BOX},
            "joint": {"type": "rests_on", "position": [float(centre[0]), float(centre[1])], "yaw_deg": 0.0}}
    model = model_from_dict([node])
    pins = []
    for pid, cam in cameras(project).items():
        for h in model.node("box").primitive.handle_names():
            X = model.handle_world("box", h)
            if (cam.R @ (X - cam.C))[2] > 0:
                uv = project_point(cam.K, cam.R, cam.C, X, cam.lens)
                pins.append({"photo": pid, "node": "box", "handle": h, "uv": [float(v) for v in uv], "fixed": True})
    data["model"] = {"nodes": [node], "edge_observations": [], "pins": pins}
    save_project(project)
