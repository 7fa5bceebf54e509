"""The modelling screen's camera groups with real input (a window under a virtual X server,
xdotool's clicks and keys): the Cameras tab lists each photo's camera; ticking photos and pressing
"These photos share one camera" groups them, "Release this photo from its camera" releases the photo
shown, and Ctrl+Z takes a release back."""

from __future__ import annotations

import shutil

import pytest
from edit_driver import Driver

from vebuild.edit.session import photo_cameras
from vebuild.resources import example_project_dir


@pytest.mark.usefixtures("xvfb_display")
def test_the_screen_groups_and_releases_photos_of_one_camera(tmp_path, xdotool) -> None:
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    d = Driver(folder / "room.vebuild.json", xdotool)
    try:
        s, e = d.session, d.editor
        # The example's photos record one camera body zoomed to other focal lengths: no group.
        assert set(photo_cameras(s.data).values()) == {"own camera"}
        d.click("tab:Cameras")
        for pid in ("p1", "p2"):
            assert f"camera:{pid}" in e.widget_rects
            d.click(f"camera:{pid}")
        assert e.panels.camera_ticks == {"p1", "p2"}
        d.click("These photos share one camera")
        assert s.data["camera_groups"] == [{"id": "camera 1", "photos": ["p1", "p2"]}]
        assert photo_cameras(s.data)["p1"] == "camera 'camera 1' (grouped by you)"
        assert e.panels.camera_ticks == set()
        assert e.photo == "p1"
        d.click("Release this photo from its camera")
        assert s.data["photos"][0]["own_camera"] is True and "camera_groups" not in s.data  # a group of one: none
        assert photo_cameras(s.data)["p1"] == "own camera, released from its group"
        d.send("key", "ctrl+z")
        assert "own_camera" not in s.data["photos"][0]
        assert s.data["camera_groups"] == [{"id": "camera 1", "photos": ["p1", "p2"]}]
        # One photo ticked is no group: the screen says what to do.
        d.click("camera:p3")
        d.click("These photos share one camera")
        assert s.data["camera_groups"] == [{"id": "camera 1", "photos": ["p1", "p2"]}]
        assert "tick two photos or more" in e.messages[-1]
    finally:
        d.close()
