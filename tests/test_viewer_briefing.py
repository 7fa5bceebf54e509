"""The walk-through for a briefing room, driven for real (Xvfb and xdotool, as test_viewer.py):
its panel sized to the window, moves said in metres and degrees in the world frame, and the
presentation mode (F11 full screen, Tab in the window) with its legend in place of the panel."""

from __future__ import annotations

import math
import re
import subprocess
from pathlib import Path

import glfw
import numpy as np
import pytest
from viewer_scene import ROOM_X, ROOM_Y, write_project
from xinput import XInput

from vebuild.camera import fov_to_focal
from vebuild.camera import project as project_points
from vebuild.gl.window import Window
from vebuild.project import load_project
from vebuild.render.observed import UNOBSERVED_SRGB
from vebuild.render.renderer import RenderOptions
from vebuild.viewer.app import Viewer
from vebuild.viewer.layout import (
    MIN_TEXT_MM,
    PANEL_WIDTH_EM,
    TEXT_FRACTION_OF_HEIGHT,
    fit_text,
    panel_layout,
    screen_px_per_mm,
    text_size,
)
from vebuild.viewer.presentation import SCALE_BAR_LENGTHS_M, SCALE_BAR_MAX_EM, scale_bar

pytestmark = pytest.mark.usefixtures("xvfb_display")
TITLE = "vebuild briefing test"
#: The Xvfb screen the tests start (conftest.py): full screen is this size.
SCREEN = (1600, 1200)
#: Figures in the move report are rounded to 3 decimals (metres) and 1 (degrees): half a unit.
ROUND_M, ROUND_DEG = 0.0005, 0.05


@pytest.fixture
def room(tmp_path):
    return write_project(tmp_path)


class Driver:
    def __init__(self, project_file: Path, xdotool: str, view: str, size=(640, 360)):
        self.window = Window(size[0], size[1], TITLE, visible=True)
        self.viewer = Viewer(load_project(project_file), self.window, RenderOptions.interactive(), view=view)
        self.viewer.enable_gui()
        self.xdotool = xdotool
        self.frames(3)
        self.wid = subprocess.run([xdotool, "search", "--name", TITLE], capture_output=True,
                                  text=True).stdout.split()[-1]
        subprocess.run([xdotool, "windowfocus", "--sync", self.wid], check=True)
        self.input = XInput(xdotool, self.window.handle, self.viewer.frame)

    def frames(self, n: int) -> None:
        for _ in range(n):
            self.viewer.frame()

    def send(self, *args: str) -> None:
        self.input.send(*args)
        self.frames(4)

    def move_to(self, x: float, y: float) -> list[str]:
        return ["mousemove", "--window", self.wid, str(int(round(x))), str(int(round(y)))]

    def screen(self) -> np.ndarray:
        self.viewer.draw()
        W, H = self.window.framebuffer_size()
        data = self.window.ctx.screen.read(viewport=(0, 0, W, H), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(H, W, 3)[::-1]

    def where(self, X) -> np.ndarray:
        cam = self.viewer.camera()
        return project_points(cam.K, cam.R, cam.C, np.asarray(X, float))

    def close(self) -> None:
        self.viewer.close()
        self.window.close()


@pytest.fixture
def drive(xdotool):
    made = []

    def make(project_file, view, **kw):
        d = Driver(project_file, xdotool, view, **kw)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def _centre(model, node):
    """The centre of a node's box in the world (its vertices' mean: the box is symmetric)."""
    T = model.world_transforms()[node]
    V = model.node(node).primitive.mesh(None, 4).vertices
    return (V @ T[:3, :3].T + T[:3, 3]).mean(axis=0)


# -- the panel's size ---------------------------------------------------------------------------------


def test_text_is_sized_for_the_room_and_never_below_the_desk_minimum():
    # The room's rule: about 1/30 of the picture's height (a 16' capital at 5 heights).
    assert 1 / 32 < TEXT_FRACTION_OF_HEIGHT < 1 / 28
    assert text_size(1080, 96 / 25.4) == pytest.approx(1080 * TEXT_FRACTION_OF_HEIGHT)
    # A small window on an ordinary monitor: the desk's 4 mm (15 px at 96 dpi) wins.
    assert 3.8 < MIN_TEXT_MM < 4.2
    assert text_size(360, 96 / 25.4) == pytest.approx(MIN_TEXT_MM * 96 / 25.4)
    # A dense screen (4K at 27": 163 dpi) has larger text in its pixels; a framebuffer of 2 pixels
    # per window coordinate halves it in window coordinates.
    assert text_size(360, 163 / 25.4) == pytest.approx(MIN_TEXT_MM * 163 / 25.4)
    assert text_size(360, 163 / 25.4, 2.0) == pytest.approx(MIN_TEXT_MM * 163 / 25.4 / 2)
    lay = panel_layout(1920, 1080, 96 / 25.4)
    assert lay.width == pytest.approx(max(PANEL_WIDTH_EM * lay.text_px, 0.3 * 1920))
    assert lay.x + lay.width == pytest.approx(1920 - 0.5 * lay.text_px)
    # A title too long for the panel is shortened with "…" (one unit a character here).
    assert fit_text("vebuild: a long name", 12, len) == "vebuild: a…"
    assert fit_text("short", 12, len) == "short"


def test_the_panel_follows_the_window_size(room, drive):
    d = drive(room, "entrance")
    v = d.viewer
    dpi = screen_px_per_mm(d.window.handle)
    sizes = {}
    for W, H in ((640, 360), (1280, 720)):
        d.send("windowsize", d.wid, str(W), str(H))
        assert glfw.get_window_size(d.window.handle) == (W, H)
        lay = v.panel.layout
        f = max(TEXT_FRACTION_OF_HEIGHT * H, MIN_TEXT_MM * dpi)
        assert lay.text_px == pytest.approx(f)
        x0, y0, x1, y1 = v.panel.rects["panel"]
        m = 0.5 * f
        assert x1 == pytest.approx(W - m, abs=1.5) and y0 == pytest.approx(m, abs=1.5)  # right, below the top
        assert x1 - x0 == pytest.approx(max(PANEL_WIDTH_EM * f, 0.3 * W), abs=1.5)
        assert y1 <= H - m + 1.5  # never past the window
        # The frame shows it there: ImGui's dark panel with light text, the scene beside it.
        img = d.screen().astype(int)
        inside = img[int(y0) + 4:int(y1) - 4, int(x0) + 4:int(x1) - 4]
        assert inside.mean() < 90 and inside.max() > 200
        sizes[W] = (f, x1 - x0)
        # The key sheet holds every binding in the window, without scrolling, its text as large as fits.
        v.panel.show_keys = True
        d.frames(3)
        kx0, ky0, kx1, ky1 = v.panel.rects["keys"]
        assert kx0 >= m - 1.5 and kx1 <= W - m + 1.5 and ky1 <= H - m + 1.5
        assert 8.0 <= v.panel.keys_text_px <= f
        if W == 1280:
            assert v.panel.keys_text_px > 15  # a 720-pixel window reads its keys at a desk
        v.panel.show_keys = False
    # Twice the window: larger text and a wider panel (the text by H/30 over the desk's minimum).
    assert sizes[1280][0] > sizes[640][0] * 1.3 and sizes[1280][1] > sizes[640][1] * 1.3


# -- moves in metres and degrees ---------------------------------------------------------------------


def _door_drag(d, degrees_to):
    v = d.viewer
    j = v.model.node("door").joint
    c = _centre(v.model, "door")
    T = v.model.world_transforms()["door"]
    corners = v.model.node("door").primitive.mesh(None, 4).vertices @ T[:3, :3].T + T[:3, 3]
    free = corners[np.argmax(corners[:, 1])]
    grab = 0.5 * (c + free) + [0, 0, 0.3]
    hinge = np.array([5.98, 2.05, grab[2]])
    r = np.linalg.norm((grab - hinge)[:2])
    moves = []
    for deg in np.linspace(math.degrees(j.angle) + 5, degrees_to, 4):
        a = math.radians(deg) + math.atan2(-(grab - hinge)[0], (grab - hinge)[1]) - j.angle
        moves += [*d.move_to(*d.where(hinge + r * np.array([-math.sin(a), math.cos(a), 0.0]))), "sleep", "0.1"]
    d.send(*d.move_to(*d.where(grab)), "mousedown", "1", "sleep", "0.1", *moves, "mouseup", "1")


def test_a_dragged_door_is_reported_in_metres_and_degrees(room, drive):
    d = drive(room, "at the door")
    v = d.viewer
    c0 = _centre(v.model, "door")
    a0 = math.degrees(v.model.node("door").joint.angle)
    _door_drag(d, 60.0)
    a1 = math.degrees(v.model.node("door").joint.angle)
    assert a1 - a0 > 20  # the drag opened it
    line = v.messages[-1]
    m = re.fullmatch(r"door: moved (\S+) m \(x (\S+), y (\S+), z (\S+) m\), turned (\S+)° about the vertical "
                     r"from where measured; now open (\S+)°", line)
    assert m, line
    num = [float(g.replace("−", "-")) for g in m.groups()]
    # The turn is the hinge's (counter-clockwise seen from above, +), and the door's centre moved on
    # a circle about the hinge line: a chord of 2 r sin(turn / 2), r its distance from the hinge.
    assert num[4] == pytest.approx(a1 - a0, abs=ROUND_DEG) and num[4] > 0
    assert num[5] == pytest.approx(a1, abs=ROUND_DEG)
    r = np.linalg.norm(c0[:2] - [5.98, 2.05])
    assert num[0] == pytest.approx(2 * r * math.sin(math.radians(a1 - a0) / 2), abs=2 * ROUND_M)
    c1 = _centre(v.model, "door")
    np.testing.assert_allclose(num[1:4], c1 - c0, atol=ROUND_M)
    assert num[3] == pytest.approx(0.0, abs=ROUND_M)  # a vertical hinge keeps it at its height
    # The panel's line for the selection: the hinge in the world frame, no joint coordinates.
    text = v.describe("door")
    assert "about the vertical at x 5.98 m, y 2.05 m" in text and f"open {a1:.1f}°" in text
    assert not re.search(r"\bs -?\d|\bt [−-]?\d", text)


def test_a_box_is_placed_in_world_coordinates_and_its_move_said_so(room, drive):
    d = drive(room, "at the box")
    v = d.viewer
    c0 = _centre(v.model, "box")
    u, w = d.where(c0 + [0, 0, 0.25])
    d.send(*d.move_to(u, w), "click", "1")
    # The box rests at (−1.0, −0.5) from the floor's centre (ROOM_X / 2, ROOM_Y / 2): the room's (2.0, 2.0).
    assert f"centre x {ROOM_X / 2 - 1.0:.2f}, y {ROOM_Y / 2 - 0.5:.2f}, z 0.25 m, facing 0.0°" in v.messages[-1]
    d.send(*d.move_to(u, w), "mousedown", "1", "sleep", "0.1", *d.move_to(u - 40, w + 15), "sleep", "0.1",
           *d.move_to(u - 90, w + 30), "sleep", "0.1", "mouseup", "1")
    c1 = _centre(v.model, "box")
    m = re.fullmatch(r"box: moved (\S+) m \(x (\S+), y (\S+), z (\S+) m\) from where measured", v.messages[-1])
    assert m, v.messages[-1]
    num = [float(g.replace("−", "-")) for g in m.groups()]
    assert num[0] == pytest.approx(np.linalg.norm(c1 - c0), abs=ROUND_M) and num[0] > 0.2
    np.testing.assert_allclose(num[1:], c1 - c0, atol=ROUND_M)
    d.send("key", "e")  # a turn of 5° clockwise seen from above (E): said with its sign
    assert "turned −5.0° about the vertical" in v.messages[-1]


# -- presentation ------------------------------------------------------------------------------------


def test_tab_presents_the_view_with_a_legend_and_a_true_scale_bar(room, drive):
    d = drive(room, "facing the west wall")
    v = d.viewer
    x0, y0, x1, y1 = (int(c) for c in v.panel.rects["panel"])
    before = d.screen().astype(int)
    d.send("key", "Tab")
    assert v.presentation.on and not v.show_panel
    img = d.screen().astype(int)
    # The panel is gone: where it was, the wall (light grey), not its dark background.
    assert before[y0 + 20:y1 - 20, x0 + 20:x1 - 20].mean() < 90
    assert img[y0 + 20:y1 - 20, x0 + 20:x1 - 20].mean() > 120
    items = {kind: (text, rect) for kind, text, rect in v.presentation.drawn}
    assert "hypothesis" not in items  # nothing moved
    assert "unobserved" not in items  # an untextured model marks no surface as unseen
    # The scale bar is true at the wall straight ahead: 1 m away (the eye at x = 1, the wall's face at 0).
    text, _ = items["scale"]
    f = fov_to_focal(math.radians(75.0), 640)
    L = float(text.split()[0]) / (100 if text.split()[1] == "cm" else 1)
    assert text.endswith("at 1.0 m from the eye")
    bx0, by0, bx1, by1 = items["scale bar"][1]
    assert bx1 - bx0 == pytest.approx(f * L / 1.0, abs=0.01)
    longer = SCALE_BAR_LENGTHS_M[SCALE_BAR_LENGTHS_M.index(L) + 1]
    assert f * L <= SCALE_BAR_MAX_EM * v.panel.layout.text_px < f * longer  # the longest that fits
    bar = img[int(by0) + 1:int(by1), int(bx0) + 2:int(bx1) - 2]
    assert bar.size and bar.min() > 230  # drawn white
    lx0, ly0, lx1, ly1 = items["legend"][1]
    assert img[int(ly0) + 2:int(ly1) - 2, int(lx1) - 6:int(lx1) - 2].mean() < 80  # on its dark background
    # Turning the box (click, E) is a hypothesis: the legend says so in red.
    d.send("key", "Tab")
    assert not v.presentation.on and v.show_panel is True
    v.select("box")
    d.send("key", "e", "key", "Tab")
    items = {kind: (text, rect) for kind, text, rect in v.presentation.drawn}
    assert items["hypothesis"][0] == "HYPOTHESIS: unsaved arrangement (not the measured scene)"
    hx0, hy0, hx1, hy1 = (int(c) for c in items["hypothesis"][1])
    red = d.screen().astype(int)[hy0:hy1, hx0:hx1].reshape(-1, 3)
    assert np.any((red[:, 0] > 200) & (red[:, 1] < 110) & (red[:, 2] < 110))


def test_f11_presents_full_screen_and_back(room, drive):
    d = drive(room, "entrance")
    v = d.viewer
    d.send("key", "F11")
    assert v.presentation.fullscreen and v.presentation.on and not v.show_panel
    assert glfw.get_window_size(d.window.handle) == SCREEN
    assert v.camera().width == SCREEN[0]
    items = {kind for kind, _, _ in v.presentation.drawn}
    assert {"legend", "scale", "scale bar"} <= items
    d.send("key", "F11")
    assert not v.presentation.fullscreen and v.show_panel
    assert glfw.get_window_size(d.window.handle) == (640, 360)


def test_the_legend_marks_unobserved_surfaces_in_their_colour(textured_room, drive):
    d = drive(textured_room, "doorway")
    v = d.viewer
    assert v.renderer.marks_unobserved
    d.send("key", "Tab")
    items = {kind: (text, rect) for kind, text, rect in v.presentation.drawn}
    assert "no photo saw" in items["unobserved"][0]
    sx0, sy0, sx1, sy1 = (int(round(c)) for c in items["unobserved swatch"][1])
    assert items["unobserved swatch"][1][2] - items["unobserved swatch"][1][0] > 10
    swatch = d.screen().astype(int)[sy0 + 1:sy1 - 1, sx0 + 1:sx1 - 1].reshape(-1, 3)
    # Hatched as the surfaces are: stripes of the mark's colour on light grey, both present.
    mark = np.abs(swatch - np.array(UNOBSERVED_SRGB)).max(axis=1) <= 2
    grey = np.abs(swatch - 204).max(axis=1) <= 2
    assert 0.2 < mark.mean() < 0.8 and 0.2 < grey.mean() < 0.8
    # U: tinted surfaces, a filled swatch.
    d.send("key", "u")
    assert v.renderer.unobserved == "tint"
    items = {kind: (text, rect) for kind, text, rect in v.presentation.drawn}
    sx0, sy0, sx1, sy1 = (int(round(c)) for c in items["unobserved swatch"][1])
    swatch = d.screen().astype(int)[sy0 + 1:sy1 - 1, sx0 + 1:sx1 - 1].reshape(-1, 3)
    assert np.abs(swatch - np.array(UNOBSERVED_SRGB)).max() <= 2


def test_a_scale_bar_is_none_behind_the_eye_and_the_shortest_when_nothing_fits():
    from vebuild.camera import ImageCamera, intrinsic_matrix

    cam = ImageCamera("c", intrinsic_matrix(500.0, 320, 180), np.eye(3), np.zeros(3), 640, 360)
    assert scale_bar(cam, [0, 0, -2.0], 200) is None
    bar = scale_bar(cam, [0, 0, 2.0], 200)
    assert bar.length_m == 0.5 and bar.pixels == pytest.approx(125.0) and bar.label == "50 cm at 2.0 m from the eye"
    assert scale_bar(cam, [0, 0, 0.01], 200).length_m == 0.01  # 1 cm is 500 px: the shortest, drawn anyway
