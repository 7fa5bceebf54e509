"""A photo that cannot be calibrated is left out, not the project refused.

Generated photos (vebuild.synthetic) reproduce the failure: a frontal photo with no EXIF and no
focal length given, whose lines cannot fix f, among photos that can be calibrated.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

from vebuild.synthetic import random_scene, write_project

#: |error| / reported 1σ that no camera may exceed (as in test_calibration: a 1-in-10⁵ draw).
UNCERTAINTY_BOUND = 4.5


def _cli(*args: str | Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "vebuild", *map(str, args)], capture_output=True, text=True,
                          timeout=300)


def test_a_photo_whose_focal_length_cannot_be_fixed_is_left_out(tmp_path: Path) -> None:
    """A frontal photo with no EXIF (its lines fix f to 105 %, 1σ) among three good photos: it is
    left out with its reason, and the three are calibrated and placed as they are without it;
    `vebuild check` says so, and the commands that need its camera say why it has none."""
    from vebuild.actions.solve import uncalibrated_pin_warnings
    from vebuild.project import load_project
    from vebuild.report.cameras import calibration
    from vebuild.report.page import Report

    photos, markers = random_scene(np.random.default_rng(3), ("3vp", "3vp", "2vp", "1vp"))
    path = write_project(tmp_path, photos, markers)
    data = json.loads(path.read_text())
    del data["photos"][3]["focal_px"]  # the frontal photo: no focal length given, and no EXIF
    path.write_text(json.dumps(data, indent=2))
    r = _cli("calibrate", path)
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    cal = json.loads(path.read_text())["calibration"]
    assert set(cal["cameras"]) == {"p1", "p2", "p3"}
    reason = cal["left_out"]["p4"]["reason"]
    assert reason.startswith("the focal length is not determined: from these segments its 1σ would be")
    assert "give its focal length (the photo's focal_px" in reason
    warning = (f"photo 'p4' is left out of the calibration, the other photos calibrated without "
               f"it: {reason}\ndetails: $.photos[3]")
    assert warning in cal["warnings"] and warning in r.stdout
    for ph in photos[:3]:  # placed where they are, each coordinate within its 1σ bound
        cam = cal["cameras"][ph.id]
        err = np.asarray(cam["position"]["value"]) - ph.C
        assert np.all(np.abs(err) < UNCERTAINTY_BOUND * np.asarray(cam["position"]["sigma"])), (ph.id, err)
    # `vebuild check` agrees.
    r = _cli("check", path)
    assert r.returncode == 0, r.stderr
    assert f"calibration: photo 'p4' left out, no camera ($.calibration.left_out.p4): {reason}" in r.stdout
    # A command that needs its camera says why it has none, and changes nothing.
    before = path.read_bytes()
    r = _cli("render", path, "--photo", "p4", "--out", tmp_path / "p4.png", "--size", "64x48")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "$.calibration.left_out.p4: photo 'p4' has no camera: the calibration left it out (the focal" in r.stderr
    assert path.read_bytes() == before and not (tmp_path / "p4.png").exists()
    # The solve's warning for its marks points at the reason, and the report lists it.
    project = load_project(path)
    project.data["model"] = {"pins": [{"photo": "p4", "node": "box", "handle": "v0", "uv": [800.0, 600.0]}]}
    said = uncalibrated_pin_warnings(project.data, {})
    assert len(said) == 1 and "once what the calibration left it out for is fixed" in said[0], said
    assert "$." not in said[0]
    from vebuild.report.limitations import limitations

    left = [lim for lim in limitations(load_project(path)) if lim.kind == "left-out"]
    assert len(left) == 1 and left[0].items == (f"p4: {reason}",)
    rep = Report(tmp_path / "report")
    calibration(load_project(path), rep)
    assert "Left out of the calibration" in rep.sections[0] and "p4 (the focal length is not determined" in \
        rep.sections[0]
