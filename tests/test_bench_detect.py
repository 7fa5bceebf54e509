"""``vebuild bench detect`` run itself, on six small generated photos (640 × 480, cast afresh in a
temporary cache): its figures' structure, and bounds from what the generator puts in the photos."""

from __future__ import annotations

import numpy as np
import pytest

from vebuild.bench import detect as bench
from vebuild.bench.detect_photos import KINDS

N, WIDTH, HEIGHT = 6, 640, 480
#: The photos' kinds: the generator's cycle from its start (3vp, 3vp, 2vp, 3vp, corridor, 2vp).
PHOTO_KINDS = KINDS[:N]
#: A shown direction's calibrated error, degrees: the bench's own 3° criterion. The generator's
#: worst photo (blur σ 1.4 px, noise 4 grey levels, JPEG 80, barrel lens) fits each edge to a few
#: tenths of a pixel over ≥ 2 % of the diagonal (≥ 16 px here), some 1–2°; edges along a
#: direction average that down.
SHOWN_TOL_DEG = 3.0
#: The reported 95 % interval of f: of the photos with a focal estimate, at most this share may
#: miss the truth (a claimed 5 %, over a handful of photos: one miss of up to four).
MAX_FOCAL_MISSES = 1
#: The median relative focal error: 0.18 % measured over the bench's 100 photos at 4000 px; an
#: edge's direction error grows as 1/length, so 6.25 × that at 640 px, with 3× room over six photos.
FOCAL_MEDIAN_MAX = 0.0018 * (4000 / WIDTH) * 3


#: The tests that share `figures` run in one pytest-xdist worker (`--dist loadgroup`, pyproject's
#: addopts), so that it is computed once, not once per worker.
SHARES_FIGURES = pytest.mark.xdist_group("bench_detect.figures")


@pytest.fixture(scope="module")
def figures(tmp_path_factory):
    mp = pytest.MonkeyPatch()
    mp.setenv("VEBUILD_CACHE", str(tmp_path_factory.mktemp("cache")))
    try:
        yield bench.run(progress=False, n=N, width=WIDTH, height=HEIGHT, room=False)
    finally:
        mp.undo()


@SHARES_FIGURES
def test_the_figures_have_their_structure(figures):
    f = figures
    assert (f["photos"], f["width"], f["height"]) == (N, WIDTH, HEIGHT)
    assert [r["kind"] for r in f["per_photo"]] == list(PHOTO_KINDS)
    assert set(bench.GOALS) <= set(f)
    assert "room_photos" not in f  # room=False: the example's photos are not run
    for suffix in ("", "_calibrated", "_all"):
        shares = [f[f"vp_within_{t}deg_share{suffix}"] for t in (1, 3, 5)]
        assert all(0.0 <= s <= 1.0 for s in shares) and shares == sorted(shares), (suffix, shares)
    # The best estimate is the calibrated rotation where there is one: never fewer within 3°.
    assert f["vp_within_3deg_share"] >= f["vp_within_3deg_share_calibrated"]
    for r in f["per_photo"]:
        if r["detected_mode"] is not None:
            assert r["best_axis_err"] == r["detected_axis_err"]
    shown = np.array([r["shown"] for r in f["per_photo"]], bool)
    assert f["vps_shown"] == int(shown.sum()) <= 3 * N
    assert 0 <= f["no_result"] <= N and f["focal_photos"] <= N
    assert all(r["detect_ms"] > 0 and r["message"] for r in f["per_photo"])
    assert f["detect_ms_per_photo"] <= f["detect_ms_max"]
    text = bench.table(f)
    assert "vp_within_3deg_share_all" in text and "vps_shown" in text and "vp_within_3deg_share_calibrated" in text


@SHARES_FIGURES
def test_every_shown_direction_within_the_bound_and_the_focal_intervals_honest(figures):
    f = figures
    rows = f["per_photo"]
    # Every photo of these kinds shows two directions at least (its room's floor, walls, rails).
    assert all(sum(r["shown"]) >= 2 for r in rows), [r["shown"] for r in rows]
    for r in rows:
        err = np.array(r["detected_axis_err"])[np.array(r["shown"], bool)]
        assert np.all(err <= SHOWN_TOL_DEG), (r["photo"], r["kind"], r["detected_axis_err"], r["message"])
    assert f["vp_within_3deg_share"] == 1.0
    covered = [r["detected_covered"] for r in rows if r["detected_mode"] in ("3vp", "2vp")]
    assert len(covered) == f["focal_photos"] >= 1
    assert sum(not c for c in covered) <= MAX_FOCAL_MISSES
    assert 0.0 < f["focal_rel_error_median"] <= FOCAL_MEDIAN_MAX


def _row(shown: list[bool], calibrated: list[float] | None, detector: list[float]) -> dict:
    """A per-photo row as the bench makes it: calibrated (its errors) or not (None)."""
    return {"shown": shown, "detected_axis_err": calibrated or [180.0] * 3, "detector_axis_err": detector,
            "best_axis_err": calibrated or detector, "detected_mode": "3vp" if calibrated else None,
            "detected_focal_err": 0.01 if calibrated else None, "detected_covered": True if calibrated else None,
            "grouping_axis_err": detector, "detect_ms": 100.0}


def test_a_photo_not_calibrated_is_scored_by_the_detectors_own_direction_and_counted_apart():
    rows = [_row([True, True, True], [0.5, 2.0, 4.0], [0.4, 2.5, 180.0]),  # calibrated: its rotation counts
            _row([False, True, False], None, [180.0, 0.7, 180.0]),        # one direction shown, found
            _row([True, False, True], None, [180.0, 180.0, 2.5])]          # two shown, one found
    f = bench._summary(rows)
    assert f["vps_shown"] == 6
    assert f["vp_within_1deg_share"] == pytest.approx(2 / 6)   # 0.5 (calibrated), 0.7 (detector)
    assert f["vp_within_3deg_share"] == pytest.approx(4 / 6)   # and 2.0 (calibrated), 2.5 (detector)
    assert f["vp_within_5deg_share"] == pytest.approx(5 / 6)
    assert f["vp_within_3deg_share_calibrated"] == pytest.approx(2 / 6)  # the calibrated rotations alone
    assert f["vps_from_the_detector_alone"] == 2
    assert f["vp_within_3deg_share_all"] == pytest.approx(4 / 9)
    assert f["vp_within_3deg_share_all_calibrated"] == pytest.approx(2 / 9)
    assert f["no_result"] == 2 and f["focal_photos"] == 1
