"""Assisted marking in the modelling screen's window, with real input under a virtual X server: a
segment stroke near a photo edge snaps to it (shown before release, said in the status line), Alt
places exactly, D shows line proposals dashed, a click with the Select tool accepts one, a click
with the Delete tool rejects one, Enter accepts the rest, Ctrl+Z undoes each accept."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from edit_driver import Driver

from vebuild.camera import project
from vebuild.cli import main
from vebuild.edit.snap import SNAP_RADIUS_PX
from vebuild.resources import example_project_dir

pytestmark = pytest.mark.usefixtures("xvfb_display")

#: How near the true edge a snapped segment's ends land in the example's rendered JPEG. Measured
#: over 400 segments drawn 1.5 px off this edge, their ends moved at random (±0.5 px across, ±1 px
#: along): median 0.21 px, 95th percentile 0.42, 99th 0.50 (the render's anti-aliasing and the
#: JPEG's blocks move the edge points together, so the fit's ends err more than its 111 points
#: suggest); the drag below, its ends on whole window pixels, lands at 0.55 px with the window
#: stack of 2026-12-06 (0.5 px had passed before). Half the 1.5 px it is drawn off: a segment
#: left where it was drawn fails.
EDGE_TOL_PX = 0.75


@pytest.fixture
def bare(tmp_path):
    folder = tmp_path / "bare"
    shutil.copytree(example_project_dir() / "photos", folder / "photos")
    path = folder / "bare.vebuild.json"
    assert main(["new", str(path), str(folder / "photos" / "p3.jpg")]) == 0
    return path


def test_snapping_proposals_accept_reject_and_undo(bare, xdotool):
    d = Driver(bare, xdotool)
    try:
        e, s = d.editor, d.session
        pid = e.photo
        # A true vertical edge of the room (its ends projected by the ground truth's camera), drawn
        # 1.5 px off it by hand: snapped back onto it.
        t = json.loads((example_project_dir() / "ground_truth.json").read_text())["photos"][pid]
        K, R, C = (np.asarray(t[k], float) for k in ("K", "R", "C"))
        ends = [(project(K, R, C, np.asarray(g["X1"])), project(K, R, C, np.asarray(g["X2"])))
                for g in t["segments"]["z"]]
        a, b = max(ends, key=lambda ab: float(np.linalg.norm(ab[1] - ab[0])))
        n = np.array([-(b - a)[1], (b - a)[0]]) / np.linalg.norm(b - a)
        pa, pb = a + 0.25 * (b - a) + 1.5 * n, a + 0.45 * (b - a) + 1.5 * n
        e.set_view(2.0, tuple(0.5 * (pa + pb)))
        wa, wb = (tuple(float(round(v)) for v in e.image_to_window(None, q)) for q in (pa, pb))  # whole pixels
        d.send("key", "3", *d.move_to(*wa), "mousedown", "1", "sleep", "0.05", *d.move_to(*wb), "sleep", "0.05")
        shown = e.snap_preview()  # before release: where it will land
        assert shown is not None and shown[0] == "segment" and shown[2] is not None
        d.send("mouseup", "1")
        seg = np.asarray(s.photo(pid)["vanishing_segments"]["z"][0])
        line_d = [abs(float((q - a) @ n)) for q in (seg[:2], seg[2:])]
        assert max(line_d) < EDGE_TOL_PX
        assert np.linalg.norm(seg[:2] - np.asarray(e.window_to_image(*wa))) <= SNAP_RADIUS_PX
        assert s.segment_sigma(pid, "z", 0) is not None
        assert any("snapped to the image line" in m for m in s.messages[-3:])
        # Alt held: exactly as drawn.
        d.send("keydown", "alt", *d.move_to(*wa), "mousedown", "1", "sleep", "0.05", *d.move_to(*wb), "sleep", "0.05",
               "mouseup", "1", "keyup", "alt")
        seg2 = s.photo(pid)["vanishing_segments"]["z"][1]
        np.testing.assert_allclose(seg2, [*e.window_to_image(*wa), *e.window_to_image(*wb)], atol=1e-9)
        assert s.segment_sigma(pid, "z", 1) is None
        d.send("key", "Escape", "key", "Home")
        before = json.dumps(s.data, sort_keys=True)

        # D: proposals shown dashed; a click accepts one, the Delete tool rejects one, Enter the rest.
        d.send("key", "d")
        props = list(s.proposals[pid])
        assert props and {p.axis for p in props} == {"x", "y", "z"}
        first = props[0]
        mid = 0.5 * (np.asarray(first.segment[:2]) + np.asarray(first.segment[2:]))
        d.send(*d.move_to(*e.image_to_window(None, mid)), "click", "1")
        assert first not in s.proposals[pid] and len(s.proposals[pid]) == len(props) - 1
        rows = s.photo(pid)["vanishing_segments"][first.axis]
        assert rows[-1] == pytest.approx(list(first.points or first.segment), abs=1e-3)
        sig = s.photo(pid)["vanishing_segment_sigmas"][first.axis][-1]
        assert sig == pytest.approx(first.sigma_px, abs=1e-3)
        # One whose middle no other proposal passes near (the Delete tool takes the one under the cursor).
        second = next(p for p in s.proposals[pid] if _alone(p, s.proposals[pid]))
        mid = 0.5 * (np.asarray(second.segment[:2]) + np.asarray(second.segment[2:]))
        d.send("key", "Delete", *d.move_to(*e.image_to_window(None, mid)), "click", "1", "key", "Escape")
        assert second not in s.proposals[pid] and len(s.proposals[pid]) == len(props) - 2
        d.send("key", "Return")
        assert not s.proposals[pid]
        total = sum(len(v) for v in s.photo(pid)["vanishing_segments"].values())
        assert total == 2 + len(props) - 1
        # Ctrl+Z undoes the Enter (one edit), then the one click's accept.
        d.send("key", "ctrl+z")
        assert sum(len(v) for v in s.photo(pid)["vanishing_segments"].values()) == 3
        d.send("key", "ctrl+z")
        assert json.dumps(s.data, sort_keys=True) == before
    finally:
        d.close()


def _alone(p, proposals, margin_px: float = 25.0) -> bool:
    """No other proposal passes within margin_px (image pixels) of p's middle."""
    mid = 0.5 * (np.asarray(p.segment[:2]) + np.asarray(p.segment[2:]))
    for q in proposals:
        if q is p:
            continue
        a, b = np.asarray(q.segment[:2]), np.asarray(q.segment[2:])
        t = float(np.clip((mid - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0))
        if np.linalg.norm(a + t * (b - a) - mid) < margin_px:
            return False
    return True

