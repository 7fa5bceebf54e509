"""The walk-through's measuring and marking by clicking (a part of the
:class:`~vebuild.viewer.app.Viewer`): the measure tool (T: distance, height, dimension in turn),
evidence markers (M: a click places one, a click on one removes it) and trajectories (J: the entry
hole, then the exit hole; H: from the entry hole straight along the view).

A click is picked through the renderer's one-pixel ID buffer (the node and world point seen
there) and handed to :mod:`vebuild.actions.click_measure`, which makes the command line's point
reference and runs its request; each result is drawn over the view (a line with its label) and
saved in the project's ``analyses`` (the markers in ``evidence_markers``), as the walk-through
saves views and hypotheses.

With no solved model, a photo shown at its calibrated camera (P) is measured on its own
(single-view metrology, :mod:`vebuild.actions.click_single_view`): T cycles the single-view
measurements, the message line names each point to click on the photo, and the result is the
command line's ``vebuild analyse PROJECT photo-height --photo ID U V …`` on the saved words.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import glfw
import numpy as np

from vebuild.actions import click_measure as cm
from vebuild.actions import click_single_view as sv
from vebuild.camera import project as project_points
from vebuild.camera import world_to_camera
from vebuild.errors import VebuildError
from vebuild.project import save_project

if TYPE_CHECKING:
    from vebuild.analysis.solved import SolvedModel

#: The tool's modes, in the order T cycles the measurements.
MODES = (*cm.MEASURES, "marker", "trajectory")
MEASURE_COLOUR = (0.15, 0.85, 1.0, 1.0)


class ViewerMeasure:
    """Measure, marker and trajectory tools (mixed into the Viewer, which provides ``pick``,
    ``camera``, ``say``, ``project``, ``renderer``, ``arranged``, ``viewport`` and ``window``)."""

    measure_mode: str | None = None

    def _measure_state(self) -> dict[str, Any]:
        st = self.__dict__.get("_measure")
        if st is None:
            st = self.__dict__["_measure"] = {"clicks": [], "drawn": [], "solved": None, "pixels": []}
        return st

    @property
    def single_view_clicks(self) -> list[tuple[float, float]]:
        """The photo pixels clicked so far for the single-view measurement under way."""
        return list(self._measure_state()["pixels"])

    def single_view(self) -> bool:
        """Whether T measures the photo shown on its own: no solved model, a photo shown at its
        camera (P). Neither: a :class:`VebuildError` saying what each needs."""
        v: Any = self
        if not v.has_model:
            if v.photo is None:
                raise cm.ClickError("the project has no model: T measures on a photo shown at its camera; P shows one")
            return True
        try:
            self._solved()
            return False
        except cm.ClickError as e:
            if v.photo is not None:
                return True
            raise cm.ClickError(f"{e}; or show a calibrated photo at its camera (P) to measure on the photo "
                                "alone") from None

    @property
    def measure_clicks(self) -> list[cm.Clicked]:
        return list(self._measure_state()["clicks"])

    @property
    def measured(self) -> list[cm.Measured]:
        """What was measured by clicking in this window, drawn over the view."""
        return list(self._measure_state()["drawn"])

    def _set_mode(self, mode: str | None) -> None:
        v: Any = self
        self.measure_mode = mode
        self._measure_state().update(clicks=[], pixels=[])
        if mode in sv.kinds():
            v.say(f"measure on photo {v.photo} alone: {sv.prompt(str(mode), 0)} (T: the next measurement)")
            return
        hints = {"distance": "click two surface points", "height": "click a surface point (its height above the floor)",
                 "dimension": "click an object (its dimensions)",
                 "marker": "click a surface to place an evidence marker, click a marker to remove it",
                 "trajectory": "click the entry hole, then the exit hole (or H: along the view)"}
        v.say(f"measure: {mode}: {hints[mode]}" if mode else "measure tool off")

    def measure_cycle(self) -> None:
        """T: the measure tool, distance → height → dimension → off; on a photo shown at its camera
        with no solved model, the single-view measurements → off."""
        m = self.measure_mode
        try:
            order: list[str | None] = [*(sv.kinds() if self.single_view() else cm.MEASURES), None]
        except cm.ClickError as e:
            v: Any = self
            v.say(str(e))
            return
        self._set_mode(order[order.index(m) + 1] if m in order[:-1] else order[0])

    def show_saved_single_view(self) -> None:
        """Draw the single-view measurements the project has saved, each on its photo: its saved
        words run again (the command line's figure); one that cannot be run is said and left out."""
        v: Any = self
        for rec in v.project.data.get("analyses") or []:
            words = rec.get("command") or []
            if not words or words[0] not in sv.kinds() or len(words) < 3 or words[1] != "--photo":
                continue
            try:
                photo, clicks = sv.saved_clicks(list(words))
                measured = sv.measure_on_photo(v.project, words[0], photo, clicks)
            except (ValueError, VebuildError) as e:
                reason = str(e) if isinstance(e, VebuildError) else "its pixels are not pairs of numbers"
                v.say(f"saved measurement {rec.get('name')!r} not drawn: {reason}")
                continue
            measured.name = str(rec.get("name", ""))
            self._measure_state()["drawn"].append(measured)

    def marker_tool(self) -> None:
        """M: the evidence marker tool on or off."""
        v: Any = self
        v.needs_model("Placing evidence markers on the model's surfaces")
        self._set_mode(None if self.measure_mode == "marker" else "marker")

    def trajectory_tool(self) -> None:
        """J: the trajectory tool on or off."""
        v: Any = self
        v.needs_model("A trajectory (a sight line through the model)")
        self._set_mode(None if self.measure_mode == "trajectory" else "trajectory")

    def clear_measures(self) -> None:
        """N: stop drawing the measurements (they stay saved in the project)."""
        self._measure_state()["drawn"] = []
        self._measure_state()["clicks"] = []
        v: Any = self
        v.say("measurements cleared from the view (the saved analyses stay in the project)")

    def _solved(self) -> SolvedModel:
        st = self._measure_state()
        if st["solved"] is None:
            v: Any = self
            st["solved"] = cm.solved_model(v.project)
        solved: SolvedModel = st["solved"]
        return solved

    def measure_click(self) -> bool:
        """A left press: taken by the tool when one is on (True), else left to selection."""
        if self.measure_mode is None:
            return False
        v: Any = self
        v.guard(self._click)
        return True

    def _single_view_click(self, kind: str) -> None:
        """A click of a single-view measurement on the photo shown: the next point, or the last and
        the measurement (the view's pixel taken back to the photo's)."""
        v: Any = self
        uv = v.cursor_image()
        if uv is None or v.photo is None:
            raise VebuildError("click on the photo (P shows one at its camera)")
        scale = v.viewport()[2] / v.project.photo(v.photo)["width"]
        st = self._measure_state()
        if st.get("for") != (kind, v.photo):  # clicks of another measurement or photo
            st["pixels"], st["for"] = [], (kind, v.photo)
        st["pixels"].append((uv[0] / scale, uv[1] / scale))
        if len(st["pixels"]) < len(sv.prompts(kind)):
            v.say(f"({uv[0] / scale:.1f}, {uv[1] / scale:.1f}); {sv.prompt(kind, len(st['pixels']))}")
            return
        pixels, st["pixels"] = st["pixels"], []
        try:
            measured = sv.measure_on_photo(v.project, kind, v.photo, pixels)
        except cm.ClickError as e:  # the clicks cannot be measured: said, and begun again
            raise cm.ClickError(f"{e}; begin again: {sv.prompt(kind, 0)}") from None
        self._finish(measured)

    def _click(self) -> None:
        v: Any = self
        mode = self.measure_mode
        if mode in sv.kinds():
            if not self.single_view():  # solved since T was pressed: measure on the model
                self._set_mode(cm.MEASURES[0])
                return
            self._single_view_click(str(mode))
            return
        if mode == "marker" and self._remove_marker_at_cursor():
            return
        node, X = v.pick()
        if node is None or X is None:
            raise VebuildError("no surface under the cursor")
        if v.arranged():
            raise VebuildError("measurements are of the measured scene: put the objects back first (Shift+R)")
        if mode == "marker":
            rec = cm.place_marker(v.project.data, node, X)
            save_project(v.project)
            v.say(f"evidence marker {rec['label']} on {node} at ({', '.join(f'{c:.3f}' for c in X)}) m, saved in "
                  f"{v.project.path.name}")
            return
        if mode == "dimension":
            clicked = cm.Clicked(node, node, "", np.asarray(X, float))
        else:
            clicked = cm.surface_reference(self._solved(), node, X)
        st = self._measure_state()
        st["clicks"].append(clicked)
        need = cm.CLICKS[mode] if mode is not None else 0
        if len(st["clicks"]) < need:
            v.say(f"{mode}: {clicked.reference}; click the {'exit hole' if mode == 'trajectory' else 'second point'}")
            return
        clicks, st["clicks"] = st["clicks"], []
        if mode == "trajectory":
            self._finish(cm.trajectory(v.project, clicks[0], clicks[1]))
        else:
            self._finish(cm.measure(v.project, str(mode), clicks))

    def trajectory_along_view(self) -> None:
        """H: the trajectory from the clicked entry hole along the view's direction."""
        v: Any = self
        v.needs_model("A trajectory (a sight line through the model)")
        st = self._measure_state()
        if self.measure_mode != "trajectory" or len(st["clicks"]) != 1:
            raise VebuildError("H: turn the trajectory tool on (J) and click the entry hole first")
        entry, st["clicks"] = st["clicks"][0], []
        self._finish(cm.trajectory(v.project, entry, direction=np.asarray(v.camera().R, float)[2]))

    def _finish(self, measured: cm.Measured) -> None:
        v: Any = self
        cm.save_analysis(v.project.data, measured)
        save_project(v.project)
        self._measure_state()["drawn"].append(measured)
        v.say(f"{measured.label}; saved as analysis '{measured.name}' in {v.project.path.name}")

    def _remove_marker_at_cursor(self) -> bool:
        from vebuild.analysis.markers import visible_markers

        v: Any = self
        markers = v.project.data.get("evidence_markers") or []
        uv = v.cursor_image()
        if not markers or uv is None:
            return False
        pins = [(m["label"], float(p[0]), float(p[1])) for m, p, _ in visible_markers(v.renderer, v.camera(), markers)]
        label = cm.marker_near(v.project.data, pins, uv)
        if label is None:
            return False
        cm.remove_marker(v.project.data, label)
        save_project(v.project)
        v.say(f"evidence marker {label} removed from {v.project.path.name}")
        return True

    # -- drawing ---------------------------------------------------------------------------------

    def _photo_to_window(self, uv: Any) -> Any:
        """The window point (ImGui's) of a pixel of the photo shown."""
        from imgui_bundle import imgui

        v: Any = self
        W, H = v.window.framebuffer_size()
        ww, wh = glfw.get_window_size(v.window.handle)
        sx, sy = W / max(ww, 1), H / max(wh, 1)
        vx, vy, vw, vh = v.viewport()
        s = vw / v.project.photo(v.photo)["width"]
        return imgui.ImVec2((vx + s * float(uv[0])) / sx, (H - vy - vh + s * float(uv[1])) / sy)

    def _to_window(self, X: Any) -> Any:
        """Window points (ImGui's) of world points in front of the camera; None for one behind it."""
        from imgui_bundle import imgui

        v: Any = self
        cam = v.camera()
        W, H = v.window.framebuffer_size()
        ww, wh = glfw.get_window_size(v.window.handle)
        sx, sy = W / max(ww, 1), H / max(wh, 1)
        vx, vy, vw, vh = v.viewport()
        P = np.atleast_2d(np.asarray(X, float))
        out: list[Any] = []
        for p in P:
            if world_to_camera(cam.R, cam.C, p)[2] <= 0.05:
                out.append(None)
                continue
            u, w = project_points(cam.K, cam.R, cam.C, p, cam.lens)
            out.append(imgui.ImVec2((vx + u) / sx, (H - vy - vh + w) / sy))
        return out

    def draw_measures(self, imgui: Any) -> None:
        """The measurements and the points clicked so far over the view (ImGui's foreground list;
        called by the panel between its frame's start and end)."""
        v: Any = self
        st = self._measure_state()
        if (not st["drawn"] and not st["clicks"] and not st["pixels"]) or v.stereo is not None:
            return
        dl = imgui.get_foreground_draw_list()
        colour = imgui.get_color_u32(imgui.ImVec4(*MEASURE_COLOUR))
        white = imgui.get_color_u32(imgui.ImVec4(1.0, 1.0, 1.0, 1.0))
        black = imgui.get_color_u32(imgui.ImVec4(0.0, 0.0, 0.0, 0.75))
        for c in st["clicks"]:
            (p,) = self._to_window(c.world)
            if p is not None:
                dl.add_circle(p, 5.0, colour, 0, 2.0)
        if v.photo is not None and st.get("for", (None, None))[1] == v.photo:
            for k, uv in enumerate(st["pixels"]):  # a single-view measurement's clicks so far, numbered
                p = self._photo_to_window(uv)
                dl.add_circle(p, 5.0, colour, 0, 2.0)
                dl.add_text(imgui.ImVec2(p.x + 7, p.y - 16), white, str(k + 1))
        for m in st["drawn"]:
            if m.kind == "trajectory":
                continue  # drawn with its cone from the project's analyses
            if m.photo is not None:  # measured on a photo alone: drawn on that photo only
                if m.photo != v.photo:
                    continue
                pairs = sv.drawn_pairs(m.kind, m.pixels)
                for k, (a, b) in enumerate(pairs):
                    dl.add_line(self._photo_to_window(a), self._photo_to_window(b), colour, 2.0 if k == 0 else 1.0)
                pts = [self._photo_to_window(p) for p in (pairs[0] if pairs else [])]
                for uv in m.pixels:
                    dl.add_circle_filled(self._photo_to_window(uv), 4.0, colour)
            else:
                pts = self._to_window(np.array(m.points))
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                if a is not None and b is not None:
                    dl.add_line(a, b, colour, 2.0)
            shown = [p for p in pts if p is not None]
            for p in shown:
                dl.add_circle_filled(p, 4.0, colour)
            if shown:
                size = imgui.calc_text_size(m.label)
                ww = glfw.get_window_size(v.window.handle)[0]  # the label kept inside the window
                at = imgui.ImVec2(max(2.0, min(sum(p.x for p in shown) / len(shown) + 8, ww - size.x - 4)),
                                  sum(p.y for p in shown) / len(shown))
                dl.add_rect_filled(imgui.ImVec2(at.x - 2, at.y - 1), imgui.ImVec2(at.x + size.x + 2, at.y + size.y + 1),
                                   black)
                dl.add_text(at, white, m.label)

