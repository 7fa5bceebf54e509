"""Where a saved single-view measurement lies in the world: the two 3-D ends of the line it
measures, for drawing it in the hand-offs (the camera-only glTF, the web viewer).

A single-view measurement (:mod:`vebuild.analysis.single_view`) is saved as the words of a
``vebuild analyse KIND --photo ID U1 V1 …`` command (:data:`SINGLE_VIEW_CLICKS` gives each kind's
clicks, in order). Its figures (value, 1σ, 95 % interval) come from running those words; this
module only places its line, from the same clicks and the photo's camera (K, R, C and k1):

- ``photo-height``: from the foot F (its ray meets the floor) up to F + (0, 0, h), h where the
  top's ray passes nearest the vertical through F;
- ``floor-distance``: the two floor points;
- ``wall-length``: the wall is the vertical plane through the two floor points clicked where it
  meets the floor; the ends are where the last two clicks' rays meet it;
- ``raised-height``: the raised plane is z = h0, h0 the height of the edge point above its floor
  foot; the foot is where its ray meets that plane, the top above it as for ``photo-height``;
- ``plane-length``: the plane through three points, each on the vertical through its floor foot at
  the height its click gives (on the floor where the two clicks coincide); the ends are where the
  last two clicks' rays meet it.

The length of the line drawn is checked against the measured value by the caller
(:func:`line_length_agrees`): a drawing that does not show the measured figure is refused.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..camera import ImageCamera, pixel_rays_world
from .single_view import MIN_FLOOR_SLOPE, SINGLE_VIEW_CLICKS, SingleViewError

Array = NDArray[np.float64]

#: A ray meeting a plane at a grazing angle below this (|cos| of its angle to the plane's normal)
#: has no usable meeting point.
MIN_INCIDENCE = 1e-6
#: The drawn line's length and the measured value agree within this share of the value (plus the
#: rounding of a saved pixel, far below): the same clicks, the same camera, the same geometry.
AGREE_REL = 1e-6


@dataclass(frozen=True)
class MeasuredLine:
    """One measurement's line in the world (metres, or relative units where the photo has no scale)."""

    kind: str  # the single-view kind (``photo-height``, ...)
    quantity: str  # "height" or "distance"
    ends: Array  # (2, 3) world points
    clicks: Array  # (n, 2) the pixels clicked, in SINGLE_VIEW_CLICKS order

    @property
    def length(self) -> float:
        return float(np.linalg.norm(self.ends[1] - self.ends[0]))


def single_view_kind(words: Sequence[str]) -> str | None:
    """The single-view kind of a saved command's words, or None for any other analysis."""
    return words[0] if words and words[0] in SINGLE_VIEW_CLICKS else None


def command_photo_and_pixels(words: Sequence[str]) -> tuple[str, list[float]]:
    """The photo id and the pixel numbers of a single-view command's words."""
    photo = None
    pixels: list[float] = []
    rest = list(words[1:])
    i = 0
    while i < len(rest):
        w = rest[i]
        if w == "--photo" and i + 1 < len(rest):
            photo = rest[i + 1]
            i += 2
            continue
        if w.startswith("--photo="):
            photo = w.split("=", 1)[1]
        else:
            try:
                pixels.append(float(w))
            except ValueError:
                raise SingleViewError(f"{words[0]}: the word {w!r} is neither --photo nor a pixel coordinate") from None
        i += 1
    if photo is None:
        raise SingleViewError(f"{words[0]}: the command names no photo (--photo ID)")
    return photo, pixels


class _Geometry:
    def __init__(self, cam: ImageCamera) -> None:
        self.K = np.asarray(cam.K, float)
        self.R = np.asarray(cam.R, float)
        self.C = np.asarray(cam.C, float)
        self.k1 = float(cam.k1)
        self.id = cam.id

    def ray(self, uv: Array) -> Array:
        return np.asarray(pixel_rays_world(self.K, self.R, np.asarray(uv, float), self.k1), float)

    def on_plane(self, uv: Array, point: Array, normal: Array, what: str) -> Array:
        d = self.ray(uv)
        den = float(d @ normal)
        if abs(den) < MIN_INCIDENCE:
            raise SingleViewError(f"photo '{self.id}': {what}: its ray runs along the plane, so it meets it nowhere")
        t = float((point - self.C) @ normal) / den
        if t <= 0:
            raise SingleViewError(f"photo '{self.id}': {what}: the plane lies behind the camera along its ray")
        return self.C + t * d

    def floor(self, uv: Array, what: str) -> Array:
        if not self.ray(uv)[2] < -MIN_FLOOR_SLOPE:
            raise SingleViewError(f"photo '{self.id}': {what}: pixel ({uv[0]:.1f}, {uv[1]:.1f}) lies on or above the "
                                  "horizon, so it cannot show a point of the floor; click where it touches the floor")
        return self.on_plane(uv, np.zeros(3), np.array([0.0, 0.0, 1.0]), what)

    def above(self, foot: Array, uv: Array) -> Array:
        """The point of the vertical through ``foot`` nearest the ray of ``uv``."""
        d = self.ray(uv)
        A = np.column_stack([[0.0, 0.0, 1.0], -d])
        (s, _), *_ = np.linalg.lstsq(A, self.C - foot, rcond=None)
        return foot + np.array([0.0, 0.0, float(s)])


def measured_lines(cam: ImageCamera, kind: str, pixels: Sequence[float]) -> list[MeasuredLine]:
    """The line of each measurement in a single-view command's pixels (groups of the kind's clicks)."""
    n = len(SINGLE_VIEW_CLICKS[kind])
    if not pixels or len(pixels) % (2 * n):
        raise SingleViewError(f"{kind}: expected pixels in groups of {2 * n} ({n} clicks of U V each), got "
                              f"{len(pixels)} numbers")
    g = _Geometry(cam)
    up = np.array([0.0, 0.0, 1.0])
    out = []
    for k in range(0, len(pixels), 2 * n):
        c = np.asarray(pixels[k:k + 2 * n], float).reshape(n, 2)
        if kind == "photo-height":
            foot = g.floor(c[0], "the foot")
            ends, quantity = np.array([foot, g.above(foot, c[1])]), "height"
        elif kind == "floor-distance":
            ends, quantity = np.array([g.floor(c[0], "the first point"), g.floor(c[1], "the second point")]), "distance"
        elif kind == "wall-length":
            a, b = g.floor(c[0], "the wall's first floor point"), g.floor(c[1], "the wall's second floor point")
            normal = np.cross(b - a, up)
            if np.linalg.norm(normal) < 1e-12:
                raise SingleViewError(f"photo '{g.id}': the wall's two floor points coincide: they fix no wall")
            normal /= np.linalg.norm(normal)
            ends = np.array([g.on_plane(c[2], a, normal, "the length's first end"),
                             g.on_plane(c[3], a, normal, "its second end")])
            quantity = "distance"
        elif kind == "raised-height":
            edge = g.above(g.floor(c[0], "the raised surface's floor point"), c[1])
            foot = g.on_plane(c[2], edge, up, "the foot on the raised surface")
            ends, quantity = np.array([foot, g.above(foot, c[3])]), "height"
        else:  # plane-length
            pts = []
            for j in range(3):
                foot = g.floor(c[2 * j], f"point {j + 1}'s floor foot")
                pts.append(foot if np.allclose(c[2 * j], c[2 * j + 1]) else g.above(foot, c[2 * j + 1]))
            normal = np.cross(pts[1] - pts[0], pts[2] - pts[0])
            if np.linalg.norm(normal) < 1e-12:
                raise SingleViewError(f"photo '{g.id}': the plane's three points lie on one line: they fix no plane")
            normal /= np.linalg.norm(normal)
            ends = np.array([g.on_plane(c[6], pts[0], normal, "the length's first end"),
                             g.on_plane(c[7], pts[0], normal, "its second end")])
            quantity = "distance"
        out.append(MeasuredLine(kind, quantity, ends, c))
    return out


def line_length_agrees(line: MeasuredLine, value: float) -> bool:
    """Whether the drawn line is as long as the measured value (the height for a height)."""
    length = line.length if line.quantity == "distance" else float(line.ends[1][2] - line.ends[0][2])
    return abs(length - value) <= AGREE_REL * max(abs(value), 1e-9) + 1e-9
