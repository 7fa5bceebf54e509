"""Registering further photos to the solved model (paper §3.2), on the example room."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from claims import FOCAL_TOL_REL, POSITION_TOL_REL, ROTATION_TOL_DEG

from vebuild.camera import log_so3
from vebuild.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"
# One photo registered to the model's vertices, whose own positions are good to a few mm: the
# issue's calibration tolerances apply (focal 1 %, rotation 0.3°, position 1 % of the room).
POSITION_TOL_M = POSITION_TOL_REL * np.linalg.norm([5.0, 4.0, 2.6])


def _errors(folder: Path, pid: str) -> tuple[float, float, float]:
    cam = json.loads((folder / "room.vebuild.json").read_text())["calibration"]["cameras"][pid]
    t = json.loads((folder / "ground_truth.json").read_text())["photos"][pid]
    f_err = abs(cam["focal_px"]["value"] - t["f"]) / t["f"]
    rot = np.degrees(np.linalg.norm(log_so3(np.asarray(t["R"]) @ np.asarray(cam["R"]).T)))
    return f_err, rot, float(np.linalg.norm(np.asarray(cam["position"]["value"]) - t["C"]))


@pytest.mark.parametrize("keep_segments", [False, True], ids=["from-points", "with-vanishing-points"])
def test_register_a_photo_left_out_of_calibration(tmp_path: Path, keep_segments: bool,
                                                  capsys: pytest.CaptureFixture) -> None:
    shutil.copytree(EXAMPLE, tmp_path, dirs_exist_ok=True)
    path = tmp_path / "room.vebuild.json"
    data = json.loads(path.read_text())
    segments = data["photos"][4]["vanishing_segments"]
    data["photos"][4]["vanishing_segments"] = {}
    path.write_text(json.dumps(data, indent=1))
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert "photo 'p5' has no vanishing segments" in capsys.readouterr().out
    assert main(["solve", str(path), "--recalibrate"]) == 0
    if keep_segments:  # the user now marks p5's vanishing lines too
        data = json.loads(path.read_text())
        data["photos"][4]["vanishing_segments"] = segments
        path.write_text(json.dumps(data, indent=1))
    assert main(["register", str(path), "p5"]) == 0
    out = capsys.readouterr().out
    assert "photo p5: mode registered" in out
    assert ("vanishing-point calibration" in out) == keep_segments
    f_err, rot, pos = _errors(tmp_path, "p5")
    assert f_err < FOCAL_TOL_REL and rot < ROTATION_TOL_DEG and pos < POSITION_TOL_M


def test_register_needs_enough_known_points(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    shutil.copytree(EXAMPLE, tmp_path, dirs_exist_ok=True)
    path = tmp_path / "room.vebuild.json"
    data = json.loads(path.read_text())
    data["photos"][4]["vanishing_segments"] = {}
    path.write_text(json.dumps(data, indent=1))
    assert main(["calibrate", str(path), "--quiet"]) == 0
    # Before the model is solved only the markers are known: p5 sees too few of them.
    data = json.loads(path.read_text())
    data["photos"][4]["marker_observations"] = dict(list(data["photos"][4]["marker_observations"].items())[:3])
    data["model"]["pins"] = [p for p in data["model"]["pins"] if p["photo"] != "p5"]
    path.write_text(json.dumps(data, indent=1))
    assert main(["register", str(path), "p5"]) == 2
    assert "needs at least 4 marked points of known position" in capsys.readouterr().err
