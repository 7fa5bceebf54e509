"""Measuring and marking by clicking in the walk-through, driven for real (Xvfb, xdotool): a
clicked distance is `vebuild analyse distance` on the same points to the last digit, a height, a
marker placed by clicking appears in `vebuild render`, a trajectory saved by clicking is one of
the project's analyses."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from xinput import XInput

from vebuild.analysis.markers import MARKER_COLOUR
from vebuild.analysis.recorded import run_recorded
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.gl.window import Window
from vebuild.project import load_project
from vebuild.project.decode import find_view
from vebuild.render.renderer import RenderOptions
from vebuild.viewer.app import Viewer

pytestmark = pytest.mark.usefixtures("xvfb_display")
TITLE = "vebuild viewer measure test"
W, H = 640, 360
ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
#: The example room's table top is 0.76 m above the floor (ground_truth.json); the solve's 1σ is
#: about 0.4 mm, the tape's rounding 5 mm: a clicked height within 1 cm is the table's.
TABLE_HEIGHT_M, TABLE_TOL_M = 0.76, 0.01


@pytest.fixture(scope="module")
def solved_room(tmp_path_factory):
    """The example room calibrated and solved (no textures: the viewer draws it untextured)."""
    folder = tmp_path_factory.mktemp("measure") / "room"
    shutil.copytree(ROOM, folder)
    proj = folder / "room.vebuild.json"
    assert main(["calibrate", str(proj), "--quiet"]) == 0
    assert main(["solve", str(proj)]) == 0
    return proj


@pytest.fixture
def room(solved_room, tmp_path):
    folder = tmp_path / "room"
    shutil.copytree(solved_room.parent, folder)
    return folder / solved_room.name


class Driver:
    def __init__(self, project_file: Path, xdotool: str, view: str):
        self.window = Window(W, H, TITLE, visible=True)
        self.viewer = Viewer(load_project(project_file), self.window, RenderOptions.interactive(), view=view)
        self.viewer.enable_gui()
        self.xdotool = xdotool
        self.frames(3)
        self.wid = subprocess.run([xdotool, "search", "--name", TITLE], capture_output=True,
                                  text=True).stdout.split()[-1]
        subprocess.run([xdotool, "windowfocus", "--sync", self.wid], check=True)
        self.input = XInput(xdotool, self.window.handle, self.viewer.frame)
        self.send("key", "F1")  # the panel off: it covers none of the scene

    def frames(self, n: int) -> None:
        for _ in range(n):
            self.viewer.frame()

    def send(self, *args: str) -> None:
        self.input.send(*args)
        self.frames(4)

    def click_at(self, X) -> None:
        cam = self.viewer.camera()
        u, v = project_points(cam.K, cam.R, cam.C, np.asarray(X, float))
        assert 0 < u < W and 0 < v < H
        self.send("mousemove", "--window", self.wid, str(int(u)), str(int(v)), "click", "1")

    def screen(self) -> np.ndarray:
        self.viewer.draw()
        data = self.window.ctx.screen.read(viewport=(0, 0, W, H), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(H, W, 3)[::-1]

    def close(self) -> None:
        self.viewer.close()
        self.window.close()


@pytest.fixture
def drive(xdotool):
    made = []

    def make(project_file, view="overview"):
        d = Driver(project_file, xdotool, view)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def _vertices(viewer, node):
    T = viewer.model.world_transforms()[node]
    return viewer.model.node(node).primitive.mesh(None, 4).vertices @ T[:3, :3].T + T[:3, 3]


def _top_centre(viewer, node="table.top"):
    V = _vertices(viewer, node)
    return np.array([*V[:, :2].mean(axis=0), V[:, 2].max()])


def test_a_clicked_distance_is_the_command_lines_to_the_last_digit(room, drive, capsys):
    d = drive(room)
    v = d.viewer
    top = _top_centre(v)
    floor = np.array([top[0] + 0.9, top[1] - 0.6, 0.0])
    d.send("key", "t")
    assert v.measure_mode == "distance"
    d.click_at(top + [0.1, 0.05, 0])
    assert len(v.measure_clicks) == 1 and v.selection is None  # the tool took the click
    d.click_at(floor)
    (m,) = v.measured
    a, b = m.command[1:]
    assert a.startswith("table.top@top:") and b.startswith("floor@")
    capsys.readouterr()
    assert main(["analyse", str(room), "distance", a, b]) == 0
    printed = capsys.readouterr().out.strip()
    assert m.result.table.strip() == printed  # value, 1σ and 95 % interval, every digit
    value, sigma = m.result.figures["measurements"][0]["value_m"], m.result.figures["measurements"][0]["sigma_m"]
    assert f"{value:.4f}" in printed and f"{1000 * sigma:.2f}" in printed
    assert f"{value:.4f} m (1σ {1000 * sigma:.2f} mm" in m.label
    # The clicked points are where the cursor was (the ID buffer's depth, 0.1 mm rounding).
    assert np.linalg.norm(m.points[1] - floor) < 0.02
    # Saved as an analysis of the project; the report runs the record again to the same table.
    saved = json.loads(room.read_text())["analyses"]
    assert saved[-1]["command"] == ["distance", a, b] and saved[-1]["name"] == "clicked distance 1"
    _, again = run_recorded(load_project(room), len(saved) - 1, saved[-1])
    assert again.table == m.result.table
    # Drawn: the measurement's colour along the line between the two points.
    img = d.screen().astype(int)
    cam = v.camera()
    on = project_points(cam.K, cam.R, cam.C, 0.75 * m.points[0] + 0.25 * m.points[1])  # clear of the label
    u, w = int(on[0]), int(on[1])
    patch = img[w - 2:w + 3, u - 2:u + 3].reshape(-1, 3)
    assert any(p[2] > 200 and p[1] > 170 and p[0] < 120 for p in patch)  # (0.15, 0.85, 1.0)


def test_a_clicked_height_and_dimensions(room, drive, capsys):
    d = drive(room)
    v = d.viewer
    d.send("key", "t", "key", "t")
    assert v.measure_mode == "height"
    d.click_at(_top_centre(v))
    (m,) = v.measured
    h = m.result.figures["measurements"][0]
    assert abs(h["value_m"] - TABLE_HEIGHT_M) < TABLE_TOL_M
    assert 0 < h["sigma_m"] < 0.005 and h["ci95_m"][0] < h["value_m"] < h["ci95_m"][1]
    capsys.readouterr()
    assert main(["analyse", str(room), "height", m.command[1]]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()
    d.send("key", "t")
    assert v.measure_mode == "dimension"
    V = _vertices(v, "cabinet")
    cam = v.camera()
    uv = project_points(cam.K, cam.R, cam.C, V)
    d.click_at(V[np.argmin(np.abs(uv[:, 0] - W / 2) + np.abs(uv[:, 1] - H / 2))] * 0.9
               + 0.1 * V.mean(axis=0))  # near the cabinet's corner nearest the view's centre
    assert v.measured[-1].command == ["dimensions", "cabinet"]
    assert "cabinet.height" in v.measured[-1].label
    d.send("key", "t")
    assert v.measure_mode is None
    names = [r["name"] for r in json.loads(room.read_text())["analyses"]]
    assert names == ["clicked height 1", "clicked dimension 1"]
    d.send("key", "n")  # the view cleared, the analyses kept
    assert v.measured == [] and len(json.loads(room.read_text())["analyses"]) == 2


def test_a_marker_placed_by_clicking_appears_in_a_render_and_a_click_removes_it(room, drive, tmp_path):
    d = drive(room)
    spot = np.array([2.2, 1.2, 0.0])  # on the floor, in the open
    d.send("key", "m")
    d.click_at(spot)
    (rec,) = json.loads(room.read_text())["evidence_markers"]
    assert rec["label"] == "E1" and rec["node"] == "floor"
    assert np.linalg.norm(np.array(rec["position"]) - spot) < 0.02
    out = tmp_path / "view.png"
    assert main(["render", str(room), "--view", "overview", "--out", str(out), "--size", "640x360",
                 "--samples", "1"]) == 0
    img = np.asarray(Image.open(out).convert("RGB")).astype(int)
    vc = find_view(load_project(room), "overview").resized(640, 360)
    u, w = project_points(vc.K, vc.R, vc.C, np.array(rec["position"]))
    patch = img[int(w) - 2:int(w) + 3, int(u) - 2:int(u) + 3].reshape(-1, 3)
    assert any(np.abs(p - MARKER_COLOUR).max() < 40 for p in patch), patch
    # The pin is clicked again: the marker is removed.
    d.click_at(rec["position"])
    assert json.loads(room.read_text()).get("evidence_markers") == []


def test_a_trajectory_from_two_clicked_holes_is_saved_and_drawn(room, drive):
    d = drive(room)
    v = d.viewer
    top = _top_centre(v)
    d.send("key", "j")
    d.click_at(top + [-0.2, 0.1, 0])
    d.click_at(np.array([top[0] + 0.8, top[1] - 0.9, 0.0]))
    rec = json.loads(room.read_text())["analyses"][-1]
    assert rec["name"] == "clicked trajectory 1"
    words = rec["command"]
    assert words[0] == "trajectory" and words[words.index("--sigma") + 1].count(",") == 1
    sa, sb = (float(s) for s in words[words.index("--sigma") + 1].split(","))
    assert 0 < sa < 0.01 and 0 < sb < 0.01  # the holes' 1σ from the solve, a few tenths of a mm
    (tr,) = v.trajectories()
    assert tr.cone_deg is not None and tr.cone_deg > 0
    img = d.screen().astype(int)
    cam = v.camera()
    mid = project_points(cam.K, cam.R, cam.C, 0.5 * (tr.entry + tr.exit))
    u, w = int(mid[0]), int(mid[1])
    patch = img[w - 2:w + 3, u - 2:u + 3].reshape(-1, 3)
    # The path's red, or its cone's orange over it (a cone of a few hundredths of a degree).
    assert any(p[0] > 180 and p[1] < 170 and p[2] < 80 for p in patch)


def test_measuring_needs_a_solved_model(tmp_path, drive):
    from viewer_scene import write_project

    proj = write_project(tmp_path)
    d = drive(proj, view="entrance")
    v = d.viewer
    d.send("key", "t")
    d.click_at(_top_centre(v, "box"))
    assert v.measured == [] and any("measuring needs a solved model" in m for m in v.messages)
    assert "analyses" not in json.loads(proj.read_text())


def test_a_trajectory_from_a_clicked_hole_along_the_view(room, drive):
    d = drive(room)
    v = d.viewer
    d.send("key", "h")
    assert any("click the entry hole first" in m for m in v.messages)
    d.send("key", "j")
    d.click_at(_top_centre(v) + [0.1, 0.0, 0.0])
    d.send("key", "h")
    words = json.loads(room.read_text())["analyses"][-1]["command"]
    forward = np.asarray(v.camera().R, float)[2]  # the camera's optical axis in the world
    az, el = float(words[words.index("--azimuth") + 1]), float(words[words.index("--elevation") + 1])
    assert az == pytest.approx(np.degrees(np.arctan2(forward[1], forward[0])), abs=0.005)
    assert el == pytest.approx(np.degrees(np.arcsin(forward[2])), abs=0.005)
    assert "--sigma" not in words and v.measure_clicks == []


def test_measurements_are_of_the_measured_scene(room, drive):
    d = drive(room)
    v = d.viewer
    v.select("box")
    v.turn_selection(0.3)  # a hypothesis: the box turned
    assert v.arranged()
    d.send("key", "t")
    d.click_at(_top_centre(v))
    assert v.measure_clicks == [] and any("measurements are of the measured scene" in m for m in v.messages)
    d.send("key", "R")  # Shift+R: everything back where it was measured
    assert not v.arranged()
    d.click_at(_top_centre(v))
    assert len(v.measure_clicks) == 1
