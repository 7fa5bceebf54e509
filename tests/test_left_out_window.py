"""Vanishing segments the calibration leaves out, on the modelling screen driven for real (Xvfb,
xdotool): a generated photo with clutter (vebuild.synthetic.clutter: roof slopes grouped with the
x and z edges), Calibrate pressed in the window, the framebuffer read. The left-out segments are
drawn grey and crossed in their axis' colour where they are, the kept ones in their axis' colour;
the Calibration tab's legend says what the grey lines are and how many of each axis; pointing at
one names why it was left out; its Delete button removes exactly them as one undoable edit, and the
saved file read back holds every other segment as it was."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from edit_driver import Driver

from vebuild.edit.layout import PICK_RADIUS_PX
from vebuild.edit.left_out import WHAT_TO_DO, legend_line
from vebuild.edit.overlay import AXIS_COLOURS, GREY, YELLOW
from vebuild.edit.photo_view import CROSS_HALF_PX
from vebuild.synthetic import random_scene, write_project
from vebuild.synthetic.clutter import add_clutter

pytestmark = pytest.mark.usefixtures("xvfb_display")

#: The generated photos' plain grey (vebuild.synthetic.write_project), 0–255.
PHOTO_GREY = 128
#: The grey line's colour over that photo: GREY blended by its alpha, 0–255.
DRAWN_GREY = 255 * np.asarray(GREY[:3]) * GREY[3] + PHOTO_GREY * (1 - GREY[3])
#: How far a drawn pixel may be from the colour asked for, per channel (0–255): anti-aliasing at a
#: line's centre and the framebuffer's rounding stay within a few levels; the photo's grey (128) is
#: 40 levels from the drawn grey (168), and every axis colour 60 or more from either.
COLOUR_TOL = 16
#: Half the square searched around a point of a line for its colour, window pixels: the line is
#: 2 px wide, its ends placed to a fraction of a pixel.
PATCH_HALF = 2
#: Where along a segment its body is sampled (fractions of its length): clear of its arrow head at
#: the end and of the cross at the middle of a left-out one.
ALONG = (0.2, 0.3, 0.38, 0.62, 0.7, 0.8)


@pytest.fixture
def cluttered(tmp_path: Path) -> tuple[Path, dict[str, list[int]]]:
    """Four generated photos (3vp, 3vp, 2vp, 3vp: plain grey pictures, their marks exact plus click
    noise); the first with two roof slopes grouped with its x edges and two with its z edges.
    Returns the project file and axis → the clutter's indices in the first photo."""
    rng = np.random.default_rng(4407)
    photos, markers = random_scene(rng, ("3vp", "3vp", "2vp", "3vp"))
    clutter = {"x": add_clutter(photos[0], rng, "slopes", "x", 2), "z": add_clutter(photos[0], rng, "slopes", "z", 2)}
    return write_project(tmp_path, photos, markers), clutter


def _near(img: np.ndarray, x: float, y: float, rgb: np.ndarray, half: int = PATCH_HALF) -> bool:
    """Whether a pixel within ``half`` of window point (x, y) has colour ``rgb`` (within COLOUR_TOL)."""
    xi, yi = int(round(x)), int(round(y))
    patch = img[yi - half:yi + half + 1, xi - half:xi + half + 1, :3].astype(float).reshape(-1, 3)
    return bool(np.any(np.all(np.abs(patch - rgb) <= COLOUR_TOL, axis=1)))


Rect = tuple[float, float, float, float]


def _samples(e, photo: str, seg: list[float], avoid: list[Rect]) -> list[tuple[float, float]]:
    """Window points along a segment's body (ALONG), those inside the view and outside ``avoid``."""
    a, b = np.asarray(seg[:2], float), np.asarray(seg[-2:], float)
    x0, y0, x1, y1 = e.view_rect()
    out = []
    for t in ALONG:
        x, y = e.image_to_window(photo, a + t * (b - a))
        inside = x0 + 4 <= x <= x1 - 4 and y0 + 4 <= y <= y1 - 4
        if inside and not any(r[0] - 4 <= x <= r[2] + 4 and r[1] - 4 <= y <= r[3] + 4 for r in avoid):
            out.append((x, y))
    return out


def _cross_arm(e, photo: str, seg: list[float]) -> tuple[tuple[float, float], tuple[float, float]]:
    """Two points on the arm of a left-out segment's cross that is more across the segment than
    the other, CROSS_HALF_PX · 0.8 from its middle each way (window pixels)."""
    a = np.asarray(e.image_to_window(photo, seg[:2]))
    b = np.asarray(e.image_to_window(photo, seg[-2:]))
    m, u = 0.5 * (a + b), (b - a) / np.linalg.norm(b - a)
    arms = [np.array([1.0, 1.0]) / np.sqrt(2), np.array([1.0, -1.0]) / np.sqrt(2)]
    d = min(arms, key=lambda v: abs(float(v @ u)))
    r = 0.8 * CROSS_HALF_PX
    return (float(m[0] + r * d[0]), float(m[1] + r * d[1])), (float(m[0] - r * d[0]), float(m[1] - r * d[1]))


def test_left_out_segments_are_drawn_explained_and_deleted_in_the_window(cluttered, xdotool) -> None:
    path, clutter = cluttered
    before_file = json.loads(path.read_text())
    segs0 = {a: [list(s) for s in v] for a, v in before_file["photos"][0]["vanishing_segments"].items()}
    d = Driver(path, xdotool)
    try:
        e, s = d.editor, d.session
        assert e.photo == "p1"
        d.send(*d.move_to(e.panels_rect()[0] + 5, e.size()[1] - 5))  # the pointer off the photo
        colour = {a: 255 * np.asarray(AXIS_COLOURS[a][:3]) for a in "xyz"}
        yellow = 255 * np.asarray(YELLOW[:3])
        avoid = [e.widget_rects[k] for k in ("messages",) if k in e.widget_rects]
        img = d.screen()
        # Before any calibration: every segment in its axis' colour (or yellow, an outlier of the
        # fit the slopes pull), nothing grey, no legend.
        for axis, rows in segs0.items():
            for k, seg in enumerate(rows):
                pts = _samples(e, "p1", seg, avoid)
                assert len(pts) >= 3, (axis, k)
                assert all(_near(img, x, y, colour[axis]) or _near(img, x, y, yellow) for x, y in pts), (axis, k)
                assert not any(_near(img, x, y, DRAWN_GREY) for x, y in pts), (axis, k)
        assert e.panels.left_out_text == [] and "delete left out" not in e.widget_rects
        d.click("Calibrate")
        assert e.calibration_error is None, e.calibration_error
        assert {a: sorted(v) for a, v in s.left_out_segments("p1").items()} == clutter
        d.send(*d.move_to(e.panels_rect()[0] + 5, e.size()[1] - 5))
        avoid = [e.widget_rects[k] for k in ("messages",) if k in e.widget_rects]
        img = d.screen()
        for axis, rows in segs0.items():
            for k, seg in enumerate(rows):
                pts = _samples(e, "p1", seg, avoid)
                assert len(pts) >= 3, (axis, k)
                if k in clutter.get(axis, ()):
                    assert all(_near(img, x, y, DRAWN_GREY) for x, y in pts), (axis, k)
                    assert all(_near(img, x, y, colour[axis], 1) for x, y in _cross_arm(e, "p1", seg)), (axis, k)
                else:
                    assert all(_near(img, x, y, colour[axis]) for x, y in pts), (axis, k)
                    assert not any(_near(img, x, y, DRAWN_GREY) for x, y in pts), (axis, k)
        # The legend in the Calibration tab: what the grey lines are, how many of each axis, what to do.
        legend = [legend_line("x", 2), legend_line("z", 2), WHAT_TO_DO, "Delete the 4 left out"]
        assert e.panels.left_out_text == legend
        assert legend[0] == ("2 grey crossed x segments: left out by the calibration: they do not meet the "
                             "other x lines' vanishing point")
        px0, py0, px1, py1 = e.panels_rect()
        for label in ("left out:x", "left out:z", "delete left out"):
            x0, y0, x1, y1 = e.widget_rects[label]
            assert px0 <= x0 < x1 <= px1 and py0 <= y0 < y1 <= py1, label  # on screen, in the panel
        assert [legend_line("x", 2), legend_line("z", 2)] == [t for t, _ in e.shown_messages()][-2:]
        # Pointing at a grey line names why it was left out.
        ov = e.overlay()
        for axis, ks in clutter.items():
            for k in ks:
                x, y = _clearest(e, ov, (axis, k), _samples(e, "p1", segs0[axis][k], avoid))
                d.send(*d.move_to(x, y))
                hover = e.hovered(e.overlay())
                assert hover is not None and hover.key == (axis, k) and e.labelled(hover, True)
                assert hover.label.startswith(f"{axis}{k}: left out by the calibration: ")
                assert hover.label.endswith("σ off the vanishing point of the other lines")
        d.send(*d.move_to(px0 + 5, e.size()[1] - 5))
        # Deleted in one action: exactly the left-out segments; undone and redone by keys; saved.
        kept = {a: [row for k, row in enumerate(rows) if k not in clutter.get(a, ())] for a, rows in segs0.items()}
        d.click("delete left out")
        assert s.photo("p1")["vanishing_segments"] == kept
        assert s.messages[-1].startswith("deleted the 4 segments of p1 left out by the calibration (x: 6, 7; z: 6, 7)")
        assert e.panels.left_out_text == [] and "delete left out" not in e.widget_rects
        img = d.screen()
        for axis, ks in clutter.items():
            for k in ks:
                pts = _samples(e, "p1", segs0[axis][k], avoid)
                assert not any(_near(img, x, y, DRAWN_GREY) for x, y in pts), (axis, k)
        for axis, rows in kept.items():
            for k, seg in enumerate(rows):
                pts = _samples(e, "p1", seg, avoid)
                assert all(_near(img, x, y, colour[axis]) for x, y in pts), (axis, k)
        d.send("key", "ctrl+z")
        assert s.photo("p1")["vanishing_segments"] == segs0 and e.panels.left_out_text == legend
        d.send("key", "ctrl+y")
        assert s.photo("p1")["vanishing_segments"] == kept
        d.send("key", "ctrl+s")
        assert not s.dirty
    finally:
        d.close()
    saved = json.loads(path.read_text())
    assert saved["photos"][0]["vanishing_segments"] == kept
    for before, after in zip(before_file["photos"][1:], saved["photos"][1:], strict=True):
        assert after["vanishing_segments"] == before["vanishing_segments"]


def _clearest(e, ov, key: tuple[str, int], pts: list[tuple[float, float]]) -> tuple[float, float]:
    """Of window points on the line ``key``, the one farthest from every other line and named
    point the pointer could pick; it must be farther than the picking radius, so that the line
    under the pointer is the one meant."""
    others = [ln.p for ln in ov.lines if ln.key != key and ln.kind != "vp-ray" and e.shows(ln.kind)]
    named = [p.uv for p in ov.points if p.label and e.shows(p.kind)]

    def clearance(x: float, y: float) -> float:
        q = np.asarray(e.window_to_image(x, y))
        d = [float(np.linalg.norm(q - np.asarray(uv))) for uv in named]
        for u1, v1, u2, v2 in others:
            a, b = np.array([u1, v1]), np.array([u2, v2])
            t = float(np.clip((q - a) @ (b - a) / max(float((b - a) @ (b - a)), 1e-12), 0.0, 1.0))
            d.append(float(np.linalg.norm(q - (a + t * (b - a)))))
        return min(d) * e.zoom  # window pixels

    best = max(pts, key=lambda p: clearance(*p))
    assert clearance(*best) > PICK_RADIUS_PX, (key, clearance(*best))
    return best
