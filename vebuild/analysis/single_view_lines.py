"""Where a saved single-view measurement lies in the world: the two 3-D ends of the line it
measures, for drawing it in the hand-offs (the camera-only glTF, the web viewer).

A single-view measurement (:mod:`vebuild.analysis.single_view`) is saved as the words of a
``vebuild analyse KIND --photo ID U1 V1 …`` command (:data:`SINGLE_VIEW_CLICKS` gives each kind's
clicks, in order). Its figures (value, 1σ, 95 % interval) come from running those words; this
module only places its line, from the same clicks and the photo's camera (K, R, C and k1):

a height's foot and the point above it, a distance's or a length's two ends, by the geometry
that measures it (:func:`vebuild.analysis.single_view.measured_line`).

The length of the line drawn is checked against the measured value by the caller
(:func:`line_length_agrees`): a drawing that does not show the measured figure is refused.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera

from .single_view import SINGLE_VIEW_CLICKS, SingleViewError, measured_line

Array = NDArray[np.float64]

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


#: The kinds whose value is a height (the line's rise); the others measure the line's length.
HEIGHT_KINDS = ("photo-height", "raised-height")


def measured_lines(cam: ImageCamera, kind: str, pixels: Sequence[float]) -> list[MeasuredLine]:
    """The line of each measurement in a single-view command's pixels (groups of the kind's clicks),
    placed by the very geometry that measures it (:func:`~.single_view.measured_line`)."""
    n = len(SINGLE_VIEW_CLICKS[kind])
    if not pixels or len(pixels) % (2 * n):
        raise SingleViewError(f"{kind}: expected pixels in groups of {2 * n} ({n} clicks of U V each), got "
                              f"{len(pixels)} numbers")
    quantity = "height" if kind in HEIGHT_KINDS else "distance"
    out = []
    for k in range(0, len(pixels), 2 * n):
        c = np.asarray(pixels[k:k + 2 * n], float).reshape(n, 2)
        out.append(MeasuredLine(kind, quantity, np.asarray(measured_line(cam, kind, c.tolist()), dtype=np.float64), c))
    return out


def line_length_agrees(line: MeasuredLine, value: float) -> bool:
    """Whether the drawn line is as long as the measured value (the height for a height)."""
    length = line.length if line.quantity == "distance" else float(line.ends[1][2] - line.ends[0][2])
    return abs(length - value) <= AGREE_REL * max(abs(value), 1e-9) + 1e-9
