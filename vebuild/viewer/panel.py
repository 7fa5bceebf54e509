"""The walk-through's Dear ImGui layer: the panel (position, lighting, stereo, the selection, the
messages, the keys from :data:`vebuild.viewer.keys.VIEWER_KEYS`, named views and hypotheses), the
HYPOTHESIS banner, and the evidence markers and recorded trajectories drawn over the view."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import glfw
import numpy as np

from vebuild.camera import project, world_to_camera
from vebuild.project import Project
from vebuild.project.hypotheses import LABEL
from vebuild.project.provenance import stale, stale_line

if TYPE_CHECKING:
    from vebuild.viewer.app import Viewer


def stale_lines(project: Project) -> list[str]:
    """The panel's stale lines: the short line, then each stale result's message; none if current."""
    found = stale(project.data, str(project.path))
    line = stale_line(found)
    return [line, *(s.message for s in found)] if line else []


class ViewerPanel:
    """The panel of a :class:`~vebuild.viewer.app.Viewer` (``viewer.panel``): it holds the names
    being typed into it and draws with the viewer's state, calling its commands."""

    def __init__(self, viewer: Viewer):
        self.v = viewer
        self._new_view_name = ""
        self._new_hypothesis_name = ""
        self.stale = stale_lines(viewer.project)  # the walk-through never changes a result

    def draw(self) -> None:
        from imgui_bundle import imgui

        gui, keys = self.v.gui, self.v.keys
        gui.new_frame()
        self._draw_markers(imgui)
        self._draw_trajectories(imgui)
        banner = self.v.banner()
        if banner:
            imgui.set_next_window_pos(imgui.ImVec2(10, 10))
            imgui.begin("##hypothesis", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                        | imgui.WindowFlags_.no_inputs)
            imgui.text_colored(imgui.ImVec4(1.0, 0.25, 0.2, 1.0), banner)
            imgui.end()
        if self.v.show_panel:
            W, _ = glfw.get_window_size(self.v.window.handle)
            imgui.set_next_window_pos(imgui.ImVec2(W - 370, 10), imgui.Cond_.first_use_ever)
            imgui.set_next_window_size(imgui.ImVec2(360, 0), imgui.Cond_.first_use_ever)
            imgui.begin(f"vebuild: {self.v.project.data.get('name', self.v.project.path.name)}")
            p = self.v.walker.position
            imgui.text(f"{self.v.fps:5.1f} fps   {'flying' if self.v.walker.fly else 'walking'}   "
                       f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) m")
            imgui.text(f"lighting: {self.v.lighting}   ({keys.key_for('next_lighting')})")
            imgui.text(f"stereo: {self.v.stereo or 'off'}   ({keys.key_for('next_stereo')})")
            self._draw_unobserved(imgui)
            if self.v.photo is not None:
                opacity = f"{keys.key_for('change_opacity', -0.1)} {keys.key_for('change_opacity', 0.1)}"
                imgui.text(f"photo {self.v.photo}, overlay {100 * self.v.photo_opacity:.0f} %  ({opacity})")
            imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.45, 0.1, 1.0))
            for line in self.stale:
                imgui.text_wrapped(line)
            imgui.pop_style_color()
            imgui.separator()
            imgui.text_wrapped("selection: " + (self.v.describe(self.v.selection) if self.v.selection else "none"))
            if banner:
                imgui.text_colored(imgui.ImVec4(1.0, 0.25, 0.2, 1.0), LABEL)
            for m in self.v.messages[-3:]:
                imgui.text_wrapped(m)
            if imgui.collapsing_header("Keys"):
                for k, what in self.v.keys.rows():
                    imgui.text_wrapped(f"{k}: {what}")
            if imgui.collapsing_header("Views"):
                for v in self.v.project.data.get("views", []):
                    if imgui.button(v["name"]):
                        self.v.jump_to_view(v["name"])
                _, self._new_view_name = imgui.input_text("name##view", self._new_view_name)
                if imgui.button("save the current view"):
                    self.v.guard(self.v.save_view, self._new_view_name)
            if imgui.collapsing_header("Hypotheses"):
                if imgui.button("measured scene"):
                    self.v.reset(everything=True)
                for h in self.v.project.data.get("hypotheses", []):
                    if imgui.button(h["name"]):
                        self.v.guard(self.v.load_hypothesis, h["name"])
                _, self._new_hypothesis_name = imgui.input_text("name##hyp", self._new_hypothesis_name)
                if imgui.button("save this arrangement as a hypothesis"):
                    self.v.guard(self.v.save_hypothesis, self._new_hypothesis_name)
            imgui.end()
        gui.render()

    def _draw_unobserved(self, imgui: Any) -> None:
        """The unobserved-surface setting, and its legend in the mark's colour where it marks any."""
        from vebuild.render.observed import LEGEND_TEXT, UNOBSERVED_SRGB

        r = self.v.renderer
        imgui.text(f"unobserved: {r.unobserved}   ({self.v.keys.key_for('next_unobserved')})")
        if r.marks_unobserved:
            c = [v / 255.0 for v in UNOBSERVED_SRGB]
            imgui.text_colored(imgui.ImVec4(c[0], c[1], c[2], 1.0), LEGEND_TEXT[r.unobserved])

    def _draw_markers(self, imgui: Any) -> None:
        """The project's evidence markers over the view: a filled pin where seen, hollow where hidden."""
        from vebuild.analysis.markers import MARKER_COLOUR, visible_markers

        markers = self.v.project.data.get("evidence_markers", [])
        if not markers or self.v.stereo is not None:
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
                    uv = project(cam.K, cam.R, cam.C, P[ok], cam.k1)  # a photo's camera: through its lens
                    pts = [imgui.ImVec2((vx + u) / sx, (H - vy - vh + v) / sy) for u, v in uv]
                    for a, b in zip(pts[:-1], pts[1:], strict=True):
                        dl.add_line(a, b, colours.get(kind, colours["cone"]), 2.0 if kind == "path" else 1.0)
