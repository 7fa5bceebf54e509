"""The modelling screen's measuring and marking by clicking on the photo (a part of the Editor):
the Measure tool (T: distance, height, dimension in turn), the Evidence marker tool (X: a click on
a surface places one, a click on one removes it) and the Trajectory tool (J: the entry hole, then
the exit hole); U clears what was measured from the view.

A click at photo pixel (u, v) is the command line's ``photo:ID@u,v`` pick on the solved model,
written as its ``node@face:s,t`` reference and measured by the command line's own request
(:mod:`vebuild.actions.click_measure`). Each result is drawn over the photo (a line with its
label) and added to the project's ``analyses`` as one undoable edit of the session (saved with
the project, Ctrl+S); markers likewise to ``evidence_markers``.

With no solved model, the Measure tool measures a calibrated photo on its own (single-view
metrology, :mod:`vebuild.actions.click_single_view`): T cycles the single-view measurements (a
height above the floor, a distance on the floor, …), the message line names the next point to
click, and the result is the command line's ``vebuild analyse PROJECT photo-height --photo ID U V
…`` on the saved words, drawn on the photo and saved in the same way.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from imgui_bundle import imgui

from vebuild.actions import click_measure as cm
from vebuild.actions import click_single_view as sv
from vebuild.camera import project as project_points
from vebuild.camera import world_to_camera
from vebuild.errors import VebuildError

from .layout import EditorPart, u32

#: The tools this part handles.
MEASURE_TOOLS = ("measure", "evidence", "trajectory")
MEASURE_COLOUR = (0.15, 0.85, 1.0, 1.0)
TRAJECTORY_COLOUR = (0.9, 0.1, 0.1, 1.0)
CONE_COLOUR = (1.0, 0.6, 0.1, 0.9)


class MeasureTool(EditorPart):
    """Measure, Evidence marker and Trajectory tools (a part of the Editor)."""

    measure_kind: str = cm.MEASURES[0]
    #: The single-view measurement the Measure tool makes on a calibrated photo with no solved model.
    single_view_kind: str = "photo-height"

    def _measure_state(self) -> dict[str, Any]:
        st = self.__dict__.get("_measure")
        if st is None:
            st = self.__dict__["_measure"] = {"clicks": [], "drawn": [], "solved": None, "revision": None,
                                              "pixels": []}
        return st

    @property
    def measure_clicks(self) -> list[cm.Clicked]:
        return list(self._measure_state()["clicks"])

    @property
    def single_view_clicks(self) -> list[tuple[float, float]]:
        """The photo pixels clicked so far for the single-view measurement under way."""
        return list(self._measure_state()["pixels"])

    @property
    def measured(self) -> list[cm.Measured]:
        """What was measured by clicking and is still in the project's analyses (an undone one is
        not), drawn over the photos."""
        names = {r.get("name") for r in self.session.data.get("analyses") or []}
        return [m for m in self._measure_state()["drawn"] if m.name in names]

    def measure_prompt(self) -> str | None:
        """While the Measure tool measures the photo shown on its own, the point to click next, in
        words (the message area holds it above the messages); None otherwise."""
        if self.tool != "measure" or self.photo is None:
            return None
        st = self._measure_state()
        key = (self.session.revision, self.photo)
        if st.get("alone_for") != key:  # whether it measures the photo alone, once per edit and photo
            try:
                st["alone"] = self.single_view()
            except cm.ClickError:
                st["alone"] = False
            st["alone_for"] = key
        if not st["alone"]:
            return None
        kind = self.single_view_kind
        done = len(st["pixels"]) if st.get("for") == ("single", kind, self.photo) else 0
        return f"measure on the photo alone: {sv.prompt(kind, done)}; T: the next measurement, Esc: stop"

    def single_view(self) -> bool:
        """Whether the Measure tool measures the photo shown on its own: the project has no solved
        model and the photo is calibrated. Neither: a :class:`ClickError` saying what each needs."""
        try:
            self._solved()
            return False
        except cm.ClickError as e:
            if self.photo is not None and self.photo in self.session.cameras:
                return True
            why = str(e).removeprefix("measuring needs a solved model: ")
            raise cm.ClickError(f"measuring needs this photo calibrated (Calibrate, in the Calibration tab), to "
                                f"measure on the photo alone, or a solved model, to measure on the model ({why})"
                                ) from None

    def measure_cycle(self) -> None:
        """T: the Measure tool; pressed again, the next measurement (distance, height, dimension;
        on a calibrated photo with no solved model, the single-view measurements)."""
        again = self.tool == "measure"
        if not again:
            self.set_tool("measure")
        st = self._measure_state()
        st["clicks"], st["pixels"] = [], []
        try:
            alone = self.single_view()
        except cm.ClickError as e:
            self.say(str(e))
            return
        if alone:
            kinds = sv.kinds()
            k = kinds.index(self.single_view_kind) if self.single_view_kind in kinds else -1
            self.single_view_kind = kinds[(k + 1) % len(kinds) if again or k < 0 else k]
            self.say(f"measure on photo {self.photo} alone: {sv.prompt(self.single_view_kind, 0)} "
                     "(T: the next measurement)")
            return
        if again:
            self.measure_kind = cm.MEASURES[(cm.MEASURES.index(self.measure_kind) + 1) % len(cm.MEASURES)]
        hint = {"distance": "click two points on the model's surfaces",
                "height": "click a point (its height above the floor)", "dimension": "click an object"}
        self.say(f"measure {self.measure_kind}: {hint[self.measure_kind]} in the photo (T: the next measurement)")

    def clear_measures(self) -> None:
        """U: stop drawing the measurements (they stay in the project's analyses)."""
        self._measure_state().update(clicks=[], drawn=[], pixels=[])
        self.say("measurements cleared from the view (the analyses stay in the project)")

    def _solved(self) -> Any:
        st = self._measure_state()
        if st["solved"] is None or st["revision"] != self.session.revision:
            st["solved"], st["revision"] = cm.solved_model(self.session.project), self.session.revision
        return st["solved"]

    def _single_view_click(self, uv: tuple[float, float]) -> None:
        """A click of a single-view measurement: the next point, or the last and the measurement."""
        st, kind = self._measure_state(), self.single_view_kind
        assert self.photo is not None
        if st.get("for") != ("single", kind, self.photo):  # clicks of another measurement or photo
            st["pixels"], st["for"] = [], ("single", kind, self.photo)
        shown = self.session.photo(self.photo)
        sv.check_click(int(shown["width"]), int(shown["height"]), uv)
        st["pixels"].append((float(uv[0]), float(uv[1])))
        if len(st["pixels"]) < len(sv.prompts(kind)):
            self.say(f"({uv[0]:.1f}, {uv[1]:.1f}); {sv.prompt(kind, len(st['pixels']))}")
            return
        pixels, st["pixels"] = st["pixels"], []
        try:
            measured = sv.measure_on_photo(self.session.project, kind, self.photo, pixels)
        except cm.ClickError as e:  # the clicks cannot be measured: said, and begun again
            raise cm.ClickError(f"{e}; begin again: {sv.prompt(kind, 0)}") from None
        self._measured(measured)
        self.say(f"next: {sv.prompt(kind, 0)} (T: the next measurement)")

    def measure_release(self, x: float, y: float) -> None:
        """A click with one of :data:`MEASURE_TOOLS` at window point (x, y)."""
        if self.photo is None:
            return
        uv = self.window_to_image(x, y)
        s, st = self.session, self._measure_state()
        if self.tool == "measure" and self.single_view():
            self._single_view_click(uv)
            return
        if st.get("for") != (self.tool, self.measure_kind, self.photo):  # clicks of another tool or photo
            st["clicks"], st["for"] = [], (self.tool, self.measure_kind, self.photo)
        if self.tool == "measure" and self.measure_kind == "dimension":
            clicked = cm.photo_reference(s.project, self._solved(), self.photo, uv)
            self._measured(cm.measure(s.project, "dimension", [cm.Clicked(clicked.node, clicked.node, "",
                                                                          clicked.world)]))
            return
        if self.tool == "evidence":
            label = self._marker_at(uv)
            if label is not None:
                with s._edit(f"remove evidence marker {label}"):
                    cm.remove_marker(s.data, label)
                self.say(f"evidence marker {label} removed")
                return
        clicked = cm.photo_reference(s.project, self._solved(), self.photo, uv)
        if self.tool == "evidence":
            with s._edit("place an evidence marker"):
                rec = cm.place_marker(s.data, clicked.node, clicked.world)
            self.say(f"evidence marker {rec['label']} on {clicked.node} at "
                     f"({', '.join(f'{c:.3f}' for c in clicked.world)}) m")
            return
        kind = "trajectory" if self.tool == "trajectory" else self.measure_kind
        st["clicks"].append(clicked)
        if len(st["clicks"]) < cm.CLICKS[kind]:
            then = "the exit hole" if kind == "trajectory" else "the second point"
            self.say(f"{kind}: {clicked.reference}; click {then}")
            return
        clicks, st["clicks"] = st["clicks"], []
        if kind == "trajectory":
            self._measured(cm.trajectory(s.project, clicks[0], clicks[1]))
        else:
            self._measured(cm.measure(s.project, kind, clicks))

    def _measured(self, m: cm.Measured) -> None:
        with self.session._edit(f"clicked {m.kind}"):
            cm.save_analysis(self.session.data, m)
        self._measure_state()["drawn"].append(m)
        self.say(f"{m.label}; added to the analyses as '{m.name}' (Ctrl+S saves)")

    def _marker_at(self, uv: tuple[float, float]) -> str | None:
        markers = self.session.data.get("evidence_markers") or []
        cam = self.session.cameras.get(self.photo)
        if not markers or cam is None:
            return None
        pins = []
        for m in markers:
            X = np.asarray(m["position"], float)
            if world_to_camera(cam.R, cam.C, X)[2] > 0:
                u, v = project_points(cam.K, cam.R, cam.C, X, cam.lens)
                pins.append((m["label"], float(u), float(v)))
        return cm.marker_near(self.session.data, pins, uv, cm.MARKER_PICK_PX / self.zoom)

    # -- drawing ---------------------------------------------------------------------------------

    def _photo_points(self, P: Any) -> list[tuple[float, float] | None]:
        cam = self.session.cameras.get(self.photo)
        out: list[tuple[float, float] | None] = []
        for X in np.asarray(P, float).reshape(-1, 3):
            if cam is None or world_to_camera(cam.R, cam.C, X)[2] <= 0.05:
                out.append(None)
                continue
            out.append(self.image_to_window(None, project_points(cam.K, cam.R, cam.C, X, cam.lens)))
        return out

    def _draw_measures(self) -> None:
        """The measurements, the evidence markers and the points clicked so far, over the photo."""
        if self.photo is None:
            return
        st = self._measure_state()
        markers = self.session.data.get("evidence_markers") or []
        if not (st["drawn"] or st["clicks"] or st["pixels"] or markers):
            return
        try:
            self._draw_measures_on(imgui.get_background_draw_list(), st, markers)
        except VebuildError as e:
            self.say(str(e))

    def _draw_measures_on(self, dl: Any, st: dict[str, Any], markers: list[dict[str, Any]]) -> None:
        from vebuild.analysis.markers import MARKER_COLOUR

        x0, y0, x1, y1 = self.view_rect()
        st["labels"] = []  # the labels placed in this frame
        dl.push_clip_rect((x0, y0), (x1, y1), True)
        colour, white = u32(MEASURE_COLOUR), u32((1, 1, 1, 1))
        pin = u32((*(c / 255 for c in MARKER_COLOUR), 1.0))
        for mark, p in zip(markers, self._photo_points([mk["position"] for mk in markers]), strict=True):
            if p is not None:
                dl.add_circle_filled(p, 6.0, pin)
                dl.add_text((p[0] + 9, p[1] - 8), white, mark["label"])
        for c in st["clicks"]:
            (p,) = self._photo_points(c.world)
            if p is not None:
                dl.add_circle(p, 5.0, colour, 0, 2.0)
        if st.get("for", (None,) * 3)[2] == self.photo:  # a single-view measurement's clicks so far, numbered
            for k, uv in enumerate(st["pixels"]):
                p = self.image_to_window(None, uv)
                dl.add_circle(p, 5.0, colour, 0, 2.0)
                dl.add_text((p[0] + 7, p[1] - 16), white, str(k + 1))
        for m in self.measured:
            if m.photo is not None:
                if m.photo == self.photo:
                    self._draw_single_view(dl, m, colour)
                continue
            pts = self._photo_points(np.array(m.points))
            if m.kind == "trajectory":  # its path and cone, the label at the entry hole
                self._draw_trajectory(dl, m)
                pts = pts[:1]
            for a, b in zip(pts[:-1], pts[1:], strict=True):
                if a is not None and b is not None:
                    dl.add_line(a, b, colour, 2.0)
            shown = [p for p in pts if p is not None]
            for p in shown:
                dl.add_circle_filled(p, 4.0, colour)
            if shown:
                self._draw_label(dl, m.label, (sum(p[0] for p in shown) / len(shown),
                                               sum(p[1] for p in shown) / len(shown)))
        dl.pop_clip_rect()

    def _draw_label(self, dl: Any, label: str, near: tuple[float, float]) -> None:
        """A measurement's label beside window point ``near``, on a dark band, kept inside the view
        and clear of the labels drawn before it in this frame (moved down a line until clear)."""
        x0, _, x1, _ = self.view_rect()
        size = imgui.calc_text_size(label)
        at = (max(x0 + 2, min(near[0] + 8, x1 - size.x - 4)), near[1])
        placed: list[tuple[float, float, float, float]] = self._measure_state().setdefault("labels", [])
        for _ in range(len(placed) + 1):
            box = (at[0] - 2, at[1] - 1, at[0] + size.x + 2, at[1] + size.y + 1)
            if not any(box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3] for b in placed):
                break
            at = (at[0], at[1] + size.y + 3)
        placed.append((at[0] - 2, at[1] - 1, at[0] + size.x + 2, at[1] + size.y + 1))
        dl.add_rect_filled((at[0] - 2, at[1] - 1), (at[0] + size.x + 2, at[1] + size.y + 1), u32((0, 0, 0, 0.75)))
        dl.add_text(at, u32((1, 1, 1, 1)), label)

    def _draw_single_view(self, dl: Any, m: cm.Measured, colour: int) -> None:
        """A measurement on the photo alone: foot → top (or end → end) with its label, the
        reference clicks (a wall's foot, a raised surface, a plane) thinner."""
        pairs = sv.drawn_pairs(m.kind, m.pixels)
        for k, (a, b) in enumerate(pairs):
            pa, pb = self.image_to_window(None, a), self.image_to_window(None, b)
            dl.add_line(pa, pb, colour, 3.0 if k == 0 else 1.5)
        for uv in m.pixels:
            dl.add_circle_filled(self.image_to_window(None, uv), 4.0, colour)
        if pairs:
            a, b = (self.image_to_window(None, p) for p in pairs[0])
            self._draw_label(dl, m.label, (0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])))

    def _draw_trajectory(self, dl: Any, m: cm.Measured) -> None:
        """The path and its cone (the world polylines :func:`vebuild.analysis.trajectory.path_polylines`
        gives), over the photo."""
        from vebuild.analysis.rays import Occluders
        from vebuild.analysis.trajectory import path_polylines
        from vebuild.render.scene import load_scene

        cache = self._measure_state().setdefault("polylines", {})
        if id(m) not in cache:
            request: Any = m.request  # a TrajectoryRequest
            cache[id(m)] = path_polylines(request.trajectory(Occluders(load_scene(self.session.project))))
        for kind, lines in cache[id(m)].items():
            c = u32(TRAJECTORY_COLOUR if kind == "path" else CONE_COLOUR)
            for P in lines:
                pts = self._photo_points(P)
                for a, b in zip(pts[:-1], pts[1:], strict=True):
                    if a is not None and b is not None:
                        dl.add_line(a, b, c, 2.0 if kind == "path" else 1.0)
