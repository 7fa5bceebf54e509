"""Input events sent with xdotool to a real window under the virtual X server, and the wait until
the window has read them all (shared by the window tests' drivers).

xdotool returns once the X server has taken its requests, but the server hands the events to the
window later: on a loaded machine, after the few frames a driver used to draw. A test would then
look at the screen's state before the click or key it sent had arrived, and the late event would
land in the next step (a lost click, a key taken by a field still being typed in). So each command
line is followed by a key bound to nothing in vebuild's windows (Pause), sent by a second xdotool
once the first has exited: the server queues input events in the order it takes them, so the line
has arrived when that key has. The key is taken out before the window's own handler sees it.
"""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable
from typing import Any

import glfw

END_KEY = "Pause"
END_KEY_GLFW = glfw.KEY_PAUSE
ARRIVAL_TIMEOUT_S = 60.0  # far beyond any delay seen under load; a line that never arrives (focus lost) fails


class XInput:
    """Sends xdotool command lines to one window and draws its frames until each has arrived."""

    def __init__(self, xdotool: str, handle: Any, frame: Callable[[], None]):
        self.xdotool, self.frame = xdotool, frame
        self.arrived = 0
        previous = glfw.set_key_callback(handle, None)

        def on_key(window: Any, key: int, scancode: int, action: int, mods: int) -> None:
            if key == END_KEY_GLFW:
                if action == glfw.RELEASE:
                    self.arrived += 1
                return
            if previous is not None:
                previous(window, key, scancode, action, mods)

        glfw.set_key_callback(handle, on_key)

    def send(self, *args: str) -> None:
        """Run one xdotool command line, drawing frames (they read the events) until it has arrived."""
        before = self.arrived
        for line in (args, ("key", END_KEY)):  # apart: `type` takes all the words after it as its text
            proc = subprocess.Popen([self.xdotool, *line])
            while proc.poll() is None:
                self.frame()
            assert proc.returncode == 0, f"xdotool {' '.join(line)} exited with {proc.returncode}"
        deadline = time.monotonic() + ARRIVAL_TIMEOUT_S
        while self.arrived == before:
            assert time.monotonic() < deadline, f"the window never received xdotool {' '.join(args)}"
            self.frame()
