"""The walk-through on a project with no model, driven for real (Xvfb, xdotool): one photo of the
example room (p3) alone, calibrated from its lines, its two floor markers (O, the origin, and X5)
and their distance, no model at all. It opens at the photo's camera with the floor grid and the
axes drawn over the photo, T measures a height by two clicks (saved; the command line gives the
same table; drawn again when the project is opened again), the grid lies on the floor markers'
clicks (read from the framebuffer), and what needs a model says so."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from xinput import XInput

from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.errors import VebuildError
from vebuild.gl.window import Window
from vebuild.project import load_project
from vebuild.render.renderer import RenderOptions
from vebuild.viewer.app import Viewer, run_viewer
from vebuild.viewer.floor import AXIS_RGBA

pytestmark = pytest.mark.usefixtures("xvfb_display")
TITLE = "vebuild viewer no model test"
W, H = 1000, 750  # the photo's 4:3: it fills the window, 1 window pixel = 1.6 photo pixels
ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
TRUTH = json.loads((ROOM / "ground_truth.json").read_text())
PHOTO = "p3"
#: The door's hinge edge in p3: its foot on the floor and its height (2.045 m).
DOOR_FOOT, DOOR_M = np.array([4.2, 0.0, 0.0]), 2.045
#: 1σ of a user's click on the photo (pixels): the noise added to each true pixel clicked.
CLICK_NOISE_PX = 0.7
#: How far (window pixels) a drawn line's fitted centre may lie from where it should pass: an
#: anti-aliased line's centre is found to about 0.1 px (0.05-0.10 px seen), and the calibration
#: places X5 on x = 5 m to 0.02 mm (0.005 px); a drawing off by one pixel, or by half of one (the
#: pixel centre's convention), fails.
LINE_TOLERANCE_PX = 0.4


def one_photo(folder: Path) -> Path:
    """p3 of the example room alone: its vanishing segments, the floor markers O (the origin) and
    X5 and their distance (5 m), calibrated; no model."""
    (folder / "photos").mkdir(parents=True)
    d = json.loads((ROOM / "room.vebuild.json").read_text())
    p = next(p for p in d["photos"] if p["id"] == PHOTO)
    shutil.copy(ROOM / p["file"], folder / "photos")
    keep = {"O", "X5"}
    p["marker_observations"] = {k: v for k, v in p["marker_observations"].items() if k in keep}
    d["photos"] = [p]
    d["markers"] = [{**m, "on_floor": True} for m in d["markers"] if m["name"] in keep]
    d["reference_distances"] = [r for r in d["reference_distances"] if {r["a"], r["b"]} <= keep]
    for k in ("model", "views", "lighting"):
        d.pop(k)
    path = folder / "one.vebuild.json"
    path.write_text(json.dumps(d, indent=1))
    assert main(["calibrate", str(path), "--quiet"]) == 0
    return path


@pytest.fixture
def no_model(tmp_path):
    return one_photo(tmp_path / "one")


@pytest.fixture
def open_viewer(xdotool):
    """Opens a project's walk-through (one at a time: the one open before is closed)."""
    opened = []

    def close() -> None:
        while opened:
            v, window = opened.pop()
            v.close()
            window.close()

    def open_(path: Path):
        close()
        window = Window(W, H, TITLE, visible=True)
        v = Viewer(load_project(path), window, RenderOptions.interactive())
        v.enable_gui()
        opened.append((v, window))
        for _ in range(3):
            v.frame()
        wid = subprocess.run([xdotool, "search", "--name", TITLE], capture_output=True,
                             text=True).stdout.split()[-1]
        subprocess.run([xdotool, "windowfocus", "--sync", wid], check=True)
        inp = XInput(xdotool, window.handle, v.frame)

        def send(*args: str) -> None:
            inp.send(*args)
            for _ in range(4):
                v.frame()

        send("key", "F1")  # the panel off: it covers none of the photo
        return v, send, wid

    yield open_
    close()


def _window_xy(v, uv) -> np.ndarray:
    """The framebuffer point (x right, y down, pixel centres at i + 0.5) of a pixel of the photo shown."""
    vx, vy, vw, vh = v.viewport()
    fw, fh = v.window.framebuffer_size()
    s = vw / v.project.photo(v.photo)["width"]
    return np.array([vx + s * float(uv[0]), fh - vy - vh + s * float(uv[1])])


def _click_at(v, X, rng) -> tuple[str, str]:
    """The window point a user clicks on world point X in the photo shown (its true pixel, with a
    click's noise)."""
    t = TRUTH["photos"][v.photo]
    K, R, C = (np.asarray(t[k], float) for k in ("K", "R", "C"))
    xy = _window_xy(v, project_points(K, R, C, np.asarray(X, float)) + rng.normal(0.0, CLICK_NOISE_PX, 2))
    return str(int(xy[0])), str(int(xy[1]))  # the pixel whose square holds the point


def _frame(v) -> np.ndarray:
    v.draw()
    fw, fh = v.window.framebuffer_size()
    return np.frombuffer(v.window.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1),
                         np.uint8).reshape(fh, fw, 3)[::-1].astype(int)


def _fit_line(pts: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The weighted least-squares line through points: a point on it and its unit normal."""
    c = (weights[:, None] * pts).sum(axis=0) / weights.sum()
    d = pts - c
    cov = (weights[:, None, None] * d[:, :, None] * d[:, None, :]).sum(axis=0)
    _, vecs = np.linalg.eigh(cov)
    return c, vecs[:, 0]


def _two_lines(pts: np.ndarray, weights: np.ndarray, rng) -> list[tuple[np.ndarray, np.ndarray]]:
    """The two lines crossing among the points (RANSAC, then each fitted to its pixels)."""
    lines = []
    left = np.ones(len(pts), bool)
    for _ in range(2):
        best = None
        idx = np.flatnonzero(left)
        for _ in range(400):
            a, b = pts[rng.choice(idx, 2, replace=False)]
            if np.linalg.norm(b - a) < 4:
                continue
            n = np.array([a[1] - b[1], b[0] - a[0]]) / np.linalg.norm(b - a)
            inl = left & (np.abs((pts - a) @ n) < 1.5)
            if best is None or inl.sum() > best.sum():
                best = inl
        assert best is not None
        lines.append(_fit_line(pts[best], weights[best]))
        c, n = lines[-1]
        left &= np.abs((pts - c) @ n) >= 2.5
    return lines


def _crossing(lines) -> np.ndarray:
    (c1, n1), (c2, n2) = lines
    return np.linalg.solve(np.array([n1, n2]), np.array([n1 @ c1, n2 @ c2]))


def test_a_photo_alone_opens_at_its_camera_and_a_height_is_measured_by_clicks(no_model, open_viewer, capsys):
    v, send, wid = open_viewer(no_model)
    assert not v.has_model and v.photo == PHOTO and v.show_floor and v.photo_opacity == 1.0
    assert v.messages[-1].startswith("no model yet: the photo at its camera with the floor grid")
    rng = np.random.default_rng(4623)
    send("key", "t")
    assert v.measure_mode == "photo-height" and "click its foot on the floor" in v.messages[-1]
    send("mousemove", "--window", wid, *_click_at(v, DOOR_FOOT, rng), "click", "1")
    assert len(v.single_view_clicks) == 1 and "click its top" in v.messages[-1], v.messages
    send("mousemove", "--window", wid, *_click_at(v, DOOR_FOOT + [0, 0, DOOR_M], rng), "click", "1")
    (m,) = v.measured
    assert m.photo == PHOTO and m.label.startswith("height "), v.messages
    (rec,) = json.loads(no_model.read_text())["analyses"]
    assert rec == {"name": "clicked photo-height 1", "description": m.label, "command": m.command}
    capsys.readouterr()
    assert main(["analyse", str(no_model), *rec["command"]]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()
    h = m.result.figures["measurements"][0]
    assert h["ci95_m"][0] <= DOOR_M <= h["ci95_m"][1], (h, DOOR_M)
    assert 0 < h["sigma_m"] < 0.05 * DOOR_M
    # What needs a model says so in words; nothing else changes.
    for key, words in (("l", "Lighting presets: this needs a model"), ("u", "surfaces no photo saw"),
                       ("m", "evidence markers"), ("j", "A trajectory (a sight line"), ("b", "Stereo"),
                       ("F12", "A screenshot")):
        send("key", key)
        assert words in v.messages[-1] and "needs a model" in v.messages[-1], (key, v.messages[-1])
        assert "Traceback" not in v.messages[-1]
    assert v.measure_mode == "photo-height" and v.stereo is None  # the refusals changed nothing
    # Off the photo's camera (walking back): the grid and the photo's frustum, said in words.
    send("keydown", "s")
    for _ in range(20):
        v.frame()
    send("keyup", "s")
    assert v.photo is None and any(s.startswith(f"off photo {PHOTO}'s camera") for s in v.messages), v.messages
    assert np.linalg.norm(v.walker.position[:2] - v.photo_cameras()[0].C[:2]) > 0.2
    shown = _frame(v)
    send("key", "g")
    assert not v.show_floor
    hidden = _frame(v)
    orange = (shown[..., 0] > 200) & (shown[..., 1] > 100) & (shown[..., 1] < 180) & (shown[..., 2] < 80)
    assert orange.sum() > 100 and not ((hidden[..., 0] > 200) & (hidden[..., 2] < 80)).any()
    # Opened again: the saved measurement is drawn on its photo, its figure the saved words' again.
    v2, _, _ = open_viewer(no_model)
    (again,) = v2.measured
    assert again.name == rec["name"] and again.label == m.label and again.command == rec["command"]


def test_the_floor_grid_lies_on_the_floor_markers_clicks(no_model, open_viewer):
    v, send, _ = open_viewer(no_model)
    shown = _frame(v)
    send("key", "g")
    hidden = _frame(v)
    drawn = np.abs(shown - hidden).sum(axis=2)  # what the grid and the axes changed
    rows, cols = np.nonzero(drawn > 60)
    pts, weight = np.c_[cols, rows] + 0.5, drawn[rows, cols].astype(float)
    obs = load_project(no_model).photo(PHOTO)["marker_observations"]
    rng = np.random.default_rng(46)
    # The origin marker O: where the x (red) and y (green) axes cross is its click.
    o = _window_xy(v, obs["O"])
    near = np.linalg.norm(pts - o, axis=1) < 40
    axes = []
    for axis in "xy":
        want = np.array(AXIS_RGBA[axis][:3]) * 255
        px = shown[rows[near], cols[near]]
        own = np.linalg.norm(px - want, axis=1) < 90
        assert own.sum() > 15, axis
        axes.append(_fit_line(pts[near][own], weight[near][own]))
    assert np.linalg.norm(_crossing(axes) - o) < LINE_TOLERANCE_PX, (_crossing(axes), o)
    # X5, 5 m along x on the floor: the grid line x = 5 m passes through its click (the calibration
    # puts X5 at x = 4.99998 m), and the grid's lines x = 5 and y = 0 cross beside it.
    x5 = _window_xy(v, obs["X5"])
    near = np.linalg.norm(pts - x5, axis=1) < 25
    lines = _two_lines(pts[near], weight[near], rng)
    gap = min(abs((x5 - c) @ n) for c, n in lines)
    assert gap < LINE_TOLERANCE_PX, (gap, lines, x5)
    cal = json.loads(no_model.read_text())["calibration"]["markers"]["X5"]
    cam = v.camera()
    grid_point = _window_xy(v, project_points(cam.K, cam.R, cam.C, np.array([5.0, 0.0, 0.0]))
                            * v.project.photo(PHOTO)["width"] / cam.width)
    assert np.linalg.norm(_crossing(lines) - grid_point) < LINE_TOLERANCE_PX
    assert abs(cal["position"][0] - 5.0) < 1e-3


def test_a_project_with_nothing_to_show_is_refused_in_words(tmp_path):
    d = json.loads((ROOM / "room.vebuild.json").read_text())
    d.pop("model")
    (tmp_path / "photos").mkdir()
    for p in d["photos"]:
        shutil.copy(ROOM / p["file"], tmp_path / "photos")
    path = tmp_path / "uncalibrated.vebuild.json"
    path.write_text(json.dumps(d))
    with pytest.raises(VebuildError, match="no model yet and no calibrated photo to show; calibrate"):
        run_viewer(load_project(path), frames=1)
