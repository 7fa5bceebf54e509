"""The modelling screen's edit logic without a window (vebuild.edit.session): the example room
rebuilt from nothing through the calls the screen's tools make, checked against its ground truth,
and every edit's undo, autosave and the clear messages for bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from edit_scene import DISTANCES, PHOTOS, assert_box_matches, assert_cameras_match, make_plan, photo_file, rebuild

from vebuild.edit.session import FOLLOW_TOL_PX, EditError, EditSession
from vebuild.project import load_project


@pytest.fixture(scope="module")
def rebuilt(tmp_path_factory):
    plan = make_plan(tmp_path_factory.mktemp("edit") / "room")
    session = EditSession.open(plan.project)
    feedback = rebuild(plan, session, np.random.default_rng(5))
    return plan, session, feedback


def test_rebuilt_cameras_and_box_match_the_ground_truth(rebuilt):
    plan, session, feedback = rebuilt
    assert_cameras_match(plan, session.cameras)
    assert all(f.ok for f in feedback), [f.reason for f in feedback if not f.ok]
    assert_box_matches(plan, session.model)
    floor = session.model.node("floor").primitive
    assert floor.params == pytest.approx([5.0, 4.0], abs=0.05)  # 1 cm per metre
    # The final solve over every fixed vertex keeps the box within the same tolerances.
    result = session.solve()
    assert result["outliers"] == []
    assert_box_matches(plan, session.model)


def test_every_edit_is_saved_beside_the_project_and_recovered_after_a_crash(rebuilt):
    plan, session, _ = rebuilt
    side = plan.project.with_name(plan.project.name + ".autosave")
    assert side.exists()
    assert json.loads(side.read_text()) == session.data
    # The project file itself is untouched until saved: a new session offers the autosave.
    assert load_project(plan.project).data["photos"] == []
    again = EditSession.open(plan.project)
    assert again.recovery_available
    again.recover()
    assert again.data == session.data
    assert sorted(again.cameras) == sorted(PHOTOS)


def test_save_writes_the_project_and_removes_the_side_file(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    s.add_photo(photo_file(plan, "p1"))
    assert s.autosave_path.exists() and s.dirty
    s.save()
    assert not s.autosave_path.exists() and not s.dirty
    data = load_project(plan.project).data
    assert [p["id"] for p in data["photos"]] == ["p1"]
    assert len(data["photos"][0]["sha256"]) == 64
    assert not EditSession.open(plan.project).recovery_available


def test_undo_and_redo_every_kind_of_edit(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    rebuild(plan, s, np.random.default_rng(1))
    states = []
    while True:
        states.append(json.dumps(s.data, sort_keys=True))
        if not s.undo():
            break
    assert json.loads(states[-1])["photos"] == []  # back to the empty project
    for expected in reversed(states[:-1]):
        assert s.redo()
        assert json.dumps(s.data, sort_keys=True) == expected
    assert not s.redo()


def test_a_zero_length_segment_is_refused_and_changes_nothing(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    s.add_photo(photo_file(plan, "p1"))
    rev, label = s.revision, s.undo_label
    with pytest.raises(EditError, match=r"x segment is 0\.0 px long.*at least 2 px apart"):
        s.add_segment("p1", "x", (100.0, 200.0), (100.0, 200.0))
    assert s.revision == rev and s.undo_label == label
    assert not (s.photo("p1").get("vanishing_segments") or {}).get("x")


def test_a_vanishing_point_that_cannot_be_fitted_yet_says_why(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    s.add_photo(photo_file(plan, "p1"))
    s.add_segment("p1", "z", (100, 100), (100, 300))
    vs = s.vanishing("p1", "z")
    assert vs.point is None and "1 segment; a vanishing point needs two or more" in vs.problem
    s.add_segment("p1", "z", (100, 400), (100, 600))  # on the same image line: no vanishing point
    vs = s.vanishing("p1", "z")
    assert vs.point is None and "all 2 segments lie on one image line" in vs.problem
    assert any("lie on one image line" in n for n in s.overlay("p1").notes)
    with pytest.raises(EditError, match="no photo has vanishing segments|axis z"):
        s.calibrate()


def test_a_drag_the_constraints_cannot_follow_leaves_the_box_and_says_why(rebuilt):
    plan, session, _ = rebuilt
    before = session.model.vector().copy()
    uv = next(uv for n, h, uv, _ in session.handles("p3") if (n, h) == ("box", "v4"))
    session.begin_drag("p3", "box", "v4")
    # The box rests on the floor and v0, v1, v3 are fixed: its top corner cannot go 150 px sideways.
    fb = session.drag_to((uv[0] + 150.0, uv[1]))
    assert not fb.ok
    assert "box:v4 cannot go there" in fb.reason and "rests on the 'floor' top" in fb.reason
    assert "fixed vertices" in fb.reason
    assert np.hypot(fb.handle_px[0] - uv[0], fb.handle_px[1] - uv[1]) < FOLLOW_TOL_PX  # it stayed
    session.cancel_drag()
    assert np.array_equal(session.model.vector(), before)


def test_a_photo_that_fails_to_load_names_its_file(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    s.add_photo(photo_file(plan, "p1"))
    assert s.photo_pixels("p1").shape == (1200, 1600, 3)
    photo_file(plan, "p1").write_bytes(b"not an image any more")
    with pytest.raises(EditError, match=r"photo 'p1' fails to load: .*p1.*(changed|SHA-256)"):
        s.photo_pixels("p1")
    photo_file(plan, "p1").unlink()
    with pytest.raises(EditError, match=r"photo 'p1' fails to load: .*cannot be read"):
        s.photo_pixels("p1")


def test_adding_a_photo_from_outside_the_project_folder_is_refused(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    outside = tmp_path / "elsewhere.png"
    outside.write_bytes(photo_file(plan, "p1").read_bytes())
    with pytest.raises(EditError, match="outside the project folder"):
        s.add_photo(outside)
    assert s.photo_ids == []


def test_overlay_shows_segments_by_axis_vanishing_points_horizon_edges_and_handles(rebuilt):
    plan, session, _ = rebuilt
    ov = session.overlay("p3", selected="box")
    segs, _ = ov.of_kind("segment")
    assert {ln.key[0] for ln in segs} == {"x", "y", "z"}
    assert all(ln.label and ln.label.endswith("px") for ln in segs)  # each segment's residual
    assert ov.of_kind("horizon")[0] and len(ov.of_kind("axis")[0]) == 3
    edges, _ = ov.of_kind("edge")
    assert {ln.key[0] for ln in edges} == {"floor", "box"}
    box_white = [ln for ln in edges if ln.key[0] == "floor"]
    assert all(ln.colour[:3] == (1.0, 1.0, 1.0) for ln in box_white)
    _, pins = ov.of_kind("pin")
    assert {p.key for p in pins} >= {("box", "v0"), ("box", "v1"), ("box", "v3"), ("box", "v4")}
    # The horizon is the image of the horizontal planes at infinity: every x and y vanishing point on it.
    cam = session.cameras["p3"]
    h = np.linalg.inv(cam.K).T @ cam.R[:, 2]
    for k in (0, 1):
        vp = cam.K @ cam.R[:, k]
        assert abs(h @ vp) / (np.linalg.norm(h[:2]) * np.linalg.norm(vp)) < 1e-9


def test_user_edges_are_red_and_pull_the_model(rebuilt):
    plan, session, _ = rebuilt
    cam = session.cameras["p5"]
    from vebuild.camera import project as project_points

    a, b = (project_points(cam.K, cam.R, cam.C, plan.vertex("box", h)) for h in ("v1", "v5"))
    assert session.nearest_edge("p5", a, b, node="box") == ("box", "e9")
    session.add_edge_observation("p5", "box", "e9", a, b)
    red = session.overlay("p5").of_kind("user-edge")[0]
    assert len(red) == 1 and red[0].colour[:3] == (1.0, 0.15, 0.15)
    result = session.solve()
    assert any(e["edge"] == "e9" for e in result["edge_observations"])
    session.undo()
    session.undo()


def test_recalibration_reports_residuals_and_highlights_an_outlier(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    rebuild(plan, s, np.random.default_rng(2))
    uv = next(uv for n, h, uv, _ in s.handles("p5") if (n, h) == ("box", "v6"))
    s.fix("p5", "box", "v6", (uv[0] + 25.0, uv[1]))  # a slip: the vertex fixed 25 px off
    steps = []
    result = s.solve(recalibrate=True, progress=lambda f, t: steps.append(f))
    assert steps[0] == 0.0 and steps[-1] == 1.0
    assert any("box:v6 in photo 'p5'" in o for o in result["outliers"])
    assert len(result["pins"]) == sum(1 for p in s.data["model"]["pins"])
    flagged = [ln for ln in s.overlay("p5").of_kind("residual")[0] if ln.key == ("box", "v6")]
    assert flagged and "outlier" in flagged[0].label


def test_register_another_photo_from_known_points(tmp_path):
    import shutil

    from edit_scene import EXAMPLE

    plan = make_plan(tmp_path / "room")
    session = EditSession.open(plan.project)
    rebuild(plan, session, np.random.default_rng(6))
    src = json.loads((EXAMPLE / "room.vebuild.json").read_text())
    p2 = next(p for p in src["photos"] if p["id"] == "p2")
    shutil.copy(EXAMPLE / p2["file"], plan.folder / p2["file"])
    session.add_photo(plan.folder / p2["file"])
    rng = np.random.default_rng(3)
    for name in ("O", "T1", "T2", "C1", "C2"):
        if name in session.project.marker_names():
            session.place_marker("p2", name, plan.pixel("p2", plan.truth["markers"][name], rng))
    for h in ("v0", "v4", "v5", "v1"):
        session.fix("p2", "box", h, plan.pixel("p2", plan.vertex("box", h), rng))
    session.solve()
    session.register("p2")
    cam = session.cameras["p2"]
    K, R, C = plan.camera("p2")
    assert session.data["calibration"]["cameras"]["p2"]["mode"] == "registered"
    assert np.linalg.norm(cam.C - C) < 0.01 * np.linalg.norm(plan.truth["room"])  # as a calibrated camera
    assert abs(cam.K[0, 0] - K[0, 0]) / K[0, 0] < 0.01


def test_group_keeps_the_parts_where_they_are(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    rebuild(plan, s, np.random.default_rng(4))
    at = plan.pixel("p3", plan.vertex("box", "v2"), np.random.default_rng(0))
    s.add_primitive("cylinder", name="bin", parent="floor", at=("p3", at))
    before = {n: s.model.world_transforms()[n] for n in ("box", "bin")}
    s.group(["box", "bin"], "things")
    after = s.model.world_transforms()
    for n, T in before.items():
        assert np.allclose(after[n], T, atol=1e-9)
        assert s.model.node(n).parent == "things"
    with pytest.raises(EditError, match="a group needs a new name"):
        s.group(["floor"], "things")


def test_a_primitive_hung_on_a_marker_has_that_handle_on_it(rebuilt):
    plan, session, _ = rebuilt
    session.add_primitive("sphere", name="ball", marker="T2")
    X = session.model.handle_world("ball", "bottom")
    assert np.allclose(X, session.data["calibration"]["markers"]["T2"]["position"], atol=1e-12)
    with pytest.raises(EditError, match="marker 'nowhere' has no calibrated position yet"):
        session.add_primitive("box", marker="nowhere")
    session.undo()
    assert "ball" not in session.model.index


def test_distances_and_markers_are_checked(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    s.add_photo(photo_file(plan, "p1"))
    s.place_marker("p1", "O", (10, 10))
    assert s.data["origin_marker"] == "O"
    with pytest.raises(EditError, match="positive number of metres"):
        s.add_distance("O", "X5", -1.0)
    with pytest.raises(EditError, match="no marker of that name"):
        s.add_distance("O", "nowhere", 1.0)
    assert s.data["reference_distances"] == []
    assert DISTANCES


# -- middle points, known lengths, camera heights, markers on the floor (real photographs) ---------


def _one_photo_session(tmp_path):
    from edit_scene import make_one_photo

    path, truth = make_one_photo(tmp_path / "one")
    return EditSession.open(path), truth


def _saved(s):
    return json.loads(s.autosave_path.read_text())


def test_middle_points_make_a_polyline_segment_and_each_is_undoable(tmp_path):
    s, _ = _one_photo_session(tmp_path)
    i = s.add_segment("p3", "x", (100.0, 500.0), (700.0, 520.0))
    assert s.insert_segment_point("p3", "x", i, (520.0, 512.0)) == 1
    assert s.insert_segment_point("p3", "x", i, (300.0, 503.0)) == 1  # kept in order along the edge
    row = [100.0, 500.0, 300.0, 503.0, 520.0, 512.0, 700.0, 520.0]  # FORMAT.md: [u1, v1, ..., un, vn]
    assert s.photo("p3")["vanishing_segments"]["x"][i] == row
    assert _saved(s)["photos"][0]["vanishing_segments"]["x"][i] == row  # autosaved
    assert s.segment_point_at("p3", (301.0, 504.0), 3.0) == ("x", i, 1)
    assert s.segment_point_at("p3", (100.0, 500.0), 3.0) is None  # an end is not a middle point
    vs = s.vanishing("p3", "x")
    assert vs.polylines[i].shape == (4, 2) and list(vs.segments[i]) == [100.0, 500.0, 700.0, 520.0]
    _, points = s.overlay("p3").of_kind("segment-point")
    assert sorted(p.uv for p in points if p.key == ("x", i)) == [(300.0, 503.0), (520.0, 512.0)]
    s.move_segment_point("p3", "x", i, 2, (521.5, 514.0))
    assert s.photo("p3")["vanishing_segments"]["x"][i][4:6] == [521.5, 514.0]
    s.delete_segment_point("p3", "x", i, 1)
    assert s.photo("p3")["vanishing_segments"]["x"][i] == [100.0, 500.0, 521.5, 514.0, 700.0, 520.0]
    assert s.undo_label == f"delete a middle point of x segment {i} in p3"
    s.undo()
    s.undo()
    assert s.photo("p3")["vanishing_segments"]["x"][i] == row
    s.redo()
    assert s.photo("p3")["vanishing_segments"]["x"][i][4:6] == [521.5, 514.0]
    # The segment's ends still move alone; its middle points stay.
    s.move_segment("p3", "x", i, [90.0, 499.0, 710.0, 521.0])
    assert s.photo("p3")["vanishing_segments"]["x"][i][2:6] == [300.0, 503.0, 521.5, 514.0]


def test_bad_middle_points_are_refused_with_a_message_and_change_nothing(tmp_path):
    s, _ = _one_photo_session(tmp_path)
    i = s.add_segment("p3", "y", (100.0, 100.0), (300.0, 100.0))
    n = i + 1  # the example's y segments, and this one
    rev = s.revision
    with pytest.raises(EditError, match=r"must lie between the y segment's two ends \(this one is 150 % of the way.*"
                                        "drag its end"):
        s.insert_segment_point("p3", "y", i, (400.0, 101.0))
    with pytest.raises(EditError, match=rf"photo 'p3' has no y segment {n + 4} \(it has {n}\)"):
        s.insert_segment_point("p3", "y", n + 4, (200.0, 101.0))
    with pytest.raises(EditError, match=rf"y segment {i} has no middle point 1 \(it has 0\)"):
        s.move_segment_point("p3", "y", i, 1, (200.0, 101.0))
    with pytest.raises(EditError, match=rf"y segment {i} has no middle point 0 \(it has 0\)"):
        s.delete_segment_point("p3", "y", i, 0)
    with pytest.raises(EditError, match="not a number"):
        s.insert_segment_point("p3", "y", i, (float("nan"), 101.0))
    assert s.revision == rev
    s.insert_segment_point("p3", "y", i, (200.0, 101.0))
    with pytest.raises(EditError, match=r"vanishing_segments\.y\[\d+\].*within .* image sizes of the 1600×1200 photo"):
        s.move_segment_point("p3", "y", i, 1, (200.0, -1e5))  # every point lies on the photo
    assert s.revision == rev + 1 and s.photo("p3")["vanishing_segments"]["y"][i][2:4] == [200.0, 101.0]


def test_a_known_length_is_written_as_the_format_says_drawn_and_undoable(tmp_path):
    s, _ = _one_photo_session(tmp_path)
    k = s.add_known_length("p3", "z", [(1388.9, 913.6), (1388.9, 351.3)], "2.6", "")
    want = {"photo": "p3", "axis": "z", "ends": [[1388.9, 913.6], [1388.9, 351.3]], "length": 2.6, "sigma": 0.002,
            "floor_end": 0}
    assert s.data["known_lengths"] == [want] and _saved(s)["known_lengths"] == [want]
    s.add_known_length("p3", "x", [(150.0, 1100.0), (1380.0, 915.0)], 5.0, 0.01)
    assert s.data["known_lengths"][1] == {"photo": "p3", "axis": "x", "ends": [[150.0, 1100.0], [1380.0, 915.0]],
                                          "length": 5.0, "sigma": 0.01}  # on the floor: no floor_end
    lines, ends = s.overlay("p3").of_kind("known-length")[0], s.overlay("p3").of_kind("known-length-end")[1]
    assert [ln.label for ln in lines] == ["L0: 2.6 m ± 2 mm along z", "L1: 5 m ± 10 mm along x"]
    assert [p.filled for p in ends if p.key[0] == 0] == [True, False]  # the foot on the floor, filled
    assert s.known_length_at("p3", (1390.0, 600.0), 4.0) == 0 and s.known_length_at("p3", (900, 100), 4.0) is None
    s.remove_known_length(0)
    assert [kl["axis"] for kl in s.data["known_lengths"]] == ["x"]
    s.undo()
    assert s.data["known_lengths"][0] == want
    s.undo()
    s.undo()
    assert "known_lengths" not in s.data and s.undo_label is None and k == 0


@pytest.mark.parametrize(("length", "sigma", "message"), [
    ("abc", "", r"the known length must be a number of metres \(e\.g\. 2\.03\), not 'abc'"),
    ("-1", "", "the known length must be a positive number of metres, not -1"),
    ("0", "", "the known length must be a positive number of metres, not 0"),
    ("20000", "", "the known length must lie between 0.0001 m and 10000 m, not 20000 m"),
    ("", "", r"the known length must be a number of metres \(e\.g\. 2\.03\), not ''"),
    (None, "", r"the known length is missing: type a number of metres"),
    ("2.0", "tiny", r"the known length's σ must be a number of metres \(e\.g\. 2\.03\), not 'tiny'"),
    ("2.0", "-0.01", "the known length's σ must be a positive number of metres, not -0.01"),
])
def test_a_known_length_that_is_not_a_positive_number_is_refused(tmp_path, length, sigma, message):
    s, _ = _one_photo_session(tmp_path)
    rev = s.revision
    with pytest.raises(EditError, match=message):
        s.add_known_length("p3", "z", [(100.0, 900.0), (100.0, 300.0)], length, sigma)
    assert s.revision == rev and "known_lengths" not in s.data


def test_a_known_length_needs_an_axis_two_ends_and_a_photo(tmp_path):
    s, _ = _one_photo_session(tmp_path)
    with pytest.raises(EditError, match="a known length runs along world axis x, y or z, not 'w'"):
        s.add_known_length("p3", "w", [(100.0, 900.0), (100.0, 300.0)], 2.0)
    with pytest.raises(EditError, match=r"two ends are 0\.5 px apart: press on one end .*at least 2 px apart"):
        s.add_known_length("p3", "z", [(100.0, 900.0), (100.0, 900.5)], 2.0)
    with pytest.raises(EditError, match="no photo"):
        s.add_known_length("nowhere", "z", [(100.0, 900.0), (100.0, 300.0)], 2.0)
    with pytest.raises(EditError, match="a known length has two ends, not 3"):
        s.add_known_length("p3", "z", [(100.0, 900.0), (100.0, 600.0), (100.0, 300.0)], 2.0)
    with pytest.raises(EditError, match="a known length's end is not a number"):
        s.add_known_length("p3", "z", [(100.0, float("inf")), (100.0, 300.0)], 2.0)
    with pytest.raises(EditError, match=r"there is no known length 0 \(there are 0\)"):
        s.remove_known_length(0)
    assert "known_lengths" not in s.data


def test_the_camera_height_is_typed_checked_and_removed(tmp_path):
    s, _ = _one_photo_session(tmp_path)
    s.set_camera_height("p3", "1.62", "")
    assert s.photo("p3")["camera_height"] == {"value": 1.62, "sigma": 0.05}
    assert _saved(s)["photos"][0]["camera_height"] == {"value": 1.62, "sigma": 0.05}
    s.set_camera_height("p3", "1.45 m", "0.01")
    assert s.photo("p3")["camera_height"] == {"value": 1.45, "sigma": 0.01}
    rev = s.revision
    for value, sigma, message in (("tall", "", "the camera height must be a number of metres"),
                                  ("-1.6", "", "the camera height must be a positive number of metres, not -1.6"),
                                  ("0.0001", "", "the camera height must lie between 0.001 m and 10000 m"),
                                  ("1.6", "x", "the camera height's σ must be a number of metres")):
        with pytest.raises(EditError, match=message):
            s.set_camera_height("p3", value, sigma)
    assert s.revision == rev and s.photo("p3")["camera_height"]["value"] == 1.45
    s.set_camera_height("p3", None)
    assert "camera_height" not in s.photo("p3")
    with pytest.raises(EditError, match="photo 'p3' has no camera height to remove"):
        s.set_camera_height("p3", "")
    s.undo()
    assert s.photo("p3")["camera_height"] == {"value": 1.45, "sigma": 0.01}


def test_a_marker_is_marked_on_the_floor_and_off_it(tmp_path):
    s, _ = _one_photo_session(tmp_path)
    s.place_marker("p3", "X5", (153.8, 1107.9))
    s.set_on_floor("X5", True)
    assert {"name": "X5", "on_floor": True} in s.data["markers"]
    assert {"name": "X5", "on_floor": True} in _saved(s)["markers"]
    s.set_on_floor("X5", False)
    assert {"name": "X5"} in s.data["markers"]
    s.undo()
    assert {"name": "X5", "on_floor": True} in s.data["markers"]
    with pytest.raises(EditError, match="no marker is called 'nowhere'; place it in a photo first"):
        s.set_on_floor("nowhere", True)


def test_a_one_photo_project_is_calibrated_with_the_scale_given_in_the_session(tmp_path):
    s, truth = _one_photo_session(tmp_path)
    # No scale: it calibrates and says that lengths are relative.
    r = s.calibrate()
    assert r["cameras"]["p3"]["placement"]["lengths"] == "relative"
    said = next(m for m in reversed(s.messages) if m.startswith("calibrated p3"))
    assert said.endswith("; placed alone, no scale: lengths are relative (in units of the camera's height)")
    s.undo()
    # The room's corner, from the floor up to the ceiling, as a known length: metres.
    s.add_known_length("p3", "z", truth["corner"], str(truth["corner_m"]))
    r = s.calibrate()
    placed = r["cameras"]["p3"]["placement"]
    h = placed["camera_height_m"]
    assert placed["how"] == "alone" and placed["lengths"] == "metres" and "known length" in placed["scale"]
    assert abs(h["value"] - truth["C"][2]) < 3 * h["sigma"], (h, truth["C"])
    pos = r["cameras"]["p3"]["position"]  # each coordinate within 3σ of the truth
    assert np.all(np.abs(np.subtract(pos["value"], truth["C"])) < 3 * np.asarray(pos["sigma"])), (pos, truth["C"])
    said = next(m for m in reversed(s.messages) if m.startswith("calibrated p3"))
    assert f"placed alone, camera {h['value']:.3f} ± {h['sigma']:.3f} m above the floor (scale: the known length" \
        in said
    # A camera height as well: the two are combined, and both are named.
    s.set_camera_height("p3", f"{truth['C'][2]:.3f}", "0.02")
    r = s.calibrate()
    assert len(r["cameras"]["p3"]["placement"]["scale_estimates"]) == 2


def test_middle_points_let_a_one_photo_calibration_measure_the_lens(tmp_path):
    """The example's photo is a pinhole render: with three middle points on every segment (where the
    true edges pass, with a click's noise) the calibration tests k1 on them, finds the lines do not
    bend, holds k1 at 0 (vebuild/calibration/bending.py), and the session says so with the test's
    figures and the corner displacement."""
    from edit_scene import CLICK_NOISE_PX, EXAMPLE

    s, truth = _one_photo_session(tmp_path)
    edges = json.loads((EXAMPLE / "ground_truth.json").read_text())["photos"]["p3"]["segments"]
    rng = np.random.default_rng(8)
    from vebuild.camera import project as project_points

    for axis, axis_edges in edges.items():
        for i, e in enumerate(axis_edges):
            for t in (0.25, 0.5, 0.75):
                X = (1 - t) * np.asarray(e["X1"]) + t * np.asarray(e["X2"])
                uv = project_points(truth["K"], truth["R"], truth["C"], X) + rng.normal(0.0, CLICK_NOISE_PX, 2)
                s.insert_segment_point("p3", axis, i, uv)
    assert all(len(r) == 10 for rows in s.photo("p3")["vanishing_segments"].values() for r in rows)
    s.add_known_length("p3", "z", truth["corner"], str(truth["corner_m"]))
    r = s.calibrate()
    lens = r["cameras"]["p3"]["distortion"]
    assert lens["source"].startswith("k1 held at 0: the lines do not bend (LR test: Δχ² = ")
    assert lens["k1"] == {"value": 0.0, "sigma": 0.0}  # the truth, 0
    said = next(m for m in reversed(s.messages) if m.startswith("calibrated p3"))
    assert f"lens k1 +0.0000 ± 0.0000 ({lens['source']})" in said
    assert f"corners moved {lens['corner_displacement_px']['value']:.1f}" in said


def _assert_same_overlay(got, expected) -> None:
    """The same items in the same order, kinds, keys, colours, labels and notes; the same pixels to
    float rounding (the nodes taken from an earlier overlay were projected by other code)."""
    assert [(ln.kind, ln.key, ln.colour, ln.label) for ln in got.lines] == \
        [(ln.kind, ln.key, ln.colour, ln.label) for ln in expected.lines]
    assert [(p.kind, p.key, p.colour, p.label) for p in got.points] == \
        [(p.kind, p.key, p.colour, p.label) for p in expected.points]
    assert got.notes == expected.notes
    for a, b in zip(got.lines, expected.lines, strict=True):
        assert np.allclose(a.p, b.p, atol=1e-6)
    for a, b in zip(got.points, expected.points, strict=True):
        assert np.allclose(a.uv, b.uv, atol=1e-6)


def test_a_drags_still_layer_is_the_rest_overlay_less_what_moves(rebuilt, monkeypatch):
    """The still layer of a drag is taken from the overlay drawn when it began (the moving nodes'
    edges and handles and the pins' residuals left out), and is what working it out afresh gives."""
    plan, session, _ = rebuilt
    if not (session.data.get("model_solution") or {}).get("pins"):
        session.solve()  # the pins' residuals, which a drag does not draw
    rest = session.overlay("p3", selected="floor")
    assert any(ln.kind == "residual" and ln.key[0] == "box" for ln in rest.lines)  # a pin's
    uv = next(uv for n, h, uv, _ in session.handles("p3") if (n, h) == ("box", "v4"))
    made = []
    parts = type(session)._overlay_parts
    monkeypatch.setattr(type(session), "_overlay_parts", lambda s, *a: made.append(a) or parts(s, *a))
    session.begin_drag("p3", "box", "v4")
    try:
        session.drag_to((uv[0], uv[1] - 2.0))
        still, moving = session.overlay_layers("p3", selected="floor")
        assert made == []  # nothing worked out again for what does not move
        moved = set(session._drag.session.moved)
        assert "box" in moved and "floor" not in moved
        afresh = session._overlay("p3", "floor", skip=moved)
    finally:
        session.cancel_drag()
    assert not [ln for ln in still.lines if ln.kind == "edge" and ln.key[0] in moved]
    assert not [p for p in still.points if p.kind in ("handle", "pin") and p.key[0] in moved]
    assert {p.key for p in moving.points} == {p.key for p in rest.points if p.kind in ("handle", "pin")
                                              and p.key[0] in moved}
    _assert_same_overlay(still, afresh)


def test_the_copy_kept_for_undo_is_whole_and_apart_from_the_document():
    """What an edit may change in the document (its objects, lists, and anything not JSON) is
    copied; what cannot change (text, numbers, true, false, null) is shared."""
    import numpy as np

    from vebuild.edit.history import document_copy

    doc = {"a": [1, {"b": [2.5, "s", None, True]}], "arr": np.zeros(3), "pair": (1, [2]), "n": {}}
    kept = document_copy(doc)
    assert kept["a"] == doc["a"] and kept["pair"] == doc["pair"] and kept["n"] == {}
    assert np.array_equal(kept["arr"], doc["arr"])
    doc["a"][1]["b"].append(5)
    doc["a"].append("x")
    doc["arr"][0] = 9.0
    doc["pair"][1].append(3)
    doc["n"]["k"] = 1
    assert kept == {"a": [1, {"b": [2.5, "s", None, True]}], "arr": kept["arr"], "pair": (1, [2]), "n": {}}
    assert not kept["arr"].any()


def test_a_packed_document_unpacks_whole_and_apart_sharing_only_what_it_names():
    """An undo step's document: unpacked, equal to the one packed, keys in their order, its own
    objects but for the shared paths' values; packing leaves the document as it was, also when it
    fails."""
    import threading

    from vebuild.edit.history import PackedDocument, document_snapshot

    matrix = [[1.0, 0.5], [0.5, 2.0]]
    doc = {"a": [1, {"b": [2.5, None]}], "model_solution": {"covariance": {"matrix": matrix, "parameters": ["x", "y"]},
                                                           "rms_px": 0.4}, "z": (1, 2)}
    packed = PackedDocument(doc)
    assert doc["model_solution"]["covariance"]["matrix"] is matrix
    out = packed.unpack()
    assert out == doc and list(out["model_solution"]["covariance"]) == ["matrix", "parameters"]
    assert out["model_solution"]["covariance"]["matrix"] is matrix
    out["a"][1]["b"].append(3)
    out["model_solution"]["covariance"]["parameters"].append("w")
    assert doc["a"] == [1, {"b": [2.5, None]}] and doc["model_solution"]["covariance"]["parameters"] == ["x", "y"]
    assert packed.unpack()["a"] == [1, {"b": [2.5, None]}]
    assert PackedDocument({"a": 1}).unpack() == {"a": 1}  # no shared path in it
    snap = document_snapshot(doc)
    assert snap == doc and snap["model_solution"]["covariance"]["matrix"] is matrix
    assert snap["model_solution"]["covariance"]["parameters"] is not doc["model_solution"]["covariance"]["parameters"]
    doc["lock"] = threading.Lock()  # cannot be pickled
    with pytest.raises(TypeError):
        PackedDocument(doc)
    assert doc["model_solution"]["covariance"]["matrix"] is matrix


def test_an_undo_step_is_packed_and_shares_the_solutions_covariance(rebuilt):
    """Each undo step of a solved project is one pickled string without the solution's covariance
    matrix (on a house most of the document, which no edit changes in place); undo and redo give
    back the documents as they were, the matrix the same object."""
    import copy
    import pickle

    from vebuild.edit.history import PackedDocument

    _, session, _ = rebuilt
    session.solve()
    matrix = session.data["model_solution"]["covariance"]["matrix"]
    before = copy.deepcopy(session.data)
    width = session.model.node("box").primitive.params[0]
    session.set_params("box", {"width": width + 0.01})
    after = copy.deepcopy(session.data)
    assert session.data["model_solution"]["covariance"]["matrix"] is matrix  # the solution kept (stale)
    step = session.history._undo[-1][1]
    assert isinstance(step, PackedDocument)
    n = len(matrix)
    # A pickled float takes 9 bytes: the step is the whole document's pickle less at least the
    # matrix's n² numbers.
    assert step.nbytes <= len(pickle.dumps(before, protocol=pickle.HIGHEST_PROTOCOL)) - 9 * n * n
    assert session.undo()
    assert session.data == before and session.data["model_solution"]["covariance"]["matrix"] is matrix
    assert session.redo()
    assert session.data == after and session.data["model_solution"]["covariance"]["matrix"] is matrix
    assert session.undo()


def test_an_edits_model_is_decoded_once_and_is_the_documents(rebuilt, monkeypatch):
    """The model an edit checks is the model shown after it: not decoded a second time, and the
    same as decoding the edited document afresh."""
    from vebuild.project import decode

    plan, session, _ = rebuilt
    calls = []
    real = decode.model_nodes
    monkeypatch.setattr(decode, "model_nodes", lambda *a, **k: calls.append(1) or real(*a, **k))
    width = session.model.node("box").primitive.params[0]
    calls.clear()
    session.set_params("box", {"width": width + 0.01})
    model = session.model
    assert len(calls) == 1
    assert model.node("box").primitive.params[0] == pytest.approx(width + 0.01)
    afresh = session._decoded_model()
    assert np.array_equal(model.vector(), afresh.vector())
    assert [n.name for n in model.nodes] == [n.name for n in afresh.nodes]
    session.undo()
    assert session.model.node("box").primitive.params[0] == pytest.approx(width)


def test_the_overlay_after_a_kept_drag_takes_what_did_not_move_from_before_it(rebuilt, monkeypatch):
    """After a drag is kept, only the nodes it moved are projected again; the overlay is what
    working it all out afresh gives."""
    from vebuild.edit import photo_overlay

    plan, session, _ = rebuilt
    session.add_primitive("box", name="crate", parent="floor", at=("p3", (700.0, 900.0)))
    session.overlay("p3", selected="floor")  # drawn before the drag, as the screen draws it
    uv = next(uv for n, h, uv, _ in session.handles("p3") if (n, h) == ("crate", "v4"))
    session.begin_drag("p3", "crate", "v4")
    fb = session.drag_to((uv[0] - 6.0, uv[1] - 4.0))
    assert fb.ok, fb.reason
    moved = set(session._drag.session.moved)
    assert moved == {"crate"}
    projected = []
    real = photo_overlay.project_edge_curves
    monkeypatch.setattr(photo_overlay, "project_edge_curves",
                        lambda model, cam, names, *a: projected.append(list(names)) or real(model, cam, names, *a))
    session.end_drag()
    after = session.overlay("p3", selected="floor")
    assert projected == [["crate"]]
    session._cache.clear()  # the same revision worked out whole
    whole = session.overlay("p3", selected="floor")
    assert len(projected) == 2 and "box" in projected[1] and "floor" in projected[1]
    _assert_same_overlay(after, whole)
    assert any(p.kind == "pin" and p.key == ("crate", "v4") for p in after.points)  # the drag fixed it
    session.undo()
    session.undo()
