"""The six cameras and their projection (x_cam = R (X − C), u ~ K x_cam; pixel centres at i + 0.5).

Five are pinholes. The sixth, p6, looks through a wide lens with barrel distortion, by the
one-parameter division model (Fitzgibbon 2001) on f-normalised coordinates centred on the
principal point, written out here on its own (vebuild has its own, in vebuild/camera.py):

    x_d = (u − c) / f                   where the lens put a pixel (distorted)
    x_u = x_d / (1 + k1 |x_d|²)         where a pinhole would have put it
    x_d = x_u · 2 / (1 + √(1 − 4 k1 |x_u|²))     the inverse (the root of k1 r_u r_d² − r_d + r_u = 0
                                                 that tends to r_u as k1 → 0)

k1 < 0 is barrel distortion: a pixel near the corner shows a point a pinhole would have put
farther out, so straight lines bow outward and the corners are pulled in.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

from .parameters import BASE_HEIGHT, BASE_WIDTH

# id, centre C (m), yaw/pitch/roll (deg, FORMAT.md), f (px), principal point offset from the
# image centre (px), exposure gain — all at scale 1 (1600 × 1200). p6 stands in the south-west
# corner, looking across the room to the north-east corner, tilted down.
P6_CENTRE, P6_YAW, P6_PITCH, P6_ROLL = (0.35, 0.35, 2.10), 40.0, -35.0, 1.0
CAMERA_SPECS = [
    ("p1", (4.50, 3.60, 1.65), 200.0, -17.0, 2.0, 1350.0, (24.0, -18.0), 1.00),
    ("p2", (4.60, 1.90, 1.75), 193.0, -16.0, -2.2, 1700.0, (-27.0, 15.0), 0.93),
    ("p3", (4.65, 3.75, 1.45), 246.0, 0.0, 0.0, 1150.0, (0.0, 0.0), 1.06),
    ("p4", (2.35, 0.40, 1.50), 90.0, 0.0, 0.0, 1000.0, (0.0, 0.0), 0.97),
    ("p5", (1.40, 3.80, 1.70), 285.0, -22.0, 1.8, 1100.0, (12.0, 26.0), 1.03),
    ("p6", P6_CENTRE, P6_YAW, P6_PITCH, P6_ROLL, 1224.0, (-16.0, 12.0), 0.98),
]

#: The lens of each photo that is not a pinhole: the division model's k1 (module docstring). p6 is an
#: 18 mm lens on an APS-C sensor (a 66° horizontal field, a kit zoom at its wide end): k1 = −0.035
#: moves its farthest corner 25.4 px toward the centre, 2.5 % of the 1000 px half-diagonal (wide
#: lenses show 1–3 %). k1 is on f-normalised coordinates, so it does not change with --scale.
LENS_K1 = {"p6": -0.035}
#: Sensor pixel pitch (mm, at scale 1) of each photo's camera. The others are a small phone sensor
#: (PIXEL_PITCH_MM); p6 is a camera with an APS-C sensor 23.5 mm wide (1600 px at 1/68 mm: its
#: 1224 px focal length is 18 mm exactly).
SENSOR_PITCH_MM = {"p6": Fraction(1, 68)}
#: How far each photo's EXIF focal length is off the truth, relative (0 where it is exact). p4's camera
#: records its lens's nominal focal length, 2.5 % short of the calibrated one (a fixed lens reports
#: one value; a real camera's was 4.1 % short of its calibrated value): the photo whose f rests on EXIF.
EXIF_FOCAL_ERROR_REL = {"p4": -0.025}


def rotation_from_ypr(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """World → camera rotation R (rows: the camera's right, down, forward axes in the world).

    forward = (cos p cos y, cos p sin y, sin p); right before roll = (sin y, −cos y, 0) (level);
    down = forward × right; roll turns right toward down (clockwise seen from behind).
    """
    y, p, r = (math.radians(v) for v in (yaw_deg, pitch_deg, roll_deg))
    fwd = np.array([math.cos(p) * math.cos(y), math.cos(p) * math.sin(y), math.sin(p)])
    right0 = np.array([math.sin(y), -math.cos(y), 0.0])
    down0 = np.cross(fwd, right0)
    right = math.cos(r) * right0 + math.sin(r) * down0
    down = -math.sin(r) * right0 + math.cos(r) * down0
    return np.vstack([right, down, fwd])


def cameras(scale: float = 1.0) -> list[dict]:
    """The six cameras, for photos of (1600 × scale) × (1200 × scale) pixels.

    Scaling an image with a corner-origin pixel frame maps u → scale·u exactly, so f, cx and cy
    all scale by the same factor.
    """
    out = []
    for pid, C, yaw, pitch, roll, f, (dx, dy), exposure in CAMERA_SPECS:
        w, h = int(round(BASE_WIDTH * scale)), int(round(BASE_HEIGHT * scale))
        sx, sy = w / BASE_WIDTH, h / BASE_HEIGHT
        if abs(sx - sy) > 1e-12:
            raise ValueError(f"scale {scale} gives non-square pixels ({w} x {h})")
        fs, cx, cy = f * sx, (BASE_WIDTH / 2 + dx) * sx, (BASE_HEIGHT / 2 + dy) * sx
        K = np.array([[fs, 0.0, cx], [0.0, fs, cy], [0.0, 0.0, 1.0]])
        out.append({"id": pid, "width": w, "height": h, "scale": sx, "K": K,
                    "R": rotation_from_ypr(yaw, pitch, roll), "C": np.array(C, dtype=np.float64),
                    "f": fs, "principal_point": (cx, cy), "yaw_deg": yaw, "pitch_deg": pitch,
                    "roll_deg": roll, "exposure": exposure, "k1": LENS_K1.get(pid, 0.0)})
    return out


def distort_normalised(x_u: np.ndarray, k1: float) -> np.ndarray:
    """Pinhole normalised coordinates (n, 2) → where the lens puts them (module docstring)."""
    if k1 == 0.0:
        return x_u
    r2 = np.sum(x_u * x_u, axis=1, keepdims=True)
    disc = 1.0 - 4.0 * k1 * r2
    if np.any(disc < 0):  # only a pincushion lens (k1 > 0) has a field edge; this example's is barrel
        raise ValueError("a point beyond the field of the pincushion lens")
    return x_u * (2.0 / (1.0 + np.sqrt(disc)))


def undistort_normalised(x_d: np.ndarray, k1: float) -> np.ndarray:
    """The lens's normalised coordinates (n, 2) → the pinhole's: x_u = x_d / (1 + k1 |x_d|²)."""
    if k1 == 0.0:
        return x_d
    return x_d / (1.0 + k1 * np.sum(x_d * x_d, axis=1, keepdims=True))


def corner_displacement_px(cam: dict) -> float:
    """How far the lens moves the photo's farthest corner from where a pinhole would put it (px)."""
    K = cam["K"]
    w, h = cam["width"], cam["height"]
    uv = np.array([[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]])
    x_d = (uv - K[:2, 2]) / np.array([K[0, 0], K[1, 1]])
    moved = (undistort_normalised(x_d, cam["k1"]) - x_d) * np.array([K[0, 0], K[1, 1]])
    return float(np.max(np.linalg.norm(moved, axis=1)))


def project(cam: dict, X: np.ndarray, lens: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (n, 2) and camera depths z_cam (n,) of world points X (n, 3): where the
    photo shows them, through its lens; with lens=False where a pinhole would (the same for a
    pinhole camera)."""
    x_cam = (np.atleast_2d(X) - cam["C"]) @ cam["R"].T
    z = x_cam[:, 2]
    K = cam["K"]
    k1 = cam.get("k1", 0.0) if lens else 0.0
    if k1 == 0.0:
        u = K[0, 0] * x_cam[:, 0] / z + K[0, 2]
        v = K[1, 1] * x_cam[:, 1] / z + K[1, 2]
        return np.column_stack([u, v]), z
    x_d = distort_normalised(x_cam[:, :2] / z[:, None], k1)
    return x_d * np.array([K[0, 0], K[1, 1]]) + K[:2, 2], z


def pixel_rays(cam: dict, uv: np.ndarray) -> np.ndarray:
    """World directions (n, 3) of the rays through pixel positions uv (n, 2) (not normalised): a
    pixel as the lens put it is undistorted to the pinhole's normalised coordinate first."""
    K = cam["K"]
    x_d = np.column_stack([(uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1]])
    x_u = undistort_normalised(x_d, cam.get("k1", 0.0))
    d_cam = np.column_stack([x_u, np.ones(len(uv))])
    return d_cam @ cam["R"]  # row-vector form of Rᵀ d_cam


def pinhole_pixels(cam: dict, uv: np.ndarray) -> np.ndarray:
    """Where a pinhole would have put the pixel positions uv (n, 2) that the lens put there."""
    K = cam["K"]
    f = np.array([K[0, 0], K[1, 1]])
    return undistort_normalised((uv - K[:2, 2]) / f, cam.get("k1", 0.0)) * f + K[:2, 2]


