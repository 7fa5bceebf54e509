"""Measuring and marking by clicking on the photo in the modelling screen, driven for real (Xvfb,
xdotool): a clicked distance is `vebuild analyse distance` on the same points to the last digit
(and the command line's own pick of those pixels within the references' rounding), a height, an
evidence marker placed by clicking appears in `vebuild render`, a trajectory clicked is one of the
project's analyses once saved."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from edit_driver import Driver
from PIL import Image

from vebuild.actions.click_measure import ST_DECIMALS
from vebuild.analysis.markers import MARKER_COLOUR
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.project import load_project
from vebuild.project.decode import photo_camera
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")
#: Two face coordinates rounded to 10^-ST_DECIMALS m each move a point by at most √2/2 of that,
#: a distance between two such points by at most √2 times it.
ROUNDING_M = 2 ** 0.5 * 10.0 ** -ST_DECIMALS
#: The example room's table top is 0.76 m above the floor (ground_truth.json), solved to ~0.4 mm.
TABLE_HEIGHT_M, TABLE_TOL_M = 0.76, 0.01
TABLE_UV, FLOOR_UV = (800.0, 600.0), (400.0, 900.0)  # photo p1: the table's top, the floor


@pytest.fixture
def room(solved_room, tmp_path):
    shutil.copytree(solved_room.parent, tmp_path / "room")
    return tmp_path / "room" / solved_room.name


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


def _click(d, uv) -> tuple[float, float]:
    """Click the photo at (about) pixel uv; the photo pixel the click is at."""
    x, y = (int(round(c)) for c in d.editor.image_to_window(None, uv))
    d.send(*d.move_to(x, y), "click", "1")
    return d.editor.window_to_image(x, y)


def test_a_distance_clicked_on_the_photo_is_the_command_lines(room, drive, capsys):
    d = drive(room)
    e = d.editor
    assert e.photo == "p1"
    d.send("key", "t")
    assert e.tool == "measure" and e.measure_kind == "distance"
    uv_a = _click(d, TABLE_UV)
    assert len(e.measure_clicks) == 1
    uv_b = _click(d, FLOOR_UV)
    (m,) = e.measured
    a, b = m.command[1:]
    assert a.startswith("table.top@top:") and b.startswith("floor@")
    capsys.readouterr()
    assert main(["analyse", str(room), "distance", a, b]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()  # every digit, value and 1σ
    # The command line's own pick of the same pixels gives the same distance, but for the rounding.
    assert main(["analyse", str(room), "distance", f"photo:p1@{uv_a[0]:.2f},{uv_a[1]:.2f}",
                 f"photo:p1@{uv_b[0]:.2f},{uv_b[1]:.2f}", "--json", str(room.parent / "d.json")]) == 0
    picked = json.loads((room.parent / "d.json").read_text())["measurements"][0]
    mine = m.result.figures["measurements"][0]
    assert abs(picked["value_m"] - mine["value_m"]) <= ROUNDING_M
    assert picked["sigma_m"] == pytest.approx(mine["sigma_m"], rel=0.05)
    # An undoable edit of the session; saved with the project (Ctrl+S), where the report finds it.
    assert "analyses" not in json.loads(room.read_text())
    d.send("key", "ctrl+s")
    (rec,) = json.loads(room.read_text())["analyses"]
    assert rec == {"name": "clicked distance 1", "description": m.label, "command": ["distance", a, b]}
    # Drawn over the photo: the line between the two points in the measurement's colour.
    img = d.screen().astype(int)
    on = e.image_to_window(None, 0.75 * np.asarray(uv_a) + 0.25 * np.asarray(uv_b))  # clear of the label
    x, y = int(on[0]), int(on[1])
    patch = img[y - 3:y + 4, x - 3:x + 4].reshape(-1, 3)
    assert any(p[2] > 200 and p[1] > 170 and p[0] < 120 for p in patch)


def test_a_height_and_a_dimension_clicked_on_the_photo(room, drive, capsys):
    d = drive(room)
    e = d.editor
    d.send("key", "t", "key", "t")
    assert e.measure_kind == "height"
    _click(d, TABLE_UV)
    (m,) = e.measured
    h = m.result.figures["measurements"][0]
    assert abs(h["value_m"] - TABLE_HEIGHT_M) < TABLE_TOL_M and 0 < h["sigma_m"] < 0.005
    capsys.readouterr()
    assert main(["analyse", str(room), "height", m.command[1]]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()
    d.send("key", "t")
    _click(d, TABLE_UV)
    assert e.measured[-1].command == ["dimensions", "table.top"]
    d.send("key", "ctrl+z")  # one undoable edit each
    assert [r["name"] for r in e.session.data["analyses"]] == ["clicked height 1"]
    d.send("key", "u")  # the view cleared, the analyses kept
    assert e.measured == [] and len(e.session.data["analyses"]) == 1


def test_an_evidence_marker_clicked_on_the_photo_appears_in_a_render(room, drive, tmp_path):
    d = drive(room)
    e = d.editor
    d.send("key", "x")
    assert e.tool == "evidence"
    _click(d, FLOOR_UV)
    (rec,) = e.session.data["evidence_markers"]
    assert rec["label"] == "E1" and rec["node"] == "floor" and abs(rec["position"][2]) < 1e-6
    d.send("key", "ctrl+s")
    out = tmp_path / "view.png"
    assert main(["render", str(room), "--photo", "p1", "--out", str(out), "--size", "800x600", "--samples", "1"]) == 0
    img = np.asarray(Image.open(out).convert("RGB")).astype(int)
    cam = photo_camera(load_project(room), "p1").resized(800, 600)
    u, v = project_points(cam.K, cam.R, cam.C, np.asarray(rec["position"]), cam.lens)
    patch = img[int(v) - 2:int(v) + 3, int(u) - 2:int(u) + 3].reshape(-1, 3)
    assert any(np.abs(p - MARKER_COLOUR).max() < 40 for p in patch)
    # A click on the marker removes it.
    _click(d, FLOOR_UV)
    assert e.session.data["evidence_markers"] == []


def test_a_trajectory_clicked_on_the_photo_is_an_analysis(room, drive):
    d = drive(room)
    e = d.editor
    d.send("key", "j")
    _click(d, TABLE_UV)
    _click(d, FLOOR_UV)
    d.send("key", "ctrl+s")
    (rec,) = json.loads(room.read_text())["analyses"]
    assert rec["name"] == "clicked trajectory 1" and rec["command"][:2] == ["trajectory", "--from"]
    assert "--sigma" in rec["command"]
    (m,) = e.measured
    assert m.result.figures["trajectory"]["cone_half_angle_95_deg"] > 0
    img = d.screen().astype(int)
    mid = e.image_to_window(None, 0.5 * (np.asarray(TABLE_UV) + np.asarray(FLOOR_UV)))
    x, y = int(mid[0]), int(mid[1])
    patch = img[y - 3:y + 4, x - 3:x + 4].reshape(-1, 3)
    assert any(p[0] > 180 and p[2] < 80 for p in patch)  # the path's red, the cone's orange


def test_measuring_an_unsolved_project_says_so(tmp_path, drive):
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    d = drive(folder / "room.vebuild.json")
    d.send("key", "t")
    _click(d, TABLE_UV)
    # Neither calibrated (to measure on the photo alone) nor solved: it says what each needs.
    assert d.editor.measured == [] and any("measuring needs this photo calibrated (Calibrate, in the Calibration "
                                           "tab), to measure on the photo alone, or a solved model" in m
                                           for m in d.editor.messages)
