"""The modelling screen's bars: the toolbar (tools, marker name, undo, redo, save, fit, labels,
status), the strip of photos, the messages, the recovery question and the progress of a long task."""

from __future__ import annotations

from imgui_bundle import imgui

from vebuild.project.provenance import stale_line

from .keys import EDITOR_KEYS, tool_key
from .layout import MIDDLE_POINT_HINT, STRIP_H, THUMB_H, TOOL_HINTS, TOOLBAR_H, TOOLS, EditorPart

#: The toolbar's marker name field's width, window pixels.
MARKER_FIELD_W = 90.0


class Bars(EditorPart):
    """Toolbar, strip, messages and the busy bar (a part of the Editor)."""

    def _flow(self, width: float, first: bool = False) -> None:
        """The next toolbar item beside the last, or on the next row where it would not fit."""
        if first:
            return
        imgui.same_line()
        if imgui.get_content_region_avail().x < width:
            imgui.new_line()

    @staticmethod
    def _button_w(label: str) -> float:
        return float(imgui.calc_text_size(label.split("##")[0]).x + 2 * imgui.get_style().frame_padding.x)

    def _draw_toolbar(self) -> None:
        # The photo was clicked while a field had the keyboard: the field lets it go before it is drawn.
        # What was typed is in already (each character is taken as typed), and the marker name field's
        # text is not put back over the offer its click moved on to.
        ending = bool(self.__dict__.pop("_end_typing", False))
        if ending:
            imgui.set_window_focus(None)
        x0, _, x1, _ = self.view_rect()
        self.fixed_window("##toolbar", (x0, 0, x1, TOOLBAR_H), imgui.WindowFlags_.no_decoration)
        for i, (tool, label) in enumerate(TOOLS.items()):  # in rows as the view's width allows
            self._flow(self._button_w(label), first=i == 0)
            active = self.tool == tool
            if active:
                imgui.push_style_color(imgui.Col_.button, imgui.ImVec4(0.85, 0.55, 0.1, 1.0))
            middle = MIDDLE_POINT_HINT if tool in ("x", "y", "z") else ""
            if self.button(label, tip=f"{TOOL_HINTS[tool]}{middle} (key {tool_key(tool)})"):
                self.set_tool(tool)
            if active:
                imgui.pop_style_color()
        style = imgui.get_style()
        self._flow(MARKER_FIELD_W + style.item_inner_spacing.x + imgui.calc_text_size("marker name").x)
        imgui.set_next_item_width(MARKER_FIELD_W)
        self.refresh_marker_offer()
        if self.take_marker_field_focus():
            imgui.set_keyboard_focus_here()
        changed, name = imgui.input_text("marker name", self.marker_name, imgui.InputTextFlags_.auto_select_all)
        self.rect("marker name")
        imgui.set_item_tooltip(f"the name the Marker tool's next click places (a new name makes a new marker); "
                               f"{EDITOR_KEYS.key_for('type_marker_name')}: type one; offered: the next marker this "
                               f"photo lacks ({EDITOR_KEYS.key_for('step_marker_offer', 1)} / "
                               f"{EDITOR_KEYS.key_for('step_marker_offer', -1)}: the next / previous), "
                               f"{EDITOR_KEYS.key_for('offer_new_marker')}: a new name")
        if changed and not ending:
            self.marker_name, self._marker_name_default = name, False
        s = self.session
        self._flow(self._button_w("Undo"))
        imgui.begin_disabled(s.undo_label is None)
        if self.button("Undo", tip=f"{EDITOR_KEYS.key_for('undo')}: undo {s.undo_label or ''}"):
            self.undo()
        imgui.end_disabled()
        self._flow(self._button_w("Redo"))
        imgui.begin_disabled(s.redo_label is None)
        if self.button("Redo", tip=f"{EDITOR_KEYS.key_for('redo')}: redo {s.redo_label or ''}"):
            self.redo()
        imgui.end_disabled()
        self._flow(self._button_w("Save"))
        if self.button("Save", tip=f"{EDITOR_KEYS.key_for('save')}: write the project file (the autosave is removed)"):
            self.guard(s.save)
        self._flow(self._button_w("Fit"))
        if self.button("Fit", tip=f"{EDITOR_KEYS.key_for('fit')}: the whole photo"):
            self.fit()
        self._flow(self._button_w("Photos…"))
        if self.button("Photos…", tip=f"{EDITOR_KEYS.key_for('open_browser')}: add photos from a file browser (or "
                       "drop image files onto the window)"):
            self.open_browser()
        self._flow(self._button_w("Help"))
        if self.button("Help", tip=f"{EDITOR_KEYS.key_for('toggle_help')} or ?: every key and mouse input; "
                       f"{EDITOR_KEYS.key_for('toggle_guide')}: the first steps"):
            self.toggle_help()
        self._flow(imgui.get_frame_height() + style.item_inner_spacing.x + imgui.calc_text_size("labels").x)
        _, self.show_labels = imgui.checkbox("labels", self.show_labels)
        self.rect("labels")
        imgui.set_item_tooltip(f"{EDITOR_KEYS.key_for('toggle_labels')}: residuals and names over the photo "
                               "(markers' names stay)")
        imgui.same_line()
        status = f"{self.photo or '-'}  ×{self.zoom:.2f}"
        if self._photo_takes(*self._cursor):
            u, v = self.window_to_image(*self._cursor)
            status += f"  ({u:.1f}, {v:.1f}) px"
        if s.dirty:
            status += "   unsaved (autosaved)"
        imgui.text(status)
        self._draw_stale()
        imgui.end()

    def _draw_stale(self) -> None:
        """The stale line: which results no longer fit the project, each message in its tooltip."""
        line = stale_line(self.session.stale)
        if line:
            imgui.same_line()
            imgui.text_colored(imgui.ImVec4(1.0, 0.45, 0.1, 1.0), line)
            imgui.set_item_tooltip("\n".join(s.message for s in self.session.stale))

    def _draw_strip(self) -> None:
        W, H = self.size()
        x0, _, x1, _ = self.view_rect()
        self.fixed_window("##strip", (x0, H - STRIP_H, x1, H), imgui.WindowFlags_.no_title_bar
                           | imgui.WindowFlags_.horizontal_scrollbar)
        for pid in self.session.photo_ids:
            thumb = self._thumbs.get(pid)
            current = pid == self.photo
            if current:
                imgui.push_style_color(imgui.Col_.button, imgui.ImVec4(0.85, 0.55, 0.1, 1.0))
            label = f"photo:{pid}"
            if thumb is not None:
                clicked = imgui.image_button(label, self.gui.texture_ref(thumb), thumb.size)
                self.rect(label)
            else:
                note = "cannot load" if pid in self._photo_errors else "loading"
                clicked = imgui.button(f"{pid}\n({note})##{label}", (THUMB_H * 4 / 3, THUMB_H + 6))
                self.rect(label)
            if current:
                imgui.pop_style_color()
            imgui.set_item_tooltip(pid + (f": {self._photo_errors[pid]}" if pid in self._photo_errors else ""))
            if clicked:
                self.guard(self.set_photo, pid)
            imgui.same_line()
        imgui.new_line()
        if self.button("Browse…##strip", tip=f"{EDITOR_KEYS.key_for('open_browser')}: pick photos in a file browser "
                       "(or drop image files onto the window)"):
            self.open_browser()
        imgui.same_line()
        imgui.set_next_item_width(220)
        _, self.add_photo_path = imgui.input_text("file##add photo file", self.add_photo_path)
        self.rect("add photo file")
        imgui.set_item_tooltip("an image file's path in the project's folder, for Add photo")
        imgui.same_line()
        if self.button("Add photo", tip="an image file in the project's folder (its SHA-256 is recorded)"):
            pid = self.guard(self.session.add_photo, self.add_photo_path.strip())
            if pid is not None:
                self.add_photo_path = ""
                self.guard(self.set_photo, pid)
        imgui.same_line()
        if self.button("Add all photos", tip="every image file in the project's folder (and the folders inside it) "
                       "that the project lacks, one undoable edit"):
            ids = self.guard(self.session.add_folder_photos)
            if ids:
                self.guard(self.set_photo, ids[0])
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
            if self.button("Recover the autosaved edits", tip="take the edits kept in the autosave side file"):
                self.guard(s.recover)
                imgui.close_current_popup()
            imgui.same_line()
            if self.button("Discard", tip="open the project as it was last saved (the side file is removed)"):
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
        self.rect("progress")
        imgui.end()
