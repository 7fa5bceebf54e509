"""The Marker tool's offer (vebuild/edit/entry_keys.py): in a photo that lacks markers placed in
other photos, the toolbar's field offers them in the order of their first placement, then a new
name; ] and [ step through them, Shift+M offers a new name, a typed name stays; F2 types a name and a
click on the photo ends the typing; Ctrl+D, Tab and Ctrl+Enter type a reference distance."""

from __future__ import annotations

import shutil

import glfw
import pytest

from vebuild.resources import example_project_dir

#: The example room's markers in the order of their first placement (its file's list), and those
#: its photo p4 lacks, in that order.
P4_LACKS = ["O", "X5", "C1", "C2", "B1", "B2", "D1"]


@pytest.fixture
def example(tmp_path):
    folder = tmp_path / "room"
    shutil.copytree(example_project_dir(), folder)
    return folder / "room.vebuild.json"


@pytest.fixture
def screen(example):
    from vebuild.edit.screen import Editor
    from vebuild.edit.session import EditSession
    from vebuild.gl.context import headless_context
    from vebuild.gl.surface import OffscreenSurface

    s = EditSession.open(example, recover=False)
    surface = OffscreenSurface(headless_context(), 1200, 780)
    e = Editor(s, surface)
    for _ in range(len(s.photo_ids) + 3):
        e.draw()
    yield s, e
    e.close()
    surface.release()


def _key(e, key: int, mods: int = 0) -> None:
    e.on_key(key, glfw.PRESS, mods)
    e.on_key(key, glfw.RELEASE, mods)
    e.draw()


def _click(e, uv=None) -> None:
    """A click in the photo shown, at uv or (None) at a spot far from its markers."""
    if uv is None:
        obs = list((e.session.photo(e.photo).get("marker_observations") or {}).values())
        uv = next((u, v) for v in range(100, 1200, 150) for u in range(100, 1600, 150)
                  if all(abs(u - a) + abs(v - b) > 100 for a, b in obs))
    x, y = e.image_to_window(None, uv)
    e.on_cursor(x, y)
    e.on_button(glfw.MOUSE_BUTTON_LEFT, glfw.PRESS, 0)
    e.on_button(glfw.MOUSE_BUTTON_LEFT, glfw.RELEASE, 0)
    e.draw()


def test_the_offer_follows_the_order_of_first_placement_and_the_keys_step_it(screen):
    s, e = screen
    assert s.project.marker_names()[:3] == ["O", "X5", "Y4"]
    e.set_photo("p4")
    _key(e, glfw.KEY_M)
    assert e.tool == "marker" and e.marker_offers() == [*P4_LACKS, "M1"]
    assert e.marker_name == "O"
    _key(e, glfw.KEY_RIGHT_BRACKET)
    assert e.marker_name == "X5"
    _key(e, glfw.KEY_LEFT_BRACKET)
    _key(e, glfw.KEY_LEFT_BRACKET)  # round, through the new name
    assert e.marker_name == "M1"
    _key(e, glfw.KEY_RIGHT_BRACKET)
    assert e.marker_name == "O"
    _key(e, glfw.KEY_M, glfw.MOD_SHIFT)
    assert e.marker_name == "M1" and e.tool == "marker"
    # A click places the marker offered, and the offer moves on to the next one after it that the
    # photo lacks (C1 is stepped over here with ], as a user who does not see it would).
    _key(e, glfw.KEY_M)
    _key(e, glfw.KEY_RIGHT_BRACKET)
    assert e.marker_name == "X5"
    _click(e)
    assert "X5" in s.photo("p4")["marker_observations"] and e.marker_name == "C1"
    assert any(m.startswith("marker X5 at") and m.endswith("; next: C1") for m in s.messages)
    _key(e, glfw.KEY_RIGHT_BRACKET)
    _click(e)
    assert "C2" in s.photo("p4")["marker_observations"] and e.marker_name == "B1"
    # After the last marker the photo lacks, a new name; after a new marker, the next new name.
    for name in ("B1", "B2", "D1"):
        assert e.marker_name == name
        _click(e)
    assert e.marker_name == "M1"
    _click(e)
    assert "M1" in s.photo("p4")["marker_observations"] and e.marker_name == "M2"
    # Another photo: its own first missing marker (p3 lacks Y4 first).
    e.set_photo("p3")
    assert e.marker_name == "Y4"


def test_a_typed_or_picked_name_stays_and_an_offer_placed_by_other_means_moves_on(screen):
    s, e = screen
    e.set_photo("p4")
    _key(e, glfw.KEY_M)
    assert e.marker_name == "O"
    s.place_marker("p4", "O", (300.0, 300.0))  # as an accepted proposal would
    e.draw()
    assert e.marker_name == "X5"
    s.undo()
    e.draw()
    assert e.marker_name == "X5"  # still lacking here: the offer stays
    e.pick_marker("D1")
    e.set_photo("p1")
    assert e.marker_name == "D1"  # picked: it stays until a click places it
    _key(e, glfw.KEY_M)
    assert e.marker_name == "D1"
    _click(e)
    assert "D1" in s.photo("p1")["marker_observations"]
    assert e.marker_name == "M1"  # p1 lacked nothing after D1 (B1, B2 come before it): a new name


@pytest.fixture
def bare(tmp_path):
    """A new project of two of the example room's photos: no marks."""
    from vebuild.cli import main

    folder = tmp_path / "bare"
    (folder / "photos").mkdir(parents=True)
    for name in ("p1.jpg", "p3.jpg"):
        shutil.copy(example_project_dir() / "photos" / name, folder / "photos" / name)
    path = folder / "bare.vebuild.json"
    assert main(["new", str(path), *sorted(str(p) for p in (folder / "photos").glob("*.jpg"))]) == 0
    return path


@pytest.mark.usefixtures("xvfb_display")
def test_f2_types_a_name_a_click_ends_it_and_the_distance_row_is_typed(bare, xdotool):
    from edit_driver import Driver

    d = Driver(bare, xdotool)
    try:
        e, s = d.editor, d.session
        d.send("key", "m")
        assert e.photo == "p1" and e.marker_name == "M1"
        d.send("key", "F2")
        d.send("type", "--delay", "20", "door")
        d.send(*d.move_to(*e.image_to_window(None, (800.0, 600.0))), "click", "1")
        assert "door" in s.photo("p1")["marker_observations"] and e.marker_name == "M1"
        # The click ended the typing: the next key is the screen's (the next photo), not the field's.
        d.send("key", "Next")
        assert e.photo == "p3" and e.marker_name == "door"
        d.send(*d.move_to(*e.image_to_window(None, (700.0, 600.0))), "click", "1")
        d.send(*d.move_to(*e.image_to_window(None, (900.0, 500.0))), "click", "1")
        assert set(s.photo("p3")["marker_observations"]) == {"door", "M1"}
        # Ctrl+D, Tab, Ctrl+Enter: a mistake is said and the row keeps what was typed.
        d.send("key", "ctrl+d")
        for text, then in (("door", "Tab"), ("door", "Tab"), ("2.5", "ctrl+Return")):
            d.send("type", "--delay", "20", text)
            d.send("key", then)
        assert not s.data["reference_distances"] and "two different ends" in s.messages[-1]
        assert e.panels.dist_a == "door" and e.panels.distance_row_active
        d.send("key", "Tab")
        d.send("type", "--delay", "20", "M1")
        d.send("key", "ctrl+Return")
        assert [(r["a"], r["b"], r["distance"]) for r in s.data["reference_distances"]] == [("door", "M1", 2.5)]
        # The row is emptied and keeps the cursor for the next distance; Esc leaves it.
        assert (e.panels.dist_a, e.panels.dist_b) == ("", "") and e.panels.distance_row_active
        d.send("key", "Escape")
        assert not e.panels.distance_row_active and e.tool == "marker"
        d.send("key", "Escape")
        assert e.tool == "select"
    finally:
        d.close()
