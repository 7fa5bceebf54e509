"""The modelling screen's first steps, as a part of the :class:`~vebuild.edit.screen.Editor`: the
guided sequence's card over the photo (:mod:`.guide`), with an axis gizmo; the help overlay
(:mod:`.help`, F1 or ?); the file browser (:mod:`.browser`, Ctrl+O) and files dropped onto the
window. While the help or the browser is open it takes the keys (Esc closes it) and the mouse; the
card takes the clicks that land on it."""

from __future__ import annotations

import math
from typing import Any

import glfw
from imgui_bundle import imgui

from .browser import PhotoBrowser
from .guide import STEPS, Guide, Step, floor_node, is_new
from .help import HelpOverlay
from .layout import inside, u32
from .overlay import AXIS_COLOURS

#: In the browser's frame chooser: , and Left a frame back, . and Right a frame on.
_FRAME_STEPS = {glfw.KEY_COMMA: -1, glfw.KEY_LEFT: -1, glfw.KEY_PERIOD: 1, glfw.KEY_RIGHT: 1}

#: The card's width and its gap from the photo view's top-right corner, window pixels.
GUIDE_W = 340.0
GUIDE_GAP = 8.0
#: The axis gizmo's size, window pixels.
GIZMO_H = 120.0
DONE_COLOUR = (0.45, 0.85, 0.45, 1.0)
NOW_COLOUR = (1.0, 0.8, 0.3, 1.0)
TODO_COLOUR = (0.6, 0.6, 0.6, 1.0)
#: The side of a step's square in the card's progress row, window pixels.
STEP_BOX = 14.0
#: The tool each marking step offers, and the Panels tab it shows.
STEP_TOOLS = {"x": "x", "y": "y", "z": "z", "markers": "marker"}
STEP_TABS = {"markers": "Calibration", "distance": "Calibration", "calibrate": "Calibration",
             "floor": "Model", "object": "Model"}


class FirstSteps(HelpOverlay, PhotoBrowser):
    """The guide, the help overlay and the photo browser (a part of the Editor)."""

    guide: Guide | None = None

    def first_steps_init(self, handle: Any) -> None:
        """The guide (hidden until :meth:`open_guide_if_new`), the help and the browser closed; the
        window's drop callback."""
        self.guide = Guide()
        self.help_open = False
        self.help_listed = []
        self.browser = None
        self.browser_problems: list[str] = []
        if handle is not None:
            def dropped(window: Any, paths: Any) -> None:
                self.on_drop([str(p) for p in paths])

            glfw.set_drop_callback(handle, dropped)  # type: ignore[arg-type]  # glfw's stub: (window, count, str)

    def open_guide_if_new(self) -> bool:
        """Show the guide if the project is new or empty (``vebuild edit`` does, as the window opens)."""
        if self.guide is not None and is_new(self.session):
            self.guide.shown = True
        return bool(self.guide is not None and self.guide.shown)

    # -- commands (the key table's) ---------------------------------------------------------------

    def toggle_guide(self) -> None:
        if self.guide is not None:
            self.guide.shown = not self.guide.shown

    def show_guide(self) -> None:
        if self.guide is not None:
            self.guide.shown = True

    # -- input --------------------------------------------------------------------------------------

    def on_key(self, key: int, action: int, mods: int) -> None:
        """While the help or the browser is open (ImGui then holds the keyboard): Esc closes it, and
        F1 or ? the help, Ctrl+O the browser; other keys do nothing but type into its fields."""
        if not (self.help_open or self.browser is not None) or action != glfw.PRESS or self.input_blocked():
            super().on_key(key, action, mods)  # type: ignore[misc]  # WindowApp's, further along the Editor's bases
            return
        if self.gui is not None:
            self.gui.on_key(key, action, mods)
            if imgui.get_io().want_text_input:  # typing a folder: Esc leaves the field
                return
        chord = self.keys.find(key, mods)
        if self.help_open:
            if key == glfw.KEY_ESCAPE or (chord is not None and chord.command == "toggle_help"):
                self.help_open = False
        elif self.browser is not None and self.browser.video is not None and key in _FRAME_STEPS:
            self.step_video_frame(_FRAME_STEPS[key])  # the frame chooser: a frame back or on
        elif key == glfw.KEY_ESCAPE and self.browser is not None and self.browser.video is not None:
            self.browser.video = None  # back to the folder
        elif key == glfw.KEY_ESCAPE or (chord is not None and chord.command == "open_browser"):
            self.browser = None

    def _photo_takes(self, x: float, y: float) -> bool:
        """Not where the guide's card is, nor while the help or the browser is open."""
        if self.help_open or self.browser is not None:
            return False
        card = self.widget_rects.get("guide") if self.guide is not None and self.guide.shown else None
        if card is not None and inside(card, x, y):
            return False
        return bool(super()._photo_takes(x, y))  # type: ignore[misc]

    # -- drawing ------------------------------------------------------------------------------------

    def _draw_first_steps(self) -> None:
        self._draw_guide()
        self._draw_help()
        self._draw_browser()

    def _draw_guide(self) -> None:
        g = self.guide
        if g is None or not g.shown:
            return
        s, photo = self.session, self.photo
        x0, y0, x1, _ = self.view_rect()
        other = self.widget_rects.get("Layers")  # the Layers popup (V) has the same corner: below it
        top = other[3] + GUIDE_GAP if other is not None else y0 + GUIDE_GAP
        imgui.set_next_window_pos((x1 - GUIDE_W - GUIDE_GAP, top), imgui.Cond_.always)
        imgui.set_next_window_size((GUIDE_W, 0.0), imgui.Cond_.always)
        imgui.set_next_window_bg_alpha(0.92)
        imgui.begin("First steps##guide", None, imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize
                    | imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.always_auto_resize | imgui.WindowFlags_.no_focus_on_appearing)
        done = g.done(s, photo)
        step = g.current(s, photo)
        n_done = sum(done)
        imgui.text(f"{n_done} of {len(STEPS)} steps done" + (f" (photo {photo})" if photo else ""))
        imgui.same_line(GUIDE_W - 60)
        if self.button("Hide##guide", tip=f"hide the first steps ({self.keys.key_for('toggle_guide')} or the help "
                                          f"overlay, {self.keys.key_for('toggle_help')}, shows them again)"):
            g.shown = False
        dl = imgui.get_window_draw_list()
        for k, (st, ok) in enumerate(zip(STEPS, done, strict=True)):  # a row of squares, one a step
            if k:
                imgui.same_line(0.0, 4.0)
            p = imgui.get_cursor_screen_pos()
            imgui.dummy((STEP_BOX, STEP_BOX))
            self.rect(f"guide step:{st.key}")
            colour = DONE_COLOUR if ok else NOW_COLOUR if st is step else TODO_COLOUR
            if ok or st is step:
                dl.add_rect_filled((p.x, p.y), (p.x + STEP_BOX, p.y + STEP_BOX), u32(colour), 3.0)
            else:
                dl.add_rect((p.x, p.y), (p.x + STEP_BOX, p.y + STEP_BOX), u32(colour), 3.0, 1.5)
            imgui.set_item_tooltip(f"{k + 1}. {st.title}: " + ("done (" if ok else "done when ") + st.done_when
                                   + (")" if ok else ""))
        imgui.separator()
        if step is None:
            imgui.push_text_wrap_pos(0.0)
            imgui.text_colored(imgui.ImVec4(*DONE_COLOUR), "All first steps done.")
            imgui.text("Next: drag the floor's and the object's corners onto the photos (Select tool, Esc), Solve "
                       f"(Model tab), more photos, Extract textures. {self.keys.key_for('toggle_help')} lists every "
                       "key.")
            imgui.pop_text_wrap_pos()
        else:
            self._guide_step(g, step)
        pos, size = imgui.get_window_pos(), imgui.get_window_size()
        self._rects["guide"] = (pos.x, pos.y, pos.x + size.x, pos.y + size.y)
        imgui.end()

    def _guide_step(self, g: Guide, step: Step) -> None:
        s, photo = self.session, self.photo
        imgui.text_colored(imgui.ImVec4(*NOW_COLOUR), f"Step {STEPS.index(step) + 1}: {step.title}")
        self.rect("guide now")
        imgui.push_text_wrap_pos(0.0)
        imgui.text(step.todo)
        imgui.text_disabled(f"done when: {step.done_when}")
        nxt = g.next_after(step, s, photo)
        imgui.text_disabled(f"next: {nxt.title if nxt is not None else 'the model, then Solve'}")
        imgui.pop_text_wrap_pos()
        if step.key == "axes":
            self._draw_gizmo()
        if step.key == "photo":
            if self.button("Browse photos…##guide", tip=f"the file browser ({self.keys.key_for('open_browser')})"):
                self.open_browser()
        elif step.key in STEP_TOOLS:
            tool = STEP_TOOLS[step.key]
            label = {"x": "Segment X", "y": "Segment Y", "z": "Segment Z", "marker": "Marker"}[tool]
            if self.button(f"Use {label}##guide", tip=f"the {label} tool (key {self._tool_key(tool)})"):
                self.set_tool(tool)
        elif step.key == "calibrate":
            if self.button("Calibrate##guide", tip="calibrate every photo from its segments and markers"):
                self.later(self.calibrate)
        elif step.key == "floor":
            if self.button("Click the floor's corners##guide", tip=f"the Room tool (key {self._tool_key('room')}): "
                                                                   "the floor's corners, then the wall's height"):
                self.set_tool("room")
            imgui.same_line()
            if self.button("A floor quad##guide", tip="a quad named floor (Model tab's Add); then click in the photo "
                                                      "where it lies, and drag its corners onto the floor's"):
                self.panels.prepare_add("quad", "floor", None)
                self.panels.arm_placement()
        elif step.key == "object":
            if self.button("Box by its corners##guide", tip=f"the Box tool (key {self._tool_key('box')}): three "
                                                            "corners of its footprint, then its top"):
                self.set_tool("box")
            imgui.same_line()
            if self.button("Add a box##guide", tip="a box on the floor (Model tab's Add); then click in the photo "
                                                   "where it stands"):
                self.panels.prepare_add("box", "", floor_node(s))
                self.panels.arm_placement()
        if step.key in STEP_TABS and g.tab_for != step.key:  # once, as the step begins: the user may leave it
            self.panels.show_tab(STEP_TABS[step.key])
            g.tab_for = step.key
        if step.key != "photo":
            if step.key != "axes":  # beside the step's own button
                imgui.same_line()
            what = "Next" if step.check is None else "Skip"
            tip = "I have read it" if step.check is None else "go on without this step (it is done another way)"
            if self.button(f"{what}##guide", tip=tip):
                g.skip(step.key)

    def _tool_key(self, tool: str) -> str:
        from .keys import tool_key

        return tool_key(tool)

    def _draw_gizmo(self) -> None:
        """The world's axes as a small drawing: the floor (x and y) seen obliquely from above, z up."""
        dl = imgui.get_window_draw_list()
        p = imgui.get_cursor_screen_pos()
        w = imgui.get_content_region_avail().x
        imgui.dummy((w, GIZMO_H))
        self.rect("gizmo")
        ox, oy = p.x + 0.18 * w, p.y + GIZMO_H - 30
        # x to the right and a little toward the viewer, y away to the right, z up (window y grows down).
        ends = {"x": (0.45 * w, 26.0), "y": (0.30 * w, -48.0), "z": (0.0, -(GIZMO_H - 44))}
        fx, fy = ends["x"], ends["y"]
        dl.add_quad_filled((ox, oy), (ox + fx[0], oy + fx[1]), (ox + fx[0] + fy[0], oy + fx[1] + fy[1]),
                           (ox + fy[0], oy + fy[1]), u32((0.55, 0.55, 0.6, 0.35)))
        names = {"x": "x (floor)", "y": "y (floor)", "z": "z (up)"}
        for a in ("x", "y", "z"):
            col = u32(AXIS_COLOURS[a])
            dx, dy = ends[a]
            n = math.hypot(dx, dy)
            ux, uy = dx / n, dy / n
            ex, ey = ox + dx, oy + dy
            dl.add_line((ox, oy), (ex, ey), col, 3.0)
            head = 9.0
            dl.add_triangle_filled((ex + ux * head, ey + uy * head), (ex - uy * head * 0.6, ey + ux * head * 0.6),
                                   (ex + uy * head * 0.6, ey - ux * head * 0.6), col)
            at = {"x": (ex + 12, ey - 6), "y": (ex + 10, ey - 14), "z": (ex + 8, ey - 4)}[a]
            dl.add_text(at, col, names[a])
        dl.add_circle_filled((ox, oy), 4.0, u32((1.0, 1.0, 1.0, 1.0)))
        imgui.text_disabled("white dot: the origin, the first marker, on the floor (z = 0)")
