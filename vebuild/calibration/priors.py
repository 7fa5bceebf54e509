"""What is known about a photo's camera before its calibration: priors with their 1σ and source.

A focal length (from the user, or EXIF with a sensor size) and a lens distortion (from a lens
profile, or the user) enter the vanishing-point calibration as Gaussian priors; ``source`` says
where each came from, for the calibration's mode reason and report.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FocalPrior:
    """A focal length known before calibration: value and 1σ in pixels, and where it came from."""

    value: float
    sigma: float
    source: str  # "user" or "exif" (possibly with detail: "exif (35 mm equivalent)")


@dataclass(frozen=True)
class DistortionPrior:
    """A lens distortion known before calibration: the division model's k1 (vebuild/camera.py)
    and its 1σ, and where it came from (``"lens profile: <lens>"``, ``"user"``)."""

    k1: float
    sigma: float
    source: str
