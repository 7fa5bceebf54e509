"""Where an interactive screen draws: a window on a display, or an off-screen framebuffer.

The modelling screen (:mod:`vebuild.edit.screen`) draws through this small interface so that the
same code runs in a glfw :class:`~vebuild.gl.window.Window` and, for its benchmark, off-screen on
the shared headless context (:func:`~vebuild.gl.context.headless_context`), with the input events
fed by the caller instead of the window system.

Sizes: ``size()`` is in window coordinates (where the mouse and ImGui live), ``framebuffer_size()``
in pixels of the framebuffer (larger on a high-density screen; the same off-screen).
"""

from __future__ import annotations

import time

import moderngl
import numpy as np
from numpy.typing import NDArray

from vebuild.gl.window import Window


class WindowSurface:
    """A glfw window: its framebuffer, events and buffer swaps."""

    def __init__(self, window: Window):
        self.window = window
        self.ctx = window.ctx
        self.handle = window.handle

    @property
    def fbo(self) -> moderngl.Framebuffer:
        return self.ctx.screen

    def size(self) -> tuple[int, int]:
        import glfw

        w, h = glfw.get_window_size(self.handle)
        return int(w), int(h)

    def framebuffer_size(self) -> tuple[int, int]:
        return self.window.framebuffer_size()

    def make_current(self) -> None:
        self.window.make_current()

    def poll(self) -> None:
        self.window.poll()

    def swap(self) -> None:
        self.window.swap()

    def should_close(self) -> bool:
        return self.window.should_close()

    def time(self) -> float:
        return time.perf_counter()

    def read(self) -> NDArray[np.uint8]:
        """What the framebuffer holds, (h, w, 3) in image order (row 0 at the top)."""
        return _read(self.fbo, self.framebuffer_size())


class OffscreenSurface:
    """A colour framebuffer of ``width`` × ``height`` on ``ctx`` (no events; they are fed by hand).
    Rows are stored as a window's are (row 0 at the bottom), so that what draws into a window
    draws here unchanged; :meth:`read` returns image order."""

    handle = None

    def __init__(self, ctx: moderngl.Context, width: int, height: int):
        self.ctx = ctx
        self._size = (int(width), int(height))
        self._colour = ctx.renderbuffer(self._size, 4)
        self.fbo = ctx.framebuffer(color_attachments=[self._colour])

    def size(self) -> tuple[int, int]:
        return self._size

    def make_current(self) -> None:
        self.ctx.__enter__()  # the shared headless context: what off-screen work uses too

    def framebuffer_size(self) -> tuple[int, int]:
        return self._size

    def poll(self) -> None:
        pass

    def swap(self) -> None:
        pass

    def should_close(self) -> bool:
        return False

    def time(self) -> float:
        return time.perf_counter()

    def read(self) -> NDArray[np.uint8]:
        return _read(self.fbo, self._size)

    def release(self) -> None:
        self.fbo.release()
        self._colour.release()


def _read(fbo: moderngl.Framebuffer, size: tuple[int, int]) -> NDArray[np.uint8]:
    w, h = size
    data = fbo.read(viewport=(0, 0, w, h), components=3, alignment=1)
    return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()
