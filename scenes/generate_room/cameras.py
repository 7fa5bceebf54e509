"""The five cameras and their projection (x_cam = R (X − C), u ~ K x_cam; pixel centres at i + 0.5)."""

from __future__ import annotations

import math

import numpy as np

from .parameters import BASE_HEIGHT, BASE_WIDTH

# id, centre C (m), yaw/pitch/roll (deg, FORMAT.md), f (px), principal point offset from the
# image centre (px), exposure gain — all at scale 1 (1600 × 1200).
CAMERA_SPECS = [
    ("p1", (4.50, 3.60, 1.65), 200.0, -17.0, 2.0, 1350.0, (24.0, -18.0), 1.00),
    ("p2", (4.60, 1.90, 1.75), 193.0, -16.0, -2.2, 1700.0, (-27.0, 15.0), 0.93),
    ("p3", (4.65, 3.75, 1.45), 246.0, 0.0, 0.0, 1150.0, (0.0, 0.0), 1.06),
    ("p4", (2.35, 0.40, 1.50), 90.0, 0.0, 0.0, 1000.0, (0.0, 0.0), 0.97),
    ("p5", (1.40, 3.80, 1.70), 285.0, -22.0, 1.8, 1100.0, (12.0, 26.0), 1.03),
]


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
    """The five cameras, for photos of (1600 × scale) × (1200 × scale) pixels.

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
                    "roll_deg": roll, "exposure": exposure})
    return out


def project(cam: dict, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (n, 2) and camera depths z_cam (n,) of world points X (n, 3)."""
    x_cam = (np.atleast_2d(X) - cam["C"]) @ cam["R"].T
    z = x_cam[:, 2]
    K = cam["K"]
    u = K[0, 0] * x_cam[:, 0] / z + K[0, 2]
    v = K[1, 1] * x_cam[:, 1] / z + K[1, 2]
    return np.column_stack([u, v]), z


def pixel_rays(cam: dict, uv: np.ndarray) -> np.ndarray:
    """World directions (n, 3) of the rays through pixel positions uv (n, 2) (not normalised)."""
    K = cam["K"]
    d_cam = np.column_stack([(uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1],
                             np.ones(len(uv))])
    return d_cam @ cam["R"]  # row-vector form of Rᵀ d_cam


