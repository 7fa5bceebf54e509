"""The walk-through window driven for real: a virtual X server (Xvfb) and input events sent to it
with xdotool (CI's .ci/run installs both), as a user's keyboard and mouse would."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from viewer_scene import DOOR_LIMITS_DEG, write_project
from xinput import XInput

from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.gl.window import Window
from vebuild.project import load_project
from vebuild.render.renderer import RenderOptions
from vebuild.viewer.app import Viewer
from vebuild.viewer.walk import BODY_RADIUS_M

pytestmark = pytest.mark.usefixtures("xvfb_display")
TITLE = "vebuild viewer test"
W, H = 640, 360


@pytest.fixture
def room(tmp_path):
    return write_project(tmp_path)


class Driver:
    """A viewer in a real window, and xdotool to type and click into it."""

    def __init__(self, project_file: Path, xdotool: str, view: str, hypothesis: str | None = None, gui=True,
                 panel=False):
        self.window = Window(W, H, TITLE, visible=True)
        self.viewer = Viewer(load_project(project_file), self.window, RenderOptions.interactive(),
                             hypothesis=hypothesis, view=view)
        if gui:
            self.viewer.enable_gui()
        self.xdotool = xdotool
        self.frames(3)
        ids = subprocess.run([xdotool, "search", "--name", TITLE], capture_output=True, text=True).stdout.split()
        self.wid = ids[-1]
        subprocess.run([xdotool, "windowfocus", "--sync", self.wid], check=True)
        self.input = XInput(xdotool, self.window.handle, self.viewer.frame)
        if gui and not panel:
            self.send("key", "F1")  # the panel off, so that it covers none of the small window's scene
            assert not self.viewer.show_panel

    def frames(self, n: int) -> None:
        for _ in range(n):
            self.viewer.frame()

    def send(self, *args: str) -> None:
        """Run one xdotool command line while the window keeps drawing frames (it reads the events)."""
        self.input.send(*args)
        self.frames(4)

    def move_to(self, x: float, y: float) -> list[str]:
        return ["mousemove", "--window", self.wid, str(int(round(x))), str(int(round(y)))]

    def screen(self) -> np.ndarray:
        self.viewer.draw()
        data = self.window.ctx.screen.read(viewport=(0, 0, W, H), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(H, W, 3)[::-1]

    def where(self, X) -> np.ndarray:
        """The window pixel where world point X appears."""
        cam = self.viewer.camera()
        return project_points(cam.K, cam.R, cam.C, np.asarray(X, float))

    def close(self) -> None:
        self.viewer.close()
        self.window.close()


@pytest.fixture
def driver_factory(xdotool):
    made = []

    def make(project_file, view, **kw):
        d = Driver(project_file, xdotool, view, **kw)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def _centre(viewer, node):
    T = viewer.model.world_transforms()[node]
    V = viewer.model.node(node).primitive.mesh(None, 4).vertices
    return (V @ T[:3, :3].T + T[:3, 3]).mean(axis=0), V @ T[:3, :3].T + T[:3, 3]


def test_walking_into_a_wall_stops_and_slides_along_it(room, driver_factory):
    d = driver_factory(room, "facing the west wall")
    v = d.viewer
    d.send("keydown", "w", "sleep", "1.2", "keyup", "w")  # 1.2 s at 1.4 m/s: through the wall 1 m away
    assert v.walker.position[0] == pytest.approx(BODY_RADIUS_M, abs=1e-6)
    y0 = v.walker.position[1]
    # Turn right a little with the mouse (right button held) and walk on: it slides along the wall.
    d.send(*d.move_to(320, 180), "mousedown", "3", *d.move_to(260, 180), "mouseup", "3")
    assert v.walker.yaw > math.pi - 0.01  # the view turned toward +y (left of the wall's normal)
    d.send("keydown", "w", "sleep", "0.6", "keyup", "w")
    assert v.walker.position[0] == pytest.approx(BODY_RADIUS_M, abs=1e-6)
    assert abs(v.walker.position[1] - y0) > 0.05
    assert v.walker.position[2] == pytest.approx(1.6)


def test_clicking_picks_the_object_under_the_cursor(room, driver_factory):
    d = driver_factory(room, "entrance")
    v = d.viewer
    box_centre, _ = _centre(v, "box")
    u, w = d.where(box_centre + [0, 0, 0.25])
    d.send(*d.move_to(u, w), "click", "1")
    assert v.selection == "box"
    assert any("box in floor; joint rests_on" in m for m in v.messages)
    top, _ = _centre(v, "table.top")
    assert 0 < d.where(top)[0] < W and 0 < d.where(top)[1] < H
    d.send(*d.move_to(*d.where(top + [0, 0, 0.02])), "click", "1")
    assert v.selection == "table.top"
    assert "moves 'table'" in v.describe("table.top")
    # The selection is highlighted in the frame.
    img = d.screen()
    u, w = (int(round(c)) for c in d.where(top + [0, 0, 0.02]))
    assert img[w, u, 0] > img[w, u, 2] + 40  # the highlight's orange


def test_dragging_a_resting_object_keeps_it_on_the_floor(room, driver_factory):
    d = driver_factory(room, "at the box")
    v = d.viewer
    measured = json.loads(room.read_text())["model"]
    c0, corners0 = _centre(v, "box")
    u, w = d.where(c0 + [0, 0, 0.25])
    d.send(*d.move_to(u, w), "mousedown", "1", "sleep", "0.1", *d.move_to(u - 30, w + 10), "sleep", "0.1",
           *d.move_to(u - 80, w + 25), "sleep", "0.1", "mouseup", "1")
    c1, corners1 = _centre(v, "box")
    assert np.linalg.norm(c1[:2] - c0[:2]) > 0.2
    assert corners1[:, 2].min() == pytest.approx(0.0, abs=1e-9) and c1[2] == pytest.approx(c0[2], abs=1e-9)
    # Undo with Ctrl+Z, redo with Ctrl+Y.
    d.send("key", "ctrl+z")
    np.testing.assert_allclose(_centre(v, "box")[0], c0, atol=1e-12)
    d.send("key", "ctrl+y")
    np.testing.assert_allclose(_centre(v, "box")[0], c1, atol=1e-12)
    # The wheel turns it about the vertical; it stays on the floor.
    d.send("click", "5", "click", "5")
    assert v.model.node("box").joint.yaw != pytest.approx(0.0)
    assert _centre(v, "box")[1][:, 2].min() == pytest.approx(0.0, abs=1e-9)
    assert json.loads(room.read_text())["model"] == measured  # the measured scene is unchanged
    d.send("key", "shift+r")
    assert v.mover.arrangement() == {}


def test_a_door_dragged_past_its_limit_stops_at_it(room, driver_factory):
    d = driver_factory(room, "at the door")
    v = d.viewer
    j = v.model.node("door").joint
    c, corners = _centre(v, "door")
    free = corners[np.argmax(corners[:, 1])]  # the free edge (the hinge is at y = 2.05)
    grab = 0.5 * (c + free) + [0, 0, 0.3]
    u0, w0 = d.where(grab)
    # Where the grabbed point would be with the door at its limit, and beyond it on the same circle.
    hinge = np.array([5.98, 2.05, grab[2]])
    r = np.linalg.norm((grab - hinge)[:2])
    targets = []
    for deg in (40, 70, DOOR_LIMITS_DEG[1], 130):
        a = math.radians(deg) + math.atan2(-(grab - hinge)[0], (grab - hinge)[1]) - j.angle
        targets.append(hinge + r * np.array([-math.sin(a), math.cos(a), 0.0]))
    moves = []
    for t in targets:
        moves += [*d.move_to(*d.where(t)), "sleep", "0.1"]
    d.send(*d.move_to(u0, w0), "mousedown", "1", "sleep", "0.1", *moves, "mouseup", "1")
    assert v.selection == "door"
    assert math.degrees(j.angle) == pytest.approx(DOOR_LIMITS_DEG[1], abs=0.5)
    assert math.degrees(j.angle) <= DOOR_LIMITS_DEG[1] + 1e-9


def test_fixed_objects_say_they_cannot_move(room, driver_factory):
    d = driver_factory(room, "facing the west wall")
    v = d.viewer
    before = v.mover.arrangement()
    d.send(*d.move_to(320, 120), "mousedown", "1", "sleep", "0.1", *d.move_to(200, 150), "sleep", "0.1", "mouseup",
           "1")
    assert v.selection == "wall.west"
    assert any("'wall.west' cannot move" in m for m in v.messages)
    assert v.mover.arrangement() == before


def test_a_saved_hypothesis_reloads_labelled_and_the_measured_scene_stays(room, driver_factory, tmp_path):
    d = driver_factory(room, "at the box")
    v = d.viewer
    measured = json.loads(room.read_text())["model"]
    c0, _ = _centre(v, "box")
    u, w = d.where(c0 + [0, 0, 0.25])
    d.send(*d.move_to(u, w), "mousedown", "1", "sleep", "0.1", *d.move_to(u + 60, w - 20), "sleep", "0.1",
           "mouseup", "1")
    moved, _ = _centre(v, "box")
    assert v.banner() == "HYPOTHESIS: unsaved arrangement (not the measured scene)"
    v.save_hypothesis("box moved")
    d.close()
    data = json.loads(room.read_text())
    assert data["model"] == measured
    assert [h["name"] for h in data["hypotheses"]] == ["box moved"]
    # Opened again with the hypothesis: the box is where it was left, and the window says so in red.
    d2 = Driver(room, d.xdotool, "at the box", hypothesis="box moved")
    try:
        np.testing.assert_allclose(_centre(d2.viewer, "box")[0], moved, atol=1e-9)
        assert d2.viewer.banner() == "HYPOTHESIS: box moved (not the measured scene)"
        img = d2.screen()
        top_left = img[:60, :420].reshape(-1, 3).astype(int)
        assert np.any((top_left[:, 0] > 200) & (top_left[:, 1] < 100))  # the red label
        # A screenshot (F12) is labelled too, in the image and in its metadata.
        d2.send("key", "F12")
        shot = sorted((room.parent / "screenshots").glob("*.png"))[-1]
        im = Image.open(shot)
        assert im.text["vebuild:hypothesis"] == "box moved"
        band = np.asarray(im)[:8].reshape(-1, 3).astype(int)
        assert np.all(band[:, 0] > 150) and np.all(band[:, 1] < 60)
    finally:
        d2.close()
    # `vebuild render --hypothesis` labels its image as well.
    out = tmp_path / "h.png"
    assert main(["render", str(room), "--view", "at the box", "--hypothesis", "box moved", "--out", str(out)]) == 0
    assert Image.open(out).text["vebuild:hypothesis"] == "box moved"


def test_keys_switch_lighting_stereo_and_views(room, driver_factory):
    d = driver_factory(room, "entrance")
    v = d.viewer
    lit0 = d.screen().astype(float).mean()
    d.send("key", "l")
    assert v.lighting == "lamp"
    assert d.screen().astype(float).mean() != pytest.approx(lit0, rel=0.02)
    d.send("key", "b")
    assert v.stereo == "anaglyph"
    img = d.screen().astype(int)
    assert np.any(img[..., 0] - img[..., 1] > 30)  # red fringes of the left eye
    d.send("key", "b", "key", "b")
    assert v.stereo == "tb"
    d.send("key", "b")
    assert v.stereo is None
    d.send("key", "v")
    assert v.view_index == 1
    np.testing.assert_allclose(v.walker.position, [1.0, 1.0, 1.6])
    d.send("key", "f")
    assert v.walker.fly
    d.send("keydown", "space", "sleep", "0.4", "keyup", "space")
    assert v.walker.position[2] > 1.8


def test_the_panel_is_drawn(room, driver_factory):
    d = driver_factory(room, "entrance", panel=True)
    img = d.screen()
    panel = img[10:60, W - 300:W - 20].astype(int)
    # Dear ImGui's dark panel with light text over the scene.
    assert panel.mean() < 120 and panel.max() > 200
    d.send("key", "F1")
    assert not d.viewer.show_panel


def test_vebuild_view_without_a_display_names_the_headless_way(room, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(room)]) == 2
    err = capsys.readouterr().err
    assert "use `vebuild render`" in err and "Traceback" not in err


def test_vebuild_view_of_a_project_without_a_model(tmp_path, capsys):
    path = write_project(tmp_path, with_model=False)
    assert main(["view", str(path)]) == 2
    assert "the project has no model yet" in capsys.readouterr().err


def test_vebuild_view_runs(room):
    from vebuild.viewer.app import run_viewer

    run_viewer(load_project(room), (320, 200), frames=5)


def test_a_photo_is_shown_over_its_own_camera(textured_room, driver_factory):
    d = driver_factory(textured_room, "doorway", gui=False)
    v = d.viewer
    d.send("key", "p")
    assert v.photo == "p1"
    # The photo fills a letterbox of its shape; at full opacity the window shows the photo itself.
    x, y, w, h = v.viewport()
    assert (w, h) == (480, 360) and (x, y) == (80, 0)
    for _ in range(5):
        d.send("key", "bracketright")
    assert v.photo_opacity == pytest.approx(1.0)
    img = d.screen()[:, 80:560].astype(float)
    photo = np.asarray(Image.open(textured_room.parent / "photos" / "p1.jpg").resize((480, 360),
                                                                                    Image.Resampling.BOX))
    assert np.abs(img - photo).mean() < 6  # the photo, up to texture filtering
    for _ in range(10):
        d.send("key", "bracketleft")
    rendered = d.screen()[:, 80:560].astype(float)
    # Without the overlay the model from the photo's camera still looks like the photo where it covers it.
    assert np.abs(rendered - photo).mean() > 2


def test_markers_and_recorded_trajectories_are_drawn_in_the_window(room, driver_factory):
    data = json.loads(room.read_text())
    data["evidence_markers"] = [{"label": "A", "position": [2.0, 2.0, 0.5], "node": "box"}]
    data["analyses"] = [{"name": "shot", "command": ["trajectory", "--from", "1.0,0.5,1.0", "--to", "2.0,1.0,0.8"]}]
    room.write_text(json.dumps(data))
    d = driver_factory(room, "entrance")
    v = d.viewer
    assert len(v.trajectories()) == 1
    img = d.screen().astype(int)
    u, w = (int(round(c)) for c in d.where([2.0, 2.0, 0.5]))
    assert np.abs(img[w - 2:w + 3, u - 2:u + 3] - [230, 30, 200]).sum(-1).min() < 40  # the marker's pin
    mid = d.where([1.5, 0.75, 0.9])  # a point of the path between the holes
    patch = img[int(mid[1]) - 3:int(mid[1]) + 4, int(mid[0]) - 3:int(mid[0]) + 4]
    assert np.any((patch[..., 0] > 180) & (patch[..., 1] < 80))  # the red path
