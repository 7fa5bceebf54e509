"""Headless OpenGL contexts: moderngl on EGL (Mesa's llvmpipe where there is no GPU).

Everything that renders off-screen asks :func:`headless_context` for its context; one context is
made per process and shared. Set ``VEBUILD_GL_BACKEND`` to choose another moderngl backend (the
default is ``egl``).
"""

from __future__ import annotations

import os
import threading
from typing import Any

import moderngl

from vebuild.errors import VebuildError

#: Core profile 3.3 is all vebuild's shaders need.
REQUIRED_VERSION = 330

INSTALL_HINT = (
    "vebuild renders off-screen through EGL. On Debian or Ubuntu install Mesa's EGL and its "
    "software renderer with `sudo apt-get install libegl1 libgl1-mesa-dri libegl-mesa0`; on Fedora "
    "`sudo dnf install mesa-libEGL mesa-dri-drivers`. With an NVIDIA GPU, its driver provides EGL."
)

_lock = threading.Lock()
_context: moderngl.Context | None = None


class GLUnavailableError(VebuildError):
    """No OpenGL context could be made; the message says what to install."""


def headless_context() -> moderngl.Context:
    """The process's shared off-screen context (made on first use)."""
    global _context
    with _lock:
        if _context is None:
            backend = os.environ.get("VEBUILD_GL_BACKEND", "egl")
            try:
                settings: dict[str, Any] = {"backend": backend}
                ctx = moderngl.create_standalone_context(require=REQUIRED_VERSION, **settings)
            except Exception as e:  # moderngl raises plain Exception for a missing library or display
                raise GLUnavailableError(
                    f"cannot create an OpenGL {REQUIRED_VERSION // 100}.{REQUIRED_VERSION // 10 % 10} "
                    f"context with the '{backend}' backend ({str(e).strip() or type(e).__name__}). "
                    + INSTALL_HINT) from None
            _context = ctx
        return _context


def make_current(ctx: moderngl.Context) -> None:
    """Make ``ctx`` the thread's current context. GL calls go to whichever context is current, not
    to the one whose objects they name: making the shared headless context (on first use) makes it
    current over a window's, and a window's drawing between off-screen work would go astray. A
    released context (a closed window's) is left alone: its objects went with it."""
    if not isinstance(ctx.mglo, moderngl.InvalidObject):
        ctx.__enter__()


def max_texture_size(ctx: moderngl.Context) -> int:
    """GL_MAX_TEXTURE_SIZE: the longest side of a texture or render target."""
    return int(ctx.info["GL_MAX_TEXTURE_SIZE"])


def renderer_name(ctx: moderngl.Context) -> str:
    """The GL renderer and version, for reports and benchmarks."""
    return f"{ctx.info['GL_RENDERER']} ({ctx.info['GL_VERSION']})"
