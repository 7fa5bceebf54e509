"""The modelling screen's relations driven for real (Xvfb and xdotool, as tests/test_edit_window.py):
the Relate tool's clicks on two faces in the photo and its popup or keys make a flush relation (with
an offset, one face chosen by name) and an aligned one (of two edges, Shift+click), Make equal in
the properties panel shares a size of the selected nodes, the Relations section lists and removes
them; each saved in the project, whose model then decodes with its relations."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from edit_driver import Driver

from vebuild import camera as cam_math
from vebuild.cli import main
from vebuild.edit.relate_tool import PICK_COLOURS
from vebuild.project import decode, load_project
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")

#: A blended pixel's channels within this of the exact blend: 8-bit rounding of the colour, its
#: alpha and the result (three half-levels), no more.
BLEND_TOL = 2.0

#: Box faces by the handles at their corners (first side, second side), as the primitives name them.
BOX_FACES = {"front": ("v0", "v1", "v5", "v4"), "right": ("v1", "v2", "v6", "v5"), "back": ("v2", "v3", "v7", "v6"),
             "left": ("v3", "v0", "v4", "v7"), "top": ("v4", "v5", "v6", "v7")}


@pytest.fixture(scope="module")
def driver(tmp_path_factory, xvfb_display, xdotool):
    """One window over a copy of the example room, calibrated and solved, for the whole file."""
    folder = tmp_path_factory.mktemp("relate-window") / "room"
    shutil.copytree(example_project_dir(), folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    d = Driver(path, xdotool)
    for _ in range(3):  # a click on a tab the window had not drawn yet is lost: again, until it shows
        d.click("tab:Model")
        d.frames(2)
        if "Add" in d.editor.widget_rects:
            break
    assert "Add" in d.editor.widget_rects
    yield d
    d.close()


def _face_pixel(s, photo, node, face):
    """A window-independent pixel where ``photo`` shows ``face`` of the box ``node``: points across
    the face (from its corner handles), the first whose ray meets that face first."""
    c = [s.model.handle_world(node, h) for h in BOX_FACES[face]]
    cam = s.cameras[photo]
    for a in np.linspace(0.1, 0.9, 9):
        for b in (0.5, 0.3, 0.7):
            X = (1 - b) * ((1 - a) * c[0] + a * c[1]) + b * ((1 - a) * c[3] + a * c[2])
            uv = cam_math.project(cam.K, cam.R, cam.C, X, cam.lens)
            hit = s.face_at(photo, uv)
            w, h = s.photo(photo)["width"], s.photo(photo)["height"]
            if hit is not None and hit.ref == f"{node}:{face}" and 0 < uv[0] < w and 0 < uv[1] < h:
                return uv
    raise AssertionError(f"{node}:{face} is not seen in {photo}")


def _click_photo(d, uv, *keys):
    x, y = d.editor.image_to_window(d.editor.photo, uv)
    mods = [k for key in keys for k in ("keydown", key)]
    ups = [k for key in keys for k in ("keyup", key)]
    d.send(*d.move_to(x, y), "sleep", "0.05", *mods, "click", "1", *ups)


def _saved(d):
    d.send("key", "ctrl+s")
    assert not d.session.dirty
    path = d.session.project.path
    data = json.loads(path.read_text())
    project = load_project(path, verify_photos=False)
    return data, decode.model(project)


def test_flush_is_made_with_the_relate_tool_and_its_popup(driver):
    d = driver
    e, s = d.editor, d.session
    d.send("key", "r")
    assert e.tool == "relate"
    x, y = (int(v) for v in e.image_to_window("p1", _face_pixel(s, "p1", "cabinet", "right")))
    before = d.screen()[y, x].astype(float)
    _click_photo(d, _face_pixel(s, "p1", "cabinet", "right"))
    assert [p.ref for p in e.relate_picks] == ["cabinet:right"]
    assert "cabinet:right picked" in s.messages[-1]
    # The picked face is drawn translucent orange over the photo: blended over what was there.
    r, g, b, alpha = PICK_COLOURS[0]
    want = before + alpha * (255.0 * np.array([r, g, b]) - before)
    assert np.abs(d.screen()[y, x].astype(float) - want).max() <= BLEND_TOL
    _click_photo(d, _face_pixel(s, "p1", "wall_west", "front"))
    assert [p.ref for p in e.relate_picks] == ["cabinet:right", "wall_west:front"]
    d.frames(2)
    assert "relate faces" in e.widget_rects and "relate a" in e.widget_rects
    # The photo shows the cabinet's side; its back on the wall is its left face, chosen by name.
    d.click("relate a")
    d.frames(2)
    d.click("relate a:left")
    assert e.relate_picks[0].ref == "cabinet:left"
    d.click("relate offset")
    d.send("type", "--delay", "30", "0.01")
    d.click("Flush (F)##relate")
    rel = s.data["model"]["relations"][-1]
    assert rel == {"type": "flush", "a": "cabinet:left", "b": "wall_west:front", "offset": 0.01}
    assert e.relate_picks == [] and s.undo_label == "flush cabinet:left – wall_west:front"
    d.frames(3)
    assert "relate faces" not in e.widget_rects
    i = len(s.data["model"]["relations"]) - 1
    assert f"relation:{i}" in e.widget_rects  # the Relations section lists it, with its residual
    state = s.relation_states()[i]
    assert state.distance_m is not None and state.angle_deg is not None
    data, model = _saved(d)
    assert data["model"]["relations"][i] == rel
    assert any(r.type == "flush" and r.a == "cabinet:left" for r in model.relations)
    # The same faces again, 2 cm off: a conflict, named on screen; nothing added.
    _click_photo(d, _face_pixel(s, "p1", "cabinet", "right"))
    _click_photo(d, _face_pixel(s, "p1", "wall_west", "front"))
    d.frames(2)
    d.click("relate a")
    d.frames(2)
    d.click("relate a:left")
    d.click("relate offset")
    d.send("key", "ctrl+a", "type", "--delay", "30", "0.02")
    d.click("Flush (F)##relate")
    assert "conflicts with $.model.relations[0]" in s.messages[-1], s.messages[-1]
    assert len(s.data["model"]["relations"]) == i + 1 and len(e.relate_picks) == 2  # still picked: try again
    d.send("key", "Escape")
    assert e.relate_picks == []


def test_aligned_edges_by_shift_click_and_the_a_key_and_esc_cancels(driver):
    d = driver
    e, s = d.editor, d.session
    d.send("key", "r")
    # Esc drops a pick.
    _click_photo(d, _face_pixel(s, "p1", "cabinet", "right"))
    d.send("key", "Escape")
    assert e.relate_picks == [] and "relation cancelled" in s.messages[-1]
    n = len((s.data["model"]).get("relations", []))
    edges = {ln.key: ln for ln in e.overlay().lines if ln.kind == "edge"}
    picks = []
    for key in (("cabinet", "e9"), ("table.top", "e5")):
        ln = edges[key]
        picks.append(np.add(ln.p[:2], ln.p[2:]) / 2)
        _click_photo(d, picks[-1], "shift")
    assert [(p.ref, p.what) for p in e.relate_picks] == [("cabinet:e9", "edge"), ("table.top:e5", "edge")]
    assert "A aligned (collinear)" in s.messages[-1]
    d.send("key", "a")
    assert s.data["model"]["relations"][n] == {"type": "aligned", "a": "cabinet:e9", "b": "table.top:e5"}
    # A face of the same node twice: said, not picked.
    _click_photo(d, _face_pixel(s, "p1", "cabinet", "right"))
    _click_photo(d, _face_pixel(s, "p1", "cabinet", "right"))
    assert len(e.relate_picks) == 1 and "same node" in s.messages[-1]
    d.send("key", "Escape")
    data, model = _saved(d)
    assert data["model"]["relations"][n]["type"] == "aligned"
    assert any(r.type == "aligned" and r.a == "cabinet:e9" for r in model.relations)


def test_make_equal_over_the_selected_nodes_and_the_relations_section_removes_one(driver):
    d = driver
    e, s = d.editor, d.session
    d.send("key", "Escape")
    d.send(*d.at("node:box"), "click", "1")
    d.send(*d.at("node:cabinet"), "keydown", "ctrl", "click", "1", "keyup", "ctrl")
    assert e.selected_nodes == ["box", "cabinet"] and e.selected == "cabinet"
    d.frames(2)
    d.click("equal param")
    d.frames(2)
    d.click("equal param:height")
    n = len(s.data["model"].get("relations", []))
    d.click("Make equal")
    assert s.data["model"]["relations"][n] == {"type": "equal", "params": ["cabinet.height", "box.height"]}
    assert "share one value" in s.messages[-1]
    d.frames(2)
    assert f"relation:{n}" in e.widget_rects
    data, model = _saved(d)
    assert any(r.type == "equal" and set(r.params) == {"cabinet.height", "box.height"} for r in model.relations)
    # Removed from the Relations section; undone by Ctrl+Z.
    d.click(f"x##relation{n}")
    assert len(s.data["model"].get("relations", [])) == n
    d.send("key", "ctrl+z")
    assert s.data["model"]["relations"][n]["type"] == "equal"
