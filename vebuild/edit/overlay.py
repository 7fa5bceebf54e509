"""What the modelling screen draws over a photo, in that photo's pixel coordinates (paper Figures
1–3, 5 and 7): the user's vanishing segments in their axis' colour with their residuals, the fitted
vanishing points, the calibrated camera's horizon and world axes, markers, the model's projected
edges (white), the user's edges (red), handles (filled where fixed) and observation residuals.

Everything projected is drawn through the photo's lens (the camera's k1): a straight line of the
world (a model edge, an axis, the horizon) is a curve in a distorted photo, drawn as consecutive
lines with the same kind and key, within :data:`vebuild.model.drag.CURVE_TOL_PX` of the true
curve.

Plain data, no GL: :meth:`vebuild.edit.session.EditSession.overlay` computes it, the screen maps it
to the window and draws it, tests read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from vebuild.camera import PINHOLE, Lens, project, undistort_pixels, world_to_camera
from vebuild.model.drag import lens_polyline

RGBA = tuple[float, float, float, float]

#: One colour per world axis, as in the paper's Figure 1 (x red, y green, z blue).
AXIS_COLOURS: dict[str, RGBA] = {"x": (0.95, 0.25, 0.2, 1.0), "y": (0.25, 0.85, 0.3, 1.0), "z": (0.3, 0.55, 1.0, 1.0)}
WHITE: RGBA = (1.0, 1.0, 1.0, 1.0)
RED: RGBA = (1.0, 0.15, 0.15, 1.0)
YELLOW: RGBA = (1.0, 0.9, 0.1, 1.0)
MAGENTA: RGBA = (1.0, 0.2, 0.9, 1.0)
ORANGE: RGBA = (1.0, 0.6, 0.1, 1.0)
CYAN: RGBA = (0.2, 0.95, 0.95, 1.0)
GREY: RGBA = (0.7, 0.7, 0.7, 0.8)


@dataclass
class Line:
    """A segment from (u1, v1) to (u2, v2), pixels of the photo. ``kind`` says what it is:
    ``segment`` (a vanishing segment; ``key`` = (axis, index)), ``segment-path`` (a polyline
    segment's path through its middle points), ``vp-ray`` (midpoint to vanishing
    point), ``horizon``, ``axis`` (world axis from the origin), ``edge`` (a projected model edge;
    ``key`` = (node, edge)), ``user-edge`` (an edge observation; ``key`` = index), ``residual``,
    ``known-length`` (a length known at the scene; ``key`` = its index in ``$.known_lengths``)."""

    p: tuple[float, float, float, float]
    colour: RGBA
    width: float = 1.5
    kind: str = ""
    key: object = None
    label: str | None = None
    arrow: bool = False  # draw an arrow head at the second end (directed vanishing segments)
    cross: RGBA | None = None  # a cross of this colour at the middle (a segment left out, its axis' colour)


@dataclass
class Point:
    """A point at (u, v): ``kind`` is ``vp`` (a vanishing point), ``marker`` (an observed marker),
    ``marker-projected`` (where the calibration puts it), ``handle`` (``key`` = (node, handle)),
    ``pin`` (a fixed vertex), ``origin``, ``segment-point`` (a polyline segment's middle point),
    ``known-length-end`` (``key`` = (index, end); filled at a z length's foot on the floor)."""

    uv: tuple[float, float]
    colour: RGBA
    radius: float = 4.0
    filled: bool = True
    kind: str = ""
    key: object = None
    label: str | None = None


@dataclass
class Overlay:
    photo: str
    lines: list[Line] = field(default_factory=list)
    points: list[Point] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # one line each, shown beside the photo

    def of_kind(self, kind: str) -> tuple[list[Line], list[Point]]:
        return [ln for ln in self.lines if ln.kind == kind], [p for p in self.points if p.kind == kind]


def _clip_line(line: np.ndarray, width: float, height: float) -> tuple[float, float, float, float] | None:
    """The part of the homogeneous image line inside the image rectangle, or None."""
    a, b, c = line
    pts = []
    for u in (0.0, width):
        if abs(b) > 1e-12:
            v = -(a * u + c) / b
            if 0 <= v <= height:
                pts.append((u, v))
    for v in (0.0, height):
        if abs(a) > 1e-12:
            u = -(b * v + c) / a
            if 0 <= u <= width:
                pts.append((u, v))
    if len(pts) < 2:
        return None
    pts.sort()
    return (*pts[0], *pts[-1])


def vanishing_rays(ov: Overlay, vs: Any, width: float, height: float, skip: set[int] | None = None) -> None:
    """Thin lines from each segment's midpoint toward the vanishing point (paper Figure 2), and the
    point itself where it is not too far outside the image. ``vs``: a session VanishingState;
    ``skip``: the indices of segments given no ray (those the calibration left out)."""
    v = vs.point
    colour = AXIS_COLOURS[vs.axis]
    faint = (*colour[:3], 0.45)
    reach = 3.0 * math.hypot(width, height)
    for i, s in enumerate(vs.segments):
        if skip and i in skip:
            continue
        m = 0.5 * (s[:2] + s[2:])
        if abs(v[2]) > 1e-12 and np.linalg.norm(v[:2] / v[2] - m) < reach:
            end = v[:2] / v[2]
        else:
            d = v[:2] if abs(v[2]) <= 1e-12 else v[:2] / v[2] - m
            d = d / max(np.linalg.norm(d), 1e-12)
            d = d if np.dot(d, s[2:] - s[:2]) >= 0 else -d
            end = m + reach * d
        ov.lines.append(Line((float(m[0]), float(m[1]), float(end[0]), float(end[1])), faint, 1.0, "vp-ray", vs.axis))
    if abs(v[2]) > 1e-12:
        q = v[:2] / v[2]
        if np.all(np.abs(q - [width / 2, height / 2]) < reach):
            ov.points.append(Point((float(q[0]), float(q[1])), colour, 6.0, False, "vp",
                                   vs.axis, f"VP {vs.axis}  rms {vs.rms_px:.2f} px"))


def curve_lines(ov: Overlay, K: Any, lens: Lens, a: Any, b: Any, colour: RGBA, width: float, kind: str,
                key: object = None, label: str | None = None, arrow: bool = False) -> None:
    """The straight segment a–b of the pinhole image, drawn through the lens k1: one line for a
    pinhole, else the pieces of :func:`~vebuild.model.drag.lens_polyline`, the label and arrow on
    the last."""
    q = lens_polyline(K, lens, a, b)
    for i in range(len(q) - 1):
        last = i == len(q) - 2
        ov.lines.append(Line((float(q[i, 0]), float(q[i, 1]), float(q[i + 1, 0]), float(q[i + 1, 1])), colour,
                             width, kind, key, label if last else None, arrow and last))


#: Points along each side of the photo whose undistorted places bound the pinhole image it shows.
RIM_SAMPLES = 33


def polyline_points(ov: Overlay, vs: Any) -> None:
    """A polyline segment's path through its middle points (thin, kind ``segment-path``, key (axis,
    index)) and those points (kind ``segment-point``): how the clicked edge bends in the photo."""
    colour = AXIS_COLOURS[vs.axis]
    for i, q in enumerate(getattr(vs, "polylines", [])):
        if len(q) <= 2:
            continue
        for a, b in zip(q[:-1], q[1:], strict=True):
            ov.lines.append(Line((float(a[0]), float(a[1]), float(b[0]), float(b[1])), colour, 1.0, "segment-path",
                                 (vs.axis, i)))
        for m in q[1:-1]:
            ov.points.append(Point((float(m[0]), float(m[1])), colour, 3.0, True, "segment-point", (vs.axis, i)))


def horizon_and_axes(ov: Overlay, cam: Any, width: float, height: float) -> None:
    """The calibrated camera's horizon (the image of the horizontal planes' line at infinity) and
    the world axes, 1 m long from the origin, through the camera's lens (its ``k1``, 0 if none)."""
    lens = getattr(cam, "lens", PINHOLE)
    horizon = np.linalg.inv(cam.K).T @ cam.R[:, 2]
    # The horizon is straight in the pinhole image: clip it there, to the box of what the photo
    # shows (the photo's rim undistorted), then bend it through the lens.
    s = np.linspace(0.0, 1.0, RIM_SAMPLES)[:, None]
    rim = np.concatenate([s * [width, 0.0], [width, 0.0] + s * [0.0, height], s * [width, 0.0] + [0.0, height],
                          s * [0.0, height]])
    und = undistort_pixels(cam.K, rim, lens)
    lo, hi = und.min(axis=0), und.max(axis=0)
    seg = _clip_line(horizon + np.r_[0.0, 0.0, horizon[:2] @ lo], *(hi - lo))  # shifted by lo
    if seg is not None:
        curve_lines(ov, cam.K, lens, np.add(seg[:2], lo), np.add(seg[2:], lo), CYAN, 1.0, "horizon", None, "horizon")
    origin = np.zeros(3)
    if world_to_camera(cam.R, cam.C, origin)[2] <= 0:
        return
    o = project(cam.K, cam.R, cam.C, origin)  # pinhole ends of the axes; drawn through the lens
    for k, axis in enumerate("xyz"):
        E = np.eye(3)[k]
        if world_to_camera(cam.R, cam.C, E)[2] <= 0:
            continue
        e = project(cam.K, cam.R, cam.C, E)
        curve_lines(ov, cam.K, lens, o, e, AXIS_COLOURS[axis], 3.0, "axis", axis, f"+{axis} 1 m", arrow=True)
    od = project(cam.K, cam.R, cam.C, origin, lens)
    ov.points.append(Point((float(od[0]), float(od[1])), WHITE, 4.0, True, "origin", None, "origin"))
