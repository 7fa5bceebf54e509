"""Rooms, openings and boxes made by clicking on a calibrated photo (vebuild/edit/room_clicks.py),
headless: the generated L-shaped room with two walls missing (vebuild.synthetic.click_room), its
floor corners, a wall's top, the doorway's corners and the table's footprint clicked at their true
pixels with a careful user's noise, then solved: every dimension within the room bench's 1 cm per
metre. A room's missing walls have no faces (nothing to texture, nothing hiding what lies behind),
and a drag a joint refuses says so in words."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click_room_scene import PHOTO, TOL_PER_M, calibrated_room, table_clicks, true_pixels, worst_error_per_m

from vebuild.edit.history import EditError
from vebuild.edit.room_clicks import LINE_MEET_RADIUS_PX, line_meet, plan_room
from vebuild.edit.session import EditSession
from vebuild.errors import ProjectError
from vebuild.model.primitives import primitive_from_dict
from vebuild.project import load_project
from vebuild.synthetic.click_room import WALLS


@pytest.fixture(scope="module")
def clicked(tmp_path_factory):
    """The room, modelled by clicks in a session and solved: (room truth, session, room, table)."""
    room, path = calibrated_room(tmp_path_factory.mktemp("click-room"))
    s = EditSession.open(path)
    rng = np.random.default_rng(3)
    floor = np.column_stack([room.corners, np.zeros(6)])
    node = s.room_from_clicks(PHOTO, list(true_pixels(room, floor, rng)))
    top = np.r_[room.corners[1], room.height]
    s.room_height_from_click(node, PHOTO, true_pixels(room, top, rng)[0])
    s.set_room_walls(node, list(WALLS))
    door = room.door_points()
    s.opening_from_clicks(node, PHOTO, list(true_pixels(room, np.array([door[k] for k in ("sb", "eb", "st")]), rng)))
    corners = room.table_corners()
    feet, top_k = table_clicks(room)
    table = s.box_from_clicks(PHOTO, list(true_pixels(room, corners[feet], rng)))
    s.box_height_from_click(table, PHOTO, true_pixels(room, corners[top_k], rng)[0])
    s.solve()
    return room, s, node, table


def test_the_clicked_room_solves_within_a_centimetre_per_metre(clicked):
    room, s, node, _ = clicked
    solved = s.model.node(node).primitive.to_dict()["params"]
    truth = {k.replace("door_", "door1_"): v for k, v in room.params().items()}
    err, which = worst_error_per_m(solved, truth)
    assert err <= TOL_PER_M, (which, solved[which], truth[which])
    # The room stands where it was clicked: corner 0 on the origin, its walls along the axes.
    np.testing.assert_allclose(s.model.handle_world(node, "f0"), [0, 0, 0], atol=TOL_PER_M * 5.0)
    np.testing.assert_allclose(s.model.handle_world(node, "f1")[1], 0.0, atol=TOL_PER_M * 5.0)


def test_the_clicked_table_stands_on_the_room_floor_where_it_is(clicked):
    room, s, node, table = clicked
    doc = next(n for n in s.data["model"]["nodes"] if n["name"] == table)
    assert doc["parent"] == node and doc["joint"]["type"] == "rests_on" and doc["joint"]["face"] == "floor"
    size = s.model.node(table).primitive.to_dict()["params"]
    err, which = worst_error_per_m(size, dict(zip(("width", "depth", "height"), room.table_size, strict=True)))
    assert err <= TOL_PER_M, (which, size)
    # Its corners lie on the true ones (within the tolerance of the room's 5 m span), not at the origin.
    got = np.array([s.model.handle_world(table, f"v{k}") for k in range(8)])
    dist = np.linalg.norm(got[:, None, :] - room.table_corners()[None, :, :], axis=2).min(axis=1)
    assert dist.max() <= TOL_PER_M * 5.0, dist


def test_the_missing_walls_have_no_faces_and_the_doorway_is_held_on_the_floor(clicked):
    _, s, node, _ = clicked
    prim = s.model.node(node).primitive
    names = prim.mesh().face_names
    assert {"wall0", "wall1", "wall2", "wall3", "outer3", "wtop3"} <= set(names)
    assert not {"wall4", "wall5", "outer4", "outer5", "wtop4", "wtop5"} & set(names)
    assert prim.to_dict()["walls"] == list(WALLS)
    doc = next(n for n in s.data["model"]["nodes"] if n["name"] == node)
    assert "door1_sill" in doc["hold"] and [o["wall"] for o in doc["primitive"]["openings"]] == [1]


def test_floor_corners_clicked_clockwise_make_the_same_rectilinear_room():
    pts = np.array([[1.0, 1.0], [6.0, 1.0], [6.0, 3.5], [3.5, 3.5], [3.5, 5.0], [1.0, 5.0]])
    yaw_true = np.radians(30.0)
    R = np.array([[np.cos(yaw_true), -np.sin(yaw_true)], [np.sin(yaw_true), np.cos(yaw_true)]])
    world = pts @ R.T + 0.01 * np.random.default_rng(0).normal(size=pts.shape)
    a = plan_room(world)
    b = plan_room(world[[0, 5, 4, 3, 2, 1]])
    assert a[3] and b[3]
    np.testing.assert_allclose(a[2], [[0, 0], [5, 0], [5, 2.5], [2.5, 2.5], [2.5, 4], [0, 4]], atol=0.03)
    np.testing.assert_allclose(b[2], a[2], atol=1e-12)
    assert b[4] == [0, 5, 4, 3, 2, 1]
    assert abs(np.degrees(a[1]) - 30.0) < 1.0
    # A slanted wall: the corners are the clicks.
    tri = plan_room(np.array([[0.0, 0.0], [4.0, 0.0], [1.0, 3.0]]))
    assert not tri[3]
    np.testing.assert_allclose(tri[2], [[0, 0], [4, 0], [1, 3]], atol=1e-12)


def test_a_click_above_the_horizon_is_refused_in_words(clicked):
    _, s, _, _ = clicked
    before = json.dumps(s.data)
    with pytest.raises(EditError, match="does not look at the floor"):
        s.room_from_clicks(PHOTO, [(800.0, 10.0), (900.0, 10.0), (850.0, 20.0)])
    assert json.dumps(s.data) == before


def test_a_room_without_a_wall_list_of_the_right_length_is_refused_naming_the_field(tmp_path, clicked):
    _, s, node, _ = clicked
    data = json.loads(json.dumps(s.data))
    doc = next(n for n in data["model"]["nodes"] if n["name"] == node)
    doc["primitive"]["walls"] = [True, False, True, True]
    path = tmp_path / "bad.vebuild.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ProjectError) as e:
        from vebuild.project import decode
        decode.model(load_project(path, verify_photos=False))
    assert "walls" in str(e.value) and "6 true or false" in str(e.value)
    with pytest.raises(ValueError, match="not have"):
        primitive_from_dict({**doc["primitive"], "walls": [True, False, True, True, True, True]})


def test_a_drag_a_marker_joint_refuses_says_so_in_words_first(clicked):
    """A quad tied to a marker, its far corner dragged toward the camera: the first line says what
    holds it and which key frees it, with no project-file names (node:vertex, joint types)."""
    s = EditSession.open(clicked[1].project.path)  # the calibrated project as written: no model
    s.add_primitive("quad", name="rug", marker="M2")
    uv = next(uv for n, h, uv, _ in s.handles(PHOTO) if (n, h) == ("rug", "v1"))
    s.begin_drag(PHOTO, "rug", "v1")
    fb = s.drag_to((uv[0], uv[1] - 200.0))  # away from the camera: it would have to grow
    s.cancel_drag()
    assert not fb.ok
    first, _, detail = fb.reason.partition("\n")
    assert first.startswith("This corner turns about marker M2 only. Press F"), first
    assert "rug" not in first and ":v" not in first and "marker'" not in first, first
    assert "rug:v1 cannot go there" in detail  # the detail follows, for who wants it
    # The corner on the marker itself cannot leave it: the joint is the change offered.
    uv = next(uv for n, h, uv, _ in s.handles(PHOTO) if (n, h) == ("rug", "v0"))
    s.begin_drag(PHOTO, "rug", "v0")
    fb = s.drag_to((uv[0] + 40.0, uv[1] + 150.0))
    s.cancel_drag()
    assert not fb.ok and fb.reason.startswith("This corner sits on marker M2 and cannot leave it. Choose the joint")


def test_a_corner_click_snaps_to_where_two_marked_lines_meet_near_it():
    """A wall's foot marked along x and a vertical marked along z meet at (400, 300): a click 3 px
    off lands on the meet; one farther than the radius, or near the meet of two lines of one axis,
    or where the lines' extensions meet far beyond their ends, stays where it was."""
    segs = {"x": [[100.0, 310.0, 385.0, 300.5]], "z": [[400.0, 600.0, 400.0, 320.0]],
            "y": [[700.0, 900.0, 710.0, 700.0]]}
    got = line_meet(segs, (402.0, 302.0))
    assert got is not None and np.allclose(got, (400.0, 300.0), atol=1e-9)
    assert line_meet(segs, (400.0 + LINE_MEET_RADIUS_PX + 0.5, 300.0)) is None
    assert line_meet({"x": segs["x"] + [[400.0, 600.0, 400.0, 320.0]]}, (402.0, 302.0)) is None
    far = {"x": [[100.0, 310.0, 200.0, 306.55]], "z": [[400.0, 600.0, 400.0, 500.0]]}  # both ends 100+ px away
    assert line_meet(far, (400.0, 300.0)) is None


def test_a_box_clicked_on_the_table_top_stands_on_the_table(clicked):
    """A box (a book) whose footprint is clicked on the table's top rests on the table's top where
    it was clicked, not on the floor below it."""
    room, s, _, table = clicked
    a = np.radians(room.table_yaw_deg)
    ex, ey = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
    top = np.r_[room.table_centre, room.table_size[2]]
    feet = np.array([top, top + 0.3 * ex, top + 0.3 * ex + 0.2 * ey])  # 0.3 × 0.2 m on the top
    book = s.box_from_clicks(PHOTO, list(true_pixels(room, feet, np.random.default_rng(9))))
    doc = next(n for n in s.data["model"]["nodes"] if n["name"] == book)
    assert doc["parent"] == table and doc["joint"]["face"] == "top", doc
    got = np.array([s.model.handle_world(book, f"v{k}") for k in range(3)])
    assert np.abs(got - feet).max() <= TOL_PER_M * 2.0, got - feet


def test_a_wall_unticked_takes_the_lines_marked_along_its_top_with_it(clicked):
    """A line marked along the top of a wall that is then said not to be there goes with it (the
    model would otherwise name an edge it no longer has), and the message says so."""
    s = EditSession.open(clicked[1].project.path)  # the calibrated project as written: no model
    node = s.room_from_clicks(PHOTO, [(400.0, 900.0), (1200.0, 900.0), (1100.0, 650.0), (500.0, 650.0)])
    line = {"photo": PHOTO, "node": node, "edge": "top2", "points": [[600.0, 500.0], [1000.0, 500.0]]}
    s.data["model"]["edge_observations"].append(line)
    s.set_room_walls(node, [True, True, False, True])
    assert line not in s.data["model"]["edge_observations"]
    assert "removed with them: 1 line marked along them (in p1)" in s.messages[-1]
    s.undo()
    assert line in s.data["model"]["edge_observations"] and all(s.model.node(node).primitive.walls_present)
