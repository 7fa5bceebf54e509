"""The modelling screen (``vebuild edit``) driven for real: a virtual X server (Xvfb) and input
events sent with xdotool, as a user's mouse and keyboard would (CI's .ci/run installs both).

Widgets are found by :attr:`Editor.widget_rects` (each drawn ImGui widget's rectangle by its label)
and photo points by :meth:`Editor.image_to_window`, so the clicks land on what is drawn.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from edit_driver import Driver

from vebuild.cli import main
from vebuild.edit.layout import MAX_ZOOM, PICK_RADIUS_PX, WHEEL_STEP
from vebuild.edit.screen import run_editor
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")


@pytest.fixture
def bare(tmp_path):
    """A new project of the example room's five photos: no marks, no calibration, no model."""
    folder = tmp_path / "bare"
    shutil.copytree(example_project_dir() / "photos", folder / "photos")
    path = folder / "bare.vebuild.json"
    assert main(["new", str(path), *sorted(str(p) for p in (folder / "photos").glob("*.jpg"))]) == 0
    return path


@pytest.fixture(scope="module")
def solved_room(tmp_path_factory):
    folder = tmp_path_factory.mktemp("edit") / "room"
    shutil.copytree(example_project_dir(), folder)
    path = folder / "room.vebuild.json"
    assert main(["calibrate", str(path), "--quiet"]) == 0
    assert main(["solve", str(path)]) == 0
    return path


@pytest.fixture
def room(solved_room, tmp_path):
    """The example room calibrated and solved, a copy per test."""
    shutil.copytree(solved_room.parent, tmp_path / "room")
    return tmp_path / "room" / solved_room.name


@pytest.fixture
def driver_factory(xdotool):
    made = []

    def make(project_file, **kw):
        d = Driver(project_file, xdotool, **kw)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def _view_centre(editor):
    x0, y0, x1, y1 = editor.view_rect()
    return 0.5 * (x0 + x1), 0.5 * (y0 + y1)


def test_zoom_and_pan_map_window_and_photo_pixels_exactly(bare, driver_factory):
    d = driver_factory(bare)
    e = d.editor
    assert e.photo == "p1"
    fit = e.zoom
    assert fit == pytest.approx(min((e.view_rect()[2] - e.view_rect()[0]) / 1600,
                                    (e.view_rect()[3] - e.view_rect()[1]) / 1200))
    # The mapping and its inverse agree exactly, sub-pixel.
    for uv in ((0.0, 0.0), (1600.0, 1200.0), (123.25, 456.75)):
        assert e.window_to_image(*e.image_to_window("p1", uv)) == pytest.approx(uv, abs=1e-9)
    # The wheel zooms about the cursor: the photo point under it stays under it.
    cx, cy = 431, 377
    d.send(*d.move_to(cx, cy))
    uv = e.window_to_image(cx, cy)
    d.send("click", "4", "sleep", "0.05", "click", "4", "sleep", "0.05", "click", "4")
    assert e.zoom == pytest.approx(fit * WHEEL_STEP**3)
    assert e.window_to_image(cx, cy) == pytest.approx(uv, abs=1e-9)
    d.send("click", "--repeat", "20", "--delay", "20", "4")
    assert e.zoom == MAX_ZOOM
    assert e.window_to_image(cx, cy) == pytest.approx(uv, abs=1e-9)
    # At 16× every photo pixel is a 16×16 block of exactly its colour (nearest-texel filtering).
    img = d.screen()
    photo = d.session.photo_pixels("p1")
    i0, j0 = int(uv[0]), int(uv[1])
    for i in range(i0 - 3, i0 + 4):
        for j in range(j0 - 3, j0 + 4):
            x, y = e.image_to_window("p1", (i + 0.5, j + 0.5))
            np.testing.assert_array_equal(img[int(y), int(x)], photo[j, i])
            x, y = e.image_to_window("p1", (i + 0.05, j + 0.95))  # a corner of the same block
            np.testing.assert_array_equal(img[int(y), int(x)], photo[j, i])
    # Middle-drag pans by exactly the mouse's movement.
    pan = e.pan
    d.send("mousedown", "2", "sleep", "0.05", *d.move_to(cx - 100, cy + 40), "sleep", "0.05",
           *d.move_to(cx - 120, cy + 50), "sleep", "0.05", "mouseup", "2")
    assert e.pan == pytest.approx((pan[0] - 120, pan[1] + 50))
    assert e.window_to_image(cx - 120, cy + 50) == pytest.approx(uv, abs=1e-9)
    # Space + left drag pans too; Home fits the photo again.
    pan = e.pan
    d.send("keydown", "space", *d.move_to(cx, cy), "mousedown", "1", "sleep", "0.05", *d.move_to(cx + 30, cy + 30),
           "sleep", "0.05", "mouseup", "1", "keyup", "space")
    assert e.pan == pytest.approx((pan[0] + 30, pan[1] + 30))
    assert d.session.revision == 0  # panning edits nothing
    d.send("key", "Home")
    assert e.zoom == pytest.approx(fit)


def test_a_segment_is_drawn_by_dragging_and_undone_by_keys(bare, driver_factory):
    d = driver_factory(bare)
    e, s = d.editor, d.session
    d.send("key", "1")
    assert e.tool == "x"
    a, b = (300, 520), (520, 470)
    d.send(*d.move_to(*a), "sleep", "0.05")
    assert e.magnifier_visible() and "magnifier" in e.widget_rects  # sub-pixel placement under the cursor
    # Alt held: placed exactly as drawn (without it the stroke snaps to the image line it covers).
    d.send("keydown", "alt", "mousedown", "1", "sleep", "0.05", *d.move_to(400, 500), "sleep", "0.05", *d.move_to(*b),
           "sleep", "0.05", "mouseup", "1", "keyup", "alt")
    segs = s.photo("p1")["vanishing_segments"]["x"]
    assert len(segs) == 1
    np.testing.assert_allclose(segs[0], [*e.window_to_image(*a), *e.window_to_image(*b)], atol=1e-9)
    # Drawn in the x colour (red) with its arrow head at the second end, above the photo.
    img = d.screen().astype(int)
    mid = (int(round((a[0] + b[0]) / 2)), int(round((a[1] + b[1]) / 2)))
    patch = img[mid[1] - 2:mid[1] + 3, mid[0] - 2:mid[0] + 3].reshape(-1, 3)
    assert np.any((patch[:, 0] > 200) & (patch[:, 1] < 110))
    # Undo / redo by keys, and by the toolbar's buttons.
    d.send("key", "ctrl+z")
    assert not (s.photo("p1").get("vanishing_segments") or {}).get("x")
    d.send("key", "ctrl+y")
    assert len(s.photo("p1")["vanishing_segments"]["x"]) == 1
    d.send("key", "ctrl+z", "key", "ctrl+shift+z")
    assert len(s.photo("p1")["vanishing_segments"]["x"]) == 1
    d.click("Undo")
    assert not (s.photo("p1").get("vanishing_segments") or {}).get("x")
    d.click("Redo")
    assert len(s.photo("p1")["vanishing_segments"]["x"]) == 1
    # The Delete tool removes it by a click on it.
    d.send("key", "Delete", *d.move_to(400, 500), "sleep", "0.05")
    d.send(*d.move_to(*e.image_to_window("p1", np.add(segs[0][:2], segs[0][2:]) / 2)), "sleep", "0.05", "click", "1")
    assert not (s.photo("p1").get("vanishing_segments") or {}).get("x")
    assert "deleted x segment 0" in s.messages[-1]


def test_a_zero_length_segment_says_so_on_screen_and_adds_nothing(bare, driver_factory):
    d = driver_factory(bare)
    e, s = d.editor, d.session
    d.send("key", "2", *d.move_to(500, 400), "sleep", "0.05", "click", "1")
    assert e.tool == "y"
    assert not (s.photo("p1").get("vanishing_segments") or {}).get("y")
    assert "0.0 px long" in s.messages[-1] and "at least 2 px apart" in s.messages[-1]
    assert s.revision == 0 and s.undo_label is None
    # The message area is drawn over the photo view's bottom-left, light text on a dark box.
    x0, y0, x1, y1 = (int(v) for v in e.widget_rects["messages"])
    assert e.view_rect()[0] <= x0 and y1 <= e.view_rect()[3]
    box = d.screen()[y0:y1, x0:x1].astype(int)
    assert np.median(box) < 90 and box.max() > 200


def test_a_photo_that_fails_to_load_shows_a_message_and_a_placeholder(bare, driver_factory):
    (bare.parent / "photos" / "p2.jpg").write_bytes(b"not a jpeg")
    d = driver_factory(bare)
    e, s = d.editor, d.session
    assert "photo:p2" in e.widget_rects
    d.click("photo:p2")
    assert e.photo == "p2"
    assert any("photo 'p2' fails to load" in m for m in s.messages)
    img = d.screen().astype(int)
    x, y = (int(v) for v in e.image_to_window("p2", (400, 200)))
    assert np.all(np.abs(img[y, x] - 64) < 12)  # the grey placeholder, the photo's size
    # The screen goes on: the next photo (PageDown) shows.
    d.send("key", "Next")
    assert e.photo == "p3"
    x, y = (int(v) for v in e.image_to_window("p3", (800.5, 600.5)))
    assert np.abs(d.screen()[y, x].astype(int) - s.photo_pixels("p3")[600, 800]).max() <= 40
    d.send("key", "Prior", "key", "Prior")
    assert e.photo == "p1"


def test_panels_respond_to_clicks(bare, driver_factory):
    shutil.copy(bare.parent / "photos" / "p1.jpg", bare.parent / "photos" / "extra.jpg")
    d = driver_factory(bare)
    e, s = d.editor, d.session
    d.click("Segment Z")
    assert e.tool == "z"
    d.click("Marker")
    assert e.tool == "marker"
    d.click("photo:p4")
    assert e.photo == "p4"
    # Typing a file name and pressing "Add photo" adds it, hash and all, and shows it.
    d.click("add photo file")
    d.send("type", "--delay", "30", "photos/extra.jpg")
    d.click("Add photo")
    assert s.photo_ids[-1] == "extra" and e.photo == "extra"
    assert s.photo("extra")["sha256"] == s.photo("p1")["sha256"]
    d.frames(3)
    assert "photo:extra" in e.widget_rects
    # A marker is placed where clicked, with the name from the toolbar's field.
    d.send(*d.move_to(420, 300), "sleep", "0.05", "click", "1")
    assert s.photo("extra")["marker_observations"]["M1"] == pytest.approx(e.window_to_image(420, 300))
    assert e.marker_name == "M2"
    # Calibrating with too few marks shows why in the panel, no traceback.
    d.click("Calibrate")
    assert e.calibration_error and e.calibration_result is None
    d.click("tab:Model")
    assert "Add at centre" in e.widget_rects and "Calibrate" not in e.widget_rects
    d.click("Add at centre")
    assert "calibrate first" in s.messages[-1]
    # Ctrl+S saves the project file; the autosave side file goes.
    assert s.autosave_path.exists()
    d.send("key", "ctrl+s")
    assert not s.dirty and not s.autosave_path.exists()
    assert "extra" in [p["id"] for p in json.loads(bare.read_text())["photos"]]


def test_dragging_a_vertex_solves_live_and_esc_cancels(room, driver_factory):
    d = driver_factory(room)
    e, s = d.editor, d.session
    node = s.add_primitive("box", name="crate", parent="floor", at=("p1", (800.0, 1000.0)))
    e.select(node)
    d.frames(2)

    def handle(h):
        return next(p for n, k, p, _ in s.handles("p1") if (n, k) == (node, h))
    before = s.data["model"]["nodes"][-1]["joint"]["position"]
    start = e.image_to_window("p1", handle("v0"))
    # Esc during a drag puts it back.
    d.send(*d.move_to(*start), "sleep", "0.05", "mousedown", "1", "sleep", "0.05",
           *d.move_to(start[0] - 20, start[1] + 10), "sleep", "0.1", "key", "Escape", "mouseup", "1")
    assert not s.dragging and s.undo_label == "add box crate"
    assert handle("v0") == pytest.approx(e.window_to_image(*start), abs=PICK_RADIUS_PX / e.zoom)
    # A drag: the solver moves the box with the mouse, live; on release the corner is fixed there.
    moves = []
    for k in range(1, 6):
        moves += [*d.move_to(start[0] - 8 * k, start[1] + 4 * k), "sleep", "0.08"]
    d.send(*d.move_to(*start), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *moves)
    end = e.window_to_image(round(start[0] - 40), round(start[1] + 20))  # where xdotool put the mouse
    assert s.dragging and e.last_feedback.ok
    assert np.hypot(*np.subtract(e.last_feedback.handle_px, end)) < 2.0  # the session's "it follows"
    d.send("mouseup", "1")
    assert not s.dragging and s.undo_label.startswith("drag crate:v0")
    assert np.hypot(*np.subtract(handle("v0"), end)) < 2.0
    assert s.data["model"]["nodes"][-1]["joint"]["position"] != before
    pin = [p for p in s.data["model"]["pins"] if (p["node"], p["handle"]) == (node, "v0")]
    assert pin and pin[0]["uv"] == pytest.approx(end)
    # F over a vertex fixes it, F again unfixes it.
    at = e.image_to_window("p1", handle("v6"))
    d.send(*d.move_to(*at), "sleep", "0.05", "key", "f")
    assert any((n, h, f) == (node, "v6", True) for n, h, _, f in s.handles("p1"))
    d.send("key", "f")
    assert not any((n, h, f) == (node, "v6", True) for n, h, _, f in s.handles("p1"))
    # The 3-D preview followed the model after the drag.
    assert e._preview_key[0] == s.revision and e._preview_tex is not None


def test_a_drag_the_constraints_cannot_follow_says_why_and_the_model_stays(room, driver_factory):
    d = driver_factory(room)
    e, s = d.editor, d.session
    e.select("cabinet")
    uv0 = next(p for n, h, p, _ in s.handles("p1") if (n, h) == ("cabinet", "v0"))
    x, y = e.image_to_window("p1", uv0)
    params = dict(s.model.node("cabinet").primitive.to_dict()["params"])
    d.send(*d.move_to(x, y), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *d.move_to(x - 30, y + 15),
           "sleep", "0.1", *d.move_to(x - 60, y + 30), "sleep", "0.1")
    assert e.drag_problem is not None and "cannot go there" in e.drag_problem
    assert "it stays where it was" in s.messages[-1]
    d.send("key", "Escape", "mouseup", "1")
    assert s.model.node("cabinet").primitive.to_dict()["params"] == params


def test_the_recovery_question_is_asked_and_answered(room, driver_factory):
    data = json.loads(room.read_text())
    data["name"] = "edited, not saved"
    side = room.with_name(room.name + ".autosave")
    side.write_text(json.dumps(data))
    d = driver_factory(room, recover=None)
    e, s = d.editor, d.session
    assert s.recovery_available and "Recover the autosaved edits" in e.widget_rects
    d.click("Recover the autosaved edits")
    assert s.data["name"] == "edited, not saved" and not s.recovery_available
    d.frames(2)
    assert "Recover the autosaved edits" not in e.widget_rects


def test_vebuild_edit_runs_and_without_a_display_names_the_headless_way(bare, monkeypatch, capsys):
    shutil.copy(bare.parent / "photos" / "p1.jpg", bare.parent / "photos" / "more.jpg")
    s = run_editor(bare, (640, 480), recover=None, add_photos=["photos/more.jpg", "photos/none.jpg"], frames=5)
    assert s.photo_ids[-1] == "more"
    assert any("none.jpg" in m for m in s.messages)
    assert "unsaved edits are kept in" in capsys.readouterr().err
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["edit", str(bare)]) == 2
    err = capsys.readouterr().err
    assert "xvfb-run" in err and "Traceback" not in err


def test_the_screen_draws_off_screen_for_its_benchmark():
    from vebuild.bench import BENCHES

    bench = BENCHES["edit"]
    fig = bench.run(quick=True, progress=False)
    for n in bench.SCENARIOS:
        assert fig[f"drag_moves_not_followed_{n}"] == 0
        assert 0 < fig[f"drag_solve_ms_median_{n}"] < fig[f"drag_update_ms_median_{n}"]
    assert fig["drag_update_ms_p95"] >= fig["drag_solve_ms_p95_0_fixed"]
    assert fig["static_redraw_ms_median"] > 0 and fig["drag_update_ratio_vs_static_redraw"] > 0
    text = bench.table(fig)
    assert "goal (drag update p95" in text and "v6, 1 fixed" in text


def test_the_model_panel_adds_places_edits_solves_and_the_edge_tool_draws(room, driver_factory):
    d = driver_factory(room)
    e, s = d.editor, d.session
    d.click("tab:Model")
    # Add, then a click in the photo: a box standing on the floor where the click's ray meets it.
    d.click("Add")
    assert e._placing is not None
    at = e.image_to_window("p1", (1200.0, 1000.0))
    d.send(*d.move_to(*at), "sleep", "0.05", "click", "1")
    assert e.selected == "box1" and "box1" in s.model.index
    doc = next(n for n in s.data["model"]["nodes"] if n["name"] == "box1")
    assert doc["joint"]["type"] == "rests_on" and doc["joint"]["position"] != [0.0, 0.0]
    # The tree lists it; its width is typed into its field.
    assert "node:box1" in e.widget_rects
    d.click("node:box1")
    assert e.selected == "box1"
    d.click("width (m)##param:width")
    d.send("key", "ctrl+a", "type", "--delay", "30", "0.8")
    d.send("key", "Return")
    assert s.model.node("box1").primitive.to_dict()["params"]["width"] == pytest.approx(0.8)
    assert s.undo_label == "sizes of box1"
    # The Edge tool: a stroke along one of the selected box's projected edges observes that edge.
    e.select("cabinet")
    d.frames(2)
    edge = next(ln for ln in e.overlay().lines if ln.kind == "edge" and ln.key == ("cabinet", "e8"))
    a = e.image_to_window("p1", edge.p[:2])
    b = e.image_to_window("p1", edge.p[2:])
    p, q = np.add(a, np.subtract(b, a) * 0.2), np.add(a, np.subtract(b, a) * 0.8)
    n_edges = len(s.data["model"]["edge_observations"])
    d.send("key", "e", *d.move_to(*p), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *d.move_to(*q),
           "sleep", "0.05", "mouseup", "1")
    obs = s.data["model"]["edge_observations"]
    assert len(obs) == n_edges + 1 and (obs[-1]["node"], obs[-1]["edge"]) == ("cabinet", "e8")
    # Solve: the new box has nothing pinned, which the panel says; removed, the model solves.
    d.click("Solve")
    assert "too few observations" in e.solve_error and "box1" in e.solve_error
    d.send("key", "Escape")  # the Select tool again: a click on one of box1's edges selects it
    edge = next(ln for ln in e.overlay().lines if ln.kind == "edge" and ln.key == ("box1", "e8"))
    d.send(*d.move_to(*e.image_to_window("p1", np.add(edge.p[:2], edge.p[2:]) / 2)), "sleep", "0.05", "click", "1")
    assert e.selected == "box1" and "node:box1" in e.widget_rects  # the tree scrolled to it
    d.click("Remove##node")
    assert "box1" not in s.model.index and e.selected is None
    d.click("Solve")
    assert e.solve_error is None and e.solve_result["rms_px"] < 2.0
    assert s.undo_label == "solve" and any(m.startswith("solved: rms") for m in s.messages)


def test_recalibrate_register_group_a_marker_primitive_and_textures_from_the_model_panel(room, driver_factory):
    d = driver_factory(room)
    e, s = d.editor, d.session
    d.click("tab:Model")
    # Re-calibration (paper §3.2): cameras and markers solved with the model, residuals listed.
    d.click("Re-calibrate")
    assert e.solve_error is None, e.solve_error
    assert s.data["model_solution"]["recalibrated"] and s.undo_label == "re-calibrate"
    assert all(c.get("recalibrated") for c in s.data["model_solution"]["cameras"].values())
    assert not any(c.get("recalibrated") for c in s.data["calibration"]["cameras"].values())
    # Register the photo shown from the known points marked in it.
    d.click("photo:p2")
    d.click("Register this photo")
    assert s.data["calibration"]["cameras"]["p2"]["mode"] == "registered"
    # Group two objects from the tree (Ctrl+click selects several).
    d.send(*d.at("node:box"), "click", "1")
    d.send(*d.at("node:cabinet"), "keydown", "ctrl", "click", "1", "keyup", "ctrl")
    assert e.selected_nodes == ["box", "cabinet"]
    d.send(*d.at("group name"), "click", "1", "key", "ctrl+a", "type", "furniture")
    d.send("key", "Return")
    d.click("Group")
    assert {s.model.node(n).parent for n in ("box", "cabinet")} == {"furniture"}
    # A sphere hung on a calibrated marker: its lowest point on the marker.
    d.click("kind")
    d.frames(2)
    d.click("kind:sphere")
    d.click("parent")
    d.frames(2)
    d.click("parent:marker T2")
    d.click("Add")
    ball = e.selected
    assert s.model.node(ball).joint.type == "marker"
    assert np.allclose(s.model.handle_world(ball, "bottom"), s.data["calibration"]["markers"]["T2"]["position"])
    # Textures extracted on demand (off-screen GL beside the window's context); the screen goes on
    # drawing, and the 3-D preview shows them.
    x0, y0, x1, _ = (int(v) for v in e.view_rect())
    y1 = int(e.widget_rects["messages"][1]) - 60  # the photo view above the messages (they change)
    before = d.screen()[y0:y1, x0:x1]
    d.click("Extract textures")
    assert s.data.get("textures") and s.undo_label == "extract textures"
    d.frames(3)
    assert e._renderer.scene.textured and e.preview_note == ""
    assert np.array_equal(d.screen()[y0:y1, x0:x1], before)  # the window's context is current again


def test_a_drag_frame_shows_what_a_whole_redraw_shows(room):
    """During a drag the screen copies the panels and the still part of the photo view from the
    frame of the press and draws only the moving primitive: the frame must be the one a whole
    redraw gives, but where the moving primitive's lines cross other lines (drawn over them)."""
    import glfw

    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.context import headless_context
    from vebuild.gl.surface import OffscreenSurface

    s = EditSession.open(room, recover=False)
    surface = OffscreenSurface(headless_context(), 1200, 780)
    e = Editor(s, surface)
    try:
        e.set_photo("p3")
        e.select(s.add_primitive("box", name="crate", parent="floor", at=("p3", (900.0, 1000.0))))
        for _ in range(len(s.photo_ids) + 3):
            e.draw()
        uv = next(p for n, h, p, _ in s.handles("p3") if (n, h) == ("crate", "v4"))
        x, y = e.image_to_window("p3", uv)
        e.on_cursor(x, y)
        e.on_button(glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
        e.draw()  # the frame of the press, kept
        for k in range(1, 6):  # nothing of it fixed yet: it slides on the floor
            e.on_cursor(x - 6 * k, y + 3 * k)
            e.draw()
        assert s.dragging and e.last_feedback.ok, s.messages[-1:]
        live = surface.read()
        e._frame_cache_press = None  # the same state drawn whole
        e.draw()
        whole = surface.read()
        differ = np.any(live != whole, axis=2)
        x0, y0, x1, y1 = (int(v) for v in e.view_rect())
        assert differ[:y0].sum() == 0 and differ[y1:].sum() == 0 and differ[:, x1:].sum() == 0  # panels
        # Where the moving box's lines cross others (23 pixels here): under 0.1 % of the view.
        assert differ[y0:y1, x0:x1].mean() < 0.001, differ[y0:y1, x0:x1].mean()
    finally:
        e.close()
        surface.release()


def test_l_hides_and_shows_the_labels_over_the_photo(room):
    import glfw

    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.context import headless_context
    from vebuild.gl.surface import OffscreenSurface

    s = EditSession.open(room, recover=False)
    surface = OffscreenSurface(headless_context(), 1200, 780)
    e = Editor(s, surface)
    try:
        e.set_photo("p3")
        for _ in range(len(s.photo_ids) + 3):
            e.draw()
        x0, y0, x1, y1 = (int(v) for v in e.view_rect())
        shown = surface.read()[y0:y1 - 80, x0:x1]
        e.on_key(glfw.KEY_L, glfw.PRESS, 0)
        e.on_key(glfw.KEY_L, glfw.RELEASE, 0)
        e.draw()
        hidden = surface.read()[y0:y1 - 80, x0:x1]
        assert not e.show_labels and np.any(shown != hidden)
        e.on_key(glfw.KEY_L, glfw.PRESS, 0)
        e.draw()
        assert e.show_labels and np.array_equal(surface.read()[y0:y1 - 80, x0:x1], shown)
    finally:
        e.close()
        surface.release()


def test_the_edges_runs_are_laid_out_once_per_view_and_drawn_as_laid_out_afresh(room, monkeypatch):
    """The model edges' seen and hidden runs are placed in the window (clipped, dashed) once per
    visibility and view: a frame that only moves the cursor reuses them and is the frame drawn
    with them laid out afresh; a zoom lays them out again."""
    from vebuild.edit import photo_view
    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.context import headless_context
    from vebuild.gl.surface import OffscreenSurface

    s = EditSession.open(room, recover=False)
    surface = OffscreenSurface(headless_context(), 1200, 780)
    e = Editor(s, surface)
    calls: list[int] = []
    real = photo_view._run_pieces
    monkeypatch.setattr(photo_view, "_run_pieces", lambda *a: calls.append(1) or real(*a))
    try:
        e.set_photo("p3")
        for _ in range(len(s.photo_ids) + 3):
            e.draw()
        runs = e.edge_visibility()
        assert runs and any(not r.visible for v in runs.values() for r in v)  # hidden runs among them
        x0, y0, x1, y1 = (int(v) for v in e.view_rect())
        e.on_cursor(x0 + 3, y1 - 3)  # over the photo's corner, away from every label
        calls.clear()
        e.draw()
        kept = surface.read()
        assert calls == []
        e._runs_drawn = None
        e.draw()
        assert len(calls) >= len(runs) // 2 and np.array_equal(surface.read(), kept)
        calls.clear()
        e.zoom *= 1.25
        e.draw()
        assert calls
        calls.clear()
        e.draw()
        assert calls == []
    finally:
        e.close()
        surface.release()


def test_the_hovered_line_is_the_nearest_a_loop_over_the_lines_finds(room):
    """The line under the cursor, found for all lines at once, is as near as the one a loop over
    the shown lines finds within the picking radius (to 1e-9 px: where two edges overlap, either
    is the nearest), over a grid of cursor positions on a photo of the solved example."""
    from vebuild.edit.layout import PICK_RADIUS_PX as radius
    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.context import headless_context
    from vebuild.gl.surface import OffscreenSurface

    def distance(ln, u, v):
        a, b = np.array(ln.p[:2]), np.array(ln.p[2:])
        d = b - a
        t = float(np.clip(np.dot([u, v] - a, d) / max(float(d @ d), 1e-12), 0.0, 1.0))
        return float(np.hypot(*(a + t * d - [u, v])))

    def loop(e, ov, u, v):
        best = (radius / e.zoom, None)
        for ln in ov.lines:
            if ln.kind != "vp-ray" and e.shows(ln.kind) and distance(ln, u, v) <= best[0]:
                best = (distance(ln, u, v), ln)
        return best[1]

    s = EditSession.open(room, recover=False)
    surface = OffscreenSurface(headless_context(), 1200, 780)
    e = Editor(s, surface)
    try:
        e.set_photo("p3")
        e.draw()
        ov = e.overlay()
        x0, y0, x1, y1 = e.view_rect()
        found = 0
        for x in np.linspace(x0 + 2, x1 - 2, 41):
            for y in np.linspace(y0 + 2, y1 - 2, 31):
                e._cursor = (float(x), float(y))
                got = e.hovered(ov)
                if got is not None and not hasattr(got, "p"):  # a point, found as before
                    continue
                u, v = e.window_to_image(x, y)
                expected = loop(e, ov, u, v)
                assert (got is None) == (expected is None), (x, y)
                if got is not None:
                    assert abs(distance(got, u, v) - distance(expected, u, v)) <= 1e-9, (x, y)
                    found += 1
        assert found > 30
    finally:
        e.close()
        surface.release()


@pytest.fixture
def one_photo(tmp_path):
    """The example room's photo p3 alone, as an archived photograph: its segments and the origin
    marker, no scale (tests/edit_scene.py)."""
    from edit_scene import make_one_photo

    return make_one_photo(tmp_path / "one")


def _colour_near(img, x, y, want, r=2):
    """Whether a pixel within r of window point (x, y) has the colour ``want`` (RGB 0–1) within 20 %."""
    patch = img[int(y) - r:int(y) + r + 1, int(x) - r:int(x) + r + 1].reshape(-1, 3).astype(float) / 255.0
    return bool(np.any(np.all(np.abs(patch - np.asarray(want[:3])) < 0.2, axis=1)))


def test_middle_points_are_added_dragged_and_deleted_by_the_mouse(one_photo, driver_factory):
    from vebuild.edit.layout import MIDDLE_PICK_PX
    from vebuild.edit.overlay import AXIS_COLOURS

    path, _ = one_photo
    d = driver_factory(path)
    e, s = d.editor, d.session
    segs = s.photo("p3")["vanishing_segments"]["x"]
    i = max(range(len(segs)), key=lambda k: np.hypot(segs[k][2] - segs[k][0], segs[k][3] - segs[k][1]))
    a, b = np.asarray(segs[i][:2]), np.asarray(segs[i][2:4])
    normal = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
    # Ctrl+click with the Segment X tool 2 window px beside the segment's line, 40 % along it.
    at = np.add(e.image_to_window("p3", a + 0.4 * (b - a)), 2.0 * normal)
    d.send("key", "1", *d.move_to(*at), "sleep", "0.05", "keydown", "ctrl", "click", "1", "keyup", "ctrl")
    row = s.photo("p3")["vanishing_segments"]["x"][i]
    assert len(row) == 6 and row[:2] == list(a) and row[4:] == list(b)
    assert row[2:4] == pytest.approx(e.window_to_image(round(at[0]), round(at[1])), abs=1e-9)
    assert "middle point 1 of x segment" in s.messages[-1] and "lens distortion" in s.messages[-1]
    assert s.undo_label == f"add a middle point to x segment {i} in p3"
    # Far from every x segment: a message, nothing added.
    far = np.add(e.image_to_window("p3", a + 0.4 * (b - a)), (MIDDLE_PICK_PX + 40) * normal)
    rev = s.revision
    d.send(*d.move_to(*far), "sleep", "0.05", "keydown", "ctrl", "click", "1", "keyup", "ctrl")
    assert s.revision == rev and f"no x segment passes within {MIDDLE_PICK_PX:g} px" in s.messages[-1]
    # Select (Esc), then drag the middle point 12 window px off the line: drawn there, as a red dot.
    start = e.image_to_window("p3", row[2:4])
    goal = np.add(start, 12.0 * normal)
    d.send("key", "Escape", *d.move_to(*start), "sleep", "0.05", "mousedown", "1", "sleep", "0.05",
           *d.move_to(*np.add(start, 6.0 * normal)), "sleep", "0.05", *d.move_to(*goal), "sleep", "0.05",
           "mouseup", "1")
    assert e.tool == "select"
    row = s.photo("p3")["vanishing_segments"]["x"][i]
    assert row[2:4] == pytest.approx(e.window_to_image(round(goal[0]), round(goal[1])), abs=1e-9)
    assert s.undo_label == f"move a middle point of x segment {i} in p3"
    x, y = e.image_to_window("p3", row[2:4])
    assert _colour_near(d.screen(), x, y, AXIS_COLOURS["x"])
    # The Delete tool removes the middle point, not the segment.
    d.send("key", "Delete", *d.move_to(x, y), "sleep", "0.05", "click", "1")
    assert s.photo("p3")["vanishing_segments"]["x"][i] == [*a, *b]
    assert f"deleted middle point 1 of x segment {i}" in s.messages[-1]


def test_a_known_length_typed_on_screen_scales_a_one_photo_calibration(one_photo, driver_factory):
    from vebuild.edit.overlay import AXIS_COLOURS

    path, truth = one_photo
    d = driver_factory(path)
    e, s = d.editor, d.session
    # The Known length tool: press on the corner's foot on the floor, drag up to its top, release.
    foot, top = (e.image_to_window("p3", uv) for uv in truth["corner"])
    d.send("key", "k", *d.move_to(*foot), "sleep", "0.05", "mousedown", "1", "sleep", "0.05",
           *d.move_to(foot[0], 0.5 * (foot[1] + top[1])), "sleep", "0.05", *d.move_to(*top), "sleep", "0.05",
           "mouseup", "1")
    assert e.tool == "length" and e.pending_length is not None
    assert "type its length in metres (σ optional) in the Scale tab" in s.messages[-1]
    assert "known_lengths" not in s.data  # not until its metres are typed
    d.click("tab:Scale")
    # Add length with nothing typed, then with a word: said on screen, nothing added.
    d.click("Add length")
    assert "the known length must be a number of metres (e.g. 2.03), not ''" in s.messages[-1]
    d.send(*d.at("length m"), "click", "1", "type", "--delay", "30", "tall")
    d.click("Add length")
    assert "the known length must be a number of metres (e.g. 2.03), not 'tall'" in s.messages[-1]
    d.send(*d.at("length m"), "click", "1", "key", "ctrl+a", "key", "minus", "type", "2")
    d.click("Add length")
    assert "must be a positive number of metres, not -2" in s.messages[-1]
    assert "known_lengths" not in s.data
    d.send(*d.at("length m"), "click", "1", "key", "ctrl+a", "type", "--delay", "30", f"{truth['corner_m']:g}")
    d.click("Add length")
    (kl,) = s.data["known_lengths"]
    assert (kl["photo"], kl["axis"], kl["length"], kl["sigma"], kl["floor_end"]) == ("p3", "z", truth["corner_m"],
                                                                                    0.002, 0)
    assert kl["ends"] == [pytest.approx(e.window_to_image(round(foot[0]), round(foot[1])), abs=1e-9),
                          pytest.approx(e.window_to_image(round(top[0]), round(top[1])), abs=1e-9)]
    assert e.pending_length is None and s.undo_label.startswith("known length 2.6 m along z")
    d.frames(2)
    assert any("L0: 2.6 m ± 2 mm along z" in m for m in [ln.label or "" for ln in e.overlay().lines])
    img = d.screen()
    assert _colour_near(img, foot[0], 0.5 * (foot[1] + top[1]), AXIS_COLOURS["z"])  # drawn, in the z colour
    # A camera height that is not a number is refused too.
    d.send(*d.at("height m"), "click", "1", "type", "--delay", "30", "high")
    d.click("Set height")
    assert "the camera height must be a number of metres (e.g. 2.03), not 'high'" in s.messages[-1]
    assert "camera_height" not in s.photo("p3")
    # Calibrate from the screen: the photo alone, its scale the known length; the result shown.
    d.click("tab:Calibration")
    d.click("Calibrate")
    assert e.calibration_error is None, e.calibration_error
    placed = e.calibration_result["cameras"]["p3"]["placement"]
    h = placed["camera_height_m"]
    assert placed["how"] == "alone" and "known length" in placed["scale"]
    assert abs(h["value"] - truth["C"][2]) < 3 * h["sigma"], (h, truth["C"])
    pos = e.calibration_result["cameras"]["p3"]["position"]  # each coordinate within 3σ of the truth
    assert np.all(np.abs(np.subtract(pos["value"], truth["C"])) < 3 * np.asarray(pos["sigma"])), (pos, truth["C"])
    d.frames(2)
    assert "calibrated:p3" in e.widget_rects  # the panel shows it
    assert f"camera {h['value']:.3f} ± {h['sigma']:.3f} m above the floor" in \
        next(m for m in reversed(s.messages) if m.startswith("calibrated p3"))
    assert s.undo_label == "calibrate"


def test_the_scale_tab_sets_a_camera_height_and_the_markers_on_the_floor_and_says_each(one_photo, driver_factory):
    path, truth = one_photo
    d = driver_factory(path)
    e, s = d.editor, d.session
    d.click("tab:Scale")
    # Add length before one is drawn says how to draw it; Set height before a height is typed says so.
    d.click("Add length")
    assert "draw the known length first: the Known length tool (K)" in s.messages[-1]
    d.click("Set height")
    assert "type the camera's height above the floor in metres first (e.g. 1.62)" in s.messages[-1]
    d.send(*d.at("height m"), "click", "1", "type", "--delay", "30", "1.45")
    d.send(*d.at("height sigma"), "click", "1", "type", "--delay", "30", "0.02")
    d.click("Set height")
    assert s.photo("p3")["camera_height"] == {"value": 1.45, "sigma": 0.02}
    assert s.messages[-1] == "camera height in p3: 1.45 ± 0.02 m above the floor"
    d.frames(2)
    d.click("Remove height")
    assert "camera_height" not in s.photo("p3") and s.undo_label == "remove the camera height of p3"
    # A drawn known length that Esc cancels, and one the Delete tool removes.
    foot, top = (e.image_to_window("p3", uv) for uv in truth["corner"])
    d.send("key", "k", *d.move_to(*foot), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *d.move_to(*top),
           "sleep", "0.05", "mouseup", "1", "key", "Escape")
    assert e.pending_length is None and s.messages[-1] == "known length cancelled"
    d.send("key", "k", *d.move_to(*foot), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *d.move_to(*top),
           "sleep", "0.05", "mouseup", "1")
    d.send(*d.at("length m"), "click", "1", "type", "--delay", "30", "2.6")
    d.click("Add length")
    assert s.messages[-1] == "known length L0: 2.6 m along z in p3" and len(s.data["known_lengths"]) == 1
    d.send("key", "Delete", *d.move_to(foot[0], 0.5 * (foot[1] + top[1])), "sleep", "0.05", "click", "1")
    assert "known_lengths" not in s.data and s.messages[-1] == "removed known length L0"
    # A second marker, ticked "on the floor" in the Calibration tab (the origin is on it already).
    x5 = e.image_to_window("p3", (153.8, 1107.9))
    d.send("key", "m", *d.move_to(*x5), "sleep", "0.05", "click", "1")
    name = next(iter(set(s.photo("p3")["marker_observations"]) - {"O"}))
    d.click("tab:Calibration")
    d.click(f"on floor:{name}")
    assert {"name": name, "on_floor": True} in s.data["markers"] and s.undo_label == f"{name} on the floor"
    d.click(f"on floor:{name}")
    assert {"name": name} in s.data["markers"]


def test_a_polyline_is_clicked_point_by_point_with_shift(one_photo, driver_factory):
    path, _ = one_photo
    d = driver_factory(path)
    e, s = d.editor, d.session
    n = len(s.photo("p3")["vanishing_segments"]["y"])
    pts = [(200, 300), (300, 306), (400, 310), (520, 312)]
    # A stroke from the first point to the second released with Shift, a Shift+click on the third,
    # a plain click on the last: one y polyline of four points.
    d.send("key", "2", *d.move_to(*pts[0]), "sleep", "0.05", "mousedown", "1", "sleep", "0.05",
           *d.move_to(*pts[1]), "sleep", "0.05", "keydown", "shift", "mouseup", "1", "keyup", "shift")
    assert e.open_polyline is not None and "y polyline: 2 points; Shift+click adds the next point" in s.messages[-1]
    assert len(s.photo("p3")["vanishing_segments"]["y"]) == n  # nothing added yet
    d.send(*d.move_to(*pts[2]), "sleep", "0.05", "keydown", "shift", "click", "1", "keyup", "shift")
    assert "y polyline: 3 points" in s.messages[-1]
    d.send(*d.move_to(*pts[3]), "sleep", "0.05", "click", "1")
    row = s.photo("p3")["vanishing_segments"]["y"][n]
    assert np.reshape(row, (-1, 2)) == pytest.approx(np.array([e.window_to_image(*p) for p in pts]), abs=1e-9)
    assert e.open_polyline is None and s.messages[-1] == f"y segment {n} in p3: a polyline of 4 points (2 middle)"
    s.undo()
    # Esc cancels one under way: nothing added.
    d.send(*d.move_to(*pts[0]), "sleep", "0.05", "keydown", "shift", "click", "1", "keyup", "shift")
    assert "y polyline: 1 point;" in s.messages[-1]
    d.send("key", "Escape")
    assert e.open_polyline is None and s.messages[-1] == "polyline cancelled"
    assert len(s.photo("p3")["vanishing_segments"]["y"]) == n and e.tool == "y"
