"""A solved project with an entered value: vebuild.synthetic.model_scene's floor and boxes seen by
known cameras (calibrated exactly: covariance 0), the floor's size held exactly, box0's ``hold``
as the test asks (tests/test_entered.py, tests/test_determination.py)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.actions.solve import solve_project
from vebuild.model.scene import model_from_dict
from vebuild.project import load_project
from vebuild.project.records import camera_record
from vebuild.synthetic import model_scene, write_project

N_PHOTOS, N_BOXES = 5, 2


def entered_project(folder: Path, seed: int, entered: Any, tape_error: float = 0.0) -> tuple[Any, Any]:
    """A solved project of seed ``seed`` whose box0 ``hold`` is ``entered`` (its width set to the
    truth + ``tape_error``), and the true model. The photos' files are written once per folder
    (plain grey, the same size for every seed)."""
    rng = np.random.default_rng(seed)
    truth, start, pins, photos = model_scene(rng, n_boxes=N_BOXES, n_photos=N_PHOTOS)
    path = folder / "synthetic.vebuild.json"
    if not path.exists():
        write_project(folder, list(photos.values()), {"O": np.zeros(3), "M1": np.array([1.0, 0.0, 0.0])})
    project = load_project(path)
    data = project.data
    data["reference_distances"], data["markers"] = [], [{"name": "O"}]
    start["nodes"][0]["hold"] = ["width", "depth"]
    box = start["nodes"][1]
    box["primitive"]["params"]["width"] = truth["nodes"][1]["primitive"]["params"]["width"] + tape_error
    box["hold"] = copy.deepcopy(entered)
    data["model"] = {"nodes": start["nodes"], "pins": pins}
    data["calibration"] = {
        "cameras": {p.id: {"mode": "3vp", **camera_record(p.K, p.R, p.C, np.zeros((9, 9)))} for p in photos.values()},
        "lengths": "metres", "origin_marker": "O",
        "markers": {"O": {"position": [0.0, 0.0, 0.0], "sigma": [0.0, 0.0, 0.0]}}}
    solve_project(project)
    return project, model_from_dict(truth["nodes"], {"O": np.zeros(3)})
