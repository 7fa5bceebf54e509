"""What `vebuild detect` proposes and what it groups a photo's edges into (:mod:`.detect`).

Apart from the detection so that its checks (:mod:`.detect_checks`) and the choice of x
(:mod:`.x_axis`) can name them without importing the detection itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vebuild.calibration.lines import orient_axes


@dataclass(frozen=True)
class SegmentProposal:
    axis: str                                   # 'x', 'y' or 'z'
    segment: tuple[float, float, float, float]  # u1, v1, u2, v2 in photo pixels, directed (DESIGN.md)
    sigma_px: float                             # its end points' measured 1σ
    score: float                                # agreement with its vanishing point (higher is better)
    points: tuple[float, ...] = ()              # what is written: a polyline u1, v1, ..., un, vn along the
                                                # edge (directed; sigma_px is each point's 1σ); () = segment


@dataclass(frozen=True)
class PhotoProposals:
    photo: str                                  # the photo's id
    segments: tuple[SegmentProposal, ...]
    focal_px: float | None                      # the grouping's focal estimate, if any
    message: str                                # what was found, or why nothing
    directions: tuple[tuple[float, float, float], ...] = ()  # the vanishing directions the message
                                                # names, unit, camera frame (principal point at the
                                                # centre; the grouping's f, or EXIF's for a photo
                                                # showing one direction), up to sign; () = none


@dataclass(frozen=True)
class Grouped:
    """A photo's edges grouped into vanishing directions, before any choice of x."""
    pid: str
    width: int
    height: int
    found: Any                                  # lines.DetectedLines
    segs: np.ndarray                            # the segments as grouped (undistorted by k1)
    k1: float
    f0: float                                   # the focal length the undistortion used
    frame: Any                                  # lines.ManhattanFrame, or None
    elapsed: float
    failure: PhotoProposals | None              # nothing to propose, and why
    f_exif: float | None = None                 # EXIF's focal length, where it gives one
    left_out: tuple[int, int, int] = (0, 0, 0)  # edges not grouped: short, in texture, curved

    def rotation(self, x_axis: str) -> np.ndarray:
        """World → camera rotation for a choice of x (its columns: world x, y, z in the camera)."""
        return orient_axes(self.frame.directions, x_axis)[0]
