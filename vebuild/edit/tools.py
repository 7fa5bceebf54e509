"""The modelling screen's tools: the mouse and keys over the photo mapped to the session's calls
(drawing segments and edges, placing markers and primitives, dragging vertices, deleting, fixing,
selecting), and the window's close button while edits are unsaved."""

from __future__ import annotations

import math
import time
from typing import Any

import glfw
import numpy as np
from imgui_bundle import imgui

from vebuild.errors import VebuildError

from .click_tools import BUILD_TOOLS
from .layout import CLICK_SLOP_PX, MIDDLE_PICK_PX, PICK_RADIUS_PX, TOOLS, WHEEL_STEP, EditorPart, inside
from .marks import check_length_ends
from .measure_tool import MEASURE_TOOLS


class ScreenTools(EditorPart):
    """The tools and input (a part of the Editor)."""

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

    def on_close(self, handle: Any) -> None:
        if self.session.dirty and not self._close_warned:
            glfw.set_window_should_close(handle, False)
            self._close_warned = True
            self.say(f"unsaved edits: Ctrl+S saves them; close again to leave them in "
                     f"{self.session.autosave_path.name} (offered for recovery when the project is opened)")

    def _photo_takes(self, x: float, y: float) -> bool:
        """Whether a mouse event at (x, y) is the photo view's (not a panel's or a popup's)."""
        if self.photo is None or self._busy or not inside(self.view_rect(), x, y):
            return False
        return not imgui.is_popup_open("", imgui.PopupFlags_.any_popup_id)

    def input_blocked(self) -> bool:
        return bool(self._busy)

    def toggle_labels(self) -> None:
        self.show_labels = not self.show_labels

    def fix_under_cursor(self) -> None:
        """F: fix the vertex under the cursor; with two faces picked by the Relate tool, flush them."""
        if self.tool == "relate" and len(self.relate_picks) == 2:
            self.relate_choose("flush")
            return
        self.toggle_fix_at(*self._cursor)

    def save(self) -> None:
        self.session.save()

    def pick_marker(self, name: str) -> None:
        """The Marker tool, placing marker ``name`` (one already in the project) with the next click."""
        self.marker_name, self._marker_name_default = name, False
        self.set_tool("marker")
        self.say(f"marker {name}: click where it is in {self.photo or 'the photo'}")

    def set_tool(self, tool: str) -> None:
        if tool not in TOOLS:
            raise VebuildError(f"no tool '{tool}'; the tools are {', '.join(TOOLS)}")
        self.escape(keep_tool=True)
        self.tool = tool
        if tool == "marker" and self._marker_name_default:
            self.offer_marker()  # the first marker this photo lacks (entry_keys.py), else a new name

    def escape(self, keep_tool: bool = False) -> None:
        """Cancel what is under way (a drag, a stroke, a placement); if nothing, the Select tool."""
        busy = self.session.dragging or self._press is not None or self._placing is not None \
            or self.pending_length is not None or self.open_polyline is not None or bool(self.relate_picks)
        busy = self.build_reset() or busy
        if self.session.dragging:
            self.session.cancel_drag()
            self.say("drag cancelled")
        self._press = None
        self._pending_drag = None
        self.drag_problem = None
        self._placing = None
        self.relate_cancel()
        if self.open_polyline is not None:
            self.open_polyline = None
            self.say("polyline cancelled")
        if self.pending_length is not None and not keep_tool:
            self.pending_length = None
            self.say("known length cancelled")
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
        if imgui.get_io().want_text_input:  # a click on the photo ends the typing in a field (the next frame)
            self.__dict__["_end_typing"] = True
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
        if self.tool == "select" and s.proposals.get(photo):
            k = s.proposal_at(photo, uv, r)
            if k is not None:
                s.accept_proposal(photo, k)
                return
        if self.tool in ("x", "y", "z") and self.ctrl_held():
            index = s.nearest_segment(photo, self.tool, uv, MIDDLE_PICK_PX / self.zoom)
            if index is None:
                raise VebuildError(f"Ctrl+click on an {self.tool} segment adds a middle point where the edge runs: "
                                   f"no {self.tool} segment passes within {MIDDLE_PICK_PX:g} px of the click")
            self._press = {**base, "kind": "insert-point", "axis": self.tool, "index": index}
            return
        if self.tool in BUILD_TOOLS:
            self.build_click(x, y)
            return
        if self.tool in ("x", "y", "z", "edge", "marker", "delete", "length", "relate", *MEASURE_TOOLS):
            self._press = {**base, "kind": self.tool}
            return
        hit = s.handle_at(photo, uv, r, prefer=self.selected)
        if hit is not None:
            self.select(hit[0])
            self._press = {**base, "kind": "handle", "node": hit[0], "handle": hit[1]}
            return
        point = s.segment_point_at(photo, uv, r)
        if point is not None:
            self._press = {**base, "kind": "segment-point", "axis": point[0], "index": point[1], "point": point[2]}
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
        if p is None:
            return
        s, photo = self.session, self.photo
        uv = self.window_to_image(x, y)
        kind = p["kind"]
        try:
            if kind == "handle":
                if s.dragging:
                    self._pending_drag = self.snap_release(uv)
                    self._apply_pending_drag()
                    s.end_drag()
                    self.drag_problem = None
            elif kind in ("x", "y", "z"):
                self._segment_released(kind, p, uv)
            elif kind == "insert-point":
                at = s.insert_segment_point(photo, p["axis"], p["index"], uv)
                self.say(f"middle point {at} of {p['axis']} segment {p['index']} in {photo}: how the edge bends "
                         "there measures the lens distortion (calibrate to estimate it)")
            elif kind == "segment-point" and p.get("moved"):
                s.move_segment_point(photo, p["axis"], p["index"], p["point"], uv)
            elif kind == "length":
                ends = check_length_ends([p["uv"], uv])
                self.pending_length = {"photo": photo, "ends": [list(ends[0]), list(ends[1])]}
                self.say(f"known length drawn in {photo} from ({ends[0][0]:.1f}, {ends[0][1]:.1f}) to "
                         f"({ends[1][0]:.1f}, {ends[1][1]:.1f}): type its length in metres (σ optional) in the "
                         "Scale tab and press Add length")
            elif kind == "edge":
                self._add_edge(p["uv"], uv)
            elif kind == "marker":
                name = self.marker_name.strip()
                uv, snapped = s.snap(photo, uv, exact=self.alt_held())
                s.place_marker(photo, name, uv)
                # The field offers the next marker after it that this photo lacks, else a new name.
                self.offer_marker(after=name)
                self.say(f"marker {name} at ({uv[0]:.2f}, {uv[1]:.2f}) in {photo}" + snap_note(snapped)
                         + f"; next: {self.marker_name}")
            elif kind == "delete":
                self.delete_at(x, y)
            elif kind == "relate":
                self.relate_click(x, y)
            elif kind in MEASURE_TOOLS:
                self.measure_release(x, y)
            elif kind == "segment-end" and p.get("moved"):
                seg = list(p["segment"])
                uv, snapped = s.snap(photo, uv, exact=self.alt_held())
                if snapped is not None:
                    self.say("segment end" + snap_note(snapped))
                seg[2 * p["end"]:2 * p["end"] + 2] = uv
                s.move_segment(photo, p["axis"], p["index"], seg)
            elif kind == "marker-move" and p.get("moved"):
                uv, snapped = s.snap(photo, uv, exact=self.alt_held())
                s.place_marker(photo, p["name"], uv)
                if snapped is not None:
                    self.say(f"marker {p['name']}" + snap_note(snapped))
        except VebuildError as e:
            self.say(str(e))

    def shift_held(self) -> bool:
        """Whether Shift is down (the keys held, or the button event's modifiers)."""
        return bool({glfw.KEY_LEFT_SHIFT, glfw.KEY_RIGHT_SHIFT} & self._held) or bool(self._mods & glfw.MOD_SHIFT)

    def _segment_released(self, axis: str, press: dict[str, Any], uv: tuple[float, float]) -> None:
        """A Segment tool's stroke ended: a segment from press to release; released with Shift, the
        release point is a middle point of a polyline that goes on (each Shift+click adds one, a click
        without Shift ends it there)."""
        s, photo = self.session, self.photo
        poly = self.open_polyline
        if poly is not None and (poly["axis"], poly["photo"]) != (axis, photo):
            poly = self.open_polyline = None
        if poly is not None:
            points = [*poly["points"], uv]
        elif press.get("moved") or not self.shift_held():
            points = [press["uv"], uv]  # a stroke (or a plain click: too short, which add_segment says)
        else:
            points = [press["uv"]]  # Shift+click: the polyline's first point
        if self.shift_held():
            self.open_polyline = {"axis": axis, "photo": photo, "points": points}
            self.say(f"{axis} polyline: {len(points)} point{'s' if len(points) != 1 else ''}; Shift+click adds the "
                     "next point along the edge (its bend measures the lens distortion), a click without Shift ends "
                     "it there, Esc cancels")
            return
        self.open_polyline = None
        if len(points) == 2:
            a, b, fit = s.snap_segment(photo, points[0], points[1], exact=self.alt_held())
            index = s.add_segment(photo, axis, a, b, sigma_px=fit.sigma_px if fit is not None else None)
            if fit is not None:
                self.say(f"{axis} segment {index} in {photo} snapped to the image line: ends moved up to "
                         f"{fit.moved_px:.2f} px, σ {fit.sigma_px:.2f} px from {fit.points} edge points "
                         "(hold Alt to place it exactly as drawn)")
        else:
            index = s.add_polyline(photo, axis, points)
            self.say(f"{axis} segment {index} in {photo}: a polyline of {len(points)} points "
                     f"({len(points) - 2} middle)")

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
        k = s.proposal_at(photo, uv, r) if s.proposals.get(photo) else None
        if k is not None:
            s.reject_proposal(photo, k)
            return
        point = s.segment_point_at(photo, uv, r)
        if point is not None:
            s.delete_segment_point(photo, *point)
            self.say(f"deleted middle point {point[2]} of {point[0]} segment {point[1]} in {photo}")
            return
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
        length = s.known_length_at(photo, uv, r)
        if length is not None:
            s.remove_known_length(length)
            self.say(f"removed known length L{length}")
            return
        edge = self._nearest_line(("user-edge",), x, y)
        if edge is not None:
            s.remove_edge_observation(edge.key)
            self.say("removed the drawn edge")
            return
        self.say("nothing to delete there (a segment, a middle point, a marker, a known length or a drawn edge)")

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
            last = self.selected_nodes[-1] if self.selected_nodes else None
            self.selected = node if node in self.selected_nodes else last
        else:
            self.selected, self.selected_nodes = node, [node]
        self.panels.forget_edits()
        self._scroll_to_selected = True

    def alt_held(self) -> bool:
        """Whether Alt is down: a mark is placed exactly where the cursor is, not snapped."""
        return bool({glfw.KEY_LEFT_ALT, glfw.KEY_RIGHT_ALT} & self._held) or bool(self._mods & glfw.MOD_ALT)

    # -- proposals (D, N, P, Enter, C) ------------------------------------------------------------

    def detect_here(self) -> None:
        """D: detect the shown photo's vanishing segments and show them as proposals."""
        if self.photo is not None:
            self._long("detecting lines", lambda progress: self.session.detect_lines(self.photo))

    def suggest_markers_here(self, features: bool = False) -> None:
        """N: the markers placed in the other calibrated photos, suggested in the shown photo;
        Shift+N: new markers at feature points matched with them."""
        if self.photo is not None:
            self._long("suggesting markers", lambda progress: self.session.suggest_markers(self.photo, features))

    def suggest_pins_here(self) -> None:
        """P: pins proposed at the image corners near the model's vertices in the shown photo."""
        if self.photo is not None:
            self.session.suggest_pins(self.photo)

    def accept_all_here(self) -> None:
        """Enter: accept every proposal shown on the photo (one undoable edit); with the Room tool,
        close the floor's outline."""
        if self.tool in BUILD_TOOLS:
            self.build_enter()
        elif self.photo is not None:
            self.session.accept_all(self.photo)

    def clear_proposals_here(self) -> None:
        """C: drop the photo's proposals."""
        if self.photo is not None and self.session.proposals.get(self.photo):
            self.session.clear_proposals(self.photo)
            self.say(f"proposals in {self.photo} dropped")

    def ctrl_held(self) -> bool:
        """Whether Ctrl is down (the keys held, as glfw reported them: X11 gives a modifier key's own
        press without its modifier, which ImGui's key_ctrl then misses)."""
        return bool({glfw.KEY_LEFT_CONTROL, glfw.KEY_RIGHT_CONTROL} & self._held) or bool(self._mods & glfw.MOD_CONTROL)

    def _over_preview(self, x: float, y: float) -> bool:
        r = self.widget_rects.get("preview")
        return r is not None and inside(r, x, y)


def snap_note(snapped: Any) -> str:
    """The status line's note of a snap (nothing where the mark was placed as clicked)."""
    if snapped is None:
        return ""
    return (f", snapped {snapped.moved_px:.2f} px to the image {snapped.kind} (σ {snapped.sigma_px:.2f} px; "
            "hold Alt to place exactly)")
