"""The modelling screen's messages, in one place (the bottom left of the photo view), the newest on
top: each message the session says (:meth:`~vebuild.edit.history.SessionState.say`) shows for
:data:`MESSAGE_SECONDS` and goes; at most :data:`MESSAGES_SHOWN` at a time. Above them what holds
now (a refused drag's reason while the drag lasts, the click a placement or a measurement on the
photo alone waits for); under them the photo's notes (why it has no vanishing point or model yet),
dimmer, for as long as they hold."""

from __future__ import annotations

import time
from collections.abc import Callable

from imgui_bundle import imgui

from .layout import EditorPart

#: How long a message shows (seconds).
MESSAGE_SECONDS = 8.0
#: How many of the latest messages show at once.
MESSAGES_SHOWN = 3

RGBA = tuple[float, float, float, float]


def new_messages(old: list[str], new: list[str]) -> list[str]:
    """What ``new`` (the session's messages now) has that ``old`` (as last seen) had not: the list
    only grows at its end and drops its oldest, so the new ones follow the longest end of ``old``
    that ``new`` starts with."""
    for k in range(min(len(old), len(new)), 0, -1):
        if old[len(old) - k:] == new[:k]:
            return new[k:]
    return list(new)


class MessageArea(EditorPart):
    """The message area (a part of the Editor)."""

    message_clock: Callable[[], float] = staticmethod(time.monotonic)

    def shown_messages(self) -> list[tuple[str, RGBA]]:
        """What the message area shows now, top to bottom, with its colour."""
        seen: list[str] = getattr(self, "_messages_seen", [])
        timed: list[tuple[str, float]] = getattr(self, "_messages_timed", [])
        now = self.message_clock()
        if self.messages is not seen:
            fresh = new_messages(seen, self.messages)
            timed = timed + [(m, now) for m in fresh]
            self._messages_seen = self.messages
        timed = [(m, t) for m, t in timed if now - t < MESSAGE_SECONDS][-MESSAGES_SHOWN:]
        self._messages_timed = timed
        lines: list[tuple[str, RGBA]] = []
        if self.drag_problem:
            lines.append((self.drag_problem, (1.0, 0.35, 0.3, 1.0)))
        if self._placing is not None:
            lines.append((f"click in the photo where the new {self._placing['kind']} stands (Esc cancels)",
                          (1.0, 0.8, 0.2, 1.0)))
        prompt = self.measure_prompt() or self.build_prompt()  # the next point to click
        if prompt:
            lines.append((prompt, (1.0, 0.8, 0.2, 1.0)))
        lines += [(m, (1.0, 1.0, 1.0, 1.0)) for m, _ in reversed(timed) if m != self.drag_problem]
        ov = self._overlay if self._overlay_key and self._overlay_key[1] == self.photo else None
        lines += [(note, (0.75, 0.75, 0.75, 1.0)) for note in (ov.notes if ov is not None else [])]
        return lines

    def _draw_messages(self) -> None:
        x0, _, x1, y1 = self.view_rect()
        lines = self.shown_messages()
        if not lines:
            return
        imgui.set_next_window_pos((x0 + 6, y1 - 6), imgui.Cond_.always, (0.0, 1.0))
        imgui.set_next_window_bg_alpha(0.7)
        imgui.begin("##messages", None, imgui.WindowFlags_.no_decoration | imgui.WindowFlags_.always_auto_resize
                    | imgui.WindowFlags_.no_inputs | imgui.WindowFlags_.no_saved_settings
                    | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav)
        imgui.push_text_wrap_pos(max(200.0, x1 - x0 - 40))
        for text, colour in lines:
            imgui.text_colored(imgui.ImVec4(*colour), text)
        imgui.pop_text_wrap_pos()
        pos, size = imgui.get_window_pos(), imgui.get_window_size()
        self._rects["messages"] = (pos.x, pos.y, pos.x + size.x, pos.y + size.y)
        imgui.end()
