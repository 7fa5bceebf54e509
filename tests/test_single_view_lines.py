"""Where each single-view measurement's line lies in the world (vebuild/analysis/single_view_lines.py),
from clicks that are the exact projections (lens included) of known 3-D points: the ends come back
to those points, for every kind of SINGLE_VIEW_CLICKS; bad clicks are named."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vebuild.analysis.single_view import SINGLE_VIEW_CLICKS, SingleViewError, single_view_command
from vebuild.analysis.single_view_lines import (
    command_photo_and_pixels,
    line_length_agrees,
    measured_lines,
    single_view_kind,
)
from vebuild.camera import ImageCamera, Lens, rotation_from_ypr
from vebuild.camera import project as project_points

#: Exact clicks (to double precision) must give the points back to rounding (metres).
EXACT_M = 1e-9


def _camera(k1: float) -> ImageCamera:
    R = rotation_from_ypr(math.radians(75.0), math.radians(-22.0), math.radians(1.5))
    K = np.array([[1150.0, 0, 815.0], [0, 1150.0, 588.0], [0, 0, 1]])
    return ImageCamera("p", K, R, np.array([1.5, -1.0, 1.7]), 1600, 1200, lens=Lens(k1))


def _clicks(cam: ImageCamera, points: list[np.ndarray]) -> list[float]:
    uv = project_points(cam.K, cam.R, cam.C, np.array(points, float), cam.lens)
    assert np.all((uv > 0) & (uv < [cam.width, cam.height])), uv
    return [float(v) for v in uv.ravel()]


Z = np.array([0.0, 0.0, 1.0])
A, B = np.array([1.2, 3.5, 0.0]), np.array([2.9, 4.1, 0.0])  # where a wall meets the floor
EDGE = np.array([2.0, 2.0, 0.75])  # a table top's edge, 0.75 above the floor
RAMP = [np.array([1.0, 2.0, 0.0]), np.array([2.6, 2.2, 0.4]), np.array([1.4, 3.2, 0.1])]  # a sloping plane


def _on_ramp(s: float, t: float) -> np.ndarray:
    return RAMP[0] + s * (RAMP[1] - RAMP[0]) + t * (RAMP[2] - RAMP[0])


CASES = {
    "photo-height": ([np.array([2.2, 2.5, 0]), np.array([2.2, 2.5, 1.3])], [[2.2, 2.5, 0], [2.2, 2.5, 1.3]]),
    "floor-distance": ([np.array([1.0, 2.0, 0]), np.array([2.5, 3.0, 0])], [[1.0, 2.0, 0], [2.5, 3.0, 0]]),
    "wall-length": ([A, B, A + 0.3 * (B - A) + 1.2 * Z, A + 0.8 * (B - A) + 0.4 * Z],
                    [A + 0.3 * (B - A) + 1.2 * Z, A + 0.8 * (B - A) + 0.4 * Z]),
    "raised-height": ([EDGE * [1, 1, 0], EDGE, np.array([2.3, 2.4, 0.75]), np.array([2.3, 2.4, 1.05])],
                      [[2.3, 2.4, 0.75], [2.3, 2.4, 1.05]]),
    "plane-length": ([RAMP[0] * [1, 1, 0], RAMP[0], RAMP[1] * [1, 1, 0], RAMP[1], RAMP[2] * [1, 1, 0], RAMP[2],
                      _on_ramp(0.2, 0.3), _on_ramp(0.7, 0.5)], [_on_ramp(0.2, 0.3), _on_ramp(0.7, 0.5)]),
}


@pytest.mark.parametrize("k1", [0.0, -0.05], ids=["pinhole", "k1"])
@pytest.mark.parametrize("kind", sorted(SINGLE_VIEW_CLICKS))
def test_exact_clicks_give_the_points_back(kind, k1):
    cam = _camera(k1)
    clicked, want = CASES[kind]
    assert len(clicked) == len(SINGLE_VIEW_CLICKS[kind])
    pixels = _clicks(cam, clicked)
    (line,) = measured_lines(cam, kind, pixels)
    np.testing.assert_allclose(line.ends, np.array(want, float), atol=EXACT_M)
    value = line.length if line.quantity == "distance" else float(line.ends[1][2] - line.ends[0][2])
    assert line_length_agrees(line, value) and not line_length_agrees(line, value * (1 + 1e-4))
    assert line.quantity == ("height" if kind in ("photo-height", "raised-height") else "distance")


def test_a_command_s_words_give_its_photo_pixels_and_groups():
    cam = _camera(0.0)
    first, _ = CASES["floor-distance"]
    second = [np.array([1.5, 2.5, 0]), np.array([2.0, 4.0, 0])]
    words = single_view_command("floor-distance", "p", np.reshape(_clicks(cam, first), (2, 2)))
    words += [f"{v:.2f}" for v in _clicks(cam, second)]  # a second measurement in the same command
    assert single_view_kind(words) == "floor-distance" and single_view_kind(["distance", "a", "b"]) is None
    photo, pixels = command_photo_and_pixels(words)
    assert photo == "p" and len(pixels) == 8
    lines = measured_lines(cam, "floor-distance", pixels)
    # Saved pixels are rounded to 1/100 px: the ends move by well under a millimetre.
    np.testing.assert_allclose(lines[1].ends, np.array(second), atol=1e-3)


@pytest.mark.parametrize("kind, points, said", [
    ("wall-length", [A, A, A + Z, A + 0.5 * Z],
     "the wall's two floor points are the same point, so they do not fix a wall"),
    ("plane-length", [RAMP[0] * [1, 1, 0], RAMP[0]] * 3 + [RAMP[0], RAMP[0] + 0.01 * Z],
     "the plane's three points lie on one line"),
])
def test_clicks_that_fix_no_plane_are_named(kind, points, said):
    cam = _camera(0.0)
    with pytest.raises(SingleViewError, match=said):
        measured_lines(cam, kind, _clicks(cam, points))


def test_a_click_above_the_horizon_and_bad_words_are_named():
    cam = _camera(0.0)
    sky = [float(cam.K[0][2]), 5.0]  # high in the photo, looking 22° down: above the horizon
    with pytest.raises(SingleViewError, match="photo 'p': the first point: pixel .* lies on or above the horizon"):
        measured_lines(cam, "floor-distance", sky + _clicks(cam, [np.array([1.0, 2.0, 0])]))
    with pytest.raises(SingleViewError, match="expected pixels in groups of 4"):
        measured_lines(cam, "photo-height", [1.0, 2.0, 3.0])
    with pytest.raises(SingleViewError, match="names no photo"):
        command_photo_and_pixels(["photo-height", "1", "2", "3", "4"])
    with pytest.raises(SingleViewError, match="neither --photo nor a pixel"):
        command_photo_and_pixels(["photo-height", "--photo", "p", "x", "2", "3", "4"])
