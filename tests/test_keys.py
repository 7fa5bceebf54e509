"""Each window's keys are stated once (a KeyTable): the manual's key list is that table's
rendering, and the window's dispatch calls the command of every chord in it."""

from __future__ import annotations

from pathlib import Path

import glfw
import pytest

from vebuild.edit.keys import EDITOR_KEYS
from vebuild.edit.screen import Editor
from vebuild.gl.app import CTRL, SHIFT, WindowApp
from vebuild.viewer.app import Viewer
from vebuild.viewer.keys import VIEWER_KEYS

MANUAL = Path(__file__).resolve().parents[1] / "docs" / "manual.md"
WINDOWS = {"viewer": (Viewer, VIEWER_KEYS, "## The walk-through: `vebuild view`"),
           "editor": (Editor, EDITOR_KEYS, "## The modelling screen: `vebuild edit`")}


def readme_key_list(heading: str) -> str:
    text = MANUAL.read_text(encoding="utf-8")
    start = text.index("| input | does |", text.index(heading))
    lines = []
    for line in text[start:].splitlines():
        if not line.startswith("|"):
            break
        lines.append(line)
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("window", WINDOWS)
def test_the_manual_lists_the_keys_the_table_binds(window):
    _, table, heading = WINDOWS[window]
    assert readme_key_list(heading) == table.markdown()


@pytest.mark.parametrize("window", WINDOWS)
def test_every_chord_in_the_table_reaches_its_command(window):
    cls, table, _ = WINDOWS[window]
    app = cls.__new__(cls)  # the dispatch alone: no window, no GL
    WindowApp.__init__(app)
    app._busy = None
    assert table.chords
    for chord in table.chords:
        assert callable(getattr(cls, chord.command, None)), f"{window}: no command {chord.command}"
        calls = []
        setattr(app, chord.command, lambda *args, _c=calls: _c.append(args))
        app.on_key(chord.key, glfw.PRESS, chord.mods)
        app.on_key(chord.key, glfw.RELEASE, chord.mods)
        assert calls == [chord.args], f"{window}: {chord.label} did not call {chord.command}{chord.args}"
        delattr(app, chord.command)


def test_a_key_bound_without_shift_answers_with_shift_but_not_with_ctrl():
    q = VIEWER_KEYS.find(glfw.KEY_Q, 0)
    assert q is not None and VIEWER_KEYS.find(glfw.KEY_Q, SHIFT) == q
    assert VIEWER_KEYS.find(glfw.KEY_Q, CTRL) is None
    assert VIEWER_KEYS.find(glfw.KEY_R, SHIFT).args == (True,)
    assert EDITOR_KEYS.find(glfw.KEY_Y, CTRL | SHIFT).command == "redo"
    assert EDITOR_KEYS.find(glfw.KEY_1, CTRL) is None


def test_on_screen_hints_name_the_keys_the_table_binds():
    assert EDITOR_KEYS.key_for("undo") == "Ctrl+Z" and EDITOR_KEYS.key_for("redo") == "Ctrl+Y"
    assert EDITOR_KEYS.key_for("set_tool", "x") == "1" and EDITOR_KEYS.key_for("escape") == "Esc"
    assert VIEWER_KEYS.key_for("next_lighting") == "L" and VIEWER_KEYS.key_for("change_opacity", -0.1) == "["
    with pytest.raises(KeyError):
        VIEWER_KEYS.key_for("no_such_command")
