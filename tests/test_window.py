"""Windows (glfw) drawing with the same renderer as off-screen, under a virtual X server."""

from __future__ import annotations

import numpy as np
import pytest
from render_scenes import box_on_floor_model, off_centre_camera

from vebuild.errors import VebuildError
from vebuild.gl import headless_context
from vebuild.gl.window import Window, WindowUnavailableError
from vebuild.render.renderer import Renderer, RenderOptions, Stereo
from vebuild.render.scene import scene_from_model

pytestmark = pytest.mark.usefixtures("xvfb_display")

OPTIONS = RenderOptions(samples=1)


def _screen(window, w, h):
    """The window's framebuffer in image order (row 0 at the top)."""
    data = window.ctx.screen.read(viewport=(0, 0, w, h), components=3, alignment=1)
    return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1]


@pytest.mark.parametrize("stereo", [None, Stereo("tb", 0.1, 2.0), Stereo("sbs", 0.1, 2.0), Stereo("anaglyph")])
def test_a_window_shows_what_the_headless_renderer_draws(stereo):
    scene = scene_from_model(box_on_floor_model())
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2], w=240, h=180)
    off = Renderer(headless_context(), scene, OPTIONS)
    want = off.render(cam, stereo)
    off.release()
    h, w = want.shape[:2]
    with Window(w, h, visible=False) as window:
        assert window.framebuffer_size() == (w, h)
        r = Renderer(window.ctx, scene, OPTIONS)
        r.draw(window.ctx.screen, cam, stereo, flip=True)
        got = _screen(window, w, h)
        window.swap()
        r.release()
    # The same pixels, but for a few whose centres lie exactly on an edge: the window's flipped rows
    # turn the rasteriser's top-left fill rule into a bottom-left one there.
    diff = np.abs(got.astype(int) - want).max(axis=-1)
    assert np.mean(diff > 1) < 1e-3, np.count_nonzero(diff > 1)
    # The off-screen context is current again after the window closed.
    again = Renderer(headless_context(), scene, OPTIONS)
    assert np.mean(again.render(cam, stereo) != want) < 1e-3
    again.release()


def test_quad_buffered_stereo_is_asked_for_and_its_absence_reported():
    scene = scene_from_model(box_on_floor_model())
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2], w=160, h=120)
    with Window(160, 120, visible=False, stereo=True) as window:
        # A virtual X server (and software GL) offers no stereo visual: the window opens without it.
        assert window.stereo is False
        assert "no quad-buffered stereo" in window.stereo_note
        with pytest.raises(VebuildError, match="no left and right buffers"):
            window.select_buffer("left")
        r = Renderer(window.ctx, scene, OPTIONS)
        with pytest.raises(VebuildError, match="quad-buffered stereo needs a window"):
            r.draw(window.ctx.screen, cam, Stereo("quad"), flip=True)
        r.release()


def test_without_a_display_the_error_names_the_headless_way(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(WindowUnavailableError, match="use `vebuild render`"):
        Window(64, 64, visible=False)


def test_each_renderer_draws_and_picks_in_its_own_context_whichever_is_current():
    # GL calls go to the current context, not to the one whose objects they name: off-screen work
    # between a window's frames (an in-process render, whose headless context is made current on
    # first use) left the window's picks reading another context's buffers (garbage ids).
    scene = scene_from_model(box_on_floor_model())
    cam = off_centre_camera([2.3, -1.2, 1.9], [2.1, 1.4, 0.2], w=240, h=180)
    off = Renderer(headless_context(), scene, OPTIONS)
    want = off.render(cam)
    faces, _ = off.id_buffer(cam)
    rows, cols = np.nonzero(faces > 0)
    picks = [(float(cols[k]) + 0.5, float(rows[k]) + 0.5) for k in np.linspace(0, len(rows) - 1, 5).astype(int)]
    wanted = [off.pick(cam, u, v) for u, v in picks]
    with Window(240, 180, visible=False) as window:
        r = Renderer(window.ctx, scene, OPTIONS)
        headless_context().__enter__()  # what off-screen work between frames leaves current
        for (u, v), (node, X) in zip(picks, wanted, strict=True):
            got_node, got_X = r.pick(cam, u, v)
            assert got_node == node and got_X is not None
            np.testing.assert_allclose(got_X, X, atol=1e-4)
        headless_context().__enter__()
        r.draw(window.ctx.screen, cam, flip=True)
        diff = np.abs(_screen(window, 240, 180).astype(int) - want).max(axis=-1)
        assert np.mean(diff > 1) < 1e-3
        window.make_current()  # and the headless renderer while the window's context is current
        assert np.mean(off.render(cam) != want) < 1e-3
        r.release()
    off.release()
