"""Seeded synthetic photo sets taken with one camera: one K and one lens for every photo.

A photographer's set: one body, one lens, one zoom setting. Every photo of the set has the same
focal length, principal point (a few per cent off centre, as real cameras have it) and, with
``distortion``, the same barrel lens; its EXIF names the same make, model, body serial and focal
length. Among oblique (3vp, 2vp) photos a near-frontal one (kind ``frontal``: a wall seen square to
within 2°) whose lines alone barely fix f: the photo that must borrow the camera's focal length.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from vebuild.project import save_project

from . import (
    CLICK_NOISE_PX,
    REAL_DISTORTION_CORNER_REL,
    SyntheticPhoto,
    add_segments,
    k1_for_corner_shift,
    markers_in_two_photos,
    observe_markers,
    random_camera,
    random_scene,
    write_project,
)

#: The one camera's EXIF: a make and model the sensor database does not know (the focal-plane
#: resolution gives the pixels), one body serial, and the sensor of an APS-C camera (23.6 mm wide).
MAKE, MODEL, SERIAL = "Synthetic", "SC-1", "0000417"
SENSOR_WIDTH_MM = 23.6
#: 1σ of the relative error of the one EXIF focal length the whole set shares.
EXIF_ERROR_REL = 0.02
#: The kinds of a default set: three oblique photos and a near-frontal one.
ONE_CAMERA_KINDS = ("3vp", "3vp", "2vp", "frontal")


def one_camera_set(rng: np.random.Generator, kinds: tuple[str, ...] = ONE_CAMERA_KINDS, width: int = 1600,
                   height: int = 1200, distortion: bool = False, principal_point_sigma_rel: float = 0.03,
                   noise_px: float = CLICK_NOISE_PX, middle_points: int = 0,
                   ) -> tuple[list[SyntheticPhoto], dict[str, np.ndarray]]:
    """Photos of one synthetic room, all taken with one camera (one K, one k1), sharing markers.

    The scene's layout is :func:`vebuild.synthetic.random_scene`'s (a frontal camera faces one of
    the room's walls from anywhere in it, and may see no marker); every camera is then given the
    first one's focal length and a principal point off centre by principal_point_sigma_rel × the
    longer side (1σ per coordinate), its markers observed and its edges marked again through it.
    """
    placed = tuple(k for k in kinds if k != "frontal")
    photos, markers = random_scene(rng, placed, width, height, noise_px, n_markers=20)
    for i, kind in enumerate(kinds):  # a frontal camera faces a wall, wherever it stands: not aimed
        if kind == "frontal":
            photos.insert(i, random_camera(rng, kind, width, height, f"p{i + 1}"))
    for i, p in enumerate(photos):
        p.id = f"p{i + 1}"
    f = photos[0].K[0, 0]
    c = np.array([width / 2.0, height / 2.0]) + rng.normal(0.0, principal_point_sigma_rel * max(width, height), 2)
    K = np.array([[f, 0.0, c[0]], [0.0, f, c[1]], [0.0, 0.0, 1.0]])
    k1 = k1_for_corner_shift(rng.uniform(*REAL_DISTORTION_CORNER_REL), K, width, height) if distortion else 0.0
    exif_f = float(f * (1.0 + rng.normal(0.0, EXIF_ERROR_REL)))
    for p in photos:
        p.K, p.k1, p.exif_focal_px, p.exif_focal_sigma_rel = K.copy(), k1, exif_f, EXIF_ERROR_REL
        p.markers = {}
        observe_markers(p, markers, rng, noise_px)
        p.segments = {}
        add_segments(p, rng, noise_px, middle_points=middle_points)
    return photos, markers_in_two_photos(photos, markers)


def exif_record(photo: SyntheticPhoto, serial: str | None = SERIAL) -> dict[str, Any]:
    """The EXIF a camera of this set writes (FORMAT.md "Photo `exif` object"): its focal length
    exactly as written (no rounding step) on a 23.6 mm sensor."""
    res = photo.width / SENSOR_WIDTH_MM
    f_px = photo.exif_focal_px if photo.exif_focal_px is not None else photo.K[0, 0]
    out: dict[str, Any] = {"make": MAKE, "model": MODEL, "focal_length_mm": round(f_px / res, 4),
                           "focal_length_mm_step": 0, "focal_plane_x_resolution_per_mm": res}
    if serial is not None:
        out["body_serial"] = serial
    return out


def write_one_camera_project(folder: Path, photos: list[SyntheticPhoto], markers: dict[str, np.ndarray],
                             exif: bool = True, serial: str | None = SERIAL) -> Path:
    """:func:`vebuild.synthetic.write_project` with each photo's EXIF record (``exif``)."""
    path = write_project(folder, photos, markers)
    data = json.loads(path.read_text(encoding="utf-8"))
    for entry, p in zip(data["photos"], photos, strict=True):
        entry.pop("focal_px", None)
        if exif:
            entry["exif"] = exif_record(p, serial)
    save_project(path, data)
    return path
