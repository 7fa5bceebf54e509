"""Stills of one fixed camera (frames of one video) calibrate as one photo: lines and markers marked
on different frames add up (vebuild/actions/fixed_camera.py)."""

from __future__ import annotations

import copy
import shutil
from pathlib import Path

import numpy as np
import pytest
from camera_group_scene import with_box
from chromium_cdp import Browser, find_chromium
from one_photo_scene import one_photo, write_one_photo

from vebuild.actions.calibrate import calibrate_project
from vebuild.actions.export_html import export_html
from vebuild.actions.solve import solve_project
from vebuild.console.tables import calibration_table
from vebuild.project import load_project, save_project, sha256_file
from vebuild.report.page import Report
from vebuild.report.sections import photos

ORIGIN = {"video": "cctv.mp4", "sha256": "ab" * 32, "container": "mov,mp4,m4a,3gp,3g2,mj2", "stream": 0,
          "decoder": "h264 (FFmpeg libavcodec 62.28.103)", "frames": 100, "time_base": "1/12800",
          "interlaced": False, "field": "both"}


def _split_over_two_frames(path: Path, own_camera: bool = False) -> Path:
    """The one-photo project at ``path`` made into two stills of one video: the even segments of
    each axis and markers O, F1 on the first frame; the odd segments, F2, F3 and the known length on
    the second."""
    project = load_project(path)
    d = project.data
    (photo,) = d["photos"]
    src = project.photo_path(photo)
    a, b = copy.deepcopy(photo), copy.deepcopy(photo)
    for k, (p, n) in enumerate(((a, 10), (b, 40))):
        p["id"] = f"cctv.f{n:06d}"
        p["file"] = f"photos/{p['id']}.jpg"
        shutil.copy(src, path.parent / p["file"])
        p["sha256"] = sha256_file(path.parent / p["file"])
        p["origin"] = {**ORIGIN, "frame": n, "pts": 512 * n, "time": n * 0.04, "width": photo["width"],
                       "height": photo["height"]}
        p["vanishing_segments"] = {ax: rows[k::2] for ax, rows in photo["vanishing_segments"].items()}
        if own_camera:
            p["own_camera"] = True
    a["marker_observations"] = {n: photo["marker_observations"][n] for n in ("O", "F1")}
    b["marker_observations"] = {n: photo["marker_observations"][n] for n in ("F2", "F3")}
    for length in d.get("known_lengths", []):
        length["photo"] = b["id"]
    d["photos"] = [a, b]
    out = path.with_name("split.vebuild.json")
    save_project(out, d)
    return out


@pytest.mark.parametrize("seed", [3, 11])
def test_lines_split_over_two_frames_calibrate_as_all_on_one(tmp_path: Path, seed: int) -> None:
    ph = one_photo(np.random.default_rng(seed))
    whole = load_project(write_one_photo(tmp_path, ph))
    one = calibrate_project(whole)["cameras"][ph.cam.id]
    split = load_project(_split_over_two_frames(whole.path))
    cams = calibrate_project(split)["cameras"]
    assert set(cams) == {"cctv.f000010", "cctv.f000040"}
    for pid, cam in cams.items():
        assert cam["fixed_camera"] == {"stills": ["cctv.f000010", "cctv.f000040"]}
        # The same marks, in another order: the same least-squares minimum, to the solvers'
        # convergence (1e-6 of the focal length, 1e-6 m, 1e-6 of a rotation).
        assert cam["focal_px"]["value"] == pytest.approx(one["focal_px"]["value"], rel=1e-6), pid
        assert np.allclose(cam["position"]["value"], one["position"]["value"], atol=1e-6), pid
        assert np.allclose(cam["R"], one["R"], atol=1e-6), pid
        assert cam["focal_px"]["sigma"] == pytest.approx(one["focal_px"]["sigma"], rel=1e-4), pid
    # And what it is worth against the truth: the camera's centre where the generator put it,
    # within 4σ of the calibration's own covariance, on every axis.
    C, sig = np.array(cams["cctv.f000010"]["position"]["value"]), np.array(cams["cctv.f000010"]["position"]["sigma"])
    assert np.all(np.abs(C - ph.C) < 4 * sig + 1e-9)
    save_project(split)  # the record is valid against the schema: written and read back
    said = calibration_table(load_project(split.path).data["calibration"])
    assert "fixed camera     one camera with cctv.f000040 (stills of one video" in said
    assert load_project(split.path).data["calibration"]["cameras"]["cctv.f000040"]["fixed_camera"]


def test_frames_released_from_the_fixed_camera_calibrate_each_alone(tmp_path: Path) -> None:
    """Each frame alone has half the lines: with own_camera, neither is the camera of all of them."""
    ph = one_photo(np.random.default_rng(3))
    whole = load_project(write_one_photo(tmp_path, ph))
    one = calibrate_project(whole)["cameras"][ph.cam.id]
    split = load_project(_split_over_two_frames(whole.path, own_camera=True))
    result = calibrate_project(split)
    for cam in result["cameras"].values():
        assert "fixed_camera" not in cam
        assert cam["focal_px"]["sigma"] > one["focal_px"]["sigma"]


def test_the_report_and_the_html_viewer_name_each_stills_video_frame_time_and_field(tmp_path: Path) -> None:
    ph = one_photo(np.random.default_rng(3))
    split = load_project(_split_over_two_frames(write_one_photo(tmp_path, ph)))
    split.data["photos"][1]["origin"].update(field="top", interlaced=True)
    calibrate_project(split)
    save_project(split)
    rep = Report(tmp_path / "report")
    photos(split, rep)
    html = "".join(rep.sections)
    for text in ("cctv.mp4", "ab" * 32, ">10<", ">40<", "0.400", "1.600", ">top<", "both (whole frame)"):
        assert text in html, text
    # A measurement on a still is drawn on its frame, the caption naming the video, frame, time and field.
    from vebuild.analysis.single_view import single_view_command
    from vebuild.report.single_view import section

    split.data["analyses"] = [{"name": "box", "command": single_view_command(
        "photo-height", "cctv.f000040", [ph.clicks["box_foot"], ph.clicks["box_top"]])}]
    (tmp_path / "report" / "images").mkdir(parents=True, exist_ok=True)
    rep = Report(tmp_path / "report")
    section(split, rep)
    (measured,) = rep.sections
    assert ("a still: frame 40 at 1.6 s of cctv.mp4 (SHA-256 " + "ab" * 32 + "), top field only") in measured
    export_html(split, tmp_path / "web", photo="cctv.f000040")
    written = "".join(p.read_text(errors="replace") for p in (tmp_path / "web").rglob("*.js*"))
    assert "frame 40 at 1.6 s of cctv.mp4 (SHA-256 " + "ab" * 32 + "), top field only (interlaced" in written


@pytest.mark.slow  # a headless Chromium
def test_the_html_viewer_shows_each_stills_video_and_frame_in_its_camera_list(tmp_path: Path) -> None:
    """In a real headless Chromium (tests/chromium_cdp.py): the panel's camera list names the video,
    its SHA-256, the frame, its time and the field beside the still's camera."""
    chromium = find_chromium()
    if chromium is None:
        pytest.skip("the HTML viewer's tests need a headless Chromium: `apt-get install chromium`")
    split = load_project(_split_over_two_frames(write_one_photo(tmp_path, one_photo(np.random.default_rng(3)))))
    split.data["photos"][1]["origin"].update(field="bottom", interlaced=True)
    calibrate_project(split)
    save_project(split)
    export_html(split, tmp_path / "web", photo="cctv.f000040")
    browser = Browser(chromium, 800, 600)
    try:
        browser.open((tmp_path / "web" / "index.html").as_uri())
        state = "JSON.parse(document.getElementById('vebuild-state').textContent)"
        browser.wait_for(f"(function(){{var s={state};return s.errors.length>0||s.stage==='running';}})()", 60)
        assert browser.evaluate(f"{state}.errors") == []
        shown = browser.evaluate("document.getElementById('cameras').textContent")
    finally:
        browser.close()
    assert ("cctv.f000040: frame 40 at 1.6 s of cctv.mp4 (SHA-256 " + "ab" * 32 + "), bottom field only (interlaced"
            in shown)


def test_a_recalibrating_solve_warns_that_it_does_not_hold_the_fixed_camera_as_one(tmp_path: Path) -> None:
    split = load_project(_split_over_two_frames(write_one_photo(tmp_path, one_photo(np.random.default_rng(3)))))
    calibrate_project(split)
    save_project(split)
    with_box(split.path)
    project = load_project(split.path)
    plain = solve_project(project)
    assert not any("fixed camera" in w for w in plain["warnings"])
    result = solve_project(project, recalibrate=True)
    assert any("are one fixed camera, but the re-calibration refines each still's camera on its own" in w
               and "by up to √2" in w for w in result["warnings"])
