"""The modelling screen's line proposals record a photo whose x axis they could not choose
(`x_axis_unresolved`, scenes/FORMAT.md) exactly as `vebuild detect` does: the example room, p3
keeping two of its markers (too few shared with the other photos to tell its x). Shift+D says so
for p3, Q writes the record on p3 alone, and the calibration leaves p3 out instead of placing it
with its axes turned; x chosen (D again) and accepted onto a photo without segments removes it, and
so does deleting the last segment. D on p3 alone, the other photos' segments accepted, says and
records it too. In the window, by real keys: Shift+D says p3's x was not chosen,
Enter writes the record, and the photo's note says so for as long as it holds."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from stripped_room import stripped_room

from vebuild.actions.detect import UNRESOLVED
from vebuild.edit.assist import SCREEN_DETECTION
from vebuild.edit.session import EditSession

#: The start of the photo's note while its record holds.
NOTE = "x axis not chosen when this photo's segments were detected"


def _records(s: EditSession) -> dict[str, str]:
    return {p["id"]: p[UNRESOLVED] for p in s.data["photos"] if UNRESOLVED in p}


def test_the_screens_proposals_record_an_x_axis_not_chosen_and_calibration_leaves_the_photo_out(tmp_path: Path):
    s = EditSession.open(stripped_room(tmp_path / "room", "p3", 2), autosave=False)
    s.detect_everywhere()
    said = s.messages[-1]
    p3 = said[said.index("; p3: "):said.index("; p4: ")]
    assert "x not chosen" in p3 and "press D on this photo" in p3, said
    assert said.count("x not chosen") == 1, said
    assert _records(s) == {}  # proposals are no part of the project

    s.accept_everywhere()
    records = _records(s)
    assert list(records) == ["p3"], records
    assert any(NOTE in n for n in s.overlay("p3").notes) and not any(NOTE in n for n in s.overlay("p1").notes)
    assert records["p3"].startswith(f"{SCREEN_DETECTION} could not choose its x axis and kept 'right': "), records
    s.calibrate()
    cal = s.data["calibration"]
    assert "p3" in cal["left_out"] and "p3" not in cal["cameras"], cal.get("left_out")
    assert "could not choose its x axis" in cal["left_out"]["p3"]["reason"]
    assert sorted(cal["cameras"]) == ["p1", "p2", "p4", "p5", "p6"]

    s.undo()  # the calibration
    s.undo()  # Q: the record goes with the segments it was about
    assert _records(s) == {} and not s.photo("p3").get("vanishing_segments")

    # One proposal accepted with x not chosen records it; deleting that last segment removes it,
    # as `vebuild detect --replace` does.
    s.detect_everywhere()
    s.accept_proposal("p3", 0)
    assert list(_records(s)) == ["p3"]
    axis = next(a for a, rows in s.photo("p3")["vanishing_segments"].items() if rows)
    s.delete_segment("p3", axis, 0)
    assert _records(s) == {}

    # D again chooses x by hand ('left': p3's 'right' is the truth's -x): no record, and none said.
    s.detect_lines("p3", "left")
    assert "x not chosen" not in s.messages[-1], s.messages[-1]
    s.accept_all("p3")
    assert _records(s) == {}
    s.calibrate()
    assert "could not choose" not in str(s.data["calibration"].get("left_out") or {})


def test_d_on_one_photo_records_it_too_and_a_chosen_x_keeps_the_record_while_older_segments_stay(tmp_path: Path):
    """D on p3 alone, the other photos' segments accepted (their x shown by them): p3's x is not
    chosen, said and recorded. As `vebuild detect` without --replace: segments kept from a detection
    whose x was not chosen are still directed by it, so a chosen x added beside them leaves the record."""
    s = EditSession.open(stripped_room(tmp_path / "room", "p3", 2), autosave=False)
    s.detect_everywhere()
    for pid in s.photo_ids:
        if pid != "p3":
            s.accept_all(pid)
    s.save()
    s = EditSession.open(s.project.path, autosave=False)  # D's first press on p3: x by the markers
    s.detect_lines("p3")
    assert "with x right" in s.messages[-1] and "x not chosen" in s.messages[-1], s.messages[-1]
    s.accept_all("p3")
    assert list(_records(s)) == ["p3"]
    s.detect_lines("p3", "left")
    assert "x not chosen" not in s.messages[-1]
    s.accept_all("p3")
    assert list(_records(s)) == ["p3"]


@pytest.mark.usefixtures("xvfb_display")
def test_in_the_window_shift_d_says_x_was_not_chosen_and_enter_records_it(tmp_path: Path, xdotool):
    from edit_driver import Driver

    d = Driver(stripped_room(tmp_path / "room", "p3", 2), xdotool)
    try:
        e, s = d.editor, d.session
        if e.photo != "p3":
            d.click("photo:p3")
        assert e.photo == "p3"
        d.send("key", "shift+d")  # every photo: p3's x is the one the markers do not tell
        shown = [text for text, _ in e.shown_messages()]
        assert s.proposals.get("p3") and any(t.startswith("detected") and re.search(r"p3: \d+ \(x not chosen", t)
                                             for t in shown), shown
        d.send("key", "Return")
        assert list(_records(s)) == ["p3"]
        d.frames(2)
        assert any(t.startswith(NOTE) for t, _ in e.shown_messages()), e.shown_messages()
        d.send("key", "ctrl+z")
        assert _records(s) == {}
        d.frames(2)
        assert not any(t.startswith(NOTE) for t, _ in e.shown_messages())
    finally:
        d.close()
