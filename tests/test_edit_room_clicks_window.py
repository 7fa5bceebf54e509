"""A room modelled by clicking, driven for real (Xvfb and xdotool, as tests/test_edit_window.py): the
generated L-shaped room with two walls missing, a doorway and a table (vebuild.synthetic.click_room),
from calibrated photos to a solved, textured model by clicks and keys alone, no JSON edited.

The photos are calibrated headlessly in the set-up (`vebuild calibrate` on the generated marks):
calibrating by clicks is covered by tests/test_edit_first_steps.py and tests/test_edit_window.py;
this test is the modelling. Each click is a user's: the true pixel of the corner it aims at, with a
careful user's 0.7 px noise, rounded to the window's pixel (the photo is shown at about half size,
so up to a photo pixel more)."""

from __future__ import annotations

import numpy as np
import pytest
from click_room_scene import PHOTO, TOL_PER_M, calibrated_room, table_clicks, true_pixels, worst_error_per_m
from edit_driver import Driver

from vebuild.synthetic.click_room import WALLS

pytestmark = pytest.mark.usefixtures("xvfb_display")


@pytest.fixture
def driver(tmp_path, xdotool):
    room, path = calibrated_room(tmp_path / "room")
    d = Driver(path, xdotool)
    yield room, d
    d.close()


def _zoom_on(d, X) -> None:
    """Home (the whole photo), then three wheel steps in about world point X's pixel: the photo at
    about one window pixel a photo pixel there, as a user zooms to click small things."""
    d.send("key", "Home")
    x, y = d.editor.image_to_window(None, true_pixels_of(d, X))
    d.send(*d.move_to(x, y), "click", "4", "sleep", "0.05", "click", "4", "sleep", "0.05", "click", "4")


def true_pixels_of(d, X):
    return true_pixels(d.room, np.atleast_2d(X))[0]


def _click_at(d, uv) -> None:
    x, y = d.editor.image_to_window(None, uv)
    d.send(*d.move_to(x, y), "sleep", "0.05", "click", "1")


def test_an_l_shaped_room_with_two_walls_missing_a_doorway_and_a_table_by_clicks(driver):
    """Clicks and keys, counted: H, 6 floor corners, Enter, 1 wall top, Esc; 2 ticks off (walls 4
    and 5); O, Home, 3 wheel steps, 3 doorway corners; B, Home, 3 wheel steps, 3 table corners, 1
    table top, Esc; Solve; Extract textures; Ctrl+S. That is 17 clicks on the photo, 6 wheel
    steps, 4 clicks on the panel and 8 keys."""
    room, d = driver
    d.room = room
    e, s = d.editor, d.session
    assert e.photo == PHOTO
    rng = np.random.default_rng(5)
    # Room: the floor's six corners, closed by Enter, then a wall's top above corner 1.
    d.send("key", "h")
    assert e.tool == "room"
    for uv in true_pixels(room, np.column_stack([room.corners, np.zeros(6)]), rng):
        _click_at(d, uv)
    assert "6 corners" in (e.build_prompt() or "")
    d.send("key", "Return")
    node = e.selected
    assert node is not None and s.model.node(node).primitive.TYPE == "room", s.messages[-3:]
    assert "click the top of a wall" in e.build_prompt()
    _click_at(d, true_pixels(room, np.r_[room.corners[1], room.height], rng)[0])
    assert s.model.node(node).primitive.param("height") == pytest.approx(room.height, rel=TOL_PER_M)
    d.send("key", "Escape")
    # The walls the photos do not show: ticked off in the Model tab.
    d.frames(2)
    for i in (4, 5):
        d.click(f"wall there {i}")
        d.frames(1)
    assert s.model.node(node).primitive.walls_present == WALLS
    # The doorway: its two feet, then its top, zoomed in on it.
    d.send("key", "o")
    door = room.door_points()
    _zoom_on(d, 0.5 * (door["sb"] + door["et"]))
    for uv in true_pixels(room, np.array([door[k] for k in ("sb", "eb", "st")]), rng):
        _click_at(d, uv)
    assert s.model.node(node).primitive.opening_names() == ["door1"], s.messages[-3:]
    # The table: three corners of its footprint on the room's floor, then its top, zoomed in on it.
    d.send("key", "b")
    corners = room.table_corners()
    _zoom_on(d, corners.mean(axis=0))
    feet, top = table_clicks(room)
    for uv in true_pixels(room, corners[feet], rng):
        _click_at(d, uv)
    table = e.selected
    assert table != node and s.model.node(table).parent == node, s.messages[-3:]
    _click_at(d, true_pixels(room, corners[top], rng)[0])
    d.send("key", "Escape")
    # Solve and texture by their buttons.
    d.frames(2)
    d.click("Solve")
    assert e.solve_error is None, e.solve_error
    d.frames(2)
    d.click("Extract textures")
    assert s.data.get("textures"), s.messages[-3:]
    d.send("key", "ctrl+s")
    assert not s.dirty
    # The solved room and table within the room bench's 1 cm per metre of the truth.
    params = s.model.node(node).primitive.to_dict()["params"]
    err, which = worst_error_per_m(params, {k.replace("door_", "door1_"): v for k, v in room.params().items()})
    assert err <= TOL_PER_M, (which, params[which])
    size = s.model.node(table).primitive.to_dict()["params"]
    err, which = worst_error_per_m(size, dict(zip(("width", "depth", "height"), room.table_size, strict=True)))
    assert err <= TOL_PER_M, (which, size)
    # The missing walls have no faces: nothing of them is textured; the walls there and the floor are,
    # and the photos through the gap see the inner faces of the walls there.
    faces = {(f["node"], f["face"]): f for f in s.data["textures"]["faces"]}
    assert not {(node, f"{k}{i}") for k in ("wall", "outer", "wtop") for i in (4, 5)} & set(faces)
    assert {(node, "floor"), (node, "wall0"), (node, "wall1"), (node, "wall2"), (node, "wall3"), (table, "top")} \
        <= set(faces)
    assert all(faces[(node, f"wall{i}")]["seen_fraction"] > 0.5 for i in (0, 1, 3)), \
        {i: faces[(node, f"wall{i}")]["seen_fraction"] for i in range(4)}
