"""Suggested correspondences (vebuild.edit.suggest and the session's proposals) on the example
room's photos with their true cameras (scenes/room/ground_truth.json): SIFT matches that pass the
epipolar check lie on the true geometry, wrong pairs are rejected by it, a marker placed in one
photo is found in another along its epipolar line, a pin's image corner is proposed, each accept is
one undoable edit, and a photo with no features gives no proposals (and no hang)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from vebuild.camera import ImageCamera, project
from vebuild.edit.suggest import (
    EPIPOLAR_SIGMAS,
    FEATURE_SIGMA_PX,
    along_epipolar,
    check_matches,
    fundamental,
    match_photos,
    pin_corner,
    sampson,
)

ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
TRUTH = json.loads((ROOM / "ground_truth.json").read_text())
#: A true correspondence's distance from its epipolar line with exact cameras: the two key points'
#: noise, EPIPOLAR_SIGMAS of it (the check's own threshold).
TRUE_TOL_PX = EPIPOLAR_SIGMAS * np.sqrt(2.0) * FEATURE_SIGMA_PX


def camera(pid: str) -> ImageCamera:
    t = TRUTH["photos"][pid]
    return ImageCamera(pid, np.asarray(t["K"]), np.asarray(t["R"]), np.asarray(t["C"]), t["width"], t["height"])


@pytest.fixture(scope="module")
def photos():
    return {p: np.asarray(Image.open(ROOM / "photos" / f"{p}.jpg").convert("RGB")) for p in ("p1", "p3")}


@pytest.fixture(scope="module")
def matches(photos):
    return match_photos(photos["p1"], camera("p1"), photos["p3"], camera("p3"))


def test_matched_features_lie_on_the_true_geometry(matches):
    found, rejected = matches
    assert len(found) >= 10 and rejected > 0
    a, b = camera("p1"), camera("p3")
    F = fundamental(a, b)
    d = sampson(F, np.array([m.uv_a for m in found]), np.array([m.uv_b for m in found]))
    assert np.all(d <= TRUE_TOL_PX)
    # Their triangulated points reproject where they were found and lie inside the room.
    X = np.array([m.X for m in found])
    for cam, uv in ((a, [m.uv_a for m in found]), (b, [m.uv_b for m in found])):
        assert np.max(np.linalg.norm(project(cam.K, cam.R, cam.C, X) - np.asarray(uv), axis=1)) < TRUE_TOL_PX
    room = np.asarray(TRUTH["room"], float)
    assert np.all(X > -0.05) and np.all(X < room + 0.05)


def test_wrong_pairs_are_rejected_by_the_epipolar_check(matches):
    found, _ = matches
    uva = np.array([m.uv_a for m in found])
    uvb = np.array([m.uv_b for m in found])
    wrong = np.roll(uvb, 3, axis=0)  # each point paired with another's match
    kept, rejected = check_matches(camera("p1"), camera("p3"), uva, wrong)
    assert len(kept) <= 0.1 * len(found) and rejected >= 0.9 * len(found)


def test_a_marker_is_found_along_its_epipolar_line(photos):
    a, b = camera("p1"), camera("p3")
    for name in ("O", "T2"):
        X = np.asarray(TRUTH["markers"][name], float)
        got = along_epipolar(photos["p1"], a, project(a.K, a.R, a.C, X), photos["p3"], b)
        assert got is not None, name
        uv, ncc, depth = got
        # The corner refinement of the found patch: within 1.5 px (JPEG, the view's foreshortening).
        assert np.linalg.norm(np.asarray(uv) - project(b.K, b.R, b.C, X)) < 1.5, name
        assert ncc > 0.7 and depth > 0


def test_a_pin_is_proposed_at_the_image_corner_near_the_vertex(photos):
    b = camera("p3")
    X = np.asarray(TRUTH["markers"]["O"], float)  # the room's corner on the floor
    true = project(b.K, b.R, b.C, X)
    got = pin_corner(photos["p3"], true + np.array([6.0, -4.0]))
    assert got is not None and np.linalg.norm(np.asarray(got) - true) < 1.5


def test_a_photo_with_no_features_gives_nothing():
    flat = np.full((600, 800, 3), 128, np.uint8)
    a = camera("p1").resized(800, 600)
    assert match_photos(flat, a, flat, a) == ([], 0)
    assert pin_corner(flat, (400.0, 300.0)) is None


def test_suggested_markers_accepted_one_by_one_and_undone(tmp_path):
    from vebuild.edit.session import EditSession

    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder)
    s = EditSession.open(folder / "room.vebuild.json", autosave=False)
    s.calibrate()
    obs = s.photo("p3")["marker_observations"]
    s.remove_marker("p3", "T2")
    n = s.suggest_markers("p3")
    props = s.proposals["p3"]
    assert n == len(props) and any(p.name == "T2" for p in props)
    k = next(i for i, p in enumerate(props) if p.name == "T2")
    cam = s.cameras["p3"]
    true = project(cam.K, cam.R, cam.C, np.asarray(TRUTH["markers"]["T2"], float))
    # Triangulated from two calibrated photos (about a pixel, the cameras' own error) and snapped to
    # the image corner there, which moves it at most SNAP_RADIUS_PX.
    from vebuild.edit.snap import SNAP_RADIUS_PX

    assert np.linalg.norm(np.asarray(props[k].uv) - true) < SNAP_RADIUS_PX + 1.0
    before = json.dumps(s.data, sort_keys=True)
    s.accept_proposal("p3", k)
    assert "T2" in obs or "T2" in s.photo("p3")["marker_observations"]
    assert s.undo() and json.dumps(s.data, sort_keys=True) == before
    # The matched features: new markers placed in both photos by one accept, one undo.
    assert s.suggest_markers("p3", features=True) > 0
    assert all(p.also and p.name not in s.project.marker_names() for p in s.proposals["p3"])
    p = s.proposals["p3"][0]
    s.accept_proposal("p3", 0)
    assert p.name in s.photo(p.also[0][0])["marker_observations"] and p.name in s.photo("p3")["marker_observations"]
    assert s.undo() and json.dumps(s.data, sort_keys=True) == before
    # Accept all is one edit; reject drops one.
    left = len(s.proposals["p3"])
    s.reject_proposal("p3", 0)
    assert len(s.proposals["p3"]) == left - 1
    assert s.accept_all("p3") == left - 1 and not s.proposals["p3"]
    assert s.undo() and json.dumps(s.data, sort_keys=True) == before


def test_a_pin_proposal_accepted_and_undone(tmp_path):
    from vebuild.edit.assist import Proposal
    from vebuild.edit.session import EditSession

    folder = tmp_path / "room"
    shutil.copytree(ROOM, folder)
    s = EditSession.open(folder / "room.vebuild.json", autosave=False)
    nodes = [n["name"] for n in s.data["model"]["nodes"]]
    assert nodes, "the example room has a model"
    before = json.dumps(s.data, sort_keys=True)
    s.proposals["p3"] = [Proposal("pin", "p3", uv=(100.0, 200.0), node=nodes[0], handle="v0")]
    s.accept_proposal("p3", 0)
    pins = s.data["model"]["pins"]
    assert any(p["photo"] == "p3" and p["node"] == nodes[0] and p["uv"] == [100.0, 200.0] for p in pins)
    assert s.undo() and json.dumps(s.data, sort_keys=True) == before
