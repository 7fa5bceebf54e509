"""The walk-through's Dear ImGui layer: the panel (position, lighting, stereo, the selection, the
messages, the keys from :data:`vebuild.viewer.keys.VIEWER_KEYS`, named views and hypotheses), the
HYPOTHESIS banner, and the evidence markers and recorded trajectories drawn over the view."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import glfw
import moderngl
import numpy as np

from vebuild.camera import project, world_to_camera
from vebuild.gl.app import KeyTable
from vebuild.project import Project
from vebuild.project.hypotheses import LABEL
from vebuild.project.provenance import stale, stale_line
from vebuild.viewer.layout import PanelLayout, fit_text, panel_layout, screen_px_per_mm
from vebuild.viewer.presentation import Presentation, PresentedViewer
from vebuild.viewer.walk import Walker

#: The key sheet's text is made no smaller than this (window coordinates) to fit.
MIN_KEYS_TEXT_PX = 8.0


def stale_lines(project: Project) -> list[str]:
    """The panel's stale lines: the short line, then each stale result's message; none if current."""
    found = stale(project.data, str(project.path))
    line = stale_line(found)
    return [line, *(s.message for s in found)] if line else []


class PanelViewer(PresentedViewer, Protocol):
    """What the panel reads and calls of the walk-through it belongs to
    (:class:`vebuild.viewer.app.Viewer` is one)."""

    project: Project
    ctx: moderngl.Context
    keys: KeyTable
    gui: Any
    walker: Walker
    messages: list[str]
    selection: str | None
    photo: str | None
    photo_opacity: float
    fps: float
    _trajectory_cache: list[tuple[Any, Any]]

    @property
    def lighting(self) -> str: ...
    @property
    def presentation(self) -> Presentation: ...
    def viewport(self) -> tuple[int, int, int, int]: ...
    def trajectories(self) -> list[Any]: ...
    def grid_unit(self) -> str: ...
    def describe(self, node: str) -> str: ...
    def draw_floor(self, imgui: Any) -> None: ...
    def draw_measures(self, imgui: Any) -> None: ...
    def jump_to_view(self, name: str) -> None: ...
    def save_view(self, name: str) -> None: ...
    def load_hypothesis(self, name: str) -> None: ...
    def save_hypothesis(self, name: str) -> None: ...
    def reset(self, everything: bool = False) -> None: ...
    def guard(self, fn: Callable[..., Any], *args: Any, **kw: Any) -> Any: ...


class ViewerPanel:
    """The panel of a :class:`~vebuild.viewer.app.Viewer` (``viewer.panel``): it holds the names
    being typed into it and draws with the viewer's state, calling its commands."""

    def __init__(self, viewer: PanelViewer):
        self.v = viewer
        self._new_view_name = ""
        self._new_hypothesis_name = ""
        self.stale = stale_lines(viewer.project)  # the walk-through never changes a result
        self.show_keys = False
        self.layout: PanelLayout | None = None
        #: The panel's and the key sheet's rectangles in the last frame (window coordinates).
        self.rects: dict[str, tuple[float, float, float, float]] = {}
        self._style_scale = 0.0
        self.keys_text_px = 0.0

    def make_gui(self) -> Any:
        """The window's Dear ImGui layer, with a TrueType font (ImGui's own lacks −, °, σ, Δ)."""
        import imgui_bundle

        from vebuild.gl.imgui import Gui

        font_file = Path(imgui_bundle.__file__).parent / "assets" / "fonts" / "DroidSans.ttf"
        return Gui(self.v.ctx, self.v.window.handle, font=str(font_file) if font_file.is_file() else None)

    def _layout(self, imgui: Any) -> PanelLayout:
        """The text size and the panel's place for this frame (the window's size and screen)."""
        h = self.v.window.handle
        W, H = glfw.get_window_size(h)
        fw, _ = glfw.get_framebuffer_size(h)
        return panel_layout(W, H, screen_px_per_mm(h), fw / max(W, 1))

    def title(self) -> str:
        return f"vebuild: {self.v.project.data.get('name', self.v.project.path.name)}"

    def _scale_style(self, imgui: Any, scale: float) -> None:
        """Paddings, spacings and scroll bars grown with the text (from ImGui's dark style)."""
        if abs(scale - self._style_scale) < 1e-3:
            return
        style = imgui.Style()
        imgui.style_colors_dark(style)
        style.scale_all_sizes(scale)
        imgui.get_current_context().style = style
        self._style_scale = scale

    def draw(self) -> None:
        from imgui_bundle import imgui

        gui = self.v.gui
        gui.new_frame()
        lay = self.layout = self._layout(imgui)
        self._scale_style(imgui, lay.scale)
        imgui.push_font(None, lay.text_px)
        self.rects = {}
        self.v.draw_floor(imgui)  # the floor grid, the axes, the photos' frustums (vebuild.viewer.floor)
        self._draw_markers(imgui)
        self._draw_trajectories(imgui)
        self.v.draw_measures(imgui)  # what was measured by clicking (vebuild.viewer.measure)
        fb = self.v.window.framebuffer_size()[0] / max(glfw.get_window_size(self.v.window.handle)[0], 1)
        if self.v.presentation.on:
            self.v.presentation.draw_legend(imgui, lay.text_px, fb)
        else:
            self.v.presentation.drawn = []
            self._draw_banner(imgui, lay)
        if self.v.show_panel:
            self._draw_panel(imgui, lay)
            if self.show_keys:
                self._draw_keys(imgui, lay)
        imgui.pop_font()
        gui.render()

    def _draw_banner(self, imgui: Any, lay: PanelLayout) -> None:
        banner = self.v.banner()
        if banner:
            m = 0.5 * lay.text_px
            W = glfw.get_window_size(self.v.window.handle)[0]
            room = (lay.x if self.v.show_panel else W) - 2 * m  # left of the panel, wrapped if need be
            imgui.set_next_window_pos(imgui.ImVec2(m, m))
            imgui.set_next_window_size_constraints(imgui.ImVec2(0, 0), imgui.ImVec2(max(room, 4 * m), 1e6))
            imgui.begin("##hypothesis", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                        | imgui.WindowFlags_.no_inputs)
            imgui.push_text_wrap_pos(max(room, 4 * m) - m)
            imgui.text_colored(imgui.ImVec4(1.0, 0.25, 0.2, 1.0), banner)
            imgui.pop_text_wrap_pos()
            imgui.end()

    def _window_rect(self, imgui: Any, name: str) -> None:
        p, s = imgui.get_window_pos(), imgui.get_window_size()
        self.rects[name] = (p.x, p.y, p.x + s.x, p.y + s.y)

    def _draw_panel(self, imgui: Any, lay: PanelLayout) -> None:
        keys = self.v.keys
        banner = self.v.banner()
        imgui.set_next_window_pos(imgui.ImVec2(lay.x, lay.y))
        imgui.set_next_window_size_constraints(imgui.ImVec2(lay.width, 0.0), imgui.ImVec2(lay.width, lay.max_height))
        title = self.title()
        room = lay.width - 2 * imgui.get_style().window_padding.x - imgui.get_style().frame_padding.x
        shown = fit_text(title, room, lambda t: float(imgui.calc_text_size(t).x))
        imgui.begin(f"{shown}###vebuild-panel", None, imgui.WindowFlags_.always_auto_resize
                    | imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_collapse)
        self._window_rect(imgui, "panel")
        if shown != title:  # the title shortened: in full here
            imgui.text_wrapped(title)
        p = self.v.walker.position
        imgui.text_wrapped(f"{'flying' if self.v.walker.fly else 'walking'}: x {p[0]:.2f}, y {p[1]:.2f}, "
                           f"z {p[2]:.2f} m   {self.v.fps:.0f} fps")
        if self.v.has_model:
            imgui.text(f"lighting: {self.v.lighting}   ({keys.key_for('next_lighting')})")
            imgui.text(f"stereo: {self.v.stereo or 'off'}   ({keys.key_for('next_stereo')})")
            self._draw_unobserved(imgui)
        else:
            imgui.text_wrapped(f"no model yet: the calibrated photos ({keys.key_for('step_photo', 1)}), the floor grid "
                               f"1 {self.v.grid_unit()} apart and the axes ({keys.key_for('toggle_floor')}); "
                               f"{keys.key_for('measure_cycle')} measures on the photo alone")
        if self.v.photo is not None:
            opacity = f"{keys.key_for('change_opacity', -0.1)} {keys.key_for('change_opacity', 0.1)}"
            imgui.text_wrapped(f"photo {self.v.photo}, overlay {100 * self.v.photo_opacity:.0f} %  ({opacity})")
        imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.45, 0.1, 1.0))
        for line in self.stale:
            imgui.text_wrapped(line)
        imgui.pop_style_color()
        imgui.separator()
        imgui.text_wrapped("selection: " + (self.v.describe(self.v.selection) if self.v.selection else "none"))
        if banner:
            imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.25, 0.2, 1.0))
            imgui.text_wrapped(LABEL)
            imgui.pop_style_color()
        sel = self.v.selection
        for m in self.v.messages[-2:]:  # the newest two, but what the selection's line above says
            if m and not (sel and (m.startswith((f"{sel}: ", f"{sel} in ")) or m == f"selected '{sel}'")):
                imgui.text_wrapped(m)
        imgui.separator()
        if imgui.button("Keys (hide)" if self.show_keys else "Keys"):
            self.show_keys = not self.show_keys
        imgui.same_line()
        imgui.text_disabled(f"{keys.key_for('toggle_panel')}: panel   {keys.key_for('toggle_presentation')}: present")
        if imgui.collapsing_header("Views"):
            for v in self.v.project.data.get("views", []):
                if imgui.button(v["name"]):
                    self.v.jump_to_view(v["name"])
            _, self._new_view_name = imgui.input_text("name##view", self._new_view_name)
            if imgui.button("save the current view"):
                self.v.guard(self.v.save_view, self._new_view_name)
        if self.v.has_model and imgui.collapsing_header("Hypotheses"):
            if imgui.button("measured scene"):
                self.v.reset(everything=True)
            for h in self.v.project.data.get("hypotheses", []):
                if imgui.button(h["name"]):
                    self.v.guard(self.v.load_hypothesis, h["name"])
            _, self._new_hypothesis_name = imgui.input_text("name##hyp", self._new_hypothesis_name)
            if imgui.button("save this arrangement as a hypothesis"):
                self.v.guard(self.v.save_hypothesis, self._new_hypothesis_name)
        imgui.end()

    def _fit_keys(self, imgui: Any, width: float, height: float, f: float) -> tuple[float, float, float, float]:
        """The text size (at most ``f``) at which the key table's two columns fit a sheet of
        ``width`` × ``height``; with the key and description columns' widths and the height needed."""
        rows = self.v.keys.rows()
        half = (len(rows) + 1) // 2
        for _ in range(8):  # shrink the text until both columns fit the sheet's height
            imgui.push_font(None, f)
            style = imgui.get_style()
            col = (width - 2 * style.window_padding.x) / 2 - style.item_spacing.x
            kw, dw = 0.3 * col, 0.7 * col - style.item_spacing.x
            need = max(sum(max(imgui.calc_text_size(k, False, kw).y, imgui.calc_text_size(d, False, dw).y)
                           + style.item_spacing.y for k, d in part) for part in (rows[:half], rows[half:]))
            need += 2 * style.window_padding.y + imgui.get_frame_height() + style.item_spacing.y
            imgui.pop_font()
            if need <= height or f <= MIN_KEYS_TEXT_PX:
                break
            f = max(MIN_KEYS_TEXT_PX, f * math.sqrt(0.97 * height / need))  # the height goes as f²
        return f, kw, dw, need

    def _draw_keys(self, imgui: Any, lay: PanelLayout) -> None:
        """The key table as a sheet in two columns, its text made smaller until every binding fits
        (never a scrolled list): left of the panel, or over it where the whole window gives larger
        text (a narrow window). Its close box or the Keys button hides it."""
        W, _ = glfw.get_window_size(self.v.window.handle)
        m = 0.5 * lay.text_px
        rows = self.v.keys.rows()
        half = (len(rows) + 1) // 2
        height = lay.max_height
        fits = [(self._fit_keys(imgui, w, height, lay.text_px), w) for w in (max(1.0, lay.x - 2 * m), W - 2 * m)]
        (f, kw, dw, need), width = max(fits, key=lambda fw: fw[0][0])  # the larger text; the left on a tie
        imgui.push_font(None, f)
        imgui.set_next_window_pos(imgui.ImVec2(m, lay.y))
        imgui.set_next_window_size(imgui.ImVec2(width, min(height, need)))
        _, self.show_keys = imgui.begin("Keys and mouse", True, imgui.WindowFlags_.no_move
                                        | imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_resize
                                        | imgui.WindowFlags_.no_scrollbar)
        self._window_rect(imgui, "keys")
        self.keys_text_px = f
        if imgui.begin_table("##keys", 4):
            imgui.table_setup_column("k1", imgui.TableColumnFlags_.width_fixed, kw)
            imgui.table_setup_column("d1", imgui.TableColumnFlags_.width_fixed, dw)
            imgui.table_setup_column("k2", imgui.TableColumnFlags_.width_fixed, kw)
            imgui.table_setup_column("d2", imgui.TableColumnFlags_.width_fixed, dw)
            for i in range(half):
                imgui.table_next_row()
                for j, (k, d) in enumerate(p for p in (rows[i], rows[i + half] if i + half < len(rows) else None)
                                           if p is not None):
                    imgui.table_set_column_index(2 * j)
                    imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.85, 0.4, 1.0))
                    imgui.text_wrapped(k)
                    imgui.pop_style_color()
                    imgui.table_set_column_index(2 * j + 1)
                    imgui.text_wrapped(d)
            imgui.end_table()
        imgui.end()
        imgui.pop_font()

    def _draw_unobserved(self, imgui: Any) -> None:
        """The unobserved-surface setting, and its legend in the mark's colour where it marks any."""
        from vebuild.render.observed import LEGEND_TEXT, UNOBSERVED_SRGB

        r = self.v.renderer
        imgui.text(f"unobserved: {r.unobserved}   ({self.v.keys.key_for('next_unobserved')})")
        if r.marks_unobserved:
            c = [v / 255.0 for v in UNOBSERVED_SRGB]
            imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(c[0], c[1], c[2], 1.0))
            imgui.text_wrapped(LEGEND_TEXT[r.unobserved])
            imgui.pop_style_color()

    def _draw_markers(self, imgui: Any) -> None:
        """The project's evidence markers over the view: a filled pin where seen, hollow where hidden."""
        from vebuild.analysis.markers import MARKER_COLOUR, visible_markers

        markers = self.v.project.data.get("evidence_markers", [])
        if not markers or self.v.stereo is not None or not self.v.has_model:
            return
        W, H = self.v.window.framebuffer_size()
        ww, wh = glfw.get_window_size(self.v.window.handle)
        sx, sy = W / max(ww, 1), H / max(wh, 1)
        vx, vy, vw, vh = self.v.viewport()
        dl = imgui.get_foreground_draw_list()
        colour = imgui.get_color_u32(imgui.ImVec4(*(c / 255 for c in MARKER_COLOUR), 1.0))
        white = imgui.get_color_u32(imgui.ImVec4(1.0, 1.0, 1.0, 1.0))
        for m, (u, v), visible in visible_markers(self.v.renderer, self.v.camera(), markers):
            p = imgui.ImVec2((vx + u) / sx, (H - vy - vh + v) / sy)
            if visible:
                dl.add_circle_filled(p, 6.0, colour)
            else:
                dl.add_circle(p, 6.0, colour, 0, 2.0)
            dl.add_text(imgui.ImVec2(p.x + 9, p.y - 8), white, m["label"] + ("" if visible else " (hidden)"))

    def _draw_trajectories(self, imgui: Any) -> None:
        """Recorded trajectories over the view: the path in red, its uncertainty cone in orange (not
        depth-tested: drawn over what hides them)."""
        if not self.v.trajectories() or self.v.stereo is not None:
            return
        cam = self.v.camera()
        W, H = self.v.window.framebuffer_size()
        ww, wh = glfw.get_window_size(self.v.window.handle)
        sx, sy = W / max(ww, 1), H / max(wh, 1)
        vx, vy, vw, vh = self.v.viewport()
        dl = imgui.get_foreground_draw_list()
        colours = {"path": imgui.get_color_u32(imgui.ImVec4(0.9, 0.1, 0.1, 1.0)),
                   "cone": imgui.get_color_u32(imgui.ImVec4(1.0, 0.6, 0.1, 0.8))}
        for _, polylines in self.v._trajectory_cache:
            for kind, lines in polylines.items():
                for P in lines:
                    P = np.asarray(P, float)
                    ok = world_to_camera(cam.R, cam.C, P)[:, 2] > 0.05  # in front of the camera
                    uv = project(cam.K, cam.R, cam.C, P[ok], cam.lens)  # a photo's camera: through its lens
                    pts = [imgui.ImVec2((vx + u) / sx, (H - vy - vh + v) / sy) for u, v in uv]
                    for a, b in zip(pts[:-1], pts[1:], strict=True):
                        dl.add_line(a, b, colours.get(kind, colours["cone"]), 2.0 if kind == "path" else 1.0)
