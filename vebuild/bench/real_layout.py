"""The layout ``vebuild bench real --data DIR`` reads: multi-view sets of real photos with surveyed
cameras, as C. Strecha's "dense multi-view stereo" benchmark sets are distributed (Strecha et al.,
"On benchmarking camera calibration and multi-view stereo for high resolution imagery", CVPR
2008; the sets are in the repository openMVG/SfM_quality_evaluation, for research use).

DIR is one set, or a folder of sets. A set is a folder holding::

    images/NNNN.jpg                      the photos (JPEG or PNG), already undistorted
    gt_dense_cameras/NNNN.jpg.camera     each photo's surveyed camera

A ``.camera`` file is plain text, nine rows of numbers separated by blanks:

- rows 1–3: K, the 3 × 3 intrinsic matrix (pixels; fx, fy may differ slightly);
- row 4: ``0 0 0``;
- rows 5–7: R, the rotation from the camera to the world (its columns are the camera's axes in
  the world, so vebuild's world → camera rotation is its transpose);
- row 8: C, the camera centre in the world (metres);
- row 9: ``W H``, the photo's size in pixels, which must be the image file's.

Anything else is refused with an error naming the file, the row and what was expected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from vebuild.errors import ProjectError, VebuildError

Array = NDArray[np.float64]

IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png")
#: A rotation whose RᵀR differs from the identity by more than this is not one.
ROTATION_TOLERANCE = 1e-3


@dataclass(frozen=True)
class SurveyedPhoto:
    """One photo of a set and its surveyed camera, in vebuild's conventions (DESIGN.md)."""

    id: str            # the image's stem
    image: Path
    K: Array           # as surveyed (fx, fy)
    R: Array           # world → camera (the transpose of the file's)
    C: Array           # camera centre, world, metres
    width: int
    height: int

    @property
    def focal_px(self) -> float:
        """The focal length vebuild's square-pixel camera has: the mean of fx and fy."""
        return float(0.5 * (self.K[0, 0] + self.K[1, 1]))

    @property
    def principal_point(self) -> Array:
        return np.array(self.K[:2, 2], float)


@dataclass(frozen=True)
class SurveyedSet:
    name: str
    folder: Path
    photos: tuple[SurveyedPhoto, ...]


def read_camera(path: Path) -> tuple[Array, Array, Array, int, int]:
    """K, the world → camera R, C, W, H from a ``.camera`` file; ProjectError naming the file and
    the row otherwise."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ProjectError(path, "", "camera file not found") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ProjectError(path, "", f"cannot read the camera file: {getattr(e, 'strerror', None) or e}") from None
    rows = [line.split() for line in text.splitlines() if line.strip()]
    if len(rows) != 9:
        raise ProjectError(path, "", f"expected 9 rows (K: 3, '0 0 0', R: 3, C, 'W H'), found {len(rows)}")
    values: list[list[float]] = []
    for i, row in enumerate(rows):
        want = 2 if i == 8 else 3
        if len(row) != want:
            raise ProjectError(path, f"row {i + 1}", f"expected {want} numbers, found {len(row)}: {' '.join(row)!r}")
        try:
            numbers = [float(v) for v in row]
        except ValueError:
            raise ProjectError(path, f"row {i + 1}", f"expected numbers, found {' '.join(row)!r}") from None
        if not all(math.isfinite(v) for v in numbers):
            raise ProjectError(path, f"row {i + 1}", f"expected finite numbers, found {' '.join(row)!r}")
        values.append(numbers)
    K = np.array(values[0:3])
    if not (K[0, 0] > 0 and K[1, 1] > 0 and K[2, 2] == 1 and K[1, 0] == 0 and K[2, 0] == 0 and K[2, 1] == 0):
        raise ProjectError(path, "rows 1-3", "expected an intrinsic matrix [[fx, s, cx], [0, fy, cy], [0, 0, 1]] "
                           "with fx, fy > 0")
    if any(v != 0 for v in values[3]):
        raise ProjectError(path, "row 4", f"expected '0 0 0', found {' '.join(rows[3])!r}")
    R_cw = np.array(values[4:7])
    if np.abs(R_cw.T @ R_cw - np.eye(3)).max() > ROTATION_TOLERANCE or np.linalg.det(R_cw) < 0:
        raise ProjectError(path, "rows 5-7", "expected a rotation (camera to world): orthonormal rows, "
                           "determinant +1")
    w, h = values[8]
    if w != int(w) or h != int(h) or w < 1 or h < 1:
        raise ProjectError(path, "row 9", "expected the photo's width and height in pixels, found "
                           f"{' '.join(rows[8])!r}")
    return K, R_cw.T.copy(), np.array(values[7]), int(w), int(h)


def _image_size(path: Path) -> tuple[int, int]:
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(path) as im:
            return int(im.size[0]), int(im.size[1])
    except (OSError, UnidentifiedImageError) as e:
        raise ProjectError(path, "", f"cannot read the image: {e}") from None


def read_set(folder: Path) -> SurveyedSet:
    """One set: every image with its ``.camera`` file, in name order."""
    images_dir, cams_dir = folder / "images", folder / "gt_dense_cameras"
    images = sorted(p for p in images_dir.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file())
    if not images:
        raise ProjectError(images_dir, "", f"expected photos ({', '.join(IMAGE_SUFFIXES)}), found none")
    photos = []
    for image in images:
        cam = cams_dir / f"{image.name}.camera"
        if not cam.is_file():
            raise ProjectError(cam, "", f"camera file not found: every photo of {images_dir} needs its surveyed "
                               f"camera, {cams_dir}/NAME.camera (NAME the image's file name)")
        K, R, C, w, h = read_camera(cam)
        size = _image_size(image)
        if size != (w, h):
            raise ProjectError(cam, "row 9", f"the camera is {w}×{h} pixels but its image {image} is "
                               f"{size[0]}×{size[1]}")
        photos.append(SurveyedPhoto(image.stem, image, K, R, C, w, h))
    if len(photos) < 2:
        raise ProjectError(images_dir, "", f"expected two photos or more in a set, found {len(photos)}")
    return SurveyedSet(folder.name, folder, tuple(photos))


def _is_set(folder: Path) -> bool:
    return (folder / "images").is_dir() and (folder / "gt_dense_cameras").is_dir()


def find_sets(data: Path, names: tuple[str, ...] | None = None) -> list[SurveyedSet]:
    """The sets under ``data`` (itself a set, or a folder of sets, searched two levels deep);
    ``names``: only the sets of these folder names, each of which must be there."""
    if not data.is_dir():
        raise VebuildError(f"{data}: --data: expected a folder of photo sets (each with images/ and "
                           "gt_dense_cameras/), found " + ("a file" if data.exists() else "nothing there"))
    folders = [data] if _is_set(data) else sorted(
        {p for p in [*data.glob("*/"), *data.glob("*/*/")] if p.is_dir() and _is_set(p)})
    if names is not None:
        missing = [n for n in names if not any(f.name == n for f in folders)]
        if missing:
            raise VebuildError(f"{data}: --data: expected the set(s) {', '.join(missing)} (a folder with images/ and "
                               "gt_dense_cameras/), found " + (", ".join(f.name for f in folders) or "none"))
        folders = [f for f in folders if f.name in names]
    if not folders:
        raise VebuildError(f"{data}: --data: expected a photo set (a folder with images/ and gt_dense_cameras/) "
                           "or a folder of them, found none")
    return [read_set(f) for f in folders]
