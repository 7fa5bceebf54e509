"""Shift+D, Q and W without a window: detection on every photo with each photo's x chosen through
the markers the photos share (the world axes then agree with the truth's, the first reference
distance from the origin along +x), every photo's proposals accepted by one undoable edit, and
markers suggested in every calibrated photo (refused, with a reason, before calibration)."""

from __future__ import annotations

import pytest
from edit_scene import DISTANCES, PHOTOS, make_plan, photo_file
from edit_user import x_choice

from vebuild.edit.history import EditError
from vebuild.edit.session import EditSession


@pytest.fixture(scope="module")
def marked(tmp_path_factory):
    plan = make_plan(tmp_path_factory.mktemp("everywhere") / "room", noise_px=0.5)
    s = EditSession.open(plan.project, autosave=False)
    for pid in PHOTOS:
        s.add_photo(photo_file(plan, pid))
        for name, uv in plan.markers[pid].items():
            s.place_marker(pid, name, uv)
    for a, b, d in DISTANCES:
        s.add_distance(a, b, d)
    return plan, s


def test_detect_everywhere_chooses_each_photos_x_as_the_truth_has_it_and_q_accepts_all_in_one_edit(marked):
    plan, s = marked
    with pytest.raises(EditError, match="two or more photos are calibrated"):
        s.suggest_markers_everywhere()
    total = s.detect_everywhere()
    assert total == sum(len(s.proposals[p]) for p in PHOTOS) > 0
    for pid in PHOTOS:
        assert s.__dict__["_x_axis"][pid] == x_choice(plan.camera(pid)[1]), (pid, s.messages[-1])
        assert {p.axis for p in s.proposals[pid]} == {"x", "y", "z"}
    assert "O→X5 runs along +x" in s.messages[-1]
    # D on a photo after Shift+D turns that photo's x to the next choice, from the chosen one.
    first = s.__dict__["_x_axis"]["p3"]
    s.detect_lines("p3")
    assert s.__dict__["_x_axis"]["p3"] != first
    s.detect_lines("p3", first)
    assert s.accept_everywhere() == total
    assert not any(s.proposals.get(p) for p in PHOTOS)
    assert all(len(s.vanishing(p, a).segments) >= 2 for p in PHOTOS for a in "xyz")
    s.undo()  # one edit: every photo's accepted segments go together
    assert all(len(s.vanishing(p, a).segments) == 0 for p in PHOTOS for a in "xyz")
    s.redo()
    assert all(len(s.vanishing(p, a).segments) >= 2 for p in PHOTOS for a in "xyz")
    assert s.accept_everywhere() == 0 and "no proposals to accept" in s.messages[-1]


def test_w_suggests_in_every_calibrated_photo(marked):
    plan, s = marked
    if not all(len(s.vanishing(p, "z").segments) for p in PHOTOS):
        s.detect_everywhere()
        s.accept_everywhere()
    s.calibrate()
    # Every marker is already placed wherever the plan sees it: W proposes nothing wrong, and says so.
    n = s.suggest_markers_everywhere()
    assert n == sum(len(s.proposals.get(p, [])) for p in PHOTOS)
    assert all(p.kind == "marker" and p.name not in (s.photo(pid).get("marker_observations") or {})
               for pid in PHOTOS for p in s.proposals.get(pid, []))
    assert s.messages[-1].startswith(f"suggested {n} markers: ")
