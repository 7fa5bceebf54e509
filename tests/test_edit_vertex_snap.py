"""A dragged vertex released near an image corner snaps to it (the corner refined to a fraction
of a pixel, as a marker's click is), said in the status line; with Alt held it is released exactly
where the mouse is. Real input under a virtual X server, on the example room calibrated and solved."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from edit_driver import Driver

from vebuild.edit.snap import SNAP_RADIUS_PX
from vebuild.edit.suggest import pin_corner

pytestmark = pytest.mark.usefixtures("xvfb_display")

#: The snapped release lands on the corner the snapper finds at the corner itself, to this (the
#: Förstner refinement from two nearby starts agrees to a few hundredths of a pixel on a rendered
#: corner; a tenth of a pixel allows for its iteration).
SAME_CORNER_PX = 0.1
#: Where to look for an image corner to drag the new box's corner onto.
CORNER_SEARCH_PX = 80.0


@pytest.fixture
def room(solved_room, tmp_path):
    shutil.copytree(solved_room.parent, tmp_path / "room")
    return tmp_path / "room" / solved_room.name


def _crate_and_corner(s, photo):
    """A new box standing on the floor (its bottom corner v0 free to slide over it), and the image
    corner nearest that vertex's projection (the snapper's refined corner)."""
    node = s.add_primitive("box", name="crate", parent="floor", at=(photo, (800.0, 1000.0)))
    uv = next(p for n, k, p, _ in s.handles(photo) if (n, k) == (node, "v0"))
    near = pin_corner(s.photo_pixels(photo), uv, search_px=CORNER_SEARCH_PX)
    assert near is not None, f"no image corner within {CORNER_SEARCH_PX} px of {uv} in {photo}"
    at, snap = s.snap_vertex(photo, near)
    assert snap is not None and snap.kind == "corner"
    return node, "v0", uv, at


@pytest.mark.parametrize("alt", [False, True])
def test_a_vertex_released_near_an_image_corner_snaps_to_it_unless_alt(room, xdotool, alt):
    d = Driver(room, xdotool)
    try:
        e, s = d.editor, d.session
        photo = e.photo
        node, handle, uv, corner = _crate_and_corner(s, photo)
        e.select(node)
        d.frames(2)
        start = e.image_to_window(photo, uv)
        # Released at the window pixel nearest the corner: off it by up to half a window pixel each
        # way (a pixel of the photo or so at this zoom), within the snapping radius.
        goal = e.image_to_window(photo, corner)
        release = (round(goal[0]), round(goal[1]))
        at = e.window_to_image(*release)
        assert 0.05 < np.hypot(*np.subtract(at, corner)) < SNAP_RADIUS_PX
        # The hand goes out and back (a drag of a pixel or two is a click, not a drag).
        moves = []
        out_and_back = ((start[0] + 12, start[1] + 8), (start[0] + 24, start[1] + 16), (start[0] + 10, start[1] + 6))
        for p in (*out_and_back, release):
            moves += [*d.move_to(*p), "sleep", "0.08"]
        keys = ["keydown", "alt"] if alt else []
        d.send(*d.move_to(*start), "sleep", "0.05", "mousedown", "1", "sleep", "0.05", *moves, *keys,
               "sleep", "0.05", "mouseup", "1", *(["keyup", "alt"] if alt else []))
        d.frames(2)
        assert not s.dragging and (s.undo_label or "").startswith(f"drag {node}:{handle}"), s.messages[-3:]
        pin = next(p for p in s.data["model"]["pins"] if (p["photo"], p["node"], p["handle"]) == (photo, node, handle))
        if alt:
            assert pin["uv"] == pytest.approx(at, abs=1e-6)
        else:
            assert np.hypot(*np.subtract(pin["uv"], corner)) < SAME_CORNER_PX, (pin["uv"], corner)
            assert any("image corner" in m for m in s.messages[-3:]), s.messages[-3:]
    finally:
        d.close()
