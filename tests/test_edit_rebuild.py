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

import numpy as np
import pytest
from edit_driver import Driver, H, W
from edit_scene import (
    BOX_DRAGS,
    DISTANCES,
    FLOOR_DRAGS,
    PHOTOS,
    assert_box_matches,
    assert_cameras_match,
    make_plan,
    photo_file,
)
from edit_user import User, window_noise

from vebuild.edit.layout import PANEL_W, STRIP_H, TOOLBAR_H

pytestmark = pytest.mark.usefixtures("xvfb_display")


def test_the_example_rebuilt_from_nothing_by_clicking(tmp_path, xdotool):
    # The screen shows each photo whole; the plan adds what the window's pixel grid does not.
    x0, y0, x1, y1 = 0, TOOLBAR_H, W - PANEL_W, H - STRIP_H
    zoom = min((x1 - x0) / 1600, (y1 - y0) / 1200)
    plan = make_plan(tmp_path / "room", noise_px=window_noise(zoom))
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
