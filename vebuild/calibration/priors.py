"""What is known about a photo's camera before its calibration: priors with their 1σ and source.

A focal length (from the user, or EXIF with a sensor size) and a lens distortion (from a lens
profile, or the user) enter the vanishing-point calibration as Gaussian priors; ``source`` says
where each came from, for the calibration's mode reason and report.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Default 1σ of the prior that pulls the principal point toward the image centre, as a fraction
#: of the image's longer side (per coordinate). Real cameras do not put it at the centre: the
#: issue's set of real photographs has its calibrated principal point 17 px (2.7 % of the 640 px
#: side) from the centre, and sensor placement, cropping and image stabilisation move it by a few
#: per cent on other cameras. A 1σ of 1 % left 76 % of such points outside their 95 % interval;
#: at 3 % a 2.7 % offset is a 0.9σ draw, while three strong vanishing points (1σ of some 5–15 px
#: on a 1600 px photo) still move it where it is.
PRINCIPAL_POINT_SIGMA_REL = 0.03


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
