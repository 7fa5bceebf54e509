"""Single-view metrology (Criminisi, Reid & Zisserman, IJCV 2000): lengths measured on one
calibrated photo against the floor, the reference plane (z = 0).

- the **height** of a point above the floor: the user clicks its foot (where the vertical through
  it meets the floor) and the point itself; the foot's ray meets the floor at F, and the height is
  where the point's ray passes nearest the vertical through F;
- the **distance** between two points on the floor: each click's ray meets the floor.

No model and no solve are needed: only the photo's camera (K, R, C and its lens distortion k1),
whose 9×9 covariance over (f, cx, cy, ω, C) carries the calibration's uncertainty and, for a photo
placed alone, its scale's (the camera's height came from a known length, a camera height or a
floor distance; vebuild/calibration/single_photo.py), with their correlations.

Uncertainty: first order over every input at once, σ² = J Σ Jᵀ, with J by central differences over
(f, cx, cy, ω, C), k1 and the clicks; Σ the camera's covariance, k1's 1σ (the distortion record's,
independent of the rest) and each click's 1σ per coordinate (``settings.click_sigma_px``). Several
measurements on one photo are correlated through the camera; each is reported with its own 1σ.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..calibration.lsq import numeric_jacobian
from ..camera import ImageCamera, exp_so3, intrinsic_matrix, pixel_rays_world
from ..errors import VebuildError
from .measure import Measurement

Array = NDArray[np.float64]

#: A ray whose downward slope (|d_z|) is below this meets the floor more than 1000 camera heights
#: away, or not at all: the pixel lies at or above the horizon.
MIN_FLOOR_SLOPE = 1e-3
#: Finite-difference steps: pixels, radians, metres, k1.
STEPS = {"px": 1e-3, "rad": 1e-7, "m": 1e-6, "k1": 1e-7}


class SingleViewError(VebuildError):
    """A click that cannot be measured on the photo (above the horizon, outside the photo)."""


#: The single-view measurements, each a `vebuild analyse KIND --photo ID U1 V1 U2 V2 …` command:
#: the points a user clicks for one measurement, in order, one pixel (U V) each. The modelling
#: screen prompts with these words and saves the command (:func:`single_view_command`), so the
#: command line reproduces what was clicked to the last digit.
SINGLE_VIEW_CLICKS: dict[str, tuple[str, ...]] = {
    "photo-height": ("its foot on the floor", "its top"),
    "floor-distance": ("the first point on the floor", "the second point on the floor"),
    "wall-length": ("a point where the wall meets the floor", "another point where the wall meets the floor",
                    "the length's first end, on the wall", "its second end, on the wall"),
    "raised-height": ("a point on the raised surface's edge: the floor below it", "that point on the raised surface",
                      "the foot, on the raised surface", "the top"),
    "plane-length": ("the plane's first point: the floor below it (the point itself if on the floor)",
                     "the plane's first point", "its second point: the floor below it", "its second point",
                     "its third point: the floor below it", "its third point",
                     "the length's first end, on the plane", "its second end, on the plane"),
}
#: Decimal places of a clicked pixel in a saved command (1/100 px: far below any click's σ).
PIXEL_DECIMALS = 2


def single_view_command(kind: str, photo: str, clicks: Sequence[Sequence[float]]) -> list[str]:
    """The `vebuild analyse` words of one single-view measurement clicked at ``clicks`` (pixels, in
    :data:`SINGLE_VIEW_CLICKS` order), rounded as saved: measure from these words, not the clicks."""
    if kind not in SINGLE_VIEW_CLICKS:
        raise SingleViewError(f"no single-view measurement '{kind}'; they are {', '.join(SINGLE_VIEW_CLICKS)}")
    want = len(SINGLE_VIEW_CLICKS[kind])
    if len(clicks) != want:
        raise SingleViewError(f"a {kind} takes {want} clicked points, got {len(clicks)}")
    words = [kind, "--photo", photo]
    for u, v in clicks:
        words += [f"{float(u):.{PIXEL_DECIMALS}f}", f"{float(v):.{PIXEL_DECIMALS}f}"]
    return words


@dataclass(frozen=True)
class _Cam:
    K: Array
    R: Array
    C: Array
    k1: float
    photo: str

    def ray(self, uv: Array) -> Array:
        return pixel_rays_world(self.K, self.R, uv, self.k1)

    def floor(self, uv: Array, what: str) -> Array:
        if not self.C[2] > 0:
            raise SingleViewError(f"photo '{self.photo}': its camera is not above the floor (z = {self.C[2]:.3g}), "
                                  "so nothing in it can be measured against the floor; calibrate it with the floor "
                                  "at z = 0")
        d = self.ray(uv)
        if not d[2] < -MIN_FLOOR_SLOPE:
            raise SingleViewError(f"photo '{self.photo}': {what}: pixel ({uv[0]:.1f}, {uv[1]:.1f}) lies on or above "
                                  "the horizon, so it cannot show a point of the floor; click where it touches the "
                                  "floor")
        return self.C + d * (-self.C[2] / d[2])

    def height_above(self, foot: Array, uv: Array, what: str) -> float:
        d = self.ray(uv)
        A = np.column_stack([[0.0, 0.0, 1.0], -d])
        (s, t), *_ = np.linalg.lstsq(A, self.C - foot, rcond=None)
        if t <= 0:
            raise SingleViewError(f"photo '{self.photo}': {what}: the point lies behind the camera; check its click")
        return float(s)


def _camera(cam: ImageCamera, p: Array) -> _Cam:
    return _Cam(intrinsic_matrix(p[0], p[1], p[2]), exp_so3(p[3:6]) @ np.asarray(cam.R, float),
                np.asarray(p[6:9], float), float(p[9]), cam.id)


def _check_on_photo(cam: ImageCamera, uv: Array, what: str) -> None:
    if not (np.all(np.isfinite(uv)) and 0 <= uv[0] <= cam.width and 0 <= uv[1] <= cam.height):
        raise SingleViewError(f"photo '{cam.id}': {what}: pixel ({uv[0]:g}, {uv[1]:g}) lies outside the "
                              f"{cam.width}×{cam.height} photo; expected a pixel on it")


def _measure(cam: ImageCamera, clicks: Array, fn: Callable[[_Cam, Array], float], click_sigma_px: float,
             k1_sigma: float) -> tuple[float, float]:
    """Value and first-order 1σ of ``fn(camera, clicks)`` over the camera, k1 and the clicks."""
    if cam.covariance is None:
        raise SingleViewError(f"photo '{cam.id}': its camera has no covariance; run `vebuild calibrate` again")
    K = np.asarray(cam.K, float)
    p0 = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0, np.asarray(cam.C, float), cam.k1, clicks.ravel()]
    n_c = clicks.size
    cov = np.zeros((len(p0), len(p0)))
    c9 = np.asarray(cam.covariance, float)
    determined = bool(np.all(np.isfinite(c9)))  # else a quantity the data left undetermined: σ infinite
    cov[:9, :9] = np.where(np.isfinite(c9), c9, 0.0)
    cov[9, 9] = k1_sigma**2
    cov[10:, 10:] = np.eye(n_c) * click_sigma_px**2
    steps = np.r_[[STEPS["px"]] * 3, [STEPS["rad"]] * 3, [STEPS["m"]] * 3, STEPS["k1"], [STEPS["px"]] * n_c]

    def f(p: Array) -> Array:
        return np.array([fn(_camera(cam, p), p[10:].reshape(clicks.shape))])

    value = float(f(p0)[0])
    J = numeric_jacobian(f, p0, steps)
    return value, float(np.sqrt(max(float((J @ cov @ J.T)[0, 0]), 0.0))) if determined else np.inf


def height_on_photo(cam: ImageCamera, foot: Sequence[float], top: Sequence[float], *, click_sigma_px: float = 1.0,
                    k1_sigma: float = 0.0) -> Measurement:
    """The height above the floor of the point clicked at ``top``, standing over the floor point
    clicked at ``foot``, with its first-order 1σ (module docstring)."""
    clicks = np.array([foot, top], float)
    _check_on_photo(cam, clicks[0], "the foot")
    _check_on_photo(cam, clicks[1], "the top")

    def height(c: _Cam, uv: Array) -> float:
        return c.height_above(c.floor(uv[0], "the foot"), uv[1], "the top")

    v, s = _measure(cam, clicks, height, click_sigma_px, k1_sigma)
    pts = [{"point": f"photo {cam.id} pixel ({clicks[k][0]:g}, {clicks[k][1]:g})", "kind": k_name}
           for k, k_name in enumerate(("foot on the floor", "top"))]
    return Measurement("height", f"photo {cam.id}: ({top[0]:g}, {top[1]:g}) above its foot ({foot[0]:g}, "
                       f"{foot[1]:g}) on the floor", v, s, photos=[cam.id], points=pts,
                       source=f"single view (photo '{cam.id}')")


def floor_distance_on_photo(cam: ImageCamera, a: Sequence[float], b: Sequence[float], *, click_sigma_px: float = 1.0,
                            k1_sigma: float = 0.0) -> Measurement:
    """The distance between the two floor points clicked at ``a`` and ``b``, with its first-order
    1σ (module docstring)."""
    clicks = np.array([a, b], float)
    _check_on_photo(cam, clicks[0], "the first point")
    _check_on_photo(cam, clicks[1], "the second point")

    def dist(c: _Cam, uv: Array) -> float:
        return float(np.linalg.norm(c.floor(uv[0], "the first point") - c.floor(uv[1], "the second point")))

    v, s = _measure(cam, clicks, dist, click_sigma_px, k1_sigma)
    pts = [{"point": f"photo {cam.id} pixel ({p[0]:g}, {p[1]:g})", "kind": "on the floor"} for p in clicks]
    return Measurement("distance", f"photo {cam.id}: ({a[0]:g}, {a[1]:g}) to ({b[0]:g}, {b[1]:g}) on the floor", v, s,
                       photos=[cam.id], points=pts, source=f"single view (photo '{cam.id}')")
