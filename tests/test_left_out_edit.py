"""The segments a calibration left out, as the edit session holds them (vebuild/edit/left_out.py):
which they are, read from the calibration record only while the axis' segments are those it
calibrated; deleting them as one undoable edit, each segment's own 1σ going with it; refused, in
plain words, where there is nothing to delete. The window test (test_left_out_window.py) drives
the same through the screen."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from vebuild.edit.history import EditError
from vebuild.edit.overlay import GREY
from vebuild.edit.session import EditSession
from vebuild.synthetic import CLICK_NOISE_PX, random_scene, write_project
from vebuild.synthetic.clutter import add_clutter


@pytest.fixture
def calibrated(tmp_path: Path) -> tuple[EditSession, dict[str, list[int]], list[float | None]]:
    """Four generated photos, the first with two roof slopes among its x edges and two among its z
    edges, its x segments each with its own 1σ (as `vebuild detect` writes them; every third one
    clicked, null), calibrated in the session. Returns the session, axis → the clutter's indices,
    and the x segments' 1σ as written."""
    rng = np.random.default_rng(4407)
    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp", "3vp"))
    clutter = {"x": add_clutter(photos[0], rng, "slopes", "x", 2), "z": add_clutter(photos[0], rng, "slopes", "z", 2)}
    path = write_project(tmp_path, photos, markers)
    data = json.loads(path.read_text())
    n = len(data["photos"][0]["vanishing_segments"]["x"])
    sigmas: list[float | None] = [None if k % 3 == 2 else 0.5 + 0.05 * k for k in range(n)]
    data["photos"][0]["vanishing_segment_sigmas"] = {"x": sigmas}
    path.write_text(json.dumps(data))
    s = EditSession.open(path)
    with pytest.raises(EditError, match="photo 'p1' has no segments left out by its calibration: nothing to delete"):
        s.delete_left_out("p1")
    s.calibrate()
    return s, clutter, sigmas


#: The chance of a false failure allowed to a bound on the RMS residual of the segments kept.
FALSE_ALARM = 1e-5


def test_the_screen_fits_each_point_to_the_segments_kept(calibrated) -> None:
    """Each axis' point on the screen is fitted to the segments the calibration kept: their RMS
    residual is that of click noise alone (n kept, 2 degrees of freedom taken by the point: n·rms²/σ²
    is χ² with n − 2), below its 1-in-10⁵ bound; fitted to all, the slopes pull it to tens of pixels."""
    s, clutter, _ = calibrated
    for axis, ks in clutter.items():
        vs = s.vanishing("p1", axis)
        n = len(vs.segments) - len(ks)
        assert vs.left_out == frozenset(ks)
        bound = CLICK_NOISE_PX * np.sqrt(chi2.ppf(1 - FALSE_ALARM, n - 2) / n)
        assert vs.rms_px is not None and vs.rms_px < bound, (axis, vs.rms_px, bound)
        assert float(np.sqrt(np.mean(np.asarray(vs.residuals_px) ** 2))) > 10 * bound  # the left-out ones' misfit


def test_deleting_the_left_out_segments_is_one_undoable_edit(calibrated) -> None:
    s, clutter, sigmas = calibrated
    found = s.left_out_segments("p1")
    assert {a: sorted(v) for a, v in found.items()} == clutter
    whys = [why for v in found.values() for why in v.values()]
    assert all(why.endswith("σ off the vanishing point of the other lines") for why in whys), whys
    before = json.loads(json.dumps(s.photo("p1")))
    rev = s.revision
    assert s.delete_left_out("p1") == clutter
    assert s.revision == rev + 1 and s.undo_label.startswith("delete the 4 segments of p1 left out")
    p = s.photo("p1")
    for axis, rows in before["vanishing_segments"].items():
        assert p["vanishing_segments"][axis] == [r for k, r in enumerate(rows) if k not in clutter.get(axis, ())]
    assert p["vanishing_segment_sigmas"] == {"x": [g for k, g in enumerate(sigmas) if k not in clutter["x"]]}
    assert s.left_out_segments("p1") == {}  # the record's indices no longer name these segments
    with pytest.raises(EditError, match="nothing to delete .calibrate first, or its segments have changed since."):
        s.delete_left_out("p1")
    s.undo()
    assert s.photo("p1") == before and {a: sorted(v) for a, v in s.left_out_segments("p1").items()} == clutter


def test_an_axis_changed_since_the_calibration_shows_nothing_left_out(calibrated) -> None:
    """A segment added to x after the calibration: x's recorded indices may name other segments
    now, so none of x is shown left out (none grey); z's still are."""
    s, clutter, _ = calibrated
    s.add_segment("p1", "x", (100.0, 100.0), (300.0, 110.0))
    assert set(s.left_out_segments("p1")) == {"z"}
    lines = {ln.key: ln for ln in s.overlay("p1").of_kind("segment")[0]}
    assert not any(ln.colour == GREY for (axis, _), ln in lines.items() if axis == "x")
    assert all(lines[("z", k)].colour == GREY for k in clutter["z"])
    assert not s.vanishing("p1", "x").left_out and s.vanishing("p1", "z").left_out == frozenset(clutter["z"])
