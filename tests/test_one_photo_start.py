"""A one-photo project from its first step, as a new user takes it: `vebuild new` with one photo,
`vebuild detect`, `vebuild calibrate`, with no marker and no scale. Nothing may end in a traceback:
the calibration is written, its origin is the floor below the camera, and the user is told in
words what gives the lengths a scale. The photo is the bundled example's p1 (rendered by vebuild's
own generator; its true camera is in scenes/room/ground_truth.json)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from vebuild.calibration.single_photo import BELOW_THE_CAMERA
from vebuild.cli import main

EXAMPLE = Path(__file__).resolve().parents[1] / "scenes" / "room"


def test_detect_then_calibrate_one_photo_with_no_marker(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    shutil.copy(EXAMPLE / "photos" / "p1.jpg", tmp_path / "p1.jpg")
    project = tmp_path / "one.vebuild.json"
    assert main(["new", str(project), str(tmp_path / "p1.jpg")]) == 0
    assert main(["detect", str(project)]) == 0
    assert main(["calibrate", "--quiet", str(project)]) == 0
    out = capsys.readouterr().out
    assert f"origin {BELOW_THE_CAMERA}" in out and "lengths are RELATIVE" in out
    assert "press K, drag along an edge whose length you know" in out
    cal = json.loads(project.read_text())["calibration"]
    cam = cal["cameras"]["p1"]
    truth = json.loads((EXAMPLE / "ground_truth.json").read_text())["photos"]["p1"]
    # The photo determines its focal length whatever else is missing: within 4σ of the truth.
    f = cam["focal_px"]
    assert abs(f["value"] - truth["f"]) < 4 * f["sigma"]
    # Relative units: the camera stands one unit above the floor point below it, the origin.
    assert cam["position"]["value"] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
    assert cam["placement"]["lengths"] == "relative"


def test_calibrate_before_any_line_names_detect(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The first try without lines: a refusal (status 2) that names the command proposing them."""
    shutil.copy(EXAMPLE / "photos" / "p1.jpg", tmp_path / "p1.jpg")
    project = tmp_path / "one.vebuild.json"
    assert main(["new", str(project), str(tmp_path / "p1.jpg")]) == 0
    before = project.read_bytes()
    assert main(["calibrate", "--quiet", str(project)]) == 2
    err = capsys.readouterr().err
    assert "no photo has vanishing segments" in err and "`vebuild detect one.vebuild.json` proposes them" in err
    assert "Traceback" not in err and project.read_bytes() == before
