"""The Calibration tab's rename field: a marker's name and its new name, then Rename (the
session's :meth:`~vebuild.edit.rename.MarkerRename.rename_marker`; refused names say why in the
status line)."""

from __future__ import annotations

from typing import Any

from imgui_bundle import imgui


def rename_field(panels: Any) -> None:
    """Draw the field under the list of markers (``panels``: the screen's Panels, whose ``ed`` is
    the screen); its widgets' rectangles are ``rename from``, ``rename to`` and ``rename##marker``."""
    ed = panels.ed
    old = getattr(panels, "rename_from", "")
    new = getattr(panels, "rename_to", "")
    imgui.text("rename a marker")
    imgui.set_next_item_width(70)
    _, old = imgui.input_text("marker##rename from", old)
    ed.rect("rename from")
    imgui.set_item_tooltip("the marker to rename")
    imgui.same_line()
    imgui.set_next_item_width(70)
    _, new = imgui.input_text("new name##rename to", new)
    ed.rect("rename to")
    imgui.set_item_tooltip("its new name (not one in use)")
    imgui.same_line()
    if ed.button("rename##marker", tip="rename the marker in every photo, distance and joint (undoable)"):
        ed.guard(ed.session.rename_marker, old.strip(), new)
        names = ed.session.project.marker_names()
        if new.strip() in names and old.strip() not in names:  # done: the fields are cleared
            old, new = "", ""
    panels.rename_from, panels.rename_to = old, new
