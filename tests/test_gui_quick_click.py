"""A quick move and click that reach the screen within one slow frame still click what is under
the new position: ImGui takes a move and a press in one frame together and then finds no widget
there, so the Gui holds the press for the next frame (gl/imgui.py). Off-screen, the events given
as glfw's callbacks would give them between two frames."""

from __future__ import annotations

import shutil

import glfw
import pytest

from vebuild.resources import example_project_dir


@pytest.fixture
def screen(tmp_path):
    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.context import headless_context
    from vebuild.gl.surface import OffscreenSurface

    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    s = EditSession.open(folder / "room.vebuild.json", recover=False)
    surface = OffscreenSurface(headless_context(), 1200, 780)
    e = Editor(s, surface)
    for _ in range(len(s.photo_ids) + 3):
        e.draw()
    yield e
    e.close()
    surface.release()


@pytest.mark.parametrize("also", ["the release", "the release and a move away"])
def test_a_move_and_a_click_in_one_frame_select_the_tab_under_it(screen, also):
    e = screen
    assert "new name" not in e.widget_rects  # the Calibration tab is shown
    x0, y0, x1, y1 = e.widget_rects["tab:Model"]
    e.on_cursor(0.5 * (x0 + x1), 0.5 * (y0 + y1))
    e.on_button(glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
    e.on_button(glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)
    if also == "the release and a move away":
        e.on_cursor(x1 + 200, y1 + 300)
    for _ in range(4):
        e.draw()
    assert "new name" in e.widget_rects  # the Model tab's field for a new primitive's name
