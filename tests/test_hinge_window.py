"""The modelling screen's joint editor ticks a hinge's "solve axis" (under Xvfb, as
tests/test_edit_window.py drives the screen)."""

from __future__ import annotations

import shutil

import pytest
from edit_driver import Driver

from vebuild.cli import main
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")


def test_the_joint_editor_ticks_and_unticks_solve_axis(tmp_path, xdotool):
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    assert main(["calibrate", str(folder / "room.vebuild.json"), "--quiet"]) == 0
    d = Driver(folder / "room.vebuild.json", xdotool)
    try:
        e, s = d.editor, d.session
        d.click("tab:Model")
        e.select("door")
        d.frames(2)
        d.send(*d.at("joint type"), "sleep", "0.05", "click", "--repeat", "12", "--delay", "30", "5")  # scroll down
        assert "solve axis" in e.widget_rects and "limits" in e.widget_rects, " | ".join(sorted(e.widget_rects))
        d.click("solve axis")
        doc = next(n for n in s.data["model"]["nodes"] if n["name"] == "door")
        assert doc["joint"]["solve_axis"] is True
        assert s.model.node("door").joint.dof_names == ("angle", "axis_u", "axis_v")
        d.frames(2)
        assert "solve axis" in e.widget_rects
        d.click("solve axis")
        assert s.model.node("door").joint.dof_names == ("angle",)
    finally:
        d.close()
