"""`vebuild bench single-view`: generated single photos measured as a user would, and whether the
95 % intervals hold the truth as often as they claim."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from vebuild.bench import single_view as sv
from vebuild.bench.single_view_scenes import (
    CCTV_M,
    EXIF_ERROR_REL,
    FULL_FRAME_DIAGONAL_MM,
    HAND_HELD_M,
    LENS_MM,
    PRINCIPAL_POINT_OFF_REL,
    Item,
    scene,
)


def _binomial_bounds(n: int, p: float, tail: float) -> tuple[float, float]:
    """The shares k/n below which and above which a Binomial(n, p) count falls with probability
    ``tail`` each (exact, by summing the distribution)."""
    pmf = [math.exp(math.lgamma(n + 1) - math.lgamma(k + 1) - math.lgamma(n - k + 1) + k * math.log(p)
                    + (n - k) * math.log1p(-p)) for k in range(n + 1)]
    cdf = np.cumsum(pmf)
    lo = int(np.searchsorted(cdf, tail))  # P(X < lo) < tail
    hi = int(np.searchsorted(cdf, 1.0 - tail))  # P(X > hi) ≤ tail
    return lo / n, hi / n


#: Each tail of the coverage test (0.1 %): with honest intervals and independent measurements the
#: test fails once in 500 draws of its seed. The measurements of one photo share its camera's
#: errors, so the true spread is wider (the bench's coverage_95_sigma_by_photo: 1.3 × the
#: binomial's on the full run); the bounds below are the binomial's, stated as such.
TAIL = 0.001


#: The tests that share `quick` run in one pytest-xdist worker (`--dist loadgroup`, pyproject's
#: addopts), so that it is computed once, not once per worker.
SHARES_QUICK = pytest.mark.xdist_group("bench_single_view.quick")


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The quick bench, run as a user runs it: `vebuild bench single-view --quick --json OUT`."""
    from vebuild.cli import main

    out = tmp_path_factory.mktemp("bench") / "single-view.json"
    assert main(["bench", "single-view", "--quick", "--quiet", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert isinstance(doc, dict)
    return doc


@SHARES_QUICK
def test_the_quick_bench_gives_its_figures_with_their_units(quick: dict[str, Any]) -> None:
    # Counts: 60 photos, some 6 measurements each, at least the 300 the goal is stated over.
    assert quick["photos"] == sv.QUICK_PHOTOS
    assert quick["photos_refused"] == 0 and quick["photos_refused_reasons"] == {}
    assert quick["measurements_refused"] == 0
    assert sum(quick[f"{name}s_measured"] for name in sv.KINDS.values()) == quick["measurements"] >= 300
    assert quick["heights_measured"] >= 150 and quick["distances_measured"] >= 150
    # Fractions, not per cent: shares in [0, 1], relative errors and σ as fractions of the truth.
    for key in ("height_coverage_95", "distance_coverage_95", "coverage_95", "height_rel_error_median",
                "distance_rel_error_median", "height_rel_error_p95", "height_rel_sigma_median"):
        assert 0.0 < quick[key] < 1.0, key
    assert quick["click_sigma_px"] == 0.7
    # Every condition the figures are split by is there, and its photos add up.
    for cond, values in sv.CONDITIONS.items():
        assert sum(quick[f"{v}_photos"] for v in values) == quick["photos"], cond
        assert sum(quick[f"{v}_measurements"] for v in values) == quick["measurements"], cond
        for v in values:
            assert quick[f"{v}_photos"] > 0, f"no photo is {v}"
            assert quick[f"{v}_height_coverage_95"] is not None and quick[f"{v}_distance_coverage_95"] is not None
    assert quick["goals"] == sv.GOALS and isinstance(quick["goals_met"], bool)


@SHARES_QUICK
def test_the_intervals_hold_the_truth_as_often_as_they_claim(quick: dict[str, Any]) -> None:
    """Inside the 95 % intervals (two-sided) within the binomial's 0.1 % tails for each count: for
    the quick run's ~180 heights and ~180 distances 89.4–99.4 %, for ~55 of each of the wall, raised
    and plane kinds about 84–100 %, for all ~510 together about 91.8–97.6 %;
    the heights' median error within the goal, 1 %, with a known length in view."""
    for key, count in [*((f"{name}_coverage_95", f"{name}s_measured") for name in sv.KINDS.values()),
                       ("coverage_95", "measurements")]:
        lo, hi = _binomial_bounds(quick[count], 0.95, TAIL)
        assert lo <= quick[key] <= hi, f"{key} {quick[key]:.3f} outside [{lo:.3f}, {hi:.3f}] for {quick[count]}"
    assert quick["height_rel_error_median"] <= 0.01
    # The errors over their σ: 1 in RMS where the σ is honest; the sampling 1σ of an RMS over n
    # normal draws is 1/√(2n) (5 % at 180), 4σ either side.
    for kind in ("height", "distance"):
        n = quick[f"{kind}s_measured"]
        assert abs(quick[f"{kind}_z_rms"] - 1.0) < 4.0 / math.sqrt(2 * n), kind


def _row(truth: float, value: float, sigma: float | None, kind: str = "photo-height") -> dict[str, Any]:
    return {"kind": kind, "what": "x", "truth_m": truth, "value_m": value, "sigma_m": sigma}


def test_coverage_counts_the_truth_inside_value_plus_minus_1_96_sigma() -> None:
    s = scene(np.random.default_rng(1), "room")
    # Heights: 1.9σ and −1.9σ inside, 2.0σ outside, an undetermined σ inside; distances: 0.5σ.
    rows = [_row(1.0, 1.019, 0.01), _row(1.0, 0.981, 0.01), _row(1.0, 1.02, 0.01), _row(2.0, 2.5, None),
            _row(4.0, 4.005, 0.01, "floor-distance")]
    fig = sv.summarise([(s, {"rows": rows}), (s, {"refused": "/x/a.vebuild.json: photo 'p': no axis 2"}),
                        (s, {"refused": "/y/b.vebuild.json: photo 'q': no axis 3"})])
    assert fig["heights_measured"] == 4 and fig["height_coverage_95"] == 0.75
    assert fig["distances_measured"] == 1 and fig["distance_coverage_95"] == 1.0
    assert fig["height_rel_error_median"] == pytest.approx(np.median([0.019, 0.019, 0.02, 0.25]))
    # Alike refusals are counted together, without their file, names and numbers.
    assert fig["photos_refused"] == 2 and fig["photos_refused_reasons"] == {"photo '…': no axis #": 2}
    assert fig["goals_met"] is False  # 5 measurements, not 300


def test_the_scenes_are_what_the_bench_says_they_are() -> None:
    """Lenses 16–85 mm, both settings, hand-held and CCTV heights, principal points off centre up to
    4 % of the width, distortion on some, EXIF on some and a few per cent off; each measurement's
    points in the photo and its truth what they are apart."""
    scenes = [scene(np.random.default_rng([5, i]), ("room", "street")[i % 2]) for i in range(60)]
    lens = [s.lens_mm for s in scenes]
    assert LENS_MM[0] <= min(lens) < 22 and 60 < max(lens) <= LENS_MM[1]
    for s in scenes:
        p = s.photo
        f35 = p.K[0, 0] * FULL_FRAME_DIAGONAL_MM / math.hypot(p.width, p.height)
        assert f35 == pytest.approx(s.lens_mm)
        lo, hi = CCTV_M if s.mount == "cctv" else HAND_HELD_M
        assert lo <= p.C[2] <= hi
        assert PRINCIPAL_POINT_OFF_REL[0] <= s.principal_point_off_rel <= PRINCIPAL_POINT_OFF_REL[1]
        if s.exif and "focal_length_35mm" in s.exif:  # whole mm, off by EXIF_ERROR_REL (1σ): 5σ at most
            assert abs(s.exif["focal_length_35mm"] - s.lens_mm) <= 5 * EXIF_ERROR_REL * s.lens_mm + 0.5
        for it in s.items:
            for X in it.points:
                u, v = s.pixel(X)
                assert 0 < u < p.width and 0 < v < p.height
                assert (p.R @ (X - p.C))[2] > 0  # in front of the camera
            _check_truth(it)
    assert {s.mount for s in scenes} == {"hand-held", "cctv"} and {s.view for s in scenes} == {"frontal", "oblique"}
    assert sum(s.exif is not None for s in scenes) in range(15, 46)
    assert sum(s.photo.k1 != 0 for s in scenes) in range(8, 36)
    assert {s.scale["what"] for s in scenes} == {"a door's height", "a run of kerb"}


def _check_truth(it: Item) -> None:
    P = it.points
    if it.kind == "photo-height":  # the top straight above its foot on the floor
        assert P[0][2] == 0 and np.allclose(P[1][:2], P[0][:2]) and it.truth == pytest.approx(P[1][2])
    elif it.kind == "floor-distance":
        assert P[0][2] == P[1][2] == 0 and it.truth == pytest.approx(np.linalg.norm(P[0] - P[1]))
    elif it.kind == "raised-height":  # an edge point over its floor foot; the top over its foot on that plane
        assert P[0][2] == 0 and np.allclose(P[1][:2], P[0][:2]) and P[2][2] == pytest.approx(P[1][2])
        assert np.allclose(P[3][:2], P[2][:2]) and it.truth == pytest.approx(P[3][2] - P[2][2])
    else:  # wall-length, plane-length: the ends on the wall, every point of it on one vertical plane
        on_floor = P[:2] if it.kind == "wall-length" else P[0::2][:3]
        assert all(X[2] == 0 for X in on_floor)
        assert len({round(float(X[1]), 9) for X in P}) == 1
        assert it.truth == pytest.approx(np.linalg.norm(P[-1] - P[-2]))
