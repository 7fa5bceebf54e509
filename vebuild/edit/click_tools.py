"""The modelling screen's building tools (a part of the Editor): Room (H: click the floor's corners,
close the outline by clicking the first corner again or Enter, then click a wall's top above a
corner or type the height), Opening (O: a doorway's or window's two bottom corners, then its top,
on a wall of the selected room) and Box (B: three corners of its footprint on the floor, then its
top above a corner, or type the height). Each click is snapped to the meet of two marked lines, or
else the image corner, within a few pixels (Alt: exactly where clicked); the session makes the primitive from the clicks
(:mod:`vebuild.edit.room_clicks`)."""

from __future__ import annotations

from typing import Any

import numpy as np
from imgui_bundle import imgui

from vebuild.errors import VebuildError

from .layout import PICK_RADIUS_PX, EditorPart, u32

#: The tools this part handles.
BUILD_TOOLS = ("room", "opening", "box")
BUILD_COLOUR = (1.0, 0.8, 0.2, 1.0)
#: How many clicks an opening and a box's footprint take.
OPENING_CLICKS = 3
FOOTPRINT_CLICKS = 3


class ClickTools(EditorPart):
    """Room, Opening and Box by clicking (a part of the Editor)."""

    def _build(self) -> dict[str, Any]:
        st = self.__dict__.get("_build_state")
        if st is None or st["photo"] != self.photo or st["tool"] != self.tool:
            st = self.__dict__["_build_state"] = {"photo": self.photo, "tool": self.tool, "clicks": [],
                                                  "stage": "corners", "node": None}
        return st

    def build_reset(self) -> bool:
        """Drop the clicks of a room, opening or box under way; whether there were any."""
        st = self.__dict__.pop("_build_state", None)
        return bool(st and (st["clicks"] or st["stage"] != "corners"))

    def build_prompt(self) -> str | None:
        """What to click next with a building tool, in words (the message area shows it)."""
        if self.tool not in BUILD_TOOLS or self.photo is None:
            return None
        st = self._build()
        n = len(st["clicks"])
        if self.tool == "room":
            if st["stage"] == "height":
                return ("click the top of a wall straight above one of the floor's corners, or type the height in the "
                        "Model tab (height); Esc when done")
            if n < 3:
                return f"Room: click the floor's corners in turn ({n} so far)"
            return f"Room: click the next corner, or the first again (or Enter) to close the floor ({n} corners)"
        if self.tool == "opening":
            what = ("its first bottom corner", "its other bottom corner", "its top, above a bottom corner")[min(n, 2)]
            return f"Opening: click {what} on the wall (a doorway's bottom on the floor)"
        if st["stage"] == "height":
            return "Box: click its top straight above a corner, or type the height in the Model tab; Esc when done"
        return f"Box: click a corner of its footprint on the floor, then the next round it ({n} of 3)"

    def build_click(self, x: float, y: float) -> None:
        """A click with a building tool at window point (x, y)."""
        s, photo = self.session, self.photo
        st = self._build()
        uv = self.window_to_image(x, y)
        if st["stage"] == "height":
            node, st["stage"], st["node"] = st["node"], "corners", None
            if self.tool == "room":
                s.room_height_from_click(node, photo, uv)
            else:
                s.box_height_from_click(node, photo, uv)
            self.select(node)
            return
        uv = s.snap_corner_click(photo, uv, exact=self.alt_held())
        clicks = st["clicks"]
        if self.tool == "room" and len(clicks) >= 3:
            fx, fy = self.image_to_window(None, clicks[0])
            if np.hypot(fx - x, fy - y) <= PICK_RADIUS_PX:
                self.build_enter()
                return
        clicks.append((float(uv[0]), float(uv[1])))
        if self.tool == "opening" and len(clicks) == OPENING_CLICKS:
            st["clicks"] = []
            s.opening_from_clicks(self._room_for_opening(), photo, clicks)
        elif self.tool == "box" and len(clicks) == FOOTPRINT_CLICKS:
            st["clicks"] = []
            st["node"] = s.box_from_clicks(photo, clicks)
            st["stage"] = "height"
            self.select(st["node"])
            self.panels.show_tab("Model")

    def build_enter(self) -> None:
        """Enter with the Room tool: the floor's outline closed, the room made."""
        if self.tool != "room" or self.photo is None:
            return
        st = self._build()
        node = self.session.room_from_clicks(self.photo, st["clicks"])  # refused: the clicks stay (Esc drops them)
        st["clicks"], st["stage"], st["node"] = [], "height", node
        self.select(node)
        self.panels.show_tab("Model")

    def _room_for_opening(self) -> str:
        model = self.session.model
        rooms = [n.name for n in model.nodes if n.primitive is not None and n.primitive.TYPE == "room"] if model else []
        if self.selected in rooms:
            return str(self.selected)
        if len(rooms) == 1:
            return rooms[0]
        raise VebuildError("select the room the opening is in (click one of its edges with Select, or its name in "
                           "the Model tab), then click the opening's corners" if rooms else
                           "there is no room yet: make one with the Room tool (H) first")

    def _draw_build(self) -> None:
        """The corners clicked so far, joined in order, over the photo."""
        st = self.__dict__.get("_build_state")
        if st is None or not st["clicks"] or st["photo"] != self.photo or self.tool not in BUILD_TOOLS:
            return
        dl = imgui.get_background_draw_list()
        x0, y0, x1, y1 = self.view_rect()
        dl.push_clip_rect((x0, y0), (x1, y1), True)
        colour = u32(BUILD_COLOUR)
        pts = [self.image_to_window(None, uv) for uv in st["clicks"]]
        for k, p in enumerate(pts):
            dl.add_circle(p, 6.0, colour, 0, 2.0)
            dl.add_text((p[0] + 8, p[1] - 18), colour, str(k + 1))
            if k:
                dl.add_line(pts[k - 1], p, colour, 2.0)
        dl.pop_clip_rect()
