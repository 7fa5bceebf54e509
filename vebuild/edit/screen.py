"""``vebuild edit``: the interactive modelling screen (paper §2–3.2, Figures 1–3, 5 and 7).

A photo at full resolution with zoom and pan, the project's photos in a strip below it, what
:meth:`~vebuild.edit.session.EditSession.overlay` says to draw over it, and panels (Dear ImGui)
for the tools, the calibration, the model and a 3-D preview. All the edit logic is the
:class:`~vebuild.edit.session.EditSession`'s; this module maps the mouse and keys to its calls and
draws. It draws into a :mod:`vebuild.gl.surface`: a window, or an off-screen framebuffer (the
benchmark, ``vebuild bench edit``).

Its keys and mouse: :data:`vebuild.edit.keys.EDITOR_KEYS` (the Keys tab lists them).

Tests and the benchmark drive it through :meth:`Editor.on_cursor`, :meth:`Editor.on_button`,
:meth:`Editor.on_key` (or real events in a window), and find things on screen with
:meth:`Editor.image_to_window` / :meth:`Editor.window_to_image` and :attr:`Editor.widget_rects`
(each drawn ImGui widget's rectangle, in window coordinates, by its label).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import imgui_bundle
import numpy as np
from imgui_bundle import imgui

from vebuild.errors import VebuildError
from vebuild.gl.app import WindowApp
from vebuild.gl.imgui import Gui
from vebuild.gl.surface import OffscreenSurface, WindowSurface

from .assist_keys import AssistKeys
from .bars import Bars
from .click_tools import ClickTools
from .entry_keys import EntryKeys
from .first_steps import FirstSteps
from .keys import EDITOR_KEYS
from .layers import OverlayLayers
from .layout import MAX_ZOOM, PANEL_W, PREVIEW_H, STRIP_H, TOOLBAR_H, Rect
from .measure_tool import MeasureTool
from .messages import MessageArea
from .overlay import Overlay
from .panels import Panels
from .photo_view import PhotoView
from .preview import Preview
from .relate_tool import RelateTool
from .tools import ScreenTools


class Editor(FirstSteps, EntryKeys, AssistKeys, OverlayLayers, MessageArea, ScreenTools, MeasureTool, RelateTool,
             ClickTools, PhotoView, Bars, Preview, WindowApp):
    """The modelling screen over one :class:`~vebuild.edit.session.EditSession`, drawing into one
    surface (:class:`~vebuild.gl.surface.WindowSurface` or :class:`~vebuild.gl.surface.OffscreenSurface`).
    :meth:`frame` polls, draws and runs what a button asked for; :meth:`draw` only draws."""

    keys = EDITOR_KEYS

    def __init__(self, session: Any, surface: WindowSurface | OffscreenSurface):
        super().__init__()
        self.session = session
        self.surface = surface
        self.ctx = surface.ctx
        font_file = Path(imgui_bundle.__file__).parent / "assets" / "fonts" / "DroidSans.ttf"
        font = str(font_file) if font_file.is_file() else None  # the messages' –, …, σ, ≥ (ImGui's own font lacks them)
        if surface.handle is not None:
            self.gui = Gui(self.ctx, surface.handle, font=font)
        else:
            self.gui = Gui(self.ctx, None, display_size=surface.size(), target=surface.fbo, font=font)
        self.photo = None
        self.zoom = 1.0
        self.pan = (0.0, 0.0)  # window position of the photo's top-left corner
        self.tool = "select"
        self.show_labels = True  # residuals and names over the photo (L)
        self.selected = None
        self.selected_nodes = []
        self._scroll_to_selected = False
        self.widget_rects = {}
        self._rects = {}
        self.drag_problem = None
        self.last_feedback = None
        self.timings = {}  # the last frame's drag solve and draw, milliseconds
        self._press = None
        self._pan_from = None
        self._pending_drag = None
        self._placing = None
        self.open_polyline = None  # a polyline being clicked with Shift: its axis, photo and points
        self.pending_length = None  # a known length's two ends drawn, its metres not typed yet
        self.relate_picks = []  # the faces (or edges) picked with the Relate tool, up to two
        self.relate_offset = ""  # a flush offset typed in the Relate popup (metres)
        self._relate_popup = False
        self._relate_popup_shown = False
        self._photo_tex = {}
        self._photo_errors = {}
        self._thumbs = {}
        self._overlay_key = None
        self._overlay = None
        self._pending = None
        self._busy = None
        self._progress = (0.0, "")
        self._progress_shown = 0.0
        self._recovery_asked = False
        self._close_warned = False
        self._frame_cache = None
        self._frame_cache_rb = None
        self._frame_cache_press = None
        self._frame_cache_serial = 0
        self._view_cache = None
        self._view_cache_rb = None
        self._view_cache_key = None
        # panel state
        self.marker_name = session.next_marker_name()
        self._marker_name_default = True
        self.add_photo_path = ""
        self.calibration_result = None
        self.calibration_error = None
        self.solve_result = None
        self.solve_error = None
        self.panels = Panels(self)
        # 3-D preview
        self.preview_size = (PANEL_W - 20, PREVIEW_H - 44)
        self.preview_yaw, self.preview_pitch, self.preview_distance = math.radians(-60.0), math.radians(30.0), None
        self._renderer = None
        self._renderer_pages = None
        self._preview_key = None
        self._preview_tex = None
        self._preview_shape = None
        self._preview_pages = None
        self.preview_note = ""
        if surface.handle is not None:
            self.install_callbacks(surface.handle)
        self.first_steps_init(surface.handle)  # the guide for a new project, the help, the browser, drops
        if session.photo_ids:
            self.set_photo(session.photo_ids[0])

    # -- messages -----------------------------------------------------------------------------------

    @property
    def messages(self) -> list[str]:
        return self.session.messages

    def say(self, text: str) -> None:
        self.session.say(text)

    # -- geometry -----------------------------------------------------------------------------------

    def size(self) -> tuple[int, int]:
        return self.gui.size()

    def view_rect(self) -> Rect:
        """Where the photo is shown, window coordinates (x0, y0, x1, y1)."""
        W, H = self.size()
        return 0.0, float(TOOLBAR_H), float(max(W - PANEL_W, 100)), float(max(H - STRIP_H, TOOLBAR_H + 100))

    def panels_rect(self) -> Rect:
        """Where the Calibration and Model panels are, window coordinates (x0, y0, x1, y1)."""
        W, H = self.size()
        return float(W - PANEL_W), 0.0, float(W), float(H - PREVIEW_H)

    def photo_size(self, photo: str | None = None) -> tuple[int, int]:
        p = self.session.photo(photo or self.photo)
        return int(p["width"]), int(p["height"])

    def fit_zoom(self) -> float:
        x0, y0, x1, y1 = self.view_rect()
        w, h = self.photo_size()
        return min((x1 - x0) / w, (y1 - y0) / h)

    def fit(self) -> None:
        """The whole photo, centred in the view."""
        if self.photo is None:
            return
        x0, y0, x1, y1 = self.view_rect()
        w, h = self.photo_size()
        self.zoom = self.fit_zoom()
        self.pan = (x0 + 0.5 * (x1 - x0 - self.zoom * w), y0 + 0.5 * (y1 - y0 - self.zoom * h))

    def _check_photo(self, photo: str | None) -> None:
        if photo is not None and photo != self.photo:
            raise VebuildError(f"photo '{photo}' is not the one shown ('{self.photo}'); show it first")

    def image_to_window(self, photo: str | None, uv: Any) -> tuple[float, float]:
        """Window coordinates of photo pixel coordinates (u, v) (photo: the one shown, or None)."""
        self._check_photo(photo)
        return self.pan[0] + self.zoom * float(uv[0]), self.pan[1] + self.zoom * float(uv[1])

    def window_to_image(self, x: float, y: float) -> tuple[float, float]:
        """Photo pixel coordinates (sub-pixel) under window position (x, y)."""
        return (float(x) - self.pan[0]) / self.zoom, (float(y) - self.pan[1]) / self.zoom

    def zoom_at(self, x: float, y: float, factor: float) -> None:
        """Zoom by ``factor`` keeping the photo point under (x, y) where it is."""
        if self.photo is None:
            return
        u, v = self.window_to_image(x, y)
        self.zoom = float(np.clip(self.zoom * factor, self.fit_zoom() / 4.0, MAX_ZOOM))
        self.pan = (x - self.zoom * u, y - self.zoom * v)

    def set_view(self, zoom: float, centre_uv: tuple[float, float]) -> None:
        """Show photo point ``centre_uv`` at the view's centre at ``zoom`` (window px per photo px)."""
        x0, y0, x1, y1 = self.view_rect()
        self.zoom = float(np.clip(zoom, self.fit_zoom() / 4.0, MAX_ZOOM))
        self.pan = (0.5 * (x0 + x1) - self.zoom * centre_uv[0], 0.5 * (y0 + y1) - self.zoom * centre_uv[1])

    # -- photos -------------------------------------------------------------------------------------

    def set_photo(self, photo: str) -> None:
        """Show this photo (loading it if need be; a photo that fails to load shows a placeholder
        and its error)."""
        if photo not in self.session.photo_ids:
            raise VebuildError(f"the project has no photo '{photo}'")
        if self.session.dragging:
            self.session.cancel_drag()
        self._press = None
        changed, self.photo = photo != self.photo, photo
        if changed and self._marker_name_default:
            self.offer_marker()  # the first marker this photo lacks (entry_keys.py)
        if self._photo_texture(photo) is None:
            self.say(self._photo_errors.get(photo, f"photo '{photo}' cannot be shown"))
        self.fit()

    def step_photo(self, step: int) -> None:
        ids = self.session.photo_ids
        if not ids:
            return
        i = ids.index(self.photo) if self.photo in ids else -1
        self.set_photo(ids[(i + step) % len(ids)])

    # -- overlay ------------------------------------------------------------------------------------

    def overlay(self) -> Overlay | None:
        """What to draw over the shown photo (cached per session revision, photo and selection)."""
        if self.photo is None:
            return None
        key = (self.session.revision, self.photo, self.selected)
        if key != self._overlay_key:
            t0 = time.perf_counter()
            self._overlay = self.guard(self.session.overlay, self.photo, self.selected)
            self._overlay_key = key
            self.timings["overlay_ms"] = 1e3 * (time.perf_counter() - t0)
        return self._overlay

    # -- input --------------------------------------------------------------------------------------

    # -- long actions ---------------------------------------------------------------------------------

    def later(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` after this frame is drawn (a button's long action, with progress frames)."""
        self._pending = fn

    def _progress_fn(self, title: str) -> Callable[[float, str], None]:
        def progress(fraction: float, text: str) -> None:
            self._progress = (float(fraction), text or title)
            now = time.perf_counter()
            if now - self._progress_shown > 0.05:
                self._progress_shown = now
                self.surface.poll()
                self.draw()
                self.surface.swap()
        return progress

    def _long(self, title: str, fn: Callable[[Callable[[float, str], None]], Any]) -> tuple[Any, str | None]:
        self._busy = title
        self._progress = (0.0, title)
        self._progress_shown = 0.0
        try:
            return fn(self._progress_fn(title)), None
        except VebuildError as e:
            self.say(str(e))
            return None, str(e)
        finally:
            self._busy = None

    def calibrate(self) -> None:
        self.calibration_result, self.calibration_error = self._long("calibrating", self.session.calibrate)

    def solve(self, recalibrate: bool = False) -> None:
        self.solve_result, self.solve_error = self._long(
            "re-calibrating" if recalibrate else "solving",
            lambda progress: self.session.solve(recalibrate=recalibrate, progress=progress))

    def extract_textures(self) -> None:
        """Texture extraction draws on the shared off-screen context; the progress frames, and
        everything after, on the screen's."""
        from vebuild.gl.context import headless_context

        def work(progress: Callable[[float, str], None]) -> Any:
            def shown(fraction: float, text: str) -> None:
                self.surface.make_current()
                progress(fraction, text)
                headless_context().__enter__()

            headless_context().__enter__()
            try:
                return self.session.texture(shown)
            finally:
                self.surface.make_current()

        self._long("extracting textures", work)

    # -- frames -------------------------------------------------------------------------------------

    def frame(self) -> None:
        """Poll events, draw, swap, then run what a button asked for."""
        self.surface.poll()
        self.draw()
        self.surface.swap()
        if self._pending is not None:
            fn, self._pending = self._pending, None
            fn()

    def draw(self) -> None:
        t0 = time.perf_counter()
        if not self._busy:
            self._apply_pending_drag()
            self._load_next_thumbnail()
            self._update_preview()
            self._update_visibility()  # the photo's hidden model edges (layers.py)
        fbo = self.surface.fbo
        fw, fh = self.surface.framebuffer_size()
        fbo.use()
        fbo.viewport = (0, 0, fw, fh)
        # During a drag only the photo view changes: the toolbar, strip and panels are copied from the
        # frame drawn when the vertex was pressed (a plain copy, where drawing them again costs a
        # software renderer as much as the solve), and updated again on release.
        # The photo and what does not move are drawn once too, at the drag's first move, and copied
        # again for every move after it: each move draws only the moving primitives over them.
        live = self._drag_frame_cached((fw, fh))
        if live:
            self._cache_still_view(fbo, (fw, fh))
            assert self._view_cache is not None  # made by _cache_still_view
            self.ctx.copy_framebuffer(fbo, self._view_cache)
            x0, _, x1, _ = self._view_pixels((fw, fh))  # the toolbar is drawn anew: its status line
            th = int(math.ceil(TOOLBAR_H * fh / max(self.size()[1], 1)))  # follows the cursor
            fbo.clear(0.11, 0.11, 0.12, 1.0, viewport=(x0, fh - th, x1 - x0, th))
        else:
            fbo.clear(0.11, 0.11, 0.12, 1.0)
        self.gui.new_frame()
        self._rects = {}
        imgui.begin_disabled(self._busy is not None)
        self._draw_photo_view("moving" if live else "all")
        if not live:
            self._draw_measures()  # what was measured by clicking (measure_tool.py)
            self._draw_build()  # the corners clicked so far with Room, Opening or Box (click_tools.py)
        self._draw_toolbar()
        if not live:
            self._draw_strip()
            self.panels.draw()
            self._draw_preview()
        elif self.preview_following():  # the preview follows a drag now and then (preview.py)
            self._draw_preview_image()
        imgui.end_disabled()
        self._draw_messages()
        self._draw_magnifier()
        if not live:
            self._draw_recovery()
            self._draw_relate_popup()
            self._draw_layers_popup()
            self._draw_first_steps()
        self._draw_busy()
        self.gui.render()
        self.widget_rects = {**self.widget_rects, **self._rects} if live else self._rects
        if not live and self._press is not None and self._press.get("kind") == "handle":
            self._cache_frame((fw, fh))
        self.timings["draw_ms"] = 1e3 * (time.perf_counter() - t0)

    def rect(self, label: str) -> bool:
        """Record the last item's rectangle under ``label``, the part of it its window shows (an item
        scrolled out of view is not recorded); returns whether it is wholly shown."""
        mn, mx = imgui.get_item_rect_min(), imgui.get_item_rect_max()
        wp, ws = imgui.get_window_pos(), imgui.get_window_size()
        x0, y0, x1, y1 = max(mn.x, wp.x), max(mn.y, wp.y), min(mx.x, wp.x + ws.x), min(mx.y, wp.y + ws.y)
        if x1 > x0 and y1 > y0:
            self._rects[label] = (x0, y0, x1, y1)
        return (x0, y0, x1, y1) == (mn.x, mn.y, mx.x, mx.y)

    def button(self, label: str, size: tuple[float, float] | None = None, tip: str | None = None) -> bool:
        clicked = imgui.button(label, size) if size is not None else imgui.button(label)
        self.rect(label)
        if tip:
            imgui.set_item_tooltip(tip)
        return bool(clicked)

    def combo(self, label: str, index: int, items: list[str]) -> int:
        """A drop-down list; its rectangle is recorded as ``label`` and, while open, each item's as
        ``label:item``. Returns the chosen index."""
        opened = imgui.begin_combo(f"##{label}", items[index] if 0 <= index < len(items) else "",
                                   imgui.ComboFlags_.height_largest)  # as many items as the screen holds
        self.rect(label)
        if opened:
            for i, item in enumerate(items):
                if imgui.selectable(f"{item}##{label}{i}", i == index)[0]:
                    index = i
                self.rect(f"{label}:{item}")
            imgui.end_combo()
        return index

    def fixed_window(self, name: str, rect: Rect, flags: int = 0) -> None:
        imgui.set_next_window_pos((rect[0], rect[1]), imgui.Cond_.always)
        imgui.set_next_window_size((rect[2] - rect[0], rect[3] - rect[1]), imgui.Cond_.always)
        imgui.begin(name, None, flags | imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize
                    | imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.no_bring_to_front_on_focus)
        self._rects[name] = rect

    # -- the photo view -----------------------------------------------------------------------------

    # -- toolbar, strip, messages -------------------------------------------------------------------

    # -- 3-D preview --------------------------------------------------------------------------------

    # -- end ----------------------------------------------------------------------------------------

    def close(self) -> None:
        if self.session.dragging:
            self.session.cancel_drag()
        self._release_frame_cache()
        self.gui.release()
        for t in list(self._photo_tex.values()) + [t for t in self._thumbs.values() if t is not None]:
            t.release()
        self._photo_tex.clear()
        self._thumbs.clear()
        if self._renderer is not None:
            self._renderer.release()
            self._renderer = None


def run_editor(path: str | Path, size: tuple[int, int] = (1400, 860), recover: bool | None = None,
               add_photos: tuple[str, ...] | list[str] = (), frames: int | None = None) -> Any:
    """Open the project in the modelling screen and run until the window closes (or ``frames``
    frames). ``recover``: take (True) or discard (False) an autosave's edits; None asks on screen.
    Returns the session (its project as left)."""
    from vebuild.edit.session import EditSession
    from vebuild.gl.window import Window

    session = EditSession.open(path, recover=recover)
    with Window(size[0], size[1], f"vebuild edit — {session.project.path.name}") as window:
        editor = Editor(session, WindowSurface(window))
        editor.open_guide_if_new()  # first steps, for a new or empty project
        for f in add_photos:  # in the window, so that a file that cannot be added says so there
            pid = editor.guard(session.add_photo, f)
            if pid is not None:
                editor.set_photo(pid)
        editor.run(window, frames)
    if session.dirty:
        print(f"vebuild edit: the unsaved edits are kept in {session.autosave_path}; opening the project again "
              "offers to recover them (or `vebuild edit --recover`)", file=sys.stderr)
    return session
