"""Plumb lines of a room seen through a true fisheye lens, for the two-term lens tests.

A CCTV camera high in a room's corner looks down across it through an equidistant lens (r = f θ,
θ the angle off the optical axis) whose diagonal field of view is ``fov_deg``. The room's straight
edges along x, y and z (its floor, wall and ceiling edges and lines on its walls and floor) are
projected through that lens exactly, each kept where it lies in the frame and sampled as a polyline
of ``points`` evenly spaced points with Gaussian noise of ``noise_px`` per coordinate, directed
toward its axis' positive end, as calibrate_photo takes them. No vebuild lens model is used to
make them: the truth is the fisheye's own mapping.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vebuild.camera import look_rotation

ROOM = np.array([6.0, 5.0, 2.8])  # metres along x, y, z


@dataclass(frozen=True)
class FisheyeView:
    width: int
    height: int
    f: float  # the lens's focal length (dr/dθ at the centre), pixels
    c: np.ndarray  # principal point, pixels
    R: np.ndarray
    C: np.ndarray
    segments: dict[str, list[np.ndarray]]

    def pixels(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where the lens puts world points (n, 3), and whether each is in front of it (θ < 90°)."""
        x = (np.asarray(X, float) - self.C) @ self.R.T
        rho = np.hypot(x[:, 0], x[:, 1])
        theta = np.arctan2(rho, x[:, 2])
        scale = np.where(rho > 0, self.f * theta / np.where(rho > 0, rho, 1.0), 0.0)
        return self.c + x[:, :2] * scale[:, None], theta < np.radians(89.0)

    def corner_displacement_px(self) -> float:
        """How far the lens moves the photo's farthest corner from where a pinhole of the same f
        and principal point puts it: f tan θ − r at the corner, θ = r / f."""
        r = float(np.max(np.hypot(np.array([0.0, self.width]) - self.c[0],
                                  np.array([[0.0], [self.height]]) - self.c[1])))
        return self.f * np.tan(r / self.f) - r


def _edges() -> dict[str, list[tuple[np.ndarray, np.ndarray]]]:
    """Straight edges of the room along each axis: (start, end) in the axis' positive sense."""
    L = ROOM
    out: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {"x": [], "y": [], "z": []}
    for y in (0.0, 1.2, 2.5, 3.8, L[1]):  # floor and ceiling lines along x (tiles, beams, wall feet)
        for z in (0.0, L[2]):
            out["x"].append((np.array([0.0, y, z]), np.array([L[0], y, z])))
    for z in (0.9, 1.8):  # lines along the walls y = 0 and y = L (a dado rail, shelves)
        for y in (0.0, L[1]):
            out["x"].append((np.array([0.0, y, z]), np.array([L[0], y, z])))
    for x in (0.0, 1.5, 3.0, 4.5, L[0]):
        for z in (0.0, L[2]):
            out["y"].append((np.array([x, 0.0, z]), np.array([x, L[1], z])))
    for z in (0.9, 1.8):
        for x in (0.0, L[0]):
            out["y"].append((np.array([x, 0.0, z]), np.array([x, L[1], z])))
    for x, y in ((0.0, 0.0), (L[0], 0.0), (0.0, L[1]), (L[0], L[1]), (2.0, 0.0), (4.0, 0.0), (0.0, 1.7),
                 (0.0, 3.4), (2.0, L[1]), (4.0, L[1]), (L[0], 1.7), (L[0], 3.4)):
        out["z"].append((np.array([x, y, 0.0]), np.array([x, y, L[2]])))
    return out


def fisheye_view(rng: np.random.Generator, fov_deg: float = 150.0, width: int = 1280, height: int = 720,
                 points: int = 9, noise_px: float = 0.5, min_length_px: float = 120.0) -> FisheyeView:
    """The room seen by a corner camera through an equidistant lens of ``fov_deg`` diagonally."""
    C = np.array([0.35, 0.3, 2.55])
    target = np.array([ROOM[0] * 0.65, ROOM[1] * 0.6, 0.4])
    R = look_rotation(target - C, roll=float(rng.normal(0.0, 0.02)))
    c = np.array([width / 2.0, height / 2.0]) + rng.normal(0.0, 4.0, 2)
    f = 0.5 * float(np.hypot(width, height)) / np.radians(0.5 * fov_deg)
    view = FisheyeView(width, height, f, c, R, C, {})
    segs: dict[str, list[np.ndarray]] = {}
    t = np.linspace(0.0, 1.0, 2001)
    for axis, edges in _edges().items():
        for a, b in edges:
            uv, front = view.pixels(a + t[:, None] * (b - a))
            ok = front & (uv[:, 0] >= 1) & (uv[:, 1] >= 1) & (uv[:, 0] <= width - 1) & (uv[:, 1] <= height - 1)
            if not ok.any():
                continue
            # the longest run of samples in the frame
            edges_ok = np.diff(np.r_[0, ok.astype(int), 0])
            starts, stops = np.flatnonzero(edges_ok == 1), np.flatnonzero(edges_ok == -1)
            k = int(np.argmax(stops - starts))
            run = slice(starts[k], stops[k])
            if np.sum(np.linalg.norm(np.diff(uv[run], axis=0), axis=1)) < min_length_px:
                continue
            tt = np.linspace(t[run][0], t[run][-1], points)
            p, _ = view.pixels(a + tt[:, None] * (b - a))
            p = p + rng.normal(0.0, noise_px, p.shape)
            segs.setdefault(axis, []).append(p.ravel())
    return FisheyeView(width, height, f, c, R, C, segs)
