"""One photo placed alone: its camera in a world frame of the user's choice, at the user's scale.

A calibrated photo (K, R, k1 from its vanishing points) knows the direction of every pixel's ray
in the world, but not where the camera stands. On one photo the floor (z = 0) closes that gap
(single-view geometry, Criminisi, Reid & Zisserman, IJCV 2000): with the camera at height h above
the floor, a pixel known to show a floor point is the meeting of its ray with z = 0, and a
vertical segment standing on the floor has the height at which its top's ray passes the vertical
through its foot. Every such length is h times what it is at unit height, so one known length
gives h, and h gives every other length.

- The **origin** is a floor point the user chooses: a marker clicked in the photo (the origin
  marker lies at (0, 0, 0), on the floor by definition), or, with none, the foot of the camera's
  plumb line: the floor point straight below the camera, which stands at (0, 0, h). That origin
  needs no click and always exists, so a photo is placed whatever its marks (only its scale may be
  missing, and then lengths are relative).
- The **scale** (h) comes from any of: the camera's height above the floor; a known length on an
  axis-aligned segment (a vertical one standing on the floor, such as a door's height; or one along
  x or y on the floor, such as a tile's edge); a reference distance between two markers on the
  floor. Several are combined, each weighted by the inverse of its variance from its own clicks and
  tape; with none the camera's height is 1 and every length is relative.

The uncertainty is first order over every input at once: the calibration's (f, cx, cy, ω[, k1])
with its covariance, each click (1σ ``click_sigma_px`` per coordinate), each given length's or
height's 1σ; the Jacobian of the whole placement (the weights held at their values) by central
differences. The camera's 9×9 covariance over (f, cx, cy, ω, C) therefore holds the scale's and the
calibration's uncertainty and their correlation. The vanishing segments that fix the origin also
took part in the calibration; that correlation is neglected (their share of the calibration is one
segment among many).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from vebuild.camera import Lens, exp_so3, intrinsic_matrix, pixel_rays_world
from vebuild.errors import CalibrationError

from .lsq import numeric_jacobian

Array = NDArray[np.float64]

#: A ray whose downward slope (|d_z| of its unit direction) is below this meets the floor farther
#: than 1000 camera heights away, or not at all: the pixel lies at (or above) the horizon.
MIN_FLOOR_SLOPE = 1e-3
#: A scale source whose own camera height differs from the combined one by more than this many of
#: its σ is named in a warning: the user's lengths contradict each other.
SCALE_DISAGREEMENT_SIGMAS = 3.0
#: A known length along x or y whose two ends' floor points run more than this (degrees) off its
#: axis is named in a warning: with the ends ≥ 50 px apart and 1 px clicks the direction is good to
#: a degree or two, so 10° is a wrong axis (or an end off the floor), not noise.
KNOWN_LENGTH_AXIS_DEG = 10.0
#: The origin of a photo placed alone with no origin marker, in words.
BELOW_THE_CAMERA = "the floor point straight below the camera (the camera stands at x = y = 0)"
#: Finite-difference steps of the placement's Jacobian: pixels, radians, k1, metres.
STEP_PX, STEP_RAD, STEP_K1, STEP_M = 1e-3, 1e-7, 1e-7, 1e-6


@dataclass(frozen=True)
class CameraHeight:
    """The camera's height above the floor, metres, with its 1σ; ``where``: its JSON path."""

    value: float
    sigma: float
    where: str = "camera_height"


@dataclass(frozen=True)
class KnownLength:
    """A length known at the scene along a world axis, clicked in the photo.

    ``ends``: (2, 2) pixels of its two ends. Along ``z`` it stands on the floor: ``floor_end`` (0
    or 1) is the end clicked on the floor, the other its top. Along ``x`` or ``y`` it lies on the
    floor (both ends). ``where``: its JSON path, for messages.
    """

    axis: str
    ends: Array
    length: float
    sigma: float
    floor_end: int = 0
    where: str = "known_lengths"


@dataclass(frozen=True)
class FloorDistance:
    """A reference distance between two markers on the floor, each clicked in the photo."""

    a: str
    b: str
    uv_a: Array
    uv_b: Array
    distance: float
    sigma: float
    where: str = "reference_distances"


ScaleSource = CameraHeight | KnownLength | FloorDistance


@dataclass(frozen=True)
class Origin:
    """The floor point at the world origin: a marker and its click (``pixels`` (2,)), or, with no
    marker (``marker`` None, ``pixels`` empty), the floor point below the camera."""

    marker: str | None = None
    pixels: Array = field(default_factory=lambda: np.zeros(0))

    def describe(self) -> str:
        if self.marker is not None:
            return f"marker '{self.marker}'"
        return BELOW_THE_CAMERA


@dataclass(frozen=True)
class ScaleEstimate:
    """What one scale source says the camera's height is (metres, 1σ from its own clicks and tape)."""

    source: ScaleSource
    height: float
    sigma: float

    def describe(self) -> str:
        s = self.source
        if isinstance(s, CameraHeight):
            return f"the camera's height {s.value:g} ± {s.sigma:g} m ({s.where})"
        if isinstance(s, KnownLength):
            return f"the known length {s.length:g} ± {s.sigma:g} m along {s.axis} ({s.where})"
        return f"the distance {s.a}–{s.b} {s.distance:g} ± {s.sigma:g} m on the floor ({s.where})"


@dataclass(frozen=True)
class SinglePhotoPlacement:
    """A camera placed from its own photo alone.

    covariance : (9, 9) over (f, cx, cy, ωx, ωy, ωz, Cx, Cy, Cz), as a PlacedCamera's.
    camera_height, camera_height_sigma : h and its 1σ (metres; 1 and 0 when ``relative``).
    relative : no scale was given: lengths are in units of the camera's height.
    markers : floor markers placed by this photo: name → (position, 3×3 covariance).
    estimates : what each scale source said h is; ``warnings``: sources that contradict the others.
    """

    photo: str
    K: Array
    R: Array
    k1: float
    k1_sigma: float
    C: Array
    covariance: Array
    camera_height: float
    camera_height_sigma: float
    relative: bool
    origin: Origin
    markers: dict[str, tuple[Array, Array]]
    estimates: list[ScaleEstimate]
    marker_residuals_px: dict[str, Array] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    marker_covariance: Array = field(default_factory=lambda: np.zeros((0, 0)))

    def distance(self, a: str, b: str) -> tuple[float, float]:
        """The distance between two markers it placed (the origin marker among them) and its 1σ,
        from their joint covariance (they share the photo's scale and calibration)."""
        names = list(self.markers)
        pos = {n: self.markers[n][0] for n in names}
        if self.origin.marker is not None:
            pos[self.origin.marker] = np.zeros(3)
        diff = pos[a] - pos[b]
        d = float(np.linalg.norm(diff))
        g = np.zeros(3 * len(names))
        u = diff / max(d, 1e-12)
        for n, sign in ((a, 1.0), (b, -1.0)):
            if n in names:
                k = names.index(n)
                g[3 * k : 3 * k + 3] += sign * u
        return d, float(np.sqrt(max(float(g @ self.marker_covariance @ g), 0.0)))

    @property
    def scale_source(self) -> str:
        if self.relative:
            return "none: lengths are relative, in units of the camera's height above the floor"
        return "; ".join(e.describe() for e in self.estimates)


# -- geometry at unit camera height ----------------------------------------------------------------


class _Camera:
    """The calibrated camera of parameters q = (f, cx, cy, ω[, k1]), R = exp([ω]×) R̂, standing at
    (0, 0, 1): one unit above the floor point below it."""

    def __init__(self, q: Array, R0: Array, k1: float, photo: str, k2: float = 0.0):
        self.K = intrinsic_matrix(q[0], q[1], q[2])
        self.R = exp_so3(q[3:6]) @ R0
        self.k1 = float(q[6]) if len(q) > 6 else k1
        self.lens = Lens(self.k1, k2)  # k2 held as calibrated
        self.photo = photo

    def ray(self, uv: Array) -> Array:
        return pixel_rays_world(self.K, self.R, np.asarray(uv, float), self.lens)

    def floor(self, uv: Array, what: str) -> Array:
        """The floor point (z = 0) seen at pixel uv, the camera at (0, 0, 1)."""
        d = self.ray(uv)
        if not d[2] < -MIN_FLOOR_SLOPE:
            raise CalibrationError(self.photo, f"{what}: pixel ({uv[0]:.1f}, {uv[1]:.1f}) lies on or above the "
                                   "horizon, so it cannot show a point of the floor; click the point where it "
                                   "touches the floor")
        return np.array([0.0, 0.0, 1.0]) + d / -d[2]

    def height_above(self, foot: Array, uv_top: Array, what: str) -> float:
        """Height of the point seen at uv_top on the vertical through the floor point ``foot``:
        where the top's ray passes nearest that vertical line."""
        d = self.ray(uv_top)
        A = np.column_stack([[0.0, 0.0, 1.0], -d])
        if abs(np.linalg.det(A.T @ A)) < 1e-12:
            raise CalibrationError(self.photo, f"{what}: its top's ray runs along the vertical; click its top again")
        (s, t), *_ = np.linalg.lstsq(A, np.array([0.0, 0.0, 1.0]) - foot, rcond=None)
        if t <= 0:
            raise CalibrationError(self.photo, f"{what}: its top lies behind the camera; check its clicks")
        return float(s)


def unit_length(cam: _Camera, s: ScaleSource) -> float:
    """What the source's length is with the camera one unit above the floor."""
    if isinstance(s, KnownLength):
        ends = np.asarray(s.ends, float).reshape(2, 2)
        if s.axis == "z":
            foot = cam.floor(ends[s.floor_end], f"{s.where}: its end on the floor")
            h = cam.height_above(foot, ends[1 - s.floor_end], s.where)
            if h <= 0:
                raise CalibrationError(cam.photo, f"{s.where}: its top is at or below the floor where its foot is; "
                                       "check which end is on the floor (floor_end) and the clicks")
            return h
        a = cam.floor(ends[0], f"{s.where}: its first end")
        b = cam.floor(ends[1], f"{s.where}: its second end")
        return float(np.linalg.norm(a - b))
    if isinstance(s, FloorDistance):
        a = cam.floor(s.uv_a, f"{s.where}: marker '{s.a}'")
        b = cam.floor(s.uv_b, f"{s.where}: marker '{s.b}'")
        return float(np.linalg.norm(a - b))
    return 1.0


def _clicks(s: ScaleSource) -> Array:
    if isinstance(s, KnownLength):
        return np.asarray(s.ends, float).ravel()
    if isinstance(s, FloorDistance):
        return np.r_[np.asarray(s.uv_a, float), np.asarray(s.uv_b, float)]
    return np.zeros(0)


def _with_clicks(s: ScaleSource, z: Array, value: float) -> ScaleSource:
    if isinstance(s, KnownLength):
        return KnownLength(s.axis, z.reshape(2, 2), value, s.sigma, s.floor_end, s.where)
    if isinstance(s, FloorDistance):
        return FloorDistance(s.a, s.b, z[:2], z[2:], value, s.sigma, s.where)
    return CameraHeight(value, s.sigma, s.where)


def _value(s: ScaleSource) -> float:
    return s.value if isinstance(s, CameraHeight) else (s.length if isinstance(s, KnownLength) else s.distance)


def _height(cam: _Camera, s: ScaleSource) -> float:
    if isinstance(s, CameraHeight):
        return s.value
    u = unit_length(cam, s)
    return _value(s) / u if u > 0 else np.inf  # its two ends at one floor point: refused by the caller


# -- placement -------------------------------------------------------------------------------------


class _Inputs:
    """Every input of a placement in one vector z with its covariance and finite-difference steps:
    q (the calibration), the origin's clicks, each scale source's clicks and value, the floor
    markers' clicks."""

    def __init__(self, q0: Array, cov_q: Array, origin_px: Array, scales: Sequence[ScaleSource],
                 marker_px: Array, click_sigma_px: float):
        parts: list[tuple[Array, Array, float]] = [(q0, cov_q, STEP_PX)]
        parts.append((origin_px, np.eye(len(origin_px)) * click_sigma_px**2, STEP_PX))
        self.sources: list[tuple[slice, int]] = []
        i = len(q0) + len(origin_px)
        for s in scales:
            zc = _clicks(s)
            parts.append((zc, np.eye(len(zc)) * click_sigma_px**2, STEP_PX))
            parts.append((np.array([_value(s)]), np.array([[s.sigma**2]]), STEP_M))
            self.sources.append((slice(i, i + len(zc)), i + len(zc)))
            i += len(zc) + 1
        parts.append((marker_px, np.eye(len(marker_px)) * click_sigma_px**2, STEP_PX))
        self.n_q = len(q0)
        self.origin = slice(len(q0), len(q0) + len(origin_px))
        self.markers = slice(i, i + len(marker_px))
        self.z0 = np.concatenate([p[0] for p in parts])
        n = len(self.z0)
        self.cov = np.zeros((n, n))
        self.steps = np.zeros(n)
        j = 0
        for v, c, step in parts:
            self.cov[j : j + len(v), j : j + len(v)] = c
            self.steps[j : j + len(v)] = step
            j += len(v)
        self.steps[3:6] = STEP_RAD
        if self.n_q == 7:
            self.steps[6] = STEP_K1

    def heights(self, z: Array, cam: _Camera, scales: Sequence[ScaleSource]) -> Array:
        return np.array([_height(cam, _with_clicks(s, z[sl], float(z[iv])))
                         for s, (sl, iv) in zip(scales, self.sources, strict=True)])


def _calibration(K: ArrayLike, covariance: ArrayLike, k1: float) -> tuple[Array, Array]:
    K = np.asarray(K, float)
    cov_q = np.asarray(covariance, float)
    if cov_q.shape not in ((6, 6), (7, 7)):
        raise ValueError(f"the calibration covariance must be 6×6 or 7×7 (k1 last), got {cov_q.shape}")
    q0 = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0, [k1] if cov_q.shape == (7, 7) else []]
    return q0, cov_q


def scale_estimates(photo: str, K: ArrayLike, R: ArrayLike, scales: Sequence[ScaleSource], *, k1: float = 0.0,
                    k2: float = 0.0,
                    click_sigma_px: float = 1.0) -> list[ScaleEstimate]:
    """What each scale source alone says the camera's height is, with its 1σ from its own clicks
    and length (not the calibration's, which all share): the weights that combine them."""
    K, R0 = np.asarray(K, float), np.asarray(R, float)
    q0 = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0]
    cam0 = _Camera(q0, R0, k1, photo, k2)
    out = []
    for s in scales:
        h = _height(cam0, s)
        if not (np.isfinite(h) and h > 0):
            raise CalibrationError(photo, f"{s.where}: gives the camera a height of {h:g} m above the floor; "
                                   "expected a positive number: check its clicks and which end is on the floor")
        zc = _clicks(s)
        var = (h * s.sigma / _value(s)) ** 2
        if len(zc):
            def h_of(z: Array, s: ScaleSource = s) -> Array:
                return np.array([_height(cam0, _with_clicks(s, z, _value(s)))])

            var += float(np.sum(numeric_jacobian(h_of, zc, STEP_PX) ** 2)) * click_sigma_px**2
        out.append(ScaleEstimate(s, h, float(np.sqrt(var))))
    return out


def camera_height_estimate(
    photo: str, K: ArrayLike, R: ArrayLike, covariance: ArrayLike, scales: Sequence[ScaleSource], *,
    k1: float = 0.0, k2: float = 0.0, click_sigma_px: float = 1.0,
) -> tuple[float, float, list[ScaleEstimate]]:
    """The camera's height above the floor from the photo's own scale sources (at least one), its
    1σ first order over the calibration, the clicks and the lengths, and each source's estimate:
    how a photo placed with others brings its own scale to the joint placement (no origin needed)."""
    q0, cov_q = _calibration(K, covariance, k1)
    R0 = np.asarray(R, float)
    estimates = scale_estimates(photo, K, R0, scales, k1=k1, k2=k2, click_sigma_px=click_sigma_px)
    w = np.array([1.0 / e.sigma**2 for e in estimates])
    inp = _Inputs(q0, cov_q, np.zeros(0), scales, np.zeros(0), click_sigma_px)

    def h(z: Array) -> Array:
        return np.array([w @ inp.heights(z, _Camera(z[: inp.n_q], R0, k1, photo, k2), scales) / w.sum()])

    J = numeric_jacobian(h, inp.z0, inp.steps)
    return float(h(inp.z0)[0]), float(np.sqrt(max(float((J @ inp.cov @ J.T)[0, 0]), 0.0))), estimates


def place_single_photo(
    photo: str,
    K: ArrayLike,
    R: ArrayLike,
    covariance: ArrayLike,
    origin: Origin,
    scales: Sequence[ScaleSource] = (),
    floor_markers: Mapping[str, ArrayLike] | None = None,
    *,
    k1: float = 0.0, k2: float = 0.0,
    click_sigma_px: float = 1.0,
) -> SinglePhotoPlacement:
    """Place one calibrated photo alone (module docstring).

    covariance : (6, 6) over (f, cx, cy, ω), or (7, 7) with k1 last.
    floor_markers : markers on the floor clicked in this photo (name → pixel): placed too.
    Raises CalibrationError naming the photo and the mark when a pixel cannot lie on the floor.
    """
    R0 = np.asarray(R, float)
    q0, cov_q = _calibration(K, covariance, k1)
    markers_px = {n: np.asarray(uv, float) for n, uv in sorted((floor_markers or {}).items()) if n != origin.marker}
    skipped = []
    for n in list(markers_px):  # a floor marker clicked above the horizon is named, not placed
        try:
            _Camera(q0, R0, k1, photo, k2).floor(markers_px[n], f"marker '{n}' (on the floor)")
        except CalibrationError as err:
            skipped.append(f"{err} (it is not placed)")
            del markers_px[n]
    estimates = scale_estimates(photo, K, R0, scales, k1=k1, k2=k2, click_sigma_px=click_sigma_px)
    w = np.array([1.0 / e.sigma**2 for e in estimates])
    o_px = np.asarray(origin.pixels, float).ravel()
    m_px = np.concatenate([markers_px[n] for n in markers_px] or [np.zeros(0)])
    inp = _Inputs(q0, cov_q, o_px, scales, m_px, click_sigma_px)

    def solve(z: Array) -> Array:
        cam = _Camera(z[: inp.n_q], R0, k1, photo, k2)
        h = float(w @ inp.heights(z, cam, scales) / w.sum()) if len(w) else 1.0
        O1 = (cam.floor(z[inp.origin], f"the origin ({origin.describe()})") if origin.marker is not None
              else np.zeros(3))
        C = h * (np.array([0.0, 0.0, 1.0]) - O1)
        zm = z[inp.markers]
        X = [h * (cam.floor(zm[2 * m : 2 * m + 2], f"marker '{n}' (on the floor)") - O1)
             for m, n in enumerate(markers_px)]
        return np.concatenate([z[:6], C, [h], *X])

    out0 = solve(inp.z0)
    J = numeric_jacobian(solve, inp.z0, inp.steps)
    cov = J @ inp.cov @ J.T
    h = float(out0[9])
    relative = not scales
    markers = {}
    for m, n in enumerate(markers_px):
        sl = slice(10 + 3 * m, 13 + 3 * m)
        markers[n] = (out0[sl].copy(), cov[sl, sl].copy())
    warnings = skipped
    cam0 = _Camera(q0, R0, k1, photo, k2)
    for src in scales:
        if isinstance(src, KnownLength) and src.axis in ("x", "y"):
            ends = np.asarray(src.ends, float).reshape(2, 2)
            d = cam0.floor(ends[1], src.where) - cam0.floor(ends[0], src.where)
            axis = np.eye(3)["xyz".index(src.axis)]
            off = float(np.degrees(np.arccos(min(1.0, abs(d @ axis) / max(np.linalg.norm(d), 1e-300)))))
            if off > KNOWN_LENGTH_AXIS_DEG:
                warnings.append(f"photo '{photo}': {src.where}: on the floor its two ends lie {off:.0f}° off the "
                                f"{src.axis} axis; a length along {src.axis} should lie along it: check its axis "
                                "and that both ends are on the floor")
    if len(estimates) > 1:
        for e in estimates:
            if abs(e.height - h) > SCALE_DISAGREEMENT_SIGMAS * e.sigma:
                warnings.append(f"photo '{photo}': {e.describe()} puts the camera {e.height:.3f} m above the floor, "
                                f"{abs(e.height - h) / e.sigma:.1f}σ from the {h:.3f} m of all its scale sources "
                                "together: check its value, its units (m) and its clicks")
    cam = _Camera(q0, R0, k1, photo, k2)
    k1_sigma = float(np.sqrt(cov_q[6, 6])) if len(q0) == 7 else 0.0
    return SinglePhotoPlacement(photo, cam.K, cam.R, cam.k1, k1_sigma, out0[6:9].copy(), cov[:9, :9].copy(), h,
                                0.0 if relative else float(np.sqrt(max(cov[9, 9], 0.0))), relative, origin,
                                markers, estimates, warnings=warnings, marker_covariance=cov[10:, 10:].copy())


def floor_point(photo: str, K: ArrayLike, R: ArrayLike, C: ArrayLike, covariance: ArrayLike, uv: ArrayLike, *,
                k1: float = 0.0, k2: float = 0.0, click_sigma_px: float = 1.0,
                what: str = "the point") -> tuple[Array, Array]:
    """The floor point (z = 0) a placed camera sees at pixel uv, and its 3×3 covariance, first order
    over the camera's 9×9 covariance (f, cx, cy, ω, C) and the click: how a floor marker that one
    photo of a joint placement shows is placed from that photo alone."""
    K, R0 = np.asarray(K, float), np.asarray(R, float)
    cov = np.zeros((11, 11))
    c9 = np.asarray(covariance, float)
    cov[:9, :9] = np.where(np.isfinite(c9), c9, 0.0)
    cov[9:, 9:] = np.eye(2) * click_sigma_px**2
    z0 = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0, np.asarray(C, float), np.asarray(uv, float)]
    steps = np.r_[[STEP_PX] * 3, [STEP_RAD] * 3, [STEP_M] * 3, [STEP_PX] * 2]

    def X(z: Array) -> Array:
        cam = _Camera(z[:6], R0, k1, photo, k2)
        c = z[6:9]
        if not c[2] > 0:
            raise CalibrationError(photo, f"{what}: the camera is not above the floor (z = {c[2]:.3g}), so it cannot "
                                   "place a point on the floor; check the origin marker lies on the floor")
        d = cam.ray(z[9:11])
        if not d[2] < -MIN_FLOOR_SLOPE:
            raise CalibrationError(photo, f"{what}: pixel ({z[9]:.1f}, {z[10]:.1f}) lies on or above the horizon, so "
                                   "it cannot show a point of the floor; click the point where it touches the floor")
        return np.asarray(c + d * (-c[2] / d[2]), float)

    J = numeric_jacobian(X, z0, steps)
    return X(z0), J @ cov @ J.T
