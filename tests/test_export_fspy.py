"""`vebuild export PROJECT --camera PHOTO --out FILE.fspy`: a calibrated photo as the fSpy project
that fSpy's Blender add-on imports (vebuild/project/fspy_write.py).

Checked against the add-on's own code (github.com/stuffmatic/fSpy-Blender at eec40b0,
fspy_blender/fspy.py and addon.py): what it reads (the header as ``unpack('<I')`` words, the
state's ``cameraParameters`` principalPoint x/y, horizontalFieldOfView, cameraTransform.rows,
imageWidth, imageHeight, ``calibrationSettingsBase.referenceDistanceUnit``, the image bytes) and
the camera it then sets up in Blender (angle = the field of view across the larger render side,
matrix_world = cameraTransform, shift_x / shift_y from the principal point, both in units of the
larger side), whose projection must be vebuild's; against fSpy's solver (tests/fspy_writer.py
re-derives it from fSpy's solver.ts) run on the control points written; and round trip through
vebuild's own fSpy import, which re-solves the control points.
"""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fspy_writer import KnownCamera, StateBuilder
from handoff_project import make_project

from vebuild.actions.fspy import import_fspy
from vebuild.actions.fspy_compare import fspy_camera_in_vebuild
from vebuild.camera import ImageCamera, rotation_from_ypr
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.project import load_project, save_project
from vebuild.project.decode import photo_camera
from vebuild.project.fspy import read_fspy
from vebuild.project.fspy_write import fspy_bytes, fspy_state

#: Noise-free: the conventions must reproduce the camera to rounding (pixels; rotation matrix
#: entries; metres; the focal length relative).
EXACT_PX = 1e-6
EXACT = 1e-9
#: The units the add-on's set_reference_distance_unit knows (addon.py).
ADDON_UNITS = ("Millimeters", "Centimeters", "Meters", "Kilometers", "Inches", "Feet", "Miles", "No unit")


def addon_reads(data: bytes) -> dict[str, Any]:
    """What fspy_blender/fspy.py's ``Project`` reads from the file, the way it reads it."""
    file_id, version, state_size, image_size = struct.unpack_from("<IIII", data, 0)
    assert file_id == 2037412710, "Trying to import a file that is not an fSpy project"
    assert version == 1 and image_size > 0
    state = json.loads(data[16:16 + state_size].decode("utf-8"))
    cp = state["cameraParameters"]
    assert cp is not None, "Trying to import an fSpy project with no camera parameters"
    return {"principal_point": (cp["principalPoint"]["x"], cp["principalPoint"]["y"]),
            "fov_horiz": cp["horizontalFieldOfView"], "camera_transform": cp["cameraTransform"]["rows"],
            "image_width": cp["imageWidth"], "image_height": cp["imageHeight"],
            "reference_distance_unit": state["calibrationSettingsBase"]["referenceDistanceUnit"],
            "image_data": data[16 + state_size:16 + state_size + image_size], "state": state}


def blender_pixels(read: dict[str, Any], X: np.ndarray) -> np.ndarray:
    """Where the camera addon.py's ``set_up_camera`` makes puts world points X (render pixels, y down):
    Blender fits the angle to the larger render side (sensor fit auto) and shifts by that side."""
    W, H = read["image_width"], read["image_height"]
    image_aspect = W / H
    x_shift_scale = W / H if H > W else 1.0
    y_shift_scale = 1.0 if H > W else H / W
    pp = read["principal_point"]
    if image_aspect <= 1:
        pp_rel = (0.5 * (pp[0] / image_aspect + 1), 0.5 * (-pp[1] + 1))
    else:
        pp_rel = (0.5 * (pp[0] + 1), 0.5 * (-pp[1] * image_aspect + 1))
    shift_x = x_shift_scale * (0.5 - pp_rel[0])
    shift_y = y_shift_scale * (-0.5 + pp_rel[1])
    S = max(W, H)
    fpx = S / 2 / math.tan(read["fov_horiz"] / 2)
    M = np.asarray(read["camera_transform"], float)
    x = (np.c_[X, np.ones(len(X))] @ np.linalg.inv(M).T)[:, :3]  # camera local: looking along −z, y up
    u = W / 2 + fpx * x[:, 0] / -x[:, 2] - shift_x * S
    v = H / 2 - fpx * x[:, 1] / -x[:, 2] + shift_y * S
    return np.c_[u, v]


def _points(cam: ImageCamera, n: int = 60) -> np.ndarray:
    rng = np.random.default_rng(1)
    X = np.c_[rng.uniform(-4, 4, (n, 2)) + np.asarray(cam.C)[:2], rng.uniform(0, 2.5, n)]
    return X[(X - cam.C) @ np.asarray(cam.R)[2] > 0.3]


def _portrait() -> ImageCamera:
    R = rotation_from_ypr(math.radians(200.0), math.radians(-20.0), math.radians(3.0))
    K = np.array([[900.0, 0, 480 / 2 - 31.0], [0, 900.0, 640 / 2 + 17.0], [0, 0, 1]])
    return ImageCamera("portrait", K, R, np.array([2.0, 3.0, 1.5]), 480, 640)


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    h = make_project(tmp_path_factory.mktemp("fspy"))
    out = h.path.parent / "photo.fspy"
    assert main(["export", str(h.path), "--camera", "p", "--out", str(out)]) == 0
    return h, out


def test_the_blender_addon_reads_every_field_it_needs(exported):
    h, out = exported
    data = out.read_bytes()
    read = addon_reads(data)
    assert read["image_data"] == (h.path.parent / "photos" / "p.jpg").read_bytes()  # the photo, byte for byte
    assert len(data) == 16 + struct.unpack_from("<I", data, 8)[0] + len(read["image_data"])
    assert (read["image_width"], read["image_height"]) == (1600, 1200)
    assert read["reference_distance_unit"] == "Meters" and read["reference_distance_unit"] in ADDON_UNITS
    assert read["fov_horiz"] == pytest.approx(2 * math.atan(800 / h.cam.K[0][0]), rel=1e-12)
    M = np.asarray(read["camera_transform"])
    assert M.shape == (4, 4) and np.allclose(M[3], [0, 0, 0, 1]) and np.allclose(M[:3, 3], h.cam.C, atol=EXACT)


@pytest.mark.parametrize("which", ["project", "portrait"])
def test_blender_s_camera_projects_as_vebuild_s(exported, which):
    """The camera the add-on sets up in Blender puts every point where vebuild's camera does, the
    principal point off centre included, for landscape and portrait photos."""
    cam = exported[0].cam if which == "project" else _portrait()
    state, _, _ = fspy_state(cam, relative_units=False)
    read = addon_reads(fspy_bytes(state, b"\xff\xd8 an image"))
    X = _points(cam)
    got, want = blender_pixels(read, X), project_points(cam.K, cam.R, cam.C, X)
    assert np.max(np.linalg.norm(got - want, axis=1)) < EXACT_PX
    # Without the principal point's shift the points would be off by its offset: the check can fail.
    off = np.asarray(cam.K)[:2, 2] - [cam.width / 2, cam.height / 2]
    assert np.linalg.norm(off) > 10


@pytest.mark.parametrize("which", ["project", "portrait"])
def test_fspy_s_solver_on_the_control_points_gives_the_stored_camera(exported, which):
    """fSpy re-solves a project from its control points when it opens it: its solver (re-derived in
    tests/fspy_writer.py) on the points written gives the camera stored, field by field."""
    cam = exported[0].cam if which == "project" else _portrait()
    state, _, _ = fspy_state(cam, relative_units=False)
    known = KnownCamera(cam.width, cam.height, float(cam.K[0][0]), np.asarray(cam.K)[:2, 2], np.asarray(cam.R),
                        np.asarray(cam.C))
    b = StateBuilder(known, np.random.default_rng(0), noise_px=0.0, reference_unit="Meters")
    solved = b.solve(state)
    stored = state["cameraParameters"]
    for key in ("horizontalFieldOfView", "verticalFieldOfView", "relativeFocalLength"):
        assert solved[key] == pytest.approx(stored[key], rel=EXACT), key
    for key in ("x", "y"):
        assert solved["principalPoint"][key] == pytest.approx(stored["principalPoint"][key], abs=EXACT)
    assert solved["vanishingPointAxes"] == stored["vanishingPointAxes"]
    for p, q in zip(solved["vanishingPoints"][:2], stored["vanishingPoints"][:2], strict=True):
        assert p["x"] == pytest.approx(q["x"], rel=1e-7, abs=EXACT) and p["y"] == pytest.approx(q["y"], rel=1e-7,
                                                                                                 abs=EXACT)
    assert np.allclose(np.asarray(solved["viewTransform"]["rows"]), np.asarray(stored["viewTransform"]["rows"]),
                       atol=1e-9)
    # The first two axes point toward their vanishing points, in front of the camera (fSpy's convention).
    for axis in stored["vanishingPointAxes"][:2]:
        e = np.zeros(3)
        e["xyz".index(axis[0])] = 1.0 if axis.endswith("Positive") else -1.0
        assert (np.asarray(cam.R) @ e)[2] > 0, axis


def test_round_trip_through_vebuild_s_fspy_import(exported, tmp_path):
    """vebuild's fSpy import reads the stored camera back unchanged, and re-solving the control points
    (vanishing points, principal point, origin, reference distance) gives the same camera."""
    h, out = exported
    fp = read_fspy(out)
    stored = fspy_camera_in_vebuild(fp)
    assert stored is not None and stored.metric
    cam = h.cam
    assert stored.f == pytest.approx(cam.K[0][0], rel=EXACT)
    assert np.allclose(stored.c, np.asarray(cam.K)[:2, 2], atol=EXACT_PX)
    assert np.allclose(stored.R, cam.R, atol=EXACT) and np.allclose(stored.C, cam.C, atol=EXACT)
    result = import_fspy(out, tmp_path / "imported")
    assert result.calibrated and result.warnings == []
    project = load_project(result.project)
    again = photo_camera(project, project.data["photos"][0]["id"])
    assert again.K[0][0] == pytest.approx(cam.K[0][0], rel=1e-7)
    assert np.allclose(np.asarray(again.K)[:2, 2], np.asarray(cam.K)[:2, 2], atol=1e-4)
    assert np.allclose(again.R, cam.R, atol=1e-7)
    assert np.allclose(again.C, cam.C, atol=1e-6)  # metres: the reference distance gave the scale


def test_a_relative_photo_has_no_unit_and_a_lens_is_warned_of(tmp_path, capsys):
    h = make_project(tmp_path / "p", k1=-0.04)
    project = load_project(h.path)
    project.data["calibration"]["lengths"] = "relative"
    save_project(project)
    out = tmp_path / "p" / "rel.fspy"
    assert main(["export", str(h.path), "--camera", "p", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "warning: the photo's lens distortion (k1 -0.04" in text and "pinhole part" in text
    read = addon_reads(out.read_bytes())
    base = read["state"]["calibrationSettingsBase"]
    assert base["referenceDistanceUnit"] == "No unit" and base["referenceDistanceAxis"] is None


def test_written_file_opens_as_fspy_writes_it(exported):
    """The state holds every part of fSpy's SavedState (src/gui/io/saved-state.ts), as fSpy loads it."""
    read = addon_reads(exported[1].read_bytes())
    assert set(read["state"]) == {"globalSettings", "calibrationSettingsBase", "calibrationSettings1VP",
                                  "calibrationSettings2VP", "controlPointsStateBase", "controlPointsState1VP",
                                  "controlPointsState2VP", "cameraParameters", "resultDisplaySettings"}
    base = read["state"]["controlPointsStateBase"]
    for seg in base["firstVanishingPoint"]["lineSegments"]:
        for p in seg:
            assert 0 <= p["x"] <= 1 and 0 <= p["y"] <= 1  # on the photo, where a user can drag them
    assert Path(exported[1]).suffix == ".fspy"


def test_an_origin_below_the_camera_is_stood_in_for_by_a_floor_point_in_view(tmp_path, capsys):
    """A photo placed with no origin marker has its origin on the floor below the camera: fSpy's
    reference distance, which starts at the origin, cannot scale such a camera (the camera lies in
    each reference plane through it). The control points put fSpy's origin on a floor point in view
    instead, which the command says: the camera Blender reads is exact in vebuild's world, and
    vebuild's import of the file (re-solving the control points) gives the same camera, in metres,
    moved by that floor point."""
    from vebuild.project.fspy_write import _floor_in_view

    h = make_project(tmp_path / "p")
    project = load_project(h.path)
    pos = project.data["calibration"]["cameras"]["p"]["position"]["value"]
    project.data["calibration"]["cameras"]["p"]["position"]["value"] = [0.0, 0.0, pos[2]]
    project.data["analyses"] = []
    save_project(project)
    cam = photo_camera(load_project(h.path), "p")
    out = tmp_path / "p" / "below.fspy"
    assert main(["export", str(h.path), "--camera", "p", "--out", str(out)]) == 0
    stand_in = _floor_in_view(np.asarray(cam.K), np.asarray(cam.R), np.asarray(cam.C), cam.width, cam.height)
    assert stand_in is not None
    said = capsys.readouterr().out
    assert "warning: the world's origin (the floor below the camera, or behind it) cannot anchor" in said
    assert f"the floor point ({stand_in[0]:.3f}, {stand_in[1]:.3f}, 0) in view" in said
    read = addon_reads(out.read_bytes())
    assert read["reference_distance_unit"] == "Meters"
    assert read["state"]["calibrationSettingsBase"]["referenceDistanceAxis"] is not None
    X = _points(cam)
    assert np.max(np.linalg.norm(blender_pixels(read, X) - project_points(cam.K, cam.R, cam.C, X), axis=1)) < EXACT_PX
    result = import_fspy(out, tmp_path / "imported")
    assert result.calibrated and result.warnings == []
    again = photo_camera(load_project(result.project), "below")
    assert again.K[0][0] == pytest.approx(cam.K[0][0], rel=1e-7) and np.allclose(again.R, cam.R, atol=1e-7)
    assert np.allclose(np.asarray(again.C), np.asarray(cam.C) - stand_in, atol=1e-6)
