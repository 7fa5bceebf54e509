"""Single-view measuring in the walk-through's photo view, driven for real (Xvfb, xdotool): the
example room calibrated but not solved, a photo shown at its camera (P), a height measured on it
alone by two clicks (T), saved as an analysis whose words the command line runs to the same table,
within its 95 % interval of the generated truth (scenes/room/ground_truth.json)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from xinput import XInput

from vebuild.actions import click_single_view as sv
from vebuild.camera import project as project_points
from vebuild.cli import main
from vebuild.gl.window import Window
from vebuild.project import load_project
from vebuild.render.renderer import RenderOptions
from vebuild.viewer.app import Viewer

pytestmark = pytest.mark.usefixtures("xvfb_display")
TITLE = "vebuild viewer single view test"
W, H = 1000, 750  # the photos' 4:3: the photo fills the window, 1 window pixel = 1.6 photo pixels
ROOM = Path(__file__).resolve().parents[1] / "scenes" / "room"
TRUTH = json.loads((ROOM / "ground_truth.json").read_text())
#: The table's far right leg in photo p1 (clear of the messages at the window's foot): its corner
#: nearest the camera on the floor, and where that corner meets the table top's underside (0.72 m:
#: the legs' height).
LEG_FOOT, LEG_M = np.array([2.84, 2.42, 0.0]), 0.72
#: 1σ of a user's click on the photo (pixels): the noise added to each true pixel clicked.
CLICK_NOISE_PX = 0.7


@pytest.fixture
def calibrated_room(tmp_path):
    """The example room calibrated (its markers and scale distances), its model not solved."""
    shutil.copytree(ROOM, tmp_path / "room")
    proj = tmp_path / "room" / "room.vebuild.json"
    assert main(["calibrate", str(proj), "--quiet"]) == 0
    return proj


@pytest.fixture
def viewer(calibrated_room, xdotool):
    window = Window(W, H, TITLE, visible=True)
    v = Viewer(load_project(calibrated_room), window, RenderOptions.interactive())
    v.enable_gui()
    for _ in range(3):
        v.frame()
    wid = subprocess.run([xdotool, "search", "--name", TITLE], capture_output=True, text=True).stdout.split()[-1]
    subprocess.run([xdotool, "windowfocus", "--sync", wid], check=True)
    inp = XInput(xdotool, window.handle, v.frame)

    def send(*args: str) -> None:
        inp.send(*args)
        for _ in range(4):
            v.frame()

    send("key", "F1")  # the panel off: it covers none of the photo
    yield v, send, wid
    v.close()
    window.close()


def _window_at(v, X, rng) -> tuple[str, str]:
    """The window point a user clicks on world point X in the photo shown (its true pixel, with a
    click's noise)."""
    t = TRUTH["photos"][v.photo]
    K, R, C = (np.asarray(t[k], float) for k in ("K", "R", "C"))
    u, w = project_points(K, R, C, np.asarray(X, float)) + rng.normal(0.0, CLICK_NOISE_PX, 2)
    vx, vy, vw, vh = v.viewport()
    s = vw / t["width"]
    fw, fh = v.window.framebuffer_size()
    return str(int(round(vx + s * u))), str(int(round(fh - vy - vh + s * w)))


def test_a_height_measured_on_a_photo_shown_at_its_camera(viewer, calibrated_room, capsys):
    v, send, wid = viewer
    rng = np.random.default_rng(4622)
    send("key", "t")  # no solved model and no photo shown: it says what measuring needs
    assert v.measure_mode is None and "show a calibrated photo at its camera (P)" in v.messages[-1]
    send("key", "p")
    assert v.photo == "p1"
    send("key", "t")
    assert v.measure_mode == "photo-height" and "click its foot on the floor" in v.messages[-1]
    send("mousemove", "--window", wid, *_window_at(v, LEG_FOOT, rng), "click", "1")
    assert len(v.single_view_clicks) == 1 and "click its top" in v.messages[-1], v.messages
    send("mousemove", "--window", wid, *_window_at(v, LEG_FOOT + [0, 0, LEG_M], rng), "click", "1")
    (m,) = v.measured
    assert m.photo == "p1" and m.label.startswith("height ") and "95 % between" in m.label
    # Saved in the project file at once, as the walk-through saves; the words run to the same table.
    (rec,) = json.loads(calibrated_room.read_text())["analyses"]
    assert rec == {"name": "clicked photo-height 1", "description": m.label, "command": m.command}
    capsys.readouterr()
    assert main(["analyse", str(calibrated_room), *rec["command"]]) == 0
    assert capsys.readouterr().out.strip() == m.result.table.strip()
    h = m.result.figures["measurements"][0]
    assert h["ci95_m"][0] <= LEG_M <= h["ci95_m"][1], (h, LEG_M)
    assert 0 < h["sigma_m"] < 0.05 * LEG_M
    # Drawn on the photo: the line from foot to top in the measurement's colour.
    v.draw()
    fw, fh = v.window.framebuffer_size()
    img = np.frombuffer(v.window.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1),
                        np.uint8).reshape(fh, fw, 3)[::-1].astype(int)
    a, b = (np.array([float(c) for c in _window_at(v, X, np.random.default_rng(0))])
            for X in (LEG_FOOT, LEG_FOOT + [0, 0, LEG_M]))
    x, y = (int(c) for c in 0.5 * (a + b))
    patch = img[y - 4:y + 5, x - 4:x + 5].reshape(-1, 3)
    assert any(p[2] > 200 and p[1] > 170 and p[0] < 120 for p in patch)
    # T again: the next single-view measurement, round to off.
    for kind in sv.kinds()[1:]:
        send("key", "t")
        assert v.measure_mode == kind
    send("key", "t")
    assert v.measure_mode is None
