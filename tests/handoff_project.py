"""A calibrated one-photo project for the hand-off tests (camera-only glTF, fSpy, web viewer): a
generated photo of a room (tests/one_photo_scene.py ``one_photo``, principal point off centre),
calibrated with no model, two single-view measurements saved as analyses, optionally a lens
distortion k1, and optionally a photo whose pixels show red dots at known floor points (for reading
a screenshot against the camera's projection)."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from one_photo_scene import OnePhoto, one_photo, write_one_photo
from PIL import Image, ImageDraw

from vebuild.actions.calibrate import calibrate_project
from vebuild.analysis.single_view import single_view_command
from vebuild.camera import ImageCamera
from vebuild.camera import project as project_points
from vebuild.project import load_project, save_project
from vebuild.project.decode import photo_camera
from vebuild.project.images import sha256_bytes

#: Radius of the red dots drawn into the test photo (pixels).
DOT_PX = 5


@dataclass
class HandoffProject:
    path: Path
    ph: OnePhoto
    cam: ImageCamera
    dots: np.ndarray  # (n, 3) the floor points drawn as red dots in the photo (world, after calibration)


def _dot_photo(cam: ImageCamera, dots: np.ndarray) -> bytes:
    """A black PNG of the camera's size with a red dot where the lens puts each floor point."""
    img = Image.new("RGB", (cam.width, cam.height), (0, 0, 0))
    uv = project_points(cam.K, cam.R, cam.C, dots, cam.lens)
    big = 8  # drawn 8× larger and reduced, so that each dot's centroid lies where it should to 1/100 px
    hi = Image.new("L", (cam.width * big, cam.height * big), 0)
    dh = ImageDraw.Draw(hi)
    for u, v in uv:
        # the pixel centre (i + 0.5) of the reduced image is at big·i + big/2 − 0.5 in the large one
        cx, cy = u * big - 0.5, v * big - 0.5
        dh.ellipse([cx - DOT_PX * big, cy - DOT_PX * big, cx + DOT_PX * big, cy + DOT_PX * big], fill=255)
    mask = hi.resize((cam.width, cam.height), Image.Resampling.BOX)
    img.paste((255, 0, 0), (0, 0), mask)
    buf = io.BytesIO()
    img.save(buf, "PNG")
    return buf.getvalue()


def make_project(folder: Path, seed: int = 11, k1: float = 0.0, dots: bool = False) -> HandoffProject:
    """The project (module docstring), calibrated and saved in ``folder``."""
    from vebuild.project.records import distortion_record

    folder.mkdir(parents=True, exist_ok=True)
    ph = one_photo(np.random.default_rng(seed))
    path = write_one_photo(folder, ph)
    project = load_project(path)
    calibrate_project(project)
    pid = project.data["photos"][0]["id"]
    rec = project.data["calibration"]["cameras"][pid]
    if k1 != 0.0:
        rec["distortion"] = distortion_record(np.asarray(rec["K"], float), ph.cam.width, ph.cam.height, k1, 0.002,
                                              "test: a wide lens")
    project.data["analyses"] = [
        {"name": "box height", "description": "the box's top above the floor",
         "command": single_view_command("photo-height", pid, [ph.clicks["box_foot"], ph.clicks["box_top"]])},
        {"name": "F1 to F2", "description": "two floor markers",
         "command": single_view_command("floor-distance", pid, [ph.clicks["F1"], ph.clicks["F2"]])},
    ]
    save_project(project)
    project = load_project(path)
    cam = photo_camera(project, pid)
    drawn = np.zeros((0, 3))
    if dots:
        # Floor points at the centres of the grid's cells (off its lines), in front and on the photo.
        xs, ys = np.meshgrid(np.arange(-20, 20) + 0.5, np.arange(-20, 20) + 0.5)
        X = np.c_[xs.ravel(), ys.ravel(), np.zeros(xs.size)]
        depth = (X - cam.C) @ np.asarray(cam.R)[2]
        X = X[depth > 0.5]
        uv = project_points(cam.K, cam.R, cam.C, X, cam.lens)
        inside = (uv[:, 0] > 20) & (uv[:, 0] < cam.width - 20) & (uv[:, 1] > 20) & (uv[:, 1] < cam.height - 20)
        drawn = X[inside & (depth[depth > 0.5] < 12.0)]
        data = _dot_photo(cam, drawn)
        photo = project.data["photos"][0]
        (folder / "photos" / "p.png").write_bytes(data)
        photo["file"] = "photos/p.png"
        photo["sha256"] = sha256_bytes(data)
        save_project(project)
        project = load_project(path)
        cam = photo_camera(project, pid)
    return HandoffProject(path, ph, cam, drawn)
