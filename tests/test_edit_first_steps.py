"""First steps in the modelling screen: the guided sequence of a new project (each step ticked by
itself from the session's state), the help overlay made from the key table (F1 or ?), the file
browser inside the window (Ctrl+O) and files dropped onto it, tooltips on the buttons and labels on
the fields.

The window tests run under a virtual X server and drive the screen by real input (xdotool), as
tests/test_edit_window.py does; widgets are found by ``Editor.widget_rects``. xdotool has no drag
source, so files are dropped by X's drag and drop protocol from tests/xdnd_source.py, as a file
manager drops them; another test calls the C function registered with glfwSetDropCallback with a
count and an array of paths, as GLFW does on a drop, with a file that is no photo among them.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil

import glfw
import numpy as np
import pytest
from edit_driver import Driver
from edit_scene import PHOTOS, make_plan, photo_file
from imgui_bundle import imgui

from vebuild.edit import guide as guide_mod
from vebuild.edit.browser import FileBrowser, add_files
from vebuild.edit.guide import STEP_KEYS, STEPS, Guide, is_new
from vebuild.edit.keys import EDITOR_KEYS
from vebuild.edit.session import EditSession
from vebuild.resources import example_project_dir

#: The marks of photo p1 used by the guided run: its first segments per axis, two markers and the
#: distance between them (the example's: O to Y4 is 4 m along y).
MARKERS = ("O", "Y4")
DISTANCE = ("O", "Y4", 4.0)


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


# -- the guide's logic, headless ------------------------------------------------------------------------

def test_each_step_is_done_by_the_sessions_state_alone(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    g = Guide(shown=is_new(s))
    assert g.shown
    assert g.current(s, None).key == "photo"
    s.add_photo(photo_file(plan, "p1"))
    assert g.current(s, "p1").key == "axes"
    g.skip("axes")
    expect = iter(["x", "y", "z"])
    for axis in ("x", "y", "z"):
        assert g.current(s, "p1").key == next(expect)
        for n, seg in enumerate(plan.segments["p1"][axis][:guide_mod.SEGMENTS_PER_AXIS]):
            assert g.current(s, "p1").key == axis, (axis, n)  # one segment is not enough
            s.add_segment("p1", axis, seg[:2], seg[2:])
    # A project of one photo needs no marker (its origin is the floor below the camera): the scale
    # comes next; the markers placed here serve the distance.
    assert g.current(s, "p1").key == "distance"
    s.place_marker("p1", "O", plan.markers["p1"]["O"])
    s.place_marker("p1", "Y4", plan.markers["p1"]["Y4"])
    assert g.current(s, "p1").key == "distance"
    s.add_distance(*DISTANCE)
    assert g.current(s, "p1").key == "calibrate"
    s.calibrate()
    assert g.current(s, "p1").key == "floor"
    s.add_primitive("quad", name="floor")
    assert g.current(s, "p1").key == "object"
    s.add_primitive("box", name="box", parent="floor")
    assert g.current(s, "p1") is None and all(g.done(s, "p1"))
    # An undo takes a step back; another photo has its own marks.
    s.undo()
    assert g.current(s, "p1").key == "object"
    s.add_photo(photo_file(plan, "p3"))
    assert g.current(s, "p3").key == "x"
    # With two photos, markers tie them: the step is p3's to do, and p1's (it has its two) done.
    markers_done = dict(zip(STEP_KEYS, g.done(s, "p3"), strict=True))["markers"]
    assert not markers_done and dict(zip(STEP_KEYS, g.done(s, "p1"), strict=True))["markers"]
    # A project with marks or a model is not new: the guide is not shown by itself.
    assert not is_new(s)
    assert [st.key for st in STEPS] == ["photo", "axes", "x", "y", "z", "markers", "distance", "calibrate",
                                        "floor", "object"]


def test_the_guides_state_is_not_saved_in_the_project(tmp_path):
    plan = make_plan(tmp_path / "room")
    before = plan.project.read_text()
    s = EditSession.open(plan.project)
    g = Guide(shown=True)
    g.skip("axes")
    s.add_photo(photo_file(plan, "p1"))
    s.save()
    text = plan.project.read_text()
    assert text != before and "axes" not in text and "guide" not in text and "first" not in text


# -- the browser's logic, headless ------------------------------------------------------------------------

def test_the_browser_lists_folders_and_the_photos_vebuild_reads(tmp_path):
    plan = make_plan(tmp_path / "room")
    f = plan.folder
    (f / "photos" / "notes.txt").write_text("not a photo")
    (f / "photos" / ".hidden.jpg").write_bytes(b"x")
    (f / "photos" / "scene.NEF").write_bytes(b"raw")
    (f / "photos" / "more").mkdir()
    (f / ".cache").mkdir()
    b = FileBrowser(f)
    dirs, files = b.listing()
    assert "photos" in dirs and ".cache" not in dirs and files == []
    assert b.enter("photos")
    dirs, files = b.listing()
    assert dirs == ["more"] and files == ["p1.jpg", "p3.jpg", "p4.jpg", "p5.jpg", "scene.NEF"]
    b.toggle("p3.jpg")
    b.toggle("p1.jpg")
    b.toggle("notes.txt")  # not offered: not picked
    assert b.chosen() == [f / "photos" / "p1.jpg", f / "photos" / "p3.jpg"]
    b.toggle("p3.jpg")
    assert b.chosen() == [f / "photos" / "p1.jpg"]
    assert not b.go("no such folder") and "is not a folder" in b.error and b.folder == f / "photos"
    assert b.up() and b.folder == f and b.picked == set()
    # A photo the project has already is marked, and not picked.
    b2 = FileBrowser(f / "photos", have={f / "photos" / "p1.jpg"})
    b2.pick_all()
    assert b2.in_project("p1.jpg") and "p1.jpg" not in b2.picked and "p3.jpg" in b2.picked


def test_files_that_cannot_be_added_are_named_with_why_and_left_unchanged(tmp_path):
    plan = make_plan(tmp_path / "room")
    s = EditSession.open(plan.project)
    f = plan.folder
    (f / "notes.txt").write_text("not a photo")
    (f / "broken.jpg").write_bytes(b"not an image")
    outside = tmp_path / "elsewhere.jpg"
    shutil.copy(photo_file(plan, "p1"), outside)
    good = photo_file(plan, "p3")
    sha, mtime = _sha(good), good.stat().st_mtime_ns
    added, problems = add_files(s, [f / "notes.txt", f / "broken.jpg", outside, f / "missing.jpg", good])
    assert added == ["p3"] and s.photo_ids == ["p3"]
    assert len(problems) == 4
    assert "notes.txt: not a photo vebuild reads" in problems[0] and ".jpg" in problems[0]
    assert problems[1].startswith("broken.jpg:") and "broken.jpg" in problems[1]
    assert problems[2].startswith("elsewhere.jpg:") and "outside the project folder" in problems[2]
    assert "missing.jpg: no such file" in problems[3]
    assert _sha(good) == sha and good.stat().st_mtime_ns == mtime  # the user's file is never changed
    assert s.photo("p3")["sha256"] == sha
    # A folder adds the photos directly in it.
    added, problems = add_files(s, [f / "photos"])
    assert added == ["p1", "p4", "p5"] and problems == ["p3.jpg: the project has it already, as photo 'p3'"]


# -- the window ---------------------------------------------------------------------------------------------

@pytest.fixture
def driver_factory(xdotool, xvfb_display):
    made = []

    def make(project_file, **kw):
        d = Driver(project_file, xdotool, **kw)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def _now(d):
    step = d.editor.guide.current(d.session, d.editor.photo)
    return None if step is None else step.key


def _strokes(d, segs):
    e = d.editor
    events = []
    for u1, v1, u2, v2 in segs:
        a, b = np.array([u1, v1]), np.array([u2, v2])
        events += [*d.move_to(*e.image_to_window(None, a)), "mousedown", "1"]
        for t in (0.5, 1.0):
            events += d.move_to(*e.image_to_window(None, a + t * (b - a)))
        events += ["mouseup", "1"]
    d.send(*events)


def _type_into(d, label, text):
    d.send(*d.at(label), "click", "1", "key", "ctrl+a", "type", "--delay", "20", text)
    d.send("key", "Return")


def test_the_guided_steps_advance_as_the_user_completes_them(tmp_path, driver_factory):
    plan = make_plan(tmp_path / "room")
    d = driver_factory(plan.project)
    e, s = d.editor, d.session
    assert e.open_guide_if_new()  # as `vebuild edit` does for a new project
    d.frames(2)
    assert e.guide.shown and "guide" in e.widget_rects and _now(d) == "photo"
    # Photos through the browser: Ctrl+O, into photos/, pick p1 by a click, Add.
    d.send("key", "ctrl+o")
    assert e.browser is not None and e.browser.folder == plan.folder
    d.click("browser:photos/")
    assert e.browser.folder == plan.folder / "photos"
    d.click("browser:p1.jpg")
    assert e.browser.picked == {"p1.jpg"}
    d.click("browser add")
    assert s.photo_ids == ["p1"] and e.photo == "p1" and e.browser is None
    assert _now(d) == "axes" and "gizmo" in e.widget_rects  # the axes drawn in the card
    d.click("Next##guide")
    assert _now(d) == "x"
    # A click on the card is the card's: no segment is drawn under it.
    d.send("key", "1")
    x0, y0, x1, y1 = e.widget_rects["guide step:photo"]  # a line of the card's list
    ym = (y0 + y1) / 2
    d.send(*d.move_to(x0 + 2, ym), "mousedown", "1", *d.move_to(x0 + 60, ym), "mouseup", "1")
    assert not (s.photo("p1").get("vanishing_segments") or {}).get("x")
    # The lines: each step is done at its second segment, and the next one begins.
    for key, axis, after in (("1", "x", "y"), ("2", "y", "z"), ("3", "z", "distance")):  # one photo: no marker
        d.send("key", key)
        first, second, *rest = plan.segments["p1"][axis]
        _strokes(d, [first])
        assert _now(d) == axis and len(s.photo("p1")["vanishing_segments"][axis]) == 1
        _strokes(d, [second])
        assert _now(d) == after, axis
        _strokes(d, rest)
    # Markers by clicks; the Calibration tab comes forward for the distance.
    for name in MARKERS:
        _type_into(d, "marker name", name)
        d.send("key", "m", *d.move_to(*e.image_to_window(None, plan.markers["p1"][name])), "click", "1")
        assert name in s.photo("p1")["marker_observations"]
    assert _now(d) == "distance"
    d.send("key", "Escape")
    a, b, metres = DISTANCE
    _type_into(d, "distance a", a)
    _type_into(d, "distance b", b)
    _type_into(d, "distance m", f"{metres}")
    d.click("add##distance")
    assert _now(d) == "calibrate"
    d.click("Calibrate##guide")
    d.frames(3)
    assert e.calibration_error is None and "p1" in s.cameras and _now(d) == "floor"
    # The floor and a first object from the card's buttons and a click in the photo each.
    d.click("A floor quad##guide")  # the example's p1 sees no floor corner to click: a quad
    d.send(*d.move_to(*e.image_to_window(None, plan.markers["p1"]["O"])), "click", "1")
    assert s.model.node("floor").primitive.TYPE == "quad" and _now(d) == "object"
    d.click("Add a box##guide")
    d.send(*d.move_to(*e.image_to_window(None, (800, 800))), "click", "1")
    boxes = [n for n in s.model.nodes if n.name != "floor"]
    assert [(n.primitive.TYPE, n.parent) for n in boxes] == [("box", "floor")]
    assert _now(d) is None and "guide now" not in e.widget_rects
    # Hidden with Tab (and its button), shown again with Tab; never saved.
    d.send("key", "Tab")
    assert not e.guide.shown and "guide" not in e.widget_rects
    d.send("key", "Tab")
    assert e.guide.shown and "guide" in e.widget_rects
    d.click("Hide##guide")
    assert not e.guide.shown
    d.send("key", "ctrl+s")
    assert "guide" not in plan.project.read_text()


def test_an_opened_project_with_marks_shows_no_guide_until_asked(driver_factory, tmp_path):
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    d = driver_factory(folder / "room.vebuild.json")
    e = d.editor
    assert not e.open_guide_if_new()
    d.frames(2)
    assert not e.guide.shown and "guide" not in e.widget_rects
    d.send("key", "F1")
    d.click("First steps")
    assert e.guide.shown and not e.help_open and "guide" in e.widget_rects


def test_vebuild_edit_opens_a_new_project_with_the_guide_shown(tmp_path, xvfb_display, monkeypatch):
    from vebuild.edit.first_steps import FirstSteps
    from vebuild.edit.screen import run_editor

    shown = []
    real = FirstSteps.open_guide_if_new
    monkeypatch.setattr(FirstSteps, "open_guide_if_new", lambda self: shown.append(real(self)) or shown[-1])
    plan = make_plan(tmp_path / "room")
    run_editor(plan.project, (900, 600), frames=2)
    folder = tmp_path / "example"
    shutil.copytree(example_project_dir(), folder)
    run_editor(folder / "room.vebuild.json", (900, 600), frames=2)
    assert shown == [True, False]


def test_the_help_overlay_lists_every_entry_of_the_key_table(tmp_path, driver_factory):
    plan = make_plan(tmp_path / "room")
    d = driver_factory(plan.project)
    e = d.editor
    rows = [k for k, _ in EDITOR_KEYS.rows()]
    d.send("key", "F1")
    assert e.help_open and e.help_listed == rows
    # Each row is drawn on screen: scrolled into view by the wheel, its rectangle appears.
    x0, y0, x1, y1 = e.widget_rects["help"]
    seen = {k for k in rows if f"help:{k}" in e.widget_rects}
    for _ in range(40):
        if seen == set(rows):
            break
        d.send(*d.move_to((x0 + x1) / 2, (y0 + y1) / 2), "click", "5")
        seen |= {k for k in rows if f"help:{k}" in e.widget_rects}
    assert seen == set(rows)
    # Keys do nothing else while it is open: 1 does not pick a tool; Esc closes it.
    d.send("key", "1")
    assert e.tool == "select" and e.help_open
    d.send("key", "Escape")
    assert not e.help_open and "help" not in e.widget_rects
    d.send("key", "question")
    assert e.help_open
    d.send("key", "question")
    assert not e.help_open
    d.send("key", "F1")
    assert e.help_open
    d.send("key", "F1")
    assert not e.help_open
    d.click("Help")  # the toolbar's button
    assert e.help_open


def test_a_photo_is_added_through_the_browser_and_bad_files_are_named(tmp_path, driver_factory):
    plan = make_plan(tmp_path / "room")
    (plan.folder / "photos" / "broken.jpg").write_bytes(b"not an image")
    d = driver_factory(plan.project)
    e, s = d.editor, d.session
    d.click("Photos…")  # the toolbar's button
    assert e.browser is not None
    d.click("browser:photos/")
    d.click("browser:broken.jpg")
    d.click("browser:p4.jpg")
    d.click("browser:p5.jpg")
    d.click("browser:p5.jpg")  # a second click unpicks it
    assert e.browser.picked == {"broken.jpg", "p4.jpg"}
    d.click("browser add")
    assert s.photo_ids == ["p4"] and e.photo == "p4"
    # The bad file is named in the browser, which stays open, and in the messages.
    assert e.browser is not None and "broken.jpg" in e.browser.error
    assert any("broken.jpg" in m for m in s.messages)
    assert "p4.jpg" in e.browser.listing()[1] and e.browser.in_project("p4.jpg")
    d.send("key", "Escape")
    assert e.browser is None
    # The folder typed into its field; Up.
    d.send("key", "ctrl+o")
    assert e.browser.folder == plan.folder / "photos"  # the shown photo's folder
    d.click("Up")
    assert e.browser.folder == plan.folder
    _type_into(d, "browser folder", "photos")  # relative to the folder shown
    assert e.browser.folder == plan.folder / "photos"
    d.click("Pick all##browser")
    assert e.browser.picked == {"broken.jpg", "p1.jpg", "p3.jpg", "p5.jpg"}
    d.click("Cancel##browser")
    assert e.browser is None and s.photo_ids == ["p4"]


def test_files_dropped_onto_the_window_are_added(tmp_path, driver_factory):
    plan = make_plan(tmp_path / "room")
    (plan.folder / "notes.txt").write_text("not a photo")
    d = driver_factory(plan.project)
    e, s = d.editor, d.session
    handle = d.window.handle
    addr = ctypes.cast(ctypes.pointer(handle), ctypes.POINTER(ctypes.c_long)).contents.value
    _, c_callback = glfw._window_drop_callback_repository[addr]  # what glfwSetDropCallback was given
    files = [photo_file(plan, "p3"), photo_file(plan, "p5"), plan.folder / "notes.txt"]
    paths = (ctypes.c_char_p * len(files))(*(os.fsencode(p) for p in files))
    c_callback(handle, len(files), paths)
    d.frames(2)
    assert s.photo_ids == ["p3", "p5"] and e.photo == "p3"
    assert any("notes.txt: not a photo vebuild reads" in m for m in s.messages)
    assert all(len(s.photo(p)["sha256"]) == 64 for p in ("p3", "p5"))


def test_files_dropped_by_x_drag_and_drop_are_added(tmp_path, driver_factory):
    """A real drop over the X server, as a file manager makes it (tests/xdnd_source.py)."""
    from xdnd_source import drop_files

    plan = make_plan(tmp_path / "room")
    d = driver_factory(plan.project)
    e, s = d.editor, d.session
    x0, y0, x1, y1 = e.view_rect()
    files = [photo_file(plan, "p4"), photo_file(plan, "p1")]
    answer = drop_files(int(d.wid), (int((x0 + x1) / 2), int((y0 + y1) / 2)), files, lambda: d.frames(1))
    d.frames(2)
    assert answer == {"accepted": True, "finished": True}
    assert s.photo_ids == ["p4", "p1"] and e.photo == "p4"


def test_every_button_has_a_tooltip_and_every_field_a_label(driver_factory, tmp_path, monkeypatch):
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    d = driver_factory(folder / "room.vebuild.json")
    e = d.editor
    untipped, unlabelled, drawn = [], [], []
    button = e.button

    def tipped(label, size=None, tip=None):
        drawn.append(label)
        if not tip:
            untipped.append(label)
        return button(label, size, tip)
    monkeypatch.setattr(e, "button", tipped)
    for name in ("input_text", "input_float", "input_int", "input_float2", "input_float3", "combo", "checkbox"):
        real = getattr(imgui, name)

        def field(label, *args, _real=real, **kw):
            if not label.split("##")[0].strip():
                unlabelled.append(label)
            return _real(label, *args, **kw)
        monkeypatch.setattr(imgui, name, field)
    d.send("key", "Tab")  # the guide's card too
    e.select("cabinet")
    for tab in ("Calibration", "Scale", "Model"):
        d.click(f"tab:{tab}")
        d.frames(2)
    d.send("key", "ctrl+o")
    d.frames(2)
    d.send("key", "Escape")
    assert {"Calibrate", "Solve", "Add", "Browse…##strip", "Photos…", "Hide##guide", "Up"} <= set(drawn)
    assert sorted(set(untipped)) == [] and sorted(set(unlabelled)) == []
    assert PHOTOS  # the plan's photos are those the browser offers
