"""The example room rebuilt from nothing in the modelling screen by "clicking": under a virtual X
server, xdotool types and clicks as a user would. Photos are added through the strip's field,
vanishing segments drawn with the Segment tools, markers placed with the Marker tool, the reference
distances typed into the calibration panel, Calibrate pressed, the floor and a box added from the
model panel and their vertices dragged onto the photos (paper Figures 1, 3, 5 and 7). The cameras
and the box then match the example's ground truth within the calibration and modelling issues'
tolerances (tests/edit_scene.py), as the same plan does headless (tests/test_edit_session.py).

Clicks land on whole window pixels: at the view's zoom z a click is off by up to 0.5/z photo pixels
(1σ 0.29/z). The plan adds the rest of a click's 0.7 px noise, so that the total is the noise the
tolerances were stated for.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from edit_driver import Driver, H, W
from edit_scene import (
    BOX_DRAGS,
    CLICK_NOISE_PX,
    DISTANCES,
    FLOOR_DRAGS,
    PHOTOS,
    assert_box_matches,
    assert_cameras_match,
    make_plan,
    photo_file,
)

from vebuild.edit.layout import CLICK_SLOP_PX, PANEL_W, STRIP_H, TOOLBAR_H

pytestmark = pytest.mark.usefixtures("xvfb_display")


class User:
    """What a user does on the screen, as xdotool input events."""

    def __init__(self, d: Driver):
        self.d, self.e, self.s = d, d.editor, d.session

    def xy(self, uv) -> list[str]:
        x, y = self.e.image_to_window(None, uv)
        return self.d.move_to(x, y)

    def type_into(self, label: str, text: str) -> None:
        self.d.send(*self.d.at(label), "click", "1", "key", "ctrl+a", "type", "--delay", "20", text)
        self.d.send("key", "Return")

    def choose(self, combo: str, item: str) -> None:
        self.d.click(combo)
        self.d.frames(2)
        self.d.click(f"{combo}:{item}")

    def show(self, photo: str) -> None:
        if self.e.photo != photo:
            self.d.click(f"photo:{photo}")
        assert self.e.photo == photo

    def strokes(self, tool_key: str, segments) -> None:
        """Press, drag and release along each segment with the tool of that key."""
        self.d.send("key", tool_key)
        events: list[str] = []
        for u1, v1, u2, v2 in segments:
            a, b = np.array([u1, v1]), np.array([u2, v2])
            events += [*self.xy(a), "mousedown", "1"]
            for t in (0.5, 1.0):
                events += self.xy(a + t * (b - a))
            events += ["mouseup", "1"]
        self.d.send(*events)

    def drag(self, node: str, handle: str, goal) -> None:
        """Drag the vertex onto ``goal``; one already within a few pixels of it (twice a click's slop:
        a shorter drag would be taken for a click) is fixed where it is, with F, as a user would."""
        start = next(uv for n, h, uv, _ in self.s.handles(self.e.photo) if (n, h) == (node, handle))
        a, b = np.asarray(start, float), np.asarray(goal, float)
        if np.linalg.norm(b - a) * self.e.zoom <= 2 * CLICK_SLOP_PX:
            self.d.send(*self.xy(a), "key", "f")
            return
        events = [*self.xy(a), "mousedown", "1"]
        for t in np.linspace(0.125, 1.0, 8):
            events += [*self.xy(a + t * (b - a)), "sleep", "0.03"]
        self.d.send(*events, "mouseup", "1")


def _window_noise(zoom: float) -> float:
    """1σ of the noise to add so that a click rounded to the window's pixels has 0.7 px in all."""
    grid = 0.5 / zoom / math.sqrt(3.0)  # a uniform error of ±0.5 window pixel, in photo pixels
    return math.sqrt(max(CLICK_NOISE_PX**2 - grid**2, 0.0))


def test_the_example_rebuilt_from_nothing_by_clicking(tmp_path, xdotool):
    # The screen shows each photo whole; the plan adds what the window's pixel grid does not.
    x0, y0, x1, y1 = 0, TOOLBAR_H, W - PANEL_W, H - STRIP_H
    zoom = min((x1 - x0) / 1600, (y1 - y0) / 1200)
    plan = make_plan(tmp_path / "room", noise_px=_window_noise(zoom))
    d = Driver(plan.project, xdotool)
    try:
        u = User(d)
        s, e = d.session, d.editor
        # Photos, added by typing their file names into the strip's field: size and SHA-256 recorded.
        for pid in PHOTOS:
            u.type_into("add photo file", photo_file(plan, pid).relative_to(plan.folder).as_posix())
            d.click("Add photo")
        assert s.photo_ids == list(PHOTOS)
        assert all(len(p["sha256"]) == 64 for p in s.data["photos"])
        for pid in PHOTOS:
            u.show(pid)
            assert e.zoom == pytest.approx(zoom)
            for key, axis in (("1", "x"), ("2", "y"), ("3", "z")):
                u.strokes(key, plan.segments[pid][axis])
                assert len(s.vanishing(pid, axis).segments) == len(plan.segments[pid][axis]), (pid, axis)
            for name, uv in plan.markers[pid].items():
                u.type_into("marker name", name)
                d.send("key", "m", *u.xy(uv), "click", "1")
                assert name in s.photo(pid)["marker_observations"], (pid, name)
            d.send("key", "Escape")
        assert s.data["origin_marker"] == "O"
        for a, b, dist in DISTANCES:
            u.type_into("distance a", a)
            u.type_into("distance b", b)
            u.type_into("distance m", f"{dist}")
            d.click("add##distance")
        assert [(r["a"], r["b"], r["distance"]) for r in s.data["reference_distances"]] == list(DISTANCES)
        d.click("Calibrate")
        d.frames(3)
        assert e.calibration_error is None, e.calibration_error
        assert_cameras_match(plan, s.cameras)

        # The floor: a quad on the origin marker, its far corners dragged onto the photos.
        rng = np.random.default_rng(17)
        d.click("tab:Model")
        u.choose("kind", "quad")
        u.type_into("new name", "floor")
        d.click("Add")
        d.send(*u.xy((800, 600)), "click", "1")
        assert s.model.node("floor").joint.type == "marker"
        for pid, h in FLOOR_DRAGS:
            u.show(pid)
            u.drag("floor", h, plan.pixel(pid, plan.vertex("floor", h), rng))
        # The box: on the floor where its first corner is seen, then sized corner by corner.
        u.choose("kind", "box")
        u.choose("parent", "floor")
        u.type_into("new name", "box")
        d.click("Add")
        u.show("p3")
        d.send(*u.xy(plan.pixel("p3", plan.vertex("box", "v0"), rng)), "click", "1")
        assert s.model.node("box").parent == "floor"
        for pid, h in BOX_DRAGS:
            u.show(pid)
            u.drag("box", h, plan.pixel(pid, plan.vertex("box", h), rng))
            assert e.drag_problem is None, e.drag_problem
        pins = {(p["photo"], p["handle"]) for p in s.data["model"]["pins"] if p["node"] == "box"}
        assert pins == set(BOX_DRAGS)
        assert_box_matches(plan, s.model)
        floor = s.model.node("floor").primitive
        assert floor.params == pytest.approx([5.0, 4.0], abs=0.05)  # 1 cm per metre
        # Saved with Ctrl+S: the project file holds it all, the autosave is gone.
        d.send("key", "ctrl+s")
        assert not s.dirty and not s.autosave_path.exists()
    finally:
        d.close()
