"""Single-view metrology (Criminisi, Reid & Zisserman, IJCV 2000): lengths measured on one
calibrated photo against the floor, the reference plane (z = 0), and against planes the user marks
from it.

- ``photo-height``: the **height** of a point above the floor: the user clicks its foot (where the
  vertical through it meets the floor) and the point itself; the foot's ray meets the floor at F,
  and the height is where the point's ray passes nearest the vertical through F;
- ``floor-distance``: the **distance** between two points on the floor: each click's ray meets the
  floor;
- ``wall-length``: a **length on a wall** (any vertical plane): two clicks where the wall meets the
  floor fix the wall (the vertical plane through those two floor points), then the length's two
  ends, anywhere on the wall: each end's ray meets the wall;
- ``raised-height``: a **height above a raised surface** (a table top, a kerb, a stage): the floor
  below a point of the surface's edge, then that point, give the surface's height h0 (as a
  photo-height); then the foot, on the raised surface (its ray meets z = h0), and the top: the
  height of the top above that foot, as a photo-height above the raised surface;
- ``plane-length``: a **length on any plane** the user marks by three points: each point by the
  floor below it, then the point itself (the point on the vertical through that floor point, as a
  photo-height finds it; a point on the floor is clicked twice, at the same place); then the
  length's two ends on that plane, each end's ray meeting the plane. A **wall**: two points where
  it meets the floor (each clicked twice) and a third up the wall (a door frame's top corner, over
  the frame's foot). A **ramp**: its two lower corners on the floor (each clicked twice) and an
  upper corner over the floor point below it (where a handrail post or a side wall shows it). A
  **table top**: three of its corners, each over the foot of the leg beneath it.

No model and no solve are needed: only the photo's camera (K, R, C and its lens distortion k1, k2),
whose 9×9 covariance over (f, cx, cy, ω, C) carries the calibration's uncertainty and, for a photo
placed alone, its scale's (the camera's height came from a known length, a camera height or a
floor distance; vebuild/calibration/single_photo.py), with their correlations.

Uncertainty: first order over every input at once, σ² = J Σ Jᵀ, with J by central differences over
(f, cx, cy, ω, C), k1, k2 and the clicks; Σ the camera's covariance, k1's and k2's 1σ and their
correlation (the distortion record's, independent of the rest) and each click's 1σ per coordinate
(``settings.click_sigma_px``): the clicks that fix a plane count as fully as the ends measured on
it. Several measurements on one photo are correlated through the camera; each is reported with its own 1σ.

A measurement made by clicking is the command line's: :func:`vebuild.analysis.recorded.measure_clicked`
makes the saved words (:func:`single_view_command`) and runs the request parsed from them.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vebuild.calibration.lsq import numeric_jacobian
from vebuild.camera import ImageCamera, Lens, intrinsic_matrix, pixel_rays_world, skew
from vebuild.errors import VebuildError

from .measure import Measurement

Array = NDArray[np.float64]

#: A ray whose downward slope (|d_z|) is below this meets the floor more than 1000 camera heights
#: away, or not at all: the pixel lies at or above the horizon. The same bound, on the sine of the
#: angle between a ray and a marked plane, refuses a ray that runs along that plane.
MIN_FLOOR_SLOPE = 1e-3
#: Two points that fix a plane closer together than this fraction of their distance from the
#: camera (three: spanning an angle whose sine is below it) fix no plane.
MIN_PLANE_SPAN = 1e-3
#: Finite-difference steps: pixels, radians, metres, k1 and k2.
STEPS = {"px": 1e-3, "rad": 1e-7, "m": 1e-6, "k1": 1e-7}
#: Where the clicks start in the parameter vector (f, cx, cy, ω, C, k1, k2, clicks).
CLICKS_AT = 11


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


# -- the geometry ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Cam:
    K: Array
    R: Array
    C: Array
    lens: Lens
    photo: str

    def ray(self, uv: Array) -> Array:
        return pixel_rays_world(self.K, self.R, uv, self.lens)

    def _at(self, uv: Array) -> str:
        return f"pixel ({uv[0]:.1f}, {uv[1]:.1f})"

    def floor(self, uv: Array, what: str) -> Array:
        if not self.C[2] > 0:
            raise SingleViewError(f"photo '{self.photo}': its camera is not above the floor (z = {self.C[2]:.3g}), "
                                  "so nothing in it can be measured against the floor; calibrate it with the floor "
                                  "at z = 0")
        d = self.ray(uv)
        if not d[2] < -MIN_FLOOR_SLOPE:
            raise SingleViewError(f"photo '{self.photo}': {what}: {self._at(uv)} lies on or above "
                                  "the horizon, so it cannot show a point of the floor; click where it touches the "
                                  "floor")
        return self.C + d * (-self.C[2] / d[2])

    def height_above(self, foot: Array, uv: Array, what: str) -> float:
        d = self.ray(uv)
        if np.hypot(d[0], d[1]) < MIN_FLOOR_SLOPE:
            raise SingleViewError(f"photo '{self.photo}': {what}: the line of sight through {self._at(uv)} runs "
                                  "straight up or down, along the vertical it should cross, so it fixes no height; "
                                  "measure from a photo that sees the vertical from the side")
        A = np.column_stack([[0.0, 0.0, 1.0], -d])
        (s, t), *_ = np.linalg.lstsq(A, self.C - foot, rcond=None)
        if t <= 0:
            raise SingleViewError(f"photo '{self.photo}': {what}: the point lies behind the camera; check its click")
        return float(s)

    def above_floor(self, uv: Array, what: tuple[str, str]) -> Array:
        """The point clicked at ``uv[1]`` on the vertical through the floor point clicked at
        ``uv[0]`` (``what``: the two clicks' names)."""
        foot = self.floor(uv[0], what[0])
        return foot + np.array([0.0, 0.0, self.height_above(foot, uv[1], what[1])])

    def on_plane(self, uv: Array, plane: _Plane, what: str) -> Array:
        """Where the ray of ``uv`` meets ``plane``."""
        d = self.ray(uv)
        gap = plane.offset - float(plane.normal @ self.C)
        cos = float(plane.normal @ d)
        if abs(gap) < MIN_PLANE_SPAN * float(self.C[2]):  # the camera's height: the scale of the scene
            raise SingleViewError(f"photo '{self.photo}': {plane.name} passes through the camera, so the photo "
                                  f"sees it edge on and no point of it can be measured; mark {plane.name} by points "
                                  "that put it to one side of the camera")
        if abs(cos) < MIN_FLOOR_SLOPE:
            raise SingleViewError(f"photo '{self.photo}': {what}: the line of sight through {self._at(uv)} runs "
                                  f"parallel to {plane.name}, so it shows no point of it; click a point on "
                                  f"{plane.name}")
        t = gap / cos
        if t <= 0:
            raise SingleViewError(f"photo '{self.photo}': {what}: the line of sight through {self._at(uv)} meets "
                                  f"{plane.name} only behind the camera; click a point on {plane.name}")
        return self.C + t * d


@dataclass(frozen=True)
class _Plane:
    """The points X with ``normal · X = offset`` (``normal`` a unit vector), called ``name`` in
    messages."""

    normal: Array
    offset: float
    name: str


def _wall(c: _Cam, a: Array, b: Array) -> _Plane:
    """The vertical plane through the floor points ``a`` and ``b``."""
    along = b - a
    if np.linalg.norm(along) < MIN_PLANE_SPAN * max(np.linalg.norm(a - c.C), np.linalg.norm(b - c.C)):
        raise SingleViewError(f"photo '{c.photo}': the wall's two floor points are the same point, so they do not "
                              "fix a wall; click two points well apart along the line where the wall meets the "
                              "floor")
    n = np.array([along[1], -along[0], 0.0]) / np.linalg.norm(along[:2])
    return _Plane(n, float(n @ a), "the wall")


def _plane_through(c: _Cam, X: Array) -> _Plane:
    """The plane through the three points ``X`` (3, 3)."""
    u, v = X[1] - X[0], X[2] - X[0]
    n = np.cross(u, v)
    spans = [np.linalg.norm(X[i] - X[j]) for i, j in ((0, 1), (0, 2), (1, 2))]
    far = max(float(np.linalg.norm(x - c.C)) for x in X)
    if min(spans) < MIN_PLANE_SPAN * far or np.linalg.norm(n) < MIN_PLANE_SPAN * np.linalg.norm(u) * np.linalg.norm(v):
        raise SingleViewError(f"photo '{c.photo}': the plane's three points lie on one line (or two of them are the "
                              "same point), so they do not fix a plane; mark three points of the plane that are not "
                              "in a line")
    n = n / np.linalg.norm(n)
    return _Plane(n, float(n @ X[0]), "the marked plane")


# -- the measurements: each a function of the camera and the clicks (n, 2) giving its value and the
# -- two world points of the line it measures (a height: its foot, then the point above it) ----------

_Line = tuple[float, Array]


def _up(foot: Array, h: float) -> _Line:
    return h, np.array([foot, foot + [0.0, 0.0, h]])


def _between(a: Array, b: Array) -> _Line:
    return float(np.linalg.norm(a - b)), np.array([a, b])


def _photo_height(c: _Cam, uv: Array) -> _Line:
    foot = c.floor(uv[0], "the foot")
    return _up(foot, c.height_above(foot, uv[1], "the top"))


def _floor_distance(c: _Cam, uv: Array) -> _Line:
    return _between(c.floor(uv[0], "the first point"), c.floor(uv[1], "the second point"))


def _wall_length(c: _Cam, uv: Array) -> _Line:
    wall = _wall(c, c.floor(uv[0], "the wall's first floor point"), c.floor(uv[1], "the wall's second floor point"))
    return _between(c.on_plane(uv[2], wall, "the length's first end"),
                    c.on_plane(uv[3], wall, "the length's second end"))


def _raised_height(c: _Cam, uv: Array) -> _Line:
    edge = c.above_floor(uv[:2], ("the floor below the raised surface's edge", "the raised surface's edge"))
    if not edge[2] > 0:
        raise SingleViewError(f"photo '{c.photo}': the raised surface's edge point lies {-edge[2]:.3g} below the "
                              "floor, not above it; click first the floor just below a point of the surface's edge, "
                              "then that point")
    if not edge[2] < c.C[2]:
        raise SingleViewError(f"photo '{c.photo}': the raised surface's edge point lies at or above the camera "
                              f"({edge[2]:.3g} against the camera's {c.C[2]:.3g}), so the photo cannot show the top "
                              "of that surface; measure what stands above it with photo-height")
    raised = _Plane(np.array([0.0, 0.0, 1.0]), float(edge[2]), "the raised surface")
    foot = c.on_plane(uv[2], raised, "the foot on the raised surface")
    return _up(foot, c.height_above(foot, uv[3], "the top"))


def _plane_length(c: _Cam, uv: Array) -> _Line:
    X = np.array([c.above_floor(uv[2 * k : 2 * k + 2], (f"the floor below the plane's {n} point",
                                                         f"the plane's {n} point"))
                  for k, n in enumerate(("first", "second", "third"))])
    plane = _plane_through(c, X)
    return _between(c.on_plane(uv[6], plane, "the length's first end"),
                    c.on_plane(uv[7], plane, "the length's second end"))


@dataclass(frozen=True)
class _Kind:
    quantity: str  # the Measurement's quantity
    line: Callable[[_Cam, Array], _Line]
    clicks: tuple[str, ...]  # each click's name in messages and in the measurement's points
    what: str  # after "photo ID: ", with the pixels p0, p1, … of the clicks measured (the others: in points)


_KINDS: dict[str, _Kind] = {
    "photo-height": _Kind("height", _photo_height, ("the foot", "the top"), "{p1} above its foot {p0} on the floor"),
    "floor-distance": _Kind("distance", _floor_distance, ("the first point", "the second point"),
                            "{p0} to {p1} on the floor"),
    "wall-length": _Kind("length", _wall_length, ("the wall's first floor point", "the wall's second floor point",
                                                  "the length's first end", "the length's second end"),
                         "{p2} to {p3} on the wall"),
    "raised-height": _Kind("height", _raised_height, ("the floor below the raised surface's edge",
                                                      "the raised surface's edge", "the foot on the raised surface",
                                                      "the top"),
                           "{p3} above its foot {p2} on the raised surface"),
    "plane-length": _Kind("length", _plane_length, ("the floor below the plane's first point",
                                                    "the plane's first point", "the floor below its second point",
                                                    "the plane's second point", "the floor below its third point",
                                                    "the plane's third point", "the length's first end",
                                                    "the length's second end"),
                          "{p6} to {p7} on the marked plane"),
}


def _exp_so3(w: Array) -> Array:
    """exp([w]×), Rodrigues' formula (the same rotation as :func:`vebuild.camera.exp_so3`, without
    the import of scipy's rotations: half a second of a command that measures in milliseconds)."""
    t = float(np.linalg.norm(w))
    W = skew(w)
    if t < 1e-4:  # the series to t²: the terms dropped are below 1e-17
        return np.eye(3) + (1.0 - t * t / 6.0) * W + (0.5 - t * t / 24.0) * (W @ W)
    return np.eye(3) + np.sin(t) / t * W + (1.0 - np.cos(t)) / t**2 * (W @ W)


def _camera(cam: ImageCamera, p: Array) -> _Cam:
    return _Cam(intrinsic_matrix(p[0], p[1], p[2]), _exp_so3(p[3:6]) @ np.asarray(cam.R, float),
                np.asarray(p[6:9], float), Lens(float(p[9]), float(p[10])), cam.id)


def _check_on_photo(cam: ImageCamera, uv: Array, what: str) -> None:
    if not (np.all(np.isfinite(uv)) and 0 <= uv[0] <= cam.width and 0 <= uv[1] <= cam.height):
        raise SingleViewError(f"photo '{cam.id}': {what}: pixel ({uv[0]:g}, {uv[1]:g}) lies outside the "
                              f"{cam.width}×{cam.height} photo; expected a pixel on it")


def _measure(cam: ImageCamera, clicks: Array, fn: Callable[[_Cam, Array], float], click_sigma_px: float,
             k1_sigma: float, k2_sigma: float = 0.0, k1_k2_correlation: float = 0.0) -> tuple[float, float]:
    """Value and first-order 1σ of ``fn(camera, clicks)`` over the camera, k1, k2 and the clicks."""
    if cam.covariance is None:
        raise SingleViewError(f"photo '{cam.id}': its camera has no covariance; run `vebuild calibrate` again")
    K = np.asarray(cam.K, float)
    p0 = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0, np.asarray(cam.C, float), cam.lens.k1, cam.lens.k2,
                 clicks.ravel()]
    n_c = clicks.size
    cov = np.zeros((len(p0), len(p0)))
    c9 = np.asarray(cam.covariance, float)
    determined = bool(np.all(np.isfinite(c9)))  # else a quantity the data left undetermined: σ infinite
    cov[:9, :9] = np.where(np.isfinite(c9), c9, 0.0)
    cov[9, 9], cov[10, 10] = k1_sigma**2, k2_sigma**2
    cov[9, 10] = cov[10, 9] = k1_k2_correlation * k1_sigma * k2_sigma
    cov[CLICKS_AT:, CLICKS_AT:] = np.eye(n_c) * click_sigma_px**2
    steps = np.r_[[STEPS["px"]] * 3, [STEPS["rad"]] * 3, [STEPS["m"]] * 3, STEPS["k1"], STEPS["k1"],
                  [STEPS["px"]] * n_c]

    def f(p: Array) -> Array:
        return np.array([fn(_camera(cam, p), p[CLICKS_AT:].reshape(clicks.shape))])

    value = float(f(p0)[0])
    J = numeric_jacobian(f, p0, steps)
    return value, float(np.sqrt(max(float((J @ cov @ J.T)[0, 0]), 0.0))) if determined else np.inf


def _checked(cam: ImageCamera, kind: str, clicks: Sequence[Sequence[float]]) -> tuple[_Kind, Array]:
    if kind not in _KINDS:
        raise SingleViewError(f"no single-view measurement '{kind}'; they are {', '.join(_KINDS)}")
    k = _KINDS[kind]
    uv = np.asarray(clicks, float).reshape(-1, 2)
    if len(uv) != len(k.clicks):
        raise SingleViewError(f"a {kind} takes {len(k.clicks)} clicked points, got {len(uv)}")
    for p, name in zip(uv, k.clicks, strict=True):
        _check_on_photo(cam, p, name)
    return k, uv


def measured_line(cam: ImageCamera, kind: str, clicks: Sequence[Sequence[float]]) -> Array:
    """The two world points (2, 3) of the line the single-view measurement ``kind`` clicked at
    ``clicks`` measures, by the very geometry that measures it: a height's foot then the point
    above it, a distance's or a length's two ends. For drawing a measurement in a 3-D hand-off;
    refusals as :func:`measure_on_photo`'s."""
    k, uv = _checked(cam, kind, clicks)
    K = np.asarray(cam.K, float)
    p = np.r_[K[0, 0], K[0, 2], K[1, 2], 0.0, 0.0, 0.0, np.asarray(cam.C, float), cam.lens.k1, cam.lens.k2]
    return k.line(_camera(cam, p), uv)[1]


def measure_on_photo(cam: ImageCamera, kind: str, clicks: Sequence[Sequence[float]], *, click_sigma_px: float = 1.0,
                     k1_sigma: float = 0.0, k2_sigma: float = 0.0, k1_k2_correlation: float = 0.0) -> Measurement:
    """The single-view measurement ``kind`` (:data:`SINGLE_VIEW_CLICKS`) clicked at ``clicks``
    (pixels, in that order) on the photo of ``cam``, with its first-order 1σ (module docstring)."""
    k, uv = _checked(cam, kind, clicks)
    v, s = _measure(cam, uv, lambda c, p: k.line(c, p)[0], click_sigma_px, k1_sigma, k2_sigma, k1_k2_correlation)
    pts = [{"point": f"photo {cam.id} pixel ({p[0]:g}, {p[1]:g})", "kind": name}
           for p, name in zip(uv, SINGLE_VIEW_CLICKS[kind], strict=True)]
    what = k.what.format(**{f"p{i}": f"({p[0]:g}, {p[1]:g})" for i, p in enumerate(uv)})
    return Measurement(k.quantity, f"photo {cam.id}: {what}", v, s, photos=[cam.id], points=pts,
                       source=f"single view (photo '{cam.id}')")


def height_on_photo(cam: ImageCamera, foot: Sequence[float], top: Sequence[float], *, click_sigma_px: float = 1.0,
                    k1_sigma: float = 0.0, k2_sigma: float = 0.0, k1_k2_correlation: float = 0.0) -> Measurement:
    """The height above the floor of the point clicked at ``top``, standing over the floor point
    clicked at ``foot``, with its first-order 1σ (module docstring)."""
    return measure_on_photo(cam, "photo-height", [foot, top], click_sigma_px=click_sigma_px, k1_sigma=k1_sigma,
                            k2_sigma=k2_sigma, k1_k2_correlation=k1_k2_correlation)


def floor_distance_on_photo(cam: ImageCamera, a: Sequence[float], b: Sequence[float], *, click_sigma_px: float = 1.0,
                            k1_sigma: float = 0.0, k2_sigma: float = 0.0,
                            k1_k2_correlation: float = 0.0) -> Measurement:
    """The distance between the two floor points clicked at ``a`` and ``b``, with its first-order
    1σ (module docstring)."""
    return measure_on_photo(cam, "floor-distance", [a, b], click_sigma_px=click_sigma_px, k1_sigma=k1_sigma,
                            k2_sigma=k2_sigma, k1_k2_correlation=k1_k2_correlation)
