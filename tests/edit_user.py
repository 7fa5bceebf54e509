"""A user at the modelling screen, as xdotool input events (tests/test_edit_rebuild.py and its
assisted twin): what the user does, the click noise a window adds, and which way the arrows show
world x in a photo."""

from __future__ import annotations

import math

import numpy as np
from edit_driver import Driver
from edit_scene import CLICK_NOISE_PX

from vebuild.edit.layout import CLICK_SLOP_PX


class User:
    """What a user does on the screen, as xdotool input events."""

    def __init__(self, d: Driver):
        self.d, self.e, self.s = d, d.editor, d.session

    def xy(self, uv) -> list[str]:
        x, y = self.e.image_to_window(None, uv)
        return self.d.move_to(x, y)

    def type_into(self, label: str, text: str) -> None:
        self.d.send(*self.d.at(label), "click", "1", "key", "ctrl+a", "type", "--delay", "20", text)
        self.d.send("key", "Return")

    def choose(self, combo: str, item: str) -> None:
        self.d.click(combo)
        self.d.frames(2)
        self.d.click(f"{combo}:{item}")

    def show(self, photo: str) -> None:
        if self.e.photo != photo:
            self.d.click(f"photo:{photo}")
        assert self.e.photo == photo

    def strokes(self, tool_key: str, segments) -> None:
        """Press, drag and release along each segment with the tool of that key."""
        self.d.send("key", tool_key)
        events: list[str] = []
        for u1, v1, u2, v2 in segments:
            a, b = np.array([u1, v1]), np.array([u2, v2])
            events += [*self.xy(a), "mousedown", "1"]
            for t in (0.5, 1.0):
                events += self.xy(a + t * (b - a))
            events += ["mouseup", "1"]
        self.d.send(*events)

    def drag(self, node: str, handle: str, goal) -> None:
        """Drag the vertex onto ``goal``; one already within a few pixels of it (twice a click's slop:
        a shorter drag would be taken for a click) is fixed where it is, with F, as a user would."""
        start = next(uv for n, h, uv, _ in self.s.handles(self.e.photo) if (n, h) == (node, handle))
        a, b = np.asarray(start, float), np.asarray(goal, float)
        if np.linalg.norm(b - a) * self.e.zoom <= 2 * CLICK_SLOP_PX:
            self.d.send(*self.xy(a), "key", "f")
            return
        events = [*self.xy(a), "mousedown", "1"]
        for t in np.linspace(0.125, 1.0, 8):
            events += [*self.xy(a + t * (b - a)), "sleep", "0.03"]
        self.d.send(*events, "mouseup", "1")


def window_noise(zoom: float) -> float:
    """1σ of the noise to add so that a click rounded to the window's pixels has 0.7 px in all."""
    grid = 0.5 / zoom / math.sqrt(3.0)  # a uniform error of ±0.5 window pixel, in photo pixels
    return math.sqrt(max(CLICK_NOISE_PX**2 - grid**2, 0.0))


def x_choice(R) -> str:
    """Which horizontal direction of the photo world x runs (what a user sees from the arrows)."""
    D = np.asarray(R) @ np.eye(3)
    side = max((0, 1), key=lambda i: abs(D[0, i]) / max(np.hypot(D[0, i], D[2, i]), 1e-12))
    if side == 0:
        return "right" if D[0, 0] >= 0 else "left"
    return "away" if D[2, 0] >= 0 else "toward"
