"""A person's height from one calibrated still, by single-view metrology
(:mod:`vebuild.analysis.single_view`, whose camera, lens and propagation it uses).

The user clicks the **top of the head**, then the **foot point**: the point on the floor between
the feet, or each foot where it meets the floor (the foot point is then their midpoint). The foot
point's ray meets the floor (z = 0, or a stated floor height for a person standing on a step or a
platform); the vertical through it rises to where the head-top's ray passes nearest: its rise is
the **height in the image**, the figure's sole-to-head-top line as the frame shows it.

The height estimate adds the allowances the user enters (:mod:`vebuild.analysis.person_terms`):
height = image height − footwear − head covering + stance and stride + head-top visibility, with
σ² = the metrology's σ² (the camera's 9×9 covariance, the lens' σ, every click's σ) + Σ each
allowance's σ². It is the height of the figure in that frame as imaged, not the person's
documented standing height. Several frames of one person are combined in
:mod:`vebuild.analysis.person_combine`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.camera import ImageCamera
from vebuild.constants import Z95

from .person_terms import Term, not_entered
from .single_view import SingleViewError, _Cam, _camera, _check_on_photo, _measure, _Plane

Array = NDArray[np.float64]

#: The points clicked for one person-height, in order: the head-top and the foot point, or the
#: head-top and each foot (``--feet``).
PERSON_CLICKS = ("the top of the head", "the point between the feet on the floor")
PERSON_FEET_CLICKS = ("the top of the head", "the left foot on the floor", "the right foot on the floor")
#: What the figure is, in the words of every table and report.
WHAT_IT_IS = ("the height of the figure in that frame as imaged (the floor under its feet to the top of its head, "
              "with the allowances entered), not the person's documented standing height")


@dataclass(frozen=True)
class PersonFrame:
    """One person-height measured on one frame (photo): the clicks (head-top first), the height in
    the image with the 1σ of the calibration (camera and lens) and of the clicks, the allowances
    entered, and the world points of the vertical measured (its foot on the floor, its top)."""

    photo: str
    person: str | None
    clicks: Array  # (2, 2) or (3, 2): head-top, then the foot point or the two feet
    floor_height: float
    image_height: float
    sigma_calibration: float
    sigma_clicks: float
    terms: tuple[Term, ...]
    foot: Array  # (3,) the foot point on the floor
    top: Array  # (3,) the top of the vertical through it
    click_sigma_px: float = 1.0  # each click's 1σ, per coordinate
    #: The calibration the frame's camera shares with other frames' (the photo's own, or the first
    #: still of a fixed camera whose stills are calibrated as one): "" for the photo's own.
    camera: str = ""

    @property
    def calibrated_as(self) -> str:
        """Frames with the same ``calibrated_as`` share one calibration's error."""
        return self.camera or self.photo

    @property
    def sigma_image(self) -> float:
        """The metrology's 1σ of the height in the image."""
        return float(np.hypot(self.sigma_calibration, self.sigma_clicks))

    @property
    def value(self) -> float:
        """The height estimate: the height in the image with every allowance entered."""
        return self.image_height + sum(t.signed for t in self.terms)

    @property
    def sigma(self) -> float:
        return float(np.sqrt(self.sigma_image**2 + sum(t.sigma**2 for t in self.terms)))

    @property
    def ci95(self) -> tuple[float, float]:
        return self.value - Z95 * self.sigma, self.value + Z95 * self.sigma

    def to_json(self) -> dict[str, object]:
        lo, hi = self.ci95
        return {"photo": self.photo, "person": self.person, "clicks_px": self.clicks.tolist(),
                "floor_height_m": self.floor_height, "image_height_m": self.image_height,
                "sigma_image_m": self.sigma_image, "sigma_calibration_m": self.sigma_calibration,
                "sigma_clicks_m": self.sigma_clicks, "click_sigma_px": self.click_sigma_px,
                "terms": [t.to_json() for t in self.terms],
                "no_allowance_for": not_entered(self.terms), "value_m": self.value, "sigma_m": self.sigma,
                "ci95_m": [lo, hi], "foot_m": self.foot.tolist(), "top_m": self.top.tolist(), "what": WHAT_IT_IS}


def _foot_point(c: _Cam, uv: Array, floor_height: float) -> Array:
    """The foot point: the floor point of the one foot click, or the midpoint of the two feet's."""
    names = ("the point between the feet",) if len(uv) == 1 else ("the left foot", "the right foot")
    if floor_height == 0.0:
        pts = [c.floor(p, n) for p, n in zip(uv, names, strict=True)]
    else:
        if not floor_height < c.C[2]:
            raise SingleViewError(f"photo '{c.photo}': the floor height {floor_height:g} m lies at or above the "
                                  f"camera ({c.C[2]:.3g} m), so the photo cannot show the feet on it; check "
                                  "--floor-height")
        plane = _Plane(np.array([0.0, 0.0, 1.0]), floor_height, f"the floor at {floor_height:g} m")
        pts = [c.on_plane(p, plane, n) for p, n in zip(uv, names, strict=True)]
    return np.mean(pts, axis=0)


def _line(c: _Cam, uv: Array, floor_height: float) -> tuple[float, Array]:
    foot = _foot_point(c, uv[1:], floor_height)
    return c.height_above(foot, uv[0], "the top of the head"), foot


def measure_person(cam: ImageCamera, head: Sequence[float], feet: Sequence[Sequence[float]], *,
                   floor_height: float = 0.0, terms: Sequence[Term] = (), person: str | None = None,
                   click_sigma_px: float = 1.0, k1_sigma: float = 0.0, k2_sigma: float = 0.0,
                   k1_k2_correlation: float = 0.0) -> PersonFrame:
    """A person's height clicked on the photo of ``cam``: ``head`` the top of the head, ``feet``
    the foot point (one pixel) or the two feet (two), with the allowances ``terms`` (module
    docstring). Refusals (a click off the photo or above the horizon, the head below the feet, an
    undetermined calibration) are :class:`SingleViewError` sentences naming the photo and click."""
    if len(feet) not in (1, 2):
        raise SingleViewError(f"photo '{cam.id}': a person-height takes the foot point or the two feet, got "
                              f"{len(feet)} foot clicks")
    uv = np.array([head, *feet], dtype=float).reshape(-1, 2)
    names = PERSON_CLICKS if len(uv) == 2 else PERSON_FEET_CLICKS
    for p, name in zip(uv, names, strict=True):
        _check_on_photo(cam, p, name)
    if not np.isfinite(floor_height):
        raise SingleViewError(f"photo '{cam.id}': --floor-height {floor_height}: expected the floor's height in "
                              "metres, a number")
    lens_sigma = (k1_sigma, k2_sigma, k1_k2_correlation)
    total = _measure(cam, uv, lambda c, p: _line(c, p, floor_height)[0], click_sigma_px, *lens_sigma)
    h, s_total = total
    if not h > 0:
        raise SingleViewError(f"photo '{cam.id}': the top of the head ({uv[0][0]:g}, {uv[0][1]:g}) lies "
                              f"{-h:.3f} m below the foot point, not above it; click the top of the head first, "
                              "then the feet")
    if not np.isfinite(s_total):
        raise SingleViewError(f"photo '{cam.id}': its calibration leaves the scale undetermined, so no height "
                              "measured on it has an uncertainty; give the photo a known length or the camera's "
                              "height and calibrate again")
    _, s_cal = _measure(cam, uv, lambda c, p: _line(c, p, floor_height)[0], 0.0, *lens_sigma)
    s_clicks = float(np.sqrt(max(s_total**2 - s_cal**2, 0.0)))
    K = np.asarray(cam.K, float)
    p0 = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0, np.asarray(cam.C, float), cam.lens.k1, cam.lens.k2]
    _, foot = _line(_camera(cam, p0), uv, floor_height)
    return PersonFrame(cam.id, person, uv, floor_height, h, s_cal, s_clicks, tuple(terms), foot,
                       foot + np.array([0.0, 0.0, h]), click_sigma_px)
