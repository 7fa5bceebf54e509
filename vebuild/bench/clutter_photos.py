"""Generated photos of a street façade with the clutter real photos have, for detection's tests.

A building stands on the plane y = 0 (x along the façade, z up; 24 m wide, 12 m high): pilasters
and downpipes run its full height (the long verticals), storey bands and a cornice run across it,
and its windows are recessed 0.25 m, so their reveals show short edges along y, the third
direction. The camera stands 10–22 m in front of it, 1.6 m up, looking up at it by 2–10°, turned
from the façade's normal by 2–9° (``frontal``: near-frontal, the third direction weak) or 20–40°
(``oblique``, the building's corner and side wall in view). Each photo carries a mix of the
clutter classes of real streets (:data:`CLUTTER`):

- ``cobbles``: a pavement of stones 0.12–0.2 m, each turned at random (many short edges in every
  direction, on the ground, so toward points on the horizon);
- ``tree``: a trunk and a crown of some 2500 leaves turned at random in 3D (short edges, every way);
- ``wires``: two or three wires sagging 0.8–2 m between poles across the view (curves);
- ``railing``: a stair along the façade rising 28–38°, with a handrail, a mid-rail and a string
  (long straight edges toward a point off the horizontal axes) and vertical balusters;
- ``roof``: a roof rising 30–45° back from the cornice, its tile rows along the slope (many long
  edges toward a point between the vertical and the depth direction), or a gable in the
  façade's plane.

Every surface is a flat polygon projected exactly by the pinhole camera (clipped at a near plane,
drawn far to near, anti-aliased at twice the resolution), then the lens's division-model
distortion is applied exactly by resampling (on half of the photos, the corners moved 1–3 %),
and the photo is blurred (σ 0.5–1.2 px), given noise (1.5–3.5 grey levels) and written as a JPEG
(quality 82–95). The camera is :mod:`vebuild.synthetic`'s realistic one: f 0.6–1.5 × the width,
the principal point 3 % off centre (1σ), EXIF 4 % off. Photos are cached under
``~/.cache/vebuild/clutter`` (``VEBUILD_CACHE`` overrides ``~/.cache/vebuild``).
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from vebuild.project.atomic import write_bytes
from vebuild.resources import cache_dir
from vebuild.synthetic import (
    REAL_DISTORTION_CORNER_REL,
    REAL_EXIF_FOCAL_ERROR_REL,
    REAL_PRINCIPAL_POINT_SIGMA_REL,
    exif_focal_px,
    k1_for_corner_shift,
    rotation,
)

from .detect_photos import GeneratedPhoto

Array = NDArray[np.float64]

#: Bump when the rendering changes: old caches are then not reused.
GENERATOR_VERSION = 1  # (its truth names the sloped edges' directions: "slopes")
#: The clutter classes (module docstring).
CLUTTER = ("cobbles", "tree", "wires", "railing", "roof")
#: The building: width, height (m), window recess depth (m).
FACADE_W, FACADE_H, RECESS = 24.0, 12.0, 0.25
NEAR_M = 0.3
SUPERSAMPLE = 2
#: The set's seed.
SEED = 4401

Poly = tuple[Array, float]  # world polygon (k, 3), grey level 0–255


def _quad(o: Array, a: Array, b: Array) -> Array:
    return np.array([o, o + a, o + a + b, o + b], float)


def _facade(rng: np.random.Generator, C: Array) -> list[Poly]:
    ex, ez, ey = np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), np.array([0, 1.0, 0])
    out: list[Poly] = [(_quad(np.zeros(3), FACADE_W * ex, FACADE_H * ez), 190.0)]
    if C[0] < 0:  # the side wall at x = 0, seen from the left
        out.append((_quad(np.zeros(3), 14.0 * ey, FACADE_H * ez), 150.0))
    if C[0] > FACADE_W:
        out.append((_quad(np.array([FACADE_W, 0, 0]), 14.0 * ey, FACADE_H * ez), 150.0))
    for x in (0.0, 6.0, 12.0, 18.0, FACADE_W - 0.5):  # pilasters: the long verticals
        out.append((_quad(np.array([x, -0.001, 0]), 0.5 * ex, FACADE_H * ez), 215.0))
    for x in (5.6, 17.6):  # downpipes
        out.append((_quad(np.array([x, -0.002, 0]), 0.12 * ex, FACADE_H * ez), 95.0))
    for z in (3.6, 7.2, 10.8):  # storey bands
        out.append((_quad(np.array([0, -0.003, z]), FACADE_W * ex, 0.2 * ez), 160.0))
    out.append((_quad(np.array([0, -0.004, FACADE_H - 0.5]), FACADE_W * ex, 0.5 * ez), 225.0))
    for bay in range(4):
        for k in range(2):
            x0 = 6.0 * bay + 1.2 + 2.2 * k
            for z0 in (1.2, 4.6, 8.2):
                out += _window(np.array([x0, 0.0, z0]), 1.2, 1.9, C, float(rng.uniform(40, 80)))
    return out


def _window(o: Array, w: float, h: float, C: Array, dark: float) -> list[Poly]:
    ex, ez, ey = np.array([w, 0, 0]), np.array([0, 0, h]), np.array([0, RECESS, 0])
    out: list[Poly] = [(_quad(o + np.array([0, -0.005, 0]), ex, ez), dark)]
    # Reveals (the faces the camera sees): short edges along y.
    if C[0] > o[0]:
        out.append((_quad(o, ey, ez), 130.0))
    if C[0] < o[0] + w:
        out.append((_quad(o + ex, ey, ez), 130.0))
    if C[2] < o[2] + h:
        out.append((_quad(o + ez, ey, ex), 110.0))
    if C[2] > o[2]:
        out.append((_quad(o, ey, ex), 170.0))
    return out


def _cobbles(rng: np.random.Generator, C: Array, slopes: list[list[float]]) -> list[Poly]:
    out: list[Poly] = [(_quad(np.array([C[0] - 30, C[1] - 1, 0]), np.array([60.0, 0, 0]),
                              np.array([0, -C[1] + 1, 0])), 120.0)]
    for y in np.arange(C[1] + 1.0, -0.1, 0.22):
        for x in np.arange(C[0] - 14.0, C[0] + 14.0, 0.22):
            s = rng.uniform(0.12, 0.2)
            t = rng.uniform(0, np.pi)
            a = 0.5 * s * np.array([np.cos(t), np.sin(t), 0])
            b = 0.5 * s * np.array([-np.sin(t), np.cos(t), 0])
            ctr = np.array([x, y, 0.001]) + rng.uniform(-0.03, 0.03, 3) * [1, 1, 0]
            out.append((np.array([ctr - a - b, ctr + a - b, ctr + a + b, ctr - a + b]), float(rng.uniform(70, 170))))
    return out


def _tree(rng: np.random.Generator, C: Array, slopes: list[list[float]]) -> list[Poly]:
    base = np.array([C[0] + rng.uniform(-4, 4), rng.uniform(-5.0, -2.5), 0.0])
    top = base + np.array([rng.uniform(-0.4, 0.4), rng.uniform(-0.3, 0.3), 4.5])
    out: list[Poly] = [(np.array([base - [0.15, 0, 0], base + [0.15, 0, 0], top + [0.08, 0, 0], top - [0.08, 0, 0]]),
                        60.0)]
    centre = top + np.array([0, 0, 2.0])
    for _ in range(2500):
        p = centre + rng.normal(0, 1.0, 3) * [1.4, 1.0, 1.1]
        a, b = rng.normal(0, 1, 3), rng.normal(0, 1, 3)
        s = rng.uniform(0.1, 0.25)
        a = s * a / np.linalg.norm(a)
        b = s * b / np.linalg.norm(b)
        out.append((np.array([p - a, p + b, p + a, p - b]), float(rng.uniform(30, 110))))
    return out


def _ribbon(P: Array, d: Array, grey: float) -> list[Poly]:
    return [(np.array([P[i], P[i + 1], P[i + 1] + d, P[i] + d]), grey) for i in range(len(P) - 1)]


def _wires(rng: np.random.Generator, C: Array, slopes: list[list[float]]) -> list[Poly]:
    out: list[Poly] = []
    y = rng.uniform(-6.0, -3.0)
    a, b = C[0] - 25.0, C[0] + 25.0
    for _ in range(int(rng.integers(2, 4))):
        za, zb, sag = rng.uniform(6.0, 8.5), rng.uniform(6.0, 8.5), rng.uniform(0.8, 2.0)
        t = np.linspace(0.0, 1.0, 120)
        x = a + (b - a) * t
        z = za + (zb - za) * t - 4 * sag * t * (1 - t)
        P = np.c_[x, np.full_like(x, y + rng.uniform(-0.5, 0.5)), z]
        out += _ribbon(P, np.array([0, 0, 0.025]), 35.0)
    return out


def _railing(rng: np.random.Generator, C: Array, slopes: list[list[float]]) -> list[Poly]:
    slope = np.radians(rng.uniform(28, 38))
    x0, y = C[0] + rng.uniform(-6, 0), rng.uniform(-2.5, -1.0)
    run = 6.0
    d = np.array([np.cos(slope), 0, np.sin(slope)]) * run / np.cos(slope)
    slopes.append([float(np.cos(slope)), 0.0, float(np.sin(slope))])
    o = np.array([x0, y, 0.0])
    out: list[Poly] = [(_quad(o + [0, 0, -0.3], d, np.array([0, 0, 0.3])), 90.0)]  # the string
    for h, th in ((0.5, 0.04), (1.0, 0.06)):  # mid-rail, handrail
        out.append((_quad(o + [0, -0.02, h], d, np.array([0, 0, th])), 45.0))
    for t in np.arange(0.05, 1.0, 0.03):
        p = o + t * d
        out.append((_quad(p + [0, -0.01, 0], np.array([0.025, 0, 0]), np.array([0, 0, 1.0])), 55.0))
    return out


def _roof(rng: np.random.Generator, C: Array, slopes: list[list[float]]) -> list[Poly]:
    out: list[Poly] = []
    top = FACADE_H
    if rng.uniform() < 0.6:  # rising back from the cornice, tile rows along the slope
        slope = np.radians(rng.uniform(30, 45))
        up = np.array([0, np.cos(slope), np.sin(slope)]) * 7.0
        slopes.append([0.0, float(np.cos(slope)), float(np.sin(slope))])
        out.append((_quad(np.array([0, 0, top]), np.array([FACADE_W, 0, 0]), up), 100.0))
        for x in np.arange(0.3, FACADE_W, 0.45):
            out.append((_quad(np.array([x, -0.01, top + 0.01]), np.array([0.04, 0, 0]), up), 55.0))
        for x0 in (5.0, 15.0):  # dormers: sloped cheeks
            o = np.array([x0, 1.5, top + 1.5 * np.tan(slope)])
            out.append((np.array([o, o + [2.5, 0, 0], o + [1.25, 0, 1.4]]), 175.0))
    else:  # a gable in the façade's plane
        pitch = np.radians(rng.uniform(30, 45))
        peak = np.array([FACADE_W / 2, -0.01, top + FACADE_W / 2 * np.tan(pitch)])
        slopes += [[float(np.cos(pitch)), 0.0, float(s * np.sin(pitch))] for s in (1.0, -1.0)]
        out.append((np.array([[0, -0.01, top], [FACADE_W, -0.01, top], peak]), 175.0))
        for k in range(1, 9):
            s = k / 9.0
            a, b = np.array([0, -0.02, top]), np.array([FACADE_W, -0.02, top])
            for e in (a, b):
                p, q = e + s * 0.9 * (peak - e), e + (s * 0.9 + 0.05) * (peak - e)
                out.append((np.array([p, q, q + [0, 0, -0.08], p + [0, 0, -0.08]]), 80.0))
    return out


def _clip(Xc: Array) -> Array:
    """A camera-frame polygon clipped to z ≥ NEAR_M (Sutherland–Hodgman, one plane)."""
    out = []
    for i in range(len(Xc)):
        a, b = Xc[i], Xc[(i + 1) % len(Xc)]
        ina, inb = a[2] >= NEAR_M, b[2] >= NEAR_M
        if ina:
            out.append(a)
        if ina != inb:
            t = (NEAR_M - a[2]) / (b[2] - a[2])
            out.append(a + t * (b - a))
    return np.array(out).reshape(-1, 3)


def render(K: Array, R: Array, C: Array, w: int, h: int, polys: list[Poly]) -> NDArray[np.float32]:
    """The polygons as a pinhole camera sees them, far to near, (h, w) grey 0–255."""
    import cv2

    s = SUPERSAMPLE
    img = np.full((h * s, w * s), 200.0, np.float32)  # the sky
    depth = []
    cam = []
    for X, g in polys:
        Xc = (X - C) @ R.T
        depth.append(float(np.max(Xc[:, 2])))
        cam.append((Xc, g))
    shift = 4
    for k in np.argsort(depth)[::-1]:
        Xc, g = cam[k]
        if depth[k] < NEAR_M:
            continue
        Xc = _clip(Xc)
        if len(Xc) < 3:
            continue
        uv = (Xc @ K.T)[:, :2] / Xc[:, 2:3] * s
        if np.all(uv[:, 0] < 0) or np.all(uv[:, 0] > w * s) or np.all(uv[:, 1] < 0) or np.all(uv[:, 1] > h * s):
            continue
        uv = np.clip(uv - 0.5, -1e5, 1e5)  # pixel centres at integer + 0.5
        pts = np.round(uv * (1 << shift)).astype(np.int32)
        cv2.fillPoly(img, [pts], float(g), lineType=cv2.LINE_AA, shift=shift)
    return np.asarray(cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA), np.float32)


def camera(rng: np.random.Generator, kind: str, width: int, height: int) -> tuple[Array, Array, Array]:
    """K, R (world → camera), C of a photo of the façade (module docstring)."""
    f = width * rng.uniform(0.6, 1.5)
    c = np.array([width / 2, height / 2]) + rng.normal(0.0, REAL_PRINCIPAL_POINT_SIGMA_REL * width, 2)
    turn = rng.uniform(2, 9) if kind == "frontal" else rng.uniform(20, 40)
    turn = np.radians(turn) * rng.choice([-1, 1])
    dist = rng.uniform(10, 22)
    C = np.array([FACADE_W / 2 + rng.uniform(-5, 5), -dist, 1.6])
    if kind == "oblique":  # stand off to one side, so that the corner shows
        C[0] = FACADE_W / 2 - np.sign(turn) * (FACADE_W / 2 + rng.uniform(-4, 6))
        turn = np.arctan2(FACADE_W / 2 - C[0], dist) + np.radians(rng.uniform(-8, 8))
    yaw = np.pi / 2 - turn
    pitch = np.radians(rng.uniform(2, 10))
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    return K, rotation(yaw, pitch, np.radians(rng.normal(0.0, 1.5))), C


def photograph(rng: np.random.Generator, kind: str, clutter: tuple[str, ...], width: int, height: int,
               distortion: bool) -> tuple[bytes, dict]:
    """The JPEG bytes of one photo and its truth."""
    import cv2

    from vebuild.camera import Lens, undistort_pixels

    K, R, C = camera(rng, kind, width, height)
    polys = _facade(rng, C)
    makers = {"cobbles": _cobbles, "tree": _tree, "wires": _wires, "railing": _railing, "roof": _roof}
    slopes: list[list[float]] = []
    for name in clutter:
        polys += makers[name](rng, C, slopes)
    k1 = k1_for_corner_shift(rng.uniform(*REAL_DISTORTION_CORNER_REL), K, width, height) if distortion else 0.0
    m = int(0.15 * max(width, height)) if distortion else 0  # margin the lens pulls in
    Km = K.copy()
    Km[:2, 2] += m
    img = render(Km, R, C, width + 2 * m, height + 2 * m, polys)
    if distortion:
        uu, vv = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
        src = undistort_pixels(K, np.stack([uu, vv], -1).reshape(-1, 2), Lens(k1)).reshape(height, width, 2) + m - 0.5
        img = np.asarray(cv2.remap(img, src[..., 0].astype(np.float32), src[..., 1].astype(np.float32),
                                   cv2.INTER_LINEAR), np.float32)
    blur, noise, quality = float(rng.uniform(0.5, 1.2)), float(rng.uniform(1.5, 3.5)), int(rng.integers(82, 96))
    img = np.asarray(cv2.GaussianBlur(img, (0, 0), blur), np.float32)
    img = img + rng.normal(0, noise, img.shape).astype(np.float32)
    buf = io.BytesIO()
    Image.fromarray(np.clip(img, 0, 255).astype(np.uint8), "L").save(buf, "JPEG", quality=quality)
    truth = {"kind": kind, "clutter": list(clutter), "slopes": slopes, "width": width, "height": height,
             "K": K.tolist(), "R": R.tolist(), "C": C.tolist(), "k1": k1,
             "exif_focal_px": exif_focal_px(K[0, 0], rng, REAL_EXIF_FOCAL_ERROR_REL),
             "exif_focal_sigma_rel": REAL_EXIF_FOCAL_ERROR_REL, "blur_px": blur, "noise_grey": noise,
             "jpeg_quality": quality}
    return buf.getvalue(), truth


def clutter_photo(i: int, *, width: int = 1600, height: int = 1200, seed: int = SEED) -> GeneratedPhoto:
    """Photo i of the set (cached), with its truth: kinds alternate frontal and oblique; each carries
    one to four clutter classes, every class in turn; the lens distorts every other pair."""
    folder = cache_dir() / "clutter" / f"v{GENERATOR_VERSION}" / f"{width}x{height}-s{seed}"
    path, meta = folder / f"c{i:03d}.jpg", folder / f"c{i:03d}.json"
    if path.exists() and meta.exists():
        return GeneratedPhoto(path, json.loads(meta.read_text()))
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng([seed, i])
    kind = ("frontal", "oblique")[i % 2]
    k = int(rng.integers(2, 5))
    clutter = tuple(sorted({CLUTTER[i % len(CLUTTER)], *(str(c) for c in rng.choice(CLUTTER, k - 1, replace=False))}))
    data, truth = photograph(rng, kind, clutter, width, height, distortion=bool((i // 2) % 2))
    write_bytes(path, data)
    write_bytes(meta, json.dumps(truth).encode())
    return GeneratedPhoto(path, truth)


def clutter_photos(n: int, *, width: int = 1600, height: int = 1200, seed: int = SEED) -> list[GeneratedPhoto]:
    """Photos 0 … n − 1 of the set (:func:`clutter_photo`)."""
    return [clutter_photo(i, width=width, height=height, seed=seed) for i in range(n)]


def photo_record(photo: GeneratedPhoto, pid: str, *, exif: bool = True) -> dict:
    """The photo object detection takes (its id, size and, with ``exif``, EXIF's focal length)."""
    from .detect_photos import exif_record

    rec: dict = {"id": pid, "file": str(photo.path), "width": photo.truth["width"], "height": photo.truth["height"]}
    if exif:
        rec["exif"] = exif_record(photo.truth)
    return rec


def load(photo: GeneratedPhoto) -> NDArray[np.uint8]:
    return np.asarray(Image.open(Path(photo.path)).convert("L"), np.uint8)
