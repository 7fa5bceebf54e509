"""On-screen windows: a glfw window with an OpenGL 3.3 core context wrapped by moderngl.

The one place that opens windows (the headless contexts are made in :mod:`vebuild.gl.context`).
A window draws with the same :class:`~vebuild.render.renderer.Renderer` as off-screen rendering,
into its framebuffer (``ctx.screen``) with ``flip=True``. Quad-buffered stereo is asked for where
wanted; whether the display gave it is :attr:`Window.stereo` (most desktop drivers, and every
software one, do not offer it: :attr:`Window.stereo_note` then says so).
"""

from __future__ import annotations

import ctypes
import os
from typing import Any

import glfw
import moderngl

from vebuild.errors import VebuildError
from vebuild.gl import context
from vebuild.gl.context import REQUIRED_VERSION

GL_BACK_LEFT = 0x0402
GL_BACK_RIGHT = 0x0403

NO_DISPLAY_HINT = ("vebuild opens its window on a screen; there is none here (no DISPLAY or WAYLAND_DISPLAY). "
                   "To make images without a screen use `vebuild render` (evidence views) or `vebuild video`; "
                   "to test windows on a server, run under a virtual X server such as `xvfb-run`.")


class WindowUnavailableError(VebuildError):
    """No window could be opened; the message says why and what to use instead."""


_errors: list[str] = []


def _on_error(code: int, message: bytes | str) -> None:
    _errors.append(message.decode() if isinstance(message, bytes) else str(message))


class _GlfwLoader:
    """moderngl's loader interface over glfw's proc addresses (the window's context is current);
    entering it (``ctx.__enter__()``, :func:`vebuild.gl.context.make_current`) makes the window's
    context current again."""

    def __init__(self) -> None:
        self.handle: Any = None

    def __enter__(self) -> None:
        if self.handle is not None:
            glfw.make_context_current(self.handle)

    def __exit__(self, *exc: object) -> None:
        pass

    def load_opengl_function(self, name: str) -> int:
        return int(glfw.get_proc_address(name) or 0)

    def release(self) -> None:
        pass


class Window:
    """A window with a current OpenGL context (``ctx``).

    Parameters
    ----------
    width, height : size of the window's drawable area in pixels (the framebuffer may be larger
        on a high-density screen: see :meth:`framebuffer_size`).
    title : the title bar's text.
    stereo : ask for a quad-buffered stereo context (left and right back buffers).
    samples : multisampling of the window's framebuffer (0: none).
    visible : show the window (tests draw into hidden ones).
    """

    def __init__(self, width: int, height: int, title: str = "vebuild", *, stereo: bool = False, samples: int = 0,
                 visible: bool = True, vsync: bool = False) -> None:
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            raise WindowUnavailableError(NO_DISPLAY_HINT)
        glfw.set_error_callback(_on_error)
        _errors.clear()
        if not glfw.init():
            why = "; ".join(_errors) or "glfw.init failed"
            raise WindowUnavailableError(f"cannot start the window system ({why}). " + NO_DISPLAY_HINT)
        self.stereo_note = ""
        win = None
        for want_stereo in ((True, False) if stereo else (False,)):
            glfw.default_window_hints()
            glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, REQUIRED_VERSION // 100)
            glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, REQUIRED_VERSION // 10 % 10)
            glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
            glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
            glfw.window_hint(glfw.SAMPLES, int(samples))
            glfw.window_hint(glfw.STEREO, want_stereo)
            glfw.window_hint(glfw.VISIBLE, visible)
            # EGL, as the off-screen contexts: GLX beside a current EGL context fails. EGL has no
            # quad-buffered stereo, so a stereo window asks the native API (GLX) when this process
            # has made no off-screen context.
            native = want_stereo and context._context is None
            glfw.window_hint(glfw.CONTEXT_CREATION_API, glfw.NATIVE_CONTEXT_API if native else glfw.EGL_CONTEXT_API)
            _errors.clear()
            win = glfw.create_window(int(width), int(height), title, None, None)
            if win:
                break
            if want_stereo:
                self.stereo_note = ("this display offers no quad-buffered stereo context "
                                    f"({'; '.join(_errors) or 'no stereo visual'}); use sbs, tb or anaglyph")
        if not win:
            reason = "; ".join(_errors) or "unknown reason"
            glfw.terminate()
            version = f"{REQUIRED_VERSION // 100}.{REQUIRED_VERSION // 10 % 10}"
            raise WindowUnavailableError(f"cannot open an OpenGL {version} window ({reason}). To make images without "
                                         "a window use `vebuild render`.")
        self.handle: Any = win
        glfw.make_context_current(win)
        glfw.swap_interval(1 if vsync else 0)
        self._loader = loader = _GlfwLoader()
        loader.handle = win
        moderngl.init_context(loader)  # GL entry points through glfw (its EGL)
        self.ctx = moderngl.get_context()
        if self.ctx.version_code < REQUIRED_VERSION:
            self.close()
            raise WindowUnavailableError(f"the window's OpenGL is version {self.ctx.version_code / 100:.1f}; vebuild "
                                         f"needs {REQUIRED_VERSION / 100:.1f}")
        self.stereo = bool(glfw.get_window_attrib(win, glfw.STEREO)) if stereo else False
        self._draw_buffer = None
        if self.stereo:
            proc = glfw.get_proc_address("glDrawBuffer")
            self._draw_buffer = ctypes.CFUNCTYPE(None, ctypes.c_uint)(int(proc or 0))

    def select_buffer(self, side: str) -> None:
        """Draw into the ``"left"`` or ``"right"`` back buffer (quad-buffered stereo only)."""
        if self._draw_buffer is None:
            raise VebuildError("this window has no left and right buffers (no quad-buffered stereo); "
                               + (self.stereo_note or "open it with stereo=True"))
        self._draw_buffer(GL_BACK_LEFT if side == "left" else GL_BACK_RIGHT)

    def framebuffer_size(self) -> tuple[int, int]:
        w, h = glfw.get_framebuffer_size(self.handle)
        return int(w), int(h)

    def should_close(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def swap(self) -> None:
        glfw.swap_buffers(self.handle)

    def poll(self) -> None:
        """Handle events, the window's context current (off-screen work between frames, such as
        an in-process render on the shared headless context, makes that one current)."""
        self.make_current()
        glfw.poll_events()

    def close(self) -> None:
        """Destroy the window; an off-screen context made before it is current again."""
        if self.handle is not None:
            from vebuild.gl.shaders import forget_context

            forget_context(self.ctx)
            self.ctx.release()
            glfw.destroy_window(self.handle)
            self.handle = self._loader.handle = None
            glfw.terminate()
            if context._context is not None:
                context._context.__enter__()  # the shared headless context, current again

    def make_current(self) -> None:
        """Make the window's context current again (off-screen work, such as texture extraction on
        the shared headless context, makes that one current)."""
        glfw.make_context_current(self.handle)

    def __enter__(self) -> Window:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
