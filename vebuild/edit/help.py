"""The modelling screen's help overlay (F1 or ?): every line of its key table
(:data:`vebuild.edit.keys.EDITOR_KEYS`, the table the dispatch uses), the inputs and what they do,
in a modal window over the screen; Esc, F1 or ? closes it. The lines drawn are recorded
(``editor.help_listed``) for the window tests, each row's rectangle as ``help:KEYS``."""

from __future__ import annotations

from imgui_bundle import imgui

from .keys import EDITOR_KEYS
from .layout import EditorPart

HELP_TITLE = "Keys and mouse"
#: The overlay's margin from the window's edges, window pixels.
HELP_MARGIN = 40.0
#: The width of the inputs' column, window pixels.
KEYS_COLUMN_W = 230.0
KEY_COLOUR = (1.0, 0.8, 0.4, 1.0)


class HelpOverlay(EditorPart):
    """The help overlay (a part of the Editor): open or closed, and the lines it drew."""

    help_open = False
    help_listed: list[str] = []  # noqa: RUF012 (set per window by first_steps_init)

    def toggle_help(self) -> None:
        self.help_open = not self.help_open

    def _draw_help(self) -> None:
        """The overlay, while ``help_open``."""
        if not self.help_open:
            return
        if not imgui.is_popup_open(HELP_TITLE):
            imgui.open_popup(HELP_TITLE)
        W, H = self.size()
        size = (max(300.0, W - 2 * HELP_MARGIN), max(200.0, H - 2 * HELP_MARGIN))
        imgui.set_next_window_pos((W / 2, H / 2), imgui.Cond_.always, (0.5, 0.5))
        imgui.set_next_window_size(size, imgui.Cond_.always)
        opened, keep = imgui.begin_popup_modal(HELP_TITLE, True, imgui.WindowFlags_.no_saved_settings
                                               | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_move)
        if not opened:
            self.help_open = False
            return
        if not keep:
            self.help_open = False
        pos = imgui.get_window_pos()
        self._rects["help"] = (pos.x, pos.y, pos.x + size[0], pos.y + size[1])
        close = EDITOR_KEYS.key_for("toggle_help")
        imgui.text(f"Esc, {close} or ? closes this list.")
        imgui.same_line()
        if self.button("First steps", tip=f"show the guided first steps ({EDITOR_KEYS.key_for('toggle_guide')})"):
            self.help_open = False
            self.show_guide()
        imgui.same_line()
        if self.button("Close##help", tip="close this list (Esc)"):
            self.help_open = False
        listed: list[str] = []
        flags = imgui.TableFlags_.row_bg | imgui.TableFlags_.borders_inner_h | imgui.TableFlags_.scroll_y
        if imgui.begin_table("help keys", 2, flags, (0.0, 0.0)):
            imgui.table_setup_column("input", imgui.TableColumnFlags_.width_fixed, KEYS_COLUMN_W)
            imgui.table_setup_column("does", imgui.TableColumnFlags_.width_stretch)
            imgui.table_setup_scroll_freeze(0, 1)
            imgui.table_headers_row()
            for keys, does in EDITOR_KEYS.rows():
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.push_text_wrap_pos(0.0)
                imgui.text_colored(imgui.ImVec4(*KEY_COLOUR), keys)
                imgui.pop_text_wrap_pos()
                self.rect(f"help:{keys}")
                imgui.table_next_column()
                imgui.push_text_wrap_pos(0.0)
                imgui.text(does)
                imgui.pop_text_wrap_pos()
                listed.append(keys)
            imgui.end_table()
        self.help_listed = listed
        if not self.help_open:
            imgui.close_current_popup()
        imgui.end_popup()
