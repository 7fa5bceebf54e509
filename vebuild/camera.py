"""The pinhole camera of DESIGN.md, in one place.

``K = [[f, 0, cx], [0, f, cy], [0, 0, 1]]`` in pixels (zero skew, square pixels); ``R`` rotates
world into camera coordinates; ``C`` is the camera centre; ``x_cam = R (X - C)``; the camera looks
along +z_cam and image v grows along +y_cam; ``u ~ K x_cam``. Pixel (u, v) has its origin at the
top-left corner of the image, so pixel column i, row j has its centre at (i + 0.5, j + 0.5).

**Lens distortion** (the one convention; every projection in vebuild goes through it): the
division model (Fitzgibbon, CVPR 2001) with up to two terms, on normalised image coordinates
centred on the principal point and divided by f. A photo's pixel u (as the lens put it) has the
distorted normalised coordinate x_d = (u − c) / f, r_d = |x_d|; the pinhole's (undistorted)
coordinate is

    x_u = x_d / (1 + k1 r_d² + k2 r_d⁴)

so undistorting a pixel is closed-form. Distorting a pinhole point inverts the radial map
g(r_d) = r_d / (1 + k1 r_d² + k2 r_d⁴) = |x_u|: with k2 = 0 a quadratic, x_d = x_u · 2 / (1 +
√(1 − 4 k1 |x_u|²)); with k2 ≠ 0 a monotone 1-D inversion per radius (safeguarded Newton, to
1e-13 relative). Where g stops increasing (a pincushion lens's rim, g'(r_d) = 0) a farther
pinhole point is put on the rim, where it lies outside any real image. k1 < 0 is barrel
distortion (wide lenses: lines bow outward, the corners are pulled in), k1 > 0 pincushion; k2
bends the outer field further (a fisheye's, docs/lenses.md); k1 = k2 = 0 is the pinhole. Since x
is divided by f, k1 and k2 do not change when the image is scaled. A camera's distortion is
:attr:`ImageCamera.lens`, a :class:`Lens`; the free functions take a :class:`Lens`
(:data:`PINHOLE` for none).

Free functions over numpy arrays; nothing here does I/O or GL.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]

#: A level camera looking along world +X: its x (image right) is world -Y, its y (image down) is
#: world -Z, its optical axis world +X. Columns are the camera axes in world coordinates.
LEVEL_CAMERA_TO_WORLD: Array = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
LEVEL_CAMERA_TO_WORLD.flags.writeable = False  # shared constant: nobody may edit it in place

AXES = ("x", "y", "z")


def intrinsic_matrix(f: float, cx: float, cy: float) -> Array:
    """K = [[f, 0, cx], [0, f, cy], [0, 0, 1]]."""
    return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Lens:
    """A photo's lens distortion: the division model's k1 and k2 (module docstring).

    ``Lens()`` (:data:`PINHOLE`) is the pinhole; ``Lens(k1)`` is the one-term model.
    """

    k1: float = 0.0
    k2: float = 0.0

    @property
    def is_pinhole(self) -> bool:
        return self.k1 == 0.0 and self.k2 == 0.0

    def rim(self) -> float:
        """The distorted normalised radius r_d beyond which the lens shows nothing: where
        g(r_d) = r_d / (1 + k1 r_d² + k2 r_d⁴) stops increasing (g' = 0: 1 − k1 t − 3 k2 t² = 0,
        t = r_d²) or, first, where its denominator vanishes (g → ∞ there: the whole pinhole plane
        is within the field). ∞ where neither happens (the pinhole, a barrel one-term lens)."""
        t = min(_least_positive_root(3.0 * self.k2, self.k1, -1.0),
                _least_positive_root(self.k2, self.k1, 1.0))
        return float(np.sqrt(t))

    def rim_is_field_edge(self) -> bool:
        """Whether :meth:`rim` is where g stops increasing (pinhole points beyond it are put on
        it) rather than a pole of g (every pinhole point has its place inside it)."""
        return _least_positive_root(3.0 * self.k2, self.k1, -1.0) < _least_positive_root(self.k2, self.k1, 1.0)


#: No distortion.
PINHOLE = Lens()


def _least_positive_root(a: float, b: float, c: float) -> float:
    """The least positive root of a t² + b t + c (∞ where none)."""
    if a == 0.0:
        return -c / b if b != 0.0 and -c / b > 0.0 else float("inf")
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return float("inf")
    q = -0.5 * (b + np.copysign(np.sqrt(disc), b))  # the stable pair of roots
    roots = [r for r in ((q / a), (c / q if q != 0.0 else float("inf"))) if r > 0.0]
    return min(roots, default=float("inf"))


def project(K: ArrayLike, R: ArrayLike, C: ArrayLike, X_world: ArrayLike, lens: Lens = PINHOLE) -> Array:
    """Pixel coordinates u = K·D(π(R (X - C))) of world points, D the ``lens``'s distortion.

    Parameters
    ----------
    K, R : (3, 3) intrinsics and world→camera rotation.
    C : (3,) camera centre.
    X_world : (..., 3) points.
    lens : the division model's coefficients (module docstring); :data:`PINHOLE` for none.

    Returns
    -------
    (..., 2) pixel coordinates (u, v), origin at the image's top-left corner.
    """
    x = world_to_camera(R, C, X_world)
    if lens.is_pinhole:
        h = x @ np.asarray(K, float).T
        return h[..., :2] / h[..., 2:3]
    return normalised_to_pixels(K, distort_normalised(x[..., :2] / x[..., 2:3], lens))


#: Newton's stopping step, relative to the radius: the inversion is exact to about 1e-13.
NEWTON_RTOL = 1e-13
NEWTON_MAX_ITER = 100


def distortion_scale(r2_undistorted: ArrayLike, lens: Lens) -> Array:
    """s with x_d = s · x_u, from |x_u|² (division model, module docstring).

    With k2 = 0, s = 2 / (1 + √(1 − 4 k1 |x_u|²)); beyond the field a pincushion lens (k1 > 0)
    can show (4 k1 |x_u|² > 1) the square root is taken at 0. With k2 ≠ 0, r_d solves
    g(r_d) = |x_u| by Newton's method kept inside a bisection bracket; beyond the rim (g' = 0) the
    point is put on the rim. Either way such a point lies outside any real image.
    """
    r2 = np.asarray(r2_undistorted, float)
    k1, k2 = lens.k1, lens.k2
    if k2 == 0.0:
        return np.asarray(2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * k1 * r2, 0.0))), float)
    r_u = np.sqrt(np.maximum(r2, 0.0))
    rim = lens.rim()  # finite for k2 ≠ 0: one of the two quadratics has a positive root
    rho = _invert_radial(r_u, k1, k2, rim)
    if lens.rim_is_field_edge():
        rho = np.where(r_u >= rim / (1.0 + k1 * rim**2 + k2 * rim**4), rim, rho)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.where(r_u > 0.0, rho / np.where(r_u > 0.0, r_u, 1.0), 1.0)
    return np.asarray(s, float)


def _invert_radial(r_u: Array, k1: float, k2: float, rim: float) -> Array:
    """r_d ∈ [0, rim] with r_d / (1 + k1 r_d² + k2 r_d⁴) = r_u (g increasing on [0, rim))."""
    lo, hi = np.zeros_like(r_u), np.full_like(r_u, rim)
    rho = np.minimum(r_u, 0.5 * rim)  # g(r) ≈ r near the centre
    for _ in range(NEWTON_MAX_ITER):
        r2 = rho * rho
        D = 1.0 + k1 * r2 + k2 * r2 * r2
        g = rho / D
        gp = (1.0 - k1 * r2 - 3.0 * k2 * r2 * r2) / (D * D)
        below = g < r_u
        lo, hi = np.where(below, rho, lo), np.where(below, hi, rho)
        with np.errstate(invalid="ignore", divide="ignore"):
            new = rho - (g - r_u) / gp
        bad = ~np.isfinite(new) | (new < lo) | (new > hi)
        new = np.where(bad, 0.5 * (lo + hi), new)
        done = np.abs(new - rho) <= NEWTON_RTOL * np.maximum(rho, 1.0)
        rho = new
        if np.all(done):
            break
    # Two more Newton steps from there: the root to the rounding of g itself, so that r_d is as
    # smooth a function of r_u as the closed form (a solver differencing it sees no steps).
    for _ in range(2):
        r2 = rho * rho
        D = 1.0 + k1 * r2 + k2 * r2 * r2
        gp = (1.0 - k1 * r2 - 3.0 * k2 * r2 * r2) / (D * D)
        with np.errstate(invalid="ignore", divide="ignore"):
            new = rho - (rho / D - r_u) / gp
        rho = np.where(np.isfinite(new) & (new >= lo) & (new <= hi), new, rho)
    return rho


def distortion_derivatives(r2_undistorted: ArrayLike, lens: Lens) -> tuple[Array, Array, Array, Array]:
    """s (as :func:`distortion_scale`) and its derivatives ∂s/∂|x_u|², ∂s/∂k1, ∂s/∂k2.

    s solves s = 1 + k1 s² r² + k2 s⁴ r⁴ (r = |x_u|), so with F_s = 1 − 2 k1 s r² − 4 k2 s³ r⁴:
    ∂s/∂r² = (k1 s² + 2 k2 s⁴ r²) / F_s, ∂s/∂k1 = s² r² / F_s, ∂s/∂k2 = s⁴ r⁴ / F_s. F_s is
    floored at 1e-12 (at the rim the map has no derivative).
    """
    r2 = np.asarray(r2_undistorted, float)
    s = distortion_scale(r2, lens)
    Fs = np.maximum(1.0 - 2.0 * lens.k1 * s * r2 - 4.0 * lens.k2 * s**3 * r2**2, 1e-12)
    return s, (lens.k1 * s**2 + 2.0 * lens.k2 * s**4 * r2) / Fs, s**2 * r2 / Fs, s**4 * r2**2 / Fs


def distortion_derivatives_each(r2_undistorted: ArrayLike, lenses: ArrayLike) -> tuple[Array, Array, Array, Array]:
    """:func:`distortion_derivatives` of n points, point i through lens i: |x_u|² (n,), lenses (n, 2)
    (k1, k2) → s, ∂s/∂|x_u|², ∂s/∂k1, ∂s/∂k2, each (n,). Pinholes give 1, 0, |x_u|², |x_u|⁴."""
    r2 = np.asarray(r2_undistorted, float).reshape(-1)
    k = np.asarray(lenses, float).reshape(-1, 2)
    s, ds_dr2, ds_dk1, ds_dk2 = np.ones(len(r2)), np.zeros(len(r2)), r2.copy(), r2 * r2
    if not np.any(k):
        return s, ds_dr2, ds_dk1, ds_dk2
    pairs, which = np.unique(k, axis=0, return_inverse=True)
    which = np.asarray(which).reshape(-1)
    for i, (k1, k2) in enumerate(pairs):
        if k1 == 0.0 and k2 == 0.0:
            continue
        sel = which == i
        s[sel], ds_dr2[sel], ds_dk1[sel], ds_dk2[sel] = distortion_derivatives(r2[sel], Lens(float(k1), float(k2)))
    return s, ds_dr2, ds_dk1, ds_dk2


def distort_normalised(x_u: ArrayLike, lens: Lens) -> Array:
    """Pinhole normalised coordinates (..., 2) → the lens's (distorted) ones."""
    x_u = np.asarray(x_u, float)
    if lens.is_pinhole:
        return x_u.copy()
    return x_u * distortion_scale(np.sum(x_u**2, axis=-1), lens)[..., None]


def undistort_normalised(x_d: ArrayLike, lens: Lens) -> Array:
    """The lens's normalised coordinates (..., 2) → the pinhole's: x_u = x_d / (1 + k1 r_d² + k2 r_d⁴)."""
    x_d = np.asarray(x_d, float)
    if lens.is_pinhole:
        return x_d.copy()
    r2 = np.sum(x_d**2, axis=-1)
    if lens.k2 == 0.0:
        return x_d / (1.0 + lens.k1 * r2)[..., None]
    return x_d / (1.0 + lens.k1 * r2 + lens.k2 * r2 * r2)[..., None]


def pixels_to_normalised(K: ArrayLike, uv: ArrayLike) -> Array:
    """(u − c) / f of pixels (..., 2)."""
    K = np.asarray(K, float)
    return (np.asarray(uv, float) - K[:2, 2]) / K[0, 0]


def normalised_to_pixels(K: ArrayLike, x: ArrayLike) -> Array:
    """c + f x of normalised coordinates (..., 2)."""
    K = np.asarray(K, float)
    return np.asarray(x, float) * K[0, 0] + K[:2, 2]


def undistort_pixels(K: ArrayLike, uv: ArrayLike, lens: Lens) -> Array:
    """Where the pinhole camera K would have put what the lens put at pixels uv (..., 2)."""
    if lens.is_pinhole:
        return np.asarray(uv, float).copy()
    return normalised_to_pixels(K, undistort_normalised(pixels_to_normalised(K, uv), lens))


def distort_pixels(K: ArrayLike, uv: ArrayLike, lens: Lens) -> Array:
    """Where the lens puts what the pinhole camera K puts at pixels uv (..., 2)."""
    if lens.is_pinhole:
        return np.asarray(uv, float).copy()
    return normalised_to_pixels(K, distort_normalised(pixels_to_normalised(K, uv), lens))


def distortion_displacement_px(K: ArrayLike, width: int, height: int, lens: Lens) -> float:
    """The largest distance (pixels) between a corner of the photo and where a pinhole camera K
    would have put what it shows: how far the lens moves the image at its corners."""
    corners = np.array([[0.0, 0.0], [width, 0.0], [0.0, height], [width, height]])
    return float(np.max(np.linalg.norm(undistort_pixels(K, corners, lens) - corners, axis=-1)))


def world_to_camera(R: ArrayLike, C: ArrayLike, X_world: ArrayLike) -> Array:
    """x_cam = R (X − C) of world points (..., 3); its z is the depth in front of the camera."""
    return (np.asarray(X_world, float) - np.asarray(C, float)) @ np.asarray(R, float).T


def project_each(Ks: ArrayLike, Rs: ArrayLike, Cs: ArrayLike, X_world: ArrayLike,
                 lenses: ArrayLike | None = None) -> Array:
    """Pixels of n world points, point i seen by camera i: Ks, Rs (n, 3, 3), Cs, X (n, 3) → (n, 2);
    ``lenses`` (n, 2): each camera's lens distortion (k1, k2) (None: all pinholes).

    The same projection as :func:`project`, batched over many cameras (a solve's observations).
    """
    x_cam = np.einsum("nij,nj->ni", np.asarray(Rs, float), np.asarray(X_world, float) - np.asarray(Cs, float))
    Ks = np.asarray(Ks, float)
    x = x_cam[:, :2] / x_cam[:, 2:3]
    if lenses is not None:
        x = x * distortion_derivatives_each(np.sum(x**2, axis=-1), lenses)[0][:, None]
    return x * Ks[:, 0, 0, None] + Ks[:, :2, 2]


def pixel_rays_world(K: ArrayLike, R: ArrayLike, uv: ArrayLike, lens: Lens = PINHOLE) -> Array:
    """Unit viewing directions in the world of pixels uv, shape (..., 2) → (..., 3).

    d_world = Rᵀ K⁻¹ [u, v, 1]ᵀ, normalised (paper eq. 5), after undistorting uv by ``lens``.
    """
    uv = undistort_pixels(K, uv, lens)
    h = np.concatenate([uv, np.ones(uv.shape[:-1] + (1,))], axis=-1)
    d_cam = np.linalg.solve(np.asarray(K, float), h.reshape(-1, 3).T).T.reshape(h.shape)
    d = d_cam @ np.asarray(R, float)  # row-vector form of Rᵀ d_cam
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def skew(w: ArrayLike) -> Array:
    """[w]×, the matrix with [w]× v = w × v."""
    x, y, z = np.asarray(w, float)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def skew_batch(v: ArrayLike) -> Array:
    """[vᵢ]× for each row of v (n, 3), shape (n, 3, 3)."""
    v = np.asarray(v, float)
    S = np.zeros((len(v), 3, 3))
    S[:, 0, 1], S[:, 0, 2] = -v[:, 2], v[:, 1]
    S[:, 1, 0], S[:, 1, 2] = v[:, 2], -v[:, 0]
    S[:, 2, 0], S[:, 2, 1] = -v[:, 1], v[:, 0]
    return S


def so3_left_jacobian(w: ArrayLike) -> Array:
    """J_l(ω) of SO(3): exp([ω + δ]×) ≈ exp([J_l(ω) δ]×) exp([ω]×)."""
    w = np.asarray(w, float)
    t = float(np.linalg.norm(w))
    W = skew(w)
    if t < 1e-8:
        return np.eye(3) + 0.5 * W
    return np.eye(3) + (1 - np.cos(t)) / t**2 * W + (t - np.sin(t)) / t**3 * (W @ W)


def exp_so3(w: ArrayLike) -> Array:
    """exp([w]×): the rotation by |w| radians about w."""
    from scipy.spatial.transform import Rotation  # imported at first use: docs/start-up.md

    return Rotation.from_rotvec(np.asarray(w, float)).as_matrix()


def log_so3(R: ArrayLike) -> Array:
    """The rotation vector w with exp([w]×) = R."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, float)).as_rotvec()


def nearest_rotation(M: ArrayLike) -> Array:
    """The rotation closest to M in the Frobenius norm (polar decomposition), det +1."""
    U, _, Vt = np.linalg.svd(np.asarray(M, float))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    return U @ D @ Vt


def _rz(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a: float) -> Array:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_from_ypr(yaw: float, pitch: float, roll: float) -> Array:
    """World→camera rotation R from yaw, pitch, roll in radians.

    camera→world = Rz(yaw) · Ry(−pitch) · B · Rz(roll), B = LEVEL_CAMERA_TO_WORLD. Yaw turns the
    optical axis counter-clockwise from +X about +Z; pitch raises it (positive looking up); roll
    turns the camera clockwise about its optical axis as seen from behind.
    """
    cam2world = _rz(yaw) @ _ry(-pitch) @ LEVEL_CAMERA_TO_WORLD @ _rz(roll)
    return cam2world.T


def ypr_from_rotation(R: ArrayLike) -> Array:
    """(yaw, pitch, roll) in radians of a world→camera rotation; inverse of rotation_from_ypr."""
    cam2world = np.asarray(R, float).T
    d = cam2world[:, 2]  # optical axis in the world
    yaw = np.arctan2(d[1], d[0])
    pitch = np.arcsin(np.clip(d[2], -1.0, 1.0))
    # What is left after undoing yaw and pitch is B · Rz(roll).
    rest = LEVEL_CAMERA_TO_WORLD.T @ _ry(pitch) @ _rz(-yaw) @ cam2world
    roll = np.arctan2(rest[1, 0], rest[0, 0])
    return np.array([yaw, pitch, roll])


#: Far plane: this share beyond the farthest point, plus FAR_MARGIN_M, so nothing drawn is clipped.
FAR_SCALE = 1.05
FAR_MARGIN_M = 0.5
#: Near plane: this share of the far plane, but no nearer than MIN_NEAR_M (1 mm: nothing a photo
#: shows is nearer the lens).
NEAR_FROM_FAR = 2e-5
MIN_NEAR_M = 1e-3


def depth_range(R: ArrayLike, C: ArrayLike, points: ArrayLike) -> tuple[float, float]:
    """The near and far planes of :func:`gl_projection` for a camera (R, C) viewing ``points``
    (world, (n, 3): a scene's vertices or its bounding box's corners).

    The one choice of near and far for every pass (the renderer, the texture's ID buffer and its
    CPU reference), so that their depths agree: far lies beyond every point (at least 1 m), near is
    a fixed small share of far. A depth buffer's resolution at depth z is about z²/(near · 2²⁴):
    with near = 1 mm, some 6 mm at 10 m.
    """
    P = np.asarray(points, float).reshape(-1, 3)
    z_max = float(world_to_camera(R, C, P)[:, 2].max()) if len(P) else 0.0
    far = max(1.0, z_max * FAR_SCALE + FAR_MARGIN_M)
    return max(MIN_NEAR_M, far * NEAR_FROM_FAR), far


def gl_projection(K: ArrayLike, width: int, height: int, near: float, far: float, flip_y: bool = False) -> Array:
    """The one conversion from this camera to OpenGL clip space: a (4, 4) matrix P with
    ``clip = P @ [x_cam, 1]`` (DESIGN.md, "OpenGL").

    Clip x, y map pixel u ∈ [0, width] and v ∈ [0, height] onto NDC [−1, 1]; w = z_cam (depth in
    front of the camera); NDC z runs from −1 at ``near`` to +1 at ``far``. The principal point
    (K's cx, cy) is honoured, so the frustum is off-axis when it is off-centre.

    By default (``flip_y=False``) image row v lands on framebuffer row v: a framebuffer read back
    into numpy is in image order (row 0 at the top), and a photo uploaded row 0 first is sampled
    at t = v / height. A window shows framebuffer row 0 at the bottom, so rendering for display
    uses ``flip_y=True`` (then NDC y = 1 − 2v/height).
    """
    K = np.asarray(K, float)
    if not (0 < near < far):
        raise ValueError(f"need 0 < near < far, got near={near}, far={far}")
    f_u, f_v, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    P = np.zeros((4, 4))
    P[0, 0], P[0, 2] = 2.0 * f_u / width, 2.0 * cx / width - 1.0
    P[1, 1], P[1, 2] = 2.0 * f_v / height, 2.0 * cy / height - 1.0
    if flip_y:
        P[1] = -P[1]
    P[2, 2], P[2, 3] = (far + near) / (far - near), -2.0 * far * near / (far - near)
    P[3, 2] = 1.0
    return P


def gl_orthographic(R: ArrayLike, lo: ArrayLike, hi: ArrayLike) -> Array:
    """(4, 4) world → clip of an orthographic view along R's z axis (a directional light's shadow
    map): x_cam = R X, and the box lo ≤ x_cam ≤ hi maps onto NDC [−1, 1]³, rows as in
    :func:`gl_projection` without ``flip_y`` (camera y grows with the framebuffer row)."""
    R, lo, hi = np.asarray(R, float), np.asarray(lo, float), np.asarray(hi, float)
    if np.any(hi <= lo):
        raise ValueError(f"need lo < hi on every axis, got lo={lo.tolist()}, hi={hi.tolist()}")
    S = np.eye(4)
    S[:3, :3] = np.diag(2.0 / (hi - lo)) @ R
    S[:3, 3] = -(hi + lo) / (hi - lo)
    return S


def view_matrix(R: ArrayLike, C: ArrayLike) -> Array:
    """(4, 4) world → camera: ``[x_cam, 1] = V @ [X, 1]`` with x_cam = R (X − C)."""
    R = np.asarray(R, float)
    V = np.eye(4)
    V[:3, :3] = R
    V[:3, 3] = -R @ np.asarray(C, float)
    return V


@dataclass(frozen=True)
class ImageCamera:
    """A camera with an image: K, R, C in the convention above and the image's size in pixels.

    A calibrated photo, a named evidence view, or one eye of a stereo pair; ``id`` names it.
    ``source`` says where its image size came from (``"$.views[2] (width × height)"``,
    ``"--size"``), for the messages of :mod:`vebuild.render.sizes`; it takes no part in equality.
    ``covariance``: a calibrated photo's (9, 9) covariance over (f, cx, cy, ω, C) (ω the rotation
    vector of a small turn, left-multiplied: R' = exp([ω]×) R), or None for a camera given
    exactly (an evidence view, an eye). A derived camera (scaled, resized, an eye) carries none.
    ``lens``: the lens distortion of the photo (the division model of the module docstring;
    :data:`PINHOLE` for a pinhole, as every rendered view and eye is). A scaled or resized camera
    keeps it (x is divided by f).
    """

    id: str
    K: Array
    R: Array
    C: Array
    width: int
    height: int
    source: str = field(default="", compare=False, repr=False, kw_only=True)
    covariance: Array | None = field(default=None, compare=False, repr=False, kw_only=True)
    lens: Lens = field(default=PINHOLE, kw_only=True)

    def scaled(self, s: float) -> ImageCamera:
        """The same camera for an image scaled by s (pixel corners stay at corners)."""
        K = np.array(self.K, float)
        K[:2] *= s
        return ImageCamera(self.id, K, self.R, self.C, max(1, round(self.width * s)), max(1, round(self.height * s)),
                           source=self.source, lens=self.lens)

    def resized(self, width: int, height: int, source: str | None = None) -> ImageCamera:
        """The same view at another image size: the horizontal field of view is kept, and the
        principal point keeps its place relative to the image (a different aspect ratio shows more
        or less above and below). ``source``: where the new size came from (default: the old's)."""
        s = width / self.width
        K = np.array(self.K, float)
        K[0, 0] *= s
        K[1, 1] *= s
        K[0, 2] *= s
        K[1, 2] = (K[1, 2] / self.height) * height
        return ImageCamera(self.id, K, self.R, self.C, int(width), int(height),
                           source=self.source if source is None else source, lens=self.lens)


def look_rotation(direction: ArrayLike, roll: float = 0.0) -> Array:
    """World→camera R of a camera looking along ``direction`` (world), image up toward +Z.

    ``roll`` (radians) turns the camera clockwise about its optical axis as seen from behind, as in
    :func:`rotation_from_ypr`. A camera looking straight up or down has no "up"; its image right is
    then taken along world −Y (the heading +X, as a level camera's).
    """
    d = np.asarray(direction, float)
    n = float(np.linalg.norm(d))
    if not np.isfinite(n) or n == 0.0:
        raise ValueError(f"a look direction must be a non-zero vector, got {d.tolist()}")
    d = d / n
    yaw = float(np.arctan2(d[1], d[0])) if np.hypot(d[0], d[1]) > 1e-12 else 0.0
    return rotation_from_ypr(yaw, float(np.arcsin(np.clip(d[2], -1.0, 1.0))), roll)


def fov_to_focal(fov: float, size: float) -> float:
    """Focal length in pixels of a field of view ``fov`` (radians) across ``size`` pixels."""
    return 0.5 * size / np.tan(0.5 * fov)


def focal_to_fov(f: float, size: float) -> float:
    """Field of view (radians) across ``size`` pixels of a focal length ``f`` in pixels; inverse of
    :func:`fov_to_focal`."""
    return float(2.0 * np.arctan(0.5 * size / f))


def stereo_pair(cam: ImageCamera, separation: float, convergence: float) -> tuple[ImageCamera, ImageCamera]:
    """Left and right eyes of a parallel stereo rig centred on ``cam`` (off-axis, not toe-in).

    Both eyes keep ``cam``'s orientation and are moved ∓ separation/2 along its image x axis; their
    principal points are shifted by ± f·separation / (2·convergence) so that a point at depth
    ``convergence`` in front of ``cam`` lands on the same pixel in both images (zero parallax, the
    screen plane). A point at depth z then has parallax u_right − u_left = f·separation·(1/convergence −
    1/z): negative (in front of the screen) nearer, positive (behind it) farther.
    """
    if not separation > 0.0:
        raise ValueError(f"the eye separation must be > 0 m, got {separation}")
    if not convergence > 0.0:
        raise ValueError(f"the convergence distance must be > 0 m, got {convergence}")
    x_axis = np.asarray(cam.R, float)[0]  # image right, in the world
    shift = cam.K[0, 0] * separation / (2.0 * convergence)
    eyes = []
    for side, sign in (("left", -1.0), ("right", 1.0)):
        K = np.array(cam.K, float)
        K[0, 2] += sign * shift
        C = np.asarray(cam.C, float) + sign * 0.5 * separation * x_axis
        eyes.append(ImageCamera(f"{cam.id}:{side}", K, cam.R, C, cam.width, cam.height))
    return eyes[0], eyes[1]


def near_reach(K: ArrayLike, width: int, height: int, near: float) -> float:
    """How far from the camera centre its near plane's rectangle reaches (metres)."""
    corners = np.array([[0, 0, 1], [width, 0, 1], [0, height, 1], [width, height, 1]], float)
    rays = np.linalg.solve(np.asarray(K, float), corners.T).T
    return float(near * np.linalg.norm(rays, axis=1).max()) * 1.01 + 1e-6
