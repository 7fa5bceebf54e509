"""The generated CCTV scenes (vebuild.synthetic.cctv): the truth they record is what they render,
and their video's lossless encoding gives the generator's frames back bit for bit."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from vebuild.synthetic.cctv import cctv_case, edge_candidates, truth_record
from vebuild.synthetic.cctv_lens import LENS_KINDS, TrueLens, lens_for_field, matching_division_lens
from vebuild.synthetic.cctv_render import figure_hits, render
from vebuild.synthetic.cctv_video import (
    FIELD_S,
    WALK_M_S,
    cast_frame,
    decode,
    empty_scene,
    encode,
    frames,
    place_frames,
    positions,
)

#: Small frames keep the ray-casting fast; the lenses' fields are the generator's.
SMALL = (320, 240)
CASES = [("street", "equidistant"), ("shop", "equisolid"), ("street", "rectilinear"), ("shop", "equidistant")]


@pytest.mark.parametrize("kind", LENS_KINDS)
def test_lens_puts_a_ray_where_its_model_says(kind: str) -> None:
    """Each true lens's image radius is its model's (module docstring) of the ray's angle off the
    axis, computed here from the direction itself; rays() inverts pixels()."""
    lens = lens_for_field(kind, 140.0 if kind != "rectilinear" else 100.0, 1280, 720, (643.0, 356.5),
                          0.05 if kind == "rectilinear" else 0.0)
    rng = np.random.default_rng(3)
    uv = rng.uniform([0.0, 0.0], [1280.0, 720.0], (200, 2))  # pixels over the whole frame
    d = lens.rays(uv)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    theta = np.arccos(d[:, 2])
    r = np.linalg.norm(uv - lens.c, axis=1)
    want = {"equidistant": lens.f * theta, "equisolid": 2 * lens.f * np.sin(theta / 2),
            "rectilinear": lens.f * np.tan(theta) * (1 + lens.barrel * np.tan(theta) ** 2)}[kind]
    np.testing.assert_allclose(r, want, rtol=1e-9)
    # The ray's direction about the axis is the pixel's about the principal point.
    np.testing.assert_allclose(d[:, :2] / np.linalg.norm(d[:, :2], axis=1)[:, None],
                               (uv - lens.c) / r[:, None], atol=1e-12)
    np.testing.assert_allclose(lens.pixels(d), uv, atol=1e-8)
    # The field across the diagonal is the one asked for (the principal point a few px off centre).
    assert abs(lens.diagonal_fov_deg(1280, 720) - (140.0 if kind != "rectilinear" else 100.0)) < 0.5


def test_reference_lens_moves_the_corner_as_far_as_the_true_lens() -> None:
    lens = lens_for_field("equidistant", 150.0, 704, 576, (355.0, 290.0))
    ref = matching_division_lens(lens, 704, 576)
    assert ref.corner_displacement_px(704, 576) == pytest.approx(lens.corner_displacement_px(704, 576), rel=1e-9)
    assert -1.0 < ref.k1 < 0.0  # a barrel lens vebuild's project files accept (|k1| < 1)


@pytest.mark.parametrize("setting,kind", CASES)
def test_head_and_foot_pixels_reproject_onto_the_figure(setting: str, kind: str) -> None:
    """The head-top and foot pixels of the truth record, cast back through the true lens, pass
    through the figure's head-top and foot points; the ray through the head-top pixel meets the
    rendered figure first at its head's top."""
    case = cctv_case((11, len(setting), LENS_KINDS.index(kind)), setting, kind, SMALL)
    rec = truth_record(case)
    assert len(rec["places"]) == len(case.places) >= 3
    assert 1.50 <= rec["figure_height_m"] <= 1.95 and 2.5 <= case.C[2] <= 4.0
    for k, place in enumerate(rec["places"]):
        for which in ("foot", "top"):
            X = np.array(place[f"{which}_world"])
            d = case.R.T @ case.lens.rays(np.array(place[f"{which}_px"]))
            # The point's distance from the ray through its pixel: rounding only.
            off = np.linalg.norm(np.cross(d, X - case.C))
            assert off < 1e-9, (k, which, off)
        d_top = case.R.T @ case.lens.rays(np.array(place["top_px"]))
        t, _ = figure_hits(case.C, d_top[None], case.places[k], case.figure_height)
        assert abs(t[0] - np.linalg.norm(np.array(place["top_world"]) - case.C)) < 1e-6


def _on_line(dark: np.ndarray, p: np.ndarray, n: np.ndarray) -> tuple[bool, bool]:
    """Whether the painted line covers the pixels about ``p`` (3 × 3), and at least half as much
    as it covers any pixel up to 3 px across (``n``: the unit normal; a far line is thinner than
    a pixel, so its coverage splits between two)."""
    c, r = int(p[0]), int(p[1])
    near = dark[r - 1:r + 2, c - 1:c + 2].max()
    across = max(dark[int(q[1]), int(q[0])] for q in (p + s * n for s in np.arange(-3.0, 3.5, 0.5)))
    return bool(near > 0.0), bool(near >= 0.5 * across)


def _samples(case, shift: float = 0.0):
    """Points along every candidate edge's traced polyline (moved ``shift`` px across), with their
    unit normals, 5 px or more inside the frame."""
    for got in edge_candidates(case).values():
        for _, uv in got:
            for j in range(2, len(uv) - 2, 8):
                t = uv[j + 1] - uv[j - 1]
                n = np.array([-t[1], t[0]]) / np.linalg.norm(t)
                p = uv[j] + shift * n
                if 5 <= p[0] < case.width - 5 and 5 <= p[1] < case.height - 5:
                    yield p, n


@pytest.mark.parametrize("setting,kind", CASES)
def test_marked_polylines_lie_on_the_rendered_edges(setting: str, kind: str) -> None:
    """Every edge a user may mark is drawn where its traced polyline says, within a pixel
    (:func:`_on_line`: every sample touches its line, 95 % or more at its ridge: another line
    crossing within 3 px may be the stronger), and the frame is darker there than 4 px to either
    side across the line (where no other line or surface edge intervenes: at least 90 % of the
    samples)."""
    case = cctv_case((12, len(setting), LENS_KINDS.index(kind)), setting, kind, SMALL)
    img, dark = render(case.layout, case.lens, case.R, case.C, case.width, case.height,
                       (case.places[0], case.figure_height), case.tex_seed)
    grey = img.mean(axis=2)
    assert all(len(v) >= 3 for v in edge_candidates(case).values())
    checked = ridge = darker = 0
    for p, n in _samples(case):
        touches, at_ridge = _on_line(dark, p, n)
        assert touches, p
        c, r = int(p[0]), int(p[1])
        sides = [grey[int(q[1]), int(q[0])] for q in (p + 4 * n, p - 4 * n)]
        checked += 1
        ridge += at_ridge
        darker += grey[r - 1:r + 2, c - 1:c + 2].min() < min(sides)
    assert checked >= 30
    assert ridge / checked >= 0.95 and darker / checked >= 0.9, (ridge, darker, checked)


def test_polylines_shifted_across_miss_the_edges() -> None:
    """The check above tells: moved 2.5 px across, most of the polylines' points miss their lines."""
    case = cctv_case((12, 6, 1), "street", "equidistant", SMALL)
    _, dark = render(case.layout, case.lens, case.R, case.C, case.width, case.height,
                     (case.places[0], case.figure_height), case.tex_seed)
    hits = [all(_on_line(dark, p, n)) for p, n in _samples(case, 2.5)]
    assert len(hits) >= 30 and sum(hits) / len(hits) < 0.5


#: The lossy encoding's error: libx264 at crf 23 keeps these frames at 37–40 dB (the bench's
#: figures); 30 dB (an RMS error of 8 grey levels, 2.7 × the largest sensor noise drawn) is the
#: least a frame "within the codec's error" may show.
LOSSY_PSNR_MIN_DB = 30.0


def test_lossless_round_trip_is_bit_exact_and_lossy_within_the_codec_error(tmp_path) -> None:
    """The clip (interlaced here) through libx264rgb qp 0 decodes to the generator's frames bit
    for bit; through libx264 crf 23, to frames within the codec's error."""
    case = cctv_case((13, 1), "street", "equisolid", SMALL, interlaced=True)
    got = frames(case, np.random.default_rng(5))
    assert len(got) == 2 * len(case.places) - 1 and place_frames(case)[-1] == len(got) - 1
    assert all(f.shape == (SMALL[1], SMALL[0], 3) and f.dtype == np.uint8 for f in got)
    encode(got, tmp_path / "lossless.mp4", lossless=True, interlaced=True)
    encode(got, tmp_path / "lossy.mp4", lossless=False, interlaced=True)
    exact = decode(tmp_path / "lossless.mp4")
    assert len(exact) == len(got)
    assert all(np.array_equal(a, b) for a, b in zip(got, exact, strict=True))
    lossy = decode(tmp_path / "lossy.mp4")
    assert len(lossy) == len(got)
    for a, b in zip(got, lossy, strict=True):
        mse = float(np.mean((a.astype(float) - b) ** 2))
        assert 0.0 < mse and 10 * np.log10(255.0**2 / mse) >= LOSSY_PSNR_MIN_DB


def test_interlaced_frame_weaves_two_instants() -> None:
    """An interlaced frame's even rows are the frame cast at its instant, its odd rows the frame
    cast 1/50 s later, the figure having walked on (the two differ)."""
    case = cctv_case((14, 2), "shop", "rectilinear", SMALL, interlaced=True)
    progressive = replace(case, interlaced=False)
    empty = empty_scene(case)
    at, u = positions(case)[1]  # walking between its first two places
    woven = cast_frame(case, empty, at, u)
    now = cast_frame(progressive, empty, at, u)
    later = cast_frame(progressive, empty, at + WALK_M_S * FIELD_S * u, u)
    assert np.array_equal(woven[0::2], now[0::2]) and np.array_equal(woven[1::2], later[1::2])
    assert not np.array_equal(now[1::2], later[1::2])


def test_case_is_deterministic_from_its_seed() -> None:
    a, b = cctv_case((15, 3), "shop", "equisolid", SMALL), cctv_case((15, 3), "shop", "equisolid", SMALL)
    assert isinstance(a.lens, TrueLens) and a.lens == b.lens
    assert truth_record(a) == truth_record(b)


def test_rectilinear_lens_images_no_ray_beyond_its_field() -> None:
    """Beyond r_u² = 1 / (3 |a|) the barrel polynomial turns back: a ray there would land inside
    the frame, on another ray's pixel. The lens images no such ray, and the case sees no point there."""
    lens = lens_for_field("rectilinear", 100.0, 320, 240, (160.0, 120.0), 0.08)
    edge = np.arctan(np.sqrt(-1.0 / (3.0 * lens.barrel)))
    d = np.array([[np.sin(edge * 1.2), 0.0, np.cos(edge * 1.2)], [np.sin(edge * 0.9), 0.0, np.cos(edge * 0.9)]])
    uv = lens.pixels(d)
    assert np.all(np.isnan(uv[0])) and np.all(np.isfinite(uv[1]))
    case = cctv_case((16, 1), "street", "rectilinear", SMALL)
    X = case.C + case.R.T @ np.array([np.sin(1.45), 0.0, np.cos(1.45)]) * 10.0  # 83° off the axis
    assert not case.sees(X[None])[0]


def test_truth_records_each_edge_and_its_image() -> None:
    """The truth's edges: each polyline pixel, cast back through the true lens, meets its 3D edge
    (the ray and the line cross, to rounding), and the record is plain JSON."""
    case = cctv_case((17, 2), "shop", "equisolid", SMALL)
    rec = json.loads(json.dumps(truth_record(case, edge_candidates(case))))
    assert {a: len(v) >= 3 for a, v in rec["edges"].items()} == {"x": True, "y": True, "z": True}
    for axis, edges in rec["edges"].items():
        for e in edges:
            assert "xyz"[e["axis"]] == axis
            along = np.eye(3)[e["axis"]]
            for uv in e["polyline_px"]:
                d = case.R.T @ case.lens.rays(np.array(uv))
                n = np.cross(d, along)
                gap = abs((np.array(e["at"]) - case.C) @ n) / np.linalg.norm(n)
                assert gap < 1e-9, (axis, e, uv, gap)
