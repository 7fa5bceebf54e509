"""Single-view measuring on the modelling screen, driven for real (Xvfb, xdotool): one generated
photo of the example room (scenes/room p3, its truth in ground_truth.json), from a project holding
the photo and nothing else to a saved height by clicks and keys alone; the saved words re-run on the
command line print the same table, and the height lies within its 95 % interval of the truth."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
from edit_driver import Driver

from vebuild.actions import click_single_view as sv
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")
TRUTH = json.loads((example_project_dir() / "ground_truth.json").read_text())
PHOTO = "p3"
#: The door's hinge edge (its top 2.045 m above the floor: the door 2.035 m tall over a 1 cm gap),
#: the known length a user reads off the door's specification.
DOOR_FOOT, DOOR_M = np.array([4.2, 0.0, 0.0]), 2.045
#: 1σ of a user's click on the photo (pixels): the noise added to each true pixel clicked.
CLICK_NOISE_PX = 0.7


def _camera():
    t = TRUTH["photos"][PHOTO]
    return tuple(np.asarray(t[k], float) for k in ("K", "R", "C"))


def _box_edge() -> tuple[np.ndarray, np.ndarray]:
    """The box's vertical edge nearest the camera (always in sight): its foot and its top (truth)."""
    box = next(o for o in TRUTH["objects"] if o["name"] == "box")
    c, (sx, sy, sz), a = np.asarray(box["centre"], float), box["size"], np.radians(box["yaw_deg"])
    R2 = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    feet = [np.r_[c[:2] + R2 @ [i * sx / 2, j * sy / 2], 0.0] for i in (-1, 1) for j in (-1, 1)]
    C = _camera()[2]
    foot = min(feet, key=lambda X: float(np.linalg.norm(X - C)))
    return foot, foot + [0.0, 0.0, sz]


@pytest.fixture
def one_photo(tmp_path) -> Path:
    """A project of the photo alone, as `vebuild new` makes it: no marks, no calibration, no model."""
    src = example_project_dir() / "photos" / f"{PHOTO}.jpg"
    (tmp_path / "photos").mkdir()
    shutil.copy(src, tmp_path / "photos" / src.name)
    path = tmp_path / "one.vebuild.json"
    assert main(["new", str(path), str(tmp_path / "photos" / src.name)]) == 0
    return path


@pytest.fixture
def drive(xdotool):
    made = []

    def make(project_file):
        d = Driver(project_file, xdotool)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def _at(d, X, rng) -> tuple[int, int]:
    """The window pixel a user clicks on world point X (its true image, with a click's noise)."""
    uv = project_points(*_camera(), np.asarray(X, float)) + rng.normal(0.0, CLICK_NOISE_PX, 2)
    x, y = d.editor.image_to_window(None, uv)
    return int(round(x)), int(round(y))


def test_a_height_measured_on_one_photo_by_clicks_and_keys_alone(one_photo, drive, capsys):
    """From `vebuild new`'s project to a saved height: 5 keys (D, Enter, K, T, Ctrl+S), 5 typed
    characters (the door's 2.045), 1 drag (the door's hinge edge, foot to top) and 7 clicks (the
    Scale tab, the metres field, Add length, the Calibration tab, Calibrate, the box's foot and
    top): 18 inputs in all."""
    rng = np.random.default_rng(4620)
    d = drive(one_photo)
    e, s = d.editor, d.session
    assert e.photo == PHOTO and not s.data["photos"][0].get("vanishing_segments")
    d.send("key", "d")  # line proposals
    assert sum(p.kind == "segment" for p in s.proposals[PHOTO]) >= 9
    d.send("key", "Return")  # all accepted
    assert not s.proposals.get(PHOTO) and all(len(v) >= 3 for v in s.photo(PHOTO)["vanishing_segments"].values())
    # The door's height, by the Known length tool: press on the hinge edge's foot, drag to its top.
    foot, top = _at(d, DOOR_FOOT, rng), _at(d, DOOR_FOOT + [0, 0, DOOR_M], rng)
    d.send("key", "k", *d.move_to(*foot), "sleep", "0.05", "mousedown", "1", "sleep", "0.05",
           *d.move_to(foot[0], (foot[1] + top[1]) // 2), "sleep", "0.05", *d.move_to(*top), "sleep", "0.05",
           "mouseup", "1")
    assert e.pending_length is not None
    d.click("tab:Scale")
    d.send(*d.at("length m"), "click", "1", "type", "--delay", "30", f"{DOOR_M:g}")
    d.click("Add length")
    assert [k["length"] for k in s.data["known_lengths"]] == [DOOR_M]
    d.click("tab:Calibration")
    d.click("Calibrate")
    assert e.calibration_error is None and PHOTO in s.cameras, e.calibration_error
    # T: a height on the photo alone; the message line names each point to click.
    d.send("key", "t")
    assert e.tool == "measure" and e.single_view_kind == "photo-height"
    assert "click its foot on the floor" in e.messages[-1]
    assert [t for t, _ in e.shown_messages()][0] == ("measure on the photo alone: height: click its foot on the floor "
                                                     "(point 1 of 2); T: the next measurement, Esc: stop")
    box_foot, box_top = _box_edge()
    d.send(*d.move_to(*_at(d, box_foot, rng)), "click", "1")
    assert len(e.single_view_clicks) == 1 and "click its top" in e.messages[-1]
    assert "height: click its top (point 2 of 2)" in e.shown_messages()[0][0]
    d.send(*d.move_to(*_at(d, box_top, rng)), "click", "1")
    (m,) = e.measured
    assert m.label.startswith("height ") and "95 % between" in m.label and f"'{m.name}'" in e.messages[-2]
    assert "height: click its foot on the floor (point 1 of 2)" in e.shown_messages()[0][0]  # the next one
    assert "analyses" not in json.loads(one_photo.read_text())
    d.send("key", "ctrl+s")
    (rec,) = json.loads(one_photo.read_text())["analyses"]
    assert rec == {"name": "clicked photo-height 1", "description": m.label, "command": m.command}
    assert rec["command"][:3] == ["photo-height", "--photo", PHOTO] and len(rec["command"]) == 7
    # The saved words, run on the command line, print the table the screen's figure came from.
    capsys.readouterr()
    out = one_photo.parent / "height.json"
    assert main(["analyse", str(one_photo), *rec["command"]]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()  # every digit, value, 1σ and interval
    assert main(["analyse", str(one_photo), *rec["command"], "--json", str(out)]) == 0
    (h,) = json.loads(out.read_text())["measurements"]
    assert h["value_m"] == m.result.figures["measurements"][0]["value_m"]
    # Within its 95 % interval of the generated truth, the box's height; the interval not absurd.
    true_h = float(box_top[2])
    lo, hi = h["ci95_m"]
    assert lo <= true_h <= hi, (h, true_h)
    assert 0 < h["sigma_m"] < 0.05 * true_h
    # A while later the messages are gone; the next point to click stays said.
    later = time.monotonic() + 60
    e.message_clock = lambda: later
    d.frames(2)
    assert [t for t, _ in e.shown_messages()] == [("measure on the photo alone: height: click its foot on the floor "
                                                   "(point 1 of 2); T: the next measurement, Esc: stop")]
    # Drawn on the photo: the line from foot to top in the measurement's colour (where no message is).
    img = d.screen().astype(int)
    a, b = (np.asarray(e.image_to_window(None, p)) for p in m.pixels)
    mx0, my0, mx1, my1 = e._rects["messages"]
    clear = [p for p in (b + t * (a - b) for t in np.linspace(0.05, 0.95, 19))
             if not (mx0 - 4 <= p[0] <= mx1 + 4 and my0 - 4 <= p[1] <= my1 + 4)]
    assert clear, "the whole line lies under the messages"
    x, y = (int(c) for c in clear[0])
    patch = img[y - 3:y + 4, x - 3:x + 4].reshape(-1, 3)
    assert any(p[2] > 200 and p[1] > 170 and p[0] < 120 for p in patch)
    # One undoable edit: Ctrl+Z takes it out of the analyses and off the photo.
    d.send("key", "ctrl+z")
    assert not s.data.get("analyses") and e.measured == []


def test_t_cycles_the_single_view_measurements_and_a_floor_distance_is_the_command_lines(one_photo, drive,
                                                                                          capsys):
    rng = np.random.default_rng(4621)
    d = drive(one_photo)
    e, s = d.editor, d.session
    # Before calibration the Measure tool says what it needs.
    d.send("key", "t")
    assert "measuring needs this photo calibrated" in e.messages[-1]
    # Calibrated headlessly (the first test drives it by the screen); the scale from the door.
    s.detect_lines(PHOTO)
    s.accept_all(PHOTO)
    ends = [project_points(*_camera(), DOOR_FOOT + [0, 0, z]) for z in (0.0, DOOR_M)]
    s.add_known_length(PHOTO, "z", ends, DOOR_M)
    s.calibrate()
    d.send("key", "Escape", "key", "t")
    assert e.single_view_kind == "photo-height"
    seen = [e.single_view_kind]
    for _ in sv.kinds()[1:]:
        d.send("key", "t")
        seen.append(e.single_view_kind)
    assert seen == list(sv.kinds()) and seen[:2] == ["photo-height", "floor-distance"]
    d.send("key", "t")  # round again
    assert e.single_view_kind == "photo-height"
    d.send("key", "t")
    assert e.single_view_kind == "floor-distance" and "the first point on the floor" in e.messages[-1]
    # Two floor points: the box's near foot and the door's hinge foot.
    box_foot, _ = _box_edge()
    for X in (box_foot, DOOR_FOOT):
        d.send(*d.move_to(*_at(d, X, rng)), "click", "1")
    (m,) = e.measured
    assert m.command[0] == "floor-distance" and m.label.startswith("floor distance ")
    d.send("key", "ctrl+s")
    capsys.readouterr()
    out = one_photo.parent / "distance.json"
    assert main(["analyse", str(one_photo), *m.command]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()
    assert main(["analyse", str(one_photo), *m.command, "--json", str(out)]) == 0
    (f,) = json.loads(out.read_text())["measurements"]
    true_d = float(np.linalg.norm(box_foot - DOOR_FOOT))
    assert f["ci95_m"][0] <= true_d <= f["ci95_m"][1], (f, true_d)
    # Two points on the ceiling, above the horizon: said in words, nothing measured, begun again.
    for uv in ((800.0, 40.0), (900.0, 60.0)):
        x, y = (int(round(c)) for c in e.image_to_window(None, uv))
        d.send(*d.move_to(x, y), "click", "1")
    assert "lies on or above the horizon" in e.messages[-1]
    assert e.messages[-1].endswith("begin again: floor distance: click the first point on the floor (point 1 of 2)")
    assert len(e.measured) == 1 and e.single_view_clicks == []
    # A click beside the photo (the view zoomed out by the wheel) is not counted.
    x0, y0, x1, y1 = e.view_rect()
    d.send(*d.move_to(0.5 * (x0 + x1), 0.5 * (y0 + y1)), "click", "5", "click", "5")
    left, _ = e.image_to_window(None, (0.0, 600.0))
    assert left - x0 > 10, "the photo fills the view's width: no margin to click"
    d.send(*d.move_to(int(x0 + 0.5 * (left - x0)), int(0.5 * (y0 + y1))), "click", "1")
    assert "lies outside the 1600×1200 photo: click on the photo" in e.messages[-1] and e.single_view_clicks == []
