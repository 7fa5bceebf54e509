"""The one check of an image size before OpenGL is asked to draw it (no GL here).

Every render — a named view (``$.views[i]``), ``vebuild render --size``, the report's images, a
recorded sight line's witness view, a viewshed map, a video's frames, the viewer's window — passes
its size through :func:`check_render_size` with the place the size came from, so that a size no
OpenGL can draw, or one that would exhaust memory, is refused with a message naming that place
instead of a GL error or a crash in native code. :func:`check_gl_render_size` adds the limits of
the OpenGL context at hand (:func:`gl_max_side`); the renderer calls it before it allocates.

Limits, and why:

- each side 1 … :data:`MAX_SIDE` (16384) pixels: the largest render target that common OpenGL
  implementations (Mesa's llvmpipe, most desktop GPUs) allow, fixed so that a project that renders on
  one machine renders on another; a context with a smaller ``GL_MAX_TEXTURE_SIZE``,
  ``GL_MAX_RENDERBUFFER_SIZE`` or ``GL_MAX_VIEWPORT_DIMS`` lowers it;
- at most :data:`MAX_PIXELS` (64 MiP = 8192 × 8192) pixels in all: a frame is drawn 4×
  multisampled (colour and depth, 8 bytes a sample: 2 GiB at this size), resolved (256 MiB) and read
  back into memory (another 256 MiB and its copies); a larger one runs out of GPU or main memory.
"""

from __future__ import annotations

import numbers
import re
from typing import Any

from vebuild.errors import VebuildError

#: The longest side of any render, in pixels (lowered further by the GL context's own limits).
MAX_SIDE = 16384
#: The most pixels in one render (8192 × 8192); see the module's docstring for why.
MAX_PIXELS = 64 * 1024 * 1024


def _is_int(v: Any) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def check_render_size(width: Any, height: Any, source: str, max_side: int = MAX_SIDE,
                      max_pixels: int = MAX_PIXELS, why_side: str = "",
                      advice: str = "choose a smaller size") -> tuple[int, int]:
    """(width, height) as ints if a render of that size can be drawn; otherwise a
    :class:`VebuildError` naming ``source`` (where the size came from, such as
    ``"$.views[2] (width × height)"`` or ``"--size"``) and what is allowed."""
    allowed = (f"each side 1 to {max_side} pixels{why_side} and at most {max_pixels:,} pixels in all "
               f"({max_pixels / 2**20:g} MP, such as 8192×8192: larger frames exhaust the GPU's and this "
               "machine's memory)")
    if not (_is_int(width) and _is_int(height)):
        raise VebuildError(f"{source}: expected a whole number of pixels on each side, {allowed}; "
                           f"got {width!r}×{height!r}")
    w, h = int(width), int(height)
    if not (1 <= w <= max_side and 1 <= h <= max_side) or w * h > max_pixels:
        raise VebuildError(f"{source}: a {w}×{h} image cannot be rendered: expected {allowed}; {advice}")
    return w, h


def gl_max_side(ctx: Any) -> int:
    """The longest side an OpenGL context can render to: the least of its largest texture,
    renderbuffer and viewport."""
    info = ctx.info
    dims = info.get("GL_MAX_VIEWPORT_DIMS") or ()
    values = [info.get("GL_MAX_TEXTURE_SIZE"), info.get("GL_MAX_RENDERBUFFER_SIZE"), *dims]
    return min(int(v) for v in values if v)


def gl_limits(ctx: Any) -> dict[str, Any]:
    """The keyword arguments of :func:`check_render_size` for an OpenGL context: its
    :func:`gl_max_side`, where that is below :data:`MAX_SIDE`."""
    limit = gl_max_side(ctx)
    return {"max_side": limit, "why_side": " (the most this machine's OpenGL draws)"} if limit < MAX_SIDE else {}


def check_gl_render_size(ctx: Any, width: Any, height: Any, source: str) -> tuple[int, int]:
    """:func:`check_render_size` with the limits of the OpenGL context ``ctx`` as well."""
    return check_render_size(width, height, source, **gl_limits(ctx))


def size_source(cam: Any, default: str = "the image to render") -> str:
    """Where a camera's image size came from (:attr:`ImageCamera.source`), or ``default``."""
    return getattr(cam, "source", "") or default


def check_camera(cam: Any, stereo: str | None = None, **limits: Any) -> tuple[int, int]:
    """The size of the image composed from ``cam`` (``stereo``: None, or the mode: ``sbs`` doubles
    the width, ``tb`` the height), if it can be rendered; else a VebuildError naming
    ``cam.source``. ``limits``: those of :func:`gl_limits`, where a context is at hand."""
    source = size_source(cam)
    w, h = check_render_size(cam.width, cam.height, source, **limits)
    if stereo == "sbs":
        return check_render_size(2 * w, h, f"{source}, in stereo side by side (twice the width)", **limits)
    if stereo == "tb":
        return check_render_size(w, 2 * h, f"{source}, in stereo top and bottom (twice the height)", **limits)
    return w, h


#: The width of the report's image of a view, a photo or a hypothesis, in pixels.
IMAGE_WIDTH = 960


def image_size(width: int, height: int) -> tuple[int, int]:
    """The size of the report's image of a view or photo of ``width`` × ``height`` pixels:
    :data:`IMAGE_WIDTH` wide, its height from their aspect."""
    return IMAGE_WIDTH, max(1, round(IMAGE_WIDTH * height / width))


def parse_size(text: str) -> tuple[int, int]:
    """'1280x720' → (1280, 720); an error saying what was expected otherwise."""
    m = re.fullmatch(r"\s*(\d+)\s*[x×X]\s*(\d+)\s*", text or "")
    if not m or int(m[1]) < 1 or int(m[2]) < 1:
        raise VebuildError(f"--size: expected WIDTHxHEIGHT in pixels, each at least 1 (such as 1280x720), "
                           f"got {text!r}")
    return check_render_size(int(m[1]), int(m[2]), "--size")
