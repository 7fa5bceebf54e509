"""The modelling screen's keys for marking without the mouse's trips to the panel: the Marker
tool's offer (which marker the next click places), and the reference distance row typed from the
keyboard.

The offer: in a photo that lacks markers placed in other photos, the toolbar's name field offers
the first of them in the order they were first placed (the project's list of markers: the
Calibration tab lists them in that order, those this photo lacks first, the one offered
highlighted). A click places it, and the field moves on to the next marker after it that this
photo lacks, then to a new name (M1, M2, …), so that a user who follows the order places a later
sighting with one click. ] and [ step the offer forward and back through the markers the photo
lacks and the new name, Shift+M offers the new name at once, F2 puts the cursor in the field to type
a name. A name typed, or picked in the Calibration tab, stays until a click places it; an offered
one follows the photo shown.

The distance row: Ctrl+D puts the cursor in the Calibration tab's first marker field; Tab goes on to
the second and to the metres; Ctrl+Enter adds the distance and puts the cursor back in an emptied row
for the next one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import glfw

from vebuild.gl.app import CTRL

from .keys import EDITOR_KEYS


class EntryKeys:
    """Mixed into the screen (:class:`vebuild.edit.screen.Editor`)."""

    if TYPE_CHECKING:
        session: Any
        panels: Any
        photo: str | None
        tool: str
        marker_name: str
        _marker_name_default: bool

        def say(self, text: str) -> None: ...

        def set_tool(self, tool: str) -> None: ...

    # -- the Marker tool's offer ------------------------------------------------------------------

    def marker_offers(self) -> list[str]:
        """What the Marker tool's field offers in the photo shown, in order: the markers placed
        elsewhere that this photo lacks, in the order of their first placement, then a new name."""
        s = self.session
        shown: dict[str, Any] = next((p for p in s.data["photos"] if p["id"] == self.photo), {})  # none: removed
        here = set(shown.get("marker_observations") or {})
        return [n for n in s.project.marker_names() if n not in here] + [s.next_marker_name()]

    def offer_marker(self, after: str | None = None) -> None:
        """Offer the first marker this photo lacks that comes after ``after`` in the order (from the
        start where ``after`` is None); a new name where none does."""
        offers = self.marker_offers()
        names = self.session.project.marker_names()
        rest = offers[:-1]
        if after is not None and after in names:
            rest = [n for n in rest if names.index(n) > names.index(after)]
        self.marker_name, self._marker_name_default = (rest or offers[-1:])[0], True

    def refresh_marker_offer(self) -> None:
        """An offered name that no longer fits the photo shown (placed here since, by an undo, a
        proposal accepted or another photo shown) is offered afresh; a typed or picked one stays."""
        if self._marker_name_default and self.marker_name not in self.marker_offers():
            self.offer_marker()

    def step_marker_offer(self, step: int) -> None:
        """] / [: the next / previous of the markers this photo lacks and the new name (round)."""
        if self.tool != "marker":  # the Marker tool, stepping from what its field shows
            name, offered = self.marker_name, self._marker_name_default
            self.set_tool("marker")
            self.marker_name, self._marker_name_default = name, offered
        offers = self.marker_offers()
        i = offers.index(self.marker_name) if self.marker_name in offers else (-1 if step > 0 else 0)
        self.marker_name, self._marker_name_default = offers[(i + step) % len(offers)], True
        self._say_offer()

    def offer_new_marker(self) -> None:
        """Shift+M: the Marker tool with a new name (M1, M2, …)."""
        self.set_tool("marker")
        self.marker_name, self._marker_name_default = self.session.next_marker_name(), True
        self._say_offer()

    def type_marker_name(self) -> None:
        """F2: the Marker tool, and the cursor in its name field (what is there selected)."""
        if self.tool != "marker":
            self.set_tool("marker")
        self.__dict__["_focus_marker_field"] = True

    def take_marker_field_focus(self) -> bool:
        """Whether the toolbar should put the cursor in the name field now (once per F2)."""
        return bool(self.__dict__.pop("_focus_marker_field", False))

    def _say_offer(self) -> None:
        name, where = self.marker_name, self.photo or "the photo"
        steps = f"{EDITOR_KEYS.key_for('step_marker_offer', 1)} / {EDITOR_KEYS.key_for('step_marker_offer', -1)}"
        if name in self.session.project.marker_names():
            self.say(f"marker {name} (placed elsewhere): click where it is in {where}; {steps} the next / previous "
                     f"one this photo lacks, {EDITOR_KEYS.key_for('offer_new_marker')} a new marker")
        else:
            self.say(f"new marker {name}: click to place it in {where}; {steps} the markers this photo lacks")

    # -- the distance row -------------------------------------------------------------------------

    def type_distance(self) -> None:
        """Ctrl+D: the Calibration tab, the cursor in the distance row's first marker field."""
        self.panels.show_tab("Calibration")
        self.panels.focus_distance = True

    def on_key(self, key: int, action: int, mods: int) -> None:
        """Ctrl+Enter in the distance row adds the distance (ImGui has the keyboard then, so the key
        table does not see it)."""
        panels = self.__dict__.get("panels")
        if (action == glfw.PRESS and key in (glfw.KEY_ENTER, glfw.KEY_KP_ENTER) and mods & CTRL
                and panels is not None and panels.distance_row_active):
            panels.add_distance_pending = True
        super().on_key(key, action, mods)  # type: ignore[misc]  # WindowApp's, further along the Editor's bases
