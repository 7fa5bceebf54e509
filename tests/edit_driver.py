"""The modelling screen in a real window under a virtual X server, and xdotool to type and click
into it, as a user's keyboard and mouse would (shared by the window tests)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
from xinput import XInput

from vebuild.edit.screen import Editor
from vebuild.edit.session import EditSession
from vebuild.gl.surface import WindowSurface
from vebuild.gl.window import Window

TITLE = "vebuild edit test"
W, H = 1200, 780


class Driver:
    """The modelling screen in a real window, and xdotool to type and click into it."""

    def __init__(self, project_file: Path, xdotool: str, recover: bool | None = False):
        self.window = Window(W, H, TITLE, visible=True)
        self.session = EditSession.open(project_file, recover=recover)
        self.editor = Editor(self.session, WindowSurface(self.window))
        self.xdotool = xdotool
        self.frames(3)
        ids = subprocess.run([xdotool, "search", "--name", TITLE], capture_output=True, text=True).stdout.split()
        self.wid = ids[-1]
        subprocess.run([xdotool, "windowfocus", "--sync", self.wid], check=True)
        self.input = XInput(xdotool, self.window.handle, self.editor.frame)
        self.frames(len(self.session.photo_ids) + 2)  # the thumbnails, one a frame

    def frames(self, n: int) -> None:
        for _ in range(n):
            self.editor.frame()

    def send(self, *args: str) -> None:
        """Run one xdotool command line while the window keeps drawing frames (it reads the events)."""
        self.input.send(*args)
        self.frames(4)

    def move_to(self, x: float, y: float) -> list[str]:
        return ["mousemove", "--window", self.wid, str(int(round(x))), str(int(round(y)))]

    def at(self, label: str) -> list[str]:
        x0, y0, x1, y1 = self.editor.widget_rects[label]
        return self.move_to(0.5 * (x0 + x1), 0.5 * (y0 + y1))

    def click(self, label: str) -> None:
        self.send(*self.at(label), "sleep", "0.05", "click", "1")

    def screen(self) -> np.ndarray:
        self.editor.draw()
        return self.editor.surface.read()

    def close(self) -> None:
        self.editor.close()
        self.window.close()
