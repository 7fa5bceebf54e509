"""The modelling screen's Relate tool: a click on a face of a node in the photo picks it (highlighted),
a click on a face of another node picks the second; then a small popup (or a key: F flush, A
aligned, Esc cancels) makes the relation, a flush one with the offset typed in it. Shift+click picks
the projected edge under the cursor instead (two edges are aligned: collinear)."""

from __future__ import annotations

import dataclasses
from typing import Any

from imgui_bundle import imgui

from vebuild.errors import VebuildError

from .layout import EditorPart, u32

#: How a picked face is shown over the photo: translucent orange (first), cyan (second).
PICK_COLOURS = ((1.0, 0.6, 0.1, 0.35), (0.2, 0.9, 0.95, 0.35))
POPUP = "relate faces"


class RelateTool(EditorPart):
    """The Relate tool (a part of the Editor)."""

    relate_picks: list[Any]
    relate_offset: str
    _relate_popup: bool
    _relate_popup_shown: bool

    def relate_click(self, x: float, y: float) -> None:
        """A click with the Relate tool: pick the face (Shift: the edge) under window point (x, y)."""
        s, photo = self.session, self.photo
        if self.shift_held():
            line = self._nearest_line(("edge",), x, y)
            if line is None:
                self.say("no projected edge under the cursor (Shift+click picks an edge, a click a face)")
                return
            pick = s.edge_pick(*line.key)
        else:
            pick = s.face_at(photo, self.window_to_image(x, y))
            if pick is None:
                self.say("no face of the model under the cursor: click on a face of a primitive")
                return
        picks = list(self.relate_picks)
        if picks and picks[0].node == pick.node:
            self.say(f"{pick.ref} is on the same node as {picks[0].ref}: pick a face of another node")
            return
        if picks and picks[0].what != pick.what:
            self.say(f"{picks[0].ref} is {'an edge' if picks[0].what == 'edge' else 'a face'}: pick "
                     f"{'an edge (Shift+click)' if picks[0].what == 'edge' else 'a face'} to relate it to")
            return
        picks.append(pick)
        self.relate_picks = picks
        if len(picks) == 1:
            self.say(f"{pick.ref} picked: now click the {pick.what} to relate it to (on another node)")
        else:
            self._relate_popup = True
            self.say(f"{picks[0].ref} and {pick.ref}: " +
                     ("F flush (with the offset typed), A aligned, Esc cancels" if pick.what == "face"
                      else "A aligned (collinear), Esc cancels"))

    def relate_choose(self, kind: str) -> None:
        """Make the relation between the two picks (F: flush, A: aligned)."""
        if len(self.relate_picks) != 2:
            self.say("pick two faces with the Relate tool first (R, then a click on each)")
            return
        text = self.relate_offset.strip()
        offset = 0.0
        if kind in ("flush", "flush joint") and text:
            try:
                offset = float(text)
            except ValueError:
                self.say(f"the flush offset must be a number of metres (e.g. 0.02), not {text!r}")
                return
        a, b = self.relate_picks
        try:
            if kind == "flush joint":
                if self._parent_of(a.node) != b.node:
                    a, b = b, a  # the child's face on its parent's
                self.session.make_flush_joint(a, b, offset=offset)
            else:
                self.session.add_relation(kind, a, b, offset=offset)
        except VebuildError as e:
            self.say(str(e))
            return
        self.relate_picks = []
        self._relate_popup = False

    def _parent_of(self, node: str) -> str | None:
        model = self.session.model
        return model.node(node).parent if model is not None and node in model.index else None

    def relate_cancel(self) -> bool:
        """Esc: drop the picks (True if there were any)."""
        had = bool(self.relate_picks)
        self.relate_picks = []
        self._relate_popup = False
        if had:
            self.say("relation cancelled")
        return had

    def _draw_relate(self, dl: Any) -> None:
        """The picked faces (or edges) over the photo."""
        if self.photo is None or not self.relate_picks:
            return
        # The second first, so that the first (often in front: a cabinet before its wall) shows over it.
        for pick, colour in reversed(list(zip(self.relate_picks, PICK_COLOURS, strict=False))):
            col = u32(colour)
            edge = u32((colour[0], colour[1], colour[2], 1.0))
            for poly in self.guard(self.session.pick_outline, self.photo, pick) or []:
                pts = [self.image_to_window(None, q) for q in poly]
                if len(pts) == 3:
                    dl.add_triangle_filled(pts[0], pts[1], pts[2], col)
                else:
                    dl.add_line(pts[0], pts[1], edge, 4.0)

    def _draw_relate_popup(self) -> None:
        """The popup over the photo once two faces are picked: the offset, Flush, Aligned, Cancel."""
        if self._relate_popup and not self._relate_popup_shown:
            imgui.open_popup(POPUP)
        x0, y0, x1, _ = self.view_rect()
        imgui.set_next_window_pos((0.5 * (x0 + x1), y0 + 20), imgui.Cond_.always, (0.5, 0.0))
        opened = imgui.begin_popup(POPUP, imgui.WindowFlags_.always_auto_resize | imgui.WindowFlags_.no_saved_settings)
        if not opened:
            if self._relate_popup_shown:  # shown, and closed now: chosen, or a click outside it
                self._relate_popup_shown = False
                if self._relate_popup:
                    self.relate_cancel()
            return
        self._relate_popup_shown = True
        pos, size = imgui.get_window_pos(), imgui.get_window_size()
        self._rects[POPUP] = (pos.x, pos.y, pos.x + size.x, pos.y + size.y)
        faces = len(self.relate_picks) == 2 and self.relate_picks[0].what == "face"
        if faces:  # a face the photo hides (a cabinet's back on the wall) is chosen here, by name
            for i, side in enumerate(("a", "b")):
                pick = self.relate_picks[i]
                names = self.session.plane_names(pick.node)
                imgui.text(f"{side}: {pick.node}")
                imgui.same_line()
                imgui.set_next_item_width(110)
                at = names.index(pick.name) if pick.name in names else 0
                chosen = self.combo(f"relate {side}", at, names)
                if names and chosen != at:
                    self.relate_picks[i] = dataclasses.replace(pick, name=names[chosen])
        else:
            a, b = (p.ref for p in self.relate_picks) if len(self.relate_picks) == 2 else ("?", "?")
            imgui.text(f"{a}  and  {b}")
        if faces:
            a, b = self.relate_picks  # read before a button below clears them
            child = self._parent_of(a.node) == b.node or self._parent_of(b.node) == a.node
            imgui.set_next_item_width(90)
            _, self.relate_offset = imgui.input_text("offset m##relate", self.relate_offset)
            self.rect("relate offset")
            imgui.set_item_tooltip("flush: how far a lies from b along b's outward normal (metres; blank: 0)")
            if self.button("Flush (F)##relate", tip="a's face against b's, facing it (a cabinet's back on a wall)"):
                self.relate_choose("flush")
            imgui.same_line()
            if child and self.button("Flush joint##relate", tip="the same, exactly, by the node's joint: it hangs on "
                                                                "that face of its parent and slides and turns on it"):
                self.relate_choose("flush joint")
            if child:
                imgui.same_line()
        if self.button("Aligned (A)##relate", tip="coplanar faces facing the same way (cabinet fronts in a row), "
                                                  "or collinear edges"):
            self.relate_choose("aligned")
        imgui.same_line()
        if self.button("Cancel (Esc)##relate"):
            self.relate_cancel()
        if not self._relate_popup:
            imgui.close_current_popup()
        imgui.end_popup()
