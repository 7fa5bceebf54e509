"""vebuild import FILE.fspy: fSpy projects made from known cameras (tests/fspy_writer.py) are
imported, calibrated and compared with the truth and with fSpy's own solver's result."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import pytest
from fspy_writer import RELEASES, KnownCamera, StateBuilder, as_saved_by, axis_vec, fspy_bytes, make_image
from pixel_formats import float_tiff

from vebuild.actions.fspy import import_fspy
from vebuild.actions.fspy_compare import fspy_camera_in_vebuild, rotation_difference_deg
from vebuild.calibration.priors import PRINCIPAL_POINT_SIGMA_REL
from vebuild.camera import log_so3
from vebuild.cli import main
from vebuild.errors import ProjectError, VebuildError
from vebuild.project import load_project
from vebuild.project.fspy import image_plane_to_pixels, parse_fspy, read_fspy, relative_to_pixels
from vebuild.project.outputs import temporaries

#: Noise-free marks: the import's conventions (axes, directions, coordinates) must reproduce the
#: camera to rounding: focal length relative, rotation in degrees, position in metres.
EXACT_REL = 1e-6
EXACT_DEG = 1e-5
EXACT_M = 1e-5
#: Noisy marks: the error of each quantity within this many of vebuild's own 1σ (computed from the
#: click σ the import is given, the injected noise): 4σ fails one honest run in ~16 000.
SIGMAS = 4.0
NOISE_PX = 0.5


def write(tmp_path, builder: StateBuilder, name: str = "scene", fmt: str = "JPEG", state=None, image=None, **kw):
    state = builder.build() if state is None else state
    image = make_image(builder.cam.width, builder.cam.height, fmt) if image is None else image
    path = tmp_path / f"{name}.fspy"
    path.write_bytes(fspy_bytes(state, image, **kw))
    return path, state, image


def camera_of(result):
    project = load_project(result.project)
    pid = project.data["photos"][0]["id"]
    return project, project.data["calibration"]["cameras"][pid]


def assert_directed(project, cam: KnownCamera):
    """Every imported segment runs along its axis' positive sense (vebuild's directed segments)."""
    photo = project.data["photos"][0]
    for axis, segs in photo["vanishing_segments"].items():
        e = axis_vec(f"{axis}Positive")
        for s in segs:
            p1, p2 = np.array(s[:2]), np.array(s[-2:])
            # Image direction of +axis at p1: toward the projection of a point a little along it.
            ray = np.linalg.solve(cam.K, [*p1, 1.0])
            X = cam.C + cam.R.T @ ray * 3.0
            ahead = cam.project(X + 0.05 * e) - cam.project(X)
            assert (p2 - p1) @ ahead > 0, (axis, s)


# -- coordinates --------------------------------------------------------------------------------


@pytest.mark.parametrize("w,h", [(640, 480), (480, 640)])
def test_fspy_coordinates(w, h):
    """Relative coordinates run 0..1 over each side, y down; fSpy's image plane has y up and one
    unit per half of the longer side (portrait: x spans ±w/h)."""
    assert relative_to_pixels((0.25, 0.75), w, h).tolist() == [0.25 * w, 0.75 * h]
    a = w / h
    corner = (1.0, 1 / a) if a > 1 else (a, 1.0)  # the top-right corner in fSpy's image plane
    assert np.allclose(image_plane_to_pixels(corner, w, h), [w, 0])
    assert np.allclose(image_plane_to_pixels((0, 0), w, h), [w / 2, h / 2])


def test_fspy_stored_camera_of_a_real_project():
    """fSpy-Blender's test_data/json_export.json (fSpy's solver output for a 1439×956 photo): the
    stored camera turned into vebuild's K, R projects each world axis onto fSpy's own stored
    vanishing point, and its field of view is 2 atan(1 / relative focal length)."""
    stored = {
        "principalPoint": {"x": 0, "y": 0},
        "viewTransform": {"rows": [
            [-0.8432786760114586, 0.0008594611278942136, -0.5374758933300462, 0.3346571584818884],
            [-0.0005363911022935677, 0.9999968777735306, 0.002440640853491923, -0.9315262352851599],
            [0.537476312844526, 0.0023464376744316683, -0.8432755820971535, -4.120414307919244],
            [0, 0, 0, 1]]},
        "cameraTransform": {"rows": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
        "horizontalFieldOfView": 1.5479845321227295, "verticalFieldOfView": 1.1518580723726943,
        "vanishingPoints": [{"x": 1.6051650133994935, "y": 0.001021010320067342},
                            {"x": -0.652074716204382, "y": 0.0029610261811691915},
                            {"x": -0.3747357368992343, "y": -436.0110710388304}],
        "vanishingPointAxes": ["xNegative", "zPositive", "yPositive"],
        "relativeFocalLength": 1.0230759978297743, "imageWidth": 1439, "imageHeight": 956,
    }
    cam = KnownCamera.looking_at_corner(1439, 956)
    b = StateBuilder(cam, np.random.default_rng(0), noise_px=0.0, first_axis="xNegative", second_axis="zPositive")
    state = b.build()
    state["cameraParameters"] = stored
    fp = parse_fspy(fspy_bytes(state, make_image(1439, 956)), Path("json_export.fspy"))
    fs = fspy_camera_in_vebuild(fp)
    assert fs is not None
    assert math.isclose(2 * math.atan(1 / stored["relativeFocalLength"]), stored["horizontalFieldOfView"],
                        rel_tol=1e-9)
    assert math.isclose(fs.f, stored["relativeFocalLength"] * 1439 / 2, rel_tol=1e-12)
    K = np.array([[fs.f, 0, fs.c[0]], [0, fs.f, fs.c[1]], [0, 0, 1]])
    for i, (p, axis) in enumerate(zip(stored["vanishingPoints"], stored["vanishingPointAxes"], strict=True)):
        v = K @ fs.R @ axis_vec(axis)
        # fSpy's first two axes point toward their vanishing points, in front of the camera (the
        # third, here near infinity, is their cross product, of either depth).
        assert i == 2 or v[2] > 0, f"{axis}: fSpy's vanishing point lies behind the camera"
        want = image_plane_to_pixels((p["x"], p["y"]), 1439, 956)
        got = v[:2] / v[2]
        assert np.linalg.norm(got - want) <= 1e-6 * max(1.0, np.linalg.norm(want)), (axis, got, want)


# -- noise-free: the conventions --------------------------------------------------------------------


CASES = {
    "2vp": {},
    "quad": {"quad": True},
    "manual": {"principal_point_mode": "Manual"},
    "third": {"principal_point_mode": "FromThirdVanishingPoint"},
    "1vp": {"mode": "OneVanishingPoint"},
    "1vp-manual": {"mode": "OneVanishingPoint", "principal_point_mode": "Manual"},
    "1vp-tall-sensor": {"mode": "OneVanishingPoint", "sensor_mm": (24.0, 36.0)},
    "y-z": {"first_axis": "yNegative", "second_axis": "zNegative"},
}


@pytest.mark.parametrize("portrait", [False, True], ids=["landscape", "portrait"])
@pytest.mark.parametrize("case", sorted(CASES))
def test_exact_marks_give_the_camera(tmp_path, case, portrait):
    w, h = (480, 640) if portrait else (640, 480)
    cam = KnownCamera.looking_at_corner(w, h)
    b = StateBuilder(cam, np.random.default_rng(3), noise_px=0.0, **CASES[case])
    path, state, image = write(tmp_path, b)
    r = import_fspy(path, tmp_path / "out")
    assert r.calibrated and r.fspy_camera
    project, rec = camera_of(r)
    assert_directed(project, cam)
    K, R = np.array(rec["K"]), np.array(rec["R"])
    assert abs(K[0, 0] / cam.f - 1) < EXACT_REL
    assert np.allclose(K[:2, 2], cam.c, atol=EXACT_REL * cam.f)
    assert rotation_difference_deg(R, cam.R) < EXACT_DEG
    # The scale: fSpy's reference distance became the camera's height.
    assert np.allclose(rec["position"]["value"], cam.C, atol=EXACT_M)
    # fSpy's own result (re-derived from the same marks) agrees, row by row.
    for row in r.rows:
        assert row.difference is not None and abs(row.difference) < 1e-3, row
    photo = project.data["photos"][0]
    assert photo["imported_from"]["software"] == "fSpy"
    assert photo["imported_from"]["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    if case.startswith("1vp"):
        assert "focal_px" in photo and any("DERIVED" in n for n in photo["imported_from"]["notes"])
    if "manual" in case:
        assert np.allclose(photo["principal_point"]["value"], cam.c)
    else:
        assert "principal_point" not in photo
    if case == "third":
        assert len(photo["vanishing_segments"]) == 3


def test_axes_that_put_the_floor_overhead_are_imported_uncalibrated(tmp_path):
    """fSpy's zPositive for the verticals of a camera looking down makes +z point down (fSpy's axis
    points toward its vanishing point): the marks are imported as they are, and the calibration's
    refusal is reported, with what to check, rather than a world upside down."""
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0,
                     first_axis="yNegative", second_axis="zPositive")
    path, _, _ = write(tmp_path, b)
    r = import_fspy(path, tmp_path / "o")
    assert not r.calibrated and not r.rows
    assert any("check fSpy's axes" in w and str(tmp_path / "o") in w for w in r.warnings), r.warnings
    project = load_project(r.project)
    assert "calibration" not in project.data and set(project.data["photos"][0]["vanishing_segments"]) == {"y", "z"}


def test_photo_is_the_embedded_image_byte_for_byte(tmp_path):
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0)
    path, _, image = write(tmp_path, b, fmt="PNG")
    assert main(["import", str(path), "--out", str(tmp_path / "new")]) == 0
    photo, proj = tmp_path / "new" / "scene.png", tmp_path / "new" / "scene.vebuild.json"
    assert photo.read_bytes() == image
    project = load_project(proj)  # verifies the recorded hash against the file
    assert project.data["photos"][0]["sha256"] == hashlib.sha256(image).hexdigest()
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == ["scene.png", "scene.vebuild.json"]
    # Written as `vebuild new` writes a project: one audit entry, for the command that made it.
    (entry,) = project.data["audit"]
    assert entry["command"] == "import" and entry["before_sha256"] is None
    # The calibration is current, and `vebuild calibrate` run again gives the same camera.
    assert main(["check", str(proj)]) == 0
    before = project.data["calibration"]["cameras"]["scene"]
    assert main(["calibrate", str(proj), "--quiet"]) == 0
    after = load_project(proj).data["calibration"]["cameras"]["scene"]
    assert np.allclose(after["K"], before["K"]) and np.allclose(after["R"], before["R"])
    assert np.allclose(after["position"]["value"], before["position"]["value"])


# -- every layout fSpy's releases save (tests/fspy_writer.py's RELEASES) ---------------------------

#: name → (fSpy release, the marks and settings, how it was saved). ``horizon_moved``: the horizon
#: saved as {"0": ..., "1": ...}, as every release saves it once it has been dragged.
LAYOUTS = {
    "alpha1-2vp-yards": ("1.0.0-alpha.1", {"reference_unit": "Yards"}, {}),
    "alpha1-1vp-preset": ("1.0.0-alpha.1", {"mode": "OneVanishingPoint", "preset": "canon_5d"}, {}),
    "alpha1-1vp-horizon-moved": ("1.0.0-alpha.1", {"mode": "OneVanishingPoint"}, {"horizon_moved": True}),
    "alpha5-1vp-preset-horizon-moved": ("1.0.0-alpha.5", {"mode": "OneVanishingPoint", "preset": "aps-c",
                                                          "reference_unit": "Yards"}, {"horizon_moved": True}),
    "alpha5-third": ("1.0.0-alpha.5", {"principal_point_mode": "FromThirdVanishingPoint"}, {}),
    "1.0.0-quad": ("1.0.0", {"quad": True}, {}),
    "1.0.0-1vp-preset-horizon-moved": ("1.0.0", {"mode": "OneVanishingPoint", "preset": "iphone_6s"},
                                       {"horizon_moved": True}),
    "1.0.2-1vp-feet-horizon-moved": ("1.0.2", {"mode": "OneVanishingPoint", "reference_unit": "Feet"},
                                     {"horizon_moved": True}),
    "1.0.2-1vp-manual-horizon-moved": ("1.0.2", {"mode": "OneVanishingPoint", "principal_point_mode": "Manual",
                                                 "reference_unit": "Inches"}, {"horizon_moved": True}),
    "1.0.2-manual-millimeters": ("1.0.2", {"principal_point_mode": "Manual", "reference_unit": "Millimeters"}, {}),
}


def test_layouts_cover_every_release():
    assert {release for release, _, _ in LAYOUTS.values()} == set(RELEASES)


@pytest.mark.parametrize("case", sorted(LAYOUTS))
def test_every_release_layout_gives_the_camera(tmp_path, case):
    """A project saved as each of fSpy's releases saves it (no saved camera before 1.0.0-alpha.5, no
    preset sensor size before 1.0.0, yards before 1.0.2, the dragged horizon as an object in all)
    is imported, and its noise-free marks give the true camera; fSpy's saved camera, where there is
    one, agrees row by row."""
    release, settings, saved = LAYOUTS[case]
    cam = KnownCamera.looking_at_corner()
    b = StateBuilder(cam, np.random.default_rng(3), noise_px=0.0, **settings)
    state = as_saved_by(b.build(), release, **saved)
    path, _, _ = write(tmp_path, b, state=state)
    r = import_fspy(path, tmp_path / "out")
    assert r.calibrated and r.fspy_camera == RELEASES[release]["camera"]
    project, rec = camera_of(r)
    assert abs(rec["K"][0][0] / cam.f - 1) < EXACT_REL
    assert rotation_difference_deg(np.array(rec["R"]), cam.R) < EXACT_DEG
    assert np.allclose(rec["position"]["value"], cam.C, atol=EXACT_M)
    for row in r.rows:
        assert row.fspy is None or abs(row.difference) < 1e-3, row
    notes = project.data["photos"][0]["imported_from"]["notes"]
    if "preset" in settings:
        assert any(repr(settings["preset"]) in n for n in notes), notes


def test_a_preset_fspy_does_not_know_falls_back_to_the_custom_sensor(tmp_path):
    """fSpy's loader drops a camera preset it does not know (and saved no sensor size for): its
    solver then uses the custom sensor size, and so does vebuild."""
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(3), noise_px=0.0,
                     mode="OneVanishingPoint", sensor_mm=(24.0, 16.0))
    state = as_saved_by(b.build(), "1.0.0-alpha.5")
    state["calibrationSettingsBase"]["cameraData"]["presetId"] = "no_such_camera"
    fp = read_fspy(write(tmp_path, b, state=state)[0])
    assert fp.sensor_mm == (24.0, 16.0) and "no_such_camera" in fp.sensor_source


# -- noisy marks: within vebuild's own 1σ, both sides ----------------------------------------------


@pytest.mark.parametrize("case", ["2vp", "quad", "1vp", "third"])
def test_noisy_marks_within_sigma(tmp_path, case):
    """Over 6 draws of 0.5 px click noise, and of the true principal point from vebuild's prior
    (1σ 3 % of the longer side about the centre, which fSpy's Default mode takes as exact), each
    error lies within 4σ of vebuild's own 1σ (from the click σ given, the injected noise, and the
    prior), and the errors' RMS in units of σ is neither far above 1 (σ too small) nor far below
    it (σ too large): between 0.4 and 1.8 (measured over 20 draws: 0.8 to 0.97)."""
    z = []
    for seed in range(6):
        offset = np.random.default_rng(900 + seed).normal(0.0, PRINCIPAL_POINT_SIGMA_REL * 640, 2)
        cam = KnownCamera.looking_at_corner(c_offset=(float(offset[0]), float(offset[1])))
        b = StateBuilder(cam, np.random.default_rng(100 + seed), noise_px=NOISE_PX, **CASES[case])
        path, _, _ = write(tmp_path, b, name=f"s{seed}")
        r = import_fspy(path, tmp_path / f"out{seed}", click_sigma_px=NOISE_PX)
        _, rec = camera_of(r)
        cov = np.array(rec["covariance"])
        f = rec["focal_px"]["value"]
        if not case.startswith("1vp"):  # in 1-VP mode f is fSpy's given focal length, exact here
            z.append((f - cam.f) / rec["focal_px"]["sigma"])
        # Rotation error as the small rotation ω on the camera side, R_true = exp([ω]×) R.
        w = log_so3(cam.R @ np.array(rec["R"]).T)
        z.extend((w / np.sqrt(np.diag(cov)[3:6])).tolist())
    z = np.array(z)
    assert np.all(np.abs(z) < SIGMAS), z
    rms = float(np.sqrt(np.mean(z ** 2)))
    assert 0.4 < rms < 1.8, (rms, z)


# -- format corner cases --------------------------------------------------------------------------


def test_no_saved_camera(tmp_path, capsys):
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.3, with_camera=False)
    path, state, _ = write(tmp_path, b)
    assert state["cameraParameters"] is None
    assert main(["import", str(path), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "holds no saved camera" in out and "focal length (px)" in out
    r = import_fspy(path, tmp_path / "o2")
    assert not r.fspy_camera and r.rows and all(row.fspy is None for row in r.rows)
    assert all(row.vebuild is not None for row in r.rows)


def test_units_and_no_reference(tmp_path):
    cam = KnownCamera.looking_at_corner()
    b = StateBuilder(cam, np.random.default_rng(0), noise_px=0.0, reference_unit="Centimeters")
    r = import_fspy(write(tmp_path, b, name="cm")[0], tmp_path / "cm")
    assert abs(camera_of(r)[1]["position"]["value"][2] - cam.C[2]) < EXACT_M
    b = StateBuilder(cam, np.random.default_rng(0), noise_px=0.0, reference_unit="No unit")
    r = import_fspy(write(tmp_path, b, name="nounit")[0], tmp_path / "nounit")
    assert any("no unit" in w for w in r.warnings)
    assert load_project(r.project).data["calibration"]["lengths"] == "relative"
    b = StateBuilder(cam, np.random.default_rng(0), noise_px=0.0, reference_axis=None)
    r = import_fspy(write(tmp_path, b, name="none")[0], tmp_path / "none")
    assert load_project(r.project).data["calibration"]["lengths"] == "relative"
    assert not any(row.quantity.startswith("position") for row in r.rows)


@pytest.mark.parametrize("axis", ["xPositive", "yPositive"])
def test_reference_distance_along_a_horizontal_axis(tmp_path, axis):
    """A reference distance along x (or y), from an anchor on the wall plane x = 0 (y = 0) above the
    floor: the handles need not lie on the floor; the camera's height still comes out."""
    cam = KnownCamera.looking_at_corner()
    b = StateBuilder(cam, np.random.default_rng(0), noise_px=0.0, reference_axis=axis)
    r = import_fspy(write(tmp_path, b)[0], tmp_path / "o")
    rec = camera_of(r)[1]
    assert np.allclose(rec["position"]["value"], cam.C, atol=EXACT_M)
    assert load_project(r.project).data["calibration"]["lengths"] == "metres"


def test_a_killed_import_is_cleaned_up(tmp_path):
    """A staging folder left by an import that was killed (its process gone, vebuild's mark in it)
    is removed by the next import into the same parent folder; nothing else there is touched."""
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0)
    path, _, _ = write(tmp_path, b)
    dead = tmp_path / ".old.999999999.0123abcd.vebuild-tmp"
    dead.mkdir()
    (dead / ".vebuild-output.json").write_text('{"software": "vebuild", "files": {}}')
    (dead / "scene.jpg").write_bytes(b"half")
    import_fspy(path, tmp_path / "new")
    assert not dead.exists() and path.exists()


def test_empty_out_folder_is_used_and_a_full_one_refused(tmp_path, monkeypatch):
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0)
    path, _, _ = write(tmp_path, b)
    (tmp_path / "empty").mkdir()
    import_fspy(path, tmp_path / "empty")
    with pytest.raises(VebuildError, match="not empty"):
        import_fspy(path, tmp_path / "empty")
    (tmp_path / "here").mkdir()
    monkeypatch.chdir(tmp_path / "here")
    with pytest.raises(VebuildError, match="working in"):
        import_fspy(path, ".")
    (tmp_path / "afile").write_text("x")
    with pytest.raises(VebuildError, match="is a file"):
        import_fspy(path, tmp_path / "afile")
    assert temporaries(tmp_path) == []


def test_the_folder_is_put_in_place_by_the_atomic_writer_and_replaces_nothing(tmp_path, monkeypatch, capsys):
    """Something written into --out after vebuild last looked (another program) is never replaced:
    the one rename is refused, the import says so (exit 2), and its staging folder is removed."""
    import vebuild.actions.fspy as action

    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0)
    path, _, _ = write(tmp_path, b)
    out = tmp_path / "out"
    out.mkdir()
    checks = []

    def check_then_someone_writes(folder):
        action_check(folder)
        checks.append(folder)
        if len(checks) == 2:  # the last look, just before the folder is put in place
            (folder / "letter.txt").write_text("someone's")

    action_check = action.check_out_folder
    monkeypatch.setattr(action, "check_out_folder", check_then_someone_writes)
    assert main(["import", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and str(out) in err and "nothing was written" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["letter.txt"] and temporaries(tmp_path) == []


def test_only_the_atomic_writer_renames_into_place():
    """vebuild/project/atomic.py is the one module that puts a file or a folder in place by a rename."""
    import re

    root = Path(__file__).resolve().parents[1] / "vebuild"
    rename = re.compile(r"\bos\.(rename|renames|replace)\(|\bshutil\.move\(|\.rename\(")
    found = [f"{p.relative_to(root)}:{i}" for p in sorted(root.rglob("*.py")) if p.name != "atomic.py"
             for i, line in enumerate(p.read_text("utf-8").splitlines(), 1) if rename.search(line)]
    assert found == []


def _state(**kw):
    return StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0, **kw).build()


def _state_1vp(**changes):
    s = _state(mode="OneVanishingPoint")
    for keys, value in changes.items():
        node = s
        *head, last = keys.split(".")
        for k in head:
            node = node[k]
        node[last] = value
    return s


def _without(path_keys):
    s = _state()
    node = s
    for k in path_keys[:-1]:
        node = node[k]
    del node[path_keys[-1]]
    return s


def _with(path_keys, value):
    s = _state()
    node = s
    for k in path_keys[:-1]:
        node = node[k]
    node[path_keys[-1]] = value
    return s


IMG = make_image(640, 480)
BAD = {
    "not-fspy": (IMG, "header", "not an fSpy project file"),
    "empty": (b"", "header", "not an fSpy project file"),
    "short-header": (b"fspy\x01\x00", "header", "truncated"),
    "truncated": (fspy_bytes(_state(), IMG)[:-100], "header.image_size", "truncated"),
    "longer": (fspy_bytes(_state(), IMG) + b"junk", "header.image_size", "bytes more"),
    "version": (fspy_bytes(_state(), IMG, version=2), "header.project_file_version", "version 2"),
    "no-image": (fspy_bytes(_state(), b""), "header.image_size", "no image"),
    "image-size": (fspy_bytes(_state(), IMG, image_size=len(IMG) + 10), "header.image_size", "truncated"),
    "bad-json": (fspy_bytes(b'{"globalSettings": {', IMG), "state", "not valid JSON"),
    "not-utf8": (fspy_bytes(b'{"a": "\xff"}', IMG), "state", "UTF-8"),
    "nan": (fspy_bytes(b'{"a": NaN}', IMG), "state", "not valid JSON"),
    "list-state": (fspy_bytes(b"[]", IMG), "$", "JSON object"),
    "bad-image": (fspy_bytes(_state(), b"\x89PNG not really"), "image", "cannot be decoded"),
    "gif": (fspy_bytes(_state(), make_image(64, 48, "GIF")), "image", "GIF"),
    "float-image": (fspy_bytes(_state(), float_tiff(np.random.default_rng(0), 480, 640).data or b""), "image",
                    "embedded image has pixels of 32-bit floating point (Pillow mode 'F')"),
    "axis-missing": (fspy_bytes(_without(["calibrationSettingsBase", "firstVanishingPointAxis"]), IMG),
                     "$.calibrationSettingsBase.firstVanishingPointAxis", "missing"),
    "axis-bad": (fspy_bytes(_with(["calibrationSettingsBase", "secondVanishingPointAxis"], "up"), IMG),
                 "$.calibrationSettingsBase.secondVanishingPointAxis", "expected one of"),
    "axis-same": (fspy_bytes(_with(["calibrationSettingsBase", "secondVanishingPointAxis"], "xPositive"), IMG),
                  "$.calibrationSettingsBase.secondVanishingPointAxis", "other than"),
    "mode": (fspy_bytes(_with(["globalSettings", "calibrationMode"], "1VP"), IMG),
             "$.globalSettings.calibrationMode", "expected one of"),
    "segment-missing": (fspy_bytes(_with(["controlPointsStateBase", "firstVanishingPoint", "lineSegments"], [[]]),
                                   IMG), "$.controlPointsStateBase.firstVanishingPoint.lineSegments", "two line"),
    "point-nonnumber": (fspy_bytes(_with(["controlPointsStateBase", "origin"], {"x": "a", "y": 0.5}), IMG),
                        "$.controlPointsStateBase.origin.x", "relative image coordinate"),
    "point-far": (fspy_bytes(_with(["controlPointsStateBase", "origin"], {"x": 40, "y": 0.5}), IMG),
                  "$.controlPointsStateBase.origin.x", "relative image coordinate"),
    "unit": (fspy_bytes(_with(["calibrationSettingsBase", "referenceDistanceUnit"], "Parsecs"), IMG),
             "$.calibrationSettingsBase.referenceDistanceUnit", "expected one of"),
    "distance": (fspy_bytes(_with(["calibrationSettingsBase", "referenceDistance"], -1), IMG),
                 "$.calibrationSettingsBase.referenceDistance", "above 0"),
    "matrix": (fspy_bytes(_with(["cameraParameters", "viewTransform"], {"rows": [[1, 0, 0]]}), IMG),
               "$.cameraParameters.viewTransform.rows", "4×4"),
    "vp-axes": (fspy_bytes(_with(["cameraParameters", "vanishingPointAxes"], ["xPositive", "xNegative", "zPositive"]),
                        IMG), "$.cameraParameters.vanishingPointAxes", "one each of x, y and z"),
    "image-dims": (fspy_bytes(_with(["cameraParameters", "imageWidth"], 480), IMG),
                   "$.cameraParameters.imageWidth", "embedded image is 640×480"),
    "parallel": (fspy_bytes(_with(["controlPointsStateBase", "firstVanishingPoint", "lineSegments"],
                                  [[{"x": 0.1, "y": 0.1}, {"x": 0.5, "y": 0.1}], [{"x": 0.1, "y": 0.3},
                                                                                  {"x": 0.5, "y": 0.3}]]), IMG),
                 "$.controlPointsStateBase.firstVanishingPoint.lineSegments", "parallel"),
    # Values of the wrong type or size (each a Python exception before): a whole number too large
    # for a float, a list or an object where a name is expected, a lens no camera has.
    "huge-integer": (fspy_bytes(json.dumps(_state()).replace('"origin": {"x": ', '"origin": {"x": ' + "9" * 400 +
                                                             ', "was": ', 1).encode(), IMG),
                     "$.controlPointsStateBase.origin.x", "relative image coordinate"),
    "axis-list": (fspy_bytes(_with(["calibrationSettingsBase", "firstVanishingPointAxis"], ["xPositive"]), IMG),
                  "$.calibrationSettingsBase.firstVanishingPointAxis", "expected one of"),
    "reference-axis-object": (fspy_bytes(_with(["calibrationSettingsBase", "referenceDistanceAxis"], {"a": 1}), IMG),
                              "$.calibrationSettingsBase.referenceDistanceAxis", "expected one of"),
    "unit-object": (fspy_bytes(_with(["calibrationSettingsBase", "referenceDistanceUnit"], {"unit": "Meters"}), IMG),
                    "$.calibrationSettingsBase.referenceDistanceUnit", "expected one of"),
    "vp-axes-lists": (fspy_bytes(_with(["cameraParameters", "vanishingPointAxes"], [["x"], ["y"], ["z"]]), IMG),
                      "$.cameraParameters.vanishingPointAxes", "one each of x, y and z"),
    "lens-no-camera-has": (fspy_bytes(_state_1vp(**{
        "calibrationSettings1VP.absoluteFocalLength": 100000,
        "calibrationSettingsBase.cameraData": {"presetId": None, "presetData": None, "customSensorWidth": 0.001,
                                               "customSensorHeight": 0.001}}), IMG),
        "$.calibrationSettings1VP.absoluteFocalLength", "expected 0.6° to 178°"),
    "quad-mode-number": (fspy_bytes(_with(["calibrationSettings2VP", "quadModeEnabled"], 0), IMG),
                         "$.calibrationSettings2VP.quadModeEnabled", "expected true or false"),
    "preset-id-list": (fspy_bytes(_state_1vp(**{"calibrationSettingsBase.cameraData.presetId": ["canon_5d"]}), IMG),
                       "$.calibrationSettingsBase.cameraData.presetId", "preset's name or null"),
    "horizon-other-keys": (fspy_bytes(_state_1vp(**{"controlPointsState1VP.horizon": {
        "0": {"x": 0.2, "y": 0.5}, "2": {"x": 0.8, "y": 0.5}}}), IMG), "$.controlPointsState1VP.horizon",
        "expected a pair of control points"),
    "horizon-object-point": (fspy_bytes(_state_1vp(**{"controlPointsState1VP.horizon": {
        "0": {"x": 0.2, "y": 0.5}, "1": {"x": [0.8], "y": 0.5}}}), IMG), '$.controlPointsState1VP.horizon["1"].x',
        "relative image coordinate"),
    "horizon-missing": (fspy_bytes(_with(["controlPointsState1VP"], {}) | {"globalSettings": {
        "calibrationMode": "OneVanishingPoint"}}, IMG), "$.controlPointsState1VP.horizon", "horizon"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_names_file_and_field(tmp_path, case, capsys):
    data, field, words = BAD[case]
    path = tmp_path / f"{case}.fspy"
    path.write_bytes(data)
    out = tmp_path / "out"
    with pytest.raises(VebuildError) as e:
        import_fspy(path, out)
    msg = str(e.value)
    assert str(path) in msg and field in msg and words in msg, msg
    if isinstance(e.value, ProjectError):
        assert e.value.where == field
    assert not out.exists() and temporaries(tmp_path) == []
    # The command line says it in one line, exit status 2, no traceback.
    assert main(["import", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and field in err
    assert not out.exists()


def test_missing_file_and_bad_click_sigma(tmp_path):
    with pytest.raises(VebuildError, match="not found"):
        read_fspy(tmp_path / "nothing.fspy")
    b = StateBuilder(KnownCamera.looking_at_corner(), np.random.default_rng(0), noise_px=0.0)
    path, _, _ = write(tmp_path, b)
    with pytest.raises(VebuildError, match="--click-sigma"):
        import_fspy(path, tmp_path / "o", click_sigma_px=0.0)
    assert not (tmp_path / "o").exists()


def test_fspy_state_is_kept_readable(tmp_path):
    """The parser reads back every field the writer put (no field silently ignored)."""
    b = StateBuilder(KnownCamera.looking_at_corner(480, 640), np.random.default_rng(0), noise_px=0.0, quad=True)
    path, state, _ = write(tmp_path, b)
    fp = read_fspy(path)
    assert (fp.width, fp.height) == (480, 640) and fp.quad_mode and fp.mode == "TwoVanishingPoints"
    a, c = state["controlPointsStateBase"]["firstVanishingPoint"]["lineSegments"]
    assert fp.second_segments == (((a[0]["x"], a[0]["y"]), (c[0]["x"], c[0]["y"])),
                                  ((a[1]["x"], a[1]["y"]), (c[1]["x"], c[1]["y"])))
    assert fp.third_axis == "zPositive"  # (−x) × (−y)
    assert json.loads(json.dumps(fp.state)) == state
    # A file from before fSpy had a quad mode has no quadModeEnabled: off, as fSpy reads it.
    del state["calibrationSettings2VP"]["quadModeEnabled"]
    assert not parse_fspy(fspy_bytes(state, make_image(480, 640)), path).quad_mode


def test_exif_turned_photo_uses_the_displayed_size(tmp_path):
    """A JPEG stored 640×480 with EXIF orientation 6 is shown (by fSpy's browser, and by vebuild)
    turned a quarter, 480×640: fSpy's marks are relative to that, and so is the imported photo."""
    import io

    from PIL import Image

    cam = KnownCamera.looking_at_corner(480, 640)
    b = StateBuilder(cam, np.random.default_rng(0), noise_px=0.0)
    exif = Image.Exif()
    exif[0x0112] = 6
    buf = io.BytesIO()
    Image.new("RGB", (640, 480), (90, 90, 90)).save(buf, format="JPEG", exif=exif.tobytes())
    path, _, image = write(tmp_path, b, image=buf.getvalue())
    r = import_fspy(path, tmp_path / "o")
    project, rec = camera_of(r)
    photo = project.data["photos"][0]
    assert (photo["width"], photo["height"]) == (480, 640) and r.photo.read_bytes() == image
    assert rotation_difference_deg(np.array(rec["R"]), cam.R) < EXACT_DEG
