"""The modelling screen's room shell driven for real (Xvfb and xdotool, as tests/test_edit_window.py):
a room added from the Model tab onto the origin marker, its ceiling, a corner step added and removed,
a doorway and a window added to chosen walls, a door leaf on the doorway's jamb, a window pane in the
window and a second room joined through the doorway; each saved in the project, whose model then
decodes, and the room's edges and handles drawn over the photo."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from edit_driver import Driver

from vebuild.cli import main
from vebuild.project import decode, load_project
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")


@pytest.fixture(scope="module")
def driver(tmp_path_factory, xvfb_display, xdotool):
    """One window over the example room's photos, calibrated, its model taken away: the room shell
    is modelled from nothing."""
    folder = tmp_path_factory.mktemp("room-window") / "room"
    shutil.copytree(example_project_dir(), folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    data = json.loads(path.read_text())
    for key in ("model", "model_solution", "textures"):
        data.pop(key, None)
    data["reference_distances"] = [r for r in data["reference_distances"] if ":" not in r["a"] + r["b"]]
    path.write_text(json.dumps(data))
    d = Driver(path, xdotool)
    for _ in range(3):  # a click on a tab the window had not drawn yet is lost: again, until it shows
        d.click("tab:Model")
        d.frames(2)
        if "Add" in d.editor.widget_rects:
            break
    assert "Add" in d.editor.widget_rects
    yield d
    d.close()


def _saved(d):
    d.send("key", "ctrl+s")
    assert not d.session.dirty
    path = d.session.project.path
    return json.loads(path.read_text()), decode.model(load_project(path, verify_photos=False))


def _node(s, name):
    return next(n for n in s.data["model"]["nodes"] if n["name"] == name)


def _type_into(d, label, text):
    d.send(*d.at(label), "click", "1", "key", "ctrl+a", "type", "--delay", "30", text)
    d.send("key", "Return")


def test_a_room_is_added_on_the_origin_marker_and_shaped_from_its_panel(driver):
    d = driver
    e, s = d.editor, d.session
    d.click("kind")
    d.frames(2)
    d.click("kind:room")
    d.click("Add")  # then a click in the photo: the first object goes on the origin marker
    x0, y0, x1, y1 = e.view_rect()
    d.send(*d.move_to(0.5 * (x0 + x1), 0.5 * (y0 + y1)), "sleep", "0.05", "click", "1")
    room = e.selected
    assert room is not None, s.messages[-3:]
    doc = _node(s, room)
    assert doc["primitive"]["type"] == "room" and doc["joint"] == {"type": "marker", "marker": "O", "handle": "f0",
                                                                    "yaw_deg": 0.0}
    np.testing.assert_allclose(s.model.handle_world(room, "f0"), s.data["calibration"]["markers"]["O"]["position"])
    np.testing.assert_allclose(s.model.node(room).primitive.corners(), [[0, 0], [4, 0], [4, 3], [0, 3]])
    # Its edges are drawn over the photo (the overlay draws every primitive's edges), its handles too.
    d.frames(2)
    drawn = {ln.key[1] for ln in e.overlay().lines if ln.kind == "edge" and ln.key[0] == room}
    assert {"floor0", "top0", "corner0", "ofloor0"} <= drawn
    assert any(n == room and h == "f1" for n, h, _, _ in s.handles("p1"))
    # Ceiling on.
    d.click("ceiling")
    assert _node(s, room)["primitive"]["ceiling"] is True
    # A step after corner 1, then removed again (corner 2 begins it).
    _type_into(d, "room corner", "1")
    d.click("Add corner after")
    assert len(s.model.node(room).primitive.corners()) == 6
    _type_into(d, "room corner", "2")
    d.click("Remove corner")
    assert len(s.model.node(room).primitive.corners()) == 4
    # A doorway in wall 0, a window in wall 1.
    d.click("Add opening")
    d.click("wall")
    d.frames(2)
    d.click("wall:wall1")
    d.click("opening kind")
    d.frames(2)
    d.click("opening kind:window")
    d.click("Add opening")
    openings = _node(s, room)["primitive"]["openings"]
    assert [(o["name"], o["wall"], o["kind"]) for o in openings] == [("door1", 0, "door"), ("window1", 1, "window")]
    data, model = _saved(d)
    assert model.node(room).primitive.opening_names() == ["door1", "window1"]
    assert _node(s, room)["primitive"] == next(n for n in data["model"]["nodes"] if n["name"] == room)["primitive"]


def test_door_leaf_window_pane_and_a_room_joined_through_the_doorway(driver):
    d = driver
    e, s = d.editor, d.session
    room = next(n["name"] for n in s.data["model"]["nodes"] if n["primitive"]["type"] == "room")
    d.click(f"node:{room}")
    d.frames(2)
    d.click("Door leaf##door1")
    leaf = e.selected
    assert leaf != room, s.messages[-1]
    j = _node(s, leaf)["joint"]
    assert _node(s, leaf)["parent"] == room and j["type"] == "hinge" and j["solve_axis"] is True
    assert j["jamb"] == {"opening": "door1", "side": "start"}
    d.click(f"node:{room}")
    d.frames(2)
    d.click("Window pane##window1")
    pane = e.selected
    assert _node(s, pane)["joint"]["type"] == "opening" and _node(s, pane)["joint"]["opening"] == "window1"
    d.click(f"node:{room}")
    d.frames(2)
    d.click("Join room##door1")
    other = e.selected
    assert _node(s, other)["joint"] == {"type": "through", "opening": "door1", "own_opening": "door1"}
    assert s.data["model"]["relations"][-2:] == [
        {"type": "equal", "params": [f"{room}.door1_width", f"{other}.door1_width"]},
        {"type": "equal", "params": [f"{room}.door1_height", f"{other}.door1_height"]}]
    data, model = _saved(d)
    assert {leaf, pane, other} <= set(model.index)
    assert model.node(leaf).joint.type == "hinge" and model.node(other).joint.type == "through"
    # Joined back to back: the second room's doorway lies on the first's, facing it.
    a = np.array([model.handle_world(room, h) for h in ("door1_osb", "door1_oeb")])
    b = np.array([model.handle_world(other, h) for h in ("door1_osb", "door1_oeb")])
    assert np.allclose(np.sort(a, axis=0), np.sort(b, axis=0), atol=1e-6)


def test_a_box_on_the_room_floor_made_flush_against_a_wall_by_its_joint(driver):
    """From p6 (inside the room, facing its walls 1 and 2): a box added on the room stands on its
    floor where clicked; the Relate tool's clicks on the box and on wall 2, its back chosen by name,
    and Flush joint put the box's back on the wall by its joint."""
    from vebuild import camera as cam_math

    d = driver
    e, s = d.editor, d.session
    room = next(n["name"] for n in s.data["model"]["nodes"] if n["primitive"]["type"] == "room"
                and n["joint"]["type"] == "marker")
    d.click("photo:p6")
    assert e.photo == "p6"
    cam = s.cameras["p6"]

    def pixel(X):
        return cam_math.project(cam.K, cam.R, cam.C, np.asarray(X, float), cam.lens)

    d.click("kind")
    d.frames(2)
    d.click("kind:box")
    d.click("parent")
    d.frames(2)
    d.click(f"parent:{room}")
    d.click("Add")
    d.send(*d.move_to(*e.image_to_window("p6", pixel((2.0, 1.5, 0.0)))), "sleep", "0.05", "click", "1")
    box = e.selected
    j = _node(s, box)["joint"]
    assert _node(s, box)["parent"] == room and (j["type"], j["face"]) == ("rests_on", "floor")
    np.testing.assert_allclose(s.model.handle_world(box, "v0")[:2] + 0.25, (2.0, 1.5), atol=0.01)
    # Relate: the box's top (seen from above), then wall 2's inner face; the box's back chosen by name.
    d.send("key", "r")
    top = np.mean([s.model.handle_world(box, h) for h in ("v4", "v5", "v6", "v7")], axis=0)
    d.send(*d.move_to(*e.image_to_window("p6", pixel(top))), "sleep", "0.05", "click", "1")
    d.send(*d.move_to(*e.image_to_window("p6", pixel((2.0, 3.0, 1.5)))), "sleep", "0.05", "click", "1")
    assert [p.ref for p in e.relate_picks] == [f"{box}:top", f"{room}:wall2"]
    d.frames(2)
    d.click("relate a")
    d.frames(2)
    d.click("relate a:back")
    d.click("Flush joint##relate")
    j = _node(s, box)["joint"]
    assert (j["type"], j["face"], j["own_face"]) == ("flush", "wall2", "back")
    assert s.model.handle_world(box, "v2")[1] == pytest.approx(3.0, abs=1e-9)  # its back on the wall
    data, model = _saved(d)
    assert model.node(box).joint.type == "flush"
