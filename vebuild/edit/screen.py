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

import functools
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import glfw
import imgui_bundle
import moderngl
import numpy as np
from imgui_bundle import imgui

from vebuild.camera import ImageCamera, fov_to_focal, intrinsic_matrix, look_rotation
from vebuild.errors import VebuildError
from vebuild.gl.app import WindowApp
from vebuild.gl.imgui import Gui
from vebuild.gl.surface import OffscreenSurface, WindowSurface

from .keys import EDITOR_KEYS, tool_key
from .overlay import AXIS_COLOURS, RED, Overlay
from .panels import Panels

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
         "edge": "Edge", "delete": "Delete"}
TOOL_HINTS = {"select": "drag a vertex; click an edge to select its primitive",
              "x": "press, drag along an edge toward +x, release", "y": "press, drag along an edge toward +y, release",
              "z": "press, drag along an edge toward +z (up), release", "marker": "click where the marker is",
              "edge": "press, drag along an edge of the selected primitive, release",
              "delete": "click a segment, marker or drawn edge to remove it"}
#: How many messages the message area shows (the latest last).
MESSAGES_SHOWN = 3

Rect = tuple[float, float, float, float]


@functools.lru_cache(maxsize=256)
def _u32(rgba: tuple[float, float, float, float]) -> int:
    r, g, b, a = (min(255, max(0, int(round(c * 255)))) for c in rgba)
    return (a << 24) | (b << 16) | (g << 8) | r


def _inside(rect: Rect, x: float, y: float) -> bool:
    return rect[0] <= x < rect[2] and rect[1] <= y < rect[3]


class Editor(Panels, WindowApp):
    """The modelling screen over one :class:`~vebuild.edit.session.EditSession`, drawing into one
    surface (:class:`~vebuild.gl.surface.WindowSurface` or :class:`~vebuild.gl.surface.OffscreenSurface`).
    :meth:`frame` polls, draws and runs what a button asked for; :meth:`draw` only draws."""

    keys = EDITOR_KEYS

    def __init__(self, session: Any, surface: WindowSurface | OffscreenSurface):
        super().__init__()
        self.session = session
        self.surface = surface
        self.ctx: moderngl.Context = surface.ctx
        font = Path(imgui_bundle.__file__).parent / "assets" / "fonts" / "DroidSans.ttf"
        font = str(font) if font.is_file() else None  # the messages' –, …, σ, ≥ (ImGui's own font lacks them)
        if surface.handle is not None:
            self.gui = Gui(self.ctx, surface.handle, font=font)
        else:
            self.gui = Gui(self.ctx, None, display_size=surface.size(), target=surface.fbo, font=font)
        self.photo: str | None = None
        self.zoom = 1.0
        self.pan = (0.0, 0.0)  # window position of the photo's top-left corner
        self.tool = "select"
        self.show_labels = True  # residuals and names over the photo (L)
        self.selected: str | None = None
        self.selected_nodes: list[str] = []
        self._scroll_to_selected = False
        self.widget_rects: dict[str, Rect] = {}
        self._rects: dict[str, Rect] = {}
        self.drag_problem: str | None = None
        self.last_feedback: Any = None
        self.timings: dict[str, float] = {}  # the last frame's drag solve and draw, milliseconds
        self._press: dict[str, Any] | None = None
        self._pan_from: tuple[float, float] | None = None
        self._pending_drag: tuple[float, float] | None = None
        self._placing: dict[str, Any] | None = None
        self._photo_tex: dict[str, moderngl.Texture] = {}
        self._photo_errors: dict[str, str] = {}
        self._thumbs: dict[str, moderngl.Texture | None] = {}
        self._overlay_key: Any = None
        self._overlay: Overlay | None = None
        self._pending: Callable[[], None] | None = None
        self._busy: str | None = None
        self._progress = (0.0, "")
        self._progress_shown = 0.0
        self._recovery_asked = False
        self._close_warned = False
        self._frame_cache: moderngl.Framebuffer | None = None
        self._frame_cache_rb: moderngl.Renderbuffer | None = None
        self._frame_cache_press: dict[str, Any] | None = None
        self._frame_cache_serial = 0
        self._view_cache: moderngl.Framebuffer | None = None
        self._view_cache_rb: moderngl.Renderbuffer | None = None
        self._view_cache_key: Any = None
        # panel state
        self.marker_name = session.next_marker_name()
        self._marker_name_default = True
        self.add_photo_path = ""
        self.new_kind = 1  # box
        self.new_parent = 0  # (none)
        self.new_name = ""
        self.group_name = "group1"
        self.dist_a, self.dist_b, self.dist_m, self.dist_role = "", "", 1.0, 0
        self.calibration_result: dict[str, Any] | None = None
        self.calibration_error: str | None = None
        self.solve_result: dict[str, Any] | None = None
        self.solve_error: str | None = None
        self._param_edits: dict[str, float] = {}
        # 3-D preview
        self.preview_size = (PANEL_W - 20, PREVIEW_H - 44)
        self.preview_yaw, self.preview_pitch, self.preview_distance = math.radians(-60.0), math.radians(30.0), None
        self._renderer: Any = None
        self._renderer_pages: Any = None
        self._preview_key: Any = None
        self._preview_tex: moderngl.Texture | None = None
        self._preview_shape: Any = None
        self._preview_pages: tuple[Any, list[Any]] | None = None
        self.preview_note = ""
        if surface.handle is not None:
            self.install_callbacks(surface.handle)
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
            raise VebuildError(f"photo '{photo}' is not the one shown ('{self.photo}'); show it first (set_photo)")

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
        self.photo = photo
        if self._photo_texture(photo) is None:
            self.say(self._photo_errors.get(photo, f"photo '{photo}' cannot be shown"))
        self.fit()

    def step_photo(self, step: int) -> None:
        ids = self.session.photo_ids
        if not ids:
            return
        i = ids.index(self.photo) if self.photo in ids else -1
        self.set_photo(ids[(i + step) % len(ids)])

    def _photo_texture(self, photo: str) -> moderngl.Texture | None:
        tex = self._photo_tex.get(photo)
        if tex is not None:
            self._photo_tex[photo] = self._photo_tex.pop(photo)  # most recently used last
            return tex
        try:
            pixels = self.session.photo_pixels(photo)
        except VebuildError as e:
            self._photo_errors[photo] = str(e)
            return None
        self._photo_errors.pop(photo, None)
        h, w = pixels.shape[:2]
        tex = self.ctx.texture((w, h), 3, np.ascontiguousarray(pixels, np.uint8).tobytes(), alignment=1)
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST, moderngl.LINEAR)
        tex.repeat_x = tex.repeat_y = False
        self._photo_tex[photo] = tex
        if photo not in self._thumbs:
            self._thumbs[photo] = self._make_thumb(pixels)
        while len(self._photo_tex) > PHOTO_CACHE:
            old = next(iter(self._photo_tex))
            self.gui.forget_texture(self._photo_tex[old])
            self._photo_tex.pop(old).release()
        return tex

    def _make_thumb(self, pixels: np.ndarray) -> moderngl.Texture:
        from PIL import Image

        h, w = pixels.shape[:2]
        im = Image.fromarray(pixels).resize((max(1, round(w * THUMB_H / h)), THUMB_H), Image.Resampling.BOX)
        t = self.ctx.texture(im.size, 3, im.tobytes(), alignment=1)
        t.filter = (moderngl.LINEAR, moderngl.LINEAR)
        return t

    def _load_next_thumbnail(self) -> None:
        """One missing thumbnail per frame (each photo is read once)."""
        for pid in self.session.photo_ids:
            if pid not in self._thumbs:
                try:
                    self._thumbs[pid] = self._make_thumb(self.session.photo_pixels(pid))
                except VebuildError as e:
                    self._photo_errors[pid] = str(e)
                    self._thumbs[pid] = None
                return

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

    def _nearest_line(self, kinds: tuple[str, ...], x: float, y: float, radius: float = PICK_RADIUS_PX) -> Any:
        """The overlay line of these kinds nearest window point (x, y), within ``radius`` window px."""
        ov = self.overlay()
        if ov is None:
            return None
        best, q = None, np.array([x, y])
        for ln in ov.lines:
            if ln.kind not in kinds:
                continue
            a = np.array(self.image_to_window(None, ln.p[:2]))
            b = np.array(self.image_to_window(None, ln.p[2:]))
            t = float(np.clip(np.dot(q - a, b - a) / max(float(np.dot(b - a, b - a)), 1e-12), 0.0, 1.0))
            d = float(np.linalg.norm(q - (a + t * (b - a))))
            if d <= radius and (best is None or d < best[0]):
                best = (d, ln)
        return best[1] if best else None

    # -- input --------------------------------------------------------------------------------------

    def on_close(self, handle: Any) -> None:
        if self.session.dirty and not self._close_warned:
            glfw.set_window_should_close(handle, False)
            self._close_warned = True
            self.say(f"unsaved edits: Ctrl+S saves them; close again to leave them in "
                     f"{self.session.autosave_path.name} (offered for recovery when the project is opened)")

    def _photo_takes(self, x: float, y: float) -> bool:
        """Whether a mouse event at (x, y) is the photo view's (not a panel's or a popup's)."""
        if self.photo is None or self._busy or not _inside(self.view_rect(), x, y):
            return False
        return not imgui.is_popup_open("", imgui.PopupFlags_.any_popup_id)

    def input_blocked(self) -> bool:
        return bool(self._busy)

    def toggle_labels(self) -> None:
        self.show_labels = not self.show_labels

    def fix_under_cursor(self) -> None:
        self.toggle_fix_at(*self._cursor)

    def save(self) -> None:
        self.session.save()

    def set_tool(self, tool: str) -> None:
        if tool not in TOOLS:
            raise VebuildError(f"no tool '{tool}'; the tools are {', '.join(TOOLS)}")
        self.escape(keep_tool=True)
        self.tool = tool

    def escape(self, keep_tool: bool = False) -> None:
        """Cancel what is under way (a drag, a stroke, a placement); if nothing, the Select tool."""
        busy = self.session.dragging or self._press is not None or self._placing is not None
        if self.session.dragging:
            self.session.cancel_drag()
            self.say("drag cancelled")
        self._press = None
        self._pending_drag = None
        self.drag_problem = None
        self._placing = None
        if not busy and not keep_tool:
            self.tool = "select"

    def undo(self) -> None:
        if not self.session.undo():
            self.say("nothing to undo")

    def redo(self) -> None:
        if not self.session.redo():
            self.say("nothing to redo")

    def toggle_fix_at(self, x: float, y: float) -> None:
        """F: fix the vertex under (x, y) where it is seen, or unfix it."""
        if self.photo is None:
            return
        uv = self.window_to_image(x, y)
        hit = self.session.handle_at(self.photo, uv, PICK_RADIUS_PX / self.zoom, prefer=self.selected)
        if hit is None:
            self.say("no vertex under the cursor to fix (F fixes or unfixes the vertex under the cursor)")
            return
        fixed = {(n, h) for n, h, _, f in self.session.handles(self.photo) if f}
        if hit in fixed:
            self.session.unfix(self.photo, *hit)
            self.say(f"{hit[0]}:{hit[1]} unfixed in {self.photo}")
        else:
            self.session.fix(self.photo, *hit)
            self.say(f"{hit[0]}:{hit[1]} fixed in {self.photo}")

    def on_scroll(self, dx: float, dy: float) -> None:
        if self._busy:
            return
        x, y = self._cursor
        if self._photo_takes(x, y) and not self._over_preview(x, y):
            self.zoom_at(x, y, WHEEL_STEP ** dy)
        else:
            self.gui.on_scroll(dx, dy)

    def on_cursor(self, x: float, y: float) -> None:
        if self._busy:
            return
        self.gui.on_cursor(x, y)
        dx, dy = x - self._cursor[0], y - self._cursor[1]
        self._cursor = (x, y)
        if self._pan_from is not None:
            self.pan = (self.pan[0] + dx, self.pan[1] + dy)
            return
        p = self._press
        if p is None:
            return
        far = math.hypot(x - p["xy"][0], y - p["xy"][1]) > CLICK_SLOP_PX
        p["moved"] = p.get("moved", False) or far
        if p["kind"] == "handle" and not self.session.dragging and far:
            try:
                self.session.begin_drag(self.photo, p["node"], p["handle"])
            except VebuildError as e:
                self.say(str(e))
                self._press = None
                return
        if p["kind"] == "handle" and self.session.dragging:
            self._pending_drag = self.window_to_image(x, y)

    def on_button(self, button: int, action: int, mods: int = 0) -> None:
        if self._busy:
            return
        x, y = self._cursor
        self._mods = mods
        if action == glfw.RELEASE:
            self.gui.on_button(button, action)
            if self._pan_from is not None and button in (glfw.MOUSE_BUTTON_MIDDLE, glfw.MOUSE_BUTTON_LEFT):
                self._pan_from = None
            elif button == glfw.MOUSE_BUTTON_LEFT and self._press is not None:
                self._release(x, y)
            return
        if not self._photo_takes(x, y):
            self.gui.on_button(button, action)
            return
        if button == glfw.MOUSE_BUTTON_MIDDLE or (button == glfw.MOUSE_BUTTON_LEFT and glfw.KEY_SPACE in self._held):
            self._pan_from = (x, y)
        elif button == glfw.MOUSE_BUTTON_LEFT:
            try:
                self._press_left(x, y)
            except VebuildError as e:
                self.say(str(e))
                self._press = None

    def _press_left(self, x: float, y: float) -> None:
        s, photo = self.session, self.photo
        uv = self.window_to_image(x, y)
        r = PICK_RADIUS_PX / self.zoom
        base = {"xy": (x, y), "uv": uv}
        if self._placing is not None:
            place, self._placing = self._placing, None
            made = s.add_primitive(place["kind"], name=place["name"] or None, parent=place["parent"],
                                   marker=place.get("marker"), at=(photo, uv))
            self.select(made)
            return
        if self.tool in ("x", "y", "z", "edge", "marker", "delete"):
            self._press = {**base, "kind": self.tool}
            return
        hit = s.handle_at(photo, uv, r, prefer=self.selected)
        if hit is not None:
            self.select(hit[0])
            self._press = {**base, "kind": "handle", "node": hit[0], "handle": hit[1]}
            return
        seg = s.segment_at(photo, uv, r)
        if seg is not None and seg[2] is not None:
            axis, index, end = seg
            self._press = {**base, "kind": "segment-end", "axis": axis, "index": index, "end": end,
                           "segment": list(s.vanishing(photo, axis).segments[index])}
            return
        marker = s.marker_at(photo, uv, r)
        if marker is not None:
            self._press = {**base, "kind": "marker-move", "name": marker}
            return
        edge = self._nearest_line(("edge",), x, y)
        self.select(edge.key[0] if edge is not None else None)
        self._press = {**base, "kind": "click"}

    def _release(self, x: float, y: float) -> None:
        p, self._press = self._press, None
        s, photo = self.session, self.photo
        uv = self.window_to_image(x, y)
        kind = p["kind"]
        try:
            if kind == "handle":
                if s.dragging:
                    self._pending_drag = uv
                    self._apply_pending_drag()
                    s.end_drag()
                    self.drag_problem = None
            elif kind in ("x", "y", "z"):
                s.add_segment(photo, kind, p["uv"], uv)
            elif kind == "edge":
                self._add_edge(p["uv"], uv)
            elif kind == "marker":
                name = self.marker_name.strip()
                s.place_marker(photo, name, uv)
                self.say(f"marker {name} at ({uv[0]:.2f}, {uv[1]:.2f}) in {photo}")
                if self._marker_name_default or name == "":
                    self.marker_name = s.next_marker_name()
                    self._marker_name_default = True
            elif kind == "delete":
                self.delete_at(x, y)
            elif kind == "segment-end" and p.get("moved"):
                seg = list(p["segment"])
                seg[2 * p["end"]:2 * p["end"] + 2] = uv
                s.move_segment(photo, p["axis"], p["index"], seg)
            elif kind == "marker-move" and p.get("moved"):
                s.place_marker(photo, p["name"], uv)
        except VebuildError as e:
            self.say(str(e))

    def _add_edge(self, p1: tuple[float, float], p2: tuple[float, float]) -> None:
        s = self.session
        hit = s.nearest_edge(self.photo, p1, p2, node=self.selected)
        if hit is None:
            self.say("no projected model edge near that stroke" + ("" if self.selected else
                     "; select a primitive first (click one of its edges with the Select tool)"))
            return
        s.add_edge_observation(self.photo, hit[0], hit[1], p1, p2)
        self.say(f"edge {hit[0]}:{hit[1]} drawn in {self.photo}")

    def delete_at(self, x: float, y: float) -> None:
        """Remove the segment, marker or drawn edge under window point (x, y)."""
        s, photo = self.session, self.photo
        uv = self.window_to_image(x, y)
        r = PICK_RADIUS_PX / self.zoom
        seg = s.segment_at(photo, uv, r)
        if seg is not None:
            s.delete_segment(photo, seg[0], seg[1])
            self.say(f"deleted {seg[0]} segment {seg[1]} in {photo}")
            return
        marker = s.marker_at(photo, uv, r)
        if marker is not None:
            s.remove_marker(photo, marker)
            self.say(f"removed marker {marker} from {photo}")
            return
        edge = self._nearest_line(("user-edge",), x, y)
        if edge is not None:
            s.remove_edge_observation(edge.key)
            self.say("removed the drawn edge")
            return
        self.say("nothing to delete there (a segment, a marker or a drawn edge)")

    def _apply_pending_drag(self) -> None:
        """The solve for the latest mouse position of a drag (once per frame, however many moves)."""
        uv, self._pending_drag = self._pending_drag, None
        if uv is None or not self.session.dragging:
            return
        t0 = time.perf_counter()
        fb = self.session.drag_to(uv)
        self.timings["drag_solve_ms"] = 1e3 * (time.perf_counter() - t0)
        self.last_feedback = fb
        if fb.ok:
            self.drag_problem = None
        else:
            if fb.reason != self.drag_problem:
                self.say(fb.reason)
            self.drag_problem = fb.reason

    def select(self, node: str | None, add: bool = False) -> None:
        if node is None:
            self.selected, self.selected_nodes = None, []
        elif add:
            if node in self.selected_nodes:
                self.selected_nodes.remove(node)
            else:
                self.selected_nodes.append(node)
            self.selected = node if node in self.selected_nodes else (self.selected_nodes or [None])[-1]
        else:
            self.selected, self.selected_nodes = node, [node]
        self._param_edits.clear()
        self._scroll_to_selected = True

    def _ctrl_held(self) -> bool:
        """Whether Ctrl is down (the keys held, as glfw reported them: X11 gives a modifier key's own
        press without its modifier, which ImGui's key_ctrl then misses)."""
        return bool({glfw.KEY_LEFT_CONTROL, glfw.KEY_RIGHT_CONTROL} & self._held) or bool(self._mods & glfw.MOD_CONTROL)

    def _over_preview(self, x: float, y: float) -> bool:
        r = self.widget_rects.get("preview")
        return r is not None and _inside(r, x, y)

    # -- long actions ---------------------------------------------------------------------------------

    def _later(self, fn: Callable[[], None]) -> None:
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
        self._draw_toolbar()
        if not live:
            self._draw_strip()
            self._draw_panels()
            self._draw_preview()
        imgui.end_disabled()
        self._draw_messages()
        self._draw_magnifier()
        if not live:
            self._draw_recovery()
        self._draw_busy()
        self.gui.render()
        self.widget_rects = {**self.widget_rects, **self._rects} if live else self._rects
        if not live and self._press is not None and self._press.get("kind") == "handle":
            self._cache_frame((fw, fh))
        self.timings["draw_ms"] = 1e3 * (time.perf_counter() - t0)

    def _view_pixels(self, fb_size: tuple[int, int]) -> tuple[int, int, int, int]:
        """The photo view in framebuffer pixels (x0, y0, x1, y1), rows from the top."""
        W, H = self.size()
        sx, sy = fb_size[0] / max(W, 1), fb_size[1] / max(H, 1)
        x0, y0, x1, y1 = self.view_rect()
        return (int(math.floor(x0 * sx)), int(math.floor(y0 * sy)), int(math.ceil(x1 * sx)),
                int(math.ceil(y1 * sy)))

    def _view_uncovered(self, fb_size: tuple[int, int]) -> list[tuple[int, int, int, int]]:
        """The parts of the photo view (framebuffer pixels, rows from the top) that the photo does
        not cover: at most four bands (a software renderer clears a small band much faster than the
        whole view)."""
        vx0, vy0, vx1, vy1 = self._view_pixels(fb_size)
        if self.photo is None or self._photo_tex.get(self.photo) is None:
            return [(vx0, vy0, vx1, vy1)]
        W, H = self.size()
        sx, sy = fb_size[0] / max(W, 1), fb_size[1] / max(H, 1)
        w, h = self.photo_size()
        px0, py0 = self.image_to_window(None, (0, 0))
        px1, py1 = self.image_to_window(None, (w, h))
        # The photo's inner whole pixels: a band of one pixel overlaps its edge rather than a gap.
        cx0 = min(max(int(math.ceil(px0 * sx)), vx0), vx1)
        cy0 = min(max(int(math.ceil(py0 * sy)), vy0), vy1)
        cx1 = max(min(int(math.floor(px1 * sx)), vx1), cx0)
        cy1 = max(min(int(math.floor(py1 * sy)), vy1), cy0)
        bands = [(vx0, vy0, vx1, cy0), (vx0, cy1, vx1, vy1), (vx0, cy0, cx0, cy1), (cx1, cy0, vx1, cy1)]
        return [b for b in bands if b[2] > b[0] and b[3] > b[1]]

    def _cache_frame(self, fb_size: tuple[int, int]) -> None:
        """Keep the frame just drawn, for the drag that this press may begin."""
        if self._frame_cache is None or self._frame_cache.size != fb_size:
            self._release_frame_cache()
            self._frame_cache_rb = self.ctx.renderbuffer(fb_size, 4)
            self._frame_cache = self.ctx.framebuffer(color_attachments=[self._frame_cache_rb])
        self.ctx.copy_framebuffer(self._frame_cache, self.surface.fbo)
        self._frame_cache_press = self._press  # the press itself (an id could be reused by the next)
        self._frame_cache_serial += 1

    def _cache_still_view(self, fbo: moderngl.Framebuffer, fb_size: tuple[int, int]) -> None:
        """The frame of the press with the photo view redrawn without the moving primitives, kept
        for the moves of this drag (drawn anew if the view is zoomed or panned meanwhile)."""
        key = (self._frame_cache_serial, self.photo, self.zoom, self.pan, self.selected, fb_size)
        if key == self._view_cache_key and self._view_cache is not None:
            return
        self.ctx.copy_framebuffer(fbo, self._frame_cache)
        for x0, y0, x1, y1 in self._view_uncovered(fb_size):  # the photo covers the rest
            fbo.clear(0.11, 0.11, 0.12, 1.0, viewport=(x0, fb_size[1] - y1, x1 - x0, y1 - y0))
        self.gui.new_frame()
        self._draw_photo_view("still")
        self.gui.render()
        if self._view_cache is None or self._view_cache.size != fb_size:
            if self._view_cache is not None:
                self._view_cache.release()
                self._view_cache_rb.release()
            self._view_cache_rb = self.ctx.renderbuffer(fb_size, 4)
            self._view_cache = self.ctx.framebuffer(color_attachments=[self._view_cache_rb])
        self.ctx.copy_framebuffer(self._view_cache, fbo)
        self._view_cache_key = key

    def _drag_frame_cached(self, fb_size: tuple[int, int]) -> bool:
        return (self.session.dragging and self._busy is None and self._frame_cache is not None
                and self._frame_cache.size == fb_size and self._press is not None
                and self._frame_cache_press is self._press)

    def _release_frame_cache(self) -> None:
        for fb, rb in ((self._frame_cache, self._frame_cache_rb), (self._view_cache, self._view_cache_rb)):
            if fb is not None:
                fb.release()
                rb.release()
        self._frame_cache = self._view_cache = None
        self._view_cache_key = None

    def _rect(self, label: str) -> bool:
        """Record the last item's rectangle under ``label``, the part of it its window shows (an item
        scrolled out of view is not recorded); returns whether it is wholly shown."""
        mn, mx = imgui.get_item_rect_min(), imgui.get_item_rect_max()
        wp, ws = imgui.get_window_pos(), imgui.get_window_size()
        x0, y0, x1, y1 = max(mn.x, wp.x), max(mn.y, wp.y), min(mx.x, wp.x + ws.x), min(mx.y, wp.y + ws.y)
        if x1 > x0 and y1 > y0:
            self._rects[label] = (x0, y0, x1, y1)
        return (x0, y0, x1, y1) == (mn.x, mn.y, mx.x, mx.y)

    def _button(self, label: str, size: tuple[float, float] | None = None, tip: str | None = None) -> bool:
        clicked = imgui.button(label, size) if size is not None else imgui.button(label)
        self._rect(label)
        if tip:
            imgui.set_item_tooltip(tip)
        return bool(clicked)

    def _combo(self, label: str, index: int, items: list[str]) -> int:
        """A drop-down list; its rectangle is recorded as ``label`` and, while open, each item's as
        ``label:item``. Returns the chosen index."""
        opened = imgui.begin_combo(f"##{label}", items[index] if 0 <= index < len(items) else "",
                                   imgui.ComboFlags_.height_largest)  # as many items as the screen holds
        self._rect(label)
        if opened:
            for i, item in enumerate(items):
                if imgui.selectable(f"{item}##{label}{i}", i == index)[0]:
                    index = i
                self._rect(f"{label}:{item}")
            imgui.end_combo()
        return index

    def _fixed_window(self, name: str, rect: Rect, flags: int = 0) -> None:
        imgui.set_next_window_pos((rect[0], rect[1]), imgui.Cond_.always)
        imgui.set_next_window_size((rect[2] - rect[0], rect[3] - rect[1]), imgui.Cond_.always)
        imgui.begin(name, None, flags | imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize
                    | imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.no_bring_to_front_on_focus)
        self._rects[name] = rect

    # -- the photo view -----------------------------------------------------------------------------

    def _draw_photo_view(self, layer: str = "all") -> None:
        """The photo and what is drawn over it; during a drag, ``still`` (the photo and what does
        not move) or ``moving`` (the moving primitives and the stroke), drawn over the other."""
        dl = imgui.get_background_draw_list()
        x0, y0, x1, y1 = self.view_rect()
        dl.push_clip_rect((x0, y0), (x1, y1), False)
        if layer == "moving":
            t0 = time.perf_counter()
            layers = self.guard(self.session.overlay_layers, self.photo, self.selected)
            self.timings["overlay_ms"] = 1e3 * (time.perf_counter() - t0)
            if layers is not None:
                self._draw_overlay(dl, layers[1])
            self._draw_stroke(dl)
            dl.pop_clip_rect()
            return
        if self.photo is None:
            dl.add_text((x0 + 20, y0 + 20), _u32((1, 1, 1, 1)), "no photos yet: type a file name below and Add photo")
            dl.pop_clip_rect()
            return
        w, h = self.photo_size()
        a = self.image_to_window(None, (0, 0))
        b = self.image_to_window(None, (w, h))
        tex = self._photo_texture(self.photo)
        if tex is not None:
            mag = moderngl.NEAREST if self.zoom >= NEAREST_ABOVE_ZOOM else moderngl.LINEAR
            tex.filter = (moderngl.LINEAR_MIPMAP_NEAREST, mag)  # trilinear costs 20 % of a frame on llvmpipe
            dl.add_image(self.gui.texture_ref(tex, opaque=True), a, b)
        else:
            grey, red = _u32((0.25, 0.25, 0.27, 1.0)), _u32((0.8, 0.2, 0.2, 1.0))
            dl.add_rect_filled(a, b, grey)
            dl.add_line(a, b, red, 2.0)
            dl.add_line((a[0], b[1]), (b[0], a[1]), red, 2.0)
            text = self._photo_errors.get(self.photo, "photo not loaded")
            dl.add_text((max(a[0], x0) + 12, max(a[1], y0) + 12), _u32((1, 0.6, 0.6, 1)),
                        f"photo '{self.photo}' cannot be shown: {text}")
        if layer == "still":
            layers = self.guard(self.session.overlay_layers, self.photo, self.selected)
            if layers is not None:
                self._draw_overlay(dl, layers[0])
            dl.pop_clip_rect()
            return
        ov = self.overlay()
        if ov is not None:
            self._draw_overlay(dl, ov)
        self._draw_stroke(dl)
        dl.pop_clip_rect()

    def _draw_overlay(self, dl: Any, ov: Overlay) -> None:
        z, (px, py) = self.zoom, self.pan
        for ln in ov.lines:
            u1, v1, u2, v2 = ln.p
            a, b = (px + z * u1, py + z * v1), (px + z * u2, py + z * v2)
            col = _u32(ln.colour)
            dl.add_line(a, b, col, ln.width)
            if ln.arrow:
                self._arrow_head(dl, a, b, col, 6.0 + 2.0 * ln.width)
            if ln.label and self.show_labels and ln.kind in ("segment", "axis", "user-edge", "horizon", "residual"):
                dl.add_text((0.5 * (a[0] + b[0]) + 6, 0.5 * (a[1] + b[1]) + 2), col, ln.label)
        for pt in ov.points:
            c = (px + z * pt.uv[0], py + z * pt.uv[1])
            col = _u32(pt.colour)
            if pt.filled:
                dl.add_circle_filled(c, pt.radius, col)
            else:
                dl.add_circle(c, pt.radius, col, 0, 1.5)
            if pt.label and (self.show_labels or pt.kind == "marker"):
                dl.add_text((c[0] + pt.radius + 3, c[1] - 7), col, pt.label)

    @staticmethod
    def _arrow_head(dl: Any, a: tuple[float, float], b: tuple[float, float], col: int, size: float) -> None:
        dx, dy = b[0] - a[0], b[1] - a[1]
        n = math.hypot(dx, dy)
        if n < 1e-6:
            return
        dx, dy = dx / n, dy / n
        size = min(size, 0.5 * n)
        bx, by = b[0] - size * dx, b[1] - size * dy
        w = 0.45 * size
        dl.add_triangle_filled(b, (bx - w * dy, by + w * dx), (bx + w * dy, by - w * dx), col)

    def _draw_stroke(self, dl: Any) -> None:
        """The stroke being drawn (a segment, an edge) or the segment end being moved."""
        p = self._press
        if p is None:
            return
        x, y = self._cursor
        if p["kind"] in ("x", "y", "z", "edge"):
            col = _u32(AXIS_COLOURS[p["kind"]] if p["kind"] in AXIS_COLOURS else RED)
            a = self.image_to_window(None, p["uv"])
            dl.add_line(a, (x, y), col, 2.0)
            self._arrow_head(dl, a, (x, y), col, 10.0)
        elif p["kind"] == "segment-end" and p.get("moved"):
            seg = list(p["segment"])
            seg[2 * p["end"]:2 * p["end"] + 2] = self.window_to_image(x, y)
            col = _u32(AXIS_COLOURS[p["axis"]])
            a, b = self.image_to_window(None, seg[:2]), self.image_to_window(None, seg[2:])
            dl.add_line(a, b, col, 2.0)
            self._arrow_head(dl, a, b, col, 10.0)
        elif p["kind"] == "marker-move" and p.get("moved"):
            dl.add_circle((x, y), 6.0, _u32((1.0, 0.6, 0.1, 1.0)), 0, 2.0)

    def magnifier_visible(self) -> bool:
        x, y = self._cursor
        want = self.tool in ("x", "y", "z", "marker", "edge") or bool(self._mods & glfw.MOD_SHIFT) \
            or glfw.KEY_LEFT_SHIFT in self._held or glfw.KEY_RIGHT_SHIFT in self._held
        return want and self._photo_takes(x, y) and self._pan_from is None

    def _draw_magnifier(self) -> None:
        if not self.magnifier_visible():
            return
        tex = self._photo_texture(self.photo)
        if tex is None:
            return
        x, y = self._cursor
        W, H = self.size()
        side = MAGNIFIER_PX
        px = x + 28 if x + 28 + side < W - PANEL_W else x - 28 - side
        py = y + 28 if y + 28 + side < H - STRIP_H else y - 28 - side
        u, v = self.window_to_image(x, y)
        w, h = self.photo_size()
        half = 0.5 * side / MAGNIFIER_ZOOM
        imgui.set_next_window_pos((px, py), imgui.Cond_.always)
        imgui.push_style_var(imgui.StyleVar_.window_padding, (2, 2))
        imgui.begin("##magnifier", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                    | imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav)
        imgui.image(self.gui.texture_ref(tex, nearest=True, opaque=True), (side, side),
                    ((u - half) / w, (v - half) / h), ((u + half) / w, (v + half) / h))
        mn = imgui.get_item_rect_min()
        c = (mn.x + 0.5 * side, mn.y + 0.5 * side)
        wdl = imgui.get_window_draw_list()
        cross = _u32((1.0, 0.2, 0.9, 0.9))
        wdl.add_line((c[0] - side / 2, c[1]), (c[0] - 4, c[1]), cross, 1.0)
        wdl.add_line((c[0] + 4, c[1]), (c[0] + side / 2, c[1]), cross, 1.0)
        wdl.add_line((c[0], c[1] - side / 2), (c[0], c[1] - 4), cross, 1.0)
        wdl.add_line((c[0], c[1] + 4), (c[0], c[1] + side / 2), cross, 1.0)
        p = self._press
        if p is not None and p["kind"] in ("x", "y", "z", "edge"):  # the stroke being drawn, magnified
            col = _u32(AXIS_COLOURS[p["kind"]] if p["kind"] in AXIS_COLOURS else RED)
            a = (c[0] + MAGNIFIER_ZOOM * (p["uv"][0] - u), c[1] + MAGNIFIER_ZOOM * (p["uv"][1] - v))
            wdl.push_clip_rect(mn, (mn.x + side, mn.y + side), True)
            wdl.add_line(a, c, col, 1.5)
            wdl.pop_clip_rect()
        imgui.text(f"({u:.2f}, {v:.2f}) px, {MAGNIFIER_ZOOM:.0f}× the photo")
        self._rects["magnifier"] = (mn.x, mn.y, mn.x + side, mn.y + side)
        imgui.end()
        imgui.pop_style_var()

    # -- toolbar, strip, messages -------------------------------------------------------------------

    def _draw_toolbar(self) -> None:
        x0, _, x1, _ = self.view_rect()
        self._fixed_window("##toolbar", (x0, 0, x1, TOOLBAR_H), imgui.WindowFlags_.no_decoration)
        for tool, label in TOOLS.items():
            active = self.tool == tool
            if active:
                imgui.push_style_color(imgui.Col_.button, imgui.ImVec4(0.85, 0.55, 0.1, 1.0))
            if self._button(label, tip=f"{TOOL_HINTS[tool]} (key {tool_key(tool)})"):
                self.set_tool(tool)
            if active:
                imgui.pop_style_color()
            imgui.same_line()
        imgui.set_next_item_width(90)
        changed, name = imgui.input_text("marker name", self.marker_name)
        self._rect("marker name")
        if changed:
            self.marker_name, self._marker_name_default = name, False
        s = self.session
        imgui.begin_disabled(s.undo_label is None)
        if self._button("Undo", tip=f"Ctrl+Z: undo {s.undo_label or ''}"):
            self.undo()
        imgui.end_disabled()
        imgui.same_line()
        imgui.begin_disabled(s.redo_label is None)
        if self._button("Redo", tip=f"Ctrl+Y: redo {s.redo_label or ''}"):
            self.redo()
        imgui.end_disabled()
        imgui.same_line()
        if self._button("Save", tip="Ctrl+S: write the project file (the autosave is removed)"):
            self.guard(s.save)
        imgui.same_line()
        if self._button("Fit", tip="Home: the whole photo"):
            self.fit()
        imgui.same_line()
        _, self.show_labels = imgui.checkbox("labels", self.show_labels)
        self._rect("labels")
        imgui.set_item_tooltip("L: residuals and names over the photo (markers' names stay)")
        imgui.same_line()
        status = f"{self.photo or '-'}  ×{self.zoom:.2f}"
        if self._photo_takes(*self._cursor):
            u, v = self.window_to_image(*self._cursor)
            status += f"  ({u:.1f}, {v:.1f}) px"
        if s.dirty:
            status += "   unsaved (autosaved)"
        imgui.text(status)
        imgui.end()

    def _draw_strip(self) -> None:
        W, H = self.size()
        x0, _, x1, _ = self.view_rect()
        self._fixed_window("##strip", (x0, H - STRIP_H, x1, H), imgui.WindowFlags_.no_title_bar
                           | imgui.WindowFlags_.horizontal_scrollbar)
        for pid in self.session.photo_ids:
            thumb = self._thumbs.get(pid)
            current = pid == self.photo
            if current:
                imgui.push_style_color(imgui.Col_.button, imgui.ImVec4(0.85, 0.55, 0.1, 1.0))
            label = f"photo:{pid}"
            if thumb is not None:
                clicked = imgui.image_button(label, self.gui.texture_ref(thumb), thumb.size)
                self._rect(label)
            else:
                note = "cannot load" if pid in self._photo_errors else "loading"
                clicked = imgui.button(f"{pid}\n({note})##{label}", (THUMB_H * 4 / 3, THUMB_H + 6))
                self._rect(label)
            if current:
                imgui.pop_style_color()
            imgui.set_item_tooltip(pid + (f": {self._photo_errors[pid]}" if pid in self._photo_errors else ""))
            if clicked:
                self.guard(self.set_photo, pid)
            imgui.same_line()
        imgui.new_line()
        imgui.set_next_item_width(260)
        _, self.add_photo_path = imgui.input_text("##add photo file", self.add_photo_path)
        self._rect("add photo file")
        imgui.same_line()
        if self._button("Add photo", tip="an image file in the project's folder (its SHA-256 is recorded)"):
            pid = self.guard(self.session.add_photo, self.add_photo_path.strip())
            if pid is not None:
                self.add_photo_path = ""
                self.guard(self.set_photo, pid)
        imgui.end()

    def _draw_messages(self) -> None:
        x0, _, x1, y1 = self.view_rect()
        lines: list[tuple[str, tuple[float, float, float, float]]] = []
        ov = self._overlay if self._overlay_key and self._overlay_key[1] == self.photo else None
        for note in (ov.notes if ov is not None else []):
            lines.append((note, (0.75, 0.75, 0.75, 1.0)))
        for m in self.messages[-MESSAGES_SHOWN:]:
            lines.append((m, (1.0, 1.0, 1.0, 1.0)))
        if self.drag_problem:
            lines.append((self.drag_problem, (1.0, 0.35, 0.3, 1.0)))
        if self._placing is not None:
            lines.append((f"click in the photo where the new {self._placing['kind']} stands (Esc cancels)",
                          (1.0, 0.8, 0.2, 1.0)))
        if not lines:
            return
        imgui.set_next_window_pos((x0 + 6, y1 - 6), imgui.Cond_.always, (0.0, 1.0))
        imgui.set_next_window_bg_alpha(0.7)
        imgui.begin("##messages", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                    | imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav)
        imgui.push_text_wrap_pos(max(200.0, x1 - x0 - 40))
        for text, colour in lines:
            imgui.text_colored(imgui.ImVec4(*colour), text)
        imgui.pop_text_wrap_pos()
        pos, size = imgui.get_window_pos(), imgui.get_window_size()
        self._rects["messages"] = (pos.x, pos.y, pos.x + size.x, pos.y + size.y)
        imgui.end()

    def _draw_recovery(self) -> None:
        s = self.session
        if s.recovery_available and not self._recovery_asked:
            imgui.open_popup("Recover autosaved edits?")
            self._recovery_asked = True
        W, H = self.size()
        imgui.set_next_window_pos((W / 2, H / 2), imgui.Cond_.always, (0.5, 0.5))
        opened, _ = imgui.begin_popup_modal("Recover autosaved edits?", None, imgui.WindowFlags_.always_auto_resize)
        if opened:
            imgui.text(f"{s.autosave_path.name} holds edits that were not saved.")
            if self._button("Recover the autosaved edits"):
                self.guard(s.recover)
                imgui.close_current_popup()
            imgui.same_line()
            if self._button("Discard"):
                self.guard(s.discard_recovery)
                imgui.close_current_popup()
            imgui.end_popup()

    def _draw_busy(self) -> None:
        if self._busy is None:
            return
        W, H = self.size()
        imgui.set_next_window_pos((W / 2, H / 2), imgui.Cond_.always, (0.5, 0.5))
        imgui.begin("##busy", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                    | imgui.WindowFlags_.no_saved_settings)
        frac, text = self._progress
        imgui.text(f"{self._busy}…")
        imgui.progress_bar(frac, (320, 0), text)
        self._rect("progress")
        imgui.end()

    # -- 3-D preview --------------------------------------------------------------------------------

    def preview_camera(self) -> ImageCamera | None:
        r = self._renderer
        if r is None:
            return None
        lo, hi = r.scene.bounds()
        target = 0.5 * (lo + hi)
        if self.preview_distance is None:
            self.preview_distance = max(1.0, 1.2 * float(np.linalg.norm(hi - lo)))
        cp, sp = math.cos(self.preview_pitch), math.sin(self.preview_pitch)
        C = target + self.preview_distance * np.array([cp * math.cos(self.preview_yaw),
                                                       cp * math.sin(self.preview_yaw), sp])
        w, h = self.preview_size
        f = fov_to_focal(math.radians(PREVIEW_FOV_DEG), w)
        return ImageCamera("preview", intrinsic_matrix(f, w / 2, h / 2), look_rotation(target - C), C, w, h)

    def _preview_scene(self, model: Any) -> Any:
        """The model as a render scene: the last one's faces and pages when only the sizes and
        joints changed (half the time), else laid out anew (with the textures, if any)."""
        from vebuild.render.scene import load_scene, scene_from_model

        record = self.session.data.get("textures")
        pages_key = tuple(p.get("atlas_sha256") for p in record.get("pages", [])) if record else ()
        shape = (tuple((n.name, n.primitive.TYPE if n.primitive is not None else None) for n in model.nodes),
                 pages_key)
        r = self._renderer
        if r is not None and shape == self._preview_shape:
            try:
                return r.scene.with_model(model)
            except (ValueError, KeyError):
                pass
        self._preview_shape = shape
        if record is None:
            return scene_from_model(model)
        if self._preview_pages is None or self._preview_pages[0] != pages_key:
            try:
                pages = load_scene(self.session.project).pages
            except VebuildError as e:
                self.say(f"3-D preview untextured: {e}")
                pages = []
            self._preview_pages = (pages_key, pages)
        return scene_from_model(model, record if self._preview_pages[1] else None, self._preview_pages[1])

    def _update_preview(self) -> None:
        s = self.session
        key = (s.revision, self.preview_yaw, self.preview_pitch, self.preview_distance, self.selected)
        if key == self._preview_key or s.dragging:  # during a drag the photo view shows the model; after it, this
            return
        model = s.model
        if model is None or not any(n.primitive is not None for n in model.nodes):
            self.preview_note = "no model yet"
            self._preview_key = key
            return
        from vebuild.render.renderer import Renderer, RenderOptions

        try:
            scene = self._preview_scene(model)
            pages = self._preview_shape[1]
            if self._renderer is not None and self._renderer_pages != pages:  # new textures: new pages
                self._renderer.release()
                self._renderer = None
            if self._renderer is None:
                self._renderer = Renderer(self.ctx, scene, RenderOptions(samples=1, anisotropy=1.0,
                                                                         trilinear=False, shadows=False))
                self._renderer_pages = pages
            else:
                self._renderer.set_scene(scene)
            self._renderer.highlight = self.selected
            cam = self.preview_camera()
            self._preview_tex = self._renderer.frame(cam)
            self.preview_note = ""
        except VebuildError as e:
            self.preview_note = str(e)
        self._preview_key = (s.revision, self.preview_yaw, self.preview_pitch, self.preview_distance, self.selected)

    def _draw_preview(self) -> None:
        W, H = self.size()
        self._fixed_window("3-D preview", (W - PANEL_W, H - PREVIEW_H, W, H), 0)
        w, h = self.preview_size
        if self._preview_tex is not None and not self.preview_note:
            imgui.image(self.gui.texture_ref(self._preview_tex), (w, h))
        else:
            imgui.dummy((w, h))
            mn = imgui.get_item_rect_min()
            imgui.get_window_draw_list().add_text((mn.x + 10, mn.y + 10), _u32((0.8, 0.8, 0.8, 1)),
                                                  self.preview_note or "no model yet")
        self._rect("preview")
        if imgui.is_item_hovered():
            io = imgui.get_io()
            if imgui.is_mouse_dragging(imgui.MouseButton_.left):
                d = io.mouse_delta
                self.preview_yaw -= 0.01 * d.x
                self.preview_pitch = float(np.clip(self.preview_pitch + 0.01 * d.y, -1.5, 1.5))
            if io.mouse_wheel and self.preview_distance is not None:
                self.preview_distance *= 0.9 ** io.mouse_wheel
        imgui.end()

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
        for f in add_photos:  # in the window, so that a file that cannot be added says so there
            pid = editor.guard(session.add_photo, f)
            if pid is not None:
                editor.set_photo(pid)
        try:
            n = 0
            while not window.should_close() and (frames is None or n < frames):
                editor.frame()
                n += 1
        finally:
            editor.close()
    if session.dirty:
        print(f"vebuild edit: the unsaved edits are kept in {session.autosave_path}; opening the project again "
              "offers to recover them (or `vebuild edit --recover`)", file=sys.stderr)
    return session
