"""The modelling screen's file browser takes a video file: its frames are stepped with the keys (, and
., Left and Right), the frame's number and time shown, and the frame chosen is added as a still
(vebuild/edit/browser.py, vebuild/edit/video_frames.py)."""

from __future__ import annotations

import numpy as np
import pytest
from edit_driver import Driver
from edit_scene import make_plan
from PIL import Image
from video_clips import random_frames, write_clip

from vebuild.edit.browser import FileBrowser
from vebuild.edit.history import EditError
from vebuild.edit.session import EditSession
from vebuild.edit.video_frames import VideoFrames
from vebuild.project import load_project


def test_the_browser_lists_videos_and_steps_their_frames_headless(tmp_path) -> None:
    frames = random_frames(8, 32, 24)
    write_clip(tmp_path / "clip.mp4", frames)
    (tmp_path / "text.mp4").write_text("no video")
    b = FileBrowser(tmp_path)
    assert "clip.mp4" in b.listing()[1]
    b.pick_all()
    assert not b.picked  # videos are opened to choose a frame, never picked whole
    assert not b.open_video("text.mp4", tmp_path) and "text.mp4" in b.error
    v = VideoFrames.open(tmp_path / "clip.mp4", tmp_path)
    assert (v.count, v.index) == (8, 0)
    v.step(-1)
    assert v.index == 0  # stops at the first
    v.step(5)
    assert v.index == 5 and v.time == pytest.approx(0.2) and "frame 5 (of 0 to 7) at 0.200 s" in v.label()
    assert np.array_equal(v.still().rgb, frames[5])
    v.step(10)
    assert v.index == 7  # and at the last


@pytest.fixture
def driver_factory(xdotool, xvfb_display):
    made = []

    def make(project_file, **kw):
        d = Driver(project_file, xdotool, **kw)
        made.append(d)
        return d
    yield make
    for d in made:
        d.close()


def test_a_frame_chosen_by_stepping_in_the_browser_is_added_as_a_still(tmp_path, driver_factory) -> None:
    plan = make_plan(tmp_path / "room")
    frames = random_frames(10, 64, 48, seed=2)
    write_clip(plan.folder / "cctv.mp4", frames)
    d = driver_factory(plan.project)
    e, s = d.editor, d.session
    d.send("key", "ctrl+o")
    assert e.browser is not None and e.browser.folder == plan.folder
    d.click("browser:cctv.mp4")
    assert e.browser.video is not None
    d.send("key", "Escape")  # back to the folder, the browser still open
    assert e.browser is not None and e.browser.video is None
    d.click("browser:cctv.mp4")
    v = e.browser.video
    assert v is not None and v.index == 0 and "frame label" in e.widget_rects
    d.send("key", "period", "key", "period", "key", "period")
    assert v.index == 3
    d.send("key", "comma")
    assert v.index == 2
    d.send("key", "Right")
    d.send("key", "Right")
    d.send("key", "Left")
    assert v.index == 3 and "frame 3 (of 0 to 9) at 0.120 s" in v.label()
    d.click("frame on")  # the chooser's buttons do the same
    assert v.index == 4
    d.click("frame add")
    assert e.browser is None and s.photo_ids == ["cctv.f000004"] and e.photo == "cctv.f000004"
    # A video dropped onto the window opens its frames in the browser (as glfw's drop callback does).
    e.on_drop([str(plan.folder / "cctv.mp4")])
    d.frames(2)
    assert e.browser is not None and e.browser.video is not None and e.browser.video.index == 0
    d.send("key", "Escape")
    d.send("key", "Escape")
    assert e.browser is None
    s.save()
    p = load_project(plan.project)
    (photo,) = p.data["photos"]
    assert photo["origin"]["frame"] == 4 and photo["origin"]["time"] == pytest.approx(0.16)
    assert np.array_equal(np.asarray(Image.open(p.photo_path(photo))), frames[4])  # lossless, exact


def test_the_session_adds_frames_of_one_video_to_one_camera_group(tmp_path) -> None:
    plan = make_plan(tmp_path / "room")
    write_clip(plan.folder / "cctv.mp4", random_frames(6, 32, 24))
    s = EditSession.open(plan.project)
    a, b = s.add_video_still(plan.folder / "cctv.mp4", 1), s.add_video_still(plan.folder / "cctv.mp4", 5)
    assert s.data["camera_groups"] == [{"id": "video cctv.mp4", "photos": [a, b]}]
    s.undo()
    assert s.photo_ids == [a] and not s.data.get("camera_groups")


def test_a_video_frame_named_on_the_command_line_is_added_as_the_screen_opens(tmp_path) -> None:
    """`vebuild edit --add-photo CLIP@frame=N` goes through the session's add_photo."""
    plan = make_plan(tmp_path / "room")
    frames = random_frames(6, 32, 24, seed=4)
    write_clip(plan.folder / "cctv.mp4", frames)
    s = EditSession.open(plan.project)
    pid = s.add_photo("cctv.mp4@time=0.1")  # relative to the project's folder; 0.1 s: frame 2 at 25 fps
    assert pid == "cctv.f000002" and s.photo(pid)["origin"]["frame"] == 2
    with pytest.raises(EditError, match="a video file needs the frame to take"):
        s.add_photo("cctv.mp4")
    assert s.photo_ids == [pid]
