"""Seeded synthetic scenes with known answers, for tests and benchmarks.

Random cameras inside a room look at random edges along the world axes and at named markers;
the "user's" clicks are the true projections plus Gaussian noise. The projection here is written
out independently of :mod:`vebuild.camera` (as P = K [R | −RC] with a homogeneous division), so a
convention slip in the product is not silently repeated by its test data.

The kinds of photo:

- ``3vp``: the camera is tilted, all three axes recede;
- ``2vp``: a level camera, verticals are parallel in the image (vertical vanishing point at infinity);
- ``1vp``: a level camera facing a wall squarely: only one vanishing point is finite, the focal length
  comes from EXIF;
- ``frontal``: as ``1vp``, turned and tilted up to 2° off square (the others near infinity);
- ``corridor``: looking down the room's length, up to 6° off its axis and 4° up or down: one
  strong vanishing point near the centre, the others some 10 focal lengths out or more.

Real photographs are unkinder than the defaults: :func:`realistic_camera` adds lens distortion (a
wide APS-C lens), a principal point a few per cent off centre and an EXIF focal length a few per
cent off, and :func:`add_segments` can mark long edges as polylines with middle points, clicked on
the distorted photo.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from vebuild.model.scene import model_from_dict
from vebuild.project import new_photo_entry, new_project, save_project

Array = NDArray[np.float64]

ROOM = np.array([6.0, 5.0, 2.8])  # x, y, z extent of the synthetic room, metres
#: Click noise of a careful user (the issue's figure), px: the default for every synthetic mark.
CLICK_NOISE_PX = 0.7
#: 1σ of the relative error in a camera's EXIF focal length: the focal length in millimetres is
#: rounded (to 0.1 mm on a 4–6 mm phone lens: up to 1.2 %) and the sensor width is a nominal one
#: (1–2 %). Synthetic photos carry an EXIF focal length off by this much, never the exact truth.
EXIF_FOCAL_ERROR_REL = 0.02
#: What real cameras do, for :func:`realistic_camera`. The principal point's offset from the
#: centre, 1σ per coordinate as a share of the longer side: the prior calibration claims
#: (calibration.priors.PRINCIPAL_POINT_SIGMA_REL; a real camera measured 2.7 %).
REAL_PRINCIPAL_POINT_SIGMA_REL = 0.03
#: 1σ of the relative error of a real EXIF focal length: nominal focal lengths rounded to 0.1 mm or
#: 1 mm (35 mm equivalent), nominal sensor widths, focus breathing; a real camera, calibrated on
#: a public set of its photographs, was 4.1 % off. The σ calibration is told for EXIF in these photos.
REAL_EXIF_FOCAL_ERROR_REL = 0.04
#: How far a wide APS-C lens (18–24 mm) moves the photo's corners by barrel distortion, as a share
#: of the half-diagonal: 1–3 %.
REAL_DISTORTION_CORNER_REL = (0.01, 0.03)


@dataclass
class SyntheticPhoto:
    """A known camera and the marks a careful user would make on its photo."""

    id: str
    kind: str
    width: int
    height: int
    K: Array
    R: Array  # world → camera
    C: Array
    segments: dict[str, Any] = field(default_factory=dict)  # axis → (n, 4) array, or a list of polylines
    markers: dict[str, Array] = field(default_factory=dict)
    exif_focal_px: float | None = None
    #: The lens's distortion (division model, vebuild/camera.py: x_u = x_d / (1 + k1 |x_d|²)); the
    #: marks are made on the distorted photo.
    k1: float = 0.0
    #: The 1σ (relative) of the error drawn for exif_focal_px.
    exif_focal_sigma_rel: float = EXIF_FOCAL_ERROR_REL
    #: axis → indices into segments[axis] of segments that are not along it (vebuild/synthetic/clutter.py).
    clutter: dict[str, list[int]] = field(default_factory=dict)


def projection_matrix(K: Array, R: Array, C: Array) -> Array:
    """P = K [R | −R C]."""
    return K @ np.hstack([R, -(R @ C)[:, None]])


def project_points(P: Array, X: Array) -> tuple[Array, Array]:
    """Pixels and depths of world points X (n, 3) under the 3×4 P."""
    h = np.hstack([X, np.ones((len(X), 1))]) @ P.T
    return h[:, :2] / h[:, 2:3], h[:, 2]


def rotation(yaw: float, pitch: float, roll: float) -> Array:
    """World→camera rotation built from the camera's axes in the world (written out directly).

    The optical axis points at heading `yaw` with elevation `pitch`; image right is horizontal
    before roll; roll turns right/down about the optical axis (clockwise seen from behind).
    """
    fwd = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    right0 = np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    down0 = np.cross(fwd, right0)
    right = np.cos(roll) * right0 + np.sin(roll) * down0
    down = np.cross(fwd, right)
    return np.vstack([right, down, fwd])  # rows: camera axes in the world


def random_camera(rng: np.random.Generator, kind: str, width: int = 1600, height: int = 1200,
                  photo_id: str = "p", principal_point_sigma_rel: float = 0.01) -> SyntheticPhoto:
    """A random camera of the given kind standing in the synthetic room; its principal point is
    off the centre by principal_point_sigma_rel × the width (1σ per coordinate)."""
    f = width * rng.uniform(0.6, 1.5)
    c = np.array([width / 2, height / 2]) + rng.normal(0.0, principal_point_sigma_rel * width, 2)
    C = np.array([rng.uniform(1.0, ROOM[0] - 1.0), rng.uniform(1.0, ROOM[1] - 1.0), rng.uniform(1.2, 1.9)])
    if kind == "3vp":
        yaw = rng.uniform(0, 2 * np.pi)
        pitch = np.radians(rng.uniform(12, 40)) * rng.choice([-1, 1])
        roll = np.radians(rng.normal(0.0, 3.0))
    elif kind == "2vp":
        yaw = rng.uniform(0, 2 * np.pi)
        pitch = np.radians(rng.uniform(-1.5, 1.5))
        roll = np.radians(rng.normal(0.0, 2.0))
    elif kind == "1vp":
        yaw = np.radians(90.0 * rng.integers(4) + rng.uniform(-1.0, 1.0))
        pitch = np.radians(rng.uniform(-1.0, 1.0))
        roll = np.radians(rng.normal(0.0, 1.0))
    elif kind == "frontal":
        yaw = np.radians(90.0 * rng.integers(4) + rng.uniform(-2.0, 2.0))
        pitch = np.radians(rng.uniform(-2.0, 2.0))
        roll = np.radians(rng.normal(0.0, 1.0))
    elif kind == "corridor":
        # Down the room's length (x), from near one end wall.
        yaw = np.radians(180.0 * rng.integers(2) + rng.uniform(-6.0, 6.0))
        pitch = np.radians(rng.uniform(-4.0, 4.0))
        roll = np.radians(rng.normal(0.0, 1.0))
    else:
        raise ValueError(f"kind must be 3vp, 2vp, 1vp, frontal or corridor, got {kind!r}")
    if kind == "corridor":
        C[0] = ROOM[0] - 0.4 if np.cos(yaw) < 0 else 0.4
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    photo = SyntheticPhoto(photo_id, kind, width, height, K, rotation(yaw, pitch, roll), C)
    photo.exif_focal_px = exif_focal_px(f, rng)
    return photo


def exif_focal_px(f: float, rng: np.random.Generator, sigma_rel: float = EXIF_FOCAL_ERROR_REL) -> float:
    """What a camera's EXIF says its focal length ``f`` (px) is: off by sigma_rel (1σ).

    The error is drawn from a child of ``rng`` (``spawn``), which leaves ``rng``'s own stream as it
    was: the scene's other draws do not depend on whether EXIF is asked for.
    """
    return float(f * (1.0 + sigma_rel * rng.spawn(1)[0].standard_normal()))


def k1_for_corner_shift(corner_rel: float, K: Array, width: int, height: int) -> float:
    """The division model's k1 of a barrel lens that pulls the photo's corners in by corner_rel of
    the half-diagonal: a corner at normalised radius r_d came from r_u = r_d / (1 + k1 r_d²), so
    corner_rel = (r_u − r_d) / r_d gives k1 = −corner_rel / (r_d² (1 + corner_rel))."""
    corners = np.array([[0.0, 0.0], [width, 0.0], [0.0, height], [width, height]])
    r_d = float(np.max(np.linalg.norm(corners - K[:2, 2], axis=1))) / K[0, 0]
    return -corner_rel / (r_d**2 * (1.0 + corner_rel))


def realistic_camera(rng: np.random.Generator, kind: str, width: int = 1600, height: int = 1200,
                     photo_id: str = "p", distortion: bool = True,
                     principal_point_sigma_rel: float = REAL_PRINCIPAL_POINT_SIGMA_REL,
                     exif_sigma_rel: float = REAL_EXIF_FOCAL_ERROR_REL,
                     principal_point_offset_rel: tuple[float, float] | None = None,
                     exif_error_rel: tuple[float, float] | None = None) -> SyntheticPhoto:
    """A camera as real photographs have them: a principal point off centre by
    principal_point_sigma_rel (1σ), an EXIF focal length off by exif_sigma_rel (1σ) and, with
    ``distortion``, a barrel lens moving the corners by REAL_DISTORTION_CORNER_REL of the
    half-diagonal (uniform).

    principal_point_offset_rel : instead, a principal point this far off centre (a share of the
        longer side, uniform in the range, in a random direction).
    exif_error_rel : instead, an EXIF focal length off by this much (uniform, either sign);
        exif_sigma_rel is still what the photo says its EXIF's 1σ is.
    """
    photo = random_camera(rng, kind, width, height, photo_id, principal_point_sigma_rel)
    photo.exif_focal_px = exif_focal_px(photo.K[0, 0], rng, exif_sigma_rel)
    photo.exif_focal_sigma_rel = exif_sigma_rel
    if principal_point_offset_rel is not None:
        a = rng.uniform(0.0, 2.0 * np.pi)
        r = rng.uniform(*principal_point_offset_rel) * max(width, height)
        photo.K[:2, 2] = np.array([width / 2.0, height / 2.0]) + r * np.array([np.cos(a), np.sin(a)])
    if exif_error_rel is not None:
        photo.exif_focal_px = float(photo.K[0, 0] * (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(*exif_error_rel)))
    if distortion:
        photo.k1 = k1_for_corner_shift(rng.uniform(*REAL_DISTORTION_CORNER_REL), photo.K, width, height)
    return photo


def distort(photo: SyntheticPhoto, uv: Array) -> Array:
    """Where the photo's lens puts pinhole pixels uv (n, 2): x_d = x_u · 2 / (1 + √(1 − 4 k1 |x_u|²)),
    the division model's inverse, written out here apart from vebuild.camera."""
    if photo.k1 == 0.0:
        return uv
    c, f = photo.K[:2, 2], photo.K[0, 0]
    x = (uv - c) / f
    r2 = np.sum(x**2, axis=1)
    return c + f * x * (2.0 / (1.0 + np.sqrt(np.maximum(1.0 - 4.0 * photo.k1 * r2, 0.0))))[:, None]


def add_segments(photo: SyntheticPhoto, rng: np.random.Generator, noise_px: float = 0.7,
                 per_axis: tuple[int, int] = (4, 6), min_length_rel: float = 0.2, middle_points: int = 0,
                 polyline_min_length_rel: float = 0.35) -> None:
    """Mark 4–6 directed segments per axis along long edges the camera sees.

    A careful user marks long edges: each segment spans at least min_length_rel of the image's
    longer side. With ``middle_points`` > 0, an edge spanning polyline_min_length_rel of it or more
    is marked as a polyline with that many middle points, evenly along the edge (a plumb line).
    Every point is clicked on the distorted photo (``photo.k1``).
    """
    min_length_px = min_length_rel * max(photo.width, photo.height)
    P = projection_matrix(photo.K, photo.R, photo.C)
    for i, axis in enumerate("xyz"):
        n_want = rng.integers(per_axis[0], per_axis[1] + 1)
        out: list[Array] = []
        for _ in range(20000):
            if len(out) == n_want:
                break
            # A point 1.5–7 m ahead, off the optical axis, and an edge through it along the axis.
            depth = rng.uniform(1.5, 7.0)
            lateral = np.linalg.solve(photo.K, np.r_[rng.uniform(0, photo.width), rng.uniform(0, photo.height), 1.0])
            mid = photo.C + depth * (photo.R.T @ (lateral / lateral[2]))
            half = rng.uniform(0.3, 2.5)
            e = np.eye(3)[i]
            ends = np.array([mid - half * e, mid + half * e])
            uv, z = project_points(P, ends)
            if np.any(z < 0.5) or not inside_image(uv, photo.width, photo.height, 5.0):
                continue
            if np.linalg.norm(uv[1] - uv[0]) < min_length_px:
                continue
            if middle_points and np.linalg.norm(uv[1] - uv[0]) >= polyline_min_length_rel * max(photo.width,
                                                                                               photo.height):
                t = np.linspace(0.0, 1.0, middle_points + 2)[:, None]
                uv, _ = project_points(P, ends[0] + t * (ends[1] - ends[0]))
            uv = distort(photo, uv)
            if photo.k1 != 0.0 and not inside_image(uv, photo.width, photo.height, 5.0):
                continue
            out.append((uv + rng.normal(0.0, noise_px, uv.shape)).reshape(-1))
        photo.segments[axis] = np.array(out) if len({len(s) for s in out}) <= 1 else out


def inside_image(uv: Array, w: float, h: float, margin: float) -> bool:
    """Whether every pixel of uv (n, 2) lies at least ``margin`` inside a w × h image."""
    u, v = uv[:, 0], uv[:, 1]
    return bool(np.all((u >= margin) & (u <= w - margin) & (v >= margin) & (v <= h - margin)))


def observe_markers(photo: SyntheticPhoto, markers: dict[str, Array], rng: np.random.Generator,
                    noise_px: float = 0.7) -> None:
    """Record every marker in front of the camera and inside the image (no occluders here)."""
    P = projection_matrix(photo.K, photo.R, photo.C)
    names = list(markers)
    uv, z = project_points(P, np.array([markers[n] for n in names]))
    for n, p, d in zip(names, uv, z, strict=True):
        if d > 0.3 and inside_image(p[None], photo.width, photo.height, 5.0):
            photo.markers[n] = p + rng.normal(0.0, noise_px, 2)


def random_markers(rng: np.random.Generator, n: int = 12) -> dict[str, Array]:
    """The origin marker O at a floor corner, and n − 1 markers around the room."""
    pts = {"O": np.zeros(3)}
    for k in range(1, n):
        pts[f"M{k}"] = rng.uniform([0.2, 0.2, 0.0], ROOM - 0.2)
    return pts


def random_scene(rng: np.random.Generator, kinds: tuple[str, ...] = ("3vp", "3vp", "2vp", "3vp"),
                 width: int = 1600, height: int = 1200, noise_px: float = 0.7,
                 n_markers: int = 12) -> tuple[list[SyntheticPhoto], dict[str, Array]]:
    """Several photos of one synthetic room sharing markers, the origin marker seen by most.

    Cameras of kind 3vp and 2vp look toward the origin corner region; a 1vp camera faces a wall
    squarely (and may not see the origin).
    """
    markers = random_markers(rng, n_markers)
    photos: list[SyntheticPhoto] = []
    for k, kind in enumerate(kinds):
        for _ in range(2000):
            cam = random_camera(rng, kind, width, height, f"p{k + 1}")
            if kind == "1vp":
                # Face a wall squarely, back toward the origin corner, where the markers are.
                cam.R = rotation(np.radians(rng.choice([180.0, 270.0]) + rng.uniform(-1.0, 1.0)),
                                  np.radians(rng.uniform(-1.0, 1.0)), np.radians(rng.normal(0.0, 1.0)))
            if kind in ("3vp", "2vp"):
                # Aim at a point near the origin corner so the cameras share markers.
                target = rng.uniform([0.5, 0.5, 0.0], [3.0, 2.5, 1.0])
                cam.C = np.array([rng.uniform(2.5, ROOM[0] - 0.3), rng.uniform(2.0, ROOM[1] - 0.3), cam.C[2]])
                d = target - cam.C
                yaw = np.arctan2(d[1], d[0])
                if kind == "3vp":
                    pitch = np.arctan2(d[2], np.hypot(d[0], d[1]))
                    pitch = np.clip(pitch, -np.radians(40), -np.radians(14))
                else:
                    pitch = np.radians(rng.uniform(-1.5, 1.5))
                cam.R = rotation(yaw, pitch, np.radians(rng.normal(0.0, 2.0)))
            observe_markers(cam, markers, rng, noise_px)
            shared = set(cam.markers) & {n for p in photos for n in p.markers}
            if kind == "1vp" and len(shared) >= 3 and photos:
                break
            if kind != "1vp" and len(cam.markers) >= 4 and "O" in cam.markers:
                break
        else:
            raise RuntimeError(f"no {kind} camera found that sees enough markers")
        add_segments(cam, rng, noise_px)
        photos.append(cam)
    # A user marks a marker only where it helps: in two photos or more.
    return photos, markers_in_two_photos(photos, markers)


def markers_in_two_photos(photos: list[SyntheticPhoto], markers: dict[str, Array]) -> dict[str, Array]:
    """Keep each photo's marks of the markers seen in two photos or more (a user marks a marker only
    where it helps), and return those markers."""
    counts: dict[str, int] = {}
    for p in photos:
        for n in p.markers:
            counts[n] = counts.get(n, 0) + 1
    for p in photos:
        p.markers = {n: uv for n, uv in p.markers.items() if counts[n] >= 2}
    return {n: X for n, X in markers.items() if counts.get(n, 0) >= 2}


def scale_reference(photos: list[SyntheticPhoto], markers: dict[str, Array]) -> tuple[str, str, float]:
    """The distance a careful user would tape: from O to the best-observed marker far from it.

    Markers seen by more photos are preferred (their positions are better determined), then the
    longer distance (a tape's error is a smaller share of it).
    """
    def score(n: str) -> tuple[int, float]:
        return (sum(n in p.markers for p in photos), float(np.linalg.norm(markers[n])))

    best = max((n for n in markers if n != "O"), key=score)
    return "O", best, float(np.linalg.norm(markers[best] - markers["O"]))


def write_project(folder: Path, photos: list[SyntheticPhoto], markers: dict[str, Array],
                  check: tuple[str, str] | None = None) -> Path:
    """Write a project file for a synthetic scene, with plain grey photos of the right size.

    The photos carry no picture (calibration reads only the marks) but are real JPEG files whose
    hashes the project records. Returns the project file's path.
    """
    folder = Path(folder)
    (folder / "photos").mkdir(parents=True, exist_ok=True)
    data = new_project("synthetic scene")
    data["settings"]["click_sigma_px"] = 0.7
    for p in photos:
        img = folder / "photos" / f"{p.id}.jpg"
        Image.new("RGB", (p.width, p.height), (128, 128, 128)).save(img, quality=90)
        entry = new_photo_entry(folder, img, p.id)
        entry["vanishing_segments"] = {a: [[float(x) for x in s] for s in seg] for a, seg in p.segments.items()}
        entry["marker_observations"] = {n: [float(uv[0]), float(uv[1])] for n, uv in p.markers.items()}
        if p.kind == "1vp" and p.exif_focal_px:
            entry["focal_px"] = {"value": p.exif_focal_px, "sigma": EXIF_FOCAL_ERROR_REL * p.exif_focal_px}
        data["photos"].append(entry)
    data["markers"] = [{"name": n} for n in sorted(markers)]
    data["origin_marker"] = "O"
    a, b, d = scale_reference(photos, markers)
    data["reference_distances"] = [{"a": a, "b": b, "distance": round(d, 4), "sigma": 0.002, "role": "scale"}]
    if check:
        dc = float(np.linalg.norm(markers[check[0]] - markers[check[1]]))
        data["reference_distances"].append({"a": check[0], "b": check[1], "distance": round(dc, 4),
                                            "sigma": 0.002, "role": "check"})
    path = folder / "synthetic.vebuild.json"
    save_project(path, data)
    return path


def model_scene(rng: np.random.Generator, n_boxes: int = 3, n_photos: int = 8, noise_px: float = CLICK_NOISE_PX,
                width: int = 1600, height: int = 1200) -> tuple[dict, dict, list[dict], dict[str, SyntheticPhoto]]:
    """A floor (tied to the origin marker) with boxes resting on it, seen by known cameras.

    Returns the true model nodes, a perturbed starting model (sizes and positions off by ~15 %,
    yaws by ~8°, as a user's first placement), the fixed pins (every box corner visible in a photo,
    with noise) and the photos. Room-sized: boxes within a 6 × 5 m floor.
    """
    floor = {"width": float(ROOM[0]), "depth": float(ROOM[1])}
    truth: list[Mapping[str, Any]] = [{"name": "floor", "primitive": {"type": "quad", "params": floor},
                                    "joint": {"type": "marker", "marker": "O", "handle": "v0", "yaw_deg": 0.0}}]
    start: list[dict[str, Any]] = [dict(truth[0])]
    for k in range(n_boxes):
        size = rng.uniform([0.3, 0.3, 0.3], [1.2, 1.2, 1.8])
        pos = rng.uniform([-2.2, -1.7], [2.2, 1.7])
        yaw = rng.uniform(-45, 45)
        node: dict[str, Any] = {"name": f"box{k}", "parent": "floor",
                "primitive": {"type": "box", "params": dict(zip(("width", "depth", "height"), map(float, size),
                                                                 strict=True))},
                "joint": {"type": "rests_on", "face": "top", "position": [float(pos[0]), float(pos[1])],
                          "yaw_deg": yaw}}
        truth.append(node)
        guess = {**node, "primitive": {"type": "box", "params": {k2: v * rng.uniform(0.85, 1.15)
                                                                  for k2, v in node["primitive"]["params"].items()}},
                 "joint": {**node["joint"], "position": [float(p + rng.normal(0, 0.1)) for p in pos],
                           "yaw_deg": yaw + rng.normal(0, 8.0)}}
        start.append(guess)
    photos: dict[str, SyntheticPhoto] = {}
    for i in range(n_photos):
        cam = random_camera(rng, "3vp", width, height, f"p{i + 1}")
        ang = 2 * np.pi * i / n_photos + rng.uniform(-0.2, 0.2)
        cam.C = np.array([ROOM[0] / 2 + 2.6 * np.cos(ang), ROOM[1] / 2 + 2.1 * np.sin(ang), rng.uniform(1.4, 1.9)])
        d = np.array([ROOM[0] / 2, ROOM[1] / 2, 0.4]) - cam.C
        cam.R = rotation(np.arctan2(d[1], d[0]), np.arctan2(d[2], np.hypot(d[0], d[1])), np.radians(rng.normal(0, 2)))
        photos[cam.id] = cam
    model = model_from_dict(truth, {"O": np.zeros(3)})
    T = model.world_transforms()
    pins = []
    for cam in photos.values():
        P = projection_matrix(cam.K, cam.R, cam.C)
        for mnode in model.nodes:
            if mnode.primitive is None:
                continue
            hs = mnode.primitive.handles() @ T[mnode.name][:3, :3].T + T[mnode.name][:3, 3]
            uv, z = project_points(P, hs)
            for h, p, d in zip(mnode.primitive.handle_names(), uv, z, strict=True):
                if d > 0.3 and inside_image(p[None], cam.width, cam.height, 5.0):
                    pins.append({"photo": cam.id, "node": mnode.name, "handle": h,
                                 "uv": [float(v) for v in p + rng.normal(0, noise_px, 2)], "fixed": True})
    return {"nodes": truth}, {"nodes": start}, pins, photos


def longest_run(flags: Any) -> tuple[int, int]:
    """The longest run of true values in ``flags`` as (start, end), end exclusive; (0, 0) for none:
    the stretch of an edge's samples a photo sees whole, where the generators mark a segment."""
    best, run, start = (0, 0), 0, 0
    for j, v in enumerate(flags):
        run = run + 1 if v else 0
        if run == 1:
            start = j
        if run > best[1] - best[0]:
            best = (start, start + run)
    return best
