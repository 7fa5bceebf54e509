"""Image files (layer 3): opened bounded in pixels and decoded whole, hashed, their EXIF read.

Every image vebuild reads (photos, atlas pages) is opened through :func:`open_image`, so that an
image too large, damaged or truncated is a :class:`~vebuild.errors.ProjectError` naming the file
and the field, before its pixels are decoded where it is too large.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from PIL import Image, UnidentifiedImageError

from ..errors import ProjectError

#: The most pixels an image vebuild reads may have: 120 megapixels, more than the largest camera
#: sensor in use (100 MP) and below Pillow's decompression-bomb guard (179 MP). Larger images are
#: refused before they are decoded.
MAX_IMAGE_PIXELS = 120_000_000
_CHUNK = 1 << 20


def image_size(image: Path, file: Any, where: str) -> tuple[int, int]:
    # The whole image is decoded, so that a truncated or damaged file is refused now rather than
    # when a later stage reads its pixels.
    if not image.is_file():
        raise ProjectError(file, where, f"photo file not found: {image}")
    with open_image(image, file, where, decode=True) as img:
        return img.size


@contextlib.contextmanager
def open_image(image: Path | Any, file: Any, where: str, decode: bool = True,
               max_pixels: int = MAX_IMAGE_PIXELS, label: str | None = None) -> Iterator[Image.Image]:
    """An image opened with Pillow, its size bounded before its pixels are decoded (``decode``:
    decoded whole here, so that a damaged file is refused with a clear message).

    Raises
    ------
    ProjectError naming ``file`` and ``where`` (the JSON path of the field that names the image):
    the image is missing, not an image, damaged or truncated, or larger than ``max_pixels``.
    """
    shown = label or str(image)
    try:
        with warnings.catch_warnings():
            # Pillow warns above 89 MP and refuses above 179 MP; the bound here is checked below.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            img = Image.open(image)
    except FileNotFoundError:
        raise ProjectError(file, where, f"image file not found: {shown}") from None
    except Image.DecompressionBombError:
        raise ProjectError(file, where, f"the image {shown} has more than {max_pixels / 1e6:g} megapixels, more "
                           "than vebuild reads (a larger one is refused before it is decoded)") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as e:
        raise ProjectError(file, where, f"cannot open {shown} as an image: {e}") from None
    with img:
        w, h = img.size
        if w * h > max_pixels:
            raise ProjectError(file, where, f"the image {shown} is {w}×{h} = {w * h / 1e6:.4g} megapixels, more than "
                               f"the {max_pixels / 1e6:g} megapixels vebuild reads (refused before decoding it)")
        if decode:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                    img.load()
            except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:
                raise ProjectError(file, where, f"the image {shown} cannot be decoded: it is damaged or truncated "
                                   f"({e})") from None
        yield img


def sha256_bytes(data: bytes) -> str:
    """SHA-256 (lowercase hex) of bytes already in memory."""
    return hashlib.sha256(data).hexdigest()


def sha256_file(path: str | os.PathLike[str]) -> str:
    """SHA-256 (lowercase hex) of a file's bytes, read in 1 MiB chunks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


# EXIF tags (EXIF 2.3): Make and Model in IFD0; the rest in the Exif IFD.
_MAKE, _MODEL, _EXIF_IFD = 0x010F, 0x0110, 0x8769
_FOCAL_LENGTH, _FOCAL_35MM, _FOCAL_PLANE_XRES, _FOCAL_PLANE_UNIT = 37386, 41989, 41486, 41488
#: FocalPlaneResolutionUnit → millimetres per unit (2 inch, the default, 3 cm, 4 mm, 5 µm).
_MM_PER_UNIT = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}


def read_exif(path: str | os.PathLike[str]) -> dict[str, Any]:
    """What the camera recorded about a photo's focal length.

    Returns
    -------
    dict with the keys of FORMAT.md's ``exif`` object that the file gives (``{}`` for none):
    make, model, focal_length_mm, focal_length_35mm, focal_plane_x_resolution_per_mm, and the
    derived focal_length_px, preferably f_mm × resolution, else from the 35 mm equivalent over the
    image diagonal. The focal-plane resolution is taken to refer to the image as stored.
    """
    with Image.open(path) as img:
        width, height = img.size
        try:
            exif = img.getexif()
            sub = exif.get_ifd(_EXIF_IFD)
        except Exception:  # noqa: BLE001 -- EXIF is advisory: a damaged block must not stop the photo
            return {}
    out: dict[str, Any] = {}
    for key, tag in (("make", _MAKE), ("model", _MODEL)):
        if text := _text(exif.get(tag)):
            out[key] = text
    # EXIF writes 0 for "unknown"; only positive values are kept.
    if (f_mm := _positive(sub.get(_FOCAL_LENGTH))) is not None:
        out["focal_length_mm"] = f_mm
    if (f_35 := _positive(sub.get(_FOCAL_35MM))) is not None:
        out["focal_length_35mm"] = f_35
    res = _positive(sub.get(_FOCAL_PLANE_XRES))
    mm_per_unit = _MM_PER_UNIT.get(sub.get(_FOCAL_PLANE_UNIT, 2))
    if res is not None and mm_per_unit is not None:
        out["focal_plane_x_resolution_per_mm"] = res / mm_per_unit
    if f_mm is not None and "focal_plane_x_resolution_per_mm" in out:
        out["focal_length_px"] = f_mm * out["focal_plane_x_resolution_per_mm"]
    elif f_35 is not None:
        # The 35 mm equivalent matches the diagonals of the image and of a 36 × 24 mm frame.
        out["focal_length_px"] = f_35 * math.hypot(width, height) / math.hypot(36.0, 24.0)
    return out


def _positive(value: Any) -> float | None:
    try:
        x = float(value)  # IFDRational and int alike; a 0/0 rational gives nan
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return x if math.isfinite(x) and x > 0 else None


def _text(value: Any) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return value.strip("\x00 ") if isinstance(value, str) else ""
