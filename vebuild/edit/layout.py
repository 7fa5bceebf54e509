"""The modelling screen's layout and the things its parts share: the window's regions, the zoom and
picking constants, the tools, colour packing, and :class:`EditorPart`, the base of the parts
(:mod:`.tools`, :mod:`.photo_view`, :mod:`.bars`, :mod:`.preview`) that make
:class:`~vebuild.edit.screen.Editor` up."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import moderngl

from .overlay import Overlay

#: Layout, in window pixels.
TOOLBAR_H = 62
STRIP_H = 124
PANEL_W = 390
PREVIEW_H = 250
THUMB_H = 72
#: Zoom (window pixels per photo pixel) is kept within [fit / 4, MAX_ZOOM].
MAX_ZOOM = 16.0
WHEEL_STEP = 1.25
#: Vertices, segment ends and markers are picked within this many window pixels of the cursor.
PICK_RADIUS_PX = 8.0
#: A press and release closer than this (window pixels) is a click, not a drag.
CLICK_SLOP_PX = 3.0
#: The magnifier: its side (window pixels) and magnification relative to the photo's pixels.
MAGNIFIER_PX = 168
MAGNIFIER_ZOOM = 6.0
#: Above this zoom the photo is drawn with nearest-texel filtering (its pixels seen as squares).
NEAREST_ABOVE_ZOOM = 2.0
#: Full-resolution photos kept as textures (the current one and the last few shown).
PHOTO_CACHE = 3
PREVIEW_FOV_DEG = 50.0

TOOLS = {"select": "Select", "x": "Segment X", "y": "Segment Y", "z": "Segment Z", "marker": "Marker",
         "edge": "Edge", "length": "Known length", "relate": "Relate", "delete": "Delete",
         "measure": "Measure", "evidence": "Evidence marker", "trajectory": "Trajectory", "room": "Room",
         "opening": "Opening", "box": "Box"}
TOOL_HINTS = {"select": "drag a vertex; click an edge to select its primitive",
              "x": "press, drag along an edge toward +x, release", "y": "press, drag along an edge toward +y, release",
              "z": "press, drag along an edge toward +z (up), release", "marker": "click where the marker is",
              "edge": "press, drag along an edge of the selected primitive, release",
              "length": "press on a known length's end (a vertical's foot on the floor first), drag to its other end, "
                        "release; then type its metres in the Scale tab",
              "relate": "click a face of one node, then a face of another (Shift+click: an edge), then Flush (F) "
                        "or Aligned (A)",
              "delete": "click a segment, a middle point, a marker, a known length or a drawn edge to remove it",
              "measure": "click two points (distance), a point (height) or an object (dimensions), with 1σ and 95 %; "
                         "with no solved model, on a calibrated photo alone: the points the message line names; "
                         "T again: the next measurement",
              "evidence": "click a surface to place an evidence marker, click a marker to remove it",
              "trajectory": "click the entry hole, then the exit hole: the path with its cone",
              "room": "click the floor's corners in turn, then the first again (or Enter); then a wall's top above a "
                      "corner, or type the height; untick the walls the photos do not show in the Model tab",
              "opening": "click a doorway's or window's two bottom corners on the wall, then its top",
              "box": "click three corners of its footprint on the floor in turn, then its top above a corner (or "
                     "type the height)"}
#: Ctrl+click with a Segment tool adds a middle point to the segment of that axis whose path passes
#: within this many window pixels (more than the picking radius: a lens bends an edge away from the
#: straight line between the segment's ends).
MIDDLE_PICK_PX = 3 * PICK_RADIUS_PX
#: What the Segment tools' tooltips add: what their middle points are and what they are for.
MIDDLE_POINT_HINT = ("; Ctrl+click on a segment adds a middle point where the edge runs, Shift+click clicks a polyline "
                     "point by point: a long edge's bend measures the lens distortion")
Rect = tuple[float, float, float, float]


@functools.lru_cache(maxsize=256)
def u32(rgba: tuple[float, float, float, float]) -> int:
    r, g, b, a = (min(255, max(0, int(round(c * 255)))) for c in rgba)
    return (a << 24) | (b << 16) | (g << 8) | r


def inside(rect: Rect, x: float, y: float) -> bool:
    return rect[0] <= x < rect[2] and rect[1] <= y < rect[3]


class EditorPart:
    """A part of the :class:`~vebuild.edit.screen.Editor`, mixed into it: its methods read and set
    the editor's state, declared here and set in ``Editor.__init__``; what one part calls of
    another is the editor's (the type checker sees it through ``__getattr__``)."""

    session: Any
    ctx: moderngl.Context
    _cursor: tuple[float, float]
    _held: set[int]
    _mods: int
    gui: Any
    panels: Any
    photo: str | None
    selected: str | None
    selected_nodes: list[str]
    widget_rects: dict[str, Rect]
    _rects: dict[str, Rect]
    drag_problem: str | None
    last_feedback: Any
    timings: dict[str, float]
    _press: dict[str, Any] | None
    _pan_from: tuple[float, float] | None
    _pending_drag: tuple[float, float] | None
    _placing: dict[str, Any] | None
    pending_length: dict[str, Any] | None
    open_polyline: dict[str, Any] | None
    _photo_tex: dict[str, moderngl.Texture]
    _photo_errors: dict[str, str]
    _thumbs: dict[str, moderngl.Texture | None]
    _overlay_key: Any
    _overlay: Overlay | None
    _pending: Callable[[], None] | None
    _busy: str | None
    _frame_cache: moderngl.Framebuffer | None
    _frame_cache_rb: moderngl.Renderbuffer | None
    _frame_cache_press: dict[str, Any] | None
    _view_cache: moderngl.Framebuffer | None
    _view_cache_rb: moderngl.Renderbuffer | None
    _view_cache_key: Any
    calibration_result: dict[str, Any] | None
    calibration_error: str | None
    solve_result: dict[str, Any] | None
    solve_error: str | None
    _renderer: Any
    _renderer_pages: Any
    _preview_key: Any
    _preview_tex: moderngl.Texture | None
    _preview_shape: Any
    _preview_pages: tuple[Any, list[Any]] | None
    zoom: float
    pan: tuple[float, float]
    tool: str
    show_labels: bool
    _scroll_to_selected: bool
    _progress: tuple[float, str]
    _progress_shown: float
    _recovery_asked: bool
    _close_warned: bool
    _frame_cache_serial: int
    marker_name: str
    _marker_name_default: bool
    add_photo_path: str
    preview_size: tuple[int, int]
    preview_yaw: float
    preview_pitch: float
    preview_distance: float | None
    preview_note: str

    if TYPE_CHECKING:
        def __getattr__(self, name: str) -> Any: ...
