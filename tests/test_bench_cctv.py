"""`vebuild bench cctv`: generated CCTV stills calibrated and measured as a user would, and the
video round trip compared with the generator's frames."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from vebuild.bench import BENCHES
from vebuild.bench import cctv as bench
from vebuild.bench import cctv_cases as cc
from vebuild.synthetic.cctv import cctv_case
from vebuild.synthetic.cctv_video import encode, frames, place_frames


def test_round_trip_counts_exact_frames_by_the_generators_digests(tmp_path) -> None:
    """Decoded lossless frames whose digest is the generator's count as exact; a frame the
    generator made otherwise (its digest changed here) does not; the lossy frames are compared
    with the exact ones."""
    case = cctv_case((21, 1), "shop", "equidistant", (320, 240))
    got = frames(case, np.random.default_rng(2))
    encode(got, tmp_path / "a.mp4", lossless=True, interlaced=False)
    encode(got, tmp_path / "b.mp4", lossless=False, interlaced=False)
    clip = cc.Clip(tmp_path / "a.mp4", tmp_path / "b.mp4", [cc.frame_digest(f) for f in got], place_frames(case))
    fig, lossy = cc.round_trip(clip)
    assert fig["frames"] == fig["exact"] == len(got) == len(lossy)
    assert fig["stills_checked"] == len({0, len(got) - 1, *clip.place_frames}) == fig["stills_exact"]
    assert len(fig["psnr_db"]) == len(got) and min(fig["psnr_db"]) > 30.0
    assert all(0 < e <= 255 for e in fig["max_error_grey"])
    other = replace(clip, digests=[cc.frame_digest(got[0][::-1])] + clip.digests[1:])
    fig, _ = cc.round_trip(other)
    assert fig["exact"] == len(got) - 1 and len(fig["psnr_db"]) == len(got) - 1
    assert fig["stills_exact"] == fig["stills_checked"] - 1  # frame 0, taken as a still, is not the generator's


def test_a_case_is_calibrated_and_its_heights_measured(tmp_path) -> None:
    """A case without video, through its true lens and the reference: the lens found and each
    height measured with its σ; the figures carry the issue's names."""
    cases = [bench.run_case(i, tmp_path) for i in (1, 2)]  # an equidistant and an equisolid fisheye
    for c in cases:
        assert "video" not in c and c["lens"] in bench.FISHEYES
        for run in ("true", "reference"):
            got = c[run]
            assert "refused" not in got, got
            assert got["lens"]["corner_displacement_px"] > 0 and got["corner_true_px"] > 100
            assert got["heights"] and all("value_m" in h and h["sigma_m"] > 0 for h in got["heights"])
    fig = bench.summarise(cases)
    assert fig["frames_decoded_exact"] is None and fig["video_cases"] == 0
    assert fig["fisheye_cases_calibrated"] == 2 and fig["fisheye_corner_px_error_median"] >= 0
    assert 0 <= fig["person_height_rel_error_median"] < 0.2
    assert 0 <= fig["person_height_coverage_95"] <= 1
    assert fig["person_heights_measured"] == sum(len(c["true"]["heights"]) for c in cases)
    assert fig["goals_met"] is False  # two cases are not the 200 the goal asks
    assert "fisheye corner error median (px)" in bench.table(fig)


def test_reference_case_keeps_the_corner_shift() -> None:
    case = cc.make_case(2)
    ref = cc.reference_case(case)
    assert abs(ref.lens.corner_displacement_px(case.width, case.height)
               - case.lens.corner_displacement_px(case.width, case.height)) < 1e-6
    np.testing.assert_array_equal(ref.lens.K, case.lens.K)


def test_bench_is_registered() -> None:
    assert BENCHES["cctv"] is bench
