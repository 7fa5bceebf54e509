"""What the two windows (the walk-through and the modelling screen) share: the glfw input
callbacks, the keys held, a key-binding table, and a user's mistakes shown as messages.

Each window states its keys once, as a :class:`KeyTable`; from it come the dispatch
(:meth:`WindowApp.on_key` calls the bound command), the window's on-screen help and the manual's
key list (:meth:`KeyTable.markdown`; a test holds the manual to it).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import glfw

from vebuild.errors import VebuildError

#: The modifiers a binding distinguishes (Alt, Super and the locks are ignored).
SHIFT = glfw.MOD_SHIFT
CTRL = glfw.MOD_CONTROL
_MODS = SHIFT | CTRL

_NAMES = {glfw.KEY_ESCAPE: "Esc", glfw.KEY_DELETE: "Delete", glfw.KEY_HOME: "Home", glfw.KEY_END: "End",
          glfw.KEY_PAGE_UP: "PageUp", glfw.KEY_PAGE_DOWN: "PageDown", glfw.KEY_SPACE: "Space",
          glfw.KEY_LEFT_BRACKET: "[", glfw.KEY_RIGHT_BRACKET: "]", glfw.KEY_TAB: "Tab", glfw.KEY_ENTER: "Enter"}


def key_label(key: int, mods: int = 0) -> str:
    """How a key (with modifiers) is written on screen and in the manual: ``Ctrl+Shift+Z``, ``F1``."""
    if key in _NAMES:
        name = _NAMES[key]
    elif glfw.KEY_F1 <= key <= glfw.KEY_F25:
        name = f"F{key - glfw.KEY_F1 + 1}"
    elif 32 < key < 128:
        name = chr(key)
    else:
        raise ValueError(f"no label for key code {key}")
    return ("Ctrl+" if mods & CTRL else "") + ("Shift+" if mods & SHIFT else "") + name


@dataclass(frozen=True)
class Chord:
    """A key with exact modifiers (Shift, Ctrl) that calls ``command(*args)`` on the window."""

    key: int
    command: str
    args: tuple[Any, ...] = ()
    mods: int = 0

    @property
    def label(self) -> str:
        return key_label(self.key, self.mods)


@dataclass(frozen=True)
class Binding:
    """One line of a window's key list: the inputs as written (``keys``), what they do, and the
    chords the dispatch maps to commands. A binding with no chords is handled by the window's
    mouse code or read from the keys held (walking, the magnifier)."""

    keys: str
    does: str
    chords: tuple[Chord, ...] = field(default_factory=tuple)


class KeyTable:
    """A window's bindings in the order they are listed."""

    def __init__(self, bindings: Sequence[Binding]):
        self.bindings = tuple(bindings)
        self._chords: dict[tuple[int, int], Chord] = {}
        for b in self.bindings:
            for c in b.chords:
                if (c.key, c.mods) in self._chords:
                    raise ValueError(f"{c.label} is bound twice")
                if c.label not in b.keys:
                    raise ValueError(f"the binding '{b.keys}' does not name its key {c.label}")
                self._chords[(c.key, c.mods)] = c

    @property
    def chords(self) -> list[Chord]:
        return list(self._chords.values())

    def find(self, key: int, mods: int) -> Chord | None:
        """The chord a key press calls: the exact modifiers first; a key bound without Shift also
        answers with Shift held (Q turns whether or not Shift is down), Ctrl never is dropped."""
        mods &= _MODS
        chord = self._chords.get((key, mods))
        if chord is None and mods & SHIFT:
            chord = self._chords.get((key, mods & ~SHIFT))
        return chord

    def chord_for(self, command: str, *args: Any) -> Chord | None:
        """The first chord bound to ``command(*args)`` (for a tooltip's "key …")."""
        return next((c for c in self._chords.values() if c.command == command and c.args == args), None)

    def key_for(self, command: str, *args: Any) -> str:
        """The key bound to ``command(*args)``, as written (for on-screen hints); KeyError if none."""
        chord = self.chord_for(command, *args)
        if chord is None:
            raise KeyError(f"no key is bound to {command}{args}")
        return chord.label

    def rows(self) -> list[tuple[str, str]]:
        return [(b.keys, b.does) for b in self.bindings]

    def markdown(self) -> str:
        """The manual's key list: a two-column table, one row per binding."""
        lines = ["| input | does |", "|---|---|"]
        lines += [f"| {k} | {d} |" for k, d in self.rows()]
        return "\n".join(lines) + "\n"


class WindowApp(ABC):
    """The input plumbing of a window with a Dear ImGui layer (``gui``, optional: tests run
    without). Subclasses set :attr:`keys`, implement :meth:`say`, and take the mouse in
    :meth:`on_cursor`, :meth:`on_button` and :meth:`on_scroll`."""

    keys: KeyTable
    _held: set[int]
    _mods: int
    _cursor: tuple[float, float]
    #: Whether keys pressed while an ImGui text field has the keyboard count as held.
    keys_held_while_typing = True

    def __init__(self) -> None:
        self.gui: Any = None
        self._held: set[int] = set()
        self._mods = 0
        self._cursor = (0.0, 0.0)

    # -- to be provided by the window ----------------------------------------------------------------

    @abstractmethod
    def say(self, text: str) -> None:
        """Show ``text`` to the user (the window's message line)."""

    def input_blocked(self) -> bool:
        """Whether input is ignored now (a long task runs)."""
        return False

    @abstractmethod
    def on_cursor(self, x: float, y: float) -> None:
        """The mouse moved to window pixel (x, y)."""

    @abstractmethod
    def on_button(self, button: int, action: int, mods: int = 0) -> None:
        """A mouse button went down or up."""

    @abstractmethod
    def on_scroll(self, dx: float, dy: float) -> None:
        """The wheel turned."""

    def on_close(self, handle: Any) -> None:  # noqa: B027 (an optional hook: most windows just close)
        """The window's close button (glfw has already set its should-close flag); a window with
        unsaved work overrides it to ask first."""

    # -- shared -----------------------------------------------------------------------------------

    def install_callbacks(self, handle: Any) -> None:
        glfw.set_key_callback(handle, lambda w, key, sc, action, mods: self.on_key(key, action, mods))
        glfw.set_char_callback(handle, lambda w, c: self.on_char(c))
        glfw.set_cursor_pos_callback(handle, lambda w, x, y: self.on_cursor(x, y))
        glfw.set_mouse_button_callback(handle, lambda w, b, action, mods: self.on_button(b, action, mods))
        glfw.set_scroll_callback(handle, lambda w, dx, dy: self.on_scroll(dx, dy))
        glfw.set_window_close_callback(handle, lambda w: self.on_close(w))

    def guard(self, fn: Callable[..., Any], *args: Any, **kw: Any) -> Any:
        """Call ``fn``; a user's mistake (VebuildError) becomes a message on screen."""
        try:
            return fn(*args, **kw)
        except VebuildError as e:
            self.say(str(e))
            return None

    def held(self, *keys: int) -> bool:
        """Whether any of ``keys`` is held down."""
        return any(k in self._held for k in keys)

    def on_char(self, char: int) -> None:
        if self.gui is not None and not self.input_blocked():
            self.gui.on_char(char)

    def on_key(self, key: int, action: int, mods: int) -> None:
        if self.input_blocked():
            return
        typing = False
        if self.gui is not None:
            self.gui.on_key(key, action, mods)
            typing = self.gui.wants_keyboard()
        self._mods = mods
        if action == glfw.RELEASE:
            self._held.discard(key)
            return
        if action == glfw.PRESS and (self.keys_held_while_typing or not typing):
            self._held.add(key)
        if action != glfw.PRESS or typing:
            return
        self.key_pressed(key, mods)

    def key_pressed(self, key: int, mods: int) -> None:
        """Run the command the key table binds to this key, its mistakes shown as messages."""
        chord = self.keys.find(key, mods)
        if chord is not None:
            self.guard(getattr(self, chord.command), *chord.args)

    # -- the main loop ---------------------------------------------------------------------------------

    @abstractmethod
    def frame(self) -> None:
        """Draw one frame and take its input (provided by the window)."""

    @abstractmethod
    def close(self) -> None:
        """Release what the window holds (provided by the window)."""

    def run(self, window: Any, frames: int | None = None) -> None:
        """Draw frames until the window is closed (or ``frames`` have been drawn), then close."""
        try:
            n = 0
            while not window.should_close() and (frames is None or n < frames):
                self.frame()
                n += 1
        finally:
            self.close()
