"""Generated single photos of rooms and streets, with what a user clicks on them and the truth:
the scenes of ``vebuild bench single-view`` (:mod:`vebuild.bench.single_view`).

A scene is one photo of a floor (z = 0) before a wall or a building's front: the plane y = D, D
3–7 m ahead in a **room**, 8–25 m in a **street**. The camera stands at (0, 0, h), h 1.2–2 m
(hand-held) or 3–5 m (a CCTV camera on a wall or a pole, on a fifth of the photos), and faces
the wall **near-frontally** (its heading within 8° of the wall's normal) or **obliquely** (20–55°
off it), looking down 2–20° (hand-held) or 15–40° (CCTV), rolled by 1° (1σ). The lens is 16–85 mm in
35 mm terms (drawn evenly in its logarithm), on a 1600 × 1200 photo; the principal point lies
0–4 % of the width off centre in a random direction; on a third of the photos a barrel lens moves
the corners by 1–3 % of the half-diagonal (the division model's k1, :mod:`vebuild.camera`). Half
of the photos carry EXIF: the focal length as cameras write it (a 35 mm equivalent in whole mm,
or the focal length in mm with the sensor's focal-plane resolution), off the truth by a few per
cent (:data:`EXIF_ERROR_REL`, 1σ) as real EXIF is; the other half none.

What the user marks (every click the true pixel, through the lens, plus :data:`CLICK_SIGMA_PX`
noise per coordinate): 4–6 vanishing segments per axis along long edges of the scene, those
spanning a third of the photo as polylines with two middle points (a careful user's plumb lines);
the origin marker on the floor; and the scale, one known length with its tape's 1σ: in a room the
height of a door in the wall (2.0–2.1 m, 2 mm), in a street a door in the building's front (2.1–
2.4 m, 3 mm) or a run of kerb along the building (2–4 m, 5 mm). Then the measurements, each the
world points of its clicks in :data:`vebuild.analysis.single_view.SINGLE_VIEW_CLICKS` order and
its true value: the heights above the floor of a person (1.6–1.9 m), a box or a car's roof
corner (0.4–1 m, 1.4–1.6 m) and a window sill (0.8–1.1 m, 0.9–1.2 m) over its foot where the wall
meets the floor; the distances between pairs of floor points (0.5–4 m, 1–10 m); and, for the
other single-view kinds (measured where :data:`vebuild.bench.single_view.KINDS` names them), a
length on the wall (``wall-length``), an object's height on a table or a low wall
(``raised-height``) and a length on the wall as a plane marked by three points (``plane-length``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from vebuild.synthetic import SyntheticPhoto, distort, k1_for_corner_shift, projection_matrix, rotation

Array = NDArray[np.float64]

WIDTH, HEIGHT = 1600, 1200
#: 1σ of one click per coordinate (pixels): a careful user's (vebuild.synthetic.CLICK_NOISE_PX).
CLICK_SIGMA_PX = 0.7
#: The diagonal of a 36 × 24 mm frame (mm), which a 35 mm-equivalent focal length refers to.
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)
#: The lenses, 35 mm-equivalent focal lengths (mm), and where wide ends and long begins.
LENS_MM = (16.0, 85.0)
WIDE_BELOW_MM, LONG_ABOVE_MM = 28.0, 50.0
#: The camera's height above the floor (m): hand-held, and a CCTV camera's; the share of CCTV.
HAND_HELD_M, CCTV_M, CCTV_SHARE = (1.2, 2.0), (3.0, 5.0), 0.2
#: How far the principal point lies off the photo's centre: a share of the width, uniform.
PRINCIPAL_POINT_OFF_REL = (0.0, 0.04)
#: Where the figures split the photos: a principal point nearer the centre than this (a share of
#: the width), or farther.
PRINCIPAL_POINT_NEAR_REL = 0.02
#: The share of photos through a barrel lens, and how far it moves the corners (a share of the
#: half-diagonal; vebuild.synthetic.REAL_DISTORTION_CORNER_REL).
DISTORTED_SHARE, DISTORTION_CORNER_REL = 1.0 / 3.0, (0.01, 0.03)
#: The share of photos with EXIF, and the 1σ of its focal length's error (relative): a lens's
#: marked focal length, a nominal sensor width, focusing (vebuild/calibration/exif.py).
EXIF_SHARE, EXIF_ERROR_REL = 0.5, 0.02
#: The sensor of the EXIF photos that give the focal length in mm (an APS-C camera's width, mm).
SENSOR_WIDTH_MM = 23.5
#: Distance of the wall (room) or the building's front (street) ahead of the camera (m).
WALL_M = {"room": (3.0, 7.0), "street": (8.0, 25.0)}
#: The floor distances measured: how far apart the two points lie (m).
FLOOR_PAIR_M = {"room": (0.5, 4.0), "street": (1.0, 10.0)}
#: Least distance of a clicked point from the photo's edge (px).
MARGIN_PX = 8.0


@dataclass(frozen=True)
class Item:
    """One measurement: its kind (a `vebuild analyse` subcommand), what it measures, the world
    points clicked (in SINGLE_VIEW_CLICKS order) and the true value (m)."""

    kind: str
    what: str
    points: tuple[Array, ...]
    truth: float


@dataclass
class Scene:
    """One generated photo, its conditions, its marks and its measurements."""

    setting: str  # room or street
    photo: SyntheticPhoto
    lens_mm: float  # 35 mm equivalent
    view: str  # frontal or oblique
    mount: str  # hand-held or cctv
    exif: dict[str, Any] | None
    origin: Array  # the origin marker's floor point
    scale: dict[str, Any]  # axis, ends (world), length, sigma, what
    items: list[Item] = field(default_factory=list)
    #: Whether the user marks the origin marker (else calibration puts the origin on the floor
    #: below the camera).
    origin_marker: bool = True

    def pixel(self, X: Array) -> Array:
        """Where the lens puts world point X in the photo (no click noise)."""
        h = projection_matrix(self.photo.K, self.photo.R, self.photo.C) @ np.r_[X, 1.0]
        return distort(self.photo, (h[:2] / h[2])[None])[0]

    @property
    def principal_point_off_rel(self) -> float:
        """How far the principal point lies off the photo's centre, a share of the width."""
        p = self.photo
        return float(np.hypot(*(p.K[:2, 2] - [p.width / 2, p.height / 2])) / p.width)

    @property
    def lens(self) -> str:
        return "wide" if self.lens_mm < WIDE_BELOW_MM else "long" if self.lens_mm > LONG_ABOVE_MM else "normal"

    def conditions(self) -> dict[str, str]:
        """The conditions a figure is split by: each a name → this scene's value."""
        return {"setting": self.setting, "exif": "exif_present" if self.exif else "exif_absent",
                "lens": f"lens_{self.lens}", "view": self.view, "mount": self.mount.replace("-", "_"),
                "lens_distortion": "distorted" if self.photo.k1 else "undistorted",
                "principal_point": ("principal_point_near" if self.principal_point_off_rel < PRINCIPAL_POINT_NEAR_REL
                                    else "principal_point_off"),
                "origin": "origin_marker" if self.origin_marker else "origin_below_camera"}


def _sees(photo: SyntheticPhoto, X: Array, margin: float = MARGIN_PX) -> bool:
    """Whether world point X lies at least 0.5 m in front of the camera and inside the photo."""
    xc = photo.R @ (X - photo.C)
    if xc[2] < 0.5:
        return False
    uv = distort(photo, ((photo.K @ xc)[:2] / xc[2])[None])[0]
    return bool(margin <= uv[0] <= photo.width - margin and margin <= uv[1] <= photo.height - margin)


def _floor_at(photo: SyntheticPhoto, uv: Array) -> Array | None:
    """The floor point a pinhole pixel uv shows, or None above the horizon."""
    d = photo.R.T @ np.linalg.solve(photo.K, np.r_[uv, 1.0])
    if d[2] > -1e-3:
        return None
    X = photo.C + d * (-photo.C[2] / d[2])
    X[2] = 0.0  # on the floor exactly, not to rounding
    return X


def _camera(rng: np.random.Generator, setting: str) -> tuple[SyntheticPhoto, float, str, str, float]:
    """A camera facing the wall y = D: the photo, its lens (mm), view, mount and D."""
    lens_mm = float(np.exp(rng.uniform(*np.log(LENS_MM))))
    f = lens_mm * math.hypot(WIDTH, HEIGHT) / FULL_FRAME_DIAGONAL_MM
    mount = "cctv" if rng.random() < CCTV_SHARE else "hand-held"
    h = rng.uniform(*(CCTV_M if mount == "cctv" else HAND_HELD_M))
    view = "frontal" if rng.random() < 0.5 else "oblique"
    off = rng.uniform(0.0, 8.0) if view == "frontal" else rng.uniform(20.0, 55.0)
    yaw = np.radians(90.0 + rng.choice([-1.0, 1.0]) * off)
    pitch = -np.radians(rng.uniform(15.0, 40.0) if mount == "cctv" else rng.uniform(2.0, 20.0))
    roll = np.radians(rng.normal(0.0, 1.0))
    a, r = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(*PRINCIPAL_POINT_OFF_REL) * WIDTH
    c = np.array([WIDTH / 2.0, HEIGHT / 2.0]) + r * np.array([np.cos(a), np.sin(a)])
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    photo = SyntheticPhoto("p", "single-view", WIDTH, HEIGHT, K, rotation(yaw, pitch, roll), np.array([0.0, 0.0, h]))
    if rng.random() < DISTORTED_SHARE:
        photo.k1 = k1_for_corner_shift(rng.uniform(*DISTORTION_CORNER_REL), K, WIDTH, HEIGHT)
    return photo, lens_mm, view, mount, float(rng.uniform(*WALL_M[setting]))


def _exif(rng: np.random.Generator, lens_mm: float) -> dict[str, Any]:
    """What the camera wrote: its focal length off by EXIF_ERROR_REL (1σ), rounded as cameras round
    it (whole mm)."""
    err = 1.0 + EXIF_ERROR_REL * rng.standard_normal()
    if rng.random() < 0.5:
        return {"make": "Generated", "model": "Phone", "focal_length_35mm": float(max(1, round(lens_mm * err)))}
    # An APS-C camera: the focal length in mm on a sensor SENSOR_WIDTH_MM wide, rounded to whole mm.
    f_px = lens_mm * math.hypot(WIDTH, HEIGHT) / FULL_FRAME_DIAGONAL_MM
    f_mm = float(max(1, round(f_px * SENSOR_WIDTH_MM / WIDTH * err)))
    return {"make": "Generated", "model": "APS-C", "focal_length_mm": f_mm,
            "focal_plane_x_resolution_per_mm": WIDTH / SENSOR_WIDTH_MM}


def _floor_point(rng: np.random.Generator, photo: SyntheticPhoto, D: float, tries: int = 50) -> Array | None:
    """A floor point the photo shows, in front of the wall y = D and within D of the camera's foot."""
    for _ in range(tries):
        X = _floor_at(photo, np.array([rng.uniform(0, photo.width), rng.uniform(0, photo.height)]))
        if X is not None and X[1] < D - 0.1 and np.hypot(X[0], X[1]) <= D and _sees(photo, X):
            return X
    return None


def _on_wall(rng: np.random.Generator, photo: SyntheticPhoto, D: float, z: tuple[float, float],
             tries: int = 60) -> tuple[Array, Array] | None:
    """A point on the wall y = D at a height in ``z``, and its foot where the wall meets the floor,
    both in the photo."""
    for _ in range(tries):
        uv = np.array([rng.uniform(0, photo.width), rng.uniform(0, photo.height)])
        d = photo.R.T @ np.linalg.solve(photo.K, np.r_[uv, 1.0])
        if d[1] <= 1e-3:
            continue
        x = photo.C[0] + d[0] * (D - photo.C[1]) / d[1]
        foot = np.array([x, D, 0.0])
        top = foot + [0.0, 0.0, rng.uniform(*z)]
        if _sees(photo, foot) and _sees(photo, top):
            return foot, top
    return None


def _standing(rng: np.random.Generator, photo: SyntheticPhoto, D: float, height: tuple[float, float],
              tries: int = 30) -> tuple[Array, Array] | None:
    """A floor point and the point ``height`` above it, both in the photo."""
    for _ in range(tries):
        foot = _floor_point(rng, photo, D)
        if foot is None:
            continue
        top = foot + [0.0, 0.0, rng.uniform(*height)]
        if _sees(photo, top):
            return foot, top
    return None


def _items(rng: np.random.Generator, s: Scene, D: float) -> list[Item]:
    """The measurements of a scene (module docstring); those that the photo cannot show are left out."""
    photo, street = s.photo, s.setting == "street"
    out: list[Item] = []
    objects = [("a person", (1.6, 1.9)), ("a car's roof corner" if street else "a box's top corner",
                                          (1.4, 1.6) if street else (0.4, 1.0))]
    for what, height in objects:
        if got := _standing(rng, photo, D, height):
            out.append(Item("photo-height", what, got, float(got[1][2])))
    if got := _on_wall(rng, photo, D, (0.9, 1.2) if street else (0.8, 1.1)):
        out.append(Item("photo-height", "a window sill", got, float(got[1][2])))
    lo, hi = FLOOR_PAIR_M[s.setting]
    for _ in range(3):
        for _try in range(40):
            a, b = _floor_point(rng, photo, D), _floor_point(rng, photo, D)
            if a is not None and b is not None and lo <= np.linalg.norm(a - b) <= hi:
                out.append(Item("floor-distance", "two floor points", (a, b), float(np.linalg.norm(a - b))))
                break
    # The other kinds, measured where vebuild.bench.single_view.KINDS names them.
    w1, w2 = _on_wall(rng, photo, D, (0.5, 2.0)), _on_wall(rng, photo, D, (0.5, 2.0))
    if w1 and w2 and abs(w1[0][0] - w2[0][0]) > 0.3:
        e1, e2 = _on_wall(rng, photo, D, (0.2, 2.5)), _on_wall(rng, photo, D, (0.2, 2.5))
        if e1 and e2:
            out.append(Item("wall-length", "a length on the wall", (w1[0], w2[0], e1[1], e2[1]),
                            float(np.linalg.norm(e1[1] - e2[1]))))
            if (w3 := _on_wall(rng, photo, D, (0.5, 2.0))) and abs(np.cross(w2[1] - w1[1], w3[1] - w1[1])[1]) > 0.1:
                out.append(Item("plane-length", "a length on the wall marked as a plane",
                                (w1[0], w1[1], w2[0], w2[1], w3[0], w3[1], e1[1], e2[1]),
                                float(np.linalg.norm(e1[1] - e2[1]))))
    top_h = rng.uniform(0.4, 1.0) if street else rng.uniform(0.7, 0.8)  # a low wall, a table
    if edge := _standing(rng, photo, D, (top_h, top_h)):
        foot = edge[1] + np.r_[rng.uniform(-0.5, 0.5, 2), 0.0]
        top = foot + [0.0, 0.0, rng.uniform(0.2, 0.4)]
        if _sees(photo, foot) and _sees(photo, top):
            out.append(Item("raised-height", "an object on a table" if not street else "an object on a low wall",
                            (edge[0], edge[1], foot, top), float(top[2] - foot[2])))
    return out


def _scale(rng: np.random.Generator, s: Scene, D: float) -> dict[str, Any] | None:
    """The known length in view (module docstring), or None where the photo shows none."""
    if s.setting == "room" or rng.random() < 0.5:
        lo, hi, sigma = (2.0, 2.1, 0.002) if s.setting == "room" else (2.1, 2.4, 0.003)
        door = _on_wall(rng, s.photo, D, (lo, hi))
        if door is None:
            return None
        return {"axis": "z", "ends": door, "length": float(door[1][2]), "sigma": sigma, "what": "a door's height"}
    kerb_y = D - rng.uniform(2.0, 4.0)
    for _ in range(60):
        a = np.array([rng.uniform(-15.0, 15.0), kerb_y, 0.0])
        b = a + [rng.uniform(2.0, 4.0), 0.0, 0.0]
        if _sees(s.photo, a) and _sees(s.photo, b):
            return {"axis": "x", "ends": (a, b), "length": float(b[0] - a[0]), "sigma": 0.005,
                    "what": "a run of kerb"}
    return None


def _mark_segments(rng: np.random.Generator, s: Scene, D: float) -> bool:
    """4–6 vanishing segments per axis along long edges in front of the wall (module docstring);
    False where the photo does not show enough of them."""
    photo = s.photo
    longer = max(photo.width, photo.height)
    for i, axis in enumerate("xyz"):
        want, out = int(rng.integers(4, 7)), list[Array]()
        for _ in range(4000):
            if len(out) == want:
                break
            uv = np.array([rng.uniform(0, photo.width), rng.uniform(0, photo.height)])
            d = photo.R.T @ np.linalg.solve(photo.K, np.r_[uv, 1.0])
            mid = photo.C + rng.uniform(1.5, 1.1 * D) * d / np.linalg.norm(d)
            half = rng.uniform(0.3, 2.5 if s.setting == "room" else 5.0)
            ends = mid + np.outer([-half, half], np.eye(3)[i])
            if not (_sees(photo, ends[0], 5.0) and _sees(photo, ends[1], 5.0)):
                continue
            P = projection_matrix(photo.K, photo.R, photo.C)
            t = np.linspace(0.0, 1.0, 4)[:, None]
            line = ends[0] + t * (ends[1] - ends[0])
            h = np.hstack([line, np.ones((4, 1))]) @ P.T
            pin = h[:, :2] / h[:, 2:]
            span = float(np.linalg.norm(pin[-1] - pin[0]))
            if span < 0.2 * longer:
                continue
            pts = distort(photo, pin if span >= longer / 3.0 else pin[[0, -1]])
            out.append((pts + rng.normal(0.0, CLICK_SIGMA_PX, pts.shape)).reshape(-1))
        if len(out) < 4:
            return False
        photo.segments[axis] = out
    return True


def scene(rng: np.random.Generator, setting: str, tries: int = 200, contents: int = 10) -> Scene:
    """One photo of a room or a street (module docstring) that shows its scale, its origin marker
    and at least one height and one floor distance. Each camera drawn is given ``contents`` tries
    at what it shows before another is drawn, so that the lenses, views and mounts keep near the
    shares they are drawn in (a long lens in a room sees a door only from far enough)."""
    for _ in range(tries):
        photo, lens_mm, view, mount, D = _camera(rng, setting)
        exif = _exif(rng, lens_mm) if rng.random() < EXIF_SHARE else None
        for _c in range(contents):
            photo.segments = {}
            origin = _floor_point(rng, photo, D)
            if origin is None:
                continue
            s = Scene(setting, photo, lens_mm, view, mount, exif, origin, {})
            scale = _scale(rng, s, D)
            if scale is None:
                continue
            s.scale = scale
            s.items = _items(rng, s, D)
            kinds = {it.kind for it in s.items}
            if {"photo-height", "floor-distance"} <= kinds and _mark_segments(rng, s, D):
                return s
    raise RuntimeError(f"no {setting} photo shows its scale and measurements in {tries} tries")


def click(s: Scene, X: Array, rng: np.random.Generator) -> list[float]:
    """A user's click on world point X: its pixel through the lens plus the click noise."""
    return [float(v) for v in s.pixel(X) + rng.normal(0.0, CLICK_SIGMA_PX, 2)]
