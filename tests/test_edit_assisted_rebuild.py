"""The example room rebuilt from nothing by clicking, with assistance (tests/test_edit_rebuild.py's
twin): the same photos, markers, distances, floor and box under the same tolerances, but the
vanishing segments come from detection: the markers and the distances first, then Shift+D on
every photo at once (each photo's x chosen through the markers the photos share, the whole turned
so that the first distance from the origin runs along +x) and Q to accept them all; each marker
click snaps to the image, each later sighting is the marker the Marker tool offers, and the
distances are typed from the keyboard (Ctrl+D, Tab, Ctrl+Enter). The clicks and key presses of
both are counted by the same rules and printed beside each other; the goal is one fifth of the
by-hand counts or fewer, for both.

Counting: a mouse press (a click or a drag's press) is one click; a key or chord is one key press;
a typed character is one key press too (file names, marker names, distances); a wheel notch (to
scroll the panel) is one click.
"""

from __future__ import annotations

import numpy as np
import pytest
from edit_driver import Driver, H, W
from edit_scene import (
    BOX_DRAGS,
    DISTANCES,
    FLOOR_DRAGS,
    PHOTOS,
    assert_box_matches,
    assert_cameras_match,
    make_plan,
    photo_file,
)
from edit_user import User, window_noise, x_choice

from vebuild.edit.layout import PANEL_W, STRIP_H, TOOLBAR_H

pytestmark = pytest.mark.usefixtures("xvfb_display")

#: The markers whose names the user types: those the reference distances name.
TYPED_NAMES = frozenset(n for a, b, _ in DISTANCES for n in (a, b))
#: The counts this test reaches up to calibration (clicks, key presses), asserted so that a change
#: that costs the user more shows; docs/assisted-marking.md quotes them.
ASSISTED_COUNTS = (26, 41)


class Count:
    def __init__(self, clicks: int = 0, keys: int = 0) -> None:
        self.clicks = clicks
        self.keys = keys

    def events(self, args) -> None:
        args = list(args)
        for a in args:
            if a in ("click", "mousedown"):
                self.clicks += 1
            elif a == "key":
                self.keys += 1
            elif a == "type":
                self.keys += len(args[-1])


def original_counts(plan, shows: int) -> Count:
    """The clicks and key presses of tests/test_edit_rebuild.py's plan, by the same rules (``shows``:
    the thumbnails clicked to show each photo, as the assisted run clicked them)."""
    c = Count(clicks=shows)
    for pid in PHOTOS:
        c.clicks += 2  # the file field, Add photo
        c.keys += 2 + len(photo_file(plan, pid).relative_to(plan.folder).as_posix())  # ctrl+a, Return, the name
        c.keys += 3 + 1  # the three Segment tools, Esc
        c.clicks += sum(len(s) for s in plan.segments[pid].values())
        for name in plan.markers[pid]:
            c.clicks += 2
            c.keys += 3 + len(name)  # ctrl+a, Return, m and the name
    for a, b, d in DISTANCES:
        c.clicks += 4
        c.keys += 6 + len(a) + len(b) + len(f"{d}")
    c.clicks += 1  # Calibrate
    return c


def test_the_example_rebuilt_with_assistance(tmp_path, xdotool):
    x0, y0, x1, y1 = 0, TOOLBAR_H, W - PANEL_W, H - STRIP_H
    zoom = min((x1 - x0) / 1600, (y1 - y0) / 1200)
    plan = make_plan(tmp_path / "room", noise_px=window_noise(zoom))
    d = Driver(plan.project, xdotool)
    count = Count()
    send = d.send

    def counted(*args):
        count.events(args)
        send(*args)

    d.send = counted  # type: ignore[method-assign]
    try:
        u = User(d)
        s, e = d.session, d.editor
        d.click("Add all photos")  # the project's folder holds just the four photos
        assert s.photo_ids == list(PHOTOS) and e.photo == PHOTOS[0]
        shows = 0
        called: dict[str, str] = {}  # the ground truth's marker names: the names they were given
        # The Marker tool (M) once: it stays on from photo to photo, and its field offers the markers
        # placed in other photos that this photo lacks, in the order of their first placement, then a
        # new name (M1, M2, …). The user follows the offer: a marker seen here is one click; one not
        # seen here is stepped over (]); once only markers new to the project remain, Shift+M offers a
        # new name (where the offer is still an old marker). The reference distances' markers are named
        # by typing (F2, then the name: the click on the photo ends the typing), as the user reads them
        # off the tape's notes. PageDown steps to the next photo.
        d.send("key", "m")
        for pid in PHOTOS:
            if e.photo != pid:
                d.send("key", "Next")
                shows += 1
            assert e.photo == pid
            todo = dict(plan.markers[pid])
            while todo:
                assert e.tool == "marker"
                offered = e.marker_name
                truth = next((t for t, n in called.items() if n == offered), None)
                if truth not in todo:
                    if any(t in called for t in todo):  # a marker placed elsewhere and seen here comes later
                        d.send("key", "bracketright")
                        continue
                    truth = min(todo)  # a marker new to the project
                    if truth in TYPED_NAMES:  # the click on the photo ends the typing
                        d.send("key", "F2")
                        d.send("type", "--delay", "20", truth)
                    elif offered in s.project.marker_names():
                        d.send("key", "shift+m")
                name = e.marker_name
                assert name not in (s.photo(pid).get("marker_observations") or {}), (pid, name)
                d.send(*u.xy(todo.pop(truth)), "click", "1")
                assert name in s.photo(pid)["marker_observations"], (pid, truth, name, s.messages[-1:])
                assert called.setdefault(truth, name) == name
        assert all(called[n] == n for n in TYPED_NAMES)
        # The reference distances, typed: Ctrl+D puts the cursor in the row's first field, Tab goes on,
        # Ctrl+Enter adds the distance and keeps the cursor in the emptied row; Esc leaves it. The first
        # from the origin marker sets which way world x runs. The row lies under Calibrate: no scrolling.
        d.send("key", "ctrl+d")
        for a, b, dist in DISTANCES:
            for text, then in ((a, "Tab"), (b, "Tab"), (f"{dist}", "ctrl+Return")):
                d.send("type", "--delay", "20", text)
                d.send("key", then)
        d.send("key", "Escape")
        assert [(r["a"], r["b"], r["distance"]) for r in s.data["reference_distances"]] == list(DISTANCES)
        d.send("key", "Escape")  # the Select tool (the model's vertices are dragged with it)
        assert e.tool == "select"
        # Shift+D: every photo's edges detected, each photo's x chosen through the markers the
        # photos share, so that the world axes agree; the arrows show what the truth says.
        d.send("key", "shift+d")
        d.frames(2)
        for pid in PHOTOS:
            assert s.__dict__["_x_axis"][pid] == x_choice(plan.camera(pid)[1]), (pid, s.messages[-1])
            assert {p.axis for p in s.proposals[pid]} == {"x", "y", "z"}
        import os

        from PIL import Image

        out = os.environ.get("VEBUILD_PROPOSALS_SHOT")
        if out:  # docs/images/proposals.png: `VEBUILD_PROPOSALS_SHOT=docs/images/proposals.png` (one more click)
            u.show("p3")
            shot = d.screen()
            im = Image.fromarray(shot[:, :, :3]).crop((0, 0, W - PANEL_W, H))
            im.resize((im.width // 2, im.height // 2)).save(out, optimize=True)
        d.send("key", "q")  # every photo's proposals accepted, one undoable edit
        for pid in PHOTOS:
            assert not s.proposals.get(pid) and all(len(s.vanishing(pid, a).segments) >= 2 for a in "xyz")
        d.click("Calibrate")
        d.frames(3)
        assert e.calibration_error is None, e.calibration_error
        assert_cameras_match(plan, s.cameras)
        before = Count()
        before.clicks, before.keys = count.clicks, count.keys

        # The floor and the box as in the twin (their drags are the same clicks in both).
        rng = np.random.default_rng(17)
        d.click("tab:Model")
        u.choose("kind", "quad")
        u.type_into("new name", "floor")
        d.click("Add")
        d.send(*u.xy((800, 600)), "click", "1")
        for pid, h in FLOOR_DRAGS:
            u.show(pid)
            u.drag("floor", h, plan.pixel(pid, plan.vertex("floor", h), rng))
        u.choose("kind", "box")
        u.choose("parent", "floor")
        u.type_into("new name", "box")
        d.click("Add")
        u.show("p3")
        d.send(*u.xy(plan.pixel("p3", plan.vertex("box", "v0"), rng)), "click", "1")
        for pid, h in BOX_DRAGS:
            u.show(pid)
            u.drag("box", h, plan.pixel(pid, plan.vertex("box", h), rng))
            assert e.drag_problem is None, e.drag_problem
        assert_box_matches(plan, s.model)
        d.send("key", "ctrl+s")
        assert not s.dirty
        orig = original_counts(plan, shows)
        strokes = sum(len(v) for segs in plan.segments.values() for v in segs.values())
        model_clicks, model_keys = count.clicks - before.clicks, count.keys - before.keys  # the same in both
        print(f"\nmarking up to calibration: by hand {orig.clicks} clicks and {orig.keys} key presses "
              f"({strokes} segment strokes); assisted {before.clicks} clicks and {before.keys} key presses"
              f"\nthe whole rebuild (with the floor and the box, the same in both): by hand "
              f"{orig.clicks + model_clicks} clicks and {orig.keys + model_keys} key presses; assisted "
              f"{count.clicks} clicks and {count.keys} key presses")
        print(f"one fifth of by hand: {orig.clicks / 5:.1f} clicks, {orig.keys / 5:.1f} key presses")
        assert (before.clicks, before.keys) == ASSISTED_COUNTS
        # Every segment stroke is gone; the Segment tools' keys become Shift+D and Q; adding the
        # photos is one click; a marker's later sightings cost no click but their own.
        assert before.clicks < orig.clicks - strokes
        assert before.keys < orig.keys / 2
        # The goal: at most one fifth of the by-hand clicks and key presses.
        assert before.clicks <= orig.clicks / 5 and before.keys <= orig.keys / 5
    finally:
        d.close()
