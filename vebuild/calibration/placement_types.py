"""What the joint placement of cameras and markers takes and gives (:mod:`.positions`).

The photos' calibrations and clicked markers in (:class:`PhotoInput`, :class:`CameraGroupPrior`,
:class:`ReferenceDistance`), the cameras, markers and measured distances out (:class:`Placement`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


@dataclass(frozen=True)
class PhotoInput:
    """What placement needs from one calibrated photo.

    covariance : (6, 6) over (f, cx, cy, ω) from the vanishing-point calibration, or (7, 7) with
        the lens distortion k1 last: then k1 is refined too, held by that prior.
    markers : marker name → observed pixel (u, v), as the lens put it.
    k1 : the lens distortion (the division model of vebuild/camera.py; 0 for a pinhole); every
        marker is projected through it. ``k1_sigma``: its 1σ where it is held fixed (reported).
    """

    id: str
    K: Array
    R: Array
    covariance: Array
    markers: Mapping[str, Array]
    k1: float = 0.0
    k1_sigma: float = 0.0
    #: the lens's second term (camera.Lens; 0 for the one-term model): held as calibrated
    k2: float = 0.0
    #: the half diagonal of the photo in pixels (0: not known), for the range of real lenses' k1
    corner_px: float = 0.0


@dataclass(frozen=True)
class CameraGroupPrior:
    """Photos of one camera (.shared_camera) placed with one set of intrinsics: their ids and the
    joint covariance of the shared (f, cx, cy[, k1]) and each photo's ω, in that order. It replaces
    their own priors (the shared intrinsics held once, not once per photo); each photo's are tied to
    the first's within :data:`TIE_SIGMA_PX`."""

    photos: tuple[str, ...]
    covariance: Array


#: How closely a camera group's photos keep one f and principal point in placement, pixels (k1:
#: TIE_SIGMA_K1): equal well below what any figure is printed to.
TIE_SIGMA_PX = 1e-3
TIE_SIGMA_K1 = 1e-8


@dataclass(frozen=True)
class ReferenceDistance:
    a: str
    b: str
    distance: float
    sigma: float = 0.002
    role: str = "scale"  # "scale" fixes the scale; "check" is only reported


@dataclass(frozen=True)
class PlacedCamera:
    """covariance : (9, 9) over (f, cx, cy, ωx, ωy, ωz, Cx, Cy, Cz), R_true = exp([ω]×) R.
    k1, k1_sigma : the lens distortion (refined where the photo's covariance held it) and its 1σ."""

    id: str
    K: Array
    R: Array
    C: Array
    covariance: Array
    marker_residuals_px: dict[str, Array]
    outliers: list[str] = field(default_factory=list)
    k1: float = 0.0
    k1_sigma: float = 0.0
    #: the lens's second term, as calibrated (placement holds it)
    k2: float = 0.0
    #: each outlier's offset (px) from where the other observations put it (its deleted residual)
    outlier_offsets_px: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class MeasuredDistance:
    reference: ReferenceDistance
    measured: float
    measured_sigma: float


@dataclass(frozen=True)
class Placement:
    cameras: dict[str, PlacedCamera]
    markers: dict[str, tuple[Array, Array]]  # name → (position, 3×3 covariance)
    distances: list[MeasuredDistance]
    origin: str
    variance_factor: float
    #: photo id → (camera height above the floor, 1σ) each photo's own scale gave (``camera_heights``)
    camera_heights: dict[str, tuple[float, float]] = field(default_factory=dict)
    #: what the placement's own checks found (:mod:`.placement_checks`), one sentence each
    warnings: list[str] = field(default_factory=list)
    #: photo id → the factor its σ were widened by, where its markers contradicted its prior
    widened: dict[str, float] = field(default_factory=dict)
    #: photo id → its vanishing-point prior's variance factor, where its markers contradicted it
    prior_factors: dict[str, float] = field(default_factory=dict)
    #: the placement before any prior was widened (where one was): the turned-photo test
    #: (vebuild.actions.orientation) looks there, since a widened prior lets markers turn a camera
    unwidened: Placement | None = None
