"""The true lenses of the generated CCTV cameras (:mod:`vebuild.synthetic.cctv`): models that are
not vebuild's own (the division model of :mod:`vebuild.camera`), written out here apart from it.

- ``equidistant`` fisheye: a ray θ off the optical axis lands r = f θ from the principal point;
- ``equisolid`` fisheye: r = 2 f sin(θ / 2);
- ``rectilinear`` wide lens with a little barrel distortion (Brown's polynomial, one term):
  r = f r_u (1 + a r_u²), r_u = tan θ, a < 0.

f is the focal length near the axis (each model's r ≈ f θ for small θ), so the pinhole K = [[f, 0,
cx], [0, f, cy], [0, 0, 1]] is the lens's "K-equivalent": the camera vebuild's model would be
with its distortion taken away. The lens's **corner displacement** is what vebuild reports for its
own lens (vebuild.camera.distortion_displacement_px): the largest distance, over the photo's four
corners, between a corner and where the K-equivalent pinhole would put that corner's ray.

Pixel coordinates put a pixel's centre at (column + ½, row + ½), as the ray-caster casts them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

LENS_KINDS = ("rectilinear", "equidistant", "equisolid")


class _Lens(Protocol):
    """What the two lenses share: a principal point, a focal length and the rays of pixels."""

    @property
    def c(self) -> tuple[float, float]: ...

    @property
    def f(self) -> float: ...

    def rays(self, uv: Array) -> Array: ...


def corner_displacement_px(lens: _Lens, width: int, height: int) -> float:
    """The largest distance from a corner of the photo to where the K-equivalent pinhole puts that
    corner's ray (module docstring)."""
    corners = np.array([[0.0, 0.0], [width, 0.0], [0.0, height], [width, height]])
    d = lens.rays(corners)
    pin = np.asarray(lens.c) + lens.f * d[:, :2] / d[:, 2:3]
    return float(np.max(np.linalg.norm(pin - corners, axis=1)))


def diagonal_fov_deg(lens: _Lens, width: int, height: int) -> float:
    """The field across the photo's diagonal: the angle between its two opposite corners' rays."""
    d = lens.rays(np.array([[0.0, 0.0], [width, height]]))
    return float(np.degrees(np.arccos(np.clip(d[0] @ d[1], -1.0, 1.0))))


@dataclass(frozen=True)
class TrueLens:
    """A lens of one of :data:`LENS_KINDS`: f (px), principal point c (px), ``barrel`` the
    rectilinear lens's a (0 for the fisheyes)."""

    kind: str
    f: float
    c: tuple[float, float]
    barrel: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in LENS_KINDS:
            raise ValueError(f"a lens is one of {', '.join(LENS_KINDS)}, got {self.kind!r}")

    @property
    def K(self) -> Array:
        """The K-equivalent (module docstring)."""
        return np.array([[self.f, 0.0, self.c[0]], [0.0, self.f, self.c[1]], [0.0, 0.0, 1.0]])

    def radius(self, theta: Array) -> Array:
        """Image radius (px) of rays θ (radians) off the axis."""
        theta = np.asarray(theta, float)
        if self.kind == "equidistant":
            return self.f * theta
        if self.kind == "equisolid":
            return 2.0 * self.f * np.sin(theta / 2.0)
        ru = np.tan(np.minimum(theta, np.radians(89.9)))
        r = self.f * ru * (1.0 + self.barrel * ru**2)
        # Beyond r_u² = 1 / (3 |a|) the polynomial turns back: no ray there reaches the sensor.
        return np.where(3.0 * self.barrel * ru**2 > -1.0, r, np.nan) if self.barrel < 0 else r

    def angle(self, r: Array) -> Array:
        """The ray's angle θ off the axis of image radius r (px): :meth:`radius` inverted."""
        r = np.asarray(r, float)
        if self.kind == "equidistant":
            return r / self.f
        if self.kind == "equisolid":
            return 2.0 * np.arcsin(np.clip(r / (2.0 * self.f), 0.0, 1.0))
        # r_d = r_u + a r_u³: Newton from r_u = r_d, monotone while 1 + 3 a r_u² > 0.
        rd = r / self.f
        ru = rd.copy()
        for _ in range(30):
            ru = ru - (ru + self.barrel * ru**3 - rd) / (1.0 + 3.0 * self.barrel * ru**2)
        return np.arctan(ru)

    def pixels(self, d_cam: Array) -> Array:
        """Pixels (n, 2) of camera-frame directions (n, 3) (x right, y down, z forward); NaN for
        rays the lens does not image (beyond the rectilinear lens's field)."""
        d = np.asarray(d_cam, float).reshape(-1, 3)
        rho = np.hypot(d[:, 0], d[:, 1])
        theta = np.arctan2(rho, d[:, 2])
        r = self.radius(theta)
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(rho > 0, r / np.where(rho > 0, rho, 1.0), 0.0)
        return np.asarray(self.c) + d[:, :2] * s[:, None]

    def rays(self, uv: Array) -> Array:
        """Unit camera-frame directions (..., 3) of pixels uv (..., 2)."""
        uv = np.asarray(uv, float)
        x = uv - np.asarray(self.c)
        r = np.hypot(x[..., 0], x[..., 1])
        theta = self.angle(r)
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(r > 0, np.sin(theta) / np.where(r > 0, r, 1.0), 0.0)
        return np.stack([x[..., 0] * s, x[..., 1] * s, np.cos(theta)], axis=-1)

    def corner_displacement_px(self, width: int, height: int) -> float:
        """The largest distance from a corner of the photo to where the K-equivalent pinhole puts
        that corner's ray (module docstring)."""
        return corner_displacement_px(self, width, height)

    def diagonal_fov_deg(self, width: int, height: int) -> float:
        """The field across the photo's diagonal: the angle between its two opposite corners' rays."""
        return diagonal_fov_deg(self, width, height)


def lens_for_field(kind: str, fov_deg: float, width: int, height: int, c: tuple[float, float],
                   barrel_corner_rel: float = 0.0) -> TrueLens:
    """The lens of ``kind`` whose half-diagonal (from the photo's centre) sees fov_deg / 2 off the
    axis. ``barrel_corner_rel`` (rectilinear only): how far the barrel pulls a corner in, as a
    share of where the pinhole would put it (a = −share / r_u²)."""
    half = np.radians(fov_deg) / 2.0
    rd = float(np.hypot(width, height) / 2.0)
    if kind == "rectilinear":
        ru = float(np.tan(half))
        a = -barrel_corner_rel / ru**2
        return TrueLens(kind, rd / (ru * (1.0 + a * ru**2)), c, a)
    unit = TrueLens(kind, 1.0, c)
    return TrueLens(kind, rd / float(unit.radius(np.array(half))), c)


@dataclass(frozen=True)
class DivisionLens:
    """vebuild's own lens model (the division model of vebuild.camera, written out here apart from
    it): x_u = x_d / (1 + k1 |x_d|²) in coordinates divided by f. The reference of the CCTV
    benchmark: the same scenes seen through the model vebuild fits."""

    f: float
    c: tuple[float, float]
    k1: float

    @property
    def K(self) -> Array:
        return np.array([[self.f, 0.0, self.c[0]], [0.0, self.f, self.c[1]], [0.0, 0.0, 1.0]])

    def pixels(self, d_cam: Array) -> Array:
        d = np.asarray(d_cam, float).reshape(-1, 3)
        with np.errstate(divide="ignore", invalid="ignore"):
            xu = d[:, :2] / d[:, 2:3]
        r2 = np.sum(xu**2, axis=1)
        xd = xu * (2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * self.k1 * r2, 0.0))))[:, None]
        return np.asarray(self.c) + self.f * xd

    def rays(self, uv: Array) -> Array:
        x = (np.asarray(uv, float) - np.asarray(self.c)) / self.f
        xu = x / (1.0 + self.k1 * np.sum(x**2, axis=-1))[..., None]
        d = np.concatenate([xu, np.ones(xu.shape[:-1] + (1,))], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def corner_displacement_px(self, width: int, height: int) -> float:
        return corner_displacement_px(self, width, height)

    def diagonal_fov_deg(self, width: int, height: int) -> float:
        return diagonal_fov_deg(self, width, height)


def matching_division_lens(lens: TrueLens, width: int, height: int) -> DivisionLens:
    """The division-model lens with the true lens's K-equivalent that moves the photo's farthest
    corner as far as the true lens does."""
    corners = np.array([[0.0, 0.0], [width, 0.0], [0.0, height], [width, height]])
    far = corners[int(np.argmax(np.linalg.norm(corners - np.asarray(lens.c), axis=1)))]
    d = lens.rays(far[None])[0]
    r_u = float(np.hypot(d[0], d[1]) / d[2])
    r_d = float(np.linalg.norm(far - np.asarray(lens.c))) / lens.f
    # x_u = x_d / (1 + k1 r_d²) at the corner: k1 = (r_d / r_u − 1) / r_d².
    return DivisionLens(lens.f, lens.c, (r_d / r_u - 1.0) / r_d**2)
