"""The modelling screen's panels (vebuild edit): calibration (vanishing points, markers, the
origin, reference distances, Calibrate) and the model (adding primitives, the scene graph, a
node's properties and joint, Solve, Re-calibrate, Register, Extract textures, the residuals). The
node's properties are drawn by :mod:`.node_panel`, relations and rooms by :mod:`.model_panels`.

A component of :class:`vebuild.edit.screen.Editor` (``editor.panels``): it keeps what is typed into
its fields, draws with Dear ImGui through the editor's widgets and calls the editor's session.
A Keys tab lists the screen's keys from :data:`vebuild.edit.keys.EDITOR_KEYS`.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from imgui_bundle import imgui

from vebuild.console.tables import camera_group_lines
from vebuild.model.primitives import primitive_kinds
from vebuild.project import decode

from .keys import EDITOR_KEYS, tool_key
from .left_out import WHAT_TO_DO, legend_line
from .marks import AXES, CAMERA_HEIGHT_SIGMA_M, KNOWN_LENGTH_SIGMA_M
from .model_panels import relations_section
from .node_panel import properties_section
from .overlay import AXIS_COLOURS, GREY
from .panel_fields import PanelFields
from .session import exif_text, photo_cameras, placement_text

#: The primitives the panel offers, from the registry (each type, then its named variants).
KINDS = list(primitive_kinds())

#: The most markers the Calibration tab's list shows without scrolling.
MARKER_ROWS = 11


class Panels(PanelFields):
    """The right-hand panels of an :class:`~vebuild.edit.screen.Editor` (``editor.panels``): they
    hold what is being typed into them and draw with the editor's widgets, calling its session."""

    def prepare_add(self, kind: str, name: str, parent: str | None) -> None:
        """Set the Model tab's kind, name and parent fields (what its Add then adds)."""
        self.new_kind = KINDS.index(kind)
        self.new_name = name
        choices = self._attach_choices()
        self.new_parent = choices.index(parent) if parent in choices else 0

    def draw(self) -> None:
        self.ed.fixed_window("##panels", self.ed.panels_rect(), imgui.WindowFlags_.no_title_bar)
        if imgui.begin_tab_bar("panels"):
            select, self._select_tab = self._select_tab, None
            for name, fn in (("Calibration", self._calibration_tab), ("Scale", self._scale_tab),
                             ("Cameras", self._cameras_tab), ("Model", self._model_tab), ("Keys", self._keys_tab)):
                flags = imgui.TabItemFlags_.set_selected if name == select else 0
                shown, _ = imgui.begin_tab_item(name, None, flags)
                self.ed.rect(f"tab:{name}")
                if shown:
                    fn()
                    imgui.end_tab_item()
            imgui.end_tab_bar()
        imgui.end()

    def _keys_tab(self) -> None:
        """The screen's keys and mouse, from the key table the dispatch uses."""
        for keys, does in EDITOR_KEYS.rows():
            imgui.text_colored(imgui.ImVec4(1.0, 0.8, 0.4, 1.0), keys)
            imgui.push_text_wrap_pos(0.0)
            imgui.text(does)
            imgui.pop_text_wrap_pos()

    def _calibration_tab(self) -> None:
        s = self.ed.session
        if self.ed.button("Calibrate", tip="calibrate every photo from its segments and markers (paper §2)"):
            self.ed.later(self.ed.calibrate)
        if self.ed.calibration_error:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(1.0, 0.4, 0.35, 1.0), self.ed.calibration_error)
            imgui.pop_text_wrap_pos()
        elif self.ed.calibration_result:
            for pid, c in self.ed.calibration_result.get("cameras", {}).items():
                imgui.push_text_wrap_pos(0.0)
                imgui.text(f"{pid}: {c.get('mode', '?')}, f {c['focal_px']['value']:.1f} ± "
                           f"{c['focal_px']['sigma']:.1f} px, rms {c['rms_px']:.2f} px{exif_text(c)}"
                           + placement_text(c))
                imgui.pop_text_wrap_pos()
                self.ed.rect(f"calibrated:{pid}")
            for pid, u in (self.ed.calibration_result.get("left_out") or {}).items():
                imgui.push_text_wrap_pos(0.0)
                imgui.text_colored(imgui.ImVec4(1.0, 0.4, 0.35, 1.0),
                                   f"{pid}: left out of the calibration: {u['reason']}")
                imgui.pop_text_wrap_pos()
                self.ed.rect(f"left-out:{pid}")
        imgui.separator()
        self._distances()
        imgui.separator()
        if self.ed.photo is not None:
            imgui.text(f"vanishing points in {self.ed.photo}")
            for axis in ("x", "y", "z"):
                vs = self.ed.guard(s.vanishing, self.ed.photo, axis)
                if vs is None:
                    continue
                colour = imgui.ImVec4(*AXIS_COLOURS[axis])
                if vs.point is not None:
                    v = vs.point
                    where = _vanishing_point_text(v, *self.ed.photo_size())
                    out = f" ({len(vs.left_out)} left out, grey)" if vs.left_out else ""
                    text = f"{axis}: {len(vs.segments)} segments{out}, VP {where}, rms {vs.rms_px:.2f} px"
                else:
                    text = vs.problem or f"{axis}: {len(vs.segments)} segments"
                imgui.push_text_wrap_pos(0.0)
                imgui.text_colored(colour, text)
                imgui.pop_text_wrap_pos()
            self._left_out_legend(self.ed.photo)
        imgui.separator()
        origin = s.data.get("origin_marker")
        imgui.text(f"markers (origin: {origin or 'none'})")
        observed = (s.photo(self.ed.photo).get("marker_observations") or {}) if self.ed.photo else {}
        rows = min(max(len(decode.markers(s.data, "named")), 5), MARKER_ROWS)  # then it scrolls
        imgui.begin_child("markers", (0, rows * imgui.get_frame_height_with_spacing() + 10), imgui.ChildFlags_.borders)
        floor = decode.floor_markers(s.data)
        # Those not yet placed in this photo first, in the order of first placement (the Marker tool's
        # offer follows it, and the one offered is highlighted): a click on the name places it with the
        # next click.
        offered = self.ed.marker_name if self.ed.tool == "marker" else None
        for name in sorted(decode.markers(s.data, "named"), key=lambda n: n in observed):
            if name == offered:
                imgui.push_style_color(imgui.Col_.button, imgui.ImVec4(0.85, 0.55, 0.1, 1.0))
            picked = self.ed.button(f"{name}##pick", tip=f"the Marker tool, placing {name} with the next click")
            if name == offered:
                imgui.pop_style_color()
            if picked:
                self.ed.pick_marker(name)
            if name in observed:
                imgui.same_line(60)
                imgui.text("in this photo")
            imgui.same_line(140)
            if name == origin:
                imgui.text("on the floor")
            else:
                changed, on = imgui.checkbox(f"on the floor##{name}", name in floor)
                self.ed.rect(f"on floor:{name}")
                imgui.set_item_tooltip("it lies on the floor (z = 0): one photo places it")
                if changed:
                    self.ed.guard(s.set_on_floor, name, bool(on))
            imgui.same_line(270)
            if name == origin:
                imgui.text("origin")
            elif self.ed.button(f"origin##{name}", tip=f"the world's origin at {name}"):
                self.ed.guard(s.set_origin, name)
        imgui.end_child()
        self.ed.draw_rename_field(self)

    def _left_out_legend(self, photo: str) -> None:
        """What the photo's grey crossed segments are, how many of each axis, and what to do with
        them: point at one to read why it was left out; keep them (each calibration leaves them out
        again) or delete them all from this photo in one undoable edit. The lines shown are kept in
        :attr:`left_out_text` (for tests and the Help)."""
        left = self.ed.guard(self.ed.session.left_out_segments, photo) or {}
        self.left_out_text = []
        if not left:
            return
        imgui.push_text_wrap_pos(0.0)
        for axis, found in left.items():
            line = legend_line(axis, len(found))
            imgui.text_colored(imgui.ImVec4(*GREY), line)
            self.ed.rect(f"left out:{axis}")
            self.left_out_text.append(line)
        imgui.text_disabled(WHAT_TO_DO)
        imgui.pop_text_wrap_pos()
        self.left_out_text.append(WHAT_TO_DO)
        n = sum(len(f) for f in left.values())
        label = f"Delete the {n} left out"
        if self.ed.button(label, tip=f"delete the {n} grey crossed segments of {photo} (Ctrl+Z brings them back); "
                          "calibrate again afterwards"):
            self.ed.guard(self.ed.session.delete_left_out, photo)
        self.ed.rect("delete left out")
        self.left_out_text.append(label)

    def _cameras_tab(self) -> None:
        """Each photo's camera (FORMAT.md "Camera groups"): tick photos and say they share one camera,
        or release the photo shown from its group; both undoable, both take effect at Calibrate.
        After a calibration, each group's shared values."""
        s = self.ed.session
        imgui.text("photos of one camera share f, principal point and lens")
        for pid, text in photo_cameras(s.data).items():
            changed, ticked = imgui.checkbox(f"{pid}: {text}##camera", pid in self.camera_ticks)
            self.ed.rect(f"camera:{pid}")
            if changed:
                self.camera_ticks = self.camera_ticks | {pid} if ticked else self.camera_ticks - {pid}
        if self.ed.button("These photos share one camera", tip="the ticked photos were taken with one camera (one "
                          "body, lens and zoom): calibrated with one focal length, principal point and lens"):
            chosen = [p for p in s.photo_ids if p in self.camera_ticks]
            if len(chosen) < 2:
                self.ed.say("tick two photos or more (in the list above) to say they share one camera")
            else:
                taken = {g["id"] for g in s.data.get("camera_groups") or []}
                name = next(f"camera {i}" for i in range(1, len(taken) + 2) if f"camera {i}" not in taken)
                self.ed.guard(s.group_cameras, name, chosen)
                self.camera_ticks = set()
        if self.ed.photo is not None and self.ed.button(
                "Release this photo from its camera", tip=f"{self.ed.photo} gets a focal length, principal point "
                "and lens of its own (a zoom moved, a crop, another body)"):
            self.ed.guard(s.release_camera, self.ed.photo)
        groups = (self.ed.calibration_result or {}).get("camera_groups") or []
        if groups:
            imgui.separator()
            imgui.push_text_wrap_pos(0.0)
            for line in camera_group_lines(groups):
                if line.strip():
                    imgui.text(line.strip())
            imgui.pop_text_wrap_pos()

    def _distances(self) -> None:
        """The reference distances and the row that adds one (under Calibrate, in view with it).
        From the keyboard (entry_keys.py): Ctrl+D puts the cursor in its first field, Tab goes on,
        Ctrl+Enter adds the distance and empties the row for the next."""
        s = self.ed.session
        imgui.text("reference distances")
        for i, d in enumerate(s.data.get("reference_distances", [])):
            imgui.text(f"{d['a']}–{d['b']} {d['distance']:.4f} m ({d.get('role', 'scale')})")
            imgui.same_line()
            if self.ed.button(f"remove##distance{i}", tip=f"remove the distance {d['a']}–{d['b']}"):
                self.ed.guard(s.remove_distance, i)
        select_all = imgui.InputTextFlags_.auto_select_all
        active = False
        imgui.set_next_item_width(70)
        if self.focus_distance:
            imgui.set_keyboard_focus_here()
            self.focus_distance = False
        _, self.dist_a = imgui.input_text("marker a##distance a", self.dist_a, select_all)
        active |= imgui.is_item_active()
        self.ed.rect("distance a")
        imgui.set_item_tooltip("the first marker's name (or node:vertex, e.g. floor:v1); "
                               f"{EDITOR_KEYS.key_for('type_distance')} puts the cursor here, Tab goes on, Ctrl+Enter "
                               "adds the distance")
        imgui.same_line()
        imgui.set_next_item_width(70)
        _, self.dist_b = imgui.input_text("marker b##distance b", self.dist_b, select_all)
        active |= imgui.is_item_active()
        self.ed.rect("distance b")
        imgui.set_item_tooltip("the second marker's name (or node:vertex)")
        imgui.set_next_item_width(80)
        _, self.dist_m = imgui.input_float("m##distance", self.dist_m, 0.0, 0.0, "%.4f", select_all)
        active |= imgui.is_item_active()
        self.ed.rect("distance m")
        imgui.set_item_tooltip("the distance measured at the scene between the two, in metres")
        imgui.same_line()
        imgui.set_next_item_width(90)
        _, self.dist_role = imgui.combo("role##distance", self.dist_role, ["scale", "check"])
        self.ed.rect("distance role")
        imgui.set_item_tooltip("scale: it sets the model's size; check: kept aside, its residual reported")
        imgui.same_line()
        if self.ed.button("add##distance", tip="a measured distance between two markers (or node:vertex)"):
            self._add_distance()
        # Ctrl+Enter in the row: added once its field has taken the Enter (the value typed is in).
        if self.add_distance_pending and not active:
            self.add_distance_pending = False
            if self._add_distance():
                self.dist_a, self.dist_b = "", ""
            self.focus_distance = True
        self.distance_row_active = active

    def _add_distance(self) -> bool:
        """The row's distance added; whether it was (a mistake is said in the status line)."""
        s = self.ed.session
        n = len(s.data.get("reference_distances", []))
        self.ed.guard(s.add_distance, self.dist_a, self.dist_b, float(self.dist_m),
                      role=["scale", "check"][self.dist_role])
        return len(s.data.get("reference_distances", [])) > n

    def _scale_tab(self) -> None:
        """A photo's own scale, for a photo placed alone: its known lengths (drawn with the Known
        length tool, then their metres typed here), its camera's height; the markers on the floor are
        ticked in the Calibration tab."""
        s, photo = self.ed.session, self.ed.photo
        if photo is None:
            imgui.text_disabled("no photo")
            return
        imgui.push_text_wrap_pos(0.0)
        imgui.text_disabled("the scale of a photo placed alone (one photo, or none of its markers in other "
                            "photos): any of these, combined by their σ")
        imgui.pop_text_wrap_pos()
        imgui.separator()
        imgui.text(f"known lengths in {photo}")
        for i, k in enumerate(s.data.get("known_lengths", [])):
            if k["photo"] != photo:
                continue
            imgui.text(f"L{i}: {k['length']:g} m ± {1e3 * k.get('sigma', KNOWN_LENGTH_SIGMA_M):g} mm along {k['axis']}")
            imgui.same_line()
            if self.ed.button(f"remove##length{i}", tip=f"remove the known length L{i}"):
                self.ed.guard(s.remove_known_length, i)
        pending = self.ed.pending_length
        if pending is None or pending["photo"] != photo:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_disabled(f"draw one with the Known length tool ({tool_key('length')}): press on one end "
                                "(a vertical's foot on the floor first), drag to the other, release")
            imgui.pop_text_wrap_pos()
        else:
            imgui.text_colored(imgui.ImVec4(1.0, 0.8, 0.2, 1.0), "drawn: now its axis, metres and σ, then Add length")
        imgui.set_next_item_width(60)
        self.length_axis = self.ed.combo("length axis", self.length_axis, list(AXES))
        imgui.set_item_tooltip("the world axis the length runs along (z: a vertical standing on the floor)")
        imgui.same_line()
        imgui.text("axis")
        imgui.same_line()
        self.length_m, self.length_sigma = self._metres_and_sigma("length", self.length_m, self.length_sigma,
                                                                  KNOWN_LENGTH_SIGMA_M)
        if self.ed.button("Add length", tip="the length drawn with the Known length tool, with these metres"):
            self.add_length()
        imgui.separator()
        h = s.photo(photo).get("camera_height")
        imgui.text(f"camera height in {photo}: " + (f"{h['value']:g} ± {h['sigma']:g} m" if h else "not given"))
        self.height_m, self.height_sigma = self._metres_and_sigma("height", self.height_m, self.height_sigma,
                                                                  CAMERA_HEIGHT_SIGMA_M)
        imgui.same_line()
        if self.ed.button("Set height", tip="the camera's height above the floor when the photo was taken"):
            self.set_height()
        if h:
            imgui.same_line()
            if self.ed.button("Remove height", tip=f"forget the camera height of {photo}"):
                self.ed.guard(s.set_camera_height, photo, None)

    def _metres_and_sigma(self, what: str, metres: str, sigma: str, default_sigma: float) -> tuple[str, str]:
        """A length's two fields, metres and its 1σ (blank: ``default_sigma``), as typed; each
        registered under "WHAT m" and "WHAT sigma" for the window tests."""
        imgui.set_next_item_width(80)
        _, metres = imgui.input_text(f"m##{what}", metres)
        self.ed.rect(f"{what} m")
        imgui.set_item_tooltip(f"the {what} in metres")
        imgui.same_line()
        imgui.set_next_item_width(70)
        _, sigma = imgui.input_text(f"σ m##{what}", sigma)
        self.ed.rect(f"{what} sigma")
        imgui.set_item_tooltip(f"its 1σ in metres; blank: {default_sigma:g} m")
        return metres, sigma

    def set_height(self) -> None:
        """Set height: the typed camera height and σ for the photo shown."""
        photo = self.ed.photo
        if self.height_m.strip() == "":
            self.ed.say("type the camera's height above the floor in metres first (e.g. 1.62), then Set height")
            return
        s = self.ed.session
        rev = s.revision
        self.ed.guard(s.set_camera_height, photo, self.height_m, self.height_sigma)
        if s.revision != rev:
            h = s.photo(photo)["camera_height"]
            self.ed.say(f"camera height in {photo}: {h['value']:g} ± {h['sigma']:g} m above the floor")

    def add_length(self) -> None:
        """Add length: the drawn known length with the typed axis, metres and σ."""
        pending, photo = self.ed.pending_length, self.ed.photo
        if pending is None or pending["photo"] != photo:
            self.ed.say(f"draw the known length first: the Known length tool ({tool_key('length')}), press on one end "
                        "(a vertical's foot on the floor first), drag to the other, release")
            return
        axis = AXES[self.length_axis]
        index = self.ed.guard(self.ed.session.add_known_length, photo, axis, pending["ends"], self.length_m,
                              self.length_sigma)
        if index is not None:
            self.ed.pending_length = None
            self.ed.say(f"known length L{index}: {self.ed.session.data['known_lengths'][index]['length']:g} m along "
                        f"{axis} in {photo}")

    def _model_tab(self) -> None:
        s = self.ed.session
        model = s.model
        imgui.set_next_item_width(100)
        self.new_kind = self.ed.combo("kind", self.new_kind, KINDS)
        imgui.set_item_tooltip("the kind of primitive Add makes")
        imgui.same_line()
        imgui.text("kind")
        imgui.same_line()
        parents = self._attach_choices()
        self.new_parent = min(self.new_parent, len(parents) - 1)
        imgui.set_next_item_width(110)
        self.new_parent = self.ed.combo("parent", self.new_parent, parents)
        imgui.set_item_tooltip("what it rests on: nothing (the first goes on the origin marker), a node's top, or a "
                               "calibrated marker")
        imgui.same_line()
        imgui.text("on")
        imgui.set_next_item_width(150)
        _, self.new_name = imgui.input_text("name##new name", self.new_name)
        self.ed.rect("new name")
        imgui.set_item_tooltip("the new node's name (blank: made from its kind)")
        imgui.same_line()
        if self.ed.button("Add", tip="then click in the photo where it stands"):
            self.arm_placement()
        imgui.same_line()
        if self.ed.button("Add at centre", tip="where the photo's centre looks at its support"):
            self.add_at_centre()
        imgui.separator()
        if self.ed.button("Solve", tip="fit the model's sizes and poses to the pins and edges in every photo"):
            self.ed.later(lambda: self.ed.solve(False))
        imgui.same_line()
        if self.ed.button("Re-calibrate", tip="solve the cameras and markers with the model (paper §3.2)"):
            self.ed.later(lambda: self.ed.solve(True))
        imgui.same_line()
        if self.ed.button("Register this photo", tip="place this photo's camera from known points (paper §3.2)"):
            if self.ed.photo is not None:
                self.ed.later(lambda: self.ed.guard(s.register, self.ed.photo))
        if self.ed.button("Extract textures", tip="each face's texture from the photos that see it best (paper §4)"):
            self.ed.later(self.ed.extract_textures)
        imgui.same_line()
        imgui.set_next_item_width(90)
        _, self.group_name = imgui.input_text("group##group name", self.group_name)
        self.ed.rect("group name")
        imgui.set_item_tooltip("the name of the group that Group makes")
        imgui.same_line()
        if self.ed.button("Group", tip="the selected nodes (Ctrl+click in the tree) become one object"):
            if self.ed.guard(s.group, list(self.ed.selected_nodes), self.group_name) is not None:
                self.ed.select(self.group_name.strip())
        imgui.separator()
        imgui.begin_child("tree", (0, 150), imgui.ChildFlags_.borders)
        if model is None:
            imgui.text_disabled("no model yet: calibrate, then Add a primitive")
        else:
            for n in model.nodes:
                if n.parent is None:
                    self._tree_node(model, n.name)
        imgui.end_child()
        relations_section(self)
        if self.ed.selected is not None and model is not None and self.ed.selected in model.index:
            properties_section(self, model, self.ed.selected)
        self._residuals()

    def _attach_choices(self) -> list[str]:
        """What a new primitive can hang on: nothing (the first goes on the origin marker, later
        ones rest on the floor), a node (resting on its top), or a calibrated marker."""
        model = self.ed.session.model
        names = [n.name for n in model.nodes] if model is not None else []
        markers = sorted(decode.markers(self.ed.session.data, "calibration"))
        return ["(none)"] + names + [f"marker {m}" for m in markers]

    def _attachment(self) -> dict[str, str | None]:
        choice = self._attach_choices()[self.new_parent] if self.new_parent < len(self._attach_choices()) else ""
        if choice.startswith("marker "):
            return {"parent": None, "marker": choice[len("marker "):]}
        return {"parent": None if choice in ("", "(none)") else choice, "marker": None}

    def arm_placement(self) -> None:
        """Add: the next click in the photo places the new primitive there."""
        model = self.ed.session.model
        kind = KINDS[self.new_kind]
        where = self._attachment()
        if self.ed.photo is None or (model is None and not self.ed.session.cameras) or where["marker"] is not None:
            made = self.ed.guard(self.ed.session.add_primitive, kind, name=self.new_name.strip() or None, **where)
            if made is not None:
                self.ed.select(made)
            return
        self.ed._placing = {"kind": kind, "name": self.new_name.strip(), **where}
        self.ed.say(f"click in the photo where the new {kind} stands")

    def add_at_centre(self) -> None:
        model = self.ed.session.model
        at = None
        if self.ed.photo is not None and self.ed.photo in self.ed.session.cameras and model is not None:
            w, h = self.ed.photo_size()
            at = (self.ed.photo, (w / 2, h / 2))
        made = self.ed.guard(self.ed.session.add_primitive, KINDS[self.new_kind], name=self.new_name.strip() or None,
                           at=at, **self._attachment())
        if made is not None:
            self.ed.select(made)

    def _tree_node(self, model: Any, name: str) -> None:
        kids = model.children.get(name, [])
        flags = imgui.TreeNodeFlags_.open_on_arrow | imgui.TreeNodeFlags_.default_open \
            | imgui.TreeNodeFlags_.span_avail_width
        if not kids:
            flags |= imgui.TreeNodeFlags_.leaf
        if name in self.ed.selected_nodes:
            flags |= imgui.TreeNodeFlags_.selected
        node = model.node(name)
        what = node.primitive.TYPE if node.primitive is not None else "group"
        opened = imgui.tree_node_ex(f"{name}  ({what}, {node.joint.type})##node:{name}", flags)
        if not self.ed.rect(f"node:{name}") and name == self.ed.selected and self.ed._scroll_to_selected:
            imgui.set_scroll_here_y(0.5)  # a node selected in the photo is shown in the tree
        if name == self.ed.selected:
            self.ed._scroll_to_selected = False
        if imgui.is_item_clicked() and not imgui.is_item_toggled_open():
            self.ed.select(name, add=self.ed.ctrl_held())
        if opened:
            for k in kids:
                self._tree_node(model, k)
            imgui.tree_pop()

    def _residuals(self) -> None:
        if self.ed.solve_error:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(1.0, 0.4, 0.35, 1.0), self.ed.solve_error)
            imgui.pop_text_wrap_pos()
        r = self.ed.solve_result
        if not r:
            return
        imgui.separator()
        imgui.text(f"rms {r.get('rms_px', float('nan')):.2f} px; {len(r.get('outliers', []))} outlier(s)")
        outliers = " | ".join(r.get("outliers", []))
        imgui.begin_child("residuals", (0, 0), imgui.ChildFlags_.borders)
        for kind, items in (("pin", r.get("pins", [])), ("edge", r.get("edge_observations", []))):
            for o in items:
                what = o.get("handle") or o.get("edge")
                res = float(np.hypot(*o["residual_px"][:2])) if len(o["residual_px"]) >= 2 else float("nan")
                bad = f"{o['node']}:{what}" in outliers and f"'{o['photo']}'" in outliers
                text = f"{kind} {o['node']}:{what} in {o['photo']}: {res:.2f} px" + ("  OUTLIER" if bad else "")
                if bad:
                    imgui.text_colored(imgui.ImVec4(1.0, 0.35, 0.3, 1.0), text)
                else:
                    imgui.text(text)
        imgui.end_child()


def _vanishing_point_text(v: Any, width: float, height: float) -> str:
    """A vanishing point as pixels, or, far outside the image (beyond ten times its size), as the
    direction it lies in from the image's centre: a pixel position there says little."""
    centre = np.array([width / 2, height / 2])
    if abs(v[2]) > 1e-12:
        p = np.asarray(v[:2], float) / v[2]
        if np.all(np.abs(p - centre) < 10 * max(width, height)):
            return f"({p[0]:.0f}, {p[1]:.0f})"
        d = p - centre
        d = d / np.linalg.norm(d)
        return f"far, toward ({d[0]:+.3f}, {d[1]:+.3f})"
    d = np.asarray(v[:2], float) / np.linalg.norm(v[:2])
    return f"at infinity, along ({d[0]:+.3f}, {d[1]:+.3f})"

