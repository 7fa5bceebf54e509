"""What the modelling screen's panels hold (:class:`~vebuild.edit.panels.Panels`): the values being
typed into their fields, the tab to bring forward, and the two field helpers that the panels' parts
(:mod:`.node_panel`, :mod:`.model_panels`) share with them."""

from __future__ import annotations

from typing import Any

from imgui_bundle import imgui

from .layout import EditorPart


class PanelFields:
    """The panels' fields of an :class:`~vebuild.edit.screen.Editor` (``ed``), as typed."""

    def __init__(self, editor: EditorPart):
        self.ed = editor
        self.new_kind = 1  # box
        self.new_parent = 0  # (none)
        self.new_name = ""
        self.group_name = "group1"
        self.dist_a, self.dist_b, self.dist_m, self.dist_role = "", "", 1.0, 0
        self.focus_distance = False  # Ctrl+D: the cursor in the distance row's first field at the next frame
        self.distance_row_active = False  # a field of the distance row has the cursor (Ctrl+Enter adds)
        self.add_distance_pending = False  # Ctrl+Enter was pressed in the distance row
        self.length_axis, self.length_m, self.length_sigma = 2, "", ""  # z; typed as text: checked on Add
        self.height_m, self.height_sigma = "", ""
        self.equal_param = 0  # the size "Make equal" shares
        self.room_corner, self.room_wall, self.room_kind = 0, 0, 0  # a room's corner, wall, opening kind
        self.param_edits: dict[str, Any] = {}
        self._select_tab: str | None = None  # a tab to bring forward at the next frame (the first steps')
        self.camera_ticks: set[str] = set()  # the photos ticked to share one camera
        self.left_out_text: list[str] = []  # the shown photo's legend of its left-out segments, as drawn

    def forget_edits(self) -> None:
        """Drop the values typed but not committed (another node was selected)."""
        self.param_edits.clear()

    def show_tab(self, name: str) -> None:
        """Bring a tab forward at the next frame."""
        self._select_tab = name

    def node_doc(self, name: str) -> dict[str, Any] | None:
        """The project document's node ``name`` (None: no such node)."""
        for n in (self.ed.session.data.get("model") or {}).get("nodes", []):
            if n["name"] == name:
                return n
        return None

    def float_field(self, label: str, value: float, fmt: str = "%.4f") -> float | None:
        """An input committed by Enter or by leaving it; returns the committed value or None."""
        shown = self.param_edits.get(label, value)
        changed, v = imgui.input_float(label, float(shown), 0.0, 0.0, fmt)
        self.ed.rect(label)
        if changed:
            self.param_edits[label] = float(v)
        if imgui.is_item_deactivated_after_edit():
            return self.param_edits.pop(label, float(v))
        return None
