"""Generated 12 MP photos of a room for ``vebuild bench detect``: a fast, honest ray-caster.

The camera of each photo is vebuild's own realistic synthetic camera
(:func:`vebuild.synthetic.realistic_camera`: focal lengths 0.6–1.5 × the width, the principal
point off centre, the EXIF focal length some 4 % off, and a barrel lens moving the corners by
1–3 % of the half-diagonal on half of them), standing in the synthetic room
(:data:`vebuild.synthetic.ROOM`), of the kinds ``3vp``, ``2vp``, ``1vp``, ``frontal`` and
``corridor``. Every pixel's ray is cast exactly (through the division model's closed-form
undistortion, at the pixel's centre) against the room's six faces. The faces carry tile joints,
skirting, dado and picture rails, tile courses below the dado, wall panels and ceiling panels:
lines along the world axes, 1.5 cm wide, box-filtered over each pixel's footprint so that they
are not aliased. As clutter the grouping must reject, tilted posters hang on the walls and a
turned rug lies on the floor. Each face has its own albedo under a smooth light fall-off; the
room's corners are step edges. The image is then blurred (Gaussian, σ 0.5–1.4 px), given sensor
noise (1.5–4 grey levels) and written as a JPEG (quality 80–95). Photos are cached under
``~/.cache/vebuild/bench-detect`` (``VEBUILD_CACHE`` overrides ``~/.cache/vebuild``), never in
the repository: a 12 MP photo takes some seconds to cast.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from vebuild.project.atomic import write_bytes
from vebuild.resources import cache_dir
from vebuild.synthetic import ROOM, SyntheticPhoto, realistic_camera

Array = NDArray[np.float64]

#: Bump when the rendering changes: old caches are then not reused.
GENERATOR_VERSION = 2
#: The kinds of view, cycled through.
KINDS = ("3vp", "3vp", "2vp", "3vp", "corridor", "2vp", "frontal", "3vp", "1vp", "2vp")
LINE_HALF_WIDTH_M = 0.0075


@dataclass(frozen=True)
class GeneratedPhoto:
    path: Path
    truth: dict  # K, R, C, k1, exif_focal_px, kind, width, height, noise, blur, quality


def cache_folder() -> Path:
    return cache_dir() / "bench-detect" / f"v{GENERATOR_VERSION}"


def _coverage(q: Array, step: float, fp: Array, offset: float = 0.0) -> Array:
    """How much of each pixel (footprint fp, metres) the lines q ≡ offset (mod step) cover."""
    d = np.abs((q - offset) - step * np.round((q - offset) / step))
    return np.asarray(np.clip((LINE_HALF_WIDTH_M - d) / fp + 0.5, 0.0, 1.0), np.float32)


def render(cam: SyntheticPhoto, rng: np.random.Generator, band_rows: int = 200) -> NDArray[np.float32]:
    """The room as the camera sees it, (h, w) grey 0–255 before blur, noise and JPEG."""
    w, h = cam.width, cam.height
    f, cx, cy = cam.K[0, 0], cam.K[0, 2], cam.K[1, 2]
    lo, hi = np.zeros(3), ROOM.astype(float)
    albedo = {(0, 0): 0.70, (0, 1): 0.60, (1, 0): 0.76, (1, 1): 0.64, (2, 0): 0.50, (2, 1): 0.88}
    posters = []
    for wall in range(4):
        for _ in range(2):
            posters.append((wall, rng.uniform(0.8, 4.0), rng.uniform(1.0, 2.0), rng.uniform(0.15, 0.35),
                            np.radians(rng.uniform(10, 35) * rng.choice([-1, 1]))))
    rug = (rng.uniform(2.0, ROOM[0] - 2.0), rng.uniform(1.5, ROOM[1] - 1.5), rng.uniform(0.5, 0.9),
           np.radians(rng.uniform(15, 40)))
    light = np.array([ROOM[0] * 0.4, ROOM[1] * 0.6, ROOM[2] - 0.1])
    out = np.empty((h, w), np.float32)
    u = (np.arange(w, dtype=np.float64) + 0.5 - cx) / f
    Rt = cam.R.T
    for r0 in range(0, h, band_rows):
        v = (np.arange(r0, min(h, r0 + band_rows), dtype=np.float64) + 0.5 - cy) / f
        xd, yd = np.meshgrid(u, v)
        s = 1.0 / (1.0 + cam.k1 * (xd**2 + yd**2))
        ray = np.stack([xd * s, yd * s, np.ones_like(xd)], axis=-1)  # camera, z = 1
        d = ray @ Rt.T  # world directions
        with np.errstate(divide="ignore", invalid="ignore"):
            t_ax = np.where(d > 0, (hi - cam.C) / d, (lo - cam.C) / d)
        t_ax = np.where(np.isfinite(t_ax) & (t_ax > 0), t_ax, np.inf)
        axis = np.argmin(t_ax, axis=-1)
        t = np.take_along_axis(t_ax, axis[..., None], -1)[..., 0]
        X = cam.C + t[..., None] * d
        side = (np.take_along_axis(d, axis[..., None], -1)[..., 0] > 0).astype(int)
        cos_inc = np.abs(np.take_along_axis(d, axis[..., None], -1)[..., 0]) / np.linalg.norm(d, axis=-1)
        fp = t * np.linalg.norm(ray, axis=-1) / f / np.maximum(cos_inc, 0.15)
        a = np.zeros_like(t)
        for (ax, sd), al in albedo.items():
            a[(axis == ax) & (side == sd)] = al
        dark = np.zeros_like(t, dtype=np.float32)
        floor, ceil = (axis == 2) & (side == 0), (axis == 2) & (side == 1)
        wall = axis < 2
        # Tile joints on the floor, panels on the ceiling, rails and panels on the walls.
        dark = np.maximum(dark, floor * np.maximum(_coverage(X[..., 0], 0.4, fp), _coverage(X[..., 1], 0.4, fp)))
        ceil_lines = np.maximum(_coverage(X[..., 0], 0.6, fp, 0.3), _coverage(X[..., 1], 0.6, fp, 0.3))
        dark = np.maximum(dark, ceil * ceil_lines)
        along = np.where(axis == 0, X[..., 1], X[..., 0])
        # Walls: skirting, dado and picture rails, tile courses between them, panels.
        rails = np.maximum(_coverage(X[..., 2], 100.0, fp, 0.1), _coverage(X[..., 2], 100.0, fp, 0.9))
        rails = np.maximum(rails, _coverage(X[..., 2], 100.0, fp, 2.5))
        courses = np.where(X[..., 2] < 0.9, _coverage(X[..., 2], 0.2, fp, 0.1), 0.0)
        panels = np.where(X[..., 2] < 0.9, _coverage(along, 0.3, fp, 0.1), _coverage(along, 0.7, fp, 0.25))
        dark = np.maximum(dark, wall * np.maximum(np.maximum(rails, courses), panels))
        shade = np.ones_like(t, dtype=np.float32)
        for wl, ac, zc, half, th in posters:
            on = wall & (axis == wl % 2) & (side == wl // 2)
            pa, pz = along - ac, X[..., 2] - zc
            qa, qz = np.cos(th) * pa + np.sin(th) * pz, -np.sin(th) * pa + np.cos(th) * pz
            cov = np.clip((half - np.maximum(np.abs(qa), np.abs(qz))) / fp + 0.5, 0.0, 1.0)
            shade = np.where(on, shade * (1.0 - 0.45 * cov), shade)
        pa, pz = X[..., 0] - rug[0], X[..., 1] - rug[1]
        qa, qz = np.cos(rug[3]) * pa + np.sin(rug[3]) * pz, -np.sin(rug[3]) * pa + np.cos(rug[3]) * pz
        cov = np.clip((rug[2] - np.maximum(np.abs(qa), np.abs(qz))) / fp + 0.5, 0.0, 1.0)
        shade = np.where(floor, shade * (1.0 - 0.3 * cov), shade)
        fall = 1.0 / (1.0 + 0.04 * np.sum((X - light) ** 2, axis=-1))
        val = a * shade * (1.0 - 0.55 * dark) * (0.55 + 0.45 * fall)
        out[r0:r0 + len(v)] = (235.0 * val).astype(np.float32)
    return out


def photograph(cam: SyntheticPhoto, rng: np.random.Generator) -> tuple[bytes, dict]:
    """The JPEG bytes of the camera's photo and what was done to it."""
    import cv2

    img = render(cam, rng)
    blur = float(rng.uniform(0.5, 1.4))
    noise = float(rng.uniform(1.5, 4.0))
    quality = int(rng.integers(80, 96))
    blurred = np.asarray(cv2.GaussianBlur(img, (0, 0), blur), np.float32)
    img = blurred + rng.normal(0.0, noise, img.shape).astype(np.float32)
    buf = io.BytesIO()
    Image.fromarray(np.clip(img, 0, 255).astype(np.uint8), "L").save(buf, "JPEG", quality=quality)
    return buf.getvalue(), {"blur_px": blur, "noise_grey": noise, "jpeg_quality": quality}


def generated_photos(n: int, *, width: int = 4000, height: int = 3000, seed: int = 2107,
                     progress: bool = False) -> list[GeneratedPhoto]:
    """n photos (cached), each with its truth."""
    folder = cache_folder() / f"{width}x{height}-s{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    items = range(n)
    if progress:
        from vebuild.console.bars import Bar

        items = Bar(items, desc="generating photos", unit="photo")
    for i in items:
        path, meta = folder / f"g{i:03d}.jpg", folder / f"g{i:03d}.json"
        if path.exists() and meta.exists():
            out.append(GeneratedPhoto(path, json.loads(meta.read_text())))
            continue
        rng = np.random.default_rng([seed, i])
        kind = KINDS[i % len(KINDS)]
        cam = realistic_camera(rng, kind, width, height, photo_id=f"g{i:03d}", distortion=bool(i % 2))
        data, how = photograph(cam, rng)
        truth = {"kind": kind, "width": width, "height": height, "K": cam.K.tolist(), "R": cam.R.tolist(),
                 "C": cam.C.tolist(), "k1": cam.k1, "exif_focal_px": cam.exif_focal_px,
                 "exif_focal_sigma_rel": cam.exif_focal_sigma_rel, **how}
        write_bytes(path, data)
        write_bytes(meta, json.dumps(truth).encode())
        out.append(GeneratedPhoto(path, truth))
    return out


def exif_record(truth: dict) -> dict:
    """An EXIF record (FORMAT.md) whose focal length is the photo's EXIF focal length: an APS-C
    sensor 23.5 mm wide, the focal length in mm to 0.01 mm."""
    res = truth["width"] / 23.5
    return {"make": "vebuild", "model": "synthetic", "focal_length_mm": round(truth["exif_focal_px"] / res, 2),
            "focal_plane_x_resolution_per_mm": res}
