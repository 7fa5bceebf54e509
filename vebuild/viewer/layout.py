"""The size of the walk-through's text and panel, from the window's size and the screen's density.

The walk-through is shown in briefing rooms, on a projector or a large screen, so its text is
sized for the back of the room as well as for the desk:

- **the room**: a capital letter subtends at least :data:`MIN_CAP_ARCMIN` (16 arc minutes, the
  smallest character height ISO 9241-303 allows for reading) at :data:`ROOM_DISTANCE_HEIGHTS`
  picture heights, about where the back row of a briefing room sits. That makes the text a fixed
  fraction of the window's height (:data:`TEXT_FRACTION_OF_HEIGHT`, about 1/30), whatever the
  projector's resolution;
- **the desk**: on a monitor seen from :data:`DESK_DISTANCE_M`, the same angle needs a capital
  letter of about 2.8 mm, so the text is never smaller than that in the screen's own pixels per
  millimetre (glfw's monitor physical size, or its content scale where the monitor does not say).

The larger of the two wins. The panel is as wide as :data:`PANEL_WIDTH_EM` text heights (most of
its lines fit without wrapping), or :data:`PANEL_WIDTH_FRACTION` of the window if that is wider,
and as tall as what it holds, at most the window less a margin. A title longer than the panel is
shortened with "…" (:func:`fit_text`) and given in full on the panel's first line.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: A capital letter's height as a share of the font's size (ImGui's size is the line's em).
CAP_SHARE = 0.7
#: The smallest angle a capital letter may subtend to be read (ISO 9241-303: 16 arc minutes).
MIN_CAP_ARCMIN = 16.0
#: The back row of a briefing room, in picture heights from the screen.
ROOM_DISTANCE_HEIGHTS = 5.0
#: A monitor on a desk is read from about this far (metres).
DESK_DISTANCE_M = 0.6
#: The font's size as a share of the window's height, for the room (about 1/30).
TEXT_FRACTION_OF_HEIGHT = ROOM_DISTANCE_HEIGHTS * math.tan(math.radians(MIN_CAP_ARCMIN / 60.0)) / CAP_SHARE
#: The smallest font (millimetres on the screen), for the desk (about 4 mm).
MIN_TEXT_MM = 1000.0 * DESK_DISTANCE_M * math.tan(math.radians(MIN_CAP_ARCMIN / 60.0)) / CAP_SHARE
#: Where the monitor does not give its physical size: a screen of 96 dots per inch at scale 1.
FALLBACK_PX_PER_MM = 96.0 / 25.4
#: A physical size giving fewer or more pixels per millimetre than this is not believed.
PLAUSIBLE_PX_PER_MM = (1.5, 25.0)
PANEL_WIDTH_EM = 16.0
PANEL_WIDTH_FRACTION = 0.3
#: The panel's distance from the window's edges, in text heights.
MARGIN_EM = 0.5


@dataclass(frozen=True)
class PanelLayout:
    """Sizes in window coordinates (where ImGui and the mouse live)."""

    text_px: float
    x: float
    y: float
    width: float
    max_height: float

    @property
    def scale(self) -> float:
        """The text's size against ImGui's own 13-pixel font (paddings grow with it)."""
        return self.text_px / 13.0


def text_size(window_h: float, px_per_mm: float, framebuffer_scale: float = 1.0) -> float:
    """The font's size (window coordinates) for a window ``window_h`` high on a screen of
    ``px_per_mm`` pixels per millimetre whose framebuffer has ``framebuffer_scale`` pixels per
    window coordinate."""
    room = TEXT_FRACTION_OF_HEIGHT * window_h
    desk = MIN_TEXT_MM * px_per_mm / max(framebuffer_scale, 1e-6)
    return float(max(room, desk))


def panel_layout(window_w: float, window_h: float, px_per_mm: float, framebuffer_scale: float = 1.0) -> PanelLayout:
    """The panel's text size and place: against the window's right edge, below its top."""
    f = text_size(window_h, px_per_mm, framebuffer_scale)
    m = MARGIN_EM * f
    width = max(PANEL_WIDTH_EM * f, PANEL_WIDTH_FRACTION * window_w)
    width = max(1.0, min(width, window_w - 2 * m))
    return PanelLayout(f, window_w - width - m, m, width, max(1.0, window_h - 2 * m))


def screen_px_per_mm(handle: Any) -> float:
    """Pixels per millimetre of the screen a glfw window is on: the monitor's video mode over its
    physical size; where that is missing or implausible, 96 dpi times the window's content scale."""
    import glfw

    monitor = glfw.get_window_monitor(handle) or glfw.get_primary_monitor()
    if monitor:
        mm_w, _ = glfw.get_monitor_physical_size(monitor)
        mode = glfw.get_video_mode(monitor)
        if mm_w and mode is not None:
            d = mode.size.width / mm_w
            if PLAUSIBLE_PX_PER_MM[0] <= d <= PLAUSIBLE_PX_PER_MM[1]:
                return float(d)
    sx, _ = glfw.get_window_content_scale(handle)
    return FALLBACK_PX_PER_MM * float(sx or 1.0)


def fit_text(text: str, width: float, measure: Callable[[str], float]) -> str:
    """``text``, or its longest beginning that with "…" is at most ``width`` wide by ``measure``."""
    if measure(text) <= width:
        return text
    lo, hi = 0, len(text)
    while lo < hi:  # the longest prefix that fits
        mid = (lo + hi + 1) // 2
        if measure(text[:mid].rstrip() + "…") <= width:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo].rstrip() + "…"
