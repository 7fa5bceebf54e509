"""Photos from one camera share its focal length, principal point and lens distortion.

Generated sets (vebuild.synthetic.shared) reproduce the failure: every photo taken with one camera
(one K, EXIF make, model, serial and focal length equal), a near-frontal photo among oblique ones
whose lines alone cannot fix f. Calibrated apart, it is left out (no EXIF) or gets EXIF's f; in its
group it borrows the oblique photos' f, with their σ.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from camera_group_scene import camera_set, run_vebuild, with_box

from vebuild.calibration.camera_groups import camera_groups
from vebuild.calibration.photo import calibrate_photo
from vebuild.calibration.priors import FocalPrior
from vebuild.calibration.shared_camera import GroupMember, calibrate_shared
from vebuild.camera import log_so3
from vebuild.errors import CalibrationError
from vebuild.synthetic import CLICK_NOISE_PX, SyntheticPhoto, add_segments
from vebuild.synthetic.shared import one_camera_set, write_one_camera_project

#: |error| / reported 1σ that no estimate may exceed (as in test_calibration: a 1-in-10⁵ draw).
UNCERTAINTY_BOUND = 4.5
#: How far apart the placed photos of one group may put f and c: the placement's tie (positions.TIE_SIGMA_PX) and
#: the solver's tolerance; a thousandth of a pixel is below any figure printed.
TIE_PX = 1e-3
#: Sets over which the shared intrinsics' intervals are checked (each against UNCERTAINTY_BOUND).
COVERAGE_SETS = 30


def _members(photos: list[SyntheticPhoto]) -> list[GroupMember]:
    return [GroupMember(p.id, dict(segments=p.segments, width=p.width, height=p.height, photo=p.id,
                                   click_sigma_px=CLICK_NOISE_PX)) for p in photos]


def _photo(pid: str, exif: dict | None = None, size: tuple[int, int] = (1600, 1200), **kw: object) -> dict:
    return {"id": pid, "width": size[0], "height": size[1], **({"exif": exif} if exif else {}), **kw}


def test_photos_of_one_camera_are_grouped_by_exif_make_model_serial_and_focal_length() -> None:
    cam = {"make": "NIKON CORPORATION", "model": "NIKON D7000", "body_serial": "6012345", "focal_length_mm": 18.0}
    other_body = {**cam, "body_serial": "6099999"}
    no_serial = {k: v for k, v in cam.items() if k != "body_serial"}
    photos = [_photo("a", cam), _photo("b", cam), _photo("c", other_body), _photo("d", other_body),
              _photo("e", {**cam, "focal_length_mm": 35.0}), _photo("f", cam, size=(1200, 1600)),
              _photo("g", cam, own_camera=True), _photo("h"), _photo("i"), _photo("j", no_serial),
              _photo("k", no_serial)]
    groups = {g.photos: g for g in camera_groups(photos)}
    # One body at one focal length, one size: a group; another body of the model: another group.
    assert set(groups) == {("a", "b"), ("c", "d"), ("j", "k")}
    assert groups[("a", "b")].source == "exif" and groups[("a", "b")].serial == "6012345"
    assert groups[("a", "b")].id == "NIKON CORPORATION NIKON D7000 #6012345 at 18 mm"
    # No serial recorded: grouped, and the group says so (two bodies would be merged).
    assert groups[("j", "k")].serial is None
    # The user's groups come first and take their photos out of EXIF's; photos without EXIF are
    # grouped only by the user; one left alone in an EXIF group is no group.
    user = camera_groups(photos, [{"id": "mine", "photos": ["b", "h", "i"]}])
    assert [(g.id, g.photos, g.source) for g in user] == [("mine", ("b", "h", "i"), "user"),
                                                          ("NIKON CORPORATION NIKON D7000 #6099999 at 18 mm",
                                                           ("c", "d"), "exif"),
                                                          ("NIKON CORPORATION NIKON D7000 at 18 mm", ("j", "k"),
                                                           "exif")]


def test_read_exif_records_the_body_serial(tmp_path: Path) -> None:
    """EXIF BodySerialNumber (0xA431): what tells two bodies of one model apart."""
    from PIL import Image

    from vebuild.project import read_exif

    exif = Image.Exif()
    exif[0x010F], exif[0x0110] = "NIKON CORPORATION", "NIKON D7000"
    sub = exif.get_ifd(0x8769)
    sub[0xA431], sub[37386] = "6012345", 18.0
    path = tmp_path / "a.jpg"
    Image.new("RGB", (64, 48), (128, 128, 128)).save(path, format="JPEG", exif=exif)
    got = read_exif(path)
    assert got["body_serial"] == "6012345"
    assert list(got)[:3] == ["make", "model", "body_serial"]


def test_a_frontal_photo_borrows_the_focal_length_of_its_camera_group() -> None:
    """The frontal photo's lines leave f undetermined: alone it is refused; in its group its f is
    the group's, inside its interval, with a 1σ no wider than the oblique photos' own."""
    photos, _ = camera_set()
    frontal = photos[3]
    assert frontal.kind == "frontal"
    with pytest.raises(CalibrationError, match="the focal length is not determined"):
        calibrate_photo(frontal.segments, frontal.width, frontal.height, photo=frontal.id,
                        click_sigma_px=CLICK_NOISE_PX)
    alone = [calibrate_photo(p.segments, p.width, p.height, photo=p.id, click_sigma_px=CLICK_NOISE_PX)
             for p in photos[:3]]
    shared = calibrate_shared("one camera", _members(photos))
    assert shared is not None and not shared.released and set(shared.photos) == {"p1", "p2", "p3", "p4"}
    cal = shared.photos["p4"]
    f_true = frontal.K[0, 0]
    assert abs(cal.f - f_true) < UNCERTAINTY_BOUND * cal.f_sigma
    assert cal.f_sigma == pytest.approx(shared.f_sigma, rel=1e-9)
    assert cal.f_sigma <= max(c.f_sigma for c in alone)
    assert all(np.allclose(c.K, cal.K) for c in shared.photos.values())  # one set of intrinsics
    w = log_so3(frontal.R @ cal.R.T)
    assert float(w @ np.linalg.solve(cal.covariance[3:6, 3:6], w)) < UNCERTAINTY_BOUND**2
    assert "shared by the 4 photos of camera group 'one camera'" in cal.mode_reason


def test_a_photo_whose_lines_contradict_its_group_is_released() -> None:
    """p2 taken at another zoom (f 20 % longer) but with the same EXIF: its own lines contradict
    the group's f by far more than 3σ, so it leaves the group, saying so; the others share theirs."""
    photos, _ = camera_set()
    zoomed = photos[1]
    zoomed.K = zoomed.K.copy()
    zoomed.K[0, 0] = zoomed.K[1, 1] = 1.2 * photos[0].K[0, 0]
    add_segments(zoomed, np.random.default_rng(1), CLICK_NOISE_PX)
    shared = calibrate_shared("one camera", _members(photos))
    assert shared is not None and list(shared.released) == ["p2"]
    assert "from the camera group's" in shared.released["p2"] and "limit 3σ" in shared.released["p2"]
    assert set(shared.photos) == {"p1", "p3", "p4"}
    assert abs(shared.f - photos[0].K[0, 0]) < UNCERTAINTY_BOUND * shared.f_sigma


def test_the_shared_intrinsics_intervals_hold_the_truth() -> None:
    """Over generated one-camera sets (three oblique photos and a frontal one, the principal point
    3 % off centre, EXIF 2 % off and combined as evidence) no shared f, principal point or photo
    rotation is more than UNCERTAINTY_BOUND σ off. (Over 150 sets without EXIF, 93 % of f, 97 % of
    principal point coordinates and 95 % of rotations lay inside their 95 % intervals.)"""
    worst = 0.0
    inside = []
    for seed in range(COVERAGE_SETS):
        photos, _ = one_camera_set(np.random.default_rng(100 + seed))
        K = photos[0].K
        exif = FocalPrior(photos[0].exif_focal_px, 0.03 * photos[0].exif_focal_px, "exif")
        s = calibrate_shared("g", _members(photos), exif_focal=exif)
        assert s is not None
        z = np.r_[(s.f - K[0, 0]) / s.f_sigma, (s.principal_point - K[:2, 2]) / s.principal_point_sigma]
        for p in photos:
            if p.id in s.photos:
                c = s.photos[p.id]
                w = log_so3(p.R @ c.R.T)
                z = np.r_[z, w / c.rotation_sigma_rad]
        worst = max(worst, float(np.abs(z).max()))
        inside.append(abs(z[0]) < 1.96)
    assert worst < UNCERTAINTY_BOUND
    assert np.mean(inside) >= 0.8  # 95 % expected; 0.8 is 3.7σ below it over 30 sets


def test_calibrate_groups_the_photos_of_one_camera_by_exif(tmp_path: Path) -> None:
    photos, markers = camera_set()
    path = write_one_camera_project(tmp_path, photos, markers)
    r = run_vebuild("calibrate", path, "--quiet")
    assert r.returncode == 0, r.stderr
    cal = json.loads(path.read_text(encoding="utf-8"))["calibration"]
    [group] = cal["camera_groups"]
    assert group["source"] == "exif" and group["body_serial"] == "0000417" and group["shared"]
    assert group["photos"] == ["p1", "p2", "p3", "p4"] and group["released"] == {}
    f_true = photos[0].K[0, 0]
    assert abs(group["focal_px"]["value"] - f_true) < UNCERTAINTY_BOUND * group["focal_px"]["sigma"]
    records = {**cal["cameras"], **cal["unplaced"]}
    assert {pid: rec["camera_group"] for pid, rec in records.items()} == {p: group["id"] for p in group["photos"]}
    # Placement keeps one set of intrinsics for the group's placed photos (held by the group's one
    # prior, not by each photo's: the shared f would otherwise count once per photo).
    placed = [cal["cameras"][p] for p in ("p1", "p2", "p3")]
    for key in ("focal_px", "principal_point"):
        assert np.allclose([c[key]["value"] for c in placed], placed[0][key]["value"], rtol=0, atol=TIE_PX)
        assert np.allclose([c[key]["sigma"] for c in placed], placed[0][key]["sigma"], rtol=1e-3)
    assert abs(placed[0]["focal_px"]["value"] - f_true) < UNCERTAINTY_BOUND * placed[0]["focal_px"]["sigma"]
    # The frontal photo (no marker shared with the others: not placed) has the group's camera.
    assert records["p4"]["focal_px"]["value"] == pytest.approx(group["focal_px"]["value"], rel=1e-12)
    assert f"{group['id']} (exif): photos p1, p2, p3, p4" in r.stdout
    # The report's calibration section has a row per group, with its shared values.
    from vebuild.project import load_project
    from vebuild.report.cameras import calibration
    from vebuild.report.page import Report

    rep = Report(tmp_path / "report")
    calibration(load_project(path), rep)
    section = rep.sections[0]
    assert "<h3>Camera groups</h3>" in section
    f = group["focal_px"]
    assert f"{f['value']:.1f} ± {f['sigma']:.1f}" in section.split("<h3>Camera groups</h3>")[1]


def test_the_user_groups_photos_and_releases_one(tmp_path: Path) -> None:
    """No EXIF: alone, the frontal photo is left out (its f undetermined); grouped by the user on the
    command line it is calibrated with the others' f; released again, it is left out again. The
    groups and the release are saved in the project (camera_groups, own_camera)."""
    photos, markers = camera_set()
    path = write_one_camera_project(tmp_path, photos, markers, exif=False)
    r = run_vebuild("calibrate", path, "--quiet")
    assert r.returncode == 0, r.stderr
    assert "p4" in json.loads(path.read_text(encoding="utf-8"))["calibration"]["left_out"]
    r = run_vebuild("calibrate", path, "--quiet", "--group", "body=p1,p2,p3,p4")
    assert r.returncode == 0, r.stderr
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["camera_groups"] == [{"id": "body", "photos": ["p1", "p2", "p3", "p4"]}]
    cal = doc["calibration"]
    assert "left_out" not in cal and cal["unplaced"]["p4"]["camera_group"] == "body"
    f = cal["unplaced"]["p4"]["focal_px"]
    assert abs(f["value"] - photos[0].K[0, 0]) < UNCERTAINTY_BOUND * f["sigma"]
    r = run_vebuild("calibrate", path, "--quiet", "--release", "p4")
    assert r.returncode == 0, r.stderr
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["camera_groups"] == [{"id": "body", "photos": ["p1", "p2", "p3"]}]
    assert doc["photos"][3]["own_camera"] is True and "p4" in doc["calibration"]["left_out"]
    before = path.read_bytes()
    r = run_vebuild("calibrate", path, "--quiet", "--group", "x=p1,p9")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "--group 'x=p1,p9': names the photo 'p9'" in r.stderr and "expected one of" in r.stderr
    assert path.read_bytes() == before
    # The groups are an input of the calibration: changed, the calibration is stale.
    doc["camera_groups"] = [{"id": "body", "photos": ["p1", "p2"]}]
    path.write_text(json.dumps(doc), encoding="utf-8")
    r = run_vebuild("check", path)
    assert "the calibration is stale: camera_groups changed after calibrating" in r.stdout + r.stderr


def test_the_modelling_screen_groups_releases_and_shows_camera_groups(tmp_path: Path) -> None:
    """The screen's session: the user groups the photos (one undoable edit), calibrates (the group
    shown with its shared values), releases a photo; undo takes the release back."""
    from vebuild.edit.session import EditSession

    photos, markers = camera_set()
    path = write_one_camera_project(tmp_path, photos, markers, exif=False)
    s = EditSession.open(path)
    s.group_cameras("body", ["p1", "p2", "p3", "p4"])
    assert s.data["camera_groups"] == [{"id": "body", "photos": ["p1", "p2", "p3", "p4"]}]
    result = s.calibrate()
    [group] = result["camera_groups"]
    f = group["focal_px"]
    assert "body (user): photos p1, p2, p3, p4" in s.messages
    assert f"focal length     {f['value']:.1f} ± {f['sigma']:.1f} px   (from {group['focal_source']})" in s.messages
    s.release_camera("p4")
    assert s.data["photos"][3]["own_camera"] is True
    assert s.data["camera_groups"] == [{"id": "body", "photos": ["p1", "p2", "p3"]}]
    assert s.undo() and "own_camera" not in s.data["photos"][3]


def test_exif_contradicted_in_a_group_is_warned_once(tmp_path: Path) -> None:
    """The group's EXIF focal length 30 % longer than its photos' lines say (far beyond the 3σ
    limit): EXIF is not combined, and the warning names the group's photos once, not once per photo."""
    photos, markers = camera_set()
    for p in photos:
        p.exif_focal_px = 1.3 * p.K[0, 0]
    path = write_one_camera_project(tmp_path, photos, markers)
    r = run_vebuild("calibrate", path, "--quiet")
    assert r.returncode == 0, r.stderr
    cal = json.loads(path.read_text(encoding="utf-8"))["calibration"]
    [group] = cal["camera_groups"]
    assert not group["exif_focal_check"]["combined"]
    said = [w for w in cal["warnings"] if "EXIF's focal length" in w]
    assert len(said) == 1, said
    assert said[0].startswith("photos 'p1', 'p2', 'p3', 'p4' (one camera group): ")
    assert "EXIF is not combined" in said[0]


def test_solve_recalibrate_shares_one_camera_per_group(tmp_path: Path) -> None:
    """Calibrated as one camera, re-calibrated by `solve --recalibrate`: the group's placed photos
    keep one K and k1 (to TIE_PX: one unknown, not tied ones), their 1σ no wider than the
    calibration's and the truth inside UNCERTAINTY_BOUND σ; the group's record in model_solution
    gives them once. A photo released from the group keeps its own f."""
    photos, markers = camera_set()
    f_true, c_true = photos[0].K[0, 0], photos[0].K[:2, 2]
    path = write_one_camera_project(tmp_path, photos, markers)
    assert run_vebuild("calibrate", path, "--quiet").returncode == 0
    with_box(path)
    r = run_vebuild("solve", path, "--recalibrate")
    assert r.returncode == 0, r.stderr
    doc = json.loads(path.read_text(encoding="utf-8"))
    [cal_group] = doc["calibration"]["camera_groups"]
    [group] = doc["model_solution"]["camera_groups"]
    solved = doc["model_solution"]["cameras"]
    assert group["id"] == cal_group["id"] and group["photos"] == [p for p in ("p1", "p2", "p3") if p in solved]
    assert len(group["photos"]) >= 2
    recs = [solved[p] for p in group["photos"]]
    for key in ("focal_px", "principal_point"):
        assert np.allclose([c[key]["value"] for c in recs], group[key]["value"], rtol=0, atol=TIE_PX)
    assert group["focal_px"]["sigma"] <= cal_group["focal_px"]["sigma"]
    assert np.all(np.array(group["principal_point"]["sigma"]) <= np.array(cal_group["principal_point"]["sigma"]))
    assert abs(group["focal_px"]["value"] - f_true) < UNCERTAINTY_BOUND * group["focal_px"]["sigma"]
    f = group["focal_px"]
    assert f"  {group['id']}: photos {', '.join(group['photos'])}" in r.stdout
    assert f"focal length {f['value']:.1f} ± {f['sigma']:.1f} px" in r.stdout
    assert np.all(np.abs(np.array(group["principal_point"]["value"]) - c_true)
                  < UNCERTAINTY_BOUND * np.array(group["principal_point"]["sigma"]))
    # --fixed-intrinsics: every K as calibrated, as for any photo; no group re-calibrated.
    assert run_vebuild("solve", path, "--recalibrate", "--fixed-intrinsics").returncode == 0
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert "camera_groups" not in doc["model_solution"]
    for pid, rec in doc["model_solution"]["cameras"].items():
        assert rec["K"] == doc["calibration"]["cameras"][pid]["K"]
    # Released: p3 is calibrated and re-calibrated with its own camera, no longer the group's.
    assert run_vebuild("calibrate", path, "--quiet", "--release", "p3").returncode == 0
    with_box(path)
    r = run_vebuild("solve", path, "--recalibrate")
    assert r.returncode == 0, r.stderr
    doc = json.loads(path.read_text(encoding="utf-8"))
    [group] = doc["model_solution"]["camera_groups"]
    solved = doc["model_solution"]["cameras"]
    assert "p3" not in group["photos"] and "p3" in solved
    assert abs(solved["p3"]["focal_px"]["value"] - group["focal_px"]["value"]) > TIE_PX
