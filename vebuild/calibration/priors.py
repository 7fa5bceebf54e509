"""What is known about a photo's camera before its calibration: priors with their 1σ and source.

A focal length (from the user, or EXIF with a sensor size) and a lens distortion (from a lens
profile, or the user) enter the vanishing-point calibration as Gaussian priors; ``source`` says
where each came from, for the calibration's mode reason and report.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from vebuild.errors import CalibrationError

#: Default 1σ of the prior that pulls the principal point toward the image centre, as a fraction
#: of the image's longer side (per coordinate). Real cameras do not put it at the centre: the
#: calibrated camera of a public set of real photographs has its calibrated principal point 17 px (2.7 % of the 640 px
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


def check_focal_prior(photo: str, name: str, prior: FocalPrior | None) -> None:
    """Refuse a focal length given as a prior that is not a positive length with a positive 1σ;
    ``name`` says where it came from (``focal_px``, ``the EXIF focal length``)."""
    if prior is not None and not (np.isfinite(prior.value) and prior.value > 0 and np.isfinite(prior.sigma)
                                  and prior.sigma > 0):
        raise CalibrationError(photo, f"{name}: expected a focal length > 0 px with a σ > 0 px, got "
                               f"{prior.value!r} ± {prior.sigma!r}")


def check_principal_point(photo: str, principal_point: tuple[ArrayLike, float] | None) -> None:
    """Refuse a principal point given as a prior that is not a finite (u, v) with a positive 1σ."""
    if principal_point is not None and not (np.all(np.isfinite(np.asarray(principal_point[0], float)))
                                            and np.isfinite(principal_point[1]) and principal_point[1] > 0):
        raise CalibrationError(photo, f"principal_point: expected a finite (u, v) with a σ > 0 px, got "
                               f"{principal_point[0]!r} ± {principal_point[1]!r}")


@dataclass(frozen=True)
class ExifCheck:
    """A photo's EXIF focal length compared with what its vanishing points alone give.

    The sign convention, the same in every record, table and message: EXIF relative to the
    vanishing points' estimate, ``difference_rel = (f_EXIF − f_lines) / f_lines`` (positive where
    EXIF says longer).

    ``sigmas`` is how many σ apart the two are, the smaller of two measures that agree for Gaussian
    estimates: √T, with T the likelihood-ratio statistic (the least-squares cost of the photo with
    EXIF's prior less its cost without it, over the marks' variance factor where they fit worse
    than the click noise), and |f_EXIF − f_lines| / √(σ_EXIF² + σ_lines²). Where the lines fix f
    weakly their likelihood is skewed (a frontal view's f grows far more readily than it shrinks),
    and either alone can call an honest EXIF contradicted. ``lines_sigma_px`` is the wider of the
    lines' linearised 1σ at their own estimate and at EXIF's. ``sigma_rel``, the 1σ of
    ``difference_rel``, is |difference_rel| / ``sigmas``. ``combined``: whether the calibration
    combined EXIF with the lines.
    """

    exif: FocalPrior
    lines_px: float
    lines_sigma_px: float
    sigmas: float
    combined: bool

    @property
    def difference_rel(self) -> float:
        return (self.exif.value - self.lines_px) / self.lines_px

    @property
    def sigma_rel(self) -> float:
        if self.sigmas > 0:
            return abs(self.difference_rel) / self.sigmas
        return float(np.hypot(self.exif.sigma, self.lines_sigma_px)) / self.lines_px
